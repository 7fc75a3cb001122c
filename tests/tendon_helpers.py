"""Shared test helpers for tendon robots: the shipped backbone, a one-section robot
and its file, a few tilt samples of it with their tensions, and a shipped recording as
the command line reads it."""

from __future__ import annotations

import functools
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.load_hypotheses import LoadHypothesesKalmanFilter
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import open_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Backbone, ImuPlacement, Robot, Section, Tendon
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


@dataclass
class EkfRun:
    """The EKF that ``make_estimator`` gives (two hypotheses) run over a whole shipped
    recording, and the count of its compiled measurement terms' remembered evaluations
    taken during the run (``hits``)."""

    f: TendonFormulation
    t: np.ndarray
    z: np.ndarray
    estimator: LoadHypothesesKalmanFilter
    series: object
    hits: int


@functools.cache
def default_ekf_run(scenario: str, imu: str) -> EkfRun:
    """The :class:`EkfRun` of the shipped recording ``scenario`` (``raw`` or ``tilt``
    IMUs), run once a test process and shared by the test modules that read the default
    EKF's run over the whole of it (each such run takes seconds). Read only: a test that
    changes the estimator makes its own."""
    from continuum_mhe.estimators.fast import node_functions

    f, t, z = shipped_recording(scenario, imu)
    memo = node_functions(f).measurement
    est = make_estimator("ekf", f)
    assert isinstance(est, LoadHypothesesKalmanFilter)
    before = memo.hits
    series = est.run(t, z)
    return EkfRun(f, t, z, est, series, memo.hits - before)


#: the shipped tendon robot's backbone (nitinol-like, 0.7 mm)
BACKBONE = Backbone(54e9, 20.77e9, 0.0007)
EI = BACKBONE.bending_stiffness

#: a robot file: one 0.2 m section, one tendon, an IMU at its middle disk
TENDON_FILE = """
[backbone]
youngs_modulus = 54e9
shear_modulus = 20.77e9
radius = 0.0007
[[section]]
length = 0.2
disks = 10
[[tendon]]
section = 1
angle = 90
radius = 0.01
[[imu]]
section = 1
disk = 5
"""


def one_section_robot(*tendons: Tendon, backbone: Backbone = BACKBONE) -> Robot:
    """A 0.2 m section of 10 disks with an IMU at its end and ``tendons``."""
    return Robot((Section(0.2, 3.0, 10),), (ImuPlacement(0, 1.0),), "z-up", backbone, tendons)


def small_robot(tmp_path: Path) -> Path:
    """:data:`TENDON_FILE` with its IMU at the section's end, written to
    ``tmp_path/robot.toml``."""
    path = tmp_path / "robot.toml"
    path.write_text(TENDON_FILE.replace("disk = 5", "disk = 10"))
    return path


def write_text_table(path: Path, columns: list[str], rows: list[list[object]]) -> None:
    """A CSV table as a user's program may write it (``nan`` included)."""
    lines = [",".join(columns), *(",".join(str(v) for v in row) for row in rows)]
    path.write_text("\n".join(lines) + "\n")


@functools.cache
def small_robot_recording_rows() -> tuple[tuple[float, ...], ...]:
    """The rows of :func:`small_robot_recording`'s readings (the same for every test: computed once
    a process, the model's build and six statics solutions being most of its time)."""
    with tempfile.TemporaryDirectory() as folder:
        robot = read_robot(small_robot(Path(folder)))
    f = TendonFormulation(robot=robot)
    t = np.arange(6) * 0.02
    tau = 1.0 + 5 * t
    rows = []
    for tk, tauk in zip(t, tau):
        k0, _ = f.statics.solve(np.zeros(3), np.array([tauk]))
        x = np.zeros(f.nx)
        x[:3], x[6] = k0, tauk
        h = np.asarray(f.functions.observe(x), float).ravel()
        rows.append((float(tk), *map(float, h[:2])))
    return tuple(rows)


def small_robot_recording(tmp_path: Path) -> tuple[Path, Path]:
    """A few tilt samples of the one-section robot with its tendon pulled, and their
    tensions: ``(tmp_path/m.csv, tmp_path/tensions.csv)``, the robot written beside
    them as ``tmp_path/robot.toml`` (:func:`small_robot`)."""
    small_robot(tmp_path)
    meas = tmp_path / "m.csv"
    write_table(meas, ["t", "roll", "pitch"], [list(r) for r in small_robot_recording_rows()])
    tensions = tmp_path / "tensions.csv"
    write_table(tensions, ["t", "tension_1"], [[0.0, 1.0], [0.1, 1.5]])
    return meas, tensions
