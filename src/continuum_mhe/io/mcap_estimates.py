"""Estimates as MCAP, next to the robot's other topics in Foxglove.

``write_estimates_mcap`` writes JSON-encoded channels: ``/continuum/tip``
(``foxglove.PoseInFrame``, frame ``continuum_base``), ``/continuum/backbone``
(``foxglove.PosesInFrame``, poses along the backbone: :func:`estimate_poses`) and
``/continuum/estimate`` (the estimate CSV's fields); ``read_estimates_mcap`` and
``read_estimate_table_mcap`` read them back.
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.extras import require
from continuum_mhe.io.estimate_csv import STD_PREFIX
from continuum_mhe.io.output_files import atomic_binary_writer
from continuum_mhe.io.robot_logs import cut_short
from continuum_mhe.io.state_tables import StateTable
from continuum_mhe.model.descriptions import OutputSpec, section_bends, section_end_indices
from continuum_mhe.model.pcc import backbone_frames
from continuum_mhe.model.robot import Section
from continuum_mhe.results import STATUS_MEANINGS, EstimateSeries

BASE_FRAME = "continuum_base"


_TIME = {
    "type": "object",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
}
_VEC = {
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z")},
}
_QUAT = {
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z", "w")},
}
_POSE = {"type": "object", "properties": {"position": _VEC, "orientation": _QUAT}}
SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.PoseInFrame": {
        "title": "foxglove.PoseInFrame",
        "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE},
    },
    "foxglove.PosesInFrame": {
        "title": "foxglove.PosesInFrame",
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "poses": {"type": "array", "items": _POSE},
        },
    },
}
ESTIMATE_SCHEMA = "continuum_mhe.Estimate"
TOPICS = {
    "/continuum/tip": "foxglove.PoseInFrame",
    "/continuum/backbone": "foxglove.PosesInFrame",
    "/continuum/estimate": ESTIMATE_SCHEMA,
}


#: the ``/continuum/estimate`` field of a robust MHE's flags, as the estimate CSV's column
OUTLIER_FIELD = "outlier"


def estimate_schema(outputs: Sequence[OutputSpec], outlier: bool = False) -> dict[str, Any]:
    """The JSON schema of ``/continuum/estimate``: the estimate CSV's fields for these
    ``outputs`` (each with its unit), their ``std_`` fields, ``outlier`` (with
    ``outlier``: a robust MHE's flags), ``status`` and ``solve_ms``."""
    number = {"type": ["number", "null"]}
    fields: dict[str, Any] = {"t": {**number, "description": "s"}}
    for o in outputs:
        fields[o.name] = {**number, "description": o.unit}
    for o in outputs:
        fields[STD_PREFIX + o.name] = {**number, "description": f"{o.unit}, one std"}
    if outlier:
        fields[OUTLIER_FIELD] = {
            "type": "integer",
            "enum": [0, 1],
            "description": "1 where the robust cost down-weighted the reading",
        }
    return {
        "title": ESTIMATE_SCHEMA,
        "description": "Estimate CSV row: output fields null without an estimate, std_ "
        "fields (one standard deviation) null where unknown",
        "type": "object",
        "properties": {
            **fields,
            "status": {"type": "string"},
            "solve_ms": {"type": "number", "description": "ms"},
        },
    }


def backbone_poses(
    bends: FloatArray, lengths: Sequence[float], per_section: int = 10
) -> list[dict[str, Any]]:
    """Poses along the PCC backbone from base to tip (bends (n_sections, 2) rad,
    lengths m), Foxglove JSON: the base, then ``per_section`` poses per section."""
    from scipy.spatial.transform import Rotation

    rots, positions = backbone_frames(bends, lengths, per_section)
    quats = Rotation.from_matrix(rots).as_quat()  # (x, y, z, w)
    return [
        {
            "position": dict(zip("xyz", map(float, p))),
            "orientation": dict(zip("xyzw", map(float, q))),
        }
        for p, q in zip(positions, quats)
    ]


def _twist(psi: float) -> FloatArray:
    """The rotation by ``psi`` rad about the backbone's tangent (the frame's z axis)."""
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def estimate_poses(
    outputs: Sequence[OutputSpec],
    values: Sequence[float] | FloatArray,
    lengths: Sequence[float],
    per_section: int = 10,
) -> list[dict[str, Any]]:
    """Poses along the backbone of one estimate row, base to tip, Foxglove JSON: the
    base, then ``per_section`` poses per section, the last the tip.

    A robot of constant-curvature sections: its arcs (:func:`backbone_poses`). A tendon
    robot (outputs ``psi_k``), whose sections are not arcs: each section's end frame is
    the one below's turned by the section's bend ``theta_k, phi_k`` and twist ``psi_k``
    (``R(theta_k, phi_k) Rz(psi_k)``, as its outputs are defined) and its end is the
    estimated ``x_k, y_k, z_k``, so the tip pose is the estimate's tip; between them the
    arc of the bend, the twist growing along it, bent by the arc's miss of the
    estimated end in proportion to the arc length."""
    bends = section_bends(outputs, values)
    names = [o.name for o in outputs]
    if "psi_1" not in names:
        return backbone_poses(bends, lengths, per_section)
    from scipy.spatial.transform import Rotation

    rotations, positions = [np.eye(3)], [np.zeros(3)]
    for k in range(len(bends)):
        local_r, local_p = backbone_frames(bends[k : k + 1], [lengths[k]], per_section)
        psi = float(values[names.index(f"psi_{k + 1}")])
        end = np.array([float(values[i]) for i in section_end_indices(outputs, k + 1)])
        base_r, base_p = rotations[-1], positions[-1]
        miss = end - (base_p + base_r @ local_p[-1])
        for j in range(1, per_section + 1):
            f = j / per_section
            rotations.append(base_r @ local_r[j] @ _twist(psi * f))
            positions.append(base_p + base_r @ local_p[j] + f * miss)
        positions[-1] = end  # exactly the estimate's
    quats = Rotation.from_matrix(np.array(rotations)).as_quat()  # (x, y, z, w)
    return [
        {
            "position": dict(zip("xyz", map(float, p))),
            "orientation": dict(zip("xyzw", map(float, q))),
        }
        for p, q in zip(positions, quats)
    ]


def estimate_messages(
    series: EstimateSeries, lengths: Sequence[float], t0_ns: int = 0
) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """``(topic, log_time_ns, message)`` for every estimate (no pose without one); an
    ``outlier`` field where the series carries a robust MHE's flags."""
    names = [o.name for o in series.outputs]
    flags = [None] * len(series.t) if series.outlier is None else list(series.outlier)
    rows = zip(series.t, series.output, series.std, series.status, series.solve_ms, flags)
    for t, out, sd, st, ms, flag in rows:
        yield from sample_messages(series.outputs, names, float(t), out, str(st), float(ms),
                                   lengths, t0_ns, sd, flag)  # fmt: skip


def sample_messages(
    outputs: Sequence[OutputSpec],
    names: Sequence[str],
    t: float,
    out: FloatArray | None,
    st: str,
    ms: float,
    lengths: Sequence[float],
    t0_ns: int = 0,
    std: Sequence[float] | FloatArray | None = None,
    outlier: bool | None = None,
) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """The messages of one estimate (``out`` None or NaN: no pose; ``std``: one standard
    deviation per output, NaN or None where unknown; ``outlier``: a robust MHE's flag,
    written 0 or 1 before the status, None: no such field)."""
    ns = t0_ns + int(round(t * 1e9))
    stamp = {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}
    has = out is not None and st != "no-estimate" and bool(np.all(np.isfinite(out)))
    row: dict[str, Any] = {"t": t}
    row.update({k: (float(v) if has else None) for k, v in zip(names, out)}
               if out is not None else dict.fromkeys(names))  # fmt: skip
    sd = [math.nan] * len(names) if std is None else std
    row.update({f"std_{k}": (float(v) if has and math.isfinite(v) else None)
                for k, v in zip(names, sd)})  # fmt: skip
    if outlier is not None:
        row[OUTLIER_FIELD] = int(bool(outlier))
    row.update(status=st, solve_ms=ms)
    yield "/continuum/estimate", ns, row
    if not has:
        return
    assert out is not None
    poses = estimate_poses(outputs, out, lengths)
    yield "/continuum/tip", ns, {"timestamp": stamp, "frame_id": BASE_FRAME, "pose": poses[-1]}
    yield "/continuum/backbone", ns, {"timestamp": stamp, "frame_id": BASE_FRAME, "poses": poses}


def write_estimates_mcap(
    path: str | os.PathLike[str],
    series: EstimateSeries,
    lengths: Sequence[float],
    t0_ns: int = 0,
) -> None:
    """Write estimates as an MCAP file (JSON channels, see module doc), atomically.

    Args:
        path: the file to write.
        series: the estimates (``run``'s :class:`~continuum_mhe.results.EstimateSeries`).
        lengths: the length (m) of each of the robot's sections, base first: the
            backbone poses are drawn from the estimated bends on them.
        t0_ns: the absolute time (ns since the epoch) of ``t = 0``, as a robot log's
            messages are stamped (0: the estimates' ``t`` as they are).
    """
    sections = max((o.section for o in series.outputs), default=0) or 1
    try:
        given = [float(v) for v in lengths]
        for v in given:  # the model's checks of a section's length (m, not mm)
            Section(v)
    except TypeError:
        raise UserError(
            f"lengths must be the {sections} section length(s) in m, got {lengths!r}"
        ) from None
    if len(given) != sections:
        raise UserError(
            f"lengths has {len(given)} section length(s) but the estimates are of a robot "
            f"of {sections} section(s)"
        )
    with atomic_binary_writer(path) as fh:
        writer = mcap_estimate_writer(fh, series.outputs, series.outlier is not None)
        for seq, (topic, ns, msg) in enumerate(estimate_messages(series, lengths, t0_ns)):
            writer.add(topic, ns, msg, seq)
        writer.finish()


class McapEstimateWriter:
    """An MCAP writer with the estimate channels registered (see the module doc), the
    estimate's schema that of ``outputs`` (with ``outlier``: and a robust MHE's flags)."""

    def __init__(self, fh: IO[bytes], outputs: Sequence[OutputSpec], outlier: bool = False) -> None:
        require("mcap", "robot", "writing MCAP")
        from mcap.writer import CompressionType, Writer

        self._writer = Writer(fh, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="continuum-mhe")
        self._channels: dict[str, int] = {}
        schemas = {**SCHEMAS, ESTIMATE_SCHEMA: estimate_schema(outputs, outlier)}
        for topic, schema in TOPICS.items():
            sid = self._writer.register_schema(
                name=schema, encoding="jsonschema", data=json.dumps(schemas[schema]).encode()
            )
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="json", schema_id=sid
            )

    def add(self, topic: str, ns: int, msg: dict[str, Any], seq: int) -> None:
        self._writer.add_message(
            self._channels[topic], log_time=ns, data=json.dumps(msg).encode(),
            publish_time=ns, sequence=seq,
        )  # fmt: skip

    def metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record ``name`` (e.g. the options the estimates were made with)."""
        self._writer.add_metadata(name, data)

    def finish(self) -> None:
        self._writer.finish()


def mcap_estimate_writer(
    fh: IO[bytes], outputs: Sequence[OutputSpec], outlier: bool = False
) -> McapEstimateWriter:
    """Start an estimate MCAP of estimates with these ``outputs`` (with ``outlier``: and
    a robust MHE's flags) on an open binary file."""
    return McapEstimateWriter(fh, outputs, outlier)


def read_estimates_mcap(
    path: str | os.PathLike[str],
) -> tuple[FloatArray, FloatArray, NDArray[np.str_]]:
    """``t`` (n,), outputs (n, k) in the file's column order with NaN where empty, and
    status (n,) from an estimate MCAP (:func:`read_estimate_table_mcap`, whose
    :class:`InputError` it raises)."""
    table = read_estimate_table_mcap(path)
    return table.t, table.values, table.status


#: what the MCAP reader raises on a file that is not an MCAP, or is cut short (a file
#: of a few bytes: struct.error)
_FOREIGN_FILE_ERRORS = (ValueError, KeyError, TypeError, IndexError, EOFError, struct.error)


def _decompression_error(exc: BaseException) -> bool:
    """Whether ``exc`` is a decompressor's error on damaged data (zstandard's or lz4's,
    which an MCAP's compressed chunks raise; their modules are not imported here)."""
    return type(exc).__module__.split(".")[0] in ("zstandard", "lz4", "_zstd")


#: the MCAP metadata record of an estimate file's notes (options, model, partial)
NOTES_RECORD = "continuum-mhe"


def read_notes_mcap(path: str | os.PathLike[str]) -> dict[str, str]:
    """The notes an estimate MCAP records (its :data:`NOTES_RECORD` metadata records,
    later ones over earlier ones): an estimate CSV's ``# key = value`` comment lines, by
    key (``options``, ``model``...). Empty where the file has none or cannot be read
    as an MCAP (:func:`read_estimate_table_mcap` says why)."""
    require("mcap", "robot", f"reading the MCAP file {path}")
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    notes: dict[str, str] = {}
    try:
        with Path(path).open("rb") as fh:
            for record in make_reader(fh).iter_metadata():
                if record.name == NOTES_RECORD:
                    notes.update(record.metadata)
    except (OSError, McapError, *_FOREIGN_FILE_ERRORS):
        return {}
    return notes


def read_estimate_table_mcap(path: str | os.PathLike[str]) -> StateTable:
    """An estimate MCAP's ``/continuum/estimate`` messages as the estimate CSV's table
    (its outputs named as in the file, their ``std_`` fields, the status). A one-line
    :class:`InputError` for an MCAP without them (a robot log, say), one that is not an
    MCAP or not written by continuum-mhe, or a status outside the vocabulary."""
    require("mcap", "robot", f"reading the MCAP file {path}")
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    t, out, sd, status, flags = [], [], [], [], []
    names: list[str] = []
    has_std = False
    try:
        with Path(path).open("rb") as fh:
            reader = make_reader(fh, validate_crcs=True)  # damage in a chunk is said
            for _, _, message in reader.iter_messages(topics=["/continuum/estimate"]):
                row = json.loads(message.data)
                if not names:
                    names = [
                        k
                        for k in row
                        if k not in ("t", "status", "solve_ms", OUTLIER_FIELD)
                        and not k.startswith(STD_PREFIX)
                    ]
                    has_std = any(k.startswith(STD_PREFIX) for k in row)
                t.append(row["t"])
                out.append([math.nan if row[k] is None else row[k] for k in names])
                sd.append([_number(row.get(STD_PREFIX + k)) for k in names])
                flags.append(row.get(OUTLIER_FIELD))
                if row["status"] not in STATUS_MEANINGS:
                    raise InputError(
                        f"{path}: message {len(t)}: status {row['status']!r} is not one of "
                        f"{', '.join(STATUS_MEANINGS)}"
                    )
                status.append(row["status"])
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: a folder, not an estimate MCAP") from None
    except (McapError, OSError, *_FOREIGN_FILE_ERRORS) as exc:  # not ours, or cut
        why = (
            "the file ends inside a record, or is damaged: cut short?"
            if cut_short(exc) and not isinstance(exc, struct.error)
            else "too short for an MCAP"
            if isinstance(exc, struct.error)
            else repr(exc)
        )
        raise InputError(f"{path}: cannot read it as an estimate MCAP ({why})") from None
    except Exception as exc:  # a damaged compressed chunk: the compressor's own error
        if not _decompression_error(exc):
            raise
        raise InputError(
            f"{path}: cannot read it as an estimate MCAP (a compressed chunk is damaged: "
            f"{' '.join(str(exc).split())})"
        ) from None
    if not t:
        raise InputError(
            f"{path}: no /continuum/estimate messages: not an estimate MCAP (a robot log? "
            "run continuum-mhe estimate on it first)"
        )
    k = len(names)
    std = np.array(sd, dtype=float).reshape(len(t), k)
    flagged = all(f is not None for f in flags)
    return StateTable(
        t=np.array(t, dtype=float), names=tuple(names),
        values=np.array(out, dtype=float).reshape(len(t), k),
        status=np.array(status, dtype=str), std=std, std_columns=has_std, status_column=True,
        outlier=np.array(flags, dtype=bool) if flagged else None,
    )  # fmt: skip


def _number(v: Any) -> float:
    return math.nan if v is None else float(v)
