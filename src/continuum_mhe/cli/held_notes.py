"""Notes and warnings held until a command has found its inputs fit: a refusal is its
one line alone, without the notes said on the way to it."""

from __future__ import annotations

import contextlib
import io
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def said_unless_refused() -> Iterator[None]:
    """Hold what the block writes to the standard error (notes, warnings) and write it
    there when the block ends normally; drop it when the block raises (the refusal's
    one line says the problem)."""
    held = io.StringIO()
    with contextlib.redirect_stderr(held):
        yield
    sys.stderr.write(held.getvalue())
