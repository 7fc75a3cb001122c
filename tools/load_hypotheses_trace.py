"""The two load hypotheses of the tendon EKF (:mod:`continuum_mhe.estimators.
load_hypotheses`) on a generator recording, sample by sample: why the estimate follows
the one it follows. The estimator is the command line's (``make_estimator("ekf", f)``,
its sensor-health policy included), each step of :class:`LoadHypothesesInference`
watched from outside. Prints, per ``--every`` seconds (means over the interval): each
hypothesis' tip error (mm); the evidence for the robot free of load and the share of the
interval's samples whose estimate is the free-of-load one; the step's log-likelihood
difference, free of load minus loaded, and its parts: the IMU readings' (given the
tensions and the tip condition) split into the innovations' Mahalanobis term and the
log-determinant term, and the rest's (the tensions' and the tip condition's rows); the
loaded hypothesis' tip-force error and its standard deviation (N, norms) and the
normalised innovation squared of the IMU rows, given the other rows, of each hypothesis
(6 where consistent, one raw IMU; 12 with two); the smallest singular value over the
interval of each hypothesis' tip condition's Jacobian in the base curvature (about 1 for
the straight robot; near 0 near buckling, where the tip condition's predicted spread
narrows). Then
one JSON line over the samples after ``--skip``.

``--whole``: the hypotheses weighed by the whole measurement's density (the tensions'
and the tip condition's rows too) instead of the IMU readings' given the rest.

    python tools/load_hypotheses_trace.py DIR SCENARIO [--imu direct|tilt]
        [--tip-imu-only] [--set NAME=VALUE] [--every S] [--skip S] [--csv FILE] [--whole]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from tendon_study import _table, imu_readings, study_formulation

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
from continuum_mhe.estimators.load_hypotheses import LoadHypothesesInference
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.tensions import read_tensions


def _log_density(r: np.ndarray, S: np.ndarray) -> tuple[float, float]:
    """``(-r^T S^-1 r / 2, -log|S| / 2)``."""
    L = np.linalg.cholesky(S)
    w = np.linalg.solve(L, r)
    return -0.5 * float(w @ w), -float(np.sum(np.log(np.diag(L))))


def _parts(
    hyp: CompiledExtendedKalmanInference, before: tuple[Any, ...], m: Measurement, imu: np.ndarray
) -> tuple[float, float, float, float, float] | None:
    """The step's log-likelihood from the hypothesis' state ``before`` it, split: (the
    IMU rows' Mahalanobis and log-determinant terms given the other rows, the other
    rows' log-density, the IMU rows' normalised innovation squared given the other
    rows), then the smallest singular value of the tip condition's Jacobian in the base
    curvature (``eq_kx, eq_ky, eq_kz`` in ``k0x, k0y, k0z``) at the predicted state; None
    where it had no state."""
    x, P, t_prev, z_prev = before
    if x is None or z_prev is None:
        return None
    f = hyp.formulation
    dt = m.t - t_prev
    u = f.inputs(z_prev, m.z, dt)
    xp, F, _, _ = hyp._node.evaluate(x, u, dt)
    Pp = F @ P @ F.T + hyp._q(dt)[0]
    mask = f.measurement_mask(m.z)
    zf = np.where(np.isfinite(m.z), m.z, 0.0)
    _, _, H, r = hyp._node.evaluate(xp, np.zeros(f.nu), 0.0, zf, mask)
    S = H @ Pp @ H.T + hyp._R
    rows = np.flatnonzero(mask)
    b = np.setdiff1d(rows, imu)
    q_all, d_all = _log_density(r[rows], S[np.ix_(rows, rows)])
    q_b, d_b = _log_density(r[b], S[np.ix_(b, b)])
    eq = [f.measurement_names.index(n) for n in ("eq_kx", "eq_ky", "eq_kz")]
    k0 = [f.state_names.index(n) for n in ("k0x", "k0y", "k0z")]
    sv = float(np.linalg.svd(H[np.ix_(eq, k0)], compute_uv=False)[-1])
    return q_all - q_b, d_all - d_b, q_b + d_b, -2.0 * (q_all - q_b), sv


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--imu", choices=("tilt", "direct"), default="direct")
    p.add_argument("--robot", default="tendon-two-section")
    p.add_argument("--tip-imu-only", action="store_true", help="use only the last IMU")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--every", type=float, default=0.5, help="s per printed line")
    p.add_argument("--skip", type=float, default=1.0)
    p.add_argument("--csv", type=Path, help="write the per-sample trace here")
    p.add_argument(
        "--whole", action="store_true",
        help="weigh the hypotheses by the whole measurement's density",
    )  # fmt: skip
    a = p.parse_args()
    options = InputOptions()
    f, used = study_formulation(a.robot, a.imu, a.tip_imu_only, 2.0, options, a.set)
    tensions = read_tensions(a.folder / f"{a.scenario}_tensions.csv", f.robot.n_tendons)
    t, z_imu = imu_readings(a.folder, a.scenario, a.imu, used)
    names, truth = _table(a.folder / f"{a.scenario}_truth.csv")
    z = np.array([f.measurement_row(zi, *tensions.at(ti)) for ti, zi in zip(t, z_imu)])
    imu_rows = np.arange(z_imu.shape[1])
    est = make_estimator("ekf", f)
    inf = est.inference
    assert isinstance(inf, LoadHypothesesInference)
    if a.whole:
        inf.loaded.likelihood_given = inf.unloaded.likelihood_given = ()
    cols = [o.name for o in f.outputs]
    tip = [cols.index(n) for n in ("x", "y", "z")]
    force = [cols.index(n) for n in ("fx", "fy", "fz")]
    true_tip = truth[:, [names.index(n) for n in ("x", "y", "z")]]
    true_force = truth[:, [names.index(n) for n in ("fx", "fy", "fz")]]
    index = {float(ti): i for i, ti in enumerate(t)}
    trace: list[list[float]] = []
    step = inf.infer

    def watched(m: Measurement) -> Any:
        hyps = (inf.loaded, inf.unloaded)
        before = [(h._x, h._P, h._t_prev, h._z_prev) for h in hyps]  # type: ignore[union-attr]
        out = step(m)
        i = index.get(float(m.t))
        if i is None:
            return out
        parts = [_parts(h, b, m, imu_rows) for h, b in zip(hyps, before)]  # type: ignore[arg-type]
        row = [m.t, inf.evidence, float(inf.unloaded_chosen)]
        for h in hyps:
            x = h._x  # type: ignore[union-attr]
            e = np.linalg.norm(h.output(x)[tip] - true_tip[i]) if x is not None else math.nan
            row.append(e)
        xl, Pl = inf.loaded._x, inf.loaded._P  # type: ignore[union-attr]
        if xl is not None and Pl is not None:
            yl = inf.loaded.output(xl)
            sl = inf.loaded.output_std(xl, Pl)
            row += [np.linalg.norm(yl[force] - true_force[i]), np.linalg.norm(sl[force])]
        else:
            row += [math.nan, math.nan]
        for pt in parts:
            row += list(pt) if pt is not None else [math.nan] * 5
        trace.append(row)
        return out

    inf.infer = watched  # type: ignore[method-assign]
    series = est.run(t, z)
    r = np.array(trace)
    head = ("t,evidence,free,tip_loaded,tip_free,force_err,force_std,"
            "l_maha,l_logdet,l_rest,l_nis,l_sv,u_maha,u_logdet,u_rest,u_nis,u_sv")  # fmt: skip
    if a.csv is not None:
        np.savetxt(a.csv, r, delimiter=",", header=head, comments="")
    out = np.asarray(series.output, dtype=float)
    err = np.linalg.norm(out[:, tip] - true_tip, axis=1)
    print("   t  tipL  tipF   evid  free  dMaha dLogdet  dRest  |dF|  Fstd  nisL  nisF"
          "     svL    svF")  # fmt: skip
    for s0 in np.arange(0.0, t[-1] + 1e-9, a.every):
        w = (r[:, 0] >= s0) & (r[:, 0] < s0 + a.every)
        if not w.any():
            continue
        m_ = np.nanmean(r[w], axis=0)
        low = np.nanmin(r[w], axis=0)
        print(
            f"{s0:4.1f} {m_[3] * 1e3:5.2f} {m_[4] * 1e3:5.2f} {m_[1]:6.1f} {m_[2]:5.2f} "
            f"{m_[12] - m_[7]:6.2f} {m_[13] - m_[8]:7.2f} {m_[14] - m_[9]:6.2f} "
            f"{m_[5]:.3f} {m_[6]:.3f} {m_[10]:5.1f} {m_[15]:5.1f} {low[11]:7.1e} {low[16]:6.3f}"
        )
    keep = t >= a.skip
    statuses: dict[str, int] = {}
    for s in series.status:
        statuses[str(s)] = statuses.get(str(s), 0) + 1
    print(json.dumps({
        "scenario": a.scenario, "set": a.set, "whole": a.whole,
        "tip_mean_mm": round(float(np.nanmean(err[keep]) * 1e3), 2),
        "free_of_load_rows": inf.free_of_load_samples, "statuses": statuses,
    }))  # fmt: skip


if __name__ == "__main__":
    main()
