"""Gyro biases from a recording's still start, on the shipped two-section rods.

The shipped rod recordings start moving. For each, this puts the first ``--rest``
seconds of its rest recording (the same IMUs, the rod straight and still) before its
raw recording, the times and the truth moved by as much, and runs ``continuum-mhe
estimate`` with the shipped, uncalibrated robot file: as it is (the gyro biases taken
from the still start, the twist weighed on the readings), with ``--no-imu-twist`` (the
biases, the constant-curvature frames) and with ``--no-still-start`` (neither). Prints
per estimate the tip error's mean after the rest (mm, ``evaluate --skip-start``), the
rows ``ok`` and those of them more than 4 standard deviations off on a tip axis, and
what the summary said of the twist::

    python tools/still_start_study.py                    # every rod, the MHE
    python tools/still_start_study.py --only spatial --methods mhe ekf ukf
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
RODS = ("spatial", "spatial-stiff-torsion", "spatial-tendon", "planar-s")
CASES = {
    "default": [],
    "--no-imu-twist": ["--no-imu-twist"],
    "--no-still-start": ["--no-still-start"],
}


def cli(*argv: str) -> subprocess.CompletedProcess[str]:
    """``continuum-mhe ARGV`` in a new process (a failure raised)."""
    return subprocess.run(
        [sys.executable, "-m", "continuum_mhe", *argv], check=True, capture_output=True, text=True
    )


def moved(lines: list[str], seconds: float) -> list[str]:
    """CSV ``lines`` (a header, then rows led by ``t``) with every ``t`` moved by
    ``seconds``."""
    out = [lines[0]]
    for line in lines[1:]:
        t, rest = line.split(",", 1)
        out.append(f"{float(t) + seconds!r},{rest}")
    return out


def rest_then_run(name: str, rest_s: float, folder: Path) -> tuple[Path, Path]:
    """The rod ``name``'s rest recording's first ``rest_s`` s, then its raw recording,
    and its truth, both moved by ``rest_s``; written in ``folder``."""
    rest = (DATA / f"{name}_rest.csv").read_text().splitlines()
    raw = (DATA / f"{name}_raw.csv").read_text().splitlines()
    still = [ln for ln in rest[1:] if float(ln.split(",", 1)[0]) < rest_s - 1e-9]
    run = folder / f"{name}_still_raw.csv"
    run.write_text("\n".join([raw[0], *still, *moved(raw, rest_s)[1:]]) + "\n")
    truth = folder / f"{name}_still_truth.csv"
    truth.write_text(
        "\n".join(moved((DATA / f"{name}_truth.csv").read_text().splitlines(), rest_s)) + "\n"
    )
    return run, truth


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", nargs="+", choices=RODS, default=list(RODS))
    p.add_argument("--methods", nargs="+", choices=("mhe", "ekf", "ukf"), default=["mhe"])
    p.add_argument("--rest", type=float, default=2.0, help="seconds of rest put first (default 2)")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in a.only:
            run, truth = rest_then_run(name, a.rest, folder)
            for method in a.methods:
                for case, extra in CASES.items():
                    est = folder / f"{name}_{method}_{case.strip('-')}.csv"
                    said = cli("estimate", str(run), "--robot", "two-section", "--method", method,
                               *extra, "-o", str(est)).stderr.strip().splitlines()[-1]  # fmt: skip
                    scores = json.loads(cli("evaluate", str(est), str(truth), "--robot",
                                            "two-section", "--skip-start", str(a.rest),
                                            "--json").stdout)  # fmt: skip
                    twist = "twist estimated" if "twist estimated" in said else (
                        "frames" if "twist not estimated" in said else "not weighed")  # fmt: skip
                    ok = scores["calibration_ok"]
                    print(
                        f"{name:22s} {method} {case:16s} tip mean {scores['tip_mean_mm']:7.2f} "
                        f"mm; ok {scores['ok_rows']}, over 4 std off {ok['tip_far']}; {twist}",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
