"""The UKF's sigma-point spread (Van der Merwe's alpha) on the shipped two-section rod
recordings (PCC robot ``two-section``, raw and tilt, read as ``continuum-mhe estimate``
reads them): per recording and alpha, the mean and largest tip error (mm) against the
truth, and the estimator's restarts::

    python tools/ukf_alpha_study.py                 # alpha 0.5, 0.1, 0.02
    python tools/ukf_alpha_study.py --alphas 0.5 0.01
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from continuum_mhe.estimators.kalman import SigmaPointSettings, UnscentedKalmanFilter
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import open_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.registry import make_formulation

ROD = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
NAMES = ("planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--alphas", type=float, nargs="+", default=[0.5, 0.1, 0.02])
    a = p.parse_args()
    for name in NAMES:
        truth = read_state_table(ROD / f"{name}_truth.csv")
        for kind in ("raw", "tilt"):
            base = make_formulation("bend", read_robot("two-section"))
            with open_input(ROD / f"{name}_{kind}.csv", InputOptions(), base) as stream:
                f = stream.formulation
                blocks = list(stream.blocks)
            t = np.concatenate([b[0] for b in blocks])
            z = np.vstack([b[1] for b in blocks])
            rows = np.searchsorted(truth.t, t - 1e-9)
            tip = np.column_stack([truth.column(c)[rows] for c in "xyz"])
            cols = [o.name for o in f.outputs]
            cells = []
            for alpha in a.alphas:
                est = UnscentedKalmanFilter(f, SigmaPointSettings(alpha=alpha))
                out = np.asarray(est.run(t, z).output, dtype=float)
                err = np.linalg.norm(out[:, [cols.index(c) for c in "xyz"]] - tip, axis=1) * 1e3
                cells.append(
                    f"alpha {alpha:g}: {np.nanmean(err):.2f} / {np.nanmax(err):.0f} mm, "
                    f"{est.diagnostics.restarts} restarts"
                )
            print(f"{name} {kind}: " + "; ".join(cells), flush=True)


if __name__ == "__main__":
    main()
