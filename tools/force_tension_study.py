"""A tendon robot's estimated tip force against the tensions given, row by row
(docs/tendon-studies.md, "A tip force beyond the tensions"): with the right inputs the
force stays a fraction of the largest tension; with wrong inputs (tilt angles in radians
read with ``--degrees``, tensions in another unit or order) it can grow past every
tension, and make the readings fit.

For each recording ``NAME`` of ``FOLDER`` (``NAME_raw.csv`` or ``NAME_tilt.csv``,
``NAME_tensions.csv``, ``NAME_truth.csv``; ``continuum-mhe rod tendon``), each IMU
kind and estimator (``--method``), and each variant of the inputs:

* ``own``: as recorded;
* ``deg``: ``--degrees`` (tilt IMUs: the angles read in degrees, nearly straight);
* ``kgf``: the tensions divided by 9.80665 (N given as kgf);
* ``x9.8``: the tensions times 9.80665;
* ``swap``: the two sections' tendon columns swapped;
* ``rot``: each section's tendon columns turned by one (1 2 3 -> 2 3 1),

runs ``continuum-mhe estimate REC --robot tendon-two-section --inputs TENSIONS
[--degrees] [--method M] -o EST.csv`` and prints one line: the rows by status, the
``ok`` rows more than 20 mm off at the tip, and the ratio ``|F| / T`` of the tip force
to the largest tension given, ``T`` the largest at the row (``now``) or the largest of
the run up to the row (``run``): its largest value over every row where ``|F|`` is over
``--floor`` N, and over the ``ok`` rows; and, for the ``ok`` rows more than 20 mm off,
the smallest such ratio and the count of them under ``--ratio`` (with ``|F|`` over the
floor, the rows a rule ``|F| > max(ratio * T, floor)`` would flag).

::

    python tools/force_tension_study.py src/continuum_mhe/data/tendon
    python tools/force_tension_study.py DIR --names force-29-s1 --variants own deg
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np
from tip_push_study import NAMES, csv_columns

from continuum_mhe.cli.app import main as cli_main

VARIANTS = ("own", "deg", "kgf", "x9.8", "swap", "rot")
FAR_MM = 20.0


def _tensions(src: Path, dst: Path, variant: str) -> None:
    """``src``'s tensions file changed as ``variant`` says, written to ``dst``."""
    if variant == "own":
        dst.write_bytes(src.read_bytes())
        return
    d = np.loadtxt(src, delimiter=",", skiprows=1)
    k = d.shape[1] - 1
    if variant == "kgf":
        d[:, 1:] /= 9.80665
    elif variant == "x9.8":
        d[:, 1:] *= 9.80665
    elif variant == "swap":
        d[:, 1:] = d[:, [1 + (j + k // 2) % k for j in range(k)]]
    elif variant == "rot":
        half = k // 2
        order = [s * half + (j + 1) % half for s in range(2) for j in range(half)]
        d[:, 1:] = d[:, [1 + j for j in order]]
    head = "t," + ",".join(f"tension_{j}" for j in range(1, k + 1))
    np.savetxt(dst, d, delimiter=",", fmt="%.9g", header=head, comments="")


def _estimate(argv: list[str]) -> None:
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        if cli_main(argv) != 0:
            raise SystemExit(f"continuum-mhe {' '.join(argv)} failed")


def measure(
    est: dict[str, np.ndarray], truth: dict[str, np.ndarray], tens: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Per row: ``F`` (N), ``now`` and ``run`` (N: the largest tension at the row, and up
    to it), ``err`` (mm, the tip), ``ok``."""
    t = est["t"]
    cols = [c for c in tens if c.startswith("tension_")]
    given = np.column_stack([np.interp(t, tens["t"], tens[c]) for c in cols])
    now = given.max(axis=1)
    force = np.linalg.norm(np.column_stack([est[c] for c in ("fx", "fy", "fz")]), axis=1)
    tip = np.column_stack([np.interp(t, truth["t"], truth[c]) for c in ("x", "y", "z")])
    err = 1e3 * np.linalg.norm(np.column_stack([est[c] for c in ("x", "y", "z")]) - tip, axis=1)
    return {
        "F": force,
        "now": now,
        "run": np.maximum.accumulate(now),
        "err": err,
        "ok": est["status"] == "ok",
        "status": est["status"],
    }


def _largest(values: np.ndarray) -> float:
    return float(np.max(values)) if len(values) else float("nan")


def summary(m: dict[str, np.ndarray], floor: float, ratio: float) -> str:
    """One line of :func:`measure`'s rows."""
    statuses, counts = np.unique(m["status"], return_counts=True)
    far = m["ok"] & (m["err"] > FAR_MM)
    big = m["F"] > floor
    out = [" ".join(f"{s} {c}" for s, c in zip(statuses, counts))]
    out.append(f"ok>{FAR_MM:g}mm {far.sum()}; Fmax {np.nanmax(m['F']):.3g} N")
    for key in ("now", "run"):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = m["F"] / m[key]
        caught = far & big & (r > ratio)
        out.append(
            f"{key}: max {_largest(r[big]):.3g} (ok {_largest(r[big & m['ok']]):.3g}), "
            f"far min {-_largest(-r[far]) if far.any() else float('nan'):.3g}, "
            f"far uncaught {far.sum() - caught.sum()}"
        )
    return "; ".join(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", type=Path)
    p.add_argument("--names", nargs="+", default=list(NAMES))
    p.add_argument("--imus", nargs="+", default=["raw", "tilt"])
    p.add_argument("--methods", nargs="+", default=["ekf", "ukf"])
    p.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    p.add_argument("--floor", type=float, default=0.05, help="N (default 0.05)")
    p.add_argument("--ratio", type=float, default=1.0, help="(default 1)")
    p.add_argument("--keep", type=Path, help="a folder to keep the estimates in")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as name:
        tmp = args.keep or Path(name)
        tmp.mkdir(exist_ok=True)
        for rec in args.names:
            truth = csv_columns(args.folder / f"{rec}_truth.csv")
            for variant in args.variants:
                tens = tmp / f"{rec}_{variant}_tensions.csv"
                _tensions(args.folder / f"{rec}_tensions.csv", tens, variant)
                for imu in args.imus:
                    if variant == "deg" and imu != "tilt":
                        continue
                    for method in args.methods:
                        out = tmp / f"{rec}_{imu}_{variant}_{method}.csv"
                        argv = ["estimate", str(args.folder / f"{rec}_{imu}.csv")]
                        argv += ["--robot", "tendon-two-section", "--inputs", str(tens)]
                        argv += ["--method", method, "-o", str(out)]
                        argv += ["--degrees"] if variant == "deg" else []
                        _estimate(argv)
                        m = measure(csv_columns(out), truth, csv_columns(tens))
                        line = summary(m, args.floor, args.ratio)
                        print(f"{rec} {imu} {method} {variant}: {line}", flush=True)


if __name__ == "__main__":
    main()
