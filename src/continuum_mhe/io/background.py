"""Reading ahead and writing behind in daemon threads, so that a command's input and
output go on while the estimator steps a block in compiled code (which runs without
the GIL): :func:`read_ahead` and :class:`WriteBehind`.

Both keep at most one item waiting, so memory stays flat in the length of the
recording, and both raise a worker's exception in the caller's thread, where the
caller would have met it without them: an input's error after the items before it, an
output's at the next write or at :meth:`WriteBehind.finish`.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Generator, Iterable
from typing import Any, TypeVar

T = TypeVar("T")

#: How often (s) a worker blocked on a full queue looks whether its caller has stopped.
POLL_S = 0.05

_END = object()  # the items are exhausted


def _put(q: queue.Queue[Any], item: Any, stop: threading.Event) -> bool:
    """``item`` into ``q``, waiting while it is full; False (not put) once ``stop`` is set."""
    while not stop.is_set():
        try:
            q.put(item, timeout=POLL_S)
            return True
        except queue.Full:
            continue
    return False


def read_ahead(items: Iterable[T], name: str = "read-ahead") -> Generator[T, None, None]:
    """The items of ``items`` in order, each taken from it in a daemon thread while the
    caller works on the one before (one item read ahead). An exception raised by
    ``items`` is raised here after the items before it. Closing the generator (a
    ``break``, an exception in the caller) stops the thread after the item it is
    reading, and waits for it: ``items`` is free to close then. For inputs whose reads
    end by themselves (files); a pipe that may wait for data would hold the closing."""
    waiting: queue.Queue[tuple[bool, Any]] = queue.Queue(maxsize=1)
    stop = threading.Event()

    def work() -> None:
        try:
            for item in items:
                if not _put(waiting, (True, item), stop):
                    return
            _put(waiting, (True, _END), stop)
        except BaseException as exc:  # raised in the caller's thread  # noqa: BLE001
            _put(waiting, (False, exc), stop)

    worker = threading.Thread(target=work, name=name, daemon=True)
    worker.start()
    try:
        while True:
            ok, item = waiting.get()
            if not ok:
                raise item
            if item is _END:
                return
            yield item
    finally:
        stop.set()
        if threading.current_thread() is not worker:  # (a collector may close it there)
            worker.join()


class WriteBehind:
    """Calls of writing functions run in order in a daemon thread, one waiting at most:
    :meth:`submit` returns as soon as the call before the last one is done. The first
    exception a call raises is raised by the next :meth:`submit` or by :meth:`finish`,
    and no later call runs. Use as a context manager: leaving it waits for every call
    submitted (:meth:`finish`), raising their error where the block itself raised none.

    The worker looks for calls every :data:`POLL_S` as well as when woken: a signal's
    exception in the caller's ``put`` can leave a call queued without the wake-up.
    """

    def __init__(self, name: str = "write-behind") -> None:
        self._calls: queue.Queue[Any] = queue.Queue(maxsize=1)
        self._failed: BaseException | None = None  # the first call's error, set once
        self._said = False  # ... and whether the caller got it
        self._closing = threading.Event()  # no call comes after those queued
        self._done = threading.Event()
        threading.Thread(target=self._work, name=name, daemon=True).start()

    def _work(self) -> None:
        try:
            while not (self._closing.is_set() and self._calls.empty()):
                try:
                    call = self._calls.get(timeout=POLL_S)
                except queue.Empty:
                    continue
                if call is _END:  # finish's wake-up
                    continue
                fn, args = call
                if self._failed is None:  # after a failure the calls are dropped
                    try:
                        fn(*args)
                    except BaseException as exc:  # raised in the caller's thread  # noqa: BLE001
                        self._failed = exc
        finally:
            self._done.set()

    def _raise(self) -> None:
        if self._failed is not None:
            if self._said:
                raise RuntimeError("a write failed before: nothing more is written")
            self._said = True
            raise self._failed

    def submit(self, fn: Callable[..., object], *args: object) -> None:
        """``fn(*args)`` in the worker thread, after the calls submitted before it."""
        self._raise()
        if self._closing.is_set():
            raise RuntimeError("WriteBehind: finished; nothing more is written")
        self._calls.put((fn, args))

    def finish(self) -> None:
        """Wait for every call submitted, then raise the first error one raised (once)."""
        self._closing.set()
        try:
            self._calls.put_nowait(_END)  # wakes the worker now
        except queue.Full:
            pass  # a call is queued: the worker takes it, then sees the closing
        self._done.wait()
        if not self._said:
            self._raise()

    def __enter__(self) -> WriteBehind:
        return self

    def __exit__(self, typ: Any, exc: Any, tb: Any) -> None:
        if typ is None:
            self.finish()
            return
        # the block raised: its exception goes on, once the calls in flight are done
        # (they write to what the caller is about to close)
        self._said = True
        self.finish()
