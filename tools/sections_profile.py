"""Samples 40 to 119 of a ``sections_ratio.py`` recording under callgrind, the rest not.

For ``k`` sections (1, 2 or 3, tilt IMUs at each section's end, N = 30) and a method
(``mhe`` or ``ekf``): the estimator is built and run over the first 40 samples with the
instrumentation off, then switched on (``callgrind_control -i on``) for the next 80
samples, so that the counts are those of 80 full-window steps::

    valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=cg.2.mhe \\
        python tools/sections_profile.py 2 mhe
    callgrind_annotate --inclusive=yes cg.2.mhe

Divide the counts by 80 for one sample. Build the core with ``-g`` (``RelWithDebInfo``
with ``-O3``) for the names of its functions.
"""

from __future__ import annotations

import argparse
import os
import subprocess

import numpy as np
from sections_ratio import sections_case

from continuum_mhe.estimators import make_estimator
from continuum_mhe.settings import MHESettings

N = 30
WARM, COUNTED = 40, 80


def instrument(on: bool) -> None:
    """Switch callgrind's instrumentation of this process on or off."""
    state = "on" if on else "off"
    subprocess.run(
        ["callgrind_control", "-i", state, str(os.getpid())], check=True, capture_output=True
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sections", type=int, choices=(1, 2, 3), help="sections of the robot")
    p.add_argument("method", choices=("mhe", "ekf"), help="the estimator profiled")
    a = p.parse_args()
    k, method = a.sections, a.method
    f, rec = sections_case(k)
    est = make_estimator(method, f, MHESettings(horizon=N))
    t, z = np.ascontiguousarray(rec.t), np.ascontiguousarray(rec.z)
    est.run(t[:WARM], z[:WARM])
    instrument(True)
    batch = est.continue_run(
        np.ascontiguousarray(t[WARM : WARM + COUNTED]),
        np.ascontiguousarray(z[WARM : WARM + COUNTED]),
    )
    instrument(False)
    print(f"{k} section(s), {method}: median solve_ms {np.median(batch.solve_ms):.3f}")


if __name__ == "__main__":
    main()
