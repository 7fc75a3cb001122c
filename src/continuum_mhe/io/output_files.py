"""Output files and folders, written so that an error never leaves a partial one.

An output file is written to a temporary file in its folder (``.NAME.PID.XXXXXXXX.tmp``)
and renamed over the target only once complete (:func:`atomic_writer`,
:func:`atomic_binary_writer`); a killed writer's temporary file is removed by the next
writer into that folder once its process is gone. :func:`check_output_target` refuses,
in one line and before any work, a target that cannot be written, and
:func:`refuse_inputs` one that is an input of the command;
:func:`check_new_folder` and :func:`new_files` do the same for a command that writes
several files into a folder; :func:`check_output_target` tries the target's folder
itself (:func:`check_folder_takes`: a read-only file system refuses even root). A
writer that opens its file itself (Rerun) writes to :func:`temporary_beside` and
renames it.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import stat
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from continuum_mhe.errors import InputError, expect_type
from continuum_mhe.signals import raise_if_signalled


def current_umask() -> int:
    """The process's umask now (a new file's mode is ``0o666 & ~umask``): read from
    ``/proc/self/status`` where there is one (it changes nothing), else by setting and
    restoring it."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: Errors of writing that belong to the output file when they carry no file name.
_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS}


def check_output_target(
    path: str | os.PathLike[str], overwrite: bool = True, option: str = "-o"
) -> Path:
    """The output file ``path`` as a :class:`Path`, or a one-line :class:`InputError`:
    ``-``, a name ending in ``/`` (a folder), a missing folder, a directory, a special
    file, a read-only file (never silently replaced), unless ``overwrite`` an existing
    file (the error names ``--overwrite`` and the command's ``option``), or a folder
    that cannot take a new file (:func:`check_folder_takes`). A
    symbolic link stands for the file it points to, which is checked and returned
    (written there, the link stays: ``/dev/stdout`` is not replaced by a file)."""
    expect_type("path", path, (str, os.PathLike), "a file path (a str or pathlib.Path)")
    text = os.fspath(path)
    target = Path(text)
    if text == "-":
        raise InputError("-: writing to standard output is not supported; give a file name")
    if target.is_symlink():
        target = Path(os.path.realpath(target))
        text = os.fspath(target)
    if text.endswith(("/", os.sep)):
        raise InputError(
            f"{text}: names a folder; give a file name, e.g. {text.rstrip('/' + os.sep)}/"
            "estimates.csv"
        )
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{target}: {missing_folder(folder)}")
    if target.is_dir():
        raise InputError(f"{target}: is a directory, expected a file name")
    if target.exists() and not target.is_file():
        raise InputError(f"{target}: not a regular file; give a file name")
    if target.exists() and not overwrite:
        raise InputError(f"{target}: exists; give --overwrite to replace it, or another {option}")
    if target.exists() and not target.stat().st_mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH):
        raise InputError(f"{target}: the file is read-only; not replaced (make it writable "
                         "or remove it)")  # fmt: skip
    check_folder_takes(target)
    return target


def refuse_inputs(
    target: str | os.PathLike[str], inputs: Sequence[tuple[str, str | os.PathLike[str] | None]]
) -> None:
    """A one-line :class:`InputError` when the output ``target`` is one of the command's
    input files (the same file by any name: a link, another path), given as ``(what,
    path)`` pairs such as ``("the tensions file --inputs", args.inputs)``; a path that is
    None, ``-`` or not an existing file (a built-in robot's name) is no file to protect.
    Checked before any work, so that ``--overwrite`` never replaces an input."""
    out = Path(target)
    if not out.exists():
        return
    for what, path in inputs:
        if path is None or os.fspath(path) == "-" or not Path(path).is_file():
            continue
        if os.path.samefile(out, path):
            raise InputError(f"{target}: refusing to overwrite {what}, an input of this command")


def _open_temporary(target: Path) -> tuple[int, str]:
    """A new temporary file beside ``target`` (``.NAME.PID.XXXXXXXX.tmp``, the usual
    mode), open for writing, after removing the stale ones of killed writers; a folder
    that cannot take it is a one-line :class:`InputError` naming ``target``."""
    folder = target.parent if str(target.parent) else Path(".")
    _remove_stale_temporaries(folder)
    try:
        fd, tmp = tempfile.mkstemp(
            prefix=f".{target.name}.{os.getpid()}.", suffix=".tmp", dir=folder
        )
    except OSError as exc:  # name the output, not the temporary file
        raise InputError(f"{target}: cannot write in folder {folder} ({exc.strerror})") from None
    os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp makes 0600: the usual mode
    return fd, tmp


def temporary_beside(target: Path) -> Path:
    """An empty temporary file beside ``target``, named as :func:`atomic_writer` names
    its own (so that a killed writer's is removed by the next one), for a writer that
    opens the file itself (Rerun's .rrd) and renames it over ``target`` when complete;
    a one-line :class:`InputError` where the folder cannot take it."""
    fd, tmp = _open_temporary(target)
    os.close(fd)
    return Path(tmp)


def check_folder_takes(path: str | os.PathLike[str]) -> None:
    """A one-line :class:`InputError`, before any work, where the folder of the output
    ``path`` cannot take a new file (read-only, a read-only file system, no space for
    a file's entry): a file is made there and removed, so the answer is the file
    system's, whoever the user is."""
    target = Path(path)
    fd, tmp = _open_temporary(target)
    os.close(fd)
    try:
        os.unlink(tmp)
    except FileNotFoundError:
        pass
    except OSError as exc:  # an append-only folder: its files are never replaced
        folder = target.parent if str(target.parent) else Path(".")
        raise InputError(
            f"{target}: cannot write in folder {folder} (a file made there cannot be "
            f"removed or replaced: {exc.strerror})"
        ) from None


@contextlib.contextmanager
def _atomic(path: str | os.PathLike[str], binary: bool) -> Iterator[IO[Any]]:
    target = check_output_target(path)
    fd, tmp = _open_temporary(target)
    try:
        try:
            if binary:
                with os.fdopen(fd, "wb") as fb:
                    yield fb
            else:
                with os.fdopen(fd, "w", newline="", encoding="utf-8") as fh:
                    yield fh
            os.replace(tmp, target)
        except OSError as exc:
            if exc.errno in _WRITE_ERRNOS and exc.filename in (None, tmp):
                raise OSError(exc.errno, f"{exc.strerror} (nothing written)", str(target)) from None
            raise
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


#: The temporary file of :func:`_atomic`: ``.NAME.PID.XXXXXXXX.tmp`` (mkstemp's suffix).
_TEMPORARY = re.compile(r"\..+\.(\d+)\.[A-Za-z0-9_]+\.tmp")


def _remove_stale_temporaries(folder: Path) -> None:
    """Remove the ``.NAME.PID.XXXXXXXX.tmp`` files that killed writers (SIGKILL) of any
    output in ``folder`` left, once their process is gone."""
    for stale in folder.glob(".*.tmp"):
        m = _TEMPORARY.fullmatch(stale.name)
        if m is None:
            continue
        pid = int(m.group(1))
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            with contextlib.suppress(OSError):
                stale.unlink()
        except PermissionError:  # alive, another user's
            continue


def atomic_writer(path: str | os.PathLike[str]) -> contextlib.AbstractContextManager[IO[str]]:
    """Open a temporary text file next to ``path``; rename it over ``path`` on success
    only, so an error never leaves a partial file (or touches an existing one)."""
    return _atomic(path, binary=False)


def atomic_binary_writer(
    path: str | os.PathLike[str],
) -> contextlib.AbstractContextManager[IO[bytes]]:
    """Binary counterpart of :func:`atomic_writer`."""
    return _atomic(path, binary=True)


def refuse_missing_parent(folder: Path) -> None:
    """A one-line error where ``folder`` does not exist and neither does the folder it
    would be made in: an output folder is made, but not the folders above it (a mistyped
    path), as an output file's folder must exist."""
    if not folder.exists() and not folder.absolute().parent.is_dir():
        raise InputError(f"{folder}: {missing_folder(folder.parent)}")


def missing_folder(folder: Path) -> str:
    """Why ``folder``, which is not a folder, cannot hold an output: it does not exist,
    or it is a file."""
    if folder.exists():
        return f"{folder} is not a folder"
    return f"folder {folder} does not exist"


def check_new_folder(folder: Path, overwrite: bool, names: Sequence[str]) -> None:
    """A one-line error, before any work, unless ``folder`` is, or can be made, a
    writable folder (in a folder that exists: a mistyped parent is refused as an output
    file's is), and, unless ``overwrite``, holds none of the files ``names`` that the
    command writes."""
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder}: exists and is not a folder")
    refuse_missing_parent(folder)
    taken = next((folder / n for n in names if (folder / n).exists()), None)
    if taken is not None and not overwrite:
        raise InputError(f"{taken}: exists; give --overwrite to replace it, or another --out")
    existing = next(p for p in (folder, *folder.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise InputError(f"{folder}: {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{folder}: {existing} is not writable")


@contextlib.contextmanager
def new_files(folder: Path) -> Iterator[list[Path]]:
    """Create ``folder`` (and missing parents); on any exception (Ctrl-C too), remove
    the files put in the yielded list that did not exist before (each is put there once
    written, atomically), then the folders created here, and re-raise. A file that
    existed keeps its new content if it was replaced, else its old one. A signal whose
    exception a library dropped while the block ran (:func:`.signals.raise_if_signalled`)
    is raised at its end, with the same clean-up."""
    created = [p for p in (folder, *folder.absolute().parents) if not p.exists()]
    before = {p.name for p in folder.iterdir()} if folder.is_dir() else set()
    folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        yield written
        raise_if_signalled()
    except BaseException:
        for path in written:
            if path.name not in before:
                path.unlink(missing_ok=True)
        for made in created:  # innermost first
            with contextlib.suppress(OSError):
                made.rmdir()
        raise
