"""Robust MHE against outliers: Monte Carlo on ``paper3d``, paired against the EKF.

Every seed simulates ``paper3d`` (20 s at 20 Hz, 2 deg noise, one 0.2 m section) and
runs the EKF and the fast MHE (N = 30) with the l2, Huber and Cauchy losses (default
scales) on the same three versions of the data, with the same model, Q and R:

* ``clean``: no outliers;
* ``spikes``: 2 % of the samples get an isolated (never adjacent) spike of +-30 deg on
  roll and on pitch (independent signs);
* ``bursts``: round(1 % of the samples) bursts of 5 consecutive samples, each burst
  one +-30 deg offset on roll and pitch (independent signs), not overlapping.

Corrupted readings are what a sensor reports for the offset orientation
(``model.imu.as_sensor_reads``); ``--corruption clipped`` clips their pitch at +-90 deg
and wraps their roll instead (the tables of docs/robust.md's first study, with
``--no-second-start``: the robust MHE without its second start). The score is the mean
tip error over the recording (mm). Intervals are 95 % percentile
bootstrap over seeds, paired (the same resampled seeds for both sides).

    python tools/outlier_study.py                   # 50 seeds, writes docs/robust_study.json
    python tools/outlier_study.py --seeds 5 --out /tmp/quick.json
    python tools/outlier_study.py efficiency        # the default loss scales
    python tools/outlier_study.py --corruption clipped --no-second-start --cauchy-scale 2.0
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import integrate, optimize, stats

import continuum_mhe._core as _core
from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.estimators.loss import LOSS_CODES
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.model.imu import wrap_angle
from continuum_mhe.reproduce import beyond
from continuum_mhe.settings import DEFAULT_LOSS_SCALE
from continuum_mhe.simulation.scenarios import simulate

METHODS = ("ekf", "mhe-l2", "mhe-huber", "mhe-cauchy")
CONDITIONS = ("clean", "spikes", "bursts")
SPIKE_DEG = 30.0
SPIKE_FRACTION = 0.02
BURST_FRACTION = 0.01
BURST_LENGTH = 5


# --- corruption (the package's, so this study and `reproduce` corrupt alike) -----------------
def spikes(z: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Isolated spikes on ``SPIKE_FRACTION`` of the samples; returns ``(z, indices)``."""
    out, mask = beyond.spikes(z, _spec("spikes", seed))
    return out, np.flatnonzero(mask)


def bursts(z: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``round(BURST_FRACTION n)`` bursts of ``BURST_LENGTH`` samples, each one offset."""
    out, mask = beyond.bursts(z, _spec("bursts", seed))
    return out, np.flatnonzero(mask)


def _spec(group: str, seed: int) -> beyond.BeyondSpec:
    return beyond.BeyondSpec(
        group,  # type: ignore[arg-type]
        seed,
        20.0,
        spike_deg=SPIKE_DEG,
        spike_fraction=SPIKE_FRACTION,
        burst_fraction=BURST_FRACTION,
        burst_length=BURST_LENGTH,
    )


# --- runs ------------------------------------------------------------------------------------
def run_seed(seed: int, horizon: int, scales: dict[str, float | None]) -> dict[str, dict]:
    rec = simulate("paper3d", duration=20.0, dt=0.05, noise_deg=2.0, seed=seed)
    f = make_formulation("bend")
    data = {"clean": (rec.z, np.zeros(0, dtype=int))}
    data["spikes"] = spikes(rec.z, seed)
    data["bursts"] = bursts(rec.z, seed)
    out: dict[str, dict] = {}
    for cond, (z, idx) in data.items():
        out[cond] = {}
        for m in METHODS:
            if m == "ekf":
                est = make_estimator("ekf", f)
            else:
                loss = m.split("-")[1]
                mhe = MHESettings(horizon=horizon, loss=loss, loss_scale=scales.get(loss))  # type: ignore[arg-type]
                est = make_estimator("mhe", f, mhe)
            t0 = time.perf_counter()
            s = est.run(rec.t, z)
            wall = time.perf_counter() - t0
            met = compute_metrics(s.output, rec.truth, rec.length)
            flagged = np.zeros(len(rec.t), dtype=bool) if s.outlier is None else s.outlier
            corrupted = np.zeros(len(rec.t), dtype=bool)
            corrupted[idx] = True
            out[cond][m] = {
                "tip_mean_mm": met.tip_mean_mm,
                "tip_max_mm": met.tip_max_mm,
                "flagged": int(flagged.sum()),
                "flagged_corrupted": int((flagged & corrupted).sum()),
                "corrupted": int(corrupted.sum()),
                "fallbacks": int(np.sum(s.status != "ok")),
                "ms_per_step": 1e3 * wall / len(rec.t),
            }
    return out


# --- statistics ------------------------------------------------------------------------------
def paired(a: np.ndarray, b: np.ndarray, kind: str) -> dict[str, float]:
    """``mean(a) / mean(b)`` (``ratio``) or ``mean(a - b)`` (``diff``) with a 95 %
    paired percentile-bootstrap interval over seeds (the package's)."""
    return beyond.paired(a, b, kind)  # type: ignore[arg-type]


def summarise(results: list[dict[str, dict]]) -> dict[str, dict]:
    def col(cond: str, m: str) -> np.ndarray:
        return np.array([r[cond][m]["tip_mean_mm"] for r in results])

    summary: dict[str, dict] = {"mean_mm": {}, "targets": {}, "flags": {}, "ms_per_step": {}}
    for cond in CONDITIONS:
        summary["mean_mm"][cond] = {m: float(col(cond, m).mean()) for m in METHODS}
        summary["flags"][cond] = {
            m: {
                k: int(sum(r[cond][m][k] for r in results))
                for k in ("flagged", "flagged_corrupted", "corrupted", "fallbacks")
            }
            for m in METHODS
        }
        summary["ms_per_step"][cond] = {
            m: float(np.median([r[cond][m]["ms_per_step"] for r in results])) for m in METHODS
        }
    for m in METHODS:
        t: dict[str, dict] = {}
        for cond in ("spikes", "bursts"):
            own = paired(col(cond, m), col("clean", m), "ratio")
            ekf = paired(col(cond, m), col(cond, "ekf"), "diff")
            t[cond] = {
                "ratio_to_own_clean": own,
                "ratio_met": own["hi"] <= 1.1,
                "minus_ekf_mm": ekf,
                "below_ekf_met": ekf["hi"] < 0.0,
            }
        clean = paired(col("clean", m), col("clean", "mhe-l2"), "ratio")
        t["clean"] = {"ratio_to_l2_mhe": clean, "within_2pct_met": clean["hi"] <= 1.02}
        summary["targets"][m] = t
    return summary


def print_table(summary: dict[str, dict], n: int) -> None:
    print(f"\nmean tip error, mm ({n} seeds)")
    print("| condition | " + " | ".join(METHODS) + " |")
    print("|---|" + "---:|" * len(METHODS))
    for cond in CONDITIONS:
        vals = " | ".join(f"{summary['mean_mm'][cond][m]:.2f}" for m in METHODS)
        print(f"| {cond} | {vals} |")
    print("\ntargets (ratio or difference [95 % paired bootstrap interval], verdict)")
    for m in METHODS:
        t = summary["targets"][m]
        for cond in ("spikes", "bursts"):
            r, d = t[cond]["ratio_to_own_clean"], t[cond]["minus_ekf_mm"]
            print(
                f"{m:11s} {cond:6s}: / own clean {r['value']:.3f} [{r['lo']:.3f}, "
                f"{r['hi']:.3f}] {'met' if t[cond]['ratio_met'] else 'NOT met'}; - EKF "
                f"{d['value']:+.3f} mm [{d['lo']:+.3f}, {d['hi']:+.3f}] "
                f"{'met' if t[cond]['below_ekf_met'] else 'NOT met'}"
            )
        c = t["clean"]["ratio_to_l2_mhe"]
        print(
            f"{m:11s} clean : / l2 MHE {c['value']:.4f} [{c['lo']:.4f}, {c['hi']:.4f}] "
            f"{'met' if t['clean']['within_2pct_met'] else 'NOT met'}"
        )
    print("\nflags (flagged, of them corrupted, corrupted samples; non-ok statuses)")
    for cond in CONDITIONS:
        for m in METHODS[2:]:
            fl = summary["flags"][cond][m]
            print(
                f"{cond:6s} {m:11s}: {fl['flagged']} flagged, {fl['flagged_corrupted']} of them "
                f"corrupted, {fl['corrupted']} corrupted; {fl['fallbacks']} non-ok"
            )


# --- the default scales ----------------------------------------------------------------------
def efficiency(loss: str, scale: float, p: int) -> float:
    """Asymptotic efficiency on Gaussian noise of the location M-estimator of a
    ``p``-component block with the loss ``1/2 rho(|r|^2)`` (relative to least squares):
    ``(E[psi'] + (p-1) E[psi/r])^2 / (p E[psi^2])`` with ``psi(r) = r rho'(r^2)``."""
    code = LOSS_CODES[loss]

    def expect(g) -> float:
        return integrate.quad(lambda r: g(r) * stats.chi.pdf(r, p), 0, np.inf, limit=200)[0]

    def w(r: float) -> tuple[float, float]:
        _, d1, d2 = _core.rho_derivatives(code, scale, r * r)
        return d1, d2

    a = expect(lambda r: w(r)[0] + 2 * r * r * w(r)[1] + (p - 1) * w(r)[0])
    b = expect(lambda r: (r * w(r)[0]) ** 2)
    return a * a / (p * b)


def print_efficiency() -> None:
    for p in (1, 2):
        for loss in ("huber", "cauchy", "welsch"):
            k95 = optimize.brentq(lambda c, ls=loss, k=p: efficiency(ls, c, k) - 0.95, 0.5, 10)
            print(f"{loss:6s} p={p}: 95 % efficiency at scale {k95:.3f}")
    for loss, scale in DEFAULT_LOSS_SCALE.items():
        if loss != "l2":
            print(f"{loss:6s} default {scale:g}: efficiency {efficiency(loss, scale, 2):.3f} (p=2)")


def clipped_reads(z: np.ndarray) -> np.ndarray:
    """Offset readings ``(n, 2)`` (roll, pitch, rad) with the pitch clipped at +-90 deg and
    the roll wrapped: the corruption of docs/robust.md's first studies, where a pitch
    offset near 90 deg becomes a smaller fault at gimbal lock than the one stated."""
    out = np.array(z, dtype=float)
    out[:, 0] = wrap_angle(out[:, 0])
    out[:, 1] = np.clip(out[:, 1], -np.pi / 2, np.pi / 2)
    return out


def apply_study_options(corruption: str, second_start: bool) -> None:
    """The corruption of ``reproduce``'s outlier groups (``sensor``, as
    ``model.imu.as_sensor_reads``, or ``clipped``: :func:`clipped_reads`) and, without
    ``second_start``, every MHE made from here on without its second start."""
    if corruption == "clipped":
        beyond.as_sensor_reads = clipped_reads  # type: ignore[assignment]
    if not second_start:
        from continuum_mhe.estimators import mhe

        mhe.MovingHorizonInference._second_start = lambda self: None  # type: ignore[assignment,method-assign,return-value]


def add_study_options(p: argparse.ArgumentParser) -> None:
    """``--corruption`` and ``--no-second-start`` (:func:`apply_study_options`)."""
    p.add_argument("--corruption", choices=("sensor", "clipped"), default="sensor")
    p.add_argument("--no-second-start", action="store_true")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("what", nargs="?", default="study", choices=("study", "efficiency"))
    p.add_argument("--seeds", type=int, default=50)
    p.add_argument("--horizon", type=int, default=30)
    p.add_argument("--huber-scale", type=float, default=None)
    p.add_argument("--cauchy-scale", type=float, default=None)
    p.add_argument("--out", default=str(Path(__file__).parents[1] / "docs" / "robust_study.json"))
    add_study_options(p)
    args = p.parse_args()
    apply_study_options(args.corruption, not args.no_second_start)
    if args.what == "efficiency":
        print_efficiency()
        return
    warnings.simplefilter("ignore")
    scales = {"huber": args.huber_scale, "cauchy": args.cauchy_scale}
    results = []
    for seed in range(args.seeds):
        results.append(run_seed(seed, args.horizon, scales))
        print(f"seed {seed} done", file=sys.stderr, flush=True)
    summary = summarise(results)
    print_table(summary, len(results))
    cfg = {"seeds": args.seeds, "horizon": args.horizon, "scales": scales}
    Path(args.out).write_text(
        json.dumps({"config": cfg, "summary": summary, "per_seed": results}, indent=1) + "\n"
    )
    print(f"\nwrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
