"""``estimate`` as a stream: samples in and estimate rows out, one at a time.

A CSV input (tilt or raw, a file, ``-``, a pipe or a FIFO) is read once, front to
back, in chunks of :data:`CHUNK` rows; estimates are written as they come to a
temporary file that replaces the output only when the run completes. Memory stays
flat in the length of the recording (``tools/memory_study.py``, docs/reliability.md).
ROS bags and MCAP inputs are read whole (their readers index the file).
"""

from __future__ import annotations

import csv
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from continuum_mhe.io.csv_files import (
    FloatArray,
    ReadingCounts,
    atomic_binary_writer,
    atomic_writer,
    check_time_units,
    estimate_columns,
    estimate_row,
    format_cells,
    tilt_sample_columns,
    tilt_values,
)
from continuum_mhe.io.input_options import (
    EstimateInput,
    InputOptions,
    check_mounting,
    check_options_apply,
    formulation_for,
    imu_settings_for,
    load_log_input,
    with_imu_model,
)
from continuum_mhe.io.mcap_estimates import mcap_estimate_writer, sample_messages
from continuum_mhe.io.raw_imu import RawImuConverter, raw_blocks, raw_layout, sample_kind
from continuum_mhe.io.robot_logs import is_robot_log
from continuum_mhe.io.text_rows import InputError, RowProblems, TextRows, iter_samples, open_rows
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.results import Estimate

#: Rows validated and converted together (bounds the memory of a streamed input).
CHUNK = 4096

Convert = Callable[[FloatArray, FloatArray, Sequence[int]], FloatArray]


@dataclass
class SampleStream:
    """Measurements of one input, produced one at a time.

    Attributes:
        name: the input as shown in messages.
        kind: ``"tilt-csv"``, ``"raw-csv"`` or ``"log"``.
        formulation: the formulation the measurements are for.
        samples: ``(t, z)``: s, (nz,) measurement; read once.
        problems: rows skipped with ``skip_bad`` (count and the first few).
        t0_ns: absolute time of ``t = 0``, ns (0 for CSV input).
        notes: lines for the user about how the input was read (e.g. how the samples
            of several IMU topics paired).
        readings: which IMUs reported, counted as the samples are read (once they are
            all read, a :class:`DropoutWarning` names an IMU that never reported).
    """

    name: str
    kind: str
    formulation: Formulation
    samples: Iterator[tuple[float, FloatArray]]
    problems: RowProblems = field(default_factory=RowProblems)
    t0_ns: int = 0
    _rows: TextRows | None = None
    notes: tuple[str, ...] = ()
    readings: ReadingCounts | None = None

    def close(self) -> None:
        if self._rows is not None:
            self._rows.close()

    def __enter__(self) -> SampleStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_estimate_input(
    path: str | os.PathLike[str], options: InputOptions, formulation: Formulation
) -> SampleStream:
    """Open any input of ``estimate`` (tilt or raw CSV, ``-``, bag, MCAP) as a stream."""
    if str(path) != "-" and is_robot_log(Path(path)):
        data = load_log_input(Path(path), options, formulation)
        problems = RowProblems(len(data.skipped), data.skipped[:20], dropped=len(data.skipped))
        check_mounting(str(path), data.z, data.formulation)
        readings = _readings(data.formulation)
        readings.add(data.z)
        readings.warn_silent(str(path))
        pairs = zip(data.t.tolist(), data.z)
        return SampleStream(
            str(path), data.kind, data.formulation, pairs, problems, data.t0_ns,
            notes=tuple(data.notes), readings=readings,
        )  # fmt: skip
    if str(path) != "-" and Path(path).is_dir():  # not a bag folder: is_robot_log said so
        raise InputError(
            f"{path}: is a directory without metadata.yaml, expected a CSV file or a ROS 2 "
            "bag folder"
        )
    rows = open_rows(path)
    try:
        return _csv_stream(rows, options, formulation)
    except BaseException:
        rows.close()
        raise


def load_estimate_input(
    path: str | os.PathLike[str], options: InputOptions, formulation: Formulation
) -> EstimateInput:
    """Read any supported input (tilt CSV, raw CSV, bag, MCAP) whole, as measurements."""
    p = Path(path)
    if is_robot_log(p):
        return load_log_input(p, options, formulation)
    with open_estimate_input(path, options, formulation) as stream:
        stream.problems.keep = sys.maxsize
        pairs = list(stream.samples)
    t = np.array([tv for tv, _ in pairs], dtype=float)
    z = np.array([zv for _, zv in pairs], dtype=float).reshape(len(t), stream.formulation.nz)
    return EstimateInput(stream.kind, t, z, stream.formulation, 0, stream.problems.first)


def _csv_stream(rows: TextRows, options: InputOptions, base: Formulation) -> SampleStream:
    n_imus, name = base.robot.n_imus, rows.name
    problems = RowProblems()
    convert: Convert
    if sample_kind(rows) == "raw":
        cols, has_gyro = raw_layout(rows, n_imus)
        options = with_imu_model(options, base, True, has_gyro)
        f = formulation_for(options, base, True, Path(name))
        check_options_apply(name, "raw-csv", options, base.robot)
        if options.raw.needs_gyro and not has_gyro:
            what = "--imu-model direct" if options.raw.imu_model == "direct" else (
                f"--attitude {options.raw.attitude}")  # fmt: skip
            raise InputError(f"{name}: {what} needs gyro columns gx, gy, gz")
        settings = [imu_settings_for(options.raw, place) for place in base.robot.imus]  # as live
        convs = [RawImuConverter(s) for s in settings]

        def convert(t: FloatArray, values: FloatArray, lines: Sequence[int]) -> FloatArray:
            blocks = raw_blocks(
                name, values, lines, n_imus, has_gyro, options.skip_bad, problems,
                options.raw.needs_gyro,
            )  # fmt: skip
            parts = []
            for conv, (acc, gyr) in zip(convs, blocks):
                parts.append(np.array([
                    conv.convert(float(t[i]), acc[i], None if gyr is None else gyr[i])
                    for i in range(len(t))
                ]).reshape(len(t), conv.nz))  # fmt: skip
            return np.hstack(parts)

        kind = "raw-csv"
    else:
        if n_imus > 1 and options.raw.imu_model == "direct":
            raise InputError(f"{name}: --imu-model direct needs raw accelerometer and gyro input")
        cols = tilt_sample_columns(rows, n_imus)
        f = formulation_for(options, base, False, Path(name))
        check_options_apply(name, "tilt-csv", options, base.robot)

        def convert(t: FloatArray, values: FloatArray, lines: Sequence[int]) -> FloatArray:
            return tilt_values(name, values, lines, options.degrees, n_imus)

        kind = "tilt-csv"
    found = iter_samples(
        rows, cols, skip_bad=options.skip_bad, empty_is_dropout=n_imus > 1, problems=problems
    )
    readings = _readings(f)
    samples = _chunked(rows, found, convert, readings, f)
    return SampleStream(name, kind, f, samples, problems, 0, rows, readings=readings)


def _readings(formulation: Formulation) -> ReadingCounts:
    return ReadingCounts(tuple(b.slice for b in formulation.measurement_blocks))


def _chunked(
    rows: TextRows,
    found: Iterator[tuple[int, float, list[float]]],
    convert: Convert,
    readings: ReadingCounts,
    formulation: Formulation,
) -> Iterator[tuple[float, FloatArray]]:
    """Validate and convert :data:`CHUNK` rows at a time; yield one sample at a time.
    Counts which IMUs reported in ``readings``, and warns at the end for one that never
    did. The first chunk's readings are checked against the robot's mounting
    (:func:`~continuum_mhe.io.input_options.check_mounting`)."""
    first = first_z = True
    while True:
        chunk = [r for _, r in zip(range(CHUNK), found)]
        if not chunk:
            readings.warn_silent(rows.name)
            return
        lines = [c[0] for c in chunk]
        t = np.array([c[1] for c in chunk], dtype=float)
        values = np.array([c[2] for c in chunk], dtype=float).reshape(len(chunk), -1)
        del chunk
        if first:
            check_time_units(rows, t)
            first = False
        z = convert(t, values, lines)
        if first_z:
            check_mounting(rows.name, z, formulation)
            first_z = False
        readings.add(z)
        for i, tv in enumerate(t.tolist()):
            yield tv, z[i]


#: the MCAP metadata record of an estimate file's notes (options, partial)
NOTES_RECORD = "continuum-mhe"


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
        self._write: Callable[[Sequence[Estimate]], None] | None = None

    def __enter__(self) -> EstimateSink:
        if self.mcap:
            self._cm = atomic_binary_writer(self.path)
            fb: IO[bytes] = self._cm.__enter__()
            writer = mcap_estimate_writer(fb)
            if self.notes:
                writer.metadata(NOTES_RECORD, dict(self.notes))

            def note_mcap(key: str, value: str) -> None:
                writer.metadata(NOTES_RECORD, {key: value})

            self._note: Callable[[str, str], None] = note_mcap
            names = [o.name for o in self.outputs]
            seq = iter(range(sys.maxsize))

            def write_mcap(estimates: Sequence[Estimate]) -> None:
                for e in estimates:
                    for topic, ns, msg in sample_messages(self.outputs, names, float(e.t),
                                                          e.output, str(e.status),
                                                          float(e.solve_ms), self.lengths,
                                                          self.t0_ns, e.output_std):  # fmt: skip
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

            def write_csv(estimates: Sequence[Estimate]) -> None:
                outlier, path = self.outlier, self.path
                w.writerows(
                    format_cells(path, estimate_row(e.t, e.output, str(e.status), e.solve_ms,
                                                    ny, e.output_std,
                                                    e.outlier if outlier else None))
                    for e in estimates
                )  # fmt: skip

            self._finish = lambda: None
            self._write = write_csv
        return self

    def write(self, estimate: Estimate) -> None:
        """Write one estimate."""
        self.write_many((estimate,))

    def write_many(self, estimates: Sequence[Estimate]) -> None:
        """Write estimates, in order."""
        assert self._write is not None, "use EstimateSink as a context manager"
        self._write(estimates)
        self.rows += len(estimates)

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
