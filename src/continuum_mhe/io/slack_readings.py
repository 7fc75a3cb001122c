"""Slightly negative tensions: a slack tendon read through its load cell's noise or offset.

A tendon cannot push, so a negative tension is no tension. But a load cell on a slack
tendon reads zero with its noise and offset, a little below it as often as above: such
a reading is taken as 0 (slack) and said once (a file's warning counts them), wherever
tensions come in (a tensions file, a recording's own columns, ``live``'s serial line,
an estimator's ``step`` and ``run``). A tension below zero by more than
:func:`slack_reading_limit` (a sign, an offset or a wiring that is wrong) is refused in
one line naming it; a :class:`~continuum_mhe.io.tensions.TensionStream` takes it as
missing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray

#: The least a tension may read below zero, N, and still be a slack tendon's reading.
SLACK_READING_FLOOR_N = 0.01
#: A slack tendon's reading may lie below zero by this share of the largest tension of
#: its row (the load cells' noise grows with their range), where that is more than
#: :data:`SLACK_READING_FLOOR_N`.
SLACK_READING_SHARE = 0.02


def slack_reading_limit(values: FloatArray) -> FloatArray:
    """How far below zero, N, each row of the tensions ``values`` (..., k) N may read and
    still be a slack tendon's reading (shape ``values.shape[:-1]``): the larger of
    :data:`SLACK_READING_FLOOR_N` and :data:`SLACK_READING_SHARE` times the row's largest
    finite tension."""
    v = np.asarray(values, dtype=float)
    largest = np.max(np.where(np.isfinite(v), v, 0.0), axis=-1, initial=0.0)
    return np.maximum(SLACK_READING_FLOOR_N, SLACK_READING_SHARE * largest)


@dataclass(frozen=True)
class SlackReadings:
    """The tensions of a table as taken: slack tendons' readings below zero set to 0.

    Attributes:
        given: (n, k) N, the tensions as given.
        values: (n, k) N, the tensions with each slack reading set to 0 (``given``
            where it has none).
        slack: (n, k) True where a reading below zero was taken as 0.
        too_negative: (n, k) True where a tension lies further below zero than
            :func:`slack_reading_limit` (the caller refuses it).
        limit: (n,) N, that limit for each row.
    """

    given: FloatArray
    values: FloatArray
    slack: NDArray[np.bool_]
    too_negative: NDArray[np.bool_]
    limit: FloatArray

    @property
    def count(self) -> int:
        """The readings taken as 0."""
        return int(self.slack.sum())

    @property
    def lowest(self) -> float:
        """The lowest reading taken as 0, N (0 where none)."""
        return float(np.min(np.where(self.slack, self.given, 0.0)))

    def said(self, source: str, where: str, once: bool = False) -> str:
        """The warning that :attr:`count` readings of ``source`` were taken as 0, the
        first at ``where`` (a line or a time); ``once``: the first sample's of a stream,
        said for all that follow (none counted)."""
        many = self.count != 1
        counted = (
            f"tensions below 0 (the first {self.lowest:.3g} N at {where}; said once)"
            if once
            else f"{self.count} tension{'s' if many else ''} below 0 (down to "
            f"{self.lowest:.3g} N, the first at {where})"
        )
        return (
            f"{source}: {counted}: a slack tendon read through its "
            f"load cell's noise or offset, taken as 0 N (a tendon cannot push; below "
            f"-{SLACK_READING_FLOOR_N:g} N, or {SLACK_READING_SHARE:.0%} of the row's "
            "largest tension, a tension is not a slack tendon's)"
        )


def take_slack_readings(values: FloatArray) -> SlackReadings:
    """The tensions ``values`` (n, k) N with each slack tendon's reading below zero (by
    at most :func:`slack_reading_limit`) set to 0, and those further below marked."""
    v = np.asarray(values, dtype=float)
    limit = slack_reading_limit(v)
    below = v < 0  # NaN compares False: a missing tension is its reader's to judge
    too = v < -limit[..., None]
    slack = below & ~too
    taken = np.where(slack, 0.0, v) if slack.any() else v
    return SlackReadings(v, taken, slack, too, limit)
