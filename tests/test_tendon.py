"""Tendon-driven robots estimated: starts and restarts, loaded recordings, one IMU, the
standard deviations, and a push the backbone cannot hold."""

from __future__ import annotations

import contextlib
import io
import math
import re
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from cli_helpers import figures_drawn_small
from tendon_helpers import (
    BACKBONE,
    DATA,
    EI,
    TENDON_FILE,
    one_section_robot,
    small_robot,
    small_robot_recording,
    write_text_table,
)

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.input_options import OptionWarning
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import StateTable, read_state_table
from continuum_mhe.io.tensions import read_tensions
from continuum_mhe.model.robot import Backbone, ImuPlacement, Robot, Section, Tendon
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.model.tendon_statics import TendonStatics

ROBOTS = DATA.parent / "robots"


# --- the start and its restarts ---------------------------------------------------------
def _equilibrium_state(f: TendonFormulation, tau: np.ndarray, force: np.ndarray) -> np.ndarray:
    """The state of the robot in equilibrium under the tensions ``tau`` and the tip
    force ``force``, at rest, its IMUs without errors."""
    k0, _ = f.statics.solve(force, tau)
    x = np.zeros(f.nx)
    x[:3], x[3:6], x[6 : 6 + len(tau)] = k0, force, tau
    return x


def test_the_start_recovers_the_tip_force_from_noise_free_tilts() -> None:
    """Tilts of a known tip force and tensions (two IMUs): the start's least squares
    finds the force (with a wide prior on the force: the start holds the force to its
    prior at the prior's weight, which pulls a weakly seen component towards zero)."""
    robot = read_robot("tendon-two-section")
    f = TendonFormulation(robot=robot, initial_force_std=100.0)
    tau = np.array([1.0, 0.5, 0.0, 0.0, 1.5, 0.3])
    force = np.array([0.03, -0.02, 0.01])
    h = np.asarray(f.functions.observe(_equilibrium_state(f, tau, force)), float).ravel()
    z = f.measurement_row(h[: f.n_imu_measurements], tau, np.zeros(6))
    x0 = f.initial_state(z)
    np.testing.assert_allclose(x0[3:6], force, atol=1e-6)


def test_a_start_free_of_load_reads_the_imus_errors_not_a_tip_force() -> None:
    """The shipped ``unloaded`` (raw IMUs) starts straight, slack and free of load, its
    IMUs misaligned and biased: the start takes the narrow tip force prior and reads
    well under a millinewton, where the wide prior reads the IMUs' errors as a force
    of several millinewtons (which bends this soft robot by millimetres)."""
    from continuum_mhe.model.tendon import FREE_START_FORCE_FRACTION

    f, _, z = _raw_shipped(1)
    narrow = FREE_START_FORCE_FRACTION * f.force_prior_std
    x0, P0 = f.start_prior(z[0])
    np.testing.assert_array_equal(np.diag(P0)[3:6], [narrow**2] * 3)
    assert np.linalg.norm(x0[3:6]) < 5e-4
    np.testing.assert_array_equal(f.initial_state(z[0]), x0)
    wide = replace(f, initial_force_std=f.force_prior_std)
    x1, P1 = wide.start_prior(z[0])
    np.testing.assert_array_equal(P1, f.initial_cov())
    assert np.linalg.norm(x1[3:6]) > 3e-3


def test_a_start_under_load_keeps_the_wide_tip_force_prior() -> None:
    """Noise-free raw readings of the robot under a 0.19 N tip force: fitted without a
    load they are far beyond their noise and the IMUs' own errors, so the start keeps
    the wide prior, as does a straight one under 0.02 N, one without an accelerometer
    reading, and one that the tensions bend; with tilt IMUs the start always does."""
    from continuum_mhe.model.tendon import FREE_START_MAX_BEND

    robot = read_robot("tendon-two-section")
    f = TendonFormulation(robot=robot, imu_model="direct", estimate_gyro_bias=True)
    tau = np.array([1.0, 0.5, 0.0, 0.0, 1.5, 0.3])
    x = _equilibrium_state(f, tau, np.array([0.15, -0.1, 0.05]))
    h = np.asarray(f.functions.observe(x), float).ravel()
    z = f.measurement_row(h[: f.n_imu_measurements], tau, np.zeros(6))
    _, P0 = f.start_prior(z)
    np.testing.assert_array_equal(P0, f.initial_cov())
    # straight (no tension) under 0.02 N: the bend rule lets it through, the misfit not
    tau = np.zeros(6)
    x = _equilibrium_state(f, tau, np.array([0.02, 0.0, 0.0]))
    h = np.asarray(f.functions.observe(x), float).ravel()
    z = f.measurement_row(h[: f.n_imu_measurements], tau, np.zeros(6))
    assert f.start_bend(z) == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_array_equal(f.start_prior(z)[1], f.initial_cov())
    # no accelerometer reading: nothing shows the start free of load
    z[: f.n_imu_measurements] = np.nan
    np.testing.assert_array_equal(f.start_prior(z)[1], f.initial_cov())
    # the shipped twist-29 at 3 s: bent by its tensions, under 0.17 N across the bend,
    # which the readings' misfit alone passes as free
    f, _, z = _raw_shipped(151, "twist-29")
    np.testing.assert_array_equal(f.start_prior(z[150])[1], f.initial_cov())
    assert f.start_bend(z[150]) > FREE_START_MAX_BEND
    assert f.start_bend(z[0]) == pytest.approx(0.0, abs=1e-9)
    tilt = TendonFormulation(robot=robot)
    h = np.asarray(tilt.functions.observe(x[: tilt.nx]), float).ravel()
    z = tilt.measurement_row(h[: tilt.n_imu_measurements], np.zeros(6), np.zeros(6))
    np.testing.assert_array_equal(tilt.start_prior(z)[1], tilt.initial_cov())


def test_a_start_under_load_that_keeps_restarting_gives_no_far_off_ok_row() -> None:
    """The shipped ``force-29`` from 4 s on (bent, under 0.29 N; raw IMUs, the command
    line's EKF): the start does not find the load, the readings contradict it and two
    restarts after it, and the filter started a third time bends its IMU-error states
    to the readings, narrowing around a shape that drifts tens of mm off. No row more
    than 5 mm off at the tip is ``ok``: from the chain's second restart the rows are
    ``uncertain`` until a restart has held for the bad-start probation time, and the
    IMU errors' change beyond their covariance makes them ``drifted``."""
    from continuum_mhe.estimators import make_estimator

    f, t, z = _raw_shipped(401, "force-29")
    late = t >= 4.0 - 1e-9
    series = make_estimator("ekf", f).run(t[late], z[late])
    truth = read_state_table(DATA / "force-29_truth.csv")
    assert np.allclose(truth.t[late], t[late])
    cols = [o.name for o in f.outputs]
    tip = np.asarray(series.output, float)[:, [cols.index(c) for c in "xyz"]]
    true_tip = np.column_stack([truth.column(c)[late] for c in "xyz"])
    far = np.linalg.norm(tip - true_tip, axis=1) > 5e-3
    assert far.sum() > 100  # the start under load is lost
    assert not np.any(far & (series.status == "ok"))
    assert np.sum(series.status == "reset") == 3
    assert set(series.status) <= {"reset", "uncertain", "drifted", "inconsistent", "ok"}


def _tip_errors(f: TendonFormulation, t: np.ndarray, series) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The tip error (m) of each estimate of ``series`` at the times ``t`` against the
    shipped ``force-29`` truth."""
    truth = read_state_table(DATA / "force-29_truth.csv")
    rows = np.searchsorted(truth.t, t - 1e-9)
    assert np.allclose(truth.t[rows], t)
    cols = [o.name for o in f.outputs]
    tip = np.asarray(series.output, float)[:, [cols.index(c) for c in "xyz"]]
    return np.linalg.norm(tip - np.column_stack([truth.column(c)[rows] for c in "xyz"]), axis=1)


def test_a_restart_after_a_gap_under_load_keeps_the_sensors_and_finds_the_load() -> None:
    """The shipped ``force-29`` (raw IMUs, the command line's EKF) with the samples
    between 3 and 5 s missing: the gap restarts the filter at 5 s, bent under 0.29 N.
    The restart keeps the IMUs' errors and gyro biases it had learned, so the reading
    shows the load (the force and, from the gyros, its rate): the tip is within 1 mm on
    average after the gap, as without the gap, where a start at the same sample that
    knows nothing of the sensors is over 10 mm off (every row drifted or reset). A
    caller's restart within the recording (``reset(keep_counts=True)``, as live's at a
    board reset) keeps them too, unless told not to (live's after an estimator
    failure); a reset of the estimator (a new recording) keeps nothing: it gives that
    start's estimates."""
    from continuum_mhe.estimators import make_estimator

    f, t, z = _raw_shipped(401, "force-29")
    kept = (t < 3.0 - 1e-9) | (t > 5.0 - 1e-9)
    after = t[kept] > 5.0 - 1e-9
    est = make_estimator("ekf", f)
    series = est.run(t[kept], z[kept])
    assert est.diagnostics.gap_resets == 1
    assert est.diagnostics.untrusted_start_samples == 0
    gap = _tip_errors(f, t[kept][after], series.rows(after))
    fresh = make_estimator("ekf", f).run(t[t > 5.0 - 1e-9], z[t > 5.0 - 1e-9])
    cold = _tip_errors(f, t[t > 5.0 - 1e-9], fresh)
    assert gap.mean() < 1e-3 and cold.mean() > 10e-3, (gap.mean(), cold.mean())
    assert not np.any((gap > 5e-3) & (np.asarray(series.status)[after] == "ok"))
    # a restart within the recording by the caller (live's at a board reset) keeps them
    # too; one after a failure that may have come from them does not
    from continuum_mhe.results import Measurement

    late = t > 5.0 - 1e-9
    for keep_sensors, good in ((True, True), (False, False)):
        est.reset()
        est.continue_run(t[kept][~after], z[kept][~after])
        est.reset(keep_counts=True, keep_sensors=keep_sensors)
        rows = [est.step(Measurement(float(tk), zk)) for tk, zk in zip(t[late], z[late])]
        tip = np.array([r.value(c) for r in rows for c in "xyz"]).reshape(-1, 3)
        truth = read_state_table(DATA / "force-29_truth.csv")
        true_tip = np.column_stack([truth.column(c)[late] for c in "xyz"])
        mean = float(np.linalg.norm(tip - true_tip, axis=1).mean())
        assert (mean < 1e-3) if good else (mean > 10e-3), (keep_sensors, mean)
    est.reset()  # a new recording: nothing kept from the last one
    est.run(t[kept][~after], z[kept][~after])
    again = est.run(t[t > 5.0 - 1e-9], z[t > 5.0 - 1e-9])
    # the same lost start (to rounding, which its drift amplifies: the statics' solver
    # starts from its last solution)
    lost = _tip_errors(f, t[t > 5.0 - 1e-9], again)
    assert lost.mean() == pytest.approx(cold.mean(), rel=1e-3)


def test_a_restart_keeps_no_sensor_state_one_reading_set() -> None:
    """The shipped ``unloaded`` with the tension gains estimated, the samples between
    0.02 and 1.52 s missing: the estimate before the gap is the start's second, whose
    gains one reading moved (0.83 and 0.99) and barely informed. Kept, they would set
    the rest of the run (hundreds of ``ok`` rows more than 5 mm off, 6.7 mm on average); the
    restart keeps only the states the data informed, and no ``ok`` row is 5 mm off."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.model.registry import make_formulation

    options = InputOptions(tensions=str(DATA / "unloaded_tensions.csv"), estimate_tension_gain=True)
    base = make_formulation("bend", read_robot("tendon-two-section"))
    with open_input(DATA / "unloaded_raw.csv", options, base) as stream:
        f = stream.formulation
        blocks = list(stream.blocks)
    t = np.concatenate([b[0] for b in blocks])
    z = np.vstack([b[1] for b in blocks])
    kept = (t < 0.02 + 1e-9) | (t > 1.52 - 1e-9)
    series = make_estimator("ekf", f).run(t[kept], z[kept])
    truth = read_state_table(DATA / "unloaded_truth.csv")
    rows = np.searchsorted(truth.t, t[kept] - 1e-9)
    cols = [o.name for o in f.outputs]
    tip = np.asarray(series.output, float)[:, [cols.index(c) for c in "xyz"]]
    err = np.linalg.norm(tip - np.column_stack([truth.column(c)[rows] for c in "xyz"]), axis=1)
    after = t[kept] > 1.52 - 1e-9
    assert not np.any((err > 5e-3) & (np.asarray(series.status) == "ok") & after)
    assert err[after].mean() < 2e-3


def test_what_a_restart_keeps_of_the_sensors() -> None:
    """Known answers: a tendon robot's sensor states are its IMU-error states (gyro
    biases, misalignments, accelerometer biases); a restart keeps their values and
    covariance block, and the start's prior holds them (the gyro biases fitted to the
    reading within their kept standard deviations), uncorrelated with the rest; an
    estimate that drifted or is not finite keeps nothing, nor does a PCC robot, which
    has no sensor states."""
    from continuum_mhe.model.registry import make_formulation

    f, _, z = _raw_shipped(2)
    names = [f.state_names[i] for i in f.sensor_states]
    assert names and all(n.startswith(("bg", "mis", "ba")) for n in names)
    x0, _ = f.start_prior(z[0])
    rng = np.random.default_rng(2)
    idx = np.asarray(f.sensor_states)
    x = x0.copy()
    x[idx] = 0.1 * np.sqrt(np.diag(f.initial_cov())[idx]) * rng.standard_normal(len(idx))
    A = rng.standard_normal((f.nx, f.nx))
    P = 1e-6 * (A @ A.T + np.eye(f.nx))
    kept = f.kept_sensors(x, P)
    assert kept is not None
    np.testing.assert_array_equal(kept.states, idx)
    np.testing.assert_array_equal(kept.values, x[idx])
    np.testing.assert_array_equal(kept.cov, P[np.ix_(idx, idx)])
    # a state the data have not informed (its std near its prior's) is not kept, and
    # the random walks widen what is, over the time since
    wide = P.copy()
    wide[idx[0], idx[0]] = f.initial_cov()[idx[0], idx[0]]
    partial = f.kept_sensors(x, wide, dt=10.0)
    assert partial is not None and list(partial.states) == list(idx[1:])
    grown = np.diag(partial.cov) - np.diag(P)[idx[1:]]
    np.testing.assert_allclose(grown, 10.0 * np.diag(f.process_cov(1.0))[idx[1:]], rtol=1e-9)
    xs, Ps = f.start_prior(z[0], kept)
    held = np.array([not n.startswith("bg") for n in names])  # the gyro biases: fitted
    np.testing.assert_array_equal(xs[idx[held]], x[idx[held]])
    bias = idx[~held]
    assert np.all(np.abs(xs[bias] - x[bias]) <= 5 * np.sqrt(np.diag(P)[bias]))
    np.testing.assert_array_equal(Ps[np.ix_(idx, idx)], P[np.ix_(idx, idx)])
    rest = np.setdiff1d(np.arange(f.nx), idx)
    assert not Ps[np.ix_(idx, rest)].any()
    drifted = x.copy()
    drifted[idx] = 50.0 * np.sqrt(np.diag(f.initial_cov())[idx])
    assert f.drifted(drifted) and f.kept_sensors(drifted, P) is None
    assert f.kept_sensors(np.full(f.nx, np.nan), P) is None
    assert f.kept_sensors(None, None) is None
    pcc = make_formulation("direct")
    assert pcc.sensor_states == () and pcc.kept_sensors(np.zeros(pcc.nx), np.eye(pcc.nx)) is None


def test_the_change_test_takes_the_imu_error_states_with_their_random_walks() -> None:
    """Known answer: the estimate-change test of a raw-IMU tendon robot covers its gyro
    biases, misalignments and accelerometer biases, in units of their prior standard
    deviations, with their random walks' densities; a PCC robot has none."""
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.tendon import CHANGE_LAG

    f, _, _ = _raw_shipped(2)
    test = f.change_test()
    assert test is not None and test.lag == CHANGE_LAG
    names = [f.state_names[i] for i in test.rows]
    assert names and all(n.startswith(("bg", "mis", "ba")) for n in names)
    assert len(names) == sum(n.startswith(("bg", "mis", "ba")) for n in f.state_names)
    want = {"bg": f.gyro_bias_psd, "mis": f.misalignment_psd, "ba": f.accel_bias_psd}
    prior = {
        "bg": f.initial_gyro_bias_std,
        "mis": f.initial_misalignment_std,
        "ba": f.initial_accel_bias_std,
    }
    for n, psd, scale in zip(names, test.psd, test.scale):
        kind = next(k for k in want if n.startswith(k))
        assert psd == pytest.approx(want[kind], rel=1e-12)
        assert scale == pytest.approx(prior[kind], rel=1e-12)
    assert make_formulation("bend").change_test() is None


def test_an_imu_declared_in_the_wrong_place_is_drifted_before_it_is_far_off() -> None:
    """The shipped ``unloaded`` (raw IMUs) estimated with a robot file that puts IMU 1
    at the middle of section 1 (it is at its end): the tip force and the IMUs' error
    states take up the difference, the shape runs tens of mm off with millimetre
    standard deviations, and the IMU errors' prior holds for over a second. Their
    change within a quarter of a second, against what their covariance allows, shows it
    at once: no row more than 5 mm off is ``ok``."""
    from continuum_mhe.estimators import make_estimator

    f, t, z = _raw_shipped(150)
    moved = replace(f.robot, imus=(ImuPlacement(0, 0.5), *f.robot.imus[1:]))
    wrong = replace(f, robot=moved)
    series = make_estimator("ekf", wrong).run(t, z)
    truth = read_state_table(DATA / "unloaded_truth.csv")
    cols = [o.name for o in wrong.outputs]
    tip = np.asarray(series.output, float)[:, [cols.index(c) for c in "xyz"]]
    true_tip = np.column_stack([truth.column(c)[: len(t)] for c in "xyz"])
    far = np.linalg.norm(tip - true_tip, axis=1) > 5e-3
    assert far.sum() > 100
    assert not np.any(far & (series.status == "ok"))


def test_the_start_misfit_weighs_the_direction_rows_by_noise_and_imu_errors() -> None:
    """Known answer: each accelerometer-direction row counts ``r^2 / (s^2 + m^2 +
    (b / g)^2)`` (reading noise s, misalignment and bias priors m and b), the gyro
    rows not at all, and the limit is the chi-square quantile of the rows
    counted."""
    from scipy.stats import chi2

    from continuum_mhe.model.imu import STANDARD_GRAVITY
    from continuum_mhe.model.tendon import LOADED_START_PROBABILITY

    robot = read_robot("tendon-two-section")
    f = TendonFormulation(robot=robot, imu_model="direct", estimate_gyro_bias=True)
    var = (
        f.noise.measurement_std**2
        + f.initial_misalignment_std**2
        + (f.initial_accel_bias_std / STANDARD_GRAVITY) ** 2
    )
    r = np.zeros(f.n_imu_measurements)
    r[1] = 2.0 * math.sqrt(var)  # IMU 1's y direction: 4
    r[7] = math.sqrt(var)  # IMU 2's y direction: 1
    r[3] = r[10] = 100.0  # gyros: not counted
    valid = np.ones(f.n_imu_measurements, dtype=bool)
    misfit, limit = f.start_misfit(r, valid)
    assert misfit == pytest.approx(5.0, rel=1e-12)
    assert limit == pytest.approx(chi2.ppf(1 - LOADED_START_PROBABILITY, 6), rel=1e-9)
    valid[6:9] = False  # IMU 2's direction missing
    misfit, limit = f.start_misfit(r, valid)
    assert misfit == pytest.approx(4.0, rel=1e-12)
    assert limit == pytest.approx(chi2.ppf(1 - LOADED_START_PROBABILITY, 3), rel=1e-9)


def _estimate_with_own_tensions(meas: Path, name: str, out: Path) -> str:
    """``estimate`` of ``meas`` into ``out`` with only ``--robot`` and ``--inputs`` (the
    shipped ``name``'s tensions): what it said on stderr."""
    argv = ["estimate", str(meas), "--robot", "tendon-two-section",
            "--inputs", str(DATA / f"{name}_tensions.csv"), "-o", str(out)]  # fmt: skip
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(argv) == 0
    return err.getvalue()


@pytest.fixture(scope="module")
def twist08_raw_4s(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``estimate`` with only ``--robot`` and ``--inputs`` on the first 200 samples (4 s)
    of the shipped ``twist-08`` (raw IMUs): ``(estimate file, what it said on
    stderr)``, run once a module for the tests that read its first second and its
    twist. (The estimates are causal: a row is that of the same samples cut after it.)"""
    folder = tmp_path_factory.mktemp("twist08")
    raw = folder / "twist-08_raw_4s.csv"
    raw.write_text("\n".join((DATA / "twist-08_raw.csv").read_text().splitlines()[:201]) + "\n")
    out = folder / "e.csv"
    return out, _estimate_with_own_tensions(raw, "twist-08", out)


def test_the_first_second_of_a_raw_recording_is_not_bent_by_the_imus_errors(
    twist08_raw_4s: tuple[Path, str],
) -> None:
    """``estimate`` with only ``--robot`` and ``--inputs`` on the shipped ``twist-08``
    (raw IMUs; the robot starts straight and free of load; the module's run of its
    first 4 s): over its first 60 samples the tip within 1 mm on average (2.1 mm with
    the wide start prior, which reads the IMUs' errors as a tip force)."""
    out, _ = twist08_raw_4s
    est, truth = read_state_table(out), read_state_table(DATA / "twist-08_truth.csv")
    xyz = ("x", "y", "z")
    e = np.column_stack([est.column(c) for c in xyz])[:60]
    t = np.column_stack([truth.column(c) for c in xyz])[: len(e)]
    assert len(e) == 60 and np.allclose(est.t[:60], truth.t[:60])
    assert np.linalg.norm(e - t, axis=1).mean() < 0.001


# --- the estimator a tendon robot gets --------------------------------------------------
def test_a_tendon_robot_defaults_to_the_ekf_and_a_pcc_robot_to_the_mhe(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The fast MHE cannot take the mechanics model: the EKF is the default, said in the
    summary line (nothing before the input is read, so a bad input stays one line); a
    robot without a backbone keeps the MHE, silently; a chosen method is kept."""
    import argparse

    from continuum_mhe.cli.method_options import method_from_args
    from continuum_mhe.estimators import default_method
    from continuum_mhe.model.registry import make_formulation

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots"
    tendon = TendonFormulation(robot=read_robot(shipped / "tendon_two_section.toml"))
    pcc = make_formulation("bend", read_robot(shipped / "two_section.toml"))
    assert default_method(tendon) == "ekf" and default_method(pcc) == "mhe"
    args = argparse.Namespace(method=None)
    assert method_from_args(args, tendon) == "ekf" and args.method == "ekf"
    assert args.method_note.startswith("by the ekf, this robot's default")
    pcc_args = argparse.Namespace(method=None)
    assert method_from_args(pcc_args, pcc) == "mhe" and pcc_args.method_note is None
    chosen = argparse.Namespace(method="ukf")
    assert method_from_args(chosen, tendon) == "ukf" and chosen.method_note is None
    assert capsys.readouterr().err == ""
    # the command line: the summary says it; a bad input is its one line alone
    meas, tensions = small_robot_recording(tmp_path)
    robot, out = small_robot(tmp_path), tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", str(robot), "--inputs", str(tensions),
            "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert "estimated by the ekf, this robot's default" in err[-1]
    write_table(tensions, ["t", "tension_1"], [[0.0, 1.0], [0.05, 1.0]])  # too short
    assert main([*argv[:-1], str(tmp_path / "e2.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the tensions must cover the recording" in err[0]


def test_the_fast_mhe_on_a_tendon_robot_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--method mhe`` (the fast MHE) on a tendon robot: one line naming the robot file
    and the alternatives, exit 2, nothing written; the library refuses it too."""
    from continuum_mhe.estimators import MovingHorizonEstimator

    meas, tensions = small_robot_recording(tmp_path)
    out, robot = tmp_path / "e.csv", small_robot(tmp_path)
    argv = ["estimate", str(meas), "--robot", str(robot), "--inputs", str(tensions),
            "-o", str(out), "--method", "mhe"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{robot}: --method mhe:" in err[0]
    assert "--method ekf" in err[0] and "--solver ipopt" in err[0]
    assert not out.exists()
    with pytest.raises(UserError, match="the fast MHE cannot take this formulation"):
        MovingHorizonEstimator(TendonFormulation(robot=read_robot(robot)))


def test_the_consistency_check_judges_the_readings_not_the_tip_condition() -> None:
    """An estimate that fits its readings exactly but meets the tip condition only to
    hundreds of its (pseudo-measurement) standard deviations, as after an EKF step's
    linearised update, is not ``inconsistent``; a roll reading 10 standard deviations
    off is."""
    from continuum_mhe.estimators.consistency import ConsistencyCheck

    f = TendonFormulation(robot=one_section_robot(Tendon(0, 0.0, 0.01)))
    tension = np.array([2.0])
    k0, _ = f.statics.solve(np.zeros(3), tension)
    x = np.zeros(f.nx)
    x[:3], x[6] = k0, tension[0]
    x[0] += 0.05  # off the equilibrium of these tensions
    z = np.asarray(f.functions.observe(x)).ravel()
    (eq,) = (b.slice for b in f.measurement_blocks if b.kind == "equilibrium")
    z[eq] = 0.0  # the pseudo-measurement reads zero
    r = np.asarray(f.functions.innovate(z, x)[0]).ravel()
    # the readings fit to rounding
    assert np.max(np.abs(r[: eq.start])) < 1e-15 and np.max(np.abs(r[eq])) > 100 * f.equilibrium_std
    cov = np.eye(f.nx) * 1e-4
    assert not ConsistencyCheck(f).check(0.0, z, f.measurement_mask(z), x, cov)
    z[0] += 10 * f.noise.measurement_std
    assert ConsistencyCheck(f).check(0.0, z, f.measurement_mask(z), x, cov)


# --- a loaded recording ------------------------------------------------------------------
@pytest.fixture(scope="module")
def force29_estimate(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``estimate`` with only ``--robot`` and ``--inputs`` on the whole shipped
    ``force-29`` (raw IMUs, its own tensions): ``(estimate file, what it said on
    stderr)``, run once a module (seconds) for the tests that read the one and the
    other."""
    out = tmp_path_factory.mktemp("force29") / "e.csv"
    return out, _estimate_with_own_tensions(DATA / "force-29_raw.csv", "force-29", out)


def test_plot_checks_a_tip_truth_against_the_robot_it_draws_on(
    force29_estimate: tuple[Path, str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``plot`` without ``--robot`` draws a tendon estimate on the robot its options line
    names (0.4 m here), and checks a truth of tip positions alone against that robot (on
    the default 0.2 m robot the shipped truth reads as "the truth of another robot")."""
    est, _ = force29_estimate
    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    truth = read_state_table(DATA / "force-29_truth.csv")
    tip = tmp_path / "tip.csv"
    write_table(tip, ["t", "x", "y", "z"],
                np.column_stack([truth.t, *(truth.column(c) for c in "xyz")]))  # fmt: skip
    assert main(["plot", str(est), "--truth", str(tip), "-o", str(tmp_path / "p.png")]) == 0
    err = capsys.readouterr().err
    assert "drawn on that robot" in err and "beyond the robot's length" not in err, err


def test_evaluate_refuses_a_tendon_estimate_on_a_robot_without_a_backbone(
    force29_estimate: tuple[Path, str], capsys: pytest.CaptureFixture[str]
) -> None:
    """``evaluate`` with ``--robot`` of constant-curvature sections refuses a tendon
    robot's estimate (scored there, its tip force and twists would be left out), as
    ``plot`` and ``view`` refuse the pair: one line naming the robot file."""
    est, _ = force29_estimate
    truth = str(DATA / "force-29_truth.csv")
    assert main(["evaluate", str(est), truth, "--robot", "two-section"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("continuum-mhe: error: two-section: the robot has no [backbone]")
    assert main(["evaluate", str(est), truth]) == 0  # on the robot its options line names


def test_a_tendon_truth_with_gaps_in_its_tip_force_is_plotted_and_scored(
    force29_estimate: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A truth whose force columns are empty in every third row (a force sensor's lost
    samples): plot leaves the instant's truth out of the 3D panel, without a warning (not
    its backbone drawn under a force of NaN, with "no equilibrium ... (a force in mN, or
    a backbone too soft?)"). evaluate --json
    scores the force over the rows that have it, and writes valid JSON (no NaN), with
    the fx, fy, fz columns empty throughout too."""
    import json

    from continuum_mhe.cli import main

    out, _ = force29_estimate
    header, *rows = (DATA / "force-29_truth.csv").read_text().splitlines()
    names = header.split(",")
    force = {names.index(c) for c in ("fx", "fy", "fz")}

    def gapped(every: int) -> list[str]:
        return [
            ",".join("" if j in force and i % every == 0 else v for j, v in enumerate(r.split(",")))
            for i, r in enumerate(rows)
        ]

    truth = tmp_path / "gapped_truth.csv"
    truth.write_text("\n".join([header, *gapped(3)]) + "\n")
    robot = ["--robot", "tendon-two-section"]
    inputs = ["--inputs", str(DATA / "force-29_tensions.csv")]
    fig = tmp_path / "f.png"
    capsys.readouterr()
    assert main(["plot", str(out), "--truth", str(truth), *robot, *inputs, "-o", str(fig)]) == 0
    err = capsys.readouterr().err
    assert "equilibrium" not in err and "nan" not in err.lower(), err
    assert main(["evaluate", str(out), str(truth), *robot, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["n_without_truth"] == 0
    # the rms over the rows whose force is given, from the files (rows on the same times;
    # a gap counted as an error of 0 reads sqrt(2/3) of it)
    est, given = read_state_table(out), read_state_table(DATA / "force-29_truth.csv")
    np.testing.assert_array_equal(est.t, given.t)
    error = np.column_stack([est.column(c) - given.column(c) for c in ("fx", "fy", "fz")])
    kept = np.arange(len(rows)) % 3 != 0
    want = math.sqrt(np.mean(np.sum(error[kept] ** 2, axis=1)))
    assert report["tip_force_rms_n"] == pytest.approx(want, rel=1e-9) and want > 0.0
    truth.write_text("\n".join([header, *gapped(1)]) + "\n")  # no force anywhere
    assert main(["evaluate", str(out), str(truth), *robot, "--json"]) == 0
    text = capsys.readouterr().out
    report = json.loads(text)
    assert "NaN" not in text and report["tip_force_rms_n"] is None
    assert "fx" not in report["rmse"]


def test_estimate_follows_the_loaded_robot_and_its_tip_force(
    force29_estimate: tuple[Path, str],
) -> None:
    """``estimate`` with only ``--robot`` and ``--inputs`` on the shipped ``force-29``
    (raw IMUs, a tip force up to 0.29 N made by PyElastica, not by the estimator's model):
    the tip within the 10 mm and the force within the 0.05 N rms that the tendon issue
    asks of such a recording (a PCC model is about 90 mm off there), every row written
    and none ``ok`` more than 20 mm off."""
    out, _ = force29_estimate
    est, truth = read_state_table(out), read_state_table(DATA / "force-29_truth.csv")
    np.testing.assert_array_equal(est.t, truth.t)

    def cols(table: StateTable, names: tuple[str, ...]) -> np.ndarray:
        return np.column_stack([table.column(c) for c in names])

    tip_error = np.linalg.norm(cols(est, ("x", "y", "z")) - cols(truth, ("x", "y", "z")), axis=1)
    force_error = cols(est, ("fx", "fy", "fz")) - cols(truth, ("fx", "fy", "fz"))
    assert np.abs(cols(truth, ("fx", "fy", "fz"))).max() > 0.2  # the recording is loaded
    assert tip_error.mean() < 0.010
    assert np.sqrt(np.mean(np.sum(force_error**2, axis=1))) < 0.05
    assert est.status is not None
    assert not np.any((est.status == "ok") & (tip_error > 0.020))


# --- one IMU ---------------------------------------------------------------------------
def test_the_force_random_walk_is_slower_for_a_robot_with_one_imu() -> None:
    """The tip force's white-noise acceleration defaults from the robot's IMUs, and a
    given value wins."""
    from continuum_mhe.model.tendon import FORCE_ACCEL_PSD, SINGLE_IMU_FORCE_ACCEL_PSD

    two = read_robot("tendon-two-section")
    one = Robot(two.sections, two.imus[1:], two.mounting, two.backbone, two.tendons)
    q_force = {}
    for robot in (one, two):
        f = TendonFormulation(robot=robot)
        q = np.asarray(ca.Function("q", [], [f.process_cov_sym(1.0)])()["o0"])
        k = robot.n_tendons
        q_force[robot.n_imus] = q[9 + k, 9 + k]  # the force's rate, over one second
    assert q_force == {1: SINGLE_IMU_FORCE_ACCEL_PSD, 2: FORCE_ACCEL_PSD}
    assert TendonFormulation(robot=one, force_accel_psd=0.5).force_psd == 0.5
    with pytest.raises(UserError, match="force_accel_psd"):
        TendonFormulation(robot=one, force_accel_psd=-1.0)


def test_one_raw_imu_at_the_tip_holds_the_tip_force_and_the_shape() -> None:
    """The shipped robot with its tip IMU alone (raw, with the tensions), the unloaded
    recording, the command line's EKF: after the first second the tip force, truly zero,
    is within 0.1 N rms, and the tip within the 2 mm mean error of the tendon robots'
    target. The force bound is five times the force's standard deviation that the
    Kalman covariance reaches along the true states (about 0.02 N per component). At the
    force's random walk of a two-IMU robot (1 N^2/s^3) the force is 0.11 N rms off and
    the tip 16.9 mm: the tip bound is what tells the one-IMU force's speed from it."""
    from dataclasses import replace

    from continuum_mhe.errors import UnobservableShapeWarning
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.raw_imu import RawImuSettings, raw_to_measurements
    from continuum_mhe.io.tensions import tendon_formulation_for
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.settings import NoiseSettings

    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    n = 401
    robot = read_robot("tendon-two-section")
    robot = replace(robot, imus=robot.imus[1:])
    base = make_formulation("direct", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    raw = np.loadtxt(data / "unloaded_raw.csv", delimiter=",", skiprows=1)[:n]
    t = raw[:, 0]
    z_imu = raw_to_measurements(t, raw[:, 7:10], raw[:, 10:13], RawImuSettings(imu_model="direct"))
    tensions = read_tensions(data / "unloaded_tensions.csv", robot.n_tendons)
    z = np.array([f.measurement_row(zi, *tensions.at(ti)) for ti, zi in zip(t, z_imu)])
    with pytest.warns(UnobservableShapeWarning):
        est = make_estimator("ekf", f)
    series = est.run(t, z)
    cols = [o.name for o in f.outputs]
    force = np.asarray(series.output, float)[t >= 1.0][
        :, [cols.index(c) for c in ("fx", "fy", "fz")]
    ]
    assert np.all(np.isfinite(force))
    assert float(np.sqrt(np.mean(np.sum(force**2, axis=1)))) < 0.1
    truth = read_state_table(data / "unloaded_truth.csv")
    assert np.allclose(truth.t[:n], t)
    tip = np.asarray(series.output, float)[:, [cols.index(c) for c in ("x", "y", "z")]]
    true_tip = np.column_stack([truth.column(c)[:n] for c in ("x", "y", "z")])
    assert float(np.mean(np.linalg.norm(tip - true_tip, axis=1)[t >= 1.0])) < 2e-3


def test_one_raw_imu_follows_a_turning_tip_force_by_its_acceleration() -> None:
    """The shipped robot with its tip IMU alone (raw, with the tensions) on ``twist-29``
    (a tip force of up to 0.29 N that turns), the command line's EKF: by default the tip
    force's acceleration is a state (its jerk 0.03 N^2/s^5, a white acceleration of 3e-4
    N^2/s^3 beside it) and the gyro's noise is taken as 0.005 rad/s, and the tip lies
    2.97 mm off on average after the first second, the force 0.021 N rms; at constant
    velocity (``estimate_force_acceleration=False``, the two-IMU force noise's one-IMU
    value) 19.41 mm and 0.089 N, the force's acceleration taken up by the IMU's
    misalignment; with the two-IMU robot's gyro noise (0.01 rad/s) 3.97 mm, the gyro's
    rate, which tells the force's motion from the IMU's constant errors, held too
    loosely; with a jerk of 0.01 and a white acceleration of 3e-3 5.90 mm, the force's
    motion left to the white acceleration (docs/tendon-studies.md, "The tip IMU alone
    under load")."""
    from dataclasses import replace

    from continuum_mhe.errors import UnobservableShapeWarning
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.raw_imu import RawImuSettings, raw_to_measurements
    from continuum_mhe.io.tensions import tendon_formulation_for
    from continuum_mhe.model.direct import DEFAULT_GYRO_STD
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.settings import NoiseSettings
    from continuum_mhe.model.tendon import (
        SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD,
        SINGLE_IMU_FORCE_JERK_PSD,
        SINGLE_IMU_GYRO_STD,
    )

    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    robot = read_robot("tendon-two-section")
    robot = replace(robot, imus=robot.imus[1:])
    base = make_formulation("direct", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    assert isinstance(f, TendonFormulation) and f.n_force_acceleration == 3
    assert (f.jerk_psd, f.force_psd) == (
        SINGLE_IMU_FORCE_JERK_PSD, SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD
    )  # fmt: skip
    assert f.gyro_noise_std == SINGLE_IMU_GYRO_STD < DEFAULT_GYRO_STD
    raw = np.loadtxt(data / "twist-29_raw.csv", delimiter=",", skiprows=1)
    t = raw[:, 0]
    z_imu = raw_to_measurements(t, raw[:, 7:10], raw[:, 10:13], RawImuSettings(imu_model="direct"))
    tensions = read_tensions(data / "twist-29_tensions.csv", robot.n_tendons)
    z = np.array([f.measurement_row(zi, *tensions.at(ti)) for ti, zi in zip(t, z_imu)])
    truth = read_state_table(data / "twist-29_truth.csv")
    true_tip = np.column_stack([truth.column(c) for c in ("x", "y", "z")])
    later = t >= 1.0
    errors = {}
    for name, g in [
        ("default", f),
        ("constant velocity", replace(f, estimate_force_acceleration=False)),
        ("two-IMU gyro noise", replace(f, gyro_std=DEFAULT_GYRO_STD)),
        ("white acceleration", replace(f, force_jerk_psd=0.01, force_accel_psd=3e-3)),
    ]:
        with pytest.warns(UnobservableShapeWarning):
            est = make_estimator("ekf", g)
        series = est.run(t, z)
        cols = [o.name for o in g.outputs]
        tip = np.asarray(series.output, float)[:, [cols.index(c) for c in ("x", "y", "z")]]
        errors[name] = float(np.mean(np.linalg.norm(tip - true_tip, axis=1)[later])) * 1e3
    assert errors["default"] < 4.0 < 15.0 < errors["constant velocity"], errors
    assert errors["default"] < errors["two-IMU gyro noise"] - 0.5, errors
    assert errors["default"] < errors["white acceleration"] - 2.0, errors


def test_the_gyro_noise_is_resolved_from_the_robot_s_imus() -> None:
    """``gyro_std`` None (the default) is :data:`SINGLE_IMU_GYRO_STD` for a robot with one
    IMU and the command line's 0.01 rad/s with two; a value given stays, 0.01 included
    (``InputOptions.gyro_std`` None is the model's own)."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.tensions import tendon_formulation_for
    from continuum_mhe.model.direct import DEFAULT_GYRO_STD
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.tendon import SINGLE_IMU_GYRO_STD

    two = read_robot("tendon-two-section")
    one = replace(two, imus=two.imus[1:])
    for robot, want in ((one, SINGLE_IMU_GYRO_STD), (two, DEFAULT_GYRO_STD)):
        f = TendonFormulation(robot=robot, imu_model="direct", estimate_gyro_bias=True)
        assert f.gyro_std is None and f.gyro_noise_std == want
        assert f.meas_cov()[5, 5] == pytest.approx(want**2)  # the first IMU's gz row
        assert replace(f, gyro_std=0.02).gyro_noise_std == 0.02
        base = make_formulation("direct", robot)
        assert tendon_formulation_for(base, InputOptions()).gyro_noise_std == want
        for options in (InputOptions(gyro_std=0.02), InputOptions(gyro_std=DEFAULT_GYRO_STD)):
            f = tendon_formulation_for(base, options)
            assert f.gyro_noise_std == options.gyro_std
    with pytest.raises(UserError, match="gyro_std must be a positive finite number"):
        TendonFormulation(robot=one, imu_model="direct", gyro_std=0.0)


def test_an_options_files_gyro_noise_at_the_two_imu_default_is_kept_for_one_imu(
    tmp_path: Path,
) -> None:
    """The tip IMU alone (raw) takes 0.005 rad/s of gyro noise by default; 0.01 rad/s
    given in an options file (``gyro-std = 0.01``, the two-IMU default's value) is the
    user's choice and gives the estimates of ``--gyro-std 0.01`` on the command line, not
    the default's; and an estimate file's options read back (``--config EST.csv``)
    repeat its estimates (its record leaves out the gyro noise it was not given)."""
    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"
    text = (data / "robots" / "tendon_two_section.toml").read_text()
    robot = tmp_path / "tip.toml"
    robot.write_text(text.replace("[[imu]]\nsection = 1\n\n", "", 1))
    assert read_robot(robot).n_imus == 1
    lines = (data / "tendon" / "twist-29_raw.csv").read_text().splitlines()[:101]
    header = "t," + ",".join(c.replace("_2", "_1") for c in lines[0].split(",")[7:])
    raw = tmp_path / "raw.csv"
    raw.write_text("\n".join([header] + [",".join(r.split(",")[:1] + r.split(",")[7:])
                                          for r in lines[1:]]) + "\n")  # fmt: skip
    config = tmp_path / "options.toml"
    config.write_text("gyro-std = 0.01\n")
    common = ["--robot", str(robot), "--inputs", str(data / "tendon" / "twist-29_tensions.csv")]
    runs = {
        "default": [],
        "options file": ["--config", str(config)],
        "command line": ["--gyro-std", "0.01"],
        "default record": ["--config", str(tmp_path / "default.csv")],
    }
    est = {}
    for name, extra in runs.items():
        out = tmp_path / f"{name.replace(' ', '_')}.csv"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main(["estimate", str(raw), "-o", str(out), *common, *extra]) == 0
        est[name] = read_state_table(out)
    x = {name: table.column("x") for name, table in est.items()}
    np.testing.assert_array_equal(x["options file"], x["command line"])
    np.testing.assert_array_equal(x["default record"], x["default"])
    assert np.max(np.abs(x["options file"] - x["default"])) > 1e-6


def test_the_start_takes_a_gyro_reading_as_its_bias_not_as_a_force() -> None:
    """Noise-free raw readings of a known tip force, tensions and gyro biases (two
    IMUs, the rod at rest): the start recovers the force and each gyro's bias (a wide
    prior on the force, as in the tilt case above). With the biases left at zero the
    gyros' readings would have to be explained by the force."""
    robot = read_robot("tendon-two-section")
    f = TendonFormulation(
        robot=robot, imu_model="direct", estimate_gyro_bias=True, initial_force_std=100.0
    )
    tau = np.array([1.0, 0.5, 0.0, 0.0, 1.5, 0.3])
    force = np.array([0.03, -0.02, 0.01])
    bias = np.array([0.03, -0.02, 0.05, -0.04, 0.01, 0.02])
    k0, _ = f.statics.solve(force, tau)
    x = np.zeros(f.nx)
    x[:3], x[3:6], x[6:12] = k0, force, tau
    first_bias = f.state_names.index("bgx_1")
    x[first_bias : first_bias + 6] = bias
    h = np.asarray(f.functions.observe(x), float).ravel()
    z = f.measurement_row(h[: f.n_imu_measurements], tau, np.zeros(6))
    x0 = f.initial_state(z)
    np.testing.assert_allclose(x0[3:6], force, atol=1e-4)
    np.testing.assert_allclose(x0[first_bias : first_bias + 6], bias, atol=1e-4)


def test_the_start_of_one_raw_imu_on_a_straight_rod_reads_no_axial_force() -> None:
    """The first sample of the unloaded recording (straight, no tip force), the tip IMU
    alone, raw, with its gyro's bias: the start's tip force is within 0.02 N of the
    truth's zero, where a gyro bias read as a force would put 0.59 N along the rod."""
    from dataclasses import replace

    from continuum_mhe.io.raw_imu import RawImuSettings, raw_to_measurements

    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    robot = read_robot("tendon-two-section")
    robot = replace(robot, imus=robot.imus[1:])
    wide = TendonFormulation(robot=robot).force_prior_std  # a narrow one would pin it
    f = TendonFormulation(
        robot=robot, imu_model="direct", estimate_gyro_bias=True, gyro_std=0.01,
        accel_direction_std=math.radians(2.0), initial_force_std=wide,
    )  # fmt: skip
    raw = np.loadtxt(data / "unloaded_raw.csv", delimiter=",", skiprows=1)[:3]
    truth = read_state_table(data / "unloaded_truth.csv")
    z_imu = raw_to_measurements(
        raw[:, 0], raw[:, 7:10], raw[:, 10:13], RawImuSettings(imu_model="direct")
    )
    tensions = read_tensions(data / "unloaded_tensions.csv", robot.n_tendons)
    z = f.measurement_row(z_imu[0], *tensions.at(raw[0, 0]))
    x0 = f.initial_state(z)
    true_force = np.array([truth.column(c)[0] for c in ("fx", "fy", "fz")])
    assert float(np.linalg.norm(x0[3:6] - true_force)) < 0.02


def test_the_tip_force_prior_is_a_third_of_the_buckling_load() -> None:
    """The tip force's prior standard deviation defaults to a third of the Euler load of
    the straight backbone as a cantilever, ``pi^2 EI / (4 L^2)`` (the shipped robot: E =
    54 GPa, r = 0.7 mm, L = 0.4 m, 0.157 N); a given value wins and a bad one is refused."""

    robot = read_robot("tendon-two-section")
    ei = 54e9 * math.pi * 0.0007**4 / 4
    euler = math.pi**2 * ei / (4 * 0.4**2)
    prior = np.diag(TendonFormulation(robot=robot).initial_cov())
    np.testing.assert_allclose(prior[3:6], (euler / 3) ** 2, rtol=1e-12)
    assert TendonFormulation(robot=robot, initial_force_std=0.5).initial_cov()[3, 3] == 0.25
    with pytest.raises(UserError, match="initial_force_std"):
        TendonFormulation(robot=robot, initial_force_std=0.0)


def test_a_stiff_backbone_s_prior_is_not_taken_for_a_divergence() -> None:
    """A 2 mm steel backbone's force prior (a third of its 155 N buckling load) exceeds
    50 N: the limit at which a tip force counts as diverged is ten buckling loads, at
    least 50 N (not a fixed 50 N, at which every sample would restart and ``estimate``
    give no estimate); a given value wins."""
    from continuum_mhe.model.tendon import DIVERGED_BUCKLING_MULTIPLE, MAX_FORCE_FLOOR

    shipped = read_robot("tendon-two-section")
    steel = replace(
        shipped,
        sections=shipped.sections[:1],
        imus=(ImuPlacement(0, 0.5), ImuPlacement(0)),
        backbone=Backbone(200e9, 79e9, 0.002, 7850.0),
        tendons=tuple(Tendon(0, math.radians(a), 0.01) for a in (0.0, 120.0, 240.0)),
    )
    f = TendonFormulation(robot=steel)
    ei = 200e9 * math.pi * 0.002**4 / 4
    buckling = math.pi**2 * ei / (4 * 0.2**2)
    assert f.buckling_load == pytest.approx(buckling, rel=1e-12)
    assert f.max_force_used == pytest.approx(DIVERGED_BUCKLING_MULTIPLE * buckling)
    x0, P0 = np.zeros(f.nx), f.initial_cov()
    assert not f.is_diverged(x0, P0)  # the prior alone: 3 * (155 N / 3)^2 > (50 N)^2
    assert TendonFormulation(robot=steel, max_force=50.0).is_diverged(x0, P0)
    assert TendonFormulation(robot=shipped).max_force_used == MAX_FORCE_FLOOR


# --- the standard deviations -----------------------------------------------------------
def _raw_shipped(
    n: int, scenario: str = "unloaded", kind: str = "raw"
) -> tuple[TendonFormulation, np.ndarray, np.ndarray]:
    """The first ``n`` samples of the shipped recording ``scenario`` with raw IMUs (or
    ``kind`` ``"tilt"``), read as the command line reads them (the shipped robot, its
    tensions): ``(formulation, t, z)``."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.model.registry import make_formulation

    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    options = InputOptions(tensions=str(data / f"{scenario}_tensions.csv"))
    base = make_formulation("bend", read_robot("tendon-two-section"))
    with open_input(data / f"{scenario}_{kind}.csv", options, base) as stream:
        f = stream.formulation
        assert isinstance(f, TendonFormulation)
        blocks = list(stream.blocks)
    t = np.concatenate([b[0] for b in blocks])[:n]
    z = np.vstack([b[1] for b in blocks])[:n]
    return f, t, z


def test_the_check_skips_the_shift_that_a_tendon_robot_does_not_judge() -> None:
    """The tip condition's pseudo-measurements pull each update, so a tendon robot's
    shift test is off (every shift limit infinite): the check does not evaluate the
    model again for the shift (a Jacobian of the shooting a sample), though the fit's
    NIS is beyond its limit on every sample."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.estimators.consistency import SAMPLE_QUANTILE
    from continuum_mhe.quantiles import chi2_quantile
    from continuum_mhe.results import Measurement

    f, t, z = _raw_shipped(12, "force-29")
    est = make_estimator("ekf", f)
    core = est._consistency.core
    for k, (tk, zk) in enumerate(zip(t, z)):
        est.step(Measurement(float(tk), zk))
        if k > 0:
            assert core.fit_nis > chi2_quantile(SAMPLE_QUANTILE, core.dof), k
            assert core.shift == 0.0, k


@pytest.mark.parametrize("name", ["bend", "direct"])
def test_the_estimators_refuse_a_model_that_ignores_the_robots_tendons(name: str) -> None:
    """A ``bend`` or ``direct`` model of a robot with tendons, given to an estimator
    (the library's ``make_estimator`` or a class), is one UserError saying what the
    model leaves out and how to get the tendon model: it ignores the tendons' loads,
    and on ``force-29`` with tilt IMUs the EKF's rows are 27 mm off on average, 400
    of 401 ``ok``. The same robot without its tendons is the constant-curvature model's
    to estimate."""
    from dataclasses import replace

    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.estimators.kalman import ExtendedKalmanFilter
    from continuum_mhe.model.registry import make_formulation

    robot = read_robot("tendon-two-section")
    f = make_formulation(name, robot)
    said = f"the robot has 6 tendons, but the {name} model ignores their loads"
    for method in ("mhe", "ekf", "ukf"):
        with pytest.raises(UserError, match=said):
            make_estimator(method, f)
    with pytest.raises(UserError, match=said):
        ExtendedKalmanFilter(f)
    bare_robot = replace(robot, tendons=(), backbone=None)
    assert make_estimator("ekf", make_formulation(name, bare_robot)).formulation.nx > 0


def test_the_estimators_refuse_a_negative_tension_as_the_tensions_file_does() -> None:
    """A negative tension given to ``step``, ``run`` or ``continue_run`` is one
    UserError naming the sample and the tendon (a tendon cannot push), as the tensions
    file's reader refuses one; the tensions' rates may be negative."""
    import re

    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.results import Measurement

    f, t, z = _raw_shipped(5)
    names = f.measurement_names
    z = z.copy()
    z[:, names.index("tension_1_dot")] = -0.5  # a rate: may be negative
    assert make_estimator("ekf", f).run(t, z).output.shape[0] == 5
    z[3, names.index("tension_2")] = -5.0
    message = (
        f"measurement at t={float(t[3])!r} s: tension_2 = -5 N is negative: a tendon cannot push"
    )
    for run in ("run", "continue_run"):
        with pytest.raises(UserError, match=re.escape(message)):
            getattr(make_estimator("ekf", f), run)(t, z)
    with pytest.raises(UserError, match=re.escape(message)):
        make_estimator("ekf", f).step(Measurement(float(t[3]), z[3]))


def test_the_imu_errors_that_are_states_are_not_carried_again_as_reading_errors() -> None:
    """The IMUs' misalignment and accelerometer bias are states by default, so the
    readings carry no constant error outside the state; a formulation without one of
    those states carries the base class's (``noise.reading_bias_std`` on the gravity
    directions)."""
    f = TendonFormulation(robot=read_robot("tendon-two-section"), imu_model="direct")
    assert not np.any(f.reading_bias_cov())
    for change in ({"estimate_misalignment": False}, {"estimate_accel_bias": False}):
        g = replace(f, **change)
        expected = g.gravity_direction_rows() * g.noise.reading_bias_std**2
        assert np.array_equal(np.diag(g.reading_bias_cov()), expected) and expected.any()


def test_the_tip_force_and_tip_std_are_the_filters_own() -> None:
    """The command line's EKF (its sensor-health policy and consistency check) on the
    first 60 samples of the shipped ``unloaded``, raw IMUs: every reported standard
    deviation of the tip and the tip force is the estimate's covariance mapped through
    the model, ``sqrt(diag(J P J^T))``, to 1e-9 of itself: the readings' constant
    error (1.2 degrees each) is not added on top of the misalignment and bias states,
    which would count it twice. Where the estimate is the free-of-load hypothesis' (its
    tip force 0 N), each standard deviation, the tip's and the tip force's, is the loaded
    hypothesis' where that is larger (estimators.load_hypotheses: a load the loaded
    filter cannot tell from none is not excluded, nor the shape it bends), and never
    less than the estimate's own; on most of these rows the loaded one is larger."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.results import Measurement

    f, t, z = _raw_shipped(60)
    est = make_estimator("ekf", f)
    cols = [o.name for o in f.outputs]
    tip = [cols.index(c) for c in ("x", "y", "z")]
    force = [cols.index(c) for c in ("fx", "fy", "fz")]
    checked = free = wider = 0
    for ti, zi in zip(t, z):
        e = est.step(Measurement(float(ti), zi))
        if e.state is None or e.covariance is None or e.output_std is None:
            continue
        own = f.output_std(e.state, e.covariance)
        std = np.asarray(e.output_std)
        if est.inference.unloaded_chosen:
            loaded = est.inference.loaded
            floor = f.output_std(loaded._x, loaded._P)
            for idx in (tip, force):
                np.testing.assert_allclose(std[idx], np.maximum(own[idx], floor[idx]), rtol=1e-9)
            free += 1
            wider += bool(np.all(floor[tip] > own[tip]))
        else:
            np.testing.assert_allclose(std[tip], own[tip], rtol=1e-9)
            np.testing.assert_allclose(std[force], own[force], rtol=1e-9)
        checked += 1
    assert checked == len(t) and free > 30 and wider > free // 2


def test_the_recording_generator_refuses_a_robot_it_does_not_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The tendon-robot generator places each IMU on one of its rod's nodes (a disk or a
    section's end): an IMU between two is one line and exit 2, nothing written; so is a
    robot without tendons (no motion to drive)."""
    path = tmp_path / "one.toml"
    out = tmp_path / "out"
    between = TENDON_FILE.replace("disk = 5", "at = 0.513")
    no_tendons = TENDON_FILE.split("[[tendon]]")[0] + "[[imu]]\nsection = 1\n"
    for text, said in (
        (between, "IMU 1 at 0.513 of section 1 lies between the generator's rod nodes: "
                  "place it on a disk (disk = d in the robot file) or at the section's end"),
        (no_tendons, "the tendon-robot generator writes robots with a [backbone] and "
                     "[[tendon]]s (as tendon-two-section), not 1 section"),
    ):  # fmt: skip
        path.write_text(text)
        assert main(["rod", "tendon", "--robot", str(path), "-o", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0] and not out.exists(), err
    # a hanging robot, and IMUs turned on their disks: refused too (not a standing
    # robot's readings under their names, which the same robot file would refuse)
    shipped = (DATA.parents[0] / "robots" / "tendon_two_section.toml").read_text()
    turned = shipped.replace(
        "[[imu]]\nsection = 2", "[[imu]]\nsection = 2\nmount_rpy = [180, 0, 0]"
    )
    assert turned != shipped
    for text, said in (
        (shipped.replace('mounting = "z-up"', 'mounting = "z-down"'), "mounting = 'z-down': "),
        (turned, "IMU 2 has a mount_rpy: the tendon-robot generator reads each IMU in its"),
    ):
        path.write_text(text)
        assert main(["rod", "tendon", "--robot", str(path), "-o", str(out)]) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert said in line and not out.exists(), line


ONE_SECTION_TWO_IMUS = """
mounting = "z-up"
[backbone]
youngs_modulus = 54e9
shear_modulus = 20.77e9
radius = 0.0007
density = 6450
[[section]]
length = 0.2
disks = 10
[[tendon]]
section = 1
angle = 0
radius = 0.01
[[tendon]]
section = 1
angle = 120
radius = 0.01
[[tendon]]
section = 1
angle = 240
radius = 0.01
[[imu]]
section = 1
disk = 5
[[imu]]
section = 1
"""


def test_the_generator_writes_a_robot_of_one_section_with_an_imu_inside_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot of one section with IMUs at disk 5 and at its end (not the shipped
    robot's two sections): its recording has both IMUs' columns and one section's truth,
    and the estimators' model (a shooting, with the recording's tensions) follows the
    generator's discrete rod (an energy minimisation) to a fraction of a millimetre at
    the tip; with the mid IMU placed at the end instead, the readings do not fit."""
    robot = tmp_path / "one.toml"
    robot.write_text(ONE_SECTION_TWO_IMUS)
    rec = tmp_path / "rec"
    assert main(["rod", "tendon", "--robot", str(robot), "--duration", "1",
                 "-o", str(rec)]) == 0  # fmt: skip
    raw = (rec / "unloaded_raw.csv").read_text().splitlines()[0]
    assert raw == "t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,ay_2,az_2,gx_2,gy_2,gz_2"
    truth = read_state_table(rec / "unloaded_truth.csv")
    assert truth.names[:9] == ("x", "y", "z", "theta_1", "phi_1", "x_1", "y_1", "z_1", "psi_1")
    assert "theta_2" not in truth.names and truth.column("theta_1").max() > 0.2
    tip = np.column_stack([truth.column(c) for c in ("x", "y", "z")])
    means = {}
    for name, text in (("right", ONE_SECTION_TWO_IMUS),
                       ("moved", ONE_SECTION_TWO_IMUS.replace("disk = 5\n", ""))):  # fmt: skip
        robot.write_text(text)
        out = tmp_path / f"{name}.csv"
        tensions = str(rec / "unloaded_tensions.csv")
        assert main(["estimate", str(rec / "unloaded_raw.csv"), "--robot", str(robot),
                     "--inputs", tensions, "-o", str(out)]) == 0  # fmt: skip
        est = read_state_table(out)
        e = np.column_stack([est.column(c) for c in ("x", "y", "z")]) - tip
        means[name] = float(np.mean(np.linalg.norm(e[est.t >= 0.5], axis=1)))
    capsys.readouterr()
    assert means["right"] < 0.5e-3 < 5e-3 < means["moved"], means


def test_the_recording_generator_refuses_sections_without_disks_and_warns_in_one_line(
    tmp_path: Path,
) -> None:
    """A robot file without ``disks`` (optional: the estimators' model does not need
    them) is one line and exit 2 from the generator, which routes the tendons through
    the disks (not a ZeroDivisionError traceback), nothing written; a robot
    file's warning (a tendon angle that reads as radians) prints as the generator's one
    line, not as Python's file, line and source line."""
    import subprocess

    from continuum_mhe.io.robot_file import shipped_robots

    shipped = Path(shipped_robots()["tendon-two-section"]).read_text()
    robot = tmp_path / "radians_no_disks.toml"
    lines = [ln for ln in shipped.splitlines() if not ln.startswith("disks")]
    robot.write_text("\n".join(lines).replace("angle = 240", "angle = 4.712"))
    out = tmp_path / "out"
    r = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", "rod", "tendon", "--robot", str(robot),
         "--duration", "0.04", "-o", str(out)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    err = r.stderr.strip().splitlines()
    assert len(err) == 2, r.stderr
    prog = "continuum-mhe"
    assert err[0].startswith(f"{prog}: warning: ") and "(4.712 rad is 270 degrees)" in err[0]
    assert err[1].startswith(f"{prog}: error: {robot}: section 1 has no spacer disks")
    assert not out.exists()


def test_simulate_refuses_a_tendon_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``simulate`` writes constant-curvature bends without tensions, a recording that
    ``estimate`` on a tendon robot refuses for its missing tensions: with a tendon robot,
    one line naming the robot file and the tendon generator, nothing written."""
    out = tmp_path / "m.csv"
    argv = ["simulate", "spatial", "--robot", "tendon-two-section", "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("continuum-mhe: error: tendon-two-section: a tendon")
    assert "the scenarios but rest (straight and still) are the bends of a" in err[0]
    assert "continuum-mhe rod tendon" in err[0] and not out.exists()


def test_an_imu_count_off_for_a_tendon_robot_asks_for_its_robot_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A one-IMU raw file with the two-IMU tendon robot: the fix is a tendon robot file
    of one IMU, not "leave --robot out" (one section without tendons, which the
    tensions file then refused)."""
    raw1 = tmp_path / "raw1.csv"
    lines = (DATA / "force-29_raw.csv").read_text().splitlines()[:41]
    raw1.write_text("\n".join(",".join(ln.split(",")[:7]) for ln in lines) + "\n")
    argv = ["estimate", str(raw1), "--robot", "tendon-two-section", "--inputs",
            str(DATA / "force-29_tensions.csv"), "-o", str(tmp_path / "e.csv")]  # fmt: skip
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith(
        "but the robot describes 2; pass --robot FILE with a tendon robot file of 1 IMU(s) "
        "(its [[imu]] entries; docs/tendon.md)"
    ), line
    assert "leave --robot out" not in line


def _option_warnings(tmp_path: Path, scenario: str, extra: list[str]) -> list[str]:
    """The OptionWarnings of ``estimate`` on the first 40 rows of the shipped
    ``scenario``'s raw recording with its tensions and ``extra`` options."""
    import warnings

    raw = tmp_path / f"{scenario}_raw.csv"
    rows = (DATA / f"{scenario}_raw.csv").read_text().splitlines()[:41]
    raw.write_text("\n".join(rows) + "\n")
    out = tmp_path / "e.csv"
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["estimate", str(raw), "--robot", "tendon-two-section", "--inputs",
                     str(DATA / f"{scenario}_tensions.csv"), *extra, "-o", str(out),
                     "--overwrite"]) == 0  # fmt: skip
    return [str(w.message) for w in seen if w.category is OptionWarning]


def test_gyro_biases_left_out_on_a_tendon_robot_are_warned_of(tmp_path: Path) -> None:
    """``--no-estimate-gyro-bias`` with raw IMUs on a tendon robot is measurably worse
    (force-29: 94 mm against 0.73 mm, 352 rows drifted), and says so in a warning naming
    the option (the drifted warning pointed at the tensions and the robot file); with
    the biases estimated, no such warning."""
    for extra, said in ((["--no-estimate-gyro-bias"], True), ([], False)):
        lines = _option_warnings(tmp_path, "force-29", extra)
        hits = [ln for ln in lines if ln.startswith("--no-estimate-gyro-bias on a tendon robot")]
        assert len(hits) == (1 if said else 0), lines


def test_a_gyro_std_below_the_calibrated_one_on_a_tendon_robot_is_warned_of(
    tmp_path: Path,
) -> None:
    """``--gyro-std`` below 0.005 rad/s with raw IMUs on a tendon robot makes rows ``ok``
    outside their intervals (the shipped twist-29: 0.001 puts 72 of 351 ``ok`` rows more
    than 4 standard deviations off the truth, 0.003 tip coverage 0.79), and says so in a
    warning naming the option; 0.005 and the default are not warned of."""
    for extra, said in ((["--gyro-std", "0.001"], True), (["--gyro-std", "0.005"], False),
                        ([], False)):  # fmt: skip
        lines = _option_warnings(tmp_path, "twist-29", extra)
        hits = [ln for ln in lines if ln.startswith("--gyro-std 0.001 rad/s on a tendon robot")]
        assert len(hits) == (1 if said else 0), lines
        assert not any(ln.startswith("--gyro-std") for ln in lines) or said, lines


def test_simulate_rest_of_a_tendon_robot_is_its_straight_readings_for_calibrate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``simulate rest`` (which the help gives for any robot) on a tendon robot: the
    robot straight and still, its tendons slack, read as its sections' geometry, raw or
    tilt, which ``calibrate --from`` takes with the same robot file (not refused, though
    the tendon generator has no rest)."""
    rest, truth = tmp_path / "rest.csv", tmp_path / "truth.csv"
    argv = ["simulate", "rest", "--robot", "tendon-two-section", "--imu", "raw", "-o", str(rest),
            "--truth", str(truth)]  # fmt: skip
    assert main(argv) == 0
    # the tendons' tensions, 0 N, beside it for estimate --inputs; the truth in the
    # tendon robot's columns, no twist and no tip force
    assert (tmp_path / "rest_tensions.csv").read_text() == (
        "t,tension_1,tension_2,tension_3,tension_4,tension_5,tension_6\n"
        "0,0,0,0,0,0,0\n20,0,0,0,0,0,0\n"
    )
    table = read_state_table(truth)
    assert table.names == tuple(o.name for o in TendonFormulation(
        robot=read_robot("tendon-two-section")).outputs)  # fmt: skip
    for name in ("psi_1", "psi_2", "fx", "fy", "fz"):
        assert np.all(table.values[:, table.names.index(name)] == 0.0)
    assert np.all(table.values[:, table.names.index("z")] == pytest.approx(0.4))
    assert main([*argv, "--seed", "1"]) == 2  # the tensions file is not replaced unasked
    assert "rest_tensions.csv" in capsys.readouterr().err
    header, first = rest.read_text().splitlines()[:2]
    assert header == "t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,ay_2,az_2,gx_2,gy_2,gz_2"
    values = [float(v) for v in first.split(",")]
    assert abs(values[3] - 9.81) < 0.3 and abs(values[9] - 9.81) < 0.3  # both IMUs up
    capsys.readouterr()
    assert main(["calibrate", "--from", str(rest), "--robot", "tendon-two-section"]) == 0
    out = capsys.readouterr().out
    assert out.count("mounting with the robot straight") == 2, out


def test_plot_of_a_row_whose_loads_have_no_equilibrium_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A row's tip force beyond what the rod holds (a force in mN read as N) has no
    equilibrium to draw: where no row drawn has one, one line naming the file and the
    row's time, exit 2, no figure (not reported as a bug, exit 70); where some do, the
    others are drawn and a warning names it."""
    meas, tensions = small_robot_recording(tmp_path)
    robot = str(small_robot(tmp_path))
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", robot, "--inputs", str(tensions),
                 "-o", str(est)]) == 0  # fmt: skip
    lines = est.read_text().splitlines(True)
    header = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    fx = lines[header].rstrip("\n").split(",").index("fx")
    for i in range(header + 1, len(lines)):  # every row: the figure draws a few of them
        cells = lines[i].rstrip("\n").split(",")
        cells[fx] = "80"
        lines[i] = ",".join(cells) + "\n"
    est.write_text("".join(lines))
    capsys.readouterr()
    fig = tmp_path / "e.png"
    argv = ["plot", str(est), "--robot", robot, "--inputs", str(tensions), "-o", str(fig)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {est}: the row at t = 0 s")
    assert "no equilibrium" in err[0] and not fig.exists()
    view = tmp_path / "v.rrd"  # view names the file alike
    argv = ["view", str(est), "--robot", robot, "--inputs", str(tensions), "--save", str(view)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {est}: the row at t = 0 s")
    assert not view.exists()
    # one such row among drawable ones: drawn through its section ends, as plot draws
    # it, and one warning names it
    for i in range(header + 1, len(lines)):
        cells = lines[i].rstrip("\n").split(",")
        cells[fx] = "80" if i == header + 3 else "0"
        lines[i] = ",".join(cells) + "\n"
    est.write_text("".join(lines))
    view.unlink(missing_ok=True)
    first = (
        "continuum-mhe: warning: 1 of the backbones drawn joined through their section ends: "
        "the mechanics model holds no equilibrium under their loads; the first: the row at "
        "t = 0.04 s"
    )
    capsys.readouterr()
    assert main(argv) == 0
    assert [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith(first)], first
    assert view.exists()
    # and plot: of the four rows it draws, the one without an equilibrium is drawn
    # through its section ends, said (not the whole figure refused)
    for i in range(header + 1, len(lines)):
        cells = lines[i].rstrip("\n").split(",")
        cells[fx] = "80" if i == header + 2 else "0"
        lines[i] = ",".join(cells) + "\n"
    est.write_text("".join(lines))
    argv = ["plot", str(est), "--robot", robot, "--inputs", str(tensions), "-o", str(fig)]
    said = r"^1 of the backbones drawn joined through their section ends: .* the row at t = 0.02 s"
    figures_drawn_small(monkeypatch)  # the warning of the figure's making, not its drawing
    with pytest.warns(UserWarning, match=said):
        assert main(argv) == 0
    assert fig.stat().st_size > 0


def test_plot_and_view_refuse_tensions_in_millinewtons_as_estimate_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Tensions a thousand times too large given to ``plot`` and ``view`` (mN written as
    N): the line ``estimate`` gives for them (the bend they would make), exit 2, no
    figure and no view; with the right tensions both draw."""
    meas, tensions = small_robot_recording(tmp_path)
    robot = str(small_robot(tmp_path))
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", robot, "--inputs", str(tensions),
                 "-o", str(est)]) == 0  # fmt: skip
    header, *rows = (ln.split(",") for ln in tensions.read_text().splitlines())
    mn = tmp_path / "mN.csv"
    write_table(mn, header, [[float(r[0]), *(1000 * float(v) for v in r[1:])] for r in rows])
    capsys.readouterr()
    for command, flag, out in (("plot", "-o", tmp_path / "e.png"),
                               ("view", "--save", tmp_path / "v.rrd")):  # fmt: skip
        argv = [command, str(est), "--robot", robot, "--inputs", str(mn), flag, str(out)]
        assert main(argv) == 2, command
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"{mn}: line " in err[0], (command, err)
        assert "would bend section 1 through" in err[0] and "(mN or grams?)" in err[0]
        assert not out.exists()
        argv = [command, str(est), "--robot", robot, "--inputs", str(tensions), flag, str(out)]
        assert main(argv) == 0 and out.exists(), command
        capsys.readouterr()


def test_check_robot_of_a_backbone_too_soft_for_its_weight_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A backbone whose weight bends it beyond what the mechanics model solves: the
    loads without an equilibrium are left out of check-robot's report and counted in a
    warning on stderr, one line naming the robot file as the other warnings do (the
    report, and --json's JSON, stay on stdout); where none has one, one line naming the
    robot file, exit 2 (never an internal error, exit 70)."""
    import json

    shipped = (
        Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    ).read_text()
    soft = tmp_path / "soft.toml"
    soft.write_text(shipped.replace("54e9", "2e9").replace("20.77e9", "0.77e9"))
    for json_flag in ([], ["--json"]):
        assert main(["check-robot", str(soft), "--samples", "10", *json_flag]) == 0
        out, err = capsys.readouterr()
        assert "equilibrium the mechanics model finds" not in out
        lines = err.splitlines()
        assert len(lines) == 1, err
        assert re.match(
            rf"continuum-mhe: warning: {re.escape(str(soft))}: \d+ of the 10 loads have no "
            r"equilibrium the mechanics model finds \(left out of the report\)",
            lines[0],
        ), lines[0]
        if json_flag:
            assert json.loads(out)["tendon_unsolved"] > 0
    limp = tmp_path / "limp.toml"
    limp.write_text(shipped.replace("54e9", "1e7").replace("20.77e9", "0.385e7"))
    assert main(["check-robot", str(limp), "--samples", "10"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {limp}: the mechanics")
    assert "no equilibrium of this robot at any of 10 loads" in err[0]


def test_tendon_angles_in_radians_are_said(tmp_path: Path) -> None:
    """Tendon angles that all lie within 2 pi and are not whole degrees (radians written
    for degrees: the tendons would sit within 6 degrees of each other) give one
    UnitWarning naming the file; the shipped robot's degrees give none; a robot's only
    tendon at a quarter turn in radians is said, at 1.5 or 90 degrees not."""
    import re
    import warnings

    from continuum_mhe.io.csv_files import UnitWarning
    from continuum_mhe.io.robot_file import read_robot

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    radians = iter(["0", "2.0944", "4.18879", "1.0472", "3.14159", "5.23599"])
    path = tmp_path / "rad.toml"
    path.write_text(
        re.sub(r"angle = \S+", lambda m: f"angle = {next(radians)}", shipped.read_text())
    )
    with pytest.warns(UnitWarning, match=r"rad.toml: the tendons' angles \[0, 2.0944, .*radians\?"):
        read_robot(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_robot(shipped)
    # a robot's only tendon: a quarter turn in radians is said, 1.5 or 90 degrees are not
    text = shipped.read_text()
    first = text.index("[[tendon]]")
    rest = text.index("[[imu]]")
    for angle, said in (("1.5708", True), ("1.5", False), ("90", False)):
        one = tmp_path / f"one_{angle}.toml"
        tendon = text[first : text.index("[[tendon]]", first + 1)]
        one.write_text(
            text[:first] + re.sub(r"angle = \S+", f"angle = {angle}", tendon) + text[rest:]
        )
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            read_robot(one)
        radians = [w for w in got if "radians?" in str(w.message)]
        assert bool(radians) == said, (angle, [str(w.message) for w in got])


@pytest.mark.parametrize(
    ("angles", "said"),
    [
        (["0", "2", "4", "1", "3", "5"], "section 1's end (angles [0, 2, 4], read in degrees) lie "
         "within 4 degrees"),
        (["0", "0", "0", "120", "240", "360"], "section 1's end (angles [0, 0, 0], read in "
         "degrees) lie within 0 degrees"),
        (["0", "120", "240", "60", "66", "66"], "section 2's end (angles [60, 66, 66], read in "
         "degrees) lie within 6 degrees"),
        (["0", "120", "240", "60", "67", "180"], None),
        (["357", "359", "2", "60", "180", "300"], "section 1's end (angles [357, 359, 2], read "
         "in degrees) lie within 5 degrees"),
        (["350", "355", "0", "60", "180", "300"], None),
    ],
)  # fmt: skip
def test_tendons_of_a_section_huddled_at_one_angle_are_said(
    tmp_path: Path, angles: list[str], said: str | None
) -> None:
    """A section's tendons whose angles all lie within 2 pi degrees of each other around
    the backbone (whole radians read as degrees, 0, 2, 4, which the not-whole-degrees
    rule lets pass; or one angle given to every tendon) give one UnitWarning naming the
    file and the section; the smallest arc that holds them counts (357, 359 and 2 span 5
    degrees; 350, 355 and 0 span 10, beyond it)."""
    import re
    import warnings

    from continuum_mhe.io.csv_files import UnitWarning
    from continuum_mhe.io.robot_file import read_robot

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    given = iter(angles)
    path = tmp_path / "huddled.toml"
    path.write_text(re.sub(r"angle = \S+", lambda m: f"angle = {next(given)}", shipped.read_text()))
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        read_robot(path)
    lines = [str(w.message) for w in got if issubclass(w.category, UnitWarning)]
    if said is None:
        assert lines == []
    else:
        assert len(lines) == 1 and lines[0].startswith(f"{path}: the tendons anchored at "), lines
        assert said in lines[0] and lines[0].endswith("radians? (angle = 90 is a quarter turn)")


def test_tensions_in_millinewtons_given_as_arrays_are_refused_by_the_estimator() -> None:
    """The shipped ``force-29`` rows with their tensions 1000 times too large (mN given
    for N), handed to ``run`` as arrays: refused in one UserError naming the time and
    the turns the tensions would bend a section through, as a tensions file is; the
    rows as read run."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.estimators.base import tension_rows

    f, t, z = _raw_shipped(40, "force-29")
    scaled = z.copy()
    scaled[:, tension_rows(f)] *= 1000.0
    with pytest.raises(
        UserError,
        match=r"^the measurements' tensions: at t = [0-9.]+ s the tensions \(.*\) would bend "
        r"section 1 through [0-9.]+ full turns .*: tensions in N \(mN or grams\?\), or the "
        r"robot "
        r"file's \[backbone\] too soft",
    ):
        make_estimator("ekf", f).run(t, scaled)
    assert len(make_estimator("ekf", f).run(t, z).status) == 40


def test_tensions_in_millinewtons_are_refused_by_the_bend_they_would_make(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Tensions a thousand times too large (mN written as N) would bend a section through
    hundreds of turns (the tendons' net moment over the backbone's bending stiffness):
    one line naming the file, the line and its time, exit 2, nothing written. The shipped
    recordings' tensions (up to 2 rad of bend) pass."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.io.tensions import read_tensions

    robot = read_robot("tendon-two-section")
    for name in ("unloaded", "force-29", "twist-29"):
        read_tensions(DATA / f"{name}_tensions.csv", robot.n_tendons).check_scale(robot)
    header, *rows = (
        ln.split(",") for ln in (DATA / "unloaded_tensions.csv").read_text().splitlines()
    )
    mn = tmp_path / "mN.csv"
    write_table(mn, header, [[float(r[0]), *(1000 * float(v) for v in r[1:])] for r in rows])
    out = tmp_path / "e.csv"
    argv = ["estimate", str(DATA / "unloaded_raw.csv"), "--robot", "tendon-two-section",
            "--inputs", str(mn), "-o", str(out)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    said = re.search(rf"{re.escape(str(mn))}: line (\d+): at t = (\S+) s", err[0])
    assert len(err) == 1 and said is not None, err
    line = mn.read_text().splitlines()[int(said.group(1)) - 1]  # the row it names
    assert float(line.split(",")[0]) == pytest.approx(float(said.group(2)))
    assert "would bend section 1 through" in err[0] and not out.exists()
    assert "N m^2): tensions in N (mN or grams?), or the robot file's [backbone] too soft" in err[0]
    # tensions a tendon carries in N, with a modulus given in MPa: the backbone first
    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    mpa = tmp_path / "mpa.toml"
    text = shipped.read_text().replace("youngs_modulus = 54e9", "youngs_modulus = 540000")
    mpa.write_text(text.replace("shear_modulus = 20.77e9", "shear_modulus = 207700"))
    argv = ["estimate", str(DATA / "unloaded_raw.csv"), "--robot", str(mpa),
            "--inputs", str(DATA / "unloaded_tensions.csv"), "-o", str(out)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "would bend section" in err[0] and not out.exists()
    assert (
        "N m^2): the robot file's [backbone] too soft (youngs_modulus 540000 Pa: MPa? 540000 "
        "MPa is 5.4e+11 Pa; radius 0.0007 m), or tensions in N (mN or grams?)?"
    ) in err[0]
    # a modulus ten times too low, in Pa: no unit is the mistake
    ten = tmp_path / "ten.toml"
    text = shipped.read_text().replace("youngs_modulus = 54e9", "youngs_modulus = 5.4e9")
    ten.write_text(text.replace("shear_modulus = 20.77e9", "shear_modulus = 2.077e9"))
    argv[argv.index(str(mpa))] = str(ten)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not out.exists()
    assert "too soft (youngs_modulus 5.4e+09 Pa; radius 0.0007 m)" in err[0]


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("density", "6.45", "density 6.45 kg/m\\^3 is below 100 kg/m\\^3"),
        ("shear_modulus", "5e4", r"shear_modulus 50000.0 Pa is below 100000 Pa: moduli are in "
         r"Pa \(MPa\? 50000 MPa is 5e\+10 Pa\)"),
        ("shear_modulus", "20.77", r"shear_modulus 20.77 Pa .*\(GPa\? 20.77 GPa is "
         r"2.077e\+10 Pa\)"),
        ("shear_modulus", "77000", r"77000.0 Pa .*\(MPa\? 77000 MPa is 7.7e\+10 Pa\)"),
        ("youngs_modulus", "54e15", r"youngs_modulus 5.4e\+16 Pa is above any material's"),
        ("shear_modulus", "60e9", r"shear_modulus 60000000000.0 Pa is above its youngs_modulus "
         r"54000000000.0 Pa: .*\(swapped\?\)"),
    ],
)  # fmt: skip
def test_backbone_values_in_other_units_are_refused(tmp_path: Path, key, value, match) -> None:
    """A density in g/cm^3, a modulus that looks like GPa or MPa (under 1e5 Pa, as the
    docs say: the hint names the unit that makes it a material's), one above diamond's,
    and a shear modulus above Young's are refused in one line naming the file."""
    import re

    from continuum_mhe.io.robot_file import read_robot

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    path = tmp_path / "r.toml"
    path.write_text(re.sub(rf"(?m)^#? ?{key} = \S+", f"{key} = {value}", shipped.read_text()))
    with pytest.raises(InputError, match=match):
        read_robot(path)


def test_a_tendon_inside_the_backbone_is_refused_naming_its_line(tmp_path: Path) -> None:
    """The shipped robot with its backbone's radius (0.7 mm) written as 12 mm, wider
    than the tendons' 10 mm pitch radius: one line naming the robot file, the first
    tendon's ``radius`` line and both radii."""
    from continuum_mhe.io.robot_file import read_robot

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    text = shipped.read_text()
    assert text.count("radius = 0.0007") == 1
    path = tmp_path / "r.toml"
    path.write_text(text.replace("radius = 0.0007", "radius = 0.012"))
    line = next(n for n, ln in enumerate(text.splitlines(), 1) if ln.startswith("radius = 0.01"))
    with pytest.raises(InputError) as info:
        read_robot(path)
    assert str(info.value).startswith(
        f"{path}: line {line}: tendon 1: radius 0.01 m is not outside the backbone's radius 0.012 m"
    ), str(info.value)


def test_a_tensions_file_with_a_separator_at_every_line_end_reads_as_without(
    tmp_path: Path,
) -> None:
    """A comma at the end of every line (the header's too), as some loggers write it:
    no column, as in the measurement files; the same tensions."""
    from continuum_mhe.io.tensions import read_tensions

    path = tmp_path / "trail.csv"
    text = (DATA / "unloaded_tensions.csv").read_text()
    path.write_text("".join(ln + ",\n" for ln in text.splitlines()))
    got, want = read_tensions(path, 6), read_tensions(DATA / "unloaded_tensions.csv", 6)
    np.testing.assert_array_equal(got.t, want.t)
    np.testing.assert_array_equal(got.values, want.values)


def test_a_recording_with_some_of_the_tension_columns_names_the_missing_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording that carries five of the robot's six tension columns: one line naming
    the recording and the missing column (not the robot file), exit 2, nothing written."""
    raw = (DATA / "unloaded_raw.csv").read_text().splitlines()
    ten = (DATA / "unloaded_tensions.csv").read_text().splitlines()
    path = tmp_path / "raw5.csv"
    path.write_text("".join(a + "," + ",".join(b.split(",")[1:6]) + "\n" for a, b in zip(raw, ten)))
    out = tmp_path / "e.csv"
    assert main(["estimate", str(path), "--robot", "tendon-two-section", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {path}: line 1: the robot")
    assert "tension_1,tension_2,tension_3,tension_4,tension_5: no tension_6" in err[0]
    assert not out.exists()


def test_plot_says_when_the_models_backbone_misses_the_estimated_tip(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The figure's backbone is the mechanics model re-solved at each row's tip force and
    the tensions of --inputs (the file holds no state): with the tensions the estimate
    was made with it ends at the estimated tip (no warning); with tensions of another
    recording (here four times as large) it does not, and a warning says by how much."""
    import warnings

    from continuum_mhe.evaluation.estimate_figure import FigureWarning

    meas, tensions = small_robot_recording(tmp_path)
    robot = str(small_robot(tmp_path))
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", robot, "--inputs", str(tensions),
                 "-o", str(est)]) == 0  # fmt: skip
    fig = tmp_path / "f.png"
    argv = ["plot", str(est), "--robot", robot, "-o", str(fig)]
    with warnings.catch_warnings():
        warnings.simplefilter("error", FigureWarning)
        assert main([*argv, "--inputs", str(tensions)]) == 0
    other = tmp_path / "other.csv"
    write_table(other, ["t", "tension_1"], [[0.0, 4.0], [0.1, 6.0]])
    figures_drawn_small(monkeypatch)  # the warning of the figure's making, not its drawing
    with pytest.warns(FigureWarning, match=r"backbone at the estimate's tip force .* ends up to"):
        assert main([*argv, "--inputs", str(other), "--overwrite"]) == 0
    assert fig.exists()


def test_tensions_that_look_like_a_sensor_or_logger_fault_are_said(tmp_path: Path) -> None:
    """A tendon at 0 in every row, tensions repeated exactly for 6 s, and a 2 s or a
    0.4 s hole between rows 0.02 s apart: one TensionsWarning each, naming the file, the tendon or
    the times; the shipped tensions file gives none."""
    import warnings

    from continuum_mhe.io.tensions import TensionsWarning, read_tensions

    source = DATA / "force-29_tensions.csv"
    good = read_tensions(source, 6)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TensionsWarning)
        good.warn_suspect()
    t, v = good.t, good.values
    cases = {
        "zero": (t, np.where(np.arange(6) == 1, 0.0, v)),
        "frozen": (t, np.where((t > 2.0)[:, None], v[np.searchsorted(t, 2.0)], v)),
        "hole": (t[(t < 2.0) | (t > 4.0)], v[(t < 2.0) | (t > 4.0)]),
        "short-hole": (t[(t < 1.61) | (t > 1.99)], v[(t < 1.61) | (t > 1.99)]),
    }
    said = {
        "zero": r"zero.csv: tension_2 is 0 in every row: a sensor not connected",
        "frozen": r"frozen.csv: the tensions repeat exactly from t = 2 to 8 s \(6 s\): a logger",
        "hole": r"hole.csv: no tensions between t = 1\.98 and 4\.02 s \(2\.04 s; the rows are "
        r"0\.02 s apart elsewhere\): interpolated linearly across",
        # 0.4 s: the estimate would stay off after it where the tensions curve there
        "short-hole": r"short-hole.csv: no tensions between t = 1\.6 and 2 s \(0\.4 s; .*: "
        r"interpolated linearly across; where the tensions do not change linearly there, "
        r"the estimate may stay off",
    }
    for name, (tc, vc) in cases.items():
        path = tmp_path / f"{name}.csv"
        write_table(path, ["t", *(f"tension_{j}" for j in range(1, 7))],
                    np.column_stack([tc, vc]).tolist())  # fmt: skip
        with pytest.warns(TensionsWarning, match=said[name]) as caught:
            read_tensions(path, 6).warn_suspect()
        assert len([w for w in caught if issubclass(w.category, TensionsWarning)]) == 1


def test_bends_past_a_tendon_robots_theta_max_are_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], force29_estimate: tuple[Path, str]
) -> None:
    """The mechanics model does not bound a tendon robot's bends: where its estimates
    bend a section past the robot file's theta_max, estimate says how many and how far
    (the file's bound or the inputs contradict the estimate; ``force-29``'s first 100
    samples); with the shipped bound it says nothing (the whole of ``force-29``, the
    module's run)."""
    text = (ROBOTS / "tendon_two_section.toml").read_text()
    assert text.count("theta_max = 3.0") == 2
    tight = tmp_path / "tight.toml"
    tight.write_text(text.replace("theta_max = 3.0", "theta_max = 0.3"))
    meas = tmp_path / "m.csv"
    meas.write_text("\n".join((DATA / "force-29_raw.csv").read_text().splitlines()[:101]) + "\n")
    args = ["--inputs", str(DATA / "force-29_tensions.csv"), "--method", "ekf"]
    capsys.readouterr()
    assert main(["estimate", str(meas), "--robot", str(tight), *args,
                 "-o", str(tmp_path / "t.csv")]) == 0  # fmt: skip
    said = [ln for ln in capsys.readouterr().err.splitlines() if "theta_max" in ln]
    assert len(said) == 1 and re.match(
        r"continuum-mhe: warning: \d+ of 100 estimates bend past the robot file's "
        r"theta_max: section 1 up to 0\.\d+ rad \(theta_max 0\.3\)",
        said[0],
    ), said
    _, shipped_said = force29_estimate  # the shipped robot file (theta_max 3.0)
    assert [ln for ln in shipped_said.splitlines() if "theta_max" in ln] == []


def test_the_bend_past_theta_max_tally_reads_a_one_section_tendon_robots_columns(
    tmp_path: Path,
) -> None:
    """A one-section tendon robot names its bend theta_1: the tally finds it, counts the
    rows past theta_max (NaN rows without an estimate left out) and says how far;
    a PCC robot, whose bound the estimator keeps, is not tallied."""
    from continuum_mhe.estimators.run_notices import BendsBeyondBound
    from continuum_mhe.model.registry import make_formulation

    f = TendonFormulation(robot=read_robot(small_robot(tmp_path)))
    names = [o.name for o in f.outputs]
    assert "theta_1" in names and "theta" not in names
    bound = f.robot.sections[0].theta_max
    rows = np.zeros((4, f.ny))
    rows[:, names.index("theta_1")] = [0.5 * bound, bound + 0.2, np.nan, bound + 0.1]
    rows[2] = np.nan
    tally = BendsBeyondBound(f)
    tally.add(rows)
    assert tally.active and tally.count == 2
    note = tally.notice(4)
    assert note is not None and note.startswith(
        f"2 of 4 estimates bend past the robot file's theta_max: section 1 up to "
        f"{bound + 0.2:.3g} rad (theta_max {bound:.4g})"
    )
    assert not BendsBeyondBound(make_formulation("bend")).active


def test_tensions_logged_fast_give_the_derivatives_of_the_same_tensions_at_50_hz(
    tmp_path: Path,
) -> None:
    """The shipped 50 Hz tensions interpolated linearly to a 1 kHz log: their rates and
    accelerations at the measurements' times are those of the 50 Hz file (within 1 %
    and 4 % of the largest; differences over a millisecond would turn the corners of the
    interpolation into accelerations ten times the largest), and the 50 Hz file itself
    keeps its rows' central differences."""
    from continuum_mhe.io.tensions import read_tensions

    coarse = read_tensions(DATA / "force-29_tensions.csv", 6)
    t = np.arange(coarse.t[0], coarse.t[-1] + 1e-9, 0.001)
    fast_values = np.column_stack([np.interp(t, coarse.t, v) for v in coarse.values.T])
    path = tmp_path / "fast.csv"
    write_table(path, ["t", *(f"tension_{j}" for j in range(1, 7))],
                np.column_stack([t, fast_values]).tolist())  # fmt: skip
    fast = read_tensions(path, 6)
    at = coarse.t[5:-5]
    for k, tol in ((1, 0.01), (2, 0.04)):  # rates, accelerations
        want = np.array([coarse.at(x)[k] for x in at])
        got = np.array([fast.at(x)[k] for x in at])
        assert np.abs(got - want).max() <= tol * np.abs(want).max()
    # the rows' central differences: numpy's (the same formulas, other rounding)
    rates = np.gradient(coarse.values, coarse.t, axis=0)
    np.testing.assert_allclose(coarse.rates, rates, rtol=1e-9, atol=1e-12)
    accelerations = np.gradient(rates, coarse.t, axis=0)
    np.testing.assert_allclose(coarse.accelerations, accelerations, rtol=1e-9, atol=1e-9)


def test_a_recordings_own_tensions_are_differenced_row_by_row_as_live_does(
    tmp_path: Path,
) -> None:
    """The tension columns ``live --record`` writes beside the IMUs' are differenced row
    by row, as live's stream differenced them (a replay gives live's estimates), even at
    100 Hz; the same tensions as a file of their own are averaged into 20 ms bins."""
    from continuum_mhe.io.tensions import read_tensions

    t = np.arange(0.0, 2.0, 0.01)
    values = np.column_stack([1.0 + 0.3 * np.sin(3 * t), 0.5 + 0.1 * t])
    recording, own = tmp_path / "rec.csv", tmp_path / "own.csv"
    write_table(recording, ["t", "roll", "pitch", "tension_1", "tension_2"],
                np.column_stack([t, 0 * t, 0 * t, values]).tolist())  # fmt: skip
    write_table(own, ["t", "tension_1", "tension_2"], np.column_stack([t, values]).tolist())
    replayed = read_tensions(recording, 2, other_columns=True)
    rates = np.gradient(replayed.values, replayed.t, axis=0)  # row by row: numpy's
    np.testing.assert_allclose(replayed.rates, rates, rtol=1e-9, atol=1e-12)
    accelerations = np.gradient(rates, replayed.t, axis=0)
    np.testing.assert_allclose(replayed.accelerations, accelerations, rtol=1e-9, atol=1e-9)
    assert not np.array_equal(read_tensions(own, 2).accelerations, replayed.accelerations)


def test_tensions_far_apart_that_are_not_linear_are_said() -> None:
    """The shipped tensions kept one row a second (beside samples 0.02 s apart): a
    TensionsWarning that they are taken as linear between rows; the file itself, and a
    ramp given by three rows, get none."""
    from continuum_mhe.io.tensions import Tensions, TensionsWarning, read_tensions

    full = read_tensions(DATA / "force-29_tensions.csv", 6)
    keep = np.arange(0, len(full.t), 50)
    sparse = Tensions.from_rows(full.name, full.t[keep], full.values[keep])
    with pytest.warns(TensionsWarning, match=r"its rows are 1 s apart, the samples of rec "
                      r"0\.02 s: between rows the tensions are taken as linear"):  # fmt: skip
        sparse.warn_sparse(0.02, "rec")
    t = np.array([0.0, 5.0, 10.0])
    ramp = np.column_stack([1.0 + 0.1 * t, 0.5 + 0 * t])
    with warnings.catch_warnings():
        warnings.simplefilter("error", TensionsWarning)
        full.warn_sparse(0.02, "rec")
        Tensions.from_rows("ramp.csv", t, ramp).warn_sparse(0.02, "rec")


def test_tensions_in_kgf_for_n_are_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], force29_estimate: tuple[Path, str]
) -> None:
    """Tensions given in kgf for N (``force-29``, its first 300 samples): the IMUs'
    error states make up for them, and estimate says at the end that the rows drifted
    and to check the tensions' unit; the tensions in N give no such line (the whole of
    ``force-29``, the module's run)."""
    meas = tmp_path / "m.csv"
    meas.write_text("\n".join((DATA / "force-29_raw.csv").read_text().splitlines()[:301]) + "\n")
    tensions = read_tensions(DATA / "force-29_tensions.csv", 6)
    kgf = tmp_path / "kgf.csv"
    write_table(kgf, ["t", *(f"tension_{j}" for j in range(1, 7))],
                np.column_stack([tensions.t, tensions.values / 9.80665]).tolist())  # fmt: skip
    capsys.readouterr()
    assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                 str(kgf), "--method", "ekf", "-o", str(tmp_path / "k.csv")]) == 0  # fmt: skip
    said = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    # (the first reading, read with them, shows a load too) where the estimated tip force
    # passes the largest tension (0.35 N against 0.31 N on some processors, below it on
    # others: the drifted rows' estimates differ in their rounding), a line before them
    # names kgf as well
    force = [ln for ln in said if "the estimated tip force reached" in ln]
    assert all("kgf for N?" in ln for ln in force), force
    rest = [ln for ln in said if ln not in force]
    assert len(rest) == 2 and re.match(
        r"continuum-mhe: warning: \d+ of 300 estimates drifted: .*check the tensions "
        r"\(their scale, unit, tendon order and timing",
        rest[0],
    ), said
    assert "or tensions that do not act as given" in rest[1]
    assert "check the tensions (their scale, unit" in rest[1]
    _, in_n_said = force29_estimate
    assert [ln for ln in in_n_said.splitlines() if "warning" in ln] == []


def test_a_tip_force_beyond_every_tension_is_said() -> None:
    """The end's line where the tip force went beyond every tension given (a load that
    large, or tensions in another unit): counted over blocks, rows without an estimate
    (NaN) skipped; none at or below the largest tension, or below 0.05 N."""
    from continuum_mhe.estimators.run_notices import ForceBeyondTensions

    f, _, z = _raw_shipped(3)
    names = [o.name for o in f.outputs]
    force = [names.index(c) for c in ("fx", "fy", "fz")]
    rows = [i for i, name in enumerate(f.measurement_names) if name.startswith("tension_")]

    def block(tension: float, fz: float) -> tuple[np.ndarray, np.ndarray]:
        zb = z.copy()
        zb[:, rows] = 0.0
        zb[0, rows[2]] = tension
        out = np.zeros((len(z), len(names)))
        out[1, force[2]] = fz
        out[2] = np.nan
        return zb, out

    tally = ForceBeyondTensions(f)
    tally.add(*block(0.3, 0.2))
    assert tally.notice() is None  # within the largest tension
    tally.add(*block(0.1, 0.31))
    assert tally.notice() == (
        "the estimated tip force reached 0.31 N, beyond the largest tendon tension given "
        "(0.3 N): a load that large, or tensions in another unit (kgf for N?) or order "
        "that the tip force makes up for; check them"
    )
    small = ForceBeyondTensions(f)
    small.add(*block(0.01, 0.04))
    assert small.notice() is None  # under 0.05 N
    slack = ForceBeyondTensions(f)  # every tension 0 N: no unit or order to blame
    slack.add(*block(0.0, 0.31))
    assert slack.notice() == (
        "the estimated tip force reached 0.31 N with every tendon tension given 0 N "
        "(slack all along, or not logged?): a load that large, or a push along a nearly "
        "straight backbone, which the IMUs barely see (a still robot)"
    )


def test_a_sample_without_a_tension_is_a_dropout_as_a_whole() -> None:
    """A missing (NaN) tension or tension rate makes its sample a dropout as a whole:
    the model of the IMUs' readings needs the tensions, so the IMUs' readings of that
    sample are not used either (its row says `dropout`), in ``run`` and ``step``
    alike, and the estimates after it stay those of the recording without the gap."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.results import Measurement

    f, t, z = _raw_shipped(150)
    clean = make_estimator("ekf", f).run(t, z)
    rows = [i for i, name in enumerate(f.measurement_names) if name.startswith("tension_")]
    holed = z.copy()
    holed[100, rows[1]] = np.nan
    est = make_estimator("ekf", f)
    got = est.run(t, holed)
    assert got.status[100] == "dropout"
    assert np.all(np.isfinite(holed[100, : rows[0]]))  # the IMUs' readings were there
    tip = [[o.name for o in f.outputs].index(c) for c in ("x", "y", "z")]
    apart = np.linalg.norm(got.output[101:, tip] - clean.output[101:, tip], axis=1)
    assert apart.max() < 0.002  # m
    est.reset()
    stepped = [est.step(Measurement(float(tk), zk)) for tk, zk in zip(t, holed)]
    assert stepped[100].status == "dropout"
    np.testing.assert_array_equal(np.array([e.output for e in stepped]), got.output)


def test_load_input_reads_a_tendon_robot_with_its_tensions_as_open_input_does() -> None:
    """``load_input`` reads a tendon robot's recording with its tensions file into the
    mechanics model's measurements, the same as ``open_input``'s stream, and without
    tensions refuses it in the command line's words."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.model.registry import make_formulation

    base = make_formulation("bend", read_robot("tendon-two-section"))
    got = load_input(
        DATA / "unloaded_raw.csv", InputOptions(tensions=str(DATA / "unloaded_tensions.csv")), base
    )
    f, t, z = _raw_shipped(401)
    assert got.formulation == f
    np.testing.assert_array_equal(got.t, t)
    np.testing.assert_array_equal(got.z, z)
    with pytest.raises(InputError, match=r"the robot has 6 tendons: give their tensions"):
        load_input(DATA / "unloaded_raw.csv", InputOptions(), base)


def test_measurement_row_refuses_parts_of_the_wrong_size() -> None:
    """``measurement_row`` names the part that does not fit the robot, also where seven
    tensions with five rates would make a ``z`` of the right length."""
    from continuum_mhe.model.registry import make_formulation

    f = make_formulation("tendon", read_robot("tendon-two-section"), imu_model="direct")
    imu, k = np.zeros(f.n_imu_measurements), f.robot.n_tendons
    assert f.measurement_row(imu, np.ones(k), np.zeros(k)).shape == (f.nz,)
    with pytest.raises(UserError, match=r"tensions must have shape \(6,\).*got \(7,\)"):
        f.measurement_row(imu, np.ones(k + 1), np.zeros(k - 1))
    with pytest.raises(UserError, match=r"tensions must have shape \(6,\).*got \(1, 6\)"):
        f.measurement_row(imu, np.ones((1, k)), np.zeros(k))


def test_the_tension_gains_are_the_last_states_and_scale_the_tensions_given() -> None:
    """One gain per section with tendons, after every other state (the fixed offsets of
    the other states stay); the tension residual is ``gain * given - tau`` and the given
    rates and their rates enter the IMUs' model times the gain: a gain ``g`` with the
    given tensions predicts what gain 1 does with ``g`` times them. Prior 1, positive
    bound, a random walk, and an output column each."""
    robot = read_robot("tendon-two-section")
    off = TendonFormulation(robot=robot, imu_model="direct", estimate_gyro_bias=True)
    f = replace(off, estimate_tension_gain=True)
    assert len(f.state_names) == f.nx == off.nx + 2
    assert f.state_names[: off.nx] == off.state_names
    assert f.state_names[-2:] == ("tension_gain_1", "tension_gain_2")
    assert f.tension_gain_start == off.nx
    # a robot whose tendons all end at its second section: one gain, that section's
    second = replace(robot, tendons=tuple(replace(t, section=1) for t in robot.tendons))
    assert TendonFormulation(robot=second, estimate_tension_gain=True).state_names[-1:] == (
        "tension_gain_2",
    )
    g = slice(f.nx - 2, f.nx)
    tau = np.array([2.0, 0.5, 0.0, 0.0, 1.5, 0.3])
    rates, accel = np.array([0.3, -0.2, 0.1, 0.0, 0.4, -0.1]), np.full(6, 0.2)
    imu = np.zeros(f.n_imu_measurements)
    z = f.measurement_row(imu, tau, rates, accel)
    x0 = f.initial_state(z)
    np.testing.assert_array_equal(x0[g], 1.0)
    np.testing.assert_allclose(np.sqrt(np.diag(f.initial_cov())[g]), 0.3)
    q = np.asarray(ca.Function("q", [dt := ca.SX.sym("dt")], [f.process_cov_sym(dt)])(0.02))
    np.testing.assert_allclose(np.diag(q)[g], f.tension_gain_psd * 0.02)
    lo, hi = f.state_bounds()
    assert np.all(lo[g] > 0) and np.isinf(lo[: f.nx - 2]).all() and np.isinf(hi).all()
    assert [o.name for o in f.outputs][-2:] == ["tension_gain_1", "tension_gain_2"]
    gains = np.array([1.3, 0.8])
    x = x0.copy()
    x[g] = gains
    scale = np.repeat(gains, 3)  # tendons 1-3 end at section 1, 4-6 at section 2
    np.testing.assert_allclose(f.output(x)[-2:], gains)
    r = np.asarray(f.functions.innovate(z, x)[0], float).ravel()
    n = f.n_imu_measurements
    np.testing.assert_allclose(r[n : n + 6], scale * tau - x[6:12], atol=1e-12)
    x1 = x.copy()
    x1[g] = 1.0
    z1 = f.measurement_row(imu, tau, scale * rates, scale * accel)
    r1 = np.asarray(f.functions.innovate(z1, x1)[0], float).ravel()
    np.testing.assert_allclose(r[:n], r1[:n], atol=1e-9)
    assert (
        np.abs(r[:n] - np.asarray(f.functions.innovate(z, x1)[0], float).ravel()[:n]).max() > 1e-4
    )
    assert f.is_diverged(np.where(np.arange(f.nx) == f.nx - 1, -0.1, x))


def _unloaded_with_scaled_tensions(tmp_path: Path, rows: int, scale: float) -> tuple[Path, Path]:
    """``(readings, tensions)``: the first ``rows - 1`` samples of ``unloaded`` (raw IMUs)
    and its tensions file with every tension times ``scale``."""
    meas, scaled = tmp_path / "m.csv", tmp_path / f"tensions_x{scale:g}.csv"
    meas.write_text("\n".join((DATA / "unloaded_raw.csv").read_text().splitlines()[:rows]) + "\n")
    given = read_tensions(DATA / "unloaded_tensions.csv", 6)
    write_table(scaled, ["t", *(f"tension_{j}" for j in range(1, 7))],
                np.column_stack([given.t, scale * given.values]).tolist())  # fmt: skip
    return meas, scaled


def test_the_tension_gain_finds_tensions_given_too_large_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Tensions given 1.2 times those acting (a tension sensor's gain): with
    ``--estimate-tension-gain`` both sections' gains end near 1 / 1.2 (acting over
    given), the tip follows the truth, and estimate says that the gains ended far from
    1; with the right tensions they end near 1 and nothing is said."""
    rows = 301
    meas, scaled = _unloaded_with_scaled_tensions(tmp_path, rows, 1.2)
    truth = read_state_table(DATA / "unloaded_truth.csv")
    for given, out, acting in (
        (scaled, "s.csv", 1 / 1.2),
        (DATA / "unloaded_tensions.csv", "n.csv", 1.0),
    ):
        capsys.readouterr()
        argv = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(given)]
        assert main([*argv, "--estimate-tension-gain", "-o", str(tmp_path / out)]) == 0
        said = [ln for ln in capsys.readouterr().err.splitlines() if "tension gains" in ln]
        est = read_state_table(tmp_path / out)
        gains = [est.column(f"tension_gain_{s}")[-1] for s in (1, 2)]
        np.testing.assert_allclose(gains, acting, atol=0.02)
        tip = np.linalg.norm(
            np.column_stack([est.column(c) - truth.column(c)[: rows - 1] for c in "xyz"]), axis=1
        )
        assert np.mean(tip[50:]) < 3e-3
        if acting != 1.0:
            assert len(said) == 1 and said[0].startswith(
                "continuum-mhe: warning: the estimated tension gains ended more than 3 "
                "standard deviations from 1 (section 1: 0.83"
            ), said
        else:
            assert said == []
    # the figure and the view draw the backbone at the acting tensions (the gains times
    # those given): it ends at the estimated tip; at the given ones it would not
    import warnings

    from continuum_mhe.evaluation.estimate_figure import FigureWarning
    from continuum_mhe.viewer.geometry import TendonShapes

    plot = ["plot", str(tmp_path / "s.csv"), "--robot", "tendon-two-section"]
    with warnings.catch_warnings(), pytest.MonkeyPatch.context() as m:
        warnings.simplefilter("error", FigureWarning)
        figures_drawn_small(m)  # the figure's making and its warning, not its drawing
        assert main([*plot, "--inputs", str(scaled), "-o", str(tmp_path / "s.png")]) == 0
    est = read_state_table(tmp_path / "s.csv")
    rows_drawn = np.arange(100, rows - 1, 50)
    values = np.column_stack([est.column(c) for c in est.names])[rows_drawn]
    forces = values[:, [est.names.index(c) for c in ("fx", "fy", "fz")]]
    tips = values[:, [est.names.index(c) for c in "xyz"]]
    shapes = TendonShapes(read_robot("tendon-two-section"), tensions=read_tensions(scaled, 6))
    t = est.t[rows_drawn]
    acting = shapes.solved_forces(t, forces, est.names, values)[0].tip
    given = shapes.solved_forces(t, forces)[0].tip
    assert np.max(np.linalg.norm(acting - tips, axis=1)) < 1e-3
    assert np.max(np.linalg.norm(given - tips, axis=1)) > 10e-3


def test_the_tension_gain_is_refused_for_a_robot_without_tendons(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--estimate-tension-gain`` on a robot without tendons: one line, exit 2, nothing
    written; from an options file, named by its file and line; in the library, by
    ``InputOptions``."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.model.registry import make_formulation

    meas = tmp_path / "m.csv"
    meas.write_text("t,roll_1,pitch_1\n0,0,0\n0.02,0,0\n")
    argv = ["estimate", str(meas), "-o", str(tmp_path / "e.csv")]
    assert main([*argv, "--estimate-tension-gain"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        "continuum-mhe: error: --estimate-tension-gain does not apply: it is for a tendon "
        "robot (a robot file with [[tendon]] entries and a [backbone]), and this robot has "
        "no tendons"
    ), err
    cfg = tmp_path / "opts.toml"
    cfg.write_text("estimate-tension-gain = true\n")
    assert main([*argv, "--robot", "two-section", "--config", str(cfg)]) == 2
    assert (
        f"error: {cfg}: line 1: estimate-tension-gain = True does not apply: it is for a "
        "tendon robot"
    ) in capsys.readouterr().err
    assert not (tmp_path / "e.csv").exists()
    with pytest.raises(UserError, match="--estimate-tension-gain does not apply"):
        load_input(meas, InputOptions(estimate_tension_gain=True), make_formulation("bend"))


def test_the_tension_gain_warning_keeps_what_the_readings_showed_before_a_restart() -> None:
    """Gains that ended far from 1 (0.83, std 0.01), then a restart's rows at the prior
    (1, std 0.3): the warning says the informed gains; rows at the prior alone say
    nothing."""
    from continuum_mhe.estimators.run_notices import TensionGainFromOne

    f = TendonFormulation(robot=read_robot("tendon-two-section"), estimate_tension_gain=True)
    cols = [i for i, o in enumerate(f.outputs) if o.name.startswith("tension_gain_")]

    def block(gain: float, std: float) -> tuple[np.ndarray, np.ndarray]:
        out, sd = np.zeros((3, f.ny)), np.full((3, f.ny), 1e-3)
        out[:, cols], sd[:, cols] = gain, std
        return out, sd

    said = TensionGainFromOne(f)
    said.add(*block(0.83, 0.01))
    said.add(*block(1.0, 0.3))
    note = said.notice()
    assert note is not None and "(section 1: 0.83 (std 0.01); section 2: 0.83" in note
    prior_only = TensionGainFromOne(f)
    prior_only.add(*block(1.0, 0.3))
    assert prior_only.notice() is None


def test_the_tension_gain_warning_says_when_the_sections_disagree() -> None:
    """Gains far from 1 that agree (0.83 and 0.83, a scale error) are said as the
    tensions given not acting; gains that disagree beyond their standard deviations
    (1.95 and 1.54, std 0.01: what tensions in kgf for N end at) are said as not to be
    trusted too."""
    from continuum_mhe.estimators.run_notices import TensionGainFromOne

    f = TendonFormulation(robot=read_robot("tendon-two-section"), estimate_tension_gain=True)
    cols = [i for i, o in enumerate(f.outputs) if o.name.startswith("tension_gain_")]
    notes = []
    for gains in ((0.83, 0.834), (1.95, 1.54)):
        out, sd = np.zeros((1, f.ny)), np.full((1, f.ny), 1e-3)
        out[0, cols], sd[0, cols] = gains, 0.01
        said = TensionGainFromOne(f)
        said.add(out, sd)
        notes.append(said.notice())
    agree, disagree = notes
    assert agree is not None and "the tensions given are not those acting" in agree
    assert "disagree" not in agree
    assert disagree is not None and disagree.endswith(
        "the gains, and the estimates, are not to be trusted"
    )


def test_the_tension_gain_with_tilt_imus_is_warned() -> None:
    """``--estimate-tension-gain`` with tilt readings: one OptionWarning that it
    misleads there and that raw IMUs take it; with raw readings none."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.tensions import tendon_formulation_for
    from continuum_mhe.model.registry import make_formulation

    robot = read_robot("tendon-two-section")
    options = InputOptions(estimate_tension_gain=True)
    with pytest.warns(OptionWarning, match=r"with tilt IMUs: .* raw IMUs \(accelerometer"):
        tilt = tendon_formulation_for(make_formulation("bend", robot), options)
    assert tilt.estimate_tension_gain and tilt.imu_model == "tilt"
    with warnings.catch_warnings():
        warnings.simplefilter("error", OptionWarning)
        raw = tendon_formulation_for(make_formulation("direct", robot), options)
    assert raw.estimate_tension_gain and raw.imu_model == "direct"


def test_tensions_the_robot_does_not_feel_make_rows_drifted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The first 200 samples of ``unloaded`` (raw IMUs): with its own tensions no row is
    ``drifted`` and no warning names the IMUs' error states; with twice those tensions
    (tensions in another unit) the IMU error states leave their prior, the rows are
    ``drifted``, no ``ok`` row is more than 20 mm off, and a warning names the tensions."""
    rows = 201
    meas, doubled = _unloaded_with_scaled_tensions(tmp_path, rows, 2.0)
    truth = read_state_table(DATA / "unloaded_truth.csv")
    for tensions, out in ((DATA / "unloaded_tensions.csv", "own.csv"), (doubled, "x2.csv")):
        argv = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(tensions)]
        capsys.readouterr()
        assert main([*argv, "-o", str(tmp_path / out)]) == 0
        said = [ln for ln in capsys.readouterr().err.splitlines() if "estimates drifted" in ln]
        est = read_state_table(tmp_path / out)
        tip = np.linalg.norm(
            np.column_stack([est.column(c) - truth.column(c)[: rows - 1] for c in "xyz"]), axis=1
        )
        drifted = est.status == "drifted"
        if out == "own.csv":
            assert not drifted.any() and said == []
        else:
            assert drifted.sum() > 100
            assert not np.any((est.status == "ok") & (tip > 20e-3))
            assert len(said) == 1 and said[0].startswith(
                f"continuum-mhe: warning: {drifted.sum()} of 200 estimates drifted: the IMUs' "
                "error states left their prior"
            ), said
            assert "check the tensions (their scale, unit, tendon order and timing" in said[0]
            assert "with tilt IMUs" not in said[0]  # raw IMUs


def test_tensions_no_restart_fits_stop_the_restarts_after_three_in_a_row(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The first 200 samples of ``unloaded`` (raw IMUs) with the sections' tendons
    swapped in the tensions file: the readings contradict every restart from them, and
    each restart is a fit of the start. The estimator restarts three times in a row,
    then stops (without the limit: 79 restarts, each such a fit), says so, and the rows
    are not ``ok`` far off: ``drifted`` (the drift reset restarts them once more from
    the last ok estimate's IMU errors, which does not count in the chain). The limit is
    the tendon model's; a PCC robot restarts on (``test_bad_start``)."""
    rows = 201
    meas = tmp_path / "m.csv"
    meas.write_text("\n".join((DATA / "unloaded_raw.csv").read_text().splitlines()[:rows]) + "\n")
    given = read_tensions(DATA / "unloaded_tensions.csv", 6)
    swapped = tmp_path / "swapped.csv"
    other_order = given.values[:, [3, 4, 5, 0, 1, 2]]
    write_table(swapped, ["t", *(f"tension_{j}" for j in range(1, 7))],
                np.column_stack([given.t, other_order]).tolist())  # fmt: skip
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(swapped)]
    capsys.readouterr()
    assert main([*argv, "-o", str(out)]) == 0
    said = capsys.readouterr()
    wrote = [ln for ln in (said.out + said.err).splitlines() if ln.startswith("wrote")]
    assert len(wrote) == 1
    assert "restarted 3 time(s) after readings inconsistent with the start" in wrote[0]
    assert (
        "stopped restarting 1 time(s) after 3 restarts in a row that the readings "
        "contradicted too: the model does not fit them (check the robot file and the inputs)"
    ) in wrote[0]
    est = read_state_table(out)
    truth = read_state_table(DATA / "unloaded_truth.csv")
    tip = np.linalg.norm(
        np.column_stack([est.column(c) - truth.column(c)[: rows - 1] for c in "xyz"]), axis=1
    )
    # the three the readings forced, and one from the last ok estimate's IMU errors
    # after half a second of drifted rows (which the readings contradict too)
    assert np.count_nonzero(est.status == "reset") == 4
    assert "restarted 1 time(s) from the last ok estimate's IMU errors" in wrote[0]
    assert np.count_nonzero(est.status == "drifted") > 150
    assert not np.any((est.status == "ok") & (tip > 20e-3))
    assert TendonFormulation.bad_start_chain == 3
    from continuum_mhe.model.registry import make_formulation

    assert make_formulation("bend").bad_start_chain is None


def test_the_imu_error_test_is_the_chi_square_of_the_states_against_their_prior() -> None:
    """``drifted``: the IMU error states (gyro biases, misalignments, accelerometer
    biases; 18 with raw IMUs) in prior standard deviations, against the chi-square 99.9 %
    quantile of 18 degrees of freedom (42.31): just inside, not drifted; just outside,
    drifted; the other states (the tip force) do not count."""
    from continuum_mhe.model.registry import make_formulation

    f = make_formulation("tendon", read_robot("tendon-two-section"), imu_model="direct")
    names = f.state_names
    idx = [i for i, n in enumerate(names) if n.startswith(("bg", "mis", "ba"))]
    assert len(idx) == 18
    std = np.sqrt(np.diag(f.initial_cov()))
    x = np.zeros(f.nx)
    x[names.index("fx")] = 100.0  # not an IMU error state
    for d2, drifted in ((42.2, False), (42.4, True)):
        x[idx] = std[idx] * np.sqrt(d2 / 18)
        assert f.drifted(x) is drifted


@pytest.mark.parametrize(
    ("written", "warned"), [("4.712", True), ("1.5708", True), ("5.5", True), ("2.5", False)]
)
def test_one_tendon_angle_in_radians_among_degrees_is_said(
    tmp_path: Path, written: str, warned: bool
) -> None:
    """One tendon's angle written in radians among the others' degrees (the shipped robot
    file with its third tendon's angle replaced): where it lies within 0.3 degrees of a
    multiple of 15 degrees read as radians (4.712 rad is 269.98 degrees, 5.5 rad 315.1),
    a UnitWarning names the tendon and the angle it would be; 2.5 (143.2 degrees read
    as radians) gets none."""
    import warnings

    from continuum_mhe.io.csv_files import UnitWarning
    from continuum_mhe.io.robot_file import read_robot

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    text = shipped.read_text()
    third = [m.start() for m in re.finditer(r"angle = \S+", text)][2]
    end = text.index("\n", third)
    path = tmp_path / "one.toml"
    path.write_text(text[:third] + f"angle = {written}" + text[end:])
    said = rf"one.toml: tendon 3: angle = {written} is read in degrees, beside other tendons'"
    if warned:
        with pytest.warns(UnitWarning, match=said + r" angles beyond 2 pi: radians\?"):
            read_robot(path)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("error", UnitWarning)
            read_robot(path)


def test_drifted_rows_of_an_imu_mounted_otherwise_than_declared_name_the_mounting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped robot file with its tip IMU declared turned by 90 degrees about the
    backbone (``mount_rpy = [0, 0, 90]``), on ``force-29`` with its own tensions: most
    rows drift, and the warning's list of what to check in the robot file names the
    IMUs' mountings (``mount_rpy``), the entry that is wrong, not their places alone."""
    shipped = (ROBOTS / "tendon_two_section.toml").read_text()
    assert shipped.rstrip().endswith("[[imu]]\nsection = 2")
    turned = tmp_path / "turned.toml"
    turned.write_text(shipped.rstrip() + "\nmount_rpy = [0, 0, 90]\n")
    argv = ["estimate", str(DATA / "force-29_raw.csv"), "--robot", str(turned), "--inputs",
            str(DATA / "force-29_tensions.csv"), "-o", str(tmp_path / "e.csv")]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 0
    status = [str(s) for s in read_state_table(tmp_path / "e.csv").status]
    assert status.count("drifted") > len(status) // 2
    said = [ln for ln in capsys.readouterr().err.splitlines() if "estimates drifted" in ln]
    assert len(said) == 1
    assert "the robot file: the IMUs' places and mountings (mount_rpy), the backbone" in said[0]


def test_drifted_rows_with_tilt_imus_say_that_tilt_does_not_follow_a_twisting_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``twist-29`` with tilt IMUs and its own tensions: rows drift although the inputs
    are right, and the warning, beside what to check, says that tilt IMUs do not follow
    a loaded robot that twists (raw IMUs do)."""
    given = DATA / "twist-29_tensions.csv"
    argv = ["estimate", str(DATA / "twist-29_tilt.csv"), "--robot", "tendon-two-section",
            "--inputs", str(given), "-o", str(tmp_path / "e.csv")]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "estimates drifted" in ln]
    assert len(said) == 1
    # the shipped robot has spacer disks and continuous tendons: their path is named too
    assert ("the robot file: the IMUs' places and mountings (mount_rpy), the backbone, the "
            "tendons' path (tendon_route "
            '= "disks" where they run straight between spacer disks)); or the tip force'
            in said[0])  # fmt: skip
    assert said[0].endswith(
        "presses on something); with tilt IMUs a loaded robot that twists is not followed "
        "with the right inputs either (raw IMUs are: docs/tendon.md, Limits)"
    )


def test_tension_columns_are_taken_by_name_in_any_order(tmp_path: Path) -> None:
    """A tensions file whose columns come in another order (``t,tension_6,...``) gives
    the tensions of the file in the robot file's order, value for value."""
    from continuum_mhe.io.tensions import read_tensions

    rng = np.random.default_rng(2)
    t = np.arange(6) * 0.1
    values = rng.uniform(0.0, 2.0, (6, 3))
    ordered, shuffled = tmp_path / "a.csv", tmp_path / "b.csv"
    write_text_table(ordered, ["t", "tension_1", "tension_2", "tension_3"],
                      np.column_stack([t, values]).tolist())  # fmt: skip
    write_text_table(shuffled, ["t", "tension_3", "tension_1", "tension_2"],
                      np.column_stack([t, values[:, [2, 0, 1]]]).tolist())  # fmt: skip
    a, b = read_tensions(ordered, 3), read_tensions(shuffled, 3)
    np.testing.assert_array_equal(b.values, a.values)
    np.testing.assert_array_equal(b.values, values)


OTHER_ROBOT = Path(__file__).parent / "data" / "tendon_other_robot"


def test_rows_after_a_restart_of_a_model_that_did_not_follow_are_not_ok(tmp_path: Path) -> None:
    """A robot unlike the shipped one (``tests/data/tendon_other_robot``: steel, 0.25 +
    0.15 m, four tendons a section; its ``unloaded`` made by ``continuum-mhe rod tendon
    --scenario unloaded --duration 8 --robot robot.toml``, seed 0), estimated with its
    sections' lengths swapped: the rows are ``drifted``. The single EKF (the robot loaded,
    without the free-of-load hypothesis) restarts on readings that contradict it; a restart
    clears the IMU error states whose change shows the model error, so the rows after it
    would look ``ok`` (two, 20 to 24 mm off, 18 of their standard deviations); within the
    probation time of the last drifted row they are not trusted."""
    from continuum_mhe.estimators.kalman import ExtendedKalmanFilter
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.model.registry import make_formulation

    text = (OTHER_ROBOT / "robot.toml").read_text()
    swapped = tmp_path / "swapped.toml"
    swapped.write_text(
        text.replace("length = 0.25", "length = X").replace("length = 0.15", "length = 0.25")
        .replace("length = X", "length = 0.15")
    )  # fmt: skip
    out = tmp_path / "e.csv"
    recording = ["estimate", str(OTHER_ROBOT / "unloaded_raw.csv"),
                 "--inputs", str(OTHER_ROBOT / "unloaded_tensions.csv")]  # fmt: skip
    assert main([*recording, "--robot", str(swapped), "-o", str(out)]) == 0
    est, truth = read_state_table(out), read_state_table(OTHER_ROBOT / "unloaded_truth_tip.csv")
    tip = np.linalg.norm(np.column_stack([est.column(c) - truth.column(c) for c in "xyz"]), axis=1)
    assert (est.status == "drifted").sum() > 300
    assert not np.any((est.status == "ok") & (tip > 20e-3)), est.t[
        (est.status == "ok") & (tip > 20e-3)
    ]
    # the single EKF on the same inputs: its restarts, and no row after them ok far off
    options = InputOptions(tensions=str(OTHER_ROBOT / "unloaded_tensions.csv"))
    base = make_formulation("bend", read_robot(str(swapped)))
    with open_input(OTHER_ROBOT / "unloaded_raw.csv", options, base) as stream:
        f = stream.formulation
        blocks = list(stream.blocks)
    t = np.concatenate([b[0] for b in blocks])
    z = np.vstack([b[1] for b in blocks])
    single = ExtendedKalmanFilter(f).run(t, z)
    out_single = np.asarray(single.output, dtype=float)
    names = [o.name for o in f.outputs]
    tip_single = np.linalg.norm(
        np.column_stack(
            [out_single[:, names.index(c)] - np.interp(t, truth.t, truth.column(c)) for c in "xyz"]
        ),
        axis=1,
    )
    assert (single.status == "drifted").sum() > 300 and (single.status == "reset").sum() >= 1
    late_ok = (single.status == "ok") & (tip_single > 20e-3)
    assert not late_ok.any(), t[late_ok]
    # the same robot file as the recording's: every row after the start ok, near the truth
    own_file = tmp_path / "own.csv"
    assert main([*recording, "--robot", str(OTHER_ROBOT / "robot.toml"), "-o", str(own_file)]) == 0
    own = read_state_table(own_file)
    own_tip = np.linalg.norm(
        np.column_stack([own.column(c) - truth.column(c) for c in "xyz"]), axis=1
    )
    assert (own.status == "ok").sum() >= 395 and own_tip.mean() < 2e-3


def test_tilt_estimates_of_a_twisting_robot_are_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], twist08_raw_4s: tuple[Path, str]
) -> None:
    """Tilt IMUs do not see the twist a tip force across the bend makes: where their
    estimates twist a section past 20 degrees (``twist-08``: 25) ``estimate`` says so and
    names raw IMUs; not on ``force-29`` (13 degrees, 3.5 mm off), nor with raw IMUs
    (``twist-08``'s first 4 s, the module's run, whose estimates twist section 1 up to
    22 degrees)."""
    said = {}
    for name, meas in (("twist-08", DATA / "twist-08_tilt.csv"),
                       ("force-29", DATA / "force-29_tilt.csv")):  # fmt: skip
        capsys.readouterr()
        out = tmp_path / f"{name}_tilt.csv"
        assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                     str(DATA / f"{name}_tensions.csv"), "-o", str(out)]) == 0  # fmt: skip
        said[name, "tilt"] = [
            ln for ln in capsys.readouterr().err.splitlines() if "twist section" in ln
        ]
    raw_out, raw_err = twist08_raw_4s
    said["twist-08", "raw"] = [ln for ln in raw_err.splitlines() if "twist section" in ln]
    # twisted past 20 degrees: only tilt IMUs' twist is said
    assert np.degrees(np.abs(read_state_table(raw_out).column("psi_1"))).max() > 20.0
    assert len(said["twist-08", "tilt"]) == 1
    found = re.match(
        r"continuum-mhe: warning: the estimates twist section 1 by up to (\d+) degrees",
        said["twist-08", "tilt"][0],
    )
    assert found is not None and int(found.group(1)) > 20
    assert "raw IMUs (accelerometer and gyro) follow it" in said["twist-08", "tilt"][0]
    assert said["force-29", "tilt"] == [] and said["twist-08", "raw"] == []


def test_the_tilt_twist_notice_counts_the_largest_twist_past_20_degrees() -> None:
    """``TwistWithTiltImus`` (the line of ``estimate`` and of ``live``'s summary): active
    for a tendon robot with tilt IMUs only; silent at 19 degrees of twist, said at 21
    (the largest over the blocks, NaN rows without an estimate left out)."""
    from continuum_mhe.estimators.run_notices import TwistWithTiltImus

    robot = read_robot("tendon-two-section")
    tilt = TendonFormulation(robot=robot)
    assert not TwistWithTiltImus(TendonFormulation(robot=robot, imu_model="direct")).active
    names = [o.name for o in tilt.outputs]
    notice = TwistWithTiltImus(tilt)
    assert notice.active
    out = np.zeros((3, len(names)))
    out[:, names.index("psi_2")] = np.radians([5.0, -19.0, 2.0])
    notice.add(out)
    notice.add(np.full((2, len(names)), np.nan))
    assert notice.notice() is None
    out[1, names.index("psi_2")] = np.radians(-21.0)
    notice.add(out)
    said = notice.notice()
    assert said is not None and said.startswith("the estimates twist section 2 by up to 21")


@pytest.mark.parametrize("kind", ["raw", "tilt"])
def test_a_planar_s_is_estimated_to_the_model_floor(kind: str, tmp_path: Path) -> None:
    """The shipped ``planar-s`` (the independent energy-minimised rod: the two sections
    bent about 60 degrees the opposite ways in one plane, swinging through straight to
    the mirror image; no load): ``estimate`` with only ``--robot`` and ``--inputs``
    follows it to about the model's own error (0.012 mm at the tip), every row after
    the start ``ok``, with raw IMUs and with tilt IMUs."""
    out = tmp_path / "est.csv"
    argv = ["estimate", str(DATA / f"planar-s_{kind}.csv"), "--robot", "tendon-two-section",
            "--inputs", str(DATA / "planar-s_tensions.csv"), "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    est = read_state_table(out, ("x", "y", "z", "phi_1", "phi_2", "theta_1", "theta_2"))
    truth = read_state_table(DATA / "planar-s_truth.csv")
    assert np.allclose(est.t, truth.t)
    # an S: both sections bent far, the opposite ways
    bent = (truth.column("theta_1") > 0.5) & (truth.column("theta_2") > 0.5)
    assert bent.sum() > 100
    turn = np.abs(np.angle(np.exp(1j * (truth.column("phi_1") - truth.column("phi_2")))))
    assert np.all(turn[bent] > math.pi - 0.01)

    def error(cols: tuple[str, str, str]) -> np.ndarray:
        return np.linalg.norm(
            np.column_stack([est.column(c) - truth.column(c) for c in cols]), axis=1
        )

    tip, mid = error(("x", "y", "z")), error(("x_1", "y_1", "z_1"))
    # (with tilt IMUs the first rows are up to 1.9 mm off: the straight robot's start
    # leaves part of its readings to the IMUs' misalignments)
    assert tip.mean() < 0.05e-3 and tip.max() < 2.5e-3 and tip[est.t >= 1.0].max() < 0.5e-3
    assert mid.mean() < 0.05e-3
    assert est.status[0] == "uncertain" and set(est.status[1:]) == {"ok"}


def test_the_single_loaded_ekf_trusts_no_row_of_a_start_that_shows_a_load() -> None:
    """The single loaded EKF (``free_of_load_hypothesis=False``) started at 3 s of the
    shipped ``force-08`` (raw IMUs), under load: the first reading shows a load that
    the start cannot tell from the IMUs' errors, and its estimates, about 11 mm off,
    take part of it for those errors. As with the default EKF's two hypotheses, none of
    that start's rows is ``ok``, and ``estimate``'s line counts them."""
    from continuum_mhe.estimators import ExtendedKalmanFilter
    from continuum_mhe.estimators.run_notices import untrusted_start_notice

    f, t, z = _raw_shipped(401, "force-08")
    late = t >= 3.0 - 1e-9
    est = ExtendedKalmanFilter(replace(f, free_of_load_hypothesis=False))
    series = est.run(t[late][:150], z[late][:150])
    truth = read_state_table(DATA / "force-08_truth.csv")
    rows = np.searchsorted(truth.t, t[late][:150] - 1e-9)
    cols = [o.name for o in f.outputs]
    tip = np.asarray(series.output, float)[:, [cols.index(c) for c in "xyz"]]
    true_tip = np.column_stack([truth.column(c)[rows] for c in "xyz"])
    far = np.linalg.norm(tip - true_tip, axis=1) > 5e-3
    assert far.sum() > 100  # the start under load is off
    assert "ok" not in set(series.status)
    assert est.diagnostics.untrusted_start_samples == 150
    note = untrusted_start_notice(est.diagnostics, 150)
    assert note is not None and note.startswith(
        "150 of 150 estimates are of a start whose first IMU reading"
    )


def test_tension_rows_after_the_recording_are_not_taken_for_a_frozen_logger(
    tmp_path: Path,
) -> None:
    """A tensions file that goes on for 400 s after an 8 s recording, held at its last
    row (a controller's log that outlasts the IMUs'): the rows the recording does not
    use are not said to be a frozen logger; held for its last 4 s, they are, once. (The
    recording: ``force-29``'s raw samples every 0.2 s, 0 to 8 s; the check reads only
    its first and last times.)"""
    lines = (DATA / "force-29_raw.csv").read_text().splitlines()
    recording = tmp_path / "every_10th.csv"
    recording.write_text("\n".join([lines[0], *lines[1::10]]) + "\n")
    good = read_tensions(DATA / "force-29_tensions.csv", 6)
    later = np.arange(8.02, 400.0, 0.02)
    cols = ["t", *(f"tension_{j}" for j in range(1, 7))]
    long = tmp_path / "long.csv"
    after = np.repeat(good.values[-1:], len(later), 0)
    rows = np.column_stack([np.concatenate([good.t, later]), np.vstack([good.values, after])])
    write_table(long, cols, rows.tolist())
    held = tmp_path / "held.csv"
    values = np.where(
        (good.t > 4.0)[:, None], good.values[np.searchsorted(good.t, 4.0)], good.values
    )
    write_table(held, cols, np.column_stack([good.t, values]).tolist())
    import warnings

    from continuum_mhe.io.tensions import TensionsWarning

    def estimate(inputs: Path) -> list[str]:
        out = tmp_path / f"{inputs.stem}_est.csv"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            argv = ["estimate", str(recording), "--robot", "tendon-two-section",
                    "--inputs", str(inputs), "-o", str(out)]  # fmt: skip
            assert main(argv) == 0
        return [str(w.message) for w in caught if issubclass(w.category, TensionsWarning)]

    assert estimate(long) == []
    said = estimate(held)
    assert len(said) == 1 and said[0].startswith(
        f"{held}: the tensions repeat exactly from t = 4 to 8 s (4 s): a logger that froze"
    ), said


def test_a_sample_without_imu_readings_is_a_dropout_though_its_tensions_update_it(
    tmp_path: Path,
) -> None:
    """Rows of a tendon robot's recording whose IMU cells are empty (the tensions given
    for their times): the estimate follows the tensions there, but nothing read the
    robot, so each such row is ``dropout``, as on a robot without tendons. (The first
    2 s of ``force-29``, raw: the rows after the gap are ``ok`` again.)"""
    lines = (DATA / "force-29_raw.csv").read_text().splitlines()[:101]
    empty = {50, 51, 52}  # t = 0.98, 1.0 and 1.02 s
    for i in empty:
        lines[i] = lines[i].split(",")[0] + "," * (lines[0].count(","))
    meas = tmp_path / "gaps.csv"
    meas.write_text("\n".join(lines) + "\n")
    out = tmp_path / "est.csv"
    assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                 str(DATA / "force-29_tensions.csv"), "-o", str(out)]) == 0  # fmt: skip
    est = read_state_table(out)
    rows = np.flatnonzero(est.status == "dropout")
    assert sorted(rows + 1) == sorted(empty)  # the file's line i is row i - 1
    assert set(est.status[2:]) - {"dropout"} <= {"ok"}


def test_the_ukf_spread_as_for_a_pcc_robot_restarts_on_tilt_readings_and_says_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--method ukf`` on the first 20 tilt samples of ``force-29`` with the sigma
    points spread as for a PCC robot (alpha 0.5): they spread the tilt readings across
    a half turn and it restarts on almost every sample. The end-of-run warning names
    that cause and the EKF, not the robot file."""
    monkeypatch.setattr(TendonFormulation, "unscented_alpha", 0.5)
    meas = tmp_path / "t20.csv"
    meas.write_text("\n".join((DATA / "force-29_tilt.csv").read_text().splitlines()[:21]) + "\n")
    assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                 str(DATA / "force-29_tensions.csv"), "--method", "ukf",
                 "-o", str(tmp_path / "e.csv")]) == 0  # fmt: skip
    said = [ln for ln in capsys.readouterr().err.splitlines() if "restarted the" in ln]
    assert len(said) == 1 and re.search(
        r"\d+ of 20 samples \(\d+ %\) restarted the UKF: its sigma points spread a tilt "
        r"reading across a half turn",
        said[0],
    ), said
    assert "check the robot file" not in said[0] and "--method ekf" in said[0]


def test_the_ukf_follows_a_loaded_tendon_robot_with_its_sigma_points_close() -> None:
    """The first 4 s of ``force-29`` (tip force up to 0.22 N there), raw IMUs, the UKF
    with its defaults: the tendon model's sigma points lie close about the mean (alpha
    0.01), and the tip is within 3 mm of the truth on average and the tip force within
    0.02 N rms (2.3 mm and 0.008 N; the EKF on the whole recording: 0.70 mm, 0.003 N).
    Spread as for a PCC robot, alpha 0.5, the shooting's curvature moves every update:
    16 mm and 0.25 N, 94 rows of 201 ``ok`` (19 mm, 0.30 N and 303 rows ``inconsistent``
    on the whole recording). With tilt IMUs it restarts at most once in the first 40
    samples."""
    from continuum_mhe.estimators.kalman import UnscentedKalmanFilter

    f, t, z = _raw_shipped(201, "force-29")
    est = UnscentedKalmanFilter(f)
    assert est.inference.alpha == TendonFormulation.unscented_alpha == 0.01
    series = est.run(t, z)
    later = t >= 1.0
    assert np.mean(_tip_errors(f, t, series)[later]) < 3e-3
    truth = read_state_table(DATA / "force-29_truth.csv")
    rows = np.searchsorted(truth.t, t - 1e-9)
    cols = [o.name for o in f.outputs]
    force = np.asarray(series.output, float)[:, [cols.index(c) for c in ("fx", "fy", "fz")]]
    true_force = np.column_stack([truth.column(c)[rows] for c in ("fx", "fy", "fz")])
    assert np.sqrt(np.mean(np.sum((force - true_force)[later] ** 2, axis=1))) < 0.02
    assert np.sum(series.status == "ok") > 190
    f, t, z = _raw_shipped(40, "force-29", kind="tilt")
    tilt = UnscentedKalmanFilter(f)
    tilt.run(t, z)
    assert tilt.diagnostics.restarts <= 1


@pytest.mark.parametrize("single", [False, True])
def test_a_start_under_load_on_a_sample_without_imus_is_judged_at_the_first_imu_reading(
    single: bool,
) -> None:
    """``force-08`` (raw IMUs) started at 3 s, under load, its first three samples with
    the tensions but no IMU reading (``live`` before its IMUs report): the start is
    judged at the first sample with an IMU reading, and no row of it is ``ok`` (not
    judged on the first sample, which shows nothing, with about 100 rows ``ok`` and over
    5 mm off); the default EKF and the single loaded EKF alike."""
    from continuum_mhe.estimators import ExtendedKalmanFilter, make_estimator

    f, t, z = _raw_shipped(401, "force-08")
    late = t >= 3.0 - 1e-9
    t, z = t[late][:150], z[late][:150].copy()
    z[:3, : f.n_imu_measurements] = np.nan
    est = (
        ExtendedKalmanFilter(replace(f, free_of_load_hypothesis=False))
        if single
        else make_estimator("ekf", f)
    )
    series = est.run(t, z)
    status = np.asarray(series.status).astype(str)
    assert list(status[:3]) == ["dropout"] * 3
    assert "ok" not in set(status)
    assert est.diagnostics.untrusted_start_samples == 147  # from the first IMU reading on


def test_tensions_on_a_clock_s_absolute_time_are_said_to_be() -> None:
    """Tensions stamped with a clock's time since 1970, for a recording counted from its
    start: the line says their times look like a clock's own and where the recording's
    zero is, not only that they miss the recording. Tensions that merely end
    early get no such words."""
    from continuum_mhe.errors import InputError
    from continuum_mhe.io.tensions import Tensions

    epoch = Tensions.from_rows("abs.csv", np.array([1.7e9, 1.7e9 + 10]), np.ones((2, 1)))
    said = (
        r"abs\.csv: the tensions cover t = 1700000000 to 1700000010 s \(times since 1970, "
        r"a clock's own\? the recording's t counts from its start: a robot log's t = 0 is "
        r"its first sample's stamp"
    )
    with pytest.raises(InputError, match=said):
        epoch.at(0.1, "rec.csv")
    short = Tensions.from_rows("short.csv", np.array([0.0, 0.05]), np.ones((2, 1)))
    with pytest.raises(InputError) as info:
        short.at(0.1, "rec.csv")
    assert "since 1970" not in str(info.value)


def test_uncertain_rows_of_a_wide_standard_deviation_are_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``estimate`` says how many rows are ``uncertain`` for their width (the written
    tip standard deviation over ``--uncertain-fraction`` times the robot's length) where
    they are more than a tenth of the run: the UKF on the first 80 tilt samples of
    ``unloaded``. The count is that of the file's own rows; a run without such rows (the
    EKF on the same samples) says nothing of it."""
    meas = tmp_path / "t80.csv"
    meas.write_text("\n".join((DATA / "unloaded_tilt.csv").read_text().splitlines()[:81]) + "\n")
    for method, said in (("ukf", True), ("ekf", False)):
        out = tmp_path / f"{method}.csv"
        assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                     str(DATA / "unloaded_tensions.csv"), "--method", method,
                     "-o", str(out)]) == 0  # fmt: skip
        notes = [ln for ln in capsys.readouterr().err.splitlines() if "pin the shape" in ln]
        header, *rows = [ln.split(",") for ln in out.read_text().splitlines() if ln[:1] != "#"]
        std = np.array([[float(r[header.index(f"std_{c}")]) for c in "xyz"] for r in rows])
        status = np.array([r[header.index("status")] for r in rows])
        wide = int(np.sum((np.linalg.norm(std, axis=1) > 0.04) & (status == "uncertain")))
        if said:
            assert wide > 8 and len(notes) == 1
            assert notes[0].startswith(f"continuum-mhe: note: {wide} of 80 estimates")
            assert "over --uncertain-fraction 0.1 of the robot's length (40 mm)" in notes[0]
        else:
            assert wide <= 8 and not notes


def test_evaluate_refuses_a_truths_tip_force_in_mn_and_twist_in_degrees(
    force29_estimate: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A truth whose tip force is in mN (about 1000 times the estimate's) or whose twist
    ``psi_k`` is in degrees (beyond 2 pi) is refused in one line naming the truth file
    (not scored as 108 N of force error, 67.8 deg of twist); the truth in N and rad
    is scored; an estimate free of load says nothing of the force's unit."""
    from continuum_mhe.io.position_units import force_unit_against

    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    est = force29_estimate[0]  # estimate with --robot and the recording's own --inputs
    truth = read_state_table(data / "force-29_truth.csv")
    for name, column, factor in (("mN", "f", 1000.0), ("deg", "psi", 180 / math.pi)):
        scaled = np.array(truth.values, dtype=float)
        for j, c in enumerate(truth.names):
            if c.startswith(column):
                scaled[:, j] *= factor
        path = tmp_path / f"truth_{name}.csv"
        write_table(path, ["t", *truth.names], np.column_stack([truth.t, scaled]))
        capsys.readouterr()
        assert main(["evaluate", str(est), str(path)]) == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.startswith(f"continuum-mhe: error: {path}: ")
        assert (
            "fx, fy, fz in mN? give them in N" if name == "mN" else "beyond 2 pi: degrees?"
        ) in err
    assert main(["evaluate", str(est), str(data / "force-29_truth.csv")]) == 0
    names = ["fx", "fy", "fz"]
    f = np.array([[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])
    assert "2000 times" in force_unit_against(names, f * 2000, names, f)
    assert force_unit_against(names, f * 20, names, f) == ""
    assert force_unit_against(names, f * 1000, names, f * 0) == ""  # free of load


def test_the_drift_and_start_warnings_name_tensions_only_for_a_robot_with_tendons() -> None:
    """A robot with a backbone and no tendons (a passive rod, estimated on the mechanics
    model with its tip force) has no tensions to check: the drifted rows' and the
    untrusted start's lines leave them (and --estimate-tension-gain, which is refused
    for it) out; a tendon robot's name them."""
    from dataclasses import replace

    from continuum_mhe.estimators.run_notices import drifted_notice, untrusted_start_notice
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.results import Diagnostics

    tendon = read_robot("tendon-two-section")
    passive = replace(tendon, tendons=())
    diag = Diagnostics(untrusted_start_samples=4)
    for robot, named in ((tendon, True), (passive, False)):
        f = make_formulation("tendon", robot, imu_model="direct")
        drift = drifted_notice(118, 151, f)
        start = untrusted_start_notice(diag, 151, bool(robot.tendons))
        assert drift is not None and start is not None
        assert drift.startswith("118 of 151 estimates drifted") and "robot file" in drift
        assert ("--estimate-tension-gain" in drift) == named
        assert ("tension" in drift) == named and ("tension" in start) == named


# --- a push the backbone cannot hold -----------------------------------------------------
def test_the_tip_push_against_known_answers() -> None:
    """The tip force's component against the tip's tangent: all of an axial force on the
    straight rod (a pull negative), and for a small force across it the force times the
    cantilever's tip slope ``F L^2 / (2 EI)``, negative (the tip turns towards the
    force)."""
    robot = one_section_robot()
    f = TendonFormulation(robot=robot)
    x = np.zeros(f.nx)
    x[5] = -0.2
    assert f.tip_push(x) == pytest.approx(0.2, rel=1e-12)
    x[5] = 0.2
    assert f.tip_push(x) == pytest.approx(-0.2, rel=1e-12)
    force = 1e-3
    k0, _ = TendonStatics(robot).solve(np.array([0.0, force, 0.0]), np.zeros(0))
    x = np.zeros(f.nx)
    x[:3], x[4] = k0, force
    assert f.tip_push(x) == pytest.approx(-force * force * 0.2**2 / (2 * EI), rel=1e-3)


def test_a_push_beyond_the_buckling_load_is_drifted() -> None:
    """A straight rod pushed along its axis (an equilibrium of the model at any load):
    drifted beyond the buckling load, which a free tip cannot hold, not at 0.9 of it;
    pulled as hard, not drifted."""
    f = TendonFormulation(robot=one_section_robot())
    x = np.zeros(f.nx)
    x[5] = -0.9 * f.buckling_load
    assert not f.drifted(x)
    x[5] = -1.01 * f.buckling_load
    assert f.drifted(x)
    x[5] = 1.5 * f.buckling_load  # a pull along the backbone
    assert not f.drifted(x)


def test_a_still_straight_robot_is_not_ok_under_a_push_the_imus_cannot_see(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped tendon robot straight and still, raw IMUs, no tension: along the
    backbone the IMUs barely see the tip force, and the EKF's loaded hypothesis takes
    axial forces of several newtons at standard deviations of hundredths of one. No
    such row is ok (they are drifted, and restarted after half a second), and the
    warning names the push."""
    meas, out = tmp_path / "rest.csv", tmp_path / "e.csv"
    tensions = tmp_path / "rest_tensions.csv"  # simulate writes it: the tendons slack
    assert main(["simulate", "rest", "--robot", "tendon-two-section", "--imu", "raw",
                 "--seed", "2", "-o", str(meas)]) == 0  # fmt: skip
    capsys.readouterr()
    argv = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(tensions),
            "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    est = read_state_table(out)
    fz = est.values[:, est.names.index("fz")]
    assert np.max(np.abs(fz)) > 1.0  # the loaded hypothesis pushes
    assert not np.any((np.abs(fz) > 0.1) & (est.status == "ok"))
    assert "the tip force pushed along the backbone harder than its buckling load" in err


def test_a_tensions_file_ending_a_rounding_short_of_the_recording_covers_it() -> None:
    """A last row at 1.4999999999999998 s (a time computed in floating point) covers a
    sample at 1.5 s and gives that row's tensions; 2 us short does not cover it."""
    from continuum_mhe.io.tensions import Tensions

    t = np.array([0.0, 0.5, 1.0, 1.4999999999999998])
    table = Tensions.from_rows("tensions.csv", t, np.array([[1.0], [2.0], [3.0], [4.0]]))
    assert table.covers(1.5) and table.covers(-1e-7)
    assert table.at(1.5)[0][0] == pytest.approx(4.0, abs=1e-12)
    assert not table.covers(1.5 + 2e-6)
    with pytest.raises(InputError, match="the tensions must cover the recording"):
        table.at(1.5 + 2e-6)


def test_evaluate_judges_the_tip_force_unit_over_the_rows_compared(tmp_path: Path) -> None:
    """An estimate of a recording's first rows (an interrupted run: small forces) is
    scored against the whole truth in N, not refused as a truth in mN because the
    truth's later rows carry larger forces."""
    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    head = tmp_path / "head.csv"
    head.write_text("".join((data / "force-29_raw.csv").read_text().splitlines(True)[:13]))
    est = tmp_path / "e.csv"
    argv = ["estimate", str(head), "--robot", "tendon-two-section",
            "--inputs", str(data / "force-29_tensions.csv"), "-o", str(est)]  # fmt: skip
    assert main(argv) == 0
    assert main(["evaluate", str(est), str(data / "force-29_truth.csv")]) == 0


def test_simulate_rest_of_a_one_section_tendon_robot_puts_its_section_end_at_the_tip(
    tmp_path: Path,
) -> None:
    """A one-section tendon robot at rest: the truth's section end (``x_1, y_1, z_1``) is
    its tip, the straight backbone's length above the base, not the base."""
    robot = tmp_path / "one.toml"
    robot.write_text(
        'mounting = "z-up"\n[backbone]\nyoungs_modulus = 54e9\nshear_modulus = 20.77e9\n'
        "radius = 0.0007\n[[section]]\nlength = 0.25\ndisks = 9\n"
        + "".join(f"[[tendon]]\nsection = 1\nangle = {a}\nradius = 0.01\n" for a in (0, 120, 240))
        + "[[imu]]\nsection = 1\n"
    )
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    argv = ["simulate", "rest", "--robot", str(robot), "-o", str(meas), "--truth", str(truth),
            "--duration", "1"]  # fmt: skip
    assert main(argv) == 0
    table = read_state_table(truth)
    for end, tip in (("x_1", "x"), ("y_1", "y"), ("z_1", "z")):
        assert np.array_equal(table.column(end), table.column(tip))
    assert np.allclose(table.column("z_1"), 0.25)


def test_tensions_near_the_span_buckling_load_of_a_disk_routed_robot_are_said() -> None:
    """Disks 5 cm apart on the shipped backbone: the backbone between two of them
    buckles at ``pi^2 EI / d^2`` (40.2 N); tensions of 30 N through the section (0.75 of
    it) are said, 20 N (0.50) are not, nor 30 N on tendons routed continuously."""
    from continuum_mhe.io.tensions import span_buckling_problem

    robot = Robot((Section(0.2, 3.0, 4),), (ImuPlacement(0, 1.0),), "z-up", BACKBONE,
                  (Tendon(0, 0.0, 0.01), Tendon(0, math.pi, 0.01)), "disks")  # fmt: skip
    t = np.array([0.0, 1.0])
    buckling = math.pi**2 * BACKBONE.youngs_modulus * math.pi * BACKBONE.radius**4 / 4 / 0.05**2
    assert buckling == pytest.approx(40.2, abs=0.05)
    line = span_buckling_problem(robot, t, np.array([[1.0, 1.0], [20.0, 10.0]]), "ten.csv")
    assert line.startswith("ten.csv: at t = 1 s the tensions through section 1, 30 N in all, "
                           "are 0.75 of the load that buckles its backbone"), line  # fmt: skip
    assert span_buckling_problem(robot, t, np.array([[1.0, 1.0], [10.0, 10.0]]), "x") == ""
    continuous = replace(robot, tendon_route="continuous")
    assert span_buckling_problem(continuous, t, np.array([[1.0, 1.0], [20.0, 10.0]]), "x") == ""


def test_simulate_rest_of_a_disk_routed_robot_is_its_robot_without_tendons(tmp_path: Path) -> None:
    """``simulate rest`` of a robot whose tendons run from disk to disk writes the
    straight, still robot (its tendons slack), as for any tendon robot."""
    text = (DATA.parent / "robots" / "tendon_two_section.toml").read_text()
    robot = tmp_path / "r.toml"
    robot.write_text('tendon_route = "disks"\n' + text)
    meas = tmp_path / "rest.csv"
    assert (
        main(["simulate", "rest", "--robot", str(robot), "-o", str(meas), "--duration", "1"]) == 0
    )
    assert meas.exists()
