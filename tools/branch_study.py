"""The MHE's branch check (``MHESettings.branch_check``) measured: MHE without and with
the check against EKF and UKF, tip error mean / max in mm, on the two-section
Cosserat-rod recordings (tilt only and raw IMUs) and on model-consistent two-section
``spatial`` data (tilt only, several seeds, N = 30), with how often the check fired and
restarted.

    python tools/branch_study.py [--rod NAME ...] [--seeds K] [--cases tilt raw]
    python tools/branch_study.py --rod --seeds 0 --trace spatial-stiff-torsion
    python tools/branch_study.py --rod --seeds 0 --replay spatial-stiff-torsion spatial
    python tools/branch_study.py --rod --seeds 0 --defaults DIR/NAME_tilt.csv ...
    python tools/branch_study.py --rod --seeds 0 --window-cost spatial 1 390 400 405
"""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import solve_window
from continuum_mhe.estimators.fast import window_cost as fast_window_cost
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.formulations import Formulation
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
        mean, mx = res[method][:2]
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
        branch = getattr(est.inference, "branch", None)
        counts = (
            f"; the check fired on {branch.stats.fired} windows and restarted "
            f"{branch.stats.restarted} ({branch.stats.prior_forgotten} with the prior forgotten)"
            if branch is not None
            else ""
        )
        print(
            f"trace {name} tilt, {label}: solve {ms.mean():.1f} ms mean, "
            f"{np.median(ms):.1f} ms median, {ms.max():.0f} ms max; rows with the status "
            f"branch-restart (a row that is also inconsistent says so instead) {restarts}" + counts
        )
    for i in range(first, stop, step):
        print(f"   sample {i}: " + ", ".join(f"{k} {v[i]:.0f} mm" for k, v in err.items()))


def true_states(f: Formulation, name: str) -> tuple[FloatArray, FloatArray]:
    """A rod recording's times (n,) and true PCC states (n, nx): the bends of its truth
    file, their rates by finite differences."""
    table = read_state_table(DATA / f"{name}_truth.csv")
    cols = list(table.names)
    theta = np.column_stack([table.values[:, cols.index(f"theta_{k}")] for k in (1, 2)])
    phi = np.column_stack([table.values[:, cols.index(f"phi_{k}")] for k in (1, 2)])
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=2).reshape(len(theta), -1)
    return table.t, np.concatenate([bends, np.gradient(bends, table.t, axis=0)], axis=1)


def replayed_tilt(f: Formulation, x: FloatArray, seed: int) -> FloatArray:
    """The PCC tilt model's readings (n, nz) of the states ``x`` with 2 deg noise."""
    h = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    return h + np.random.default_rng(seed).normal(size=h.shape) * np.radians(2.0)


def replay(name: str, seeds: int) -> None:
    """Model-consistent data with the rod's motion: the true PCC bends of a rod
    recording (its truth file) fed through the PCC tilt model, 2 deg noise per seed."""
    robot = read_robot("two-section")
    f = make_formulation("bend", robot)
    names = [o.name for o in f.outputs]
    t, x = true_states(f, name)
    truth = f.output(x)
    res: dict[str, list[tuple[float, float]]] = {}
    fired = restarts = 0
    for seed in range(seeds):
        z = replayed_tilt(f, x, seed)
        for label, check in METHODS:
            settings = MHESettings(horizon=30, branch_check=check)
            est = make_estimator(label.split("+")[0], f, settings)  # type: ignore[arg-type]
            s = est.run(t, z)
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


def window_cost(name: str, seed: int, samples: list[int]) -> None:
    """The replay of ``name`` (noise ``seed``), default MHE without the check: at each
    of ``samples``, the window cost of the MHE's answer and of the true trajectory, each
    with its measurement part, and the cost a solve started from the true trajectory
    reaches (equal to the answer's: the answer is the window problem's global minimum
    as far as that start can tell)."""
    f = make_formulation("bend", read_robot("two-section"))
    t, x = true_states(f, name)
    z = replayed_tilt(f, x, seed)
    est = MovingHorizonEstimator(f, MHESettings(branch_check=False))
    inf, n = est.inference, est.inference.settings.horizon
    assert inf._fast is not None
    model = inf._fast
    for k in range(max(samples) + 1):
        est.step(Measurement(float(t[k]), z[k]))
        if k not in samples or k < n:
            continue
        p = inf.window_problem()
        meas = replace(p, arrival=np.zeros_like(p.arrival), qinv=np.zeros_like(p.qinv))
        X, Xt = inf._X, x[k - n + 1 : k + 1]
        assert X is not None
        r = solve_window(model, p, Xt, inf.fast_options)
        moved = np.degrees(np.abs(r.X[-1, :4] - X[-1, :4]).max())
        print(
            f"replay of {name}, seed {seed}, sample {k}: window cost of the MHE's answer "
            f"{fast_window_cost(model, p, X):.1f} (measurements "
            f"{fast_window_cost(model, meas, X):.1f}), of the truth "
            f"{fast_window_cost(model, p, Xt):.1f} (measurements "
            f"{fast_window_cost(model, meas, Xt):.1f}); a solve from the truth reaches "
            f"{r.cost:.1f}, its newest node {moved:.2f} deg from the answer's", flush=True,
        )  # fmt: skip


def defaults(paths: list[Path]) -> None:
    """MHE and EKF with their defaults on tilt recordings ``NAME_tilt.csv`` (each beside
    its ``NAME_truth.csv``): tip error mean / max, the MHE's over the EKF's, the MHE's
    median solve time per sample."""
    robot = read_robot("two-section")
    for path in paths:
        truth = read_state_table(path.with_name(path.name.replace("_tilt", "_truth")))
        data = load_input(path, InputOptions(), make_formulation("bend", robot))
        f = data.formulation
        names = [o.name for o in f.outputs]
        res = {}
        for method in ("mhe", "ekf"):
            s = make_estimator(method, f, MHESettings()).run(data.t, data.z)
            met = compute_metrics(s.output, truth.values, robot.length, names, truth.names)
            res[method] = (met.tip_mean_mm, met.tip_max_mm, np.median(s.solve_ms))
        (a, b, ms), (c, d, _) = res["mhe"], res["ekf"]
        print(
            f"{path.name}, defaults: MHE {a:.2f} / {b:.1f} mm, EKF {c:.2f} / {d:.1f} mm, "
            f"ratio {a / c:.3f} / {b / d:.3f}; MHE median {ms:.2f} ms per sample", flush=True,
        )  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = sorted(q.name[: -len("_info.json")] for q in DATA.glob("*_info.json"))
    p.add_argument("--rod", nargs="*", default=names,
                   help="rod recordings (default all; --rod without names: none, for "
                   "--replay, --trace, --window-cost or --defaults alone)")  # fmt: skip
    p.add_argument("--cases", nargs="+", default=["tilt", "raw"])
    p.add_argument("--seeds", type=int, default=5, help="synthetic seeds (0: none)")
    p.add_argument("--replay", nargs="*", default=[], metavar="NAME", help="rod recordings")
    p.add_argument("--replay-seeds", type=int, default=3, help="noise seeds of --replay")
    p.add_argument("--trace", nargs="*", default=[], metavar="NAME", help="rod recordings")
    p.add_argument("--defaults", nargs="*", default=[], type=Path, metavar="NAME_tilt.csv")
    p.add_argument(
        "--window-cost", nargs="+", metavar=("NAME SEED", "SAMPLE"),
        help="a rod recording's replay, its noise seed and window end samples",
    )  # fmt: skip
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
    defaults(args.defaults)
    if args.window_cost:
        name, seed, *samples = args.window_cost
        window_cost(name, int(seed), [int(k) for k in samples])


if __name__ == "__main__":
    main()
