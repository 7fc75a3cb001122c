"""What a tension glitch does to the tendon robot's estimate with the glitch test off
(docs/tendon.md, the tensions file).

The shipped ``force-29`` (raw IMUs, the command line's EKF) with tension_1 0.05 N off
at one row (t = 1 s), at two rows (1 and 1.02 s), or the tensions of t = 0.98 s held
for the two rows after: the tip's mean error (mm) and the rows ``drifted``, with the
glitch test off (the tensions taken as given) and the drift reset on and off, and with
the glitch test on (the default).

    python tools/glitch_study.py
"""

from __future__ import annotations

import argparse
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np
from drift_reset_study import DATA, read_force29

import continuum_mhe.io.tensions as tensions_module
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.tension_glitches import TensionGlitches
from continuum_mhe.settings import RecoverySettings


def _faulty(folder: Path, fault: str) -> Path:
    lines = (DATA / "force-29_tensions.csv").read_text().splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    if fault == "held two rows":
        rows[50][1:] = rows[51][1:] = rows[49][1:]
    for r in {"one row": [50], "two rows": [50, 51]}.get(fault, []):
        rows[r][1] = f"{float(rows[r][1]) + 0.05:.6f}"
    path = folder / f"{fault.replace(' ', '_')}.csv"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    return path


def _no_glitches(t: object, values: np.ndarray, noise: float) -> TensionGlitches:
    return TensionGlitches(np.zeros(np.shape(values), dtype=bool), np.array(values, float))


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()
    truth = read_state_table(DATA / "force-29_truth.csv")
    true_tip = np.stack([truth.column(c) for c in "xyz"], axis=1)
    test = tensions_module.tension_glitches
    with tempfile.TemporaryDirectory() as tmp:
        for fault in ("one row", "two rows", "held two rows"):
            path = _faulty(Path(tmp), fault)
            for glitch_test, reset in ((False, None), (False, 0.5), (True, 0.5)):
                tensions_module.tension_glitches = test if glitch_test else _no_glitches  # type: ignore[assignment]
                try:
                    f, t, z = read_force29(path)
                    est = make_estimator("ekf", f, recovery=RecoverySettings(drift_reset=reset))
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        series = est.run(t, z)
                finally:
                    tensions_module.tension_glitches = test
                names = [o.name for o in f.outputs]
                tip = np.asarray(series.output, float)[:, [names.index(c) for c in "xyz"]]
                off = np.linalg.norm(tip - true_tip[: len(tip)], axis=1)
                print(json.dumps({
                    "fault": fault,
                    "glitch_test": glitch_test,
                    "drift_reset_s": reset,
                    "tip_mean_mm": round(1000 * float(off.mean()), 2),
                    "drifted": int((np.asarray(series.status) == "drifted").sum()),
                }))  # fmt: skip


if __name__ == "__main__":
    main()
