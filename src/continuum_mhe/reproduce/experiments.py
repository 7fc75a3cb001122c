"""The paper's experiments (Sec. 3) as pure functions over frozen specs.

Every independent run is a :class:`TrialSpec`; :func:`run_trial` simulates it, runs
the estimators and returns plain data (dicts of floats and lists), so trials can run
in any process or on a Dask cluster and their results can be saved as JSON. The
recording experiment (Sec. 3.3) reads the shipped rod CSV in :func:`run_rod`.

Units: time s, angles rad, positions m, solve times ms (unless a key says otherwise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators import EstimateSeries, Method, make_estimator
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import shape_from_tilt, wrap_angle
from continuum_mhe.model.kinematics import tip_position
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.reproduce.beyond import BeyondSpec, plan_beyond
from continuum_mhe.reproduce.bootstrap import mean_ci
from continuum_mhe.settings import (
    FormulationName,
    MHESettings,
    NoiseSettings,
    RecoverySettings,
    RobotSettings,
)
from continuum_mhe.simulation.scenarios import ScenarioName, simulate

Corruption = Literal["none", "bad-init", "outliers"]

#: Table 1: (sigma_beta = pitch, sigma_gamma = roll); |sigma| is read as a std in rad.
TABLE1: tuple[tuple[float, float], ...] = (
    (0.022, -0.024),
    (0.028, 0.033),
    (-0.026, 0.032),
    (0.029, -0.001),
    (0.010, 0.021),
    (-0.028, -0.025),
    (-0.015, -0.005),
    (0.003, 0.029),
    (0.032, 0.020),
    (0.033, 0.032),
)

EXPERIMENTS = (
    "exp1_synthetic3d",
    "exp2_constraints",
    "exp3_rod",
    "exp4_ekf_comparison",
    "exp5_horizon",
    "exp6_window",
    "exp7_beyond",
)


@dataclass(frozen=True)
class ReproduceConfig:
    """Sizes of every experiment.

    Attributes:
        length: section length, m. dt: sample time, s. horizon: the paper's N.
        noise_deg: measurement noise std and the estimators' assumed std, degrees.
        duration: length of the single example runs (Sec. 3.1, 3.2, 3.4 figure), s.
        mc_seeds, mc_duration: Monte Carlo trials per Table 1 scenario and their length.
        condition_seeds: trials per extra condition (bad start, outliers, ...).
        sweep_horizons, sweep_seeds, sweep_duration: Sec. 3.5 sweep.
        window_seeds, window_duration: growing window vs ``paper_start``.
        bad_init_deg: offset added to roll and pitch of the first sample, degrees.
        outlier_fraction, outlier_deg: share of samples with a spike and its size.
        large_noise_deg: noise std of the large-noise condition (R matched), degrees.
        beyond_seeds, beyond_duration: seeds per group of the beyond-the-paper
            experiment (``reproduce.beyond``) and the length of its outlier and
            coverage runs, s. beyond_recovery_duration: length of its gap and freeze
            runs, s. beyond_gap_s: the gap's length, s.
    """

    length: float = 0.2
    dt: float = 0.05
    horizon: int = 30
    noise_deg: float = 2.0
    duration: float = 20.0
    mc_seeds: int = 50
    mc_duration: float = 10.0
    condition_seeds: int = 50
    sweep_horizons: tuple[int, ...] = (5, 10, 15, 20, 30, 40, 50, 60, 80, 100)
    sweep_seeds: int = 10
    sweep_duration: float = 20.0
    window_seeds: int = 50
    window_duration: float = 6.0
    bad_init_deg: float = 40.0
    outlier_fraction: float = 0.02
    outlier_deg: float = 30.0
    large_noise_deg: float = 8.0
    beyond_seeds: int = 50
    beyond_duration: float = 20.0
    beyond_recovery_duration: float = 20.0
    beyond_gap_s: float = 3.0

    def __post_init__(self) -> None:
        for name in (
            "mc_seeds",
            "condition_seeds",
            "sweep_seeds",
            "window_seeds",
            "beyond_seeds",
        ):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 2):
                raise UserError(f"{name} must be an integer >= 2, got {v!r}")
        if not self.sweep_horizons or min(self.sweep_horizons) < 2:
            raise UserError("sweep_horizons must be non-empty integers >= 2")
        longest = int(round(self.sweep_duration / self.dt)) + 1
        if max(self.sweep_horizons) > longest:
            raise UserError("sweep_duration is shorter than the longest horizon")


FULL = ReproduceConfig()
QUICK = ReproduceConfig(
    duration=8.0,
    mc_seeds=5,
    mc_duration=3.0,
    condition_seeds=2,
    sweep_horizons=(5, 20, 50, 100),
    sweep_seeds=2,
    sweep_duration=5.5,
    window_seeds=2,
    window_duration=3.0,
    beyond_seeds=2,
    beyond_duration=5.0,
    beyond_recovery_duration=10.0,
)


@dataclass(frozen=True)
class TrialSpec:
    """One independent run: simulate, corrupt, estimate, score.

    Attributes:
        experiment: data file it belongs to; group: label inside it.
        scenario: :func:`simulate` scenario. seed: noise seed.
        duration, dt: s. length: m.
        noise_std: simulated (roll, pitch) noise std, rad.
        assumed_std: the estimators' measurement std (same R for all), rad.
        methods: estimators to run on the same data.
        horizon, paper_start: MHE settings (others at their defaults).
        formulation: motion model shared by all methods.
        corruption: ``bad-init`` offsets the first sample by ``corruption_deg`` on
            both angles; ``outliers`` adds +-``corruption_deg`` spikes to a share
            ``outlier_fraction`` of the samples.
        keep_series: return the time series too (for figures).
        score_from: also score the samples from this index on (key ``from``), so runs
            with different horizons can be compared on the same samples.
        mhe_solver: MHE backend (``MHESettings.solver``); empty for the default.
    """

    experiment: str
    group: str
    scenario: ScenarioName
    seed: int
    duration: float
    dt: float
    length: float
    noise_std: tuple[float, float]
    assumed_std: float
    methods: tuple[Method, ...]
    horizon: int = 30
    paper_start: bool = False
    formulation: FormulationName = "bend"
    corruption: Corruption = "none"
    corruption_deg: float = 0.0
    outlier_fraction: float = 0.0
    keep_series: bool = False
    score_from: int = 0
    mhe_solver: str = ""

    def __post_init__(self) -> None:
        if not self.methods:
            raise UserError("methods must name at least one estimator")
        if self.corruption not in ("none", "bad-init", "outliers"):
            raise UserError(f"unknown corruption {self.corruption!r}")
        if not 0 <= self.outlier_fraction < 1:
            raise UserError(f"outlier_fraction must lie in [0, 1), got {self.outlier_fraction}")
        if len(self.noise_std) != 2 or min(self.noise_std) < 0 or self.assumed_std <= 0:
            raise UserError("noise_std must be two stds >= 0 rad and assumed_std > 0 rad")

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["noise_std"] = list(self.noise_std)
        d["methods"] = list(self.methods)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrialSpec:
        d = dict(d)
        d["noise_std"] = tuple(d["noise_std"])
        d["methods"] = tuple(d["methods"])
        d.pop("extra", None)  # written by early versions
        return cls(**d)


# --- pure helpers ------------------------------------------------------------------
def corrupt(z: FloatArray, spec: TrialSpec) -> FloatArray:
    """Measurements after the spec's corruption (a copy; rad)."""
    z = np.array(z, dtype=float)
    if spec.corruption == "bad-init":
        z[0] += math.radians(spec.corruption_deg)
    elif spec.corruption == "outliers":
        rng = np.random.default_rng(10_000 + spec.seed)
        n = len(z)
        k = max(1, int(round(spec.outlier_fraction * n)))
        idx = rng.choice(np.arange(1, n), size=k, replace=False)
        z[idx] += math.radians(spec.corruption_deg) * rng.choice([-1.0, 1.0], size=(k, 2))
    return np.asarray(wrap_angle(z), dtype=float)


def _metrics_dict(output: FloatArray, truth: FloatArray, length: float) -> dict[str, Any] | None:
    has = np.all(np.isfinite(output), axis=1)
    if not has.any():
        return None
    m = compute_metrics(output, truth, length)
    return {
        "srmse": m.srmse,
        "rmse": m.rmse,
        "tip_mean_mm": m.tip_mean_mm,
        "tip_max_mm": m.tip_max_mm,
        "n": m.n,
        "n_without_estimate": m.n_without_estimate,
    }


def score_series(
    series: EstimateSeries, truth: FloatArray, length: float, horizon: int, score_from: int = 0
) -> dict[str, Any]:
    """Errors and timing of one estimate series.

    Keys: ``all`` (every sample with an estimate), ``early`` (the first ``horizon``
    samples), ``late`` (from sample ``horizon`` on), ``from`` (from sample
    ``score_from`` on), ``solve_ms_mean`` and
    ``solve_ms_median`` over samples with an estimate, ``solve_ms_total`` over all
    samples, ``first_estimate_index``, ``status`` counts.
    """
    out = series.output
    has = np.all(np.isfinite(out), axis=1)
    first = int(np.argmax(has)) if has.any() else -1
    est_ms = series.solve_ms[has]
    status, counts = np.unique(series.status, return_counts=True)
    return {
        "all": _metrics_dict(out, truth, length),
        "early": _metrics_dict(out[:horizon], truth[:horizon], length),
        "late": _metrics_dict(out[horizon:], truth[horizon:], length),
        "from": _metrics_dict(out[score_from:], truth[score_from:], length),
        "solve_ms_mean": float(est_ms.mean()) if len(est_ms) else math.nan,
        "solve_ms_median": float(np.median(est_ms)) if len(est_ms) else math.nan,
        "solve_ms_total": float(series.solve_ms.sum()),
        "first_estimate_index": first,
        "status": {str(s): int(c) for s, c in zip(status, counts)},
    }


def _formulation(name: FormulationName, length: float, std: float) -> Formulation:
    return make_formulation(name, RobotSettings(length=length), NoiseSettings(measurement_std=std))


def estimate_all(
    t: FloatArray,
    z: FloatArray,
    methods: Sequence[Method],
    formulation: FormulationName,
    length: float,
    assumed_std: float,
    mhe: MHESettings,
) -> dict[str, EstimateSeries]:
    """Run each method on the same measurements with the same model, Q and R, as the
    paper does: the bare estimators (no gap reset, freeze or bad-start check)."""
    f = _formulation(formulation, length, assumed_std)
    bare = RecoverySettings.off()
    return {m: make_estimator(m, f, mhe, bare).run(t, z) for m in methods}


def _mhe_settings(spec: TrialSpec) -> MHESettings:
    kw: dict[str, Any] = {"horizon": spec.horizon, "paper_start": spec.paper_start}
    if spec.mhe_solver:
        kw["solver"] = spec.mhe_solver
    return MHESettings(**kw)


def run_trial(spec: TrialSpec) -> dict[str, Any]:
    """Simulate ``spec``, run its estimators and score them against the truth."""
    rec = simulate(
        spec.scenario,
        duration=spec.duration,
        dt=spec.dt,
        length=spec.length,
        seed=spec.seed,
        noise_std=spec.noise_std,
    )
    z = corrupt(rec.z, spec)
    mhe = _mhe_settings(spec)
    f = _formulation(spec.formulation, spec.length, spec.assumed_std)
    series = estimate_all(
        rec.t, z, spec.methods, spec.formulation, spec.length, spec.assumed_std, mhe
    )
    theta_max = f.robot.theta_max
    result: dict[str, Any] = {
        "spec": spec.as_dict(),
        "mhe_settings": repr(mhe),
        "noise_settings": asdict(f.noise),
        "theta_max": theta_max,
        "methods": {
            m: score_series(s, rec.truth, spec.length, spec.horizon, spec.score_from)
            for m, s in series.items()
        },
    }
    if spec.experiment == "exp2_constraints":
        result["constraints"] = {
            m: constraint_scores(s.output, rec.truth, spec.length, theta_max)
            for m, s in series.items()
        }
    if spec.keep_series:
        result["series"] = {
            "t": rec.t,
            "z": z,
            "truth": rec.truth,
            **{m: s.output for m, s in series.items()},
            **{f"{m}_status": s.status.tolist() for m, s in series.items()},
        }
    return to_jsonable(result)


def constraint_scores(
    output: FloatArray, truth: FloatArray, length: float, theta_max: float
) -> dict[str, Any]:
    """Errors inside and outside the feasible region ``theta <= theta_max``.

    Outside, errors are given against the truth and against the closest feasible
    state (theta clipped to the bound, tip recomputed), the best a bounded estimate
    can do.
    """
    inside = truth[:, 3] <= theta_max
    feasible = truth.copy()
    feasible[:, 3] = np.minimum(truth[:, 3], theta_max)
    feasible[:, :3] = tip_position(feasible[:, 3], feasible[:, 4], length)
    has = np.all(np.isfinite(output), axis=1)
    over = has & (output[:, 3] > theta_max + 1e-6)
    return {
        "inside": _metrics_dict(output[inside], truth[inside], length),
        "outside_vs_truth": _metrics_dict(output[~inside], truth[~inside], length),
        "outside_vs_feasible": _metrics_dict(output[~inside], feasible[~inside], length),
        "n_inside": int(inside.sum()),
        "n_outside": int((~inside).sum()),
        "theta_max_estimate": float(np.nanmax(output[:, 3])),
        "n_estimates_over_bound": int(over.sum()),
        "first_t_truth_over_bound_index": int(np.argmax(~inside)) if (~inside).any() else -1,
    }


def to_jsonable(obj: Any) -> Any:
    """Arrays to lists, NaN/inf to None, recursively."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.str_):
        return str(obj)
    return obj


# --- the experiment plans --------------------------------------------------------------
def _std(deg: float) -> tuple[float, float]:
    r = math.radians(deg)
    return (r, r)


def _trial(
    cfg: ReproduceConfig,
    experiment: str,
    group: str,
    seed: int,
    duration: float,
    **kw: Any,
) -> TrialSpec:
    """A spec with the config's defaults: paper3d, 2 deg noise and R, N, MHE/EKF/UKF."""
    args: dict[str, Any] = {
        "scenario": "paper3d",
        "dt": cfg.dt,
        "length": cfg.length,
        "horizon": cfg.horizon,
        "noise_std": _std(cfg.noise_deg),
        "assumed_std": math.radians(cfg.noise_deg),
        "methods": ("mhe", "ekf", "ukf"),
    }
    args.update(kw)
    return TrialSpec(experiment=experiment, group=group, seed=seed, duration=duration, **args)


def plan_trials(cfg: ReproduceConfig) -> list[TrialSpec]:
    """Every synthetic trial of experiments 1, 2, 4, 5 and 6, in a stable order."""
    specs = [
        _trial(cfg, "exp1_synthetic3d", "example", 0, cfg.duration, keep_series=True),
        # the paper's own 5-state formulation (eq. 4), same data and noise
        _trial(
            cfg,
            "exp1_synthetic3d",
            "paper-formulation",
            0,
            min(cfg.duration, 10.0),
            formulation="paper",
            methods=("mhe", "ekf"),
        ),
        _trial(
            cfg,
            "exp2_constraints",
            "example",
            0,
            max(cfg.duration, 12.0),
            scenario="planar-overbend",
            keep_series=True,
        ),
    ]
    sb10, sg10 = TABLE1[-1]
    specs.append(
        _trial(
            cfg,
            "exp4_ekf_comparison",
            "example",
            0,
            cfg.duration,
            noise_std=(abs(sg10), abs(sb10)),
            methods=("mhe", "ekf"),
            keep_series=True,
        )
    )
    for i, (sb, sg) in enumerate(TABLE1, start=1):
        specs += [
            _trial(
                cfg,
                "exp4_ekf_comparison",
                f"table1-{i}",
                1000 * i + seed,
                cfg.mc_duration,
                noise_std=(abs(sg), abs(sb)),
            )
            for seed in range(cfg.mc_seeds)
        ]
    conditions: list[tuple[str, dict[str, Any]]] = [
        ("nominal", {}),
        ("bad-init", {"corruption": "bad-init", "corruption_deg": cfg.bad_init_deg}),
        (
            "outliers",
            {
                "corruption": "outliers",
                "corruption_deg": cfg.outlier_deg,
                "outlier_fraction": cfg.outlier_fraction,
            },
        ),
        ("straight", {"scenario": "straight"}),
        (
            "large-noise",
            {
                "noise_std": _std(cfg.large_noise_deg),
                "assumed_std": math.radians(cfg.large_noise_deg),
            },
        ),
    ]
    for name, kw in conditions:
        specs += [
            _trial(
                cfg,
                "exp4_ekf_comparison",
                f"condition-{name}",
                50_000 + seed,
                cfg.mc_duration,
                **kw,
            )
            for seed in range(cfg.condition_seeds)
        ]
    # the default backend on every seed; the paper's solver, IPOPT, for its timing on
    # fewer seeds (the optimum is the same)
    sweep_runs = (("", None, cfg.sweep_seeds), ("ipopt ", "ipopt", min(3, cfg.sweep_seeds)))
    for n in cfg.sweep_horizons:
        for prefix, solver, seeds in sweep_runs:
            extra = {"mhe_solver": solver} if solver else {}
            specs += [
                _trial(
                    cfg,
                    "exp5_horizon",
                    f"{prefix}N={n}",
                    70_000 + seed,
                    cfg.sweep_duration,
                    horizon=n,
                    paper_start=True,
                    methods=("mhe",),
                    score_from=max(cfg.sweep_horizons) - 1,
                    **extra,
                )
                for seed in range(seeds)
            ]
    for paper_start in (False, True):
        specs += [
            _trial(
                cfg,
                "exp6_window",
                "paper-start" if paper_start else "growing",
                90_000 + seed,
                cfg.window_duration,
                paper_start=paper_start,
                methods=("mhe",) if paper_start else ("mhe", "ekf"),
                keep_series=seed == 0,
            )
            for seed in range(cfg.window_seeds)
        ]
    return specs


def plan_beyond_trials(cfg: ReproduceConfig) -> list[BeyondSpec]:
    """Every run of the beyond-the-paper experiment (``exp7_beyond``)."""
    return plan_beyond(
        cfg.beyond_seeds,
        cfg.beyond_duration,
        dt=cfg.dt,
        length=cfg.length,
        noise_deg=cfg.noise_deg,
        horizon=cfg.horizon,
        recovery_duration=cfg.beyond_recovery_duration,
        gap_s=cfg.beyond_gap_s,
    )


# --- Sec. 3.3: the hardware-like rod recording ------------------------------------------
def run_rod(path: Path, cfg: ReproduceConfig) -> dict[str, Any]:
    """MHE and EKF on the rod recording; errors against the rod's truth and against the
    forward kinematics of the measurements (the paper's Fig. 7 reference), and the error
    the constant-curvature assumption makes by itself."""
    from continuum_mhe.simulation import cosserat

    cols = cosserat.read_recording(path).columns
    t = cols["t"]
    z = np.column_stack([cols["roll"], cols["pitch"]])
    length = cfg.length
    tip_true = np.column_stack([cols["x_true"], cols["y_true"], cols["z_true"]])
    truth = np.column_stack([tip_true, cols["theta_fit"], cols["phi_fit"]])
    th_m, ph_m = shape_from_tilt(z[:, 0], z[:, 1])
    fk = np.column_stack([tip_position(th_m, ph_m, length), th_m, ph_m])
    cc_fit_tip = np.column_stack([cols["x_fit"], cols["y_fit"], cols["z_fit"]])
    cc_tan_tip = tip_position(cols["theta_tangent"], cols["phi_tangent"], length)
    std = math.radians(cfg.noise_deg)
    mhe = MHESettings(horizon=cfg.horizon)
    series = estimate_all(t, z, ("mhe", "ekf"), "bend", length, std, mhe)

    def tip_err(a: FloatArray) -> dict[str, float]:
        e = np.linalg.norm(a - tip_true, axis=1) * 1e3
        return {"mean_mm": float(e.mean()), "max_mm": float(e.max())}

    result = {
        "source": str(path.name),
        "generator": cosserat.read_generator_info(path),
        "n": len(t),
        "dt": float(np.median(np.diff(t))),
        "length": length,
        "assumed_std": std,
        "mhe_settings": repr(mhe),
        "methods": {
            m: {
                "vs_truth": score_series(s, truth, length, cfg.horizon),
                "vs_fk_of_measurements": score_series(s, fk, length, cfg.horizon),
            }
            for m, s in series.items()
        },
        "fk_of_measurements_vs_truth": tip_err(fk[:, :3]),
        "cc_fit_vs_truth": tip_err(cc_fit_tip),
        "cc_from_tip_tangent_vs_truth": tip_err(cc_tan_tip),
        "theta_tangent_minus_fit_deg": {
            "mean_abs": float(np.degrees(np.abs(cols["theta_tangent"] - cols["theta_fit"])).mean()),
            "max_abs": float(np.degrees(np.abs(cols["theta_tangent"] - cols["theta_fit"])).max()),
        },
        "series": {
            "t": t,
            "z": z,
            "truth": truth,
            "fk": fk,
            "cc_fit_tip": cc_fit_tip,
            **{m: s.output for m, s in series.items()},
        },
    }
    return dict(to_jsonable(result))


# --- aggregation ---------------------------------------------------------------------------
def _get(trial: dict[str, Any], method: str, part: str, key: str) -> float:
    block = trial["methods"].get(method, {}).get(part)
    if block is None:
        return math.nan
    v = block[key]
    return math.nan if v is None else float(v)


def summarise_groups(
    trials: Sequence[dict[str, Any]], methods: Sequence[str], part: str = "all"
) -> dict[str, Any]:
    """Per group: mean and 95 % CI of SRMSE and tip error per method, and the paired
    difference MHE - EKF (negative: the MHE is better)."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for tr in trials:
        groups.setdefault(tr["spec"]["group"], []).append(tr)
    out: dict[str, Any] = {}
    for g, trs in groups.items():
        entry: dict[str, Any] = {"n_trials": len(trs)}
        for m in methods:
            if m not in trs[0]["methods"]:
                continue
            entry[m] = {
                key: mean_ci([_get(tr, m, part, key) for tr in trs])
                for key in ("srmse", "tip_mean_mm")
            }
        if "mhe" in entry and "ekf" in entry:
            entry["mhe_minus_ekf"] = {
                key: mean_ci(
                    [_get(tr, "mhe", part, key) - _get(tr, "ekf", part, key) for tr in trs]
                )
                for key in ("srmse", "tip_mean_mm")
            }
        out[g] = entry
    return out
