"""Shared test helpers: a sample file's header with columns renamed or left out, and the
check that a header problem is refused in one line naming the file and line 1, with
exit status 2 and nothing written, by ``estimate`` and by the library reader alike."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import pytest

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError


def imu_columns(fields: Sequence[str], n_imus: int) -> list[str]:
    """``t`` and the numbered columns of ``n_imus`` IMUs (``ax_1, ay_1, ..., ax_2...``)."""
    return ["t", *(f"{c}_{i}" for i in range(1, n_imus + 1) for c in fields)]


def renamed(columns: Sequence[str], changes: dict[str, str]) -> str:
    """The header of ``columns`` with each column of ``changes`` renamed to its value
    (``""``: left out)."""
    return ",".join(c for c in (changes.get(c, c) for c in columns) if c)


def assert_header_refused(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    header: str,
    n_imus: int,
    message: str,
    read: Callable[[Path], object],
) -> None:
    """A file of ``header`` and one row is refused with ``{file}: line 1: {message}``, in
    one line, by ``estimate`` (exit 2, nothing written; with a robot file of ``n_imus``
    IMUs where there are several) and by ``read``."""
    meas = tmp_path / "m.csv"
    meas.write_text(f"{header}\n0,{','.join(['0.1'] * header.count(','))}\n")
    robot = tmp_path / "robot.toml"
    robot.write_text(
        "".join(f"[[section]]\nlength = 0.1\n[[imu]]\nsection = {k}\n" for k in range(1, 4))
        if n_imus == 3
        else ""
    )
    assert n_imus in (1, 3)  # the robot file written: three sections, an IMU on each
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "-o", str(out), "--method", "ekf"]
    assert main([*argv, *(["--robot", str(robot)] if n_imus > 1 else [])]) == 2
    assert capsys.readouterr().err == f"continuum-mhe: error: {meas}: line 1: {message}\n"
    assert not out.exists()
    with pytest.raises(InputError) as info:
        read(meas)
    assert str(info.value) == f"{meas}: line 1: {message}"
