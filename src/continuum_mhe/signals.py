"""SIGINT and SIGTERM for every command: one flag list and one deferral, shared by the
command line (:mod:`continuum_mhe.cli`) and ``live`` (a neutral module, so that ``live``
needs nothing private from the CLI).

A signal raises at once (``KeyboardInterrupt``, or :class:`Terminated` for SIGTERM)
unless a loop defers it; a deferring loop polls :data:`SIGNALS_SEEN` between two
samples, so a signal never surfaces inside CasADi or numpy code.
"""

from __future__ import annotations

import contextlib
import signal
import sys
from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C (drain, write, clean up), then exit 143."""


#: signals received (a command such as ``live`` drains and returns normally)
SIGNALS_SEEN: list[int] = []

#: non-empty while a loop polls for signals between samples
_DEFER: list[bool] = []


def on_signal(signum: int, frame: object) -> None:
    """The handler of SIGINT and SIGTERM."""
    SIGNALS_SEEN.append(signum)
    if not _DEFER:  # else the loop stops at the next sample, outside any C code
        raise_for_signal()


def raise_for_signal() -> None:
    raise Terminated() if signal.SIGTERM in SIGNALS_SEEN else KeyboardInterrupt()


def quiet_unraisable(
    previous: Callable[[sys.UnraisableHookArgs], object],
) -> Callable[[sys.UnraisableHookArgs], object]:
    """A ``sys.unraisablehook`` for the command line. The handler's KeyboardInterrupt
    raised where Python cannot pass it on (a weakref callback or ``__del__`` that the
    garbage collector runs) would be printed as ``Exception ignored in ...`` with a
    traceback; it is dropped quietly instead: the signal stays in :data:`SIGNALS_SEEN`,
    where the next poll (:func:`raise_if_signalled`) finds it. (Sending the signal again
    from here would only run the handler here.) Anything else goes to ``previous``."""

    def hook(unraisable: sys.UnraisableHookArgs) -> None:
        if not (isinstance(unraisable.exc_value, KeyboardInterrupt) and SIGNALS_SEEN):
            previous(unraisable)

    return hook


def raise_if_signalled() -> None:
    """Raise the signal received so far, if any: a loop's poll between two steps. It also
    catches a signal whose exception was dropped: CasADi's argument checks (SWIG trying
    one overload after another) drop any exception raised inside them, the handler's
    KeyboardInterrupt included, and so does the garbage collector
    (:func:`quiet_unraisable`)."""
    if SIGNALS_SEEN:
        raise_for_signal()


#: IPOPT's return statuses (``stats()["return_status"]`` through CasADi) of a solve that a
#: signal stopped: CasADi runs the Python signal handler inside IPOPT's callbacks; when it
#: raises, CasADi prints only ``WARNING("KeyboardInterruptException")``, drops the
#: exception and stops IPOPT (``NonIpopt_Exception_Thrown`` from an evaluation,
#: ``User_Requested_Stop`` from the iteration callback), which returns as if it had failed
INTERRUPTED_SOLVE = frozenset({"NonIpopt_Exception_Thrown", "User_Requested_Stop"})


def raise_if_solve_interrupted(return_status: str) -> None:
    """Raise the Ctrl-C (:class:`Terminated` after SIGTERM) that stopped an IPOPT solve,
    instead of counting its answer as a failed or unconverged solve."""
    if return_status in INTERRUPTED_SOLVE:
        raise_for_signal()


def interrupt_in_chain(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM behind ``exc`` (itself, or its cause or context: a signal
    raised inside C code can surface as another exception), or None."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt):
            return seen
        seen = seen.__cause__ or seen.__context__
    return None


def defer() -> None:
    """From now on, a signal only sets :data:`SIGNALS_SEEN` (the caller polls it)."""
    _DEFER.append(True)


def stop_deferring() -> None:
    """A signal raises at once again (e.g. a second Ctrl-C while draining)."""
    _DEFER.clear()


def between_samples(samples: Iterable[T]) -> Iterator[T]:
    """``samples``, with SIGINT/SIGTERM deferred while the loop works on one and raised
    before the next: a signal never stops CasADi, IPOPT or numpy code halfway (raised
    there, it can surface as another exception, be caught as a numerical failure, or
    be swallowed by IPOPT as a failed solve)."""
    defer()
    try:
        for sample in samples:
            raise_if_signalled()
            yield sample
    finally:
        stop_deferring()


def interruptible(
    progress: Callable[[Iterable[int]], Iterator[int]] | None,
) -> Callable[[Iterable[int]], Iterator[int]]:
    """Wrap an estimation loop's sample iterator (and its progress bar) so that
    SIGINT/SIGTERM stop it between two samples (:func:`between_samples`)."""

    def wrap(idx: Iterable[int]) -> Iterator[int]:
        return between_samples(progress(idx) if progress is not None else idx)

    return wrap


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """SIGINT/SIGTERM inside the block are raised when it ends (not inside C code); in
    a loop that defers them already (``live`` drains on the first), at its next poll."""
    _DEFER.append(True)
    try:
        yield
    finally:
        if _DEFER:  # (stop_deferring() empties it)
            _DEFER.pop()
    if not _DEFER:
        raise_if_signalled()
