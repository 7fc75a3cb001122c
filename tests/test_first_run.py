"""The first run of an install: the fast kernels compile once, and a short command does
not wait for them (``estimators/fast/warmup.py``)."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from continuum_mhe.estimators.fast import warmup

EXE = str(Path(sys.executable).with_name("continuum-mhe"))


def _columns(path: Path) -> dict[str, np.ndarray]:
    with path.open() as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    out = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return out


def _wait_for_exit(pid: int, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except OSError:
            return True
        time.sleep(0.2)
    return False


def test_cold_cli_run_uses_ipopt_and_compiles_in_the_background(tmp_path):
    """With nothing compiled (a fresh numba cache), ``estimate`` says once that it
    compiles in the background, answers with IPOPT (rows ``fallback-ipopt``, the same
    estimates as the fast backend), and the next run finds the kernels compiled."""
    from continuum_mhe.cli import main

    meas, warm, cold, again = (tmp_path / n for n in ("m.csv", "w.csv", "c.csv", "a.csv"))
    # the recording and the reference estimates (the suite's kernels) in this process
    assert main(["simulate", "paper3d", "--duration", "3", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "-o", str(warm)]) == 0
    env = {k: v for k, v in os.environ.items() if k != "CONTINUUM_MHE_FIRST_RUN"}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")  # nothing compiled there
    env["CONTINUUM_MHE_CACHE"] = str(tmp_path / "models")  # no C model either: the
    # background compile caches the defaults' too, so the next run compiles nothing
    r = subprocess.run(
        [EXE, "estimate", str(meas), "-o", str(cold)], env=env, capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    notes = [ln for ln in r.stderr.splitlines() if "first run only" in ln]
    assert len(notes) == 1 and notes[0].startswith("continuum-mhe: note: "), r.stderr
    assert "in the background" in notes[0] and "IPOPT" in notes[0]
    c, w = _columns(cold), _columns(warm)
    assert set(c["status"]) == {"fallback-ipopt"} and set(w["status"]) == {"ok"}
    for col in ("x", "y", "z", "theta"):
        np.testing.assert_allclose(c[col].astype(float), w[col].astype(float), atol=1e-6)
    assert set(c["std_x"]) == {""} and "" not in set(w["std_x"])  # said in the note
    assert "without the MHE's standard deviations" in notes[0]
    pid_files = list((tmp_path / "numba").glob("continuum-mhe-kernels-*.pid"))
    assert len(pid_files) == 1
    pid = int(pid_files[0].read_text())
    try:  # compiling every kernel from nothing: one to two minutes on 2 cores
        assert _wait_for_exit(pid, 600), "the background compile did not end"
    finally:
        try:
            os.killpg(pid, signal.SIGKILL)
        except OSError:
            pass
    assert list((tmp_path / "numba").glob("continuum-mhe-kernels-*.ready"))
    assert not list((tmp_path / "numba").glob("continuum-mhe-kernels-*.pid"))
    # the next run loads the kernels from the cache: no kernel it ran missed it (before,
    # only the absent note was checked, which a silent compile would pass)
    check = (
        "import sys, importlib; from continuum_mhe.cli import main; "
        "from continuum_mhe.estimators.fast.warmup import _KERNEL_MODULES as M; "
        "rc = main(sys.argv[1:]); "
        "ks = [k for m in M for k in vars(importlib.import_module(m)).values() "
        "if hasattr(k, 'stats') and hasattr(k.stats, 'cache_hits')]; "
        "print(rc, sum(sum(k.stats.cache_hits.values()) for k in ks), "
        "sum(sum(k.stats.cache_misses.values()) for k in ks))"
    )
    r = subprocess.run(
        [sys.executable, "-c", check, "estimate", str(meas), "-o", str(again)],
        env=env, capture_output=True, text=True,
    )  # fmt: skip
    assert r.returncode == 0 and "first run only" not in r.stderr, r.stderr
    assert set(_columns(again)["status"]) == {"ok"}
    rc, hits, misses = map(int, r.stdout.split()[-3:])
    assert rc == 0 and hits >= 1 and misses == 0, r.stdout


def test_library_compiles_in_the_foreground_and_says_so_once(tmp_path, monkeypatch):
    """The library waits for the compile (said once as a CompileNotice) and then
    records it, so the next check finds the kernels ready. The compile runs the
    estimators with warnings silenced, building its own C models; the user's own C model
    (here a two-section robot's, the model cache empty) is still said once: before, the
    silenced run had recorded that notice as said, and the user's model compiled in
    silence."""
    from continuum_mhe import make_formulation
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.estimators.fast import codegen
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    monkeypatch.setattr(warmup, "_announced", set())
    # the kernels' recompile is the flush test's (below); here the wait, the notices and
    # the marker (it took a minute of the suite)
    monkeypatch.setattr(warmup, "flush_kernel_caches", lambda: None)
    monkeypatch.setenv("CONTINUUM_MHE_CACHE", str(tmp_path / "cache"))  # no C model cached
    assert not warmup.kernels_ready()
    robot = Robot((Section(0.16), Section(0.14)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        make_estimator("mhe", f)
        make_estimator("ekf", f)
    said = [str(w.message) for w in seen if issubclass(w.category, warmup.CompileNotice)]
    kernels = [m for m in said if "kernels" in m]
    assert len(kernels) == 1 and "first run only" in kernels[0]
    assert said.count(codegen.COMPILING_MODEL) == 1, said
    assert warmup.kernels_ready()


def test_new_c_model_is_announced_once_before_it_compiles(tmp_path):
    """A robot or option set whose C model is not in the model cache yet (here an empty
    ``CONTINUUM_MHE_CACHE``) says so in one line on the run that builds it, and not on
    the next run, which loads it from the cache."""
    from continuum_mhe.cli import main
    from continuum_mhe.estimators.fast.codegen import COMPILING_MODEL

    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0  # the input
    env = {**os.environ, "CONTINUUM_MHE_CACHE": str(tmp_path / "cache")}
    errs = []
    for name in ("first.csv", "second.csv"):
        r = subprocess.run(
            [EXE, "estimate", str(meas), "-o", str(tmp_path / name)],
            env=env,
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0, r.stderr
        errs.append(r.stderr)
    assert errs[0].splitlines().count(f"continuum-mhe: note: {COMPILING_MODEL}") == 1, errs[0]
    assert "compiling" not in errs[1], errs[1]
    assert len(list((tmp_path / "cache").glob("mhe_*.so"))) == 1


def test_background_mode_without_kernels_picks_the_uncompiled_paths(tmp_path, monkeypatch):
    """``first_run="background"`` with nothing compiled: IPOPT for the MHE, the CasADi
    EKF for the EKF, and one background compile (not started twice)."""
    from continuum_mhe import ExtendedKalmanFilter, make_formulation
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.estimators.kalman import CompiledExtendedKalmanFilter

    started: list[int] = []
    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    monkeypatch.setattr(warmup, "_announced", set())
    monkeypatch.setattr(warmup, "start_background_warmup", lambda: started.append(1) or True)
    f = make_formulation("bend")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", warmup.CompileNotice)
        mhe = make_estimator("mhe", f, first_run="background")
        ekf = make_estimator("ekf", f, first_run="background")
    assert mhe._fast is None and "first run only" in (mhe.backend_note or "")
    assert not mhe.reports_covariance
    assert type(ekf) is ExtendedKalmanFilter and not isinstance(ekf, CompiledExtendedKalmanFilter)
    est = mhe.step(__import__("continuum_mhe").Measurement(0.0, np.zeros(2)))
    assert est.status == "fallback-ipopt"
    assert len(started) == 2  # each asks; start_background_warmup runs one process


def test_a_failed_background_compile_is_said_with_its_log(tmp_path, monkeypatch):
    """A background compile that failed left its traceback in the log: the next run
    says so, with the error's last line and the log's path, before it tries again; a
    log of a compile that succeeded, or is still running, is not a failure."""
    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    monkeypatch.setattr(warmup, "start_background_warmup", lambda: True)
    log = warmup.log_path()
    log.write_text("Traceback (most recent call last):\n  ...\nOSError: [Errno 28] No space left\n")
    cases = ((False, False, True), (True, False, False), (False, True, False))
    for running, ready, failed in cases:  # (a compile running, kernels compiled, said)
        monkeypatch.setattr(warmup, "_announced", set())
        monkeypatch.setattr(warmup, "_running", lambda _pid, running=running: running)
        marker = tmp_path / "k.ready"
        marker.unlink(missing_ok=True)
        if ready:
            marker.write_text("compiled\n")
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            warmup.defer_compiling("IPOPT")
        said = [str(w.message) for w in seen if issubclass(w.category, warmup.CompileNotice)]
        told = [m for m in said if "failed" in m]
        if failed:
            assert told == [
                "the last background compile of the kernels failed "
                f"(OSError: [Errno 28] No space left); see {log}"
            ]
        else:
            assert told == []


def _no_compiling_here() -> None:
    raise AssertionError("compiled beside the running background compile")


def test_library_waits_for_a_running_background_compile(tmp_path, monkeypatch):
    """A foreground ``ensure_compiled`` that finds a background compile running (a live
    pid in the pid file: this test's own) says once that it waits, does not compile or
    flush numba's cache beside it, and returns when the marker appears."""
    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    monkeypatch.setattr(warmup, "_announced", set())
    monkeypatch.setattr(warmup, "_POLL_S", 0.01)
    monkeypatch.setattr(warmup, "warm_up", _no_compiling_here)
    warmup.pid_path().write_text(f"{os.getpid()}\n")
    waits: list[float] = []

    def compile_finishes(seconds: float) -> None:  # while the library waits
        waits.append(seconds)
        (tmp_path / "k.ready").write_text("compiled\n")

    clock = SimpleNamespace(sleep=compile_finishes, monotonic=time.monotonic)
    monkeypatch.setattr(warmup, "time", clock)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        warmup.ensure_compiled()
        warmup.ensure_compiled()
    assert waits == [0.01]  # it waited once, then found the marker
    notices = [str(w.message) for w in seen if issubclass(w.category, warmup.CompileNotice)]
    assert notices == [
        "waiting for the background compile of the fast solver's kernels (first run only)"
    ]
    assert warmup.kernels_ready()


def test_library_compiles_when_the_background_compile_dies(tmp_path, monkeypatch):
    """The background compile ends without the marker (killed, crashed): the waiting
    ``ensure_compiled`` compiles in the foreground, holding the pid file meanwhile."""
    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    monkeypatch.setattr(warmup, "_announced", set())
    monkeypatch.setattr(warmup, "_POLL_S", 0.01)
    held: list[str] = []

    def compile_here() -> None:
        held.append(warmup.pid_path().read_text().strip())
        (tmp_path / "k.ready").write_text("compiled\n")

    monkeypatch.setattr(warmup, "warm_up", compile_here)
    # the background compile: alive until its stdin closes, which happens while the
    # library waits for it
    dying = subprocess.Popen(
        [sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE
    )

    def compile_dies(seconds: float) -> None:
        assert dying.stdin is not None
        dying.stdin.close()
        dying.wait(timeout=60)  # reaped: its pid is gone, not a zombie

    clock = SimpleNamespace(sleep=compile_dies, monotonic=time.monotonic)
    monkeypatch.setattr(warmup, "time", clock)
    warmup.pid_path().write_text(f"{dying.pid}\n")
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            warmup.ensure_compiled()
    finally:
        if dying.poll() is None:
            dying.kill()
            dying.wait()
    notices = [str(w.message) for w in seen if issubclass(w.category, warmup.CompileNotice)]
    assert len(notices) == 2
    assert notices[0].startswith("waiting for the background compile")
    assert notices[1].startswith("compiling the fast solver's kernels")
    assert held == [str(os.getpid())] and warmup.kernels_ready()
    assert not warmup.pid_path().exists()


def test_the_pid_file_is_claimed_atomically(tmp_path, monkeypatch):
    """``_claim`` creates the pid file with O_EXCL: it fails while a live process holds
    it (leaving it as it is) and replaces a stale one (its process gone)."""
    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    pid_file = warmup.pid_path()
    assert warmup._claim(pid_file) and pid_file.read_text() == f"{os.getpid()}\n"
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        pid_file.write_text(f"{holder.pid}\n")
        assert not warmup._claim(pid_file)
        assert pid_file.read_text() == f"{holder.pid}\n"
        assert warmup.start_background_warmup()  # one is running: none started
        assert pid_file.read_text() == f"{holder.pid}\n"
    finally:
        holder.kill()
        holder.wait()
    assert warmup._claim(pid_file) and pid_file.read_text() == f"{os.getpid()}\n"


def test_a_background_compile_waits_for_a_foreground_one(tmp_path, monkeypatch):
    """While ``ensure_compiled`` compiles, the pid file names its process, so the command
    line's background start finds a compile running and starts none."""
    monkeypatch.setattr(warmup, "marker_path", lambda: tmp_path / "k.ready")
    monkeypatch.setattr(warmup, "_announced", set())
    monkeypatch.setattr(subprocess, "Popen", lambda *a, **k: _no_compiling_here())
    started: list[bool] = []
    monkeypatch.setattr(warmup, "warm_up", lambda: started.append(warmup.start_background_warmup()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", warmup.CompileNotice)
        warmup.ensure_compiled()
    assert started == [True]


def test_cold_demo_names_the_paths_it_timed_and_its_table_is_not_cut_when_piped(
    tmp_path, monkeypatch, capsys
):
    """The first ``demo`` (kernels compiling in the background) marks the rows that ran
    IPOPT and the CasADi EKF, whose times are theirs, and says why under the table; its
    output, captured as through a pipe (not a terminal, no COLUMNS), keeps whole headers
    instead of rich's 80-column cut (``theta…``)."""
    from continuum_mhe.cli import app, demo
    from continuum_mhe.estimators import mhe

    monkeypatch.setenv("CONTINUUM_MHE_FIRST_RUN", "background")
    monkeypatch.delenv("COLUMNS", raising=False)
    for module in (demo, mhe, warmup):
        monkeypatch.setattr(module, "kernels_ready", lambda: False)
    monkeypatch.setattr(warmup, "start_background_warmup", lambda: True)
    monkeypatch.setattr(warmup, "_announced", set())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", warmup.CompileNotice)
        assert app.main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "…" not in out
    header = next(ln for ln in out.splitlines() if "method" in ln)
    for column in ("tip mean mm", "theta RMSE deg", "phi RMSE deg", "median solve ms"):
        assert column in header
    rows = [ln.split("│")[1].strip() for ln in out.splitlines() if ln.startswith("│")]
    assert rows == ["MHE (IPOPT)", "EKF (CasADi)", "UKF"]
    assert "while the fast solver's kernels compile in the background" in " ".join(out.split())


@pytest.mark.parametrize(
    ("mode", "expected"),
    [("foreground", "foreground"), ("background", "background"), ("other", "foreground")],
)
def test_first_run_mode_from_the_environment(monkeypatch, mode, expected):
    monkeypatch.setenv("CONTINUUM_MHE_FIRST_RUN", mode)
    monkeypatch.setattr(warmup, "_announced", set())
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert warmup.first_run_mode("foreground") == expected
        assert warmup.first_run_mode("background") == (
            "background" if mode == "other" else expected
        )
    said = [str(w.message) for w in seen if issubclass(w.category, warmup.CompileNotice)]
    if mode == "other":  # a typo is said, once, not ignored in silence
        assert said == [
            "CONTINUUM_MHE_FIRST_RUN='other' is neither 'foreground' nor 'background': ignored"
        ]
    else:
        assert said == []


_CALLER = '''
import numba
from callee import f


@numba.njit(cache=True)
def g():
    return f() + 10
'''

_RUN = '''
import sys
sys.path.insert(0, sys.argv[1])
import caller
print(caller.g())
if sys.argv[2] == "flush":
    from continuum_mhe.estimators.fast import warmup
    warmup._KERNEL_MODULES = ("callee", "caller")
    warmup.flush_kernel_caches()
    print(caller.g())
'''


def _callee(value: int) -> str:
    return f"import numba\n\n\n@numba.njit(cache=True)\ndef f():\n    return {value}\n"


@pytest.mark.skipif(
    os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no compiled kernels without numba's JIT"
)
def test_flushing_the_kernel_caches_drops_a_caller_compiled_against_an_old_callee(
    tmp_path: Path,
) -> None:
    """numba checks a cached kernel against its own file only: after the callee's file
    changes, the unchanged caller still loads the old machine code (the first line
    here), which :func:`warmup.flush_kernel_caches` (run by ``warm_up`` whenever the
    kernels' source key changes) replaces."""
    (tmp_path / "caller.py").write_text(_CALLER)
    (tmp_path / "callee.py").write_text(_callee(1))
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}

    def run(mode: str) -> list[str]:
        out = subprocess.run(
            [sys.executable, "-c", _RUN, str(tmp_path), mode],
            capture_output=True, text=True, env=env, check=True,
        )  # fmt: skip
        return out.stdout.split()

    assert run("plain") == ["11"]  # compiled and cached
    (tmp_path / "callee.py").write_text(_callee(2))
    assert run("flush") == ["11", "12"]  # stale from the cache, then recompiled
    assert run("plain") == ["12"]  # and the fresh code is what the cache holds now


def test_going_back_to_an_earlier_source_finds_no_marker(tmp_path, monkeypatch):
    """Before: each source's marker stayed. Compiling source A, then B (which flushes
    and refills numba's cache with B's kernels), then going back to A (a checkout, a
    downgrade) found A's marker: nothing was flushed, and numba loaded callers compiled
    against B's callees, silently (seen with a deliberately broken qp.py reverted). Now
    writing B's marker removes A's, so A compiles again; another install's is kept."""
    monkeypatch.setattr(warmup, "_numba_cache_folder", lambda: tmp_path)
    other_install = tmp_path / "continuum-mhe-kernels-otherplace.ready"
    other_install.write_text("compiled\n/elsewhere/continuum_mhe/estimators/fast\n")
    old_format = tmp_path / "continuum-mhe-kernels-oldformat.ready"
    old_format.write_text("compiled\n")  # no place: may be this install's, so removed
    key = {"now": "A"}
    monkeypatch.setattr(warmup, "kernels_key", lambda: key["now"])
    warmup.write_marker()
    assert warmup.kernels_ready()
    key["now"] = "B"
    assert not warmup.kernels_ready()
    warmup.write_marker()
    key["now"] = "A"
    assert not warmup.kernels_ready()  # A must compile (and flush) again
    key["now"] = "B"
    assert warmup.kernels_ready()
    left = sorted(p.name for p in tmp_path.glob("continuum-mhe-kernels-*.ready"))
    assert left == ["continuum-mhe-kernels-B.ready", other_install.name]
    assert not list(tmp_path.glob(".*.tmp"))
