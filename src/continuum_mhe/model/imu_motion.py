"""The error an IMU's own acceleration puts into a gravity-direction reading that the
model takes as gravity alone.

An accelerometer reads the specific force, gravity's reaction plus the IMU's own
acceleration ``a``; the ``bend`` (tilt) and ``direct`` formulations without
``own_acceleration`` take its direction for gravity's. Only ``a``'s part across gravity
turns the direction, by ``atan(|a_perp| / (g + a_up))``. That error lasts as long as the motion
that makes it (a robot leaving a pose accelerates its tip IMU at a tenth of g for a
third of a second: 6 degrees, against readings' noise of about 2), and where the IMUs'
readings fit the bends exactly (a tilt IMU per section) no residual shows it. The
estimate itself says how fast its IMUs move: :func:`own_acceleration_functions` gives
each IMU's velocity from the state (the bends and their rates) and the reading error
an acceleration causes at a state; the consistency check differences the velocities
over time and carries the error in the standard deviations as a model error of the
readings (:mod:`continuum_mhe.estimators.consistency`).
"""

from __future__ import annotations

import casadi as ca

from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import (
    STANDARD_GRAVITY,
    tilt_from_gravity_sym,
    tilt_tangent_residual_sym,
)
from continuum_mhe.model.pcc import pose_at_sym, up_vector


def takes_acceleration_as_gravity(formulation: Formulation) -> bool:
    """Whether ``formulation`` reads gravity directions of IMUs on a PCC robot whose
    state holds the bends and their rates, without its IMUs' own acceleration in the
    model and without a twist of the IMUs' frames: the ``bend`` and ``direct``
    formulations as the command line makes them."""
    if formulation.name not in ("bend", "direct"):
        return False
    if getattr(formulation, "own_acceleration", False) or getattr(formulation, "imu_twist", False):
        return False
    names = formulation.state_names
    bends = formulation.sigma_states
    return bool(bends) and all(f"{names[s]}_dot" in names for s in bends)


def own_acceleration_functions(formulation: Formulation) -> tuple[ca.Function, ca.Function]:
    """``(velocity, error)`` of a formulation that :func:`takes_acceleration_as_gravity`:
    ``velocity(x)``, each IMU's velocity in the base frame (m/s, 3 per IMU in the robot
    file's order), and ``error(x, a)``, the residual (``nz``, the formulation's units;
    zero on rows that are not gravity directions) of the readings the IMUs give at the
    state ``x`` when IMU ``i`` accelerates at ``a[3 i : 3 i + 3]`` (m/s^2, base frame):
    the formulation's own residual of those readings at ``x``."""
    if not takes_acceleration_as_gravity(formulation):
        raise ValueError(f"the {formulation.name} formulation has no such readings")
    robot = formulation.robot
    names = formulation.state_names
    bends_at = list(formulation.sigma_states)
    rates_at = [names.index(f"{names[s]}_dot") for s in bends_at]
    x = ca.SX.sym("x", formulation.nx)
    acc = ca.SX.sym("a", 3 * robot.n_imus)
    bends = [(x[bends_at[2 * k]], x[bends_at[2 * k + 1]]) for k in range(robot.n_sections)]
    q = ca.vertcat(*[x[s] for s in bends_at])
    qd = ca.vertcat(*[x[s] for s in rates_at])
    up = ca.DM(up_vector(robot.mounting))
    velocity, error = [], []
    for i, imu in enumerate(robot.imus):
        R, p = pose_at_sym(bends, robot.lengths, imu.section, imu.at)
        velocity.append(ca.mtimes(ca.jacobian(p, q), qd))
        seen = up + acc[3 * i : 3 * i + 3] / STANDARD_GRAVITY  # the specific force, in g
        g0 = ca.mtimes(R.T, up)  # what the model predicts
        g1 = ca.mtimes(R.T, seen / ca.norm_2(seen))  # what the IMU reads
        if formulation.name == "bend":  # the residual of the reading tilt(g1) at g0
            error.append(tilt_tangent_residual_sym(tilt_from_gravity_sym(g1), g0))
        else:  # the unit specific force's three rows, then the gyro's three
            error += [g1 - g0, ca.DM.zeros(3)]
    return (
        ca.Function("imu_velocity", [x], [ca.vertcat(*velocity)]),
        ca.Function("acceleration_reading_error", [x, acc], [ca.vertcat(*error)]),
    )
