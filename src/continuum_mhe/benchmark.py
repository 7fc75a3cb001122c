"""``continuum-mhe benchmark``: the fast MHE beside IPOPT, do-mpc's MHE and the EKF.

Every method runs in this one process on the same simulated recording (bend
formulation, ``paper3d`` scenario, 2 degrees of noise). Per horizon ``N`` it reports
the median and 99th-percentile wall time per sample (the whole ``step``, with the
window bookkeeping and the arrival-cost update), their ratios to IPOPT and to the
strongest EKF (``ekf-compiled``: the same EKF step as one compiled call, the
fast MHE's C model and numba kernels; ``ekf`` is the EKF through CasADi calls), and
the largest difference of the estimates ``[x, y, z, theta, phi]`` from IPOPT's. A
long recording then shows that the fast MHE's memory does not grow per sample
(tracemalloc and RSS slopes).

do-mpc's MHE is built from the same CasADi expressions of the bend formulation
(transition, tilt measurement, disk constraint) and the same Q^-1, R^-1 and P0^-1;
its arrival cost stays fixed (do-mpc has no EKF arrival update), so its estimates are
close to ours but not identical.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import platform
import subprocess
import time
import tracemalloc
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from continuum_mhe.estimators.base import Estimator, FloatArray, Measurement
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanFilter, ExtendedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import wrap_angle
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import Recording, simulate, simulate_robot

METHODS = ("fast", "ipopt", "do-mpc", "ekf", "ekf-compiled")


@dataclass(frozen=True)
class Timing:
    """One method at one horizon.

    Attributes:
        method: ``fast``, ``ipopt``, ``do-mpc`` or ``ekf``.
        horizon: N (0 for the EKF).
        median_us, p99_us: wall time per sample once the window is full, us.
        max_diff_vs_ipopt: largest ``|output - IPOPT's output|`` (m and rad, phi
            wrapped) over the recording.
        max_diff_after_2n: the same from sample ``2 N`` on (after the start-up, where
            do-mpc fills its first window differently).
        fallbacks: samples the fast backend handed to IPOPT.
    """

    method: str
    horizon: int
    median_us: float
    p99_us: float
    max_diff_vs_ipopt: float
    max_diff_after_2n: float
    fallbacks: int


@dataclass(frozen=True)
class Memory:
    """Memory of the fast MHE over a long recording.

    Attributes:
        samples: recording length.
        tracemalloc_slope_bytes_per_sample: slope of Python-allocated memory (after
            a garbage collection) over the second half of the run.
        tracemalloc_peak_kib: peak Python-allocated memory during the run, KiB.
        rss_slope_bytes_per_sample: slope of the resident set size over the second
            half (Linux only; nan elsewhere).
    """

    samples: int
    tracemalloc_slope_bytes_per_sample: float
    tracemalloc_peak_kib: float
    rss_slope_bytes_per_sample: float


def _run_timed(est: Estimator, rec: Recording) -> tuple[FloatArray, FloatArray, list[str]]:
    """``(output (n, ny), seconds per sample (n,), statuses)`` from a reset."""
    est.reset()
    out = np.full((len(rec.t), est.formulation.ny), np.nan)
    sec = np.empty(len(rec.t))
    status: list[str] = []
    for i, (t, z) in enumerate(zip(rec.t, rec.z)):
        t0 = time.perf_counter()
        e = est.step(Measurement(float(t), z))
        sec[i] = time.perf_counter() - t0
        if e.output is not None:
            out[i] = e.output
        status.append(e.status)
    return out, sec, status


def _dompc_mhe(formulation: Formulation, horizon: int, dt: float) -> Any:
    """do-mpc's MHE on the bend formulation's CasADi expressions."""
    import casadi as ca

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import do_mpc

    f = formulation
    model = do_mpc.model.Model("discrete", "SX")
    x = model.set_variable("_x", "x", shape=(f.nx, 1))
    model.set_rhs("x", f.transition_sym(x, ca.SX(0, 1), dt), process_noise=True)
    model.set_meas("y", f.measurement_sym(x), meas_noise=True)
    model.setup()
    mhe = do_mpc.estimator.MHE(model)
    mhe.settings.n_horizon = horizon
    mhe.settings.t_step = dt
    mhe.settings.store_full_solution = False
    mhe.settings.meas_from_data = True
    mhe.settings.nlpsol_opts = {
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "print_time": False,
        "ipopt.tol": 1e-8,
    }
    g, _, hi = f.constraint_sym(x)
    mhe.set_nl_cons("disk", g, ub=hi)
    Q = np.asarray(f.functions.predict(np.zeros(f.nx), np.zeros(f.nu), dt)[2], float)
    mhe.set_default_objective(
        P_x=np.linalg.inv(f.initial_cov()),
        P_v=np.linalg.inv(f.meas_cov()),
        P_w=np.linalg.inv(Q.reshape(f.nx, f.nx)),
    )
    mhe.setup()
    return mhe


def _run_dompc(
    formulation: Formulation, horizon: int, rec: Recording
) -> tuple[FloatArray, FloatArray]:
    dt = float(rec.t[1] - rec.t[0])
    out = np.empty((len(rec.t), 5))
    sec = np.empty(len(rec.t))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # do-mpc calls numpy functions on CasADi values
        mhe = _dompc_mhe(formulation, horizon, dt)
        mhe.x0 = formulation.project(formulation.initial_state(rec.z[0]))
        mhe.set_initial_guess()
        for i, z in enumerate(rec.z):
            t0 = time.perf_counter()
            x = np.asarray(mhe.make_step(z.reshape(-1, 1)), float).ravel()
            out[i] = formulation.output(x)
            sec[i] = time.perf_counter() - t0
    return out, sec


def _max_diff(a: FloatArray, b: FloatArray, wrapped: tuple[int, ...] = (4,)) -> float:
    """Largest difference of two estimate series (wrapped angles wrapped); nan if empty."""
    if len(a) == 0:
        return math.nan
    d = np.abs(a - b)
    for i in wrapped:
        d[:, i] = np.abs(wrap_angle(a[:, i] - b[:, i]))
    return float(np.nanmax(d))


def raw_imu_recording(robot: Robot, duration: float, dt: float = 0.02, seed: int = 0) -> Recording:
    """The ``spatial`` scenario on ``robot`` measured by its IMUs as raw accelerometer
    direction and gyro (the ``direct`` model, noise 0.03), for timing."""
    from continuum_mhe.model.descriptions import section_bends

    rec = simulate_robot("spatial", robot, duration=duration, dt=dt, seed=seed)
    f = make_formulation("direct", robot)
    bends = np.array([section_bends(rec.outputs, row).ravel() for row in rec.truth])
    x = np.concatenate([bends, np.gradient(bends, rec.t, axis=0)], axis=1)
    z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z += np.random.default_rng(seed).normal(scale=0.03, size=z.shape)
    return replace(rec, z=z, measurement_names=f.measurement_names)


def run_robot_benchmark(robot: Robot, horizons: list[int], duration: float) -> dict[str, Any]:
    """The fast MHE against IPOPT on the same windows of a (multi-section) robot with raw
    IMUs (``direct``), per horizon: median and p99 time per sample, the ratio, and the
    largest output difference (m and rad)."""
    f = make_formulation("direct", robot)
    rec = raw_imu_recording(robot, duration)
    wrapped = tuple(i for i, o in enumerate(f.outputs) if o.wrapped)
    rows = []
    for n in horizons:
        fast = MovingHorizonEstimator(f, MHESettings(horizon=n))
        _run_timed(fast, rec)  # compile and warm up
        out_f, sec_f, status = _run_timed(fast, rec)
        out_i, sec_i, _ = _run_timed(
            MovingHorizonEstimator(f, MHESettings(horizon=n, solver="ipopt")), rec
        )
        full = slice(n, None)
        rows.append(
            {
                "horizon": n,
                "fast_median_us": float(np.median(sec_f[full]) * 1e6),
                "fast_p99_us": float(np.percentile(sec_f[full], 99) * 1e6),
                "ipopt_median_us": float(np.median(sec_i[full]) * 1e6),
                "ipopt_over_fast": float(np.median(sec_i[full]) / np.median(sec_f[full])),
                "max_diff_vs_ipopt": _max_diff(out_f, out_i, wrapped),
                "fallbacks": status.count("fallback-ipopt"),
            }
        )
    return {
        "robot": robot.describe(),
        "model": "direct",
        "samples": len(rec.t),
        **environment(f),
        "rows": rows,
    }


def print_robot_report(report: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"fast MHE vs IPOPT on the same windows: {report['robot']}, raw IMUs "
        f"({report['model']}), {report['samples']} samples"
    )
    for col in ("N", "fast us", "fast p99 us", "IPOPT us", "IPOPT / fast", "max|d|", "fallbk"):
        table.add_column(col, justify="right", no_wrap=True)
    for r in report["rows"]:
        table.add_row(
            str(r["horizon"]),
            f"{r['fast_median_us']:.0f}",
            f"{r['fast_p99_us']:.0f}",
            f"{r['ipopt_median_us']:.0f}",
            f"{r['ipopt_over_fast']:.1f}",
            f"{r['max_diff_vs_ipopt']:.1e}",
            str(r["fallbacks"]),
        )
    console = Console()
    console.print(table)
    console.print(environment_line(report))


def _rss_bytes() -> float:
    try:
        with open("/proc/self/statm") as fh:
            return float(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError):
        return math.nan


def memory_profile(formulation: Formulation, horizon: int, samples: int) -> Memory:
    """Run the fast MHE over ``samples`` samples; slopes of allocated memory and RSS."""
    rec = simulate("paper3d", duration=(samples - 1) * 0.05, seed=1)
    est = MovingHorizonEstimator(formulation, MHESettings(horizon=horizon))
    warm = min(2 * horizon + 50, samples // 4)
    for t, z in zip(rec.t[:warm], rec.z[:warm]):
        est.step(Measurement(float(t), z))
    tracemalloc.start()
    k, traced, rss = [], [], []
    every = max(samples // 40, 1)
    for i in range(warm, samples):
        est.step(Measurement(float(rec.t[i]), rec.z[i]))
        if (i - warm) % every == 0:
            gc.collect()  # count what is retained, not cycles waiting for the collector
            k.append(i)
            traced.append(tracemalloc.get_traced_memory()[0])
            rss.append(_rss_bytes())
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    half = len(k) // 2  # fit the second half: allocator free lists settle in the first
    slope = float(np.polyfit(k[half:], traced[half:], 1)[0])
    rss_ok = np.all(np.isfinite(rss))
    rss_slope = float(np.polyfit(k[half:], rss[half:], 1)[0]) if rss_ok else math.nan
    return Memory(samples, slope, peak / 1024, rss_slope)


def environment(formulation: Formulation) -> dict[str, Any]:
    """Where the numbers come from: whether the fast MHE's model is compiled C (else
    CasADi's VM), the C compiler's version line, and the machine."""
    from continuum_mhe.estimators.fast import build_window_model

    cc = os.environ.get("CC") or "cc"
    try:
        done = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30)
        compiler = (done.stdout.splitlines() or [cc])[0].strip() if done.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        compiler = None
    return {
        "compiled": build_window_model(formulation, 2).compiled,
        "compiler": compiler,
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
        "platform": platform.platform(),
    }


def run_benchmark(
    horizons: list[int],
    duration: float = 20.0,
    methods: tuple[str, ...] = METHODS,
    memory_samples: int = 20000,
) -> dict[str, Any]:
    """Time every method at every horizon on one recording; see the module docstring."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=duration, noise_deg=2.0, seed=0)
    results: list[Timing] = []
    ekf_out, ekf_sec, _ = _run_timed(ExtendedKalmanFilter(f), rec)
    ekf_out, ekf_sec, _ = _run_timed(ExtendedKalmanFilter(f), rec)  # warm caches
    filters = [("ekf", ekf_out, ekf_sec)]
    try:
        ekfc = CompiledExtendedKalmanFilter(f)
    except NotImplementedError:  # no C compiler (said once): no compiled EKF to time
        pass
    else:
        _run_timed(ekfc, rec)  # compile and warm up
        ekfc_out, ekfc_sec, _ = _run_timed(ekfc, rec)
        filters.append(("ekf-compiled", ekfc_out, ekfc_sec))
    for n in horizons:
        ipopt_out, ipopt_sec, _ = _run_timed(
            MovingHorizonEstimator(f, MHESettings(horizon=n, solver="ipopt")), rec
        )
        full = slice(n, None)
        rows = {"ipopt": (ipopt_out, ipopt_sec, 0)}
        if "fast" in methods:
            est = MovingHorizonEstimator(f, MHESettings(horizon=n, solver="fast"))
            _run_timed(est, rec)  # compile and warm up (numba, C model)
            out, sec, status = _run_timed(est, rec)
            rows["fast"] = (out, sec, status.count("fallback-ipopt"))
        if "do-mpc" in methods:
            out, sec = _run_dompc(f, n, rec)
            rows["do-mpc"] = (out, sec, 0)
        for name in (m for m in METHODS if m in rows):
            out, sec, fb = rows[name]
            results.append(
                Timing(
                    method=name,
                    horizon=n,
                    median_us=float(np.median(sec[full]) * 1e6),
                    p99_us=float(np.percentile(sec[full], 99) * 1e6),
                    max_diff_vs_ipopt=_max_diff(out, ipopt_out),
                    max_diff_after_2n=_max_diff(out[2 * n :], ipopt_out[2 * n :]),
                    fallbacks=fb,
                )
            )
        for name, out, sec in filters:
            if name not in methods:
                continue
            results.append(
                Timing(
                    method=name,
                    horizon=n,
                    median_us=float(np.median(sec[full]) * 1e6),
                    p99_us=float(np.percentile(sec[full], 99) * 1e6),
                    max_diff_vs_ipopt=_max_diff(out, ipopt_out),
                    max_diff_after_2n=_max_diff(out[2 * n :], ipopt_out[2 * n :]),
                    fallbacks=0,
                )
            )
    memory = memory_profile(f, 30, memory_samples) if memory_samples > 0 else None
    return {
        "formulation": "bend",
        "scenario": "paper3d",
        "noise_deg": 2.0,
        "samples": len(rec.t),
        "dt_s": float(rec.t[1] - rec.t[0]),
        "cpus": os.cpu_count(),
        **environment(f),
        "results": [asdict(r) for r in results],
        "memory": None if memory is None else asdict(memory),
    }


def _ratios(report: dict[str, Any]) -> list[dict[str, Any]]:
    """Each row's time over IPOPT's and over the strongest EKF baseline (the compiled
    EKF where it ran, else the CasADi-call EKF) at the same horizon."""
    rows = report["results"]
    ref = {(r["method"], r["horizon"]): r["median_us"] for r in rows}
    out = []
    for r in rows:
        n = r["horizon"]
        ekf = ref.get(("ekf-compiled", n), ref.get(("ekf", n), math.nan))
        out.append(
            {**r, "x_ipopt": r["median_us"] / ref[("ipopt", n)], "x_ekf": r["median_us"] / ekf}
        )
    return out


def print_report(report: dict[str, Any]) -> None:
    """Rich table of :func:`run_benchmark`'s report."""
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"MHE time per sample: bend, {report['scenario']}, {report['samples']} samples, "
        f"{report['cpus']} CPUs (median and p99 once the window is full; max|d|: largest "
        "estimate difference from IPOPT's, m and rad)"
    )
    cols = ("N", "method", "median us", "p99 us", "/IPOPT", "/EKFc", "max|d|", "from 2N", "fallbk")
    for col in cols:
        table.add_column(col, justify="right", no_wrap=True)
    for r in _ratios(report):
        table.add_row(
            str(r["horizon"]),
            r["method"],
            f"{r['median_us']:.0f}",
            f"{r['p99_us']:.0f}",
            f"{r['x_ipopt']:.4f}",
            f"{r['x_ekf']:.2f}",
            f"{r['max_diff_vs_ipopt']:.1e}",
            f"{r['max_diff_after_2n']:.1e}",
            str(r["fallbacks"]),
        )
    console = Console()
    console.width = max(console.width, 104)
    console.print(table)
    console.print(environment_line(report))
    fast = {r["horizon"]: r["median_us"] for r in report["results"] if r["method"] == "fast"}
    if 30 in fast and 300 in fast:
        console.print(f"fast: time(N=300) / time(N=30) = {fast[300] / fast[30]:.2f}")
    mem = report.get("memory")
    if mem:
        console.print(
            f"fast MHE memory over {mem['samples']} samples (N=30): "
            f"tracemalloc slope {mem['tracemalloc_slope_bytes_per_sample']:.3f} B/sample, "
            f"peak {mem['tracemalloc_peak_kib']:.0f} KiB; "
            f"RSS slope {mem['rss_slope_bytes_per_sample']:.2f} B/sample"
        )


def environment_line(report: dict[str, Any]) -> str:
    """One line: compiled or VM model, the compiler, the machine."""
    model = "compiled C" if report.get("compiled") else "CasADi's VM (no C compiler)"
    return (
        f"fast MHE model: {model}; compiler: {report.get('compiler') or 'none'}; "
        f"machine: {report.get('machine')}, {report.get('platform')}"
    )


def _horizons(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"horizons must be integers, got {text!r}") from exc
    if not values or min(values) < 2:
        raise argparse.ArgumentTypeError("horizons must be integers >= 2")
    return values


def cmd_benchmark(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise ValueError(f"--duration must be positive, got {args.duration}")
    if args.robot:
        from continuum_mhe.io.robot_file import read_robot

        robot_report = run_robot_benchmark(read_robot(args.robot), args.horizons, args.duration)
        print_robot_report(robot_report)
        if args.json:
            Path(args.json).write_text(json.dumps(robot_report, indent=2) + "\n")
        return 0
    methods = tuple(m for m in METHODS if m not in set(args.skip or []))
    report = run_benchmark(args.horizons, args.duration, methods, args.memory_samples)
    print_report(report)
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")
    return 0


def register(subparsers: Any) -> None:
    """Add ``benchmark`` to the CLI."""
    p = subparsers.add_parser(
        "benchmark",
        help="time the fast MHE beside IPOPT, do-mpc's MHE and the EKF",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    p.add_argument(
        "--horizons",
        type=_horizons,
        default=[10, 30, 100, 300],
        help="comma-separated horizons (default 10,30,100,300)",
    )
    p.add_argument("--duration", type=float, default=20.0, help="recording length in s")
    p.add_argument("--json", help="write the report as JSON to this file")
    p.add_argument(
        "--robot",
        metavar="ROBOT.toml",
        help="instead: fast MHE against IPOPT on this robot with raw IMUs (direct model)",
    )
    p.add_argument(
        "--skip",
        action="append",
        choices=("fast", "do-mpc", "ekf", "ekf-compiled"),
        help="leave out a method",
    )
    p.add_argument(
        "--memory-samples",
        type=int,
        default=20000,
        help="length of the memory run of the fast MHE (0: skip)",
    )
    p.set_defaults(func=cmd_benchmark)
