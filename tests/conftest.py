"""Fixtures shared by several test modules, and the order in which the test files run."""

from __future__ import annotations

import gc
import os

# One BLAS thread per test process (before numpy loads its BLAS): the estimators'
# matrices are small, and with a worker per core an idle BLAS thread's spinning takes
# the other worker's core.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from estimator_helpers import (  # noqa: E402
    LIN_DT,
    LIN_H,
    LIN_N,
    LinearBend,
    bend_process_cov,
    lin_transition,
)


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


#: Test files that run first, longest first (in a fresh environment
#: ``test_rod_generators.py`` compiles PyElastica's numba kernels and ``test_hygiene.py``
#: runs mypy without its cache): with ``--dist loadfile`` a long file taken last leaves
#: the other worker idle.
FIRST_FILES = (
    "test_tendon.py",
    "test_rod_generators.py",
    "test_hygiene.py",
    "test_reproduce.py",
    "test_live.py",
    "test_viewer.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """:data:`FIRST_FILES` first; every file's tests, and the other files, keep their
    order (a stable sort)."""
    rank = {name: i for i, name in enumerate(FIRST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(FIRST_FILES)))


#: the test file whose first test froze the collector's objects (pytest_runtest_setup)
_frozen_for: list[object] = [None]


def pytest_runtest_setup(item: pytest.Item) -> None:
    """At each test file's first test, collect the cyclic garbage and move every object
    left (the compiled models and CasADi functions that earlier files cached) out of
    the garbage collector's passes (``gc.freeze``): otherwise each pass walks them
    again, and the estimators' per-sample loops in every later file pay for it."""
    module = getattr(item, "module", None)
    if module is not _frozen_for[0]:
        _frozen_for[0] = module
        gc.collect()
        gc.freeze()
