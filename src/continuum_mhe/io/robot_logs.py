"""Robot logs in and out: ROS 1 / ROS 2 bags and MCAP files, and MCAP estimates.

Input: a ``sensor_msgs/msg/Imu`` topic. ``linear_acceleration`` (m/s^2, specific
force) and ``angular_velocity`` (rad/s) are the raw IMU samples of
:mod:`continuum_mhe.io.raw_imu`; ``orientation`` is used only when asked (its roll
and pitch become a tilt measurement). Sample time is ``header.stamp``, or the log
time where the stamp is zero; times in the estimates are seconds since the first
sample (``t0_ns`` keeps the absolute start). Messages with a non-increasing time are
skipped and counted. A robot with several IMUs takes one topic per IMU, paired by
header stamp (:mod:`continuum_mhe.io.imu_topics`).

* ROS 1 ``.bag`` files, ROS 2 bag folders (``metadata.yaml``) and ``.db3`` files are
  read with ``rosbags``' ``AnyReader``.
* ``.mcap`` files are read with the ``mcap`` library; CDR messages (ROS 2) are
  decoded by ``rosbags``' typestore, JSON messages by ``json``.

Output: ``write_estimates_mcap`` writes JSON-encoded channels that Foxglove shows
next to the robot's other topics: ``/continuum/tip`` (``foxglove.PoseInFrame``, frame
``continuum_base``), ``/continuum/backbone`` (``foxglove.PosesInFrame``, poses along
the arc) and ``/continuum/estimate`` (the estimate CSV's fields).
"""

from __future__ import annotations

import json
import math
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.extras import require
from continuum_mhe.io.csv_files import (
    FloatArray,
    InputError,
    atomic_binary_writer,
    write_estimates,
)
from continuum_mhe.io.raw_imu import (
    RawImuSettings,
    _check_accel_units,
    check_gyro_units,
    raw_to_measurements,
)
from continuum_mhe.model.descriptions import OutputSpec, section_bends
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import tilt_from_accelerometer
from continuum_mhe.model.pcc import backbone_frames
from continuum_mhe.model.robot import ImuPlacement, Robot
from continuum_mhe.results import EstimateSeries

IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
LOG_SUFFIXES = (".bag", ".mcap", ".db3")
BASE_FRAME = "continuum_base"


@dataclass(frozen=True)
class ImuLog:
    """IMU samples read from a robot log.

    Attributes:
        topic: the topic read.
        t: (n,) s since ``t0_ns``, strictly increasing.
        t0_ns: absolute time of the first sample, ns (ROS time).
        acc: (n, 3) ``linear_acceleration``, m/s^2.
        gyr: (n, 3) ``angular_velocity``, rad/s.
        orientation: (n, 4) ``(w, x, y, z)``, NaN where the message has none.
        skipped: descriptions of skipped messages.
    """

    topic: str
    t: FloatArray
    t0_ns: int
    acc: FloatArray
    gyr: FloatArray
    orientation: FloatArray
    skipped: list[str] = field(default_factory=list)


def is_robot_log(path: str | os.PathLike[str]) -> bool:
    """True for ``.bag``, ``.mcap``, ``.db3`` files and ROS 2 bag folders."""
    p = Path(path)
    return p.suffix.lower() in LOG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").exists())


def _stamp_ns(msg: Any, log_ns: int) -> int:
    if isinstance(msg, dict):  # JSON message: header.stamp {sec, nanosec | nsec}
        st = (msg.get("header") or {}).get("stamp") or {}
        sec, nsec = st.get("sec", 0), st.get("nanosec", st.get("nsec", 0))
    else:
        sec, nsec = msg.header.stamp.sec, msg.header.stamp.nanosec
    ns = int(sec) * 1_000_000_000 + int(nsec)
    return ns if ns > 0 else int(log_ns)


def _vec(v: Any) -> list[float]:
    if isinstance(v, dict):
        return [float(v["x"]), float(v["y"]), float(v["z"])]
    return [float(v.x), float(v.y), float(v.z)]


def _row(msg: Any) -> tuple[list[float], list[float], list[float]]:
    if isinstance(msg, dict):
        o = msg.get("orientation") or {}
        ocov = msg.get("orientation_covariance") or [0.0]
        acc, gyr = _vec(msg["linear_acceleration"]), _vec(msg["angular_velocity"])
        quat = [float(o.get(k, math.nan)) for k in ("w", "x", "y", "z")]
    else:
        ocov = list(msg.orientation_covariance)
        acc, gyr = _vec(msg.linear_acceleration), _vec(msg.angular_velocity)
        o = msg.orientation
        quat = [float(o.w), float(o.x), float(o.y), float(o.z)]
    if float(ocov[0]) == -1.0 or not any(quat):  # REP 145: -1 marks "no orientation"
        quat = [math.nan] * 4
    return acc, gyr, quat


def _pick_topic(path: Path, topics: dict[str, str], topic: str | None) -> str:
    imu = sorted(t for t, typ in topics.items() if typ in IMU_TYPES)
    if topic is None:
        if len(imu) == 1:
            return imu[0]
        listing = ", ".join(imu) or "none"
        raise InputError(f"{path}: pass --topic; sensor_msgs/msg/Imu topics in this log: {listing}")
    if topic not in topics:
        listing = ", ".join(f"{t} ({typ})" for t, typ in sorted(topics.items())) or "none"
        raise InputError(f"{path}: no topic {topic!r}; topics: {listing}")
    if topics[topic] not in IMU_TYPES:
        raise InputError(f"{path}: topic {topic} is {topics[topic]}, expected sensor_msgs/msg/Imu")
    return topic


def _iter_rosbags(path: Path, topic: str | None) -> tuple[str, Iterator[tuple[int, Any]]]:
    require("rosbags", "robot", f"reading the ROS bag {path}")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag = path.parent if path.suffix.lower() == ".db3" else path
    reader = AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    reader.open()
    topics = {c.topic: c.msgtype for c in reader.connections}
    name = _pick_topic(path, topics, topic)

    def gen() -> Iterator[tuple[int, Any]]:
        try:
            conns = [c for c in reader.connections if c.topic == name]
            for conn, log_ns, raw in reader.messages(connections=conns):
                yield log_ns, reader.deserialize(raw, conn.msgtype)
        finally:
            reader.close()

    return name, gen()


def _iter_mcap(path: Path, topic: str | None) -> tuple[str, Iterator[tuple[int, Any]]]:
    require("mcap", "robot", f"reading the MCAP file {path}")
    require("rosbags", "robot", f"reading the MCAP file {path}")
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    fh = path.open("rb")
    reader = make_reader(fh)
    summary = reader.get_summary()
    if summary is None:
        fh.close()
        raise InputError(f"{path}: MCAP file has no summary section (unfinished recording?)")
    topics = {
        ch.topic: (summary.schemas[ch.schema_id].name if ch.schema_id in summary.schemas else "")
        for ch in summary.channels.values()
    }
    name = _pick_topic(path, topics, topic)
    store = get_typestore(Stores.ROS2_HUMBLE)

    def gen() -> Iterator[tuple[int, Any]]:
        try:
            for schema, channel, message in reader.iter_messages(topics=[name]):
                if channel.message_encoding == "cdr":
                    msgtype = schema.name if schema is not None else IMU_TYPES[0]
                    if msgtype == "sensor_msgs/Imu":
                        msgtype = IMU_TYPES[0]
                    yield message.log_time, store.deserialize_cdr(message.data, msgtype)
                elif channel.message_encoding == "json":
                    yield message.log_time, json.loads(message.data)
                else:
                    raise InputError(
                        f"{path}: topic {name}: message encoding "
                        f"{channel.message_encoding!r} is not supported (cdr or json)"
                    )
        finally:
            fh.close()

    return name, gen()


def read_imu_log(path: str | os.PathLike[str], topic: str | None = None) -> ImuLog:
    """Read the ``sensor_msgs/msg/Imu`` samples of ``topic`` from a bag or MCAP file
    (``topic`` may be omitted when the log has exactly one Imu topic)."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    try:
        if p.suffix.lower() == ".mcap":
            name, messages = _iter_mcap(p, topic)
        else:
            name, messages = _iter_rosbags(p, topic)
        stamps: list[int] = []
        rows: list[tuple[list[float], list[float], list[float]]] = []
        skipped: list[str] = []
        for i, (log_ns, msg) in enumerate(messages):
            ns = _stamp_ns(msg, log_ns)
            if stamps and ns <= stamps[-1]:
                skipped.append(f"message {i}: time {ns} ns does not increase")
                continue
            stamps.append(ns)
            rows.append(_row(msg))
    except InputError:
        raise
    except Exception as exc:  # a corrupt or foreign file: one line, no traceback
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{p}: cannot read robot log ({msg})") from None
    if not stamps:
        raise InputError(f"{p}: topic {name} has no messages")
    t0 = stamps[0]
    arr = [np.array([r[k] for r in rows], dtype=float) for k in range(3)]
    _check_accel_units(f"{p}: topic {name}", arr[0])  # the gyro's: where it is used
    return ImuLog(
        topic=name,
        t=(np.array(stamps, dtype=np.int64) - t0) / 1e9,
        t0_ns=t0,
        acc=arr[0],
        gyr=arr[1],
        orientation=arr[2],
        skipped=skipped,
    )


def tilt_from_quaternion(q: FloatArray) -> FloatArray:
    """``(roll, pitch)`` (n, 2) rad from sensor-to-world quaternions ``(w, x, y, z)``."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w, x, y, z = q.T
    up = np.stack([2 * (x * z - w * y), 2 * (w * x + y * z), w * w - x * x - y * y + z * z], -1)
    return tilt_from_accelerometer(up)


# --- estimate command input and output ---------------------------------------------------
@dataclass(frozen=True)
class InputOptions:
    """How ``estimate`` reads its input (command-line options).

    Attributes:
        raw: raw-IMU conversion (raw CSV, bags, MCAP).
        topic: Imu topic in a bag or MCAP file (None: the only one).
        topics: one Imu topic per IMU, in the robot file's order, for a robot with
            several IMUs (see :mod:`continuum_mhe.io.imu_topics`).
        pair_tolerance: largest header-stamp difference of paired samples, s (None:
            half of IMU 1's median sample period).
        use_orientation: use the Imu message's orientation (roll, pitch) instead of
            its raw accelerometer and gyro.
        gyro_std: gyro noise, rad/s, for the direct model.
        estimate_gyro_bias: the direct model estimates each gyro's bias.
        estimate_accel_bias: the direct model estimates each accelerometer's bias.
        own_acceleration: the direct model includes each IMU's own acceleration
            (bend accelerations as states).
        degrees: a tilt CSV is in degrees.
        skip_bad: skip bad samples instead of stopping.
    """

    raw: RawImuSettings = field(default_factory=RawImuSettings)
    topic: str | None = None
    topics: tuple[str, ...] = ()
    pair_tolerance: float | None = None
    use_orientation: bool = False
    gyro_std: float = 0.05
    estimate_gyro_bias: bool = False
    estimate_accel_bias: bool = False
    own_acceleration: bool = False
    degrees: bool = False
    skip_bad: bool = False


@dataclass(frozen=True)
class EstimateInput:
    """Measurements ready for an estimator.

    Attributes:
        kind: ``"tilt-csv"``, ``"raw-csv"`` or ``"log"``.
        t: (n,) s; z: (n, nz) measurements for ``formulation``.
        t0_ns: absolute time of ``t = 0``, ns (0 for CSV input).
        skipped: descriptions of skipped samples.
        notes: one-line reports for the user (e.g. how samples of several topics paired).
    """

    kind: str
    t: FloatArray
    z: FloatArray
    formulation: Formulation
    t0_ns: int = 0
    skipped: list[str] = field(default_factory=list)
    notes: tuple[str, ...] = ()


def _formulation_for(
    options: InputOptions, base: Formulation, raw_input: bool, path: Path
) -> Formulation:
    if options.raw.imu_model != "direct":
        for flag, on in (
            ("--estimate-gyro-bias", options.estimate_gyro_bias),
            ("--estimate-accel-bias", options.estimate_accel_bias),
            ("--own-acceleration", options.own_acceleration),
        ):
            if on:
                raise InputError(f"{flag} needs --imu-model direct (raw gyros)")
        return base
    if not raw_input or options.use_orientation:
        raise InputError(f"{path}: --imu-model direct needs raw accelerometer and gyro input")
    if base.name not in ("bend", "direct"):
        raise InputError(
            f"--imu-model direct uses the bend state; --formulation {base.name} does not apply"
        )
    from continuum_mhe.model.direct import DirectFormulation

    return DirectFormulation(
        robot=base.robot,
        noise=base.noise,
        gyro_std=options.gyro_std,
        estimate_gyro_bias=options.estimate_gyro_bias,
        estimate_accel_bias=options.estimate_accel_bias,
        own_acceleration=options.own_acceleration,
    )


class OptionWarning(UserWarning):
    """A robot-file entry or option that has no effect on this input."""


def check_options_apply(name: str, kind: str, options: InputOptions, robot: Robot) -> None:
    """Refuse an option that would do nothing on this input, in one line naming it and
    why; warn, once, where a robot file's ``mount_rpy`` is not applied.

    ``kind``: ``"tilt-csv"``, ``"raw-csv"`` or ``"log"`` (a bag or MCAP: raw vectors,
    or roll and pitch from its orientation with ``use_orientation``). Roll and pitch
    are taken as already in the backbone's frame at each IMU; ``mount_rpy`` rotates raw
    accelerometer and gyro vectors only (docs/hardware.md)."""
    raw = options.raw
    tilt_input = kind == "tilt-csv" or (kind == "log" and options.use_orientation)
    if options.degrees and kind != "tilt-csv":
        units = (
            "the orientation is a quaternion"
            if tilt_input
            else "accelerations are read in m/s^2 and gyro rates in rad/s"
        )
        raise InputError(
            f"{name}: --degrees does not apply to this input: it is for roll and pitch in "
            f"tilt CSV files; {units}"
        )
    mounted = [str(i) for i, imu in enumerate(robot.imus, start=1) if any(imu.mount_rpy)]
    if not tilt_input:
        if any(raw.mount_rpy) and len(mounted) == robot.n_imus:
            raise InputError(
                f"{name}: --mount-rpy applies to no IMU: the robot file gives every IMU its "
                "own mount_rpy, which wins (leave --mount-rpy out, or edit the robot file)"
            )
        return
    why = "roll and pitch are used as they are, taken as already in the backbone's frame"
    if any(raw.mount_rpy):
        raise InputError(
            f"{name}: --mount-rpy does not apply to tilt input: it rotates raw "
            f"accelerometer and gyro vectors, and {why}"
        )
    if raw.attitude != "accel":
        raise InputError(
            f"{name}: --attitude {raw.attitude} does not apply to tilt input: it fuses raw "
            f"accelerometer and gyro readings, and {why}"
        )
    if mounted:
        warnings.warn(
            f"{name}: the robot file's mount_rpy of IMU {', '.join(mounted)} is not applied "
            f"to tilt input: it rotates raw readings, and {why}",
            OptionWarning,
            stacklevel=3,
        )


def load_estimate_input(
    path: str | os.PathLike[str], options: InputOptions, formulation: Formulation
) -> EstimateInput:
    """Read any supported input (tilt CSV, raw CSV, bag, MCAP) as measurements."""
    p = Path(path)
    if is_robot_log(p):
        check_options_apply(str(p), "log", options, formulation.robot)
    if is_robot_log(p) and (formulation.robot.n_imus > 1 or len(options.topics) > 1):
        return _load_topics(p, options, formulation)
    if is_robot_log(p):
        log = read_imu_log(p, options.topic)
        f = _formulation_for(options, formulation, True, p)
        if options.use_orientation:
            if not np.all(np.isfinite(log.orientation)):
                raise InputError(f"{p}: topic {log.topic} carries no orientation (covariance -1)")
            z = tilt_from_quaternion(log.orientation)
        else:
            z = _convert(p, log.t, log.acc, log.gyr, options.raw, log.topic)
        return EstimateInput("log", log.t, z, f, log.t0_ns, log.skipped)
    from continuum_mhe.io.sample_stream import open_estimate_input

    with open_estimate_input(path, options, formulation) as stream:
        stream.problems.keep = sys.maxsize
        pairs = list(stream.samples)
    t = np.array([tv for tv, _ in pairs], dtype=float)
    z = np.array([zv for _, zv in pairs], dtype=float).reshape(len(t), stream.formulation.nz)
    return EstimateInput(stream.kind, t, z, stream.formulation, 0, stream.problems.first)


def _load_topics(p: Path, options: InputOptions, formulation: Formulation) -> EstimateInput:
    """One Imu topic per IMU, paired by header stamp (:mod:`~continuum_mhe.io.imu_topics`)."""
    from continuum_mhe.io.imu_topics import read_imu_topics

    robot = formulation.robot
    paired = read_imu_topics(p, options.topics, robot.n_imus, options.pair_tolerance)
    f = _formulation_for(options, formulation, True, p)
    blocks = []
    for log, place in zip(paired.logs, robot.imus):
        if options.use_orientation:
            if not np.all(np.isfinite(log.orientation)):
                raise InputError(f"{p}: topic {log.topic} carries no orientation (covariance -1)")
            blocks.append(tilt_from_quaternion(log.orientation))
        else:
            blocks.append(
                _convert(
                    p, paired.t, log.acc, log.gyr, _imu_settings(options.raw, place), log.topic
                )
            )
    return EstimateInput(
        "log", paired.t, np.hstack(blocks), f, paired.t0_ns, paired.skipped, (paired.report(),)
    )


def _imu_settings(raw: RawImuSettings, place: ImuPlacement) -> RawImuSettings:
    """The conversion settings of one IMU: the robot file's mounting where it gives one,
    else ``--mount-rpy``."""
    if any(place.mount_rpy):
        return replace(raw, mount_rpy=place.mount_rpy)
    return raw


def _convert(
    path: Path,
    t: FloatArray,
    acc: FloatArray,
    gyr: FloatArray | None,
    raw: RawImuSettings,
    topic: str,
) -> FloatArray:
    if raw.needs_gyro and gyr is None:
        what = "--imu-model direct" if raw.imu_model == "direct" else f"--attitude {raw.attitude}"
        raise InputError(f"{path}: {what} needs gyro columns gx, gy, gz")
    if gyr is not None:
        check_gyro_units(f"{path}: topic {topic}", gyr, raw.needs_gyro)
    return raw_to_measurements(t, acc, gyr, raw)


def write_estimate_output(
    path: str | os.PathLike[str], series: EstimateSeries, data: EstimateInput
) -> None:
    """Estimate CSV, or MCAP when ``path`` ends in ``.mcap``."""
    if Path(path).suffix.lower() == ".mcap":
        write_estimates_mcap(path, series, data.formulation.robot.lengths, data.t0_ns)
    else:
        write_estimates(path, series)


# --- MCAP output ------------------------------------------------------------------------------
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
    "continuum_mhe.Estimate": {
        "title": "continuum_mhe.Estimate",
        "description": "Estimate CSV row: m, rad, ms; state fields null without estimate, "
        "std_ fields (one standard deviation) null where unknown",
        "type": "object",
        "properties": {
            **{k: {"type": ["number", "null"]} for k in ("t", "x", "y", "z", "theta", "phi")},
            "status": {"type": "string"},
            "solve_ms": {"type": "number"},
        },
    },
}
TOPICS = {
    "/continuum/tip": "foxglove.PoseInFrame",
    "/continuum/backbone": "foxglove.PosesInFrame",
    "/continuum/estimate": "continuum_mhe.Estimate",
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


def estimate_messages(
    series: EstimateSeries, lengths: Sequence[float], t0_ns: int = 0
) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """``(topic, log_time_ns, message)`` for every estimate (no pose without one)."""
    names = [o.name for o in series.outputs]
    rows = zip(series.t, series.output, series.std, series.status, series.solve_ms)
    for t, out, sd, st, ms in rows:
        yield from sample_messages(series.outputs, names, float(t), out, str(st), float(ms),
                                   lengths, t0_ns, sd)  # fmt: skip


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
) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """The messages of one estimate (``out`` None or NaN: no pose; ``std``: one standard
    deviation per output, NaN or None where unknown)."""
    ns = t0_ns + int(round(t * 1e9))
    stamp = {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}
    has = out is not None and st != "no-estimate" and bool(np.all(np.isfinite(out)))
    row: dict[str, Any] = {"t": t}
    row.update({k: (float(v) if has else None) for k, v in zip(names, out)}
               if out is not None else dict.fromkeys(names))  # fmt: skip
    sd = [math.nan] * len(names) if std is None else std
    row.update({f"std_{k}": (float(v) if has and math.isfinite(v) else None)
                for k, v in zip(names, sd)})  # fmt: skip
    row.update(status=st, solve_ms=ms)
    yield "/continuum/estimate", ns, row
    if not has:
        return
    assert out is not None
    poses = backbone_poses(section_bends(outputs, out), lengths)
    yield "/continuum/tip", ns, {"timestamp": stamp, "frame_id": BASE_FRAME, "pose": poses[-1]}
    yield "/continuum/backbone", ns, {"timestamp": stamp, "frame_id": BASE_FRAME, "poses": poses}


def write_estimates_mcap(
    path: str | os.PathLike[str],
    series: EstimateSeries,
    lengths: Sequence[float],
    t0_ns: int = 0,
) -> None:
    """Write estimates as an MCAP file (JSON channels, see module doc), atomically."""
    with atomic_binary_writer(path) as fh:
        writer = mcap_estimate_writer(fh)
        for seq, (topic, ns, msg) in enumerate(estimate_messages(series, lengths, t0_ns)):
            writer.add(topic, ns, msg, seq)
        writer.finish()


class McapEstimateWriter:
    """An MCAP writer with the estimate channels registered (see the module doc)."""

    def __init__(self, fh: IO[bytes]) -> None:
        require("mcap", "robot", "writing MCAP")
        from mcap.writer import CompressionType, Writer

        self._writer = Writer(fh, compression=CompressionType.NONE)
        self._writer.start(profile="", library="continuum-mhe")
        self._channels: dict[str, int] = {}
        for topic, schema in TOPICS.items():
            sid = self._writer.register_schema(
                name=schema, encoding="jsonschema", data=json.dumps(SCHEMAS[schema]).encode()
            )
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="json", schema_id=sid
            )

    def add(self, topic: str, ns: int, msg: dict[str, Any], seq: int) -> None:
        self._writer.add_message(
            self._channels[topic], log_time=ns, data=json.dumps(msg).encode(),
            publish_time=ns, sequence=seq,
        )  # fmt: skip

    def finish(self) -> None:
        self._writer.finish()


def mcap_estimate_writer(fh: IO[bytes]) -> McapEstimateWriter:
    """Start an estimate MCAP on an open binary file."""
    return McapEstimateWriter(fh)


def read_estimates_mcap(
    path: str | os.PathLike[str],
) -> tuple[FloatArray, FloatArray, NDArray[np.str_]]:
    """``t`` (n,), outputs (n, k) in the file's column order with NaN where empty, and
    status (n,) from an estimate MCAP."""
    require("mcap", "robot", f"reading the MCAP file {path}")
    from mcap.reader import make_reader

    t, out, status = [], [], []
    names: list[str] = []
    with Path(path).open("rb") as fh:
        for _, _, message in make_reader(fh).iter_messages(topics=["/continuum/estimate"]):
            row = json.loads(message.data)
            if not names:
                names = [
                    k
                    for k in row
                    if k not in ("t", "status", "solve_ms") and not k.startswith("std_")
                ]
            t.append(row["t"])
            out.append([math.nan if row[k] is None else row[k] for k in names])
            status.append(row["status"])
    return (
        np.array(t, dtype=float),
        np.array(out, dtype=float).reshape(len(t), len(names)),
        np.array(status, dtype=str),
    )
