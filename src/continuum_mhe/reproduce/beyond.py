"""Beyond the paper: outliers, calibrated uncertainty and recovery.

Every run is a :class:`BeyondSpec` (one group, one seed) on ``paper3d``;
:func:`run_beyond` simulates it, corrupts it as its group says, runs the estimators and
returns plain data; :func:`summarise_beyond` turns the trials into means with 95 %
(paired) bootstrap intervals for the report. Groups:

* ``clean``, ``spikes``, ``bursts``: the quadratic MHE, the robust MHE (the
  config's ``robust_loss`` at its default scale) and the EKF on the same data.
  ``spikes``: a share ``spike_fraction`` of the samples gets an isolated (never
  adjacent) +-``spike_deg`` spike on roll and pitch (independent signs); ``bursts``:
  ``round(burst_fraction n)`` non-touching runs of ``burst_length`` samples, each one
  +-``spike_deg`` offset. Corrupted readings are what a real sensor reports for the
  offset orientation (:func:`as_sensor_reads`: pitch inside +-90 deg, roll wrapped).
  Score: mean tip error (mm) over the recording.
* ``coverage``: MHE, EKF, UKF on clean data; per sample the tip error against the
  tip's 95 % intervals (per axis, and the ellipsoid of ``J P J^T``) and its NEES. The
  data are model-consistent for the measurement (noise isotropic on the tangent plane
  of gravity, ``noise_model="tangent"``, which is what ``R`` models); the same seeds
  with the paper's roll/pitch noise are scored too (``methods_tilt_noise``).
* ``gap``, ``freeze``, ``bad-start``: MHE, EKF, UKF with :data:`RECOVERY_ON` (the
  command line's defaults) and without (the library's). ``gap``: no data for ``gap_s``
  from :data:`EVENT_T0`; ``freeze``: the IMU repeats its reading for ``freeze_s`` from
  :data:`EVENT_T0`; ``bad-start``: the readings of the first ``bad_s`` are ``bad_deg``
  off on roll and pitch, then right. Scored over the event and :data:`AFTER_S` after
  it (gap and bad start: the 2 s after). ``bad-start`` also runs each estimator with
  the settings on over the clean recording: ``clean_fired`` (bad-start restarts, must
  be 0) and ``clean_diff_mm`` (largest tip difference from the run with them off).

Units: s, rad, m; errors in mm where a key says so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any, Literal

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators import Method, make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.evaluation.metrics import Z95
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import as_sensor_reads
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.reproduce.bootstrap import mean_ci, paired
from continuum_mhe.results import Status
from continuum_mhe.settings import (
    MHELoss,
    MHESettings,
    NoiseSettings,
    RecoverySettings,
    RobotSettings,
)
from continuum_mhe.simulation.scenarios import simulate

BeyondGroup = Literal["clean", "spikes", "bursts", "coverage", "gap", "freeze", "bad-start"]
BEYOND_GROUPS: tuple[BeyondGroup, ...] = (
    "clean", "spikes", "bursts", "coverage", "gap", "freeze", "bad-start")  # fmt: skip
OUTLIER_GROUPS = ("clean", "spikes", "bursts")
RECOVERY_GROUPS = ("gap", "freeze", "bad-start")
#: Estimators of the outlier groups: quadratic MHE, robust MHE, EKF.
OUTLIER_METHODS = ("mhe-l2", "mhe-robust", "ekf")
#: Estimators of the coverage and recovery groups.
ALL_METHODS: tuple[Method, ...] = ("mhe", "ekf", "ukf")
#: The recovery defaults (the command line's ``--gap-reset``, ``--freeze``, ``--bad-start``).
RECOVERY_ON = RecoverySettings()
#: Gap, freeze and bad-start off: the bare estimator (the coverage group's too).
RECOVERY_OFF = RecoverySettings.off()
#: The outlier groups' estimators: bare, but a robust MHE restarts after its newest
#: reading was rejected for half a second (``RecoverySettings.reject_reset``).
RECOVERY_OUTLIERS = replace(RECOVERY_OFF, reject_reset=RecoverySettings.reject_reset)
#: Start of the gap and of the freeze, s; the score window's extra time after, s.
EVENT_T0 = 5.0
AFTER_S = 2.0
#: A sample is "ok but wrong" if it says ``ok`` while its tip is more than this share
#: of the length wrong.
WRONG_SHARE = 0.1


@dataclass(frozen=True)
class BeyondSpec:
    """One run of the beyond-the-paper experiment.

    Attributes:
        group: one of :data:`BEYOND_GROUPS`. seed: noise (and corruption) seed.
        duration, dt: s. length: m. noise_deg: simulated and assumed noise std, deg.
        horizon: MHE N. robust_loss: the robust MHE's loss (default scale).
        spike_deg, spike_fraction: size and share of isolated spikes.
        burst_fraction, burst_length: bursts per sample and their length (samples).
        gap_s, freeze_s: length of the gap and of the freeze, s.
        bad_s, bad_deg: length (s) and offset (deg, roll and pitch) of the bad start.
    """

    group: BeyondGroup
    seed: int
    duration: float
    dt: float = 0.05
    length: float = 0.2
    noise_deg: float = 2.0
    horizon: int = 30
    robust_loss: MHELoss = "welsch"
    spike_deg: float = 30.0
    spike_fraction: float = 0.02
    burst_fraction: float = 0.01
    burst_length: int = 5
    gap_s: float = 3.0
    freeze_s: float = 3.0
    bad_s: float = 0.5
    bad_deg: float = 60.0
    experiment: str = "exp7_beyond"

    def __post_init__(self) -> None:
        if self.group not in BEYOND_GROUPS:
            raise UserError(f"group must be one of {BEYOND_GROUPS}, got {self.group!r}")
        if self.robust_loss == "l2":
            raise UserError("robust_loss must be a robust loss (huber, cauchy or welsch)")
        end = EVENT_T0 + max(self.gap_s, self.freeze_s) + AFTER_S
        if self.group in RECOVERY_GROUPS and self.duration < end:
            raise UserError(f"duration must be at least {end:g} s for the {self.group} group")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> BeyondSpec:
        return cls(**d)


# --- corruption ---------------------------------------------------------------------
def spikes(z: FloatArray, spec: BeyondSpec) -> tuple[FloatArray, FloatArray]:
    """Isolated spikes on ``spike_fraction`` of the samples; ``(z, corrupted mask)``."""
    rng = np.random.default_rng(20_000 + spec.seed)
    n = len(z)
    k = max(1, round(spec.spike_fraction * n))
    chosen: list[int] = []
    while len(chosen) < k:  # isolated: no two spikes adjacent
        i = int(rng.integers(1, n))
        if all(abs(i - j) > 1 for j in chosen):
            chosen.append(i)
    idx = np.sort(np.array(chosen))
    out = np.array(z, dtype=float)
    out[idx] += math.radians(spec.spike_deg) * rng.choice([-1.0, 1.0], size=(k, 2))
    mask = np.zeros(n, dtype=bool)
    mask[idx] = True
    return as_sensor_reads(out), mask


def bursts(z: FloatArray, spec: BeyondSpec) -> tuple[FloatArray, FloatArray]:
    """``round(burst_fraction n)`` bursts of ``burst_length`` samples, one offset each."""
    rng = np.random.default_rng(30_000 + spec.seed)
    n, b = len(z), spec.burst_length
    k = max(1, round(spec.burst_fraction * n))
    starts: list[int] = []
    while len(starts) < k:  # not overlapping, not touching
        s = int(rng.integers(1, n - b))
        if all(abs(s - j) > b for j in starts):
            starts.append(s)
    out = np.array(z, dtype=float)
    mask = np.zeros(n, dtype=bool)
    for s in sorted(starts):
        out[s : s + b] += math.radians(spec.spike_deg) * rng.choice([-1.0, 1.0], size=2)
        mask[s : s + b] = True
    return as_sensor_reads(out), mask


def bad_start(z: FloatArray, t: FloatArray, spec: BeyondSpec) -> FloatArray:
    """The readings before ``spec.bad_s`` s offset by ``spec.bad_deg`` on roll and pitch."""
    out = np.array(z, dtype=float)
    out[t < spec.bad_s] += math.radians(spec.bad_deg)
    return as_sensor_reads(out)


# --- scores -------------------------------------------------------------------------
def tip_calibration(
    f: Formulation, method: Method, t: FloatArray, z: FloatArray, tip: FloatArray
) -> dict[str, float]:
    """Coverage of the tip's 95 % intervals over one run, its NEES and mean error.

    Per axis: ``|e_c| <= 1.96 std_c``. 3D: ``e^T C^+ e <= chi2_k(0.95)`` with
    ``C = J P J^T`` and ``k`` its rank (2 for one section: the tip moves on a surface).
    ``nees_per_dof``: mean of ``e^T C^+ e / k`` (1 where the covariance is right)."""
    from scipy.stats import chi2

    est = make_estimator(method, f, MHESettings(), RECOVERY_OFF)
    est.reset()
    axis, in3d, nees, err_mm = [], [], [], []
    for i in range(len(t)):
        e = est.step(Measurement(float(t[i]), z[i]))
        if e.state is None or e.covariance is None:
            continue
        jac = np.asarray(f.output_jacobian(e.state), dtype=float).reshape(f.ny, f.nx)[:3]
        c = jac @ e.covariance @ jac.T
        err = np.asarray(e.output, dtype=float)[:3] - tip[i]
        axis.append(np.abs(err) <= Z95 * np.sqrt(np.diag(c)))
        ev = np.linalg.eigvalsh(c)
        k = int(np.sum(ev > 1e-9 * ev.max()))
        q = float(err @ np.linalg.pinv(c, rcond=1e-9, hermitian=True) @ err)
        nees.append(q / k)
        in3d.append(q <= chi2.ppf(0.95, k))
        err_mm.append(float(np.linalg.norm(err)) * 1e3)
    cov = np.mean(axis, axis=0)
    return {
        "coverage_x": float(cov[0]),
        "coverage_y": float(cov[1]),
        "coverage_z": float(cov[2]),
        "coverage_3d": float(np.mean(in3d)),
        "nees_per_dof": float(np.mean(nees)),
        "tip_mean_mm": float(np.mean(err_mm)),
        "n": len(nees),
    }


def _formulation(spec: BeyondSpec) -> Formulation:
    noise = NoiseSettings(measurement_std=math.radians(spec.noise_deg))
    return make_formulation("bend", RobotSettings(length=spec.length), noise)


def _tip_err(output: FloatArray, truth: FloatArray) -> FloatArray:
    """Tip error per sample, m (nan without an estimate)."""
    return np.asarray(np.linalg.norm(output[:, :3] - truth[:, :3], axis=1), dtype=float)


def _outliers(spec: BeyondSpec, t: FloatArray, z: FloatArray, truth: FloatArray) -> dict[str, Any]:
    f = _formulation(spec)
    mask = np.zeros(len(t), dtype=bool)
    if spec.group == "spikes":
        z, mask = spikes(z, spec)
    elif spec.group == "bursts":
        z, mask = bursts(z, spec)
    losses: dict[str, MHELoss] = {"mhe-l2": "l2", "mhe-robust": spec.robust_loss}
    out: dict[str, Any] = {}
    for m in OUTLIER_METHODS:
        if m == "ekf":
            s = make_estimator("ekf", f, None, RECOVERY_OUTLIERS).run(t, z)
        else:
            mhe = MHESettings(horizon=spec.horizon, loss=losses[m])
            s = make_estimator("mhe", f, mhe, RECOVERY_OUTLIERS).run(t, z)
        flagged = np.zeros(len(t), dtype=bool) if s.outlier is None else np.asarray(s.outlier)
        out[m] = {
            "tip_mean_mm": float(np.nanmean(_tip_err(s.output, truth)) * 1e3),
            "flagged": int(flagged.sum()),
            "flagged_corrupted": int((flagged & mask).sum()),
            "corrupted": int(mask.sum()),
        }
    return out


def _recovery(spec: BeyondSpec, t: FloatArray, z: FloatArray, truth: FloatArray) -> dict[str, Any]:
    f = _formulation(spec)
    if spec.group == "gap":
        keep = (t < EVENT_T0) | (t >= EVENT_T0 + spec.gap_s)
        t, z, truth = t[keep], z[keep], truth[keep]
        start = t[np.flatnonzero(t >= EVENT_T0)[0]]
        window = (t >= start) & (t < start + AFTER_S)
    elif spec.group == "bad-start":
        clean = z
        z = bad_start(z, t, spec)
        window = (t >= spec.bad_s) & (t < spec.bad_s + AFTER_S)
    else:
        z = z.copy()
        frozen = (t >= EVENT_T0) & (t < EVENT_T0 + spec.freeze_s)
        z[frozen] = z[np.flatnonzero(frozen)[0]]
        window = (t >= EVENT_T0) & (t < EVENT_T0 + spec.freeze_s + AFTER_S)
    out: dict[str, Any] = {}
    for m in ALL_METHODS:
        clean_out: dict[str, FloatArray] = {}
        for label, rs in (("off", RECOVERY_OFF), ("on", RECOVERY_ON)):
            est = make_estimator(m, f, MHESettings(horizon=spec.horizon), rs)
            s = est.run(t, z)
            err = _tip_err(s.output, truth)
            wrong = (s.status == Status.OK) & (err > WRONG_SHARE * spec.length)
            out[f"{m} {label}"] = {
                "tip_mean_mm": float(np.nanmean(err[window]) * 1e3),
                "tip_max_mm": float(np.nanmax(err[window]) * 1e3),
                "ok_wrong": int(wrong.sum()),
            }
            if spec.group == "bad-start":  # the same settings on the clean recording
                clean_out[label] = est.run(t, clean).output  # counts from its reset
                out[f"{m} {label}"]["clean_fired"] = est.diagnostics.bad_starts
        if clean_out:
            diff = np.abs(clean_out["on"][:, :3] - clean_out["off"][:, :3])
            out[f"{m} on"]["clean_diff_mm"] = float(np.nanmax(diff) * 1e3)
    return out


def run_beyond(spec: BeyondSpec) -> dict[str, Any]:
    """Simulate ``spec``'s seed, corrupt it as its group says and score the estimators."""
    rec = simulate(
        "paper3d",
        duration=spec.duration,
        dt=spec.dt,
        length=spec.length,
        seed=spec.seed,
        noise_deg=spec.noise_deg,
    )
    t, z, truth = rec.t, np.asarray(rec.z, float), np.asarray(rec.truth, float)
    if spec.group in OUTLIER_GROUPS:
        methods = _outliers(spec, t, z, truth)
    elif spec.group == "coverage":
        f = _formulation(spec)
        consistent = simulate(
            "paper3d", duration=spec.duration, dt=spec.dt, length=spec.length,
            seed=spec.seed, noise_deg=spec.noise_deg, noise_model="tangent",
        )  # fmt: skip
        tilt_noise = {m: tip_calibration(f, m, t, z, truth[:, :3]) for m in ALL_METHODS}
        methods = {
            m: tip_calibration(f, m, consistent.t, consistent.z, truth[:, :3]) for m in ALL_METHODS
        }
        return {"spec": spec.as_dict(), "methods": methods, "methods_tilt_noise": tilt_noise}
    else:
        methods = _recovery(spec, t, z, truth)
        return {"spec": spec.as_dict(), "methods": methods, "recovery_on": recovery_flags()}
    return {"spec": spec.as_dict(), "methods": methods}


def recovery_flags(r: RecoverySettings = RECOVERY_ON) -> str:
    """``r`` as the command line's options, every one of them (the recovery groups'
    ``on``, saved with each of their trials so that a report names what its data were
    measured with; a setting that is off as its option's 0)."""
    options = ("gap_reset", "freeze", "bad_start", "reject_reset", "glitch", "drift_reset")
    return " ".join(f"--{name.replace('_', '-')} {getattr(r, name) or 0:g}" for name in options)


# --- plan and summary ---------------------------------------------------------------
def plan_beyond(
    seeds: int,
    duration: float,
    *,
    dt: float,
    length: float,
    noise_deg: float,
    horizon: int,
    recovery_duration: float,
    gap_s: float,
    robust_loss: MHELoss = "welsch",
) -> list[BeyondSpec]:
    """Every run of every group, ``seeds`` seeds each, the same seeds in every group
    (so the outlier groups pair with ``clean`` seed by seed)."""
    common: dict[str, Any] = {
        "dt": dt,
        "length": length,
        "noise_deg": noise_deg,
        "horizon": horizon,
        "robust_loss": robust_loss,
        "gap_s": gap_s,
    }
    specs = []
    for g in BEYOND_GROUPS:
        d = recovery_duration if g in RECOVERY_GROUPS else duration
        specs += [BeyondSpec(g, 110_000 + s, d, **common) for s in range(seeds)]
    return specs


def summarise_beyond(trials: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Per group and method: means with 95 % bootstrap intervals; the paired targets.

    ``outliers[group][method]``: tip error; ``targets[group]``: robust MHE / its clean
    error (ratio), robust MHE - EKF (diff, mm), robust / quadratic MHE on clean data.
    ``coverage[method][key]``; ``recovery[group][method]``: off, on and ``on - off`` of
    the mean tip error and of the ok-but-wrong samples."""
    by: dict[str, list[dict[str, Any]]] = {}
    for tr in sorted(trials, key=lambda x: x["spec"]["seed"]):
        by.setdefault(tr["spec"]["group"], []).append(tr)

    def col(group: str, method: str, key: str) -> list[float]:
        return [float(tr["methods"][method][key]) for tr in by.get(group, [])]

    out: dict[str, Any] = {"n_seeds": {g: len(v) for g, v in by.items()}}
    if all(g in by for g in OUTLIER_GROUPS):
        out["outliers"] = {
            g: {m: mean_ci(col(g, m, "tip_mean_mm")) for m in OUTLIER_METHODS}
            for g in OUTLIER_GROUPS
        }
        out["flags"] = {
            g: {
                k: int(sum(col(g, "mhe-robust", k)))
                for k in ("flagged", "flagged_corrupted", "corrupted")
            }
            for g in OUTLIER_GROUPS
        }
        clean = col("clean", "mhe-robust", "tip_mean_mm")
        targets: dict[str, Any] = {}
        for g in ("spikes", "bursts"):
            robust = col(g, "mhe-robust", "tip_mean_mm")
            targets[g] = {
                "robust_over_own_clean": paired(robust, clean, "ratio"),
                "robust_minus_ekf_mm": paired(robust, col(g, "ekf", "tip_mean_mm"), "diff"),
                "ekf_over_own_clean": paired(
                    col(g, "ekf", "tip_mean_mm"), col("clean", "ekf", "tip_mean_mm"), "ratio"
                ),
            }
        targets["clean"] = {
            "robust_over_l2": paired(clean, col("clean", "mhe-l2", "tip_mean_mm"), "ratio")
        }
        out["targets"] = targets
    if "coverage" in by:
        keys = ("coverage_x", "coverage_y", "coverage_z", "coverage_3d", "nees_per_dof")
        out["coverage"] = {
            m: {k: mean_ci(col("coverage", m, k)) for k in (*keys, "tip_mean_mm")}
            for m in ALL_METHODS
        }
        tilt = [tr["methods_tilt_noise"] for tr in by["coverage"] if "methods_tilt_noise" in tr]
        if tilt:
            out["coverage_tilt_noise"] = {
                m: {k: mean_ci([float(x[m][k]) for x in tilt]) for k in (*keys, "tip_mean_mm")}
                for m in ALL_METHODS
            }
    rec: dict[str, Any] = {}
    for g in RECOVERY_GROUPS:
        if g not in by:
            continue
        rec[g] = {}
        for m in ALL_METHODS:
            entry: dict[str, Any] = {}
            for key in ("tip_mean_mm", "tip_max_mm", "ok_wrong"):
                off, on = col(g, f"{m} off", key), col(g, f"{m} on", key)
                entry[key] = {
                    "off": mean_ci(off),
                    "on": mean_ci(on),
                    "on_minus_off": paired(on, off, "diff"),
                }
            if g == "bad-start":
                entry["clean_fired"] = int(sum(col(g, f"{m} on", "clean_fired")))
                entry["clean_diff_mm"] = max(col(g, f"{m} on", "clean_diff_mm"))
            rec[g][m] = entry
    if rec:
        out["recovery"] = rec
    return out
