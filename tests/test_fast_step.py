"""The fast MHE's pieces in the compiled core against independent computations on
identical inputs: the compiled step alone (the benchmark's kernel row) against the
estimator, the EKF step against its composition from the node model, the shifted
window outputs and assembly against the whole ones."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_allclose

import continuum_mhe._core as _core
from continuum_mhe.benchmark.kernels import run_ekf_kernel, run_mhe_kernel
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import NodeEvaluator
from continuum_mhe.estimators.mhe import MovingHorizonEstimator, MovingHorizonInference
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings, NoiseSettings
from continuum_mhe.simulation.scenarios import simulate, simulate_robot

TWO = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))


def test_mhe_kernel_gives_the_fast_mhe_answers() -> None:
    """The bare kernel the benchmark times is the fast MHE (dropouts too), every window
    certified."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=3.0, seed=4)
    z = rec.z.copy()
    z[12:18] = np.nan
    rec = replace(rec, z=z)
    out, sec, uncertified = run_mhe_kernel(f, rec, 10)
    ref = MovingHorizonEstimator(f, MHESettings(horizon=10)).run(rec.t, z)
    assert uncertified == 0
    assert_allclose(out, ref.output, rtol=0, atol=1e-12)
    assert np.all(sec > 0)


def test_the_kernel_row_reads_the_compiled_steps_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """The benchmark's kernel row is the compiled step's time (``step_seconds``), not the
    window solve's: the row reads it sample by sample, and on every sample with a full
    window it exceeds the solve's, which it contains (the prior's slide, the covariance
    and the outputs come on top)."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=4)
    est = MovingHorizonEstimator(f, MHESettings(horizon=10))
    est.reset()
    for i, (t, z) in enumerate(zip(rec.t, rec.z)):
        est.step(Measurement(float(t), z))
        if i >= 10:
            assert est.inference.step_seconds > est.inference.solve_seconds > 0
    monkeypatch.setattr(MovingHorizonInference, "step_seconds", property(lambda self: 0.125))
    _, sec, _ = run_mhe_kernel(f, rec, 10)
    assert np.all(sec == 0.125)


def test_the_ekf_kernel_row_is_timed_inside_the_core_as_the_mhes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The EKF's kernel row reads the core's time of each step (as the MHE's row does),
    and that time is a positive wall time of that step alone."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=4)
    _, sec = run_ekf_kernel(f, rec)
    assert np.all(sec[1:] > 0) and sec[0] == 0  # the first sample is the EKF's start
    monkeypatch.setattr(NodeEvaluator, "step_seconds", property(lambda self: 0.25))
    _, sec = run_ekf_kernel(f, rec)
    assert np.all(sec[1:] == 0.25)


@pytest.mark.parametrize("robot", [None, TWO], ids=["one-section", "two-sections"])
def test_fused_ekf_step_equals_the_step_then_the_outputs(robot) -> None:
    """:meth:`NodeEvaluator.ekf_step_outputs` (the compiled EKF's one call per sample)
    gives the state and covariance of the EKF step composed here from the node model
    (prediction, then :func:`arrival_update` on the masked residual) and the outputs and
    standard deviations of :meth:`output` and :meth:`output_std` on that state, on
    samples with every sensor, one sensor masked and none; and the EKF estimator
    reports them."""
    from continuum_mhe._core import ekf_update as arrival_update
    from continuum_mhe.estimators.fast import NodeEvaluator, build_window_model
    from continuum_mhe.estimators.kalman import ExtendedKalmanFilter, ProcessNoiseCache

    # no constant reading error nor model error: the reported std is the covariance's,
    # times one factor
    noise = NoiseSettings(reading_bias_std=0.0, model_error_std=0.0)
    f = make_formulation("bend", robot, noise) if robot else make_formulation("bend", noise=noise)
    node = NodeEvaluator(build_window_model(f, 2))
    process_noise = ProcessNoiseCache(f)
    rng = np.random.default_rng(2)
    x = np.asarray(f.initial_state(np.full(f.nz, 0.3)), float) + rng.normal(scale=0.1, size=f.nx)
    P = f.initial_cov()
    masks = [np.ones(f.nz), np.r_[np.zeros(2), np.ones(f.nz - 2)], np.zeros(f.nz)]
    for mask in masks * 2:
        z = rng.normal(scale=0.4, size=f.nz)
        u, dt = np.zeros(f.nu), 0.05
        Q = process_noise(dt)[0]
        zm = np.where(mask > 0, z, 0.0)
        x1, F, _, _ = node.evaluate(x, u, dt, zm, mask)
        P1 = F @ P @ F.T + Q
        if mask.any():
            _, _, H, r = node.evaluate(x1, u, dt, zm, mask)
            x1, P1 = arrival_update(x1, P1, r, H, f.meas_cov())
        x2, P2, y, std = node.ekf_step_outputs(x, P, u, dt, z, mask, f.meas_cov(), Q)
        assert_allclose(x2, x1, rtol=1e-14, atol=1e-15)
        assert_allclose(P2, P1, rtol=1e-14, atol=1e-18)
        assert_allclose(y, node.output(x1), rtol=1e-14, atol=1e-15)
        assert_allclose(std, node.output_std(x1, P1), rtol=1e-12, atol=1e-15)
        assert std.min() > 0  # a real spread, not zeros (P stays positive definite)
        x, P = x2, P2
    rec = simulate_robot("s-curve", robot, duration=0.5, seed=4) if robot else simulate(
        "paper3d", duration=0.5, seed=4)  # fmt: skip
    ekf = ExtendedKalmanFilter(f)
    ekf.reset()
    for i in range(len(rec.t)):
        e = ekf.step(Measurement(float(rec.t[i]), rec.z[i]))
        assert e.state is not None and e.covariance is not None and e.output_std is not None
        assert_allclose(e.output, node.output(e.state), rtol=1e-13, atol=1e-15)
        # the estimator widens every standard deviation by one factor >= 1, the model
        # error its consistency check estimates (1 while the readings fit their noise)
        ratio = e.output_std / node.output_std(e.state, e.covariance)
        assert ratio.min() >= 1.0 - 1e-12
        assert_allclose(ratio, ratio[0], rtol=1e-12)


@pytest.mark.parametrize("in_place", [False, True])
def test_shifted_outputs_equal_the_window_model_at_the_shifted_iterate(in_place) -> None:
    """``shift_outputs`` (the previous window's model outputs moved by one node, the
    tail function for the new node and stage) gives what the window function gives at
    the shifted iterate, dropouts and two sections included: the carried nodes' bits,
    and the new node's to the last bit or, where the batch takes sin and cos from the
    vector library, to its rounding."""
    from continuum_mhe.estimators.fast import build_window_model
    from continuum_mhe.estimators.fast.sqp import Workspace

    f = make_formulation("bend", TWO)
    n, nx, nz = 7, f.nx, f.nz
    model = build_window_model(f, n)
    ws = Workspace(model)
    rng = np.random.default_rng(5)
    X = rng.normal(scale=0.5, size=(n + 1, nx))
    z = rng.normal(scale=0.3, size=(n + 1, nz))
    m = (rng.random((n + 1, nz)) > 0.2).astype(float)
    u = rng.normal(size=(n, f.nu))
    dt = rng.uniform(0.01, 0.1, size=n)

    def window(lo: int, b: int) -> np.ndarray:
        ws.Xb[b], ws.z[:], ws.m[:] = X[lo : lo + n], z[lo : lo + n] * m[lo : lo + n], m[lo : lo + n]
        ws.u[:], ws.dt[:] = u[lo : lo + n - 1], dt[lo : lo + n - 1]
        model.window.evaluate(
            [ws.Xb[b].ravel(), ws.z.ravel(), ws.m.ravel(), ws.u.ravel(), ws.dt], ws.out[b]
        )
        return ws.out[b].copy()

    src = 0 if in_place else 1
    window(0, src)
    fresh = window(1, 0 if not in_place else 1)  # buffer 0 now holds the shifted iterate
    ws.Xb[0] = X[1:]
    assert ws.core.shift_outputs(src, 0)
    # the outputs' parts (R, JR, W, FJ, SR), one column per node or stage: the last
    # column of each is the new node's or stage's, from the tail function
    per = [nz, nz * nx, nx, nx * nx]
    per.append((fresh.size - n * (per[0] + per[1]) - (n - 1) * (per[2] + per[3])) // n)
    new = np.zeros(fresh.size, dtype=bool)
    start = 0
    for size, columns in zip(per, (n, n, n - 1, n - 1, n)):
        start += size * columns
        new[start - size : start] = True
    np.testing.assert_array_equal(ws.out[0][~new], fresh[~new])  # carried: the same bits
    if _core.uses_vector_sin_cos():
        # the tail function's sin and cos are the C library's, the batched window's the
        # vector library's: a few ulp apart (test_core_tape)
        scale = max(1.0, float(np.abs(fresh).max()))
        assert_allclose(ws.out[0][new], fresh[new], rtol=0, atol=1e-12 * scale)
    else:
        assert_allclose(ws.out[0][new], fresh[new], rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize(
    ("robot", "loss", "linear", "in_place", "arrival_at", "n"),
    [
        (None, "l2", True, True, 0, 7),
        (None, "cauchy", False, False, 0, 7),
        (TWO, "huber", True, False, 0, 7),
        (TWO, "l2", False, True, 0, 7),
        (None, "l2", True, False, 0, 3),  # the smallest window that shifts
        (None, "l2", True, False, 1, 7),  # a window not yet full: the whole assembly runs
    ],
)
def test_shifted_assembly_equals_the_full_one(robot, loss, linear, in_place, arrival_at, n) -> None:
    """The shifted assembly (``WindowSolver.assemble`` with ``shifted_from``: the previous window's
    assembly moved by one node, node
    0, the last stage and the last node formed) gives the same bits as the whole
    assembly at the shifted iterate: blocks, gradient, robust weights, node costs and
    cost, dropouts (on a carried node, the carried last node and the new one), robust
    losses, two sections and stage products carried or formed included; and the
    carried nodes are carried (their model outputs are not read again)."""
    from continuum_mhe.estimators.fast import build_window_model
    from continuum_mhe.estimators.fast.sqp import Workspace
    from continuum_mhe.estimators.loss import LOSS_CODES

    f = make_formulation("bend") if robot is None else make_formulation("bend", robot)
    nx, nz = f.nx, f.nz
    model = build_window_model(f, n)
    lossk = model.loss._replace(code=LOSS_CODES[loss], scale=1.5)
    ws = Workspace(model, loss=lossk, linear=linear)
    rng = np.random.default_rng(11)
    X = rng.normal(scale=0.3, size=(n + 1, nx))
    z = rng.normal(scale=0.3, size=(n + 1, nz))
    m = (rng.random((n + 1, nz)) > 0.2).astype(float)
    # nodes without any reading (the second window's): one carried from the previous
    # window (node N-3; node 0 for N = 3), its node N-2 (the previous last) and the new last
    m[[n - 2, n - 1, n]] = 0.0
    u = rng.normal(size=(n, f.nu))
    dt = rng.uniform(0.01, 0.1, size=n)
    A = rng.normal(size=(n, nx, nx))
    qinv = np.einsum("sij,skj->sik", A, A) + np.eye(nx)

    def assembled(lo: int, b: int, shift_from: int = -1, spoil: bool = False) -> tuple:
        ws.Xb[b], ws.z[:], ws.m[:] = X[lo : lo + n], z[lo : lo + n] * m[lo : lo + n], m[lo : lo + n]
        ws.u[:], ws.dt[:] = u[lo : lo + n - 1], dt[lo : lo + n - 1]
        model.window.evaluate(
            [ws.Xb[b].ravel(), ws.z.ravel(), ws.m.ravel(), ws.u.ravel(), ws.dt], ws.out[b]
        )
        if spoil:  # the carried nodes' measurement outputs: a shifted assembly ignores them
            ws.out[b, nz : (n - 2) * nz] = np.nan
        arrival = np.zeros((n, nx, nx))
        arrival[arrival_at] = qinv[lo] + lo * np.eye(nx)  # each window its own prior
        xbar = X[lo] + 0.1 * (lo + 1)
        cost = ws.core.assemble(b, np.ascontiguousarray(qinv[lo : lo + n - 1]), xbar, arrival,
                                shift_from)  # fmt: skip
        return (cost, ws.Dgn[b].copy(), ws.E[b].copy(), ws.g[b].copy(), ws.wgt[b].copy(),
                ws.extra[b].copy(), ws.gb[b].copy(), ws.ncost[b].copy())  # fmt: skip

    full = assembled(1, 0)
    src = 0 if in_place else 1
    ws.stage_done[:] = 0  # the previous window's stage products are its own
    assembled(0, src)
    if linear:  # the stage products move with the window, the new one is formed
        for a in (ws.stage_done, ws.core.stage_eq, ws.core.stage_fqf):
            a[:-1] = a[1:].copy()
        ws.stage_done[-1] = 0
    kept = [a.copy() for a in (ws.Dgn[src], ws.E[src], ws.g[src], ws.wgt[src], ws.extra[src],
                               ws.gb[src], ws.ncost[src])]  # fmt: skip
    carried = arrival_at == 0 and n > 3
    shifted = assembled(1, 0, shift_from=src, spoil=carried)
    assert shifted[0] == full[0] and np.isfinite(full[0])
    for got, want in zip(shifted[1:], full[1:]):
        assert np.array_equal(got, want)
    if carried:  # the carried nodes come from the previous window's assembly
        for a, was in zip((ws.Dgn[src], ws.E[src], ws.g[src], ws.wgt[src], ws.extra[src],
                           ws.gb[src], ws.ncost[src]), kept):  # fmt: skip
            a[:] = was
        ws.g[src, 2] += 1.0
        assert not np.array_equal(assembled(1, 0, shift_from=src)[3], full[3])


@pytest.mark.parametrize("loss", ["l2", "cauchy"])
def test_block_columns_hold_the_whole_second_order_term(loss) -> None:
    """A three-section robot's tilt blocks depend on the first 2, 4 and 6 state
    coordinates (``WindowModel.block_columns``): the whole second-order term of each
    block (formed here by CasADi) is zero outside that leading square, the window's
    outputs hold the square, and the curvature the SQP adds to the Gauss-Newton blocks
    over those columns alone is the whole terms' ``sum_b wgt_b S_b + extra_b gb_b
    gb_b^T`` (dropouts and a robust loss, whose clipped curvature adds ``gb gb^T``,
    included)."""
    import casadi as ca

    from continuum_mhe.estimators.fast import build_window_model
    from continuum_mhe.estimators.fast.sqp import Workspace
    from continuum_mhe.estimators.loss import LOSS_CODES

    robot = Robot(
        tuple(Section(0.1, 3.0) for _ in range(3)), tuple(ImuPlacement(i) for i in range(3))
    )
    f = make_formulation("bend", robot)
    n, nx, nz = 6, f.nx, f.nz
    model = build_window_model(f, n)
    cols = model.block_columns
    assert cols.tolist() == [2, 4, 6]
    # each block's whole second-order term sum_a (R_b^-1 r_b)_a d2 r_a / dx2 (nx, nx)
    x, zs, ms = ca.SX.sym("x", nx), ca.SX.sym("z", nz), ca.SX.sym("m", nz)
    r = ms * f.measurement_residual_sym(zs, x)
    rinv = np.linalg.inv(f.meas_cov())
    whole = []
    for blk in f.measurement_blocks:
        w = ca.DM(rinv[blk.slice, blk.slice]) @ r[blk.slice]
        lam = ca.SX.sym("lam", blk.size)  # held fixed: the residuals' second derivatives
        hess = ca.jacobian(ca.jacobian(r[blk.slice], x).T @ lam, x)
        whole.append(ca.substitute(hess, lam, w))
    second = ca.Function("second", [x, zs, ms], whole)
    lossk = model.loss._replace(code=LOSS_CODES[loss], scale=1.0)
    ws = Workspace(model, loss=lossk)
    rng = np.random.default_rng(3)
    X = rng.normal(scale=0.1, size=(n, nx))  # inside the bend limits
    z = rng.normal(scale=0.1, size=(n, nz))
    m = (rng.random((n, nz)) > 0.2).astype(float)
    ws.Xb[0], ws.z[:], ws.m[:] = X, z * m, m
    ws.u[:], ws.dt[:] = rng.normal(size=(n - 1, f.nu)), rng.uniform(0.01, 0.1, size=n - 1)
    A = rng.normal(size=(n - 1, nx, nx))
    qinv = np.einsum("sij,skj->sik", A, A) + np.eye(nx)
    arrival = np.zeros((n, nx, nx))
    arrival[0] = np.eye(nx)
    lam = np.zeros((n, len(model.feasible.ball_r2)))
    r = ws.core.solve(qinv, X[0] + 0.1, arrival, lam, 30, 1e-10, 1e-10, 500, True, False)
    assert r.iterations >= 2 and not lam.any()  # no ball active: D = Dgn + the curvature
    b = 1 - r.buffer  # the last evaluated iterate's buffer
    sr = int(np.sum(cols * cols))
    S = ws.out[b][-n * sr :].reshape(n, sr)
    for i in range(n):
        got, want = ws.D[b, i] - ws.Dgn[b, i], np.zeros((nx, nx))
        start = 0
        for k, c in enumerate(cols):
            full = np.asarray(second(ws.Xb[b, i], ws.z[i], ws.m[i])[k])
            assert not full[c:].any() and not full[:, c:].any()
            held = S[i, start : start + c * c].reshape(c, c).T  # column-major
            assert_allclose(held, full[:c, :c], rtol=1e-12, atol=1e-12)
            g = ws.gb[b, i, k]
            want += ws.wgt[b, i, k] * full + ws.extra[b, i, k] * np.outer(g, g)
            start += c * c
        assert_allclose(got, want, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(ws.D[b, i]).max()))


def test_measurements_from_a_column_major_array_give_the_same_estimates() -> None:
    """The compiled step's kernels keep the types of their first call, so a sample
    ``z`` that is not contiguous (a row of a Fortran-ordered array) after contiguous
    ones is copied first: the estimates equal those from a C-ordered array, for the
    fast MHE and the compiled EKF."""
    from continuum_mhe.estimators import make_estimator

    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=7)
    zc = np.ascontiguousarray(rec.z)
    zf = np.asfortranarray(np.vstack([rec.z, rec.z]))[: len(rec.t)]
    assert not zf[0].flags.c_contiguous
    for name in ("mhe", "ekf"):
        a = make_estimator(name, f).run(rec.t, zc)
        b = make_estimator(name, f)
        rows = [zc[i] if i < 5 else zf[i] for i in range(len(rec.t))]  # C first
        out = np.array([b.step(Measurement(float(t), z)).output for t, z in zip(rec.t, rows)])
        assert_allclose(out, a.output, rtol=0, atol=1e-12, err_msg=name)


def test_a_window_model_without_its_block_columns_is_refused() -> None:
    """A window function built with each block's columns (every window from
    ``build_window_model``) writes fewer values than a layout of whole blocks holds: a
    WindowModel given without its ``block_columns`` is refused by the solver, not read
    with the Jacobian's values taken for the second-order term."""
    from continuum_mhe.estimators.fast.model import build_window_model
    from continuum_mhe.estimators.fast.sqp import Workspace

    robot = Robot((Section(0.15, 3.0), Section(0.15, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    model = build_window_model(make_formulation("bend", robot), horizon=5)
    Workspace(model)  # as built: accepted
    with pytest.raises(ValueError, match="the block_cols its window function was built with"):
        Workspace(replace(model, block_columns=None))
