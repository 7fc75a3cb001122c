"""The input-only sensor-health policy decided for a span of samples at once
(:mod:`continuum_mhe.estimators.sensor_health`) against a sample-by-sample peer written
from its documented rules, over spans of any length; and the spans of a run against
the samples one by one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from continuum_mhe.cli.estimate import sample_spans
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.sensor_health import UNOBSERVED_AFTER, SensorHealth
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import RecoverySettings
from continuum_mhe.simulation.scenarios import simulate


class SequentialPeer:
    """The same rules, one sample at a time, in plain Python (the peer)."""

    def __init__(self, formulation, recovery: RecoverySettings) -> None:
        self.f, self.r = formulation, recovery
        self.imus = [b for b in formulation.measurement_blocks if b.is_imu]
        k = len(self.imus)
        self.value: list = [None] * k
        self.since = [-math.inf] * k
        self.count = [0] * k
        self.last_t = [-math.inf] * k
        self.last_valid = -math.inf
        self.imu_last = [-math.inf] * k
        self.first = -math.inf
        self.first_freezes: dict[int, float] = {}
        self.frozen_samples = 0

    def sample(self, t: float, z: np.ndarray):
        r, freeze = self.r, self.r.freeze
        z, frozen = z.copy(), False
        for k, b in enumerate(self.imus):
            zb = z[b.slice].copy()
            gap = t - self.last_t[k] > freeze if freeze is not None else True
            self.last_t[k] = t
            if self.value[k] is None or gap or not np.array_equal(zb, self.value[k]):
                self.value[k], self.since[k], self.count[k] = zb, t, 1
                continue
            self.count[k] += 1
            if self.count[k] >= r.freeze_samples and t - self.since[k] > freeze:
                z[b.slice] = np.nan
                frozen = True
                self.first_freezes.setdefault(k, self.since[k])
        self.frozen_samples += frozen
        mask = self.f.measurement_mask(z)
        gap_reset = False
        if r.gap_reset is not None and mask.any():
            gap_reset = -math.inf < self.last_valid < t - r.gap_reset
            self.last_valid = t
        window = r.gap_reset or UNOBSERVED_AFTER
        back: list[int] = []
        if self.first == -math.inf and mask.any():
            self.first = t
        for k, b in enumerate(self.imus):
            if mask[b.start] > 0:
                if t - self.imu_last[k] > window and t - self.first > window:
                    back += list(range(b.start, b.start + b.size))
                self.imu_last[k] = t
        recent = tuple(k for k in range(len(self.imus)) if t - self.imu_last[k] <= window)
        observed = (
            len(self.imus) == 1
            or len(recent) in (0, len(self.imus))
            or self.f.imus_determine_shape(recent)
        )
        return z, mask, frozen, gap_reset, back, observed


def _two_section_recording(seed: int) -> tuple[object, np.ndarray, np.ndarray]:
    """A two-IMU tilt recording with freezes, dropouts, an IMU's silence and a gap."""
    robot = Robot((Section(0.1), Section(0.1)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rng = np.random.default_rng(seed)
    n = 400
    t = np.cumsum(rng.choice([0.02, 0.05, 0.3], size=n, p=[0.8, 0.17, 0.03]))
    z = rng.normal(0.0, 0.1, size=(n, f.nz))
    z[40:90, 0:2] = z[40, 0:2]  # IMU 1 frozen
    z[60:75, 2:4] = z[60, 2:4]  # IMU 2 frozen, shorter
    z[120:200, 2:4] = np.nan  # IMU 2 silent, then back
    z[220:226] = np.nan  # both out
    z[300, 1] = np.nan  # one component of a block: the block drops out
    t[330:] += 3.0  # a gap
    z[350:] = z[350]  # both frozen to the end
    return f, t, z


@pytest.mark.parametrize(
    "recovery",
    [
        RecoverySettings(gap_reset=1.0, freeze=0.5),
        RecoverySettings(gap_reset=None, freeze=0.05, freeze_samples=4),
        RecoverySettings(),
    ],
    ids=["gap-and-freeze", "freeze-only", "library-default"],
)
@pytest.mark.parametrize("seed", [0, 1])
def test_span_plan_matches_the_sample_by_sample_rules(recovery, seed) -> None:
    f, t, z = _two_section_recording(seed)
    peer = SequentialPeer(f, recovery)
    expected = [peer.sample(float(ti), zi) for ti, zi in zip(t, z)]
    rng = np.random.default_rng(seed + 10)
    cuts = np.sort(rng.choice(np.arange(1, len(t)), size=12, replace=False))
    for bounds in ([0, len(t)], [0, *cuts.tolist(), len(t)], list(range(len(t) + 1))):
        health = SensorHealth(f)
        got = []
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            plan = health.plan(t[lo:hi], z[lo:hi], recovery)
            for i in range(hi - lo):
                back = [] if plan.back[i] is None else plan.back[i].tolist()
                got.append(
                    (plan.z[i], plan.mask[i], bool(plan.frozen[i]), bool(plan.gap_reset[i]),
                     back, bool(plan.observed[i]))
                )  # fmt: skip
        for i, (e, g) in enumerate(zip(expected, got)):
            np.testing.assert_array_equal(g[0], e[0], err_msg=f"sample {i}")
            np.testing.assert_array_equal(g[1], e[1], err_msg=f"sample {i}")
            assert g[2:] == e[2:], (i, g[2:], e[2:])
        assert health.first_freezes == peer.first_freezes
        assert list(health.first_freezes) == list(peer.first_freezes)  # in order
        assert health.frozen_samples == peer.frozen_samples
    if recovery.freeze is not None:  # the recording exercises every rule
        kinds = np.array([(e[2], e[3], bool(e[4]), not e[5]) for e in expected])
        seen = kinds.any(axis=0)  # frozen, gap reset, a return, unobserved
        assert seen[0] and seen[2] and seen[3] and seen[1] == (recovery.gap_reset is not None)


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_run_by_spans_equals_step_by_step(method) -> None:
    rec = simulate("paper3d", duration=12, seed=4)
    z = rec.z.copy()
    z[60:90] = z[60]  # a freeze
    z[120:130] = np.nan
    keep = (rec.t < 7.0) | (rec.t > 8.5)  # a gap
    t, z = rec.t[keep], z[keep]
    recovery = RecoverySettings(gap_reset=1.0, freeze=0.5)
    est = make_estimator(method, make_formulation("bend"), recovery=recovery)
    series = est.run(t, z)
    counts = (est.gap_resets, est.frozen_samples, dict(est.first_freezes), est.restarts)
    est.reset()
    steps = [est.step(Measurement(float(ti), zi)) for ti, zi in zip(t, z)]
    assert [str(e.status) for e in steps] == [str(s) for s in series.status]
    assert {"reset", "dropout"} <= {str(s) for s in series.status}
    for e, out in zip(steps, series.output):
        np.testing.assert_array_equal(e.output, out)
    assert (est.gap_resets, est.frozen_samples, dict(est.first_freezes), est.restarts) == counts


def test_sample_spans_keep_order_and_grow() -> None:
    rows = [(float(i), np.array([i, -i], dtype=float)) for i in range(3000)]
    spans = list(sample_spans(rows, 2))
    sizes = [len(t) for t, _ in spans]
    assert sizes[:3] == [1, 2, 4] and max(sizes) == 1024 and sum(sizes) == 3000
    t = np.concatenate([s[0] for s in spans])
    z = np.concatenate([s[1] for s in spans])
    np.testing.assert_array_equal(t, np.arange(3000.0))
    np.testing.assert_array_equal(z[:, 1], -np.arange(3000.0))


def test_a_reading_error_comes_after_the_samples_read_before_it() -> None:
    def rows():
        for i in range(5):
            yield float(i), np.zeros(2)
        raise ValueError("line 7: not a number")

    spans = sample_spans(rows(), 2)
    got = []
    with pytest.raises(ValueError, match="line 7"):
        for t, _ in spans:
            got += t.tolist()
    assert got == [0.0, 1.0, 2.0, 3.0, 4.0]
