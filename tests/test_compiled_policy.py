"""The sensor-health policy in the compiled core (``csrc/sensor_health.*``): ``run`` over
a recording, ``continue_run`` in blocks and ``step`` sample by sample are one policy and
give the same estimates; a refused sample stops ``run`` with the step's error; the
formulations' checks of a state as data (``StateChecks``) against their definitions;
the estimate CSV's block writer against its row writer."""

from __future__ import annotations

import itertools
import math
import re
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import recovery_estimators

from continuum_mhe.errors import SampleTimeError, UserError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, ExtendedKalmanInference
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.io.estimate_csv import (
    estimate_lines,
    estimate_row,
    format_cells,
    format_number,
    format_time,
)
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.bend import DIVERGED_RATE, BendFormulation
from continuum_mhe.model.formulations import AT_BOUND_TOL, DIVERGED_MARGIN, Formulation
from continuum_mhe.model.kinematics import tip_position
from continuum_mhe.model.paper import DRIFT_FRACTION
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.results import Diagnostics, Measurement, Status
from continuum_mhe.settings import MHESettings, RecoverySettings
from continuum_mhe.simulation.scenarios import simulate

TWO_SECTIONS = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/two_section.toml"
RECOVERY = RecoverySettings(gap_reset=1.0, freeze=1.0, bad_start=2.0)


def faulty_recording() -> tuple[np.ndarray, np.ndarray]:
    """``paper3d`` with a bad start, a dropout, a frozen sensor and a gap."""
    rec = simulate("paper3d", duration=12.0, seed=3)
    t, z = rec.t.copy(), rec.z.copy()
    z[:8] += math.radians(50.0)  # a bad start
    z[60:70] = np.nan  # a dropout
    z[100:140] = z[100]  # frozen for 2 s
    keep = np.ones(len(t), bool)
    keep[180:210] = False  # a gap of 1.5 s
    return t[keep], z[keep]


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_run_blocks_and_steps_are_one_policy(method: str) -> None:
    f = make_formulation("bend")
    t, z = faulty_recording()
    settings = MHESettings(horizon=10)

    def estimator():
        return make_estimator(method, f, settings, RECOVERY)

    est = estimator()
    series = est.run(t, z)
    counts = est.diagnostics
    assert counts.bad_starts == 1 and counts.gap_resets == 1 and counts.frozen_samples > 0
    assert {"reset", "dropout"} <= set(series.status)
    blocks = estimator()
    blocks.reset()
    batch = blocks.continue_run(t, z, block=37)
    stepped = estimator()
    stepped.reset()
    steps = [stepped.step(Measurement(float(ti), zi)) for ti, zi in zip(t, z)]
    for other in (batch.statuses(), [e.status for e in steps]):
        assert list(series.status) == [str(s) for s in other]
    out = np.array([np.full(f.ny, np.nan) if e.output is None else e.output for e in steps])
    std = np.array([np.full(f.ny, np.nan) if e.output_std is None else e.output_std for e in steps])
    np.testing.assert_array_equal(series.output, batch.output)
    np.testing.assert_array_equal(series.output, out)
    np.testing.assert_array_equal(series.output_std, std)
    assert blocks.diagnostics == counts == stepped.diagnostics


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_reset_zeroes_the_diagnostics_a_caller_holds(method: str) -> None:
    """``est.diagnostics`` is one object for the estimator's life: ``reset`` zeroes it
    (and its ``first_freezes``) in place, so a caller that holds it, as ``estimate``
    does, reads the new recording's counts, not the last one's."""
    f = make_formulation("bend")
    t, z = faulty_recording()
    est = make_estimator(method, f, MHESettings(horizon=10) if method == "mhe" else None, RECOVERY)
    held = est.diagnostics
    freezes = held.first_freezes
    est.run(t, z)
    assert held.gap_resets == 1 and held.frozen_samples > 0 and freezes
    est.reset()
    assert est.diagnostics is held and held == Diagnostics() and held.first_freezes is freezes
    for ti, zi in zip(t[:150], z[:150]):  # the bad start and the frozen sensor
        est.step(Measurement(float(ti), zi))
    assert held is est.diagnostics and held.bad_starts == 1 and held.frozen_samples > 0
    est.reset(keep_counts=True)  # a restart within a recording keeps the counts
    assert held is est.diagnostics and held.bad_starts == 1


def test_a_refused_sample_stops_the_run_with_the_steps_error() -> None:
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=0)
    z = rec.z.copy()
    z[30, 0] = 90.0  # degrees
    est = make_estimator("ekf", f)
    with pytest.raises(UserError, match=r"t=1\.5 s: roll=90.*out of range.*degrees\?"):
        est.run(rec.t, z)
    assert est.diagnostics == make_estimator("ekf", f).run(rec.t[:30], rec.z[:30]).diagnostics
    t = rec.t.copy()
    t[20] = t[19]
    with pytest.raises(
        UserError, match=r"t=0\.95\d* s must be .* later than the previous sample's t=0\.95"
    ):
        est.run(t, rec.z)


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_a_late_sample_online_is_left_out_and_the_estimate_goes_on(method: str) -> None:
    """step() refuses a sample that came late or twice with a SampleTimeError that says
    to leave it out, and the estimator is as it was: the samples after it give the
    estimates of a run without it."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=0)
    est, clean = make_estimator(method, f), make_estimator(method, f)
    for i in range(len(rec.t)):
        if i == 20:
            for late in (rec.t[i - 1], rec.t[i - 1] - 0.005):  # twice, then late
                with pytest.raises(SampleTimeError, match="came late or twice is to be left"):
                    est.step(Measurement(float(late), rec.z[i - 1]))
        got = est.step(Measurement(float(rec.t[i]), rec.z[i]))
        want = clean.step(Measurement(float(rec.t[i]), rec.z[i]))
        assert got.status == want.status
        np.testing.assert_array_equal(got.output, want.output)


@pytest.mark.parametrize("name", ["bend", "two-sections", "direct-accel"])
def test_state_checks_are_the_formulations_definition(name: str) -> None:
    two = read_robot(TWO_SECTIONS)
    if name == "bend":
        f = make_formulation("bend")
    elif name == "two-sections":
        f = make_formulation("bend", two)
    else:
        f = make_formulation("direct", two, own_acceleration=True)
    n2, nx = 2 * f.robot.n_sections, f.nx
    rng = np.random.default_rng(0)
    for k, sec in enumerate(f.robot.sections):
        x = np.zeros(nx)
        x[2 * k : 2 * k + 2] = (sec.theta_max - AT_BOUND_TOL) * np.array([0.6, 0.8])
        assert f.at_bound(x) and not f.is_diverged(x)
        x[2 * k] *= 0.999
        assert not f.at_bound(x)
        x[2 * k : 2 * k + 2] = (sec.theta_max + DIVERGED_MARGIN) * np.array([0.6, 0.8]) * 1.001
        assert f.is_diverged(x)
    x = rng.normal(scale=0.1, size=nx)
    P = np.eye(nx) * 0.01
    assert not f.is_diverged(x, P)
    for row in range(n2, nx):
        fast = x.copy()
        fast[row] = 1.01 * DIVERGED_RATE
        own_acceleration = getattr(f, "own_acceleration", False) and 2 * n2 <= row < 3 * n2
        assert f.is_diverged(fast) != own_acceleration
    bad = x.copy()
    bad[-1] = np.nan
    assert f.is_diverged(bad)
    wide = P.copy()
    wide[n2 - 1, n2 - 1] = 1.01 * math.pi**2
    assert f.is_diverged(x, wide) and not f.is_diverged(x, P * 1e3 * (np.arange(nx) >= n2))
    wide[0, 1] = np.inf
    assert f.is_diverged(x, wide)


def test_the_block_writer_writes_the_row_writers_lines() -> None:
    rng = np.random.default_rng(1)
    n, ny = 6, 3
    t = np.cumsum(rng.uniform(0.01, 0.1, n))
    out = rng.normal(size=(n, ny))
    std = rng.uniform(0.001, 0.1, (n, ny))
    out[1], std[1] = np.nan, np.nan  # no estimate
    std[2] = np.nan  # no covariance
    std[3, 1] = np.nan
    status = ["ok", "no-estimate", "solver-failed", "ok", "reset", "uncertain"]
    ms = rng.uniform(0.1, 2.0, n)
    flags = rng.uniform(size=n) > 0.5
    for outlier in (None, flags):
        expected = ""
        for i in range(n):
            y = None if status[i] == "no-estimate" else out[i]
            s = None if np.isnan(std[i]).all() else std[i]
            flag = None if outlier is None else bool(outlier[i])
            row = estimate_row(t[i], y, status[i], ms[i], ny, s, flag)
            expected += ",".join(format_cells("x.csv", row)) + "\n"
        assert estimate_lines("x.csv", t, out, std, outlier, status, ms) == expected
    out[0, 0] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        estimate_lines("x.csv", t, out, std, None, status, ms)


def test_the_block_writer_writes_python_s_digits() -> None:
    """The compiled writer's numbers are :func:`format_number`'s (Python's ``"%.10g" %
    v``) to the character, over every magnitude, random bit patterns (subnormals, the
    largest doubles), negative zero and ties at the tenth digit; its times (increasing)
    :func:`format_time`'s."""
    rng = np.random.default_rng(7)
    scaled = rng.normal(size=20_000) * 10.0 ** rng.integers(-30, 30, 20_000)
    bits = rng.integers(0, 2**63, 20_000, dtype=np.uint64).view(np.float64)
    ties = [1234567890.5, 9999999999.5, 0.5, 2.5e-5, 1e-4, 1e-5, 123456789.25]
    special = [0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, *ties]
    values = np.concatenate([scaled, bits, special, np.negative(special)])
    values = values[np.isfinite(values)]
    n = len(values) // 2
    t = np.unique(values[:n])  # increasing, as the writer takes them (0 and -0 as one)
    n = len(t)
    ms = values[-n:]
    out = std = np.zeros((n, 0))
    lines = estimate_lines("x.csv", t, out, std, None, ["ok"] * n, ms).splitlines()
    assert lines == [
        f"{format_time(a)},ok,{format_number(b)}" for a, b in zip(t.tolist(), ms.tolist())
    ]
    # a time as "%.10g" where that keeps it to half a microsecond, else to the microsecond:
    # samples half a millisecond apart on a device clock past 1e6 s stay distinct
    t = np.array([-1.5e7 - 1e-3, 0.15000000000000002, 9999.1234565, 4294957.296, 4294957.2965])
    lines = estimate_lines("x.csv", t, np.zeros((5, 0)), np.zeros((5, 0)), None, ["ok"] * 5,
                           np.ones(5)).splitlines()  # fmt: skip
    assert [ln.split(",")[0] for ln in lines] == [
        "-15000000.001", "0.15", "9999.123456", "4294957.296", "4294957.2965"]  # fmt: skip


def test_no_writer_writes_a_negative_zero() -> None:
    """A negative zero (a straight robot's ``x``, a time of ``-0.0``) is written ``0`` by
    the compiled block writer, the row writer and the table writer alike; other numbers
    keep their sign."""
    t = np.array([-0.0, 0.05])
    out = np.array([[-0.0, -1e-300, 0.0], [-0.0, -0.0, -2.5]])
    std = np.array([[-0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    block = estimate_lines("x.csv", t, out, std, None, ["ok", "ok"], np.array([-0.0, 1.0]))
    rows = "".join(
        ",".join(format_cells("x.csv", estimate_row(t[i], out[i], "ok", [-0.0, 1.0][i], 3, std[i])))
        + "\n"
        for i in range(2)
    )
    expected = "0,0,-1e-300,0,0,0,1,ok,0\n0.05,0,0,-2.5,0,0,0,ok,1\n"
    assert block == rows == expected
    assert format_number(-0.0) == "0" and format_time(-0.0) == "0"


def test_the_compiled_ekf_in_the_policy_is_the_casadi_ekf() -> None:
    """The compiled EKF stepped inside the compiled policy (``KalmanInference``) against
    the CasADi EKF stepped through its Python ``infer``: the same statuses and, to
    rounding, the same estimates, through the bad start, dropout, freeze and gap."""
    f = make_formulation("bend")
    t, z = faulty_recording()
    compiled = make_estimator("ekf", f, recovery=RECOVERY)
    assert type(compiled.inference.policy_inference()).__name__ == "KalmanInference"
    casadi = CasadiExtendedKalmanFilter(f, RECOVERY)
    a, b = compiled.run(t, z), casadi.run(t, z)
    assert list(a.status) == list(b.status)
    np.testing.assert_allclose(a.output, b.output, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.output_std, b.output_std, rtol=1e-7, atol=1e-12)
    assert compiled.diagnostics.bad_starts == casadi.diagnostics.bad_starts == 1


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_run_lets_other_threads_go_on(method: str) -> None:
    """``continue_run`` (and so ``run``) steps its samples without holding the GIL: a
    thread that gives the GIL up at every count (``sleep(0)``) counts on meanwhile. The
    interpreter's switch interval is made long, so that only a GIL given up lets the
    counter run: with the GIL held through the block it stays where it was. An
    inference that calls back into Python (the UKF's, every sample) takes the GIL back;
    each gives the estimates it gives sample by sample."""
    duration = {"mhe": 120.0, "ekf": 600.0, "ukf": 6.0}[method]  # 0.1 s of stepping or more
    rec = simulate("paper3d", duration=duration, seed=1)
    est = make_estimator(method, make_formulation("bend"))
    counts = [0]
    running, stop = threading.Event(), threading.Event()

    def count() -> None:
        running.set()
        while not stop.is_set():
            counts[0] += 1
            time.sleep(0)

    interval = sys.getswitchinterval()
    sys.setswitchinterval(100.0)
    worker = threading.Thread(target=count, daemon=True)
    try:
        worker.start()
        running.wait()
        est.reset()
        at_start = counts[0]
        batch = est.continue_run(rec.t, rec.z)  # one block: one call into the core
        during = counts[0] - at_start
    finally:
        stop.set()
        worker.join()
        sys.setswitchinterval(interval)
    if method != "ukf":  # the UKF's step is Python's, with the GIL
        assert during >= 100
    est.reset()
    stepped = np.full_like(batch.output, np.nan)
    for i, (t, z) in enumerate(zip(rec.t, rec.z)):
        e = est.step(Measurement(float(t), z))
        if e.output is not None:
            stepped[i] = e.output
    np.testing.assert_array_equal(batch.output, stepped)


def test_a_second_thread_is_refused_while_run_steps() -> None:
    """While ``continue_run`` steps samples in one thread, another thread's call into the
    same policy (made from the run's own ``should_stop``, so that it falls inside the
    run) is a RuntimeError, not a data race; the run goes on to the last sample, and the
    policy serves any thread once the run is done."""
    rec = simulate("paper3d", duration=20.0, seed=1)
    est = make_estimator("mhe", make_formulation("bend"))
    est.reset()
    refused: list[RuntimeError] = []

    def read_from_another_thread() -> bool:
        def read() -> None:
            try:
                est._policy.last_t  # noqa: B018  # a read of the policy
            except RuntimeError as exc:
                refused.append(exc)

        other = threading.Thread(target=read)
        other.start()
        other.join()
        return False

    batch = est.continue_run(rec.t, rec.z, should_stop=read_from_another_thread)
    assert refused and all("another thread" in str(e) for e in refused)
    assert len(batch.status) == len(rec.t)
    got: list[float] = []
    other = threading.Thread(target=lambda: got.append(est._policy.last_t))
    other.start()
    other.join()
    assert got == [rec.t[-1]]


def test_continue_run_stops_where_asked_and_goes_on_from_there() -> None:
    """``should_stop`` ends the call between two samples: the samples stepped are those
    of an uninterrupted run, and the next call goes on from the next sample to the same
    estimates; asked before the first sample, True steps none."""
    rec = simulate("paper3d", duration=600.0, seed=2)
    est = make_estimator("mhe", make_formulation("bend"))
    est.reset()
    whole = est.continue_run(rec.t, rec.z)
    est.reset()
    assert len(est.continue_run(rec.t, rec.z, should_stop=lambda: True).status) == 0
    calls = itertools.count(1)  # asked before the first sample, then every 10 ms or so
    first = est.continue_run(rec.t, rec.z, should_stop=lambda: next(calls) >= 3)
    k = len(first.status)
    assert 0 < k < len(rec.t)
    rest = est.continue_run(rec.t[k:], rec.z[k:])
    np.testing.assert_array_equal(np.vstack([first.output, rest.output]), whole.output)
    np.testing.assert_array_equal(np.concatenate([first.status, rest.status]), whole.status)


def test_one_estimator_stepped_from_two_threads_is_refused() -> None:
    """``step``, and a change of the settings, from a second thread while a step runs in
    another (inside its Python inference, where the first thread lets the GIL go): a
    RuntimeError each, never two steps interleaved on one policy; the first step's
    estimate is the one it gives alone."""
    rec = simulate("paper3d", duration=2.0, seed=5)
    est = CasadiExtendedKalmanFilter(make_formulation("bend"))
    alone = CasadiExtendedKalmanFilter(make_formulation("bend"))
    refused: list[RuntimeError] = []
    infer = est.inference.infer

    def second_thread_meanwhile(m: Measurement) -> object:
        def meanwhile() -> None:
            attempts = (
                lambda: est.step(Measurement(float(rec.t[1]), rec.z[1])),
                lambda: setattr(est, "recovery", RecoverySettings()),
            )
            for attempt in attempts:
                try:
                    attempt()
                except RuntimeError as exc:
                    refused.append(exc)

        other = threading.Thread(target=meanwhile)
        other.start()
        other.join()  # the GIL is let go here: the other thread runs in this step
        return infer(m)

    est.inference.infer = second_thread_meanwhile  # type: ignore[method-assign]
    got = est.step(Measurement(float(rec.t[0]), rec.z[0]))
    assert len(refused) == 2 and all("another thread" in str(e) for e in refused)
    want = alone.step(Measurement(float(rec.t[0]), rec.z[0]))
    assert got.status == want.status and got.output is not None and want.output is not None
    np.testing.assert_array_equal(got.output, want.output)


def test_should_stop_takes_any_truth_value() -> None:
    rec = simulate("paper3d", duration=5.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for stop, stepped in ((np.bool_(True), 0), (1, 0), (None, len(rec.t)), (0, len(rec.t))):
        est.reset()
        got = est.continue_run(rec.t, rec.z, should_stop=lambda stop=stop: stop)
        assert len(got.status) == stepped
    est.reset()

    def broken() -> bool:
        raise KeyError("the caller's flag")

    with pytest.raises(KeyError, match="the caller's flag"):
        est.continue_run(rec.t, rec.z, should_stop=broken)


def test_an_estimator_is_not_copied_nor_pickled() -> None:
    """A shallow copy shared the compiled policy (stepping the copy moved the original),
    and pickling named an internal class: each is one TypeError saying what to do."""
    import copy
    import pickle

    est = make_estimator("ekf", make_formulation("bend"))
    for attempt in (copy.copy, copy.deepcopy, pickle.dumps):
        with pytest.raises(TypeError, match="cannot be copied or pickled; make another"):
            attempt(est)


@pytest.mark.parametrize("name, sections, method", [
    ("bend", 1, "ekf"), ("paper", 1, "mhe"), ("bend", 2, "mhe"), ("bend", 1, "ukf"),
])  # fmt: skip
def test_a_formulation_pickles_and_copies_after_an_estimator_used_it(
    name: str, sections: int, method: str
) -> None:
    """A formulation that an estimator has used (its cached symbolic expressions and
    compiled checks built) pickles and copies as a fresh one does (not a
    TypeError or "Cannot pickle SX objects"), and the copy estimates alike."""
    import copy
    import pickle

    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section") if sections == 2 else None
    f = make_formulation(name, robot)
    if sections == 2:
        rec = simulate_robot("spatial", f.robot, duration=0.5, seed=0)
    else:
        rec = simulate("paper3d", duration=0.5, seed=0)
    z = rec.z
    want = make_estimator(method, f).run(rec.t, z)
    for again in (pickle.loads(pickle.dumps(f)), copy.deepcopy(f), copy.copy(f)):
        assert again == f
        got = make_estimator(method, again).run(rec.t, z)
        np.testing.assert_array_equal(got.output, want.output)


def test_a_refused_sample_is_refused_before_any_sample_of_the_call_is_stepped() -> None:
    """A tilt in degrees, an infinite reading or a repeated time at sample 3 of a call:
    the UserError comes before samples 0 to 2 are stepped (not after, with their
    estimates lost), so the corrected call gives a fresh run's estimates."""
    rec = simulate("paper3d", duration=1.0, seed=1)
    t, z = rec.t[:6].copy(), rec.z[:6].copy()
    want = make_estimator("ekf", make_formulation("bend")).run(t, z)
    degrees, infinite, repeated = z.copy(), z.copy(), t.copy()
    degrees[3] = [40.0, 0.0]
    infinite[3, 1] = np.inf
    repeated[3] = repeated[2]
    est = make_estimator("ekf", make_formulation("bend"))
    for times, readings, needle in (
        (t, degrees, "roll=40, pitch=0: beyond pi"),
        (t, infinite, "pitch=inf: an infinite value"),
        (repeated, z, f"later than the previous sample's t={float(t[2])!r} s"),
    ):
        with pytest.raises(UserError, match=re.escape(needle)):
            est.continue_run(times, readings)
        assert est._policy.last_t == -math.inf  # nothing stepped
    got = est.continue_run(t, z)
    np.testing.assert_array_equal(got.output, want.output)
    # run() as well, before any sample, and without a reset() hint (run resets itself)
    with pytest.raises(UserError, match=r"previous sample's t=0\.1 s$"):
        est.run(repeated, z)


def test_the_core_s_statuses_are_the_status_vocabulary_in_its_order() -> None:
    """csrc/sensor_health.hpp repeats results.Status as a C++ enum: the same names in the
    same order (a status added on one side only would be read as another)."""
    import continuum_mhe._core as core
    from continuum_mhe.results import Status

    assert tuple(core.STATUS_NAMES) == tuple(s.value for s in Status)


@dataclass(frozen=True)
class _DistrustedStarts(BendFormulation):
    """The bend formulation, whose starts at the readings of ``distrusted`` (their
    bytes) cannot be trusted (as a tendon robot's start whose first reading shows a
    load: ``Formulation.start_untrusted``)."""

    distrusted: frozenset[bytes] = frozenset()

    def start_untrusted(self, z0: np.ndarray) -> bool:
        return np.asarray(z0, float).tobytes() in self.distrusted


def test_an_untrusted_start_gives_no_ok_row_until_the_next_start_in_every_estimator() -> None:
    """A start the formulation does not trust (its first reading shows what the start
    cannot tell from the sensors' errors) makes every estimate of that start not ``ok``
    in every estimator, counted in the diagnostics; the start after a gap is judged
    anew, and trusted, its rows are ``ok`` again."""
    rec = simulate("paper3d", duration=6.0, seed=1)
    keep = (rec.t < 2.5) | (rec.t > 4.0)  # a gap of 1.5 s: a new start at 4.05 s
    t, z = rec.t[keep], rec.z[keep]
    f = _DistrustedStarts(distrusted=frozenset({np.asarray(z[0], float).tobytes()}))
    first = t < 2.5
    for est in recovery_estimators(RECOVERY, f):
        series = est.run(t, z)
        status = np.asarray(series.status).astype(str)
        assert "ok" not in status[first], (est.inference.name, status[first])
        assert est.diagnostics.gap_resets == 1
        assert est.diagnostics.untrusted_start_samples == first.sum()
        # after the gap's start (uncertain until a reading confirms it) the rows are ok
        assert set(status[~first][2:]) == {"ok"}, (est.inference.name, status[~first])


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_the_time_windows_do_not_depend_on_where_the_clock_starts(method: str) -> None:
    """A 1.5 s stall (the gap reset's 1 s), a reading repeated for 1.5 s (a freeze) and
    a tip IMU silent for 1.2 s give the same statuses and diagnostics on times from 0
    and on Unix-epoch seconds (t about 1.7e9 s, where a double's step is 2.4e-7 s): the
    windows' rounding allowance is the times' own, not a share of t."""
    from continuum_mhe import ImuPlacement, Robot, Section, make_formulation, simulate_robot
    from continuum_mhe.simulation.scenarios import simulate

    rec = simulate("paper3d", duration=10.0, seed=1)
    t = rec.t.copy()
    t[100:] += 1.5
    z = rec.z.copy()
    z[40:70] = z[40]
    two = Robot((Section(0.16), Section(0.14)), (ImuPlacement(0), ImuPlacement(1)))
    spatial = simulate_robot("spatial", two, duration=6.0, seed=2)
    silent = spatial.z.copy()
    silent[(spatial.t >= 3.0) & (spatial.t < 4.2), 2:] = np.nan
    for f, times, readings in ((make_formulation("bend"), t, z),
                               (make_formulation("bend", two), spatial.t, silent)):  # fmt: skip
        runs = [make_estimator(method, f).run(times + base, readings) for base in (0.0, 1.7e9)]
        assert list(runs[0].status) == list(runs[1].status)
        d0, d1 = runs[0].diagnostics, runs[1].diagnostics
        assert (d0.gap_resets, d0.frozen_samples) == (d1.gap_resets, d1.frozen_samples)
    assert d0.gap_resets == 0 and "uncertain" in list(runs[0].status)


def test_a_freeze_of_exactly_its_limit_is_judged_alike_on_any_clock() -> None:
    """Readings repeated for 0.3 to 0.4 s against a freeze limit of 0.3 or 0.35 s (steps
    of exactly the limit): the same frozen samples on times from 0, from 1000 s and on
    Unix-epoch seconds, the limit compared with the times' own rounding allowed."""
    from continuum_mhe.simulation.scenarios import simulate

    rec = simulate("paper3d", duration=10.0, seed=1)
    z = rec.z.copy()
    for k in range(8):
        z[20 + 25 * k : 27 + 25 * k + k % 3] = z[20 + 25 * k]
    for freeze in (0.3, 0.35):
        frozen = [
            make_estimator(
                "ekf", make_formulation("bend"), recovery=RecoverySettings(freeze=freeze)
            )
            .run(rec.t + base, z)
            .diagnostics.frozen_samples
            for base in (0.0, 1000.0, 1.7e9)
        ]
        assert frozen[0] == frozen[1] == frozen[2] > 0, (freeze, frozen)


# --- the solved statuses: ok, fallback-ipopt, branch-restart ----------------------------
#: The statuses of a solved estimate: the fast MHE's own answer, IPOPT's answer to a
#: window the fast MHE could not certify, and another branch's answer to the window
SOLVED = ("ok", "fallback-ipopt", "branch-restart")


class _Labelled(ExtendedKalmanInference):
    """The EKF's inference, whose ``ok`` and ``dropout`` answers carry ``status`` instead
    (as the fast MHE's answers rescued by IPOPT or by the branch check do, at a sample
    without a reading too), and whose state's position rows (the paper formulation's
    x, y, z) are set to the forward kinematics of its own angles plus ``offset`` (m),
    where given."""

    def __init__(
        self, formulation: Formulation, status: str, offset: np.ndarray | None = None
    ) -> None:
        self.status, self.offset = Status(status), offset
        super().__init__(formulation)

    def infer(self, m: Measurement) -> tuple[np.ndarray | None, np.ndarray | None, Status]:
        x, P, status = super().infer(m)
        if x is not None and self.offset is not None:
            x = x.copy()
            x[:3] = tip_position(x[3], x[4], self.formulation.length).ravel() + self.offset
        return x, P, self.status if status in (Status.OK, Status.DROPOUT) else status


@pytest.mark.parametrize("status", SOLVED)
def test_a_solved_row_whose_state_the_model_does_not_hold_is_drifted(status: str) -> None:
    """The paper formulation's state holds the tip position beside the angles: with the
    position at the forward kinematics of the angles no row is ``drifted``, and each
    keeps its solved status; with it twice DRIFT_FRACTION of the length off, every row
    is ``drifted``, whether the inference answered ``ok``, ``fallback-ipopt`` or
    ``branch-restart``."""
    rec = simulate("paper3d", duration=3.0, seed=1)
    f = make_formulation("paper")
    off = np.array([2 * DRIFT_FRACTION * f.length, 0.0, 0.0])
    held = Estimator(_Labelled(f, status, np.zeros(3)), RecoverySettings())
    assert "drifted" not in set(held.run(rec.t, rec.z).status)
    moved = Estimator(_Labelled(f, status, off), RecoverySettings())
    assert set(moved.run(rec.t, rec.z).status) == {"drifted"}


@pytest.mark.parametrize("status", SOLVED)
def test_a_solved_row_with_a_wide_tip_std_is_uncertain(status: str) -> None:
    """Every row after the start keeps its solved status with the default uncertain
    fraction; with a fraction below every row's tip standard deviation (as written),
    every row is ``uncertain``, whether the inference answered ``ok``,
    ``fallback-ipopt`` or ``branch-restart``."""
    rec = simulate("paper3d", duration=3.0, seed=1)
    f = BendFormulation()
    default = Estimator(_Labelled(f, status), RecoverySettings()).run(rec.t, rec.z)
    assert list(default.status) == ["uncertain"] + [status] * (len(rec.t) - 1)
    fraction = 1e-4
    tip = np.hypot.reduce([default.std_column(c) for c in ("x", "y", "z")])
    assert tip.min() > fraction * f.robot.length  # so every row is beyond it
    wide = Estimator(_Labelled(f, status), RecoverySettings(uncertain_fraction=fraction))
    assert set(wide.run(rec.t, rec.z).status) == {"uncertain"}


@pytest.mark.parametrize("status", SOLVED[1:])
def test_no_solved_row_of_an_untrusted_start_is_trusted(status: str) -> None:
    """A start the formulation does not trust gives no ``fallback-ipopt`` or
    ``branch-restart`` row, as it gives no ``ok`` one (the rows after the gap's start,
    trusted, have that status again)."""
    rec = simulate("paper3d", duration=6.0, seed=1)
    keep = (rec.t < 2.5) | (rec.t > 4.0)  # a gap of 1.5 s: a new start at 4.05 s
    t, z = rec.t[keep], rec.z[keep]
    f = _DistrustedStarts(distrusted=frozenset({np.asarray(z[0], float).tobytes()}))
    est = Estimator(_Labelled(f, status), RECOVERY)
    got = np.asarray(est.run(t, z).status).astype(str)
    first = t < 2.5
    assert not set(got[first]) & set(SOLVED), sorted(set(got[first]))
    assert est.diagnostics.untrusted_start_samples == first.sum()
    assert set(got[~first][2:]) == {status}, sorted(set(got[~first]))


@pytest.mark.parametrize("status", SOLVED)
def test_a_solved_row_without_an_imu_reading_is_a_dropout(status: str) -> None:
    """A sample without any IMU's reading is a ``dropout`` whichever solve answered it."""
    rec = simulate("paper3d", duration=3.0, seed=1)
    z = rec.z.copy()
    lost = np.zeros(len(rec.t), bool)
    lost[[20, 30, 31]] = True
    z[lost] = np.nan
    got = np.asarray(Estimator(_Labelled(BendFormulation(), status), RECOVERY).run(rec.t, z).status)
    assert set(got[lost].astype(str)) == {"dropout"}


@pytest.mark.parametrize("status", SOLVED)
def test_no_solved_row_within_the_window_of_a_burst_of_tilt_readings(status: str) -> None:
    """0.6 rad added to the tilt IMU's roll for 6 samples of paper3d (20 Hz): the burst's
    first readings are beyond one sample's limit, and within the window (1 s) after
    them no row is ``ok``, ``fallback-ipopt`` or ``branch-restart``
    (tests/test_reliability.py measures how far off those rows are)."""
    f = BendFormulation()
    rec = simulate("paper3d", duration=10, seed=0)
    z = rec.z.copy()
    first = int(np.argmax(rec.t >= 4.0 - 1e-9))
    rolls = [b.start for b in f.measurement_blocks]  # each tilt block is (roll, pitch)
    z[first : first + 6, rolls] = np.angle(np.exp(1j * (z[first : first + 6, rolls] + 0.6)))
    got = np.asarray(Estimator(_Labelled(f, status), RecoverySettings()).run(rec.t, z).status)
    within = (rec.t >= rec.t[first]) & (rec.t < rec.t[first] + 1.0)
    assert not set(got[within].astype(str)) & set(SOLVED), got[within]
    assert status in set(got[~within].astype(str))  # the rest of the run has it


@pytest.mark.parametrize("status", SOLVED)
def test_a_solved_paper_row_whose_tip_std_passes_the_reach_is_uncertain(status: str) -> None:
    """The paper formulation (its W a weight, no noise model; positions held at the
    forward kinematics of the angles, so that no row is ``drifted``): a row whose tip
    standard deviation as written exceeds the robot's length is ``uncertain``, and every
    other row keeps its solved status, whichever it is."""
    rec = simulate("paper3d", duration=5.0, seed=0)
    f = make_formulation("paper")
    s = Estimator(_Labelled(f, status, np.zeros(3)), RecoverySettings()).run(rec.t, rec.z)
    beyond = np.hypot.reduce([s.std_column(c) for c in ("x", "y", "z")]) > f.length
    got = np.asarray(s.status).astype(str)
    assert beyond.any() and not beyond.all()
    assert set(got[beyond]) == {"uncertain"} and set(got[~beyond]) == {status}
