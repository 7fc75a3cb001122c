"""``continuum-mhe benchmark``: its baselines compute what they claim to, and its report
records the ratios and where the numbers come from."""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe.benchmark import environment as bench_env
from continuum_mhe.benchmark import harness as bm
from continuum_mhe.benchmark import peers
from continuum_mhe.benchmark.dompc import run_dompc
from continuum_mhe.benchmark.peers import PEERS
from continuum_mhe.cli import benchmark as cli_benchmark
from continuum_mhe.cli.benchmark_report import print_report
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.estimators.window_nlp import build_nlp, pack_parameters
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate


@pytest.mark.parametrize("name", ["bend", "paper"])
def test_ekf_kernel_gives_the_casadi_ekf_answers(name: str) -> None:
    """The bare compiled kernel the benchmark times is the EKF (to 1e-9), dropouts too."""
    f = make_formulation(name)
    rec = simulate("paper3d", duration=3.0, seed=4)
    z = rec.z.copy()
    z[12:18] = np.nan  # the IMU drops out: prediction only
    rec = replace(rec, z=z)
    out, sec = bm.run_ekf_kernel(f, rec)
    ref = CasadiExtendedKalmanFilter(f).run(rec.t, z)
    assert_allclose(out, ref.output, rtol=0, atol=1e-9)
    assert sec[0] == 0.0 and np.all(sec[1:] > 0)


def test_dompc_with_our_cost_solves_our_problem_once_the_window_is_full() -> None:
    """do-mpc, given the tangent-plane residual and the EKF arrival prior through its
    API, is an independent peer of the IPOPT backend from sample N on (1e-6; both
    converge to IPOPT's tolerance). Before sample N it has no growing window, so it
    differs."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=0)
    n = 6
    out, _ = run_dompc(f, n, rec)
    ref = MovingHorizonEstimator(f, MHESettings(horizon=n, solver="ipopt")).run(rec.t, rec.z)
    assert bm._max_diff(out[n:], ref.output[n:]) < 1e-6
    assert bm._max_diff(out[:n], ref.output[:n]) > 1e-4  # the start-up is not the same


def test_benchmark_command_records_ratios_and_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``continuum-mhe benchmark`` on a tiny recording: every method, the ratios, the
    agreement with IPOPT, the compiled EKF's answers, where the numbers come from (the
    losses' table is tested in ``test_robust_mhe``)."""
    import casadi

    from continuum_mhe.cli import main

    monkeypatch.setattr(bench_env, "cpu_model", lambda: "Test CPU 9000")
    out = tmp_path / "bench.json"
    args = ["benchmark", "--horizons", "4", "--duration", "0.6", "--memory-samples", "1000",
            "--loss-horizons", "none", "--repeats", "1", "--interpreted-peers"]  # fmt: skip
    assert main([*args, "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    rows = {r["method"]: r for r in report["results"]}
    assert report["casadi_peers_compiled"] is False
    assert set(report["skipped"]) <= {"acados"}  # unless comma-deps-acados is installed
    assert set(rows) == set(bm.METHODS) - set(report["skipped"]) == set(report["methods"])
    fast = rows["fast"]
    assert fast["max_diff_vs_ipopt"] < 1e-6 and fast["fallbacks"] == 0
    assert rows["do-mpc"]["max_diff_from_n"] < 1e-6
    assert rows["mhe-kernel"]["max_diff_vs_ipopt"] < 1e-6  # the fast MHE, bare
    assert rows["mhe-kernel"]["fallbacks"] == 0
    for peer in set(PEERS) & set(rows):  # converged on every window, IPOPT's answers
        assert rows[peer]["max_diff_from_n"] < 1e-6 and rows[peer]["fallbacks"] == 0
        assert rows[peer]["build_s"] > 0.0  # built before the clock, and said
    for name, r in rows.items():  # an MHE agrees with IPOPT; an EKF is not asked to
        assert r["agrees_with_ipopt"] is (True if name in bm.MHE_METHODS else None)
        assert r["warmup_s"] > 0.0
    for m in ("ekf-compiled", "ekf-kernel"):  # the same EKF, three ways
        assert rows[m]["max_diff_vs_ipopt"] == pytest.approx(
            rows["ekf"]["max_diff_vs_ipopt"], abs=1e-9
        )
    for r in rows.values():
        for key, ref in (("over_fast", "fast"), ("over_ipopt", "ipopt"),
                         ("over_ekf_compiled", "ekf-compiled"),
                         ("over_ekf_kernel", "ekf-kernel")):  # fmt: skip
            assert r[key] == pytest.approx(r["median_us"] / rows[ref]["median_us"])
    assert report["memory"]["samples"] == 1000
    assert report["versions"]["casadi"] == casadi.__version__
    assert report["machine"]["cores"] == os.cpu_count()
    assert report["machine"]["cpu"] == "Test CPU 9000"  # (known answers below)


#: /proc/cpuinfo of a two-core machine (abridged); the model name is each core's third
#: line (cores of two kinds: the first is named)
_CPUINFO = """processor\t: 0
vendor_id\t: GenuineIntel
model name\t: Intel(R) Xeon(R) Test CPU @ 2.10GHz
flags\t\t: fpu vme de pse

processor\t: 1
vendor_id\t: GenuineIntel
model name\t: Intel(R) Atom(TM) Other CPU
"""


@pytest.mark.parametrize(
    ("cpuinfo", "processor", "expected"),
    [
        (_CPUINFO, "test-processor", "Intel(R) Xeon(R) Test CPU @ 2.10GHz"),  # the first one
        ("processor\t: 0\nBogoMIPS\t: 48.00\n", "test-processor", "test-processor"),  # ARM
        (None, "test-processor", "test-processor"),  # no /proc/cpuinfo (not Linux)
        (None, "", "test-machine"),  # and a platform that names no processor
    ],
)
def test_environment_records_the_cpu_model(
    monkeypatch: pytest.MonkeyPatch, cpuinfo: str | None, processor: str, expected: str
) -> None:
    """The benchmark's machine record names the CPU: /proc/cpuinfo's first model name,
    else the platform's processor, else its machine type (a given cpuinfo and platform,
    not this machine's)."""
    import io

    def fake_open(file, *args, **kwargs):  # type: ignore[no-untyped-def]
        if str(file) != "/proc/cpuinfo":
            return open(file, *args, **kwargs)
        if cpuinfo is None:
            raise FileNotFoundError(file)
        return io.StringIO(cpuinfo)

    monkeypatch.setattr(bench_env, "open", fake_open, raising=False)  # the module's open only
    monkeypatch.setattr(platform, "processor", lambda: processor)
    monkeypatch.setattr(platform, "machine", lambda: "test-machine")
    assert bench_env.environment(make_formulation("bend"))["machine"]["cpu"] == expected


def test_benchmark_skips_a_method_and_leaves_its_ratio_empty(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    report = bm.run_benchmark([3], 0.4, tuple(m for m in bm.METHODS if m not in {
        "do-mpc", "ekf-kernel", *PEERS}), 0)  # fmt: skip
    assert {r["method"] for r in report["results"]} == {
        "fast", "mhe-kernel", "ipopt", "ekf", "ekf-compiled"}  # fmt: skip
    assert all(np.isnan(r["over_ekf_kernel"]) for r in report["results"])
    cli_benchmark._write_json(str(out), report, argparse.Namespace(acados=None))
    written = json.loads(out.read_text())
    assert written["results"][0]["over_ekf_kernel"] is None
    # what made it: the command line, when (UTC) and the acados folder
    assert written["command"].startswith("continuum-mhe") and written["acados"] is None
    assert written["run_at"].endswith("+00:00")


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--horizons", "100", "--duration", "2", "--skip", "do-mpc", "--loss-horizons", "none",
          "--repeats", "1", "--memory-samples", "0"],
         "horizon 100 needs more than 100 samples: --duration 2 s gives only 41 (one every "
         "0.05 s); raise --duration (to at least 5 s)"),
        (["--robot", "two-section", "--horizons", "10,200", "--duration", "2"],
         "horizon 200 needs more than 200 samples: --duration 2 s gives only 101 (one every "
         "0.02 s); raise --duration (to at least 4 s)"),
        (["--horizons", "10", "--loss-horizons", "41", "--duration", "2"],
         "horizon 41 needs more than 41 samples: --duration 2 s gives only 41"),
        (["--duration", "10"], "horizon 300 needs more than 300 samples: --duration 10 s "
         "gives only 201"),  # the default horizons 10,30,100,300
    ],
)  # fmt: skip
def test_a_horizon_longer_than_the_recording_is_one_line_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    """A horizon longer than the recording (no window is ever full) is one line, exit
    2, before anything runs, not an internal error once the horizon's runs are done."""
    from continuum_mhe.cli import main

    out = tmp_path / "bench.json"
    assert main(["benchmark", *argv, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {needle}") and err.count("\n") == 1
    assert not out.exists()


def test_benchmark_help_gives_the_default_duration(capsys: pytest.CaptureFixture[str]) -> None:
    from continuum_mhe.cli import main

    with pytest.raises(SystemExit):
        main(["benchmark", "--help"])
    assert "recording length in s (default 20;" in " ".join(capsys.readouterr().out.split())


#: Where the acados peer's tests look for comma-deps-acados installed apart from CasADi
#: (``pip install --no-deps --target DIR comma-deps-acados``); else among the packages.
ACADOS_DIR_VARIABLE = "CONTINUUM_MHE_ACADOS_DIR"


def _peer_folder(name: str) -> str | None:
    """The acados folder of :data:`ACADOS_DIR_VARIABLE` (or None) where the peer ``name``
    can run. A test of acados is skipped where acados is neither installed nor named by
    the variable (a local run); a peer that cannot run otherwise fails the test: the
    CasADi the test extra pins has fatrop and HPIPM, and CI sets the variable, so a peer
    missing there is a broken environment, not a test to pass without a word."""
    folder = os.environ.get(ACADOS_DIR_VARIABLE)
    why = peers.missing_peers(folder).get(name)
    if why is not None:
        if name == "acados" and folder is None and peers.find_acados(None) is None:
            pytest.skip(f"acados: {why} (or set {ACADOS_DIR_VARIABLE}=DIR)")
        pytest.fail(f"{name} cannot run here: {why}")
    return folder


@pytest.fixture(scope="module")
def acados_peer() -> Iterator[peers.WindowSolver]:
    """The acados peer of the bend formulation at N = 6, built once for the module (its
    generated solver takes seconds to build) and closed after its last test; a test
    starts it on a new recording (``reset``). Skipped where acados is not installed and
    the variable is not set (:func:`_peer_folder`)."""
    folder = _peer_folder("acados")
    solver = peers.make_peer("acados", make_formulation("bend"), 6, peers.find_acados(folder))
    try:
        yield solver
    finally:
        getattr(solver, "close", lambda: None)()


@pytest.mark.parametrize("name", PEERS)
def test_each_peer_solves_the_mhe_windows_to_ipopts_answers(
    name: str, request: pytest.FixtureRequest
) -> None:
    """Each peer, on the MHE's own windows (growing, then full; the disk bound, a
    dropout) warm-started from its shifted answer, converges and finds IPOPT's answer to
    the same window from the same guess, node by node (1e-6; both converge to 1e-8).
    (acados: the module's solver, started on this recording.)"""
    folder = _peer_folder(name)
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=1.0, seed=3)
    z = rec.z.copy()
    z[9] = np.nan  # a dropout inside the window
    rec = replace(rec, z=z)
    n = 6
    windows = peers.record_windows(f, rec, n)
    shared = name == "acados"
    if shared:
        solver = request.getfixturevalue("acados_peer")
        solver.reset()
    else:
        solver = peers.make_peer(name, f, n, peers.find_acados(folder), compiled=False)
    nlp = build_nlp(f, n, 100, 1e-10)
    X = None
    worst = 0.0
    try:
        for i, problem in enumerate(windows):
            assert problem is not None
            X0 = peers.shifted_guess(f, problem, X)
            X, converged, _ = peers.solve_window(solver, problem, X0)
            assert converged, f"{name} did not converge on window {i}"
            if i in (2, n, n + 3, len(windows) - 1):  # growing, first full, dropout, last
                ref = nlp.solver(x0=X0.ravel(), p=pack_parameters(problem), lbx=nlp.lbx,
                                 ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)  # fmt: skip
                X_ipopt = np.asarray(ref["x"], dtype=float).reshape(n, f.nx)
                worst = max(worst, float(np.abs(X - X_ipopt).max()))
    finally:
        if not shared:  # (the module's acados peer is closed by its fixture)
            getattr(solver, "close", lambda: None)()
    assert worst < 1e-6


def test_acados_starts_each_window_from_its_shifted_multipliers(
    acados_peer: peers.WindowSolver,
) -> None:
    """As sqpmethod (``shifted_multipliers``) and the fast MHE, acados starts a window
    from the last answer's multipliers moved by one sample: each stage's dynamics
    multipliers, inequality multipliers and slacks are the next stage's of the answer
    before, the last stage's and the dynamics' into it the old last ones'; a new
    recording starts from what acados holds (the module's acados peer, N = 6)."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=0.6, seed=3)
    n = 6
    windows = [w for w in peers.record_windows(f, rec, n) if w is not None]
    solver = acados_peer
    solver.reset()  # a new recording
    fields = (("pi", n - 1), ("lam", n), ("t", n))
    X = peers.shifted_guess(f, windows[0], None)
    X, converged, _ = peers.solve_window(solver, windows[0], X)
    assert converged
    s = solver.solver  # type: ignore[attr-defined]
    held = {k: [np.array(s.get(i, k)) for i in range(m)] for k, m in fields}
    assert np.any(held["pi"][1] != 0.0)
    solver.prepare(windows[1], peers.shifted_guess(f, windows[1], X))
    for k, m in fields:
        for i in range(m):
            np.testing.assert_array_equal(s.get(i, k), held[k][min(i + 1, m - 1)])
    solver.prepare(windows[1], peers.shifted_guess(f, windows[1], X))  # not again
    for k, m in fields:
        for i in range(m):
            np.testing.assert_array_equal(s.get(i, k), held[k][min(i + 1, m - 1)])
    X, converged, _ = peers.solve_window(solver, windows[1], X)
    held = {k: [np.array(s.get(i, k)) for i in range(m)] for k, m in fields}
    solver.reset()  # a new recording: nothing moved
    solver.prepare(windows[2], peers.shifted_guess(f, windows[2], X))
    for k, m in fields:
        for i in range(m):
            np.testing.assert_array_equal(s.get(i, k), held[k][i])


def test_an_acados_solver_that_does_not_build_is_one_line_and_leaves_no_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A make that fails while acados builds its generated solver: a UserError naming
    acados and --skip acados (the command line's one line, exit 2, not an internal
    error, exit 70), and the generated code's temporary folder removed, not left."""
    folder = _peer_folder("acados")
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "make").write_text("#!/bin/sh\necho 'make: no rule' >&2\nexit 2\n")
    (fake / "make").chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setattr(peers.tempfile, "tempdir", str(tmp_path))  # its folder goes here
    with pytest.raises(UserError, match=r"^acados: its generated solver for N = 6 did not build"):
        peers.make_peer("acados", make_formulation("bend"), 6, peers.find_acados(folder))
    assert not list(tmp_path.glob("continuum-mhe-acados-*"))


def test_peer_window_is_the_mhe_window() -> None:
    """The optimal-control form the peers solve has the MHE window's cost: at any states,
    with the noise the gap they leave (:func:`ocp_guess`), its objective is the IPOPT
    NLP's (to rounding), and :func:`ocp_states` gives the states back."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=1.0, seed=1)
    n = 5
    problem = peers.record_windows(f, rec, n)[-1]
    assert problem is not None
    X = problem.xbar + np.random.default_rng(0).normal(scale=0.05, size=(n, f.nx))
    ocp = peers.ocp_nlp(f, n)
    w = peers.ocp_guess(f, problem, X)
    import casadi as ca

    cost = ca.Function("c", [ocp.nlp["x"], ocp.nlp["p"]], [ocp.nlp["f"]])
    p = pack_parameters(problem)
    expected = float(build_nlp(f, n, 100, 1e-8).cost(X.ravel(), p))
    assert float(cost(w, p)) == pytest.approx(expected, rel=1e-12)
    assert_allclose(peers.ocp_states(w, f.nx, n), X, rtol=0, atol=0)


def test_interleaved_warms_each_up_then_runs_them_round_robin() -> None:
    """Every run once, then the rounds in turn, each round's order rotated by one (a, b,
    c, then b, c, a, then c, a, b: no contender always first), each sample's time the
    median over the rounds (not the warm-up), the last round's outputs (c's is the
    second round's: it ran first in the third)."""
    calls: list[str] = []
    times = {"a": iter([9.0, 1.0, 5.0, 3.0]), "b": iter([9.0, 2.0, 2.0, 8.0]),
             "c": iter([9.0, 4.0, 6.0, 5.0])}  # fmt: skip
    # (each method's values are taken in the order it runs: its rounds, whatever their order)

    def run(name: str) -> bm.Run:
        def go() -> tuple[object, ...]:
            calls.append(name)
            t = next(times[name])
            return np.array([[t]]), np.array([t]), int(t), np.array([t / 10])

        return go

    got = bm._interleaved({m: run(m) for m in "abc"}, repeats=3)
    assert calls == list("abc") + list("abc") + list("bca") + list("cab")
    assert {m: float(got[m][1][0]) for m in "abc"} == {"a": 3.0, "b": 2.0, "c": 5.0}
    assert got["b"][0][0, 0] == 8.0 and got["b"][2] == 8  # the last round's
    assert got["c"][3] is not None and float(got["c"][3][0]) == pytest.approx(0.5)
    assert all(got[m][4] >= 0.0 for m in "abc")  # the warm-up run's wall time


def test_round_order_rotates_by_the_rounds_index() -> None:
    assert bm.round_order(["a", "b", "c"], 0) == ["a", "b", "c"]
    assert bm.round_order(["a", "b", "c"], 1) == ["b", "c", "a"]
    assert bm.round_order(["a", "b", "c"], 5) == ["c", "a", "b"]
    assert bm.round_order([], 2) == []


def test_an_mhe_without_answers_where_ipopt_has_them_does_not_agree(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """An MHE whose outputs equal IPOPT's wherever it gives them, but that gives none
    (nan) at samples where IPOPT has one, does not agree with IPOPT: the largest
    difference leaves those samples out (0 here), so it alone read as agreement. The
    count is kept and said beside the ratio; samples where neither answers do not
    count."""
    ipopt = np.arange(40.0).reshape(8, 5)
    out = ipopt.copy()
    out[[2, 5], 1] = np.nan  # no answer at two samples (one output is enough)
    ipopt[6] = out[6] = np.nan  # neither answers
    assert bm.agreement(out, ipopt) == (0.0, 2, False)
    assert bm.agreement(ipopt, ipopt) == (0.0, 0, True)
    off = ipopt + 2e-6
    assert bm.agreement(off, ipopt)[1:] == (0, False)

    row = {"method": "fatrop", "horizon": 10, "median_us": 20.0, "p99_us": 20.0,
           "max_diff_vs_ipopt": 0.0, "max_diff_from_n": 0.0, "fallbacks": 2,
           "solver_median_us": float("nan"), "agrees_with_ipopt": False,
           "missing_from_n": 2, "build_s": 1.0, "warmup_s": 0.5}  # fmt: skip
    fast = {**row, "method": "fast", "median_us": 10.0, "agrees_with_ipopt": True,
            "missing_from_n": 0, "fallbacks": 0}  # fmt: skip
    ipopt_row = {**fast, "method": "ipopt", "median_us": 1000.0}
    report = {"scenario": "paper3d", "samples": 41, "repeats": 1, "methods": {},
              "results": bm.with_ratios([fast, ipopt_row, row]), "machine": {},
              "versions": {}}  # fmt: skip
    monkeypatch.setattr(
        "continuum_mhe.cli.benchmark_report.environment_line", lambda report: "machine: -"
    )
    print_report(report)
    out_text = " ".join(capsys.readouterr().out.split())
    line = out_text[out_text.index("fatrop at N = 10:") :].split("before the clock")[0]
    assert "NOT IPOPT's answers (none at 2 samples from sample N on where IPOPT has one)" in line


def test_a_contender_off_ipopts_answers_is_said_so_beside_its_ratio(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A peer (or the fast MHE) whose answers are not IPOPT's is not read as fast: its
    ratio line says so; one that agrees gets no such words; the set-up line gives each
    contender's build and warm-up times."""

    def row(method: str, median: float, from_n: float) -> dict[str, object]:
        return {"method": method, "horizon": 10, "median_us": median, "p99_us": median,
                "max_diff_vs_ipopt": from_n, "max_diff_from_n": from_n, "fallbacks": 0,
                "solver_median_us": float("nan"),
                "agrees_with_ipopt": from_n <= bm.AGREEMENT_TOL,
                "build_s": 1.25, "warmup_s": 0.5}  # fmt: skip

    rows = [row("fast", 10.0, 1e-9), row("ipopt", 1000.0, 0.0), row("fatrop", 20.0, 3e-2),
            row("sqp-hpipm", 30.0, 1e-10)]  # fmt: skip
    report = {"scenario": "paper3d", "samples": 41, "repeats": 1, "methods": {},
              "results": bm.with_ratios(rows), "machine": {}, "versions": {}}  # fmt: skip
    monkeypatch.setattr(
        "continuum_mhe.cli.benchmark_report.environment_line", lambda report: "machine: -"
    )
    print_report(report)
    out = " ".join(capsys.readouterr().out.split())
    fatrop = out[out.index("fatrop at N = 10:") :].split("sqp-hpipm at")[0]
    assert "2.00x" in fatrop and "NOT IPOPT's answers (3.0e-02" in fatrop
    sqp = out[out.index("sqp-hpipm at N = 10:") :].split("before the clock")[0]
    assert "3.00x" in sqp and "NOT" not in sqp
    fast = out[out.index("fast MHE at N = 10:") :].split("fatrop at")[0]
    assert "NOT" not in fast
    assert "fatrop 1.25 / 0.50" in out[out.index("before the clock at N = 10") :]


def test_a_missing_peer_is_skipped_with_the_line_that_installs_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """No comma-deps-acados and a CasADi without fatrop: their rows are left out, each
    with its one-line install hint in the report and the printed table; the others run."""
    import casadi

    monkeypatch.setattr(peers, "find_acados", lambda folder=None: None)
    has_nlpsol = casadi.has_nlpsol
    monkeypatch.setattr(casadi, "has_nlpsol", lambda name: name != "fatrop" and has_nlpsol(name))
    report = bm.run_benchmark([3], 0.4, ("ipopt", "acados", "fatrop", "ekf"), 0, (),
                              compile_peers=False)  # fmt: skip
    assert report["skipped"] == {
        "acados": "needs comma-deps-acados: " + peers.ACADOS_HINT,
        "fatrop": "this CasADi has no fatrop: pip install 'casadi>=3.8.2'",
    }
    assert "pip install --no-deps --target DIR comma-deps-acados" in peers.ACADOS_HINT
    assert {r["method"] for r in report["results"]} == {"ipopt", "ekf"}
    print_report(report)
    out = " ".join(capsys.readouterr().out.split())
    assert "acados: not timed: needs comma-deps-acados: pip install --no-deps" in out


def test_the_robot_benchmarks_raw_readings_are_unit_directions() -> None:
    """``benchmark --robot`` times the direct model on readings with noise: each IMU's
    specific force stays a direction, also on a three-section robot (the estimators
    refuse one that is not: readings 0.95 long would stop its benchmark)."""
    from continuum_mhe.benchmark.harness import raw_imu_recording
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot(
        tuple(Section(0.12, 3.0) for _ in range(3)), tuple(ImuPlacement(k) for k in range(3))
    )
    rec = raw_imu_recording(robot, 1.0)
    f = make_formulation("direct", robot)
    for b in f.measurement_blocks:
        norms = np.linalg.norm(rec.z[:, b.start : b.start + 3], axis=1)
        np.testing.assert_allclose(norms, 1.0, rtol=0, atol=1e-12)
    series = make_estimator("ekf", f).run(rec.t, rec.z)
    assert np.isfinite(series.output).all()


def test_the_ratios_line_names_only_the_contenders_that_ran(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """With the EKFs skipped the fast MHE's line gives its ratio to IPOPT alone, with no
    '-x the compiled EKF' for the contenders that did not run."""
    report = bm.run_benchmark([3], 0.4, ("fast", "ipopt"), 0, (), repeats=1, compile_peers=False)
    print_report(report)
    out = " ".join(capsys.readouterr().out.split())
    line = out[out.index("fast MHE at N = 3:") :].split("before the clock")[0]
    assert line.strip().endswith("of IPOPT") and "EKF" not in line and "-x" not in line


def test_a_peer_is_timed_on_its_solve_alone(monkeypatch) -> None:
    """``run_peer`` starts the peer on a new recording (``reset``: no multipliers of
    another run's last window), hands each window and its warm start to it (``prepare``:
    the guess's model calls, the parameters) before its clock starts, and stops the
    clock after the solve: the order of the calls, with the clock's reads among them."""
    calls: list[str] = []

    class Recorder:
        def reset(self) -> None:
            calls.append("reset")

        def prepare(self, problem: object, X0: np.ndarray) -> None:
            calls.append("prepare")

        def solve(self) -> tuple[np.ndarray, bool, float]:
            calls.append("solve")
            return np.zeros((3, f.nx)), True, math.nan

    def clock() -> float:
        calls.append("clock")
        return float(len(calls))

    f = make_formulation("bend")
    windows = peers.record_windows(f, simulate("paper3d", duration=0.2, seed=0), 3)
    monkeypatch.setattr(peers.time, "perf_counter", clock)
    _, sec, failed, _ = peers.run_peer(f, Recorder(), windows)
    assert calls == ["reset"] + ["prepare", "clock", "solve", "clock"] * len(windows)
    assert failed == 0 and np.all(sec == 2.0)  # the two reads around the solve alone


def test_dompc_is_timed_without_copying_the_window_into_its_templates(monkeypatch) -> None:
    """do-mpc's time per sample is the EKF arrival step and ``make_step``: its window's
    readings and masks and the prior go into do-mpc's templates before each clock
    start, as a peer's data do (a CasADi structure assignment costs tens of us, a
    window of N nodes 2N of them)."""
    from continuum_mhe.benchmark import dompc

    calls: list[str] = []
    f = make_formulation("bend")

    class Template:
        def __init__(self, name: str) -> None:
            self.name = name

        def __setitem__(self, key: object, value: object) -> None:
            calls.append(self.name)

    class Mhe:
        x0: object = None

        def set_initial_guess(self) -> None:
            pass

        def make_step(self, y: object) -> np.ndarray:
            calls.append("make_step")
            return np.zeros(f.nx)

    def clock() -> float:
        calls.append("clock")
        return float(len(calls))

    monkeypatch.setattr(dompc, "_dompc_mhe", lambda *a: (Mhe(), Template("tvp"), Template("par")))
    monkeypatch.setattr(dompc.time, "perf_counter", clock)
    n, rec = 3, simulate("paper3d", duration=0.3, seed=0)
    _, sec = run_dompc(f, n, rec)
    sample = ["tvp"] * 2 * n + ["clock", "clock", "par", "par", "clock", "make_step", "clock"]
    assert calls == sample * len(rec.t)
    assert np.all(sec == 3.0)  # (1 + 2): the arrival step and make_step alone


@pytest.mark.parametrize("name", ["fatrop", "sqp-hpipm", "ipopt-warm"])
def test_a_casadi_peers_options_change_at_its_solvers_level(name: str) -> None:
    """``CasadiPeer(options=...)`` changes the solver's own options over the
    benchmark's, as ``tools/peer_options.py`` measures them: an iteration limit of 1
    reaches the solver (it stops short, not converged, where the benchmark's takes 3 or
    more), and an option changed to None is left out (the solver's default; CasADi
    refuses a None value)."""
    f = make_formulation("bend")
    windows = peers.record_windows(f, simulate("paper3d", duration=0.4, seed=0), 3)
    window = [w for w in windows if w is not None][-1]
    guess = peers.shifted_guess(f, window, None) + 0.3  # a few iterations away
    default = {"fatrop": "mu_init", "sqp-hpipm": "max_iter_ls", "ipopt-warm": "mu_init"}
    peer = peers.CasadiPeer(f, 3, name, compiled=False, options={default[name]: None})
    assert peers.solve_window(peer, window, guess)[1]  # converged, as the benchmark's
    full = peers.CasadiPeer(f, 3, name, compiled=False)
    assert peers.solve_window(full, window, guess)[1]
    taken = full.solver.stats()["iter_count"]
    limited = peers.CasadiPeer(f, 3, name, compiled=False, options={"max_iter": 1})
    _, converged, _ = peers.solve_window(limited, window, guess)
    assert taken >= 3 and not converged and limited.solver.stats()["iter_count"] < taken


def test_a_casadi_peer_is_called_with_casadi_matrices(monkeypatch) -> None:
    """A CasADi peer's solve is the ``nlpsol`` call on the window, its guess and its
    multipliers already converted to CasADi matrices in ``prepare``: numpy arguments
    would be converted inside the timed call (about 0.1 us an element, a few hundred
    us a window at N = 30)."""
    import casadi

    f = make_formulation("bend")
    windows = peers.record_windows(f, simulate("paper3d", duration=0.4, seed=0), 3)
    peer = peers.CasadiPeer(f, 3, "sqp-hpipm", compiled=False)
    solver, kinds = peer.solver, []

    class Spy:
        def __call__(self, **kwargs: casadi.DM) -> dict[str, casadi.DM]:
            kinds.append({k: type(v) for k, v in kwargs.items()})
            return solver(**kwargs)

        def stats(self) -> dict[str, object]:
            return solver.stats()

    peer.solver = Spy()  # type: ignore[assignment]
    out, _, failed, _ = peers.run_peer(f, peer, windows)
    assert failed == 0 and np.isfinite(out[2:]).all()
    assert len(kinds) == sum(w is not None for w in windows) and "lam_x0" in kinds[-1]
    assert all(kind is casadi.DM for call in kinds for kind in call.values())


@pytest.mark.parametrize("ng", [0, 1])
def test_the_peers_multipliers_move_by_one_sample_as_their_states(ng: int) -> None:
    """Each multiplier of a window answer labelled by its stage and place: after the
    shift stage i holds stage i + 1's; the new last stage repeats the old last one's
    state bounds and constraints, its noise bounds are 0, and the dynamics before it are
    the old last dynamics'."""
    n, nx = 4, 2

    def label(i: int, size: int, base: int) -> np.ndarray:
        return base * i + 1 + np.arange(size, dtype=float)

    lam_x = np.concatenate(
        [np.concatenate([label(i, nx, 10), -label(i, nx, 10)]) for i in range(n - 1)]
        + [label(n - 1, nx, 10)]
    )
    stage = [np.concatenate([label(i, nx, 100), -label(i, ng, 100)]) for i in range(n - 1)]
    lam_g = np.concatenate([*stage, -label(n - 1, ng, 100)])
    x, g = peers.shifted_multipliers(lam_x, lam_g, nx, ng)
    states = x.reshape(-1)[np.r_[0:nx, 2 * nx : 3 * nx, 4 * nx : 5 * nx, 6 * nx : 7 * nx]]
    assert list(states) == [11, 12, 21, 22, 31, 32, 31, 32]
    assert list(x[[nx, nx + 1, 3 * nx, 3 * nx + 1]]) == [-11, -12, -21, -22]
    assert list(x[5 * nx : 6 * nx]) == [0, 0]  # the new last noise
    per = nx + ng
    dyn = [list(g[i * per : i * per + nx]) for i in range(n - 1)]
    assert dyn == [[101, 102], [201, 202], [201, 202]]
    if ng:
        cons = [float(g[i * per + nx]) for i in range(n - 1)] + [float(g[-1])]
        assert cons == [-101, -201, -301, -301]
    assert len(x) == len(lam_x) and len(g) == len(lam_g)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--robot", ""], "error: argument --robot: an empty value (a shell variable left"),
        (["--acados", " "], "error: argument --acados: an empty value (a shell variable left"),
        (["--horizons", "10,,30"], "horizons must be integers separated by commas, got '10,,30'"),
        (["--horizons", ",10"], "horizons must be integers separated by commas, got ',10'"),
        (["--horizons", "10", "--duration", "2", "--skip", "fast", "--loss-horizons", "10"],
         "continuum-mhe: error: --loss-horizons times the fast MHE's losses, which --skip "
         "fast leaves out"),
    ],
)  # fmt: skip
def test_empty_values_and_a_loss_table_without_the_fast_mhe_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    """An empty ``--robot``, an empty ``--acados``, an empty horizon and a loss table
    asked for with the fast MHE skipped: one line each, exit 2, before anything runs
    (not the whole peer benchmark, an install command without a folder, the horizon
    dropped or the table left out without a word)."""
    from continuum_mhe.cli import main

    out = tmp_path / "bench.json"
    try:
        code = main(["benchmark", *argv, "--json", str(out)])
    except SystemExit as exc:  # argparse's own refusal
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1, err
    assert not out.exists()


def test_the_robot_benchmark_takes_a_robot_of_one_section() -> None:
    """``benchmark --robot`` on a one-section robot refused it with a scenario error of
    ``simulate`` (an option the benchmark has not): it times its ``paper3d`` motion."""
    from continuum_mhe.benchmark.harness import run_robot_benchmark
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot((Section(0.2, 3.0),), (ImuPlacement(0),))
    said: list[str] = []
    report = run_robot_benchmark(robot, [10], 1.0, say=said.append)
    (row,) = report["rows"]
    assert row["horizon"] == 10 and row["fallbacks"] == 0 and row["max_diff_vs_ipopt"] < 1e-6
    # its progress as each horizon starts and ends, as the main run says it; the
    # report says what was asked
    assert said[0].startswith("N = 10 (1 of 1 horizons): the fast MHE and IPOPT")
    assert said[1].startswith("N = 10 done in ")
    assert report["horizons"] == [10] and report["duration_s"] == 1.0


def test_a_memory_check_too_short_to_fit_is_refused_before_the_run(capsys) -> None:
    """``--memory-samples`` of a few samples would fit its slope on a window still
    growing, or fail after every timing is done: it is refused before the run."""
    from continuum_mhe.cli import main

    argv = ["benchmark", "--horizons", "10", "--duration", "1", "--memory-samples", "2"]
    assert main(argv) == 2
    assert "--memory-samples 2: the memory check fits its slope over at least 1000" in (
        capsys.readouterr().err
    )


def test_benchmark_refuses_repeats_beyond_its_limit(capsys: pytest.CaptureFixture[str]) -> None:
    """``--repeats`` beyond 1000 (a run that would not end) is refused in one line before
    anything is timed."""
    from continuum_mhe.cli import main

    argv = ["benchmark", "--horizons", "10", "--duration", "2", "--repeats", str(10**20)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--repeats must lie in [1, 1000]" in err, err


def test_the_robot_benchmark_refuses_a_tendon_robot_in_its_own_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``benchmark --robot`` with a tendon robot: one line saying that the fast MHE does
    not take its model and what estimates it, not the simulator's refusal of scenarios;
    nothing written."""
    from continuum_mhe.cli import main

    out = tmp_path / "b.json"
    argv = ["benchmark", "--robot", "tendon-two-section", "--horizons", "5", "--duration",
            "1", "--repeats", "1", "--json", str(out)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == (
        "continuum-mhe: error: tendon-two-section: a tendon robot is not timed by benchmark: "
        "the fast MHE does not take its model (estimate --method ekf, ukf or mhe --solver "
        "ipopt do)\n"
    )
    assert not out.exists()


def test_a_compiled_casadi_peer_gives_the_interpreted_ones_answers() -> None:
    """The CasADi peers' functions compiled to C (as acados' are generated C; CasADi's
    SX virtual machine otherwise evaluates them, about twice as slowly): the same
    answers, bit for bit, on every window; and the benchmark's record says whether they
    were."""
    import shutil

    f = make_formulation("bend")
    windows = peers.record_windows(f, simulate("paper3d", duration=0.4, seed=0), 3)
    assert peers.casadi_peer_compile_options(False) == {}
    assert peers.casadi_peer_compile_options(True)["jit"] is True
    assert peers.casadi_peers_compiled() == (shutil.which("cc") is not None)
    compiled = peers.CasadiPeer(f, 3, "sqp-hpipm", compiled=True)
    interpreted = peers.CasadiPeer(f, 3, "sqp-hpipm", compiled=False)
    X = Y = None
    for problem in windows:
        assert problem is not None
        X, _, _ = peers.solve_window(compiled, problem, peers.shifted_guess(f, problem, X))
        Y, _, _ = peers.solve_window(interpreted, problem, peers.shifted_guess(f, problem, Y))
        np.testing.assert_array_equal(X, Y)
