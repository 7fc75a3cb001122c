"""Exception types shared by every layer (imports nothing from the package).

:class:`UserError` is a problem with what the user gave (a file, an option, a setting,
an argument of a library call): the command line prints its one-line message and exits
with status 2. Anything else that reaches the command line is a bug in continuum-mhe;
it says so and exits with status 70 (``EX_SOFTWARE``).
"""

from __future__ import annotations

import math
import numbers
import os
import sys
import warnings
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import TypeGuard


class UserError(ValueError):
    """A problem with user input or settings; the message is one line saying what is
    wrong and, where known, where (``FILE: line N: ...``) and the likely cause.

    A subclass of :class:`ValueError`, so library callers that catch ``ValueError``
    keep working."""


class FieldError(UserError):
    """A :class:`UserError` about one named field of a description or a setting (a robot
    section's ``length``): ``field`` names it, so that a reader of a file can say where
    the field is."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


class InputError(UserError):
    """A problem with an input file or option; the message is one line, naming file
    and line."""


class TimeUnitError(InputError):
    """An input refused because its times are in another unit than the one read (a
    ``t`` column in milliseconds, a ``t_ms`` one in microseconds): the line names the
    unit, which any warning of the times' steps would only repeat."""


class NotANumberError(InputError):
    """A field of an input file that is not a number; ``problem``: the message without
    the file and line that it begins with (``column C: 'x' is not a number``)."""

    def __init__(self, name: str, line: int, problem: str) -> None:
        super().__init__(f"{name}: line {line}: {problem}")
        self.problem = problem


class SampleTimeError(UserError):
    """A sample whose time is not later than the previous sample's: a sample that came
    late or twice (an online caller leaves it out and steps on: the estimator is as it
    was), or the first of a new recording without ``reset()``."""


class UnobservableShapeWarning(UserWarning):
    """The robot's IMUs cannot determine its shape (fewer independent tilt readings
    than bend coordinates): every estimate of it is ``uncertain``."""


def is_real(value: object) -> TypeGuard[float]:
    """Whether ``value`` is a real number (numpy's scalars too), not a bool, that a float
    holds (not an integer such as 10**400, beyond a float's range, which ``float()`` and
    ``math.isfinite`` refuse with an OverflowError): to the type checker a float, as
    every such number compares and converts as one."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        return False
    if isinstance(value, numbers.Integral):
        return abs(int(value)) <= _LARGEST_FLOAT_INT
    return True


#: The largest integer a float holds (larger ones overflow ``float()``).
_LARGEST_FLOAT_INT = int(sys.float_info.max)


def is_integer(value: object) -> TypeGuard[int]:
    """Whether ``value`` is an integer (numpy's integers too), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def real_number(name: str, value: object) -> float:
    """``value`` as a float, or a :class:`UserError` naming the argument ``name`` when it
    is not a real number (a string, None, a bool, a list)."""
    if not is_real(value):
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):  # 10**400
            raise UserError(f"{name} must be a number a float can hold, got {value!r:.40}")
        raise UserError(f"{name} must be a number, got {value!r}")
    return float(value)


def finite_reals(name: str, value: object, size: int, what: str) -> tuple[float, ...]:
    """``value`` (a sequence: tuple, list, array) as ``size`` finite floats, or a
    :class:`UserError` naming the argument ``name`` (``what`` says what is expected,
    e.g. ``"three finite rates in rad/s"``)."""
    values: list[float] = []
    if (
        isinstance(value, Iterable)
        and not isinstance(value, (str, bytes))
        and getattr(value, "ndim", 1) != 0  # a numpy scalar array is not a sequence
    ):
        for v in value:
            if not (is_real(v) and math.isfinite(v)):
                break
            values.append(float(v))
        else:
            if len(values) == size:
                return tuple(values)
    raise UserError(f"{name} must be {what}, got {value!r:.60}")


def time_text(t: float) -> str:
    """A time in a message: the shortest text that reads back as the same float
    (``4294965.716``, not ``%g``'s ``4.29497e+06``), so two different times never look
    equal; a whole number without ``.0``."""
    text = repr(float(t))
    return text[:-2] if text.endswith(".0") else text


def expect_type(name: str, value: object, kind: type | tuple[type, ...], what: str) -> None:
    """A :class:`UserError` naming the argument ``name`` unless ``value`` is a ``kind``
    (``what`` says what is expected, e.g. ``"a Formulation (make_formulation)"``)."""
    if not isinstance(value, kind):
        raise UserError(f"{name} must be {what}, got {type(value).__name__} {value!r:.60}")


def masked_as_missing(values: object) -> object:
    """``values`` with a numpy masked array's masked entries, and a pandas object's
    missing ones (``pd.NA`` too), as NaN (a reading that is missing, a dropout, as NaN
    says everywhere else), as floats; anything else as it is. (``numpy.asarray`` of a
    masked array drops its mask and keeps the values under it; of a nullable pandas
    column it gives objects.) A TypeError or ValueError where they are not numbers."""
    if hasattr(values, "mask") and hasattr(values, "filled") and hasattr(values, "astype"):
        return values.astype(float).filled(math.nan)
    if hasattr(values, "to_numpy"):  # a pandas Series or DataFrame
        return values.to_numpy(dtype=float, na_value=math.nan)
    return values


@contextmanager
def one_line_warnings(prog: str) -> Iterator[None]:
    """While the block runs, a warning prints as one line, ``prog: warning: message``
    (a command's own form, without Python's file, line number and source line)."""

    def one_line(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        line: str | None = None,
    ) -> str:
        return f"{prog}: warning: {message}\n"

    saved = warnings.formatwarning
    warnings.formatwarning = one_line
    try:
        yield
    finally:
        warnings.formatwarning = saved


def outside_stacklevel() -> int:
    """The ``warnings.warn`` stacklevel, for a warning raised in the function that calls
    this, of the first caller outside this package: a warning of the library names the
    user's line, not the library's."""
    package = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 1
    while frame.f_back is not None and frame.f_code.co_filename.startswith(package):
        frame, level = frame.f_back, level + 1
    return level
