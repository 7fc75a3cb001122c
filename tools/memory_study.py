"""Peak memory of ``continuum-mhe estimate`` against the length of the recording.

Writes a tilt CSV of N rows (a slow 3D bend, 100 Hz, 2 deg noise), runs ``estimate``
on it in a fresh process per (method, N) and reads that process's peak resident
memory (``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` of a child that runs only
that command). Prints a Markdown table and writes JSON.

    python tools/memory_study.py --rows 1000 1000000 --methods ekf mhe --json mem.json
    python tools/memory_study.py --rows 1000 200000 --methods ekf --suffix .mcap
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = """
import resource, subprocess, sys
code = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
peak_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(code.returncode, peak_kb)
sys.stderr.write(code.stderr.decode())
"""


def write_recording(path: Path, rows: int, dt: float = 0.01, seed: int = 0) -> None:
    """``t,roll,pitch``: a slow bend whose plane turns, with 2 deg noise (rad)."""
    rnd = random.Random(seed)
    noise = math.radians(2.0)
    with path.open("w") as fh:
        fh.write("t,roll,pitch\n")
        for i in range(rows):
            t = i * dt
            theta = 0.6 + 0.4 * math.sin(0.2 * t)
            phi = 0.3 * t
            roll = theta * math.sin(phi) + rnd.gauss(0, noise)
            pitch = -theta * math.cos(phi) + rnd.gauss(0, noise)
            fh.write(f"{t:.2f},{roll:.6f},{pitch:.6f}\n")


def peak_kib(argv: list[str]) -> tuple[int, int, str]:
    """Exit status, peak RSS (KiB) and stderr of ``argv`` run in its own process."""
    out = subprocess.run(
        [sys.executable, "-c", CHILD, *argv], capture_output=True, text=True, check=False
    )
    code, kb = out.stdout.split()
    return int(code), int(kb), out.stderr.strip()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, nargs="+", default=[1000, 1_000_000])
    ap.add_argument("--methods", nargs="+", default=["ekf", "mhe"])
    ap.add_argument("--suffix", default=".csv", choices=(".csv", ".mcap"), help="output kind")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    cli = [sys.executable, "-m", "continuum_mhe.cli"]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for rows in args.rows:
            meas = Path(tmp) / f"m{rows}.csv"
            write_recording(meas, rows)
            for method in args.methods:
                start = time.perf_counter()
                code, kb, err = peak_kib(
                    [*cli, "estimate", str(meas), "--overwrite",
                     "-o", str(Path(tmp) / f"e{args.suffix}"), "--method", method]
                )  # fmt: skip
                wall = time.perf_counter() - start
                if code != 0:
                    print(f"{method} {rows}: exit {code}: {err}", file=sys.stderr)
                    return 1
                size = meas.stat().st_size / 2**20
                results.append({"method": method, "rows": rows, "peak_mib": kb / 1024,
                                "wall_s": wall, "input_mib": size})  # fmt: skip
                print(f"{method:4s} {rows:>9,d} rows: peak {kb / 1024:7.1f} MiB, {wall:7.1f} s",
                      file=sys.stderr)  # fmt: skip
    print("| method | rows | input MiB | peak RSS MiB | over the smallest | wall s |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in results:
        base = min(x["peak_mib"] for x in results if x["method"] == r["method"])
        print(f"| {r['method']} | {r['rows']:,} | {r['input_mib']:.1f} | {r['peak_mib']:.1f} "
              f"| {r['peak_mib'] - base:+.1f} | {r['wall_s']:.1f} |")  # fmt: skip
    if args.json:
        meta = {"python": platform.python_version(), "machine": platform.machine(),
                "cpus": os.cpu_count()}  # fmt: skip
        Path(args.json).write_text(json.dumps({"meta": meta, "results": results}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
