"""How many SQP iterations the fast MHE's windows would take from better starts.

For a robot of ``K`` sections (``tools/sqp_iterations.py``'s recordings: ``paper3d`` for
one, ``spatial`` on ``K`` sections of ``0.3/K`` m with a tilt IMU at each end), N = 30,
the estimator runs sample by sample; each full window is solved again from its own start
(the previous answer shifted, the newest node predicted) and from starts that take
parts of the window's converged answer:

* ``newest angles``: the newest node's angles (its rates as predicted);
* ``newest node``: the newest node whole;
* ``every angle``: every node's angles (the rates as started).

and the count of windows by SQP iterations is printed for each. Two iterations are the
fewest a window can certify in (``docs/fast-solver.md``)::

    python tools/warm_start_oracle.py 1
    python tools/warm_start_oracle.py 3
"""

from __future__ import annotations

import argparse
import collections

import numpy as np
from sections_ratio import full_windows, sections_case

from continuum_mhe.estimators import fast as fm
from continuum_mhe.settings import MHESettings

N = 30


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sections", type=int, choices=(1, 2, 3))
    p.add_argument("--duration", type=float, default=20.0, help="s (default 20)")
    a = p.parse_args()
    f, rec = sections_case(a.sections, a.duration)
    angles = [i for i, name in enumerate(f.state_names) if not name.endswith("_dot")]
    model, options, windows = full_windows(f, rec, MHESettings(horizon=N, solver="fast"))
    counts: dict[str, list[int]] = collections.defaultdict(list)
    for problem, X0, lam0 in windows:
        answer = fm.solve_window(model, problem, X0, options, lam0)
        starts = {"own start": X0}
        starts["newest angles"] = X0.copy()
        starts["newest angles"][-1, angles] = answer.X[-1, angles]
        starts["newest node"] = X0.copy()
        starts["newest node"][-1] = answer.X[-1]
        starts["every angle"] = X0.copy()
        starts["every angle"][:, angles] = answer.X[:, angles]
        for name, start in starts.items():
            counts[name].append(fm.solve_window(model, problem, start, options, lam0).iterations)
    for name, its in counts.items():
        tally = dict(sorted(collections.Counter(its).items()))
        print(f"{name:>14}: {tally}, mean {np.mean(its):.2f}")


if __name__ == "__main__":
    main()
