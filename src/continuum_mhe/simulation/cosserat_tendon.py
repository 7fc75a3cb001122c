"""Recordings of a tendon-driven robot that its estimator's model did not generate.

Any robot file with a ``[backbone]``, ``[[tendon]]``s and spacer disks, standing on its
base (``z-up``), its IMUs on the discrete rod's nodes (a disk, or a section's end) in
their disks' frames; by default the robot of ``tendon-two-section`` (docs/tendon.md): a
nitinol-like rod (0.2 m + 0.2 m, E = 54 GPa, G = 20.77 GPa, radius 0.7 mm, density 6450
kg/m^3, under gravity, base clamped, z up), three tendons per section at 10 mm (section
1's at 0, 120 and 240 degrees, section 2's at 60, 180 and 300), an IMU at each
section's end, 50 Hz. The motions' tensions are sized for that robot: the tip section's
tendons pull as its section 2's, every other section's as its section 1's.

The recordings are the quasi-static equilibria of a discrete rod whose energy is
minimised (:func:`energy_equilibrium`, IPOPT, warm-started every 20 ms): inextensible,
bending and twisting, each tendon a polyline through every segment's end at its radius
whose tension's potential is ``tension * length``, the tip force's ``-F . p_tip`` and
the backbone's weight. Energy on a discrete rod, not the forces of the shooting model
of :mod:`continuum_mhe.model.tendon`. A tip force acts on the last node, in the base
frame. Each IMU's specific force includes its own acceleration (the equilibria's
central differences).

Scenarios (``SCENARIOS``):

* ``unloaded``: each section's tendons pull ``T_k (1 + cos(alpha_i - beta_k))`` (so the
  tendon opposite the bend goes slack), with the bending directions ``beta_k`` turning
  at different rates; bends past 90 degrees; no tip force.
* ``planar-s``: the two sections bent in one vertical plane the opposite ways (an S),
  the S swinging through straight to its mirror image and back (each tendon
  ``T_k (1 +- s(t) cos(alpha_i - beta))`` with ``s`` a sine of period
  :data:`PLANAR_S_PERIOD`, so the tendons on the bend's outside go nearly slack at the
  largest bends, about 60 degrees a section); no tip force.
* ``force-08`` and ``force-29``: moderate tendon bends and a tip force turning in the
  horizontal plane with a vertical part, up to 0.08 N and 0.29 N in magnitude.
* ``twist-08`` and ``twist-29``: both sections bent the same way (past 90 degrees in
  section 1), the bending plane turning slowly, and a tip force across the bending plane
  swinging from one side to the other, up to 0.08 N and 0.29 N: the backbone twists
  about 21 and 50 degrees.
* ``static``: constant tensions and a 0.05 N tip force along x after the ramp (the
  static equilibrium the tests compare with).

Files, per recording (``write_tendon_recording``): ``NAME_raw.csv`` (as the rod
generators', IMU noise and biases as theirs), ``NAME_tilt.csv``, ``NAME_tensions.csv``
(``t,tension_1..6``, N), ``NAME_truth.csv`` (``t,x,y,z``, per section ``theta_k,
phi_k, x_k, y_k, z_k, psi_k``, then ``fx,fy,fz``: the columns of the tendon
formulation's estimates), ``NAME_info.json`` (the largest bends, twist and force) and
``NAME_rest.csv`` (the same IMUs, their misalignments and biases, with the rod straight,
unloaded and still, fresh noise: for ``continuum-mhe calibrate --from``; every recording
of one seed and IMU settings has the same IMUs).

Regenerate (CasADi and its IPOPT, no extra)::

    continuum-mhe rod tendon --scenario unloaded -o DIR
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.io.position_units import WRAPPED_BEND_DEG
from continuum_mhe.model.descriptions import tendon_outputs
from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.model.robot import Robot
from continuum_mhe.simulation.cosserat import ImuSettings
from continuum_mhe.simulation.cosserat_sections import (
    DEFAULT_IMU,
    SectionTrajectory,
    check_standing_robot,
    imu_samples,
    write_rest_recording,
)

SCENARIOS = ("unloaded", "planar-s", "force-08", "force-29", "twist-08", "twist-29", "static")
#: The equilibria's spacing, s (:func:`quasi_static_trajectory`), the IMUs' sample time.
RECORD_DT = 2e-2
#: The quasi-static peer's segments per disk: its section ends converge as ``ds^2``;
#: at 2 the tip of a 120-degree bend is 0.3 to 0.7 mm from the converged rod's, at 4
#: about 0.1 mm, at 8 a few hundredths.
SEGMENTS_PER_DISK = 4


#: ``planar-s``: the period of the S's swing, s, and its plane's angle from the base x
#: axis, rad.
PLANAR_S_PERIOD = 6.0
PLANAR_S_PLANE = 0.4


@dataclass(frozen=True)
class TendonRodSettings:
    """The simulated robot and its numerics. Each pair is (every section but the tip
    section, the tip section): ``tendon-two-section``'s section 1 and 2.

    Attributes:
        tension: largest ``T_k`` per section, N (``unloaded``).
        loaded_tension: ``T_k`` on the loaded recordings, N.
        twist_tension: ``T_k`` on the twisting recordings, N, per peak force
            (``twist-08``, ``twist-29``).
        s_tension: ``T_k`` per section on ``planar-s``, N (the first section's
            twice the second's: the second section's tendons bend the first one too).
        ramp: s over which the tendons and the force come up from zero.
    """

    tension: tuple[float, float] = (1.0, 6.0)
    loaded_tension: tuple[float, float] = (1.0, 1.5)
    twist_tension: tuple[tuple[float, float], tuple[float, float]] = ((3.4, 1.5), (3.5, 1.8))
    s_tension: tuple[float, float] = (7.0, 3.5)
    ramp: float = 3.0


def _tip_role(k: int, n_sections: int) -> int:
    """Which of a pair of :class:`TendonRodSettings` section ``k`` (0-based) of
    ``n_sections`` takes: 1 for the tip section, 0 for every other."""
    return 1 if k == n_sections - 1 else 0


def _bending_direction(scenario: str, k: int, n_sections: int, t: float) -> float:
    """Section ``k``'s bending direction (rad from the base x axis) at ``t``: the base
    section's and the tip section's turn the opposite ways at different rates (every
    section between them as the base section's, a radian further on per section); on
    ``static`` the tip section's is 1 rad, every other's 0; on the twisting motions
    every section's is the turning plane's."""
    if scenario.startswith("twist-"):
        return _twist_plane(t)
    role = _tip_role(k, n_sections)
    if scenario == "static":
        return (0.0, 1.0)[role]
    if role == 1:
        return -2 * math.pi * t / 7.0 + 1.0
    return 2 * math.pi * t / 11.0 + float(k)


def tension_profile(robot: Robot, scenario: str, t: float, s: TendonRodSettings) -> FloatArray:
    """The tendons' tensions at ``t`` (N, in the robot's tendon order)."""
    ramp = 0.5 * (1 - math.cos(math.pi * min(t / s.ramp, 1.0)))
    amp = s.tension if scenario == "unloaded" else s.loaded_tension
    if scenario.startswith("twist-"):
        amp = s.twist_tension[scenario == "twist-29"]
    n = robot.n_sections
    out = np.zeros(robot.n_tendons)
    if scenario == "planar-s":
        swing = math.sin(2 * math.pi * t / PLANAR_S_PERIOD)
        for i, td in enumerate(robot.tendons):
            side = -1.0 if td.section % 2 else 1.0  # each section bends back from the last
            bend = side * swing * math.cos(td.angle - PLANAR_S_PLANE)
            out[i] = ramp * s.s_tension[_tip_role(td.section, n)] * (1 + bend)
        return out
    for i, td in enumerate(robot.tendons):
        k = td.section
        beta = _bending_direction(scenario, k, n, t)
        out[i] = ramp * amp[_tip_role(k, n)] * (1 + math.cos(td.angle - beta))
    return out


def _twist_plane(t: float) -> float:
    """The bending plane's angle, rad from the base x axis, on the twisting recordings."""
    return 0.3 + 2 * math.pi * t / 24.0


def tip_force(scenario: str, t: float, s: TendonRodSettings) -> FloatArray:
    """The tip force at ``t``, N, base frame."""
    if scenario in ("unloaded", "planar-s"):
        return np.zeros(3)
    peak = 0.08 if scenario in ("force-08", "twist-08") else 0.29
    ramp = 0.5 * (1 - math.cos(math.pi * min(t / s.ramp, 1.0)))
    if scenario.startswith("twist-"):
        # across the bending plane, swinging from one side to the other
        b = _twist_plane(t)
        swing = math.sin(2 * math.pi * t / 5.0)
        return ramp * peak * swing * np.array([-math.sin(b), math.cos(b), 0.0])
    if scenario == "static":
        return ramp * np.array([0.05, 0.0, 0.0])
    a = 2 * math.pi * t / 9.0
    return ramp * peak * np.array([0.8 * math.cos(a), 0.8 * math.sin(a), 0.6])


@dataclass(frozen=True)
class TendonTrajectory:
    """The rod every ``record_dt``: the trajectory of its IMUs' elements (for the IMUs:
    :func:`~continuum_mhe.simulation.cosserat_sections.imu_samples`), the directors of
    the elements ending each section (n, k, 3, 3) and those ends' node indices, and the
    tensions (n, m) and tip force (n, 3) applied."""

    sections: SectionTrajectory
    directors: FloatArray
    end_nodes: tuple[int, ...]
    tensions: FloatArray
    force: FloatArray


def imu_elements(robot: Robot, segments_per_disk: int) -> tuple[int, ...]:
    """The discrete rod's element (0-based, from the base) whose end carries each IMU of
    ``robot``, in its order: ``segments_per_disk`` elements between two disks. A
    :class:`~continuum_mhe.errors.UserError` for an IMU between two of the rod's nodes
    (the generator places each IMU on a node: a disk, or a section's end)."""
    out = []
    for k, imu in enumerate(robot.imus):
        sec = robot.sections[imu.section]
        along = imu.at * segments_per_disk * sec.disks
        if abs(along - round(along)) > 1e-6 or round(along) < 1:
            raise UserError(
                f"IMU {k + 1} at {imu.at:g} of section {imu.section + 1} lies between the "
                "generator's rod nodes: place it on a disk (disk = d in the robot file) or "
                "at the section's end"
            )
        before = sum(segments_per_disk * s.disks for s in robot.sections[: imu.section])
        out.append(before + int(round(along)) - 1)
    return tuple(out)


def check_generated_robot(robot: Robot) -> None:
    """A :class:`~continuum_mhe.errors.UserError` for a robot whose recordings this
    generator does not write: one without tendons or a backbone, one not standing on its
    base (``z-up``), an IMU turned on its disk (a ``mount_rpy``) or between two disks
    (:func:`imu_elements`), a section without spacer disks."""
    if not robot.tendons or robot.backbone is None:
        raise UserError(
            f"the tendon-robot generator writes robots with a [backbone] and [[tendon]]s "
            f"(as tendon-two-section), not {robot.describe()}"
        )
    check_standing_robot(robot, "tendon-robot", "disk's")
    for k, section in enumerate(robot.sections):
        if section.disks < 1:
            raise UserError(
                f"section {k + 1} has no spacer disks: the generator's rod has four "
                "segments per disk; give the section's disks (disks = 10 in "
                "tendon-two-section; the estimators' model takes the tendons as continuous "
                "and does not need them)"
            )
    imu_elements(robot, 1)  # each IMU on a disk or a section's end


def record_times(duration: float, record_dt: float) -> FloatArray:
    """The times (s) the rod is recorded at: every ``record_dt`` from 0 to ``duration``."""
    return np.arange(int(round(duration / record_dt)) + 1, dtype=np.float64) * record_dt


def check_tensions_estimable(
    robot: Robot,
    scenario: str,
    duration: float,
    settings: TendonRodSettings | None = None,
    robot_name: str = "tendon-two-section",
) -> None:
    """A one-line :class:`~continuum_mhe.errors.UserError` naming ``robot_name`` (as
    given), before anything is
    simulated, where the motion's tensions (sized for ``tendon-two-section``) would bend
    a section of ``robot`` through more turns than ``estimate`` takes from a tensions
    file (:func:`~continuum_mhe.io.tensions.tension_turns`): a robot far softer, or with
    tendons further out, curls through them, and the truth's bend angles (at most 180
    degrees) would hide it."""
    from continuum_mhe.io.tensions import MAX_TENDON_TURNS, tension_turns

    s = settings or TendonRodSettings()
    t = record_times(duration, RECORD_DT)
    tensions = np.array([tension_profile(robot, scenario, float(tk), s) for tk in t])
    beyond = tension_turns(robot, tensions)
    if beyond is not None:
        i, k, turns = beyond
        raise UserError(
            f"{robot_name}: --scenario {scenario}: its tensions, sized for "
            f"tendon-two-section, would bend section {k + 1} through {turns:.3g} full turns at t = "
            f"{t[i]:g} s, more than estimate takes from a tensions file ({MAX_TENDON_TURNS:g}); "
            "a stiffer backbone, or tendons nearer to it, bend less; nothing simulated"
        )


class EquilibriumError(RuntimeError):
    """The discrete rod's energy minimisation (:func:`energy_equilibrium`) did not
    converge."""


def straight_phi(theta: float, phi: float) -> float:
    """A section's ``phi``, 0 where it is straight (``theta = 0``: the bend's direction
    is undefined there, and ``atan2(-0, -0)`` gives -pi), as docs/formats.md has it."""
    return phi if theta > 0.0 else 0.0


def truth_columns(n_sections: int) -> list[str]:
    """The truth file's columns: those of the tendon formulation's outputs."""
    return ["t", *(o.name for o in tendon_outputs(n_sections))]


def recording_files(name: str) -> tuple[str, ...]:
    """The files a recording named ``name`` writes in its folder (the module docstring)."""
    kinds = ("raw.csv", "tilt.csv", "tensions.csv", "truth.csv", "info.json", "rest.csv")
    return tuple(f"{name}_{kind}" for kind in kinds)


def write_tendon_recording(
    out: Path,
    name: str,
    robot: Robot,
    scenario: str,
    duration: float,
    settings: TendonRodSettings | None = None,
    seed: int = 0,
    imu: ImuSettings = DEFAULT_IMU,
    segments_per_disk: int = SEGMENTS_PER_DISK,
    trajectory: TendonTrajectory | None = None,
    robot_name: str = "tendon-two-section",
    route: str = "continuous",
) -> dict[str, object]:
    """Simulate, sample and write the files (see the module docstring); returns the
    info. ``imu``: the IMUs' errors (``seed`` draws them); ``segments_per_disk``: the
    discrete rod's resolution (:func:`quasi_static_trajectory`); ``trajectory``: that
    trajectory, already computed (the same motion with the errors of another seed);
    ``robot_name``: the robot as the info names it; ``route``: the tendons' path
    (:func:`_energy_solver`: ``"continuous"``, the estimators' model's, or ``"disks"``,
    straight from disk to disk). A robot it does not write
    (:func:`check_generated_robot`) is a
    :class:`~continuum_mhe.errors.UserError`; an equilibrium not found, an
    :class:`EquilibriumError`. The folder ``out`` is made once the rod is simulated, in
    a folder that exists (checked first: :func:`~continuum_mhe.io.output_files.
    check_new_folder`)."""
    import casadi as ca

    from continuum_mhe.io.csv_files import tilt_columns
    from continuum_mhe.io.estimate_csv import write_table
    from continuum_mhe.io.output_files import check_new_folder
    from continuum_mhe.io.raw_imu import raw_columns
    from continuum_mhe.model.imu import tilt_from_accelerometer
    from continuum_mhe.model.tendon_statics import swing_twist_sym

    check_generated_robot(robot)
    check_new_folder(out, overwrite=True, names=())
    if trajectory is None:
        check_tensions_estimable(robot, scenario, duration, settings, robot_name)
    traj = trajectory or quasi_static_trajectory(
        robot, scenario, duration, settings, segments_per_disk=segments_per_disk, route=route
    )
    sec = traj.sections
    t, f, w, idx = imu_samples(sec, imu, seed)
    t = t - t[0]
    out.mkdir(exist_ok=True)
    n_imus = f.shape[1]
    cols = ["t", *(c for k in range(n_imus) for c in raw_columns(k, n_imus))]
    raw = np.column_stack([t] + [np.hstack([f[:, k], w[:, k]]) for k in range(n_imus)])
    # (+ 0.0 after rounding: a tiny negative value is written 0, not "-0")
    write_table(out / f"{name}_raw.csv", cols, (np.round(raw, 6) + 0.0).tolist())
    tilt = np.hstack([tilt_from_accelerometer(f[:, k]) for k in range(n_imus)])
    write_table(
        out / f"{name}_tilt.csv",
        ["t", *tilt_columns(n_imus)],
        (np.round(np.column_stack([t, tilt]), 6) + 0.0).tolist(),
    )
    tcols = ["t"] + [f"tension_{i}" for i in range(1, robot.n_tendons + 1)]
    write_table(
        out / f"{name}_tensions.csv",
        tcols,
        (np.round(np.column_stack([t, traj.tensions[idx]]), 6) + 0.0).tolist(),
    )
    Q = ca.SX.sym("Q", 3, 3)
    swing = ca.Function("swing", [Q], [ca.vertcat(*swing_twist_sym(Q))])
    truth = []
    n_sections = robot.n_sections
    for j in idx:
        row: list[float] = list(sec.nodes[j, :, -1] - sec.nodes[j, :, 0])
        R_prev = np.eye(3)
        for k in range(n_sections):
            R = traj.directors[j, k].T  # local-to-base
            th, ph, ps = np.asarray(swing(R_prev.T @ R), dtype=float).ravel()
            ph = straight_phi(th, ph)
            p = sec.nodes[j, :, traj.end_nodes[k]] - sec.nodes[j, :, 0]
            row += [th, ph, *p, ps]
            R_prev = R
        row += list(traj.force[j])
        truth.append(row)
    tr = np.column_stack([t, np.array(truth)])
    columns = truth_columns(n_sections)
    write_table(out / f"{name}_truth.csv", columns, (np.round(tr, 7) + 0.0).tolist())
    theta_cols = [columns.index(f"theta_{k + 1}") for k in range(n_sections)]
    psi = tr[:, [columns.index(f"psi_{k + 1}") for k in range(n_sections)]]
    # (theta is the swing of the section end's frame, at most 180 degrees: a bend past
    # 180 folds back below it, and is seen as it passes through 170 to 180 degrees)
    for k, c in enumerate(theta_cols):
        bend = math.degrees(float(tr[:, c].max()))
        if bend > WRAPPED_BEND_DEG:
            warnings.warn(
                f"section {k + 1} bends to {bend:.0f} degrees under the motion's tensions "
                f"(sized for tendon-two-section): a section's bend angle (theta_{k + 1} of "
                "the truth file, from its end's frame) cannot describe a bend past 180 "
                "degrees, and evaluate's check of the truth's angles against its positions "
                "fails there; a stiffer backbone, or tendons nearer to it, bend less",
                UserWarning,
                stacklevel=2,
            )
    info: dict[str, object] = {
        "scenario": scenario,
        "robot": robot_name,
        "samples": len(t),
        "theta_max_deg": [float(np.degrees(tr[:, c].max())) for c in theta_cols],
        "twist_max_deg": [float(np.degrees(np.abs(psi[:, k]).max())) for k in range(n_sections)],
        "force_max_n": float(np.linalg.norm(traj.force, axis=1).max()),
        "tension_max_n": float(traj.tensions.max()),
        "route": route,
    }
    (out / f"{name}_info.json").write_text(json.dumps(info, indent=2) + "\n")
    write_rest_recording(out, name, sec, imu, seed)  # the first state: straight and still
    return info


#: The longest recording, s: an equilibrium every 20 ms, each some 60 ms of IPOPT, so
#: 600 s (30,000 equilibria) runs for half an hour; past 1e6 s or so the arrays of the
#: tensions and states do not fit in memory (1e9 s: a numpy memory error).
MAX_DURATION_S = 600.0


# --- the quasi-static peer: a discrete rod's energy minimised -----------------------------
def _rotvec_sym(w: Any) -> Any:
    """Rotation matrix of a rotation vector (CasADi SX), Rodrigues' formula with a
    smooth series near zero."""
    import casadi as ca

    th2 = ca.sumsqr(w) + 1e-30
    th = ca.sqrt(th2)
    a = ca.if_else(th2 < 1e-8, 1 - th2 / 6, ca.sin(th) / th)
    b = ca.if_else(th2 < 1e-8, 0.5 - th2 / 24, (1 - ca.cos(th)) / th2)
    K = ca.vertcat(
        ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]), ca.horzcat(-w[1], w[0], 0)
    )
    return ca.SX.eye(3) + a * K + b * ca.mtimes(K, K)


_SOLVERS: dict[tuple[Robot, int, str], Any] = {}


def _energy_solver(robot: Robot, per: int, route: str = "continuous") -> Any:
    """The IPOPT solver of a discrete inextensible rod's total energy: each of ``per``
    segments per disk turns by a rotation vector ``w_j`` from the one before (bending
    energy ``EI/2 (w_x^2 + w_y^2)/ds``, torsion ``GJ/2 w_z^2/ds``); each tendon a
    polyline at its offset in the frames it passes (every segment's end:
    ``route="continuous"``, Rucker and Webster's routing in the limit; or only the
    disks' with ``"disks"``, straight from disk to disk), whose tension's potential is
    ``tension * length``; the tip force's ``-F . p_tip``; the weight's ``rho A g z`` per
    segment. Independent of the shooting model: energy, not forces, on a discrete
    rod. Cached per robot, resolution and routing."""
    import casadi as ca

    key = (robot, per, route)
    if key in _SOLVERS:
        return _SOLVERS[key]
    bb = robot.backbone
    assert bb is not None
    ei, gj = bb.bending_stiffness, bb.torsional_stiffness
    rho_a_g = (bb.density or 0.0) * bb.area * STANDARD_GRAVITY
    n_seg = per * sum(s.disks for s in robot.sections)
    w = ca.SX.sym("w", 3, n_seg)
    tau = ca.SX.sym("tau", robot.n_tendons)
    force = ca.SX.sym("F", 3)
    R: Any = ca.SX.eye(3)
    p: Any = ca.SX.zeros(3)
    energy: Any = ca.SX(0)
    frames = []  # (R, p) at every segment end
    seg = 0
    for sec in robot.sections:
        ds = sec.length / (per * sec.disks)
        for _ in range(per * sec.disks):
            wj = w[:, seg]
            energy += (ei * (wj[0] ** 2 + wj[1] ** 2) + gj * wj[2] ** 2) / (2 * ds)
            # the segment turns by half at its start and half at its end (midpoint)
            Rm = ca.mtimes(R, _rotvec_sym(wj / 2))
            p_new = p + ds * Rm[:, 2]
            energy += rho_a_g * ds * 0.5 * (p[2] + p_new[2])
            R = ca.mtimes(R, _rotvec_sym(wj))
            p = p_new
            frames.append((R, p))
            seg += 1
    energy += -ca.dot(force, p)
    for i, td in enumerate(robot.tendons):
        r = ca.DM([*td.offset, 0.0])
        prev: Any = r
        last = per * sum(s.disks for s in robot.sections[: td.section + 1])
        length: Any = ca.SX(0)
        for j in range(per - 1 if route == "disks" else 0, last, per if route == "disks" else 1):
            Rj, pj = frames[j]
            pt = pj + ca.mtimes(Rj, r)
            length += ca.norm_2(pt - prev)
            prev = pt
        energy += ca.fmax(tau[i], 0) * length
    outs = ca.horzcat(*[ca.vertcat(ca.vec(Rj), pj) for Rj, pj in frames])
    nlp: dict[str, Any] = {"x": ca.vec(w), "p": ca.vertcat(tau, force), "f": energy}
    opts: dict[str, Any] = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": 1e-12,
    }
    solver = ca.nlpsol("rod_energy", "ipopt", nlp, opts)
    frames_fn = ca.Function("frames", [ca.vec(w)], [outs])
    _SOLVERS[key] = (solver, frames_fn, n_seg)
    return _SOLVERS[key]


def energy_equilibrium(
    robot: Robot,
    tensions: FloatArray,
    force: FloatArray,
    start: FloatArray | None = None,
    segments_per_disk: int = 3,
    route: str = "continuous",
) -> tuple[FloatArray, FloatArray]:
    """The discrete rod's equilibrium (:func:`_energy_solver`): ``(w, frames)`` with the
    rotation vectors (3 n) and every segment end's ``[vec R, p]`` (12, n)."""
    solver, frames_fn, n_seg = _energy_solver(robot, segments_per_disk, route)
    x0 = np.zeros(3 * n_seg) if start is None else start
    sol = solver(x0=x0, p=np.r_[tensions, force])
    if not solver.stats()["success"]:
        raise EquilibriumError("the rod's energy minimisation did not converge")
    w = np.asarray(sol["x"], dtype=float).ravel()
    return w, np.asarray(frames_fn(w), dtype=float)


def quasi_static_trajectory(
    robot: Robot,
    scenario: str,
    duration: float,
    settings: TendonRodSettings | None = None,
    record_dt: float = RECORD_DT,
    segments_per_disk: int = SEGMENTS_PER_DISK,
    route: str = "continuous",
) -> TendonTrajectory:
    """The robot's equilibria (:func:`energy_equilibrium`, its tendons on ``route``) every
    ``record_dt`` s, warm started; velocities and angular velocities by central
    differences. An
    :class:`EquilibriumError` names the time of an equilibrium not found."""
    s = settings or TendonRodSettings()
    disks = [sec.disks for sec in robot.sections]
    t = record_times(duration, record_dt)
    n_rec = len(t)
    # the elements ending each section, and those whose end carries an IMU
    end_seg = tuple(segments_per_disk * sum(disks[: k + 1]) - 1 for k in range(len(disks)))
    imu_seg = imu_elements(robot, segments_per_disk)
    n_nodes = segments_per_disk * sum(disks) + 1
    nodes = np.zeros((n_rec, 3, n_nodes))
    dirs = np.zeros((n_rec, len(end_seg), 3, 3))
    imu_dirs = np.zeros((n_rec, len(imu_seg), 3, 3))
    tensions = np.array([tension_profile(robot, scenario, float(tk), s) for tk in t])
    force = np.array([tip_force(scenario, float(tk), s) for tk in t])
    w = None
    for i in range(n_rec):
        try:
            w, fr = energy_equilibrium(robot, tensions[i], force[i], w, segments_per_disk, route)
        except EquilibriumError as exc:
            raise EquilibriumError(f"{exc} at t = {t[i]:.2f} s") from None
        nodes[i, :, 1:] = fr[9:]
        for into, segs in ((dirs, end_seg), (imu_dirs, imu_seg)):
            for k, e in enumerate(segs):
                into[i, k] = fr[:9, e].reshape(3, 3, order="F").T  # rows: the frame's axes
    imu_nodes = tuple(e + 1 for e in imu_seg)
    vel = np.gradient(nodes[:, :, list(imu_nodes)], t, axis=0).transpose(0, 2, 1)
    omega = np.zeros((n_rec, len(imu_seg), 3))
    for k in range(len(imu_seg)):
        R = np.transpose(imu_dirs[:, k], (0, 2, 1))
        dR = np.gradient(R, t, axis=0)
        wh = np.einsum("nji,njk->nik", R, dR)
        omega[:, k] = 0.5 * np.stack(
            [wh[:, 2, 1] - wh[:, 1, 2], wh[:, 0, 2] - wh[:, 2, 0], wh[:, 1, 0] - wh[:, 0, 1]],
            axis=-1,
        )
    sections = SectionTrajectory(t, nodes, imu_dirs, vel, omega, np.zeros(n_rec), imu_nodes)
    ends = tuple(e + 1 for e in end_seg)
    return TendonTrajectory(sections, dirs, ends, tensions, force)


if __name__ == "__main__":  # the generator's command is the command line's
    import sys

    print(
        "continuum-mhe: error: this module is not a command: run continuum-mhe rod tendon",
        file=sys.stderr,
    )
    raise SystemExit(2)
