"""``continuum-mhe live`` on the tendon robot over a pseudo-terminal, then ``estimate``
on its recording.

The first ``--samples`` samples of a shipped tendon recording (raw IMUs, the
``tendon-two-section`` robot) are sent at their own rate (50 Hz) as serial lines with
the tensions after the IMUs' fields, and one garbled line; ``live -o --record`` runs
with its defaults (the EKF) until every sample is recorded and all but the last two
estimated (those wait for the tensions of two more samples), and is stopped with
SIGINT, which estimates them. ``estimate`` then reads the recording (its own tension columns).
Reported (JSON on stdout): the seconds to the port being read, the rows written, live's
status and summary lines, and the largest difference between the live estimates and
the replayed ones.

    PYTHONPATH=src python tools/live_tendon_replay.py --samples 40
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

import numpy as np

from continuum_mhe.io.state_tables import read_state_table

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def _rows(path: Path) -> int:
    if not path.exists():
        return 0
    return max(sum(1 for ln in path.open() if not ln.startswith("#")) - 1, 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recording", default="unloaded", help="unloaded, force-08 or force-29")
    ap.add_argument("--samples", type=int, default=40)
    ap.add_argument("--wait", type=float, default=1800, help="give up after this many s")
    args = ap.parse_args()
    raw = (DATA / f"{args.recording}_raw.csv").read_text().splitlines()[1 : args.samples + 1]
    ten = (DATA / f"{args.recording}_tensions.csv").read_text().splitlines()[1 : args.samples + 1]
    lines = []
    for r, s in zip(raw, ten):
        imu, tensions = r.split(","), s.split(",")
        assert imu[0] == tensions[0], "the tensions at the samples' times"
        lines.append(",".join([str(round(float(imu[0]) * 1e3)), *imu[1:], *tensions[1:]]))
    tmp = Path(tempfile.mkdtemp(prefix="live_tendon_"))
    est, rec, replay = tmp / "est.csv", tmp / "rec.csv", tmp / "replay.csv"
    master, slave = os.openpty()
    tty.setraw(slave)
    cmd = [sys.executable, "-m", "continuum_mhe.cli"]
    start = time.monotonic()
    live = subprocess.Popen(
        [*cmd, "live", "--port", os.ttyname(slave), "--robot", "tendon-two-section"]
        + ["-o", str(est), "--record", str(rec), "--status-every", "2"],
        stderr=subprocess.PIPE,
        text=True,
    )
    said: list[str] = []
    assert live.stderr is not None
    stderr = live.stderr
    reader = threading.Thread(target=lambda: said.extend(stderr), daemon=True)
    reader.start()

    def wait(pred: object, what: str) -> None:
        end = time.monotonic() + args.wait
        while not pred():  # type: ignore[operator]
            if time.monotonic() > end or live.poll() is not None:
                live.kill()
                raise SystemExit(f"gave up waiting for {what}:\n{''.join(said)}")
            time.sleep(0.05)

    wait(lambda: any("reading " in s for s in said), "live to read the port")
    ready_s = time.monotonic() - start
    for ln in lines:
        os.write(master, (ln + "\n").encode())
        time.sleep(0.02)
    os.write(master, b"1,2,3\n")  # a garbled line
    # each sample is estimated once the two after it are in: the last two at the end
    wait(lambda: _rows(rec) >= len(lines) and _rows(est) >= len(lines) - 2, "the estimates")
    live.send_signal(signal.SIGINT)
    code = live.wait()
    reader.join(timeout=5)
    os.close(master)
    os.close(slave)
    start = time.monotonic()
    res = subprocess.run(
        [*cmd, "estimate", str(rec), "--robot", "tendon-two-section", "-o", str(replay)],
        capture_output=True,
        text=True,
    )
    replay_s = time.monotonic() - start
    a, b = read_state_table(est), read_state_table(replay)
    same = a.names == b.names and len(a.t) == len(b.t)
    report = {
        "samples_sent": len(lines),
        "live_exit": code,
        "seconds_to_reading_the_port": round(ready_s, 1),
        "rows_estimates": _rows(est),
        "rows_recording": _rows(rec),
        "recording_header": rec.read_text().splitlines()[0],
        "estimate_columns": a.names,
        "live_said": [s.rstrip() for s in said if "Hz" in s or "samples," in s],
        "replay_exit": res.returncode,
        "replay_seconds": round(replay_s, 1),
        "replay_said": res.stderr.strip().splitlines()[-1:],
        "same_times": same and bool(np.array_equal(a.t, b.t)),
        "largest_difference": float(np.nanmax(np.abs(a.values - b.values))) if same else None,
        "same_statuses": same and list(a.status) == list(b.status),
    }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
