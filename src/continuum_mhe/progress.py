"""rich output: progress bars (shown only when stderr is a terminal) and the console
that prints tables."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    from rich.console import Console

T = TypeVar("T")


def progress_bar(
    description: str, enabled: bool | None = None
) -> Callable[[Iterable[T]], Iterator[T]] | None:
    """A wrapper that shows a progress bar over an iterable, or None when off.

    ``enabled=None`` turns it on only when stderr is a terminal.
    """
    if enabled is None:
        enabled = sys.stderr is not None and sys.stderr.isatty()
    if not enabled:
        return None

    from rich.console import Console  # imported where a bar is shown: rich takes a while
    from rich.progress import track

    def wrap(it: Iterable[T]) -> Iterator[T]:
        total = len(it) if hasattr(it, "__len__") else None  # type: ignore[arg-type]
        yield from track(
            it,
            description=description,
            total=total,
            transient=True,
            console=Console(stderr=True),
        )

    return wrap


#: the width of printed tables when stdout is not a terminal and COLUMNS is not set
#: (rich's default there is 80, which cuts headers of wide tables to ``theta…``)
PIPED_WIDTH = 1000


def table_console() -> Console:
    """A console on stdout for tables: the terminal's width, ``$COLUMNS`` where set, else
    (piped, logged) wide enough that no column is cut. Text is printed as it is: no
    console markup (``pip install 'continuum-mhe[peers]'`` keeps its brackets)."""
    from rich.console import Console

    console = Console(markup=False)
    if not console.is_terminal and not os.environ.get("COLUMNS"):
        console.width = PIPED_WIDTH
    return console
