"""Calibration of the estimators' uncertainty: coverage of the 95 % intervals and NEES.

Monte Carlo on simulated data (``paper3d`` by default, one seed per noise draw), and the
Cosserat-rod recording (data the model did not generate) with a model-error term added
to R (``--model-error-deg``, as the CLI's option). For every method and sample:

* per-axis coverage: ``|e_c| <= 1.96 std_c`` for the tip's ``x, y, z``;
* 3D coverage: the tip error inside the 95 % ellipsoid of the tip covariance
  ``C = J P J^T``: ``e^T C^+ e <= chi2_k(0.95)`` with ``k`` the rank of ``C`` (2 for one
  section: the tip moves on a surface, its position is a function of two bends);
* NEES of the tip per degree of freedom, ``e^T C^+ e / k`` (1 when calibrated).

Usage::

    python tools/coverage_study.py --seeds 50 --json coverage.json
    python tools/coverage_study.py --seeds 50 --accel-psd 0.1
    python tools/coverage_study.py --rod --model-error-deg 0,2,4,6,8 --json rod.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from continuum_mhe.model.registry import make_formulation
from continuum_mhe.reproduce.beyond import tip_calibration
from continuum_mhe.settings import NoiseSettings
from continuum_mhe.simulation.scenarios import NOISE_MODELS, simulate


def summarise(rows: list[dict[str, float]]) -> dict[str, dict[str, float]]:
    """Mean over seeds with a 95 % percentile-bootstrap interval of the mean."""
    rng = np.random.default_rng(0)
    out = {}
    for key in rows[0]:
        v = np.array([r[key] for r in rows], dtype=float)
        boot = rng.choice(v, size=(2000, len(v))).mean(axis=1)
        out[key] = {
            "mean": float(v.mean()),
            "lo": float(np.percentile(boot, 2.5)),
            "hi": float(np.percentile(boot, 97.5)),
        }
    return out


def noise(args: argparse.Namespace, model_error_deg: float) -> NoiseSettings:
    """The estimators' noise: ``--noise-deg`` and the model error in quadrature in R."""
    std = math.radians(math.hypot(args.noise_deg, model_error_deg))
    return NoiseSettings(measurement_std=std, bend_accel_psd=args.accel_psd)


def monte_carlo(args: argparse.Namespace) -> dict[str, object]:
    f = make_formulation("bend", noise=noise(args, 0.0))
    per: dict[str, list[dict[str, float]]] = {m: [] for m in args.methods}
    for seed in range(args.seeds):
        rec = simulate(
            args.scenario, duration=args.duration, seed=seed, noise_deg=args.noise_deg,
            noise_model=args.noise_model,
        )  # fmt: skip
        for m in args.methods:
            per[m].append(tip_calibration(f, m, rec.t, rec.z, rec.truth[:, :3]))
        print(f"seed {seed} done", file=sys.stderr)
    return {m: {"summary": summarise(rows), "seeds": rows} for m, rows in per.items()}


def rod(args: argparse.Namespace) -> dict[str, object]:
    from continuum_mhe.io.csv_files import read_measurements
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.cosserat import default_data_path

    path = default_data_path()
    meas = read_measurements(path)
    t, z = meas.t, meas.z
    table = read_state_table(path, ("x_true", "y_true", "z_true"))
    tip = np.column_stack([table.column(c) for c in ("x_true", "y_true", "z_true")])
    out: dict[str, object] = {}
    for me in args.model_error_deg:
        f = make_formulation("bend", noise=noise(args, me))
        out[f"{me:g}"] = {m: tip_calibration(f, m, t, z, tip) for m in args.methods}
        print(f"model error {me:g} deg done", file=sys.stderr)
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=50)
    p.add_argument("--scenario", default="paper3d")
    p.add_argument("--duration", type=float, default=20.0)
    p.add_argument("--noise-deg", type=float, default=2.0)
    p.add_argument("--accel-psd", type=float, default=NoiseSettings.bend_accel_psd)
    p.add_argument(
        "--noise-model",
        choices=NOISE_MODELS,
        default="tangent",
        help="tangent: isotropic on the tangent plane, as R models it (default); tilt: "
        "the paper's, independent on roll and pitch",
    )
    p.add_argument("--methods", type=lambda s: s.split(","), default=["mhe", "ekf", "ukf"])
    p.add_argument("--rod", action="store_true", help="the Cosserat-rod recording instead")
    p.add_argument(
        "--model-error-deg",
        type=lambda s: [float(v) for v in s.split(",")],
        default=[0.0],
        help="with --rod: model-error terms to add to R, degrees (comma-separated)",
    )
    p.add_argument("--json", help="write the results here")
    args = p.parse_args()
    start = time.perf_counter()
    result = rod(args) if args.rod else monte_carlo(args)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
    if args.rod:
        for me, by_method in result.items():
            for m, r in by_method.items():  # type: ignore[attr-defined]
                print(
                    f"model error {me:>3} deg  {m}: coverage x {r['coverage_x']:.3f} "
                    f"y {r['coverage_y']:.3f} z {r['coverage_z']:.3f} 3D {r['coverage_3d']:.3f}"
                    f"  NEES/dof {r['nees_per_dof']:.2f}  tip {r['tip_mean_mm']:.2f} mm"
                )
    else:
        for m, res in result.items():
            s = res["summary"]  # type: ignore[index]
            cells = "  ".join(
                f"{k} {s[k]['mean']:.3f} [{s[k]['lo']:.3f}, {s[k]['hi']:.3f}]"
                for k in ("coverage_x", "coverage_y", "coverage_z", "coverage_3d", "nees_per_dof")
            )
            print(f"{m}: {cells}  tip {s['tip_mean_mm']['mean']:.2f} mm")
    print(f"({time.perf_counter() - start:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
