"""The MHE's branch check (``MHESettings.branch_check``) measured: MHE without and with
the check against EKF and UKF, tip error mean / max in mm, on the two-section
Cosserat-rod recordings (tilt only and raw IMUs) and on model-consistent two-section
``spatial`` data (tilt only, several seeds, N = 30), with how often the check fired and
restarted.

    python tools/branch_study.py [--rod NAME ...] [--seeds K] [--cases tilt raw]
    python tools/branch_study.py --rod --seeds 0 --trace spatial-stiff-torsion
    python tools/branch_study.py --rod --seeds 0 --replay spatial-stiff-torsion spatial
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.io.csv_files import read_state_table
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.simulation.scenarios import simulate_robot

sys.path.insert(0, str(Path(__file__).parent))
from two_section_rod_study import DATA, evaluate  # noqa: E402

METHODS = (("mhe", False), ("mhe+check", True), ("ekf", False), ("ukf", False))


def rod(name: str, case: str) -> None:
    """One rod recording, ``case`` ``tilt`` or ``raw`` (no gyro-bias state)."""
    robot = read_robot("two-section")
    model = "tilt" if case == "tilt" else "direct"
    row = []
    for label, check in METHODS:
        method = label.split("+")[0]
        res = evaluate(
            robot, DATA / f"{name}_{case}.csv", model, False, False, DATA / f"{name}_truth.csv",
            0.0, (method,), MHESettings(horizon=30, branch_check=check),
        )  # fmt: skip
        mean, mx, _ = res[method]
        row.append(f"{label} {mean:.2f} ({mx:.0f})")
    print(f"rod {name} {case}: " + " / ".join(row), flush=True)


def trace(name: str, first: int = 100, stop: int = 520, step: int = 12) -> None:
    """Tilt only, one rod recording: the fast MHE's solve time per sample (``solve_ms``,
    including building the cost function once) without and with the check, the samples
    where a restart won, and the tip error of MHE, MHE + check and EKF every ``step``
    samples over ``first:stop``."""
    robot = read_robot("two-section")
    opts = InputOptions(raw=RawImuSettings(imu_model="tilt"))
    data = load_input(DATA / f"{name}_tilt.csv", opts, make_formulation("bend", robot))
    truth = read_state_table(DATA / f"{name}_truth.csv").values[:, :3]
    err = {}
    for label, check in METHODS[:3]:
        settings = MHESettings(horizon=30, branch_check=check)
        est = make_estimator(label.split("+")[0], data.formulation, settings)  # type: ignore[arg-type]
        s = est.run(data.t, data.z)
        err[label] = np.linalg.norm(s.output[:, :3] - truth, axis=1) * 1e3
        ms = np.asarray(s.solve_ms, dtype=float)
        restarts = np.flatnonzero(np.asarray(s.status) == "branch-restart").tolist()
        print(
            f"trace {name} tilt, {label}: solve {ms.mean():.1f} ms mean, "
            f"{np.median(ms):.1f} ms median, {ms.max():.0f} ms max; restarts at {restarts}"
        )
    for i in range(first, stop, step):
        print(f"   sample {i}: " + ", ".join(f"{k} {v[i]:.0f} mm" for k, v in err.items()))


def replay(name: str, seeds: int) -> None:
    """Model-consistent data with the rod's motion: the true PCC bends of a rod
    recording (its truth file) fed through the PCC tilt model, 2 deg noise per seed."""
    robot = read_robot("two-section")
    f = make_formulation("bend", robot)
    names = [o.name for o in f.outputs]
    table = read_state_table(DATA / f"{name}_truth.csv")
    cols = list(table.names)
    theta = np.column_stack([table.values[:, cols.index(f"theta_{k}")] for k in (1, 2)])
    phi = np.column_stack([table.values[:, cols.index(f"phi_{k}")] for k in (1, 2)])
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=2).reshape(len(theta), -1)
    x = np.concatenate([bends, np.zeros_like(bends)], axis=1)
    h = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    truth = f.output(x)
    res: dict[str, list[tuple[float, float]]] = {}
    fired = restarts = 0
    for seed in range(seeds):
        z = h + np.random.default_rng(seed).normal(size=h.shape) * np.radians(2.0)
        for label, check in METHODS:
            settings = MHESettings(horizon=30, branch_check=check)
            est = make_estimator(label.split("+")[0], f, settings)  # type: ignore[arg-type]
            s = est.run(table.t, z)
            met = compute_metrics(s.output, truth, robot.length, names)
            res.setdefault(label, []).append((met.tip_mean_mm, met.tip_max_mm))
            branch = getattr(est, "branch", None)
            if branch is not None:
                fired += branch.stats.fired
                restarts += branch.stats.restarted
    row = [
        f"{k} {np.mean([a for a, _ in v]):.2f} ({max(b for _, b in v):.0f})" for k, v in res.items()
    ]
    print(
        f"replay of {name}'s PCC bends, {seeds} seeds, tilt: " + " / ".join(row)
        + f"; check fired {fired} windows, restarted {restarts}", flush=True,
    )  # fmt: skip


def synthetic(seeds: int) -> None:
    """Model-consistent ``spatial`` data (20 s at 20 Hz, 2 deg noise), tilt only."""
    robot = read_robot("two-section")
    f = make_formulation("bend", robot)
    names = [o.name for o in f.outputs]
    res: dict[str, list[tuple[float, float]]] = {}
    restarts = fired = 0
    for seed in range(seeds):
        rec = simulate_robot("spatial", robot, duration=20, dt=0.05, seed=seed)
        for label, check in METHODS:
            settings = MHESettings(horizon=30, branch_check=check)
            est = make_estimator(label.split("+")[0], f, settings)  # type: ignore[arg-type]
            s = est.run(rec.t, rec.z)
            met = compute_metrics(s.output, rec.truth, robot.length, names)
            res.setdefault(label, []).append((met.tip_mean_mm, met.tip_max_mm))
            branch = getattr(est, "branch", None)
            if branch is not None:
                fired += branch.stats.fired
                restarts += branch.stats.restarted
    row = []
    for label, v in res.items():
        a = np.array(v)
        row.append(f"{label} {a[:, 0].mean():.2f} ({a[:, 1].max():.0f})")
    print(
        f"synthetic spatial, {seeds} seeds, tilt: " + " / ".join(row)
        + f"; check fired {fired} windows, restarted {restarts}", flush=True,
    )  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = sorted(q.name[: -len("_info.json")] for q in DATA.glob("*_info.json"))
    p.add_argument("--rod", nargs="*", default=names, help="recordings (default all)")
    p.add_argument("--cases", nargs="+", default=["tilt", "raw"])
    p.add_argument("--seeds", type=int, default=5, help="synthetic seeds (0: none)")
    p.add_argument("--replay", nargs="*", default=[], metavar="NAME", help="rod recordings")
    p.add_argument("--replay-seeds", type=int, default=3, help="noise seeds of --replay")
    p.add_argument("--trace", nargs="*", default=[], metavar="NAME", help="rod recordings")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    if args.seeds:
        synthetic(args.seeds)
    for name in args.rod:
        for case in args.cases:
            rod(name, case)
    for name in args.replay:
        replay(name, args.replay_seeds)
    for name in args.trace:
        trace(name)


if __name__ == "__main__":
    main()
