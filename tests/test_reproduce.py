"""``continuum-mhe reproduce`` / ``plot``, the parallel runners and the rod recording."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.reproduce import experiments as ex
from continuum_mhe.reproduce.figures import RENDERERS
from continuum_mhe.reproduce.pipeline import RodTask, run_task
from continuum_mhe.reproduce.runner import run_parallel
from continuum_mhe.simulation import cosserat

FIGURES = (
    "exp1_synthetic3d_trajectory",
    "exp1_synthetic3d_states",
    "exp2_constraints",
    "exp3_rod",
    "exp4_trajectory_3d",
    "exp4_monte_carlo",
    "exp4_conditions",
    "exp5_horizon",
    "exp6_window",
)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("reproduce") / "results"
    assert main(["reproduce", "--out", str(out), "--quick", "--jobs", "2"]) == 0
    return out


def test_quick_run_writes_data_figures_and_report(quick_run: Path) -> None:
    for name in ex.EXPERIMENTS:
        data = json.loads((quick_run / f"{name}.json").read_text())
        assert data["config"] == json.loads(json.dumps(ex.QUICK.__dict__))
    for fig in FIGURES:
        for suffix in (".png", ".pdf"):
            assert (quick_run / f"{fig}{suffix}").stat().st_size > 1000, fig
    report = (quick_run / "report.md").read_text()
    mc_rows = [ln for ln in report.splitlines() if ln.startswith("| ") and "| 0.0" in ln]
    scenarios = {ln.split("|")[1].strip() for ln in mc_rows}
    assert {str(i) for i in range(1, 11)} <= scenarios
    assert "## Paper vs. ours" in report and "3.5: mean time rises" in report
    assert "spec = {" in report  # the exact settings of every run


def test_quick_run_numbers_are_sane(quick_run: Path) -> None:
    mc = json.loads((quick_run / "exp4_ekf_comparison.json").read_text())
    assert len(mc["monte_carlo"]) == 10
    for g in mc["monte_carlo"].values():
        assert g["n_trials"] == ex.QUICK.mc_seeds
        for m in ("mhe", "ekf"):
            ci = g[m]["srmse"]
            assert ci["lo"] <= ci["mean"] <= ci["hi"]
    c = json.loads((quick_run / "exp2_constraints.json").read_text())["example"]["constraints"]
    assert c["mhe"]["n_estimates_over_bound"] == 0
    assert c["mhe"]["theta_max_estimate"] <= math.pi / 2 + 1e-6
    assert c["ekf"]["theta_max_estimate"] > math.pi / 2  # the EKF has no bound
    win = json.loads((quick_run / "exp6_window.json").read_text())["summary"]
    assert win["growing"]["first_estimate_s"]["mean"] == 0.0
    n, dt = ex.QUICK.horizon, ex.QUICK.dt
    assert win["paper-start"]["first_estimate_s"]["mean"] == pytest.approx((n - 1) * dt)


def test_plot_rerenders_from_data_without_estimating(
    quick_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def forbidden(*args: object, **kw: object) -> None:
        raise AssertionError("plot must not run estimators")

    monkeypatch.setattr(ex, "run_trial", forbidden)
    monkeypatch.setattr(ex, "estimate_all", forbidden)
    monkeypatch.setattr("continuum_mhe.estimators.make_estimator", forbidden)
    out = tmp_path / "figs"
    assert main(["plot", str(quick_run), "--out", str(out)]) == 0
    assert sorted(p.stem for p in out.glob("*.png")) == sorted(FIGURES)


def test_plot_without_data_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plot", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("continuum-mhe: error:") and "\n" not in err
    assert main(["plot", str(tmp_path / "missing")]) == 2


def test_reproduce_rejects_bad_jobs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["reproduce", "--out", str(tmp_path / "r"), "--jobs", "0"]) == 2
    assert "--jobs" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def _tiny_specs() -> list[ex.TrialSpec]:
    std = math.radians(2.0)
    return [
        ex.TrialSpec(
            "exp4_ekf_comparison",
            "t",
            "paper3d",
            seed,
            1.0,
            0.05,
            0.2,
            (std, std),
            std,
            ("mhe", "ekf"),
            horizon=5,
        )
        for seed in (1, 2)
    ]


def _errors(results: list[dict[str, object]]) -> list[float]:
    return [r["methods"][m]["all"]["srmse"] for r in results for m in ("mhe", "ekf")]  # type: ignore[index]


def test_dask_local_cluster_matches_local_processes() -> None:
    import dask.distributed as distributed

    specs = _tiny_specs()
    local = run_parallel(run_task, specs, jobs=2, progress=False)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        remote = run_parallel(run_task, specs, scheduler=cluster.scheduler_address, progress=False)
    assert [r["spec"] for r in remote] == [s.as_dict() for s in specs]
    np.testing.assert_allclose(_errors(remote), _errors(local), rtol=1e-9)


def test_unreachable_scheduler_is_a_user_error() -> None:
    with pytest.raises(ValueError, match="Dask scheduler"):
        run_parallel(run_task, _tiny_specs(), scheduler="tcp://127.0.0.1:9", progress=False)


def test_trial_spec_round_trips_through_json() -> None:
    spec = _tiny_specs()[0]
    assert ex.TrialSpec.from_dict(json.loads(json.dumps(spec.as_dict()))) == spec


def test_corruptions() -> None:
    std = math.radians(2.0)
    z = np.zeros((200, 2))
    base = ex.TrialSpec("e", "g", "paper3d", 3, 1.0, 0.05, 0.2, (std, std), std, ("ekf",))
    spikes = ex.corrupt(
        z,
        ex.TrialSpec(
            **{
                **base.__dict__,
                "corruption": "outliers",
                "corruption_deg": 30.0,
                "outlier_fraction": 0.02,
            }
        ),
    )
    hit = np.any(spikes != 0, axis=1)
    assert hit.sum() == 4 and not hit[0]
    np.testing.assert_allclose(np.abs(spikes[hit]), math.radians(30.0))
    bad = ex.corrupt(
        z, ex.TrialSpec(**{**base.__dict__, "corruption": "bad-init", "corruption_deg": 40.0})
    )
    np.testing.assert_allclose(bad[0], math.radians(40.0))
    assert not np.any(bad[1:])


def test_mean_ci_known_answer() -> None:
    ci = ex.mean_ci([1.0, 2.0, 3.0])
    half = 4.302652729911275 / math.sqrt(3.0)  # t(0.975, 2) * s / sqrt(n), s = 1
    assert ci["mean"] == 2.0
    assert ci["lo"] == pytest.approx(2.0 - half) and ci["hi"] == pytest.approx(2.0 + half)
    assert ex.mean_ci([])["n"] == 0


def test_every_figure_has_a_renderer() -> None:
    assert set(RENDERERS) == set(ex.EXPERIMENTS)


def test_shipped_rod_recording_is_valid() -> None:
    rec = cosserat.read_recording(cosserat.default_data_path()).columns
    t = rec["t"]
    assert len(t) == 401 and np.allclose(np.diff(t), 0.05)
    # planar: bending towards -y, no x motion, inside the workspace
    assert np.max(np.abs(rec["x_true"])) < 1e-6
    assert 0.8 < np.max(rec["theta_fit"]) < math.pi / 2
    tip = np.column_stack([rec["x_true"], rec["y_true"], rec["z_true"]])
    assert np.all(np.linalg.norm(tip, axis=1) <= 0.2 + 1e-6)
    # the accelerometer's tilt tracks the rod's tip tangent within a few degrees
    assert np.degrees(np.max(np.abs(rec["roll"] - rec["theta_tangent"]))) < 6.0
    res = run_task(RodTask(ex.QUICK))
    assert (
        res["cc_fit_vs_truth"]["mean_mm"] < res["methods"]["mhe"]["vs_truth"]["all"]["tip_mean_mm"]
    )


@pytest.mark.slow
def test_rod_generator_short_run(tmp_path: Path) -> None:
    import elastica  # noqa: F401  (a test dependency: fail loudly if missing)

    rod = cosserat.RodSettings(n_elements=8, period=0.4, sim_dt=4e-5)
    rec = cosserat.make_recording(rod, cosserat.ImuSettings(), duration=0.3, seed=1)
    cols = rec.columns
    assert set(cols) == set(cosserat.COLUMNS) and len(cols["t"]) == 7
    assert cols["theta_tangent"][0] == 0.0 and cols["z_true"][0] == pytest.approx(0.2)
    assert np.max(cols["theta_fit"]) > 0.05  # the cable bent it
    path = tmp_path / "rod.csv"
    cosserat.write_recording(path, rec)
    back = cosserat.read_recording(path).columns
    np.testing.assert_allclose(back["roll"], cols["roll"], rtol=1e-6, atol=1e-9)
    assert cosserat.main(["-o", str(tmp_path / "x.csv"), "--duration", "-1"]) == 2


def test_fit_constant_curvature_recovers_an_arc() -> None:
    from continuum_mhe.model.kinematics import tip_position

    frac = np.linspace(0, 1, 11)
    nodes = tip_position(0.9 * frac, np.full(11, 0.4), 0.2 * frac).T
    th, ph = cosserat.fit_constant_curvature(nodes, 0.2)
    assert th == pytest.approx(0.9, abs=1e-8) and ph == pytest.approx(0.4, abs=1e-8)


def test_settings_reject_bad_values() -> None:
    std = math.radians(2.0)
    with pytest.raises(ValueError, match="methods"):
        ex.TrialSpec("e", "g", "paper3d", 0, 1.0, 0.05, 0.2, (std, std), std, ())
    with pytest.raises(ValueError, match="outlier_fraction"):
        ex.TrialSpec(
            "e", "g", "paper3d", 0, 1.0, 0.05, 0.2, (std, std), std, ("ekf",), outlier_fraction=1.5
        )
    with pytest.raises(ValueError, match="sweep_duration"):
        ex.ReproduceConfig(sweep_horizons=(5, 500))
    with pytest.raises(ValueError, match="bits"):
        cosserat.ImuSettings(bits=4)
    with pytest.raises(ValueError, match="n_elements"):
        cosserat.RodSettings(n_elements=2)
