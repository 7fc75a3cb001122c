"""``continuum-mhe reproduce``: every experiment of the paper, its data, figures and
report."""

from __future__ import annotations

import argparse
import re
import shlex
import sys
import time
from pathlib import Path

from continuum_mhe.errors import InputError
from continuum_mhe.extras import require
from continuum_mhe.io.output_files import check_new_folder


def _holds_reproduce_run(out: Path) -> bool:
    """Whether ``out`` holds the manifest of an earlier ``reproduce`` run."""
    import json

    try:
        m = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(m, dict) and str(m.get("command", "")).startswith("continuum-mhe reproduce")


def run(args: argparse.Namespace) -> int:
    from continuum_mhe.reproduce.experiments import FULL, QUICK
    from continuum_mhe.reproduce.pipeline import PARTS, part_data_files, reproduce

    if args.jobs is not None and args.jobs < 1:
        raise InputError(f"--jobs must be >= 1, got {args.jobs}")
    if args.scheduler:  # before anything is written
        require("dask.distributed", "dask", "reproduce --scheduler", package="dask[distributed]")
        host = r"(?:\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+)"  # a name, IPv4 or [IPv6]
        if not re.fullmatch(rf"(?:[a-z]+://)?{host}:\d+/?", args.scheduler):
            raise InputError(
                f"--scheduler {args.scheduler}: not a scheduler's address: give its host and "
                "port, as tcp://host:8786"
            )
        if args.jobs is not None:
            raise InputError(
                "--jobs does nothing with --scheduler: the scheduler's workers run the trials"
            )
    cfg = QUICK if args.quick else FULL
    if args.rod_csv is not None:  # read once here: one line for what is wrong with it
        from continuum_mhe.simulation.cosserat import read_recording

        samples = len(read_recording(args.rod_csv).columns["t"])
        if samples <= cfg.horizon:
            raise InputError(
                f"{args.rod_csv}: {samples} samples: the rod experiment's MHE window needs "
                f"more than its N = {cfg.horizon}"
            )
    out = Path(args.out)
    parts = PARTS if args.only is None else (args.only,)
    # before the trials (the folder is made after them): another part's data may be
    # there, to be reported together; this part's is replaced only with --overwrite
    names = part_data_files(parts)
    if not _holds_reproduce_run(out):  # a folder of other files: its report.md,
        names += ["manifest.json", "report.md"]  # manifest.json are not ours to replace
    check_new_folder(out, args.overwrite, names)
    command = "continuum-mhe " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    start = time.perf_counter()
    files = reproduce(
        out,
        cfg,
        jobs=args.jobs,
        scheduler=args.scheduler,
        rod_path=args.rod_csv,
        parts=parts,
        command=command if sys.argv[1:2] == ["reproduce"] else "continuum-mhe reproduce",
    )
    wall = time.perf_counter() - start
    n_fig = sum(1 for f in files if f.suffix == ".png")
    print(
        f"wrote {n_fig} figures, {len(files)} files to {out} in {wall:.0f} s (the whole "
        "command; report.md gives the trials' own time); "
        f"see {out / 'report.md'}",
        file=sys.stderr,
    )
    return 0


DESCRIPTION = (
    "Run the paper's Sec. 3 experiments (synthetic 3D, constraints, rod "
    "recording, EKF comparison with Monte Carlo, horizon sweep, growing window) and "
    "beyond the paper (robust cost against outliers, coverage of the uncertainty, gap "
    "and freeze recovery). "
    "Writes one JSON per experiment, figures (PNG, PDF) and report.md."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="results folder (created)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the data of the experiments run that --out holds already",
    )
    p.add_argument("--quick", action="store_true", help="small sizes, for a quick look")
    p.add_argument(
        "--jobs", type=int, default=None, help="local worker processes (default: all CPUs)"
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the trials on a Dask distributed scheduler, e.g. tcp://host:8786",
    )
    p.add_argument(
        "--only",
        choices=("paper", "beyond"),
        default=None,
        help="run only the paper's experiments or only beyond the paper (outliers, "
        "coverage, gap and freeze recovery); the report covers every experiment's data "
        "in --out (default: both)",
    )
    p.add_argument(
        "--rod-csv",
        default=None,
        help="rod recording for Sec. 3.3 (default: the shipped rod_planar.csv)",
    )
