"""Without a writable cache folder numba's cached kernels must not break the tool."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest

from continuum_mhe import numba_cache


def test_no_writable_folder_uses_a_temporary_one(monkeypatch, capsys, tmp_path) -> None:  # type: ignore[no-untyped-def]
    # set first, so that the variable is restored (removed) after the test: a bare
    # ``delenv(..., raising=False)`` of an unset variable records nothing, and the
    # folder set below outlived the test (every later test then looked for the kernels
    # there: the next fast estimator compiled them all again, 70 s of the suite, and
    # the CLI tests' subprocesses compiled theirs on first call)
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # not a folder left in /tmp
    monkeypatch.setattr(numba_cache, "writable", lambda folder: False)
    folder = numba_cache.ensure_numba_cache_dir()
    assert folder is not None and Path(folder).is_dir() and Path(folder).parent == tmp_path
    import os

    assert os.environ["NUMBA_CACHE_DIR"] == folder
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no writable cache folder" in err[0]


def test_a_users_choice_and_a_writable_source_folder_change_nothing(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere")
    assert numba_cache.ensure_numba_cache_dir() is None
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setattr(numba_cache, "writable", lambda folder: True)
    assert numba_cache.ensure_numba_cache_dir() is None


@pytest.mark.parametrize("exists", [True, False])
def test_writable_detects_a_read_only_location(tmp_path: Path, exists: bool) -> None:
    target = tmp_path / "cache" if exists else tmp_path / "file" / "below"
    if not exists:
        (tmp_path / "file").write_text("a file, not a folder")
    assert numba_cache.writable(target) is exists
