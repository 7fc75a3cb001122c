"""Why the ``ok`` rows of a variant rod recording miss the truth (docs/uncertainty.md,
"Honest ``ok``: the four targets", (a)): simulate a ``tools/rod_variants.py`` motion
once, sample it with one IMU error source at a time (``tools/rod_error_sources.py``'s
variants: the same random draws of the seed, the others zeroed), estimate each with
``continuum-mhe estimate --robot two-section --method METHOD`` (the command line's
defaults), and print:

* per variant: the rows ``ok`` and the per-axis coverage of their 95 % intervals;
* the ``ok`` rows of the recording as ``rod_variants.py`` writes it (``shipped``) whose
  interval on ``--axis`` misses, in stretches: their time, the rod's bends (the truth
  file's ``theta_1, theta_2``), the mean ``--axis`` error of the constant-curvature
  shape of the rod's own end tangents (the truth file's ``theta_k, phi_k``: the
  model's error where the readings are exact) and of each variant's estimate, and the
  mean written standard deviation, and the largest difference of the estimate's bend
  directions ``phi_1, phi_2`` from the rod's (a branch flip turns them).

::

    python tools/ok_miss_sources.py spatial-tendon-p5 --seed 11 --case tilt
    python tools/ok_miss_sources.py spatial-tendon-p5 --seed 12 --method mhe
    # needs the rod extra (PyElastica); the variants go to a temporary folder
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from honesty_study import coverage, estimate, truth_tip
from rod_error_sources import VARIANTS as SOURCES
from rod_variants import VARIANTS as MOTIONS

from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.pcc import pose_at
from continuum_mhe.simulation.cosserat_sections import simulate_sections, write_trajectory_recording

#: rows further apart than this (s) start another stretch
GAP_S = 0.1


def bends(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A truth or estimate file's ``theta_1, theta_2`` and ``phi_1, phi_2`` (n, 2), rad."""
    table = read_state_table(path)
    return tuple(  # type: ignore[return-value]
        np.stack([table.column(f"{c}_{k}") for k in (1, 2)], axis=1) for c in ("theta", "phi")
    )


def pcc_of_tangents(truth: Path) -> np.ndarray:
    """The tip (n, 3) of the constant-curvature shape of the rod's own end tangents (the
    truth file's ``theta_k, phi_k``), m."""
    theta, phi = bends(truth)
    lengths = [s.length for s in read_robot("two-section").sections]
    return pose_at(np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=-1), lengths, 1)[1]


def stretches(t: np.ndarray, rows: np.ndarray) -> list[np.ndarray]:
    """The indices of ``rows`` (n,) bool in runs with no gap over ``GAP_S``."""
    idx = np.flatnonzero(rows)
    if idx.size == 0:
        return []
    cut = np.flatnonzero(np.diff(t[idx]) > GAP_S) + 1
    return np.split(idx, cut)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("motion", choices=sorted(MOTIONS))
    p.add_argument("--seed", type=int, default=11, help="the IMUs' draws (rod_variants' seed)")
    p.add_argument("--case", default="tilt", choices=["raw", "tilt"])
    p.add_argument("--method", default="ekf", choices=["mhe", "ekf", "ukf"])
    p.add_argument("--axis", default="x", choices=["x", "y", "z"])
    args = p.parse_args()
    warnings.simplefilter("ignore")
    axis = "xyz".index(args.axis)
    settings, scenario, duration = MOTIONS[args.motion]
    traj = simulate_sections(settings, scenario, duration)
    name = f"{args.motion}-seed{args.seed}"
    est = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        print(f"{name} {args.case}, {args.method}: ok share; ok rows' coverage x / y / z")
        for variant, (imu, axes, felt) in SOURCES.items():
            out = root / variant
            out.mkdir()
            tr = traj if felt else replace(traj, velocities=np.zeros_like(traj.velocities))
            write_trajectory_recording(out, name, tr, settings, scenario, imu, args.seed, axes)
            truth_path = out / f"{name}_truth.csv"
            e = estimate(
                out, out / f"{name}_{args.case}.csv", args.method, "--robot", "two-section"
            )
            ok, cov = coverage(e, truth_tip(truth_path))
            c = cov[ok].mean(axis=0)
            print(
                f"  {variant:32s} ok {ok.mean():.2f}, coverage {c[0]:.3f} / {c[1]:.3f} / "
                f"{c[2]:.3f} ({(~cov[ok, axis]).sum()} of {ok.sum()} miss {args.axis}; "
                f"{(e['status'] == 'inconsistent').sum()} rows inconsistent)",
                flush=True,
            )
            est[variant] = e
            if variant == "shipped":
                phi_est = bends(out / f"{out.name}_{name}_{args.case}_{args.method}.csv")[1]
        truth = truth_tip(truth_path)  # the same rod in every variant
        pcc = pcc_of_tangents(truth_path)
        theta, phi = bends(truth_path)
        t = read_state_table(truth_path).t
    shipped = est["shipped"]
    ok, cov = coverage(shipped, truth)
    missed = ok & ~cov[:, axis]
    print(
        f"shipped's ok rows missing {args.axis}: mean {args.axis} error, mm, of the PCC shape "
        "of the rod's tangents, then of each variant's estimate (in the order above); the "
        f"mean std_{args.axis}, mm; the largest phi_1 / phi_2 difference, deg"
    )
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (phi_est - phi)))))
    for rows in stretches(t, missed):
        errors = [1e3 * np.mean(e["tip"][rows, axis] - truth[rows, axis]) for e in est.values()]
        print(
            f"  {t[rows[0]]:.2f} to {t[rows[-1]]:.2f} s, {rows.size} rows, theta "
            f"{np.degrees(theta[rows, 0].mean()):.0f} / {np.degrees(theta[rows, 1].mean()):.0f} "
            f"deg: PCC {1e3 * np.mean(pcc[rows, axis] - truth[rows, axis]):.1f}; "
            + " ".join(f"{v:.1f}" for v in errors)
            + f"; std {1e3 * np.mean(shipped['std'][rows, axis]):.2f}; "
            f"phi {turn[rows, 0].max():.0f} / {turn[rows, 1].max():.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
