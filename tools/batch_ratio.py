"""A batch ``continuum-mhe estimate``'s wall time per sample against the median
``solve_ms`` it reports (the estimator's whole step, its outputs and their standard
deviations included): what the command costs beyond the estimator (start-up, reading
and checking the input, the policy's Python per block, writing the estimates).

The recording is ``continuum-mhe simulate paper3d --duration 500`` (10,001 samples),
and ``copies`` of it end to end, each one's ``t`` shifted after the one before::

    python tools/batch_ratio.py            # 10 copies: 100,010 samples, 3 runs
    python tools/batch_ratio.py 1 5        # the 10,001 samples, 5 runs
    python tools/batch_ratio.py --jitter 2e-4   # each t moved by up to 0.2 ms

``--jitter S`` moves each sample's time by a uniform draw in [-S, S] s (seed 0), written
to the microsecond, as a logger's clock stamps its samples: every time step then
differs a little from the others.

Each run is the command as a user runs it, in a new process (the modules' bytecode
cached, as an install has it: an untimed first run writes it where it is missing);
prints per run the wall
time, the time per sample, the median ``solve_ms`` and their ratio, the same for the
process's CPU time (user and system: on a loaded machine the wall time counts the other
processes' turns too) and the machine's load average before it.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

STEP_S = 0.05  # paper3d's sample period


def recording(folder: Path, copies: int, jitter: float = 0.0) -> Path:
    """The simulated recording, ``copies`` times end to end (one header), each time
    moved by a uniform draw in ``[-jitter, jitter]`` s."""
    one = folder / "one.csv"
    run(["simulate", "paper3d", "--duration", "500", "-o", str(one)])
    header, *rows = one.read_text().splitlines()
    t = np.array([float(r.split(",", 1)[0]) for r in rows])
    span = t[-1] - t[0] + STEP_S
    lines = [header]
    rng = np.random.default_rng(0)
    for k in range(copies):
        moved = t + k * span + rng.uniform(-jitter, jitter, len(t)) if jitter else t + k * span
        digits = ".6f" if jitter else ".10g"
        lines += [f"{tv:{digits}},{r.split(',', 1)[1]}" for tv, r in zip(moved, rows)]
    out = folder / f"x{copies}.csv"
    out.write_text("\n".join(lines) + "\n")
    return out


#: The command's environment: as a user's, whose install holds the modules' bytecode
#: (``pip install`` compiles it; an editable install writes it on first import), which
#: ``PYTHONDONTWRITEBYTECODE`` (set on some machines) would have every run compile anew.
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def run(argv: list[str]) -> tuple[float, float]:
    """Wall and CPU time (user and system, s) of ``continuum-mhe ARGV`` in a new process,
    start-up included."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "continuum_mhe", *argv], check=True,
                   capture_output=True, env=ENV)  # fmt: skip
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "copies",
        nargs="?",
        type=int,
        default=10,
        help="copies of the recording (10,001 samples each) (default 10)",
    )
    p.add_argument("runs", nargs="?", type=int, default=3, help="runs (default 3)")
    p.add_argument(
        "--jitter",
        type=float,
        default=0.0,
        help="s: each sample's time moved by a uniform draw in [-S, S] (default 0)",
    )
    a = p.parse_args()
    copies = a.copies
    runs = a.runs
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        source = recording(folder, copies, a.jitter)
        out = folder / "e.csv"
        warm = folder / "warm.csv"  # a first, untimed run writes the bytecode it lacks
        warm.write_text("\n".join(source.read_text().splitlines()[:3]) + "\n")
        run(["estimate", str(warm), "-o", str(out), "--overwrite"])
        for _ in range(runs):
            load = os.getloadavg()[0]
            wall, cpu = run(["estimate", str(source), "-o", str(out), "--overwrite"])
            rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
            column = rows[0].split(",").index("solve_ms")
            ms = np.array([float(r.split(",")[column]) for r in rows[1:]])
            per = wall / len(ms) * 1e3
            median = float(np.median(ms))
            cpu_per = cpu / len(ms) * 1e3
            print(f"{len(ms)} samples: {wall:.2f} s wall, {per:.4f} ms a sample, median "
                  f"solve_ms {median:.4f} ms: {per / median:.2f}x; CPU {cpu:.2f} s, "
                  f"{cpu_per / median:.2f}x (load {load:.1f})")  # fmt: skip


if __name__ == "__main__":
    main()
