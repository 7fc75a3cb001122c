"""Why the robust MHE loses on bursts: its tip error profiled around each burst.

Every seed of the ``bursts`` group of ``reproduce``'s beyond-the-paper section
(``paper3d``, 20 s at 20 Hz, 2 deg noise, 1 % of the samples start a burst of 5
samples with one +-30 deg offset on roll and pitch) is run twice by the same robust MHE
(N = 30), on the clean and on the corrupted data, and the extra tip error is split by
the sample's offset from the start of the nearest earlier burst (samples 0-4: during
the burst; 5-29: after it, the burst still in the window; 30-34: the burst leaving the
window into the arrival prior). At every sample near a burst the same window problem
is also solved from the clean run's trajectory (a start that never saw the burst):
when that reaches a lower window cost, the estimator sat in a local minimum.

With ``--mc`` it runs instead the outlier groups (clean, spikes, bursts) of
``reproduce``'s beyond-the-paper section exactly as ``reproduce`` does
(``plan_beyond``/``run_beyond``/``summarise_beyond``, the full configuration's seeds),
with the loss's scale, the second start and the reject reset as given
(``--no-reject-reset``: the robust MHE without ``RecoverySettings.reject_reset``), and
prints the targets:

    python tools/burst_study.py                       # 10 seeds, Cauchy, default scale
    python tools/burst_study.py --seeds 5 --scale 1.0 --no-second-start
    python tools/burst_study.py --mc --seeds 50 --scale 2.0 --no-second-start
    python tools/burst_study.py --mc --seeds 50 --loss welsch --scale 3.0
    python tools/burst_study.py --mc --seeds 50 --loss welsch --no-reject-reset
    python tools/burst_study.py --mc --seeds 50 --loss welsch --offset-deg 10
    python tools/burst_study.py --oracle --seeds 50   # burst readings dropped, l2 MHE

With ``--oracle`` it runs the quadratic MHE on each seed's clean data and on the same
data with the burst readings dropped (NaN): what an estimator that knew which readings
were corrupted would lose.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from outlier_study import add_study_options, apply_study_options

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import window_cost
from continuum_mhe.reproduce import beyond
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate

SEGMENTS = (("during 0-4", 0, 5), ("after 5-29", 5, 30), ("leaving 30-34", 30, 35))


def offsets(mask: np.ndarray, span: int) -> np.ndarray:
    """Per sample: offset from the latest burst start at most ``span`` back (-1 if none)."""
    starts = np.flatnonzero(mask & ~np.r_[False, mask[:-1]])
    rel = np.full(len(mask), -1)
    for s in starts:
        rel[s : s + span] = np.arange(min(span, len(mask) - s))
    return rel


def run_seed(seed: int, args: argparse.Namespace) -> dict[str, np.ndarray]:
    spec = beyond.BeyondSpec("bursts", 110_000 + seed, args.duration, robust_loss=args.loss)
    rec = simulate("paper3d", duration=spec.duration, dt=spec.dt, length=spec.length,
                   seed=spec.seed, noise_deg=spec.noise_deg)  # fmt: skip
    t, z, truth = rec.t, np.asarray(rec.z, float), np.asarray(rec.truth, float)
    zb, mask = beyond.bursts(z, spec)
    f = beyond._formulation(spec)
    ms = MHESettings(horizon=spec.horizon, loss=args.loss, loss_scale=args.scale)
    on_burst, on_clean = make_estimator("mhe", f, ms), make_estimator("mhe", f, ms)
    window, clean_window = on_burst.inference, on_clean.inference  # the MHEs' window solvers
    on_burst.reset()
    on_clean.reset()
    rel = offsets(mask, 40)
    n = len(t)
    eb, ec, lower = np.zeros(n), np.zeros(n), np.zeros(n, dtype=bool)
    for i in range(n):
        a = on_burst.step(Measurement(float(t[i]), zb[i]))
        c = on_clean.step(Measurement(float(t[i]), z[i]))
        eb[i] = np.linalg.norm(a.output[:3] - truth[i, :3]) * 1e3
        ec[i] = np.linalg.norm(c.output[:3] - truth[i, :3]) * 1e3
        if rel[i] < 0 or i < spec.horizon:
            continue
        p = window.window_problem()  # type: ignore[attr-defined]
        kept = window._lam  # type: ignore[attr-defined]
        X2, _ = window._solve(p, clean_window._X.copy())  # type: ignore[attr-defined]
        window._lam = kept  # type: ignore[attr-defined]
        model = window._fast  # type: ignore[attr-defined]
        j1, j2 = window_cost(model, p, window._X), window_cost(model, p, X2)  # type: ignore[attr-defined]
        lower[i] = j2 < j1 - 1e-6 * abs(j1)
    return {"eb": eb, "ec": ec, "rel": rel, "lower": lower}


def monte_carlo(args: argparse.Namespace) -> None:
    """The outlier groups of ``reproduce``'s beyond section; prints the targets."""
    from continuum_mhe import settings
    from continuum_mhe.reproduce.experiments import FULL

    if args.scale is not None:
        settings.DEFAULT_LOSS_SCALE[args.loss] = args.scale
    if args.no_reject_reset:  # every estimator of the outlier groups without it
        beyond.RECOVERY_OUTLIERS = dataclasses.replace(beyond.RECOVERY_OUTLIERS, reject_reset=None)
    c = FULL
    specs = beyond.plan_beyond(args.seeds, c.beyond_duration, dt=c.dt, length=c.length,
                               noise_deg=c.noise_deg, horizon=c.horizon,
                               recovery_duration=c.beyond_recovery_duration,
                               gap_s=c.beyond_gap_s, robust_loss=args.loss)  # fmt: skip
    if args.offset_deg is not None:
        specs = [dataclasses.replace(s, spike_deg=args.offset_deg) for s in specs]
    trials = [beyond.run_beyond(s) for s in specs if s.group in beyond.OUTLIER_GROUPS]
    s = beyond.summarise_beyond(trials)
    print(f"seeds {args.seeds}  {args.loss} scale {settings.DEFAULT_LOSS_SCALE[args.loss]}  "
          f"second start {'off' if args.no_second_start else 'on'}  "
          f"reject reset {'off' if args.no_reject_reset else 'on'}  "
          f"offset {specs[0].spike_deg:g} deg")  # fmt: skip
    for g, by in s["outliers"].items():
        print(f"  {g:7s} " + "  ".join(f"{m} {v['mean']:.3f}" for m, v in by.items()) + " mm")
    for g, targets in s["targets"].items():
        for k, v in targets.items():
            print(f"  {g:7s} {k:22s} {v['value']:.4f} [{v['lo']:.4f}, {v['hi']:.4f}]")


def oracle(args: argparse.Namespace) -> None:
    """The quadratic MHE told which readings the bursts corrupted (set to NaN, i.e.
    dropped out): the floor a robust cost can at best approach on these data."""
    runs = []
    for seed in range(args.seeds):
        spec = beyond.BeyondSpec("bursts", 110_000 + seed, args.duration)
        rec = simulate("paper3d", duration=spec.duration, dt=spec.dt, length=spec.length,
                       seed=spec.seed, noise_deg=spec.noise_deg)  # fmt: skip
        z, truth = np.asarray(rec.z, float), np.asarray(rec.truth, float)
        _, mask = beyond.bursts(z, spec)
        dropped = z.copy()
        dropped[mask] = np.nan
        f = beyond._formulation(spec)
        errs = []
        for data in (z, dropped):
            s = make_estimator("mhe", f, MHESettings(horizon=spec.horizon)).run(rec.t, data)
            errs.append(np.linalg.norm(s.output[:, :3] - truth[:, :3], axis=1) * 1e3)
        runs.append((errs[0], errs[1], offsets(mask, 40)))
    ec = np.concatenate([r[0] for r in runs])
    eo = np.concatenate([r[1] for r in runs])
    rel = np.concatenate([r[2] for r in runs])
    print(f"seeds {args.seeds}: quadratic MHE, burst readings dropped (the oracle)")
    print(f"mean tip error: clean {ec.mean():.3f} mm, bursts dropped {eo.mean():.3f} mm, "
          f"ratio {eo.mean() / ec.mean():.3f}")  # fmt: skip
    for k in range(12):
        sel = rel == k
        print(f"  offset {k:2d}  dropped {eo[sel].mean():6.2f}  clean {ec[sel].mean():6.2f} mm")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--duration", type=float, default=20.0)
    p.add_argument("--loss", default="cauchy")
    p.add_argument("--scale", type=float, default=None)
    p.add_argument("--mc", action="store_true", help="the reproduce outlier groups")
    p.add_argument(
        "--offset-deg",
        type=float,
        default=None,
        help="with --mc: spike and burst offset, deg (default: the config's 30)",
    )
    p.add_argument("--oracle", action="store_true", help="the l2 MHE, burst readings dropped")
    add_study_options(p)  # --corruption, --no-second-start
    p.add_argument(
        "--no-reject-reset",
        action="store_true",
        help="with --mc: the robust MHE without its reject reset",
    )
    args = p.parse_args()
    apply_study_options(args.corruption, not args.no_second_start)
    if args.oracle:
        oracle(args)
        return
    if args.mc:
        monte_carlo(args)
        return
    runs = [run_seed(s, args) for s in range(args.seeds)]
    eb = np.concatenate([r["eb"] for r in runs])
    ec = np.concatenate([r["ec"] for r in runs])
    rel = np.concatenate([r["rel"] for r in runs])
    lower = np.concatenate([r["lower"] for r in runs])
    excess = eb - ec
    print(f"seeds {args.seeds}  loss {args.loss} scale {args.scale or 'default'}  "
          f"second start {'off' if args.no_second_start else 'on'}")  # fmt: skip
    print(
        f"mean tip error: clean {ec.mean():.3f} mm, bursts {eb.mean():.3f} mm, "
        f"ratio {eb.mean() / ec.mean():.3f}; total excess {excess.sum():.0f} mm*samples"
    )
    for name, a, b in SEGMENTS:
        sel = (rel >= a) & (rel < b)
        print(f"  {name:14s} share of the excess {excess[sel].sum() / excess.sum():6.3f}")
    sel = rel < 0
    print(f"  {'elsewhere':14s} share of the excess {excess[sel].sum() / excess.sum():6.3f}")
    print(" offset  bursts  clean  (mm, mean)  lower cost from the clean run's start")
    for k in range(0, 36):
        sel = rel == k
        if sel.any():
            low = lower[sel].mean()
            print(f"  {k:4d} {eb[sel].mean():8.2f} {ec[sel].mean():6.2f}   {low:5.2f}")


if __name__ == "__main__":
    main()
