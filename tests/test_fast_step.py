"""The fast MHE's compiled step (:mod:`continuum_mhe.estimators.fast.step`) against the
estimator's Python path on identical inputs.

The Python path (``_push``, ``_slide_arrival``, ``_initial_guess``, ``solve_window``,
``window_covariance`` and the node evaluator's outputs) is an independent
implementation of the same bookkeeping; an estimator without its compiled step takes
it. Both must give the same estimates, covariances, standard deviations and statuses
on recordings that exercise dropouts, spikes, the growing window, ``paper_start``,
robust losses, the branch check, the box bounds of the paper formulation and two
sections.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe.benchmark.kernels import run_mhe_kernel
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate, simulate_robot

TWO = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))


def _python_path(est: MovingHorizonEstimator) -> MovingHorizonEstimator:
    """``est`` without its compiled step (the Python bookkeeping around the SQP)."""
    est._steps = None
    est.reset()
    return est


def _damaged(z: np.ndarray) -> np.ndarray:
    """Dropouts of every sensor, of one component, and spikes."""
    z = np.array(z, dtype=float)
    z[40:46] = np.nan
    z[70, 0] = np.nan
    z[90:93] += 0.4
    return z


CASES = [
    ("bend", None, {}),
    ("bend", None, {"loss": "huber"}),
    ("bend", None, {"loss": "cauchy", "horizon": 6}),
    ("bend", None, {"paper_start": True}),
    ("bend", None, {"branch_check": True}),
    ("paper", None, {}),
    ("bend", TWO, {}),
    ("bend", TWO, {"loss": "welsch"}),
]


@pytest.mark.parametrize(("name", "robot", "options"), CASES)
def test_compiled_step_equals_the_python_path(name, robot, options) -> None:
    if robot is None:
        f = make_formulation(name)
        rec = simulate("paper3d", duration=6.0, noise_deg=2.0, seed=3)
    else:
        f = make_formulation(name, robot)
        rec = simulate_robot("s-curve", robot, duration=6.0, dt=0.05, seed=0)
    z = _damaged(rec.z)
    settings = MHESettings(**{"horizon": 12, **options})
    compiled = MovingHorizonEstimator(f, settings)
    assert compiled._steps is not None
    a = compiled.run(rec.t, z)
    b = _python_path(MovingHorizonEstimator(f, settings)).run(rec.t, z)
    assert list(a.status) == list(b.status)
    assert_allclose(a.output, b.output, rtol=0, atol=1e-12)
    assert a.output_std is not None and b.output_std is not None
    assert_allclose(a.output_std, b.output_std, rtol=1e-9, atol=1e-12)
    if a.outlier is not None:
        assert b.outlier is not None and np.array_equal(a.outlier, b.outlier)


def test_compiled_step_keeps_the_window_problem() -> None:
    """After each compiled step the estimator's window problem (what IPOPT, the branch
    check and the tests read) is the Python path's."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=5.0, seed=1)
    z = _damaged(rec.z)
    a = MovingHorizonEstimator(f, MHESettings(horizon=8))
    b = _python_path(MovingHorizonEstimator(f, MHESettings(horizon=8)))
    for t, zi in zip(rec.t, z):
        a.step(Measurement(float(t), zi))
        b.step(Measurement(float(t), zi))
        if a._xbar is None:
            continue
        pa, pb = a.window_problem(), b.window_problem()
        for key, va in vars(pa).items():
            assert_allclose(va, getattr(pb, key), rtol=1e-12, atol=1e-14, err_msg=key)


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


def test_compiled_step_takes_the_second_start_as_the_python_path_does() -> None:
    # a +30 deg burst at sample 74 of seed 3 (the one tests/test_robust_mhe.py leaves)
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=8.0, noise_deg=2.0, seed=3)
    z = np.array(rec.z, dtype=float)
    z[74:79] += np.radians(30.0)
    settings = MHESettings(horizon=30, loss="cauchy")
    compiled = MovingHorizonEstimator(f, settings)
    python = _python_path(MovingHorizonEstimator(f, settings))
    a, b = compiled.run(rec.t, z), python.run(rec.t, z)
    assert compiled.second_start is not None and python.second_start is not None
    assert compiled.second_start.kept > 0
    assert (compiled.second_start.tried, compiled.second_start.kept) == (
        python.second_start.tried,
        python.second_start.kept,
    )
    assert list(a.status) == list(b.status)
    assert_allclose(a.output, b.output, rtol=0, atol=1e-10)


def test_robust_weights_come_from_the_fused_call_unless_the_newest_is_rejected(
    monkeypatch,
) -> None:
    """The robust MHE's weights come from its one compiled call per sample; the Python
    path's weights (and the second start behind them) run only for the samples whose
    answer rejects the newest reading."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=8.0, noise_deg=2.0, seed=3)
    z = np.array(rec.z, dtype=float)
    z[74:79] += np.radians(30.0)
    est = MovingHorizonEstimator(f, MHESettings(horizon=30, loss="welsch"))
    calls: list[int] = []
    original = MovingHorizonEstimator._node_weights

    def counted(self, i, x):
        calls.append(i)
        return original(self, i, x)

    monkeypatch.setattr(MovingHorizonEstimator, "_node_weights", counted)
    res = est.run(rec.t, z)
    assert res.outlier is not None
    rejected = int(np.count_nonzero(res.outlier))
    assert rejected >= 5  # the burst's samples, at least
    assert est.second_start is not None and est.second_start.tried > 0
    # each rejecting sample: the newest's weights once for the second start's check and
    # the first and last node's kept weights; no call on any other sample
    assert 0 < len(calls) <= 3 * rejected


def test_stage_products_carried_across_windows_equal_fresh_ones() -> None:
    """With an affine transition the compiled step keeps each stage's ``-(Q^-1 F)^T``
    and ``F^T Q^-1 F`` from window to window (only the new stage's are formed): after
    every sample they equal numpy's, from the window's ``Q^-1`` and CasADi's ``F``."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=6.0, seed=2)
    z = _damaged(rec.z)
    est = MovingHorizonEstimator(f, MHESettings(horizon=8))
    assert est._steps is not None
    done, eq, fqf = est._steps.workspace.stage
    assert done.shape == (7,)
    checked = 0
    for t, zi in zip(rec.t, z):
        est.step(Measurement(float(t), zi))
        s = est._steps
        for i in np.flatnonzero(done):
            F = np.asarray(f.functions.predict(np.zeros(f.nx), s.u[i], float(s.dt[i]))[1])
            F = F.reshape(f.nx, f.nx)
            qf = s.qinvw[i] @ F
            assert_allclose(eq[i], -qf.T, rtol=1e-13, atol=1e-12)
            assert_allclose(np.triu(fqf[i]), np.triu(F.T @ qf), rtol=1e-13, atol=1e-9)
            checked += 1
    assert checked > 7 * (len(rec.t) - 20)


@pytest.mark.parametrize("robot", [None, TWO], ids=["one-section", "two-sections"])
def test_fused_ekf_step_equals_the_step_then_the_outputs(robot) -> None:
    """:meth:`NodeEvaluator.ekf_step_outputs` (the compiled EKF's one call per sample)
    gives the state and covariance of the EKF step composed here from the node model
    (prediction, then :func:`arrival_update` on the masked residual) and the outputs and
    standard deviations of :meth:`output` and :meth:`output_std` on that state, on
    samples with every sensor, one sensor masked and none; and the EKF estimator
    reports them."""
    from continuum_mhe.estimators.fast import NodeEvaluator, build_window_model
    from continuum_mhe.estimators.fast.arrival import arrival_update
    from continuum_mhe.estimators.kalman import CompiledExtendedKalmanFilter, ProcessNoiseCache

    f = make_formulation("bend", robot) if robot else make_formulation("bend")
    node = NodeEvaluator(build_window_model(f, 2))
    noise = ProcessNoiseCache(f)
    rng = np.random.default_rng(2)
    x = np.asarray(f.initial_state(np.full(f.nz, 0.3)), float) + rng.normal(scale=0.1, size=f.nx)
    P = f.initial_cov()
    masks = [np.ones(f.nz), np.r_[np.zeros(2), np.ones(f.nz - 2)], np.zeros(f.nz)]
    for mask in masks * 2:
        z = rng.normal(scale=0.4, size=f.nz)
        u, dt = np.zeros(f.nu), 0.05
        Q = noise(dt)[0]
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
    ekf = CompiledExtendedKalmanFilter(f)
    ekf.reset()
    for i in range(len(rec.t)):
        e = ekf.step(Measurement(float(rec.t[i]), rec.z[i]))
        assert e.state is not None and e.covariance is not None and e.output_std is not None
        assert_allclose(e.output, node.output(e.state), rtol=1e-13, atol=1e-15)
        assert_allclose(e.output_std, node.output_std(e.state, e.covariance), rtol=1e-12,
                        atol=1e-15)  # fmt: skip


@pytest.mark.parametrize("in_place", [False, True])
def test_shifted_outputs_equal_the_window_model_at_the_shifted_iterate(in_place) -> None:
    """``shift_outputs`` (the previous window's model outputs moved by one node, the
    tail function for the new node and stage) gives exactly what the window function
    gives at the shifted iterate, dropouts and two sections included."""
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
        assert model.window(ws.ptrs[b].ctypes.data, ws.out[b].ctypes.data) == 0
        return ws.out[b].copy()

    src = 0 if in_place else 1
    window(0, src)
    fresh = window(1, 0 if not in_place else 1)  # buffer 0 now holds the shifted iterate
    ws.Xb[0] = X[1:]
    assert ws.core.shift_outputs(src, 0)
    assert_allclose(ws.out[0], fresh, rtol=1e-14, atol=1e-15)


def test_the_next_window_starts_from_the_kept_assembly() -> None:
    """In the estimator, a full window whose predecessor's answer was kept starts from
    that window's assembly shifted (:func:`_assemble` with ``shifted``): spoiling the kept
    gradient of a node that the shift carries changes the next estimate; an estimator
    given the same samples without it does not move."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=3.0, seed=4)
    n = 8
    a = MovingHorizonEstimator(f, MHESettings(horizon=n))
    b = MovingHorizonEstimator(f, MHESettings(horizon=n))
    assert a._steps is not None and b._steps is not None
    k = 3 * n
    for t, zi in zip(rec.t[:k], rec.z[:k]):
        ea, eb = a.step(Measurement(float(t), zi)), b.step(Measurement(float(t), zi))
        assert ea.state is not None and np.array_equal(ea.state, eb.state)
    kept = int(a._steps.last[0])
    assert kept >= 0 and int(a._steps.k[0]) == n
    a._steps.workspace.g[kept, 3] += 1.0  # node 3 of the kept iterate: the next one's node 2
    m = Measurement(float(rec.t[k]), rec.z[k])
    ea, eb = a.step(m), b.step(m)
    assert ea.state is not None and eb.state is not None
    assert not np.array_equal(ea.state, eb.state)


def test_rows_move_as_numpy_moves_them() -> None:
    """:func:`~continuum_mhe.estimators.fast.memory.shift_rows` (one ``memmove``) moves
    rows as numpy's slice assignment does, within one array in either direction (the
    ranges overlap), between two, for other dtypes, and refuses rows out of range."""
    import numba

    from continuum_mhe.estimators.fast.memory import move, shift_rows

    @numba.njit
    def moved(dst, at, src, src_at, count):
        move(dst, at, src, src_at, count)

    rng = np.random.default_rng(0)
    a = rng.normal(size=(9, 3, 2))
    want = a.copy()
    want[1:7] = a[2:8].copy()
    shift_rows(a, a, 1, 7)
    assert np.array_equal(a, want)
    b, c = rng.normal(size=(5, 4)), rng.normal(size=(6, 4))
    want = b.copy()
    want[0:5] = c[1:6]
    shift_rows(b, c, 0, 5)
    assert np.array_equal(b, want)
    k = np.arange(12, dtype=np.int64).reshape(6, 2)
    shift_rows(k, k, 0, 5)
    assert k.ravel().tolist() == [*range(2, 12), 10, 11]
    x = np.arange(10.0)
    moved(x, 2, x, 0, 7)  # towards the end: overlapping the other way
    assert x.tolist() == [0, 1, *range(0, 7), 9]
    with pytest.raises(IndexError):
        shift_rows(b, c, 0, 6)


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
        assert model.window(ws.ptrs[b].ctypes.data, ws.out[b].ctypes.data) == 0
        if spoil:  # the carried nodes' measurement outputs: a shifted assembly ignores them
            ws.out[b, nz : (n - 2) * nz] = np.nan
        arrival = np.zeros((n, nx, nx))
        arrival[arrival_at] = qinv[lo] + lo * np.eye(nx)  # each window its own prior
        xbar = X[lo] + 0.1 * (lo + 1)
        cost = ws.core.assemble(b, np.ascontiguousarray(qinv[lo : lo + n - 1]), xbar, arrival,
                                shift_from)  # fmt: skip
        return (cost, ws.D[b].copy(), ws.E[b].copy(), ws.g[b].copy(), ws.wgt[b].copy(),
                ws.extra[b].copy(), ws.gb[b].copy(), ws.ncost[b].copy())  # fmt: skip

    full = assembled(1, 0)
    src = 0 if in_place else 1
    ws.stage[0][:] = 0  # the previous window's stage products are its own
    assembled(0, src)
    ws.Dgn[src] = ws.D[src]  # the SQP keeps the Gauss-Newton blocks there
    if linear:  # the stage products move with the window, the new one is formed
        for a in ws.stage:
            a[:-1] = a[1:].copy()
        ws.stage[0][-1] = 0
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


@pytest.mark.parametrize(("options", "reused"), [({}, True), ({"branch_check": True}, False)])
def test_the_next_window_starts_from_the_kept_linearisation_only_when_final(
    options, reused
) -> None:
    """After a certified window whose answer is final, the compiled step keeps the
    buffer of the SQP's last evaluated iterate for the next window (its model outputs
    shift, :func:`shift_outputs`); with a branch check, which may change the answer,
    it keeps none."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=4.0, seed=6)
    est = MovingHorizonEstimator(f, MHESettings(horizon=8, **options))
    assert est._steps is not None
    kept = []
    for t, zi in zip(rec.t, rec.z):
        status = est.step(Measurement(float(t), zi)).status
        kept.append(status == "ok" and est._steps.last[0] >= 0)
    assert (sum(kept) > 0.9 * len(kept)) if reused else not any(kept)


def test_compiled_call_reuses_the_first_overload_and_accepts_plain_functions() -> None:
    """:class:`CompiledCall` answers as the dispatcher does, through the overload its
    first call selected; a plain function (no numba) is simply called."""
    import numba

    from continuum_mhe.estimators.fast.ccall import CompiledCall

    @numba.njit
    def axpy(a, x, y):
        return a * x + y

    call = CompiledCall(axpy)
    x, y = np.arange(3.0), np.ones(3)
    assert_allclose(call(2.0, x, y), [1.0, 3.0, 5.0])
    assert call._entry is axpy.overloads[axpy.signatures[0]].entry_point
    assert_allclose(call(-1.0, x, y), [1.0, 0.0, -1.0])
    plain = CompiledCall(lambda a, b: a - b)
    assert plain(5, 3) == 2 and plain(1, 1) == 0 and plain._entry is None


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


def test_the_fused_step_outputs_are_not_computed_again() -> None:
    """The outputs and their standard deviations come from the fused compiled call; the
    estimator does not evaluate them again for the estimate (the node evaluator's
    output functions are not called on certified samples)."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=8)
    est = MovingHorizonEstimator(f, MHESettings(horizon=8))
    assert est._node is not None
    for t, z in zip(rec.t[:5], rec.z[:5]):
        est.step(Measurement(float(t), z))

    def refuse(*args: object) -> None:
        raise AssertionError("outputs evaluated again")

    est._node.output = refuse  # type: ignore[method-assign]
    est._node.output_std = refuse  # type: ignore[method-assign]
    statuses = [est.step(Measurement(float(t), z)).status for t, z in zip(rec.t[5:], rec.z[5:])]
    assert statuses == ["ok"] * len(statuses)


def test_uncertified_windows_between_certified_ones_keep_the_step_sound() -> None:
    """With at most two SQP iterations many windows are not certified (IPOPT answers them and
    the outputs are evaluated afresh in the step's buffers), and some are: the
    compiled step, switching between the shifted and the fresh start, still equals
    the Python path on every sample (a stale or corrupted shift would differ or crash)."""
    from continuum_mhe.estimators.fast import FastOptions

    f = make_formulation("bend")
    rec = simulate("paper3d", duration=4.0, noise_deg=2.0, seed=9)
    options = FastOptions(max_iter=2)
    compiled = MovingHorizonEstimator(f, MHESettings(horizon=8), options)
    assert compiled._steps is not None
    a = compiled.run(rec.t, rec.z)
    b = _python_path(MovingHorizonEstimator(f, MHESettings(horizon=8), options))
    b = b.run(rec.t, rec.z)
    statuses = list(a.status)
    assert statuses == list(b.status)
    assert 0 < statuses.count("fallback-ipopt") < len(statuses) - 10  # both kinds occur
    assert_allclose(a.output, b.output, rtol=0, atol=1e-12)
