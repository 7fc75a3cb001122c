"""Backbone shapes for drawing: every section's points and the IMU frames, from the
robot and the PCC model (one CasADi function per robot and resolution)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np

from continuum_mhe.io.csv_files import FloatArray
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.model.pcc import pose_at_sym
from continuum_mhe.model.robot import Robot


@dataclass(frozen=True)
class BackboneGeometry:
    """Shapes for drawing, for ``n`` samples of one robot.

    Attributes:
        sections: (n, n_sections, points_per_section + 1, 3) m, each section's backbone
            from its base to its end (a section starts where the one below it ends).
        imu_rotation: (n, n_imus, 3, 3) sensor-to-base rotation of each IMU.
        imu_position: (n, n_imus, 3) m.
    """

    sections: FloatArray
    imu_rotation: FloatArray
    imu_position: FloatArray

    @property
    def tip(self) -> FloatArray:
        """(n, 3) m."""
        return self.sections[:, -1, -1]


@cache
def _geometry_function(
    lengths: tuple[float, ...], places: tuple[tuple[int, float], ...], points: int
) -> ca.Function:
    """One CasADi function: bends (2 n_sections,) -> backbone points (3, n_sections *
    points) and IMU poses (9 n_imus column-major rotations, 3 n_imus positions)."""
    u = ca.SX.sym("u", 2 * len(lengths))
    bends = [(u[2 * k], u[2 * k + 1]) for k in range(len(lengths))]
    pts = [
        pose_at_sym(bends, lengths, k, j / points)[1]
        for k in range(len(lengths))
        for j in range(1, points + 1)
    ]
    poses = [pose_at_sym(bends, lengths, sec, at) for sec, at in places]
    rot = ca.vertcat(*[ca.reshape(r, 9, 1) for r, _ in poses])
    pos = ca.vertcat(*[p for _, p in poses])
    return ca.Function("backbone_geometry", [u], [ca.horzcat(*pts), rot, pos])


def backbone_geometry(
    robot: Robot, bends: FloatArray, points_per_section: int = 16
) -> BackboneGeometry:
    """Backbone and IMU frames from bend vectors ``bends`` (n, n_sections, 2) rad."""
    u = np.asarray(bends, dtype=float)
    if u.ndim != 3 or u.shape[1:] != (robot.n_sections, 2):
        raise ValueError(f"bends must be (n, {robot.n_sections}, 2), got {u.shape}")
    n, n_sec, m = u.shape[0], robot.n_sections, points_per_section
    places = tuple((imu.section, float(imu.at)) for imu in robot.imus)
    fn = _geometry_function(robot.lengths, places, m)
    pts, rot, pos = (np.asarray(v, dtype=float) for v in fn.map(n)(u.reshape(n, -1).T))
    pts = pts.reshape(3, n, n_sec, m).transpose(1, 2, 3, 0)  # (n, n_sec, m, 3)
    starts = np.concatenate([np.zeros((n, 1, 3)), pts[:, :-1, -1]], axis=1)
    sections = np.concatenate([starts[:, :, None, :], pts], axis=2)
    n_imus = robot.n_imus
    rot = rot.reshape(n_imus, 3, 3, n).transpose(3, 0, 2, 1)  # column-major blocks
    mounts = np.stack([mount_rotation(imu.mount_rpy) for imu in robot.imus])
    rot = np.einsum("nkij,kjl->nkil", rot, mounts)
    pos = pos.reshape(n_imus, 3, n).transpose(2, 0, 1)
    return BackboneGeometry(sections, rot, pos)
