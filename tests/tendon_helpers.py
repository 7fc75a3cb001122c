"""Shared test helpers for tendon robots: a shipped recording as the command line
reads it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import open_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.tendon import TendonFormulation

#: the shipped tendon recordings
DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def shipped_recording(scenario: str, imu: str) -> tuple[TendonFormulation, np.ndarray, np.ndarray]:
    """The shipped recording ``scenario`` (``raw`` or ``tilt`` IMUs) of the built-in
    ``tendon-two-section`` robot as the command line reads it: ``(formulation, t, z)``."""
    options = InputOptions(tensions=str(DATA / f"{scenario}_tensions.csv"))
    base = make_formulation("bend", read_robot("tendon-two-section"))
    with open_input(DATA / f"{scenario}_{imu}.csv", options, base) as stream:
        f = stream.formulation
        blocks = list(stream.blocks)
    assert isinstance(f, TendonFormulation)
    return f, np.concatenate([b[0] for b in blocks]), np.vstack([b[1] for b in blocks])
