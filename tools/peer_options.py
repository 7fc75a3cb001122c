"""The CasADi peers' iterations on the MHE's windows, by option: fatrop's barrier start
(``mu_init``) and sqpmethod's line search (``max_iter_ls``), each warm-started from its
shifted answer as ``continuum-mhe benchmark`` runs it.

    python tools/peer_options.py                 # N = 30, a 20 s paper3d
    python tools/peer_options.py --horizon 100

Prints, for each variant, the mean and largest iterations over the full windows, the
windows not converged, and the largest output difference from the benchmark's own
setting. Iterations do not depend on the machine's speed or load.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from continuum_mhe.benchmark import peers
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.scenarios import simulate

#: Each variant: the peer, and its options over those the benchmark gives it (None: a
#: name the benchmark sets, left at the solver's default).
VARIANTS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("fatrop", "the benchmark's (mu_init 1e-6)", {}),
    ("fatrop", "mu_init at fatrop's default", {"mu_init": None}),
    ("fatrop", "mu_init 1e-4", {"mu_init": 1e-4}),
    ("fatrop", "mu_init 1e-8", {"mu_init": 1e-8}),
    ("sqp-hpipm", "the benchmark's (full steps)", {}),
    ("sqp-hpipm", "CasADi's default line search", {"max_iter_ls": None}),
)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--horizon", type=int, default=30)
    p.add_argument("--duration", type=float, default=20.0, help="s of paper3d")
    a = p.parse_args()
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=a.duration, dt=0.05, noise_deg=2.0, seed=0)
    n = a.horizon
    windows = [w for w in peers.record_windows(f, rec, n) if w is not None]
    reference: dict[str, np.ndarray] = {}
    for name, label, change in VARIANTS:
        solver = peers.CasadiPeer(f, n, name, compiled=False, options=change)  # interpreted
        X, iterations, failed, outputs = None, [], 0, []
        solver.reset()
        for w in windows:
            X, converged, _ = peers.solve_window(solver, w, peers.shifted_guess(f, w, X))
            iterations.append(int(solver.solver.stats()["iter_count"]))
            failed += not converged
            outputs.append(f.output(X[-1]))
        out = np.array(outputs)
        ref = reference.setdefault(name, out)
        full = np.array(iterations[n:])
        print(
            f"{name}, {label}: {full.mean():.2f} iterations a full window (at most "
            f"{full.max()}), {failed} of {len(windows)} not converged, "
            f"{np.abs(out - ref).max():.1e} from the benchmark's setting",
            flush=True,
        )


if __name__ == "__main__":
    main()
