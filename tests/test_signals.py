"""SIGTERM is handled like Ctrl-C: an interrupted estimate keeps its rows, marked
partial, and nothing else is left half-written, exit 143; stale temporary
files of a killed writer are removed by the next write into the same folder; a signal
that lands inside IPOPT (which stops on it and returns a status) ends the run."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from live_helpers import SAFETY_S, temporary_bytes, wait_for

from continuum_mhe.io.output_files import atomic_writer
from continuum_mhe.signals import Terminated

EXE = str(Path(sys.executable).with_name("continuum-mhe"))


def test_sigterm_during_estimate_keeps_its_rows_marked_partial_exit_143(tmp_path: Path) -> None:
    from continuum_mhe.cli import main

    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "3000", "-o", str(meas)]) == 0
    out = tmp_path / "e.csv"
    proc = subprocess.Popen(
        [EXE, "estimate", str(meas), "-o", str(out), "--method", "ukf"],
        stderr=subprocess.PIPE,
        text=True,
    )
    # well into the estimation loop (60,001 samples, about 9 MB of rows): its estimates
    # are being written to the temporary file
    wait_for(
        lambda: temporary_bytes(tmp_path, "e.csv") > 100_000 or proc.poll() is not None,
        "the first estimates",
    )
    assert proc.poll() is None, proc.communicate(timeout=SAFETY_S)[1]
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "continuum-mhe: terminated"
    assert "kept the" in err and "marked '# partial = ...'" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.csv", "m.csv"]  # no temp
    from continuum_mhe.io.state_tables import read_state_table

    rows = len(read_state_table(out).t)
    assert 0 < rows < 60_001
    last = out.read_text().rstrip("\n").rsplit("\n", 1)[-1]
    assert last.startswith(f'# partial = "interrupted after {rows} samples'), last


def test_stale_temporary_of_a_dead_writer_is_removed(tmp_path: Path) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".e.csv.{dead.pid}.abc123.tmp"
    stale.write_text("partial")
    alive = tmp_path / f".e.csv.{os.getpid()}.def456.tmp"  # ours: still running
    alive.write_text("in progress")
    other = tmp_path / f".other.csv.{dead.pid}.x.tmp"  # another output's, its writer dead
    other.write_text("x")
    mine = tmp_path / f".notes.{dead.pid}.tmp"  # not the writer's pattern: left alone
    mine.write_text("x")
    with atomic_writer(tmp_path / "e.csv") as fh:
        fh.write("t\n")
    assert not stale.exists()
    assert not other.exists()  # any write into the folder removes it, not only a write
    # of that same output
    assert alive.exists() and mine.exists()
    assert (tmp_path / "e.csv").read_text() == "t\n"


@pytest.mark.parametrize("status", ["NonIpopt_Exception_Thrown", "User_Requested_Stop"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_an_ipopt_solve_stopped_by_a_signal_raises_it(
    monkeypatch: pytest.MonkeyPatch, status: str, sig: int
) -> None:
    """A Ctrl-C that lands inside IPOPT (CasADi runs the signal handler in IPOPT's
    callbacks, prints a warning, drops the exception and stops IPOPT) is raised from
    the status IPOPT returns, not taken for an unconverged or failed solve. Here the
    real solver runs and reports the status CasADi gives after a signal
    (NonIpopt_Exception_Thrown from an evaluation, User_Requested_Stop from the
    iteration callback)."""
    from continuum_mhe import signals
    from continuum_mhe.estimators.mhe import MovingHorizonEstimator
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.results import Measurement
    from continuum_mhe.settings import MHESettings

    est = MovingHorizonEstimator(make_formulation("bend"), MHESettings(horizon=5, solver="ipopt"))
    real = est.inference._nlp.solver

    class Stopped:  # the real solver; its stats as after a signal inside IPOPT
        def __call__(self, **kwargs: object) -> object:
            return real(**kwargs)

        def stats(self) -> dict[str, object]:
            return {**real.stats(), "return_status": status, "success": False}

    est.inference._nlp = dataclasses.replace(est.inference._nlp, solver=Stopped())
    monkeypatch.setattr(signals, "SIGNALS_SEEN", [sig])
    est.reset()
    with pytest.raises(KeyboardInterrupt) as caught:
        est.step(Measurement(0.0, np.zeros(2)))
    assert caught.type is (Terminated if sig == signal.SIGTERM else KeyboardInterrupt)


#: Script lines that send SIGINT from inside IPOPT once ``signal.setitimer(signal.ITIMER_REAL,
#: 2e-4, 2e-4)`` has started the ticks: CasADi runs Python's signal handlers in IPOPT's
#: callbacks, where the Python frame is CasADi's ``Function.call``; the handler of a
#: tick sends SIGINT there, and CasADi's next check runs the SIGINT handler.
SIGINT_INSIDE_IPOPT = (
    "def tick(signum, frame):\n"
    "    code = frame.f_code if frame is not None else None\n"
    "    if code and code.co_name == 'call' and code.co_filename.endswith('casadi.py'):\n"
    "        signal.setitimer(signal.ITIMER_REAL, 0)\n"
    "        os.kill(os.getpid(), signal.SIGINT)\n"
    "signal.signal(signal.SIGALRM, tick)\n"
)


def test_ctrl_c_while_ipopt_is_timed_ends_the_benchmark(tmp_path: Path) -> None:
    """Ctrl-C during ``benchmark``'s IPOPT run ends the benchmark: the timing loop
    defers the signal to the end of the sample (as ``estimate``'s does), so the
    interrupted solve is no timing sample and the run does not go on: one line after
    the horizon's progress line, exit 130, no JSON written. The SIGINT is sent from
    inside IPOPT during the 30th window's solve (:data:`SIGINT_INSIDE_IPOPT`)."""
    script = (
        "import os, signal, sys\n"
        "from continuum_mhe import cli\n"
        "from continuum_mhe.estimators.mhe import MovingHorizonInference\n"
        "real, solves = MovingHorizonInference._solve_ipopt, []\n"
        "def solve(self, problem, X0):\n"
        "    solves.append(1)\n"
        "    if len(solves) == 30:\n"
        "        signal.setitimer(signal.ITIMER_REAL, 2e-4, 2e-4)\n"
        "    return real(self, problem, X0)\n"
        "MovingHorizonInference._solve_ipopt = solve\n"
        + SIGINT_INSIDE_IPOPT
        + "sys.exit(cli.main(sys.argv[1:]))\n"
    )
    out = tmp_path / "b.json"
    skip = [a for m in ("fast", "mhe-kernel", "do-mpc", "ekf", "ekf-compiled", "ekf-kernel")
            for a in ("--skip", m)]  # fmt: skip
    argv = ["benchmark", "--horizons", "100", "--duration", "20", *skip,
            "--loss-horizons", "none", "--memory-samples", "0", "--json", str(out)]  # fmt: skip
    r = subprocess.run(
        [sys.executable, "-c", script, *argv], capture_output=True, text=True, timeout=SAFETY_S
    )
    progress, interrupted = r.stderr.splitlines()  # the horizon's start, then the end
    assert progress.startswith("continuum-mhe benchmark: N = 100 (1 of 1 horizons)")
    assert (r.returncode, interrupted) == (130, "continuum-mhe: interrupted")
    assert not out.exists()


def test_a_signal_inside_ipopt_waits_for_the_solve() -> None:
    """With the command line's handlers and no deferring loop (a ``reproduce --jobs 1``
    trial), the MHE defers a Ctrl-C that lands inside IPOPT while IPOPT solves: the
    solve ends normally, then the signal is raised, and nothing else is printed (no
    CasADi ``WARNING("KeyboardInterruptException")`` beside our one line). The SIGINT is
    sent from inside IPOPT during the 30th solve (:data:`SIGINT_INSIDE_IPOPT`)."""
    script = (
        "import dataclasses, os, signal, sys\n"
        "from continuum_mhe.estimators.mhe import MovingHorizonEstimator\n"
        "from continuum_mhe.model.registry import make_formulation\n"
        "from continuum_mhe.settings import MHESettings\n"
        "from continuum_mhe.signals import on_signal\n"
        "from continuum_mhe.simulation.scenarios import simulate\n"
        "est = MovingHorizonEstimator(make_formulation('bend'),\n"
        "                             MHESettings(horizon=100, solver='ipopt'))\n"
        "nlp, solves = est.inference._nlp, []\n"
        "def solver(**kwargs):\n"
        "    solves.append(1)\n"
        "    if len(solves) == 30:\n"
        "        signal.setitimer(signal.ITIMER_REAL, 2e-4, 2e-4)\n"
        "    return nlp.solver(**kwargs)\n"
        "solver.stats = nlp.solver.stats\n"
        "est.inference._nlp = dataclasses.replace(nlp, solver=solver)\n"
        "signal.signal(signal.SIGINT, on_signal)\n"
        + SIGINT_INSIDE_IPOPT
        + "rec = simulate('paper3d', duration=20, seed=0)\n"
        "try:\n"
        "    est.run(rec.t, rec.z)\n"
        "except KeyboardInterrupt:\n"
        "    print(len(solves), nlp.solver.stats()['return_status'])\n"
        "    sys.exit(130)\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=SAFETY_S
    )
    assert (r.returncode, r.stdout, r.stderr) == (130, "30 Solve_Succeeded\n", "")
