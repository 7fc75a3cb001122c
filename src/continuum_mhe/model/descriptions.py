"""Self-describing outputs and measurement blocks.

A formulation names its outputs (with units, and which are wrapped angles) and its
measurement blocks (one per sensor). Estimate records, writers, metrics, plots, ``live``
and the fast backend read these descriptions; nothing downstream hard-codes a size or a
column list.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError

if TYPE_CHECKING:
    from continuum_mhe.model.robot import Robot

Unit = Literal["m", "rad", "rad/s", "1", "N"]


@dataclass(frozen=True)
class OutputSpec:
    """One output column.

    Attributes:
        name: column name, e.g. ``x`` or ``theta_2``.
        unit: its unit (``"m"``, ``"rad"``, ``"rad/s"``, ``"N"``, ``"1"``).
        wrapped: True for an angle reported in ``[-pi, pi)`` (errors are wrapped too).
        section: 1-based section it belongs to, 0 for the tip.
    """

    name: str
    unit: Unit
    wrapped: bool = False
    section: int = 0


@dataclass(frozen=True)
class MeasurementBlock:
    """The measurements of one sensor: ``z[start : start + size]``.

    Attributes:
        name: sensor name, e.g. ``imu1``.
        names: one name per component, e.g. ``("roll_1", "pitch_1")``.
        start: index of the first component in the measurement vector.
        kind: ``"tilt"`` (roll, pitch; rad) or ``"direct"`` (unit specific force and
            gyro, rad/s) for an IMU; ``"tension"`` (tendon tensions, N, given with the
            sample) or ``"equilibrium"`` (a model's pseudo-measurement, always zero) for
            the blocks of :mod:`continuum_mhe.model.tendon` that are not IMUs.
    """

    name: str
    names: tuple[str, ...]
    start: int
    kind: Literal["tilt", "direct", "tension", "equilibrium"] = "tilt"

    @property
    def is_imu(self) -> bool:
        """Whether the block is an IMU's (the sensor-health checks watch only these)."""
        return self.kind in ("tilt", "direct")

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def slice(self) -> slice:
        return slice(self.start, self.start + self.size)


#: The tip position columns every estimate and truth file has, and their outputs.
TIP_COLUMNS: tuple[str, str, str] = ("x", "y", "z")
TIP_OUTPUTS = tuple(OutputSpec(c, "m") for c in TIP_COLUMNS)
#: a tendon robot's tip force outputs (N, base frame)
TIP_FORCE_COLUMNS = ("fx", "fy", "fz")


def pcc_outputs(n_sections: int) -> tuple[OutputSpec, ...]:
    """Outputs of an ``n_sections`` robot: the tip ``x, y, z``, then per section ``k``
    its bend ``theta_k, phi_k`` and end position ``x_k, y_k, z_k``. With one section
    exactly ``x, y, z, theta, phi`` (the paper's five outputs)."""
    if n_sections == 1:
        return (*TIP_OUTPUTS, OutputSpec("theta", "rad"), OutputSpec("phi", "rad", True))
    out = list(TIP_OUTPUTS)
    for k in range(1, n_sections + 1):
        out += section_outputs(k)
    return tuple(out)


def tendon_outputs(n_sections: int) -> tuple[OutputSpec, ...]:
    """The outputs of a tendon robot's mechanics model (``n_sections`` sections): the tip
    ``x, y, z``; per section ``k`` its equivalent bend ``theta_k, phi_k`` (between its
    end tangents), end position ``x_k, y_k, z_k`` and twist ``psi_k``; then the tip force
    ``fx, fy, fz`` (N, base frame)."""
    out = list(TIP_OUTPUTS)
    for k in range(1, n_sections + 1):
        out += [*section_outputs(k), OutputSpec(f"psi_{k}", "rad", True, section=k)]
    out += [OutputSpec(name, "N") for name in TIP_FORCE_COLUMNS]
    return tuple(out)


def imu_twist_outputs(n_imus: int) -> tuple[OutputSpec, ...]:
    """Each IMU's twist (rad, unwrapped; :func:`imu_twist_names`), as ``--imu-twist``
    estimates it."""
    return tuple(OutputSpec(name, "rad") for name in imu_twist_names(n_imus))


def tension_gain_outputs(sections: Sequence[int]) -> tuple[OutputSpec, ...]:
    """The tension gain ``tension_gain_s`` (dimensionless) of each of the ``sections``
    (0-based; ``s`` is 1-based), as ``--estimate-tension-gain`` estimates them."""
    return tuple(OutputSpec(f"tension_gain_{s + 1}", "1", section=s + 1) for s in sections)


def robot_outputs(
    robot: Robot, *, imu_twist: bool = False, tension_gain: bool = False
) -> tuple[OutputSpec, ...]:
    """The outputs an estimate of ``robot`` has, in the order the estimators write them:
    a robot with a backbone (``[backbone]``), its mechanics model's
    (:func:`tendon_outputs`), then with ``tension_gain`` each tension gain of a section
    at whose end a tendon is anchored (:func:`tension_gain_outputs`); any other robot,
    the constant-curvature model's (:func:`pcc_outputs`), then with ``imu_twist`` each
    IMU's twist (:func:`imu_twist_outputs`). A :class:`UserError` for an option the
    robot's model does not have."""
    if robot.backbone is None:
        if tension_gain:
            raise UserError("tension gains are a tendon robot's (a [backbone] in the robot)")
        twists = imu_twist_outputs(robot.n_imus) if imu_twist else ()
        return (*pcc_outputs(robot.n_sections), *twists)
    if imu_twist:
        raise UserError("a tendon robot's model has no IMU twist (its sections' twist psi_k)")
    gains = tension_gain_outputs(robot.anchored_sections) if tension_gain else ()
    return (*tendon_outputs(robot.n_sections), *gains)


def bend_columns(names: Sequence[str], n_sections: int) -> tuple[str, ...]:
    """The bend columns ``theta_k, phi_k`` of ``n_sections`` sections, in section order,
    as a table of these column ``names`` writes them: one section's are ``theta, phi``
    (the constant-curvature model's) or ``theta_1, phi_1`` (the tendon model's, which
    numbers every section); the constant-curvature model's names where the table has
    neither."""
    if n_sections == 1 and "theta" not in names and "theta_1" in names:
        return ("theta_1", "phi_1")
    return tuple(o.name for o in pcc_outputs(n_sections) if o.name.startswith(("theta", "phi")))


def section_outputs(k: int) -> list[OutputSpec]:
    """Section ``k``'s (1-based) bend ``theta_k, phi_k`` and end position ``x_k, y_k,
    z_k``."""
    return [
        OutputSpec(f"theta_{k}", "rad", section=k),
        OutputSpec(f"phi_{k}", "rad", True, section=k),
        *(OutputSpec(name, "m", section=k) for name in section_end_columns(k)),
    ]


def section_end_columns(k: int) -> tuple[str, str, str]:
    """The names of section ``k``'s (1-based) end position, ``x_k, y_k, z_k``: for a
    table (a truth) that has names alone; with the outputs at hand,
    :func:`section_end_indices`."""
    x, y, z = TIP_COLUMNS
    return f"{x}_{k}", f"{y}_{k}", f"{z}_{k}"


def section_numbers(columns: Iterable[str], field: str) -> list[int]:
    """The section numbers ``k`` of the columns ``{field}_k`` among ``columns``, in
    order (a file may have some sections' columns and not others')."""
    prefix = field + "_"
    ks = (c[len(prefix) :] for c in columns if c.startswith(prefix))
    return sorted(int(k) for k in ks if k.isdigit())


def sections_with_ends(names: Sequence[str]) -> list[int]:
    """The sections ``k`` (1-based, in order) whose end's ``x_k, y_k, z_k``
    (:func:`section_end_columns`) are all among a table's column ``names``."""
    return [
        k
        for k in section_numbers(names, TIP_COLUMNS[0])
        if k > 0 and all(c in names for c in section_end_columns(k))
    ]


def section_count(names: Sequence[str]) -> int:
    """Sections of the robot a table (an estimate) was made for, from its bend columns
    (``theta``: one; ``theta_1 ... theta_n``: n); 0 when it has none."""
    if "theta" in names:
        return 1
    n = 0
    while f"theta_{n + 1}" in names:
        n += 1
    return n


def output_names(outputs: Sequence[OutputSpec]) -> tuple[str, ...]:
    return tuple(o.name for o in outputs)


def wrapped_indices(outputs: Sequence[OutputSpec]) -> tuple[int, ...]:
    return tuple(i for i, o in enumerate(outputs) if o.wrapped)


def tip_position_indices(outputs: Sequence[OutputSpec]) -> tuple[int, ...]:
    """The columns of the tip's position (section 0, in m: ``x, y, z``)."""
    return tuple(i for i, o in enumerate(outputs) if o.section == 0 and o.unit == "m")


def section_end_indices(outputs: Sequence[OutputSpec], k: int) -> tuple[int, ...]:
    """The columns of section ``k``'s (1-based) end position (section ``k``, in m:
    ``x_k, y_k, z_k``); none where the outputs have none (one constant-curvature
    section, whose end is the tip: :func:`tip_position_indices`)."""
    return tuple(i for i, o in enumerate(outputs) if o.section == k and o.unit == "m")


def imu_suffix(i: int, n_imus: int) -> str:
    """Column suffix of IMU ``i`` (0-based): ``""`` with one IMU, else ``"_1"``, ``"_2"``."""
    return "" if n_imus == 1 else f"_{i + 1}"


def imu_twist_names(n_imus: int) -> tuple[str, ...]:
    """The output names of each IMU's twist (``--imu-twist``): ``imu_twist`` for one IMU,
    else ``imu_twist_1 .. imu_twist_n``."""
    return tuple(f"imu_twist{imu_suffix(i, n_imus)}" for i in range(n_imus))


def tilt_blocks(n_imus: int) -> tuple[MeasurementBlock, ...]:
    """``roll_i, pitch_i`` per IMU (``roll, pitch`` with one IMU)."""
    return tuple(
        MeasurementBlock(
            f"imu{i + 1}",
            (f"roll{imu_suffix(i, n_imus)}", f"pitch{imu_suffix(i, n_imus)}"),
            2 * i,
        )
        for i in range(n_imus)
    )


def direct_blocks(n_imus: int) -> tuple[MeasurementBlock, ...]:
    """``fx_i, fy_i, fz_i, wx_i, wy_i, wz_i`` per IMU (unit specific force, rad/s)."""
    names = ("fx", "fy", "fz", "wx", "wy", "wz")
    return tuple(
        MeasurementBlock(
            f"imu{i + 1}", tuple(n + imu_suffix(i, n_imus) for n in names), 6 * i, "direct"
        )
        for i in range(n_imus)
    )


def section_bends(
    outputs: Sequence[OutputSpec], values: Sequence[float] | NDArray[np.float64]
) -> NDArray[np.float64]:
    """Bend vectors (n_sections, 2) rad from one row of outputs (``theta, phi`` or
    ``theta_k, phi_k``): ``(theta cos phi, theta sin phi)``."""
    names = [o.name for o in outputs]
    bends = [names.index(c) for c in bend_columns(names, section_count(names))]
    out = np.zeros((len(bends) // 2, 2))
    for k, (i, j) in enumerate(zip(bends[::2], bends[1::2])):
        th, ph = float(values[i]), float(values[j])
        out[k] = th * math.cos(ph), th * math.sin(ph)
    return out


#: The largest bend angle (``theta``, ``phi`` columns, rad) a state table takes: a
#: section bends less than a turn (``theta_max`` lies below pi), and ``phi`` is given
#: in ``[-pi, pi]`` or ``[0, 2 pi)``; beyond it, the angles are in degrees.
ANGLE_LIMIT = 2.0 * math.pi + 1e-9


def angle_beyond_a_turn(names: Sequence[str], values: FloatArray) -> tuple[int, str] | None:
    """The first row of the table ``values`` (n, len(names)) with an angle (a bend's
    ``theta`` or ``phi``, a section end's twist ``psi``) beyond :data:`ANGLE_LIMIT`,
    angles in degrees, and what to say of it (``theta=90 beyond 2 pi: degrees? ...``);
    else None. An IMU's ``imu_twist`` is unwrapped (:func:`imu_twist_outputs`): a twist
    past a turn is a twist, and not judged."""
    angles = [j for j, n in enumerate(names) if n.partition("_")[0] in ("theta", "phi", "psi")]
    turned = np.argwhere(np.abs(values[:, angles]) > ANGLE_LIMIT)
    if not len(turned):
        return None
    i, j = turned[0]
    return int(i), (
        f"{names[angles[j]]}={values[i, angles[j]]:.6g} beyond 2 pi: degrees? angles are "
        "in rad (numpy.radians converts)"
    )
