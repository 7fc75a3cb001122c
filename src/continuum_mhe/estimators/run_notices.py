"""Notices at the end of a run, from its estimates: sections whose bend sat on its
bound or passed it, rows inconsistent with their readings, a tendon robot's tip force
beyond its tensions, tension gains far from one (each a tally over the estimates, and
one line that says what it means)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray, longer, typical_of_steps
from continuum_mhe.errors import time_text
from continuum_mhe.estimators.base import Inference, tension_rows
from continuum_mhe.estimators.load_hypotheses import LoadHypothesesInference
from continuum_mhe.estimators.process_noise import bend_accel_psd_applies
from continuum_mhe.model.descriptions import TIP_FORCE_COLUMNS, tip_position_indices
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.formulations import AT_BOUND_TOL, Formulation
from continuum_mhe.model.robot import DEFAULT_THETA_MAX
from continuum_mhe.model.tendon import BUCKLED_PUSH_MULTIPLE
from continuum_mhe.results import Diagnostics, Status
from continuum_mhe.settings import RecoverySettings

#: A tendon robot's tip force beyond this many times its largest tension (and over
#: :data:`FORCE_NOTICE_MIN` N) is said at the end of ``estimate``
#: (:class:`ForceBeyondTensions`): the shipped recordings reach at most 0.11 of it.
FORCE_TENSION_RATIO = 1.0
FORCE_NOTICE_MIN = 0.05


def _bend_columns(formulation: Formulation) -> list[int]:
    """Each section's bend among ``formulation``'s outputs: ``theta_k``, or ``theta`` for
    a one-section model that names it so; -1 where there is none."""
    names = [o.name for o in formulation.outputs]
    sections = formulation.robot.sections
    return [
        names.index(f"theta_{k}")
        if f"theta_{k}" in names
        else (names.index("theta") if len(sections) == 1 and "theta" in names else -1)
        for k in range(1, len(sections) + 1)
    ]


def _largest_bends(largest: list[float], theta: FloatArray, rows: NDArray[np.bool_]) -> list[float]:
    """Each section's largest bend (rad) of ``largest`` and of the bends ``theta`` (n,
    sections) where ``rows`` (n, sections) marks them."""
    if not rows.any():
        return largest
    worst = np.nanmax(np.where(rows, theta, 0.0), axis=0)
    return [max(a, float(b)) for a, b in zip(largest, worst)]


class BendsOnBound:
    """The estimates of a constant-curvature robot that put a section's bend on its
    ``theta_max`` (within :data:`~continuum_mhe.model.formulations.AT_BOUND_TOL`) or
    beyond it, counted block by block from their outputs (``theta_k``) and statuses, by
    status (a restart's row on the bound is ``reset``, not ``at-bound``), with each
    section's largest bend, for one line at the end (:meth:`notice`). The rows counted
    are the rows of the file whose ``theta_k`` reach the bound, and every ``at-bound``
    row; not ``dropout`` rows (no reading: the motion model's prediction reached the
    bound, which says nothing of how far the robot bends)."""

    def __init__(self, formulation: Formulation) -> None:
        robot = formulation.robot
        self._robot = robot
        self._limits = np.array([s.theta_max for s in robot.sections])  # rad
        self._columns = _bend_columns(formulation)
        # a mechanics model does not bound the bend: BendsBeyondBound says those
        self.active = not robot.has_mechanics and all(c >= 0 for c in self._columns)
        self.count = 0
        #: of them, the rows whose sample lacked an IMU's reading (another IMU's given)
        self.partial = 0
        self.statuses: Counter[str] = Counter()
        self.largest = [0.0] * len(robot.sections)
        self._imu_rows = [b.start for b in formulation.measurement_blocks if b.is_imu]
        # the sections (0-based) whose bend the IMUs leave free: theirs drift to the
        # bound; the others' reach it where the robot (or the readings) bend so far
        self._free = {a // 2 for a, _, _ in formulation.free_bends()}

    def add(self, output: FloatArray, statuses: Sequence[str], z: FloatArray | None = None) -> None:
        """Count the estimates ``output`` (n, ny; NaN rows without an estimate) and
        their ``statuses``; ``z`` (n, nz): their samples' measurements (NaN where
        missing), to count the rows that lacked an IMU's reading."""
        status = np.asarray(statuses, dtype=object)
        on = status == Status.AT_BOUND.value
        if self.active and len(output):
            theta = np.abs(output[:, self._columns])
            with np.errstate(invalid="ignore"):
                reached = theta >= self._limits - AT_BOUND_TOL
            reached &= (status != Status.DROPOUT.value)[:, None]
            on = on | reached.any(axis=1)
            self.largest = _largest_bends(self.largest, theta, reached)
        if z is not None and len(self._imu_rows) > 1:
            read = np.isfinite(z[:, self._imu_rows])
            self.partial += int((on & read.any(axis=1) & ~read.all(axis=1)).sum())
        self.count += int(on.sum())
        self.statuses.update(str(v) for v in status[on])

    def notice(
        self,
        n: int,
        method: str,
        holds: bool,
        raise_it: str,
        observable: bool = True,
        contradicted: bool = False,
        causes_follow: bool = False,
    ) -> str | None:
        """One line for the estimates counted on (or beyond) the bound, of ``n``, by
        ``method`` (the estimator's name), which ``holds`` its bends to the bound (the
        MHE's constraints) or not (the filters); ``raise_it`` says how to raise the
        bound (``raise theta_max in the robot file R``); ``observable``: whether the
        robot's IMUs determine its shape (where they do not, the bends they leave free
        drift to the bound); ``contradicted``: whether the readings restarted the
        estimator on many samples (said in a warning of its own): a bound too tight
        does that, and so does a robot file that does not describe the robot, which
        raising the bound does not mend; ``causes_follow``: the warning on inconsistent
        estimates follows, and a bound that readings the model does not explain reached
        points to its list of causes instead of giving its own. None without."""
        if not self.count:
            return None
        sections = self._robot.sections
        bounds = ", ".join(f"{s.theta_max:.4g}" for s in sections)
        by_status = ", ".join(f"{k} {v}" for k, v in sorted(self.statuses.items()))
        what = f"{self.count} of {n} estimates have a section's bend"
        of = f"its bending bound theta_max ({bounds} rad; by status: {by_status})"
        reached = [s for s, big in zip(sections, self.largest) if big > 0]
        missing = (
            f" ({self.partial} of them while an IMU's reading was missing, where the bends "
            "the other IMUs leave free drift)"
            if self.partial
            else ""
        )
        # a filter does not stop the free bends at the bound: they drift past it
        drift = "drift to the bound" if holds else "drift to the bound and past it"
        free = not observable or self.partial == self.count
        if not observable:
            free_reached = any(self.largest[k] > 0 for k in self._free)
            further = (
                "and the robot's IMUs do not determine its shape: the bends they leave "
                f"free {drift} (one IMU per section determines them; "
                "check-robot tells)"
                if free_reached or not self._free
                else "and the robot's IMUs do not determine its shape (check-robot tells)"
            )
            seen = [k for k, big in enumerate(self.largest) if big > 0 and k not in self._free]
            if seen and self._free:
                # a bend the IMUs determine did not drift there: the readings put it there
                named = ", ".join(str(k + 1) for k in seen)
                if all(sections[k].theta_max >= DEFAULT_THETA_MAX for k in seen):
                    why = (
                        f"a bound of {DEFAULT_THETA_MAX:g} rad or more is one a robot does "
                        "not reach: check the robot file against the robot"
                    )
                else:
                    why = (
                        "the robot may bend further than the bound allows; "
                        f"{raise_it} if it bends so far"
                    )
                further += (
                    f"; but the IMUs determine the bend of section(s) {named}, which "
                    f"reached the bound{' too' if free_reached else ''}: {why}"
                )
        elif self.partial == self.count:
            further = (
                "and all of them while an IMU's reading was missing (a dropout): the "
                f"bends the other IMUs leave free {drift}, which says nothing "
                "of how far the robot bends"
            )
        elif reached and all(s.theta_max >= DEFAULT_THETA_MAX for s in reached):
            # a bound no robot reaches: the readings, not the robot, went there
            further = (
                f"and a bound of {DEFAULT_THETA_MAX:g} rad or more is one a robot does not "
                f"reach{missing}: readings that the model of the robot does not explain pushed the "
                "estimates there"
            )
            further += (
                f" ({CAUSES_FOLLOW})"
                if causes_follow
                else "; check the robot file against the robot (the IMUs' order, "
                "section, at and mount_rpy, the sections' lengths and order, the mounting; "
                "check-robot lists them), or the robot does what the model cannot follow "
                "(a backbone that twists about itself)"
            )
        elif contradicted:
            further = (
                f"and the robot may bend further than the bound allows{missing}; "
                f"{raise_it} if it bends so far (but the restarts warned of above say that "
                "readings contradicted the estimates: where the robot file does not "
                "describe the robot, as with IMUs swapped or turned over, raising the bound "
                "does not help)"
            )
        else:
            further = (
                f"and the robot may bend further than the bound allows{missing}; "
                f"{raise_it} if it bends so far"
            )
        if holds:
            return (
                f"{what} on {of}: the {method.upper()} holds its estimates to the bound, "
                f"so the bound, not the data, set those shapes, {further}"
            )
        largest = [
            f"section {k + 1} up to {big:.3g} rad"
            for k, big in enumerate(self.largest)
            if big > 0 and len(sections) > 1
        ] or [f"up to {big:.3g} rad" for big in self.largest if big > 0]
        reach = f", {', '.join(largest)}" if largest else ""
        # the bends the readings leave free are set by neither the readings nor the bound
        settled = "" if free else ", so the readings, not the bound, set those shapes"
        return (
            f"{what} on or beyond {of}{reach}: the {method.upper()} does "
            f"not hold its estimates to the bound{settled}, {further}"
        )


class BendsBeyondBound:
    """The estimates of a robot whose mechanics model does not bound its bends (a
    tendon robot) that bend a section past the robot file's ``theta_max``, counted
    block by block from their outputs (``theta_k``) for one line at the end
    (:meth:`notice`): the file's bound, or the inputs, contradict the estimate."""

    def __init__(self, formulation: Formulation) -> None:
        robot = formulation.robot
        self._robot = robot
        self._limits = np.array([s.theta_max for s in robot.sections])  # rad
        self._columns = _bend_columns(formulation)
        self.active = robot.has_mechanics and all(c >= 0 for c in self._columns)
        self.count = 0
        self.largest = [0.0] * len(robot.sections)

    def add(self, output: FloatArray) -> None:
        """Count the estimates ``output`` (n, ny), NaN rows without an estimate."""
        if not self.active:
            return
        theta = np.abs(output[:, self._columns])
        with np.errstate(invalid="ignore"):
            beyond = theta > self._limits
        self.count += int(beyond.any(axis=1).sum())
        self.largest = _largest_bends(self.largest, theta, beyond)

    def notice(self, n: int) -> str | None:
        """One line for the estimates counted beyond the bound, of ``n``; None without."""
        if not self.count:
            return None
        over = [
            f"section {k + 1} up to {big:.3g} rad (theta_max {s.theta_max:.4g})"
            for k, (s, big) in enumerate(zip(self._robot.sections, self.largest))
            if big > 0
        ]
        return (
            f"{self.count} of {n} estimates bend past the robot file's theta_max: "
            f"{'; '.join(over)}; the mechanics model does not bound the bend, so the "
            "file's bound or the inputs (tensions, tendon angles and radii, backbone) "
            "contradict the estimate: check them"
        )


class ForceBeyondTensions:
    """The largest tip force a tendon robot's estimates reach against the largest
    tendon tension of its inputs, counted block by block (:meth:`add`) for one line at
    the end (:meth:`notice`): a tip force beyond every tension is a large load, or
    tensions given in another unit (kgf for N) that the force makes up for; with every
    tension 0 N, a load or a push along the backbone alone."""

    def __init__(self, formulation: Formulation) -> None:
        names = [o.name for o in formulation.outputs]
        self._force = [names.index(c) for c in TIP_FORCE_COLUMNS if c in names]
        self._tensions = tension_rows(formulation)
        self.active = len(self._force) == 3 and bool(self._tensions)
        self.force = 0.0  # the largest tip force estimated, N
        self.tension = 0.0  # the largest tension given, N

    def add(self, z: FloatArray, output: FloatArray) -> None:
        """Count the samples' measurements ``z`` (n, nz) and estimates ``output`` (n, ny),
        NaN rows without an estimate."""
        if not self.active or not len(z):
            return
        with np.errstate(invalid="ignore"):
            force = np.linalg.norm(output[:, self._force], axis=1)
            tension = z[:, self._tensions]
        if np.isfinite(force).any():
            self.force = max(self.force, float(np.nanmax(force)))
        if np.isfinite(tension).any():
            self.tension = max(self.tension, float(np.nanmax(tension)))

    def notice(self) -> str | None:
        """One line where the tip force went beyond :data:`FORCE_TENSION_RATIO` times
        the largest tension (and over :data:`FORCE_NOTICE_MIN` N); None otherwise."""
        if not self.force > max(FORCE_TENSION_RATIO * self.tension, FORCE_NOTICE_MIN):
            return None
        if self.tension == 0.0:  # no unit or order of a tension can explain it
            return (
                f"the estimated tip force reached {self.force:.3g} N with every tendon "
                "tension given 0 N (slack all along, or not logged?): a load that large, "
                "or a push along a nearly straight backbone, which the IMUs barely see "
                "(a still robot)"
            )
        return (
            f"the estimated tip force reached {self.force:.3g} N, beyond the largest tendon "
            f"tension given ({self.tension:.3g} N): a load that large, or tensions in "
            "another unit (kgf for N?) or order that the tip force makes up for; check them"
        )


#: A tendon robot with tilt IMUs whose estimates twist a section by more than this
#: (rad: 20 degrees) is said at the end of ``estimate`` (:class:`TwistWithTiltImus`): on
#: the shipped recordings the tilt estimates twist ``force-29`` by up to 13 degrees and
#: are 3.5 mm off, ``twist-08`` by 32 degrees and are 63 mm off.
TILT_TWIST_NOTICE = np.radians(20.0)


class TwistWithTiltImus:
    """The largest twist (outputs ``psi_k``) of a tendon robot's estimates from tilt
    IMUs, counted block by block (:meth:`add`), for one line at the end
    (:meth:`notice`) where it passes :data:`TILT_TWIST_NOTICE`: tilt alone (no gyros)
    does not see a turn about the vertical, and the estimates of a robot that a tip
    force twists across its bend are far off while their readings fit, with rows
    ``ok``."""

    def __init__(self, formulation: Formulation) -> None:
        names = [o.name for o in formulation.outputs]
        self._twist = [i for i, n in enumerate(names) if n.startswith("psi_")]
        tilt = getattr(formulation, "imu_model", None) == "tilt"
        self.active = tilt and formulation.robot.has_mechanics and bool(self._twist)
        self.largest = np.zeros(len(self._twist))  # rad, per section

    def add(self, output: FloatArray) -> None:
        """Count the estimates ``output`` (n, ny), NaN rows without an estimate."""
        if not self.active or not len(output):
            return
        twist = np.abs(output[:, self._twist])
        if np.isfinite(twist).any():
            self.largest = np.fmax(self.largest, np.nanmax(twist, axis=0))

    def notice(self) -> str | None:
        """One line where a section's twist passed :data:`TILT_TWIST_NOTICE`; None
        otherwise."""
        if not self.active or not np.any(self.largest > TILT_TWIST_NOTICE):
            return None
        k = int(np.argmax(self.largest))
        return (
            f"the estimates twist section {k + 1} by up to {np.degrees(self.largest[k]):.0f} "
            "degrees: tilt IMUs (no gyros) do not see a turn about the vertical, and the "
            "estimates of a robot that a tip force twists are far off while the readings "
            "fit, with rows ok (the shipped twist-08 and twist-29: 67 and 200 mm mean); "
            "raw IMUs (accelerometer and gyro) follow it (docs/tendon.md, Limits)"
        )


#: A step of ``t`` longer than this many times the recording's usual one is a gap:
#: samples lost between two read (:class:`GapsInTime`; ``live``'s default
#: ``gap_factor`` for its lines' gaps).
GAP_FACTOR = 3.0
#: The steps of ``t`` whose median is the usual one (:class:`GapsInTime`).
GAP_PERIOD_STEPS = 256


class GapsInTime:
    """The gaps in a recording's ``t`` (steps longer than :data:`GAP_FACTOR` times its
    usual step) that are not longer than the gap reset and after which the estimator
    did not restart: it predicted across them without a word of its own (a longer one,
    or one whose readings disagreed with the prediction across it, restarts it, and its
    summary says so), counted block by block (:meth:`add`) for one clause at the end
    (:meth:`clause`).
    The usual step is :func:`~continuum_mhe.arrays.typical_of_steps` of the first
    :data:`GAP_PERIOD_STEPS` steps, once that many are read (of the whole recording
    where shorter)."""

    def __init__(self, gap_reset: float | None) -> None:
        self.gap_reset = gap_reset
        # the steps before the usual one is known: (steps, times after them, restarted
        # there) of each block
        self._pending: list[tuple[FloatArray, FloatArray, NDArray[np.bool_]]] = []
        self._last_t: float | None = None
        self.period: float | None = None
        self.count = 0
        self.missing = 0
        self.largest = 0.0
        self.largest_t = float("nan")  # the time of the sample after the largest gap

    def add(self, t: FloatArray, restarted: NDArray[np.bool_]) -> None:
        """Count the times ``t`` (n,) s, following those of the blocks before;
        ``restarted`` (n,): the estimator restarted at that sample (status ``reset``)."""
        if not len(t):
            return
        before = [] if self._last_t is None else [self._last_t]
        ends = np.concatenate([before, np.asarray(t, dtype=float)])
        self._last_t = float(ends[-1])
        steps, after = np.diff(ends), ends[1:]
        reset = np.asarray(restarted, dtype=bool)[len(t) - len(steps) :]
        if self.period is None:
            self._pending.append((steps, after, reset))
            if sum(len(p[0]) for p in self._pending) >= GAP_PERIOD_STEPS:
                self._settle()
            return
        self._count(steps, after, reset)

    def _settle(self) -> None:
        """Take the usual step from the steps held, and count them."""
        if not self._pending:
            return
        steps, after, reset = (np.concatenate(part) for part in zip(*self._pending))
        self._pending = []
        if not len(steps):
            return
        period = typical_of_steps(steps)
        if period > 0:
            self.period = period
            self._count(steps, after, reset)

    def _count(self, steps: FloatArray, after: FloatArray, reset: NDArray[np.bool_]) -> None:
        assert self.period is not None
        limit = np.inf if self.gap_reset is None else self.gap_reset
        # not longer than the gap reset as the compiled policy decides it (the times'
        # rounding allowed: arrays.longer), so that no gap goes unsaid at the limit
        gap = (steps > GAP_FACTOR * self.period) & ~longer(steps, limit, after) & ~reset
        if not gap.any():
            return
        self.count += int(gap.sum())
        self.missing += int(np.sum(np.maximum(np.rint(steps[gap] / self.period) - 1, 0)))
        k = int(np.argmax(np.where(gap, steps, -np.inf)))
        if steps[k] > self.largest:
            self.largest, self.largest_t = float(steps[k]), float(after[k])

    def clause(self) -> str | None:
        """The summary's clause of the gaps counted (None: none); the steps held for a
        recording shorter than :data:`GAP_PERIOD_STEPS` are judged now."""
        if self.period is None:
            self._settle()
        if not self.count:
            return None
        within = "" if self.gap_reset is None else f" up to --gap-reset {self.gap_reset:g} s"
        return (
            f"estimated across {self.count} gap(s) in t{within} (about {self.missing} "
            f"samples missing at the usual step of {self.period:.3g} s; the largest "
            f"{self.largest:.3g} s, before t = {time_text(self.largest_t)} s)"
        )


#: The share of a run's estimates ``uncertain`` for a wide tip standard deviation above
#: which ``estimate`` says why (:class:`WideUncertain`).
WIDE_NOTICE_SHARE = 0.1


class WideUncertain:
    """The estimates ``uncertain`` whose written tip standard deviation,
    ``sqrt(std_x^2 + std_y^2 + std_z^2)``, exceeds ``fraction`` times the robot's
    length (the policy's test for that status; the robot's length itself for a
    formulation whose covariance is no noise model, the paper's weight ``W``), counted
    block by block (:meth:`add`), for one line at the end (:meth:`notice`) where they
    are more than :data:`WIDE_NOTICE_SHARE` of the run: ``uncertain`` has several
    causes, and this one says the readings do not pin the shape down (or, with the
    paper's weight, that its position's standard deviation grows past the robot)."""

    def __init__(self, formulation: Formulation, fraction: float) -> None:
        self._tip = list(tip_position_indices(formulation.outputs))
        self._weighted = not formulation.calibrated_covariance
        self.limit = (1.0 if self._weighted else fraction) * formulation.robot.length  # m
        self.fraction = fraction
        self.count = 0

    def add(self, output_std: FloatArray, statuses: Sequence[str] | NDArray[Any]) -> None:
        """Count the standard deviations ``output_std`` (n, ny) of rows ``statuses``."""
        if len(self._tip) != 3 or not len(output_std):
            return
        with np.errstate(invalid="ignore"):
            wide = np.linalg.norm(output_std[:, self._tip], axis=1) > self.limit
        uncertain = np.asarray(statuses) == "uncertain"
        self.count += int(np.sum(wide & uncertain))

    def notice(self, n: int) -> str | None:
        """One line where more than :data:`WIDE_NOTICE_SHARE` of the ``n`` estimates
        are ``uncertain`` for their width; None otherwise."""
        if n == 0 or self.count <= WIDE_NOTICE_SHARE * n:
            return None
        if self._weighted:
            return (
                f"{self.count} of {n} estimates are uncertain with their tip standard "
                f"deviation past the robot's length ({self.limit * 1e3:.0f} mm): this "
                "model's process weight W is no noise model, and its position's standard "
                "deviation grows past the robot's reach (docs/uncertainty.md, the "
                "uncertain status)"
            )
        return (
            f"{self.count} of {n} estimates are uncertain with their tip standard deviation "
            f"over --uncertain-fraction {self.fraction:g} of the robot's length "
            f"({self.limit * 1e3:.0f} mm): the readings do not pin the shape down there "
            "(docs/uncertainty.md, the uncertain status)"
        )


#: A tendon robot's tension gain (:attr:`~continuum_mhe.model.tendon.TendonFormulation.
#: estimate_tension_gain`) that ends more than this many of its standard deviations from
#: 1 is said at the end of ``estimate`` (:class:`TensionGainFromOne`).
TENSION_GAIN_SIGMAS = 3.0


class TensionGainFromOne:
    """A tendon robot's estimated tension gains (outputs ``tension_gain_s``: the tension
    acting on the robot over the one given, for the tendons anchored at section ``s``),
    the last informed estimate's (:meth:`add`), for one line at the end (:meth:`notice`)
    where one ends far from 1: the tensions given are not those acting (another unit, a
    tension sensor's gain, the tendons' friction). An estimate is informed where every
    gain's standard deviation is under half its prior's
    (:attr:`~continuum_mhe.model.tendon.TendonFormulation.initial_tension_gain_std`): a
    restart late in a recording starts the gains at their prior again, and the rows
    after it would hide what the readings showed before it."""

    def __init__(self, formulation: Formulation) -> None:
        names = [o.name for o in formulation.outputs]
        self._columns = [i for i, n in enumerate(names) if n.startswith("tension_gain_")]
        self._sections = [names[i].removeprefix("tension_gain_") for i in self._columns]
        self.active = bool(self._columns)
        self._informed = 0.5 * float(getattr(formulation, "initial_tension_gain_std", np.inf))
        self.gain: FloatArray | None = None  # the last informed estimate's gains
        self.std: FloatArray | None = None  # and their standard deviations
        self._has_informed = False  # whether those are an informed estimate's

    def add(self, output: FloatArray, output_std: FloatArray) -> None:
        """Keep the last informed estimate's gains of ``output`` (n, ny) and their
        ``output_std`` (n, ny), NaN rows without an estimate; where no estimate so far is
        informed, the last estimate's."""
        if not self.active or not len(output):
            return
        gain, std = output[:, self._columns], output_std[:, self._columns]
        finite = np.all(np.isfinite(gain) & np.isfinite(std), axis=1)
        informed = np.flatnonzero(finite & np.all(std < self._informed, axis=1))
        if len(informed):
            self.gain, self.std, self._has_informed = gain[informed[-1]], std[informed[-1]], True
            return
        has = np.flatnonzero(finite)
        if len(has) and not self._has_informed:
            self.gain, self.std = gain[has[-1]], std[has[-1]]

    def notice(self) -> str | None:
        """One line where a gain ended more than :data:`TENSION_GAIN_SIGMAS` standard
        deviations from 1; None otherwise."""
        if self.gain is None or self.std is None:
            return None
        far = [
            f"section {s}: {g:.3g} (std {d:.2g})"
            for s, g, d in zip(self._sections, self.gain, self.std)
            if abs(g - 1.0) > TENSION_GAIN_SIGMAS * d
        ]
        if not far:
            return None
        line = (
            f"the estimated tension gains ended more than {TENSION_GAIN_SIGMAS:g} standard "
            f"deviations from 1 ({'; '.join(far)}): the tensions given are not those acting "
            "(another unit, kgf for N?, a tension sensor's gain, the tendons' friction): "
            "check them"
        )
        if self.disagree():
            line += (
                "; the sections' gains disagree beyond their standard deviations: a unit "
                "or one sensor gain would scale both alike, so unless the sections' "
                "friction differs this much, the gains, and the estimates, are not to be "
                "trusted"
            )
        return line

    def disagree(self) -> bool:
        """Whether two sections' last informed gains differ by more than
        :data:`TENSION_GAIN_SIGMAS` of their combined standard deviation (the gains
        taken independent)."""
        if self.gain is None or self.std is None or len(self.gain) < 2:
            return False
        g, d = self.gain, self.std
        return any(
            abs(g[i] - g[j]) > TENSION_GAIN_SIGMAS * float(np.hypot(d[i], d[j]))
            for i in range(len(g))
            for j in range(i + 1, len(g))
        )


#: A run with more than this share of its estimates ``inconsistent`` (and at least
#: :data:`INCONSISTENT_SAID` of them) is said at the end of ``estimate`` and in
#: ``live``'s summary (:func:`inconsistent_notice`): on model-consistent recordings the
#: share stays near the consistency test's false-alarm rate.
INCONSISTENT_SHARE = 0.25
INCONSISTENT_SAID = 5


def inconsistent_notice(inconsistent: int, n: int, formulation: Formulation) -> str | None:
    """The line for a run whose ``inconsistent`` rows (of ``n`` estimates) exceed
    :data:`INCONSISTENT_SHARE`: the readings disagree with the model of the robot
    beyond their noise for much of the run, so the robot file, the readings' order or
    units, or (raw IMUs) the IMUs' own acceleration are to be checked; None otherwise."""
    if inconsistent < INCONSISTENT_SAID or inconsistent <= INCONSISTENT_SHARE * n:
        return None
    robot = formulation.robot
    checks = [
        "the robot file against the robot (the IMUs' order, each IMU's section, at and "
        "mount_rpy, the sections' lengths and their order, the mounting; check-robot "
        "lists them)",
        "the readings' columns (each IMU's in the robot file's order) and units",
        "readings noisier in motion than --noise-deg "
        f"{math.degrees(formulation.noise.measurement_std):.3g} (degrees) assumes (a "
        "vibrating robot, a noisier IMU: the summary's scatter of the readings over their "
        "noise model's std says by how much; a larger --noise-deg widens the noise model)",
    ]
    if robot.has_mechanics:
        checks.append("the tensions (their scale, unit, tendon order and timing)")
    elif isinstance(formulation, DirectFormulation) and not formulation.own_acceleration:
        checks.append(
            "the IMUs' own acceleration in their readings, which the model leaves out (a "
            "fast motion, or quiet readings at 50 Hz or more, as simulate --imu raw writes "
            "them: --own-acceleration models it)"
        )
    if isinstance(formulation, DirectFormulation) and formulation.estimate_gyro_bias:
        checks.append(
            "the gyros' biases, which the model lets drift slowly: a bias that steps (a "
            "change of temperature, a board's power cycled) disagrees with the readings "
            "for seconds to minutes after"
        )
    fast = ""
    if bend_accel_psd_applies(formulation):  # --accel-psd sets its motion model
        fast = (
            ", or moves faster than the motion model lets the bends change (a larger "
            "--accel-psd, NoiseSettings.bend_accel_psd, follows a faster robot)"
        )
    twist = "a backbone that twists about itself"
    if isinstance(formulation, DirectFormulation) and not formulation.imu_twist:
        twist += " (--imu-twist follows it, the gyros calibrated at rest)"
    return (
        f"{inconsistent} of {n} estimates ({100 * inconsistent / n:.0f} %) are inconsistent: "
        "their readings disagree with the model of the robot beyond the readings' noise "
        "for much of the run; check "
        + "; ".join(checks)
        + f"; or the robot does what the model cannot follow ({twist}, a load that bends "
        f"a section off constant curvature){fast}. Until the cause is found its ok rows "
        "are not to be trusted either: a wrong robot file can fit some readings exactly, "
        "and an ok row between inconsistent ones can be far off within a narrow standard "
        "deviation"
    )


def drifted_notice(drifted: int, n: int, formulation: Formulation) -> str | None:
    """The line for a tendon robot's ``drifted`` rows (``drifted`` of ``n`` estimates):
    the IMU error states took up what the model did not explain, so check the tensions
    and the robot file; None where there are none or the robot has no mechanics model
    (``estimate``'s warning and ``live``'s summary)."""
    if not drifted or not formulation.robot.has_mechanics:
        return None
    tilt = (
        "; with tilt IMUs a loaded robot that twists is not followed with the right "
        "inputs either (raw IMUs are: docs/tendon.md, Limits)"
        if getattr(formulation, "imu_model", None) == "tilt"
        else ""
    )
    tensions = (
        "the tensions (their scale, unit, tendon order and timing; --estimate-tension-gain "
        "estimates a scale) and "
        if formulation.robot.tendons
        else ""
    )
    robot = formulation.robot
    route = (
        ', the tendons\' path (tendon_route = "disks" where they run straight between spacer disks)'
        if robot.tendons
        and robot.tendon_route == "continuous"
        and any(sec.disks for sec in robot.sections)
        else ""
    )
    buckling = getattr(formulation, "buckling_load", None)
    push = (
        f"; or the tip force pushed along the backbone harder than "
        f"{'' if BUCKLED_PUSH_MULTIPLE == 1 else f'{BUCKLED_PUSH_MULTIPLE:g} times '}its "
        "buckling load "
        f"({BUCKLED_PUSH_MULTIPLE * buckling:.3g} N), which a free tip cannot hold and the "
        "IMUs barely see along a nearly straight backbone (a still robot, or one whose tip "
        "presses on something)"
        if buckling is not None
        else ""
    )
    return (
        f"{drifted} of {n} estimates drifted: the IMUs' error states left their prior or "
        "changed faster than their model allows, where the model follows the readings "
        f"only with IMU errors these IMUs are not taken to have (check {tensions}the robot "
        f"file: the IMUs' places and mountings (mount_rpy), the backbone{route}){push}{tilt}"
    )


def free_of_load_clause(inference: Inference, n: int) -> str | None:
    """The summary's clause of the estimates, of ``n``, that a tendon robot's EKF or MHE took as
    free of load (:mod:`.load_hypotheses`); None for any other inference."""
    if not isinstance(inference, LoadHypothesesInference):
        return None
    free = inference.free_of_load_samples
    return f"taken as free of load (tip force 0 N) in {free} of the {n} estimates"


def glitch_clause(diagnostics: Diagnostics) -> str | None:
    """The summary's clause of the IMU readings skipped as glitches
    (``Diagnostics.glitches``; ``estimate``'s and ``live``'s), or None where none was."""
    if not diagnostics.glitches:
        return None
    return (
        f"skipped {diagnostics.glitches} IMU reading(s) far beyond the prediction from the ok "
        "estimate before them (glitches: that IMU's dropout for the sample, the row not ok)"
    )


def recovery_clauses(
    diagnostics: Diagnostics, recovery: RecoverySettings, n: int, frozen_by_imu: str = ""
) -> list[str]:
    """The summary's clauses of what the sensor-health policy did over ``n`` estimates
    (``estimate``'s and ``live``'s), in order: the rows with a frozen IMU (``frozen_by_imu``:
    their count by IMU, where known), the glitches skipped, and the restarts after a
    diverged estimate, a gap, a jump in t, an IMU's late first reading, a bad start and
    drifted rows;
    those that happened alone."""
    d, r = diagnostics, recovery
    clauses = []
    if d.frozen_samples:
        of = f": {frozen_by_imu}" if frozen_by_imu else ""
        clauses.append(
            f"{d.frozen_samples} of the {n} estimates had a frozen IMU (the same reading for "
            f"over {r.freeze:g} s, treated as a dropout){of}"
        )
    if glitches := glitch_clause(d):
        clauses.append(glitches)
    if d.restarts:
        clauses.append(
            f"restarted {d.restarts} time(s) after the estimate diverged, failed or its "
            "uncertainty outgrew the workspace (status reset, or no-estimate on a sample "
            "without a valid reading)"
        )
    if d.gap_resets:
        clauses.append(
            f"restarted after {d.gap_resets} gap(s) longer than {r.gap_reset:g} s without a "
            "valid reading (a gap in t, or IMUs silent or stuck on one value)"
        )
    if d.jump_resets:
        first = ""
        if d.first_jump is not None:
            t, step = d.first_jump
            first = f" (the first {step:.3g} s long, before t = {time_text(t)} s)"
        clauses.append(
            f"restarted after {d.jump_resets} jump(s) in t shorter than {r.gap_reset:g} s"
            f"{first} whose "
            "readings disagreed with the prediction across it (a clock that stepped forward, "
            "or samples lost)"
        )
    if d.late_imu_starts:
        clauses.append(
            f"restarted {d.late_imu_starts} time(s) at an IMU's first reading beside the "
            "others (the start had no reading of it)"
        )
    if d.bad_starts:
        clauses.append(
            f"restarted {d.bad_starts} time(s) after readings inconsistent with the start or "
            "an IMU's return"
        )
    if d.drift_resets:
        clauses.append(
            f"restarted {d.drift_resets} time(s) from the last ok estimate's IMU errors after "
            f"{r.drift_reset:g} s of drifted rows"
        )
    return clauses


def untrusted_start_notice(diagnostics: Diagnostics, n: int, tendons: bool = True) -> str | None:
    """The line for the estimates, of ``n``, of a start whose first reading showed a
    load it could not tell from the IMUs' errors (a tendon robot's, in any estimator:
    ``Diagnostics.untrusted_start_samples``, every row of such a start: none of them
    ``ok``); None where there are none (``estimate``'s warning and ``live``'s summary)."""
    if not diagnostics.untrusted_start_samples:
        return None
    shown = "a tip load (or tensions that do not act as given)" if tendons else "a tip load"
    check = ", and check the tensions (their scale, unit, tendon order and timing)"
    return (
        f"{diagnostics.untrusted_start_samples} of {n} estimates are of a start whose first "
        f"IMU reading showed {shown}, which a start "
        "cannot tell from the IMUs' misalignments and accelerometer biases: none of them is "
        "ok (uncertain, or drifted where the IMU errors left their prior, where not a "
        "restart or a dropout), as they may take part of the load for those errors; start "
        "the recording with the robot free of load (the estimates then learn the IMUs' "
        f"errors, and keep them across a gap){check if tendons else ''}"
    )


#: A run in which at least this many restarts, and more than the share of the samples
#: measured for Imu topics out of order
#: (:data:`~continuum_mhe.io.imu_topics.ORDER_RESTART_SHARE`), restarted the estimator is
#: said at the end of ``estimate`` and in ``live``'s summary (:func:`restarts_notice`):
#: one restart in a file of a few samples says nothing of the robot file.
RESTARTS_SAID = 5


#: What a warning of a model that does not fit the readings says instead of its own list
#: of causes where the warning on inconsistent estimates (:func:`inconsistent_notice`),
#: which lists them all, follows it.
CAUSES_FOLLOW = "what to check: the warning on inconsistent estimates, which follows"


def restarts_notice(
    samples: int, restarts: int, last_failure: str | None = None, causes_follow: bool = False
) -> str | None:
    """One line where more than ``ORDER_RESTART_SHARE`` of ``samples``, and at least
    :data:`RESTARTS_SAID`, restarted the estimator (``restarts``, gaps not counted): the
    readings do not fit the model of the robot, or (``last_failure``, the policy's last
    numerical failure, the UKF's) its sigma points spread a tilt reading across a half
    turn; None otherwise. ``causes_follow``: the warning on inconsistent estimates
    follows, and this one points to its list of causes instead of giving its own."""
    from continuum_mhe.estimators.kalman import UNSCENTED_SPREAD
    from continuum_mhe.io.imu_topics import ORDER_RESTART_SHARE

    if restarts < RESTARTS_SAID or restarts <= ORDER_RESTART_SHARE * samples:
        return None
    said = f"{restarts} of {samples} samples ({100 * restarts / samples:.0f} %) restarted the "
    if last_failure is not None and UNSCENTED_SPREAD in last_failure:
        return said + (
            "UKF: its sigma points spread a tilt reading across a half turn, where the "
            "unscented transform means nothing (a robot whose IMUs bend far from level, or "
            "an estimate this uncertain; the last restart's: "
            f"{last_failure.split(': ', 1)[-1]}); the EKF (--method ekf) has no sigma points"
        )
    said += (
        "estimator (readings inconsistent with its estimate, or an estimate that diverged): "
        "the readings do not fit the model of the robot"
    )
    if causes_follow:
        return f"{said} ({CAUSES_FOLLOW})"
    return said + (
        "; check the robot file against the "
        "robot (the IMUs' order, their mount_rpy and at, the sections' lengths; "
        "check-robot lists them), or the robot does what the model cannot follow (a "
        "backbone that twists about itself)"
    )
