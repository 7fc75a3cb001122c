"""The window model of the fast backend: feasible set, compiled functions, node evaluator.

:func:`build_window_model` turns a formulation and a horizon into a :class:`WindowModel`:
the node feasible set read from ``constraint_sym`` (:func:`feasible_set`), and the
window, node and output functions evaluated by the compiled core
(:mod:`continuum_mhe.estimators.fast.window_functions`). :class:`NodeEvaluator` evaluates one node
and runs the EKF step of the arrival prior and of the compiled EKF (the core's
``NodeModel``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.arrays import contiguous_f64 as f64
from continuum_mhe.estimators.fast.window_functions import (
    block_columns,
    core_function,
    core_window_functions,
    measurement_model,
    output_function,
    output_jacobian_function,
    transition_is_linear,
    transition_model,
)
from continuum_mhe.estimators.loss import LOSS_CODES, block_array, robust_blocks
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.tape import residual_function, residual_node_tapes, tape_function

IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class Feasible:
    """The feasible set of one node: a box and balls on disjoint coordinate sets.

    Attributes:
        lo, hi: (nx,) box bounds (may be infinite).
        ball_idx: (nb, k) coordinates ``S_b`` of ball ``b``,
            ``sum_{S_b} x_j^2 <= ball_r2[b]`` (one per robot section; ``nb = 0`` if none).
        ball_r2: (nb,) squared radii, rad^2.
    """

    lo: FloatArray
    hi: FloatArray
    ball_idx: IntArray
    ball_r2: FloatArray


def feasible_set(formulation: Formulation) -> Feasible:
    """Read the feasible set from the formulation's bounds and ``constraint_sym``.

    Every component of the path constraint must be a ball ``sum_S x_j^2 <= r^2`` (checked
    on the CasADi expression: Hessian ``2 diag(1_S)``, value and gradient 0 at 0), all of
    one size, on disjoint coordinates without box bounds. Raises ``NotImplementedError``
    with the reason otherwise.
    """
    nx = formulation.nx
    lo, hi = (np.asarray(v, dtype=float) for v in formulation.state_bounds())
    x = ca.SX.sym("x", nx)
    g, glo_v, ghi_v = formulation.constraint_sym(x)
    glo, ghi = np.ravel(np.asarray(glo_v, float)), np.ravel(np.asarray(ghi_v, float))
    if g.numel() == 0:
        return Feasible(lo, hi, np.zeros((0, 1), dtype=np.int64), np.zeros(0))
    if len(glo) != g.numel() or len(ghi) != g.numel():
        raise NotImplementedError("constraint bounds do not match the constraints")
    rng = np.random.default_rng(0)
    balls: list[IntArray] = []
    used = np.zeros(nx, dtype=bool)
    for j in range(g.numel()):
        if glo[j] > 0 or not np.isfinite(ghi[j]):
            raise NotImplementedError("only ball constraints g(x) <= r^2 are supported")
        fn = ca.Function("g", [x], [g[j], ca.gradient(g[j], x), ca.hessian(g[j], x)[0]])
        v0, g0, h0 = (np.asarray(v, dtype=float) for v in fn(np.zeros(nx)))
        idx = np.flatnonzero(np.isclose(np.diag(h0.reshape(nx, nx)), 2.0)).astype(np.int64)
        mask = np.zeros(nx)
        mask[idx] = 1.0
        for xt in rng.normal(size=(5, nx)):
            value = float(np.asarray(fn(xt)[0])[0, 0])
            if not np.isclose(value, float(np.sum(mask * xt**2)), rtol=1e-12, atol=0):
                raise NotImplementedError(f"constraint {j + 1} is not a ball sum_S x_j^2")
        if (
            np.any(v0 != 0)
            or np.any(g0 != 0)
            or np.any(np.isfinite(lo[idx]) | np.isfinite(hi[idx]))
        ):
            raise NotImplementedError("ball coordinates must have no box bounds")
        if np.any(used[idx]) or (balls and len(idx) != len(balls[0])) or len(idx) == 0:
            raise NotImplementedError("balls must be non-empty, disjoint and of one size")
        used[idx] = True
        balls.append(idx)
    return Feasible(lo, hi, np.array(balls, dtype=np.int64), ghi.copy())


class LossKernel(NamedTuple):
    """The measurement loss as the compiled core takes it.

    Attributes:
        blocks: (nblocks, 2) start and size of each measurement block.
        code: :data:`~continuum_mhe.estimators.loss.LOSS_CODES` of the loss.
        scale: loss scale, standard deviations (inf for l2).
        robust: (nblocks,) 1 where the loss acts on the block, 0 where its cost stays
            quadratic (:func:`~continuum_mhe.estimators.loss.robust_blocks`); None:
            every block.
    """

    blocks: IntArray
    code: int
    scale: float
    robust: IntArray | None = None


@dataclass(frozen=True)
class WindowModel:
    """The window model of one (formulation, horizon), evaluated by the compiled core.

    Attributes:
        nx, nu, nz, horizon: sizes.
        feasible: the node feasible set.
        rinv: (nz, nz) inverse measurement covariance (rad^-2 for tilt).
        window: the core's evaluation of
            :func:`~continuum_mhe.estimators.fast.window_functions.window_function`.
        tail: the core's evaluation of
            :func:`~continuum_mhe.estimators.fast.window_functions.tail_function`.
        transition, measurement: the core's evaluations of the two halves of
            :func:`~continuum_mhe.estimators.fast.window_functions.node_function` (its
            transition and its measurement terms: ``transition_model``,
            ``measurement_model``).
        output: the core's evaluation of the formulation's ``output_sym``.
        output_jacobian: the same of its Jacobian (ny, nx), column-major.
        ny: number of outputs; wrapped: indices of the outputs that are wrapped angles.
        loss: the measurement loss (:class:`LossKernel`).
        linear_transition: the transition is affine in the state
            (:func:`~continuum_mhe.estimators.fast.window_functions.transition_is_linear`).
        block_columns: (nblocks,) per block of ``loss.blocks``, the number of leading
            state coordinates its residual depends on at most
            (:func:`~continuum_mhe.estimators.fast.window_functions.block_columns`), and the side
            of its second-order term's square in the window's outputs; None: all.
    """

    nx: int
    nu: int
    nz: int
    horizon: int
    feasible: Feasible
    rinv: FloatArray
    window: _core.ModelFunction  # the whole window's outputs (a WindowFunction)
    transition: _core.ModelFunction  # the node function's (f, F)
    measurement: _core.ModelFunction  # the node function's (H, r)
    output: _core.ModelFunction  # formulation.output_sym: state -> the formulation's outputs
    #: state -> d outputs / d state (ny, nx), column-major
    output_jacobian: _core.ModelFunction
    ny: int = 5
    wrapped: tuple[int, ...] = (4,)
    #: see :class:`NodeFunctions`
    sigma_states: tuple[int, ...] = ()
    loss: LossKernel = LossKernel(np.zeros((0, 2), dtype=np.int64), 0, math.inf)
    linear_transition: bool = False
    #: the measurement terms' second-order part is formed (exact Newton steps); see
    #: :attr:`~continuum_mhe.model.formulations.Formulation.second_order_residuals`
    second_order_residuals: bool = True
    #: the last node and stage of a window shifted by one sample (a TailFunction)
    tail: _core.ModelFunction | None = None
    block_columns: IntArray | None = None
    #: (nx,) what a unit of each state counts for in the SQP's certificate
    #: (:func:`step_scale`); None: ones
    step_scale: FloatArray | None = None

    @property
    def window_size(self) -> int:
        n, nx, nz, nblk = self.horizon, self.nx, self.nz, len(self.loss.blocks)
        cols = np.full(nblk, nx) if self.block_columns is None else self.block_columns
        sr = int(np.sum(cols * cols))
        return nz * n + nz * nx * n + nx * (n - 1) + nx * nx * (n - 1) + sr * n


class NodeFunctions(NamedTuple):
    """One node's functions in the compiled core, without a window (the EKF's):
    the fields of :class:`WindowModel` of the same names."""

    transition: _core.ModelFunction
    measurement: _core.ModelFunction
    output: _core.ModelFunction
    output_jacobian: _core.ModelFunction
    nx: int
    nu: int
    nz: int
    ny: int
    wrapped: tuple[int, ...]
    #: the states the outputs depend on, for the outputs' standard deviations
    #: (:attr:`~continuum_mhe.model.formulations.Formulation.sigma_states`)
    sigma_states: tuple[int, ...]
    #: the masked residual ``(x, u, dt, z, m) -> m r`` (a core function: the consistency
    #: check's fit)
    residual: _core.ModelFunction


@lru_cache(maxsize=32)
def node_functions(formulation: Formulation) -> NodeFunctions:
    """The node's functions of ``formulation`` as the core evaluates them (nothing is
    compiled), built once per formulation: its transition and measurement terms (the
    EKF's node and the consistency check share these objects, and so the measurement
    terms' remembered evaluation), the outputs and their Jacobian, the masked residual."""
    out = output_function(formulation)
    residual_tape = (
        residual_node_tapes(formulation)[1]
        if formulation.forward_mode_jacobian
        else tape_function(residual_function(formulation))
    )
    return NodeFunctions(
        transition=core_function(transition_model(formulation)),
        measurement=core_function(measurement_model(formulation)),
        residual=_core.MaskedResidualFunction(residual_tape),
        output=core_function(out),
        output_jacobian=core_function(
            _core.ForwardJacobianFunction(tape_function(out))
            if formulation.forward_mode_jacobian
            else output_jacobian_function(formulation)
        ),
        nx=formulation.nx,
        nu=formulation.nu,
        nz=formulation.nz,
        ny=int(out.nnz_out(0)),
        wrapped=tuple(i for i, o in enumerate(formulation.outputs) if getattr(o, "wrapped", False)),
        sigma_states=formulation.sigma_states,
    )


class NodeEvaluator:
    """One node of the window model in the compiled core (its ``NodeModel``): the node
    function, the EKF and arrival-prior steps, the outputs (one per estimator)."""

    def __init__(self, model: WindowModel | NodeFunctions) -> None:
        #: the core's NodeModel
        self.core = self._core = _core.NodeModel(
            model.transition, model.measurement, model.output, model.output_jacobian,
            model.nx, model.nu, model.nz, model.ny, list(model.wrapped),
            list(model.sigma_states),
        )  # fmt: skip
        self._zeros, self._ones = np.zeros(model.nz), np.ones(model.nz)

    def evaluate(
        self,
        x: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray | None = None,
        mask: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(f(x, u, dt), df/dx, -dr(z, x)/dx, r(z, x))``: (nx,), (nx, nx), (nz, nx),
        (nz,). ``z`` matters for the last two only (zeros when omitted); ``mask`` (nz,)
        zeroes the components of sensors that dropped out."""
        z = self._zeros if z is None else z
        mask = self._ones if mask is None else mask
        return self._core.evaluate(f64(x), f64(u), float(dt), f64(z), f64(mask))

    def arrival_step(
        self,
        x: FloatArray,
        P: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray,
        mask: FloatArray,
        R: FloatArray,
        Q: FloatArray,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """One EKF step of the arrival prior: update with ``z`` (its valid components,
        ``mask``; none: prediction only), predict with ``(u, dt)``. Returns
        ``(x+, P+, P+^-1)``, ``P+`` symmetrised."""
        return self._core.arrival_step(
            f64(x), f64(P), f64(u), float(dt), f64(z), f64(mask), f64(R), f64(Q)
        )

    def ekf_step_outputs(
        self,
        x: FloatArray,
        P: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray,
        mask: FloatArray,
        R: FloatArray,
        Q: FloatArray,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """One EKF step (predict with ``(u, dt)``, then update with the valid components
        of ``z``, ``mask``; the equations of
        :func:`~continuum_mhe.estimators.kalman.ekf_predict` and ``ekf_update``), then
        :meth:`output` and :meth:`output_std` of its answer, in one call into the core:
        ``(x+, P+, outputs, output standard deviations)``."""
        return self._core.ekf_step_outputs(
            f64(x), f64(P), f64(u), float(dt), f64(z), f64(mask), f64(R), f64(Q)
        )

    @property
    def step_seconds(self) -> float:
        """Wall time of the last :meth:`ekf_step_outputs` call's arithmetic in the core
        (the step, the outputs and their standard deviations), s."""
        return float(self._core.step_seconds)

    def output_std(self, x: FloatArray, P: FloatArray) -> FloatArray:
        """One standard deviation of every output for a state with mean ``x`` and
        covariance ``P``: the same as :meth:`Formulation.output_std`."""
        return self._core.output_std(f64(x), f64(P))

    def output(self, x: FloatArray) -> FloatArray:
        """The outputs of state ``x`` (``output_sym``; wrapped angles in ``[-pi, pi)``
        as :meth:`Formulation.output` does)."""
        return self._core.output(f64(x))


#: The time (s) over which a rate's error counts in the SQP's certificate: a rate 1e-8
#: rad/s off moves its angle 1e-9 rad over it (:func:`step_scale`).
RATE_CERTIFICATE_SECONDS = 0.1


def step_scale(formulation: Formulation) -> FloatArray:
    """Per state, what a unit of it counts for in the max-norm of the fast SQP's
    certificate (its QP steps and error bound, ``FastOptions.step_tol`` and
    ``err_tol``): 1 for a state in its own units (an angle, rad; a gyro bias), and for a
    state named ``NAME_dot`` (``NAME_ddot``) beside a state ``NAME``, its time
    derivative, :data:`RATE_CERTIFICATE_SECONDS` (squared): the angle its error moves
    over that time. A window's rates follow its angles through the process model, so
    their error is about the angles' divided by the sample period; in state units the
    certificate would hold the angles to a sample period's fraction of ``err_tol``."""
    names = formulation.state_names
    known = set(names)
    scale = np.ones(len(names))
    for i, name in enumerate(names):
        for suffix, order in (("_ddot", 2), ("_dot", 1)):
            if name.endswith(suffix) and name[: -len(suffix)] in known:
                scale[i] = RATE_CERTIFICATE_SECONDS**order
                break
    return scale


@lru_cache(maxsize=32)
def build_window_model(
    formulation: Formulation,
    horizon: int,
    loss: str = "l2",
    scale: float = math.inf,
) -> WindowModel:
    """Build the window model (the formulation's functions, evaluated by the compiled
    core; nothing is compiled). Cached per arguments.

    ``loss`` and ``scale`` (standard deviations) choose the measurement loss
    (:mod:`continuum_mhe.estimators.loss`); the model functions do not depend on them.
    Raises ``NotImplementedError`` (with the reason) if the feasible set is not a box
    and disjoint balls, or the measurement covariance is not block-diagonal.
    """
    feasible = feasible_set(formulation)
    rinv = np.asarray(np.linalg.inv(formulation.meas_cov()), dtype=np.float64)
    blocks = block_array(formulation.measurement_blocks)
    inside = np.zeros_like(rinv, dtype=bool)
    for start, size in blocks:
        inside[start : start + size, start : start + size] = True
    if np.any(rinv[~inside] != 0.0):
        raise NotImplementedError("the measurement covariance is not block-diagonal")
    window, tail = core_window_functions(formulation, horizon)
    node = node_functions(formulation)
    return WindowModel(
        nx=formulation.nx,
        nu=formulation.nu,
        nz=formulation.nz,
        horizon=horizon,
        feasible=feasible,
        rinv=rinv,
        window=window,
        tail=tail,
        transition=node.transition,
        measurement=node.measurement,
        output=node.output,
        output_jacobian=node.output_jacobian,
        ny=node.ny,
        wrapped=node.wrapped,
        sigma_states=node.sigma_states,
        loss=LossKernel(
            blocks, LOSS_CODES[loss], float(scale), robust_blocks(formulation.measurement_blocks)
        ),
        linear_transition=transition_is_linear(formulation),
        second_order_residuals=formulation.second_order_residuals,
        block_columns=block_columns(formulation, blocks),
        step_scale=step_scale(formulation),
    )
