"""Estimates written as they come, one row at a time, to a CSV or an MCAP file that
replaces the output only when the run completes (:class:`EstimateSink`). With the
streamed input of :mod:`continuum_mhe.io.inputs`, memory stays flat in the length of
the recording (``tools/memory_study.py``, docs/reliability.md).
"""

from __future__ import annotations

import csv
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.io.estimate_csv import (
    estimate_columns,
    estimate_lines,
    estimate_row,
    format_cells,
)
from continuum_mhe.io.mcap_estimates import NOTES_RECORD, mcap_estimate_writer, sample_messages
from continuum_mhe.io.output_files import atomic_binary_writer, atomic_writer
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.results import Estimate, Status

#: Each status by its string
_STATUS_BY_NAME = {str(m): m for m in Status}


class EstimateSink:
    """Estimates written one at a time to a CSV (or an MCAP for ``.mcap``), atomically:
    use as a context manager; the output appears only when the block completes.

    ``notes`` (``(key, value)`` pairs, each value a TOML value, such as the options the
    estimates are made with) are written before the rows: ``# key = value`` lines above
    the CSV header (the comment block is a TOML document), or the MCAP's
    ``continuum-mhe`` metadata record; :meth:`note` adds one after the rows written so
    far (``partial`` of an interrupted run)."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        formulation: Formulation,
        t0_ns: int = 0,
        outlier: bool = False,
        notes: Sequence[tuple[str, str]] = (),
    ) -> None:
        self.path = path
        self.notes = tuple(notes)
        self.rows = 0  # estimates written
        self.outlier = outlier  # an ``outlier`` column (a robust MHE's flags)
        self.outputs = formulation.outputs
        self.lengths = formulation.robot.lengths
        self.t0_ns = t0_ns
        self.mcap = Path(path).suffix.lower() == ".mcap"
        self._cm: Any = None
        self._write: Callable[[Estimate], None] | None = None
        self._write_rows: Callable[..., None] | None = None  # CSV: a block of rows at once
        #: the time of the last row a block wrote (the next block's must be written after it)
        self._last_t: float | None = None

    def __enter__(self) -> EstimateSink:
        if self.mcap:
            self._cm = atomic_binary_writer(self.path)
            fb: IO[bytes] = self._cm.__enter__()
            writer = mcap_estimate_writer(fb, self.outputs, self.outlier)
            if self.notes:
                writer.metadata(NOTES_RECORD, dict(self.notes))

            def note_mcap(key: str, value: str) -> None:
                writer.metadata(NOTES_RECORD, {key: value})

            self._note: Callable[[str, str], None] = note_mcap
            names = [o.name for o in self.outputs]
            seq = iter(range(sys.maxsize))

            def write_mcap(e: Estimate) -> None:
                flag = e.outlier if self.outlier else None
                for topic, ns, msg in sample_messages(self.outputs, names, float(e.t), e.output,
                                                      str(e.status), float(e.solve_ms),
                                                      self.lengths, self.t0_ns,
                                                      e.output_std, flag):  # fmt: skip
                    writer.add(topic, ns, msg, next(seq))

            self._finish: Callable[[], None] = writer.finish
            self._write = write_mcap
        else:
            self._cm = atomic_writer(self.path)
            fh: IO[str] = self._cm.__enter__()
            w = csv.writer(fh, lineterminator="\n")
            for key, value in self.notes:
                fh.write(f"# {key} = {value}\n")
            w.writerow(estimate_columns(self.outputs, outlier=self.outlier))

            def note_csv(key: str, value: str) -> None:
                fh.write(f"# {key} = {value}\n")

            self._note = note_csv
            ny = len(self.outputs)

            def write_csv(e: Estimate) -> None:
                flag = e.outlier if self.outlier else None
                row = estimate_row(e.t, e.output, str(e.status), e.solve_ms, ny, e.output_std, flag)
                w.writerow(format_cells(self.path, row))

            def write_rows(
                t: FloatArray,
                output: FloatArray,
                output_std: FloatArray,
                outlier: NDArray[np.bool_],
                status: Sequence[str],
                solve_ms: FloatArray,
            ) -> None:
                flags = outlier if self.outlier else None
                fh.write(
                    estimate_lines(
                        self.path,
                        t,
                        output,
                        output_std,
                        flags,
                        status,
                        solve_ms,
                        self._last_t,
                        first_row=self.rows + 1,
                    )
                )
                if len(t):
                    self._last_t = float(t[-1])

            self._finish = lambda: None
            self._write = write_csv
            self._write_rows = write_rows
        return self

    def write_batch(
        self,
        t: FloatArray,
        output: FloatArray,
        output_std: FloatArray,
        outlier: NDArray[np.bool_],
        status: Sequence[str],
        solve_ms: FloatArray,
    ) -> None:
        """Rows of several samples (``t`` (n,) s, ``output`` and ``output_std`` (n, ny),
        NaN where there is none, their outlier flags, statuses and solve times): as
        :meth:`write` of each."""
        if self._write_rows is not None:
            self._write_rows(t, output, output_std, outlier, status, solve_ms)
            self.rows += len(t)
            return
        for i, st in enumerate(status):
            y = None if st == Status.NO_ESTIMATE or np.isnan(output[i]).all() else output[i]
            s = None if y is None or np.isnan(output_std[i]).all() else output_std[i]
            status_i = _STATUS_BY_NAME[str(st)]
            self.write(Estimate(float(t[i]), None, y, None, status_i, float(solve_ms[i]), s,
                                outlier=bool(outlier[i])))  # fmt: skip

    def write(self, estimate: Estimate) -> None:
        assert self._write is not None, "use EstimateSink as a context manager"
        self._write(estimate)
        self.rows += 1

    def note(self, key: str, value: str) -> None:
        """A ``# key = value`` line (``value`` a TOML value) after the rows written so
        far (MCAP: a metadata record)."""
        self._note(key, value)

    def __exit__(self, typ: Any, exc: Any, tb: Any) -> bool | None:
        if typ is None:
            try:
                self._finish()
            except BaseException:
                self._cm.__exit__(*sys.exc_info())  # removes the temporary file
                raise
        return bool(self._cm.__exit__(typ, exc, tb))
