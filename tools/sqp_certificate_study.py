"""Why the fast MHE's windows take a third SQP iteration, and how far its certified answers lie.

For a robot of ``K`` sections (``tools/sqp_iterations.py``'s recordings: ``paper3d`` for
one, ``spatial`` on ``K`` sections of ``0.3/K`` m with a tilt IMU at each end), N = 30,
the estimator runs sample by sample; each full window is solved again from its own start
with the default options (the certified answer), with the iteration limit 1, 2, 3 and no
certificate (the iterates ``X_1``, ``X_2``, ``X_3`` and the steps ``d_1``, ``d_2``,
``d_3`` of the QPs at ``X_0``, ``X_1``, ``X_2``), and iterated to 1e-13 (the converged
answer). All sizes are in the certificate's norm (``WindowModel.step_scale``). Printed:
the count of windows by iterations and the percentiles (10, 50, 90, 100) of the rate
``|d_2| / |d_1|^2``; over the windows that take three, the percentiles
(10, 50, 90, 100) of the step sizes, of the quadratic-rate estimate after the second step
``10 |d_2|^3 / |d_1|^2`` and of the true error of ``X_2`` (the answer the second step
would give), and the share of those windows whose ``X_2`` already lies within
``err_tol``; over all windows, the largest distance of a certified answer from the
converged one, the count beyond ``err_tol`` and those windows' rates::

    python tools/sqp_certificate_study.py 3
    python tools/sqp_certificate_study.py 2 --duration 100 --loss cauchy
"""

from __future__ import annotations

import argparse
import collections
from dataclasses import replace

import numpy as np
from sections_ratio import full_windows, sections_case

from continuum_mhe.estimators import fast as fm
from continuum_mhe.settings import MHE_LOSSES, MHESettings

N = 30


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sections", type=int, choices=(1, 2, 3))
    p.add_argument("--duration", type=float, default=20.0, help="s (default 20)")
    p.add_argument("--loss", choices=MHE_LOSSES, default="l2", help="default l2")
    a = p.parse_args()
    f, rec = sections_case(a.sections, a.duration)
    settings = MHESettings(horizon=N, solver="fast", loss=a.loss)
    model, options, windows = full_windows(f, rec, settings)
    scale = model.step_scale
    tight = replace(options, step_tol=1e-13, err_tol=1e-13, max_iter=200)
    bare = [replace(options, step_tol=1e-300, err_tol=1e-300, max_iter=j) for j in (1, 2, 3)]
    rows = []
    for problem, X0, lam0 in windows:
        answer = fm.solve_window(model, problem, X0, options, lam0)
        ref = fm.solve_window(model, problem, X0, tight, lam0)
        its = [fm.solve_window(model, problem, X0, o, lam0) for o in bare]
        err = [float(np.max(np.abs(r.X - ref.X) * scale)) for r in (answer, its[1])]
        rows.append([answer.iterations, *(r.step for r in its), *err])
    r = np.array(rows)
    tally = dict(sorted(collections.Counter(r[:, 0].astype(int).tolist()).items()))

    def pct(x: np.ndarray) -> str:
        return " ".join(f"{v:.1e}" for v in np.percentile(x, [10, 50, 90, 100]))

    print(f"{len(r)} full windows, by SQP iterations: {tally}, mean {r[:, 0].mean():.3f}")
    print(f"  the rate |d_2| / |d_1|^2, percentiles 10 50 90 100: {pct(r[:, 2] / r[:, 1] ** 2)}")
    three = r[r[:, 0] == 3]
    if len(three):
        d1, d2, d3, err2 = three[:, 1], three[:, 2], three[:, 3], three[:, 5]
        print(f"{len(three)} windows of three iterations, percentiles 10 50 90 100:")
        print(f"  |d_1| {pct(d1)}\n  |d_2| {pct(d2)}\n  |d_3| {pct(d3)}")
        print(f"  10 |d_2|^3 / |d_1|^2 {pct(10 * d2**3 / d1**2)}")
        print(f"  error of X_2 {pct(err2)}")
        print(f"  share with X_2 within err_tol: {np.mean(err2 <= options.err_tol):.3f}")
    far = r[:, 4] > options.err_tol
    print(f"certified answers: the farthest {r[:, 4].max():.2e} from the converged one, "
          f"{int(far.sum())} beyond err_tol {options.err_tol:g}")  # fmt: skip
    for n in sorted(set(r[far, 0].astype(int).tolist())):
        w = r[far & (r[:, 0] == n)]
        rates = ", ".join(
            f"|d_{j + 1}| / |d_{j}|^2 {np.min(w[:, j + 1] / w[:, j] ** 2):.2g} to "
            f"{np.max(w[:, j + 1] / w[:, j] ** 2):.2g}"
            for j in (1, 2)
        )
        print(f"  {len(w)} of them certified after {n} iterations: {rates}")


if __name__ == "__main__":
    main()
