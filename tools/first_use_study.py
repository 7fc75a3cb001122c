"""The first use of an installed continuum-mhe, timed as a user meets it: a
10,000-sample one-section recording (``simulate paper3d``) and a 10,000-sample
two-section raw-IMU recording (the shipped ``rod2/planar-s_raw.csv`` repeated, its
clock continued; the joins are jumps, so rows there are flagged) estimated with the
defaults (the fast MHE; raw IMUs with gyros: the direct model with the gyro biases),
each ``estimate`` a new process with an empty home folder. Prints one JSON line per
recording: wall time (s), rows, rows without their standard deviations, the statuses,
the model line, and the processes left behind (children of the run still alive).

Run it with the ``continuum-mhe`` of a fresh environment (``python -m venv V;
V/bin/pip install .``):

    python tools/first_use_study.py --exe V/bin/continuum-mhe [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import tempfile
import time
from collections import Counter
from pathlib import Path

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"
SAMPLES = 10_000


def tiled(src: Path, dst: Path, samples: int) -> None:
    """``src`` repeated until ``samples`` rows, each copy's clock after the last."""
    lines = [ln for ln in src.read_text().splitlines() if not ln.startswith("#")]
    rows = [ln.split(",") for ln in lines[1:]]
    dt = float(rows[1][0]) - float(rows[0][0])
    span = float(rows[-1][0]) - float(rows[0][0]) + dt
    out = [lines[0]]
    copy = 0
    while len(out) <= samples:
        out += [
            ",".join([f"{float(r[0]) + copy * span:.6f}", *r[1:]])
            for r in rows[: samples + 1 - len(out)]
        ]
        copy += 1
    dst.write_text("\n".join(out) + "\n")


def timed_estimate(exe: str, args: list[str], home: Path) -> float:
    start = time.perf_counter()
    subprocess.run([exe, "estimate", *args], check=True, env={"HOME": str(home), "PATH": ""},
                   stdout=subprocess.DEVNULL)  # fmt: skip
    return time.perf_counter() - start


def summary(path: Path) -> dict[str, object]:
    text = path.read_text().splitlines()
    model = next((ln[2:] for ln in text if ln.startswith("# model =")), None)
    rows = list(csv.DictReader(ln for ln in text if not ln.startswith("#")))
    stds = [k for k in rows[0] if k.startswith("std_")]
    return {
        "rows": len(rows),
        "rows_without_std": sum(any(r[k] == "" for k in stds) for r in rows),
        "statuses": dict(Counter(r["status"] for r in rows)),
        "model": model,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exe", required=True, help="continuum-mhe of a fresh environment")
    ap.add_argument("--out", type=Path, default=None, help="folder for the files (default: temp)")
    a = ap.parse_args()
    out = a.out or Path(tempfile.mkdtemp(prefix="first-use-"))
    out.mkdir(parents=True, exist_ok=True)
    one, two = out / "paper3d_10k.csv", out / "two_section_raw_10k.csv"
    duration = f"{(SAMPLES - 1) * 0.05:.2f}"
    subprocess.run([a.exe, "simulate", "paper3d", "-o", str(one), "--duration", duration,
                    "--overwrite"], check=True, stdout=subprocess.DEVNULL)  # fmt: skip
    tiled(DATA / "rod2" / "planar-s_raw.csv", two, SAMPLES)
    cases = {"one section, tilt": (one, []), "two sections, raw": (two, ["--robot", "two-section"])}
    for name, (path, extra) in cases.items():
        home = out / f"home-{path.stem}"
        home.mkdir(exist_ok=True)
        est = out / f"est_{path.name}"
        wall = timed_estimate(a.exe, [str(path), "-o", str(est), "--overwrite", *extra], home)
        left = subprocess.run(["pgrep", "-f", str(est)], capture_output=True, text=True)
        print(json.dumps({"recording": name, "wall_s": round(wall, 2), **summary(est),
                          "home_written": sorted(p.name for p in home.iterdir()),
                          "processes_left": left.stdout.split()}))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
