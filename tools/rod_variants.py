"""Two-section rod recordings with motions the shipped ``rod2`` ones do not have, to
choose defaults on data nobody tuned to (docs/uncertainty.md, "Honest ``ok``"): each
motion simulated once (PyElastica) and sampled by the IMUs of several seeds (their
misalignments, biases and noise).

    python tools/rod_variants.py -o DIR                 # every variant, seeds 11 and 12
    python tools/rod_variants.py -o DIR --only spatial-m09 --seeds 11
    python tools/honesty_study.py --only a --rods DIR
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from continuum_mhe.simulation.cosserat_sections import (
    SectionRodSettings,
    simulate_sections,
    write_trajectory_recording,
)

#: name: (rod and actuation, scenario, duration in s)
VARIANTS: dict[str, tuple[SectionRodSettings, str, float]] = {
    "planar-s-m10": (SectionRodSettings(max_moment=0.10, period=5.0), "planar-s", 8.0),
    "spatial-m09": (SectionRodSettings(max_moment=0.09, period=5.0), "spatial", 8.0),
    "spatial-tendon-p5": (
        SectionRodSettings(drive="tendon", period=5.0, max_moment=0.10),
        "spatial",
        8.0,
    ),
    "spatial-torsion-m10": (
        SectionRodSettings(shear_ratio=5.0, sim_dt=5e-6, max_moment=0.10, period=5.0),
        "spatial",
        6.0,
    ),
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", type=Path, required=True, help="folder for the files")
    p.add_argument("--only", nargs="+", choices=sorted(VARIANTS), default=list(VARIANTS))
    p.add_argument("--seeds", nargs="+", type=int, default=[11, 12])
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.only:
        settings, scenario, duration = VARIANTS[name]
        start = time.perf_counter()
        traj = simulate_sections(settings, scenario, duration)
        print(f"{name}: simulated in {time.perf_counter() - start:.0f} s", flush=True)
        for seed in args.seeds:
            info = write_trajectory_recording(
                args.out, f"{name}-seed{seed}", traj, settings, scenario, seed=seed
            )
            print(f"  seed {seed}: PCC floor {info['pcc_floor_mean_mm']:.1f} mm mean", flush=True)


if __name__ == "__main__":
    main()
