"""Backbone shapes for drawing: every section's points and the IMU frames, from the
robot and the PCC model (one CasADi function per robot and resolution), or, for a
tendon robot, from its mechanics model (:class:`TendonShapes`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache, cached_property

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.io.tensions import Tensions
from continuum_mhe.model.pcc import pose_at_sym
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.tendon import TendonFormulation, acting_tensions
from continuum_mhe.model.tendon_statics import TendonStatics, no_equilibrium_at


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
    n_imus = robot.n_imus
    rot = rot.reshape(n_imus, 3, 3, n).transpose(3, 0, 2, 1)  # column-major blocks
    pos = pos.reshape(n_imus, 3, n).transpose(2, 0, 1)
    return _assembled(robot, pts, rot, pos)


def _assembled(
    robot: Robot, points: FloatArray, disk_rotation: FloatArray, imu_position: FloatArray
) -> BackboneGeometry:
    """The shapes from each section's points after its base ``points`` (n, n_sections,
    m, 3) m, each IMU's disk frame ``disk_rotation`` (n, n_imus, 3, 3) and place
    ``imu_position`` (n, n_imus, 3) m: every section starts where the one below ends,
    and each IMU frame is turned by its ``mount_rpy``."""
    n = len(points)
    starts = np.concatenate([np.zeros((n, 1, 3)), points[:, :-1, -1]], axis=1)
    sections = np.concatenate([starts[:, :, None, :], points], axis=2)
    mounts = np.stack([mount_rotation(imu.mount_rpy) for imu in robot.imus])
    rotation = np.einsum("nkij,kjl->nkil", disk_rotation, mounts)
    return BackboneGeometry(sections, rotation, imu_position)


def with_imu_twists(robot: Robot, geom: BackboneGeometry, twists: FloatArray) -> BackboneGeometry:
    """``geom`` with each IMU's frame turned about its disk frame's z axis (the backbone's
    tangent) by ``twists`` (n, n_imus) rad, as the ``--imu-twist`` model turns it
    (:mod:`continuum_mhe.model.direct`): the disk frame ``R``, then ``Rz(psi)``, then the
    IMU's ``mount_rpy`` ``M``, where ``geom`` holds ``R M``."""
    psi = np.asarray(twists, dtype=float)
    c, s = np.cos(psi), np.sin(psi)
    turn = np.zeros((*psi.shape, 3, 3))
    turn[..., 0, 0], turn[..., 0, 1], turn[..., 1, 0], turn[..., 1, 1] = c, -s, s, c
    turn[..., 2, 2] = 1.0
    mounts = np.stack([mount_rotation(imu.mount_rpy) for imu in robot.imus])
    # R Rz M = (R M) (M^T Rz M)
    about_mount = np.einsum("kji,nkjl,klm->nkim", mounts, turn, mounts)
    rotation = np.einsum("nkij,nkjl->nkil", geom.imu_rotation, about_mount)
    return BackboneGeometry(geom.sections, rotation, geom.imu_position)


def joined_through_ends(
    geom: BackboneGeometry, rows: NDArray[np.bool_], ends: FloatArray
) -> BackboneGeometry:
    """``geom`` with the backbones of the samples ``rows`` (n,) drawn as straight lines
    from the base through their section ends ``ends`` (rows.sum(), n_sections, 3) m,
    and their IMU frames NaN (not drawn): the drawing ``plot`` makes of a row whose
    loads the mechanics model holds no equilibrium under."""
    sections = geom.sections.copy()
    m = sections.shape[2]
    starts = np.concatenate([np.zeros((len(ends), 1, 3)), ends[:, :-1]], axis=1)
    share = np.linspace(0.0, 1.0, m)[None, None, :, None]
    sections[rows] = starts[:, :, None, :] + share * (ends - starts)[:, :, None, :]
    rotation, position = geom.imu_rotation.copy(), geom.imu_position.copy()
    rotation[rows], position[rows] = np.nan, np.nan
    return BackboneGeometry(sections, rotation, position)


@dataclass(frozen=True)
class TendonShapes:
    """A tendon robot's shapes for drawing, from its mechanics model: from estimator
    states (:meth:`~continuum_mhe.model.tendon.TendonFormulation.statics_of_states`), or
    from tip forces and the ``tensions`` at their times (a replayed estimate or truth
    file, which holds no state).

    Attributes:
        robot: the robot (with a ``[backbone]`` and its tendons).
        points_per_section: points drawn per section.
        tensions: the tensions file, for :meth:`solved_forces`; None without one.
    """

    robot: Robot
    points_per_section: int = 16
    tensions: Tensions | None = None

    @cached_property
    def statics(self) -> TendonStatics:
        """The robot's statics (its drawing function is built once)."""
        return TendonStatics(self.robot)

    def _geometry(self, k0: FloatArray, force: FloatArray, tau: FloatArray) -> BackboneGeometry:
        """``k0, force`` (n, 3), ``tau`` (n, k) into the shapes of the ``n`` samples."""
        robot, m = self.robot, self.points_per_section
        fn = self.statics.drawing_function(m).map(len(k0))
        pts, rot, pos = (np.asarray(v, dtype=float) for v in fn(k0.T, force.T, tau.T))
        n, n_sec, n_imus = len(k0), robot.n_sections, robot.n_imus
        pts = pts.reshape(3, m, n_sec, n, order="F").transpose(3, 2, 1, 0)
        rot = rot.reshape(3, 3, n_imus, n, order="F").transpose(3, 2, 0, 1)
        pos = pos.reshape(3, n_imus, n, order="F").transpose(2, 1, 0)
        return _assembled(robot, pts, rot, pos)

    def from_states(self, states: FloatArray) -> BackboneGeometry:
        """Shapes of the estimator states ``states`` (n, nx)."""
        return self._geometry(*TendonFormulation.statics_of_states(states, self.robot.n_tendons))

    def solved_forces(
        self,
        t: FloatArray,
        forces: FloatArray,
        names: Sequence[str] = (),
        values: FloatArray | None = None,
    ) -> tuple[BackboneGeometry, list[UserError]]:
        """Shapes of the tip forces ``forces`` (n, 3) N at the times ``t`` (n,) s under
        the tensions there (the base curvature solved from the tip condition, each
        sample from the previous one's), times the tension gains of the rows ``values``
        (n, len(names)) where they have them (:func:`~continuum_mhe.model.tendon.
        acting_tensions`), and, in row order, the one-line error of each row whose loads
        the rod holds no equilibrium under (its shapes NaN); where no row has one, the
        first row's error is raised."""
        if self.tensions is None:
            raise ValueError("solved_forces needs the tensions")
        statics = self.statics
        forces = np.asarray(forces, dtype=float)
        tau = np.stack([self.tensions.at(float(tk))[0] for tk in t])
        if values is not None:
            tau = acting_tensions(self.robot, tau, names, values)
        k0 = np.zeros((len(forces), 3))
        previous = None
        unsolved: list[UserError] = []
        for i in range(len(forces)):
            try:
                previous, _ = statics.solve(forces[i], tau[i], previous)
            except ArithmeticError as exc:
                unsolved.append(no_equilibrium_at(float(t[i]), exc))
                previous = None
                k0[i] = np.nan
                continue
            k0[i] = previous
        if unsolved and len(unsolved) == len(forces):
            raise unsolved[0]
        return self._geometry(k0, forces, tau), unsolved
