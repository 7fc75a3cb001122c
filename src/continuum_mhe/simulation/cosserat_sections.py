"""Ground truth the PCC model did not generate: a two-section Cosserat rod (PyElastica).

Robot: one elastic rod, base clamped, z up, under gravity, split into two sections
(default 0.16 m + 0.14 m, as ``two-section``). Each section is driven by its own
"tendon", modelled as a point couple at the section's end (a tendon terminated there
and routed along the backbone loads the rod with a couple ``tension x offset``), with
a servo-like profile. Scenarios:

* ``planar-s``: both couples about base x, opposite senses: section 1 bends one way,
  section 2 the other (an S-curve in the y-z plane);
* ``spatial``: the couples' axes turn about base z at different rates (bending planes
  turning at different rates), large enough for bends over 90 degrees per section.

Two drives (``SectionRodSettings.drive``):

* ``base``: the couples are fixed in the base frame. Where a section is already bent,
  part of a base-frame couple lies along its tangent and twists the rod (up to 120
  degrees at the tip on ``spatial`` with ``G = E/3``);
* ``tendon``: each couple is fixed in the frame of the element it acts on (a follower
  couple, as a tendon terminated there pulls), perpendicular to the tangent. Section
  2's couple is ``M_2`` and section 1's is ``M_1 - M_2``, so that section ``k``
  carries about the bending moment ``M_k`` in its own frame, as when section 2's
  tendon runs through section 1. The rod bends with little twist.

The shear modulus sets how much the rod twists under the couples (the PCC model has no
torsion): ``G = E/3`` (a plain elastomer rod) or ``G = 5 E`` (a robot built to resist
torsion). An MPU9250-like IMU sits at each section's end (specific force including its
own acceleration, DLPF, noise, bias, misalignment, 16-bit quantisation; gyro with noise
and bias), as in :mod:`continuum_mhe.simulation.cosserat`.

Outputs, per recording (``write_section_recording``):

* ``NAME_raw.csv``: ``t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,...`` (m/s^2, rad/s, each
  IMU in its own frame, z along the backbone);
* ``NAME_tilt.csv``: ``t,roll_1,pitch_1,roll_2,pitch_2`` from the accelerometers;
* ``NAME_truth.csv``: ``t,x,y,z`` (the rod's tip) and per section ``theta_k, phi_k``
  (the PCC bends of the true section-end tangents) and ``x_k,y_k,z_k`` (the rod's true
  section ends);
* ``NAME_info.json``: the PCC-model floor (tip error of the PCC forward kinematics of
  the true section-end tangents), a one-section model's error (the whole robot as one
  arc through the tip tangent), the rod's total material twist, and the twist about
  the tangent at each section end (the angle about the tangent between the rod's true
  frame there and the torsion-free PCC frame of the same tangents: what an IMU there
  sees and the PCC model cannot explain);
* ``NAME_rest.csv``: the same two IMUs (the same misalignments and biases, fresh noise)
  with the rod straight and still, as long as the recording: the rest period a user
  records before a run, for ``continuum-mhe calibrate --from NAME_rest.csv --robot
  two-section`` (the mounting ``mount_rpy`` of each IMU for the robot file);
* ``NAME_bend.csv``: the same two IMUs (the same misalignments and biases, fresh noise)
  with the rod bent slowly in the base x-z plane towards ``-x`` (``phi = 0``): a
  base-frame couple about ``-y`` at each section's end, ramped up over 2 s and held
  (5 s; no twist), for ``continuum-mhe calibrate --from NAME_rest.csv --bend
  NAME_bend.csv`` (each IMU's yaw about the tangent).

Regenerate (needs the ``rod`` extra)::

    continuum-mhe rod sections --scenario planar-s -o DIR
    continuum-mhe rod sections --scenario spatial -o DIR
    continuum-mhe rod sections --scenario spatial -o DIR \
        --shear-ratio 5 --sim-dt 5e-6 --name spatial-stiff-torsion
    continuum-mhe rod sections --scenario spatial -o DIR \
        --drive tendon --name spatial-tendon

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
    """The two-section rod and its actuation.

    Attributes:
        lengths: section lengths, m.
        radius: m; youngs_modulus: Pa; shear_ratio: G / E (1/3 or 5); density: kg/m^3.
        imu_mass: each IMU board, kg.
        n_elements: Cosserat elements; every section must be a whole number of them.
        damping: uniform linear damping constant, 1/s; sim_dt: integration step, s.
        max_moment: each section's largest couple, N m.
        period: one pull-hold-release-rest cycle, s.
        drive: ``"base"`` (couples fixed in the base frame) or ``"tendon"`` (each
            couple fixed in the frame of the element it acts on); see the module.
        tendon_gain: the tendon drive's section moments ``M_1, M_2`` at full pull, in
            units of ``max_moment`` (bends to 124 and 113 degrees on ``spatial``).
    """

    lengths: tuple[float, float] = (0.16, 0.14)
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

    def __post_init__(self) -> None:
        if self.drive not in DRIVES:
            raise ValueError(f"drive must be one of {DRIVES}, got {self.drive!r}")


@dataclass(frozen=True)
class SectionTrajectory:
    """Rod states every ``record_dt``: times (n,), nodes (n, 3, k+1), the directors
    (n, m, 3, 3) of the m elements that carry an IMU (the two rods' those ending each
    section), the velocities (n, m, 3) of the nodes that end them, the angular
    velocities (n, m, 3) of those elements (their frame), the total twist (n,) rad, and
    those nodes' indices."""

    t: FloatArray
    nodes: FloatArray
    directors: FloatArray
    velocities: FloatArray
    omegas: FloatArray
    twist: FloatArray
    end_nodes: tuple[int, ...]


def couples(scenario: str, t: float, s: SectionRodSettings) -> tuple[FloatArray, FloatArray]:
    """The couples (N m) at the ends of section 1 and section 2 at ``t``: in the base
    frame for the ``base`` drive, in the frame of the end element for ``tendon``.

    Section 1 carries both couples, section 2 only its own; ``planar-s`` gives section 1
    the net moment ``+m`` and section 2 ``-m`` about base x.
    """
    if scenario == BEND:  # about -y: both sections bend towards -x (phi = 0)
        ramp = 0.5 * (1 - math.cos(math.pi * min(t / BEND_RAMP_S, 1.0)))
        c = np.array([0.0, -BEND_MOMENT * s.max_moment * ramp, 0.0])
        return c, c.copy()
    m = s.max_moment * float(servo_profile(t, s.period))
    if s.drive == "tendon":
        return tendon_couples(scenario, t, m, s)
    if scenario == "planar-s":
        return np.array([2.0 * m, 0.0, 0.0]), np.array([-m, 0.0, 0.0])
    a1, a2 = 2 * np.pi * t / 9.0, -2 * np.pi * t / 5.0 + 1.0
    m2 = 1.3 * m * np.array([math.cos(a2), math.sin(a2), 0.0])
    net1 = 1.3 * m * np.array([math.cos(a1), math.sin(a1), 0.0])
    return net1 - m2, m2


def tendon_couples(
    scenario: str, t: float, m: float, s: SectionRodSettings
) -> tuple[FloatArray, FloatArray]:
    """Follower couples (each in its element's frame, N m) for the section moments
    ``M_k = gain_k m e(alpha_k)`` perpendicular to the tangent, ``e(alpha) = (cos alpha,
    sin alpha, 0)``: section 1's end gets ``M_1 - M_2``, the tip ``M_2``. ``planar-s``:
    ``alpha_1 = 0``, ``alpha_2 = pi`` (an S); ``spatial``: the bending planes turn at
    ``2 pi / 9`` and ``-2 pi / 5`` rad/s, as in the base drive."""
    if scenario == "planar-s":
        a1, a2 = 0.0, math.pi
    else:
        a1, a2 = 2 * np.pi * t / 9.0, -2 * np.pi * t / 5.0 + 1.0
    g1, g2 = s.tendon_gain
    m1 = g1 * m * np.array([math.cos(a1), math.sin(a1), 0.0])
    m2 = g2 * m * np.array([math.cos(a2), math.sin(a2), 0.0])
    return m1 - m2, m2


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
    total = sum(s.lengths)
    e1 = int(round(s.n_elements * s.lengths[0] / total))
    if abs(e1 * total / s.n_elements - s.lengths[0]) > 1e-9:
        raise UserError(
            f"{s.n_elements} elements do not split the rod at {s.lengths[0]} m: choose "
            "n_elements so that every section is a whole number of elements"
        )
    ends = (e1, s.n_elements)  # node indices of the section ends

    class _Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    class _Couples(ea.NoForces):
        def apply_torques(self, system: object, time: float = 0.0) -> None:
            # PyElastica's external torques are in each element's own frame
            c1, c2 = couples(scenario, float(time), s)
            if s.drive == "base":
                q = system.director_collection  # type: ignore[attr-defined]
                c1, c2 = q[:, :, e1 - 1] @ c1, q[:, :, -1] @ c2
            system.external_torques[:, e1 - 1] += c1  # type: ignore[attr-defined]
            system.external_torques[:, -1] += c2  # type: ignore[attr-defined]

    sim = _Sim()
    rod = ea.CosseratRod.straight_rod(
        s.n_elements,
        np.zeros(3),
        np.array([0.0, 0.0, 1.0]),
        np.array([1.0, 0.0, 0.0]),
        total,
        s.radius,
        s.density,
        youngs_modulus=s.youngs_modulus,
        shear_modulus=s.youngs_modulus * s.shear_ratio,
    )
    rod.mass[e1] += s.imu_mass
    rod.mass[-1] += s.imu_mass
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
    t_rec = np.zeros(n_rec)
    nodes = np.zeros((n_rec, 3, s.n_elements + 1))
    directors = np.zeros((n_rec, 2, 3, 3))
    vel = np.zeros((n_rec, 2, 3))
    omega = np.zeros((n_rec, 2, 3))
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
        for k, (node, elem) in enumerate(((e1, e1 - 1), (s.n_elements, s.n_elements - 1))):
            directors[i, k] = rod.director_collection[:, :, elem]
            vel[i, k] = rod.velocity_collection[:, node]
            omega[i, k] = rod.omega_collection[:, elem]
        # total twist: the torsional curvature integrated along the rod
        twist[i] = float(np.sum(rod.kappa[2] * rod.rest_voronoi_lengths))
    return SectionTrajectory(t_rec, nodes, directors, vel, omega, twist, ends)


def tangent_twist(traj: SectionTrajectory, bends: FloatArray) -> FloatArray:
    """Twist about the tangent (n, 2) rad at each section end: the angle about the
    tangent from the torsion-free PCC frame of the bends (which have the rod's true
    section-end tangents, :func:`pcc_truth`) to the rod's true frame there."""
    R_true = np.transpose(traj.directors, (0, 1, 3, 2))
    R_pcc = section_frames_from_bends(bends, (1.0, 1.0))  # frames do not use lengths
    m = np.einsum("nkji,nkjl->nkil", R_pcc, R_true)  # rotation about z
    return np.asarray(np.arctan2(m[..., 1, 0], m[..., 0, 0]), dtype=float)


def pcc_truth(traj: SectionTrajectory, lengths: Sequence[float]) -> tuple[FloatArray, FloatArray]:
    """PCC bends (n, 2, 2) from the true section-end tangents, and the PCC forward
    kinematics' tip (n, 3) of those bends. Section 2's bend turns the PCC (torsion-free)
    frame of section 1's end into section 2's true end tangent."""
    R_true = np.transpose(traj.directors, (0, 1, 3, 2))  # local-to-base
    n = len(traj.t)
    bends = np.zeros((n, 2, 2))
    bends[:, 0] = bend_from_tangent_frames(np.broadcast_to(np.eye(3), (n, 3, 3)), R_true[:, 0])
    R1 = rotation_bend(bends[:, 0, 0], bends[:, 0, 1])
    bends[:, 1] = bend_from_tangent_frames(R1, R_true[:, 1])
    tip = pose_at(bends, lengths, 1)[1]
    return bends, tip


def one_section_tip(traj: SectionTrajectory, total: float) -> FloatArray:
    """Tip (n, 3) of one arc of the whole length through the true tip tangent (a
    one-section model of the robot fed with the tip IMU's tangent)."""
    R_tip = np.transpose(traj.directors[:, 1], (0, 2, 1))
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
    """The IMUs every ``imu.sample_dt``, one at each element of ``traj.directors`` (two
    for the rods' sections): times (n,), specific force (n, m, 3) m/s^2, gyro (n, m, 3)
    rad/s (each in its own frame), and the trajectory indices.

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
    return SectionTrajectory(
        traj.t, held(traj.nodes), held(traj.directors), still, still.copy(), held(traj.twist),
        traj.end_nodes,
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
) -> dict[str, object]:
    """Simulate, sample and write the files (see the module docstring; the bend
    recording is a second simulation, ``bend_duration`` s); returns the info (floor,
    one-section error, twist). Both simulations run before anything is written (a
    :class:`RodDivergedError` writes nothing); the folder ``out`` is made then, in a
    folder that exists (checked first: :func:`~continuum_mhe.io.output_files.
    check_new_folder`)."""
    from continuum_mhe.io.output_files import check_new_folder

    check_new_folder(out, overwrite=True, names=())
    traj = simulate_sections(settings, scenario, duration)
    bend = bend_trajectory(settings, bend_duration)
    out.mkdir(exist_ok=True)  # (as the tendon generator makes its folder)
    info = write_trajectory_recording(out, name, traj, settings, scenario, imu, seed)
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
) -> dict[str, object]:
    """The files of :func:`write_section_recording` from a simulated trajectory (so
    that one simulation can be sampled by several IMUs; ``misalignment_axes`` as in
    :func:`imu_samples`)."""
    from continuum_mhe.io.csv_files import tilt_columns
    from continuum_mhe.io.estimate_csv import write_table
    from continuum_mhe.model.descriptions import output_names, pcc_outputs
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
    truth_cols = ["t", *output_names(pcc_outputs(len(ends)))]  # the estimate's columns
    truth = [t, *tip.T]
    for k in range(len(ends)):
        truth += [theta[:, k], phi[:, k], *ends[k].T]
    write_table(out / f"{name}_truth.csv", truth_cols, (np.column_stack(truth) + 0.0).tolist())
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
    (out / f"{name}_info.json").write_text(json.dumps(info, indent=2) + "\n")
    return info


def default_sim_dt(shear_ratio: float) -> float:
    """A stable integration step (s) for a rod of ``shear_ratio`` G / E: the default
    rod's :data:`BASE_SIM_DT`, shortened as the torsional waves speed up (with the
    square root of G beyond E/3), with a tenth in hand: 7.3e-6 s at G = 2E and 4.6e-6 s
    at G = 5E, where 1e-5 and 5e-6 s were measured to run and 2e-5 s diverges at 5E."""
    if not shear_ratio > 0.0:
        raise UserError(f"shear_ratio must be > 0, got {shear_ratio!r}")
    ratio = (1.0 / 3.0) / shear_ratio
    return BASE_SIM_DT if ratio >= 1.0 else 0.9 * BASE_SIM_DT * math.sqrt(ratio)


if __name__ == "__main__":  # the generator's command is the command line's
    import sys

    print(
        "continuum-mhe: error: this module is not a command: run continuum-mhe rod sections",
        file=sys.stderr,
    )
    raise SystemExit(2)
