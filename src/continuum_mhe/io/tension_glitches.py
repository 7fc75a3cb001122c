"""Single-row glitches of the given tensions: a tension that one row alone gets wrong
(a load cell's or a serial link's error), found and replaced by the cubic through its
neighbouring rows (:func:`tension_glitches`).

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
* and the departures of rows ``i - 2`` to ``i + 2`` from their own cubics are the
  glitch's echo in them (``-w h``, ``h`` the glitch and ``w`` its weight in their
  cubics: at even times 2/3 one row away, -1/6 two rows away) within
  :data:`SIGNATURE_TOLERANCE` of ``h``: a step of the tensions (a controller's), a
  kink (a slack tendon that starts to pull) or a fast motion leaves another pattern.

Where more than :data:`MAX_GLITCH_SHARE` of the rows would be glitches, none is: such
departures are the sensor's way (a quantised or noisy load cell), which the smoothing
of :mod:`.tension_derivatives` takes. The first and last four rows are not judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray

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


def tension_glitches(t: FloatArray, values: FloatArray, noise: float) -> TensionGlitches:
    """The single-row glitches of the tensions ``values`` (n, k) N at ``t`` (n,) s,
    strictly increasing, whose row-to-row noise is ``noise`` N (module docstring)."""
    values = np.asarray(values, dtype=float)
    n, k = values.shape
    mask = np.zeros((n, k), dtype=bool)
    curve = values.copy()
    if n < 9:
        return TensionGlitches(mask, curve)
    rows = np.arange(2, n - 2)
    nodes = np.stack([rows - 2, rows - 1, rows + 1, rows + 2])  # (4, m)
    tn, tr = t[nodes], t[rows]
    weights = np.ones(nodes.shape)
    for j in range(4):
        for other in range(4):
            if other != j:
                weights[j] *= (tr - tn[other]) / (tn[j] - tn[other])
    # a white noise of std ``noise`` departs from the cubic with std noise * gain
    gain = np.sqrt(1.0 + np.sum(weights**2, axis=0))  # (m,)
    m = len(rows)
    judged = np.arange(2, m - 2)  # indices into rows whose echoes two rows away are judged
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
        h = signed[judged]
        echoed = np.ones(len(judged), dtype=bool)
        # (offset, the glitch's node index in that row's cubic: nodes i-2, i-1, i+1, i+2)
        for off, node in ((-2, 3), (-1, 2), (1, 1), (2, 0)):
            echo = signed[judged + off] + weights[node, judged + off] * h
            echoed &= np.abs(echo) < SIGNATURE_TOLERANCE * np.abs(h)
        mask[rows[judged], c] = (departure[judged] > limit[judged]) & echoed
    if mask.any(axis=1).sum() > max(1, math.floor(MAX_GLITCH_SHARE * n)):
        mask[:] = False
    return TensionGlitches(mask, curve)
