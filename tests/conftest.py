"""Fixtures shared by several test modules."""

from __future__ import annotations

import numpy as np
import pytest
from estimator_helpers import LIN_DT, LIN_H, LIN_N, LinearBend, bend_process_cov, lin_transition


@pytest.fixture(scope="module")
def linear_recording() -> tuple[LinearBend, np.ndarray, np.ndarray]:
    f = LinearBend()
    rng = np.random.default_rng(7)
    F, Q, R = lin_transition(LIN_DT), bend_process_cov(f.noise.bend_accel_psd, LIN_DT), f.meas_cov()
    x = np.array([0.3, -0.2, 0.5, 0.4])
    z = []
    for _ in range(LIN_N):
        z.append(LIN_H @ x + rng.multivariate_normal(np.zeros(2), R))
        x = F @ x + rng.multivariate_normal(np.zeros(4), Q)
    return f, np.arange(LIN_N) * LIN_DT, np.array(z)


# --- the order in which pytest-xdist hands out the test files --------------------------------
#: The files that take longest, longest first. With ``--dist loadfile`` each file runs whole
#: on one worker, and xdist hands the files out in collection order: a long file handed out
#: last keeps one worker busy after the other has finished. Files not named here follow in
#: their usual order.
LONGEST_FIRST = (
    "test_reproduce.py",
    "test_bad_start.py",
    "test_tendon.py",
    "test_estimator_peers.py",
    "test_fast_mhe.py",
    "test_hygiene.py",
    "test_live.py",
    "test_gyro_bias.py",
    "test_benchmark.py",
    "test_accel_bias.py",
    "test_multisection.py",
    "test_own_acceleration.py",
    "test_imu_topics.py",
    "test_reading.py",
    "test_defaults.py",
    "test_uncertainty.py",
    "test_robust_mhe.py",
)


def pytest_configure(config: pytest.Config) -> None:
    # xdist's default hands the files out by their number of tests, most first; keep the
    # collection order that pytest_collection_modifyitems sets below
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: files stay whole
