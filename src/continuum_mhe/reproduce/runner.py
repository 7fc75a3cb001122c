"""Run independent trials in parallel: local processes or a Dask distributed cluster.

Results come back in the order of the specs, whatever order they finish in.

Ctrl-C and SIGTERM (a terminal sends Ctrl-C to the whole process group) are the parent's
to handle: a local worker ignores SIGINT and dies quietly on SIGTERM, and the parent,
once interrupted (or when a trial fails), kills its workers instead of waiting for
them, since a worker inside IPOPT, or one that died holding the task queue's lock, may
never come back.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any, TypeVar

from continuum_mhe.errors import UserError
from continuum_mhe.extras import require
from continuum_mhe.signals import raise_if_signalled

S = TypeVar("S")
R = TypeVar("R")


@contextmanager
def _progress(description: str, total: int, enabled: bool | None) -> Iterator[Callable[[], None]]:
    """A rich progress bar (stderr, only on a terminal); yields ``advance()``."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        yield lambda: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    with Progress(
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task(description, total=total)
        yield lambda: bar.advance(task)


def default_jobs() -> int:
    """Worker processes by default: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def run_parallel(
    fn: Callable[[S], R],
    specs: Sequence[S],
    *,
    jobs: int | None = None,
    scheduler: str | None = None,
    description: str = "trials",
    progress: bool | None = None,
) -> list[R]:
    """``[fn(s) for s in specs]``, in parallel.

    ``scheduler``: address of a Dask distributed scheduler (``tcp://host:8786``); the
    trials run there through ``dask.distributed.Client``. Otherwise ``jobs`` local
    processes (default: all CPUs; ``1`` runs in this process). ``fn`` and the specs
    must be picklable (module-level function, frozen dataclasses).
    """
    if jobs is not None and jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {jobs}")
    if scheduler:
        return _run_dask(fn, specs, scheduler, description, progress)
    n_jobs = default_jobs() if jobs is None else jobs
    results: list[Any] = [None] * len(specs)
    with _progress(description, len(specs), progress) as advance:
        if n_jobs == 1 or len(specs) <= 1:
            for i, s in enumerate(specs):
                results[i] = fn(s)
                advance()
                raise_if_signalled()  # a Ctrl-C that CasADi dropped inside the trial
            return results
        pool = ProcessPoolExecutor(
            max_workers=min(n_jobs, len(specs)),
            mp_context=_worker_context(fn),
            initializer=_worker_start,
        )
        try:
            with _signals_blocked():  # the workers start here, with SIGINT/SIGTERM blocked
                futures: dict[Future[R], int] = {pool.submit(fn, s): i for i, s in enumerate(specs)}
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                advance()
        except BrokenProcessPool:  # not a signal of ours: a worker was killed
            _stop_workers(pool)
            raise UserError(
                "a worker process ended abruptly (killed, or out of memory); nothing written"
            ) from None
        except BaseException:
            _stop_workers(pool)
            raise
        pool.shutdown()
    return results


_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_MANAGER_JOIN_S = 10.0  # bound on the wait for the pool's thread after its workers die


@contextmanager
def _signals_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM wait while the block runs (the pool starts its workers and
    its threads), then arrive: the workers inherit the blocked set (from the fork
    server, which does when the first pool of the process starts it here; or from this
    process), so that a Ctrl-C before :func:`_worker_start` runs cannot interrupt a
    worker, and the pool's threads leave every signal to the main thread."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _worker_context(fn: Callable[..., Any]) -> Any:
    """On Linux, workers forked from a server process started afresh (``forkserver``),
    with ``fn``'s module imported there once, never forked from this process: a thread
    of this one (the progress bar's, a test runner's) may hold a lock at that moment,
    such as the stderr buffer's, and a child inherits it held for ever. Elsewhere, and
    for a ``fn`` of ``__main__`` (a script's or an interactive session's, which a
    server's workers cannot import), the platform's default start method (None)."""
    if not sys.platform.startswith("linux") or fn.__module__ == "__main__":
        return None
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([fn.__module__])
    return ctx


def _worker_start() -> None:
    """A worker ignores SIGINT (the parent stops it; inside IPOPT, a handler's
    KeyboardInterrupt would only be dropped) and dies at once and quietly on SIGTERM (no
    traceback, no waiting for a trial to end)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _SIGNALS)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's workers and return without waiting for their trials (what
    ``shutdown(wait=True)`` and a ``with`` block do: a worker may be inside a long IPOPT
    solve, or blocked for ever on a lock a killed one held)."""
    workers = list((pool._processes or {}).values())
    results = getattr(pool._result_queue, "_writer", None)  # the workers' end
    # (shutdown forgets the pool's thread; typeshed types it as its wake-up pipe)
    manager: threading.Thread | None = pool._executor_manager_thread  # type: ignore[assignment]
    pool.shutdown(wait=False, cancel_futures=True)
    for p in workers:
        p.kill()
    for p in workers:
        p.join()
    # the pool's thread may be reading a result a killed worker was sending: with every
    # writer closed (ours is never used) it gets end-of-file instead of waiting for ever
    if results is not None:
        results.close()
    # With its workers dead the pool's thread closes its wake-up pipe and ends. Waited
    # for here, since the interpreter's exit otherwise writes to that pipe while the
    # thread may be closing it (a traceback on stderr after the command's one line).
    if manager is not None:
        manager.join(timeout=_MANAGER_JOIN_S)


def _run_dask(
    fn: Callable[[S], R],
    specs: Sequence[S],
    address: str,
    description: str,
    progress: bool | None,
) -> list[R]:
    require("dask.distributed", "dask", "reproduce --scheduler", package="dask[distributed]")
    from dask.distributed import Client
    from dask.distributed import as_completed as dask_as_completed

    try:
        client = Client(address, timeout="10s")
    except OSError as exc:
        raise UserError(f"cannot reach the Dask scheduler at {address} ({exc})") from None
    results: list[Any] = [None] * len(specs)
    try:
        futures = client.map(fn, list(specs), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        with _progress(description, len(specs), progress) as advance:
            for fut in dask_as_completed(futures):
                results[index[fut.key]] = fut.result()
                advance()
    finally:
        client.close()
    return results
