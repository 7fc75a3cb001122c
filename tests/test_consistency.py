"""``ok`` means ok: readings that disagree with the estimate make it ``inconsistent``
(every estimator), and the model error they show widens the standard deviations
(:mod:`continuum_mhe.estimators.consistency`). Known answers on simulated recordings
with injected readings, and a property test of the normalised errors of ``ok`` rows."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from estimator_helpers import bare
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from continuum_mhe.estimators import make_estimator
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.results import Measurement
from continuum_mhe.settings import MHESettings, NoiseSettings, RecoverySettings
from continuum_mhe.simulation.scenarios import simulate, simulate_robot

#: the per-axis 95 % interval of ok rows must cover the truth at least this often per
#: axis, and at most this often over the three axes together (one recording's rows are
#: correlated: one axis alone may reach 100 % by chance)
COVERAGE = (0.85, 0.99)


def _upside_down(z: np.ndarray, k: int) -> np.ndarray:
    """``z`` with reading ``k`` of a one-IMU tilt recording turned upside down (roll
    plus or minus pi, pitch negated: the opposite gravity direction)."""
    z = z.copy()
    z[k, 0] += np.pi if z[k, 0] < 0 else -np.pi
    z[k, 1] = -z[k, 1]
    return z


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_after_one_upside_down_reading_no_row_far_off_is_ok(method) -> None:
    """paper3d with one reading upside down: every row more than 50 mm off the truth
    is flagged (not ``ok``), and rows far from the reading stay ``ok``."""
    rec = simulate("paper3d", duration=8.0, seed=3)
    formulation = make_formulation("bend", Robot.single(0.2))
    est = make_estimator(method, formulation, MHESettings(solver="ipopt"))
    series = est.run(rec.t, _upside_down(rec.z, 60))
    err = np.linalg.norm(series.output[:, :3] - rec.truth[:, :3], axis=1)
    assert not np.any((err > 0.05) & (series.status == "ok"))
    assert np.mean(series.status[100:] == "ok") > 0.9


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
@pytest.mark.parametrize("seed", [0, 1])
def test_rows_many_standard_deviations_off_at_1_hz_are_not_ok(method, seed) -> None:
    """Sampled at 1 Hz the bend moves far between readings and the EKF's one
    linearisation falls behind: its update leaves a residual that no linear update
    leaves, pointing to a shape outside its covariance. Without the checks 49 ``ok``
    rows are 4 to 25 of their own standard deviations off; with the tests on the
    innovation and the fit alone, 1 to 5 rows per recording 4 to 6.8 off. No ``ok`` row
    is 4 off in x or y, on any estimator; the MHE, which fits its window, keeps
    every row ``ok``. (The linearised ``std_z`` of a nearly straight robot is near zero,
    as its tip's ``z`` moves to second order: one EKF row at 0.04 rad of bend is 0.06
    mm and 4.5 of its ``std_z`` off in z.)"""
    rec = simulate("paper3d", duration=120.0, dt=1.0, seed=seed)
    f = make_formulation("bend", Robot.single(0.2))
    series = make_estimator(method, f).run(rec.t, rec.z)
    off = np.abs(series.output[:, :2] - rec.truth[:, :2]) / series.std[:, :2]
    ok = series.status == "ok"
    assert not np.any(ok & (off.max(axis=1) >= 4.0)), off[ok].max(axis=0)
    if method == "mhe":  # every row but the start (unconfirmed)
        assert series.status[0] == "uncertain" and ok[1:].all()


def test_a_restart_keeps_the_model_error_the_readings_showed() -> None:
    """Noise three times the assumed one: the innovations' average shows it, the rows
    are ``inconsistent`` and the standard deviations carry the model error. A gap that
    restarts the estimator does not make the model right: after it the learned model
    error and the ``inconsistent`` rows remain (forgotten, the rows after the gap would
    say ``ok`` with the noise-only standard deviations)."""

    rec = simulate("paper3d", duration=10.0, seed=2, noise_deg=6.0, noise_model="tangent")
    keep = (rec.t < 5.0) | (rec.t > 6.5)  # a 1.5 s gap: the gap reset restarts at 6.5 s
    f = make_formulation("bend", Robot.single(0.2))
    est = make_estimator("ekf", f, recovery=bare(gap_reset=1.0))
    est.reset()
    before = after = None
    for t, z in zip(rec.t[keep], rec.z[keep], strict=True):
        e = est.step(Measurement(float(t), z))
        if t < 5.0:
            before = est._consistency.model_error
        elif e.status != "reset" and after is None:
            after = (est._consistency.model_error, e.status)
    assert est.diagnostics.gap_resets == 1
    assert before is not None and before > 1.0
    assert after is not None and after[0] >= before and after[1] == "inconsistent"


def test_a_callers_restart_within_the_recording_keeps_the_model_error() -> None:
    """As a gap's restart: ``reset(keep_counts=True)`` in the middle of the recording of
    the test above (a caller's restart of the same robot, as ``live`` makes) keeps the
    model error learned and the rows after it ``inconsistent``; ``reset()`` (a new
    recording) forgets it."""
    rec = simulate("paper3d", duration=10.0, seed=2, noise_deg=6.0, noise_model="tangent")
    f = make_formulation("bend", Robot.single(0.2))
    for keep_counts in (True, False):
        est = make_estimator("ekf", f)
        est.reset()
        before = after = None
        for t, z in zip(rec.t, rec.z, strict=True):
            if before is None and t >= 5.0:
                before = est._consistency.model_error
                est.reset(keep_counts=keep_counts)
                assert (est._consistency.model_error == before) is keep_counts
            e = est.step(Measurement(float(t), z))
            if before is not None and after is None and e.status != "uncertain":
                after = (est._consistency.model_error, e.status)
        assert before is not None and before > 1.0
        assert after is not None
        if keep_counts:
            assert after[0] >= before and after[1] == "inconsistent", after
        else:
            assert after[0] < before, after


def _recording(
    length: float, seed: int, two: bool, noise_factor: float, reading_bias_std: float
) -> tuple[Robot, object]:
    """A simulated recording of a random robot (one section, ``paper3d``; or two,
    ``spatial``) with noise ``noise_factor`` times the assumed 2 deg and each reading's
    constant error (an IMU's mounting, its accelerometer's bias) drawn with
    ``reading_bias_std``, rad."""
    if not two:
        robot = Robot.single(length)
        rec = simulate(
            "paper3d", duration=10.0, length=length, seed=seed, noise_deg=2.0 * noise_factor,
            noise_model="tangent",
        )  # fmt: skip
    else:
        robot = Robot(
            (Section(0.55 * length), Section(0.45 * length)), (ImuPlacement(0), ImuPlacement(1))
        )
        rec = simulate_robot(
            "spatial", robot, duration=10.0, dt=0.05, seed=seed, noise_deg=2.0 * noise_factor
        )
    bias = np.random.default_rng(seed).normal(size=rec.z.shape[1]) * reading_bias_std
    return robot, replace(rec, z=rec.z + bias)


def _normalised_ok_errors(robot: Robot, rec, noise: NoiseSettings) -> tuple[np.ndarray, np.ndarray]:
    """The EKF's status and its ``ok`` rows' tip errors over their std (k, 3)."""
    series = make_estimator("ekf", make_formulation("bend", robot, noise)).run(rec.t, rec.z)
    ok = series.status == "ok"
    return series.status, (series.output[ok, :3] - rec.truth[ok, :3]) / series.std[ok, :3]


@settings(
    max_examples=6, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
@given(st.floats(0.1, 0.4), st.integers(0, 10_000), st.booleans(), st.sampled_from([1.0, 3.0]))
def test_ok_rows_normalised_errors_have_the_right_distribution(
    length, seed, two, noise_factor
) -> None:
    """Across random robots and trajectories, with the noise as assumed or three times
    larger (IMUs mounted exactly and the model's own motion, and said to be:
    ``reading_bias_std`` and ``model_error_std`` 0): where the noise is as assumed,
    most rows stay ``ok`` and the tip error of ``ok`` rows over its standard deviation
    falls inside the 95 % interval at least 85 % of the time per axis and at most 99 %
    over the three axes; where it is three times larger, the readings disagree with
    their noise model and almost no row is ``ok``. The examples are fixed (``derandomize``):
    one short recording's rows are correlated, and its coverage can pass 99 % by
    chance (length 0.25 m, seed 2824: 0.995, 0.995, 0.990); the pooled
    test below holds the upper bound over many."""
    noise = NoiseSettings(reading_bias_std=0.0, model_error_std=0.0)
    status, d = _normalised_ok_errors(*_recording(length, seed, two, noise_factor, 0.0), noise)
    if noise_factor == 1.0:
        assert np.mean(status == "ok") > 0.9 and len(d) >= 30
    else:
        assert np.mean(status == "ok") < 0.05
    if len(d) >= 30:
        coverage = np.mean(np.abs(d) <= 1.96, axis=0)
        assert np.all(coverage >= COVERAGE[0]) and coverage.mean() <= COVERAGE[1], coverage


def test_ok_rows_normalised_errors_over_many_recordings() -> None:
    """Pooled over random robots, trajectories and each reading's constant error drawn
    as the default ``reading_bias_std`` says a real IMU has, with the defaults but for
    the model error (the model generated the motion: ``model_error_std`` 0): the
    ``ok`` rows' 95 % intervals cover the truth 85 to 99 % of the time per axis (84 to
    86 % with the noise alone in the std). One recording's rows share its constant
    errors, so the coverage is a property of many recordings, not of one."""
    rng = np.random.default_rng(7)
    noise = NoiseSettings(model_error_std=0.0)
    bias = noise.reading_bias_std
    runs = [
        _recording(rng.uniform(0.1, 0.4), seed, bool(seed % 2), 1.0, bias) for seed in range(16)
    ]
    d = np.concatenate([_normalised_ok_errors(robot, rec, noise)[1] for robot, rec in runs])
    coverage = np.mean(np.abs(d) <= 1.96, axis=0)
    assert np.all(coverage >= COVERAGE[0]) and np.all(coverage <= COVERAGE[1]), coverage


@pytest.mark.parametrize("name", ["planar-s", "spatial-tendon"])
def test_ok_rows_cover_the_truth_on_a_cosserat_rod(name) -> None:
    """The shipped rod recordings (PyElastica, MEMS IMUs with mounting misalignment
    and biases; raw IMUs, defaults) that the model follows or nearly follows: most rows
    stay ``ok`` (planar-s, which the model follows, more than 90 %), and their 95 %
    intervals cover the truth at least 85 % of the time per axis. planar-s: 9, 46 and
    84 % with the noise alone (the IMUs' constant errors look like a different shape).
    spatial-tendon (bends to 124 degrees, a curvature that is not constant): 90, 90 and
    79 % without the model error learned from its innovations (the curvature the
    constant-curvature model gets wrong leaves no residual while the gravity directions
    fix the shape); its readings scatter at a fraction of ``R``, and against that level
    the innovations show the model error on about a fifth of the rows."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.cosserat import default_data_path

    folder = default_data_path().parent / "rod2"
    f = make_formulation("bend", read_robot("two-section"))
    data = load_input(folder / f"{name}_raw.csv", InputOptions(), f)
    truth = read_state_table(folder / f"{name}_truth.csv").values[:, :3]
    series = make_estimator("ekf", data.formulation).run(data.t, data.z)
    ok = series.status == "ok"
    assert ok.mean() > (0.9 if name == "planar-s" else 0.5)
    covered = np.abs(series.output[ok, :3] - truth[ok]) <= 1.96 * series.std[ok, :3]
    assert np.all(covered.mean(axis=0) >= COVERAGE[0]), covered.mean(axis=0)


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_ok_rows_cover_the_truth_where_the_readings_never_show_the_model_error(method) -> None:
    """The first 6 s of the shipped spatial-tendon rod recording, tilt only: two IMUs'
    roll and pitch fit the two sections' four bend coordinates exactly whatever the
    model error, no residual shows the curvature the constant-curvature model gets
    wrong, and every row is ``ok`` but those whose written tip standard deviation, the
    readings' constant errors in it, exceeds the uncertain fraction of the robot's
    length (where the IMUs barely pin the shape: ``uncertain``, 45 or 46 of the 300
    rows, at most 12 to 17 mm off). The model error assumed before the readings
    show one (``model_error_std``) makes the 95 % intervals cover the truth 85 to 99 %
    of the time per axis, in every estimator; without it (0) 81, 82 and 85 %."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.cosserat import default_data_path

    folder = default_data_path().parent / "rod2"
    n = 300  # 6 s at 50 Hz
    f = make_formulation("bend", read_robot("two-section"))
    data = load_input(folder / "spatial-tendon_tilt.csv", InputOptions(), f)
    truth = read_state_table(folder / "spatial-tendon_truth.csv").values[:n, :3]
    series = make_estimator(method, data.formulation).run(data.t[:n], data.z[:n])
    ok = series.status == "ok"
    assert ok.mean() > 0.8
    assert np.all((series.status == "ok") | (series.status == "uncertain"))
    covered = np.abs(series.output[ok, :3] - truth[ok]) <= 1.96 * series.std[ok, :3]
    coverage = covered.mean(axis=0)
    assert np.all(coverage >= COVERAGE[0]) and np.all(coverage <= COVERAGE[1]), coverage


def test_ok_rows_cover_the_truth_over_the_rods_with_the_command_line_defaults(tmp_path) -> None:
    """The four shipped two-section rod recordings (raw IMUs; one that the model follows,
    three that twist), estimated by ``continuum-mhe estimate --method ekf`` with its
    defaults, whose bad-start check restarts the estimator where the readings disagree:
    pooled, the ``ok`` rows' 95 % intervals cover the truth 85 to 99 % of the time per
    axis. A restart keeps the model error the readings showed (a restart that forgets it
    makes rows ``ok`` again at once: coverage 91 / 86 / 81 %)."""
    from continuum_mhe.cli import main
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.cosserat import default_data_path

    folder = default_data_path().parent / "rod2"
    covered = []
    for name in ["planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial"]:
        out = tmp_path / f"{name}.csv"
        argv = ["estimate", str(folder / f"{name}_raw.csv"), "--robot", "two-section"]
        assert main([*argv, "--method", "ekf", "-o", str(out)]) == 0
        est = read_state_table(out)
        truth = read_state_table(folder / f"{name}_truth.csv").values[:, :3]
        ok = est.status == "ok"
        assert est.std is not None
        covered.append(np.abs(est.values[ok, :3] - truth[ok]) <= 1.96 * est.std[ok, :3])
    coverage = np.concatenate(covered).mean(axis=0)
    assert np.all(coverage >= COVERAGE[0]) and np.all(coverage <= COVERAGE[1]), coverage


@pytest.mark.parametrize("name", ["force-29", "force-08"])
def test_loaded_tendon_robot_rows_far_off_are_not_ok(name) -> None:
    """The shipped tendon robot under a 0.29 N or 0.08 N tip force (PyElastica, 13 or
    7 degrees of twist), raw IMUs, estimated without tensions by the PCC model
    (defaults): the model cannot follow, and at least 80 % of the rows more than 20 mm
    off are not ``ok``. force-08: 73 % if a row is ``ok`` again as soon as the
    innovations' average drops below its quantile; its far rows come right after
    stretches the average flagged."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.cosserat import default_data_path

    folder = default_data_path().parent / "tendon"
    # the shipped robot without its tendons and backbone: its PCC sections and IMUs
    section = Section(0.2, theta_max=3.0)
    f = make_formulation("bend", Robot((section, section), (ImuPlacement(0), ImuPlacement(1))))
    data = load_input(folder / f"{name}_raw.csv", InputOptions(), f)
    truth = read_state_table(folder / f"{name}_truth.csv").values[:, :3]
    series = make_estimator("ekf", data.formulation).run(data.t, data.z)
    far = np.linalg.norm(series.output[:, :3] - truth, axis=1) > 0.02
    assert far.sum() > 100
    assert np.mean(series.status[far] != "ok") >= 0.8


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_loaded_tendon_robot_by_a_pcc_robot_of_its_geometry_far_rows_are_not_ok(method) -> None:
    """force-29 (raw IMUs) estimated without tensions by a PCC robot of the tendon
    robot's geometry, defaults: the model error shows in the innovations only while the
    robot moves one way, at about two to four times the level the readings scatter at
    while the model follows (which is a third of what ``R`` says), and fades between
    those phases. At least 80 % of the rows more than 20 mm off are not ``ok`` (54 %
    with the average judged against ``R``'s level, 74 % with a model error that ends as
    soon as the average touches the quiet level)."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.cosserat import default_data_path

    # tendon-two-section without its tendons and backbone (tools/honesty_study.py's)
    section = Section(0.2, theta_max=3.0)
    robot = Robot((section, section), (ImuPlacement(0), ImuPlacement(1)))
    folder = default_data_path().parent / "tendon"
    f = make_formulation("bend", robot)
    data = load_input(folder / "force-29_raw.csv", InputOptions(), f)
    truth = read_state_table(folder / "force-29_truth.csv").values[:, :3]
    series = make_estimator(method, data.formulation).run(data.t, data.z)
    far = np.linalg.norm(series.output[:, :3] - truth, axis=1) > 0.02
    assert far.sum() > 100
    assert np.mean(series.status[far] != "ok") >= 0.8


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_readings_noisier_than_their_own_level_are_inconsistent_below_r(method) -> None:
    """paper3d with readings four times less noisy than ``R`` says (0.5 degrees) for
    10 s, then nine times noisier than that (1.5 degrees, still below ``R``'s 2): the
    average of NIS / dof is judged against the level the readings scattered at while
    the model followed them, so most rows of the louder half are ``inconsistent`` (none
    would be against 1, ``R``'s level), and the quiet half stays ``ok``."""
    quiet = simulate("paper3d", duration=20.0, seed=4, noise_deg=0.5, noise_model="tangent")
    loud = simulate("paper3d", duration=20.0, seed=5, noise_deg=1.5, noise_model="tangent")
    np.testing.assert_array_equal(quiet.truth, loud.truth)  # one motion, two noises
    z = np.where((quiet.t < 10.0)[:, None], quiet.z, loud.z)
    f = make_formulation("bend", Robot.single(0.2))
    series = make_estimator(method, f).run(quiet.t, z)
    assert np.all(series.status[(quiet.t >= 2.0) & (quiet.t < 10.0)] == "ok")
    assert np.mean(series.status[quiet.t >= 12.0] == "inconsistent") > 0.5


def test_quantiles_match_scipy_stats() -> None:
    """The consistency tests' quantiles (scipy.special) against scipy.stats and known
    table values (chi-square 0.95 quantile, 2 degrees of freedom: 5.991; F(5, 10):
    3.326)."""
    from scipy.stats import chi2, f

    from continuum_mhe.quantiles import chi2_quantile, f_quantile

    assert chi2_quantile(0.95, 2) == pytest.approx(5.991464547, rel=1e-9)
    for q in (0.5, 0.9, 0.99, 0.9999):
        for dof in (1, 2, 3.5, 12, 60):
            assert chi2_quantile(q, dof) == pytest.approx(chi2.ppf(q, dof), rel=1e-10)
    # F: the 0.95 quantile of F(5, 10) is 3.326 (tables); the check's (468, 2388)
    assert f_quantile(0.95, 5, 10) == pytest.approx(3.325834530, rel=1e-9)
    for q in (0.5, 0.99, 0.999):
        for dfn, dfd in ((1, 1), (4, 39), (468, 2388)):
            assert f_quantile(q, dfn, dfd) == pytest.approx(f.ppf(q, dfn, dfd), rel=1e-10)


def test_quantile_table_is_scipy_s_at_every_level_the_estimators_use(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The table the estimators read their quantiles from (data/quantiles.json) holds
    ``scipy.special``'s values at each level the estimators use (the levels and degrees
    of freedom of ``tools/quantile_table.py``, which imports them from the checks), and a
    quantile beyond it is ``scipy.special``'s too."""
    from scipy.special import chdtri, fdtri

    from continuum_mhe.quantiles import TABLE_PATH, chi2_quantile, f_quantile

    monkeypatch.syspath_prepend(str(Path(__file__).parents[1] / "tools"))
    import quantile_table

    written = json.loads(TABLE_PATH.read_text())
    assert [float(q) for q in written["chi2"]] == quantile_table.chi2_levels()
    for level, values in written["chi2"].items():
        dof = np.arange(1, len(values) + 1)
        assert len(values) == quantile_table.CHI2_DOF
        np.testing.assert_allclose(values, chdtri(dof, 1.0 - float(level)), rtol=1e-13)
    rows = np.array(written["f"])
    assert [tuple(r) for r in rows[:, :3]] == quantile_table.f_rows()
    np.testing.assert_allclose(rows[:, 3], fdtri(rows[:, 1], rows[:, 2], rows[:, 0]), rtol=1e-13)
    n = quantile_table.CHI2_DOF + 1  # beyond the table
    assert chi2_quantile(0.999, n) == pytest.approx(float(chdtri(n, 0.001)), rel=1e-15)
    assert f_quantile(0.999, 39, 200) == pytest.approx(float(fdtri(39, 200, 0.999)), rel=1e-15)


@pytest.mark.parametrize("floor_deg", [0.0, 2.0])
def test_learned_model_error_is_carried_as_a_constant_reading_error(floor_deg) -> None:
    """One IMU on one section (tilt): the readings fix the bend, so a model error
    ``m`` in units of ``R`` on each reading shifts the bend by ``A e`` with
    ``A = M^-1 H^T R^-1``, ``M = H^T R^-1 H + I / theta_max^2`` (the bend's range, pi/2): the
    covariance is ``m M^-1 (H^T R^-1 H) M^-1``, ``H`` the residual's Jacobian by
    central differences; with none learned it is the floor's (``model_error_std``;
    zero without one, with ``reading_bias_std`` 0), and a model error learned below the
    floor carries the floor."""
    from continuum_mhe.estimators.consistency import ConsistencyCheck

    noise = NoiseSettings(reading_bias_std=0.0, model_error_std=np.radians(floor_deg))
    f = make_formulation("bend", Robot.single(0.2), noise)
    check = ConsistencyCheck(f)
    x = np.zeros(f.nx)
    x[:2] = [0.4, -0.3]
    z = np.asarray(f.functions.measure(x)[0]).ravel() + [0.01, -0.02]
    mask = np.ones(f.nz)
    H = np.zeros((f.nz, 2))
    for j in range(2):
        dx = np.zeros(f.nx)
        dx[j] = 1e-6
        r_plus = np.asarray(f.functions.innovate(z, x + dx)[0]).ravel()
        r_minus = np.asarray(f.functions.innovate(z, x - dx)[0]).ravel()
        H[:, j] = -(r_plus - r_minus) / 2e-6
    info = H.T @ np.linalg.solve(f.meas_cov(), H)
    M_inv = np.linalg.inv(info + np.eye(2) / (np.pi / 2) ** 2)  # theta_max
    unit = M_inv @ info @ M_inv  # m = 1
    floor = (floor_deg / 2.0) ** 2  # the floor in units of R (2 degrees)
    for learned in (0.0, 0.7, 1.6):
        check.model_error = learned
        got = check.constant_error_cov(z, mask, x)
        np.testing.assert_allclose(got[:2, :2], max(learned, floor) * unit, rtol=1e-6)
        assert not np.any(got[2:]) and not np.any(got[:, 2:])


def test_constant_errors_do_not_shift_a_barely_pinned_shape_beyond_its_range() -> None:
    """Three sections, a tilt IMU at each end, at a shape whose readings barely pin one
    direction of the bends (the smallest eigenvalue of ``H^T R^-1 H`` is about 0.004
    rad^-2): the readings' constant errors through the weighted least-squares
    sensitivity alone would shift the second section's bend by a standard deviation of
    about 15 rad. With the bends' range (``theta_max``, 3 rad) as information beside the
    readings', the covariance is ``A B A^T`` with ``A = M^+ H^T R^-1``,
    ``M = H^T R^-1 H + I / theta_max^2``, and no bend's standard deviation exceeds half
    the range times the largest constant error in units of ``R``."""
    from continuum_mhe.estimators.consistency import ConsistencyCheck

    robot = Robot(
        tuple(Section(length) for length in (0.12, 0.10, 0.08)),
        tuple(ImuPlacement(k) for k in range(3)),
        "z-down",
    )
    f = make_formulation("bend", robot)
    x = np.zeros(f.nx)
    for k, (theta, phi) in enumerate([(1.0866, 0.2003), (1.0514, 0.6540), (0.9873, 1.4766)]):
        x[2 * k : 2 * k + 2] = theta * np.cos(phi), theta * np.sin(phi)
    z = np.asarray(f.functions.measure(x)[0]).ravel()
    mask = f.measurement_mask(z)
    R = np.asarray(f.meas_cov(), dtype=float)
    bias = np.diag(f.reading_bias_cov()) + np.where(
        f.gravity_direction_rows(), f.model_error_floor(), 0.0
    )
    _, J = f.functions.innovate(z, x)
    H = -np.asarray(J, dtype=float)[:, :6]  # the readings depend on the bends alone
    W = np.diag(1.0 / np.diag(R))
    info = H.T @ W @ H
    assert np.linalg.eigvalsh(info)[0] < 0.01  # barely pinned
    readings_alone = np.linalg.pinv(info, hermitian=True) @ H.T @ W
    assert np.sqrt(np.diag(readings_alone @ np.diag(bias) @ readings_alone.T)).max() > 10.0
    A = np.linalg.inv(info + np.eye(6) / 3.0**2) @ H.T @ W
    want = A @ np.diag(bias) @ A.T
    got = ConsistencyCheck(f).constant_error_cov(z, mask, x)
    np.testing.assert_allclose(got[:6, :6], want, rtol=1e-8, atol=1e-14)
    assert not np.any(got[6:]) and not np.any(got[:, 6:])
    beta = float(np.max(bias / np.diag(R)))
    assert np.sqrt(np.diag(got)).max() <= 3.0 / 2.0 * np.sqrt(beta)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 8),
    rank=st.integers(0, 8),
    scale=st.floats(1e-6, 1e6),
    seed=st.integers(0, 2**32 - 1),
)
@example(n=7, rank=7, scale=1.0, seed=8)  # condition number 1e7: entries 2e5 apart by 1e-3
def test_symmetric_pseudo_inverse_matches_numpy_pinv(n, rank, scale, seed) -> None:
    """The compiled pseudo-inverse behind the constant-error covariance equals numpy's
    ``pinv(hermitian=True)``, on singular and nearly singular matrices too, and on
    symmetric matrices with negative eigenvalues."""
    from continuum_mhe import _core
    from continuum_mhe.estimators.consistency import PINV_RCOND

    rng = np.random.default_rng(seed)
    b = rng.normal(size=(n, min(rank, n))) * scale
    signs = rng.choice([-1.0, 1.0], size=min(rank, n))
    a = (b * signs) @ b.T
    expected = np.linalg.pinv(a, rcond=PINV_RCOND, hermitian=True)
    got = _core.pinv_symmetric(a, PINV_RCOND)
    # two correct pseudo-inverses differ by rounding times the condition number of the
    # eigenvalues they keep (a nearly singular full-rank matrix has entries of 1e5)
    eig = np.abs(np.linalg.eigvalsh(a))
    kept = eig[eig > PINV_RCOND * eig.max(initial=0.0)]
    cond = kept.max() / kept.min() if len(kept) else 1.0
    scale_out = np.abs(expected).max(initial=1.0)
    np.testing.assert_allclose(
        got, expected, rtol=1e-9, atol=max(1e-12, 10 * np.finfo(float).eps * cond) * scale_out
    )


def _consistent_sample(f, rng, x0=None):
    """A state near ``x0`` (or near the straight robot), a covariance and readings
    that agree with the state to half their noise (nz,)."""
    x = (np.zeros(f.nx) if x0 is None else x0) + rng.normal(0, 0.05, f.nx)
    a = rng.normal(0, 0.05, (f.nx, f.nx))
    P = a @ a.T + 1e-3 * np.eye(f.nx)
    z = np.asarray(f.functions.observe(x), dtype=float).ravel()
    z = z + 0.5 * rng.normal(size=f.nz) * np.sqrt(np.diag(f.meas_cov()))
    return x, P, z


def _formulation(name: str):
    robot = Robot((Section(0.11), Section(0.09)), (ImuPlacement(0), ImuPlacement(1)))
    if name == "direct":
        return make_formulation("direct", robot, estimate_gyro_bias=True)
    return make_formulation(name, Robot.single(0.2) if name == "paper" else robot)


@pytest.mark.parametrize("name", ["bend", "direct", "paper"])
def test_the_compiled_check_matches_an_independent_numpy_computation(name) -> None:
    """On random consistent samples (two sections tilt, two raw IMUs with gyro bias, the
    paper formulation with its inputs from the readings), the compiled check's fit,
    NIS, average, the fit's implied NIS and shift, and constant-error covariance
    against numpy on the formulation's own CasADi functions:
    ``x+, F, Q = predict(x0, u, dt)``, ``r, dr/dx = innovate(z, x)``,
    ``S = H P+ H^T + R`` over the valid readings, ``A = pinv(H^T R^-1 H) H^T R^-1`` on
    the states the readings depend on. A reading 30 standard deviations off is
    ``inconsistent``."""
    from continuum_mhe.estimators.consistency import MEMORY, ConsistencyCheck
    from continuum_mhe.quantiles import chi2_quantile

    # the quantiles as docs/options.md states them, not the module's constants: a
    # changed constant is a changed check
    SAMPLE_QUANTILE, SHIFT_QUANTILE = 0.9999, 0.95  # noqa: N806

    f = _formulation(name)
    check = ConsistencyCheck(f)
    R = np.asarray(f.meas_cov(), dtype=float)
    rng = np.random.default_rng(7)

    def innovate(z, x):
        r, J = f.functions.innovate(np.where(np.isfinite(z), z, 0.0), x)
        return np.asarray(r, dtype=float).ravel(), -np.asarray(J, dtype=float)

    x0, P0, z0 = _consistent_sample(f, rng)
    mask0 = f.measurement_mask(z0)
    assert not check.check(0.0, z0, mask0, x0, P0)
    r0, _ = innovate(z0, x0)
    assert check._core.nis == 0.0  # nothing to predict from
    assert check._core.fit == pytest.approx(np.sum(r0**2 / np.diag(R)), rel=1e-12)
    t, dt, expected_scale = 0.0, 0.02, 1.0
    for k in range(6):
        x, P, z = _consistent_sample(f, rng, x0)
        if k == 3:  # a dropout of the first IMU (the paper formulation's only one)
            z[: f.measurement_blocks[0].size] = np.nan
        mask = f.measurement_mask(z)
        rows = np.flatnonzero(mask)
        t += dt
        flagged = check.check(t, z, mask, x, P)
        (x_prev, P_prev, z_prev), (x0, P0, z0) = (x0, P0, z0), (x, P, z)
        if len(rows) == 0:  # nothing judged: only remembered
            assert check._core.dof == 0 and check._core.nis == 0.0 and not flagged
            continue
        u = np.asarray(f.inputs(z_prev, z, dt), dtype=float) if f.nu else np.zeros(0)
        xn, F, Q = (np.asarray(v, dtype=float) for v in f.functions.predict(x_prev, u, dt))
        r_pred, H = innovate(z, xn.ravel())
        Pn = F @ P_prev @ F.T + Q
        S = H[rows] @ Pn @ H[rows].T + R[np.ix_(rows, rows)]
        nis = r_pred[rows] @ np.linalg.solve(S, r_pred[rows])
        r, _ = innovate(z, x)
        assert check._core.dof == len(rows)
        assert check._core.nis == pytest.approx(nis, rel=1e-9)
        assert check._core.fit == pytest.approx(np.sum(r[rows] ** 2 / np.diag(R)[rows]), rel=1e-9)
        expected_scale += (nis / len(rows) - expected_scale) / MEMORY
        assert check.noise_scale == pytest.approx(expected_scale, rel=1e-9)
        # the innovation the fit implies, and the shift that fits the readings, in P
        w = r[rows] / np.diag(R)[rows]
        fit_nis = w @ S @ w
        assert check._core.fit_nis == pytest.approx(fit_nis, rel=1e-9)
        unexplained = False
        if fit_nis > chi2_quantile(SAMPLE_QUANTILE, len(rows)):
            _, Hx = innovate(z, x)
            cols = np.flatnonzero(np.any(Hx[rows] != 0, axis=0))
            Hs, Wr = Hx[np.ix_(rows, cols)], np.diag(1 / np.diag(R)[rows])
            d = np.linalg.pinv(Hs.T @ Wr @ Hs, rcond=1e-9, hermitian=True) @ Hs.T @ Wr @ r[rows]
            Pc = np.linalg.pinv(P[np.ix_(cols, cols)], rcond=1e-9, hermitian=True)
            assert check._core.shift == pytest.approx(d @ Pc @ d, rel=1e-6)
            k = min(len(cols), len(rows))
            unexplained = d @ Pc @ d > chi2_quantile(SHIFT_QUANTILE, k)
        assert flagged == unexplained  # the samples agree with the states otherwise

    # a model error learned below the floor carries the floor; one above it, itself
    gravity_r = np.where(f.gravity_direction_rows(), np.diag(R), 0.0)
    for learned in (0.3, 2.0):
        check.model_error = learned
        model_error = np.maximum(learned * gravity_r, f.model_error_floor())
        bias = np.diag(f.reading_bias_cov()) + np.where(gravity_r > 0, model_error, 0.0)
        rows = np.flatnonzero((f.measurement_mask(z0) > 0) & (bias > 0))
        _, H = innovate(z0, x0)
        cols = np.flatnonzero(np.any(H[rows] != 0, axis=0))
        Hs = H[np.ix_(rows, cols)]
        W = np.diag(1 / np.diag(R)[rows])
        M = Hs.T @ W @ Hs + np.diag(1.0 / f.range_std()[cols] ** 2)
        A = np.linalg.pinv(M, rcond=1e-9, hermitian=True) @ Hs.T @ W
        want = np.zeros((f.nx, f.nx))
        want[np.ix_(cols, cols)] = A @ np.diag(bias[rows]) @ A.T
        got = check.constant_error_cov(z0, f.measurement_mask(z0), x0)
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-14 * np.abs(want).max())

    x, P, z = _consistent_sample(f, rng, x0)
    z[0] += 30 * np.sqrt(R[0, 0])
    assert check.check(t + dt, z, f.measurement_mask(z), x, P)


def test_two_readings_in_a_row_beyond_the_99_percent_quantile_are_inconsistent() -> None:
    """The run rule (docs/options.md): a sample whose statistic (the larger of its NIS and
    fit) lies beyond the chi-square 99 % quantile of its degrees of freedom, after one
    that did too, is ``inconsistent``; one such sample alone is not, nor two apart, nor
    two in a row at the 98.5 % quantile. Each sample's statistic is put at a quantile by
    moving its first reading (bisection) with the previous estimate held, so it does not
    depend on the samples before it."""
    from continuum_mhe.estimators.consistency import ConsistencyCheck
    from continuum_mhe.quantiles import chi2_quantile

    f = _formulation("bend")
    x0, P0, z0 = _consistent_sample(f, np.random.default_rng(7))
    mask = f.measurement_mask(z0)
    dof, std = int(mask.sum()), math.sqrt(f.meas_cov()[0, 0])

    def run(scales: list[float]) -> tuple[list[bool], list[float]]:
        """Flags and statistics of samples 1, 2, ... with the first reading moved by
        ``scales`` of its noise std (the same estimate at each, after sample 0)."""
        check = ConsistencyCheck(f)
        assert not check.check(0.0, z0, mask, x0, P0)
        flags, worst = [], []
        for k, scale in enumerate(scales, start=1):
            z = z0.copy()
            z[0] += scale * std
            flags.append(check.check(0.02 * k, z, mask, x0, P0))
            worst.append(max(check._core.nis, check._core.fit))
        return flags, worst

    def at(quantile: float) -> float:
        a, b = 0.0, 100.0
        for _ in range(60):
            mid = (a + b) / 2
            a, b = (mid, b) if run([mid])[1][0] < chi2_quantile(quantile, dof) else (a, mid)
        return (a + b) / 2

    high, low = at(0.995), at(0.985)
    flags, worst = run([high, high, 0.0, high, 0.0, high])
    assert chi2_quantile(0.99, dof) < worst[0] < chi2_quantile(0.999, dof)
    assert flags == [False, True, False, False, False, False]
    flags, worst = run([low, low, low])
    assert worst[0] < chi2_quantile(0.99, dof) and flags == [False, False, False]


@pytest.mark.parametrize("imu", ["tilt", "raw"])
def test_a_tendon_robots_check_counts_only_the_rows_that_carry_a_residual(imu) -> None:
    """A tendon robot's tension rates are the model's inputs, whose rows of the residual
    are zero at every state: the check's degrees of freedom are the readings whose
    residual moves with the state (found here from the residual's Jacobian: the IMUs'
    readings and the six tensions, 10 with two tilt IMUs and 18 with two raw ones), not
    those rows as well (22 and 30), and a sample whose statistic lies between the
    chi-square 99.99 % quantiles of the two counts is ``inconsistent``."""
    from tendon_helpers import shipped_recording

    from continuum_mhe.estimators.consistency import ConsistencyCheck
    from continuum_mhe.quantiles import chi2_quantile

    f, t, z = shipped_recording("unloaded", imu)
    est = make_estimator("ekf", f)
    (x0, P0), (x1, P1) = (
        (e.state, e.covariance) for e in (est.step(Measurement(t[i], z[i])) for i in (0, 1))
    )
    # the rows whose residual depends on the state at all (the residual's structural
    # Jacobian: the symbolic one of the shared model functions is never built here, as
    # the compiled estimators never build it)
    xs, zs = ca.SX.sym("x", f.nx), ca.SX.sym("z", f.nz)
    dependent = set(ca.jacobian_sparsity(f.measurement_residual_sym(zs, xs), xs).get_triplet()[0])
    moves = np.isin(np.arange(f.nz), sorted(dependent))
    readings = np.concatenate(
        [np.full(b.size, b.kind != "equilibrium") for b in f.measurement_blocks]
    )
    real = int(np.sum(moves & readings & (f.measurement_mask(z[1]) > 0)))
    assert real == {"tilt": 10, "raw": 18}[imu]
    lo, hi = chi2_quantile(0.9999, real), chi2_quantile(0.9999, int(np.sum(readings)))

    def judged(scale: float) -> tuple[bool, float, int]:
        """The check of sample 1 with its first reading moved by ``scale`` of its noise
        std (after sample 0 as estimated): ``(flagged, max(NIS, fit), dof)``."""
        check = ConsistencyCheck(f)
        assert not check.check(t[0], z[0], f.measurement_mask(z[0]), x0, P0)
        zk = z[1].copy()
        zk[0] += scale * math.sqrt(f.meas_cov()[0, 0])
        flagged = check.check(t[1], zk, f.measurement_mask(zk), x1, P1)
        return flagged, max(check._core.nis, check._core.fit), check._core.dof

    a, b = 0.0, 100.0  # a statistic half way between the two quantiles
    for _ in range(60):
        mid = (a + b) / 2
        a, b = (mid, b) if judged(mid)[1] < (lo + hi) / 2 else (a, mid)
    flagged, worst, dof = judged((a + b) / 2)
    assert lo < worst < hi
    assert flagged
    assert dof == real


def test_the_check_takes_the_ekf_updates_evaluation() -> None:
    """The check's prediction from the last estimate is the state the compiled EKF's
    update evaluated the measurement terms at: with every reading valid, each sample
    after the first takes that evaluation (the measurement function's remembered
    one) instead of evaluating anew; where a reading was dropped the update's mask
    differs from the check's, and the check evaluates anew."""
    from continuum_mhe.estimators.fast import node_functions

    robot = Robot((Section(0.15, 3.0), Section(0.15, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=5, seed=4)
    memo = node_functions(f).measurement
    est = make_estimator("ekf", f)
    before = memo.hits
    est.run(rec.t, rec.z)
    n = len(rec.t)
    every = memo.hits - before
    assert every >= n - 2
    z = rec.z.copy()
    z[1::2, 2:4] = np.nan  # IMU 2 lost at every other sample
    est.reset()
    before = memo.hits
    est.run(rec.t, z)
    assert memo.hits - before <= every - (n // 2 - 2)


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_rows_the_readings_contradict_have_a_std_that_covers_the_shift_they_ask_for(
    method: str,
) -> None:
    """One reading of IMU 1 turned upside down (roll plus pi) on a two-section spatial
    recording: the rows whose readings the estimate cannot explain are not ``ok``, and
    their standard deviation grows with the shift the readings ask for, so that the tip
    error stays within 3 of them (their covariance's own does not cover it); rows
    before the flip are as without it, and no ``ok`` row is widened: every ``ok`` row
    has the standard deviation of a run whose readings disagree nowhere."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=10.0, seed=1)
    f = make_formulation("bend", robot)
    z = rec.z.copy()
    i = int(np.searchsorted(rec.t, 6.0))
    z[i, 0] += -math.pi if z[i, 0] > 0 else math.pi
    # the reading taken, not skipped as a glitch: the shift it asks for is what is tested
    taken = RecoverySettings(glitch=None)
    s = make_estimator(method, f, recovery=taken).run(rec.t, z)
    status = np.asarray(s.status)
    err = np.linalg.norm(np.asarray(s.output)[:, :3] - rec.truth[:, :3], axis=1)
    std = np.linalg.norm(np.asarray(s.output_std, dtype=float)[:, :3], axis=1)
    flagged = status == "inconsistent"
    assert flagged.any() and np.all(err[flagged] <= 3.0 * std[flagged])
    assert np.max(err[flagged]) > 0.02  # the flip put them far off
    clean = make_estimator(method, f, recovery=taken).run(rec.t, rec.z)
    before = rec.t < 6.0
    np.testing.assert_allclose(
        np.asarray(s.output_std)[before], np.asarray(clean.output_std)[before]
    )
    ok = status == "ok"
    assert np.all(std[ok] <= 2.0 * np.max(std[before]))  # no ok row widened by the shift
