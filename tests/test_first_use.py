"""The first use of an install compiles nothing and writes nothing beside its outputs:
the numeric core is built by ``pip install``, and a robot's model is data to it.

Each run is a fresh interpreter with an empty home folder (no cache can help it) and a
C and C++ compiler that always fails (``CC=false``, ``CXX=false``): a run that tried to
compile anything would fail or fall back, and every row would not come from the fast
solver with its standard deviations. The one-section run imports no part of scipy
(its start-up is part of a batch run's time: the consistency checks' quantiles come from
a table).
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXE = str(Path(sys.executable).with_name("continuum-mhe"))


def _fresh_env(home: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("XDG_", "NUMBA_"))}
    env.update(HOME=str(home), CC="false", CXX="false")
    return env


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))


ROD = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"


def _simulated(folder: Path, env: dict[str, str]) -> Path:
    meas = folder / "m.csv"
    sim = subprocess.run(
        [EXE, "simulate", "paper3d", "--duration", "10", "-o", str(meas)],
        env=env, capture_output=True, text=True, cwd=folder, timeout=600,
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    return meas


@pytest.mark.parametrize("case", ["one-section-tilt", "two-section-raw"])
def test_first_estimate_compiles_nothing(tmp_path, case) -> None:
    home = tmp_path / "home"
    home.mkdir()
    env = _fresh_env(home)
    if case == "one-section-tilt":
        meas, extra = _simulated(tmp_path, env), []
        env["PYTHONPROFILEIMPORTTIME"] = "1"  # each module imported, one line on stderr
    else:  # raw accelerometers and gyros of two IMUs: the default is the direct model
        meas, extra = ROD / "planar-s_raw.csv", ["--robot", "two-section"]
    out = tmp_path / "e.csv"
    est = subprocess.run(
        [EXE, "estimate", str(meas), "-o", str(out), *extra],
        env=env, capture_output=True, text=True, cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert est.returncode == 0, est.stderr
    assert "compiling" not in est.stderr.lower(), est.stderr
    imported = {
        ln.rsplit("|", 1)[1].strip()
        for ln in est.stderr.splitlines()
        if ln.startswith("import time:")
    }
    if case == "one-section-tilt":
        assert "numpy" in imported and not {m for m in imported if m.startswith("scipy")}
    rows = _rows(out)
    assert len(rows) > 150
    statuses = {r["status"] for r in rows}
    assert "fallback-ipopt" not in statuses and "ok" in statuses, statuses
    std_cols = [c for c in rows[0] if c.startswith("std_")]
    ok = [r for r in rows if r["status"] == "ok"]
    assert std_cols and all(r[c] not in ("", "nan") for r in ok for c in std_cols)
    assert list(home.iterdir()) == []  # no cache folder, nothing written on import or use


def test_the_first_online_step_of_a_raw_imu_robot_imports_no_scipy() -> None:
    """An online loop's first step on two raw IMUs (the direct model with its gyro
    biases) imports no part of scipy, whose import alone takes 190 to 410 ms of that
    step: the start's covariances are numpy's."""
    code = (
        "import sys\n"
        "import numpy as np\n"
        "from continuum_mhe import Measurement, make_estimator, make_formulation\n"
        "from continuum_mhe.io import read_robot\n"
        "f = make_formulation('direct', read_robot('two-section'))\n"
        "est = make_estimator('mhe', f)\n"
        "z = np.array([0, 0, 1, 0, 0, 0] * 2, dtype=float)\n"
        "assert est.step(Measurement(0.0, z)).output is not None\n"
        "print(sorted(m for m in sys.modules if m.startswith('scipy')))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
