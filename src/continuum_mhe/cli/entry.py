"""The ``continuum-mhe`` executable's entry point, light on purpose.

``continuum-mhe --help``, ``--version`` and a bare ``continuum-mhe`` are answered here
from a table of the commands, without importing numpy, CasADi or the estimators
(the full command line, :mod:`continuum_mhe.cli.app`, takes seconds to import on a small
machine); everything else goes to :func:`continuum_mhe.cli.app.main`. Both parsers list
the commands of :data:`continuum_mhe.cli.program.COMMANDS`.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from continuum_mhe.cli.program import COMMANDS, DESCRIPTION, PROG, signal_exit, version

__all__ = ["COMMANDS", "DESCRIPTION", "PROG", "main", "overview_parser", "version"]

#: The variable that sets how many threads numpy's BLAS (OpenBLAS) starts. The executable
#: sets it to 1 where it is not set: the estimators' matrices are a few dozen rows, too
#: small for BLAS threads to help, and OpenBLAS's idle threads spin on the cores that the
#: estimator, its reader and its writer threads run on. A value set outside is kept.
BLAS_THREADS_VARIABLE = "OPENBLAS_NUM_THREADS"


def overview_parser() -> argparse.ArgumentParser:
    """The top-level parser with every command listed (and none of their options)."""
    parser = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        sub.add_parser(command.name, help=command.help)
    return parser


def _light(argv: Sequence[str]) -> bool:
    """True when only the overview is asked for: no command word before any option
    other than ``-h``, ``--help`` and ``--version``."""
    return all(a in ("-h", "--help", "--version") for a in argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if _light(args):
        overview_parser().parse_args(args)  # prints help or version and exits
        return 0  # pragma: no cover - argparse exits before
    if argv is None:  # the executable, before numpy loads its BLAS
        os.environ.setdefault(BLAS_THREADS_VARIABLE, "1")
    try:  # Ctrl-C while the full command line imports (seconds): one line, not a traceback
        from continuum_mhe.cli.app import main as full_main

        code = full_main(args)
    except KeyboardInterrupt:  # (SIGTERM before cli.main's handler: killed, quietly)
        return signal_exit()
    if argv is None:  # the executable: its command is done, its output complete
        _ignore_late_signals()
    return code


def _ignore_late_signals() -> None:
    """Ignore SIGTERM and SIGINT from here to the end of the process: the command has
    finished and its status stands. The interpreter's shutdown (freeing CasADi's
    objects) takes a moment, and a signal then killed the process (status -15 after
    complete output) instead of its status."""
    import signal

    for sig in (signal.SIGTERM, signal.SIGINT):
        try:
            signal.signal(sig, signal.SIG_IGN)
        except (ValueError, OSError):  # not the main thread: nothing to change
            pass


if __name__ == "__main__":
    sys.exit(main())
