"""How far ``ok`` and the standard deviations can be trusted on the two-section
Cosserat-rod recordings (data the PCC model did not generate), with the defaults and
recovery off (``RecoverySettings.off()``: no gap reset, freeze or bad-start check):
per method and recording, the tip error (mean / max, mm), the share of rows ``ok``,
the per-axis coverage of the 95 % interval (``|e_c| <= 1.96 std_c``) over the ``ok``
rows, the rows more than 20 mm off that are not ``ok``, the rows more than 50 mm off that are
``ok``, the largest model-error factor and the model error learned (in units of ``R``).

    python tools/ok_coverage_study.py [--rod NAME ...] [--cases raw tilt] [--methods ...]
    python tools/ok_coverage_study.py --folder src/continuum_mhe/data/tendon \
        --robot tendon-two-section --rod force-08 unloaded
    python tools/ok_coverage_study.py --reading-bias-deg 0   # no constant-error term
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.settings import NoiseSettings, RecoverySettings

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
Z95 = 1.959964


def study(
    folder: Path,
    name: str,
    case: str,
    method: str,
    robot_name: str,
    noise: NoiseSettings | None = None,
) -> dict[str, float]:
    """One recording, ``case`` ``raw`` (defaults) or ``tilt``, one method; ``noise``
    (None: the defaults) for the formulation."""
    # a tendon robot's recording estimated without its tensions: its PCC sections
    robot = dataclasses.replace(read_robot(robot_name), backbone=None, tendons=())
    data = load_input(
        folder / f"{name}_{case}.csv", InputOptions(), make_formulation("bend", robot, noise)
    )
    truth = read_state_table(folder / f"{name}_truth.csv").values[:, :3]
    est = make_estimator(method, data.formulation, MHESettings(), RecoverySettings.off())  # type: ignore[arg-type]
    s = est.run(data.t, data.z)
    err = s.output[:, :3] - truth
    dist = np.linalg.norm(err, axis=1) * 1e3
    std = np.asarray(s.output_std, dtype=float)[:, :3]
    ok = np.asarray(s.status) == "ok"
    cover = (np.abs(err) <= Z95 * std)[ok].mean(axis=0) if ok.any() else np.full(3, np.nan)
    return {
        "mean": float(np.nanmean(dist)),
        "max": float(np.nanmax(dist)),
        "ok": float(ok.mean()),
        "cx": float(cover[0]),
        "cy": float(cover[1]),
        "cz": float(cover[2]),
        "far20": float(np.mean(~ok[dist > 20])) if np.any(dist > 20) else np.nan,
        "ok50": int(np.sum(ok & (dist > 50))),
        "scale": float(est.diagnostics.max_noise_scale),
        "model_error": float(est.diagnostics.model_error),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = sorted(q.name[: -len("_info.json")] for q in DATA.glob("*_info.json"))
    p.add_argument("--folder", type=Path, default=DATA)
    p.add_argument("--robot", default="two-section", help="robot file or shipped name")
    p.add_argument("--rod", nargs="+", default=names)
    p.add_argument("--cases", nargs="+", default=["raw"])
    p.add_argument("--methods", nargs="+", default=["ekf", "ukf", "mhe"])
    p.add_argument(
        "--reading-bias-deg",
        type=float,
        default=None,
        help="the readings' constant error (NoiseSettings.reading_bias_std, deg; "
        "default: the default's)",
    )
    args = p.parse_args()
    noise = (
        None
        if args.reading_bias_deg is None
        else NoiseSettings(reading_bias_std=math.radians(args.reading_bias_deg))
    )
    warnings.simplefilter("ignore")
    print(
        "recording case method: tip mean/max mm, ok share, ok coverage x/y/z, "
        ">20 mm not ok, ok >50 mm, scale, model error"
    )
    for name in args.rod:
        for case in args.cases:
            for m in args.methods:
                r = study(args.folder, name, case, m, args.robot, noise)
                print(
                    f"{name} {case} {m}: {r['mean']:.2f} / {r['max']:.1f}, ok {r['ok']:.2f}, "
                    f"cov {r['cx']:.3f} {r['cy']:.3f} {r['cz']:.3f}, "
                    f">20 not ok {r['far20']:.2f}, ok>50 {r['ok50']}, "
                    f"scale {r['scale']:.1f}, model error {r['model_error']:.2f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
