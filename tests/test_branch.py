"""The MHE's branch check (estimators/branch.py): a window stuck on the wrong branch is
restarted to a strictly lower cost, clean data is left alone, and both backends agree."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.branch import FORGET
from continuum_mhe.estimators.fast import solve_window, window_cost
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.io.estimate_csv import write_estimates
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.results import EstimateSeries
from continuum_mhe.settings import MHESettings, RecoverySettings
from continuum_mhe.simulation.scenarios import simulate_robot

TWO = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
N = 10
#: a still robot, both sections bent far (section 1 at 85 deg, section 2 at 100 deg)
TRUTH = np.array([-1.115, -0.972, 1.615, 0.706, 0.0, 0.0, 0.0, 0.0])
#: a start on the far branch of section 2, at its bound: the warm-started solver stays
#: in that basin (a local minimum at the bound, found by a scan of random starts)
WRONG = np.array([-1.57, -1.485, -2.979, -0.355, 0.0, 0.0, 0.0, 0.0])


def _filled_window(solver: str) -> MovingHorizonEstimator:
    f = make_formulation("bend", TWO)
    est = MovingHorizonEstimator(f, MHESettings(horizon=N, solver=solver, branch_check=True))
    z = np.asarray(f.functions.observe(TRUTH), dtype=float).ravel()
    for i in range(N):
        est.step(Measurement(0.05 * i, z))
    return est


@pytest.mark.parametrize("solver", ["fast", "ipopt"])
def test_branch_check_leaves_a_wrong_local_minimum(solver: str) -> None:
    est = _filled_window(solver)
    assert est.inference.branch is not None
    problem = est.inference.window_problem()
    X_wrong, status = est.inference._solve(problem, np.tile(WRONG, (N, 1)))
    assert status == "ok"  # a KKT point of the window problem ...
    wrong_cost = est.inference.window_cost(problem, X_wrong)
    assert est.inference.branch.implausible(problem, X_wrong)  # ... whose fit is implausible
    X, status = est.inference._check_branch(problem, X_wrong, status)
    assert status == "branch-restart"
    cost = est.inference.window_cost(problem, X)
    assert cost < wrong_cost - 1.0
    err = np.abs(X[-1, :4] - TRUTH[:4]).max()
    assert err < 1e-4 < np.abs(X_wrong[-1, :4] - TRUTH[:4]).max()
    assert est.inference.branch.stats.restarted == 1


def test_a_start_the_fast_sqp_does_not_certify_is_no_candidate(monkeypatch) -> None:
    """On the fast backend, a restart from which the SQP certifies no answer is left
    out of the check, not solved again by IPOPT: with no start certified, the warm
    answer stays and IPOPT is never called."""
    from dataclasses import replace

    est = _filled_window("fast")
    inference = est.inference
    problem = inference.window_problem()
    X_wrong, status = inference._solve(problem, np.tile(WRONG, (N, 1)))
    assert status == "ok" and inference.branch.implausible(problem, X_wrong)
    solve_fast = inference._solve_fast

    def uncertified(*args: object) -> object:
        return replace(solve_fast(*args), converged=False, outcome="max-iter")

    def no_ipopt(*args: object) -> None:
        raise AssertionError("IPOPT solved a branch-check start")

    monkeypatch.setattr(inference, "_solve_fast", uncertified)
    monkeypatch.setattr(inference, "_solve_ipopt", no_ipopt)
    X, status = inference._check_branch(problem, X_wrong, status)
    assert status == "ok" and np.array_equal(X, X_wrong)
    assert inference.branch.stats.fired == 1 and inference.branch.stats.restarted == 0


@pytest.mark.parametrize("solver", ["fast", "ipopt"])
def test_a_wrong_arrival_prior_is_forgotten_when_no_restart_helps(solver: str) -> None:
    f = make_formulation("bend", TWO)
    est = MovingHorizonEstimator(f, MHESettings(horizon=N, solver=solver, branch_check=True))
    z = np.asarray(f.functions.observe(TRUTH), dtype=float).ravel()
    for i in range(N + 3):  # a full, sliding window
        est.step(Measurement(0.05 * i, z))
    est.inference._set_prior(WRONG.copy(), np.eye(f.nx) * 0.01**2)  # a confident wrong prior
    problem = est.inference.window_problem()
    X_wrong, status = est.inference._solve(problem, np.tile(WRONG, (N, 1)))
    assert est.inference.branch is not None and est.inference.branch.implausible(problem, X_wrong)
    fit_wrong, _ = est.inference.branch.measurement_cost(problem, X_wrong)
    X, status = est.inference._check_branch(problem, X_wrong, status)
    assert status == "branch-restart" and est.inference.branch.stats.prior_forgotten == 1
    fit, _ = est.inference.branch.measurement_cost(problem, X)
    assert fit < 0.5 * fit_wrong
    assert np.abs(X[-1, :4] - TRUTH[:4]).max() < np.abs(X_wrong[-1, :4] - TRUTH[:4]).max()
    assert_allclose(est.inference._xbar, f.project(X[0]))  # the prior re-anchored on the answer
    assert_allclose(est.inference._P, np.eye(f.nx) * 0.01**2 * FORGET)


def test_a_branch_restart_reaches_the_estimate_file(tmp_path: Path) -> None:
    """The status reaches the user: a step warm-started on the wrong branch returns an
    estimate with status ``branch-restart`` near the truth, trusted (not turned
    ``uncertain``, standard deviations given), and the estimate file writes it and reads
    it back (its reader accepts only the statuses of ``STATUS_MEANINGS``)."""
    f = make_formulation("bend", TWO)
    # the same reading at every sample (a robot held still, read without noise): no
    # freeze check, which would take it for a frozen IMU
    recovery = RecoverySettings(freeze=None)
    est = make_estimator("mhe", f, MHESettings(horizon=N, branch_check=True), recovery)
    assert isinstance(est, MovingHorizonEstimator)
    z = np.asarray(f.functions.observe(TRUTH), dtype=float).ravel()
    estimates = []
    for i in range(N + 2):
        if i == N - 1:  # the full window's warm start on the far branch
            est.inference._X, est.inference._X_last = np.tile(WRONG, (N, 1)), None
        estimates.append(est.step(Measurement(0.05 * i, z)))
    assert [e.status for e in estimates] == ["uncertain"] + ["ok"] * (N - 2) + [
        "branch-restart",
        "ok",
        "ok",
    ]
    restarted = estimates[N - 1]
    assert restarted.state is not None and np.abs(restarted.state[:4] - TRUTH[:4]).max() < 1e-4
    assert restarted.output_std is not None and np.all(np.isfinite(restarted.output_std))
    series = EstimateSeries.from_estimates("mhe", estimates, f.outputs)
    write_estimates(tmp_path / "e.csv", series)
    table = read_state_table(tmp_path / "e.csv")
    assert list(table.status) == list(series.status)
    assert table.names == tuple(o.name for o in f.outputs)
    assert_allclose(table.values, series.output, rtol=1e-9, atol=1e-12)


@pytest.fixture(scope="module")
def clean_recording():  # type: ignore[no-untyped-def]
    return simulate_robot("spatial", TWO, duration=4.0, dt=0.05, seed=3)


def test_no_restart_on_clean_model_consistent_data(clean_recording) -> None:  # type: ignore[no-untyped-def]
    rec = clean_recording
    f = make_formulation("bend", TWO)
    runs = {}
    for check in (False, True):
        est = MovingHorizonEstimator(f, MHESettings(horizon=N, branch_check=check))
        runs[check] = est.run(rec.t, rec.z)
    assert "branch-restart" not in set(runs[True].status)
    assert np.array_equal(runs[True].output, runs[False].output)


def test_fast_and_ipopt_agree_with_the_check_on(clean_recording) -> None:  # type: ignore[no-untyped-def]
    rec = clean_recording
    f = make_formulation("bend", TWO)
    out = {}
    for solver in ("fast", "ipopt"):
        est = MovingHorizonEstimator(f, MHESettings(horizon=N, solver=solver, branch_check=True))
        s = est.run(rec.t[:30], rec.z[:30])
        out[solver] = s
    assert list(out["fast"].status) == list(out["ipopt"].status)
    names = [o.name for o in f.outputs]
    angles = [i for i, n in enumerate(names) if n.startswith("theta")]
    assert_allclose(out["fast"].output[:, angles], out["ipopt"].output[:, angles], atol=1e-6)


def test_the_check_is_on_by_default_for_tilt_only_and_the_cli_sets_it() -> None:
    import argparse

    from continuum_mhe.cli.method_options import add_mhe_options, mhe_settings_from_args

    p = argparse.ArgumentParser()
    add_mhe_options(p)
    assert mhe_settings_from_args(p.parse_args([])).branch_check is None
    assert mhe_settings_from_args(p.parse_args(["--branch-check"])).branch_check is True
    assert mhe_settings_from_args(p.parse_args(["--no-branch-check"])).branch_check is False
    assert MHESettings().branch_check is None
    tilt, gyros = make_formulation("bend", TWO), make_formulation("direct", TWO)
    assert MovingHorizonEstimator(tilt).inference.branch is not None  # tilt only: on
    assert MovingHorizonEstimator(gyros).inference.branch is None  # the gyros hold it
    assert MovingHorizonEstimator(make_formulation("bend")).inference.branch is None  # one
    on = MovingHorizonEstimator(gyros, MHESettings(branch_check=True))
    assert on.inference.branch is not None
    off = MovingHorizonEstimator(tilt, MHESettings(branch_check=False))
    assert off.inference.branch is None


ROD = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"


def test_the_estimate_file_says_whether_the_branch_check_ran(tmp_path) -> None:
    """The ``# model`` line (which ``--config`` does not apply) says whether the MHE ran
    the branch check, as the input chose it where no option set it: on for two sections
    with tilt IMUs, off with their gyros and with a robust loss, absent for a filter.
    An estimate file of raw IMUs given as ``--config`` to a tilt recording leaves the
    tilt recording's own choice (on)."""
    import tomllib

    from continuum_mhe.cli import main

    def ran(*args: str) -> bool | None:
        out = tmp_path / "e.csv"
        assert main(["estimate", *args, "--robot", "two-section", "-o", str(out),
                     "--overwrite"]) == 0  # fmt: skip
        line = next(ln for ln in out.read_text().splitlines() if ln.startswith("# model"))
        return tomllib.loads(line[2:])["model"].get("branch-check")

    tilt, raw = tmp_path / "tilt.csv", tmp_path / "raw.csv"
    for name, path in (("planar-s_tilt", tilt), ("planar-s_raw", raw)):
        path.write_text("\n".join((ROD / f"{name}.csv").read_text().splitlines()[:81]) + "\n")
    assert ran(str(tilt)) is True
    assert ran(str(raw)) is False
    assert ran(str(tilt), "--loss", "huber") is False
    assert ran(str(tilt), "--method", "ekf") is None
    profile = tmp_path / "raw_est.csv"
    assert main(["estimate", str(raw), "--robot", "two-section", "-o", str(profile)]) == 0
    assert ran(str(tilt), "--config", str(profile)) is True


def test_the_default_holds_the_branch_where_the_mhe_without_the_check_flips() -> None:
    """The first 200 samples of the torsion-stiff two-section Cosserat rod, tilt only:
    while section 1 passes 90 to 110 degrees (samples 124 to 145, where every estimator
    loses the shape), the MHE without the check settles on section 2's far branch at
    its bound and stays there (over 150 mm off through samples 146 to 199); with the
    defaults the check takes it back to the rod's shape."""
    f = make_formulation("bend", read_robot("two-section"))
    data = np.loadtxt(ROD / "spatial-stiff-torsion_tilt.csv", delimiter=",", skiprows=1)[:200]
    truth = read_state_table(ROD / "spatial-stiff-torsion_truth.csv").values[:200, :3]
    err = {}
    for check in (False, True):
        est = MovingHorizonEstimator(f, MHESettings(branch_check=check))
        s = est.run(data[:, 0], data[:, 1:])
        err[check] = np.linalg.norm(s.output[:, :3] - truth, axis=1)[146:] * 1e3  # mm
    assert err[False].mean() > 150.0
    assert err[True].mean() < 30.0
    assert err[True].max() < 0.25 * err[False].max()


def test_the_default_check_costs_no_evaluation_on_clean_data(clean_recording) -> None:  # type: ignore[no-untyped-def]
    """On model-consistent data the fast SQP's own window cost shows every window
    plausible: the default check evaluates no residual and changes nothing."""
    rec = clean_recording
    f = make_formulation("bend", TWO)
    est = MovingHorizonEstimator(f, MHESettings(horizon=N))
    s = est.run(rec.t, rec.z)
    branch = est.inference.branch
    assert branch is not None
    assert branch.stats.checked == len(rec.t)
    assert branch.stats.evaluated == 0
    off = MovingHorizonEstimator(f, MHESettings(horizon=N, branch_check=False)).run(rec.t, rec.z)
    assert np.array_equal(s.output, off.output)


def _compiled_and_python_check(f, t: np.ndarray, z: np.ndarray, settings: MHESettings):  # type: ignore[no-untyped-def]
    """The MHE with the compiled first test of the check, and the same MHE with every
    certified window through the Python check: their runs and branch checks, after
    asserting that the two agree on every estimate, standard deviation, status and
    count of the check."""
    compiled = MovingHorizonEstimator(f, settings)
    python = MovingHorizonEstimator(f, settings)
    window = python.inference._window
    assert len(window.plausible_limit) == python.inference.settings.horizon * f.nz + 1
    window.plausible_limit = np.empty(0)  # every certified window through the Python hook
    a, b = compiled.run(t, z), python.run(t, z)
    assert np.array_equal(a.output, b.output)
    assert np.array_equal(a.output_std, b.output_std, equal_nan=True)
    assert np.array_equal(a.status, b.status)
    branch_a, branch_b = compiled.inference.branch, python.inference.branch
    assert branch_a is not None and branch_b is not None
    assert branch_a.stats == branch_b.stats
    assert branch_a.stats.checked == len(t)
    return compiled, branch_a.stats


def test_the_compiled_first_test_keeps_the_answers_of_the_python_check(clean_recording) -> None:  # type: ignore[no-untyped-def]
    """The compiled step applies the check's first test (``plausible_limit``) and keeps a
    plausible window itself: the same estimates, standard deviations and statuses as the
    Python check run on every window, and the same count of checked windows; on clean
    data every window is kept in compiled code."""
    rec = clean_recording
    compiled, stats = _compiled_and_python_check(
        make_formulation("bend", TWO), rec.t, rec.z, MHESettings(horizon=N)
    )
    assert stats.evaluated == 0
    assert compiled.inference._window.plausible_kept == 0  # synced into the stats


def test_the_compiled_first_test_passes_on_the_windows_the_python_check_restarts() -> None:
    """The same comparison where the check fires: the first 200 samples of the
    torsion-stiff rod with tilt IMUs (above), whose implausible windows the check
    evaluates and restarts. The compiled first test hands each of them to the Python
    check, which restarts the same windows."""
    f = make_formulation("bend", read_robot("two-section"))
    data = np.loadtxt(ROD / "spatial-stiff-torsion_tilt.csv", delimiter=",", skiprows=1)[:200]
    _, stats = _compiled_and_python_check(f, data[:, 0], data[:, 1:], MHESettings())
    assert stats.evaluated > 0 and stats.restarted > 0


def test_the_section_tilt_inverse_recovers_random_bends_exactly() -> None:
    """``initial_state`` of a two-section robot (the branch check's start from the
    measurements): each section's bend from its IMU's gravity direction in closed
    form, checked on random bends within the bounds against the forward model."""
    f = make_formulation("bend", TWO)
    rng = np.random.default_rng(7)
    for _ in range(200):
        theta = rng.uniform(0.05, 2.9, 2)
        phi = rng.uniform(-np.pi, np.pi, 2)
        x = np.zeros(8)
        x[[0, 2]], x[[1, 3]] = theta * np.cos(phi), theta * np.sin(phi)
        z = np.asarray(f.functions.observe(x), dtype=float).ravel()
        assert_allclose(f.initial_state(z), x, atol=1e-9)


def test_where_the_readings_cannot_tell_the_branch_the_window_answer_is_its_minimum() -> None:
    """The spatial rod's true PCC bends replayed through the tilt model (2 deg noise),
    samples 330 to 400: at sample 400 section 1 is at 110 degrees and section 2 bends
    back through ``theta_2 = 2 theta_1 - pi`` in section 1's plane, where IMU 2's
    gravity is the mirror of IMU 1's and a whole curve of section-2 bends gives the
    same reading. The MHE with its defaults and the EKF are both tens of mm off there,
    and the MHE's answer is not a wrong local minimum: a solve of the same window
    started from the true trajectory converges to it, and the true trajectory's window
    cost is higher (the rod turns faster than the process noise expects). No restart
    or hypothesis of the same problem reaches the true shape there."""
    f = make_formulation("bend", read_robot("two-section"))
    table = read_state_table(ROD / "spatial_truth.csv")
    cols = list(table.names)
    theta = table.values[:, [cols.index("theta_1"), cols.index("theta_2")]]
    phi = table.values[:, [cols.index("phi_1"), cols.index("phi_2")]]
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=2).reshape(-1, 4)
    x = np.concatenate([bends, np.gradient(bends, table.t, axis=0)], axis=1)[330:401]
    t = table.t[330:401]
    h = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z = h + np.random.default_rng(1).normal(size=h.shape) * np.radians(2.0)
    truth = f.output(x)[-1, :3]
    ekf = make_estimator("ekf", f).run(t, z).output[-1, :3]
    est = MovingHorizonEstimator(f)
    mhe = est.run(t, z).output[-1, :3]
    assert np.linalg.norm(mhe - truth) > 0.03 and np.linalg.norm(ekf - truth) > 0.03  # m
    inf = est.inference
    assert inf._fast is not None and inf._X is not None
    problem, answer, n = inf.window_problem(), inf._X, inf.settings.horizon
    from_truth = solve_window(inf._fast, problem, x[-n:], inf.fast_options)
    assert from_truth.converged
    assert_allclose(from_truth.X[-1, :4], answer[-1, :4], atol=1e-6)
    assert window_cost(inf._fast, problem, x[-n:]) > window_cost(inf._fast, problem, answer) + 10


def test_the_ekf_and_prior_candidates_equal_the_casadi_filters_steps() -> None:
    """The EKF and propagated-prior starts, made on the compiled node, against the same
    filter written on the formulation's CasADi functions (``ekf_update`` then
    ``ekf_predict`` from the projected state) on a sliding window of a moving robot with
    a dropout: the same trajectories to rounding."""
    from continuum_mhe.estimators.kalman import ekf_predict, ekf_update

    f = make_formulation("bend", TWO)
    rec = simulate_robot("spatial", TWO, duration=1.5, seed=3)
    est = MovingHorizonEstimator(f, MHESettings(horizon=N, branch_check=True))
    for i in range(len(rec.t)):
        est.step(Measurement(float(rec.t[i]), rec.z[i]))
    est.inference._set_prior(WRONG.copy(), np.eye(f.nx) * 0.1**2)
    p = est.inference.window_problem()
    p = type(p)(**{**vars(p), "zmask": p.zmask.copy()})
    p.zmask[4, :2] = 0.0  # IMU 1 dropped out on one node
    check = est.inference.branch
    assert check is not None
    x, P, R = p.xbar.copy(), np.linalg.inv(p.arrival[0]), f.meas_cov()
    expected = np.empty((N, f.nx))
    for i in range(N):
        x, P = ekf_update(f, x, P, p.z[i], R, p.zmask[i])
        expected[i] = f.project(x)
        if i < N - 1:
            x, P = ekf_predict(f.functions, expected[i], P, p.u[i], float(p.dt[i]))
    ekf = check._ekf_window(p)
    assert_allclose(ekf, expected, rtol=0, atol=1e-12)
    assert np.abs(ekf - p.xbar).max() > 0.1  # the readings moved it far from the prior
    prior = [p.xbar]
    for i in range(N - 1):
        xn = np.asarray(f.functions.transition(prior[-1], p.u[i], p.dt[i]), float).ravel()
        prior.append(f.project(xn))
    assert_allclose(check._propagate_prior(p), np.array(prior), rtol=0, atol=1e-12)
