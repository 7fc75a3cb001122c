"""How a command says the notes and warnings of the library it calls: held until it has
found its inputs fit (a refusal is its one line alone, without the notes said on the
way to it), and a library's own note and warning classes said as the command's lines."""

from __future__ import annotations

import contextlib
import io
import sys
import warnings
from collections.abc import Iterator
from typing import TextIO

from continuum_mhe.cli.program import PROG


@contextlib.contextmanager
def said_unless_refused() -> Iterator[None]:
    """Hold what the block writes to the standard error (notes, warnings) and write it
    there when the block ends normally; drop it when the block raises (the refusal's
    one line says the problem)."""
    held = io.StringIO()
    with contextlib.redirect_stderr(held):
        yield
    sys.stderr.write(held.getvalue())


@contextlib.contextmanager
def said_as_lines(note: type[Warning], warning: type[Warning]) -> Iterator[None]:
    """While the block runs, the library's notes of class ``note`` are said on stderr
    as ``continuum-mhe: note: ...`` and its warnings of class ``warning`` as
    ``continuum-mhe: warning: ...``, when they are raised, whatever the warning filters
    (``-W``, ``PYTHONWARNINGS``) say: they are the command's output, not the library's
    to be filtered. Other warnings are shown as before (:mod:`warnings`' display)."""
    saved = warnings.showwarning

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if issubclass(category, note):
            print(f"{PROG}: note: {message}", file=sys.stderr)
        elif issubclass(category, warning):
            print(f"{PROG}: warning: {message}", file=sys.stderr)
        else:
            saved(message, category, filename, lineno, file, line)

    warnings.showwarning = show
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", note)
            warnings.simplefilter("always", warning)
            yield
    finally:
        warnings.showwarning = saved
