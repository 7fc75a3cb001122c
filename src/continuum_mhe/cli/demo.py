"""``continuum-mhe demo``: simulate, run MHE, EKF and UKF, print their errors, plot."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from continuum_mhe.cli.robot_options import add_robot_option, robot_from_args
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.estimators import METHODS, EstimateSeries, make_estimator
from continuum_mhe.evaluation.metrics import Metrics, compute_metrics
from continuum_mhe.io.estimate_csv import write_estimates, write_measurements, write_truth
from continuum_mhe.io.output_files import check_new_folder, new_files
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.progress import progress_bar, table_console
from continuum_mhe.settings import MHESettings, NoiseSettings
from continuum_mhe.signals import interruptible
from continuum_mhe.simulation.scenarios import Recording, ScenarioName, simulate_robot

if TYPE_CHECKING:
    from matplotlib.figure import Figure


#: The demo's own folder, where it writes without --out (and replaces its files).
DEFAULT_OUT = "continuum-mhe-demo"

DESCRIPTION = (
    "Simulate the paper's 3D motion (or a robot file's), run the MHE, EKF and UKF on it, "
    "print their errors against the truth and plot them: the whole tool on built-in data."
)


def run(args: argparse.Namespace) -> int:
    from rich.table import Table

    out = Path(args.out or DEFAULT_OUT)
    robot = robot_from_args(args) if args.robot else Robot.single(0.2)
    if robot.tendons:  # the demo simulates constant-curvature motions
        raise InputError(
            f"{args.robot}: a tendon robot ({robot.describe()}): the demo simulates the "
            "motions of a constant-curvature robot without tensions; a tendon robot's "
            "recordings (tensions, tip force) come from continuum-mhe rod tendon, "
            "estimated with --inputs (docs/tendon.md)"
        )
    # the default folder is the demo's own: a second demo there replaces its files
    check_new_folder(out, args.overwrite or args.out is None, demo_files(robot))
    scenario: ScenarioName = "paper3d" if robot.n_sections == 1 else "spatial"
    try:
        rec = simulate_robot(scenario, robot, seed=args.seed)
    except UserError as exc:  # about the robot: its file named, as simulate names it
        if args.robot is None:
            raise
        raise InputError(f"{args.robot}: {exc}") from None
    formulation = make_formulation("bend", robot, NoiseSettings())
    names = [o.name for o in rec.outputs]
    results: list[tuple[EstimateSeries, Metrics]] = []
    labels: list[str] = []
    for method in METHODS:
        est = make_estimator(method, formulation, MHESettings())
        series = est.run(rec.t, rec.z, progress=interruptible(progress_bar(f"demo: {method}")))
        results.append((series, compute_metrics(series.output, rec.truth, robot.length, names)))
        labels.append(method.upper())
    what = "0.2 m" if robot.is_single else robot.describe()
    table = Table(title=f"{scenario}, {what}, 2 deg noise, N = 30 (continuum-mhe demo)")
    angles = [n for n in names if n.startswith(("theta", "phi"))]
    for col in ("method", "tip mean mm", "tip mean %", "tip max mm"):
        table.add_column(col, justify="right")
    for n in angles:
        table.add_column(f"{n} RMSE deg", justify="right")
    table.add_column("median solve ms", justify="right")
    for label, (s, m) in zip(labels, results):
        table.add_row(
            label,
            f"{m.tip_mean_mm:.2f}",
            f"{m.tip_mean_pct:.2f}",
            f"{m.tip_max_mm:.2f}",
            *(f"{math.degrees(m.rmse[n]):.2f}" for n in angles),
            f"{float(np.median(s.solve_ms)):.3f}",
        )
    table_console().print(table)
    all_series = [s for s, _ in results]
    csvs = [out / name for name in demo_files(robot) if name.endswith(".csv")]
    with new_files(out) as written:  # after the estimates, not during them
        for path, (series, _), method in zip(csvs, results, METHODS):
            write_estimates(path, series, _options_note(method, args.robot))
            written.append(path)
        write_measurements(csvs[-2], rec.t, rec.z, rec.measurement_names)
        written.append(csvs[-2])
        write_truth(csvs[-1], rec.t, rec.truth, rec.outputs)
        written.append(csvs[-1])
        _demo_figures(out, rec, all_series, robot, scenario, what, written)
    figs = written[len(csvs) :]
    print(f"figures: {', '.join(str(p) for p in figs)}", file=sys.stderr)
    return 0


def _options_note(method: str, robot: str | None) -> list[tuple[str, str]]:
    """The ``# options = {...}`` line of a demo estimate, as ``estimate`` writes one: the
    method and the robot file (``evaluate``, ``plot`` and ``view`` of the file then take
    that robot; without one, the default 0.2 m section)."""
    import tomlkit

    table = tomlkit.inline_table()
    table["method"] = method
    if robot is not None:
        table["robot"] = robot
    return [("options", table.as_string())]


def demo_files(robot: Robot) -> list[str]:
    """The names of the files the demo writes into its folder: the estimates of each
    method, the measurements and the truth (CSV, in that order), then the figures."""
    figures = ["demo_trajectory_3d.png", "demo_states.png"]
    if not robot.is_single:
        figures.append("demo_backbone.png")
    csvs = [f"estimates_{m}.csv" for m in METHODS] + ["measurements.csv", "truth.csv"]
    return csvs + figures


def _demo_figures(
    out: Path, rec: Recording, all_series: list[EstimateSeries], robot: Robot, scenario: str,
    what: str, written: list[Path],
) -> None:  # fmt: skip
    """The demo's figures in ``out`` (PNG), each file into ``written`` once saved."""
    from continuum_mhe.evaluation import plotting

    def save(fig: Figure, name: str) -> None:
        written.extend(plotting.save(fig, out / name, ("png",)))  # atomic: saved or not

    where = f"simulated {scenario} recording, {what}"
    z_down = robot.mounting == "z-down"  # drawn as it hangs
    path_title = f"Tip path: truth and estimates ({where})"
    save(plotting.trajectory_3d(rec.truth, all_series, path_title, z_down), "demo_trajectory_3d")
    bounds = [sec.theta_max for sec in robot.sections]
    title = f"Tip error, position and bend over time ({where})"
    save(plotting.states_vs_time(rec.t, rec.truth, all_series, title, bounds), "demo_states")
    if not robot.is_single:
        title = f"Backbone at four instants: truth and estimates ({where})"
        save(
            plotting.backbone_snapshots(
                rec.t, rec.truth, all_series, robot.lengths, title, z_down=z_down
            ),
            "demo_backbone",
        )


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--out",
        default=None,
        help=f"folder for figures and CSVs (default {DEFAULT_OUT}, whose demo files a new "
        "demo replaces; in another folder only with --overwrite)",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help=f"replace the demo's files in --out if there (always in {DEFAULT_OUT})",
    )
    add_robot_option(p, replaces=(), tendons=False)
