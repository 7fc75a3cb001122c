"""acados' SQP iterations on the MHE's windows with its multipliers shifted by one sample
(the benchmark's peer) and with acados' own previous ones, unshifted, in turn.

    python tools/peer_multipliers.py --acados DIR        # N = 30, an 8 s paper3d

Prints, for each variant, the mean SQP iterations over the full windows and their
histogram, the mean QP iterations (HPIPM's, summed over a window's SQP iterations), and
the median of acados' own time (``time_tot``, us).
"""

from __future__ import annotations

import argparse

import numpy as np

from continuum_mhe.benchmark import peers
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.scenarios import simulate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--acados", required=True, help="the folder comma-deps-acados is in")
    p.add_argument("--horizon", type=int, default=30)
    p.add_argument("--duration", type=float, default=8.0, help="s of paper3d")
    a = p.parse_args()
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=a.duration, noise_deg=2.0, seed=0)
    n = a.horizon
    windows = peers.record_windows(f, rec, n)
    acados = peers.find_acados(a.acados)
    if acados is None:
        raise SystemExit(f"no comma-deps-acados in {a.acados}")
    for shifted in (True, False, True, False):
        solver = peers.make_peer("acados", f, n, acados)
        if not shifted:  # acados' own last multipliers, as they are
            solver._set_shifted_duals = lambda: None  # type: ignore[attr-defined]
        X, iterations, qp_iterations, seconds = None, [], [], []
        try:
            for w in windows:
                assert w is not None
                X, _, t = peers.solve_window(solver, w, peers.shifted_guess(f, w, X))
                stats = solver.solver.get_stats("sqp_iter")  # type: ignore[attr-defined]
                iterations.append(int(np.asarray(stats).ravel()[0]))
                qp = solver.solver.get_stats("qp_iter")  # type: ignore[attr-defined]
                qp_iterations.append(float(np.sum(np.asarray(qp))))
                seconds.append(t)
        finally:
            solver.close()  # type: ignore[attr-defined]
        it = np.array(iterations[n:])
        print(
            f"{'shifted' if shifted else 'unshifted'}: {it.mean():.2f} SQP iterations a "
            f"full window (histogram {np.bincount(it).tolist()}), "
            f"{np.mean(qp_iterations[n:]):.1f} QP iterations, acados' own time "
            f"{np.median(seconds[n:]) * 1e6:.0f} us (median)"
        )


if __name__ == "__main__":
    main()
