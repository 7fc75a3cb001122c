"""Files written row by row while a session runs (``live -o`` and ``--record``).

Each row goes to the file in one ``write`` as soon as it exists, so a crash, Ctrl-C or
SIGTERM keeps every row written so far, and every row is whole (a failed write is cut
back to the last whole row). The file is created at the first row: an existing file
is untouched until a row arrives, and replaced (never followed, if it is a symlink)
only with ``overwrite``. Every error names the file.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

from continuum_mhe.errors import InputError
from continuum_mhe.io.output_files import check_folder_takes, current_umask, missing_folder


def check_target(path: str | os.PathLike[str], overwrite: bool, option: str) -> Path:
    """Refuse, before anything starts, a target that cannot or must not be written, or
    whose name says another format than the CSV written (``.csv``, ``.txt`` or none:
    ``X.mcap`` would hold CSV text that the MCAP readers refuse)."""
    p = Path(path)
    if p.suffix.lower() not in (".csv", ".txt", ""):
        raise InputError(f"{p}: {option} writes CSV (.csv or .txt), not {p.suffix}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{p}: {missing_folder(folder)}")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, expected a file name")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{p}: folder {folder} is not writable")
    if os.path.lexists(p):
        if not overwrite:
            raise InputError(f"{p}: exists; give --overwrite to replace it, or another {option}")
        if not (p.is_symlink() or p.is_file()):
            raise InputError(f"{p}: not a regular file; give a file name")
    check_folder_takes(p)  # what the mode does not show (a read-only file system)
    return p


def csv_cell(v: object) -> str:
    """A CSV cell: floats written so that they read back as the same float."""
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError("refusing to write a non-finite number")
        return repr(v)
    return str(v)


class RowFile:
    """A CSV file built row by row (comma-separated, no quoting needed: the cells are
    numbers and simple words).

    Attributes:
        path: the target file.
        rows: data rows written.
        comments: ``#`` lines written above the header (e.g. the options).
    """

    def __init__(
        self, path: Path, header: Sequence[str], overwrite: bool, comments: Sequence[str] = ()
    ) -> None:
        self.path = path
        self.header = "".join(f"# {c}\n" for c in comments) + ",".join(header) + "\n"
        self.overwrite = overwrite
        self.rows = 0
        self._fd: int | None = None
        self._size = 0

    def write_row(self, cells: Sequence[str]) -> None:
        """Append one row (created with the header on the first)."""
        data = (",".join(cells) + "\n").encode("ascii")
        if self._fd is None:
            self._open(self.header.encode("ascii") + data)
        else:
            self._write_whole(data)
        self.rows += 1

    def _open(self, first: bytes) -> None:
        p, folder = self.path, self.path.parent if str(self.path.parent) else Path(".")
        try:
            if self.overwrite:  # a new file renamed over the old one (or its symlink)
                fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=folder)
                try:
                    os.fchmod(fd, 0o666 & ~current_umask())
                    self._fd = fd
                    self._write_whole(first)
                    os.replace(tmp, p)
                except BaseException:
                    self._fd = None
                    os.close(fd)
                    with contextlib.suppress(OSError):
                        os.unlink(tmp)
                    raise
            else:  # never replaces a file that appeared meanwhile, never follows a link
                flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
                self._fd = os.open(p, flags, 0o666)
                self._write_whole(first)
        except FileExistsError:
            raise InputError(
                f"{p}: appeared while waiting for the first sample; not replaced (give --overwrite)"
            ) from None
        except OSError as exc:
            raise InputError(f"{p}: cannot create ({exc.strerror})") from None

    def _write_whole(self, data: bytes) -> None:
        assert self._fd is not None
        done = 0
        try:
            while done < len(data):
                done += os.write(self._fd, data[done:])
        except BaseException as exc:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, self._size)  # keep whole rows only
            if isinstance(exc, OSError):
                raise InputError(
                    f"{self.path}: cannot write ({exc.strerror}); the {self.rows} whole row(s) "
                    "written before are kept"
                ) from None
            raise
        self._size += len(data)

    def mark(self) -> tuple[int, int]:
        """Where the file ends now: ``(rows, bytes)``, for :meth:`cut_back`."""
        return self.rows, self._size

    def cut_back(self, mark: tuple[int, int]) -> None:
        """Remove the rows written after ``mark`` (:meth:`mark`), and the file where no
        row was written before it: rows that must not be read (estimates from readings
        in the wrong units). The file is closed."""
        rows, size = mark
        if self._fd is not None:
            if rows:
                with contextlib.suppress(OSError):
                    os.ftruncate(self._fd, size)
                self._size = size
            self.close()
            if not rows:
                with contextlib.suppress(OSError):
                    os.unlink(self.path)
        self.rows = rows

    def close(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None
