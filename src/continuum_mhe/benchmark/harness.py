"""The timing harness of ``continuum-mhe benchmark``: the fast MHE beside IPOPT, do-mpc's
MHE, the strongest peers on the same windows (acados, CasADi's fatrop and sqpmethod with
HPIPM: :mod:`continuum_mhe.benchmark.peers`) and three EKFs, and the bare compiled
kernels of the fast MHE and the EKF (:mod:`continuum_mhe.benchmark.kernels`).

Every method runs in this one process on the same simulated recording (bend
formulation, ``paper3d`` scenario, 2 degrees of noise). Per horizon ``N`` it reports
the median and 99th-percentile wall time per sample once the window is full (every
method runs once to warm up, then ``--repeats`` rounds of all of them in turn, each
round's order rotated by one, and each sample's time is its median over the rounds, so
that a change of the shared machine's load affects them alike), the ratio of each
median to the fast MHE's, to IPOPT's, to the compiled EKF's and to the bare compiled
EKF kernel's (:data:`METHOD_NOTES` says what each method times), and the largest
difference of the outputs ``[x, y, z, theta, phi]`` from IPOPT's, over the recording
and from sample ``N`` on, and whether an MHE's answers agree with IPOPT's
(:data:`AGREEMENT_TOL`), so that a fast wrong answer is not read as a fast one. What
each contender costs before the clock starts is reported too: its build (acados'
generated C compiled, the CasADi peers' functions) and its warm-up run. Each MHE
measurement loss (``l2``, ``huber``, ``cauchy``) is then timed on both backends, clean
and with spikes, as a ratio to ``l2`` (:mod:`continuum_mhe.benchmark.losses`). A long
recording then shows that the fast MHE's memory does not grow per sample (tracemalloc
and RSS slopes). The report records where the numbers come from: the machine
(platform, CPU, cores, the load average at the start) and the package versions (the
compiled core's nanobind among them).

do-mpc's MHE: :mod:`continuum_mhe.benchmark.dompc`; the machine and memory records:
:mod:`continuum_mhe.benchmark.environment`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.benchmark.dompc import run_dompc
from continuum_mhe.benchmark.environment import (
    environment,
    memory_profile,
)
from continuum_mhe.benchmark.kernels import run_ekf_kernel, run_mhe_kernel
from continuum_mhe.benchmark.peers import PEER_NOTES, PEERS
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, ExtendedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import wrap_angle
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import MHESettings
from continuum_mhe.signals import between_samples
from continuum_mhe.simulation.scenarios import (
    Recording,
    ScenarioName,
    sample_count,
    simulate,
    simulate_robot,
)

METHODS = ("fast", "mhe-kernel", "ipopt", "do-mpc", *PEERS, "ekf", "ekf-compiled", "ekf-kernel")

#: What each method's time covers.
METHOD_NOTES: dict[str, str] = {
    "fast": "fast MHE (structure-exploiting SQP): the whole estimator step",
    "mhe-kernel": "the fast MHE's compiled step alone (arrival slide, shift, guess, "
    "SQP, covariance, outputs and their std), no estimator interface, timed inside the "
    "core, as ekf-kernel (fallbk: windows not certified)",
    "ipopt": "MHE solved by IPOPT through CasADi (the paper's solver): the whole step",
    "do-mpc": "do-mpc's MHE (IPOPT) given the same window cost through its API: "
    "make_step plus our EKF arrival step (the window's data copied into its templates "
    "before the clock starts); its first N estimates differ (no growing window)",
    **PEER_NOTES,
    "ekf": "EKF through three CasADi calls per step: the whole estimator step",
    "ekf-compiled": "the same EKF as one compiled call (the EKF make_estimator "
    "returns): the whole estimator step",
    "ekf-kernel": "the compiled EKF step with its outputs and their std (what "
    "mhe-kernel hands back) in one call alone, no estimator interface (validation, "
    "masks, divergence check); inputs prepared outside; timed inside the core",
}


@dataclass(frozen=True)
class Timing:
    """One method at one horizon.

    Attributes:
        method: one of :data:`METHODS`.
        horizon: N (the EKFs are timed again at every N, beside the fast MHE).
        median_us, p99_us: wall time per sample from sample ``N`` on (the window is
            full), us.
        max_diff_vs_ipopt: largest ``|output - IPOPT's output|`` (m and rad, phi
            wrapped) over the recording.
        max_diff_from_n: the same from sample ``N`` on (do-mpc has no growing window,
            so its first ``N`` estimates differ).
        fallbacks: samples the fast backend handed to IPOPT; for a peer
            (:data:`~continuum_mhe.benchmark.peers.PEERS`), windows it did not converge on.
        solver_median_us: the median of the time the method reports for its own solver
            per sample (acados' ``time_tot``, without the Python interface), us; nan
            for the others.
        missing_from_n: samples from ``N`` on where IPOPT has an output and the method
            none (a nan output), which ``max_diff_from_n`` leaves out.
        agrees_with_ipopt: for an MHE (:data:`MHE_METHODS`), whether ``max_diff_from_n``
            is within :data:`AGREEMENT_TOL` and ``missing_from_n`` is 0 (its time
            compares like with like; :func:`agreement`); None for the EKFs, which
            estimate otherwise.
        build_s: wall time to build the method before its runs, s (acados: generating
            and compiling its C; a CasADi peer: ``nlpsol`` with its functions compiled;
            an estimator: its construction); nan where the method builds inside each
            run, untimed (do-mpc's MHE, the bare kernels' evaluators).
        warmup_s: wall time of its warm-up run over the recording, s (not timed per
            sample: what is built on first use, IPOPT's window NLPs among it, is here).
    """

    method: str
    horizon: int
    median_us: float
    p99_us: float
    max_diff_vs_ipopt: float
    max_diff_from_n: float
    fallbacks: int
    solver_median_us: float = math.nan
    missing_from_n: int = 0
    agrees_with_ipopt: bool | None = None
    build_s: float = math.nan
    warmup_s: float = math.nan


#: The methods that solve the MHE's window problem, whose answers must be IPOPT's.
MHE_METHODS = ("fast", "mhe-kernel", "ipopt", "do-mpc", *PEERS)

#: The largest output difference from IPOPT's (from sample ``N`` on, m and rad) at which
#: an MHE's answers count as IPOPT's: the tests' agreement with IPOPT.
AGREEMENT_TOL = 1e-6


def agreement(out: FloatArray, ipopt_out: FloatArray) -> tuple[float, int, bool]:
    """``(largest difference, samples without an answer, agrees)`` of a method's
    outputs ``out`` (samples, ny) against IPOPT's ``ipopt_out`` on the same samples: the
    largest difference where both have an answer (m and rad, :func:`_max_diff`), the
    samples where IPOPT has an answer (every output finite) and the method none, and
    whether both are as IPOPT's (the difference within :data:`AGREEMENT_TOL`, no
    sample without an answer)."""
    diff = _max_diff(out, ipopt_out)
    answered = np.isfinite(ipopt_out).all(axis=1)
    missing = int(np.count_nonzero(answered & ~np.isfinite(out).all(axis=1)))
    return diff, missing, bool(diff <= AGREEMENT_TOL and missing == 0)


def _run_timed(est: Estimator, rec: Recording) -> tuple[FloatArray, FloatArray, list[str]]:
    """``(output (n, ny), seconds per sample (n,), statuses)`` from a reset."""
    est.reset()
    out = np.full((len(rec.t), est.formulation.ny), np.nan)
    sec = np.empty(len(rec.t))
    status: list[str] = []
    # a signal stops the run between two samples, never a solve (IPOPT would count it
    # as a failed solve, and the run would go on): as estimate's loop
    for i, (t, z) in between_samples(enumerate(zip(rec.t, rec.z))):
        t0 = time.perf_counter()
        e = est.step(Measurement(float(t), z))
        sec[i] = time.perf_counter() - t0
        if e.output is not None:
            out[i] = e.output
        status.append(e.status)
    return out, sec, status


def _max_diff(a: FloatArray, b: FloatArray, wrapped: tuple[int, ...] = (4,)) -> float:
    """Largest difference of two estimate series (wrapped angles wrapped); nan if empty."""
    if len(a) == 0:
        return math.nan
    d = np.abs(a - b)
    for i in wrapped:
        d[:, i] = np.abs(wrap_angle(a[:, i] - b[:, i]))
    return float(np.nanmax(d))


#: Sample time of the recordings timed, s: ``paper3d`` (tilt), and a robot's raw IMUs.
DT = 0.05
ROBOT_DT = 0.02


def check_horizons(horizons: list[int], duration: float, dt: float) -> None:
    """A one-line :class:`UserError` unless the recording of ``duration`` s at ``dt`` s
    has more samples than every horizon (each is timed once its window is full)."""
    samples = sample_count(duration, dt)
    short = [n for n in horizons if n >= samples]
    if short:
        n = max(short)
        raise UserError(
            f"horizon {n} needs more than {n} samples: --duration {duration:g} s gives "
            f"only {samples} (one every {dt:g} s); raise --duration (to at least "
            f"{n * dt:g} s)"
        )


#: The noise of :func:`raw_imu_recording`'s readings (gravity direction and gyro, rad
#: and rad/s), which the robot benchmark's model assumes for its gyros too
RAW_NOISE = 0.03


def raw_imu_model(robot: Robot) -> DirectFormulation:
    """The ``direct`` model of :func:`raw_imu_recording`'s data: its gyro noise is the
    readings' (:data:`RAW_NOISE`)."""
    return DirectFormulation(robot=robot, gyro_std=RAW_NOISE)


def raw_imu_recording(
    robot: Robot, duration: float, dt: float = ROBOT_DT, seed: int = 0
) -> Recording:
    """The ``spatial`` scenario on ``robot`` (``paper3d`` on a robot of one section)
    measured by its IMUs as raw accelerometer direction and gyro (the ``direct`` model,
    noise :data:`RAW_NOISE`), for timing."""
    from continuum_mhe.model.descriptions import section_bends

    scenario: ScenarioName = "spatial" if robot.n_sections > 1 else "paper3d"
    rec = simulate_robot(scenario, robot, duration=duration, dt=dt, seed=seed)
    f = make_formulation("direct", robot, estimate_gyro_bias=False)  # the readings' model
    bends = np.array([section_bends(rec.outputs, row).ravel() for row in rec.truth])
    x = np.concatenate([bends, np.gradient(bends, rec.t, axis=0)], axis=1)
    z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z += np.random.default_rng(seed).normal(scale=RAW_NOISE, size=z.shape)
    # a noisy direction is still a direction, as an IMU reads it
    for b in (b for b in f.measurement_blocks if b.kind == "direct"):
        force = z[:, b.start : b.start + 3]
        force /= np.linalg.norm(force, axis=1, keepdims=True)
    return replace(rec, z=z, measurement_names=f.measurement_names)


def run_robot_benchmark(
    robot: Robot,
    horizons: list[int],
    duration: float,
    repeats: int = 1,
    say: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """The fast MHE against IPOPT on the same windows of a (multi-section) robot with raw
    IMUs (``direct``), per horizon: median and p99 time per sample, the ratio, and the
    largest output difference (m and rad). Each is warmed up (the fast MHE on the whole
    recording, IPOPT, whose NLP is built on its first window, on its first ``N + 2``
    samples), then both run ``repeats`` times in turn; each sample's time is its median
    over the rounds. ``say``: called with a line as each horizon starts and ends."""
    progress = say or (lambda line: None)
    f = raw_imu_model(robot)
    rec = raw_imu_recording(robot, duration)
    env = environment(f)  # the load average at the start
    wrapped = tuple(i for i, o in enumerate(f.outputs) if o.wrapped)
    rows = []
    for k, n in enumerate(horizons, start=1):
        started = time.perf_counter()
        progress(
            f"N = {n} ({k} of {len(horizons)} horizons): the fast MHE and IPOPT, a warm-up "
            f"and {repeats} round(s) of {len(rec.t)} samples each"
        )
        fast = MovingHorizonEstimator(f, MHESettings(horizon=n))
        ipopt = MovingHorizonEstimator(f, MHESettings(horizon=n, solver="ipopt"))
        _run_timed(fast, rec)  # warm up
        _run_timed(
            ipopt, replace(rec, t=rec.t[: n + 2], z=rec.z[: n + 2], truth=rec.truth[: n + 2])
        )
        fast_sec, ipopt_sec = [], []
        for _ in range(repeats):
            out_f, sec, status = _run_timed(fast, rec)
            fast_sec.append(sec)
            out_i, sec, _ = _run_timed(ipopt, rec)
            ipopt_sec.append(sec)
        sec_f, sec_i = np.median(fast_sec, axis=0), np.median(ipopt_sec, axis=0)
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
        progress(f"N = {n} done in {time.perf_counter() - started:.0f} s")
    return {
        "robot": robot.describe(),
        "model": "direct",
        "samples": len(rec.t),
        "duration_s": duration,
        "horizons": list(horizons),
        "repeats": repeats,
        **env,
        "rows": rows,
    }


#: Rounds of every method per horizon (:func:`_interleaved`).
REPEATS = 3

#: A run of the recording: ``(output, seconds per sample, fallbacks)``, and for a peer
#: the seconds its solver reports per sample after them.
Run = Callable[[], tuple[Any, ...]]


def _cheap_runs(
    f: Formulation,
    rec: Recording,
    n: int,
    methods: tuple[str, ...],
    built: dict[str, float] | None = None,
) -> dict[str, Run]:
    """The methods that take microseconds per sample, each as a run of the recording
    returning ``(output, seconds per sample, fallbacks)``; each one's build time into
    ``built`` where it is built here."""
    runs: dict[str, Run] = {}
    built = {} if built is None else built
    if "fast" in methods:
        t0 = time.perf_counter()
        est = MovingHorizonEstimator(f, MHESettings(horizon=n, solver="fast"))
        built["fast"] = time.perf_counter() - t0

        def fast() -> tuple[FloatArray, FloatArray, int]:
            out, sec, status = _run_timed(est, rec)
            return out, sec, status.count("fallback-ipopt")

        runs["fast"] = fast
    if "mhe-kernel" in methods:
        runs["mhe-kernel"] = lambda: run_mhe_kernel(f, rec, n)
    filters: list[tuple[str, Estimator]] = []
    for name, kind in (("ekf", CasadiExtendedKalmanFilter), ("ekf-compiled", ExtendedKalmanFilter)):
        if name in methods:
            t0 = time.perf_counter()
            filters.append((name, kind(f)))
            built[name] = time.perf_counter() - t0
    for name, ekf in filters:
        runs[name] = lambda ekf=ekf: (*_run_timed(ekf, rec)[:2], 0)  # type: ignore[misc]
    if "ekf-kernel" in methods:
        runs["ekf-kernel"] = lambda: (*run_ekf_kernel(f, rec), 0)
    return runs


def round_order(names: list[str], round_index: int) -> list[str]:
    """The order of the contenders in round ``round_index`` (from 0): ``names`` rotated
    left by the round's index, so that no contender always runs first over the rounds
    (within a round each still runs after the one before it in ``names``)."""
    k = round_index % len(names) if names else 0
    return names[k:] + names[:k]


def _interleaved(
    runs: dict[str, Run], repeats: int
) -> dict[str, tuple[FloatArray, FloatArray, int, FloatArray | None, float]]:
    """Each run once (compiling, warming caches), then ``repeats`` rounds of all of them
    in turn, each round's order that of ``runs`` rotated by the round's index
    (:func:`round_order`), so that a change of the shared machine's load affects them
    alike. Returns per method the last round's outputs and fallbacks, each sample's
    median time over the rounds, the median of the solver's own times where the run
    reports them (else None), and the warm-up run's wall time, s."""
    warmup: dict[str, float] = {}
    for name, run in runs.items():
        t0 = time.perf_counter()
        run()
        warmup[name] = time.perf_counter() - t0
    got: dict[str, list[tuple[Any, ...]]] = {name: [] for name in runs}
    for r in range(repeats):
        for name in round_order(list(runs), r):
            got[name].append(runs[name]())

    def median(r: list[tuple[Any, ...]], i: int) -> FloatArray:
        return np.median(np.array([x[i] for x in r]), axis=0)

    return {
        name: (
            r[-1][0],
            median(r, 1),
            r[-1][2],
            median(r, 3) if len(r[-1]) > 3 else None,
            warmup[name],
        )
        for name, r in got.items()
    }


def _ratio(a: float, b: float | None) -> float:
    return a / b if b else math.nan


def _runs(
    f: Formulation,
    rec: Recording,
    n: int,
    methods: tuple[str, ...],
    acados: Any = None,
    closing: list[Callable[[], None]] | None = None,
    compile_peers: bool | None = None,
    built: dict[str, float] | None = None,
) -> dict[str, Run]:
    """Every method of ``methods`` at horizon ``n`` as a :data:`Run`, in the order of
    :data:`METHODS` (IPOPT, do-mpc and the peers beside the cheap ones). The peers'
    windows are recorded here, once, and their solvers built (acados' generated C
    compiled), each method's build time into ``built``; what must be removed after the
    runs goes into ``closing``."""
    from continuum_mhe.benchmark.peers import make_peer, record_windows, run_peer

    built = {} if built is None else built
    runs = _cheap_runs(f, rec, n, methods, built)
    t0 = time.perf_counter()
    ipopt = MovingHorizonEstimator(f, MHESettings(horizon=n, solver="ipopt"))
    built["ipopt"] = time.perf_counter() - t0
    runs["ipopt"] = lambda: (*_run_timed(ipopt, rec)[:2], 0)
    if "do-mpc" in methods:
        runs["do-mpc"] = lambda: (*run_dompc(f, n, rec), 0)
    peers = [p for p in PEERS if p in methods]
    if peers:
        windows = record_windows(f, rec, n)
        for name in peers:
            t0 = time.perf_counter()
            solver = make_peer(name, f, n, acados, compile_peers)
            built[name] = time.perf_counter() - t0
            close = getattr(solver, "close", None)
            if close is not None and closing is not None:
                closing.append(close)
            runs[name] = lambda solver=solver: run_peer(f, solver, windows)  # type: ignore[misc]
    return {m: runs[m] for m in METHODS if m in runs}


def run_benchmark(
    horizons: list[int],
    duration: float = 20.0,
    methods: tuple[str, ...] = METHODS,
    memory_samples: int = 20000,
    loss_horizons: tuple[int, ...] | None = None,
    repeats: int = REPEATS,
    acados_folder: str | None = None,
    say: Callable[[str], None] | None = None,
    compile_peers: bool | None = None,
) -> dict[str, Any]:
    """Time every method at every horizon on one recording, and each MHE loss at
    ``loss_horizons`` (empty: skipped; None: 30 if timed, else the first horizon); every
    method ``repeats`` times in turn (:func:`_interleaved`); a peer that cannot run here
    is skipped with the line that says what to install (``acados_folder``: where
    ``comma-deps-acados`` was installed apart, see :mod:`.peers`; ``compile_peers``: the
    CasADi peers' functions compiled, None where a C compiler is found:
    :func:`~.peers.casadi_peers_compiled`); ``say``: called with
    a line as each part starts and ends (the command line's progress); see the
    module docstring."""
    progress = say or (lambda line: None)
    from continuum_mhe.benchmark.losses import run_loss_benchmark
    from continuum_mhe.benchmark.peers import (
        acados_version,
        casadi_peers_compiled,
        find_acados,
        missing_peers,
    )

    f = make_formulation("bend")
    rec = simulate("paper3d", duration=duration, dt=DT, noise_deg=2.0, seed=0)
    env = environment(f)
    skipped = {k: v for k, v in missing_peers(acados_folder).items() if k in methods}
    methods = tuple(m for m in methods if m not in skipped)
    acados = find_acados(acados_folder) if "acados" in methods else None
    if acados is not None:
        env["versions"]["comma-deps-acados"] = acados_version(acados)
    env["casadi_peers_compiled"] = casadi_peers_compiled(compile_peers)
    results: list[Timing] = []
    for k, n in enumerate(horizons, start=1):
        closing: list[Callable[[], None]] = []
        built: dict[str, float] = {}
        started = time.perf_counter()
        progress(
            f"N = {n} ({k} of {len(horizons)} horizons): {len(methods)} methods, a warm-up "
            f"and {repeats} interleaved rounds of {len(rec.t)} samples each"
        )
        try:
            runs = _runs(f, rec, n, methods, acados, closing, compile_peers, built)
            rows = _interleaved(runs, repeats)
        finally:
            for close in closing:
                close()
        progress(f"N = {n} done in {time.perf_counter() - started:.0f} s")
        ipopt_out = rows["ipopt"][0]
        full = slice(n, None)
        for name in (m for m in METHODS if m in rows):
            out, sec, fb, own, warmup = rows[name]
            from_n, missing, agrees = agreement(out[full], ipopt_out[full])
            results.append(
                Timing(
                    method=name,
                    horizon=n,
                    median_us=float(np.median(sec[full]) * 1e6),
                    p99_us=float(np.percentile(sec[full], 99) * 1e6),
                    max_diff_vs_ipopt=_max_diff(out, ipopt_out),
                    max_diff_from_n=from_n,
                    fallbacks=fb,
                    solver_median_us=math.nan
                    if own is None or np.isnan(own[full]).all()
                    else float(np.nanmedian(own[full]) * 1e6),
                    missing_from_n=missing,
                    agrees_with_ipopt=agrees if name in MHE_METHODS else None,
                    build_s=built.get(name, math.nan),
                    warmup_s=warmup,
                )
            )
    if loss_horizons is None:
        loss_horizons = (30,) if 30 in horizons else tuple(horizons[:1])
    losses = []
    if loss_horizons and "fast" in methods:
        progress(f"the MHE's losses at N = {', '.join(map(str, loss_horizons))}")
        losses = run_loss_benchmark(f, rec, list(loss_horizons))
    # (the memory check is the fast MHE's: none where it is skipped)
    memory = None
    if memory_samples > 0 and "fast" in methods:
        progress(f"the fast MHE's memory over {memory_samples} samples")
        memory = memory_profile(f, 30, memory_samples)
    return {
        "formulation": "bend",
        "scenario": "paper3d",
        "noise_deg": 2.0,
        "samples": len(rec.t),
        "dt_s": float(rec.t[1] - rec.t[0]),
        "repeats": repeats,
        **env,
        "methods": {m: METHOD_NOTES[m] for m in METHODS if m in methods or m == "ipopt"},
        "skipped": skipped,
        "results": with_ratios([asdict(r) for r in results]),
        "losses": losses,
        "memory": None if memory is None else asdict(memory),
    }


def with_ratios(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each row with its median over the fast MHE's, IPOPT's, the compiled EKF's and
    the EKF kernel's at the same horizon (``over_fast``, ``over_ipopt``,
    ``over_ekf_compiled``, ``over_ekf_kernel``; nan where that method did not run)."""
    ref = {(r["method"], r["horizon"]): r["median_us"] for r in rows}
    return [
        {
            **r,
            "over_fast": _ratio(r["median_us"], ref.get(("fast", r["horizon"]))),
            "over_ipopt": _ratio(r["median_us"], ref.get(("ipopt", r["horizon"]))),
            "over_ekf_compiled": _ratio(r["median_us"], ref.get(("ekf-compiled", r["horizon"]))),
            "over_ekf_kernel": _ratio(r["median_us"], ref.get(("ekf-kernel", r["horizon"]))),
        }
        for r in rows
    ]
