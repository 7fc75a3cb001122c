"""The fast MHE's estimator step against the compiled EKF's, in one process.

The two ``continuum-mhe benchmark`` rows whose ratio the speed target compares (``fast`` and
``ekf-compiled``, with ``mhe-kernel`` and ``ekf-kernel`` beside them), timed as the
benchmark times them (:func:`~continuum_mhe.benchmark.harness._cheap_runs`, rounds in turn,
each sample's median over the rounds) on its 40 s ``paper3d`` recording, without IPOPT
and do-mpc, so that the ratio can be measured again in a few seconds::

    python tools/estimator_ratio.py          # N = 30, 5 rounds
    python tools/estimator_ratio.py 30 9

Prints the medians from sample N on (us) and ``fast / ekf-compiled``.
"""

from __future__ import annotations

import argparse

import numpy as np

from continuum_mhe.benchmark.harness import _cheap_runs, _interleaved
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.scenarios import simulate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("horizon", nargs="?", type=int, default=30, help="the window N (default 30)")
    p.add_argument("rounds", nargs="?", type=int, default=5, help="rounds, interleaved (default 5)")
    a = p.parse_args()
    horizon = a.horizon
    rounds = a.rounds
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=40, noise_deg=2.0, seed=0)
    runs = _cheap_runs(f, rec, horizon, ("fast", "mhe-kernel", "ekf-compiled", "ekf-kernel"))
    got = _interleaved(runs, rounds)
    med = {name: float(np.median(r[1][horizon:])) * 1e6 for name, r in got.items()}
    shown = ", ".join(f"{name} {us:.1f} us" for name, us in med.items())
    print(f"N = {horizon}: {shown}; fast / ekf-compiled {med['fast'] / med['ekf-compiled']:.2f}")


if __name__ == "__main__":
    main()
