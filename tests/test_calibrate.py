"""``continuum-mhe calibrate --from RAW.csv``: known answers on a constructed recording."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.stream.calibrate import calibrate, mounting_from_gravity

G = 9.80665


@pytest.mark.parametrize("mounting", ["z-up", "z-down"])
def test_mounting_from_gravity_inverts_the_mount_rotation(mounting: str) -> None:
    up = G if mounting == "z-up" else -G
    for rpy in [(10.0, -20.0, 0.0), (-35.0, 5.0, 0.0), (0.0, 0.0, 0.0)]:
        m = mount_rotation(rpy).T @ np.array([0.0, 0.0, up])  # what the tilted sensor reads
        np.testing.assert_allclose(mounting_from_gravity(m, mounting), rpy, atol=1e-9)  # type: ignore[arg-type]


def test_calibrate_from_a_recording_of_two_imus(tmp_path: Path) -> None:
    n, dt, d = 500, 0.002, 0.05
    rpy = [(12.0, -7.0, 0.0), (-3.0, 25.0, 0.0)]
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)  # +-d: mean 0, std d*sqrt(n/(n-1))
    cols, blocks = ["t"], []
    for k, r in enumerate(rpy, start=1):
        acc = np.tile(mount_rotation(r).T @ [0, 0, G], (n, 1))
        acc[:, 0] += d * sign
        gyr = np.tile([0.01 * k, -0.02, 0.003], (n, 1))
        blocks.append(np.hstack([acc, gyr]))
        cols += [f"{c}_{k}" for c in ("ax", "ay", "az", "gx", "gy", "gz")]
    t = 100.0 + dt * np.arange(n)
    path = tmp_path / "rest.csv"
    rows = np.column_stack([t, *blocks])
    path.write_text(
        ",".join(cols) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"
    )
    cal = calibrate(t, np.hstack(blocks), "raw", 2, "z-up")
    assert cal.rate_hz == pytest.approx(500.0, rel=1e-9)
    for k, imu in enumerate(cal.imus):
        assert imu.std[0] == pytest.approx(d * math.sqrt(n / (n - 1)), rel=1e-9)
        np.testing.assert_allclose(imu.mean[3:], [0.01 * (k + 1), -0.02, 0.003], atol=1e-12)
        # the mean is off the noise-free reading by the mean of +-d (0): the mounting is exact
        np.testing.assert_allclose(imu.mount_rpy, rpy[k], atol=1e-9)  # type: ignore[arg-type]
    res = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", "calibrate", "--from", str(path)]
        + ["--robot", "two-section"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    assert "500 samples over 0.998 s of device time: 500.0 Hz" in res.stdout
    assert "IMU 1: mounting with the robot straight: --mount-rpy 12.00,-7.00,0" in res.stdout
    assert "IMU 2: mounting with the robot straight: --mount-rpy -3.00,25.00,0" in res.stdout
    assert "IMU 2: gyro bias (rad/s) gx=0.02000 gy=-0.02000 gz=0.00300" in res.stdout


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port(tmp_path: Path) -> None:
    """A device at rest, tilted by a known mounting, through a pseudo-terminal: the
    device's messages are shown and the mounting comes back."""
    import os

    from live_helpers import LiveProcess, new_pty, raw_line

    port = tmp_path / "ttyIMU"
    master = new_pty(port)
    acc = mount_rotation((8.0, 4.0, 0.0)).T @ [0, 0, G]
    lines = ["# continuum_imu 1.1.0 imus=1", "# fields: t_ms,ax,ay,az,gx,gy,gz (ms)"]
    lines += [
        raw_line(1000 + 10 * i, acc[None], np.array([[0.002, 0.0, -0.001]])) for i in range(400)
    ]
    cal = LiveProcess(["--port", str(port), "--seconds", "2"], command="calibrate", stdout=True)
    try:
        cal.wait_ready()
        os.write(master, ("\n".join(lines) + "\n").encode())
        code = cal.finish()
    finally:
        if cal.proc.poll() is None:
            cal.proc.kill()
        os.close(master)
    assert cal.proc.stdout is not None
    out = cal.proc.stdout.read()
    assert code == 0, cal.err
    assert "device says: # continuum_imu 1.1.0 imus=1" in cal.err
    assert "201 samples over 2.000 s of device time: 100.0 Hz" in out
    assert "--mount-rpy 8.00,4.00,0" in out
