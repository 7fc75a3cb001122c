"""The tensions' rates and second derivatives as the estimators take them, from a
tensions file's rows or a recording's own tension columns: central differences,
averaged over bins where the file is logged fast, smoothed by a local cubic
(Savitzky-Golay) where its rows scatter, with the rows of a linear resampling left out
and a slower log held at every row taken between its changes
(:func:`tension_derivatives`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray, typical_step

#: The tensions' derivatives are taken on rows at least about this far apart (s; the
#: IMUs' 50 Hz): a faster file is averaged into bins of this length first
#: (:func:`tension_derivatives`).
DERIVATIVE_STEP_S = 0.02
#: Rows (or a slower log's samples) further apart than this many derivative steps take
#: second-order one-sided differences at the file's two ends, the chord to the next
#: row otherwise (:func:`tension_derivatives`).
SLOW_LOG_STEPS = 1.5
#: The noise of the tensions' rates (N/s) and second derivatives (N/s^2) the estimators
#: take without losing accuracy: the shipped ``unloaded`` (raw IMUs, EKF) with white
#: noise added to its tensions (docs/tendon-studies.md, "Noisy tensions").
TENSION_RATE_NOISE = 0.04
TENSION_ACCELERATION_NOISE = 0.2
#: The longest local cubic the tensions are smoothed over, s.
MAX_SMOOTHING_S = 1.5

#: An even grid of unevenly timed tension rows (:func:`_on_even_grid`) fills every gap
#: where it holds at most this many points a row; a longer grid (a row far from the
#: others) skips the gaps of more than :data:`MAX_GRID_GAP_STEPS` median steps.
MAX_GRID_ROWS_PER_ROW = 20
MAX_GRID_GAP_STEPS = 10
#: The order of the differences whose spread gives the tensions' noise
#: (:func:`tension_noise_std`): high enough that a smooth motion's part in them is far
#: below a load cell's noise.
NOISE_ORDER = 8
#: How far a row may lie off the line through its two neighbours, N, and count as on
#: it (:func:`line_knots`): a file written with six decimals rounds each tension by
#: half a micronewton.
ON_LINE_N = 2e-6
#: The share of the gaps between the corners of a linear resampling that are multiples
#: of its period (:func:`line_knots`; a hold spans several periods).
LINE_PATTERN_SHARE = 0.95
#: The fewest gaps of one period, and the longest period (s), of a linear resampling
#: (:func:`line_knots`): a controller's hold-ramp-hold has a few long straight stretches.
MIN_PERIODS = 5
MAX_RESAMPLED_PERIOD_S = 0.5
#: A row closer than this share of the median step to the row before it (a row written
#: twice, a logger's burst) is left out of the differences (:func:`apart_knots`).
NEAR_ROW_SHARE = 0.05


class TensionSmoothing(NamedTuple):
    """How a tensions file's rows were smoothed (:func:`tension_derivatives`).

    Attributes:
        noise_std: the rows' scatter, N (:func:`tension_noise_std`; of a fast file's
            rows, its bins' scatter times the square root of the rows in a bin).
        span_s: the local cubic's span, s.
        rate_noise, acceleration_noise: the noise the scatter leaves in the rates (N/s)
            and second derivatives (N/s^2).
    """

    noise_std: float
    span_s: float
    rate_noise: float
    acceleration_noise: float


class DifferencedTensions(NamedTuple):
    """A tensions file's rows as the estimators take them (:func:`tension_derivatives`):
    ``values`` (n, k) N (smoothed where ``smoothing`` is set; linear between the rows
    where a held value changes where ``hold_period_s`` is), ``rates`` (n, k) N/s,
    ``accelerations`` (n, k) N/s^2, ``smoothing`` (None: the rows as they are),
    ``hold_period_s`` (the period, s, of a slower log whose values the rows hold, a
    zero-order hold: :func:`hold_knots`; 0: none found)."""

    values: FloatArray
    rates: FloatArray
    accelerations: FloatArray
    smoothing: TensionSmoothing | None = None
    hold_period_s: float = 0.0


def tension_noise_std(values: FloatArray, t: FloatArray | None = None) -> float:
    """The tensions' row-to-row (white) noise, N: the largest over the columns of the
    robust spread (1.4826 times the median absolute deviation) of the rows'
    :data:`NOISE_ORDER`-th differences, over ``sqrt(C(2 k, k))`` (the k-th difference of
    white noise of standard deviation ``s`` has the standard deviation ``s sqrt(C(2 k,
    k))``). A smooth tension's k-th differences shrink as ``(2 pi f step)^k`` with its
    frequency ``f``: two newtons swinging at 3 Hz, sampled at 50 Hz, read as 7e-6 N,
    far under the noise a 50 Hz file is smoothed for (1.3e-4 N). Rows at uneven times
    ``t`` take divided differences instead, each scaled to the noise it carries
    (:func:`_unit_divided_differences`: a smooth tension at jittered times is not
    noise, and white noise reads as itself), and windows of ``k + 1`` equal rows (a
    slack tendon at exactly 0, a hold) are left out. 0 with too few rows."""
    k = NOISE_ORDER
    if len(values) < 2 * k + 1:
        return 0.0
    windows = np.lib.stride_tricks.sliding_window_view(values, k + 1, axis=0)
    varies = windows.max(axis=-1) > windows.min(axis=-1)  # (n - k, columns)
    if t is not None and not _evenly_apart(t, 1e-3):
        unit = _unit_divided_differences(np.asarray(t, dtype=float), values, k)
        scale = 1.0
    else:
        unit, scale = np.diff(values, n=k, axis=0), math.sqrt(math.comb(2 * k, k))
    spread = 0.0
    for j in range(values.shape[1]):
        dj = unit[varies[:, j], j]
        if len(dj) >= 2 * k + 1:
            mad = float(np.median(np.abs(dj - np.median(dj))))
            spread = max(spread, 1.4826 * mad)
    return spread / scale


def _unit_divided_differences(t: FloatArray, values: FloatArray, k: int) -> FloatArray:
    """The ``k``-th divided differences of ``values`` (n, columns) at the uneven times
    ``t`` (n,), each over the norm of its weights, so that white noise of standard
    deviation ``s`` gives them the standard deviation ``s`` whatever the spacing (on an
    even grid they are the rows' ``k``-th differences over ``sqrt(C(2 k, k))``); a
    smooth tension's part is its ``k``-th derivative over ``k!`` times as small a factor
    as on the grid. No resampling: a line or a cubic between the rows would read its own
    error as noise, and average the noise it moves."""
    times = np.lib.stride_tricks.sliding_window_view(t, k + 1)  # (n - k, k + 1)
    apart = times[:, :, None] - times[:, None, :]
    apart[:, np.arange(k + 1), np.arange(k + 1)] = 1.0
    weights = 1.0 / np.prod(apart, axis=2)  # (n - k, k + 1): the divided difference's
    weights /= np.linalg.norm(weights, axis=1, keepdims=True)
    rows = np.lib.stride_tricks.sliding_window_view(values, k + 1, axis=0)  # (n - k, c, k + 1)
    return np.einsum("wck,wk->wc", rows, weights)


def smoothing_rows(noise: float, step: float) -> int:
    """The rows of the local cubic that brings the tensions' rates and second
    derivatives within :data:`TENSION_RATE_NOISE` and :data:`TENSION_ACCELERATION_NOISE`
    for rows ``step`` s apart with noise ``noise`` N (the fit's weights' norm times the
    noise): 0 where the central differences already do
    (:func:`central_difference_gains`) or where five rows span more than
    :data:`MAX_SMOOTHING_S`, else the fewest odd rows from 5, at most that long."""
    if not (noise > 0.0 and step > 0.0):
        return 0
    rate, acc = central_difference_gains(step)
    if noise * rate <= TENSION_RATE_NOISE and noise * acc <= TENSION_ACCELERATION_NOISE:
        return 0
    most = 2 * int(MAX_SMOOTHING_S / step / 2) + 1
    if most < 5:  # rows too far apart for a local cubic within the longest span
        return 0
    for rows in range(5, most + 1, 2):
        rate, acc = _cubic_gains(rows, step)
        if noise * rate <= TENSION_RATE_NOISE and noise * acc <= TENSION_ACCELERATION_NOISE:
            return rows
    return most


def central_difference_gains(step: float) -> tuple[float, float]:
    """What white noise of 1 N on rows ``step`` s apart becomes in their central
    differences (N/s) and in those of the rates (N/s^2): ``sqrt(2) / (2 step)`` and
    ``sqrt(6) / (4 step^2)``."""
    return math.sqrt(2.0) / (2.0 * step), math.sqrt(6.0) / (4.0 * step * step)


def _cubic_gains(rows: int, step: float) -> tuple[float, float]:
    """The same for a local cubic over ``rows`` rows (its weights' norms)."""
    from scipy.signal import savgol_coeffs  # scipy only for a tendon robot

    return (
        float(np.linalg.norm(savgol_coeffs(rows, 3, deriv=1, delta=step))),
        float(np.linalg.norm(savgol_coeffs(rows, 3, deriv=2, delta=step))),
    )


def _evenly_apart(t: FloatArray, tol: float) -> bool:
    """Whether every step of ``t`` is within ``tol`` of their median (relative)."""
    steps = np.diff(t)
    step = float(np.median(steps))
    return bool(np.all(np.abs(steps - step) <= tol * step))


def _on_even_grid(t: FloatArray, values: FloatArray, tol: float) -> tuple[FloatArray, FloatArray]:
    """``(t, values)`` where the rows' steps are within ``tol`` of their median, else the
    rows interpolated onto an even grid at the median step from ``t[0]``. Where that grid
    would hold more than :data:`MAX_GRID_ROWS_PER_ROW` points a row (one row far from the
    others: a logger's clock that jumped), a gap of more than :data:`MAX_GRID_GAP_STEPS`
    median steps is not filled: the rows on each side get their own grid."""
    if _evenly_apart(t, tol):
        return t, values
    steps = np.diff(t)
    step = float(np.median(steps))
    if (t[-1] - t[0]) / step <= MAX_GRID_ROWS_PER_ROW * len(t):
        grid = np.arange(t[0], t[-1] + 0.5 * step, step)
        return grid, _at_rows(grid, t, values)
    starts = np.concatenate(([0], np.flatnonzero(steps > MAX_GRID_GAP_STEPS * step) + 1))
    ends = np.concatenate((starts[1:], [len(t)]))
    grid = np.concatenate(
        [np.arange(t[a], t[b - 1] + 0.5 * step, step) for a, b in zip(starts, ends)]
    )
    return grid, _at_rows(grid, t, values)


def _smoothed(t: FloatArray, values: FloatArray, noise: float) -> DifferencedTensions | None:
    """The local cubic's values, rates and second derivatives at the rows ``t``, or None
    where the rows' noise needs none (:func:`smoothing_rows`). Rows unevenly apart are
    fitted on an even grid at their median step and interpolated back."""
    if len(t) < 5:
        return None
    step = float(np.median(np.diff(t)))
    rows = smoothing_rows(noise, step)
    if rows == 0:
        return None
    grid, v = _on_even_grid(t, values, 1e-6)
    even = grid is t
    rows = min(rows, len(grid) if len(grid) % 2 else len(grid) - 1)
    if rows < 5:
        return None
    from scipy.signal import savgol_filter  # scipy only for a tendon robot

    fits = [
        savgol_filter(v, rows, 3, deriv=d, delta=step, axis=0, mode="interp") for d in (0, 1, 2)
    ]
    if not even:
        fits = [_at_rows(t, grid, f) for f in fits]
    gain1, gain2 = _cubic_gains(rows, step)
    smoothing = TensionSmoothing(noise, (rows - 1) * step, noise * gain1, noise * gain2)
    return DifferencedTensions(np.maximum(fits[0], 0.0), fits[1], fits[2], smoothing)


def _at_rows(t: FloatArray, tb: FloatArray, d: FloatArray) -> FloatArray:
    """``d`` (m, k) given at the times ``tb`` interpolated to the rows ``t``."""
    return np.column_stack([np.interp(t, tb, d[:, j]) for j in range(d.shape[1])])


def line_knots(t: FloatArray, values: FloatArray) -> NDArray[np.bool_]:
    """``(n,)`` bool: the rows a slower log resampled linearly onto these rows gave,
    where the rows follow that pattern, else every row.

    A row that is not on the line through its two neighbours in every column (within
    :data:`ON_LINE_N`) is a corner. The rows follow a resampling's pattern where the most
    common number of rows between corners (the period) is two or more, spans at most
    :data:`MAX_RESAMPLED_PERIOD_S`, is that of at least :data:`MIN_PERIODS` gaps and half
    of them, and :data:`LINE_PATTERN_SHARE` of the gaps are multiples of it. Then the
    knots are the corners and every period'th row between two corners a multiple of
    periods apart (a hold or a straight stretch of the slower log keeps its rows), the
    first and the last. The rows left out change nothing of the tensions interpolated
    linearly between rows, only their differences: a row's central difference across a
    corner is half the slope before and half after, and the second differences are
    spikes at the corners. A smooth tension sampled fast, or one held or ramped by a
    controller, has rows on the line that no slower log put there, in no such pattern."""
    keep = np.ones(len(t), dtype=bool)
    if len(t) < 3:
        return keep
    w = ((t[1:-1] - t[:-2]) / (t[2:] - t[:-2]))[:, None]
    on_line = np.abs(values[1:-1] - ((1.0 - w) * values[:-2] + w * values[2:])) <= ON_LINE_N
    corners = keep.copy()
    corners[1:-1] = ~np.all(on_line, axis=1)
    at = np.flatnonzero(corners)
    gaps = np.diff(at)
    period = int(np.bincount(gaps).argmax())
    step = float(np.median(np.diff(t)))
    if (
        period < 2
        or period * step > MAX_RESAMPLED_PERIOD_S
        or int(np.sum(gaps == period)) < MIN_PERIODS
        or np.mean(gaps == period) < 0.5
        or np.mean(gaps % period == 0) < LINE_PATTERN_SHARE
    ):
        return keep  # no resampling's pattern
    knots = corners.copy()
    for start, gap in zip(at[:-1], gaps, strict=True):
        if gap > period and gap % period == 0:
            knots[start + period : start + gap : period] = True
    return knots


def apart_knots(t: FloatArray, knots: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``knots`` (n,) bool, rows of ``t`` (n,) s, without each knot that follows the
    knot kept before it by less than :data:`NEAR_ROW_SHARE` of the knots' typical step
    (:func:`~continuum_mhe.arrays.typical_step`: every row written twice included).
    A central difference on uneven steps leans on the shorter step in proportion to the
    longer one's share: across a row written twice 1 us after the first, it is that
    microsecond's difference, zero or a load cell's noise over a microsecond. The rows
    left out keep their values; only their differences are taken from the rows
    around."""
    at = np.flatnonzero(knots)
    if len(at) < 3:
        return knots
    near = NEAR_ROW_SHARE * typical_step(t[at])
    chosen = [int(at[0])]
    for i in at[1:]:
        if t[i] - t[chosen[-1]] >= near:
            chosen.append(int(i))
        elif i == at[-1] and len(chosen) > 1:  # the file's last row stays: not the one before
            chosen[-1] = int(i)
    kept = np.zeros_like(knots)
    kept[chosen] = True
    return kept


def hold_knots(t: FloatArray, values: FloatArray) -> tuple[NDArray[np.bool_], float] | None:
    """``(knots (n,) bool, period s)`` where the rows ``values`` (n, k) at ``t`` (n,) s
    hold each value of a slower log for several rows (a zero-order hold: a logger that
    writes the last tension it received at every IMU sample), else None.

    A row that differs from the row before it in some column (by more than
    :data:`ON_LINE_N`) is a change, a new sample of the slower log. The rows hold such a
    log where the median number of rows between changes (its period, not always a whole
    number: a 9.5 Hz log on 50 Hz rows changes every 5 or 6 rows) is two or more and
    spans at most :data:`MAX_RESAMPLED_PERIOD_S`, at least :data:`MIN_PERIODS` and half
    of the gaps lie within a row of it, and :data:`LINE_PATTERN_SHARE` of them are no
    shorter than a row under it (a longer gap: the log held a value, as a controller's
    steady tension or a constant one). The knots are the changes, and where a gap is
    longer than a period and a row, or after the last change, a row every period and
    the last row (the log's samples of the held value). Differenced row by row, such
    rows give rates that are zero within a hold and a spike at each change, and second
    derivatives of twice that size; the knots give the slower log's own."""
    n = len(t)
    if n < 3:
        return None
    marks = np.ones(n, dtype=bool)
    marks[1:] = np.any(np.abs(np.diff(values, axis=0)) > ON_LINE_N, axis=1)
    at = np.flatnonzero(marks)
    gaps = np.diff(at)
    if len(gaps) < MIN_PERIODS:
        return None
    period = float(np.median(gaps))
    regular = np.abs(gaps - period) <= 1.0
    step = float(np.median(np.diff(t)))
    if (
        period < 2.0
        or period * step > MAX_RESAMPLED_PERIOD_S
        or int(regular.sum()) < MIN_PERIODS
        or np.mean(regular) < 0.5
        or np.mean(gaps >= period - 1.0) < LINE_PATTERN_SHARE
    ):
        return None
    knots = marks.copy()
    every = max(2, round(period))
    for start, stop in zip(at, [*at[1:], n], strict=True):  # the held stretches
        if stop - start > period + 1.0:
            knots[start + every : stop : every] = True
    knots[-1] = True
    return knots, float(np.mean(np.diff(t[at])[regular]))


def slower_log(t: FloatArray, values: FloatArray) -> tuple[str, float] | None:
    """``(how, period s)`` where the rows ``values`` (n, k) at ``t`` (n,) s carry a
    slower log's samples onto faster rows, ``how`` ``"hold"`` (each value repeated:
    :func:`hold_knots`) or ``"resample"`` (linear between them: :func:`line_knots`);
    else None."""
    held = hold_knots(t, values)
    if held is not None:
        return "hold", held[1]
    knots = line_knots(t, values)
    if knots.all():
        return None
    return "resample", float(np.median(np.diff(t[knots])))


def tension_derivatives(
    t: FloatArray, values: FloatArray, binned: bool = True, hold: bool = True
) -> DifferencedTensions:
    """The tensions ``values`` (n, k) at the rows' times ``t`` (n,) s as the estimators
    take them: the rows, their central differences, and those of the rates. With
    ``binned`` (a tensions file of its own; not a recording's own columns, which are
    differenced row by row as ``live`` differenced them):

    - the rows on the line through their neighbours (:func:`line_knots`: a slower log
      resampled by linear interpolation) are left out of the differences; where the
      rows hold each value of a slower log for several rows instead (:func:`hold_knots`:
      a zero-order hold), the rows where a value changes are that log's samples: the
      tensions are linear between them (``hold_period_s`` says it) and differenced
      there;
    - a file logged faster than :data:`DERIVATIVE_STEP_S` (two rows or more to a bin of
      about that length: a median step of at most two thirds of it) is first averaged
      over bins of that many rows and differenced there: a difference over a
      millisecond would turn a load cell's noise into accelerations hundreds of times
      the tensions' own;
    - where the rows left scatter so that the differences would be noisier than
      :data:`TENSION_RATE_NOISE` or :data:`TENSION_ACCELERATION_NOISE`
      (:func:`tension_noise_std`, :func:`smoothing_rows`), the tensions, rates and
      second derivatives are a local cubic's over the rows (Savitzky-Golay), described
      by ``smoothing``;

    and the derivatives (and smoothed values) are interpolated back to every row.
    ``hold`` False: a held log is not looked for (each held row taken as given; for
    comparison).
    """
    if not binned or len(t) < 3:
        rates = central_differences(t, values)
        return DifferencedTensions(values, rates, central_differences(t, rates))
    held = hold_knots(t, values) if hold else None
    knots = apart_knots(t, line_knots(t, values) if held is None else held[0])
    hold_s = 0.0 if held is None else held[1]
    tb, vb = t[knots], values[knots]
    if held is not None:  # the held rows take the line between the slower log's samples
        values = _at_rows(t, tb, vb)
    per_bin = round(DERIVATIVE_STEP_S / float(np.median(np.diff(tb)))) if len(tb) >= 3 else 1
    if per_bin >= 2:
        starts = np.arange(0, len(tb), per_bin)
        if len(starts) > 1 and len(tb) - starts[-1] < per_bin // 2 + 1:
            starts = starts[:-1]  # a short last bin joins the one before
        counts = np.diff(np.concatenate([starts, [len(tb)]]))
        tb = np.add.reduceat(tb, starts) / counts
        vb = np.add.reduceat(vb, starts, axis=0) / counts[:, None]
    noise = tension_noise_std(vb, tb)
    every_row = len(tb) == len(t)  # no row left out, none binned
    smooth = _smoothed(tb, vb, noise)
    if smooth is not None:
        assert smooth.smoothing is not None
        if per_bin >= 2:  # the noise of the file's rows, not of the bins' means
            smooth = smooth._replace(
                smoothing=smooth.smoothing._replace(noise_std=noise * math.sqrt(per_bin))
            )
        if every_row:
            return smooth
        return smooth._replace(
            values=_at_rows(t, tb, smooth.values),
            rates=_at_rows(t, tb, smooth.rates),
            accelerations=_at_rows(t, tb, smooth.accelerations),
            hold_period_s=hold_s,
        )
    # rows further apart than the derivative step (a slower log's samples): second order
    # at the ends, where a chord over the longer step errs by half that step times the
    # second derivative (at a start from rest, the first step's mean rate for none)
    slow = len(tb) >= 2 and float(np.median(np.diff(tb))) > SLOW_LOG_STEPS * DERIVATIVE_STEP_S
    edge = 2 if slow else 1
    rates = central_differences(tb, vb, edge)
    acc = central_differences(tb, rates, edge)
    if every_row:
        return DifferencedTensions(values, rates, acc)
    return DifferencedTensions(
        values, _at_rows(t, tb, rates), _at_rows(t, tb, acc), hold_period_s=hold_s
    )


def central_differences(t: FloatArray, values: FloatArray, edge_order: int = 1) -> FloatArray:
    """The derivative of ``values`` (n, k) over ``t`` (n,) s at every row: the
    second-order central difference on uneven steps inside, one-sided at the two ends
    (first order, the chord to the next row, or with ``edge_order`` 2 and three rows or
    more second order), zero with one row (numpy's ``gradient`` formulas). Written out
    because numpy's switches to another formula when the steps of the whole array are
    equal: the interior rows here depend on their neighbours alone, so a window of a
    stream gives bit for bit the values of the whole file (:class:`TensionStream`)."""
    out = np.zeros_like(values, dtype=float)
    if len(t) < 2:
        return out
    h = np.diff(t)[:, None]
    out[0] = (values[1] - values[0]) / h[0]
    out[-1] = (values[-1] - values[-2]) / h[-1]
    if edge_order == 2 and len(t) >= 3:
        a1, a2, b1, b2 = h[0], h[1], h[-2], h[-1]
        out[0] = (
            -(2 * a1 + a2) / (a1 * (a1 + a2)) * values[0]
            + (a1 + a2) / (a1 * a2) * values[1]
            - a1 / (a2 * (a1 + a2)) * values[2]
        )
        out[-1] = (
            b2 / (b1 * (b1 + b2)) * values[-3]
            - (b1 + b2) / (b1 * b2) * values[-2]
            + (2 * b2 + b1) / (b2 * (b1 + b2)) * values[-1]
        )
    h1, h2 = h[:-1], h[1:]
    a = -h2 / (h1 * (h1 + h2))
    b = (h2 - h1) / (h1 * h2)
    c = h1 / (h2 * (h1 + h2))
    out[1:-1] = a * values[:-2] + b * values[1:-1] + c * values[2:]
    return out
