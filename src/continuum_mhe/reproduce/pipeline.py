"""Run every experiment, save one JSON file per experiment, then plot and report.

Layout of a results folder::

    manifest.json              config, versions, timing, command
    exp1_synthetic3d.json ...  one data file per experiment (see EXPERIMENTS)
    *.png, *.pdf               figures (re-rendered from the JSON by ``plot``)
    report.md                  tables, settings of every run, paper vs. ours
"""

from __future__ import annotations

import json
import math
import platform
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.output_files import new_files
from continuum_mhe.reproduce.beyond import BeyondSpec, run_beyond, summarise_beyond
from continuum_mhe.reproduce.bootstrap import mean_ci
from continuum_mhe.reproduce.experiments import (
    EXPERIMENTS,
    TABLE1,
    ReproduceConfig,
    TrialSpec,
    plan_beyond_trials,
    plan_trials,
    run_rod,
    run_trial,
    summarise_groups,
    to_jsonable,
)
from continuum_mhe.reproduce.runner import run_parallel
from continuum_mhe.settings import MHESettings, NoiseSettings

Part = Literal["paper", "beyond"]
#: What ``reproduce`` can run: the paper's Sec. 3, and beyond the paper.
PARTS: tuple[Part, ...] = ("paper", "beyond")


@dataclass(frozen=True)
class RodTask:
    """The Sec. 3.3 run on a rod recording (``path``; None: the shipped example)."""

    cfg: ReproduceConfig
    path: str | None = None


def run_task(task: TrialSpec | RodTask | BeyondSpec) -> dict[str, Any]:
    """Run one task of any kind (the function the workers call)."""
    if isinstance(task, BeyondSpec):
        return dict(to_jsonable(run_beyond(task)))
    if isinstance(task, RodTask):
        from continuum_mhe.simulation.cosserat import default_data_path

        path = Path(task.path) if task.path else default_data_path()
        return run_rod(path, task.cfg)
    return run_trial(task)


def part_data_files(parts: Sequence[Part]) -> list[str]:
    """The experiment data files (JSON) that running ``parts`` writes: the paper's
    experiments, and ``exp7_beyond`` beyond it. The manifest, the figures and
    ``report.md`` are rebuilt from every experiment's data in the folder on each run."""
    from continuum_mhe.reproduce.experiments import EXPERIMENTS

    beyond = "exp7_beyond"
    names = [e for e in EXPERIMENTS if e != beyond] if "paper" in parts else []
    return [f"{e}.json" for e in names + ([beyond] if "beyond" in parts else [])]


def save_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as JSON (NaN as null), atomically."""
    from continuum_mhe.io.output_files import atomic_writer

    with atomic_writer(path) as fh:
        json.dump(to_jsonable(data), fh, allow_nan=False, separators=(",", ":"))


def load_results(folder: str | Path) -> dict[str, dict[str, Any]]:
    """Read every experiment's JSON in ``folder``; raises InputError if none is there."""
    d = Path(folder)
    if not d.is_dir():
        raise InputError(f"{d}: no such results folder")
    out: dict[str, dict[str, Any]] = {}
    for name in EXPERIMENTS:
        p = d / f"{name}.json"
        if p.is_file():
            try:
                out[name] = json.loads(p.read_text(encoding="utf-8"))
            except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                raise InputError(f"{p}: not a results file ({exc})") from None
    if not out:
        raise InputError(
            f"{d}: no experiment data (expected {EXPERIMENTS[0]}.json ...); "
            "run 'continuum-mhe reproduce --out DIR' first"
        )
    manifest = d / "manifest.json"
    if manifest.is_file():
        out["manifest"] = json.loads(manifest.read_text(encoding="utf-8"))
    return out


def _strip_series(trial: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in trial.items() if k != "series"}


def assemble(
    cfg: ReproduceConfig, trials: Sequence[dict[str, Any]], rod: dict[str, Any]
) -> dict[str, dict[str, Any]]:
    """Group the paper's trial results into the per-experiment data files."""
    by: dict[str, list[dict[str, Any]]] = {}
    for tr in trials:
        by.setdefault(tr["spec"]["experiment"], []).append(tr)
    common = {"config": asdict(cfg)}

    def example(name: str) -> dict[str, Any]:
        return next(tr for tr in by[name] if tr["spec"]["group"] == "example")

    exp4 = by["exp4_ekf_comparison"]
    mc = [_strip_series(tr) for tr in exp4 if tr["spec"]["group"].startswith("table1-")]
    cond = [_strip_series(tr) for tr in exp4 if tr["spec"]["group"].startswith("condition-")]
    sweep = by["exp5_horizon"]
    horizons: dict[int, list[dict[str, Any]]] = {}
    ipopt: dict[int, list[dict[str, Any]]] = {}
    for tr in sweep:
        if tr["spec"].get("mhe_solver"):
            ipopt.setdefault(int(tr["spec"]["horizon"]), []).append(tr["methods"]["mhe"])
        else:
            horizons.setdefault(int(tr["spec"]["horizon"]), []).append(tr)
    sweep_summary = {
        str(n): {
            "srmse": mean_ci([tr["methods"]["mhe"]["all"]["srmse"] for tr in trs]),
            "srmse_common": mean_ci([tr["methods"]["mhe"]["from"]["srmse"] for tr in trs]),
            "tip_mm_common": mean_ci([tr["methods"]["mhe"]["from"]["tip_mean_mm"] for tr in trs]),
            "score_from": trs[0]["spec"]["score_from"],
            "solve_ms_mean": mean_ci([tr["methods"]["mhe"]["solve_ms_mean"] for tr in trs]),
            "solve_ms_median": mean_ci([tr["methods"]["mhe"]["solve_ms_median"] for tr in trs]),
            "solve_ms_total": mean_ci([tr["methods"]["mhe"]["solve_ms_total"] for tr in trs]),
            "n_estimates": trs[0]["methods"]["mhe"]["all"]["n"],
            "n_samples": trs[0]["methods"]["mhe"]["all"]["n"]
            + trs[0]["methods"]["mhe"]["all"]["n_without_estimate"],
            "ipopt": {
                "n_seeds": len(ipopt[n]),
                "srmse_common": mean_ci([x["from"]["srmse"] for x in ipopt[n]]),
                **{
                    k: mean_ci([x[k] for x in ipopt[n]])
                    for k in ("solve_ms_mean", "solve_ms_median", "solve_ms_total")
                },
            }
            if n in ipopt
            else None,
        }
        for n, trs in sorted(horizons.items())
    }
    win = by["exp6_window"]
    win_summary: dict[str, Any] = {}
    for g in ("growing", "paper-start"):
        trs = [tr for tr in win if tr["spec"]["group"] == g]
        m = [tr["methods"]["mhe"] for tr in trs]
        dt = trs[0]["spec"]["dt"]
        win_summary[g] = {
            "first_estimate_s": mean_ci([x["first_estimate_index"] * dt for x in m]),
            "early_srmse": mean_ci([x["early"]["srmse"] if x["early"] else math.nan for x in m]),
            "early_tip_mm": mean_ci(
                [x["early"]["tip_mean_mm"] if x["early"] else math.nan for x in m]
            ),
            # how many of the first N samples that error is over (the paper start: 1)
            "early_estimates": mean_ci([x["early"]["n"] if x["early"] else 0 for x in m]),
            "late_srmse": mean_ci([x["late"]["srmse"] for x in m]),
            "late_tip_mm": mean_ci([x["late"]["tip_mean_mm"] for x in m]),
            "solve_ms_mean": mean_ci([x["solve_ms_mean"] for x in m]),
        }
        if g == "growing":
            e = [tr["methods"]["ekf"] for tr in trs]
            win_summary["ekf"] = {
                "first_estimate_s": mean_ci([x["first_estimate_index"] * dt for x in e]),
                "early_srmse": mean_ci([x["early"]["srmse"] for x in e]),
                "early_tip_mm": mean_ci([x["early"]["tip_mean_mm"] for x in e]),
                "early_estimates": mean_ci([x["early"]["n"] for x in e]),
                "late_srmse": mean_ci([x["late"]["srmse"] for x in e]),
                "late_tip_mm": mean_ci([x["late"]["tip_mean_mm"] for x in e]),
            }
    return {
        "exp1_synthetic3d": {
            **common,
            "example": example("exp1_synthetic3d"),
            "paper_formulation": next(
                (t for t in by["exp1_synthetic3d"] if t["spec"]["group"] == "paper-formulation"),
                None,
            ),
        },
        "exp2_constraints": {**common, "example": example("exp2_constraints")},
        "exp3_rod": {**common, **rod},
        "exp4_ekf_comparison": {
            **common,
            "table1": [list(r) for r in TABLE1],
            "example": example("exp4_ekf_comparison"),
            "monte_carlo": summarise_groups(mc, ("mhe", "ekf", "ukf")),
            "conditions": summarise_groups(cond, ("mhe", "ekf", "ukf")),
            "conditions_early": summarise_groups(cond, ("mhe", "ekf", "ukf"), part="early"),
            "trials": mc + cond,
        },
        "exp5_horizon": {
            **common,
            "summary": sweep_summary,
            "trials": [_strip_series(tr) for tr in sweep],
        },
        "exp6_window": {
            **common,
            "summary": win_summary,
            "examples": {tr["spec"]["group"]: tr for tr in win if "series" in tr},
            "trials": [_strip_series(tr) for tr in win],
        },
    }


def assemble_beyond(cfg: ReproduceConfig, trials: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The ``exp7_beyond`` data file from the :class:`BeyondSpec` results."""
    return {"config": asdict(cfg), "summary": summarise_beyond(trials), "trials": list(trials)}


def earlier_runs(path: Path, parts: Sequence[Part]) -> list[dict[str, Any]]:
    """The runs recorded in the manifest at ``path`` (itself and its own
    ``earlier_runs``, oldest first) whose data stay in the folder beside a run of
    ``parts``: those with a part that neither this run nor a later one made again
    (``--only`` into the folder of another part). Empty without a readable manifest."""
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(old, dict):
        return []
    earlier = old.pop("earlier_runs", [])
    runs = [r for r in earlier if isinstance(r, dict)] if isinstance(earlier, list) else []
    runs.append(old)
    replaced, kept = set(parts), []
    for run in reversed(runs):  # newest first: what it made replaced the older runs' data
        made = run.get("parts", PARTS)
        made = set(made) if isinstance(made, list) else set(PARTS)
        if made - replaced:
            kept.append(run)
        replaced |= made
    return kept[::-1]


def reproduce(
    out: str | Path,
    cfg: ReproduceConfig,
    *,
    jobs: int | None = None,
    scheduler: str | None = None,
    rod_path: str | None = None,
    progress: bool | None = None,
    command: str = "",
    parts: Sequence[Part] = PARTS,
) -> list[Path]:
    """Run every experiment of ``parts``, then write their data, figures and
    ``report.md`` (from every experiment's data in ``out``) into ``out``, created then.

    Returns the files written.
    """
    if not parts or not set(parts) <= set(PARTS):
        raise UserError(f"parts must be some of {PARTS}, got {tuple(parts)}")
    from continuum_mhe import __version__
    from continuum_mhe.reproduce.figures import render_all
    from continuum_mhe.reproduce.report import write_report

    folder = Path(out)
    paper = "paper" in parts
    specs = plan_trials(cfg) if paper else []
    beyond = plan_beyond_trials(cfg) if "beyond" in parts else []
    rod: list[TrialSpec | RodTask | BeyondSpec] = [RodTask(cfg, rod_path)] if paper else []
    tasks: list[TrialSpec | RodTask | BeyondSpec] = [*rod, *specs, *beyond]
    start = time.perf_counter()
    results = run_parallel(
        run_task,
        tasks,
        jobs=jobs,
        scheduler=scheduler,
        description="reproduce",
        progress=progress,
    )
    wall = time.perf_counter() - start
    n = len(rod) + len(specs)
    data = assemble(cfg, results[1:n], results[0]) if paper else {}
    if beyond:
        data["exp7_beyond"] = assemble_beyond(cfg, results[n:])
    from importlib import metadata

    import numpy

    manifest = {
        "command": command,
        "config": asdict(cfg),
        "parts": list(parts),
        "n_trials": len(specs),
        "n_beyond_trials": len(beyond),
        "wall_s_trials": wall,
        "jobs": jobs,
        "scheduler": scheduler,
        "mhe_settings_default": repr(MHESettings()),
        "noise_settings_default": repr(NoiseSettings()),
        "versions": {
            "continuum_mhe": __version__,
            "python": platform.python_version(),
            "numpy": numpy.__version__,
            "casadi": metadata.version("casadi"),
        },
        "machine": platform.platform(),
    }
    earlier = earlier_runs(folder / "manifest.json", parts)
    if earlier:
        manifest["earlier_runs"] = earlier
    # the folder and the files once the trials are done; an interruption or an error
    # while writing leaves none of the new files, nor the folders it created. Files of an
    # earlier run it replaced (--overwrite) keep their new content: the manifest, which
    # would record this run as made, is removed then, so that the folder claims no run
    replacing = (folder / "manifest.json").is_file()
    before = set(folder.iterdir()) if folder.is_dir() else set()
    record = ("manifest.json", "report.md")  # the earlier run's, kept where its data stay
    kept = {n: (folder / n).read_bytes() for n in record if (folder / n).is_file()}
    try:
        with new_files(folder) as written:
            for name, d in data.items():
                p = folder / f"{name}.json"
                save_json(p, d)
                written.append(p)
            save_json(folder / "manifest.json", manifest)
            written.append(folder / "manifest.json")
            loaded = load_results(folder)
            render_all(loaded, folder, written)
            written.append(write_report(loaded, folder))
    except BaseException:
        # the new files are removed (new_files); where a data file of the earlier run was
        # replaced, its manifest and report describe data partly not there: removed;
        # else the earlier run's record is put back as it was
        if replacing and any(p in before for p in written if p.name not in record):
            (folder / "manifest.json").unlink(missing_ok=True)
            if folder / "report.md" not in written:  # (one written here is of this data)
                (folder / "report.md").unlink(missing_ok=True)
        else:
            for name, content in kept.items():
                (folder / name).write_bytes(content)
        raise
    return written
