"""The fast backend's model: CasADi functions from the formulation, evaluated by the core.

Nothing of the model is written a second time: :func:`window_function`,
:func:`node_pieces` and :func:`node_function` are built from the formulation's symbolic
methods (``measurement_residual_sym``, ``transition_sym``, ``output_sym``). The compiled
core evaluates them from their instruction lists (:mod:`~continuum_mhe.model.tape`),
so a new robot or option set compiles nothing. The core's objects
(:class:`~continuum_mhe._core.ModelFunction`) take flat column-major inputs and write
all outputs concatenated.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.estimators.loss import block_array
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.tape import residual_function, residual_node_tapes, tape_function


def transition_is_linear(formulation: Formulation) -> bool:
    """True if the formulation's transition is affine in the state (its Jacobian
    ``df/dx`` does not depend on ``x``): then the window's exact Hessian is the
    measurement terms' Newton Hessian the fast backend forms, and Newton's quadratic rate
    applies (:func:`~continuum_mhe.estimators.fast.sqp.quadratic_rate`)."""
    f = formulation
    x, u, dt = ca.SX.sym("x", f.nx), ca.SX.sym("u", f.nu), ca.SX.sym("dt")
    return not ca.depends_on(ca.jacobian(f.transition_sym(x, u, dt), x), x)


def node_pieces(formulation: Formulation) -> tuple[ca.Function, ca.Function]:
    """``meas: (x, z, m) -> (r, JR, SR)`` and ``proc: (x, xn, u, dt) -> (W, FJ)``: one
    node's and one stage's part of :func:`window_function` (the layout described
    there); given to both :func:`window_function` and :func:`tail_function`, they
    compute each node with the same code."""
    f, nx, nz = formulation, formulation.nx, formulation.nz
    x, z, mk = ca.SX.sym("x", nx), ca.SX.sym("z", nz), ca.SX.sym("m", nz)
    r = mk * f.measurement_residual_sym(z, x)
    jr = ca.jacobian(r, x)
    rinv = np.linalg.inv(f.meas_cov())
    cols = block_columns(f, block_array(f.measurement_blocks))
    # second-order part of each block's Hessian, sum_a (R_b^-1 r_b)_a d2 r_a/dx2: the
    # Jacobian of J_b^T lam at lam = R_b^-1 r_b, which differentiates the Jacobian's own
    # expressions once more (half the instructions of the Hessian of the block's cost
    # less J_b^T R_b^-1 J_b, and no cancellation); its leading c x c block alone, the
    # rest being zero (c: the block's column count, block_columns)
    curv = []
    for b, c in zip(f.measurement_blocks, cols):
        if not f.second_order_residuals:  # Gauss-Newton: the term is zero
            curv.append(ca.SX.zeros(c * c))
            continue
        rb, jb, wb = r[b.slice], jr[b.slice, :], ca.DM(rinv[b.slice, b.slice])
        lam = ca.SX.sym("lam", rb.numel())
        hess = ca.jacobian(jb.T @ lam, x)[: int(c), : int(c)]
        curv.append(ca.vec(ca.substitute(hess, lam, wb @ rb)))
    meas = ca.Function("mhe_meas", [x, z, mk], [r, ca.vec(jr.T), ca.vertcat(*curv)])
    return meas, process_piece(f)


def block_columns(formulation: Formulation, blocks: NDArray[np.int64]) -> NDArray[np.int64]:
    """Per measurement block (``blocks``, (nblocks, 2) start and size): the number of
    leading state coordinates its residual depends on at most, from the residual's
    Jacobian sparsity (no derivative is formed). Its Jacobian rows are zero beyond them,
    and so its second-order term outside that leading square: the window's ``SR`` holds
    that square alone, and the core's assembly runs over it (``WindowSolver``'s
    ``block_cols``)."""
    f = formulation
    x, z = ca.SX.sym("x", f.nx), ca.SX.sym("z", f.nz)
    sp = ca.jacobian_sparsity(f.measurement_residual_sym(z, x), x)
    rows, cols = np.array(sp.get_triplet(), dtype=np.int64).reshape(2, -1)
    out = np.zeros(len(blocks), dtype=np.int64)
    for b, (start, size) in enumerate(blocks):
        inside = (rows >= start) & (rows < start + size)
        out[b] = cols[inside].max() + 1 if np.any(inside) else 0
    return out


def process_piece(formulation: Formulation) -> ca.Function:
    """``proc: (x, xn, u, dt) -> (W, FJ)``: one stage's part of :func:`window_function`."""
    f, nx = formulation, formulation.nx
    x, xn = ca.SX.sym("x", nx), ca.SX.sym("xn", nx)
    u, dt = ca.SX.sym("u", f.nu), ca.SX.sym("dt")
    xf = f.transition_sym(x, u, dt)
    return ca.Function("mhe_proc", [x, xn, u, dt], [xn - xf, ca.vec(ca.jacobian(xf, x).T)])


NodePieces = tuple[ca.Function, ca.Function]


def window_function(
    formulation: Formulation, horizon: int, pieces: NodePieces | None = None
) -> ca.Function:
    """``(X, Z, M, U, DT) -> (R, JR, W, FJ, SR)`` for the whole window, in one call.

    Inputs (CasADi column-major): ``X`` (nx, N), ``Z`` (nz, N), ``M`` (nz, N) the 0/1
    measurement mask (a masked component has zero residual, Jacobian and curvature: a
    sensor that dropped out), ``U`` (nu, N-1), ``DT`` (1, N-1). Outputs: masked
    measurement residuals ``R`` (nz, N); their Jacobians
    ``JR`` (nz nx, N), each column the row-major ``dr/dx``; process residuals
    ``W = x_{i+1} - f(x_i, u_i, dt_i)`` (nx, N-1); ``FJ`` (nx^2, N-1), each column
    the row-major ``df/dx_i``; ``SR`` (sum_b c_b^2, N), the second-order part of each
    measurement block's quadratic cost Hessian ``sum_a (R_b^-1 r_b)_a d2r_a/dx2`` per
    node (one per block, so that a robust loss can weight each block; ``R`` is
    block-diagonal), each block's leading ``c_b x c_b`` (c_b: its
    :func:`block_columns`; the rest is zero). ``pieces``: :func:`node_pieces` (built
    here if None).
    """
    f, nx, nu, nz, n = formulation, formulation.nx, formulation.nu, formulation.nz, horizon
    meas, proc = pieces or node_pieces(f)
    # MX, so that the maps stay loops in the generated code (SX would unroll them)
    X, Z, M = ca.MX.sym("X", nx, n), ca.MX.sym("Z", nz, n), ca.MX.sym("M", nz, n)
    U, DT = ca.MX.sym("U", nu, n - 1), ca.MX.sym("DT", 1, n - 1)
    R, JR, SR = meas.map(n, "serial")(X, Z, M)
    W, FJ = proc.map(n - 1, "serial")(X[:, : n - 1], X[:, 1:], U, DT)
    outs = [ca.densify(v) for v in (R, JR, W, FJ, SR)]
    return ca.Function("mhe_window", [X, Z, M, U, DT], outs)


def tail_function(formulation: Formulation, pieces: NodePieces | None = None) -> ca.Function:
    """``(x_prev, x, z, m, u, dt) -> (r, JR, W, FJ, SR)``: :func:`window_function`'s
    outputs of one last node ``x`` and of the stage into it from ``x_prev`` (the same
    layout, one column each): what a window shifted by one sample lacks. ``pieces``:
    :func:`node_pieces`, the same as the window function's (built here if None)."""
    f, nx, nu, nz = formulation, formulation.nx, formulation.nu, formulation.nz
    meas, proc = pieces or node_pieces(f)
    xp, x, z = ca.MX.sym("xp", nx), ca.MX.sym("x", nx), ca.MX.sym("z", nz)
    mk, u, dt = ca.MX.sym("m", nz), ca.MX.sym("u", nu), ca.MX.sym("dt")
    r, jr, sr = meas(x, z, mk)
    w, fj = proc(xp, x, u, dt)
    outs = [ca.densify(v) for v in (r, jr, w, fj, sr)]
    return ca.Function("mhe_tail", [xp, x, z, mk, u, dt], outs)


def _node_inputs(formulation: Formulation) -> list[ca.SX]:
    """The node functions' inputs ``[x, u, dt, z, m]`` as symbols."""
    f = formulation
    return [ca.SX.sym(name, size) for name, size in
            (("x", f.nx), ("u", f.nu), ("dt", 1), ("z", f.nz), ("m", f.nz))]  # fmt: skip


def node_function(formulation: Formulation, jacobian: bool = True) -> ca.Function:
    """``(x, u, dt, z, m) -> (f, F, H, r)``: transition, its Jacobian, the measurement
    Jacobian ``H = -dr(z, x)/dx`` (row-major), as the EKF uses it, and ``r(z, x)``, with
    the masked components (``m = 0``) zero. ``jacobian`` False: ``H`` zero (the core
    takes it by forward mode: :func:`measurement_model`)."""
    f, nx = formulation, formulation.nx
    x, u, dt, z, mk = inputs = _node_inputs(f)
    xf, r = f.transition_sym(x, u, dt), mk * f.measurement_residual_sym(z, x)
    H = ca.vec(-ca.jacobian(r, x).T) if jacobian else ca.SX.zeros(f.nz * nx)
    outs = [xf, ca.vec(ca.jacobian(xf, x).T), H, r]
    return ca.Function("mhe_node", inputs, [ca.densify(v) for v in outs])


def transition_model(formulation: Formulation) -> _core.TapeFunction:
    """The transition ``(f, F)`` of :func:`node_function` alone, a function of its inputs
    ``(x, u, dt, z, m)`` as the core evaluates it (a prediction evaluates no measurement
    terms); the same expressions, so the same values as the node function's. Built anew
    at each call: :func:`~continuum_mhe.estimators.fast.model.node_functions` keeps the
    formulation's one."""
    x, u, dt, _, _ = inputs = _node_inputs(formulation)
    xf = formulation.transition_sym(x, u, dt)
    F = ca.vec(ca.jacobian(xf, x).T)
    return tape_function(
        ca.Function("mhe_transition_node", inputs, [ca.densify(xf), ca.densify(F)])
    )


def measurement_model(formulation: Formulation) -> _core.RememberedFunction:
    """The measurement terms ``(H, r)`` of :func:`node_function` alone, a function of its
    inputs ``(x, u, dt, z, m)`` as the core evaluates it, shared by the EKF's node and
    the consistency check (:mod:`continuum_mhe.estimators.consistency`) through
    :func:`~continuum_mhe.estimators.fast.model.node_functions`, which keeps the
    formulation's one: their instructions, or, with
    :attr:`~continuum_mhe.model.formulations.Formulation.forward_mode_jacobian`, the
    residual's instructions with ``H`` by forward mode (``csrc/forward.hpp``). Its last
    two evaluations are remembered (per thread): the EKF's update and the check's
    prediction evaluate it at the same state (where every reading is valid), once, also
    where two EKFs of the model step side by side (a tendon robot's load hypotheses)."""
    f, nx = formulation, formulation.nx
    if f.forward_mode_jacobian:
        inner: _core.ModelFunction = _core.ResidualNodeFunction(
            *residual_node_tapes(f), with_transition=False
        )
    else:
        x, _, _, z, mk = inputs = _node_inputs(f)
        r = mk * f.measurement_residual_sym(z, x)
        outs = [ca.densify(ca.vec(-ca.jacobian(r, x).T)), ca.densify(r)]
        inner = tape_function(ca.Function("mhe_measurement_node", inputs, outs))
    return _core.RememberedFunction(inner, [nx, f.nu, 1, f.nz, f.nz])


def output_function(formulation: Formulation) -> ca.Function:
    """``x -> y``: the formulation's outputs (``output_sym``), dense."""
    x = ca.SX.sym("x", formulation.nx)
    return ca.Function("mhe_output", [x], [ca.densify(formulation.output_sym(x))])


def output_jacobian_function(formulation: Formulation) -> ca.Function:
    """``x -> dy/dx`` (ny, nx), dense: the formulation's ``output_jacobian``."""
    x = ca.SX.sym("x", formulation.nx)
    return ca.Function("mhe_output_jacobian", [x], [ca.densify(formulation.output_jacobian(x))])


class BackendFallbackWarning(UserWarning):
    """The requested MHE backend is not what runs (said once)."""


def core_function(fn: ca.Function | _core.ModelFunction) -> _core.ModelFunction:
    """The core's evaluation of ``fn``: a CasADi SX function read as a tape, or a core
    model function as it is."""
    return fn if isinstance(fn, _core.ModelFunction) else tape_function(fn)


def core_window_functions(
    formulation: Formulation, horizon: int
) -> tuple[_core.ModelFunction, _core.ModelFunction]:
    """``(window, tail)``: :func:`window_function` and :func:`tail_function` of
    ``formulation`` evaluated by the core from one node's two pieces. With
    :attr:`~continuum_mhe.model.formulations.Formulation.forward_mode_jacobian`, the
    measurement piece is the residual's instructions alone: the core propagates its
    Jacobian with the values (``csrc/forward.hpp``) and the second-order term is zero
    (the formulation's ``second_order_residuals`` is False: Gauss-Newton steps)."""
    if formulation.forward_mode_jacobian:
        if formulation.second_order_residuals:
            raise NotImplementedError("forward-mode Jacobians give no second-order term")
        residual = tape_function(residual_function(formulation))
        proc = tape_function(process_piece(formulation))
        cols = block_columns(formulation, block_array(formulation.measurement_blocks))
        sr = int(np.sum(cols * cols))  # the zero second-order term's entries per node
        window = _core.WindowFunction(residual, sr, proc, horizon)
        return window, _core.TailFunction(residual, sr, proc)
    meas, proc = (tape_function(p) for p in node_pieces(formulation))
    return _core.WindowFunction(meas, proc, horizon), _core.TailFunction(meas, proc)
