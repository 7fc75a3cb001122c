"""The robot as data: sections, IMUs and base mounting.

A :class:`Robot` is a chain of inextensible sections, numbered from the base, with IMUs
placed on them; optionally with a backbone material and tendons (a tendon-driven robot,
:mod:`continuum_mhe.model.tendon`). It says nothing about the motion model or the
estimator (that is the formulation's job), so one robot description serves every
formulation and every estimator.

Conventions: lengths in metres, angles in radians. Sections and IMUs are 0-based in
code and 1-based in the robot file (``continuum_mhe.io.robot_file``). An IMU at
fraction ``at`` of section ``k`` sits at arc length ``at * length_k`` from that
section's base; ``at = 1`` is the section's end.
"""

from __future__ import annotations

import math
import sys
import warnings
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

from continuum_mhe.errors import (
    FieldError,
    UserError,
    expect_type,
    finite_reals,
    is_integer,
    is_real,
)
from continuum_mhe.model.imu import MOUNTINGS, Mounting

#: Largest plausible section length in metres; longer is almost surely millimetres.
MAX_SECTION_LENGTH = 5.0
#: A section longer than this, m, is said as a likely slip (:func:`long_section_hint`):
#: continuum robots' sections are centimetres to tens of centimetres long, and one
#: written in centimetres under 5 cm passes :data:`MAX_SECTION_LENGTH`.
LONG_SECTION_LENGTH = 2.0
#: Shortest section accepted, m (a shorter one is a unit slip, not a robot).
MIN_SECTION_LENGTH = 1e-3
#: Most sections a robot may have. The models' symbolic Jacobians (``check-robot``, the
#: starts, the IPOPT path) grow with about the cube of the sections' number; past this
#: a robot's check or first estimate is impractical (docs/formats.md: measured costs).
MAX_SECTIONS = 16
#: Largest mounting angle accepted, degrees (as ``--mount-rpy``).
MAX_MOUNT_DEG = 360.0
#: A section's bending bound where none is given, rad (172 degrees): one that a real
#: robot does not reach, just short of the fold at pi, so that the bound never sets a
#: shape the data do not. A robot that bends less is described more tightly with its own
#: ``theta_max``; an estimate on a bound says so (status ``at-bound``).
DEFAULT_THETA_MAX = 3.0


def theta_max_hint(value: float) -> str:
    """The likely cause of a bending bound of pi or more, or of one below
    :data:`MIN_THETA_MAX` but positive, or ``""``: degrees only where the value cannot
    be radians (over 2 pi: 90, 180); from pi to 2 pi a radian value at or past the fold
    (3.1416 is pi rounded up)."""
    if 0 < value < MIN_THETA_MAX:
        return "a section that bends no further is no bending section; give its largest bend"
    if not math.isfinite(value) or value < math.pi:
        return ""
    if value > 2 * math.pi:
        return "degrees? give radians, e.g. 1.5708 for 90 degrees"
    return "a bend of pi folds the section back onto itself; give a bound below pi, e.g. 3.1"


#: How close (rad) to a multiple of pi/4 a mounting angle in radians is written.
RADIAN_TOLERANCE = 1e-3


def mount_rpy_hint(rpy: Sequence[float], name: str = "mount_rpy") -> str:
    """The likely cause of a mounting ``(roll, pitch, yaw)`` in degrees that looks like
    radians, or ``""``.

    Radians when every value is within 2 pi in magnitude and at least one non-zero
    value lies within :data:`RADIAN_TOLERANCE` (1e-3) of a non-zero multiple of pi/4
    (0.7854, 1.5708, 3.1416, 4.7124, 6.2832, ... and 1.57, written to two decimals): a
    quarter or eighth turn in radians. No whole number of degrees is that close to one
    (the nearest, 4 to 5pi/4, is 0.07 off), so ordinary degree values (0, 3, 6, 90,
    180, 30.5) never match, and a value over 2 pi (90, 180) means degrees."""
    if not all(math.isfinite(v) and abs(v) <= 2 * math.pi + RADIAN_TOLERANCE for v in rpy):
        return ""
    quarter = math.pi / 4
    # (a value near 0 is no multiple's: calibrate writes a well-mounted IMU's [-0.001, ...])
    turns = [
        v for v in rpy
        if round(v / quarter) != 0 and abs(v - round(v / quarter) * quarter) <= RADIAN_TOLERANCE
    ]  # fmt: skip
    if not turns:
        return ""
    degrees = ", ".join(f"{round(math.degrees(v), 1):g}" for v in rpy)
    return f"radians? {name} is in degrees ([{degrees}] if these are radians)"


#: A tendon's path between the spacer disks (:attr:`Robot.tendon_route`).
TendonRoute = Literal["continuous", "disks"]
TENDON_ROUTES: tuple[TendonRoute, ...] = ("continuous", "disks")

#: The smallest bending bound a section takes, rad (0.6 degrees): one below it holds
#: every estimate on the bound, and no reading could tell the section's bend.
MIN_THETA_MAX = 0.01


def check_theta_max(value: object) -> None:
    """A :class:`~continuum_mhe.errors.FieldError` unless ``value`` is a bending bound in
    ``[MIN_THETA_MAX, pi)`` rad."""
    hint = ""
    if is_real(value):
        if MIN_THETA_MAX <= float(value) < math.pi:
            return
        hint = theta_max_hint(float(value))
    raise FieldError(
        "theta_max",
        f"theta_max must lie in [{MIN_THETA_MAX:g}, pi) rad, got {value!r}"
        + (f" ({hint})" if hint else ""),
    )


@dataclass(frozen=True)
class Section:
    """One constant-curvature section.

    Attributes:
        length: arc length, m, in ``[0.001, 5]``.
        theta_max: bound on the section's bending angle, rad, in ``[0.01, pi)``
            (default :data:`DEFAULT_THETA_MAX`).
        disks: spacer disks, evenly spaced, the last one at the section's end (0: none
            given; the tendon model routes tendons continuously either way).
    """

    length: float
    theta_max: float = DEFAULT_THETA_MAX
    disks: int = 0

    def __post_init__(self) -> None:
        if not is_integer(self.disks) or self.disks < 0:
            raise FieldError(
                "disks", f"section disks must be a whole number >= 0, got {self.disks!r}"
            )
        object.__setattr__(self, "disks", int(self.disks))
        if not (is_real(self.length) and math.isfinite(self.length)):
            raise FieldError(
                "length", f"section length must be a finite number in m, got {self.length!r}"
            )
        object.__setattr__(self, "length", float(self.length))
        if not self.length > 0:
            raise FieldError("length", f"section length must be positive, got {self.length!r} m")
        if self.length < MIN_SECTION_LENGTH:
            raise FieldError(
                "length",
                f"section length {self.length!r} m is under {MIN_SECTION_LENGTH * 1e3:g} mm, "
                "too short for a section (lengths are in metres, e.g. 0.2)",
            )
        if self.length > MAX_SECTION_LENGTH:
            raise FieldError(
                "length",
                f"section length {self.length!r} m is over {MAX_SECTION_LENGTH} m: "
                "lengths are in metres (millimetres or centimetres?)",
            )
        check_theta_max(self.theta_max)


@dataclass(frozen=True)
class ImuPlacement:
    """Where an IMU sits.

    Attributes:
        section: 0-based index of the section it is on (a robot file's ``section = 1``
            is ``section=0`` here).
        at: fraction of that section's length from its base, in ``(0, 1]``, at least
            the smallest normal float (``sys.float_info.min``, 2.2e-308: a subnormal
            fraction is refused).
        mount_rpy: sensor mounting ``(roll, pitch, yaw)`` in degrees, Z-Y-X, mapping
            sensor-frame vectors into the local backbone frame: applied to raw readings
            on their way in (``continuum_mhe.io.raw_measurements``, ``load_input``); an
            estimator takes its readings in the disks' frames, and warns (a
            :class:`RobotWarning`) at the first samples handed to it where no such
            conversion took them.
        gyro_bias: the gyro's bias at rest ``(gx, gy, gz)``, rad/s, sensor frame
            (subtracted from raw gyro readings).
        accel_range: the accelerometer's full scale, m/s^2 (19.61 for +-2 g), or None
            (not known): a raw reading with an axis at it (within
            :data:`~continuum_mhe.io.raw_imu.CLIP_TOLERANCE`) or beyond is clipped, and
            skipped (that IMU's dropout for the sample, counted and said once).
        gyro_range: the gyro's full scale, rad/s (4.363 for +-250 deg/s), or None: the
            same for its rates.
    """

    section: int
    at: float = 1.0
    mount_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_range: float | None = None
    gyro_range: float | None = None

    def __post_init__(self) -> None:
        if (
            isinstance(self.mount_rpy, (str, bytes))
            or not hasattr(self.mount_rpy, "__iter__")
            or getattr(self.mount_rpy, "ndim", 1) == 0  # a numpy scalar array
        ):
            raise UserError(
                f"IMU mount_rpy must be three angles in degrees, got {self.mount_rpy!r}"
            )
        object.__setattr__(self, "mount_rpy", tuple(self.mount_rpy))  # hashable
        gyro_bias = finite_reals("IMU gyro_bias", self.gyro_bias, 3, "three finite rates in rad/s")
        object.__setattr__(self, "gyro_bias", gyro_bias)
        for key in ("accel_range", "gyro_range"):
            value = getattr(self, key)
            if value is not None:
                if problem := full_scale_problem(key, value):
                    raise UserError(f"IMU {problem}")
                object.__setattr__(self, key, float(value))
        object.__setattr__(self, "section", section_index("IMU section", self.section))
        if not (is_real(self.at) and 0 < self.at <= 1):
            raise UserError(
                f"IMU 'at' must be a number in (0, 1] (a fraction of the section), got {self.at!r}"
            )
        if self.at < sys.float_info.min:  # a subnormal: 1 / at overflows to infinity
            raise UserError(
                f"IMU 'at' must be a fraction of the section of at least "
                f"{sys.float_info.min!r} (the smallest normal float), got {self.at!r}: an "
                "IMU at the base reads nothing of the shape"
            )
        object.__setattr__(self, "at", float(self.at))
        if len(self.mount_rpy) != 3 or not all(
            is_real(v) and abs(v) <= MAX_MOUNT_DEG for v in self.mount_rpy
        ):
            raise UserError(
                f"IMU mount_rpy must be three angles in degrees within +-{MAX_MOUNT_DEG:g}, "
                f"got {self.mount_rpy!r}"
            )
        object.__setattr__(self, "mount_rpy", tuple(float(v) for v in self.mount_rpy))


def section_index(label: str, value: object) -> int:
    """``value`` as a 0-based section index (an int, numpy's integers too), or a
    :class:`UserError` naming ``label``."""
    if not is_integer(value):
        raise UserError(
            f"{label} must be an integer (a 0-based section index), got "
            f"{type(value).__name__} {value!r}"
        )
    if value < 0:
        raise UserError(f"{label} must be a non-negative index, got {value!r}")
    return int(value)


def _positive(label: str, value: object) -> float:
    """``value`` as a positive finite float (numpy's reals too, not a bool), or a
    :class:`UserError` naming ``label``."""
    if not (is_real(value) and math.isfinite(value) and value > 0):
        raise UserError(f"{label} must be a positive finite number, got {value!r}")
    return float(value)


#: Largest plausible backbone radius and tendon pitch radius, m; larger is almost surely
#: millimetres.
MAX_RADIUS = 0.1


#: The range of elastic moduli taken, Pa: from soft silicone rubbers (about 1e6) down to
#: an order of magnitude below them, up to diamond's (about 1.1e12), the stiffest
#: material there is. A modulus outside it was written in another unit.
MIN_MODULUS = 1e5
MAX_MODULUS = 1.2e12
#: The units a modulus is likely written in by mistake, with their size in Pa.
_MODULUS_UNITS = (("kPa", 1e3), ("MPa", 1e6), ("GPa", 1e9))


def modulus_unit_hint(value: float) -> str | None:
    """The unit a modulus ``value`` (Pa) was likely written in, as ``"MPa? 77000 MPa is
    7.7e+10 Pa"``: the largest of kPa, MPa and GPa that makes it a modulus between soft
    silicone's (1e6 Pa) and :data:`MAX_MODULUS`; None where none does."""
    hints = [
        f"{unit}? {value:g} {unit} is {value * size:.4g} Pa"
        for unit, size in _MODULUS_UNITS
        if 1e6 <= value * size <= MAX_MODULUS
    ]
    return hints[-1] if hints else None


def modulus_problem(name: str, value: float) -> str | None:
    """What is wrong with a backbone's elastic modulus ``value`` (Pa) named ``name``,
    for a one-line error, or None: below :data:`MIN_MODULUS` (with the unit that would
    make it a plausible modulus: ``77000`` is ``77000 MPa``), or above
    :data:`MAX_MODULUS`."""
    if value < MIN_MODULUS:
        hint = modulus_unit_hint(value)
        hint = f" ({hint})" if hint else ""
        return f"backbone {name} {value!r} Pa is below {MIN_MODULUS:g} Pa: moduli are in Pa{hint}"
    if value > MAX_MODULUS:
        return (
            f"backbone {name} {value!r} Pa is above any material's (diamond's, the "
            f"stiffest, is about 1.1e12 Pa): moduli are in Pa (steel about 2e11, nitinol "
            "about 5e10; GPa times 1e9)"
        )
    return None


#: The least backbone density taken, kg/m^3 (the lightest solid polymers are near 900; a
#: value below this is g/cm^3).
MIN_DENSITY = 100.0


@dataclass(frozen=True)
class Backbone:
    """The backbone's material and cross-section: a solid round elastic rod.

    Attributes:
        youngs_modulus: E, Pa.
        shear_modulus: G, Pa.
        radius: m.
        density: kg/m^3; None: the backbone's weight is left out.
    """

    youngs_modulus: float
    shear_modulus: float
    radius: float
    density: float | None = None

    def __post_init__(self) -> None:
        for name, label in (("youngs_modulus", "(Pa)"), ("shear_modulus", "(Pa)"),
                            ("radius", "(m)"), ("density", "(kg/m^3)")):  # fmt: skip
            value = getattr(self, name)
            if value is not None or name != "density":
                object.__setattr__(self, name, _positive(f"backbone {name} {label}", value))
        if self.radius > MAX_RADIUS:
            raise UserError(
                f"backbone radius {self.radius!r} m is over {MAX_RADIUS} m: radii are in "
                "metres (millimetres or centimetres?)"
            )
        for name in ("youngs_modulus", "shear_modulus"):
            problem = modulus_problem(name, getattr(self, name))
            if problem is not None:
                raise UserError(problem)
        if self.shear_modulus > self.youngs_modulus:
            raise UserError(
                f"backbone shear_modulus {self.shear_modulus!r} Pa is above its "
                f"youngs_modulus {self.youngs_modulus!r} Pa: an elastic material's G = E / "
                "(2 (1 + nu)) is E/3 to E/2 for a Poisson's ratio nu of 0.5 to 0 (swapped?)"
            )
        if self.density is not None and self.density < MIN_DENSITY:
            raise UserError(
                f"backbone density {self.density!r} kg/m^3 is below {MIN_DENSITY:g} kg/m^3: "
                "densities are in kg/m^3 (g/cm^3? 6.45 g/cm^3 is 6450)"
            )

    @property
    def area(self) -> float:
        """Cross-section area, m^2."""
        return math.pi * self.radius**2

    @property
    def bending_stiffness(self) -> float:
        """EI, N m^2 (``I = pi r^4 / 4``)."""
        return self.youngs_modulus * math.pi * self.radius**4 / 4

    @property
    def torsional_stiffness(self) -> float:
        """GJ, N m^2 (``J = pi r^4 / 2``)."""
        return self.shear_modulus * math.pi * self.radius**4 / 2


@dataclass(frozen=True)
class Tendon:
    """One tendon, routed parallel to the backbone through every disk from the base to
    its anchor.

    Attributes:
        section: 0-based index of the section at whose end it is anchored.
        angle: rad, around the backbone from the disk frame's x axis.
        radius: distance from the backbone (pitch radius), m.
    """

    section: int
    angle: float
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "section", section_index("tendon section", self.section))
        if not (is_real(self.angle) and math.isfinite(self.angle)):
            raise UserError(f"tendon angle must be a finite number, got {self.angle!r}")
        if abs(self.angle) > 2 * math.pi + 1e-9:
            raise UserError(
                f"tendon angle {self.angle!r} rad is beyond a full turn: Tendon takes "
                "radians (a robot file's angle is in degrees; math.radians?)"
            )
        object.__setattr__(self, "angle", float(self.angle))
        object.__setattr__(self, "radius", _positive("tendon radius (m)", self.radius))
        if self.radius > MAX_RADIUS:
            raise UserError(
                f"tendon radius {self.radius!r} m is over {MAX_RADIUS} m: radii are in "
                "metres (millimetres or centimetres?)"
            )

    @property
    def offset(self) -> tuple[float, float]:
        """The tendon's place in the disk frame, ``(x, y)`` m."""
        return self.radius * math.cos(self.angle), self.radius * math.sin(self.angle)


@dataclass(frozen=True)
class Robot:
    """A piecewise-constant-curvature robot with IMUs.

    Attributes:
        sections: from the base to the tip (at least one).
        imus: the IMUs, in measurement order (at least one).
        mounting: base orientation, ``"z-up"`` (base z against gravity) or ``"z-down"``.
        backbone: the backbone's material (None: a kinematic, constant-curvature robot).
        tendons: the tendons, in the tensions' order (needs a backbone).
        tendon_route: the tendons' path between the spacer disks: ``"continuous"``
            (along the backbone at their radius, Rucker and Webster's model) or
            ``"disks"`` (straight from disk to disk, as through a real robot's spacer
            disks: each section's tendons then need its ``disks``).
    """

    sections: tuple[Section, ...]
    imus: tuple[ImuPlacement, ...]
    mounting: Mounting = "z-up"
    backbone: Backbone | None = None
    tendons: tuple[Tendon, ...] = ()
    tendon_route: TendonRoute = "continuous"

    def __post_init__(self) -> None:
        for name, kind in (("sections", Section), ("imus", ImuPlacement)):
            items = getattr(self, name)
            if isinstance(items, (str, bytes)) or not hasattr(items, "__iter__"):
                raise UserError(
                    f"Robot {name} must be a sequence of {kind.__name__}, got {items!r}"
                )
            items = tuple(items)
            for item in items:
                expect_type(f"Robot {name} item", item, kind, kind.__name__)
            object.__setattr__(self, name, items)
        if not self.sections:
            raise UserError("a robot needs at least one section")
        if len(self.sections) > MAX_SECTIONS:
            raise UserError(
                f"{len(self.sections)} sections: a robot has at most {MAX_SECTIONS} (the "
                "models' cost grows with about the cube of the sections' number: past "
                f"{MAX_SECTIONS}, minutes and gigabytes for a check or a first estimate)"
            )
        if not self.imus:
            raise UserError("a robot needs at least one IMU")
        for i, imu in enumerate(self.imus):
            if imu.section >= len(self.sections):
                raise UserError(
                    f"IMU {i + 1}: ImuPlacement.section={imu.section} is a 0-based section "
                    f"index, but the robot has {len(self.sections)} section(s) (indices 0 to "
                    f"{len(self.sections) - 1}; robot files number sections from 1)"
                )
        if self.mounting not in MOUNTINGS:
            raise UserError(f"mounting must be one of {MOUNTINGS}, got {self.mounting!r}")
        if self.backbone is not None:
            expect_type("Robot backbone", self.backbone, Backbone, "a Backbone or None")
        if isinstance(self.tendons, (str, bytes)) or not hasattr(self.tendons, "__iter__"):
            raise UserError(f"Robot tendons must be a sequence of Tendon, got {self.tendons!r}")
        object.__setattr__(self, "tendons", tuple(self.tendons))
        for tendon in self.tendons:
            expect_type("Robot tendons item", tendon, Tendon, "Tendon")
        if self.tendons and self.backbone is None:
            raise UserError(
                "a robot with tendons needs its backbone's material ([backbone] "
                "youngs_modulus, shear_modulus, radius)"
            )
        for i, tendon in enumerate(self.tendons):
            if tendon.section >= len(self.sections):
                raise UserError(
                    f"tendon {i + 1}: section index {tendon.section} is past the robot's "
                    f"{len(self.sections)} section(s)"
                )
            if self.backbone is not None and tendon.radius <= self.backbone.radius:
                raise UserError(
                    f"tendon {i + 1}: radius {tendon.radius!r} m is not outside the "
                    f"backbone's radius {self.backbone.radius!r} m: a tendon runs through "
                    "the disks beside the backbone (radii in m; the tendon's is its "
                    "distance from the backbone's axis)"
                )
        if self.tendon_route not in TENDON_ROUTES:
            raise FieldError(
                "tendon_route",
                f"tendon_route must be one of {', '.join(TENDON_ROUTES)}, got "
                f"{self.tendon_route!r}",
            )
        if self.tendon_route == "disks":
            if not self.tendons:
                raise FieldError(
                    "tendon_route", 'tendon_route = "disks" is for a robot with [[tendon]]s'
                )
            last = max(td.section for td in self.tendons)
            for k, sec in enumerate(self.sections[: last + 1]):
                if sec.disks < 1:
                    raise FieldError(
                        "disks",
                        f"section {k + 1}: no disks, which tendons pass with "
                        'tendon_route = "disks" (they run straight from disk to disk: give '
                        "the section's disks)",
                    )

    @property
    def has_mechanics(self) -> bool:
        """Whether the robot has a backbone material (a mechanics model applies)."""
        return self.backbone is not None

    @property
    def anchored_sections(self) -> tuple[int, ...]:
        """The sections (0-based, in order) at whose end a tendon is anchored."""
        return tuple(sorted({t.section for t in self.tendons}))

    @property
    def n_tendons(self) -> int:
        """The number of tendons (the tensions' columns, in the robot file's order)."""
        return len(self.tendons)

    def without_tendons(self) -> Robot:
        """The same sections, IMUs and mounting as a constant-curvature robot: no
        backbone material, no tendons (a tendon robot straight and still reads so)."""
        return replace(self, tendons=(), backbone=None, tendon_route="continuous")

    @classmethod
    def single(
        cls, length: float = 0.2, theta_max: float = math.pi / 2, mounting: Mounting = "z-up"
    ) -> Robot:
        """One section with one IMU at its tip (the paper's robot)."""
        return cls((Section(length, theta_max),), (ImuPlacement(0, 1.0),), mounting)

    @property
    def n_sections(self) -> int:
        """The number of constant-curvature sections, base first."""
        return len(self.sections)

    @property
    def n_imus(self) -> int:
        """The number of IMUs (the readings' blocks, in :attr:`imus`' order)."""
        return len(self.imus)

    @property
    def length(self) -> float:
        """Total backbone length, m (the tip's arc length)."""
        return float(sum(s.length for s in self.sections))

    @property
    def lengths(self) -> tuple[float, ...]:
        """Each section's length, m, base first."""
        return tuple(s.length for s in self.sections)

    @property
    def theta_max(self) -> float:
        """``theta_max`` of a one-section robot (ValueError for several sections)."""
        if len(self.sections) != 1:
            raise UserError("theta_max is per section on a multi-section robot")
        return self.sections[0].theta_max

    @property
    def is_single(self) -> bool:
        """One section with one IMU at its tip, mounted as the tip frame."""
        return (
            len(self.sections) == 1
            and len(self.imus) == 1
            and self.imus[0].at == 1.0
            and self.imus[0].section == 0
        )

    def describe(self) -> str:
        """One line, e.g. ``2 sections (0.16 m, 0.14 m), IMUs at 1@1, 2@1, z-up``; an
        IMU's declared full scales follow its place (``1@1 (+-19.61 m/s^2, +-4.363
        rad/s)``)."""
        secs = ", ".join(f"{s.length:g} m" for s in self.sections)

        def place(i: ImuPlacement) -> str:
            scales = [
                f"+-{value:g} {unit}"
                for value, unit in ((i.accel_range, "m/s^2"), (i.gyro_range, "rad/s"))
                if value is not None
            ]
            return f"{i.section + 1}@{i.at:g}" + (f" ({', '.join(scales)})" if scales else "")

        imus = ", ".join(place(i) for i in self.imus)
        n = len(self.sections)
        text = f"{n} section{'s' if n > 1 else ''} ({secs}), IMUs at {imus}, {self.mounting}"
        if self.tendons:
            text += f", {len(self.tendons)} tendons"
            if self.tendon_route == "disks":
                text += " from disk to disk"
        return text


class RobotWarning(UserWarning):
    """A robot that is valid but likely a slip (IMUs out of base order, two at one
    place, a place or a mounting in another unit), as a robot file's are said."""


#: The full scales an IMU's ``accel_range`` (m/s^2) and ``gyro_range`` (rad/s) may
#: declare: a MEMS accelerometer's smallest is +-2 g (below 1.5 g a still IMU would read
#: at it: the range given in g?), a high-g one's largest near 4,000 m/s^2; a MEMS gyro's
#: from +-15.6 deg/s (0.27 rad/s) to +-4,000 deg/s (70 rad/s; beyond 100: deg/s?).
ACCEL_RANGE_LIMITS = (14.7, 1e4)
#: MEMS accelerometers' full scales in g that lie within :data:`ACCEL_RANGE_LIMITS`
#: read as m/s^2 (+-1.6 to 3.3 g is no sensor's range): refused as given in g
ACCEL_RANGES_IN_G = (16.0, 24.0, 32.0)
GYRO_RANGE_LIMITS = (0.1, 100.0)


def full_scale_problem(key: str, value: object) -> str | None:
    """What is wrong with an IMU's declared full scale ``key`` (``accel_range`` in
    m/s^2, ``gyro_range`` in rad/s) of ``value``, as a line naming it, or None."""
    accel = key == "accel_range"
    low, high = ACCEL_RANGE_LIMITS if accel else GYRO_RANGE_LIMITS
    unit = "m/s^2" if accel else "rad/s"
    example = "19.61 for +-2 g" if accel else "4.363 for +-250 deg/s"
    if not is_real(value) or not math.isfinite(value):
        return f"{key} must be a number in {unit} ({example}), got {value!r}"
    v = float(value)
    # +-16, 24 and 32 g written in g fall inside the range in m/s^2, where no sensor's is
    in_g = accel and (0 < v < low or any(abs(v - g) <= 0.01 * g for g in ACCEL_RANGES_IN_G))
    if low <= v <= high and not in_g:
        return None
    hint = (
        "in g? give m/s^2"
        if in_g
        else "deg/s? give rad/s"
        if not accel and v > high
        else "outside any MEMS sensor's"
    )
    return (
        f"{key} = {v:g} is the sensor's full scale in {unit}, from {low:g} to {high:g}: "
        f"{hint} ({example})"
    )


#: A gyro bias at rest beyond this, rad/s (about 11 deg/s; a MEMS gyro's is a few deg/s
#: at most), reads as one written in deg/s.
GYRO_BIAS_LIKE_DEG = 0.2
_MM = 1e-3  # m


def at_in_metres(at: float, length: float) -> bool:
    """Whether an IMU's ``at`` (a fraction of its section's length) looks like a place
    written in metres: it equals the section's length to the millimetre, and that length
    is neither 1 m (where the end is ``at = 1`` either way) nor 0.5 m (where ``at =
    0.5``, the middle, is the likelier meaning)."""
    return abs(at - length) <= _MM / 2 and min(abs(length - 1.0), abs(length - 0.5)) > _MM / 2


def long_section_hint(length: float) -> str:
    """``""``, or a section length's likely slip: longer than
    :data:`LONG_SECTION_LENGTH` (a length in centimetres read as metres?)."""
    if length <= LONG_SECTION_LENGTH:
        return ""
    return (
        f"length {length:g} m is longer than a continuum robot's section usually is: "
        f"lengths are in metres (centimetres? {length:g} cm is {length / 100:g})"
    )


def misplaced_imus(imus: Sequence[ImuPlacement]) -> tuple[int | None, tuple[int, int] | None]:
    """The first IMU (0-based) listed after one nearer the tip (by section, then
    ``at``; None where they run from the base to the tip), and the first pair ``(i, j)``,
    ``j < i``, of IMUs at one place (None where there is none)."""
    key = [(imu.section, imu.at) for imu in imus]
    later = next((i for i in range(1, len(key)) if key[i] < key[i - 1]), None)
    same = next(((i, key.index(key[i])) for i in range(1, len(key)) if key[i] in key[:i]), None)
    return later, same


def likely_slips(robot: Robot) -> tuple[str, ...]:
    """What in ``robot`` (built in code: 0-based ``imus[i]`` and ``sections[k]``) looks
    like a slip, one line each: a section longer than :data:`LONG_SECTION_LENGTH`, IMUs
    not listed from the base to the tip (the
    measurement columns follow their order) or two at one place, an ``at`` equal to its
    section's length in m, a ``mount_rpy`` that looks like radians, a ``gyro_bias`` that
    looks like deg/s. A robot file's reader says the same with the file's lines."""
    out = [
        f"sections[{k}]: {hint}"
        for k, s in enumerate(robot.sections)
        if (hint := long_section_hint(s.length))
    ]
    imus = robot.imus

    def place(i: int) -> str:
        return f"sections[{imus[i].section}], at {imus[i].at:g}"

    later, same = misplaced_imus(imus)
    if later is not None:
        out.append(
            f"imus[{later}] ({place(later)}) is nearer the base than imus[{later - 1}] "
            f"({place(later - 1)}) but listed after it: the measurement columns follow the "
            "IMUs' order, the first nearest the base; list them from base to tip (or check "
            "that the columns follow this order)"
        )
    if same is not None:
        out.append(
            f"imus[{same[0]}] is at the same place as imus[{same[1]}] ({place(same[0])}): "
            "two IMUs at one place (a copied entry?)"
        )
    for i, imu in enumerate(imus):
        if at_in_metres(imu.at, robot.sections[imu.section].length):
            out.append(
                f"imus[{i}].at = {imu.at:g} equals sections[{imu.section}]'s length in m: "
                "at is a fraction of the section's length (1 its end, 0.5 its middle): metres?"
            )
        if hint := mount_rpy_hint(imu.mount_rpy, f"imus[{i}].mount_rpy"):
            out.append(hint)
        if max(abs(v) for v in imu.gyro_bias) > GYRO_BIAS_LIKE_DEG:
            deg = math.degrees(max(abs(v) for v in imu.gyro_bias))
            out.append(
                f"imus[{i}].gyro_bias is in rad/s: {deg:.0f} deg/s is no MEMS gyro's bias at "
                "rest: deg/s?"
            )
    return tuple(out)


#: Robots whose slips were said (a robot file's reader says them with its lines)
_SAID: weakref.WeakSet[Robot] = weakref.WeakSet()


def slips_said(robot: Robot) -> None:
    """Take ``robot``'s slips as said (:func:`warn_slips` says nothing of it, or of an
    equal robot)."""
    _SAID.add(robot)


def warn_slips(robot: Robot) -> None:
    """A :class:`RobotWarning` for each of :func:`likely_slips`, once per robot (equal
    robots count as one; a robot file's robot is said by its reader)."""
    if robot in _SAID:
        return
    for line in likely_slips(robot):
        warnings.warn(f"robot: {line}", RobotWarning, stacklevel=3)
    _SAID.add(robot)


#: Robots whose readings are known to be in their IMUs' disk frames: turned by
#: ``mount_rpy`` on the way in (raw readings through ``imu_converters``), said not to be
#: (tilt input read from a file), or simulated in those frames
_MOUNT_TAKEN: weakref.WeakSet[Robot] = weakref.WeakSet()


def mount_taken(robot: Robot) -> None:
    """Take ``robot``'s readings as in its IMUs' disk frames: :func:`warn_mount_not_applied`
    says nothing of it, or of an equal robot."""
    _MOUNT_TAKEN.add(robot)


def warn_mount_not_applied(robot: Robot, stacklevel: int = 3) -> None:
    """A :class:`RobotWarning`, once per robot, where an IMU has a ``mount_rpy`` that no
    conversion has taken: an estimator takes its readings in each IMU's disk frame (roll
    and pitch, or the direct model's unit specific force and gyro), so a reading in the
    sensor's own frame is read as if the board sat on its disk unturned."""
    mounted = [str(i + 1) for i, imu in enumerate(robot.imus) if any(imu.mount_rpy)]
    if not mounted or robot in _MOUNT_TAKEN:
        return
    warnings.warn(
        f"robot: the mount_rpy of IMU {', '.join(mounted)} is not applied by the estimator, "
        "which takes each IMU's readings in its disk's frame (as simulate_robot gives them): "
        "raw readings in the sensor's frame go through continuum_mhe.io.raw_measurements "
        "or load_input, which turn them by mount_rpy; roll and pitch in an IMU's own frame "
        "need turning first (docs/formats.md#tilt)",
        RobotWarning,
        stacklevel=stacklevel,
    )
    _MOUNT_TAKEN.add(robot)
