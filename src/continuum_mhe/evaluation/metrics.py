"""Error metrics of estimates against truth (results as data).

Columns are named (see :mod:`continuum_mhe.model.descriptions`): the tip ``x, y, z``
(m), and per section ``theta_k`` (rad), ``phi_k`` (rad, wrapped) and its end
``x_k, y_k, z_k`` (m); one section uses ``theta, phi``. Metrics are computed over the
columns both sides have.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, real_number
from continuum_mhe.io.position_units import (
    LENGTH_RATIO_TOLERANCE,
    force_unit_against,
    mentions_bend_angles,
    position_unit_against,
    position_unit_problem,
    tip_ratio,
)
from continuum_mhe.model.descriptions import (
    TIP_COLUMNS,
    TIP_FORCE_COLUMNS,
    angle_beyond_a_turn,
    output_names,
    pcc_outputs,
    section_count,
    section_end_columns,
    sections_with_ends,
)
from continuum_mhe.model.imu import wrap_angle
from continuum_mhe.model.robot import MAX_SECTION_LENGTH
from continuum_mhe.quantiles import chi2_quantile

#: One section's outputs, the default column order of arrays without names.
STATE_NAMES = output_names(pcc_outputs(1))


def is_wrapped(name: str) -> bool:
    """``phi``, ``phi_k`` and a tendon robot's twist ``psi_k`` are angles wrapped to
    ``[-pi, pi)`` (the outputs :class:`~continuum_mhe.model.descriptions.OutputSpec`
    marks ``wrapped``)."""
    return name == "phi" or name.startswith(("phi_", "psi_"))


@dataclass(frozen=True)
class Metrics:
    """Errors over the samples that have an estimate.

    Attributes:
        rmse: RMSE per compared column (m, rad or N; phi wrapped).
        srmse: the sum of the RMSEs of the columns in m and rad (:func:`srmse_columns`:
            the last section's end, the tip again, counted once; the paper's SRMSE for
            one section, mixed units; a tendon robot's tip force and tension gains left
            out).
        tip_mean_mm, tip_max_mm: Euclidean tip error, mm.
        tip_mean_pct, tip_max_pct: the same in % of the robot's length.
        n: samples compared; n_without_estimate: samples with no estimate;
            n_without_truth: samples with an estimate but no (finite) truth.
        section_end_mean_mm, section_end_max_mm: Euclidean error of each section's end
            (1-based section number as a string key), where both sides have it.
        tip_force_rms_n: the rms of the tip force's error vector, N, where both sides
            have :data:`TIP_FORCE_COLUMNS` (a tendon robot); else None.
    """

    rmse: dict[str, float]
    srmse: float
    tip_mean_mm: float
    tip_max_mm: float
    tip_mean_pct: float
    tip_max_pct: float
    n: int
    n_without_estimate: int
    section_end_mean_mm: dict[str, float] = field(default_factory=dict)
    section_end_max_mm: dict[str, float] = field(default_factory=dict)
    tip_force_rms_n: float | None = None
    n_without_truth: int = 0

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def _column_names(what: str, names: object) -> list[str]:
    """``names`` as a list of column names, or a :class:`UserError`."""
    if isinstance(names, str) or not isinstance(names, Iterable):
        raise UserError(f"{what} must be a sequence of column names, got {names!r:.60}")
    out = list(names)
    if not all(isinstance(c, str) for c in out):
        raise UserError(f"{what} must be column names (strings), got {out!r:.60}")
    return out


def _table(what: str, values: object, names: list[str], name_arg: str) -> FloatArray:
    """``values`` as an (n, len(names)) float array, or a :class:`UserError` naming
    what does not fit (``name_arg``: the argument that names its columns)."""
    if hasattr(values, "output") and not isinstance(values, np.ndarray):
        raise UserError(
            f"{what} must be an array (n, k), not an {type(values).__name__}: pass its "
            ".output (and its outputs' names as names)"
        )
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"{what} must be an array of numbers (n, k), got {values!r:.60}") from None
    if a.ndim != 2:
        raise UserError(f"{what} must be a 2-D array (n, k), got shape {a.shape}")
    if a.shape[1] != len(names):
        raise UserError(
            f"{what} has {a.shape[1]} columns, but {name_arg} gives {len(names)} "
            f"({', '.join(names)})"
        )
    return a


def _times(what: str, values: object) -> FloatArray:
    """``values`` as a float array, or a :class:`UserError` naming ``what``."""
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"{what} must be an array of times (s), got {values!r:.60}") from None


def state_errors(
    estimate: FloatArray, truth: FloatArray, names: Sequence[str] = STATE_NAMES
) -> FloatArray:
    """Per-sample errors (n, k), estimate minus truth, of the columns ``names`` (each in
    its own unit: rad for ``theta``/``phi``, m for positions), ``phi`` columns wrapped to
    ``[-pi, pi)``."""
    err = np.asarray(estimate, float) - np.asarray(truth, float)
    for j, name in enumerate(names):
        if is_wrapped(name):
            err[:, j] = wrap_angle(err[:, j])
    return err


def in_m_or_rad(name: str) -> bool:
    """Whether the output column ``name`` is in m or rad: not a tendon robot's tip force
    (N) nor its tension gain ``tension_gain_k`` (1)."""
    return name not in TIP_FORCE_COLUMNS and not name.startswith("tension_gain")


def srmse_columns(names: Sequence[str]) -> list[str]:
    """The columns of ``names`` whose RMSEs the SRMSE sums: those in m and rad
    (:func:`in_m_or_rad`: not a tendon robot's tip force or tension gain), the last
    section's end (``x_n, y_n, z_n`` of ``n`` sections, the tip again) left out where
    the tip is there: each point counted once."""
    n = section_count(names)
    again = set(section_end_columns(n)) if n and set(TIP_COLUMNS) <= set(names) else set()
    return [c for c in names if in_m_or_rad(c) and c not in again]


def compute_metrics(
    estimate: FloatArray,
    truth: FloatArray,
    length: float,
    names: Sequence[str] = STATE_NAMES,
    truth_names: Sequence[str] | None = None,
) -> Metrics:
    """Metrics of ``estimate`` (n, k) with columns ``names`` against ``truth`` (n, k')
    with columns ``truth_names`` (default: the same), over a robot of ``length`` m.
    Columns in only one of them are ignored; both must have ``x, y, z``. Rows with a
    NaN estimate are skipped (``n_without_estimate``), and so are rows whose tip truth
    (``x, y, z``) is not finite (``n_without_truth``: a gap in a motion capture); a
    column whose truth has gaps of its own is compared over its finite rows, and one
    with none of them finite is left out.

    Raises:
        UserError: arrays that are not (n, k) numbers with a column per name, of
            different lengths, a ``length`` that is not a positive number, no common
            tip columns, or no row with both an estimate and its truth.
    """
    length = real_number("length", length)
    if not (math.isfinite(length) and length > 0):
        raise UserError(f"length must be a positive number of metres, got {length!r}")
    if length > MAX_SECTION_LENGTH:
        raise UserError(
            f"length {length:g} m is over {MAX_SECTION_LENGTH:g} m: the robot's length is in "
            "metres (millimetres or centimetres?)"
        )
    names = _column_names("names", names)
    tnames = names if truth_names is None else _column_names("truth_names", truth_names)
    est_all = _table("estimate", estimate, names, "names")
    tru_all = _table("truth", truth, tnames, "names" if truth_names is None else "truth_names")
    if len(est_all) != len(tru_all):
        raise UserError(f"estimate has {len(est_all)} rows but truth has {len(tru_all)}")
    common = [c for c in names if c in tnames]
    for c in TIP_COLUMNS:
        if c not in common:
            raise UserError(f"both sides need the tip column {c!r}")
    # positions in another unit than m (as evaluate refuses them): against the robot's
    # length, then the truth against the estimate
    # (the bend columns of several sections need their lengths, which ``length`` does not
    # give: there the tip's distance alone, as a file without angles is judged)
    for side, side_names, values in (("estimate", names, est_all), ("truth", tnames, tru_all)):
        tip_only = values[:, [side_names.index(c) for c in TIP_COLUMNS]]
        if problem := position_unit_problem(side_names, values, [length]) or (
            position_unit_problem(TIP_COLUMNS, tip_only, [length])
        ):
            raise UserError(f"{side}: {problem}")
    if problem := position_unit_against(tnames, tru_all, names, est_all):
        raise UserError(f"truth: {problem}")
    if problem := force_unit_against(tnames, tru_all, names, est_all):
        raise UserError(f"truth: {problem}")
    for side, side_names, values in (("estimate", names, est_all), ("truth", tnames, tru_all)):
        turned = angle_beyond_a_turn(side_names, values)
        if turned is not None:
            raise UserError(f"{side}: row {turned[0]}: {turned[1]}")
    est = est_all[:, [names.index(c) for c in common]]
    tru = tru_all[:, [tnames.index(c) for c in common]]
    estimated = np.all(np.isfinite(est), axis=1)
    has = compared_rows(est_all, tru_all, names, tnames)
    if not has.any():
        raise UserError(
            "no sample has an estimate"
            if not estimated.any()
            else "no estimated sample has a finite truth of the tip (x, y, z)"
        )
    # a column whose truth has gaps where the tip's has none (an angle a motion capture
    # leaves undefined) is compared over its own finite rows; one without any is left out
    kept = [j for j in range(len(common)) if np.isfinite(tru[has, j]).any()]
    common = [common[j] for j in kept]
    err = state_errors(est[has][:, kept], tru[has][:, kept], common)
    rmse = np.sqrt(np.nanmean(err**2, axis=0))
    col = {c: i for i, c in enumerate(common)}
    tip = np.linalg.norm(err[:, [col[c] for c in TIP_COLUMNS]], axis=1)
    end_mean: dict[str, float] = {}
    end_max: dict[str, float] = {}
    for k in sections_with_ends(common):  # every section end both sides have, gaps or not
        e = np.linalg.norm(err[:, [col[c] for c in section_end_columns(k)]], axis=1)
        e = e[np.isfinite(e)]
        if len(e):  # its three columns' gaps may leave no row with all of them
            end_mean[str(k)], end_max[str(k)] = float(e.mean() * 1e3), float(e.max() * 1e3)
    force = [col[c] for c in TIP_FORCE_COLUMNS if c in col]
    force_rms = None
    if len(force) == len(TIP_FORCE_COLUMNS):
        sq = np.sum(err[:, force] ** 2, axis=1)
        if np.isfinite(sq).any():
            force_rms = float(np.sqrt(np.mean(sq[np.isfinite(sq)])))
    return Metrics(
        rmse={c: float(v) for c, v in zip(common, rmse)},
        srmse=float(sum(v for c, v in zip(common, rmse) if c in srmse_columns(common))),
        tip_mean_mm=float(tip.mean() * 1e3),
        tip_max_mm=float(tip.max() * 1e3),
        tip_mean_pct=float(tip.mean() / length * 100),
        tip_max_pct=float(tip.max() / length * 100),
        n=int(has.sum()),
        n_without_estimate=int((~estimated).sum()),
        section_end_mean_mm=end_mean,
        section_end_max_mm=end_max,
        tip_force_rms_n=force_rms,
        n_without_truth=int((estimated & ~has).sum()),
    )


def compared_rows(
    estimate: FloatArray,
    truth: FloatArray,
    names: Sequence[str],
    truth_names: Sequence[str],
) -> NDArray[np.bool_]:
    """The rows that :func:`compute_metrics` compares (its ``n``): an estimate in every
    column both sides have, and a finite truth of the tip (``x, y, z``). ``estimate``
    (n, k) has the columns ``names``, ``truth`` (n, k') the columns ``truth_names``;
    both have the tip's."""
    common = [c for c in names if c in truth_names]
    est = np.asarray(estimate, dtype=float)[:, [list(names).index(c) for c in common]]
    tip = np.asarray(truth, dtype=float)[:, [list(truth_names).index(c) for c in TIP_COLUMNS]]
    return np.all(np.isfinite(est), axis=1) & np.all(np.isfinite(tip), axis=1)


#: Two-sided 95 % quantile of the standard normal: the half-width of a 95 % interval in
#: standard deviations.
Z95 = 1.959963984540054
#: An error this many of its standard deviations off is far outside its interval: a
#: Gaussian with the right standard deviation goes there about once in 16,000 samples
#: per axis.
FAR_STD = 4.0


@dataclass(frozen=True)
class Calibration:
    """How well an estimate's standard deviations describe its errors.

    Attributes:
        coverage: per output column, the fraction of samples whose error lies inside
            the 95 % interval ``estimate +- 1.96 std`` (0.95 where the std is right).
        n: per output column, the samples with a finite standard deviation.
        tip_nees: average normalised estimation error squared of the tip position,
            ``mean(sum_xyz (e / std)^2)`` (3 where the std is right; the per-axis variances
            only, as an estimate file keeps no correlations).
        tip_nees_band: its 95 % band under calibration for ``m = tip_n_eff`` samples
            and the tip axes' correlation that the normalised errors show
            (:func:`nees_band`; ``chi2(3 m) / m`` quantiles for uncorrelated axes).
        tip_n: samples in ``tip_nees``.
        tip_n_eff: the independent samples whose average NEES varies as this one does
            (:func:`effective_samples` of the per-sample NEES: an estimate's errors are
            correlated in time), at most ``tip_n``.
        tip_zero_std: samples left out of ``tip_nees`` because a tip axis' standard
            deviation is zero (their NEES is infinite where the error is not zero);
            ``coverage`` counts them, as misses unless the error is zero too.
        tip_far: samples whose error on some tip axis exceeds :data:`FAR_STD` of its
            standard deviation (a zero standard deviation with an error counts, as
            infinitely far): under a right Gaussian standard deviation about 2 in 10,000
            samples.
        tip_far_of: the samples with an estimate, a standard deviation and a truth on
            all three tip axes, of which ``tip_far`` are counted.
        tip_far_worst: the largest ``|error| / std`` over their tip axes (infinite where
            a zero standard deviation has an error; NaN without any sample).
        tip_far_worst_row: the sample where it lies, as an index of the rows given
            (-1 without any).
    """

    coverage: dict[str, float]
    n: dict[str, int]
    tip_nees: float
    tip_nees_band: tuple[float, float]
    tip_n: int
    tip_n_eff: float
    tip_zero_std: int = 0
    tip_far: int = 0
    tip_far_of: int = 0
    tip_far_worst: float = math.nan
    tip_far_worst_row: int = -1

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def nees_band(
    dof: int, n: float, level: float = 0.95, corr: FloatArray | None = None
) -> tuple[float, float]:
    """Two-sided ``level`` band of the average over ``n`` independent samples (``n`` may
    be an effective count, :func:`effective_samples`) of ``z^T z``, ``z`` ``dof``
    standard normals with correlation matrix ``corr`` (None: independent, ``chi2(dof)``
    each). Correlated axes keep the mean ``dof`` but widen the variance to ``2 tr(C^2)``
    a sample; the band is that of the scaled ``chi2`` with the same mean and variance
    (Satterthwaite): ``dof / nu * chi2(nu)`` with ``nu = dof^2 n / tr(C^2)``, which is
    ``chi2(dof n) / n`` for independent axes."""
    trace_c2 = float(dof) if corr is None else float(np.sum(np.asarray(corr, float) ** 2))
    nu = dof * dof * n / trace_c2
    a = (1 - level) / 2
    return float(dof / nu * chi2_quantile(a, nu)), float(dof / nu * chi2_quantile(1 - a, nu))


def normalised_error_correlation(z: FloatArray) -> FloatArray | None:
    """The correlation matrix (k, k) of normalised errors ``z`` (n, k) across their
    axes (Pearson, each axis' mean removed), or None with fewer than 3 rows or an axis
    without spread: an estimate file keeps each axis' standard deviation, not their
    correlations, so the NEES of its rows takes them from the errors."""
    z = np.asarray(z, dtype=float)
    if len(z) < 3 or not np.all(np.std(z, axis=0) > 0):
        return None
    return np.asarray(np.corrcoef(z, rowvar=False), dtype=float)


def effective_samples(series: FloatArray) -> float:
    """How many independent samples have an average that varies as the average of the
    correlated ``series`` (n,) does: ``n / tau``, with ``tau = 1 + 2 sum_k rho_k`` the
    integrated autocorrelation time of the series, summed over Geyer's initial positive
    sequence (the sums of consecutive pairs of lags, while they are positive); between 1
    and ``n`` (``n`` for fewer than 4 samples, a constant series, or one whose lags do
    not add up to a positive time: anti-correlated). Values that are not finite are
    left out."""
    x = np.asarray(series, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 4:
        return float(n)
    x = x - x.mean()
    if not np.dot(x, x) > 0.0:
        return float(n)
    spectrum = np.fft.rfft(x, 2 * n)
    acov = np.fft.irfft(spectrum * np.conj(spectrum), 2 * n)[:n]
    rho = acov / acov[0]
    tau = -1.0
    for m in range(n // 2):
        pair = rho[2 * m] + rho[2 * m + 1]
        if not pair > 0.0:
            break
        tau += 2.0 * pair
    if not tau > 0.0:  # anti-correlated at the first lags: as independent samples
        return float(n)
    return float(min(n, max(1.0, n / tau)))


def compute_calibration(
    estimate: FloatArray,
    std: FloatArray,
    truth: FloatArray,
    names: Sequence[str],
    truth_names: Sequence[str] | None = None,
) -> Calibration:
    """Coverage and tip NEES of ``estimate`` (n, k) with standard deviations ``std``
    (n, k), columns ``names``, against ``truth`` (n, k') with columns ``truth_names``.
    Rows without a finite estimate or standard deviation are left out per column; a
    zero standard deviation is a miss unless the error is zero too, and a row with one on
    a tip axis is left out of the tip NEES (counted in ``tip_zero_std``).

    Raises:
        UserError: arrays that are not (n, k) numbers with a column per name, of
            different lengths, or a negative standard deviation.
        ValueError: no sample has a standard deviation.
    """
    names = _column_names("names", names)
    tnames = names if truth_names is None else _column_names("truth_names", truth_names)
    est_all = _table("estimate", estimate, names, "names")
    sd_all = _table("std", std, names, "names")
    tru_all = _table("truth", truth, tnames, "names" if truth_names is None else "truth_names")
    if not len(est_all) == len(sd_all) == len(tru_all):
        raise UserError(
            f"estimate, std and truth have {len(est_all)}, {len(sd_all)} and {len(tru_all)} "
            "rows: one per sample each"
        )
    if np.any(sd_all < 0):  # (NaN compares false: a row without one)
        raise UserError("std must be standard deviations (>= 0), got a negative one")
    common = [c for c in names if c in tnames]
    est = est_all[:, [names.index(c) for c in common]]
    sd = sd_all[:, [names.index(c) for c in common]]
    tru = tru_all[:, [tnames.index(c) for c in common]]
    ok = np.isfinite(est) & np.isfinite(sd) & np.isfinite(tru)
    if not ok.any():
        raise ValueError("no sample has a standard deviation (std_* columns)")
    err = state_errors(np.where(ok, est, 0.0), np.where(ok, tru, 0.0), common)
    with np.errstate(divide="ignore", invalid="ignore"):
        zscore = np.abs(err) / sd
    inside = (zscore <= Z95) | ((err == 0) & (sd == 0))
    coverage = {
        c: float(np.mean(inside[ok[:, j], j])) if ok[:, j].any() else math.nan
        for j, c in enumerate(common)
    }
    counts = {c: int(ok[:, j].sum()) for j, c in enumerate(common)}
    tip = [common.index(c) for c in TIP_COLUMNS if c in common]
    zero = 0
    rows: NDArray[np.bool_] = np.zeros(len(ok), dtype=bool)
    if len(tip) == 3:
        finite = np.all(ok[:, tip], axis=1)
        rows = finite & np.all(sd[:, tip] > 0, axis=1)
        zero = int(np.sum(finite & ~rows))
    n_tip = int(np.sum(rows))
    far, far_of, worst, worst_row = 0, 0, math.nan, -1
    if len(tip) == 3:  # (a zero std with an error: an infinite z-score, far)
        compared = np.all(ok[:, tip], axis=1)
        per_row = np.nanmax(
            np.where(compared[:, None], zscore[:, tip], np.nan), axis=1, initial=0.0
        )
        far, far_of = int(np.sum(compared & (per_row > FAR_STD))), int(np.sum(compared))
        if far_of:
            worst_row = int(np.flatnonzero(compared)[int(np.argmax(per_row[compared]))])
            worst = float(per_row[worst_row])
    if n_tip:
        z = err[rows][:, tip] / sd[rows][:, tip]
        each = np.sum(z**2, axis=1)
        nees, n_eff = float(np.mean(each)), effective_samples(each)
        band = nees_band(3, n_eff, corr=normalised_error_correlation(z))
    else:
        nees, band, n_eff = math.nan, (math.nan, math.nan), 0.0
    return Calibration(
        coverage, counts, nees, band, n_tip, n_eff, zero, far, far_of, worst, worst_row
    )


def length_misfit(names: Sequence[str], values: FloatArray, lengths: Sequence[float]) -> str:
    """``""`` when an estimate's or truth's tip positions (``x, y, z``) fit a robot of
    these section ``lengths``, else why not, in words. With every section's bend columns
    (``theta``/``phi`` or ``theta_k``/``phi_k``): the median ratio of the tip's distance
    from the base to the one its own angles give on that robot (the file's robot's
    length over this one's); without them: a tip farther from the base than the whole
    length, which no shape of the robot reaches. A file with the angles of another number
    of sections is of another robot (the caller says so): ``""``."""
    rows = np.asarray(values, dtype=float)
    length = float(sum(lengths))
    if mentions_bend_angles(names):
        ratio = tip_ratio(names, rows, lengths)
        if ratio is None or abs(ratio - 1) <= LENGTH_RATIO_TOLERANCE:
            return ""
        return (
            f"its tip is {ratio:.2f} times as far from the base as its own angles put it on a "
            f"robot of {length:g} m: it was made for a robot of about {ratio * length:.3g} m"
        )
    tip = rows[:, [list(names).index(o.name) for o in pcc_outputs(len(lengths))[:3]]]
    far = float(np.nanmax(np.linalg.norm(tip, axis=1), initial=0.0))
    if far <= (1 + LENGTH_RATIO_TOLERANCE) * length:
        return ""
    return (
        f"its tip is up to {far:.3g} m from the base, beyond the robot's length {length:g} m, "
        "which no shape reaches: it was made for a longer robot"
    )


#: a truth row is an estimate row's when their times agree to this many seconds (and a
#: few roundings of a large clock's times; ``evaluate`` and ``plot`` match rows so)
TIME_MATCH = 1e-6

IndexArray = NDArray[np.intp]


def match_rows(t_est: FloatArray, t_truth: FloatArray) -> tuple[IndexArray, IndexArray]:
    """Indices ``(i_est, i_truth)`` of the estimate rows that have a truth row at the same
    time (within :data:`TIME_MATCH`, 1 us, and a few roundings of a large clock's times),
    and of those truth rows (none of either where the truth has no rows)."""
    t_est, t_truth = np.asarray(t_est, dtype=float), np.asarray(t_truth, dtype=float)
    if len(t_truth) == 0:
        none = np.zeros(0, dtype=np.intp)
        return none, none
    idx = np.clip(np.searchsorted(t_truth, t_est), 0, len(t_truth) - 1)
    lo = np.clip(idx - 1, 0, len(t_truth) - 1)
    nearest = np.where(np.abs(t_truth[lo] - t_est) < np.abs(t_truth[idx] - t_est), lo, idx)
    # 1 us, and the rounding of a large clock's times (epoch seconds: 0.24 us apart),
    # not a share of t (at t = 1.7e9 s a share of 1e-6 would be 1700 s)
    spacing = np.spacing(np.maximum(np.abs(t_est), np.abs(t_truth[nearest])))
    match = np.abs(t_truth[nearest] - t_est) <= TIME_MATCH + 8 * spacing
    return np.flatnonzero(match), nearest[match]


#: :func:`truth_at` interpolates a truth whose median step is at most this many times
#: the estimate's, and not across a step of more than :data:`INTERPOLATE_GAP` of its own
#: median steps.
INTERPOLATE_STEP = 2.0
INTERPOLATE_GAP = 3.0
#: :func:`truth_at` compares no truth sampled more than this many times as far apart as
#: the estimate (a truth whose ``t`` is in milliseconds, read as seconds, is 1000 times).
SPARSE_STEP_MAX = 10.0


def truth_at(
    t_est: FloatArray, t_truth: FloatArray, values: FloatArray, names: Sequence[str]
) -> tuple[IndexArray, FloatArray] | None:
    """The truth (``values`` (m, k) at ``t_truth`` (m,) s, columns ``names``) interpolated
    linearly at the estimate's times ``t_est`` (n,) s: ``(i_est, rows (len(i_est), k))``
    for the estimate rows inside the truth's time span and not inside a gap of it (a
    step over :data:`INTERPOLATE_GAP` of its median step), ``phi`` columns through their
    unwrapped values; a motion capture recorded on its own clock, at its own rate, is
    compared so. A truth sparser than :data:`INTERPOLATE_STEP` times the estimate's
    median step is interpolated only at the estimate row nearest each of its samples
    (within half the estimate's step: a short way from the sample, where a line through
    the truth's samples far apart would miss the motion between them; a row just
    outside the truth's span takes its end sample's values); not a truth more
    than :data:`SPARSE_STEP_MAX` times as sparse. None where its times do not increase
    or it is that sparse."""
    t_est, t_truth = np.asarray(t_est, dtype=float), np.asarray(t_truth, dtype=float)
    values = np.asarray(values, dtype=float)
    if len(t_truth) < 2 or len(t_est) < 2 or np.any(np.diff(t_truth) <= 0):
        return None
    step = float(np.median(np.diff(t_truth)))
    est_step = float(np.median(np.diff(t_est)))
    if step > SPARSE_STEP_MAX * est_step:  # another unit of time, or another recording
        return None
    if step > INTERPOLATE_STEP * est_step:  # at the rows nearest the truth's samples
        right = np.clip(np.searchsorted(t_est, t_truth), 1, len(t_est) - 1)
        left = right - 1
        near = np.where(
            np.abs(t_est[left] - t_truth) <= np.abs(t_est[right] - t_truth), left, right
        )
        close = np.abs(t_est[near] - t_truth) <= 0.5 * est_step * (1.0 + 1e-9)
        inside = np.zeros(len(t_est), dtype=bool)
        inside[near[close]] = True  # the span's ends included: such a row takes the end's value
    else:
        inside = (t_est >= t_truth[0]) & (t_est <= t_truth[-1])
    after = np.clip(np.searchsorted(t_truth, t_est), 1, len(t_truth) - 1)
    inside &= t_truth[after] - t_truth[after - 1] <= INTERPOLATE_GAP * step
    i_est = np.flatnonzero(inside)
    rows = np.empty((len(i_est), values.shape[1]))
    for j, name in enumerate(names):
        column = values[:, j].copy()
        wrapped = is_wrapped(name)
        if wrapped:  # through the finite values (a NaN row stops no unwrapping)
            finite = np.isfinite(column)
            column[finite] = np.unwrap(column[finite])
        rows[:, j] = np.interp(t_est[i_est], t_truth, column)
        if wrapped:
            rows[:, j] = wrap_angle(rows[:, j])
    return i_est.astype(np.intp), rows


#: :func:`aligned_truth` interpolates the truth where fewer than this share of the
#: estimate's rows have a truth row at the same t.
INTERPOLATE_BELOW = 0.5


class TruthCoverageWarning(UserWarning):
    """Fewer than half of an estimate's rows have a truth to be scored against: the
    scores are of those rows alone (the files' times do not match?)."""


def aligned_truth(
    t_est: FloatArray,
    t_truth: FloatArray,
    values: FloatArray,
    names: Sequence[str],
    *,
    warn: bool = True,
) -> tuple[IndexArray, FloatArray, bool]:
    """``(i_est, rows, interpolated)``: the estimate rows compared and the truth's values
    at them (``evaluate`` and ``plot`` compare so): the truth's rows at the same t
    (:func:`match_rows`), or, where fewer than :data:`INTERPOLATE_BELOW` of the
    estimate's rows have one, the truth interpolated at the estimate's times
    (:func:`truth_at`) where that compares more rows (``interpolated`` True). A
    :class:`TruthCoverageWarning` where fewer than half of the estimate's rows are
    compared (``warn=False``: none; the command line says it with the files' names).

    Raises:
        UserError: ``values`` that are not (len(t_truth), len(names)) numbers, or times
            that are not 1-D or do not increase.
    """
    names = _column_names("names", names)
    table = _table("values", values, names, "names")
    t_est, t_truth = _times("t_est", t_est), _times("t_truth", t_truth)
    if t_est.ndim != 1 or t_truth.ndim != 1:
        raise UserError(
            f"t_est and t_truth must be 1-D arrays of times, got shapes {t_est.shape} and "
            f"{t_truth.shape}"
        )
    if len(table) != len(t_truth):
        raise UserError(
            f"values has {len(table)} rows but t_truth has {len(t_truth)}: one truth row per time"
        )
    for name, times in (("t_est", t_est), ("t_truth", t_truth)):
        back = np.flatnonzero(~(np.diff(times) > 0))
        if len(back):  # (a row matched by its time would be the wrong one: sort them)
            i = int(back[0]) + 1
            raise UserError(
                f"{name} must increase: row {i} is at {times[i]:g} s after {times[i - 1]:g} s "
                "(sort the rows by time)"
            )
    i_est, i_truth = match_rows(t_est, t_truth)
    rows = table[i_truth]
    interpolated = False
    if len(i_est) < INTERPOLATE_BELOW * len(t_est):
        found = truth_at(t_est, t_truth, table, names)
        if found is not None and len(found[0]) > len(i_est):
            i_est, rows, interpolated = found[0], found[1], True
    if warn and len(i_est) < 0.5 * len(t_est):
        warnings.warn(
            f"only {len(i_est)} of the estimate's {len(t_est)} rows have a truth at their "
            "time: the scores are of those rows alone (t in milliseconds, another "
            "recording, a truth of part of it?)",
            TruthCoverageWarning,
            stacklevel=2,
        )
    return i_est, rows, interpolated


def truth_sparser(t_est: FloatArray, t_truth: FloatArray) -> bool:
    """Whether the truth's median step exceeds :data:`INTERPOLATE_STEP` times the
    estimate's, up to :data:`SPARSE_STEP_MAX` times (:func:`truth_at` then compares the
    rows nearest its samples alone)."""
    if len(t_est) < 2 or len(t_truth) < 2:
        return False
    ratio = float(np.median(np.diff(t_truth))) / float(np.median(np.diff(t_est)))
    return INTERPOLATE_STEP < ratio <= SPARSE_STEP_MAX


def interpolated_note(
    truth: str, estimate: str, compared: int, rows: int, sparser: bool = False
) -> str:
    """The note that the truth file ``truth`` was interpolated at the times of the
    estimate file ``estimate`` (:func:`aligned_truth`), ``compared`` of its ``rows``;
    ``sparser``: at the rows nearest its samples alone (:func:`truth_sparser`)."""
    at = (
        f"at the {compared} of its {rows} rows nearest the truth's samples (sampled more "
        f"than {INTERPOLATE_STEP:g} times as far apart)"
        if sparser
        else f"at them ({compared} of {rows} rows)"
    )
    return f"{truth}'s rows are not at {estimate}'s times: the truth is interpolated linearly {at}"


#: :func:`best_time_shift` tries shifts of the truth up to this many seconds either way
#: (about :data:`SHIFT_STEPS` of them, then the best one refined towards the estimate's
#: sample period), on at most :data:`SHIFT_ROWS` rows of the estimate.
SHIFT_MAX_S = 2.0
SHIFT_STEPS = 200
SHIFT_ROWS = 2_000


@dataclass(frozen=True)
class TimeShift:
    """The shift of the truth's clock that fits an estimate best: the truth read at
    ``t + shift_s`` (s) gives the mean tip error ``error`` (m), against ``unshifted``
    (m) at ``t``, over the same rows (:func:`best_time_shift`)."""

    shift_s: float
    error: float
    unshifted: float


def best_time_shift(
    t_est: FloatArray, tip_est: FloatArray, t_truth: FloatArray, tip_truth: FloatArray
) -> TimeShift | None:
    """The shift of the truth (``t_truth`` (m,) s, ``tip_truth`` (m, 3) m) within
    :data:`SHIFT_MAX_S` s that gives the smallest mean tip error against the estimate
    (``t_est`` (n,), ``tip_est`` (n, 3), NaN rows left out), the truth interpolated
    linearly at the shifted times: a grid of at most :data:`SHIFT_STEPS` shifts, the
    best refined in steps of the estimate's median sample period. None where fewer
    than 10 rows compare, with or without the shift, or the times do not increase. A
    clock offset between the two files shows as a shift whose error is far below the
    unshifted one (so can half the period of a motion that repeats, on an estimate
    mirrored in sign). Every shift is scored on the same rows, those at least
    :data:`SHIFT_MAX_S` s inside the truth's times, so that no shift looks better for
    leaving out a few rows far off at the ends."""
    keep = np.all(np.isfinite(tip_est), axis=1)
    t_e, x_e = t_est[keep], tip_est[keep]
    good = np.all(np.isfinite(tip_truth), axis=1)
    t_t, x_t = t_truth[good], tip_truth[good]
    if len(t_e) < 10 or len(t_t) < 2 or np.any(np.diff(t_t) <= 0) or np.any(np.diff(t_e) <= 0):
        return None
    period = float(np.median(np.diff(t_e)))
    if len(t_e) > SHIFT_ROWS:
        pick = np.linspace(0, len(t_e) - 1, SHIFT_ROWS).astype(int)
        t_e, x_e = t_e[pick], x_e[pick]

    # contiguous once: numpy.interp would copy a strided column at every call
    t_t = np.ascontiguousarray(t_t, dtype=float)
    columns = [np.ascontiguousarray(x_t[:, k], dtype=float) for k in range(3)]

    inside = (t_e >= t_t[0] + SHIFT_MAX_S) & (t_e <= t_t[-1] - SHIFT_MAX_S)
    if inside.sum() < 10:  # every shift's rows the same: too short a recording
        return None
    t_e, x_e = t_e[inside], x_e[inside]

    def error(shift: float) -> float:
        truth = np.column_stack([np.interp(t_e + shift, t_t, c) for c in columns])
        return float(np.mean(np.linalg.norm(x_e - truth, axis=1)))

    unshifted = error(0.0)
    if not math.isfinite(unshifted):
        return None
    step = max(period, 2 * SHIFT_MAX_S / SHIFT_STEPS)
    coarse = np.arange(-math.floor(SHIFT_MAX_S / step), math.floor(SHIFT_MAX_S / step) + 1) * step

    def least(shifts: NDArray[np.floating[Any]]) -> tuple[float, float]:
        errors = [error(float(s)) for s in shifts]
        i = int(np.argmin(errors))
        return float(shifts[i]), errors[i]

    best, found = least(coarse)
    if step > period:  # refine around the best, in sample periods (at most SHIFT_STEPS)
        fine_step = max(period, 2 * step / SHIFT_STEPS)
        half = math.ceil(step / fine_step)
        fine = best + np.arange(-half, half + 1) * fine_step
        best, found = least(fine[np.abs(fine) <= SHIFT_MAX_S])
    if abs(best) < 0.5 * period or not found < (1.0 - 1e-6) * unshifted:  # no better: none
        return TimeShift(0.0, unshifted, unshifted)
    return TimeShift(best, found, unshifted)


#: :func:`best_rotation` needs this many rows with both tips.
ROTATION_MIN_ROWS = 10


@dataclass(frozen=True)
class FrameRotation:
    """The rigid motion of the truth's positions that fits an estimate best
    (:func:`best_rotation`): ``matrix`` (3, 3) turns a truth position by ``angle_deg``
    degrees, then ``offset`` (3,) m moves it (zero for a turn about the base alone), into
    the estimate's frame; the mean tip error is then ``error`` (m), against ``unturned``
    (m) as the positions are."""

    matrix: FloatArray
    angle_deg: float
    offset: FloatArray
    error: float
    unturned: float


def best_rotation(
    tip_est: FloatArray, tip_truth: FloatArray, moved: bool = False
) -> FrameRotation | None:
    """The rotation about the base (the origin), and with ``moved`` a move as well, that
    brings the truth's tip positions ``tip_truth`` (n, 3) m nearest those of the estimate
    ``tip_est`` (n, 3) m at the same rows, in the least-squares sense
    (``scipy.spatial.transform.Rotation.align_vectors``, on the positions about their
    means where ``moved``); rows with a NaN on either side left out. None with fewer
    than :data:`ROTATION_MIN_ROWS` rows. A truth in another frame than the robot's base
    frame (a y-up motion capture, axes swapped) shows as a large angle whose error is
    far below the unturned one; a truth about another origin (a motion capture's), as a
    large offset. Positions along one line (a straight robot) leave the turn about that
    line free: the answer is then one of many that fit alike (SciPy's warning of it is not
    shown); :func:`~continuum_mhe.evaluation.truth_checks.frame_fit` judges a turn only
    where the positions spread over two directions."""
    from scipy.spatial.transform import Rotation

    est = np.asarray(tip_est, dtype=float)
    truth = np.asarray(tip_truth, dtype=float)
    both = np.all(np.isfinite(est), axis=1) & np.all(np.isfinite(truth), axis=1)
    if both.sum() < ROTATION_MIN_ROWS:
        return None
    est, truth = est[both], truth[both]
    est_mean, truth_mean = (
        (est.mean(axis=0), truth.mean(axis=0)) if moved else (np.zeros(3), np.zeros(3))
    )
    with warnings.catch_warnings():  # a degenerate set (a straight robot): one of many
        warnings.simplefilter("ignore", UserWarning)
        rotation, _ = Rotation.align_vectors(est - est_mean, truth - truth_mean)
    offset = np.asarray(est_mean - rotation.apply(truth_mean), dtype=float)
    turned = rotation.apply(truth) + offset
    return FrameRotation(
        matrix=rotation.as_matrix(),
        angle_deg=math.degrees(float(rotation.magnitude())),
        offset=offset,
        error=float(np.linalg.norm(turned - est, axis=1).mean()),
        unturned=float(np.linalg.norm(truth - est, axis=1).mean()),
    )
