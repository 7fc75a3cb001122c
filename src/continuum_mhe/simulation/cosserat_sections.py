"""Ground truth the PCC model did not generate: a Cosserat rod of sections (PyElastica).

Robot: one elastic rod, base clamped, z up, under gravity, split into sections: by
default two, 0.16 m + 0.14 m, an IMU at each section's end (as ``two-section``); or a
robot file's (:func:`rod_settings`: its sections' lengths and its IMUs' places, each IMU
on one of the rod's nodes: a section's end, or a disk; :func:`rod_layout`). Each
section is driven by its own "tendon", modelled as a point couple at the section's end
(a tendon terminated there and routed along the backbone loads the rod with a couple
``tension x offset``), with a servo-like profile. Section ``k``'s end gets the couple
``M_k - M_{k+1}`` (the tip ``M_n``), so that section ``k``, which carries the couples
of every end beyond its base, carries the moment ``M_k`` (:func:`section_moments`).
The moments are the shipped rod's: the tip section's is its section 2's, every other
section's its section 1's; a section longer than its role's (:data:`ROLE_LENGTHS`)
gets it times the role's length over its own, so that it bends as far, and a shorter
one bends less (no section curves more than the shipped rod's); on ``n > 2`` sections
each is ``1 / (n - 1)`` of that besides (:func:`bend_share`); a rod shorter than the
shipped one is damped more (:func:`robot_damping`). Rods curved, curled or damped less
went unstable (a shear of their elements growing without bound, at any integration
step: the couples, fixed in the base frame or following the elements, do not derive
from a potential). Scenarios:

* ``planar-s``: every moment about base x, the sections in turn the opposite senses:
  on two sections, section 1 bends one way, section 2 the other (an S-curve in the y-z
  plane); on one, a single bend;
* ``spatial``: the moments' axes turn about base z at different rates (bending planes
  turning at different rates: the tip section's at ``-2 pi / 5`` rad/s, every other's
  at ``2 pi / 9`` rad/s, section ``k``'s from ``k - 1`` rad further on), large enough
  for bends over 90 degrees per section on the shipped rod.

Two drives (``SectionRodSettings.drive``):

* ``base``: the couples are fixed in the base frame. Where a section is already bent,
  part of a base-frame couple lies along its tangent and twists the rod (up to 120
  degrees at the tip on ``spatial`` with ``G = E/3``);
* ``tendon``: each couple is fixed in the frame of the element it acts on (a follower
  couple, as a tendon terminated there pulls), perpendicular to the tangent: section
  ``k`` carries about the bending moment ``M_k`` in its own frame, as when each
  section's tendon runs through the sections before it. The rod bends with little
  twist.

The shear modulus sets how much the rod twists under the couples (the PCC model has no
torsion): ``G = E/3`` (a plain elastomer rod) or ``G = 5 E`` (a robot built to resist
torsion). An MPU9250-like IMU sits at each IMU's place (specific force including its
own acceleration, DLPF, noise, bias, misalignment, 16-bit quantisation; gyro with noise
and bias), as in :mod:`continuum_mhe.simulation.cosserat`.

Outputs, per recording (``write_section_recording``), their columns following the
robot's sections and IMUs:

* ``NAME_raw.csv``: ``t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,...`` (m/s^2, rad/s, each
  IMU in its own frame, z along the backbone; one IMU's without the ``_1``);
* ``NAME_tilt.csv``: ``t,roll_1,pitch_1,roll_2,pitch_2,...`` from the accelerometers;
* ``NAME_truth.csv``: ``t,x,y,z`` (the rod's tip) and per section ``theta_k, phi_k``
  (the PCC bends of the true section-end tangents) and ``x_k,y_k,z_k`` (the rod's true
  section ends): the columns of an estimate of the robot (one section's ``theta,
  phi`` alone, its end the tip);
* ``NAME_info.json``: the PCC-model floor (tip error of the PCC forward kinematics of
  the true section-end tangents), a one-section model's error (the whole robot as one
  arc through the tip tangent), the rod's total material twist, and the twist about
  the tangent at each section end (the angle about the tangent between the rod's true
  frame there and the torsion-free PCC frame of the same tangents: what an IMU there
  sees and the PCC model cannot explain); ``robot``: the robot file, where one was
  given;
* ``NAME_rest.csv``: the same IMUs (the same misalignments and biases, fresh noise)
  with the rod straight and still, as long as the recording: the rest period a user
  records before a run, for ``continuum-mhe calibrate --from NAME_rest.csv --robot
  two-section`` (the mounting ``mount_rpy`` of each IMU for the robot file);
* ``NAME_bend.csv``: the same IMUs (the same misalignments and biases, fresh noise)
  with the rod bent slowly in the base x-z plane towards ``-x`` (``phi = 0``): the same
  base-frame couple about ``-y`` at each section's end, sized so that the tip turns as
  far as on the shipped rod, ramped up over 2 s and held (5 s; no twist), for
  ``continuum-mhe calibrate --from NAME_rest.csv --bend NAME_bend.csv`` (each IMU's yaw
  about the tangent).

Regenerate (needs the ``rod`` extra)::

    continuum-mhe rod sections --scenario planar-s -o DIR
    continuum-mhe rod sections --scenario spatial -o DIR
    continuum-mhe rod sections --scenario spatial -o DIR \
        --shear-ratio 5 --sim-dt 5e-6 --name spatial-stiff-torsion
    continuum-mhe rod sections --scenario spatial -o DIR \
        --drive tendon --name spatial-tendon

``--robot ROBOT.toml`` simulates that robot's sections and IMUs instead (the rod's
material, radius and drive stay this module's); ``--robot two-section`` writes the
default's files (its info naming the robot).
``--bend-only`` writes only ``NAME_bend.csv`` (the same options as the recording: the
IMUs' constant errors are drawn as for it, without simulating it).
``--calibrated`` gives the IMUs no accelerometer bias and no board misalignment (noise,
quantisation and gyro bias stay), to separate the sensors' errors from the model's.
A ``--sim-dt`` too long for the rod blows the explicit integration up, sometimes
without leaving finite numbers: a recorded element strained past :data:`MAX_STRAIN`
(stretch or shear; the documented runs reach under 4e-4) stops the run in one line
naming ``--sim-dt``, before anything is written.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.extras import require
from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.model.kinematics import rotation_bend
from continuum_mhe.model.pcc import bend_from_tangent_frames, pose_at, section_frames_from_bends
from continuum_mhe.model.robot import Robot
from continuum_mhe.simulation.cosserat import (
    ImuSettings,
    _quantise,
    _rotation_xyz,
    servo_profile,
)

SCENARIOS = ("planar-s", "spatial")
#: the bend calibration's rod motion (``NAME_bend.csv``; not a recording's scenario)
BEND = "bend-xz"
#: each section end's couple in the bend recording, in units of ``max_moment``, its
#: ramp time and duration, s
BEND_MOMENT, BEND_RAMP_S, BEND_DURATION_S = 1.0 / 3.0, 2.0, 5.0
DRIVES = ("base", "tendon")
#: the recordings' IMU (50 Hz) and the same IMU calibrated (no accelerometer bias, no
#: board misalignment; noise, quantisation and gyro bias stay)
DEFAULT_IMU = ImuSettings(sample_dt=0.02)
CALIBRATED_IMU = ImuSettings(sample_dt=0.02, accel_bias=0.0, misalignment_deg=0.0)


#: The integration step of the default rod (torsion at G = E/3), s.
BASE_SIM_DT = 2.0e-5
#: The rod's states are recorded every ``RECORD_DT`` s (:func:`simulate_sections`).
RECORD_DT = 1e-3
#: The largest strain (stretch, compression or shear, :func:`rod_strain`) of any
#: element in a recorded frame; beyond it the explicit integrator has blown up, even
#: where the rod stays finite (at 2.5 times the default step, 5e-5 s, the tip went
#: 7.5 m from the base of the 0.3 m rod). The rod is extensible: the documented 12 s
#: runs reach 3.1e-4 (planar-s) to 3.6e-4 (both scenarios with the tendon drive), 2.7e-4
#: as the rod settles under its weight in its first 15 ms (the bend recording; spatial
#: at G = 5E and 5e-6 s); the 5e-5 s step passes 0.01 in its first recorded
#: millisecond and reaches 1.9e3.
MAX_STRAIN = 0.01
#: The longest recording, s: the trajectory keeps a record every ``RECORD_DT`` of
#: about 1 kB (31 nodes, the section ends' frames and velocities), and the rest
#: recording a copy of it, so 600 s holds about 1.2 GB (a longer one runs out of
#: memory, or runs for hours: 600 s is about 25 minutes at the default step).
MAX_DURATION_S = 600.0
#: ``--sim-dt``'s range, s: beyond the records' 1 ms the records would be a step
#: apart, and below 1e-7 s (200 times shorter than the default) a 12 s recording
#: takes hours.
SIM_DT_RANGE = (1e-7, RECORD_DT)
#: ``--shear-ratio``'s largest G / E: 300 times a plain elastomer's torsion (an
#: isotropic material's G / E is 1/3 to 1/2); its default step, 1e-6 s, runs a 12 s
#: recording in about half an hour.
MAX_SHEAR_RATIO = 100.0

#: The shipped rod's section lengths, m (``two-section``'s; :class:`SectionRodSettings`'
#: default): every section's but the tip section's role, and the tip section's. A
#: section longer than its role's gets its role's moment times the role's length over
#: its own, so that it bends as far and no further; a shorter one its role's moment
#: (:func:`section_moments`).
ROLE_LENGTHS = (0.16, 0.14)
#: The fewest elements of a section (:func:`rod_layout`): five nodes along its arc.
MIN_SECTION_ELEMENTS = 4
#: A section's elements go up to this many times its share to place its IMUs on nodes
#: (:func:`rod_layout`); each element shorter than the default rod's 1 cm shortens the
#: default integration step in proportion (:func:`default_sim_dt`).
MAX_ELEMENT_FACTOR = 3
#: The default rod's element length, m (0.3 m in 30 elements): the default step's.
BASE_ELEMENT_LENGTH = 0.01


class RodDivergedError(RuntimeError):
    """The explicit integration blew up (a step too long for the rod): an element's
    strain past :data:`MAX_STRAIN`, or a position not finite."""


def rod_strain(positions: FloatArray, directors: FloatArray, rest_lengths: FloatArray) -> float:
    """The largest shear-and-stretch strain ``|Q_i (x_{i+1} - x_i) / l_i - e3|`` of a
    rod's elements (PyElastica's ``sigma``): positions (3, k+1), directors (3, 3, k)
    (rows: the element's axes), rest lengths (k,). NaN where a position is not finite."""
    t = np.diff(positions, axis=1) / rest_lengths
    local = np.einsum("ijk,jk->ik", directors, t)
    local[2] -= 1.0
    return float(np.max(np.linalg.norm(local, axis=0)))


def check_rod_frame(
    positions: FloatArray, directors: FloatArray, rest_lengths: FloatArray, time: float
) -> None:
    """A :class:`RodDivergedError` where the rod at ``time`` (s) has blown up: a
    position that is not finite, or an element strained past :data:`MAX_STRAIN`."""
    if not np.all(np.isfinite(positions)):
        raise RodDivergedError(f"rod simulation diverged at t = {time:.4f} s (not finite)")
    strain = rod_strain(positions, directors, rest_lengths)
    if not strain <= MAX_STRAIN:
        raise RodDivergedError(
            f"rod simulation diverged at t = {time:.4f} s (an element strained by "
            f"{strain:.3g}, beyond {MAX_STRAIN:g})"
        )


def check_generator_arguments(
    duration: float, seed: int, sample_dt: float, max_duration: float = MAX_DURATION_S
) -> None:
    """A one-line :class:`~continuum_mhe.errors.UserError` naming the option, before
    anything is simulated: ``--duration`` shorter than the IMUs' sample time
    ``sample_dt`` (a recording of its first sample alone, as ``continuum-mhe simulate``
    refuses a duration under its ``--dt``), longer than ``max_duration`` (the
    generator's memory and time), or not a number; a negative ``--seed`` (the random
    generator takes seeds >= 0, as ``simulate``'s)."""
    if not (math.isfinite(duration) and duration >= sample_dt):
        raise UserError(
            f"--duration must be at least the IMUs' sample time, {sample_dt:g} s (a "
            f"shorter recording holds its first sample alone), got {duration:g}"
        )
    if duration > max_duration:
        raise UserError(
            f"--duration must be at most {max_duration:g} s (write longer recordings in "
            f"parts), got {duration:g}"
        )
    if seed < 0:
        raise UserError(f"--seed must be an integer >= 0, got {seed}")


def check_file_prefix(name: str) -> None:
    """A one-line :class:`~continuum_mhe.errors.UserError` for a ``--name`` that is not
    a file name prefix: one with a path separator would write outside ``-o``."""
    seps = [c for c in (os.sep, os.altsep, "/") if c]
    if any(c in name for c in seps) or name in (".", ".."):
        raise UserError(
            f"--name {name!r}: a file name prefix without a path separator (the files "
            "are written in the folder -o)"
        )


@dataclass(frozen=True)
class SectionRodSettings:
    """The rod, its sections and IMUs, and its actuation.

    Attributes:
        lengths: section lengths, m, base first (the shipped rod's two by default).
        imu_places: each IMU's place ``(section, at)``: its section (0-based) and the
            fraction of that section's length from its base, in the readings' order;
            ``None`` (the default): one IMU at each section's end.
        radius: m; youngs_modulus: Pa; shear_ratio: G / E (1/3 or 5); density: kg/m^3.
        imu_mass: each IMU board, kg.
        n_elements: Cosserat elements of the shipped rod's 0.3 m; any rod's sections
            get elements about as long, 1 cm by default (:func:`rod_layout`).
        damping: uniform linear damping constant, 1/s; sim_dt: integration step, s.
        max_moment: each section's largest couple, N m (less on a section longer
            than its role's, :data:`ROLE_LENGTHS`, and on more than two sections:
            :func:`section_moments`).
        period: one pull-hold-release-rest cycle, s.
        drive: ``"base"`` (couples fixed in the base frame) or ``"tendon"`` (each
            couple fixed in the frame of the element it acts on); see the module.
        tendon_gain: the tendon drive's section moments at full pull, in units of
            ``max_moment``: every section's but the tip section's, and the tip
            section's (bends to 124 and 113 degrees on ``spatial``).
    """

    lengths: tuple[float, ...] = ROLE_LENGTHS
    radius: float = 0.005
    youngs_modulus: float = 3.0e7
    shear_ratio: float = 1.0 / 3.0
    density: float = 1200.0
    imu_mass: float = 0.004
    n_elements: int = 30
    damping: float = 4.0
    sim_dt: float = BASE_SIM_DT
    max_moment: float = 0.12
    period: float = 6.0
    drive: Literal["base", "tendon"] = "base"
    tendon_gain: tuple[float, float] = (1.5, 1.75)
    imu_places: tuple[tuple[int, float], ...] | None = None

    def __post_init__(self) -> None:
        if self.drive not in DRIVES:
            raise ValueError(f"drive must be one of {DRIVES}, got {self.drive!r}")
        if not self.lengths or not all(v > 0 for v in self.lengths):
            raise ValueError(f"lengths must be one or more positive lengths, got {self.lengths!r}")
        for section, at in self.imu_places or ():
            if not (0 <= section < len(self.lengths) and 0.0 < at <= 1.0):
                raise ValueError(
                    f"an IMU's place is (section 0 to {len(self.lengths) - 1}, a fraction "
                    f"in (0, 1]), got {(section, at)!r}"
                )

    @property
    def places(self) -> tuple[tuple[int, float], ...]:
        """Each IMU's ``(section, at)`` (:attr:`imu_places`, or each section's end)."""
        if self.imu_places is None:
            return tuple((k, 1.0) for k in range(len(self.lengths)))
        return self.imu_places


def rod_settings(robot: Robot, base: SectionRodSettings | None = None) -> SectionRodSettings:
    """``base`` (the default rod's settings if not given) with ``robot``'s sections and
    IMUs: its sections' lengths, its IMUs' places, and a rod shorter than the shipped
    rod's 0.3 m damped more, by the square of their ratio (:func:`robot_damping`;
    :func:`check_section_robot` says whether the generator writes it)."""
    s = base or SectionRodSettings()
    return replace(
        s,
        lengths=robot.lengths,
        imu_places=tuple((imu.section, imu.at) for imu in robot.imus),
        damping=robot_damping(s.damping, robot.lengths),
    )


def robot_damping(damping: float, lengths: Sequence[float]) -> float:
    """The damping constant (1/s) of a rod of ``lengths`` for the shipped rod's
    ``damping``: the same where the rod is at least as long as the shipped rod
    (:data:`ROLE_LENGTHS`), else times the square of the shipped rod's length over its
    own, as its bending modes' frequencies rise, so that its slowest mode is damped as
    the shipped rod's is. Two sections of 0.1 m, each as curved as the shipped rod's,
    went unstable on ``spatial`` with the base-frame couples at 9.2 s under 4/s (a shear
    of the elements growing, at any step), and ran under 8/s."""
    ratio = sum(ROLE_LENGTHS) / sum(lengths)
    return damping * max(1.0, ratio * ratio)


def check_section_robot(robot: Robot) -> None:
    """A :class:`~continuum_mhe.errors.UserError` for a robot whose recordings this
    generator does not write: one with a ``[backbone]`` or tendons (its rod is the
    module's, driven by couples: ``rod tendon`` simulates a tendon robot's own), one not
    standing on its base or with an IMU turned (:func:`check_standing_robot`), an IMU
    between two of the rod's nodes (:func:`rod_layout`)."""
    if robot.backbone is not None or robot.tendons:
        raise UserError(
            "the section-rod generator drives its own rod (radius 5 mm, E = 30 MPa) by "
            "couples at the section ends: give a robot file without [backbone] and "
            f"[[tendon]]s (rod tendon simulates a tendon robot's own), not {robot.describe()}"
        )
    check_standing_robot(robot, "section-rod", "section's")
    rod_layout(rod_settings(robot))  # each IMU on a node


def check_standing_robot(robot: Robot, generator: str, frame: str) -> None:
    """A :class:`~continuum_mhe.errors.UserError` for a robot that the ``generator``
    (as its messages name it) does not simulate: one not standing on its base
    (``z-up``), or with an IMU turned in its ``frame`` (a ``mount_rpy``: the generators
    read each IMU in the rod's frame there)."""
    if robot.mounting != "z-up":
        raise UserError(
            f"mounting = {robot.mounting!r}: the {generator} generator simulates a robot "
            'standing on its base (mounting = "z-up"): give that in a copy of the robot '
            "file to generate, and estimate its recording with that copy"
        )
    rotated = [k + 1 for k, p in enumerate(robot.imus) if any(v != 0.0 for v in p.mount_rpy)]
    if rotated:
        raise UserError(
            f"IMU {', '.join(map(str, rotated))} has a mount_rpy: the {generator} generator "
            f"reads each IMU in its {frame} frame (mount_rpy = [0, 0, 0]); leave mount_rpy "
            "out of the copy of the robot file to generate, and estimate its recording "
            "with that copy"
        )


@dataclass(frozen=True)
class RodLayout:
    """The discrete rod of a :class:`SectionRodSettings` (:func:`rod_layout`).

    Attributes:
        elements: each section's elements, base first (all of one length within a
            section).
        end_nodes: the node (0-based, from the base) ending each section.
        imu_nodes: the node carrying each IMU (the end of the element whose frame it
            reads).
        uniform: whether all the rod's elements are of one length (PyElastica's
            straight rod as it makes it); else the nodes lie at :attr:`along`.
        along: each node's arc length from the base, m.
    """

    elements: tuple[int, ...]
    end_nodes: tuple[int, ...]
    imu_nodes: tuple[int, ...]
    uniform: bool
    along: FloatArray

    @property
    def shortest_element(self) -> float:
        """The shortest element's length, m (the integration step's scale)."""
        return float(np.min(np.diff(self.along)))


def _on_node(at: float, n: int) -> bool:
    """Whether fraction ``at`` of a section of ``n`` elements is one of its nodes past
    its base."""
    j = round(at * n)
    return j >= 1 and abs(at * n - j) <= 1e-6


def rod_layout(settings: SectionRodSettings) -> RodLayout:
    """Each section's elements: its share of ``n_elements`` by its length over the
    shipped rod's (:data:`ROLE_LENGTHS`; at least :data:`MIN_SECTION_ELEMENTS`), or the
    next count up to :data:`MAX_ELEMENT_FACTOR` times that which puts each of its IMUs
    on a node (an IMU at disk ``d`` of ``D``, ``at = d / D``, on a multiple of
    ``D / gcd(d, D)`` elements). No element bends further than the shipped rod's (a
    section's curvature is at most its role's there: :func:`section_moments`). A
    :class:`~continuum_mhe.errors.UserError` names the IMUs that lie between the nodes
    of every such count."""
    s = settings
    total, shipped = sum(s.lengths), sum(ROLE_LENGTHS)
    places = s.places
    elements = []
    for k, length in enumerate(s.lengths):
        share = max(MIN_SECTION_ELEMENTS, int(round(s.n_elements * length / shipped)))
        counts = range(share, MAX_ELEMENT_FACTOR * share + 1)
        mine = [(i, at) for i, (section, at) in enumerate(places) if section == k]
        n = next((n for n in counts if all(_on_node(at, n) for _, at in mine)), None)
        if n is None:  # those that fit no count, or all of them (each fits, not together)
            off = [(i, at) for i, at in mine if not any(_on_node(at, m) for m in counts)]
            off = off or mine
            imus, lie = ("IMU", "lies between") if len(off) == 1 else ("IMUs", "do not all lie on")
            raise UserError(
                f"{imus} {', '.join(str(i + 1) for i, _ in off)} at "
                f"{', '.join(f'{at:g}' for _, at in off)} of section {k + 1} {lie} the "
                f"generator's rod nodes (section {k + 1} of {share} to {counts[-1]} "
                "elements): place each at the section's end or on a disk (disk = d of the "
                "section's disks in the robot file)"
            )
        elements.append(n)
    n_total = sum(elements)
    starts = np.concatenate([[0], np.cumsum(elements)]).astype(int)
    end_nodes = tuple(int(v) for v in starts[1:])
    imu_nodes = tuple(
        int(starts[section]) + int(round(at * elements[section])) for section, at in places
    )
    uniform = all(
        abs(n * total / n_total - length) <= 1e-9 for n, length in zip(elements, s.lengths)
    )
    if uniform:
        along = np.linspace(0.0, total, n_total + 1)
    else:
        cuts = np.concatenate([[0.0], np.cumsum(s.lengths)])
        along = np.concatenate(
            [[0.0]]
            + [cuts[k] + length * np.arange(1, n + 1) / n
               for k, (n, length) in enumerate(zip(elements, s.lengths))]
        )  # fmt: skip
    return RodLayout(tuple(elements), end_nodes, imu_nodes, uniform, along)


@dataclass(frozen=True)
class SectionTrajectory:
    """Rod states every ``record_dt``: times (n,), nodes (n, 3, k+1), the directors
    (n, m, 3, 3) of the m elements that carry an IMU, the velocities (n, m, 3) of the
    nodes that end them, the angular velocities (n, m, 3) of those elements (their
    frame), the total twist (n,) rad, the nodes ending each section, and the directors
    (n, sections, 3, 3) of the elements ending each section (``None``: those of the
    IMUs' elements, an IMU at each section's end)."""

    t: FloatArray
    nodes: FloatArray
    directors: FloatArray
    velocities: FloatArray
    omegas: FloatArray
    twist: FloatArray
    end_nodes: tuple[int, ...]
    end_directors: FloatArray | None = None

    @property
    def section_directors(self) -> FloatArray:
        """The directors (n, sections, 3, 3) of the elements ending each section."""
        return self.directors if self.end_directors is None else self.end_directors


def _tip_role(k: int, n_sections: int) -> int:
    """Which of :data:`ROLE_LENGTHS` (and ``tendon_gain``) section ``k`` (0-based) of
    ``n_sections`` takes: 1 for the tip section, 0 for every other."""
    return 1 if k == n_sections - 1 else 0


def _bending_direction(k: int, n_sections: int, t: float) -> float:
    """Section ``k``'s bending direction on ``spatial`` (rad from the base x axis) at
    ``t``: the tip section's turns at ``-2 pi / 5`` rad/s from 1 rad, every other's at
    ``2 pi / 9`` from ``k`` rad (the base section's from 0)."""
    if _tip_role(k, n_sections) == 1:
        return -2 * np.pi * t / 5.0 + 1.0
    a = 2 * np.pi * t / 9.0
    return a + float(k) if k else a


def section_moments(scenario: str, t: float, m: float, s: SectionRodSettings) -> list[FloatArray]:
    """The moment ``M_k`` (N m) each section carries at ``t`` at the pull ``m`` (N m):
    in the base frame for the ``base`` drive, in the frame of the section's end element
    for ``tendon``, ``M_k = g_k m_k e(alpha_k)`` with ``e(alpha) = (cos alpha, sin alpha,
    0)`` and ``m_k`` the pull ``m`` times its role's :data:`ROLE_LENGTHS` over its
    length where that is under 1 (a section no more curved than its role's), and times
    :func:`bend_share` of the number of sections.

    ``planar-s``: the sections bend the opposite ways in turn (an S on two): ``+-m_k``
    about base x for ``base``, ``alpha_k = 0`` and ``pi`` in turn for ``tendon``.
    ``spatial``: ``alpha_k`` turning (:func:`_bending_direction`), ``g_k = 1.3`` for
    ``base``, the tendon gain of the section's role for ``tendon``.
    """
    n = len(s.lengths)
    out = []
    for k, length in enumerate(s.lengths):
        role = _tip_role(k, n)
        mk = m * min(1.0, ROLE_LENGTHS[role] / length)
        if n > 2:
            mk *= bend_share(n)
        if scenario == "planar-s" and s.drive == "base":
            out.append(np.array([-mk if k % 2 else mk, 0.0, 0.0]))
            continue
        if scenario == "planar-s":
            a = math.pi if k % 2 else 0.0
        else:
            a = _bending_direction(k, n, t)
        gain = s.tendon_gain[role] if s.drive == "tendon" else 1.3
        out.append(gain * mk * np.array([math.cos(a), math.sin(a), 0.0]))
    return out


def bend_share(n_sections: int) -> float:
    """The share of its role's moment each of ``n_sections`` sections gets
    (:func:`section_moments`): 1 on one or two sections, ``1 / (n - 1)`` on more (their
    bends add up to at most ``n / (n - 1)`` of one section's). On ``spatial``, three
    sections bent by ``2 / 3`` of it and four by ``1 / 2`` curled the rod so far that a
    shear of its elements grew without bound within 9 s (at any step, and on elements
    half as long), with either drive; so did two sections of 0.1 m each bent as far as
    the shipped rod's, curved 1.6 times as much (why a section shorter than its role's
    keeps its role's moment and bends less)."""
    return 1.0 if n_sections <= 2 else 1.0 / (n_sections - 1)


def _bend_lever(lengths: Sequence[float]) -> float:
    """The sum of each section's length times the number of section ends beyond its
    base (the couples it carries): the tip tangent turns by this times a couple over the
    bending stiffness."""
    return sum((len(lengths) - k) * length for k, length in enumerate(lengths))


def couples(scenario: str, t: float, s: SectionRodSettings) -> tuple[FloatArray, ...]:
    """The couples (N m) at each section's end at ``t``: in the base frame for the
    ``base`` drive, in the frame of the end element for ``tendon``.

    Section ``k``'s end gets ``M_k - M_{k+1}`` (the tip ``M_n``,
    :func:`section_moments`), so that section ``k``, which carries the couples of every
    end beyond its base, carries ``M_k``: on two sections ``planar-s`` gives section 1
    the net moment ``+m`` and section 2 ``-m`` about base x. The bend recording's
    (:data:`BEND`): the same couple about ``-y`` at every end, sized so that the tip
    turns as far as on the shipped rod (:func:`_bend_lever`).
    """
    if scenario == BEND:  # about -y: every section bends towards -x (phi = 0)
        ramp = 0.5 * (1 - math.cos(math.pi * min(t / BEND_RAMP_S, 1.0)))
        scale = _bend_lever(ROLE_LENGTHS) / _bend_lever(s.lengths)
        c = np.array([0.0, -BEND_MOMENT * s.max_moment * ramp * scale, 0.0])
        return (c, *(c.copy() for _ in s.lengths[1:]))
    m = s.max_moment * float(servo_profile(t, s.period))
    moments = section_moments(scenario, t, m, s)
    return (*(mk - after for mk, after in zip(moments, moments[1:])), moments[-1])


def simulate_sections(
    settings: SectionRodSettings, scenario: str, duration: float, record_dt: float = RECORD_DT
) -> SectionTrajectory:
    """Integrate the rod for ``duration`` s and record every ``record_dt`` s; a
    :class:`RodDivergedError` where a recorded frame has blown up
    (:func:`check_rod_frame`)."""
    ea: Any = require("elastica", "rod", "the rod simulation", package="pyelastica")
    if scenario not in (*SCENARIOS, BEND):
        raise UserError(f"scenario must be one of {SCENARIOS}, got {scenario!r}")
    s = settings
    layout = rod_layout(s)
    total = sum(s.lengths)
    n_elements = sum(layout.elements)
    ends = layout.end_nodes  # node indices of the section ends
    end_elems = [node - 1 for node in ends]

    class _Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    class _Couples(ea.NoForces):
        def apply_torques(self, system: object, time: float = 0.0) -> None:
            # PyElastica's external torques are in each element's own frame
            cs = couples(scenario, float(time), s)
            q = system.director_collection  # type: ignore[attr-defined]
            for elem, c in zip(end_elems, cs):
                if s.drive == "base":
                    c = q[:, :, elem] @ c
                system.external_torques[:, elem] += c  # type: ignore[attr-defined]

    sim = _Sim()
    # (the nodes where the elements are not all of one length; PyElastica's own spacing
    # where they are)
    position = None if layout.uniform else np.outer([0.0, 0.0, 1.0], layout.along)
    rod = ea.CosseratRod.straight_rod(
        n_elements,
        np.zeros(3),
        np.array([0.0, 0.0, 1.0]),
        np.array([1.0, 0.0, 0.0]),
        total,
        s.radius,
        s.density,
        youngs_modulus=s.youngs_modulus,
        shear_modulus=s.youngs_modulus * s.shear_ratio,
        **({} if position is None else {"position": position}),
    )
    for node in layout.imu_nodes:
        rod.mass[node] += s.imu_mass
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    sim.add_forcing_to(rod).using(
        ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -STANDARD_GRAVITY])
    )
    sim.add_forcing_to(rod).using(_Couples)
    sim.dampen(rod).using(
        ea.AnalyticalLinearDamper, uniform_damping_constant=s.damping, time_step=s.sim_dt
    )
    sim.finalize()
    stepper = ea.PositionVerlet()
    per_record = max(1, int(round(record_dt / s.sim_dt)))
    n_rec = int(round(duration / (per_record * s.sim_dt))) + 1
    n_imus = len(layout.imu_nodes)
    at_ends = layout.imu_nodes == ends  # an IMU at each section's end, in order
    t_rec = np.zeros(n_rec)
    nodes = np.zeros((n_rec, 3, n_elements + 1))
    directors = np.zeros((n_rec, n_imus, 3, 3))
    end_directors = None if at_ends else np.zeros((n_rec, len(ends), 3, 3))
    vel = np.zeros((n_rec, n_imus, 3))
    omega = np.zeros((n_rec, n_imus, 3))
    twist = np.zeros(n_rec)
    time = np.float64(0.0)
    for i in range(n_rec):
        if i > 0:
            for _ in range(per_record):
                time = stepper.step(sim, time, np.float64(s.sim_dt))
        check_rod_frame(
            rod.position_collection, rod.director_collection, rod.rest_lengths, float(time)
        )
        t_rec[i] = time
        nodes[i] = rod.position_collection
        for k, node in enumerate(layout.imu_nodes):
            directors[i, k] = rod.director_collection[:, :, node - 1]
            vel[i, k] = rod.velocity_collection[:, node]
            omega[i, k] = rod.omega_collection[:, node - 1]
        if end_directors is not None:
            for k, elem in enumerate(end_elems):
                end_directors[i, k] = rod.director_collection[:, :, elem]
        # total twist: the torsional curvature integrated along the rod
        twist[i] = float(np.sum(rod.kappa[2] * rod.rest_voronoi_lengths))
    return SectionTrajectory(t_rec, nodes, directors, vel, omega, twist, ends, end_directors)


def tangent_twist(traj: SectionTrajectory, bends: FloatArray) -> FloatArray:
    """Twist about the tangent (n, sections) rad at each section end: the angle about
    the tangent from the torsion-free PCC frame of the bends (which have the rod's true
    section-end tangents, :func:`pcc_truth`) to the rod's true frame there."""
    R_true = np.transpose(traj.section_directors, (0, 1, 3, 2))
    # frames do not use lengths
    R_pcc = section_frames_from_bends(bends, (1.0,) * R_true.shape[1])
    m = np.einsum("nkji,nkjl->nkil", R_pcc, R_true)  # rotation about z
    return np.asarray(np.arctan2(m[..., 1, 0], m[..., 0, 0]), dtype=float)


def pcc_truth(traj: SectionTrajectory, lengths: Sequence[float]) -> tuple[FloatArray, FloatArray]:
    """PCC bends (n, sections, 2) from the true section-end tangents, and the PCC
    forward kinematics' tip (n, 3) of those bends. Each section's bend turns the PCC
    (torsion-free) frame of the section before's end into its own true end tangent."""
    R_true = np.transpose(traj.section_directors, (0, 1, 3, 2))  # local-to-base
    n, n_sections = R_true.shape[:2]
    bends = np.zeros((n, n_sections, 2))
    bends[:, 0] = bend_from_tangent_frames(np.broadcast_to(np.eye(3), (n, 3, 3)), R_true[:, 0])
    R = rotation_bend(bends[:, 0, 0], bends[:, 0, 1])
    for k in range(1, n_sections):
        bends[:, k] = bend_from_tangent_frames(R, R_true[:, k])
        if k + 1 < n_sections:
            R = R @ rotation_bend(bends[:, k, 0], bends[:, k, 1])
    tip = pose_at(bends, lengths, n_sections - 1)[1]
    return bends, tip


def one_section_tip(traj: SectionTrajectory, total: float) -> FloatArray:
    """Tip (n, 3) of one arc of the whole length through the true tip tangent (a
    one-section model of the robot fed with the tip's tangent)."""
    R_tip = np.transpose(traj.section_directors[:, -1], (0, 2, 1))
    u = bend_from_tangent_frames(np.broadcast_to(np.eye(3), R_tip.shape), R_tip)
    return pose_at(u[:, None, :], [total], 0)[1]


def imu_samples(
    traj: SectionTrajectory,
    imu: ImuSettings,
    seed: int = 0,
    noise_seed: int | None = None,
    misalignment_axes: tuple[int, ...] = (0, 1, 2),
    errors_like: int | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.intp]]:
    """The IMUs every ``imu.sample_dt``, one at each element of ``traj.directors``:
    times (n,), specific force (n, m, 3) m/s^2, gyro (n, m, 3) rad/s (each in its own
    frame), and the trajectory indices.

    ``seed`` draws the IMUs' constant errors (misalignment, biases) and, unless
    ``noise_seed`` is given, their noise; with ``noise_seed`` the same constant errors
    come with fresh noise (the rest recording of the same IMUs). ``misalignment_axes``:
    the board axes (0 x, 1 y, 2 z) whose misalignment angle is kept (the others are
    drawn and zeroed, so the other errors stay the same; for studies).
    ``errors_like`` (with ``noise_seed``): the sample count of the recording whose
    constant errors to reproduce, when this trajectory has another (its noise draws lie
    between the constant errors' draws); default this trajectory's count."""
    rng = np.random.default_rng(seed)
    noise_rng = rng if noise_seed is None else np.random.default_rng(noise_seed)

    def noise(shape: tuple[int, ...]) -> FloatArray:
        # keeps the constant errors' draws in place
        n = rng.normal(size=shape if errors_like is None else (errors_like, *shape[1:]))
        return n if noise_seed is None else noise_rng.normal(size=shape)

    dt_rec = float(traj.t[1] - traj.t[0])
    step = max(1, int(round(imu.sample_dt / dt_rec)))
    lag = max(1, int(round(imu.dlpf_window / dt_rec)))
    idx = np.arange(0, len(traj.t), step)
    prev = np.maximum(idx - lag, 0)
    span = np.maximum((idx - prev) * dt_rec, dt_rec)
    n_imus = traj.directors.shape[1]
    f = np.zeros((len(idx), n_imus, 3))
    w = np.zeros((len(idx), n_imus, 3))
    for k in range(n_imus):
        acc = (traj.velocities[idx, k] - traj.velocities[prev, k]) / span[:, None]
        spec_base = acc - np.array([0.0, 0.0, -STANDARD_GRAVITY])
        keep = np.isin(np.arange(3), misalignment_axes)
        mis = _rotation_xyz(np.radians(imu.misalignment_deg) * rng.normal(size=3) * keep)
        spec = np.einsum("nij,nj->ni", traj.directors[idx, k], spec_base) @ mis
        spec = spec + imu.accel_bias * rng.normal(size=3) + imu.accel_noise * noise(spec.shape)
        f[:, k] = _quantise(spec, imu.accel_range, imu.bits)
        om = traj.omegas[idx, k] @ mis
        om = om + imu.gyro_bias * rng.normal(size=3) + imu.gyro_noise * noise(om.shape)
        w[:, k] = _quantise(om, imu.gyro_range, imu.bits)
    return traj.t[idx], f, w, idx


def at_rest(traj: SectionTrajectory) -> SectionTrajectory:
    """The rod held in its first recorded state (straight and still, before the
    couples act) for as long as ``traj``: what a rest recording of the same IMUs
    measures."""
    n = len(traj.t)

    def held(a: FloatArray) -> FloatArray:
        return np.repeat(a[:1], n, axis=0)

    still = np.zeros_like(traj.velocities)
    ends = None if traj.end_directors is None else held(traj.end_directors)
    return SectionTrajectory(
        traj.t, held(traj.nodes), held(traj.directors), still, still.copy(), held(traj.twist),
        traj.end_nodes, ends,
    )  # fmt: skip


def write_rest_recording(
    out: Path,
    name: str,
    traj: SectionTrajectory,
    imu: ImuSettings,
    seed: int = 0,
    misalignment_axes: tuple[int, ...] = (0, 1, 2),
) -> Path:
    """``NAME_rest.csv``: the recording's IMUs (the same misalignments and biases, fresh
    noise) with the rod straight and still, for ``continuum-mhe calibrate --from``."""
    t, f, w, _ = imu_samples(
        at_rest(traj), imu, seed, noise_seed=seed + 1_000_003, misalignment_axes=misalignment_axes
    )
    return _write_imu_table(out / f"{name}_rest.csv", t, f, w)


def _write_imu_table(path: Path, t: FloatArray, f: FloatArray, w: FloatArray) -> Path:
    """``t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,...`` (t from 0) of the IMUs' specific
    forces ``f`` and rates ``w`` (n, n_imus, 3)."""
    from continuum_mhe.io.estimate_csv import write_table
    from continuum_mhe.io.raw_imu import raw_columns

    n_imus = f.shape[1]
    cols = ["t", *(c for k in range(n_imus) for c in raw_columns(k, n_imus))]
    rows = np.column_stack([t - t[0]] + [np.hstack([f[:, k], w[:, k]]) for k in range(n_imus)])
    write_table(path, cols, (rows + 0.0).tolist())  # + 0.0: no "-0" cells
    return path


def recording_samples(settings: SectionRodSettings, duration: float, imu: ImuSettings) -> int:
    """The IMU sample count of a recording of ``duration`` s (as :func:`imu_samples`
    takes it from :func:`simulate_sections`' records, every 1 ms), without simulating."""
    per_record = max(1, int(round(RECORD_DT / settings.sim_dt)))
    n_rec = int(round(duration / (per_record * settings.sim_dt))) + 1
    step = max(1, int(round(imu.sample_dt / (per_record * settings.sim_dt))))
    return len(range(0, n_rec, step))


def bend_trajectory(
    settings: SectionRodSettings, duration: float = BEND_DURATION_S
) -> SectionTrajectory:
    """The rod bent slowly in the base x-z plane towards ``-x`` (``phi = 0``; base-frame
    couples, whatever the recording's drive) for ``duration`` s."""
    return simulate_sections(replace(settings, drive="base"), BEND, duration)


def write_bend_recording(
    out: Path,
    name: str,
    settings: SectionRodSettings,
    imu: ImuSettings,
    seed: int,
    samples_like: int,
    misalignment_axes: tuple[int, ...] = (0, 1, 2),
    duration: float = BEND_DURATION_S,
    trajectory: SectionTrajectory | None = None,
) -> Path:
    """``NAME_bend.csv``: the recording's IMUs (the constant errors of a recording of
    ``samples_like`` samples drawn from ``seed``; fresh noise) on the rod bent slowly in
    the base x-z plane towards ``-x`` (:func:`bend_trajectory`), for ``continuum-mhe
    calibrate --bend``. Simulates the rod for ``duration`` s, unless ``trajectory``
    gives that simulation."""
    traj = trajectory or bend_trajectory(settings, duration)
    t, f, w, _ = imu_samples(
        traj, imu, seed, noise_seed=seed + 2_000_003, misalignment_axes=misalignment_axes,
        errors_like=samples_like,
    )  # fmt: skip
    return _write_imu_table(out / f"{name}_bend.csv", t, f, w)


def recording_files(name: str, bend_only: bool = False) -> tuple[str, ...]:
    """The files a recording named ``name`` writes in its folder (the module docstring):
    ``NAME_bend.csv`` alone with ``bend_only``."""
    if bend_only:
        return (f"{name}_bend.csv",)
    kinds = ("raw.csv", "tilt.csv", "truth.csv", "info.json", "rest.csv", "bend.csv")
    return tuple(f"{name}_{kind}" for kind in kinds)


def write_bend_only(
    out: Path,
    name: str,
    settings: SectionRodSettings,
    duration: float,
    imu: ImuSettings = DEFAULT_IMU,
    seed: int = 0,
) -> Path:
    """``NAME_bend.csv`` alone (:func:`write_bend_recording`), with the IMUs' constant
    errors of a recording of ``duration`` s drawn from ``seed``, as
    :func:`write_section_recording` draws them, without simulating that recording; the
    folder ``out`` is made once the bend is simulated. Returns the file's path."""
    n = recording_samples(settings, duration, imu)
    bend = bend_trajectory(settings)
    out.mkdir(exist_ok=True)  # (as the tendon generator makes its folder)
    return write_bend_recording(out, name, settings, imu, seed, n, trajectory=bend)


def write_section_recording(
    out: Path,
    name: str,
    settings: SectionRodSettings,
    scenario: str,
    duration: float,
    imu: ImuSettings | None = None,
    seed: int = 0,
    bend_duration: float = BEND_DURATION_S,
    robot_name: str | None = None,
) -> dict[str, object]:
    """Simulate, sample and write the files (see the module docstring; the bend
    recording is a second simulation, ``bend_duration`` s; ``robot_name`` as
    :func:`write_trajectory_recording` takes it); returns the info (floor,
    one-section error, twist). Both simulations run before anything is written (a
    :class:`RodDivergedError` writes nothing); the folder ``out`` is made then, in a
    folder that exists (checked first: :func:`~continuum_mhe.io.output_files.
    check_new_folder`)."""
    from continuum_mhe.io.output_files import check_new_folder

    check_new_folder(out, overwrite=True, names=())
    traj = simulate_sections(settings, scenario, duration)
    bend = bend_trajectory(settings, bend_duration)
    out.mkdir(exist_ok=True)  # (as the tendon generator makes its folder)
    info = write_trajectory_recording(
        out, name, traj, settings, scenario, imu, seed, robot_name=robot_name
    )
    n = int(info["samples"])  # type: ignore[call-overload]
    write_bend_recording(out, name, settings, imu or DEFAULT_IMU, seed, n, trajectory=bend)
    return info


def write_trajectory_recording(
    out: Path,
    name: str,
    traj: SectionTrajectory,
    settings: SectionRodSettings,
    scenario: str,
    imu: ImuSettings | None = None,
    seed: int = 0,
    misalignment_axes: tuple[int, ...] = (0, 1, 2),
    robot_name: str | None = None,
) -> dict[str, object]:
    """The files of :func:`write_section_recording` from a simulated trajectory (so
    that one simulation can be sampled by several IMUs; ``misalignment_axes`` as in
    :func:`imu_samples`; ``robot_name``: the robot file as given, in the info as
    ``robot``, none for the shipped rod's settings)."""
    from continuum_mhe.io.csv_files import tilt_columns
    from continuum_mhe.io.estimate_csv import write_table
    from continuum_mhe.model.descriptions import output_names, pcc_outputs, section_end_columns
    from continuum_mhe.model.imu import tilt_from_accelerometer

    imu = imu or DEFAULT_IMU
    write_rest_recording(out, name, traj, imu, seed, misalignment_axes)
    t, f, w, idx = imu_samples(traj, imu, seed, misalignment_axes=misalignment_axes)
    t = t - t[0]
    bends, fk_tip = pcc_truth(traj, settings.lengths)
    nodes = traj.nodes[idx]
    tip = nodes[:, :, -1] - nodes[:, :, 0]
    ends = [nodes[:, :, end] - nodes[:, :, 0] for end in traj.end_nodes]
    _write_imu_table(out / f"{name}_raw.csv", t, f, w)
    tilt = np.hstack([tilt_from_accelerometer(f[:, k]) for k in range(f.shape[1])])
    write_table(
        out / f"{name}_tilt.csv",
        ["t", *tilt_columns(f.shape[1])],
        (np.column_stack([t, tilt]) + 0.0).tolist(),
    )
    b = bends[idx]
    theta = np.hypot(b[..., 0], b[..., 1])
    phi = np.where(theta > 0.0, np.arctan2(b[..., 1], b[..., 0]), 0.0)  # 0 when straight
    # the estimate's columns: on one section its bend as theta, phi (its end the tip's)
    n_sections = len(ends)
    names = output_names(pcc_outputs(n_sections))
    columns: dict[str, FloatArray] = dict(zip(("x", "y", "z"), tip.T))
    for k in range(n_sections):
        bend = ("theta", "phi") if n_sections == 1 else (f"theta_{k + 1}", f"phi_{k + 1}")
        columns.update(zip(bend, (theta[:, k], phi[:, k])))
        columns.update(zip(section_end_columns(k + 1), ends[k].T))
    truth = [t, *(columns[c] for c in names)]
    write_table(out / f"{name}_truth.csv", ["t", *names], (np.column_stack(truth) + 0.0).tolist())
    floor = np.linalg.norm(fk_tip[idx] - tip, axis=1) * 1e3
    one = np.linalg.norm(one_section_tip(traj, sum(settings.lengths))[idx] - tip, axis=1) * 1e3
    twist_t = np.degrees(np.abs(tangent_twist(traj, bends)[idx]))
    info: dict[str, object] = {
        "scenario": scenario,
        "imu": "calibrated" if imu == CALIBRATED_IMU else "default",
        "drive": settings.drive,
        "shear_ratio": settings.shear_ratio,
        "pcc_floor_mean_mm": float(floor.mean()),
        "pcc_floor_max_mm": float(floor.max()),
        "one_section_mean_mm": float(one.mean()),
        "one_section_max_mm": float(one.max()),
        "twist_max_deg": float(np.degrees(np.max(np.abs(traj.twist)))),
        "tangent_twist_max_deg": [float(twist_t[:, k].max()) for k in range(len(ends))],
        "tangent_twist_mean_deg": [float(twist_t[:, k].mean()) for k in range(len(ends))],
        "theta_max_deg": [float(np.degrees(theta[:, k].max())) for k in range(len(ends))],
        "samples": len(t),
    }
    if robot_name is not None:
        info["robot"] = robot_name
    (out / f"{name}_info.json").write_text(json.dumps(info, indent=2) + "\n")
    return info


def default_sim_dt(shear_ratio: float, element: float = BASE_ELEMENT_LENGTH) -> float:
    """A stable integration step (s) for a rod of ``shear_ratio`` G / E whose shortest
    element is ``element`` m long: the default rod's :data:`BASE_SIM_DT`, shortened as
    the torsional waves speed up (with the square root of G beyond E/3), with a tenth in
    hand: 7.3e-6 s at G = 2E and 4.6e-6 s at G = 5E, where 1e-5 and 5e-6 s were
    measured to run and 2e-5 s diverges at 5E; and in proportion to an element shorter
    than the default rod's :data:`BASE_ELEMENT_LENGTH` (the waves cross it sooner)."""
    if not shear_ratio > 0.0:
        raise UserError(f"shear_ratio must be > 0, got {shear_ratio!r}")
    ratio = (1.0 / 3.0) / shear_ratio
    dt = BASE_SIM_DT if ratio >= 1.0 else 0.9 * BASE_SIM_DT * math.sqrt(ratio)
    if element < (1.0 - 1e-9) * BASE_ELEMENT_LENGTH:
        dt *= element / BASE_ELEMENT_LENGTH
    return dt


if __name__ == "__main__":  # the generator's command is the command line's
    import sys

    print(
        "continuum-mhe: error: this module is not a command: run continuum-mhe rod sections",
        file=sys.stderr,
    )
    raise SystemExit(2)
