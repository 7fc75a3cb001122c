"""The EKF of a tendon robot as two hypotheses, loaded and free of load
(:mod:`continuum_mhe.estimators.load_hypotheses`), and the compiled step's innovation
log-density it weighs them by."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
from tendon_helpers import DATA, EkfRun, default_ekf_run, shipped_recording

from continuum_mhe.errors import UnobservableShapeWarning
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import (
    CompiledExtendedKalmanInference,
    ExtendedKalmanFilter,
    ekf_predict,
)
from continuum_mhe.estimators.load_hypotheses import (
    LoadHypothesesInference,
    LoadHypothesesKalmanFilter,
    mixture,
)
from continuum_mhe.estimators.sensor_health import UNOBSERVED_AFTER
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.simulation.scenarios import simulate


def _truth(scenario: str) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in (DATA / f"{scenario}_truth.csv").read_text().splitlines()]
    lines = [ln for ln in lines if not ln.startswith("#")]
    return lines[0].split(","), np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def _errors(f: TendonFormulation, series, scenario: str) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Tip error (m) and tip-force error (N) of every row."""
    names, truth = _truth(scenario)
    cols = [o.name for o in f.outputs]
    out = np.asarray(series.output, dtype=float)

    def err(c: tuple[str, ...]) -> np.ndarray:
        e = out[:, [cols.index(n) for n in c]] - truth[:, [names.index(n) for n in c]]
        return np.asarray(np.linalg.norm(e, axis=1), dtype=float)

    return err(("x", "y", "z")), err(("fx", "fy", "fz"))


@pytest.fixture(scope="module")
def default_ekf() -> Callable[[str, str], EkfRun]:
    """``default_ekf(scenario, imu)``: the :class:`EkfRun` of that shipped recording,
    run once a test process (:func:`tendon_helpers.default_ekf_run`) and shared by the
    tests that run the default EKF over the whole of it."""
    return default_ekf_run


@dataclass
class Stepped:
    """:class:`LoadHypothesesInference` stepped sample by sample over a whole shipped
    recording: at each sample, whether the free-of-load hypothesis was chosen, and the
    free-of-load filter's load entries after it (state, covariance rows and columns;
    None where it had no state); the loaded filter's last state."""

    f: TendonFormulation
    t: np.ndarray
    chosen: list[bool]
    unloaded_load: list[tuple[np.ndarray, np.ndarray, np.ndarray] | None]
    loaded_x: np.ndarray | None


@pytest.fixture(scope="module")
def force29_stepped() -> Stepped:
    """``force-29`` (raw IMUs) stepped through the two hypotheses once a module (two
    tests read it: which one is chosen, and the free-of-load filter's load states)."""
    f, t, z = shipped_recording("force-29", "raw")
    inference = LoadHypothesesInference(f)
    load = list(f.load_states)
    chosen, unloaded_load = [], []
    for ti, zi in zip(t, z):
        inference.infer(Measurement(float(ti), zi))
        chosen.append(inference.unloaded_chosen)
        x, P = inference.unloaded._x, inference.unloaded._P
        unloaded_load.append(
            None
            if x is None or P is None
            else (x[load].copy(), P[load, :].copy(), P[:, load].copy())
        )
    loaded_x = None if inference.loaded._x is None else inference.loaded._x.copy()
    return Stepped(f, t, chosen, unloaded_load, loaded_x)


def test_the_compiled_step_gives_its_innovation_log_density() -> None:
    """``log_likelihood`` after a compiled EKF step is ``-(r^T S^-1 r + log|S|) / 2`` of
    the innovation ``r`` and its covariance ``S = H P H^T + R`` at the predicted state,
    formed here from the CasADi model (an independent path); NaN for the first sample."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=1.0, noise_deg=2.0, seed=3)
    ekf = CompiledExtendedKalmanInference(f)
    ekf.infer(Measurement(float(rec.t[0]), rec.z[0]))
    assert math.isnan(ekf.log_likelihood)
    x, P = ekf._x.copy(), ekf._P.copy()  # type: ignore[union-attr]
    dt = float(rec.t[1] - rec.t[0])
    u = f.inputs(rec.z[0], rec.z[1], dt)
    ekf.infer(Measurement(float(rec.t[1]), rec.z[1]))
    xp, Pp = ekf_predict(f.functions, x, P, u, dt)
    fn = f.functions
    r = np.asarray(fn.innovate(rec.z[1], xp)[0], dtype=float).ravel()
    H = -np.asarray(fn.innovate(rec.z[1], xp)[1], dtype=float)
    S = H @ Pp @ H.T + f.meas_cov()
    want = -0.5 * (r @ np.linalg.solve(S, r) + np.linalg.slogdet(S)[1])
    assert ekf.log_likelihood == pytest.approx(want, rel=1e-9, abs=1e-9)


def test_a_mixture_covariance_has_the_known_moments() -> None:
    """Two unit normals at 0 and 2, even odds: about 0, the variance 0.5 * 1 + 0.5 *
    (1 + 4) = 3; the odds of 700 to 1 on the first (in logs): the first's alone."""
    one = np.eye(1)
    assert mixture(np.zeros(1), one, np.full(1, 2.0), one, 0.0)[0, 0] == pytest.approx(3.0)
    assert mixture(np.zeros(1), one, np.full(1, 2.0), one, 700.0)[0, 0] == pytest.approx(1.0)
    assert mixture(np.zeros(1), one, np.full(1, 2.0), one, -700.0)[0, 0] == pytest.approx(5.0)


def test_the_free_of_load_start_holds_the_tip_force_at_zero() -> None:
    """The tendon model's load states are the tip force and its derivatives; its start
    free of load has them zero, with zero rows and columns in the covariance, and the
    other states' prior as the loaded start has it."""
    f, t, z = shipped_recording("unloaded", "raw")
    names = f.state_names
    load = f.load_states
    assert [names[i] for i in load] == [n for n in names if n[:2] in ("fx", "fy", "fz")] and {
        "fx",
        "fy_dot",
        "fz_ddot",
    } <= {names[i] for i in load}
    x, P, _ = f.unloaded_start(z[0])
    assert np.all(x[list(load)] == 0.0)
    assert np.all(P[list(load), :] == 0.0) and np.all(P[:, list(load)] == 0.0)
    _, P_loaded = f.start_prior(z[0])
    rest = [i for i in range(f.nx) if i not in load]
    assert np.array_equal(np.diag(P)[rest], np.diag(P_loaded)[rest])
    assert not make_formulation("bend").load_states  # a PCC robot has none


@pytest.mark.parametrize("imu", ["tilt", "raw"])
def test_an_unloaded_robot_is_estimated_free_of_load(
    imu: str, default_ekf: Callable[[str, str], EkfRun]
) -> None:
    """The shipped ``unloaded`` recording: the EKF that ``make_estimator`` gives a
    tendon robot takes it as free of load after its start, and its tip is within 0.3
    mm of the truth on average (the model's own floor is 0.11 mm; the single loaded
    EKF, which takes part of the IMUs' errors for a tip force, 2.9 mm with tilt IMUs
    and 0.39 mm raw), its tip force within 0.005 N rms."""
    run = default_ekf("unloaded", imu)
    f, t, z = run.f, run.t, run.z
    assert isinstance(run.estimator, LoadHypothesesKalmanFilter)
    tip, force = _errors(f, run.series, "unloaded")
    late = t >= 1.0
    assert tip[late].mean() < 0.3e-3 and np.sqrt(np.mean(force[late] ** 2)) < 0.005
    single = make_estimator("ekf", replace(f, free_of_load_hypothesis=False))
    assert type(single) is ExtendedKalmanFilter  # the switch gives the single loaded EKF
    single_tip, _ = _errors(f, single.run(t, z), "unloaded")
    assert single_tip[late].mean() > 1.2 * tip[late].mean()


def test_a_load_that_appears_is_followed_by_the_loaded_hypothesis(
    force29_stepped: Stepped, default_ekf: Callable[[str, str], EkfRun]
) -> None:
    """``force-29`` (raw IMUs): the tip force rises from zero to 0.29 N over 2 s. After
    it, every estimate is the loaded hypothesis', and the tip and the force are as
    near the truth as the single loaded EKF's (within 0.05 mm and 0.001 N rms)."""
    run = default_ekf("force-29", "raw")
    f, t, z = run.f, run.t, run.z
    assert np.array_equal(force29_stepped.t, t)
    assert not np.any(np.array(force29_stepped.chosen)[t >= 1.0])
    tip, force = _errors(f, run.series, "force-29")
    single_tip, single_force = _errors(f, ExtendedKalmanFilter(f).run(t, z), "force-29")
    late = t >= 1.0
    assert tip[late].mean() < single_tip[late].mean() + 0.05e-3
    assert np.sqrt(np.mean(force[late] ** 2)) < np.sqrt(np.mean(single_force[late] ** 2)) + 1e-3


def test_estimate_says_how_many_rows_were_taken_as_free_of_load(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``estimate``'s summary line counts the rows of the free-of-load hypothesis: most
    of ``unloaded`` (tilt), none of ``force-29``, whose force rises from its start."""
    import re

    from continuum_mhe.cli import main

    counts = {}
    for name in ("unloaded", "force-29"):
        capsys.readouterr()
        assert main(["estimate", str(DATA / f"{name}_tilt.csv"), "--robot",
                     "tendon-two-section", "--inputs", str(DATA / f"{name}_tensions.csv"),
                     "-o", str(tmp_path / f"{name}.csv")]) == 0  # fmt: skip
        said = re.search(
            r"taken as free of load \(tip force 0 N\) in (\d+) of the 401 estimates",
            capsys.readouterr().err,
        )
        assert said is not None
        counts[name] = int(said.group(1))
    assert counts["unloaded"] >= 380 and counts["force-29"] == 0


def test_the_free_of_load_filter_keeps_its_force_at_zero_and_certain(
    force29_stepped: Stepped,
) -> None:
    """Over the whole of ``force-29`` (raw), whose force rises to 0.29 N, the
    free-of-load filter's force and its derivatives stay exactly zero, their rows and
    columns of its covariance too; the loaded filter's force does not."""
    load = list(force29_stepped.f.load_states)
    assert len(force29_stepped.unloaded_load) == len(force29_stepped.t) == 401
    for entries in force29_stepped.unloaded_load:
        assert entries is not None
        x, P_rows, P_cols = entries
        assert np.all(x == 0.0) and np.all(P_rows == 0.0) and np.all(P_cols == 0.0)
    assert np.linalg.norm(force29_stepped.loaded_x[load[:3]]) > 0.2  # type: ignore[index]


def test_the_answer_covariance_is_the_mixture_with_the_prior_odds() -> None:
    """At each sample the covariance handed back is the two hypotheses' mixture about
    the chosen one's state, weighted by the evidence against the prior odds of a load
    (``EVIDENCE_MARGIN``). The evidence is the two filters' innovation log densities'
    difference (each checked against the CasADi model above), free of load over loaded,
    plus ``EVIDENCE_MEMORY`` times the evidence before; zero before the first. At the
    first sample after the start it is below the margin, and the loaded filter's is the
    answer; after a second without a load, the free-of-load filter's."""
    from continuum_mhe.estimators.load_hypotheses import EVIDENCE_MARGIN, EVIDENCE_MEMORY

    f, t, z = shipped_recording("unloaded", "tilt")
    inference = LoadHypothesesInference(f)
    inference.infer(Measurement(float(t[0]), z[0]))
    x, P, _ = inference.infer(Measurement(float(t[1]), z[1]))
    evidence = inference.unloaded.log_likelihood - inference.loaded.log_likelihood
    assert inference.evidence == pytest.approx(evidence, rel=1e-12, abs=0.0)
    assert evidence < EVIDENCE_MARGIN and not inference.unloaded_chosen
    xl, Pl = inference.loaded._x, inference.loaded._P
    xu, Pu = inference.unloaded._x, inference.unloaded._P
    assert x is xl or np.array_equal(x, xl)  # type: ignore[arg-type]
    want = mixture(xl, Pl, xu, Pu, EVIDENCE_MARGIN - evidence)  # type: ignore[arg-type]
    assert P is not None and np.allclose(P, want, rtol=1e-12, atol=0.0)
    for ti, zi in zip(t[2:60], z[2:60]):
        x, P, _ = inference.infer(Measurement(float(ti), zi))
        ll_free, ll_loaded = inference.unloaded.log_likelihood, inference.loaded.log_likelihood
        evidence = EVIDENCE_MEMORY * evidence + (ll_free - ll_loaded)
    assert inference.evidence == pytest.approx(evidence, rel=1e-12, abs=1e-12)
    assert inference.unloaded_chosen and evidence > EVIDENCE_MARGIN
    xl, Pl = inference.loaded._x, inference.loaded._P
    xu, Pu = inference.unloaded._x, inference.unloaded._P
    assert x is xu or np.array_equal(x, xu)  # type: ignore[arg-type]
    want = mixture(xu, Pu, xl, Pl, evidence - EVIDENCE_MARGIN)  # type: ignore[arg-type]
    assert P is not None and np.allclose(P, want, rtol=1e-12, atol=0.0)


def test_a_failure_of_one_hypothesis_leaves_the_estimate_to_the_other(
    monkeypatch: pytest.MonkeyPatch, default_ekf: Callable[[str, str], EkfRun]
) -> None:
    """``force-29`` (raw): the free-of-load filter's step fails once at sample 200 (a
    numerical failure). The estimate goes on from the loaded filter, without a restart
    of the estimator, and stays as near the truth as without the failure."""
    clean = default_ekf("force-29", "raw")  # (run before the failure is patched in)
    f, t, z = clean.f, clean.t, clean.z
    est = make_estimator("ekf", f)
    clean_tip, _ = _errors(f, clean.series, "force-29")
    unloaded = est.inference.unloaded
    step = type(unloaded).infer

    def failing(self, m):  # type: ignore[no-untyped-def]
        if abs(m.t - float(t[200])) < 1e-9:
            raise np.linalg.LinAlgError("singular matrix")
        return step(self, m)

    monkeypatch.setattr(type(unloaded), "infer", failing)
    series = est.run(t, z)
    tip, _ = _errors(f, series, "force-29")
    assert est.diagnostics.restarts == 0 and not np.any(series.status == "reset")
    late = t >= t[200]
    assert tip[late].mean() < clean_tip[late].mean() + 0.05e-3


def test_a_restart_gives_both_hypotheses_the_kept_estimates_sensor_states() -> None:
    """A restart that keeps the sensor states of an estimate (the policy's last
    confirmed one, the hypothesis chosen then) gives them to both hypotheses: where the
    loaded one was chosen, the free-of-load filter's own IMU errors may have taken part
    of the load (``force-08``, raw: the force is on from its first second)."""
    f, t, z = shipped_recording("force-08", "raw")
    inference = LoadHypothesesInference(f)
    for ti, zi in zip(t[:150], z[:150]):
        x, P, _ = inference.infer(Measurement(float(ti), zi))
    assert not inference.unloaded_chosen and x is not None and P is not None
    own_unloaded = inference.unloaded._x.copy()  # type: ignore[union-attr]
    inference.restart(x, P, float(t[149]))
    inference.infer(Measurement(float(t[200]), z[200]))
    for hypothesis in (inference.loaded, inference.unloaded):
        kept = hypothesis.kept_sensors
        assert kept is not None and set(kept.states) <= set(f.sensor_states)
        assert np.array_equal(kept.values, x[kept.states])
    kept = inference.unloaded.kept_sensors
    assert kept is not None and not np.allclose(kept.values, own_unloaded[kept.states])


def test_a_row_taken_as_free_of_load_does_not_exclude_a_small_load() -> None:
    """``force-08`` (tilt IMUs): the force rises from zero, and the first rows are taken
    as free of load (0 N) while it is still small. Their tip force's standard deviation
    is the loaded hypothesis' (no less), so the true force lies within three of them on
    every axis; the free-of-load filter alone would say 0 N to a fraction of a mN."""
    f, t, z = shipped_recording("force-08", "tilt")
    est = make_estimator("ekf", f)
    free = []
    rows = []
    for ti, zi in zip(t[:120], z[:120]):
        e = est.step(Measurement(float(ti), zi))
        free.append(est.inference.unloaded_chosen)
        rows.append(e)
    names, truth = _truth("force-08")
    cols = [o.name for o in f.outputs]
    force = [cols.index(c) for c in ("fx", "fy", "fz")]
    true_force = truth[:120][:, [names.index(c) for c in ("fx", "fy", "fz")]]
    free_rows = [k for k in range(1, 120) if free[k]]
    assert len(free_rows) >= 10 and np.max(np.abs(true_force[free_rows])) > 0.005
    for k in free_rows:
        std = np.asarray(rows[k].output_std, dtype=float)[force]
        out = np.asarray(rows[k].output, dtype=float)[force]
        assert np.all(out == 0.0)
        assert np.all(np.abs(true_force[k]) <= 3.0 * std), (t[k], true_force[k], std)


def test_a_failure_of_the_loaded_hypothesis_keeps_the_force_floor_and_the_next_dropout(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``unloaded`` (raw): the loaded filter's step fails at sample 200 and sample 201
    has no valid reading. Row 200 is the free-of-load filter's, its tip force 0 N with
    the loaded hypothesis' last standard deviation (not zero); row 201, where the loaded
    filter has nothing to start from, is the free-of-load filter's prediction
    (``dropout``), not ``no-estimate``."""
    f, t, z = shipped_recording("unloaded", "raw")
    z = z.copy()
    z[201] = np.nan  # nothing read at that sample
    est = make_estimator("ekf", f)
    loaded = est.inference.loaded
    step = loaded.infer

    def failing(m):  # type: ignore[no-untyped-def]
        if abs(m.t - float(t[200])) < 1e-9:
            raise np.linalg.LinAlgError("singular matrix")
        return step(m)

    monkeypatch.setattr(loaded, "infer", failing)
    rows = [est.step(Measurement(float(ti), zi)) for ti, zi in zip(t[:205], z[:205])]
    cols = [o.name for o in f.outputs]
    force = [cols.index(c) for c in ("fx", "fy", "fz")]
    assert str(rows[200].status) == "ok" and np.all(np.asarray(rows[200].output)[force] == 0.0)
    assert np.all(np.asarray(rows[200].output_std)[force] > 1e-4)
    assert str(rows[201].status) == "dropout" and rows[201].output is not None
    assert est.diagnostics.restarts == 0


def test_a_new_stretch_at_the_last_counted_time_keeps_the_free_of_load_count() -> None:
    """``reset(keep_counts=True)`` (``live``'s reconnect) begins another stretch of the
    recording: its first sample, even at the time of the last row counted as free of
    load, is another sample, and the count keeps that row (a policy's second step of
    one sample takes it back; here nothing is stepped twice)."""
    f, t, z = shipped_recording("unloaded", "tilt")
    est = make_estimator("ekf", f)
    assert isinstance(est, LoadHypothesesKalmanFilter)
    for ti, zi in zip(t[:120], z[:120]):
        est.step(Measurement(float(ti), zi))
    inference = est.inference
    assert isinstance(inference, LoadHypothesesInference) and inference.unloaded_chosen
    counted = inference.free_of_load_samples
    assert counted > 50
    est.reset(keep_counts=True)
    est.step(Measurement(float(t[119]), z[119]))  # the restart's first sample: loaded
    assert not inference.unloaded_chosen
    assert inference.free_of_load_samples == counted


def test_the_check_takes_the_chosen_hypothesis_evaluation(
    default_ekf: Callable[[str, str], EkfRun],
) -> None:
    """Both hypotheses' EKFs evaluate the measurement terms at their predictions, and
    the policy's glitch test and the consistency check at the prediction from the chosen
    one's estimate: that evaluation is made once a sample (the glitch test's, which the
    chosen hypothesis' EKF takes, and the check keeps; or, where the glitch test does not
    run, the EKF's, which the check takes), not evaluated anew. (The hits counted over
    the run of ``unloaded``, raw, that the fixture makes: one a sample after the first.)"""
    run = default_ekf("unloaded", "raw")
    assert run.hits >= len(run.t) - 1


def test_a_start_under_load_is_not_trusted_and_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped ``force-08`` (raw IMUs) cut to start at 3 s, under 0.08 N: the first
    reading, fitted free of load, misses beyond the IMUs' noise and their own errors,
    and a start cannot tell that load from those errors (the estimates are 10.8 mm off
    on average, their force off by the whole load). No row is ``ok``, and ``estimate``
    says why; the same recording from its start, free of load, is not flagged."""
    import re

    from continuum_mhe.cli import main

    lines = (DATA / "force-08_raw.csv").read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#") or not ln[0].isdigit()]
    late = [ln for ln in lines[len(head) :] if float(ln.split(",")[0]) >= 3.0 - 1e-9]
    cut = tmp_path / "from3.csv"
    cut.write_text("\n".join(head + late) + "\n")
    said = {}
    for name, meas in (("from3", cut), ("whole", DATA / "force-08_raw.csv")):
        out = tmp_path / f"{name}_est.csv"
        capsys.readouterr()
        assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                     str(DATA / "force-08_tensions.csv"), "-o", str(out)]) == 0  # fmt: skip
        said[name] = capsys.readouterr().err
        status = [ln.rsplit(",", 2)[-2] for ln in out.read_text().splitlines()
                  if ln[:1].isdigit()]  # fmt: skip
        if name == "from3":
            assert len(status) == len(late) and set(status) == {"uncertain"}
        else:
            assert status.count("ok") > 0.9 * len(status)
    assert re.search(
        rf"warning: {len(late)} of {len(late)} estimates are of a start whose first IMU "
        r"reading showed a tip load \(or tensions that do not act as given\), which a start "
        r"cannot tell from the IMUs' misalignments and accelerometer biases: none of them "
        r"is ok",
        said["from3"],
    ), said["from3"]
    assert "first reading of their start" not in said["whole"]


@pytest.mark.parametrize("imu", ["tilt", "raw"])
def test_a_first_reading_without_imus_shows_no_load(imu: str) -> None:
    """A start on a sample with the tensions but no IMU reading (``live`` before the
    IMUs report) has nothing that shows a load: once the IMUs' readings have confirmed
    the estimate (the unobserved window after their return), its rows are ``ok``, but
    where the loaded hypothesis' tip standard deviation, which a row free of load
    reports, spreads over a tenth of the robot's length (tilt IMUs, which tell a small
    load from none only loosely): ``uncertain`` for the unobserved window after it."""
    f, t, z = shipped_recording("unloaded", imu)
    z = z.copy()
    z[0, : f.n_imu_measurements] = np.nan
    est = make_estimator("ekf", f)
    series = est.run(t[:100], z[:100])
    statuses = [str(s) for s in series.status]
    inference = est.inference
    assert isinstance(inference, LoadHypothesesInference)
    assert est.diagnostics.untrusted_start_samples == 0
    cols = [o.name for o in f.outputs]
    tip_std = np.linalg.norm(np.asarray(series.std)[:, [cols.index(c) for c in "xyz"]], axis=1)
    wide = tip_std > 0.1 * f.robot.length
    for k in range(60, 100):
        recent = wide[(t[:100] > t[k] - UNOBSERVED_AFTER - 1e-9) & (t[:100] <= t[k])]
        assert statuses[k] == ("uncertain" if recent.any() else "ok"), (k, statuses[k])
    if imu == "raw":
        assert statuses[-40:] == ["ok"] * 40


def test_the_compiled_step_weighs_the_readings_given_the_rows_it_is_told() -> None:
    """With ``likelihood_given`` rows the compiled step's ``log_likelihood`` is the other
    components' density given those: the whole innovation's log-density less theirs
    (``S``'s sub-block), formed here from the step's predicted state and covariance;
    the step's state and covariance are those of the step without it."""
    f, t, z = shipped_recording("force-29", "raw")
    given = [
        i for b in f.measurement_blocks if not b.is_imu for i in range(b.start, b.start + b.size)
    ]
    plain, weighed = CompiledExtendedKalmanInference(f), CompiledExtendedKalmanInference(f)
    weighed.likelihood_given = given
    assert weighed.likelihood_given == tuple(given) and plain.likelihood_given == ()
    for k in range(3):
        before = (weighed._x, weighed._P, weighed._t_prev, weighed._z_prev)
        xp_, Pp_, _ = plain.infer(Measurement(float(t[k]), z[k]))
        xw, Pw, _ = weighed.infer(Measurement(float(t[k]), z[k]))
        assert np.array_equal(xp_, xw) and np.array_equal(Pp_, Pw)  # type: ignore[arg-type]
    x, P, t_prev, z_prev = before
    assert x is not None and P is not None and z_prev is not None
    dt = float(t[2] - t_prev)
    xp, F, _, _ = weighed._node.evaluate(x, f.inputs(z_prev, z[2], dt), dt)
    Pp = F @ P @ F.T + weighed._q(dt)[0]
    mask = f.measurement_mask(z[2])
    _, _, H, r = weighed._node.evaluate(xp, np.zeros(f.nu), 0.0, z[2], mask)
    S = H @ Pp @ H.T + f.meas_cov()

    def log_density(rows: list[int]) -> float:
        Sr = S[np.ix_(rows, rows)]
        return float(-0.5 * (r[rows] @ np.linalg.solve(Sr, r[rows]) + np.linalg.slogdet(Sr)[1]))

    whole = log_density(list(range(f.nz)))
    assert plain.log_likelihood == pytest.approx(whole, rel=1e-9, abs=1e-6)
    want = whole - log_density(given)
    assert weighed.log_likelihood == pytest.approx(want, rel=1e-7, abs=1e-6)
    assert abs(weighed.log_likelihood - plain.log_likelihood) > 1.0  # they differ


def test_the_tip_condition_does_not_weigh_the_load_hypotheses() -> None:
    """The hypotheses are weighed by the IMU readings' density given the tensions and the
    tip condition, not by the whole measurement's: the tip condition is the model's
    pseudo-measurement (standard deviation 1e-4 rad/m), and its predicted density grows
    without bound where the tip moment's sensitivity to the base curvature falls, as
    at a force near buckling. The shipped ``planar-s`` (free of load) with the tip IMU
    alone and ``F''`` a state (jerk 1 N^2/s^5, no white acceleration beside it, the gyro
    noise 0.01 rad/s): the
    loaded hypothesis strays hundreds of
    millimetres once the robot bends; weighed by the whole measurement it took the
    estimate from 6.9 s to 7.6 s (up to 339 mm off); weighed by the IMUs, the estimate
    stays free of load."""
    f2, t, z2 = shipped_recording("planar-s", "raw")
    robot = replace(f2.robot, imus=(f2.robot.imus[-1],))
    f = replace(
        f2,
        robot=robot,
        estimate_force_acceleration=True,
        force_jerk_psd=1.0,
        force_accel_psd=0.0,
        gyro_std=0.01,  # the two-IMU gyro noise: with one IMU's 0.005 it strays less
    )
    z = np.hstack([z2[:, 6:12], z2[:, 12:]])  # IMU 2's readings, then the tensions
    assert f.nz == z.shape[1]
    with pytest.warns(UnobservableShapeWarning):  # one IMU
        est = make_estimator("ekf", f)
    assert isinstance(est, LoadHypothesesKalmanFilter)
    chosen, loaded_off = [], []
    names, truth = _truth("planar-s")
    tip = [[o.name for o in f.outputs].index(n) for n in ("x", "y", "z")]
    true_tip = truth[:, [names.index(n) for n in ("x", "y", "z")]]
    inference = est.inference
    for k, (tk, zk) in enumerate(zip(t, z)):
        est.step(Measurement(float(tk), zk))
        chosen.append(inference.unloaded_chosen)
        xl = inference.loaded._x
        loaded_off.append(
            math.nan
            if xl is None
            else np.linalg.norm(inference.loaded.output(xl)[tip] - true_tip[k])
        )
    later = t >= 1.0
    assert np.nanmax(np.asarray(loaded_off)[later]) > 0.1  # the loaded hypothesis strays
    assert all(np.asarray(chosen)[later])


def test_a_robot_with_one_imu_weighs_its_load_hypotheses_by_the_imus_alone() -> None:
    """``imu_evidence`` (None: on with one IMU) conditions both hypotheses' evidence on
    the tensions' and the tip condition's rows; with two IMUs, by default, on none (the
    whole measurement); a PCC robot has no such rows."""
    f2, _, _ = shipped_recording("unloaded", "raw")
    rest = tuple(
        i for b in f2.measurement_blocks if not b.is_imu for i in range(b.start, b.start + b.size)
    )
    assert f2.robot.n_imus == 2 and f2.evidence_given == ()
    assert replace(f2, imu_evidence=True).evidence_given == rest
    one = replace(f2, robot=replace(f2.robot, imus=(f2.robot.imus[-1],)))
    rest_one = tuple(i - 6 for i in rest)  # the first IMU's six rows gone
    assert one.evidence_given == rest_one and replace(one, imu_evidence=False).evidence_given == ()
    assert [one.measurement_names[i] for i in rest_one][-1] == "eq_kz_dot"
    for f, want in ((f2, ()), (one, rest_one)):
        inference = LoadHypothesesInference(f)
        assert inference.loaded.likelihood_given == want
        assert inference.unloaded.likelihood_given == want
    assert make_formulation("bend").evidence_given == ()
