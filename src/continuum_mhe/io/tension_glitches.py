"""Glitches of the given tensions: a tension that one row alone, or two rows in a row,
get wrong (a load cell's or a serial link's error, a logger that held a sample), found
and replaced by the cubic through the neighbouring rows (:func:`tension_glitches`; a
stream's, one row alone: :class:`StreamGlitches`).

The estimators take the tensions' rates and second derivatives from their rows'
differences, so that a row off by a few hundredths of a newton is a spike of both,
which the mechanics model turns into a jump of the shape and of the IMUs' own
acceleration that the readings do not show: on the shipped ``force-29`` (raw IMUs,
EKF) one tension 0.05 N off at one row takes the tip from 0.7 to 55 mm off, for the
rest of the recording (docs/tendon.md, the tensions file).

A tension at row ``i`` is a glitch where

* it leaves the cubic through rows ``i - 2``, ``i - 1``, ``i + 1`` and ``i + 2``
  (Lagrange, at the rows' times) by more than :data:`GLITCH_NOISE_FACTOR` times what
  the rows' noise (:func:`~.tension_derivatives.tension_noise_std`) puts there, more
  than :data:`GLITCH_SCALE_FACTOR` times the same departure of the rows 3 to 6 rows
  away (their median: a smooth motion moves those as far, a glitch does not reach
  them), and more than :data:`GLITCH_FLOOR_N`;
* and the departures of rows ``i - 2`` to ``i + 2`` (those judged, two at least, near
  a file's ends) from their own cubics are the glitch's echo in them (``-w h``, ``h``
  the glitch and ``w`` its weight in their cubics: at even times 2/3 one row away,
  -1/6 two rows away) within
  :data:`SIGNATURE_TOLERANCE` of ``h``: a step of the tensions (a controller's), a
  kink (a slack tendon that starts to pull) or a fast motion leaves another pattern.

A tension wrong at rows ``i`` and ``i + 1`` alike (neither a single-row glitch) is judged
the same way by the cubic through rows ``i - 2``, ``i - 1``, ``i + 2`` and ``i + 3``, and
the pair's echo in rows ``i - 2`` to ``i + 3`` (:func:`_pair_glitches`).

Where more than :data:`MAX_GLITCH_SHARE` of the rows would be glitches, none is: such
departures are the sensor's way (a quantised or noisy load cell), which the smoothing
of :mod:`.tension_derivatives` takes. The first and last two rows are not judged.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.io.tension_derivatives import NOISE_ORDER, tension_noise_std

#: How many times the noise's share of its departure a glitch leaves the cubic through
#: its neighbours by, at least.
GLITCH_NOISE_FACTOR = 8.0
#: How many times the median departure of the rows 3 to 6 rows away, at least.
GLITCH_SCALE_FACTOR = 4.0
#: The smallest departure taken as a glitch, N (a file written with six decimals rounds
#: a tension by half a micronewton).
GLITCH_FLOOR_N = 1e-4
#: How far the neighbours' departures may lie from a glitch's echo in them, as a share
#: of the glitch.
SIGNATURE_TOLERANCE = 0.1
#: The largest share of the rows that may be glitches (else none is).
MAX_GLITCH_SHARE = 0.01
#: How many times the same departure of the six samples before it a stream's sample
#: leaves the cubic through the four before it by, at least, to be judged
#: (:class:`StreamGlitches`).
CANDIDATE_FACTOR = 2.0
#: The samples a :class:`StreamGlitches` keeps: a candidate's eight before it, itself and
#: the two after it (the oldest kept enters the departures the newest is compared with).
STREAM_KEPT = 11
#: The rows away from a judged row whose departures give the local scale.
_AROUND = (-6, -5, -4, -3, 3, 4, 5, 6)


@dataclass(frozen=True)
class TensionGlitches:
    """The glitches of a tensions table (:func:`tension_glitches`).

    Attributes:
        mask: (n, k) True at a tension that is a glitch.
        curve: (n, k) N, the cubic through each row's neighbours at its time (the
            value a glitch is replaced by; the row itself where not judged).
    """

    mask: NDArray[np.bool_]
    curve: FloatArray

    @property
    def count(self) -> int:
        """The tensions that are glitches."""
        return int(self.mask.sum())

    def replaced(self, values: FloatArray) -> FloatArray:
        """``values`` (n, k) with each glitch replaced by its :attr:`curve` value."""
        return np.where(self.mask, self.curve, values)


def _lagrange(t_nodes: FloatArray, t_at: FloatArray | float) -> FloatArray:
    """The weights (4, ...) of the cubic through the rows at ``t_nodes`` (4, ...) s, at
    ``t_at`` (... , broadcast against ``t_nodes[0]``)."""
    w = np.ones(np.shape(t_nodes))
    for j in range(4):
        for other in range(4):
            if other != j:
                w[j] *= (t_at - t_nodes[other]) / (t_nodes[j] - t_nodes[other])
    return w


def tension_glitches(t: FloatArray, values: FloatArray, noise: float) -> TensionGlitches:
    """The single-row and two-row glitches of the tensions ``values`` (n, k) N at ``t`` (n,) s,
    strictly increasing, whose row-to-row noise is ``noise`` N (module docstring)."""
    values = np.asarray(values, dtype=float)
    n, k = values.shape
    mask = np.zeros((n, k), dtype=bool)
    curve = values.copy()
    if n < 9:
        return TensionGlitches(mask, curve)
    rows = np.arange(2, n - 2)
    nodes = np.stack([rows - 2, rows - 1, rows + 1, rows + 2])  # (4, m)
    tr = t[rows]
    weights = _lagrange(t[nodes], tr)  # (4, m)
    # a white noise of std ``noise`` departs from the cubic with std noise * gain
    gain = np.sqrt(1.0 + np.sum(weights**2, axis=0))  # (m,)
    m = len(rows)
    judged = np.arange(m)  # indices into rows: rows 2 to n - 3
    pairs = _PairCubics.of(t) if n >= 10 else None
    for c in range(k):  # a tendon at a time: the rows around take (8, n) values, not (8, n, k)
        v = values[:, c]
        curve[rows, c] = np.einsum("jm,jm->m", weights, v[nodes])
        signed = v[rows] - curve[rows, c]  # (m,)
        departure = np.abs(signed)
        around = np.full((len(_AROUND), m), np.nan)
        for a, off in enumerate(_AROUND):
            src = np.arange(m) + off
            inside = (src >= 0) & (src < m)
            around[a, inside] = departure[src[inside]]
        scale = np.zeros(m)
        full = np.isfinite(around).all(axis=0)  # all but the first and last six
        scale[full] = np.median(around[:, full], axis=0)
        edge = ~full & np.isfinite(around).any(axis=0)
        scale[edge] = np.nanmedian(around[:, edge], axis=0)
        limit = np.maximum(GLITCH_SCALE_FACTOR * scale, GLITCH_FLOOR_N)
        limit = np.maximum(limit, GLITCH_NOISE_FACTOR * noise * gain)
        # a glitch h at row i moves the cubics of rows i - 2 to i + 2 (it is one of their
        # nodes, of weight w) by w h: their departures are its echo -w h, where a step's,
        # a kink's or a motion's are not
        # (near a file's ends, those of the rows judged: two at least)
        h = signed[judged]
        echoed = np.ones(len(judged), dtype=bool)
        echoes = np.zeros(len(judged), dtype=int)
        # (offset, the glitch's node index in that row's cubic: nodes i-2, i-1, i+1, i+2)
        for off, node in ((-2, 3), (-1, 2), (1, 1), (2, 0)):
            there = (judged + off >= 0) & (judged + off < m)
            at = judged[there] + off
            echo = signed[at] + weights[node, at] * h[there]
            echoed[there] &= np.abs(echo) < SIGNATURE_TOLERANCE * np.abs(h[there])
            echoes[there] += 1
        echoed &= echoes >= 2
        mask[rows[judged], c] = (departure[judged] > limit[judged]) & echoed
        if pairs is not None:
            _pair_glitches(pairs, t, v, signed, departure, weights, noise, mask[:, c], curve[:, c])
    if mask.any(axis=1).sum() > max(1, math.floor(MAX_GLITCH_SHARE * n)):
        mask[:] = False
    return TensionGlitches(mask, curve)


#: A pair's rows' departures from their own cubics that its errors ``(h1, h2)`` give,
#: by the offset of the row from the pair's first: (the row's own error, 1 for ``h1``,
#: 2 for ``h2``, 0 for none), then (the pair's error, its node in the row's cubic: nodes
#: ``r - 2, r - 1, r + 1, r + 2`` are 0 to 3) for each error among the row's nodes.
_PAIR_ECHOES: tuple[tuple[int, int, tuple[tuple[int, int], ...]], ...] = (
    (-2, 0, ((1, 3),)),
    (-1, 0, ((1, 2), (2, 3))),
    (0, 1, ((2, 2),)),
    (1, 2, ((1, 1),)),
    (2, 0, ((1, 0), (2, 1))),
    (3, 0, ((2, 0),)),
)
#: How far a step between the rows a pair's judgement reads may lie from the median
#: step, as a share of it (rows at jittered times are judged; rows across a hole not).
PAIR_EVEN_STEPS = 0.5
#: How far (rms) the four rows each side of a pair may lie from one cubic through them
#: all, as a share of the pair's larger error (a step leaves 0.12 or more).
PAIR_OUTER_TOLERANCE = 0.08
#: The rows away from a pair's first row whose single-row departures give the local
#: scale (3 to 6 rows from either of its rows).
_PAIR_AROUND = (-6, -5, -4, -3, 4, 5, 6, 7)


@dataclass(frozen=True)
class _PairCubics:
    """The cubics through rows ``i - 2, i - 1, i + 2, i + 3`` of a table at ``t``, at the
    times of rows ``i`` and ``i + 1``, for ``i`` = 2 to n - 4: ``nodes`` (4, p) their rows,
    ``weights`` (2, 4, p) at the two rows, ``gain`` (2, p) a white noise's departure from
    them in its std."""

    first: NDArray[np.int_]
    nodes: NDArray[np.int_]
    weights: FloatArray
    gain: FloatArray

    @classmethod
    def of(cls, t: FloatArray) -> _PairCubics:
        """Those of the pairs whose rows ``i - 4`` to ``i + 5`` (those their judgement
        reads) lie :data:`PAIR_EVEN_STEPS` of the median step apart at most: across a
        hole in the rows, two rows' departures from a cubic over it are not a glitch's."""
        step = np.diff(t)
        usual = float(np.median(step))
        even = np.abs(step - usual) <= PAIR_EVEN_STEPS * usual  # (n - 1,)
        first = np.arange(2, len(t) - 3)
        uneven = np.concatenate([[0], np.cumsum(~even)])  # uneven steps before each row
        lo, hi = np.maximum(first - 4, 0), np.minimum(first + 5, len(step))  # steps lo..hi-1
        first = first[uneven[hi] == uneven[lo]]
        nodes = np.stack([first - 2, first - 1, first + 2, first + 3])
        weights = np.stack([_lagrange(t[nodes], t[first + j]) for j in (0, 1)])
        gain = np.sqrt(1.0 + np.sum(weights**2, axis=1))
        return cls(first, nodes, weights, gain)


def _outer_rows_smooth(t: FloatArray, v: FloatArray, i: int, size: float) -> bool:
    """Whether the four rows on each side of the pair at rows ``i``, ``i + 1`` (of
    tensions ``v`` at ``t``) lie on one cubic (least squares) within
    :data:`PAIR_OUTER_TOLERANCE` of the pair's larger error ``size`` (rms): a glitch
    leaves them on the motion's curve, a step (a controller's, one row before, in or
    after the pair) puts them on two levels."""
    rows = np.r_[i - 4 : i, i + 2 : i + 6]
    basis = np.vander(t[rows] - t[i], 4)
    fit = np.linalg.lstsq(basis, v[rows], rcond=None)[0]
    return bool(np.sqrt(np.mean((v[rows] - basis @ fit) ** 2)) < PAIR_OUTER_TOLERANCE * size)


def _pair_glitches(
    pairs: _PairCubics,
    t: FloatArray,
    v: FloatArray,
    signed: FloatArray,
    departure: FloatArray,
    weights: FloatArray,
    noise: float,
    mask: NDArray[np.bool_],
    curve: FloatArray,
) -> None:
    """Mark in ``mask`` (n,) the glitches of one tendon's tensions ``v`` (n,) N at ``t``
    (n,) s that two rows in a row get wrong (a logger that held a sample for two rows;
    two readings of a link that failed), where no row of the pair is a single-row
    glitch, and put in ``curve`` (n,) the cubic through the two rows either side at
    each. ``signed`` and ``departure`` (m,): rows 2 to n - 3's signed and absolute
    departures from their own cubics, of ``weights`` (4, m). Both rows leave the cubic
    beyond the limits a single row's glitch leaves it by (their gains, the single-row
    departures 3 to 6 rows away),
    and the departures of rows ``i - 2`` to ``i + 3`` from their own cubics (all six
    judged: pairs from row 4 to row n - 5) are the pair's echo in them within
    :data:`SIGNATURE_TOLERANCE` of its larger error, and the four rows each side lie on
    one cubic (:func:`_outer_rows_smooth`)."""
    m = len(signed)
    p = len(pairs.first)
    fit = np.einsum("jkp,kp->jp", pairs.weights, v[pairs.nodes])  # (2, p)
    h = v[pairs.first + np.arange(2)[:, None]] - fit  # (2, p)
    around = np.full((len(_PAIR_AROUND), p), np.nan)
    base = pairs.first - 2  # the pair's first row among the judged rows
    for j, off in enumerate(_PAIR_AROUND):
        src = base + off
        inside = (src >= 0) & (src < m)
        around[j, inside] = departure[src[inside]]
    scale = np.zeros(p)
    known = np.isfinite(around).any(axis=0)
    scale[known] = np.nanmedian(around[:, known], axis=0)
    limit = np.maximum(GLITCH_SCALE_FACTOR * scale, GLITCH_FLOOR_N)
    limit = np.maximum(limit[None, :], GLITCH_NOISE_FACTOR * noise * pairs.gain)
    larger = np.max(np.abs(h), axis=0)
    echoed = np.ones(p, dtype=bool)
    echoes = np.zeros(p, dtype=int)
    for off, own, among in _PAIR_ECHOES:
        at = base + off
        there = (at >= 0) & (at < m)
        rows = at[there]
        echo = h[own - 1, there] if own else np.zeros(len(rows))
        for which, node in among:
            echo = echo - weights[node, rows] * h[which - 1, there]
        echoed[there] &= np.abs(signed[rows] - echo) < SIGNATURE_TOLERANCE * larger[there]
        echoes[there] += 1
    found = np.all(np.abs(h) > limit, axis=0) & echoed & (echoes == len(_PAIR_ECHOES))
    taken = mask.copy()
    for q in np.flatnonzero(found):
        i = int(pairs.first[q])
        if taken[i - 1 : i + 3].any():  # a single-row glitch, or a pair beside: not this
            continue
        if not _outer_rows_smooth(t, v, i, float(larger[q])):  # a step's
            continue
        taken[i : i + 2] = True
        mask[i : i + 2] = True
        curve[i : i + 2] = fit[:, q]


class StreamGlitches:
    """The single-row glitches of tensions that come one sample at a time (``live``'s
    serial line, and a recording's own tension columns, read as ``live`` took them), by
    the samples known when the two after a sample are in.

    A sample is a candidate where its tensions leave the cubic through the four samples
    before it, extrapolated, by more than :data:`CANDIDATE_FACTOR` times the same
    departure of the six samples before it and half :data:`GLITCH_FLOOR_N` (a smooth
    motion departs alike from sample to sample). A candidate is judged once the two
    samples after it are in, as :func:`tension_glitches` judges a row, by what is known
    then: the rows around are the ones 3 to 6 samples before, the echoes those in the
    two samples before it, and the noise is that of the last :attr:`noise_rows`
    samples as given (judged from the 23rd sample on, the 25th pushed, when it is
    known). A glitch's tensions are replaced by the cubic through its neighbours, not
    below zero, and its departure is taken again out of the two samples after it (their
    candidacy compares with it). Until a candidate is judged, the samples whose
    derivatives it enters (two each side) wait (:meth:`waiting`).

    The samples are numbered from 0 as pushed; :attr:`t` and :attr:`values` keep the
    last :data:`STREAM_KEPT` (replaced where glitches)."""

    def __init__(self, noise_rows: int) -> None:
        #: samples of the noise estimate (:func:`~.tension_derivatives.tension_noise_std`)
        self.noise_rows = noise_rows
        self.t: deque[float] = deque(maxlen=STREAM_KEPT)
        self.values: deque[FloatArray] = deque(maxlen=STREAM_KEPT)
        self._candidate: deque[bool] = deque(maxlen=STREAM_KEPT)
        # each sample's departure from the cubic through the four before it, as pushed
        self._departure: deque[FloatArray] = deque(maxlen=7)
        #: the last :attr:`noise_rows` samples as given (their noise judges a candidate)
        self.given_t: deque[float] = deque(maxlen=noise_rows)
        self.given: deque[FloatArray] = deque(maxlen=noise_rows)
        #: samples pushed
        self.seen = 0
        #: (sample number, tendon, value given, value used) of each glitch replaced
        self.replaced: list[tuple[int, int, float, float]] = []

    @property
    def first(self) -> int:
        """The number of the oldest sample kept."""
        return self.seen - len(self.t)

    def push(self, t: float, values: FloatArray) -> None:
        """Add a sample (``t`` s, later than the last; ``values`` N, NaN where missing)."""
        v = np.array(values, dtype=float)
        self.t.append(float(t))
        self.values.append(v)
        self.given_t.append(float(t))
        self.given.append(v.copy())
        self.seen += 1
        self._candidate.append(self._departs())
        if len(self.t) == STREAM_KEPT and self._candidate[-3]:
            self._judge(len(self.t) - 3)
            self._candidate[-3] = False

    def waiting(self, lo: int, hi: int) -> bool:
        """Whether a sample numbered ``lo`` to ``hi`` (inclusive) is a candidate not
        judged yet."""
        first = self.first
        return any(
            self._candidate[i - first] for i in range(max(lo, first), min(hi, self.seen - 1) + 1)
        )

    def clear(self) -> None:
        """Start afresh (the stream ended): no sample kept, none pushed or replaced."""
        for kept in (self.t, self.values, self._candidate, self._departure):
            kept.clear()
        self.given_t.clear()
        self.given.clear()
        self.seen = 0
        self.replaced = []

    def _departs(self) -> bool:
        """Whether the newest sample is a candidate (the class docstring), judged once
        eleven samples are kept (its departure is kept from the fifth on)."""
        if len(self.t) < 5:
            return False
        t = np.array(list(self.t)[-5:])
        v = np.array(list(self.values)[-5:])
        self._departure.append(np.abs(v[-1] - _lagrange(t[:-1], t[-1]) @ v[:-1]))
        if len(self.t) < STREAM_KEPT:
            return False
        before = np.array(list(self._departure)[:-1])
        limit = np.maximum(CANDIDATE_FACTOR * np.median(before, axis=0), 0.5 * GLITCH_FLOOR_N)
        return bool(np.any(self._departure[-1] > limit))  # NaN compares False: no candidate

    def _judge(self, i: int) -> None:
        """Judge kept sample ``i`` (the third newest; eight kept before it)."""
        if len(self.given) < 3 * NOISE_ORDER + 1:
            return
        noise = tension_noise_std(np.array(self.given), np.array(self.given_t))
        t = np.array(self.t)
        v = np.array(self.values)
        signed = np.empty((7, v.shape[1]))  # rows i - 6 .. i from their centred cubics
        weights = np.empty((7, 4))
        for a, r in enumerate(range(i - 6, i + 1)):
            nodes = [r - 2, r - 1, r + 1, r + 2]
            weights[a] = _lagrange(t[nodes], t[r])
            signed[a] = v[r] - weights[a] @ v[nodes]
        h = signed[-1]
        gain = math.sqrt(1.0 + float(np.sum(weights[-1] ** 2)))
        scale = np.median(np.abs(signed[:4]), axis=0)  # rows i - 6 .. i - 3
        limit = np.maximum(GLITCH_SCALE_FACTOR * scale, GLITCH_FLOOR_N)
        limit = np.maximum(limit, GLITCH_NOISE_FACTOR * noise * gain)
        echoed = np.ones_like(h, dtype=bool)
        for a, node in ((4, 3), (5, 2)):  # rows i - 2 and i - 1: the glitch is node 3, 2
            echoed &= np.abs(signed[a] + weights[a, node] * h) < SIGNATURE_TOLERANCE * np.abs(h)
        glitch = (np.abs(h) > limit) & echoed
        # the curve through its neighbours as such (v - h would lose it to rounding
        # against a glitch of 1e17 N or more)
        curve = weights[-1] @ v[[i - 2, i - 1, i + 1, i + 2]]
        for c in np.flatnonzero(glitch):
            used = max(float(curve[c]), 0.0)
            self.replaced.append((self.first + i, int(c), float(v[i, c]), used))
            self.values[i][c] = used
        if glitch.any():  # the two samples after it departed from its glitch: again
            t_all, v_all = np.array(self.t), np.array(self.values)
            for back in (2, 1):
                r = len(t_all) - back
                w = _lagrange(t_all[r - 4 : r], t_all[r])
                self._departure[-back] = np.abs(v_all[r] - w @ v_all[r - 4 : r])


def stream_glitches(t: FloatArray, values: FloatArray, noise_rows: int) -> TensionGlitches:
    """The glitches :class:`StreamGlitches` finds in the rows ``values`` (n, k) N at
    ``t`` (n,) s pushed one at a time (a recording's own tension columns, judged as
    ``live`` judged them), as a :class:`TensionGlitches`."""
    watch = StreamGlitches(noise_rows)
    for tk, vk in zip(t, values):
        watch.push(float(tk), vk)
    mask = np.zeros(np.shape(values), dtype=bool)
    curve = np.array(values, dtype=float)
    for i, c, _, used in watch.replaced:
        mask[i, c], curve[i, c] = True, used
    return TensionGlitches(mask, curve)
