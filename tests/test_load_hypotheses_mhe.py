"""The MHE on IPOPT of a tendon robot as two hypotheses, loaded and free of load
(:class:`~continuum_mhe.estimators.load_hypotheses.LoadHypothesesHorizonEstimator`):
the free-of-load window's conditioning on the load held at zero, the windows' reading
log-density that weighs them, and the estimates on a shipped recording."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from tendon_helpers import DATA, shipped_recording

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement, Status
from continuum_mhe.estimators.kalman import ekf_predict, ekf_update
from continuum_mhe.estimators.load_hypotheses import (
    LoadHypothesesHorizonEstimator,
    LoadHypothesesInference,
    UnloadedHorizonInference,
)
from continuum_mhe.estimators.mhe import (
    MovingHorizonEstimator,
    MovingHorizonInference,
    ReferenceWindow,
)
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.results import EstimateSeries
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate

#: a short window and the first samples of a shipped recording: IPOPT solves each
#: window of the shooting model in a fraction of a second at this horizon
HORIZON = 3
SAMPLES = 24
#: IPOPT at that horizon, for the tests that solve windows: the first windows of
#: ``unloaded`` (every tendon slack) stop at IPOPT's iteration limit whatever it is (the
#: exact clip's kink: the smooth clip's test below), and every later one converges in
#: fewer than 10 iterations; this limit gives the default limit's free-of-load count and
#: tip errors, without the 90 iterations more on each of those first windows
IPOPT = MHESettings(horizon=HORIZON, solver="ipopt", max_iter=10)


def _shipped(scenario: str, imu: str) -> tuple[TendonFormulation, np.ndarray, np.ndarray]:
    """The first :data:`SAMPLES` samples of a shipped recording: ``(formulation, t, z)``."""
    f, t, z = shipped_recording(scenario, imu)
    return f, t[:SAMPLES], z[:SAMPLES]


def _tip_errors(f: TendonFormulation, series: EstimateSeries, scenario: str) -> np.ndarray:
    """Tip error (m) of every row of ``series`` against the recording's truth."""
    lines = [ln for ln in (DATA / f"{scenario}_truth.csv").read_text().splitlines()]
    lines = [ln for ln in lines if not ln.startswith("#")]
    names = lines[0].split(",")
    truth = np.loadtxt(lines[1 : 1 + SAMPLES], delimiter=",", ndmin=2)
    cols = [o.name for o in f.outputs]
    out = np.asarray(series.output, dtype=float)
    tip = ("x", "y", "z")
    e = out[:, [cols.index(n) for n in tip]] - truth[:, [names.index(n) for n in tip]]
    return np.asarray(np.linalg.norm(e, axis=1), dtype=float)


def test_the_free_of_load_prior_is_the_gaussian_conditional_on_a_zero_load() -> None:
    """The free-of-load window's arrival prior, conditioned on the load states at zero,
    against the conditional from the precision matrix (an independent form): the other
    states' mean ``mu_k + (Lambda_kk)^-1 Lambda_kh mu_h`` and covariance
    ``(Lambda_kk)^-1``; the load states zero and uncorrelated. A prior that holds the
    load certain (zero rows, as the start free of load gives) leaves the others as
    they are."""
    f, _, _ = _shipped("unloaded", "tilt")
    inference = UnloadedHorizonInference(f, MHESettings(horizon=HORIZON, solver="ipopt"))
    rng = np.random.default_rng(4)
    nx, h = f.nx, np.asarray(f.load_states)
    k = np.setdiff1d(np.arange(nx), h)
    A = rng.normal(size=(nx, nx))
    P = A @ A.T + 0.1 * np.eye(nx)
    x = rng.normal(size=nx)
    xc, Pc = inference.conditioned(x, P)
    L = np.linalg.inv(P)
    cov_k = np.linalg.inv(L[np.ix_(k, k)])
    assert np.allclose(Pc[np.ix_(k, k)], cov_k, rtol=1e-8, atol=1e-10)
    assert np.allclose(xc[k], x[k] + cov_k @ L[np.ix_(k, h)] @ x[h], rtol=1e-8, atol=1e-10)
    assert np.all(xc[h] == 0.0) and np.all(Pc[np.ix_(k, h)] == 0.0)
    assert np.all(np.diag(Pc)[h] > 0.0)  # invertible: the window's prior weight
    P_start = P.copy()
    P_start[h, :] = 0.0
    P_start[:, h] = 0.0
    xs, Ps = inference.conditioned(x, P_start)
    assert np.array_equal(xs[k], x[k]) and np.allclose(Ps[np.ix_(k, k)], P[np.ix_(k, k)])


def test_the_free_of_load_prior_slides_as_the_exact_conditional() -> None:
    """Each slide of the free-of-load window's arrival prior is the exact Gaussian
    recipe with the load held at zero: the EKF update with the leaving sample, the
    conditional on a zero load, the prediction with the process noise of a held load,
    the conditional again (written here from the CasADi model); the load states zero
    and uncorrelated with the others after it."""
    f, t, z = _shipped("unloaded", "tilt")
    inference = UnloadedHorizonInference(f, IPOPT)
    window = inference._window
    assert isinstance(window, ReferenceWindow)
    h = np.asarray(f.load_states)
    R = f.meas_cov()
    checked = 0
    for i in range(HORIZON + 3):
        full = window.k == HORIZON
        if full:  # this sample's step slides the prior over the leaving sample
            x, P = window.xbar.copy(), window.P.copy()
            zl, ml, ul, dtl = (
                window.zw[0].copy(),
                window.zmask[0].copy(),
                window.uw[0].copy(),
                float(window.dt[0]),
            )
        inference.infer(Measurement(float(t[i]), z[i]))
        if not full:
            continue
        x, P = ekf_update(f, x, P, zl, R, ml)
        x, P = inference.conditioned(x, P)
        Qh = f.process_cov(dtl)
        Qh[h, :] = 0.0
        Qh[:, h] = 0.0
        xn, F, _ = (np.asarray(v, dtype=float) for v in f.functions.predict(x, ul, dtl))
        F = F.reshape(f.nx, f.nx)
        want_x, want_P = inference.conditioned(xn.ravel(), F @ P @ F.T + Qh)
        assert np.allclose(window.xbar, f.project(want_x), rtol=1e-9, atol=1e-12)
        scale = np.sqrt(np.outer(np.diag(want_P), np.diag(want_P)))  # as correlations
        assert np.all(np.abs(window.P - want_P) <= 1e-9 * scale)
        assert np.all(window.xbar[h] == 0.0) and np.all(
            window.P[np.ix_(np.setdiff1d(np.arange(f.nx), h), h)] == 0.0
        )
        checked += 1
    assert checked == 3


def test_a_free_of_load_answer_has_its_own_status_and_unsolved_windows_weigh_nothing() -> None:
    """The answer taken from the free-of-load window carries that window's status (the
    loaded one's here ``not-converged``), and the loaded window's answer its own; a
    window's prediction from an answer that did not converge gives no density (NaN),
    nor does a reading either window rejects as an outlier move the evidence."""
    f, t, z = _shipped("unloaded", "tilt")
    inference = LoadHypothesesInference(f, MHESettings(horizon=HORIZON, solver="ipopt"))
    x, P = np.zeros(f.nx), np.eye(f.nx)

    def answers(status: Status):  # type: ignore[no-untyped-def]
        return lambda m: (x, P, status)

    inference.unloaded.infer = answers(Status.OK)  # type: ignore[method-assign]
    inference.loaded.infer = answers(Status.NOT_CONVERGED)  # type: ignore[method-assign]
    inference.unloaded.log_likelihood, inference.loaded.log_likelihood = 10.0, 0.0
    inference.evidence = 50.0
    assert inference.infer(Measurement(1.0, z[0]))[2] == Status.OK and inference.unloaded_chosen
    inference.evidence = -50.0
    assert inference.infer(Measurement(1.02, z[1]))[2] == Status.NOT_CONVERGED
    assert not inference.unloaded_chosen
    inference.loaded.outlier = lambda: True  # type: ignore[method-assign]
    before = inference.evidence
    inference.infer(Measurement(1.04, z[2]))
    assert inference.evidence == before
    # a real window: no density from a previous answer that did not converge
    mhe = MovingHorizonInference(f, IPOPT)
    mhe.tracks_likelihood = True
    mhe.infer(Measurement(float(t[0]), z[0]))
    mhe._answer_status = Status.NOT_CONVERGED
    mhe.infer(Measurement(float(t[1]), z[1]))
    assert math.isnan(mhe.log_likelihood)
    mhe._answer_status = Status.OK
    mhe.infer(Measurement(float(t[2]), z[2]))
    assert math.isfinite(mhe.log_likelihood)


def test_the_mhe_weighs_its_reading_by_the_previous_answers_prediction() -> None:
    """With ``tracks_likelihood`` the MHE's ``log_likelihood`` is ``-(r^T S^-1 r +
    log|S|) / 2`` of the new reading's innovation ``r`` at the previous answer's
    prediction and ``S = H P H^T + R``, formed here from the CasADi model; NaN at the
    start."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=1.0, noise_deg=2.0, seed=3)
    mhe = MovingHorizonInference(f, MHESettings(horizon=5))
    mhe.tracks_likelihood = True
    x, P, _ = mhe.infer(Measurement(float(rec.t[0]), rec.z[0]))
    assert math.isnan(mhe.log_likelihood)
    fn = f.functions
    for i in range(1, 6):
        assert x is not None and P is not None
        dt = float(rec.t[i] - rec.t[i - 1])
        xp, Pp = ekf_predict(fn, x, P, f.inputs(rec.z[i - 1], rec.z[i], dt), dt)
        x, P, _ = mhe.infer(Measurement(float(rec.t[i]), rec.z[i]))
        r = np.asarray(fn.innovate(rec.z[i], xp)[0], dtype=float).ravel()
        H = -np.asarray(fn.innovate(rec.z[i], xp)[1], dtype=float)
        S = H @ Pp @ H.T + f.meas_cov()
        want = -0.5 * (r @ np.linalg.solve(S, r) + np.linalg.slogdet(S)[1])
        assert mhe.log_likelihood == pytest.approx(want, rel=1e-9, abs=1e-9)


def test_make_estimator_gives_a_tendon_robot_the_mhe_on_both_hypotheses() -> None:
    """``make_estimator("mhe", ...)`` on a tendon robot with IPOPT's backend gives the two
    hypotheses; without the free-of-load hypothesis, the single loaded MHE; a PCC robot
    the plain MHE."""
    f, _, _ = _shipped("unloaded", "tilt")
    ipopt = MHESettings(horizon=HORIZON, solver="ipopt")
    assert isinstance(make_estimator("mhe", f, ipopt), LoadHypothesesHorizonEstimator)
    single = make_estimator("mhe", replace(f, free_of_load_hypothesis=False), ipopt)
    assert type(single) is MovingHorizonEstimator
    assert type(make_estimator("mhe", make_formulation("bend"), ipopt)) is MovingHorizonEstimator
    with pytest.raises(ValueError, match="IPOPT"):
        UnloadedHorizonInference(f, MHESettings(horizon=HORIZON))


def test_an_unloaded_robot_is_estimated_free_of_load_by_the_mhe() -> None:
    """The start of the shipped ``unloaded`` recording (tilt IMUs): the MHE on both
    hypotheses takes it as free of load after its first readings, reports a tip force of
    exactly 0 N there with a positive standard deviation, and its tip is closer to the
    truth than the single loaded MHE's, which takes part of the IMUs' errors for a tip
    force (measured on the whole recording at N = 10: docs/tendon-studies.md)."""
    f, t, z = _shipped("unloaded", "tilt")
    ipopt = IPOPT
    est = make_estimator("mhe", f, ipopt)
    assert isinstance(est, LoadHypothesesHorizonEstimator)
    series = est.run(t, z)
    assert est.inference.free_of_load_samples >= SAMPLES // 2  # 18 of 24 when measured
    cols = [o.name for o in f.outputs]
    force = [cols.index(n) for n in ("fx", "fy", "fz")]
    out, std = np.asarray(series.output, dtype=float), np.asarray(series.std, dtype=float)
    assert np.all(out[-5:, force] == 0.0) and np.all(std[-5:, force] > 0.0)
    single = make_estimator("mhe", replace(f, free_of_load_hypothesis=False), ipopt)
    late = slice(SAMPLES // 2, None)
    tip = _tip_errors(f, series, "unloaded")[late].mean()
    single_tip = _tip_errors(f, single.run(t, z), "unloaded")[late].mean()
    assert tip < 0.5 * single_tip


def test_a_smooth_slack_clip_lets_ipopt_converge_on_a_start_with_slack_tendons() -> None:
    """``slack_smoothing``: the clip of a tension at zero, exact by default with two IMUs
    (1 mN wide with one), smooth over the width given (a slack tendon pulls half of it);
    with 1 mN the MHE on IPOPT's
    first windows of ``unloaded`` (every tendon slack: with the exact clip their optimum
    sits on its kink, and the first five stop at IPOPT's iteration limit,
    ``not-converged``) converge: every row after the first is ``ok``."""
    f, t, z = _shipped("unloaded", "tilt")
    from continuum_mhe.model.tendon import SINGLE_IMU_SLACK_SMOOTHING

    exact, smooth = f.statics, replace(f, slack_smoothing=1e-3).statics
    assert (f.slack_smoothing, f.slack_width) == (None, 0.0)
    one = replace(f, robot=replace(f.robot, imus=f.robot.imus[1:]))
    assert one.slack_width == SINGLE_IMU_SLACK_SMOOTHING == 1e-3
    assert one.statics.slack_smoothing == 1e-3
    assert replace(one, slack_smoothing=0.0).slack_width == 0.0
    assert float(exact.acting(0.0)) == 0.0 and float(exact.acting(-0.2)) == 0.0
    assert float(smooth.acting(0.0)) == pytest.approx(0.5e-3, rel=1e-12)
    assert float(smooth.acting(1.0)) == pytest.approx(1.0 + 0.25e-6, rel=1e-9)
    assert float(smooth.acting(-1.0)) == pytest.approx(0.25e-6, rel=1e-6)
    with pytest.raises(ValueError, match="slack_smoothing"):
        replace(f, slack_smoothing=-1e-3)
    est = make_estimator(
        "mhe", replace(f, slack_smoothing=1e-3), MHESettings(horizon=5, solver="ipopt")
    )
    statuses = [str(s) for s in est.run(t[:8], z[:8]).status]
    assert statuses[1:] == ["ok"] * 7
