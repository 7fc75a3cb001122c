"""Robust measurement losses of the MHE, written once for both backends.

A loss acts on one measurement block (one IMU) at one node through the block's squared
whitened residual norm ``s = r_b^T R_b^-1 r_b`` (dimensionless; ``sqrt(s)`` is in
standard deviations of the measurement noise). The block's cost is ``1/2 rho(s)``:

* ``l2``:     ``rho(s) = s``;
* ``huber``:  ``rho(s) = s`` for ``s <= c^2``, else ``2 c sqrt(s) - c^2``;
* ``cauchy``: ``rho(s) = c^2 log(1 + s / c^2)``;
* ``welsch``: ``rho(s) = c^2 (1 - exp(-s / c^2))`` (redescending: the cost of a block
  is bounded by ``c^2 / 2``, so no number of far-off readings outweighs the model);

with ``c`` the loss scale (``MHESettings.scale``). Each is ``s`` to first order at 0,
so a block well inside the scale counts as in the quadratic cost. ``rho'(s)`` is the
block's weight in iteratively reweighted least squares (1 for an inlier, about
``c / sqrt(s)`` for Huber, ``c^2 / s`` for Cauchy and ``exp(-s / c^2)`` for Welsch far
out).

A loss acts on the blocks of sensors' readings (IMUs) alone: a model's
pseudo-measurement (a tendon robot's tip condition, a constraint the shape must keep)
and the tendon tensions given with each sample keep the quadratic cost whatever the
loss (:func:`robust_blocks`).

:func:`rho_sym` is the CasADi expression (IPOPT's cost), the compiled core's
``rho_derivatives(code, scale, s)`` its value and derivatives at one point (the window
solve's), :func:`block_weights` the weights of one node's blocks for a residual vector.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.model.descriptions import MeasurementBlock

#: Integer codes of the losses in the compiled core.
LOSS_CODES: dict[str, int] = {"l2": 0, "huber": 1, "cauchy": 2, "welsch": 3}

#: A block is flagged as an outlier when its weight ``rho'(s)`` falls below this:
#: it counts less than a quarter of a quadratic-cost sample (Huber: residual norm
#: beyond 4 c; Cauchy: beyond sqrt(3) c; Welsch: beyond sqrt(ln 4) c = 1.18 c).
OUTLIER_WEIGHT = 0.25


def rho_sym(loss: str, scale: float, s: ca.SX) -> ca.SX:
    """``rho(s)`` as a CasADi expression (``s`` the squared whitened block norm)."""
    if loss == "l2":
        return s
    c2 = scale * scale
    if loss == "huber":
        # fmax keeps the unused branch's derivative finite at s = 0
        return ca.if_else(s <= c2, s, 2.0 * scale * ca.sqrt(ca.fmax(s, c2)) - c2)
    if loss == "cauchy":
        return c2 * ca.log1p(s / c2)
    if loss == "welsch":
        return c2 * (1.0 - ca.exp(-s / c2))
    raise ValueError(f"unknown loss {loss!r}")


def block_array(blocks: tuple[MeasurementBlock, ...]) -> NDArray[np.int64]:
    """``(nblocks, 2)``: start and size of each measurement block (for the kernels)."""
    return np.array([(b.start, b.size) for b in blocks], dtype=np.int64).reshape(-1, 2)


def robust_blocks(blocks: tuple[MeasurementBlock, ...]) -> NDArray[np.int64]:
    """``(nblocks,)``: 1 where a robust loss acts on the block (an IMU's readings), 0
    where the block keeps the quadratic cost (a model's pseudo-measurement, the given
    tensions): a robust loss that down-weights a tip condition lets the shape leave
    its equilibrium."""
    return np.array([1 if b.is_imu else 0 for b in blocks], dtype=np.int64)


def block_weights(
    loss: str,
    scale: float,
    r: FloatArray,
    rinv: FloatArray,
    blocks: NDArray[np.int64],
    robust: NDArray[np.int64] | None = None,
) -> FloatArray:
    """``rho'(s_b)`` per block (nblocks,) for one node's residual ``r`` (nz,); 1 for a
    block whose ``robust`` entry is 0 (None: every block robust)."""
    out = _block_weights(LOSS_CODES[loss], scale, np.asarray(r, dtype=np.float64), rinv, blocks)
    if robust is not None:
        out[np.asarray(robust) == 0] = 1.0
    return out


def _block_weights(
    code: int, scale: float, r: FloatArray, rinv: FloatArray, blocks: NDArray[np.int64]
) -> FloatArray:
    out = np.ones(blocks.shape[0])
    for k in range(blocks.shape[0]):
        b0, nb = blocks[k, 0], blocks[k, 1]
        s = 0.0  # r_b^T R_b^-1 r_b, term by term
        for a in range(nb):
            for c in range(nb):
                s += r[b0 + a] * rinv[b0 + a, b0 + c] * r[b0 + c]
        out[k] = _core.rho_derivatives(code, scale, s)[1]
    return out
