"""Recovery from a bad start, a frozen sensor and a long gap: MHE, EKF and UKF.

Monte Carlo on ``paper3d`` (one noise seed per run, 2 deg, 20 s at 20 Hz), each case
with the recovery settings off (``RecoverySettings.off()``) and on (gap reset and
freeze at their defaults, the bad-start check off: ``--bad-start 0``):

* ``bad-start``: the first 0.5 s of readings are 60 deg off in roll and pitch (pitch
  kept inside +-85 deg), then correct. Reported: the mean tip error over the 2 s after
  the bad readings end, and ``settle_s``, the time from their end until the tip error
  stays within 1 mm of the same estimator's on the clean recording.
* ``freeze``: from t = 8 s the IMU repeats its reading for 3 s. Reported: the mean tip
  error from 8 s to 13 s (the freeze and 2 s after) and its max.
* ``gap-3s``, ``gap-10s``: no data from 5 s on for 3 s or 10 s. Reported: the mean tip
  error over the 2 s after.

For every case also ``ok_wrong``: the samples that say ``ok`` while the tip is more
than 20 mm (10 % of the length) wrong; the recovery settings exist to make these few.

Usage::

    python tools/recovery_study.py --seeds 20 --json recovery.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings, RecoverySettings
from continuum_mhe.simulation.scenarios import Recording, simulate

ON = RecoverySettings(bad_start=None)
OFF = RecoverySettings.off()
BAD_S, OFFSET = 0.5, math.radians(60.0)
FREEZE_T0, FREEZE_S = 8.0, 3.0
GAP_T0 = 5.0
SETTLED_M = 0.001
WRONG_M = 0.02


def bad_start(rec: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = rec.z.copy()
    bad = rec.t < BAD_S
    z[bad, 0] += OFFSET
    z[bad, 1] = np.clip(z[bad, 1] + OFFSET, -math.radians(85), math.radians(85))
    return rec.t, z, rec.truth


def freeze(rec: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = rec.z.copy()
    frozen = (rec.t >= FREEZE_T0) & (rec.t < FREEZE_T0 + FREEZE_S)
    z[frozen] = z[np.flatnonzero(frozen)[0]]
    return rec.t, z, rec.truth


def gap(seconds: float) -> Callable[[Recording], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    def make(rec: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        keep = (rec.t < GAP_T0) | (rec.t >= GAP_T0 + seconds)
        return rec.t[keep], rec.z[keep], rec.truth[keep]

    return make


CASES: dict[str, Callable[[Recording], tuple[np.ndarray, np.ndarray, np.ndarray]]] = {
    "bad-start": bad_start,
    "freeze": freeze,
    "gap-3s": gap(3.0),
    "gap-10s": gap(10.0),
}


def score(
    case: str, t: np.ndarray, tip_err: np.ndarray, clean_err: np.ndarray, status: np.ndarray
) -> dict[str, float]:
    """The case's numbers (mm, s) from the tip error (m) at times ``t``; ``clean_err``:
    the same estimator's error on the clean recording (bad start only)."""
    out = {"ok_wrong": float(np.sum((status == "ok") & (tip_err > WRONG_M)))}
    if case == "bad-start":
        after = (t >= BAD_S) & (t < BAD_S + 2.0)
        off = np.flatnonzero((t >= BAD_S) & (np.abs(tip_err - clean_err) >= SETTLED_M))
        settle = 0.0 if not len(off) else float(t[off[-1]] + (t[1] - t[0]) - BAD_S)
        return {**out, "mean_mm": float(tip_err[after].mean() * 1e3), "settle_s": settle}
    if case == "freeze":
        w = (t >= FREEZE_T0) & (t < FREEZE_T0 + FREEZE_S + 2.0)
    else:
        w = (t >= GAP_T0) & (t < t[np.flatnonzero(t >= GAP_T0)[0]] + 2.0)
    return {
        **out,
        "mean_mm": float(tip_err[w].mean() * 1e3),
        "max_mm": float(tip_err[w].max() * 1e3),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--methods", type=lambda s: s.split(","), default=["mhe", "ekf", "ukf"])
    p.add_argument("--json", help="write the per-seed results and the means here")
    args = p.parse_args()
    start = time.perf_counter()
    f = make_formulation("bend")
    rows: list[dict[str, object]] = []
    for seed in range(args.seeds):
        rec = simulate("paper3d", seed=seed)
        clean = {}
        for method in args.methods:
            s = make_estimator(method, f, MHESettings()).run(rec.t, rec.z)  # type: ignore[arg-type]
            clean[method] = np.linalg.norm(s.output[:, :3] - rec.truth[:, :3], axis=1)
        for case, make in CASES.items():
            t, z, truth = make(rec)
            for method in args.methods:
                for label, rs in (("off", OFF), ("on", ON)):
                    est = make_estimator(method, f, MHESettings(), rs)  # type: ignore[arg-type]
                    s = est.run(t, z)
                    err = np.linalg.norm(s.output[:, :3] - truth[:, :3], axis=1)
                    st = {str(k): int(v) for k, v in zip(*np.unique(s.status, return_counts=True))}
                    row = {"seed": seed, "case": case, "method": method, "recovery": label}
                    num = score(case, t, err, clean[method], s.status)
                    rows.append({**row, **num, "status": st})
        print(f"seed {seed} done", file=sys.stderr)
    means: dict[str, dict[str, float]] = {}
    for r in rows:
        key = f"{r['case']} {r['method']} recovery-{r['recovery']}"
        m = means.setdefault(key, {})
        for k, v in r.items():
            if isinstance(v, float):
                m[k] = m.get(k, 0.0) + v / args.seeds
    for key, m in means.items():
        print(f"{key:32s} " + "  ".join(f"{k} {v:.2f}" for k, v in m.items()))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"means": means, "runs": rows}, fh, indent=2)
    print(f"({time.perf_counter() - start:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
