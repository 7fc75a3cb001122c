"""``continuum-mhe benchmark``: the command line of the timing harness
(:mod:`continuum_mhe.benchmark.harness`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from continuum_mhe.benchmark.harness import (
    DT,
    METHODS,
    REPEATS,
    ROBOT_DT,
    check_horizons,
    run_benchmark,
    run_robot_benchmark,
)
from continuum_mhe.cli.benchmark_report import print_report, print_robot_report
from continuum_mhe.cli.options import add_overwrite_option
from continuum_mhe.cli.program import PROG
from continuum_mhe.errors import UserError

#: ``--memory-samples``' default: the long recording of the memory check.
MEMORY_SAMPLES = 20000
#: The fewest samples the memory check fits a slope on: its window (N = 30) full and
#: warmed up over a quarter of them, the rest enough points to fit.
MIN_MEMORY_SAMPLES = 1000


def _horizons(text: str) -> list[int]:
    items = text.split(",")
    if any(not v.strip() for v in items):
        raise argparse.ArgumentTypeError(
            f"horizons must be integers separated by commas, got {text!r}"
        )
    try:
        values = [int(v) for v in items]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"horizons must be integers, got {text!r}") from exc
    if not values or min(values) < 2 or max(values) > 1000:
        raise argparse.ArgumentTypeError("horizons must be integers in [2, 1000]")
    if len(set(values)) != len(values):  # each N's ratios are taken within its rows
        raise argparse.ArgumentTypeError(f"horizons must differ, got {text!r}")
    return values


def _write_json(path: str, report: dict[str, Any], args: argparse.Namespace) -> None:
    """The report as JSON (NaN as null), written atomically, with what made it: the
    command line, the time it was run (UTC) and the acados folder."""
    import shlex
    from datetime import datetime, timezone

    from continuum_mhe.io.output_files import atomic_writer
    from continuum_mhe.reproduce.experiments import to_jsonable

    made = {
        # the process's own command line where it ran as the command, else the command
        "command": (
            shlex.join([PROG, *sys.argv[1:]])
            if sys.argv[1:2] == ["benchmark"]
            else f"{PROG} benchmark"
        ),
        "run_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "acados": getattr(args, "acados", None),
    }
    with atomic_writer(Path(path)) as fh:
        fh.write(json.dumps(to_jsonable({**made, **report}), indent=2, allow_nan=False) + "\n")


#: The most interleaved rounds ``--repeats`` takes (each times every contender anew).
MAX_REPEATS = 1000


def run(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise UserError(f"--duration must be positive, got {args.duration}")
    if not 1 <= args.repeats <= MAX_REPEATS:
        raise UserError(f"--repeats must lie in [1, {MAX_REPEATS}], got {args.repeats}")
    timed = args.horizons + ([] if args.robot else list(args.loss_horizons or []))
    check_horizons(timed, args.duration, ROBOT_DT if args.robot else DT)
    if args.json:  # before the run, not after minutes of it
        from continuum_mhe.io.output_files import check_output_target, refuse_inputs

        refuse_inputs(args.json, [("the robot file --robot", args.robot)])
        check_output_target(args.json, args.overwrite, "--json")
    for flag, given in (("--robot", args.robot), ("--acados", args.acados)):
        if given is not None and not given.strip():
            raise UserError(f"{flag} names no file or folder (an empty value)")
    if args.robot:
        # (what --robot leaves out anyway may be asked to be left out: none, 0)
        unused = [flag for flag, given in (
            ("--skip", bool(args.skip)), ("--loss-horizons", bool(args.loss_horizons)),
            ("--acados", args.acados is not None),
            ("--memory-samples", args.memory_samples not in (MEMORY_SAMPLES, 0)),
        ) if given]  # fmt: skip
        if unused:
            raise UserError(
                f"{', '.join(unused)} {'does' if len(unused) == 1 else 'do'} not apply with "
                "--robot: it times the fast MHE against IPOPT alone"
            )
        from continuum_mhe.io.robot_file import read_robot

        robot = read_robot(args.robot)
        if robot.tendons:
            raise UserError(
                f"{args.robot}: a tendon robot is not timed by benchmark: the fast MHE does "
                "not take its model (estimate --method ekf, ukf or mhe --solver ipopt do)"
            )
        robot_report = run_robot_benchmark(
            robot, args.horizons, args.duration, args.repeats, say=_say
        )
        print_robot_report(robot_report)
        if args.json:
            _write_json(args.json, robot_report, args)
        return 0
    if 0 < args.memory_samples < MIN_MEMORY_SAMPLES:
        raise UserError(
            f"--memory-samples {args.memory_samples}: the memory check fits its slope over at "
            f"least {MIN_MEMORY_SAMPLES} samples (the window full and warmed up first); 0 "
            "skips it"
        )
    methods = tuple(m for m in METHODS if m not in set(args.skip or []))
    if args.loss_horizons and "fast" not in methods:
        raise UserError(
            "--loss-horizons times the fast MHE's losses, which --skip fast leaves out "
            "(give --loss-horizons none, or keep fast)"
        )
    if args.acados is not None and not Path(args.acados, "acados", "__init__.py").is_file():
        raise UserError(
            f"--acados {args.acados}: no acados package there (pip install --no-deps "
            f"--target {args.acados} comma-deps-acados)"
        )
    report = run_benchmark(
        args.horizons,
        args.duration,
        methods,
        args.memory_samples,
        None if args.loss_horizons is None else tuple(args.loss_horizons),
        args.repeats,
        args.acados,
        say=_say,
        compile_peers=False if args.interpreted_peers else None,
    )
    print_report(report)
    if args.json:
        _write_json(args.json, report, args)
    return 0


def _say(line: str) -> None:
    """A progress line on stderr."""
    print(f"{PROG} benchmark: {line}", file=sys.stderr, flush=True)


DESCRIPTION = (
    "Time the fast MHE beside IPOPT, do-mpc's MHE, acados, CasADi's fatrop and sqpmethod "
    "with HPIPM on the same windows, three EKFs, and the bare compiled kernels of the fast "
    "MHE and the EKF, on one simulated recording, every method repeated in turn."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--horizons",
        type=_horizons,
        default=[10, 30, 100, 300],
        help="comma-separated horizons (default 10,30,100,300; N = 300 takes minutes "
        "alone on 2 cores: --horizons 10,30,100 for a shorter run)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=20.0,
        help="recording length in s (default 20; more samples than the largest horizon)",
    )
    p.add_argument("--json", help="write the report as JSON to this file")
    add_overwrite_option(p, "--json")
    p.add_argument(
        "--robot",
        metavar="ROBOT.toml",
        help="instead: fast MHE against IPOPT on this constant-curvature robot with raw "
        "IMUs (direct model), on its simulated spatial motion sampled every "
        f"{ROBOT_DT:g} s; a tendon robot is not timed here (the fast MHE does not take "
        "its model)",
    )
    p.add_argument(
        "--skip",
        action="append",
        choices=tuple(m for m in METHODS if m != "ipopt"),
        help="leave out a method",
    )
    p.add_argument(
        "--loss-horizons",
        type=lambda text: [] if text == "none" else _horizons(text),
        default=None,
        help="horizons at which each MHE loss (l2, huber, cauchy, welsch) is timed on both "
        "backends (default: 30 if among --horizons, else the first; none: skip)",
    )
    p.add_argument(
        "--repeats",
        type=int,
        default=REPEATS,
        help="rounds of every method per horizon, in turn, after one warm-up run; each "
        f"sample's time is the median over the rounds (default {REPEATS})",
    )
    p.add_argument(
        "--acados",
        metavar="DIR",
        help="where comma-deps-acados was installed apart from CasADi (pip install "
        "--no-deps --target DIR comma-deps-acados; it ships a CasADi without IPOPT); "
        "without it, acados is looked for among the installed packages",
    )
    p.add_argument(
        "--interpreted-peers",
        action="store_true",
        help="evaluate the CasADi peers' functions (fatrop, sqp-hpipm, ipopt-warm) in "
        "CasADi's virtual machine instead of compiling them to C before the clock starts "
        "(the default where a C compiler is found; faster to set up, slower to solve)",
    )
    p.add_argument(
        "--memory-samples",
        type=int,
        default=MEMORY_SAMPLES,
        help="length of the memory run of the fast MHE (0: skip)",
    )
