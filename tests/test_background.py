"""Reading ahead and writing behind (continuum_mhe.io.background), and estimate's use of
them: the same rows as a read without them."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.cli import estimate as estimate_command
from continuum_mhe.cli import main
from continuum_mhe.io.background import WriteBehind, read_ahead
from continuum_mhe.io.estimate_csv import write_measurements
from continuum_mhe.simulation.scenarios import simulate


def _threads(name: str) -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == name]


def test_read_ahead_gives_every_item_in_order() -> None:
    assert list(read_ahead(iter(range(100)), "t-order")) == list(range(100))
    assert list(read_ahead([], "t-empty")) == []
    assert not _threads("t-order") and not _threads("t-empty")


def test_read_ahead_raises_the_input_error_after_the_items_before_it() -> None:
    def items() -> Iterator[int]:
        yield 1
        yield 2
        raise ValueError("line 3: not a number")

    got = []
    with pytest.raises(ValueError, match="line 3"):
        for item in read_ahead(items(), "t-error"):
            got.append(item)
    assert got == [1, 2]


def test_read_ahead_closed_early_stops_its_reader() -> None:
    read = []

    def endless() -> Iterator[int]:
        k = 0
        while True:
            read.append(k)
            yield k
            k += 1

    gen = read_ahead(endless(), "t-close")
    assert [next(gen) for _ in range(3)] == [0, 1, 2]
    gen.close()
    assert not _threads("t-close")  # joined on close
    assert len(read) <= 5  # one item waiting, one being read: not the whole input


def test_write_behind_runs_the_calls_in_order_and_finish_waits_for_them() -> None:
    done: list[int] = []
    with WriteBehind("t-writer") as w:
        for k in range(50):
            w.submit(done.append, k)
    assert done == list(range(50))
    assert not _threads("t-writer")


def test_write_behind_raises_the_first_error_once_and_drops_later_calls() -> None:
    done: list[int] = []

    def write(k: int) -> None:
        if k == 2:
            raise OSError(28, "No space left on device")
        done.append(k)

    w = WriteBehind("t-fail")
    w.submit(write, 1)
    w.submit(write, 2)
    with pytest.raises(OSError, match="No space left"):
        for k in range(3, 100):  # a later submit raises it
            w.submit(write, k)
    with pytest.raises(RuntimeError, match="a write failed before"):
        w.submit(write, 100)
    w.finish()  # said once: not again
    assert done == [1]


def test_write_behind_error_at_finish() -> None:
    w = WriteBehind("t-finish")
    w.submit(lambda: (_ for _ in ()).throw(OSError(5, "Input/output error")))
    with pytest.raises(OSError, match="Input/output"):
        w.finish()


def test_write_behind_keeps_the_blocks_exception_and_finishes_its_calls() -> None:
    done: list[int] = []
    with pytest.raises(KeyError):
        with WriteBehind("t-block") as w:
            w.submit(done.append, 1)
            w.submit(lambda: (_ for _ in ()).throw(OSError(5, "I/O")))
            raise KeyError("the block's own error")
    assert done == [1]
    assert not _threads("t-block")


def test_estimate_reads_ahead_and_writes_behind_the_same_rows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file of several blocks (1024 samples each) read ahead and written behind, and
    the same file read in turn (as standard input is): the same estimates."""
    rec = simulate("paper3d", duration=150, noise_deg=2.0, seed=3)  # 3001 samples
    src = tmp_path / "m.csv"
    write_measurements(src, rec.t, rec.z)
    out_file, out_pipe = tmp_path / "file.csv", tmp_path / "pipe.csv"
    assert main(["estimate", str(src), "-o", str(out_file)]) == 0
    monkeypatch.setattr(estimate_command, "_reads_ahead", lambda source: False)
    assert main(["estimate", str(src), "-o", str(out_pipe)]) == 0

    def rows(path: Path) -> np.ndarray:
        lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
        header = lines[0].split(",")
        keep = [i for i, h in enumerate(header) if h != "solve_ms"]
        return np.array([[r.split(",")[i] for i in keep] for r in lines[1:]])

    a, b = rows(out_file), rows(out_pipe)
    assert a.shape == (3001, b.shape[1])
    np.testing.assert_array_equal(a, b)


def test_estimate_reads_ahead_only_what_ends_by_itself(tmp_path: Path) -> None:
    src = tmp_path / "m.csv"
    src.write_text("t,roll,pitch\n0,0,0\n")
    assert estimate_command._reads_ahead(str(src))
    assert estimate_command._reads_ahead(str(tmp_path))  # a bag folder
    assert not estimate_command._reads_ahead("-")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert not estimate_command._reads_ahead(str(fifo))


def test_write_behind_runs_a_call_queued_without_its_wake_up() -> None:
    """A signal's exception in the caller between a call's queueing and the worker's
    wake-up (``Condition.notify``) leaves the call queued: the worker finds it at its
    next look, and ``finish`` returns (a thread here, so that a hang fails the test
    instead of holding the suite)."""
    done: list[int] = []
    w = WriteBehind("t-wake")
    cond = w._calls.not_empty
    wake = cond.notify

    def interrupted(n: int = 1) -> None:
        cond.notify = wake  # type: ignore[method-assign]
        raise KeyboardInterrupt

    cond.notify = interrupted  # type: ignore[method-assign]
    with pytest.raises(KeyboardInterrupt):
        w.submit(done.append, 1)
    finisher = threading.Thread(target=w.finish, daemon=True)
    finisher.start()
    finisher.join(60)
    assert not finisher.is_alive()
    assert done == [1]


def test_estimate_interrupted_stops_its_reader_and_keeps_the_rows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An interrupt in the second block (as Ctrl-C there): the rows of the first are
    kept and marked partial, and the reader thread has stopped when the command
    returns (the input it reads is closed then)."""
    from continuum_mhe.estimators.sensor_health import Estimator

    rec = simulate("paper3d", duration=250, noise_deg=2.0, seed=3)  # 5001 samples
    src = tmp_path / "m.csv"
    write_measurements(src, rec.t, rec.z)
    calls = [0]
    step_blocks = Estimator.continue_run

    def interrupted(self: Estimator, *args: object, **kwargs: object) -> object:
        calls[0] += 1
        if calls[0] == 2:
            raise KeyboardInterrupt
        return step_blocks(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Estimator, "continue_run", interrupted)
    out = tmp_path / "e.csv"
    assert main(["estimate", str(src), "-o", str(out)]) == 130
    assert not _threads("estimate-reader") and not _threads("estimate-writer")
    text = out.read_text()
    rows = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    assert len(rows) == 1 + 1024  # the header and the first block
    assert '# partial = "interrupted after 1024 samples' in text


@pytest.fixture
def signals_cleared() -> Iterator[list[threading.Timer]]:
    """Timers that a test starts, joined, and the signals the command line recorded,
    forgotten, when the test ends (the next test in this process starts without them)."""
    from continuum_mhe.signals import SIGNALS_SEEN

    timers: list[threading.Timer] = []
    yield timers
    for timer in timers:
        timer.join()
    SIGNALS_SEEN.clear()


def _interrupting_second_block(
    monkeypatch: pytest.MonkeyPatch, timers: list[threading.Timer], after_s: float = 0.0
) -> None:
    """A SIGINT in the second block's ``continue_run`` (as from Ctrl-C while the block
    is estimated), ``after_s`` after it starts (0: before), as the command line's
    handler takes it while a block is estimated: recorded in ``SIGNALS_SEEN`` for the
    loop to raise. (A real signal would reach the test runner's thread too.)"""
    import signal

    from continuum_mhe.estimators.sensor_health import Estimator
    from continuum_mhe.signals import SIGNALS_SEEN

    calls = [0]
    step_blocks = Estimator.continue_run

    def signalled(self: Estimator, *args: object, **kwargs: object) -> object:
        calls[0] += 1
        if calls[0] == 2:
            if after_s:
                timers.append(threading.Timer(after_s, SIGNALS_SEEN.append, (signal.SIGINT,)))
                timers[-1].start()
            else:
                SIGNALS_SEEN.append(signal.SIGINT)
        return step_blocks(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Estimator, "continue_run", signalled)


@pytest.mark.parametrize("after_s", [0.0, 0.02])
def test_estimate_signal_in_a_block_keeps_what_was_stepped(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    signals_cleared: list[threading.Timer],
    after_s: float,
) -> None:
    """A deferred signal stops the block between two samples (before its first, in the
    compiled UKF's block, or some way into the MHE on IPOPT's slow one, milliseconds a
    sample): the rows stepped are written and counted alike, the note's time is the
    last row's, and the command ends as interrupted. (Blocks of 256 samples here, not
    1024: IPOPT steps the whole first block, in 2.5 s instead of 10.)"""
    rec = simulate("paper3d", duration=250, noise_deg=2.0, seed=3)
    src = tmp_path / "m.csv"
    write_measurements(src, rec.t, rec.z)
    block = 256
    monkeypatch.setattr(estimate_command, "BLOCK", block)
    _interrupting_second_block(monkeypatch, signals_cleared, after_s)
    out = tmp_path / "e.csv"
    method = (
        ["--method", "mhe", "--solver", "ipopt", "--horizon", "5"]
        if after_s
        else ["--method", "ukf"]
    )
    assert main(["estimate", str(src), "-o", str(out), *method]) == 130
    text = out.read_text()
    rows = [ln for ln in text.splitlines() if ln and not ln.startswith("#")][1:]
    if after_s:
        assert block < len(rows) < 2 * block  # part of the second block
    else:
        assert len(rows) == block
    last = rows[-1].split(",")[0]
    assert f'# partial = "interrupted after {len(rows)} samples, at t = {last} s"' in text
    assert f"kept the {len(rows)} estimates" in capsys.readouterr().err


def test_estimate_write_error_after_a_signal_is_said(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    signals_cleared: list[threading.Timer],
) -> None:
    """The disk fills while an interrupted run writes what it keeps: the file system's
    error is said (one line, the file named) as well as the interruption, and nothing is
    left."""
    import errno

    from continuum_mhe.io.estimate_sink import EstimateSink

    rec = simulate("paper3d", duration=250, noise_deg=2.0, seed=3)
    src = tmp_path / "m.csv"
    write_measurements(src, rec.t, rec.z)
    out = tmp_path / "e.csv"

    def full(self: EstimateSink, *args: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", str(out))

    monkeypatch.setattr(EstimateSink, "write_batch", full)
    _interrupting_second_block(monkeypatch, signals_cleared)
    assert main(["estimate", str(src), "-o", str(out)]) == 130
    err = capsys.readouterr().err
    assert f"error: {out}: No space left on device" in err
    assert not out.exists() and not list(tmp_path.glob(".e.csv*"))
