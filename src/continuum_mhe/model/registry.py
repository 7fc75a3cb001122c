"""Formulations by name: the one place that maps a name to its class (no import cycles;
the names' type is ``model.settings.FormulationName``, and a test keeps the two equal).

``make_formulation("bend" | "paper" | "direct" | "tendon", robot, noise)``. A robot is a
:class:`~continuum_mhe.model.robot.Robot` or, for one section, a
:class:`~continuum_mhe.settings.RobotSettings`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from continuum_mhe.errors import UserError, expect_type
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.direct import DirectFormulation, gyro_biases_calibrated
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.paper import PaperFormulation
from continuum_mhe.model.robot import Robot, warn_slips
from continuum_mhe.model.settings import FormulationName, NoiseSettings, RobotSettings
from continuum_mhe.model.tendon import TendonFormulation

#: Formulation classes by name.
REGISTRY: dict[str, type[Formulation]] = {
    "bend": BendFormulation,
    "paper": PaperFormulation,
    "direct": DirectFormulation,
    "tendon": TendonFormulation,
}


def make_formulation(
    name: FormulationName = "bend",
    robot: Robot | RobotSettings | None = None,
    noise: NoiseSettings | None = None,
    **options: Any,
) -> Formulation:
    """Formulation by name: ``"bend"`` (default), ``"paper"``, ``"direct"`` (raw IMU) or
    ``"tendon"`` (a robot file with a backbone and tendons).

    ``options`` go to the formulation (e.g. ``gyro_std`` for ``direct``). ``"direct"``,
    and ``"tendon"`` with ``imu_model="direct"``, estimate each IMU's gyro bias unless
    ``estimate_gyro_bias=False`` is given (or ``imu_twist=True`` on a robot whose IMUs all
    have a calibrated ``gyro_bias``: held at it), as the command line and
    :func:`~continuum_mhe.io.inputs.load_input` do.
    """
    if isinstance(name, (Robot, RobotSettings)):  # the robot given first
        raise UserError(
            "make_formulation takes the formulation's name first: make_formulation('bend', "
            f"robot) (or 'direct' for raw IMUs), got a {type(name).__name__} as the name"
        )
    cls = REGISTRY.get(name) if isinstance(name, str) else None
    # raw IMUs: their gyro biases are states, as the command line has them
    if name == "direct" or (name == "tendon" and options.get("imu_model") == "direct"):
        # with the IMUs' twist a bias about z turns the bending plane: held at a calibration
        calibrated = isinstance(robot, Robot) and gyro_biases_calibrated(robot)
        options.setdefault("estimate_gyro_bias", not (options.get("imu_twist") and calibrated))
    if cls is None:
        raise UserError(f"formulation must be one of {', '.join(REGISTRY)}, got {name!r}")
    robots = (Robot, RobotSettings, type(None))
    expect_type("robot", robot, robots, "a Robot, RobotSettings or None")
    if isinstance(robot, Robot):  # built in code: what a robot file's reader would say
        warn_slips(robot)
    expect_type("noise", noise, (NoiseSettings, type(None)), "NoiseSettings or None")
    import dataclasses

    fields = {f.name: f for f in dataclasses.fields(cls)}
    known = set(fields) - {"robot", "noise", "name"}
    unknown = sorted(set(options) - known)
    if unknown:
        takes = f"its options: {', '.join(sorted(known))}" if known else "it takes none"
        raise UserError(f"the {name} formulation has no option {unknown[0]!r} ({takes})")
    for key, value in options.items():  # a switch is a bool ("false" would be true)
        kind = str(fields[key].type).replace("Optional[bool]", "bool | None")
        optional = kind == "bool | None" and value is None  # (None: the formulation's own)
        if kind in ("bool", "bool | None", "<class 'bool'>") and not optional:
            if not isinstance(value, (bool, np.bool_)):
                allowed = "True, False or None" if kind == "bool | None" else "True or False"
                raise UserError(
                    f"the {name} formulation's option {key} must be {allowed}, got {value!r}"
                )
    return cls(robot=robot or RobotSettings(), noise=noise or NoiseSettings(), **options)  # type: ignore[arg-type]
