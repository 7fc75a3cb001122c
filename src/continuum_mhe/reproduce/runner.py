"""Run independent trials in parallel: local processes or a Dask distributed cluster.

Results come back in the order of the specs, whatever order they finish in.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any, TypeVar

from continuum_mhe.errors import UserError
from continuum_mhe.extras import require

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
            return results
        with ProcessPoolExecutor(max_workers=min(n_jobs, len(specs))) as pool:
            futures: dict[Future[R], int] = {pool.submit(fn, s): i for i, s in enumerate(specs)}
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                advance()
    return results


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
