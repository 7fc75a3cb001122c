"""``continuum-mhe rod``: recordings that the estimators' models did not generate, from
Cosserat rods.

* ``rod single``: one section bent by a cable, a tip MPU9250-like IMU (PyElastica,
  the ``rod`` extra; :mod:`continuum_mhe.simulation.cosserat`);
* ``rod sections``: a rod of sections, each bent by a couple at its end, an IMU at each
  section's end or a robot file's places (PyElastica;
  :mod:`continuum_mhe.simulation.cosserat_sections`);
* ``rod tendon``: a tendon robot's quasi-static equilibria (CasADi's IPOPT, no extra;
  :mod:`continuum_mhe.simulation.cosserat_tendon`).

Each checks its arguments and output before it simulates: a mistake is one line, exit
2, nothing written. The ranges are the generators' own (``--duration`` from the IMUs'
sample time to its longest recording), not the other commands' shared ones.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

from continuum_mhe.errors import InputError, UserError
from continuum_mhe.extras import import_problem, missing

DESCRIPTION = (
    "Write recordings of Cosserat rods, which the estimators' models did not generate: "
    "single (one section bent by a cable, a tip IMU; PyElastica), sections (a robot "
    "file's sections, two by default, and IMUs; PyElastica) and tendon (a tendon robot's "
    "quasi-static equilibria; CasADi's IPOPT)."
)

#: ``rod COMMAND``: its name, its one-line help (``continuum-mhe rod --help``)
SUBCOMMANDS: tuple[tuple[str, str], ...] = (
    ("single", "one section bent by a cable, a tip MPU9250-like IMU (PyElastica)"),
    ("sections", "a robot file's sections (two by default) bent by couples (PyElastica)"),
    ("tendon", "a tendon robot's quasi-static equilibria (CasADi's IPOPT)"),
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="rod_command", metavar="COMMAND", required=True)
    helps = dict(SUBCOMMANDS)
    _single_arguments(
        sub.add_parser(
            "single",
            help=helps["single"],
            description="Simulate a cable-driven Cosserat rod with a tip MPU9250-like IMU "
            "and write the recording CSV.",
        )
    )
    _sections_arguments(
        sub.add_parser(
            "sections",
            help=helps["sections"],
            description="Simulate a Cosserat rod of sections (a robot file's, two by "
            "default) with an IMU at each section's end or where the robot file places them.",
        )
    )
    _tendon_arguments(
        sub.add_parser(
            "tendon",
            help=helps["tendon"],
            description="Recordings of a tendon-driven robot that its estimator's model did "
            "not generate.",
            formatter_class=_SetDefaultsShown,
        )
    )
    # the generators check their own ranges (run_single, run_sections, run_tendon), in
    # their own words, after the PyElastica check
    p.set_defaults(own_option_ranges=True)


class _SetDefaultsShown(argparse.ArgumentDefaultsHelpFormatter):
    """Each option's default in its help, where it has one to show (not a required
    option's or an unset one's None, nor a flag's False)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or action.default is False:
            return action.help
        return super()._get_help_string(action)


def run(args: argparse.Namespace) -> int:
    runners: dict[str, Callable[[argparse.Namespace], int]] = {
        "single": run_single,
        "sections": run_sections,
        "tendon": run_tendon,
    }
    return runners[args.rod_command](args)


def _require_elastica() -> None:
    """One line naming the pip install, before anything is checked or written."""
    if (why := import_problem("elastica")) is not None:
        raise missing("pyelastica", "rod", "the rod simulation", why)


# --- rod single ----------------------------------------------------------------------------
def _single_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "-o", "--output", required=True,
        help="CSV to write, its settings beside it as NAME_info.json (the shipped recording "
        "is src/continuum_mhe/data/rod_planar.csv in a clone of the repository)",
    )  # fmt: skip
    p.add_argument(
        "--overwrite", action="store_true", help="replace an existing -o file (else refused)"
    )
    p.add_argument("--duration", type=float, default=20.0, help="seconds (default 20)")
    p.add_argument("--seed", type=int, default=0, help="sensor noise seed (default 0)")


def run_single(args: argparse.Namespace) -> int:
    from continuum_mhe.simulation import cosserat
    from continuum_mhe.simulation.cosserat_sections import check_generator_arguments

    _require_elastica()
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise InputError("--duration must be positive")
    # the same duration and seed limits as the other generators' (memory, the seeds the
    # random generator takes)
    check_generator_arguments(args.duration, args.seed, cosserat.ImuSettings().sample_dt)
    # its targets are checked before the minute of simulation
    rec = cosserat.write_generated_recording(
        args.output, args.duration, args.seed, overwrite=args.overwrite
    )
    n = len(rec.columns["t"])
    print(f"wrote {n} sample{'s' if n != 1 else ''} to {args.output}", file=sys.stderr)
    return 0


# --- rod sections --------------------------------------------------------------------------
def _sections_arguments(p: argparse.ArgumentParser) -> None:
    from continuum_mhe.simulation.cosserat_sections import (
        DRIVES,
        MAX_DURATION_S,
        MAX_SHEAR_RATIO,
        SCENARIOS,
    )

    p.add_argument("-o", "--out", required=True, help="folder for the files")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the recording's files in -o where they exist (else refused)",
    )
    p.add_argument(
        "--scenario",
        choices=SCENARIOS,
        default="planar-s",
        help="the couples' motion: planar-s (in one plane, the sections bent the opposite "
        "ways in turn: an S on two) or spatial (bending planes turning; bends past 90 "
        "degrees on the default rod) (default planar-s)",
    )
    p.add_argument("--name", help="file name prefix (default: the scenario)")
    p.add_argument(
        "--robot",
        help="a robot file (or shipped name) whose sections and IMUs to simulate: standing on "
        "its base, its IMUs at section ends or on disks, no [backbone] (default: "
        "two-section's, 0.16 m + 0.14 m, an IMU at each end)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=12.0,
        help=f"seconds, 0.02 (the IMUs' sample time) to {MAX_DURATION_S:g} (default 12)",
    )
    p.add_argument(
        "--shear-ratio",
        type=float,
        default=1.0 / 3.0,
        help=f"G / E, above 0 and at most {MAX_SHEAR_RATIO:g} (default 1/3)",
    )
    p.add_argument(
        "--sim-dt",
        type=float,
        default=None,
        help="integration step in s, 1e-7 to 1e-3 (default: 2e-5, shorter for a stiffer "
        "torsion or elements under 1 cm: default_sim_dt)",
    )
    p.add_argument(
        "--drive",
        choices=DRIVES,
        default="base",
        help="couples fixed in the base frame (default) or in each section's frame (tendon)",
    )
    p.add_argument(
        "--calibrated",
        action="store_true",
        help="IMUs without accelerometer bias and board misalignment (as after a "
        "calibration); noise, quantisation and gyro bias stay",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="draws the IMUs' errors and noise, an integer >= 0 (default 0)",
    )
    p.add_argument(
        "--bend-only",
        action="store_true",
        help="write only NAME_bend.csv (the bend calibration recording of the IMUs that "
        "these options give the recording)",
    )


def run_sections(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from continuum_mhe.io.output_files import check_new_folder
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation import cosserat_sections as cs

    _require_elastica()
    imu = cs.CALIBRATED_IMU if args.calibrated else cs.DEFAULT_IMU
    out = Path(args.out)
    name = args.name or args.scenario
    # every argument, the folder and the robot, before anything is simulated or written
    if not (0.0 < args.shear_ratio <= cs.MAX_SHEAR_RATIO):  # NaN too
        raise InputError(
            f"--shear-ratio must be G / E > 0 and at most {cs.MAX_SHEAR_RATIO:g}, got "
            f"{args.shear_ratio:g}"
        )
    lo, hi = cs.SIM_DT_RANGE
    if args.sim_dt is not None and not (lo <= args.sim_dt <= hi):
        raise InputError(
            f"--sim-dt must be a step of {lo:g} to {hi:g} s (the records' spacing), "
            f"got {args.sim_dt:g}"
        )
    cs.check_generator_arguments(args.duration, args.seed, imu.sample_dt)
    cs.check_file_prefix(name)
    check_new_folder(out, args.overwrite, cs.recording_files(name, args.bend_only))
    settings = cs.SectionRodSettings(shear_ratio=args.shear_ratio, drive=args.drive)
    if args.robot is not None:
        robot = read_robot(args.robot)  # its errors name the file
        try:
            cs.check_section_robot(robot)
        except UserError as exc:  # a robot it does not write
            raise InputError(f"{args.robot}: {exc}") from None
        settings = cs.rod_settings(robot, settings)
    element = cs.rod_layout(settings).shortest_element
    default_dt = cs.default_sim_dt(args.shear_ratio, element)
    sim_dt = default_dt if args.sim_dt is None else args.sim_dt
    settings = replace(settings, sim_dt=sim_dt)
    try:
        if args.bend_only:
            path = cs.write_bend_only(out, name, settings, args.duration, imu, args.seed)
            print(f"wrote {path}", file=sys.stderr)
            return 0
        cs.write_section_recording(
            out, name, settings, args.scenario, args.duration, imu=imu, seed=args.seed,
            robot_name=args.robot,
        )  # fmt: skip
    except cs.RodDivergedError as err:  # the explicit integrator past its stable step
        rod = "" if args.robot is None else " and robot"
        raise InputError(
            f"{err} with --sim-dt {sim_dt:g}: give a shorter step (default_sim_dt gives "
            f"{default_dt:g} for this --shear-ratio{rod}; halve it if that diverges); "
            "nothing written"
        ) from None
    print(_wrote(out, cs.recording_files(name)), file=sys.stderr)
    return 0


def _wrote(folder: Path, files: tuple[str, ...]) -> str:
    """The line that says what a recording wrote: its files in ``folder``, its measures
    (floors, largest bends, twist, force) in the ``_info.json`` among them."""
    info = next(f for f in files if f.endswith("_info.json"))
    return f"wrote {', '.join(files)} in {folder} (the recording's measures in {info})"


# --- rod tendon ----------------------------------------------------------------------------
def _tendon_arguments(p: argparse.ArgumentParser) -> None:
    from continuum_mhe.model.robot import TENDON_ROUTES
    from continuum_mhe.simulation.cosserat_tendon import (
        MAX_DURATION_S,
        RECORD_DT,
        SCENARIOS,
        SEGMENTS_PER_DISK,
    )

    p.add_argument("--scenario", choices=SCENARIOS, default="unloaded", help="the motion")
    p.add_argument(
        "--duration",
        type=float,
        default=8.0,
        help=f"s, {RECORD_DT:g} (the IMUs' sample time) to {MAX_DURATION_S:g}; the shipped "
        "recordings' is 8",
    )
    p.add_argument(
        "--robot",
        default="tendon-two-section",
        help="a robot file (or shipped name) with a [backbone], tendons and disks, "
        "standing on its base, its IMUs on disks or section ends",
    )
    p.add_argument("--name", help="the files' prefix, the scenario's name if not given")
    p.add_argument(
        "--route",
        choices=TENDON_ROUTES,
        default=argparse.SUPPRESS,
        help="the tendons' path: continuous along the backbone at their radius, or "
        "straight from disk to disk, as through a real robot's spacer disks (default: the "
        "robot file's tendon_route, continuous where it gives none)",
    )
    p.add_argument(
        "--segments-per-disk",
        type=int,
        default=SEGMENTS_PER_DISK,
        help="the discrete rod's segments between two disks, 1 to 32: more resolve tendons "
        "drawn from disk to disk on widely spaced disks (each doubling takes about eight "
        "times as long)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="draws the IMUs' errors and noise, an integer >= 0"
    )
    p.add_argument(
        "-o",
        "--output",
        required=True,
        help="the folder to write to (made in a folder that exists)",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the recording's files in -o where they exist (else refused)",
    )


def run_tendon(args: argparse.Namespace) -> int:
    from continuum_mhe.io.output_files import check_new_folder
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation import cosserat_tendon as ct
    from continuum_mhe.simulation.cosserat_sections import (
        DEFAULT_IMU,
        check_file_prefix,
        check_generator_arguments,
    )

    name = args.name or args.scenario
    # the arguments, the folder and the robot before anything is simulated
    check_generator_arguments(
        args.duration, args.seed, max(ct.RECORD_DT, DEFAULT_IMU.sample_dt), ct.MAX_DURATION_S
    )
    check_file_prefix(name)
    if not 1 <= args.segments_per_disk <= 32:
        raise InputError(
            f"--segments-per-disk {args.segments_per_disk} is outside its valid range [1, 32]"
        )
    output = Path(args.output)
    check_new_folder(output, args.overwrite, ct.recording_files(name))
    robot = read_robot(args.robot)  # its errors name the file
    try:
        ct.check_generated_robot(robot)
    except UserError as exc:  # a robot it does not write
        raise InputError(f"{args.robot}: {exc}") from None
    try:
        ct.write_tendon_recording(
            output, name, robot, args.scenario, args.duration, ct.TendonRodSettings(),
            args.seed, robot_name=args.robot, route=getattr(args, "route", robot.tendon_route),
            segments_per_disk=args.segments_per_disk,
        )  # fmt: skip
    except ct.EquilibriumError as exc:
        raise InputError(
            f"{args.robot}: {exc} (--scenario {args.scenario}): the tensions, sized for "
            "tendon-two-section, likely bend or twist this robot further than its rod can "
            "follow (a backbone far softer, or tendons further out); a stiffer backbone or "
            "tendons nearer to it bend less; nothing written"
        ) from None
    print(_wrote(output, ct.recording_files(name)), file=sys.stderr)
    return 0
