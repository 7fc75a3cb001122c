"""Tendon tensions files: ``t,tension_1,...,tension_k`` (s, N), in the robot file's
``[[tendon]]`` order, at any rate.

The tensions at a measurement's time are interpolated linearly between the file's
rows; their rates are the central differences of the file's rows, and their second
derivatives the central differences of those rates (the rows on the line through
their neighbours, a slower log resampled linearly, left out, and a tensions file logged
at 75 Hz or faster averaged over bins of about 20 ms first; a recording's own tension
columns row by row, as ``live`` differenced them), both interpolated the same way (what the gyros
see of the tendons' pull, and the IMUs' own acceleration that the accelerometers read).
Where a tensions file's rows scatter (a load cell's noise) so that those differences
would be noisier than :data:`TENSION_RATE_NOISE` and :data:`TENSION_ACCELERATION_NOISE`,
the tensions, their rates and second derivatives are a local cubic's over the fewest
rows that bring them within these (Savitzky-Golay, at most
:data:`~.tension_derivatives.MAX_SMOOTHING_S`), and this is said
(:func:`~.tension_derivatives.tension_derivatives`). A tensions file
must cover the recording: a measurement before its first row or after its last is an
error, as are a non-finite tension, a tension further below zero than a slack tendon's
load cell reads (:mod:`.slack_readings`; one within that is taken as 0), a wrong
number of tension columns and times that do not increase.

A tension that one row alone gets wrong (a glitch; in a file, two rows in a row too) is
replaced by the cubic through its neighbours (:mod:`.tension_glitches`).

The tensions may also come one sample at a time (``live``'s serial line:
:class:`TensionStream`), with the same derivatives: those of a sample are known once
the two samples after it have arrived (four near a candidate glitch).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from continuum_mhe.arrays import FloatArray, holds_bools
from continuum_mhe.errors import (
    InputError,
    SampleTimeError,
    UserError,
    is_integer,
    is_real,
    time_text,
)
from continuum_mhe.io.csv_files import MS_LIKE_STEP_S, DropoutWarning, check_time_units
from continuum_mhe.io.imu_columns import TILT_IMU_COLUMNS
from continuum_mhe.io.input_options import DEFAULT_GYRO_STD, InputOptions, OptionWarning
from continuum_mhe.io.raw_imu import RAW_IMU_COLUMNS
from continuum_mhe.io.sample_rows import RowProblems, read_samples
from continuum_mhe.io.slack_readings import take_slack_readings
from continuum_mhe.io.tension_derivatives import (
    TENSION_ACCELERATION_NOISE,
    TENSION_RATE_NOISE,
    TensionSmoothing,
    central_difference_gains,
    central_differences,
    slower_log,
    smoothing_rows,
    tension_derivatives,
    tension_noise_std,
)
from continuum_mhe.io.tension_glitches import (
    StreamGlitches,
    TensionGlitches,
    stream_glitches,
    tension_glitches,
)
from continuum_mhe.io.text_rows import open_rows
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.robot import Robot, modulus_unit_hint
from continuum_mhe.model.tendon import SINGLE_IMU_GYRO_STD, TendonFormulation

#: The turns a section may bend through under its tendons alone (their net moment over
#: its bending stiffness, times its length) before the tensions are refused as another
#: unit: a load at the tip may hold a section against more than its tendons' own bend.
MAX_TENDON_TURNS = 2.0
#: The largest tension (N) read as a tension in N where the tensions would bend a section
#: too far: beyond it, the tensions are more likely in another unit (mN) than the
#: backbone too soft.
PLAUSIBLE_TENSION_N = 200.0
#: Tensions repeated exactly for longer than this (s) are said (a logger that froze;
#: live load cells are never exactly still); a controller may hold a tendon's set
#: tension constant for a while, so this is longer than an IMU's freeze
#: (:data:`~continuum_mhe.settings.FREEZE_S`).
TENSIONS_FROZEN_S = 1.0
#: A step between two rows of more than this many times the median step (and over
#: :data:`TENSIONS_HOLE_S`) is said: the tensions are interpolated across the hole.
TENSIONS_HOLE_FACTOR = 10.0
#: The shortest hole between two rows that is said, s.
TENSIONS_HOLE_S = 0.1
#: Rows more than this many times as far apart as the recording's samples are said.
TENSIONS_SPARSE_FACTOR = 10.0
#: Samples of a stream of tensions (``live``) whose scatter is checked at a time
#: (:class:`TensionStream`).
NOISE_CHECK_ROWS = 50


class TensionsWarning(UserWarning):
    """A tensions file whose rows look like a sensor or logger fault (read as given),
    scatter so that they are smoothed, or hold the samples of a slower log; tensions
    differenced row by row that carry a slower log's samples."""


#: Tension times from this many seconds on (1973) are a clock's absolute time (since
#: 1970), not seconds from the recording's start: said where they miss the recording.
EPOCH_LIKE_S = 1e8


def slower_log_said(what: str, t: FloatArray, values: FloatArray, taken: str, fix: str) -> str:
    """The line that says that ``what`` (``values`` (n, k) N at ``t`` (n,) s), which are
    ``taken`` row by row, carry a slower log's samples
    (:func:`~.tension_derivatives.slower_log`), and the ``fix``; ``""`` where they do
    not."""
    found = slower_log(t, values)
    if found is None:
        return ""
    how, period = found
    carried = "hold each value of" if how == "hold" else "are resampled linearly from"
    return (
        f"{what} {carried} a slower log (every {period:.3g} s, {1 / period:.3g} Hz): "
        f"{taken}, so that each of that log's samples is a spike of the tensions' rates and "
        f"second derivatives, which the estimate follows (tens of mm off at the tip); {fix}"
    )


#: The share of the load that buckles a disk-routed section's backbone between two of its
#: disks (``pi^2 EI / d^2``) beyond which its tensions are said: the model's span, a
#: beam-column, bends ever more steeply towards that load.
SPAN_BUCKLING_SHARE = 0.6


def span_buckling_problem(robot: Robot, t: FloatArray, rows: FloatArray, name: str) -> str:
    """What to say where the tensions ``rows`` (N, at ``t`` s) through a section of a
    robot whose tendons run from disk to disk (``tendon_route = "disks"``) exceed
    :data:`SPAN_BUCKLING_SHARE` of the load that buckles its backbone between two
    disks, else ``""``."""
    if robot.tendon_route != "disks" or robot.backbone is None or not len(t):
        return ""
    ei = robot.backbone.bending_stiffness
    values = np.clip(np.nan_to_num(np.atleast_2d(np.asarray(rows, dtype=float))), 0.0, None)
    for k, sec in enumerate(robot.sections):
        through = [j for j, td in enumerate(robot.tendons) if td.section >= k]
        if not through or sec.disks < 1:
            continue
        d = sec.length / sec.disks
        buckling = math.pi**2 * ei / d**2
        total = values[:, through].sum(axis=1)
        i = int(np.argmax(total))
        if total[i] > SPAN_BUCKLING_SHARE * buckling:
            return (
                f"{name}: at t = {time_text(float(t[i]))} s the tensions through section "
                f"{k + 1}, {total[i]:.3g} N in all, are {total[i] / buckling:.2f} of the "
                f"load that buckles its backbone between two disks {d * 1e3:.3g} mm apart "
                f'(pi^2 EI / d^2 = {buckling:.3g} N; tendon_route = "disks"): the model '
                "bends it ever more steeply towards that load, and the estimates there are "
                "less sure than their standard deviations say"
            )
    return ""


def tension_turns(robot: Robot, rows: FloatArray) -> tuple[int, int, float] | None:
    """``(row, section, turns)`` of the first section (0-based) of ``robot`` (with a
    ``[backbone]``) whose tendons' net moment at one of the tensions ``rows`` (n,
    tendons; N), over its bending stiffness, times its length, bends it through more
    than :data:`MAX_TENDON_TURNS` full turns, at the row where it is largest; None where
    none does (the twist left out)."""
    if robot.backbone is None or not robot.tendons:
        return None
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    ei = robot.backbone.bending_stiffness
    for k, section in enumerate(robot.sections):
        idx = [j for j, td in enumerate(robot.tendons) if td.section >= k]
        if not idx:
            continue
        arm = np.array([[robot.tendons[j].radius * math.cos(robot.tendons[j].angle),
                         robot.tendons[j].radius * math.sin(robot.tendons[j].angle)]
                        for j in idx])  # fmt: skip
        moment = np.linalg.norm(np.nan_to_num(rows[:, idx]) @ arm, axis=1)  # N m, per row
        bend = moment * section.length / ei
        i = int(np.argmax(bend))
        if bend[i] > MAX_TENDON_TURNS * 2 * math.pi:
            return i, k, float(bend[i] / (2 * math.pi))
    return None


def tension_scale_problem(
    robot: Robot,
    t: FloatArray,
    rows: FloatArray,
    name: str,
    lines: Sequence[int] | None = None,
) -> str | None:
    """The line saying where the tensions ``rows`` (n, tendons; N) at the times ``t``
    would bend a section of ``robot`` (with a ``[backbone]``) through more than
    :data:`MAX_TENDON_TURNS` full turns on their own (:func:`tension_turns`: tensions
    in mN, or a modulus far too low); ``name`` the source in the line, ``lines`` each
    row's line in it; None where no row does."""
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    beyond = tension_turns(robot, rows)
    if beyond is None or robot.backbone is None:
        return None
    i, k, turns = beyond
    bb = robot.backbone
    # a unit only for a modulus below 1e6 Pa, softer than any backbone's in Pa
    unit = modulus_unit_hint(bb.youngs_modulus) if bb.youngs_modulus < 1e6 else None
    soft = (
        f"the robot file's [backbone] too soft (youngs_modulus {bb.youngs_modulus:g} "
        f"Pa{': ' + unit if unit else ''}; radius {bb.radius:g} m)"
    )
    # tensions a tendon can carry in N point at the backbone first
    causes = [soft, "tensions in N (mN or grams?)"]
    if float(np.nanmax(rows)) > PLAUSIBLE_TENSION_N:
        causes.reverse()
    line = "" if lines is None else f"line {lines[i]}: "
    return (
        f"{name}: {line}at t = {time_text(float(t[i]))} s the tensions "
        f"({', '.join(f'{v:g}' for v in rows[i])} N) would bend section "
        f"{k + 1} through {turns:.3g} full turns (its bending "
        f"stiffness {bb.bending_stiffness:.3g} N m^2): {causes[0]}, or {causes[1]}?"
    )


#: How far beyond a tensions file's first or last row (s) a sample still counts as
#: covered by it (the estimate files' times are written to the microsecond).
COVER_TOLERANCE_S = 1e-6


@dataclass(frozen=True)
class Tensions:
    """A tensions file read whole.

    Attributes:
        name: the file as shown in messages.
        t: (n,) s, strictly increasing.
        values: (n, k) N, non-negative.
        rates: (n, k) N/s, central differences (one-sided at the ends; zero with one
            row; of 20 ms bins of a faster file; of a local cubic where the rows
            scatter: :func:`tension_derivatives`).
        accelerations: (n, k) N/s^2, the rates' central differences (the same way).
        smoothing: how the rows were smoothed, where they scatter (None: they are
            taken as they are).
        given: the file's tensions as given, where ``values`` are smoothed or taken
            between a held log's samples (else None; :attr:`rows`).
        hold_period_s: the period of a slower log whose values the rows hold (a
            zero-order hold), s: ``values`` are linear between the rows where they
            change (0: none found; :func:`~.tension_derivatives.hold_knots`).
        lines: each row's line in its file, for messages (None: rows of no file).
        time_column: the file's time column, ``t`` (s) or ``t_ms`` (ms, converted to
            s), for messages about its unit.
    """

    name: str
    t: FloatArray
    values: FloatArray
    rates: FloatArray
    accelerations: FloatArray
    smoothing: TensionSmoothing | None = None
    given: FloatArray | None = None
    hold_period_s: float = 0.0
    lines: tuple[int, ...] | None = None
    time_column: str = "t"

    @classmethod
    def from_rows(
        cls,
        name: str,
        t: FloatArray,
        values: FloatArray,
        binned: bool = True,
        lines: tuple[int, ...] | None = None,
        glitches: Literal["rows", "stream"] = "rows",
    ) -> Tensions:
        """The tensions of rows ``values`` (n, k) N at ``t`` (n,) s, with their
        derivatives (:func:`tension_derivatives`); ``lines``: each row's line in its
        file (None: rows of no file). A tension that one row alone gets wrong is
        replaced by the cubic through its neighbours, with a :class:`TensionsWarning`:
        judged by the rows around (``glitches="rows"``,
        :func:`~.tension_glitches.tension_glitches`) or as ``live``'s stream judges it
        (``"stream"``, :class:`~.tension_glitches.StreamGlitches`: a recording's own
        tension columns, so that a replay gives ``live``'s estimates).

        Raises:
            UserError: arrays that are not numbers of those shapes, of different
                lengths or without a row; a ``t`` that is not finite and strictly
                increasing; a tension that is not a finite number (leave such a row out:
                the tensions are interpolated across it) or is negative.
        """
        t, values = _checked_rows(name, t, values, lines)
        judged = (
            stream_glitches(t, values, NOISE_CHECK_ROWS)
            if glitches == "stream"
            else tension_glitches(t, values, tension_noise_std(values, t))
        )
        values_used = _without_glitches(values, judged) if judged.count else values
        if judged.count:
            warnings.warn(
                _glitches_said(name, values, values_used, judged, lines), TensionsWarning, 2
            )
        taken = tension_derivatives(t, values_used, binned=binned)
        changed = (
            taken.smoothing is not None or taken.hold_period_s > 0 or values_used is not values
        )
        return cls(
            name,
            t,
            taken.values,
            taken.rates,
            taken.accelerations,
            taken.smoothing,
            given=values if changed else None,
            hold_period_s=taken.hold_period_s,
            lines=lines,
        )

    @property
    def rows(self) -> FloatArray:
        """The file's tensions as it gives them (n, k), N: :attr:`values` unless these
        are smoothed. The checks of the file's sensors and logger read these; the scale
        check (:meth:`check_scale`) reads :attr:`values`, as the estimate takes them."""
        return self.values if self.given is None else self.given

    def warn_smoothed(self) -> None:
        """A :class:`TensionsWarning` where the rows scatter so that the tensions are
        smoothed (:attr:`smoothing`): by how much, and over what span."""
        sm = self.smoothing
        if sm is not None:
            left = (
                ""
                if sm.rate_noise <= TENSION_RATE_NOISE
                and sm.acceleration_noise <= TENSION_ACCELERATION_NOISE
                else f"; even so their rates keep a noise of about {sm.rate_noise:.2g} N/s "
                f"and their second derivatives {sm.acceleration_noise:.2g} N/s^2, more than "
                f"the estimators take without losing accuracy ({TENSION_RATE_NOISE:g} and "
                f"{TENSION_ACCELERATION_NOISE:g}): filter the tensions at their source"
            )
            warnings.warn(
                f"{self.name}: the tensions scatter by about {sm.noise_std:.2g} N from row "
                "to row (a load cell's noise?): their values, rates and second derivatives "
                f"are those of a local cubic over {sm.span_s:.2g} s (Savitzky-Golay), "
                "so that the noise does not move the estimate; a tension that changes within "
                f"less than that is smoothed too{left}",
                TensionsWarning,
                stacklevel=2,
            )

    def warn_held(self) -> None:
        """A :class:`TensionsWarning` where the rows hold each value of a slower log
        (:attr:`hold_period_s`): the tensions are taken linear between the rows where
        they change."""
        if self.hold_period_s > 0:
            warnings.warn(
                f"{self.name}: the tensions hold each value for about "
                f"{self.hold_period_s:.3g} s (a log at {1 / self.hold_period_s:.3g} Hz "
                "written at every row): the rows where a value changes are taken as that "
                "log's samples, the tensions linear between them and differenced there",
                TensionsWarning,
                stacklevel=2,
            )

    def warn_slower_log(self) -> None:
        """A :class:`TensionsWarning` where a recording's own tension columns,
        differenced row by row (as ``live`` takes them), carry a slower log's samples
        (:func:`~.tension_derivatives.slower_log`): each of that log's samples is then
        a spike of the rates and second derivatives, which the estimate follows; or
        where they scatter so that a tensions file of them would be smoothed (as
        ``live`` says of its stream)."""
        said = slower_log_said(
            f"{self.name}: the tension columns",
            self.t,
            self.values,
            "a recording's own tension columns are differenced row by row, as live takes them",
            "give the tensions as a file of their own (--inputs TENSIONS.csv, columns "
            "t,tension_1,...), whose rows are taken as that log's samples, or log them at "
            "the IMUs' rate",
        )
        if said:
            warnings.warn(said, TensionsWarning, stacklevel=2)
            return
        noise = tension_noise_std(self.values, self.t)
        step = float(np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0
        if not step > 0 or smoothing_rows(noise, step) == 0:
            return
        rate, acc = central_difference_gains(step)
        warnings.warn(
            f"{self.name}: the tension columns scatter by about {noise:.2g} N from row to "
            "row (a load cell's noise?), and a recording's own tension columns are "
            "differenced row by row, as live takes them, with a noise of about "
            f"{noise * rate:.2g} N/s and {noise * acc:.2g} N/s^2 (the estimators take "
            f"{TENSION_RATE_NOISE:g} and {TENSION_ACCELERATION_NOISE:g} without losing "
            "accuracy): give the tensions as a file of their own (--inputs TENSIONS.csv, "
            "columns t,tension_1,...), whose noise is smoothed, or filter them at their "
            "source",
            TensionsWarning,
            stacklevel=2,
        )

    def check_span(self, first: float, last: float) -> None:
        """An :class:`InputError` where the file spans over a hundred times the
        recording's times ``first`` to ``last`` (s) and either its rows step by a second
        or more or, read in milliseconds, it would cover the recording (a log faster
        than 1 kHz): ``t`` in milliseconds read as seconds, which the coverage check does
        not see (the recording lies within the file's first rows); one row so far from
        the others that its jump is most of the span is named instead (a logger's clock
        that jumped). A file at a slow rate that spans the recording passes."""
        if len(self.t) < 2 or not last > first:
            return
        step = float(np.median(np.diff(self.t)))
        span = float(self.t[-1] - self.t[0])
        # within a millisecond of each end, read in milliseconds (seconds)
        as_ms_covers = self.t[0] / 1e3 <= first + 1e-3 and self.t[-1] / 1e3 >= last - 1e-3
        if span > 100.0 * (last - first) and (step >= 1.0 or as_ms_covers):
            steps = np.diff(self.t)
            j = int(np.argmax(steps))
            if steps[j] > 0.9 * span and steps[j] > 1000.0 * step:  # one row far off
                line = f"line {self.lines[j + 1]}: " if self.lines is not None else ""
                raise InputError(
                    f"{self.name}: {line}its {self.time_column} jumps by {steps[j]:g} s from "
                    f"the row before ({self.t[j]:g} to {self.t[j + 1]:g} s; the rows step by "
                    f"{step:g} s): a logger's clock that jumped? Cut the file to the "
                    "recording's times"
                )
            unit = (
                "if t_ms is in microseconds, give milliseconds; if it is in milliseconds"
                if self.time_column == "t_ms"
                else "if t is in milliseconds, name the column t_ms (it is read in seconds; "
                "microseconds: divide them by 1000 first); if it is in seconds"
            )
            raise InputError(
                f"{self.name}: its {self.time_column} spans {span:g} s in steps of {step:g} s, "
                f"the recording {last - first:g} s: {unit}, cut the file to the recording's "
                "times"
            )

    def check_scale(self, robot: Robot) -> None:
        """An :class:`InputError` where the tensions would bend a section of ``robot``
        through more than :data:`MAX_TENDON_TURNS` full turns on their own
        (:func:`tension_scale_problem`: tensions in mN, or a modulus far too low), as
        the estimate takes them: a glitch replaced (and said) is not judged; a
        :class:`TensionsWarning` where they near the load that buckles a disk-routed
        section between its disks (:func:`span_buckling_problem`)."""
        problem = tension_scale_problem(robot, self.t, self.values, self.name, self.lines)
        if problem is not None:
            raise InputError(problem)
        near = span_buckling_problem(robot, self.t, self.values, self.name)
        if near:
            warnings.warn(near, TensionsWarning, stacklevel=2)

    def warn_suspect(self, first: float | None = None, last: float | None = None) -> None:
        """A :class:`TensionsWarning` for what the file's rows say of its sensors or
        logger: a tendon whose tension is 0 in every row (a sensor not connected, or a
        tendon slack all along), tensions that repeat exactly for over
        :data:`TENSIONS_FROZEN_S` (a logger that froze), and a hole between two rows of
        over :data:`TENSIONS_HOLE_FACTOR` times the usual step and
        :data:`TENSIONS_HOLE_S` (bridged by the linear interpolation). ``first`` and
        ``last``: the recording's first and last times, s, where known: only the rows
        the recording uses count (from the last row at or before ``first`` to the first
        at or after ``last``)."""
        t, rows = self.t, self.rows
        if first is not None and last is not None:
            lo = max(int(np.searchsorted(t, first, side="right")) - 1, 0)
            hi = int(np.searchsorted(t, last, side="left"))
            t, rows = t[lo : hi + 1], rows[lo : hi + 1]
        n = len(t)
        if n >= 2:
            zero = [j + 1 for j in range(rows.shape[1]) if not rows[:, j].any()]
            if zero:
                warnings.warn(
                    f"{self.name}: tension_{', tension_'.join(map(str, zero))} "
                    f"{'is' if len(zero) == 1 else 'are'} 0 in every row: a sensor not "
                    "connected, or a tendon slack all along? (the estimate takes them as given)",
                    TensionsWarning,
                    stacklevel=2,
                )
        if n >= 3:
            # runs of rows that repeat the row before exactly, every tendon slack (all 0)
            # left out: a robot at rest with its tendons released reads so
            same = np.all(rows[1:] == rows[:-1], axis=1) & rows[1:].any(axis=1)
            starts = np.flatnonzero(np.diff(np.concatenate([[0], same.astype(int)])) == 1)
            ends = np.flatnonzero(np.diff(np.concatenate([same.astype(int), [0]])) == -1)
            if len(starts) and not same.all():
                held = t[ends + 1] - t[starts]  # row starts .. row ends + 1
                r = int(np.argmax(held))
                if held[r] > TENSIONS_FROZEN_S:
                    warnings.warn(
                        f"{self.name}: the tensions repeat exactly from t = "
                        f"{time_text(float(t[starts[r]]))} to "
                        f"{time_text(float(t[ends[r] + 1]))} s ({held[r]:.3g} s): a "
                        "logger that froze, or tensions held exactly? (the estimate takes "
                        "them as given)",
                        TensionsWarning,
                        stacklevel=2,
                    )
            steps = np.diff(t)
            usual = float(np.median(steps))
            i = int(np.argmax(steps))
            holes = int(np.sum(steps > max(TENSIONS_HOLE_FACTOR * usual, TENSIONS_HOLE_S)))
            if holes:
                more = f"; {holes - 1} shorter hole(s) too" if holes > 1 else ""
                warnings.warn(
                    f"{self.name}: no tensions between t = {time_text(float(t[i]))} and "
                    f"{time_text(float(t[i + 1]))} s ({steps[i]:.3g} s; the rows are "
                    f"{usual:.3g} s apart elsewhere{more}): interpolated linearly across; "
                    "where the tensions do not change linearly there, the estimate may "
                    "stay off for seconds after the hole, beyond its standard deviations",
                    TensionsWarning,
                    stacklevel=2,
                )

    def warn_sparse(self, sample_step: float, source: str) -> None:
        """A :class:`TensionsWarning` where the file's rows are more than
        :data:`TENSIONS_SPARSE_FACTOR` times as far apart as the samples of ``source``
        (``sample_step`` s, on average) and over 0.1 s, and the tensions are not linear
        in time (a held or ramped load given by a few rows is): between rows the
        tensions are taken as linear and their second derivatives as 0, which a
        tension that changes faster is not."""
        if len(self.t) < 2 or not sample_step > 0:
            return
        if not np.any(np.abs(self.accelerations) > 1e-9 * max(1.0, float(self.values.max()))):
            return
        step = float(np.median(np.diff(self.t)))
        if step > max(TENSIONS_SPARSE_FACTOR * sample_step, 0.1):
            warnings.warn(
                f"{self.name}: its rows are {step:.3g} s apart, the samples of {source} "
                f"{sample_step:.3g} s: between rows the tensions are taken as linear (no "
                "second derivative); if they change faster, log them faster",
                TensionsWarning,
                stacklevel=2,
            )

    def check_steps(self) -> None:
        """An :class:`InputError` where the file's rows are over
        :data:`~continuum_mhe.io.csv_files.MS_LIKE_STEP_S` apart (median): what
        :meth:`check_span` would take for milliseconds, for a reader that has no
        recording to check the span against before it runs (``live``)."""
        if len(self.t) < 3:
            return
        step = float(np.median(np.diff(self.t)))
        if step > MS_LIKE_STEP_S:
            unit = (
                "if t_ms is in microseconds, give milliseconds"
                if self.time_column == "t_ms"
                else "if t is in milliseconds, name the column t_ms (it is read in seconds; "
                "microseconds: divide them by 1000 first)"
            )
            raise InputError(
                f"{self.name}: its {self.time_column} steps by a median of {step:g} s: "
                f"{unit}; live cannot "
                "check the tensions' times against a recording before it runs, so rows "
                f"more than {MS_LIKE_STEP_S:g} s apart are refused here: add rows between "
                "them (estimate takes the file as it is)"
            )

    def covers(self, t: float) -> bool:
        """Whether ``t`` s lies within the file's times, to :data:`COVER_TOLERANCE_S`
        (a time computed in floating point, ``1.4999999999999998`` for ``1.5``, or written
        to the microsecond; :meth:`at` takes the end row's tensions there)."""
        return bool(self.t[0] - COVER_TOLERANCE_S <= t <= self.t[-1] + COVER_TOLERANCE_S)

    def check_covers(self, t: FloatArray, source: str) -> None:
        """An :class:`InputError` (:meth:`coverage_problem`) for the first of the times
        ``t`` (s, increasing) the file does not cover (:meth:`covers`), naming
        ``source``, the recording or estimate they are of."""
        times = np.asarray(t, dtype=float)
        outside = np.flatnonzero(
            (times < self.t[0] - COVER_TOLERANCE_S) | (times > self.t[-1] + COVER_TOLERANCE_S)
        )
        if len(outside):
            raise InputError(self.coverage_problem(float(times[outside[0]]), source))

    def coverage_problem(self, t: float, source: str = "", stream: bool = False) -> str:
        """The line that says that a sample at ``t`` s lies outside the file's times
        (``source``: the recording or stream it is of; ``stream``: a ``live`` stream,
        whose ``t`` is the device clock), naming the file's first row's line for a ``t``
        before it, else its last's, where the rows have lines; ``""`` where the file
        covers ``t`` (:meth:`covers`)."""
        if self.covers(t):
            return ""
        of = f" of {source}" if source else ""
        epoch = ""
        if self.t[0] >= EPOCH_LIKE_S > abs(t):  # a clock's absolute time, s
            epoch = (
                " (times since 1970, a clock's own? the recording's t counts from its "
                "start: a robot log's t = 0 is its first sample's stamp, the estimate's "
                "# t0_ns line)"
            )
        end = 0 if t < self.t[0] else len(self.t) - 1  # the row the sample lies beyond
        line = "" if self.lines is None else f" line {self.lines[end]}:"
        clock, what = (" (the device clock)", "stream") if stream else ("", "recording")
        return (
            f"{self.name}:{line} the tensions cover t = {time_text(self.t[0])} to "
            f"{time_text(self.t[-1])} s{epoch}, but a sample{of} is at t = "
            f"{time_text(t)} s{clock}: the tensions must cover the {what}"
        )

    def at(self, t: float, source: str = "") -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(tensions, rates, accelerations)`` at ``t`` s, linear between rows; an
        :class:`InputError` outside the file's times (:meth:`coverage_problem`;
        ``source``: the recording, named in it)."""
        problem = self.coverage_problem(t, source)
        if problem:
            raise InputError(problem)
        return tuple(  # type: ignore[return-value]
            np.array([np.interp(t, self.t, v) for v in a.T])
            for a in (self.values, self.rates, self.accelerations)
        )


def on_log_clock(tensions: Tensions, t0_ns: int) -> tuple[Tensions, str]:
    """``tensions`` whose times are since 1970, as a robot log's stamps are, counted
    from the log's ``t = 0`` (``t0_ns``, ns since 1970: the first sample's stamp), with the
    note that says so; as given, and ``""``, where either is not on that clock."""
    if t0_ns < EPOCH_LIKE_S * 1e9 or not len(tensions.t) or tensions.t[0] < EPOCH_LIKE_S:
        return tensions, ""
    seconds, ns = divmod(int(t0_ns), 10**9)
    shifted = replace(tensions, t=(tensions.t - seconds) - ns * 1e-9)
    return shifted, (
        f"{tensions.name}: its times, since 1970, are taken on the log's clock: t = 0 "
        f"at the first sample's stamp, {seconds}.{ns:09d} s"
    )


def read_drawn_tensions(
    path: str | os.PathLike[str], robot: Robot, t0_ns: int = 0
) -> tuple[Tensions, str]:
    """The tensions ``path`` of a tendon robot ``robot``'s estimate for drawing its
    backbone (``plot``, ``view``): read as ``estimate --inputs`` reads a tensions file,
    or a recording's tension columns as ``estimate`` reads them from it
    (:func:`read_tensions` with ``other_columns=None``); its times on a robot log's
    clock where they are since 1970 and the estimate's ``t = 0`` is ``t0_ns`` (ns since
    1970; 0: none, :func:`on_log_clock`); refused in one line in mN for N
    (:meth:`Tensions.check_scale`). Returns ``(tensions, note)``: the note says a
    move onto the log's clock (``""``: none)."""
    table = read_tensions(path, robot.n_tendons, other_columns=None, time_warning=False)
    table, note = on_log_clock(table, t0_ns)
    table.check_scale(robot)  # mN for N, as estimate refuses them
    return table, note


def _without_glitches(values: FloatArray, glitches: TensionGlitches) -> FloatArray:
    """``values`` (n, k) N with each glitch replaced by the cubic through its
    neighbours, not below zero."""
    return np.where(glitches.mask, np.maximum(glitches.curve, 0.0), values)


def _glitches_said(
    name: str,
    values: FloatArray,
    used: FloatArray,
    glitches: TensionGlitches,
    lines: tuple[int, ...] | None,
) -> str:
    """The warning of the glitches of the tensions ``name`` (:func:`tension_glitches`):
    their count, the first one's line (or row), tendon, value and the value ``used``."""
    rows = np.flatnonzero(glitches.mask.any(axis=1))
    i = int(rows[0])
    j = int(np.flatnonzero(glitches.mask[i])[0])
    where = f"line {lines[i]}" if lines is not None else f"row {i + 1}"
    count = glitches.count
    return (
        f"{name}: {count} tension{'s' if count > 1 else ''} in {len(rows)} "
        f"row{'s' if len(rows) > 1 else ''} {'leave' if count > 1 else 'leaves'} the curve "
        f"through the rows around alone, the first at {where} (tension_{j + 1} "
        f"{values[i, j]:.6g} N where its neighbours give {used[i, j]:.6g} N): "
        "taken as glitches of the sensor "
        "or the link, each replaced by that curve (as a spike of the tensions' rates it "
        "would move the estimate far, for the rest of the recording)"
    )


def tension_columns(n_tendons: int) -> tuple[str, ...]:
    """``tension_1, ..., tension_k``: the tensions' columns (and serial fields), in the
    robot file's ``[[tendon]]`` order."""
    return tuple(f"tension_{i}" for i in range(1, n_tendons + 1))


def _checked_rows(
    name: str, t: FloatArray, values: FloatArray, lines: tuple[int, ...] | None
) -> tuple[FloatArray, FloatArray]:
    """``t`` (n,) s and ``values`` (n, k) N of the tensions ``name`` as float arrays, or a
    :class:`UserError` naming the first problem and its row (its file's line where
    ``lines`` gives them: an :class:`InputError`) (:meth:`Tensions.from_rows`)."""
    try:
        t_arr = np.asarray(t, dtype=float)
        v_arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise UserError(
            f"{name}: t and the tensions must be arrays of numbers (t (n,) s, tensions (n, k) N)"
        ) from None
    if t_arr.ndim != 1 or v_arr.ndim != 2:
        raise UserError(
            f"{name}: t must be (n,) s and the tensions (n, k) N, a row per time and a column "
            f"per tendon; got shapes {t_arr.shape} and {v_arr.shape}"
        )
    if len(t_arr) != len(v_arr):
        raise UserError(
            f"{name}: t has {len(t_arr)} times and the tensions {len(v_arr)} rows: they must match"
        )
    if not len(t_arr):
        raise UserError(f"{name}: no tension rows")
    if not np.isfinite(t_arr).all() or np.any(np.diff(t_arr) <= 0):
        raise UserError(f"{name}: t must be finite and strictly increasing (s)")

    def where(i: int) -> str:
        return f"line {lines[i]}" if lines else f"row {i} (t = {time_text(float(t_arr[i]))} s)"

    error = InputError if lines else UserError
    bad = np.argwhere(~np.isfinite(v_arr))
    if len(bad):
        i, j = bad[0]
        raise error(
            f"{name}: {where(i)}: tension_{j + 1} is {v_arr[i, j]}: leave the row out (the "
            "tensions are interpolated across it)"
        )
    taken = take_slack_readings(v_arr)
    neg = np.argwhere(taken.too_negative)
    if len(neg):
        i, j = neg[0]
        raise error(
            f"{name}: {where(i)}: tension_{j + 1} = {v_arr[i, j]:g} N is negative: a tendon "
            "cannot push (a slack tendon's tension is 0; its load cell may read down to "
            f"-{taken.limit[i]:.3g} N there, taken as 0)"
        )
    if taken.count:
        first = int(np.flatnonzero(taken.slack.any(axis=1))[0])
        warnings.warn(taken.said(name, where(first)), TensionsWarning, stacklevel=3)
    return t_arr, taken.values


def holds_imu_readings(header: Sequence[str]) -> bool:
    """Whether a table's ``header`` (lower-case) names an IMU's readings, tilt (``roll``,
    ``pitch``) or raw (``ax`` ... ``gz``), of one IMU or numbered (``roll_1``): a
    recording's columns, which a tensions file has none of."""
    return any(
        h in imu.names or imu.number(h)[0]
        for h in header
        for imu in (TILT_IMU_COLUMNS, RAW_IMU_COLUMNS)
    )


def _unnamed_hint(unnamed: Sequence[str], more: bool) -> str:
    """What a tensions header's columns without a name (``unnamed``, numbered from 1)
    may be, where it has ``more`` columns than a tensions file: the first alone, an
    index as pandas writes one; else a separator too many."""
    if not more:
        return ""
    if list(unnamed) == ["1"]:
        return " (an index, as pandas writes one? remove it: to_csv(..., index=False))"
    return " (a separator too many?)"


def read_tensions(
    path: str | os.PathLike[str],
    n_tendons: int,
    other_columns: bool | None = False,
    skip_bad: bool = False,
    time_warning: bool = True,
) -> Tensions:
    """Read and check a tensions file for a robot with ``n_tendons`` tendons
    (``other_columns``: a recording that carries its tensions beside its IMUs' columns,
    which are left out here, and whose rows are differenced one by one, as ``live``
    differenced them when it recorded them: a replay gives ``live``'s estimates; a
    tensions file of its own is differenced by :func:`tension_derivatives`; None: as
    the header says, a recording's where it has all the robot's tension columns and an
    IMU's readings (:func:`holds_imu_readings`), else a tensions file's, its header
    checked as ``estimate --inputs`` checks it: a column of another name is refused).
    ``skip_bad``: a row with a missing or non-finite tension,
    or a bad time, is left out (the tensions are interpolated across it; a
    :class:`~continuum_mhe.io.csv_files.DropoutWarning` counts them) instead of an
    error. ``time_warning``: a ``t`` that steps like milliseconds is said (a
    :class:`~continuum_mhe.io.csv_files.UnitWarning`); a caller that checks it against
    the recording (:meth:`Tensions.check_span`) leaves it off."""
    names = list(tension_columns(n_tendons))
    with open_rows(path, f"t,{','.join(names)} (or t_ms,...)") as rows:
        name = rows.name
        header = list(rows.header)
        while header and header[-1] == "":  # a separator at the end of the line: no column
            header.pop()
        written = rows.written[: len(header)]
        found = [c for c in header if c != "t"]
        recording = other_columns or (
            other_columns is None and set(names) <= set(found) and holds_imu_readings(header)
        )
        if recording:  # its other columns left out, as its IMU reader leaves out one
            found = [c for c in found if c.startswith("tension_")]  # without a name
        if "t" not in header or sorted(found) != sorted(names):  # in any order, by name
            missing = [c for c in ["t", *names] if c not in header]
            spelled = dict(zip(header, written))  # the file's own spelling of a name
            extra = [spelled.get(c, c) for c in found if c and c not in names]
            # a,,b: a tensions file's column without a name (a recording's is left out)
            unnamed = [] if recording else [str(i + 1) for i, c in enumerate(header) if not c]
            said = "; ".join(  # a column twice is refused by open_rows
                part
                for part in (
                    f"{', '.join(missing)} missing" if missing else "",
                    f"{', '.join(extra)} not the robot's" if extra else "",
                    f"column{'s' if len(unnamed) > 1 else ''} {', '.join(unnamed)} "
                    f"{'have' if len(unnamed) > 1 else 'has'} no name"
                    f"{_unnamed_hint(unnamed, len(header) > len(names) + 1)}"
                    if unnamed
                    else "",
                )
                if part
            )
            raise InputError(
                f"{name}: line 1: {said}: expected the columns "
                f"t,{','.join(names)} (one per [[tendon]] of the robot file, numbered in its "
                f"order), got {','.join(written)}"
            )
        problems = RowProblems()
        hint = (
            "estimate --skip-bad (skip_bad=True in Python) leaves the row out and "
            "interpolates across it; live, plot and view need the row fixed or removed"
        )
        data = read_samples(
            rows, ["t", *names], skip_bad=skip_bad, problems=problems, skip_hint=hint
        )
        kept = [d for d in data if all(math.isfinite(v) for v in d[2])]
        left_out = len(data) - len(kept) + problems.dropped  # a bad value, or a bad t
        if left_out:
            first = problems.first[0].split(" (")[0]  # the line and the problem
            warnings.warn(
                f"{name}: {left_out} tension row(s) with a bad value or time left out "
                f"(--skip-bad; first: {first}): the tensions are interpolated "
                "across them",
                DropoutWarning,
                stacklevel=2,
            )
        data = kept
        if not data:
            raise InputError(f"{name}: no tension rows")
        t = np.array([d[1] for d in data], dtype=float)
        if time_warning:
            check_time_units(rows, t)
    values = np.array([d[2] for d in data], dtype=float).reshape(len(t), n_tendons)
    # (a negative tension is refused on its line by from_rows)
    # a recording's own columns row by row, as live's TensionStream differenced them
    lines = tuple(int(d[0]) for d in data)
    read = Tensions.from_rows(
        name,
        t,
        values,
        binned=not recording,
        lines=lines,
        glitches="stream" if recording else "rows",
    )
    return replace(read, time_column="t_ms" if rows.time_scale == 1e-3 else "t")


def tension_columns_in(path: str | os.PathLike[str]) -> list[str]:
    """The columns ``tension_...`` of the table ``path`` (a file), in its order."""
    with open_rows(path) as rows:
        return [c for c in rows.header if c.startswith("tension_")]


@dataclass(frozen=True)
class TensionsAt:
    """One sample's tensions (N), their rates (N/s) and second derivatives (N/s^2)."""

    t: float
    values: FloatArray
    rates: FloatArray
    accelerations: FloatArray


class TensionStream:
    """Tensions that come one sample at a time, with the derivatives a recording's own
    tension columns of the same rows give (:func:`central_differences`, of the values
    and then of the rates; not smoothed): a sample's are known once the two samples
    after it are in (four where a sample near it is a candidate glitch, until it is
    judged: :class:`~.tension_glitches.StreamGlitches`, whose glitches are replaced,
    counted in :attr:`glitches` and said once), or at the :meth:`end` of the stream
    (one-sided there, as at a file's last row). Samples that scatter so that a tensions
    file of them would be smoothed are said once (:meth:`_check_noise`)."""

    def __init__(self, name: str = "the tension stream", n_tendons: int | None = None) -> None:
        if n_tendons is not None and not (is_integer(n_tendons) and n_tendons >= 1):
            raise UserError(
                f"TensionStream n_tendons must be a positive integer (the robot's tendons) or "
                f"None, got {n_tendons!r}"
            )
        #: what the stream is called in messages
        self.name = name
        #: the tensions a sample holds (the robot's tendons; else the first sample's count)
        self.n_tendons = None if n_tendons is None else int(n_tendons)
        #: the last samples (those before the oldest one not yet given out that its
        #: derivatives and the glitch test take, that one, and the ones after it), with
        #: their glitches replaced
        self._kept = StreamGlitches(NOISE_CHECK_ROWS)
        self._done = 0  # samples given out so far
        self._said_glitch = False
        self._glitches_before = 0  # replaced before the last end()
        # whether the last samples' scatter (:meth:`_check_noise`, on the samples as
        # given that the glitch test keeps) has been said
        self._noise_said = False
        # whether a slack tendon's reading below zero, and a tension further below it
        # (taken as missing), have been said
        self._slack_said = False
        self._negative_said = False

    def push(self, t: float, values: FloatArray) -> list[TensionsAt]:
        """Add a sample (``t`` s, increasing; ``values`` N, one per tendon, NaN where a
        tension is missing); the samples whose derivatives are now known, oldest first
        (none for the first two). A sample of another count of tensions than the
        robot's (:attr:`n_tendons`, else the first sample's) raises
        :class:`~continuum_mhe.errors.UserError`, and is not added. A negative tension
        is taken as 0 where it is a slack tendon's reading (the tensions file's rule,
        :mod:`.slack_readings`), and further below zero as missing (NaN: its sample and
        the two on each side dropouts, whose rates would take it), each said once. A
        sample whose time is not later than the last one's raises
        :class:`~continuum_mhe.errors.SampleTimeError` and is not added (its differences
        would be of a step back in time)."""
        if not is_real(t):
            raise UserError(f"{self.name}: a sample's time must be a number of seconds, got {t!r}")
        if not math.isfinite(t):
            raise SampleTimeError(f"{self.name}: a sample's time is {t}: left out (seconds)")
        if self._kept.t and t <= self._kept.t[-1]:
            raise SampleTimeError(
                f"{self.name}: a sample at t = {time_text(t)} s is not later than the last "
                f"one ({time_text(self._kept.t[-1])} s): left out (the tensions' times must "
                "increase)"
            )
        try:
            raw = np.asarray(values)
            if raw.dtype.kind not in "iuf" or holds_bools(values):  # text, bools: not newtons
                raise TypeError
            v = raw.astype(float)
        except (TypeError, ValueError):
            raise UserError(
                f"{self.name}: a sample at t = {time_text(t)} s has tensions that are not numbers: "
                f"{values!r:.60}"
            ) from None
        if np.isinf(v).any():
            j = int(np.flatnonzero(np.isinf(v))[0])
            raise UserError(
                f"{self.name}: a sample at t = {time_text(t)} s has tension_{j + 1} = {v[j]:g}: "
                "give NaN for a tension that is missing"
            )
        if self.n_tendons is None and v.ndim == 1:
            self.n_tendons = v.size
        if v.shape != (self.n_tendons,):
            raise UserError(
                f"{self.name}: a sample at t = {time_text(t)} s has tensions of shape {v.shape}; "
                f"the robot has {self.n_tendons} tendons: one tension each (N)"
            )
        slack = take_slack_readings(v[None, :])
        if slack.too_negative.any():  # its rates and its neighbours' would take it
            j = int(np.flatnonzero(slack.too_negative[0])[0])
            if not self._negative_said:
                self._negative_said = True
                warnings.warn(
                    f"{self.name}: tension_{j + 1} = {v[j]:g} N at t = {time_text(t)} s is below 0 "
                    "beyond a slack tendon's reading (its load cell may read down to "
                    f"-{slack.limit[0]:.3g} N there; a tendon cannot push): taken as "
                    "missing, its sample and the two on each side dropouts (said once)",
                    TensionsWarning,
                    2,
                )
            v = np.where(slack.too_negative[0], np.nan, v)
        if slack.count:
            v = np.where(slack.slack[0], 0.0, v)
            if not self._slack_said:
                self._slack_said = True
                warnings.warn(
                    slack.said(self.name, f"t = {time_text(t)} s", once=True), TensionsWarning, 2
                )
        replaced = len(self._kept.replaced)
        self._kept.push(t, v)
        if not self._noise_said and self._kept.seen % NOISE_CHECK_ROWS == 0:
            self._check_noise()
        if len(self._kept.replaced) > replaced and not self._said_glitch:
            self._said_glitch = True
            i, j, given, used = self._kept.replaced[replaced]
            warnings.warn(
                f"{self.name}: the tensions of the sample at t = "
                f"{time_text(self._kept.t[i - self._kept.first])} s leave the curve "
                f"through the samples around alone (tension_{j + 1} {given:.6g} N where "
                f"its neighbours give {used:.6g} N): taken as a glitch of the sensor or the "
                "link and replaced, as every such sample is (and counted)",
                TensionsWarning,
                stacklevel=2,
            )
        return self._ready(end=False)

    @property
    def glitches(self) -> int:
        """The tensions replaced as glitches so far (:class:`StreamGlitches`)."""
        return self._glitches_before + len(self._kept.replaced)

    def _check_noise(self) -> None:
        """A :class:`TensionsWarning`, once, where the last :data:`NOISE_CHECK_ROWS`
        samples scatter so that a tensions file of them would be smoothed
        (:func:`smoothing_rows`): the stream differences its samples as they come, and
        their noise then reaches the estimate."""
        t = np.array(self._kept.given_t)
        said = slower_log_said(
            f"{self.name}: the tensions",
            t,
            np.array(self._kept.given),
            "live takes their rates and second derivatives from consecutive samples",
            "send the tensions measured at each IMU sample",
        )
        if said:
            self._noise_said = True
            warnings.warn(said, TensionsWarning, stacklevel=3)
            return
        noise = tension_noise_std(np.array(self._kept.given), t)
        step = float(np.median(np.diff(t)))
        if smoothing_rows(noise, step) == 0:
            return
        self._noise_said = True
        rate, acc = central_difference_gains(step)
        warnings.warn(
            f"{self.name}: the tensions scatter by about {noise:.2g} N from sample to sample "
            f"(a load cell's noise?), and live takes their rates and second derivatives from "
            f"consecutive samples, with a noise of about {noise * rate:.2g} "
            f"N/s and {noise * acc:.2g} N/s^2 (the estimators "
            f"take {TENSION_RATE_NOISE:g} and {TENSION_ACCELERATION_NOISE:g} without losing "
            "accuracy): filter the tensions at their source",
            TensionsWarning,
            stacklevel=3,
        )

    def end(self) -> list[TensionsAt]:
        """The stream ended: the samples still waiting, with one-sided derivatives at
        the end; the stream starts afresh after."""
        out = self._ready(end=True)
        self._glitches_before += len(self._kept.replaced)
        self._kept.clear()
        self._done = 0
        return out

    @property
    def waiting(self) -> int:
        """Samples pushed whose derivatives are not known yet."""
        return self._kept.seen - self._done

    def _ready(self, end: bool) -> list[TensionsAt]:
        out = []
        kept = self._kept
        while self._done < kept.seen and (
            end or (kept.seen - self._done > 2 and not kept.waiting(self._done - 2, self._done + 2))
        ):
            # the window: up to two samples each side of sample `done` (its derivatives'
            # neighbours), cut where the stream starts or ends
            first = kept.first  # the index of the window's first sample
            lo, hi = max(self._done - 2, first), min(self._done + 3, kept.seen)
            t = np.array(list(kept.t)[lo - first : hi - first])
            v = np.array(list(kept.values)[lo - first : hi - first])
            rates = central_differences(t, v)
            acc = central_differences(t, rates)
            i = self._done - lo
            out.append(TensionsAt(float(t[i]), v[i], rates[i], acc[i]))
            self._done += 1
        return out


#: The smallest ``--gyro-std`` (rad/s) whose ``ok`` rows the shipped tendon recordings
#: (raw IMUs, EKF) find inside their intervals: 0.005 keeps every recording's tip
#: coverage over the ``ok`` rows at 0.90 or more; 0.003 takes twist-29's to 0.79.
TENDON_GYRO_STD_CALIBRATED = 0.005


def tendon_formulation_for(base: Formulation, options: InputOptions) -> TendonFormulation:
    """The tendon formulation of ``base``'s robot, with ``base``'s IMU model (tilt, or
    raw with ``direct``) and noise. Its IMU-error states are the formulation's defaults
    (``--estimate-accel-bias`` asks for one of them); its tension gains with
    ``--estimate-tension-gain``. The constant-curvature options that would change
    ``base``'s model (``--formulation paper``, ``--own-acceleration``, ``--imu-twist``)
    are refused in one line: the tendon model does not take them."""
    if base.name == "paper":
        raise InputError(
            "--formulation paper is not available for a tendon robot (a [backbone] robot "
            "file): it is a constant-curvature robot's model; a tendon robot's is its "
            "mechanics model (leave --formulation out)"
        )
    if options.own_acceleration:
        raise InputError(
            "--own-acceleration is not available for a tendon robot (a [backbone] robot "
            "file): its model includes each IMU's own acceleration already"
        )
    if options.imu_twist:
        raise InputError(
            "--imu-twist is not available for a tendon robot (a [backbone] robot file): "
            "its mechanics model twists the backbone already"
        )
    direct = base.name == "direct"
    if options.estimate_tension_gain and not direct:
        warnings.warn(
            "--estimate-tension-gain with tilt IMUs: the gains trade with the IMUs' "
            "misalignment and bias states and mislead (on the "
            "shipped twist-29 with its own tensions they end at 0.27 and 0.46, 124 ok "
            "rows over 20 mm off; docs/tendon-studies.md): raw IMUs (accelerometer and "
            "gyro) take them",
            OptionWarning,
            stacklevel=2,
        )
    if direct and options.estimate_gyro_bias is False:
        warnings.warn(
            "--no-estimate-gyro-bias on a tendon robot: its model takes the gyros' biases "
            "as bends and loads (on the shipped force-29, 390 of 401 rows drifted, the "
            "tip 110 mm off, against 0.73 mm with the biases estimated): leave it out "
            "unless the gyros' biases were removed",
            OptionWarning,
            stacklevel=2,
        )
    if direct and options.gyro_std is not None and options.gyro_std < TENDON_GYRO_STD_CALIBRATED:
        warnings.warn(
            f"--gyro-std {options.gyro_std:g} rad/s on a tendon robot: below "
            f"{TENDON_GYRO_STD_CALIBRATED:g} the standard deviations narrow faster than "
            "the errors, and rows are ok outside their 95 % intervals (on the shipped "
            "twist-29, 0.003: tip coverage x 0.79 over the ok rows; 0.001: 72 of 351 ok "
            "rows more than 4 standard deviations off; docs/tendon-studies.md): leave "
            f"the default ({DEFAULT_GYRO_STD:g}; {SINGLE_IMU_GYRO_STD:g} for a robot with "
            "one IMU) unless the estimate is checked against a known shape",
            OptionWarning,
            stacklevel=2,
        )
    return TendonFormulation(
        robot=base.robot,
        noise=base.noise,
        imu_model="direct" if direct else "tilt",
        gyro_std=options.gyro_std,  # None: resolved from the robot's IMUs (one IMU: less)
        estimate_gyro_bias=direct and options.estimate_gyro_bias is not False,
        estimate_accel_bias=options.estimate_accel_bias or TendonFormulation.estimate_accel_bias,
        estimate_tension_gain=options.estimate_tension_gain,
    )
