"""A writable cache folder for numba's compiled kernels, before numba is imported.

numba caches compiled functions next to their source file, else in the user's cache
folder; with neither writable (a read-only install and no writable ``HOME``, as under a
service account) ``@numba.njit(cache=True)`` fails at import and every command would
die. Then a temporary folder is used, said once on stderr. ``NUMBA_CACHE_DIR`` set by
the user is always respected.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path


def writable(folder: Path) -> bool:
    """True if a file can be created in ``folder`` (created if missing)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def ensure_numba_cache_dir() -> str | None:
    """Set ``NUMBA_CACHE_DIR`` to a temporary folder if numba has nowhere to cache;
    returns that folder, or None when nothing had to change."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    source = Path(__file__).resolve().parent / "estimators" / "fast" / "__pycache__"
    home = os.environ.get("HOME") or "/nonexistent"
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path(home) / ".cache") / "numba"
    if writable(source) or writable(user):
        return None
    folder = tempfile.mkdtemp(prefix="continuum-mhe-numba-")
    os.environ["NUMBA_CACHE_DIR"] = folder
    print(
        f"continuum-mhe: note: no writable cache folder for compiled kernels; using {folder} "
        "for this run (set NUMBA_CACHE_DIR to a writable folder to keep them)",
        file=sys.stderr,
    )
    return folder


ensure_numba_cache_dir()  # on import: the package imports this module first
