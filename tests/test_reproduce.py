"""``continuum-mhe reproduce`` / ``plot``, the parallel runners and the rod recording."""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from live_helpers import SAFETY_S, wait_for

from continuum_mhe.benchmark.losses import with_spikes
from continuum_mhe.cli import main
from continuum_mhe.errors import UserError
from continuum_mhe.model.imu import as_sensor_reads
from continuum_mhe.reproduce import beyond as by
from continuum_mhe.reproduce import bootstrap
from continuum_mhe.reproduce import experiments as ex
from continuum_mhe.reproduce import report as rp
from continuum_mhe.reproduce.figures import RENDERERS
from continuum_mhe.reproduce.pipeline import RodTask, load_results, run_task
from continuum_mhe.reproduce.runner import run_parallel
from continuum_mhe.simulation import cosserat
from continuum_mhe.simulation.scenarios import Recording

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
    "exp7_beyond",
)


# ``--quick`` with fewer and shorter trials: every experiment, figure and report section
# of a quick run
SMALL = dataclasses.replace(
    ex.QUICK,
    mc_seeds=2,
    sweep_horizons=(5, 20),
    sweep_duration=2.0,
    beyond_duration=3.0,
)


@pytest.fixture(scope="module")
def _quick(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[tuple[Any, Any]]]:
    """The quick run's folder, and each of its tasks with its result."""
    from continuum_mhe.reproduce import pipeline

    out = tmp_path_factory.mktemp("reproduce") / "results"
    done: list[tuple[Any, Any]] = []
    run_parallel = pipeline.run_parallel

    def recorded(run: Any, tasks: list[Any], **kwargs: Any) -> list[Any]:
        results = run_parallel(run, tasks, **kwargs)
        done.extend(copy.deepcopy(list(zip(tasks, results))))
        return results

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(ex, "QUICK", SMALL)
        patch.setattr(pipeline, "run_parallel", recorded)
        # in this process (the process pool: test_dask_local_cluster_matches_local_processes)
        assert main(["reproduce", "--out", str(out), "--quick", "--jobs", "1"]) == 0
    return out, done


@pytest.fixture(scope="module")
def quick_run(_quick: tuple[Path, list[tuple[Any, Any]]]) -> Path:
    return _quick[0]


@pytest.fixture
def quick_trials(
    _quick: tuple[Path, list[tuple[Any, Any]]], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``reproduce`` given the quick run's results for tasks it ran (the same trials:
    for the tests of what ``reproduce`` writes once they are done); any other task
    fails the test."""
    from continuum_mhe.reproduce import pipeline

    def replayed(run: Any, tasks: list[Any], **kwargs: Any) -> list[Any]:
        out = []
        for task in tasks:
            results = [r for t, r in _quick[1] if t == task]
            assert results, f"not a task of the quick run: {task}"
            out.append(copy.deepcopy(results[0]))
        return out

    monkeypatch.setattr(pipeline, "run_parallel", replayed)


def _first_two_experiments(quick_run: Path, folder: Path) -> Path:
    """``folder`` with the quick run's data of exp1 and exp2 alone: a results folder of
    three figures (FIGURES[:3]), for tests of an interrupted plot (each figure of a
    folder is made before the first is saved)."""
    folder.mkdir()
    for name in ("exp1_synthetic3d", "exp2_constraints"):
        (folder / f"{name}.json").write_bytes((quick_run / f"{name}.json").read_bytes())
    return folder


def _drawn_small(real_save: Any) -> Any:
    """``plotting.save`` of a one-inch empty figure in the given figure's stead (closed):
    for tests of which files are written and removed, not of what they show (the quick
    run draws every figure from the same data, in each format)."""
    from matplotlib.figure import Figure

    from continuum_mhe.evaluation import plotting

    def save(fig: Any, path: Path, *args: Any, **kw: Any) -> list[Path]:
        plotting.close(fig)
        return real_save(Figure(figsize=(1, 1)), path, *args, **kw)

    return save


def test_quick_run_writes_data_figures_and_report(quick_run: Path) -> None:
    for name in ex.EXPERIMENTS:
        data = json.loads((quick_run / f"{name}.json").read_text())
        assert data["config"] == json.loads(json.dumps(SMALL.__dict__))
    for fig in FIGURES:
        for suffix in (".png", ".pdf"):
            assert (quick_run / f"{fig}{suffix}").stat().st_size > 1000, fig
    report = (quick_run / "report.md").read_text()
    mc_rows = [ln for ln in report.splitlines() if ln.startswith("| ") and "| 0.0" in ln]
    scenarios = {ln.split("|")[1].strip() for ln in mc_rows}
    assert {str(i) for i in range(1, 11)} <= scenarios
    # a quick run says first that its verdicts come from few seeds
    assert report.splitlines()[2].startswith(f"**Few seeds (mc {SMALL.mc_seeds}, ")


def _claim_rows(report: str) -> list[list[str]]:
    """The cells of the 'Paper vs. ours' table (escaped pipes kept inside cells)."""
    lines = report.split("## Paper vs. ours\n\n", 1)[1].split("\n\n", 1)[0].splitlines()
    return [
        [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", ln)[1:-1]]
        for ln in lines[2:]
    ]


def test_report_claim_verdicts_follow_their_rules(quick_run: Path) -> None:
    """Claim 3.1's verdict, recomputed here from the saved numbers by its stated rule,
    is the one the report prints; every row states its rule."""
    results = load_results(quick_run)
    rows = _claim_rows((quick_run / "report.md").read_text())
    assert len(rows) == len(rp.claims(results)) and all(len(r) == 4 for r in rows)
    assert all(r[3].startswith(("holds if", "from the", "the per-condition")) for r in rows)
    ex1 = results["exp1_synthetic3d"]["example"]
    m, sp = ex1["methods"]["mhe"]["all"], ex1["spec"]
    ok = (m["tip_mean_mm"] <= 0.02 * sp["length"] * 1e3
          and m["rmse"]["theta"] <= sp["assumed_std"])  # fmt: skip
    (row,) = [r for r in rows if r[0].startswith("3.1")]
    assert row[2] == ("**holds**" if ok else "**does not hold**")
    assert f"{m['tip_mean_mm']:.2f} mm" in row[1]


def test_report_rerun_snippet_reproduces_its_trial(quick_run: Path) -> None:
    """The Python block the report gives for a Monte Carlo group reruns its first seed
    and gives the saved numbers."""
    report = (quick_run / "report.md").read_text()
    block = report.split("group `table1-1`:\n\n```python\n", 1)[1].split("```", 1)[0]
    namespace: dict[str, Any] = {}
    exec(compile(block, "report.md", "exec"), namespace)
    saved = json.loads((quick_run / "exp4_ekf_comparison.json").read_text())["trials"]
    first = next(t for t in saved if t["spec"]["group"] == "table1-1")
    assert namespace["SEED"] == first["spec"]["seed"]
    got = namespace["result"]["methods"]
    for m in ("mhe", "ekf"):
        assert got[m]["all"]["srmse"] == pytest.approx(first["methods"][m]["all"]["srmse"], 1e-9)


def test_report_prose_reads_the_configuration(quick_run: Path) -> None:
    """Change the saved settings: the report's prose follows (nothing typed in)."""
    results = copy.deepcopy(load_results(quick_run))
    for d in results.values():
        if "config" in d:
            d["config"].update(length=0.25, noise_deg=3.0, horizon=17, mc_seeds=50,
                               condition_seeds=50, sweep_seeds=50, window_seeds=50,
                               beyond_seeds=50)  # fmt: skip
    results["exp1_synthetic3d"]["paper_formulation"]["noise_settings"]["paper_process_weight"] = 7
    results["exp3_rod"]["generator"]["rod"]["length"] = 0.31
    results["exp1_synthetic3d"]["example"]["spec"]["horizon"] = 23
    text = rp.render_report(results)
    assert "W = 7 I), same scenario" in text
    assert "Cosserat rod (0.31 m," in text
    assert "this run uses 3.0 deg" in text and "on a 0.250 m section" in text
    assert "whole run and over the first N = 17 samples" in text
    assert "N = 23, seed 0" in text
    assert "Few seeds" not in text
    # the command line's generator, whatever the shipped settings record as theirs
    assert (
        "Regenerate it with `continuum-mhe rod single -o rod.csv --seed 0 --duration 20`." in text
    )
    results["exp3_rod"]["generator"] = None  # a recording from elsewhere
    assert "with no generator settings beside it" in rp.render_report(results)


def _flip(results: dict[str, Any], claim: Any, key: str, edit: Any) -> str:
    d = copy.deepcopy(results[key])
    edit(d)
    return str(claim(d).verdict)


def test_claim_verdicts_change_with_the_numbers(quick_run: Path) -> None:
    r = load_results(quick_run)

    def far_tip(d: dict[str, Any]) -> None:
        d["example"]["methods"]["mhe"]["all"]["tip_mean_mm"] = (
            0.03 * d["example"]["spec"]["length"] * 1e3
        )

    def over(d: dict[str, Any]) -> None:
        d["example"]["constraints"]["mhe"]["n_estimates_over_bound"] = 1

    def off_fk(d: dict[str, Any]) -> None:
        d["methods"]["mhe"]["vs_fk_of_measurements"]["all"]["tip_mean_mm"] = (
            0.05 * d["length"] * 1e3
        )

    def same_start(d: dict[str, Any]) -> None:
        d["summary"]["growing"]["first_estimate_s"] = d["summary"]["paper-start"][
            "first_estimate_s"
        ]

    assert rp.claim_synthetic(r["exp1_synthetic3d"]).verdict == "holds"
    assert _flip(r, rp.claim_synthetic, "exp1_synthetic3d", far_tip) == "does not hold"
    assert rp.claim_constraints(r["exp2_constraints"]).verdict == "holds"
    assert _flip(r, rp.claim_constraints, "exp2_constraints", over) == "does not hold"
    assert rp.claim_rod(r["exp3_rod"]).verdict == "holds on a simulated stand-in"
    assert _flip(r, rp.claim_rod, "exp3_rod", off_fk) == "does not hold on a simulated stand-in"
    assert rp.claim_growing_window(r["exp6_window"]).verdict == "holds"
    assert _flip(r, rp.claim_growing_window, "exp6_window", same_start) == "does not hold"


def _ci_block(mean: float, lo: float, hi: float) -> dict[str, float]:
    return {"mean": mean, "lo": lo, "hi": hi, "n": 5}


def _monte_carlo(mhe_lower: int, ekf_means: list[float], mhe_means: list[float]) -> dict[str, Any]:
    mc = {}
    for i, (e, m) in enumerate(zip(ekf_means, mhe_means)):
        diff = _ci_block(-0.1, -0.2, -0.05) if i < mhe_lower else _ci_block(0.0, -1e-6, 1e-6)
        mc[f"table1-{i + 1}"] = {"n_trials": 5, "ekf": {"srmse": _ci_block(e, e, e)},
                                 "mhe": {"srmse": _ci_block(m, m, m)},
                                 "mhe_minus_ekf": {"srmse": diff}}  # fmt: skip
    return {"monte_carlo": mc, "table1": [list(r) for r in ex.TABLE1],
            "example": {"methods": {m: {"all": {"srmse": 0.3, "tip_mean_mm": 2.0}}
                                    for m in ("mhe", "ekf")}}}  # fmt: skip


def test_monte_carlo_claims_follow_their_rules() -> None:
    flat = [0.3] * 10
    steep = [0.3 + 0.05 * i for i in range(10)]
    assert rp.claim_more_accurate(_monte_carlo(10, flat, flat)).verdict == "holds"
    assert rp.claim_more_accurate(_monte_carlo(3, flat, flat)).verdict == "partly holds"
    assert rp.claim_more_accurate(_monte_carlo(0, flat, flat)).verdict == "does not hold"
    assert rp.claim_noise_robust(_monte_carlo(10, steep, flat)).verdict == "holds"
    assert rp.claim_noise_robust(_monte_carlo(10, steep, steep)).verdict == "does not hold"
    assert rp.claim_noise_robust(_monte_carlo(0, steep, flat)).verdict == "does not hold"


def _sweep(per_ms: list[float], srmse: list[float], m: int = 400) -> dict[str, Any]:
    ns = [5, 20, 40, 80]
    return {"summary": {str(n): {"srmse_common": {"mean": e}, "solve_ms_median": {"mean": t},
                                 "n_estimates": m - n + 1, "n_samples": m}
                        for n, t, e in zip(ns, per_ms, srmse)}}  # fmt: skip


def test_horizon_claims_follow_their_rules() -> None:
    same = [0.35] * 4
    assert rp.claim_horizon_accuracy(_sweep([1, 2, 3, 4], same)).verdict == "holds"
    worse = [0.40, 0.35, 0.35, 0.35]
    assert rp.claim_horizon_accuracy(_sweep([1, 2, 3, 4], worse)).verdict == "does not hold"
    assert rp.claim_horizon_time(_sweep([1, 4, 2, 1], same)).verdict == "holds"
    # per estimate it rises, the total (M - N + 1) t(N) peaks inside: the M - N effect only
    assert rp.claim_horizon_time(_sweep([1, 2, 4, 4.4], same, m=100)).verdict == "partly holds"
    assert rp.claim_horizon_time(_sweep([1, 2, 3, 4], same, m=10_000)).verdict == "does not hold"
    # the paper's solver judged by the same rule, said beside the default backend's verdict
    sweep = _sweep([1, 2, 3, 4], same)
    for n, t in zip(["5", "20", "40", "80"], [10.0, 30.0, 60.0, 40.0], strict=True):
        sweep["summary"][n]["ipopt"] = {"solve_ms_median": {"mean": t}}
    claim = rp.claim_horizon_time(sweep)
    assert claim.verdict == "does not hold"
    assert (
        "IPOPT (the paper's solver) 10.00 to 40.00 ms, highest at N = 40: by the same rule it holds"
        in (claim.measured)
    ), claim.measured


def test_few_seeds_line_only_for_few_seeds() -> None:
    """A run of few seeds says so, naming ``--quick`` where its command has it (not as
    a question), else that its seeds were set low; a run of enough seeds says
    nothing."""
    quick_cmd = "continuum-mhe reproduce --out r --quick"
    assert rp._few_seeds_line(dataclasses.asdict(ex.FULL), quick_cmd) == []
    quick = rp._few_seeds_line(dataclasses.asdict(ex.QUICK), quick_cmd)[0]
    assert "verdicts come from few seeds" in quick and "per group, `--quick`): " in quick
    assert quick.endswith("Rerun without `--quick` before citing them.**")
    by_hand = rp._few_seeds_line(dataclasses.asdict(ex.QUICK), "continuum-mhe reproduce")[0]
    assert "per group, seeds set low): " in by_hand and "with more seeds" in by_hand


def test_quick_run_numbers_are_sane(quick_run: Path) -> None:
    mc = json.loads((quick_run / "exp4_ekf_comparison.json").read_text())
    assert len(mc["monte_carlo"]) == 10
    trials = [t for t in mc["trials"] if t["spec"]["group"].startswith("table1-")]
    for group, g in mc["monte_carlo"].items():
        assert g["n_trials"] == SMALL.mc_seeds
        mine = [t for t in trials if t["spec"]["group"] == group]
        for m in ("mhe", "ekf"):
            values = [t["methods"][m]["all"]["srmse"] for t in mine]
            ci = g[m]["srmse"]
            # the summary is the mean of its trials, and its interval lies within them
            assert ci["mean"] == pytest.approx(float(np.mean(values)), rel=1e-12)
            assert min(values) <= ci["lo"] < ci["hi"] <= max(values) and ci["n"] == len(values)
        diffs = [t["methods"]["mhe"]["all"]["srmse"] - t["methods"]["ekf"]["all"]["srmse"]
                 for t in mine]  # fmt: skip
        assert g["mhe_minus_ekf"]["srmse"]["mean"] == pytest.approx(float(np.mean(diffs)))
    for c in mc["conditions"].values():  # tip errors: never a negative bound
        for m in ("mhe", "ekf"):
            assert c[m]["tip_mean_mm"]["lo"] >= 0
    c = json.loads((quick_run / "exp2_constraints.json").read_text())["example"]["constraints"]
    assert c["mhe"]["n_estimates_over_bound"] == 0
    assert c["mhe"]["theta_max_estimate"] <= math.pi / 2 + 1e-6
    assert c["ekf"]["theta_max_estimate"] > math.pi / 2  # the EKF has no bound
    win = json.loads((quick_run / "exp6_window.json").read_text())["summary"]
    assert win["growing"]["first_estimate_s"]["mean"] == 0.0
    n, dt = SMALL.horizon, SMALL.dt
    assert win["paper-start"]["first_estimate_s"]["mean"] == pytest.approx((n - 1) * dt)
    # the "first N" errors are over N estimates for the growing window and the EKF, over
    # one for the paper start, and the report's table says so (without the count, the
    # paper start's one-sample error would read as better than the growing window's N)
    counts = {g: win[g]["early_estimates"]["mean"] for g in ("growing", "paper-start", "ekf")}
    assert counts == {"growing": n, "paper-start": 1, "ekf": n}
    report = (quick_run / "report.md").read_text()
    row = next(ln for ln in report.splitlines() if ln.startswith("| MHE, paper start"))
    assert row.split("|")[4].strip() == "1", row


def test_plot_rerenders_from_data_without_estimating(
    quick_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def forbidden(*args: object, **kw: object) -> None:
        raise AssertionError("plot must not run estimators")

    from continuum_mhe.evaluation import plotting

    save_small = _drawn_small(plotting.save)

    def save_png(fig: Any, path: Path, formats: Any, *args: Any, **kw: Any) -> list[Path]:
        return save_small(fig, path, formats[:1], *args, **kw)  # (the fixture made the PDFs)

    monkeypatch.setattr(ex, "run_trial", forbidden)
    monkeypatch.setattr(ex, "estimate_all", forbidden)
    monkeypatch.setattr("continuum_mhe.estimators.make_estimator", forbidden)
    monkeypatch.setattr(plotting, "save", save_png)
    out = tmp_path / "figs"
    assert main(["plot", str(quick_run), "--out", str(out)]) == 0
    assert sorted(p.stem for p in out.glob("*.png")) == sorted(FIGURES)
    # a second time into that folder (the data of three of its figures: plot makes every
    # figure before it checks): its figures are kept unless --overwrite
    part = _first_two_experiments(quick_run, tmp_path / "part")
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    assert main(["plot", str(part), "--out", str(out)]) == 2
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before

    def save_stub(fig: Any, path: Path, formats: Any, *args: Any, **kw: Any) -> list[Path]:
        plotting.close(fig)  # (the figures were drawn above: only the replacing counts here)
        target = path.with_suffix(f".{formats[0]}")
        target.write_bytes(b"replaced")
        return [target]

    monkeypatch.setattr(plotting, "save", save_stub)
    assert main(["plot", str(quick_run), "--out", str(out), "--overwrite"]) == 0
    assert {p.read_bytes() for p in out.glob("*.png")} == {b"replaced"}


def test_plot_without_data_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plot", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("continuum-mhe: error:") and "\n" not in err
    assert main(["plot", str(tmp_path / "missing")]) == 2


def test_an_interrupted_plot_leaves_nothing_it_wrote(
    quick_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C during ``plot --out NEW`` leaves nothing it wrote (``reproduce`` renders
    its figures the same way): the figures saved so far and the folders made for them
    are removed, and no figure is left open. Here at the second of three figures."""
    from continuum_mhe.evaluation import plotting

    saved: list[Path] = []
    real_save = _drawn_small(plotting.save)

    def save_then_interrupt(fig: Any, path: Path, *args: Any, **kw: Any) -> list[Path]:
        saved.append(path)
        if len(saved) == 2:
            plotting.plt.close(fig)
            raise KeyboardInterrupt
        return real_save(fig, path, *args, **kw)

    monkeypatch.setattr(plotting, "save", save_then_interrupt)
    results, out = _first_two_experiments(quick_run, tmp_path / "results"), tmp_path / "figs"
    open_before = set(plotting.plt.get_fignums())
    assert main(["plot", str(results), "--out", str(out)]) == 130
    assert len(saved) == 2
    assert not out.exists()
    assert set(plotting.plt.get_fignums()) == open_before  # the third, never saved, closed


def test_an_interrupted_overwrite_leaves_no_manifest_of_a_run_not_made(
    quick_run: Path, quick_trials: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C while ``reproduce --overwrite`` writes into an earlier run's folder: the
    files it replaced keep their new content, so the folder mixes two runs; its
    manifest, which would record the interrupted run as made, and the earlier run's
    report, which describes data partly replaced, are removed. Here
    ``--only beyond`` into the folder of an earlier one (the quick run's beyond data,
    manifest and report), with the quick run's results of its trials."""
    from continuum_mhe.evaluation import plotting

    folder = tmp_path / "results"
    folder.mkdir()
    for name in ("exp7_beyond.json", "manifest.json", "report.md"):
        (folder / name).write_bytes((quick_run / name).read_bytes())
    saved: list[Path] = []

    def save_then_interrupt(fig: Any, path: Path, *args: Any, **kw: Any) -> list[Path]:
        saved.append(path)
        plotting.plt.close(fig)
        raise KeyboardInterrupt

    monkeypatch.setattr(ex, "QUICK", SMALL)
    monkeypatch.setattr(plotting, "save", save_then_interrupt)
    argv = ["reproduce", "--out", str(folder), "--quick", "--jobs", "1", "--overwrite"]
    assert main([*argv, "--only", "beyond"]) == 130
    assert saved and not (folder / "manifest.json").exists()
    assert not (folder / "report.md").exists()


def test_a_ctrl_c_dropped_by_the_garbage_collector_still_interrupts(
    quick_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """A Ctrl-C whose handler runs inside a weakref callback (matplotlib's
    WeakKeyDictionary while reproduce writes its figures: 1 of 7 hand runs near its end),
    where Python drops the exception, still interrupts: no ``Exception ignored in: ...``
    traceback, and the signal, still recorded, is raised once the writing ends: one line,
    130 (not exit 0), the new files and folders removed. Here the signal lands in a
    callback during the second save of three."""
    import weakref

    from continuum_mhe import signals
    from continuum_mhe.evaluation import plotting

    class Thing:
        pass

    saved: list[Path] = []
    real_save = _drawn_small(plotting.save)

    def save(fig: Any, path: Path, formats: Any, *args: Any, **kw: Any) -> list[Path]:
        saved.append(path)
        if len(saved) == 2:
            thing = Thing()
            ref = weakref.ref(thing, lambda r: os.kill(os.getpid(), signal.SIGINT))
            del thing  # the callback runs now, and the handler in it
            assert ref() is None
        return real_save(fig, path, formats[:1], *args, **kw)  # one format is enough here

    monkeypatch.setattr(plotting, "save", save)
    results, out = _first_two_experiments(quick_run, tmp_path / "results"), tmp_path / "figs"
    try:
        code = main(["plot", str(results), "--out", str(out)])
    finally:
        signals.SIGNALS_SEEN.clear()  # (this process goes on with other tests)
    assert (code, capsys.readouterr().err) == (130, "continuum-mhe: interrupted\n")
    assert [p.name for p in saved] == list(FIGURES[:3])  # the writing went on to its end
    assert not out.exists()


@pytest.mark.parametrize("slow_pool", [False, True], ids=["pool", "slow-pool-thread"])
@pytest.mark.parametrize(
    ("sig", "code", "said"),
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")],
    ids=["sigint", "sigterm"],
)
def test_a_signal_to_the_process_group_stops_reproduce_at_once(
    tmp_path: Path, sig: int, code: int, said: str, slow_pool: bool
) -> None:
    """A Ctrl-C that reaches the workers too (a terminal sends it to the process group)
    while they are inside IPOPT, which drops it, stops reproduce at once: the workers
    ignore SIGINT (and die quietly on SIGTERM, no traceback), the parent kills them
    without waiting for the remaining trials, and the --out folder is made only once the
    trials are done: one line, 130 (143), nothing left. The trials here drop every
    interrupt, as IPOPT does (:func:`live_helpers.stubborn_trial`), and the signal goes
    to the whole group once both workers are inside one. With the pool's own thread slow
    to end (:func:`live_helpers.slow_pool_thread`), the exit still writes nothing more
    than the one line."""
    marks, out = tmp_path / "marks", tmp_path / "results"
    marks.mkdir()
    script = (
        "import sys\n"
        "from live_helpers import slow_pool_thread, stubborn_trial\n"
        "from continuum_mhe import cli\n"
        "from continuum_mhe.reproduce import pipeline\n"
        f"if {slow_pool}: slow_pool_thread()\n"
        "pipeline.run_task = stubborn_trial\n"
        "sys.exit(cli.main(['reproduce', '--out', sys.argv[1], '--quick', '--jobs', '2']))\n"
    )
    tests = str(Path(__file__).parent)
    path = os.pathsep.join(filter(None, [tests, os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PYTHONPATH": path, "STUBBORN_MARKS": str(marks)}
    proc = subprocess.Popen(
        [sys.executable, "-c", script, str(out)],
        env=env,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's
    )
    try:
        wait_for(lambda: len(list(marks.iterdir())) == 2 or proc.poll() is not None, "workers")
        assert proc.poll() is None, proc.communicate(timeout=SAFETY_S)[1]
        os.killpg(proc.pid, sig)
        _, err = proc.communicate(timeout=SAFETY_S)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # what is left of a failed run
    assert (proc.returncode, err) == (code, f"continuum-mhe: {said}\n")
    assert not out.exists()
    workers = [int(p.name) for p in marks.iterdir()]
    wait_for(lambda: not any(_alive(pid) for pid in workers), "the workers to end")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _killed(spec: int) -> int:
    if spec == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return spec


def test_a_killed_worker_is_a_one_line_error() -> None:
    """A worker killed from outside (the OOM killer, a SIGTERM to it alone) is a user
    error saying what happened (the other workers are stopped), not a BrokenProcessPool
    reported as a bug in continuum-mhe."""
    with pytest.raises(UserError, match="a worker process ended abruptly"):
        run_parallel(_killed, [0, 1, 2, 3], jobs=2, progress=False)


def test_a_ctrl_c_dropped_inside_a_trial_ends_a_serial_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """``reproduce --jobs 1`` (trials in this process) stops after Ctrl-C even when the
    handler's KeyboardInterrupt is raised inside CasADi's argument checks (building a
    trial's NLP), which drop any exception: the serial run checks for a signal after
    each trial. Here the trial runs the handler and drops its exception, as CasADi
    does."""
    from continuum_mhe import signals

    monkeypatch.setattr(signals, "SIGNALS_SEEN", [])
    ran: list[int] = []

    def trial(spec: int) -> int:
        ran.append(spec)
        with contextlib.suppress(KeyboardInterrupt):  # as CasADi's overload dispatch
            signals.on_signal(signal.SIGINT, None)
        return spec

    with pytest.raises(KeyboardInterrupt):
        run_parallel(trial, [0, 1, 2], jobs=1, progress=False)
    assert ran == [0]


def test_reproduce_rejects_bad_jobs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["reproduce", "--out", str(tmp_path / "r"), "--jobs", "0"]) == 2
    assert "--jobs" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_a_folder_of_the_users_own_report_is_not_written_over(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder that holds a ``report.md`` (or ``manifest.json``) of no ``reproduce`` run
    is refused before the trials, as a part's data would be, unless ``--overwrite``:
    the user's own notes are not replaced."""
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "report.md").write_text("MY OWN NOTES\n")
    argv = ["reproduce", "--out", str(folder), "--quick", "--only", "beyond"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "report.md: exists; give --overwrite" in err[0], err
    assert (folder / "report.md").read_text() == "MY OWN NOTES\n"


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


def test_local_workers_run_a_function_of_a_script(tmp_path: Path) -> None:
    """A trial function defined in ``__main__`` (a script, ``python -c``), which fork
    server workers cannot import: the pool keeps the platform's default start, and
    the trials run (with the fork server every one would fail as 'a worker process
    ended abruptly')."""
    script = (
        "from continuum_mhe.reproduce.runner import run_parallel\n"
        "def square(x):\n"
        "    return x * x\n"
        "if __name__ == '__main__':\n"
        "    print(run_parallel(square, [1, 2, 3], jobs=2, progress=False))\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=SAFETY_S
    )
    assert (r.returncode, r.stdout) == (0, "[1, 4, 9]\n"), r.stderr


def test_unreachable_scheduler_is_a_user_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import dask.distributed as distributed

    client = distributed.Client
    # the runner's Client retries a refused address for 10 s;
    # the same Client and the same error after 0.5 s
    monkeypatch.setattr(
        distributed, "Client", lambda address, **kw: client(address, **{**kw, "timeout": "0.5s"})
    )
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


def test_mean_ci_known_answers() -> None:
    """Percentile bootstrap of the mean: exact quantiles of the resampled means."""
    # two values: means 0, 1/2, 1 with probabilities 1/4, 1/2, 1/4
    two = bootstrap.mean_ci([0.0, 1.0])
    assert (two["mean"], two["lo"], two["hi"]) == (0.5, 0.0, 1.0)
    # [0, 0, 0, 10]: the mean is 2.5 k, k ~ Binomial(4, 1/4); P(k = 0) = 0.32 > 2.5 %,
    # P(k >= 3) = 0.051 > 2.5 % > P(k = 4) = 0.004: the interval is [0, 7.5] (a
    # Student-t interval would be 2.5 +- 7.96, below zero for a non-negative error)
    skew = bootstrap.mean_ci([0.0, 0.0, 0.0, 10.0])
    assert (skew["lo"], skew["hi"]) == (0.0, 7.5)
    assert bootstrap.mean_ci([3.0] * 6)["lo"] == bootstrap.mean_ci([3.0] * 6)["hi"] == 3.0
    assert math.isnan(bootstrap.mean_ci([1.0])["lo"]) and bootstrap.mean_ci([])["n"] == 0
    # many normal values: close to the Student-t interval
    from scipy.stats import t as student_t

    v = np.random.default_rng(5).normal(2.0, 1.0, 400)
    half = student_t.ppf(0.975, 399) * v.std(ddof=1) / math.sqrt(400)
    ci = bootstrap.mean_ci(v.tolist())
    assert ci["lo"] == pytest.approx(v.mean() - half, abs=0.1 * half)
    assert ci["hi"] == pytest.approx(v.mean() + half, abs=0.1 * half)


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


# --- beyond the paper ------------------------------------------------------------------
def test_quick_plan_has_every_beyond_group_on_the_same_seeds() -> None:
    for cfg in (ex.QUICK, ex.FULL):
        specs = ex.plan_beyond_trials(cfg)
        seeds = {g: sorted(s.seed for s in specs if s.group == g) for g in by.BEYOND_GROUPS}
        assert len({tuple(v) for v in seeds.values()}) == 1  # paired: the same seeds
        assert len(seeds["spikes"]) == cfg.beyond_seeds


def test_reproduce_beyond_plans_the_documented_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``reproduce --only beyond`` hands the runner the runs docs/reproduction.md's tables
    were measured on: the same 50 seeds in every group, 20 s each; ``--quick`` 2 seeds,
    5 s (10 s for the recovery groups). The tasks are caught before anything runs."""
    from continuum_mhe.reproduce import pipeline

    class Planned(BaseException):  # not an Exception: main() lets it through
        pass

    def planned(run: Any, tasks: list[Any], **kwargs: Any) -> list[Any]:
        raise Planned(tasks)

    monkeypatch.setattr(pipeline, "run_parallel", planned)
    for quick, n, outlier_s, recovery_s in ((False, 50, 20.0, 20.0), (True, 2, 5.0, 10.0)):
        args = ["reproduce", "--only", "beyond", "--out", str(tmp_path / f"q{quick}")]
        with pytest.raises(Planned) as caught:
            main([*args, "--quick"] if quick else args)
        (tasks,) = caught.value.args
        assert {t.group for t in tasks} == set(by.BEYOND_GROUPS)
        seeds = {g: sorted(t.seed for t in tasks if t.group == g) for g in by.BEYOND_GROUPS}
        assert {tuple(v) for v in seeds.values()} == {tuple(range(110_000, 110_000 + n))}
        for t in tasks:
            assert t.duration == (recovery_s if t.group in by.RECOVERY_GROUPS else outlier_s)


def test_beyond_corruptions() -> None:
    n = 400
    z = np.zeros((n, 2))
    z[:, 1] = math.radians(80.0)
    spec = by.BeyondSpec("spikes", 3, 20.0)
    zs, mask = by.spikes(z, spec)
    idx = np.flatnonzero(mask)
    assert len(idx) == round(spec.spike_fraction * n) and np.all(np.diff(idx) > 1)
    # each spike is the clean reading offset by +-spike_deg on roll and pitch, as a sensor
    # reports it: pitch inside +-90 deg, and at 80 deg pitch a +30 deg offset comes back
    # as 70 deg with roll turned by 180 deg (not clipped at 90 deg)
    s = math.radians(spec.spike_deg)
    signs = [(a, b) for a in (-1.0, 1.0) for b in (-1.0, 1.0)]
    for i in idx:
        options = [as_sensor_reads((z[i] + s * np.array(o))[None])[0] for o in signs]
        assert min(np.abs(zs[i] - o).max() for o in options) < 1e-12
    assert np.all(np.abs(zs[:, 1]) <= math.pi / 2)
    pitch = np.round(np.degrees(zs[idx, 1]), 9)
    assert set(pitch) == {50.0, 70.0}  # 80 - 30, and 80 + 30 reflected (never 90)
    assert np.array_equal(zs[~mask], z[~mask])
    zb, mask = by.bursts(z, by.BeyondSpec("bursts", 3, 20.0))
    runs = np.diff(np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0])))[::2]
    assert list(runs) == [spec.burst_length] * round(spec.burst_fraction * n)
    assert set(np.round(np.degrees(zb[mask, 1]), 9)) <= {50.0, 70.0}  # as the spikes
    assert np.array_equal(zb[~mask], z[~mask])
    bad = by.bad_start(z, np.arange(n) * 0.05, by.BeyondSpec("bad-start", 3, 20.0))
    assert set(np.round(np.degrees(bad[:10, 1]), 9)) == {40.0}  # 80 + 60 reflected
    # the loss benchmark's spikes are made the same way
    rec = Recording(t=np.arange(n) * 0.05, z=z, truth=np.zeros((n, 5)), length=0.2)
    zl = with_spikes(rec).z
    hit = np.any(zl != z, axis=1)
    assert hit.sum() == 8 and set(np.round(np.degrees(zl[hit, 1]), 9)) <= {50.0, 70.0}
    with pytest.raises(UserError, match=r"^duration must be at least 10 s for the gap group$"):
        by.BeyondSpec("gap", 0, 5.0)  # too short for the gap and the 2 s after


def test_paired_bootstrap_known_answers() -> None:
    b = np.array([1.0, 2.0, 3.0, 5.0])
    r = bootstrap.paired(2 * b, b, "ratio")  # every resample: ratio exactly 2
    assert (r["value"], r["lo"], r["hi"]) == pytest.approx((2.0, 2.0, 2.0))
    d = bootstrap.paired(b + 0.5, b, "diff")
    assert (d["value"], d["lo"], d["hi"]) == pytest.approx((0.5, 0.5, 0.5))
    assert math.isnan(bootstrap.paired([1.0], [2.0], "diff")["hi"])


def _p(value: float, lo: float, hi: float) -> dict[str, float]:
    return {"value": value, "lo": lo, "hi": hi, "n": 50}


def test_beyond_verdicts_follow_their_rules(quick_run: Path) -> None:
    d = load_results(quick_run)["exp7_beyond"]
    t = d["summary"]["targets"]
    t["spikes"]["robust_over_own_clean"] = _p(1.05, 1.04, 1.09)
    t["spikes"]["robust_minus_ekf_mm"] = _p(-1.0, -1.2, -0.1)
    assert rp.claim_outliers(d, "spikes").verdict == "holds"
    t["spikes"]["robust_over_own_clean"] = _p(1.08, 1.05, 1.11)  # the interval crosses 1.1
    assert rp.claim_outliers(d, "spikes").verdict == "partly holds (below the EKF)"
    t["spikes"]["robust_minus_ekf_mm"] = _p(-0.2, -0.4, 0.01)  # crosses zero
    assert rp.claim_outliers(d, "spikes").verdict == "does not hold"
    t["clean"]["robust_over_l2"] = _p(1.0, 0.99, 1.019)
    assert rp.claim_clean(d).verdict == "holds"
    t["clean"]["robust_over_l2"] = _p(1.0, 0.99, 1.021)
    assert rp.claim_clean(d).verdict == "does not hold"
    cov = d["summary"]["coverage"]
    for m, v in zip(("mhe", "ekf", "ukf"), (0.95, 0.901, 0.979)):
        cov[m]["coverage_3d"]["mean"] = v
    assert rp.claim_coverage(d).verdict == "holds"
    cov["ekf"]["coverage_3d"]["mean"] = 0.899
    assert rp.claim_coverage(d).verdict == "partly holds (MHE, UKF)"
    gap = d["summary"]["recovery"]["gap"]
    for e in gap.values():
        e["tip_mean_mm"]["off"]["mean"] = 10.0
        e["tip_mean_mm"]["on_minus_off"] = _p(-1.0, -2.0, 0.19)  # within 2 % of 10 mm
        e["ok_wrong"]["on"]["mean"] = 0.0
    assert rp.claim_gap(d).verdict == "holds"
    gap["ukf"]["tip_mean_mm"]["on_minus_off"] = _p(0.1, -0.1, 0.21)
    gap["ekf"]["ok_wrong"]["on"]["mean"] = 0.5
    assert rp.claim_gap(d).verdict == "partly holds (MHE)"
    frz = d["summary"]["recovery"]["freeze"]
    for e in frz.values():
        e["ok_wrong"]["on_minus_off"] = _p(-40.0, -45.0, -30.0)
    assert rp.claim_freeze(d).verdict == "holds"
    for e in frz.values():
        e["ok_wrong"]["on_minus_off"] = _p(0.0, 0.0, 0.0)
    assert rp.claim_freeze(d).verdict == "does not hold"
    bad = d["summary"]["recovery"]["bad-start"]
    for e in bad.values():
        e["tip_mean_mm"]["on_minus_off"] = _p(-2.0, -2.5, -1.5)
        e["clean_fired"], e["clean_diff_mm"] = 0, 0.0
    assert rp.claim_bad_start(d).verdict == "holds"
    bad["mhe"]["clean_fired"] = 1  # fired on clean data
    bad["ukf"]["tip_mean_mm"]["on_minus_off"] = _p(-0.1, -0.5, 0.1)  # crosses zero
    assert rp.claim_bad_start(d).verdict == "partly holds (EKF)"


def test_quick_report_has_the_beyond_section(quick_run: Path) -> None:
    """The section is there with one row per target, its verdicts are the claims' own,
    its figure exists and its rerun block gives the saved numbers."""
    report = (quick_run / "report.md").read_text()
    section = report.split("## Beyond the paper\n", 1)[1]
    d = load_results(quick_run)["exp7_beyond"]
    claims = rp.beyond_claims(d)
    assert len(claims) == 7
    for c in claims:
        assert f"| **{c.verdict}** |" in section and c.rule.startswith("holds")
    assert (quick_run / "exp7_beyond.png").stat().st_size > 1000
    block = section.split("group `spikes`:\n\n```python\n", 1)[1].split("```", 1)[0]
    namespace: dict[str, Any] = {}
    exec(compile(block, "report.md", "exec"), namespace)
    first = min((t for t in d["trials"] if t["spec"]["group"] == "spikes"),
                key=lambda t: t["spec"]["seed"])  # fmt: skip
    got = namespace["result"]["methods"]
    for m in by.OUTLIER_METHODS:
        assert got[m]["tip_mean_mm"] == pytest.approx(first["methods"][m]["tip_mean_mm"], 1e-9)


def test_reproduce_only_beyond(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--only beyond`` runs that experiment alone (here one seed per group) and the
    report has its section and no paper claims."""
    from continuum_mhe.reproduce import pipeline

    one = [s for s in ex.plan_beyond_trials(ex.QUICK) if s.seed == 110_000]
    monkeypatch.setattr(pipeline, "plan_beyond_trials", lambda cfg: one)
    out = tmp_path / "r"
    args = ["reproduce", "--quick", "--only", "beyond", "--out", str(out), "--jobs", "1"]
    assert main(args) == 0
    assert sorted(p.stem for p in out.glob("exp*.json")) == ["exp7_beyond"]
    report = (out / "report.md").read_text()
    assert "## Beyond the paper" in report and "## Paper vs. ours" not in report
    assert f"{len(one)} runs beyond the paper" in report
    assert (out / "exp7_beyond.png").is_file()


def test_a_run_of_one_part_into_the_folder_of_another_keeps_its_record(
    quick_trials: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--only beyond`` into a folder that holds another part's results records that
    earlier run in its manifest (``earlier_runs``) and report beside its own, as the
    earlier data stay there; a run of the same part replaces the record with its data.
    (The trials' results are the quick run's, its figure drawn small.)"""
    from continuum_mhe.evaluation import plotting
    from continuum_mhe.reproduce import pipeline

    monkeypatch.setattr(plotting, "save", _drawn_small(plotting.save))
    monkeypatch.setattr(ex, "QUICK", SMALL)
    one = [s for s in ex.plan_beyond_trials(SMALL) if s.seed == 110_000]
    monkeypatch.setattr(pipeline, "plan_beyond_trials", lambda cfg: one)
    out = tmp_path / "r"
    out.mkdir()
    paper_run = {"command": "continuum-mhe reproduce --only paper --out r", "parts": ["paper"]}
    (out / "manifest.json").write_text(json.dumps(paper_run))
    args = ["reproduce", "--quick", "--only", "beyond", "--out", str(out), "--jobs", "1"]
    assert main(args) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["parts"] == ["beyond"] and manifest["earlier_runs"] == [paper_run]
    report = (out / "report.md").read_text()
    assert "from an earlier run: `continuum-mhe reproduce --only paper --out r` (paper)" in report
    assert main([*args, "--overwrite"]) == 0  # beyond again: the paper run is kept, once
    again = json.loads((out / "manifest.json").read_text())
    assert again["earlier_runs"] == [paper_run]


def test_a_failed_run_of_another_part_leaves_the_earlier_runs_record(
    quick_trials: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--only beyond`` into the folder of a paper run that fails while drawing (no
    data of the paper run replaced): its new files are removed and the paper run's
    manifest and report are there as they were."""
    from continuum_mhe.evaluation import plotting
    from continuum_mhe.reproduce import pipeline

    def fail(*args: Any, **kw: Any) -> list[Path]:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(plotting, "save", fail)
    monkeypatch.setattr(ex, "QUICK", SMALL)
    one = [s for s in ex.plan_beyond_trials(SMALL) if s.seed == 110_000]
    monkeypatch.setattr(pipeline, "plan_beyond_trials", lambda cfg: one)
    out = tmp_path / "r"
    out.mkdir()
    record = {"manifest.json": '{"command": "continuum-mhe reproduce --only paper", '
                               '"parts": ["paper"]}', "report.md": "the paper run\n",
              "exp1_synthetic3d.json": "{}"}  # fmt: skip
    for name, text in record.items():
        (out / name).write_text(text)
    args = ["reproduce", "--quick", "--only", "beyond", "--out", str(out), "--jobs", "1"]
    assert main(args) == 2
    assert {p.name: p.read_text() for p in out.iterdir()} == record


def test_earlier_runs_keep_only_those_whose_data_stay(tmp_path: Path) -> None:
    """A run of every part, then ``--only beyond``, then ``--only paper``: the first
    run's data are all replaced, so only the beyond run is kept beside the paper run;
    a manifest without a readable list of earlier runs is read as having none."""
    from continuum_mhe.reproduce.pipeline import earlier_runs

    manifest = tmp_path / "manifest.json"
    everything = {"command": "a", "parts": ["paper", "beyond"]}
    beyond = {"command": "b", "parts": ["beyond"]}
    manifest.write_text(json.dumps({**beyond, "earlier_runs": [everything]}))
    assert earlier_runs(manifest, ["paper"]) == [beyond]
    assert earlier_runs(manifest, ["beyond"]) == [everything]  # its paper data stay
    manifest.write_text(json.dumps({**beyond, "earlier_runs": None}))
    assert earlier_runs(manifest, ["paper"]) == [beyond]
    manifest.write_text("not json")
    assert earlier_runs(manifest, ["paper"]) == []


def test_reproduce_refuses_a_bad_scheduler_address_or_rod_recording_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A scheduler address without a port, --jobs with a scheduler, an estimate file given
    as the rod recording, and a rod recording no longer than the MHE's window: each one
    line naming it, exit 2, no folder (not an internal error, a 403-line numpy error,
    or a claim said to hold on 3 samples)."""
    from continuum_mhe.simulation.cosserat import default_data_path

    out = tmp_path / "r"
    est = tmp_path / "e.csv"
    est.write_text('# continuum-mhe = "0.1.0 estimate m.csv"\nt,x,y,z,status\n0,0,0,0.2,ok\n')
    rod = default_data_path()
    short = tmp_path / "short.csv"
    short.write_text("".join(rod.read_text().splitlines(keepends=True)[:4]))
    one = tmp_path / "one.csv"
    one.write_text("".join(rod.read_text().splitlines(keepends=True)[:2]))
    bad = tmp_path / "bad.csv"
    lines = rod.read_text().splitlines(keepends=True)
    lines[4] = lines[4].rstrip("\n") + ",1\n"  # file line 5: a field too many
    bad.write_text("".join(lines))
    text = tmp_path / "text.csv"  # a cell that is no number: refused, not read as NaN
    lines = rod.read_text().splitlines(keepends=True)
    header = next(ln for ln in lines if not ln.startswith("#")).strip().split(",")
    at = lines.index(next(ln for ln in lines if not ln.startswith("#"))) + 3
    cells = lines[at].rstrip("\n").split(",")
    cells[header.index("roll")] = "abc"
    lines[at] = ",".join(cells) + "\n"
    text.write_text("".join(lines))
    cases = [
        (["--scheduler", "notanaddress"], "not a scheduler's address: give its host and port"),
        (["--scheduler", "tcp://h:8786", "--jobs", "2"], "--jobs does nothing with --scheduler"),
        (["--rod-csv", str(est)], "not a rod recording: missing column(s) roll, pitch"),
        (["--rod-csv", str(short)], "3 samples: the rod experiment's MHE window needs more"),
        (["--rod-csv", str(one)], "1 samples: the rod experiment's MHE window needs more"),
        (["--rod-csv", str(bad)], f"{bad}: line 5: 17 fields, the header has 16"),
        (["--rod-csv", str(text)], f"{text}: line {at + 1}: column roll: 'abc' is not a number"),
    ]
    for extra, said in cases:
        assert main(["reproduce", "--out", str(out), "--quick", *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and said in err, err
        assert not out.exists()


def test_plot_of_a_results_folder_with_a_malformed_results_file_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A results JSON of the wrong structure (valid JSON): one line naming it, exit 2,
    no figure (not an internal error)."""
    folder = tmp_path / "res"
    folder.mkdir()
    (folder / "exp2_constraints.json").write_text('{"config": {}, "example": 5}')
    out = tmp_path / "figs"
    assert main(["plot", str(folder), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exp2_constraints.json of the results: not a results" in err
    assert not any(out.glob("*.png"))


def test_the_horizon_sweeps_verdict_is_on_a_total_its_table_shows(quick_run: Path) -> None:
    """Sec. 3.5's total time: the table gives the sum of the solves and (M - N + 1) x the
    median, the one the verdict judges, and the N it names as the peak is that column's
    largest (not the sum alone, whose peak can be elsewhere)."""
    report = (quick_run / "report.md").read_text()
    lines = report[report.index("## 5. Horizon sweep") :].splitlines()
    header = next(ln for ln in lines if ln.startswith("| N |"))
    names = [c.strip() for c in header.strip("|").split("|")]
    judged = names.index("total ms, (M - N + 1) x median (judged)")
    assert "total ms, sum of the M - N + 1 solves" in names
    rows = [ln for ln in lines if re.match(r"\| \d+ \|", ln)]
    cells = [[c.strip() for c in r.strip("|").split("|")] for r in rows]
    top = max(float(c[judged]) for c in cells)  # (as printed: ties are any of them)
    named = re.search(r"peaks at N = (\d+) in this sweep", report)
    assert named, report
    assert any(c[0] == named[1] and float(c[judged]) == top for c in cells), (named[1], cells)


def test_plot_of_a_results_folder_into_a_file_says_it_is_not_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--out naming a file: one line saying it is not a folder (not the OS's 'File
    exists')."""
    folder = tmp_path / "res"
    folder.mkdir()
    (folder / "exp2_constraints.json").write_text("{}")
    target = tmp_path / "report.md"
    target.write_text("x")
    assert main(["plot", str(folder), "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{target}: not a folder: give --out a folder" in err


def test_conditions_figure_draws_the_tip_error_of_the_report_table(quick_run: Path) -> None:
    """Both panels of ``exp4_conditions`` give the mean tip error (mm) that the report's
    table of the conditions and its verdicts give, the whole run's and the first N's."""
    from matplotlib.container import BarContainer

    from continuum_mhe.evaluation import plotting

    d = load_results(quick_run)["exp4_ekf_comparison"]
    figs = RENDERERS["exp4_ekf_comparison"](d)
    try:
        whole, first = figs["exp4_conditions"].axes[:2]
        for ax, block in ((whole, d["conditions"]), (first, d["conditions_early"])):
            assert ax.get_ylabel() == "mean tip error (mm)"
            bars = next(c for c in ax.containers if isinstance(c, BarContainer))  # MHE's
            mhe = [bar.get_height() for bar in bars]
            assert mhe == pytest.approx([g["mhe"]["tip_mean_mm"]["mean"] for g in block.values()])
    finally:
        for fig in figs.values():
            plotting.close(fig)


def test_beyond_figure_tick_labels_do_not_overlap(quick_run: Path) -> None:
    """The recovery panel's labels (``bad-start off`` beside ``bad-start on``) are each
    readable: no two of a panel's x tick labels overlap."""
    from continuum_mhe.evaluation import plotting

    fig = RENDERERS["exp7_beyond"](load_results(quick_run)["exp7_beyond"])["exp7_beyond"]
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        for ax in fig.axes:
            boxes = [t.get_window_extent(renderer) for t in ax.get_xticklabels() if t.get_text()]
            for a, b in zip(boxes, boxes[1:]):
                assert a.x1 <= b.x0 or not a.overlaps(b), ax.get_title()
    finally:
        plotting.close(fig)
