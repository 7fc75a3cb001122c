"""Robot logs in: ROS 1 / ROS 2 bags and MCAP files.

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

Estimates written as MCAP: :mod:`continuum_mhe.io.mcap_estimates`.
"""

from __future__ import annotations

import bisect
import errno
import json
import math
import os
import re
import struct
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError
from continuum_mhe.extras import MissingExtraError, require
from continuum_mhe.io.csv_files import UnitWarning, check_time_steps
from continuum_mhe.model.imu import tilt_from_accelerometer

IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
LOG_SUFFIXES = (".bag", ".mcap", ".db3")


@dataclass(frozen=True)
class ImuLog:
    """IMU samples read from a robot log.

    Attributes:
        topic: the topic read.
        t: (n,) s since ``t0_ns``, strictly increasing.
        t0_ns: absolute time of the first sample, ns (ROS time).
        acc: (n, 3) ``linear_acceleration``, m/s^2.
        gyr: (n, 3) ``angular_velocity``, rad/s; None where every message marks it
            absent (``angular_velocity_covariance[0] = -1``, REP 145; NaN rows where
            some do).
        orientation: (n, 4) ``(w, x, y, z)``, NaN where the message has none.
        skipped: descriptions of skipped messages (numbered from 1 in the topic).
        clock: what ``t`` was read from: ``"header stamps"``, or ``"log times"`` where
            no message has a stamp (every ``header.stamp`` zero) or the stamps do not
            advance (``stale_stamps``).
        cut: where a file cut short was read up to (``skip_bad``), else ``""``.
        stamp_offset_s: the median of header stamp minus the log's time over the
            messages kept, s (0 with ``clock`` ``"log times"``): each topic's stamps
            against the one clock of the log.
        frames: the ``header.frame_id`` values of the messages, each once, in the order
            they first came (empty ones left out).
        numbers: (n,) each sample's message number in its topic (from 1; None where not
            known): the place an error names.
        stale_stamps: messages whose stamps did not advance where the log's times were
            taken instead (``clock`` ``"log times"``).
        reordered: messages logged after one stamped later (delivered late), put in
            their place by their header stamps.
    """

    topic: str
    t: FloatArray
    t0_ns: int
    acc: FloatArray
    gyr: FloatArray | None
    orientation: FloatArray
    skipped: list[str] = field(default_factory=list)
    clock: str = "header stamps"
    cut: str = ""
    stamp_offset_s: float = 0.0
    frames: tuple[str, ...] = ()
    numbers: NDArray[np.int64] | None = None
    stale_stamps: int = 0
    reordered: int = 0


#: The first bytes of an MCAP file and of a ROS 1 bag: a log named otherwise (a ROS 1
#: recording that did not finish, ``run.bag.active``; a file saved without its suffix)
#: is still read as the log it is, not as a CSV file.
MCAP_MAGIC = b"\x89MCAP0\r\n"
ROS1_MAGIC = b"#ROSBAG V2.0\n"


def log_kind(path: str | os.PathLike[str]) -> str:
    """``"mcap"`` or ``"ros1"`` for a regular file that starts as one, else ``""``."""
    p = Path(path)
    try:
        if not p.is_file():
            return ""
        with p.open("rb") as fh:
            head = fh.read(len(ROS1_MAGIC))
    except OSError:
        return ""
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    return "ros1" if head == ROS1_MAGIC else ""


def is_robot_log(path: str | os.PathLike[str]) -> bool:
    """True for ``.bag``, ``.mcap``, ``.db3`` files, ROS 2 bag folders, and files that
    start as an MCAP file or a ROS 1 bag whatever their name."""
    p = Path(path)
    if p.suffix.lower() in LOG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").exists()):
        return True
    return bool(log_kind(p))


def refuse_bag_metadata(path: str | os.PathLike[str]) -> None:
    """A ROS 2 bag's ``metadata.yaml`` given for the bag: one line naming the folder to
    give instead."""
    p = Path(path)
    if p.name == "metadata.yaml" and is_robot_log(p.parent):
        raise InputError(
            f"{p}: the metadata file of a ROS 2 bag: give the bag's folder, {p.parent}"
        )


#: The largest ``header.stamp.sec`` read as seconds (the year 5138): beyond it the
#: stamp is another unit (nanoseconds in ``sec``), refused.
MAX_STAMP_SEC = 1e11


#: A topic's header stamps over at least this span (s), each within 1 ms after its whole
#: second (and not all at one offset), hold microseconds in ``nanosec``: refused.
MICROSECOND_NANOSEC_SPAN_S = 2.0


def _header_ns(msg: Any) -> int:
    """A message's ``header.stamp`` in ns (0 where it has none). A JSON message's stamp
    is ``{sec, nanosec}`` (ROS 2), ``{secs, nsecs}`` (ROS 1 as rosbridge writes it) or
    ``{sec, nsec}``, and a fractional ``sec`` keeps its fraction. A ``sec`` beyond
    :data:`MAX_STAMP_SEC` raises ``ValueError``."""
    if isinstance(msg, dict):
        st = (msg.get("header") or {}).get("stamp") or {}
        sec = st.get("sec", st.get("secs", 0))
        nsec = st.get("nanosec", st.get("nsec", st.get("nsecs", 0)))
    else:
        sec, nsec = msg.header.stamp.sec, msg.header.stamp.nanosec
    if not abs(float(sec)) <= MAX_STAMP_SEC:
        raise ValueError(
            f"its header.stamp.sec is {float(sec):.4g}: nanoseconds in sec? (header.stamp "
            "must be ROS time: sec, and nanosec in ns)"
        )
    whole = int(sec)
    return whole * 1_000_000_000 + round((float(sec) - whole) * 1e9) + int(nsec)


def _frame_id(msg: Any) -> str:
    """A message's ``header.frame_id`` ("" where it has none)."""
    if isinstance(msg, dict):
        return str((msg.get("header") or {}).get("frame_id") or "")
    return str(getattr(getattr(msg, "header", None), "frame_id", "") or "")


class FrameWarning(UserWarning):
    """A topic's IMU messages name more than one frame (``header.frame_id``): another
    sensor's messages on the topic?"""


def _json_number(v: Any, name: str) -> float:
    """A JSON message's number ``v`` (the field ``name``) as a float; ``ValueError`` for
    anything else (``true`` is not 1.0, nor ``"0.5"`` 0.5)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"its {name} is {json.dumps(v)}, not a number")
    return float(v)


def _vec(v: Any, name: str) -> list[float]:
    if isinstance(v, dict):
        return [_json_number(v[k], f"{name}.{k}") for k in ("x", "y", "z")]
    return [float(v.x), float(v.y), float(v.z)]


def _row(msg: Any) -> tuple[list[float], list[float], list[float]]:
    """A message's ``linear_acceleration``, ``angular_velocity`` and orientation ``(w, x,
    y, z)``, each NaN where the first entry of its covariance is -1 (REP 145: the field
    is absent), the orientation also where it is all zeros."""
    if isinstance(msg, dict):
        o = msg.get("orientation") or {}
        ocov = msg.get("orientation_covariance") or [0.0]
        gcov = msg.get("angular_velocity_covariance") or [0.0]
        acov = msg.get("linear_acceleration_covariance") or [0.0]
        acc = _vec(msg["linear_acceleration"], "linear_acceleration")
        gyr = _vec(msg["angular_velocity"], "angular_velocity")
        quat = [_json_number(o.get(k, math.nan), f"orientation.{k}") for k in ("w", "x", "y", "z")]
    else:
        ocov, gcov = list(msg.orientation_covariance), list(msg.angular_velocity_covariance)
        acov = list(msg.linear_acceleration_covariance)
        acc = _vec(msg.linear_acceleration, "linear_acceleration")
        gyr = _vec(msg.angular_velocity, "angular_velocity")
        o = msg.orientation
        quat = [float(o.w), float(o.x), float(o.y), float(o.z)]
    if float(acov[0]) == -1.0:
        acc = [math.nan] * 3
    if float(gcov[0]) == -1.0:
        gyr = [math.nan] * 3
    if float(ocov[0]) == -1.0 or not any(quat):
        quat = [math.nan] * 4
    return acc, gyr, quat


def topics_line(topics: dict[str, str]) -> str:
    """What a log holds, for an error: its Imu topics, or that it has none and every
    topic with its type (``topics``: topic -> message type)."""
    imu = sorted(t for t, typ in topics.items() if typ in IMU_TYPES)
    if imu:
        return f"sensor_msgs/msg/Imu topics in this log: {', '.join(imu)}"
    every = ", ".join(f"{t} ({typ or 'no schema'})" for t, typ in sorted(topics.items()))
    return f"the log has no sensor_msgs/msg/Imu topic; its topics: {every or 'none'}"


def _pick_topic(path: Path, topics: dict[str, str], topic: str | None) -> str:
    imu = sorted(t for t, typ in topics.items() if typ in IMU_TYPES)
    every = ", ".join(f"{t} ({typ or 'no schema'})" for t, typ in sorted(topics.items()))
    if topic is None:
        if len(imu) == 1:
            return imu[0]
        if not imu:  # no --topic can help
            raise InputError(f"{path}: {topics_line(topics)}")
        raise InputError(
            f"{path}: name the topic to read (--topic; topic= in Python); "
            f"sensor_msgs/msg/Imu topics in this log: {', '.join(imu)}"
        )
    if topic not in topics:
        raise InputError(f"{path}: no topic {topic!r}; topics: {every or 'none'}")
    if topics[topic] not in IMU_TYPES:
        raise InputError(f"{path}: topic {topic} is {topics[topic]}, expected sensor_msgs/msg/Imu")
    return topic


def _iter_rosbags(path: Path, topic: str | None) -> tuple[str, Iterator[tuple[int, Any]]]:
    require("rosbags", "robot", f"reading the ROS bag {path}")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag = _bag_folder(path)
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


def _single_mcap(path: Path) -> Path | None:
    """The MCAP file to read ``path`` as: ``path`` itself where it is one, the one
    ``.mcap`` of a ROS 2 bag folder stored as MCAP (rosbag2's default storage; read as
    the file it is, so that a recording cut short is read up to the cut as a lone MCAP
    file is), where its ``metadata.yaml`` lists that file alone and no compression;
    else None (a ``.bag``, a SQLite bag, a bag split into several files or compressed
    by rosbag2: rosbags reads those)."""
    if path.suffix.lower() == ".mcap" or log_kind(path) == "mcap":
        return path
    meta = path / "metadata.yaml"
    if not (path.is_dir() and meta.is_file()):
        return None
    files = sorted(path.glob("*.mcap"))
    text = meta.read_text(errors="replace")
    listed = re.findall(r"^\s*-\s*['\"]?([^'\"\s]+\.mcap)['\"]?\s*$", text, re.MULTILINE)
    mode = re.search(r"^\s*compression_mode:\s*['\"]?([A-Za-z]*)", text, re.MULTILINE)
    plain = mode is None or mode.group(1).lower() in ("", "none")
    if len(files) == 1 and listed == [files[0].name] and plain:
        return files[0]
    return None


def _bag_folder(path: Path) -> Path:
    """The ROS bag to open for ``path``: a ROS 2 bag's folder for one of its ``.db3``
    files (the folder's ``metadata.yaml`` must list that file: a reader opens the bag
    the metadata describes), else ``path`` itself; a one-line :class:`InputError` for a
    ``.db3`` without its metadata or not listed in it."""
    if log_kind(path) == "ros1" and path.suffix.lower() != ".bag":
        raise InputError(
            f"{path}: a ROS 1 bag whose name does not end in .bag: a recording that did not "
            "finish (.bag.active)? rosbag reindex it, then give it named NAME.bag"
        )
    if path.suffix.lower() != ".db3":
        return path
    meta = path.parent / "metadata.yaml"
    if not meta.is_file():
        raise InputError(
            f"{path}: a ROS 2 bag's .db3 needs the metadata.yaml that rosbag2 wrote beside "
            "it (give the bag's folder, as rosbag2 recorded it); its folder has none: a "
            "recorder that stopped? ros2 bag reindex writes it"
        )
    listed = rf"^\s*-\s*['\"]?{re.escape(path.name)}['\"]?\s*$"  # a relative_file_paths entry
    if not re.search(listed, meta.read_text(errors="replace"), re.MULTILINE):
        raise InputError(
            f"{path}: {meta} describes another bag of that folder (not {path.name}): give "
            "the folder of this file's own bag"
        )
    return path.parent


def cut_short(exc: BaseException) -> bool:
    """The reader's exception says the file ends inside a record (mcap's ``EndOfFile``,
    or a record length past the end)."""
    return (
        type(exc).__name__ == "EndOfFile"
        or "exceeds limit" in str(exc)
        or (isinstance(exc, struct.error) and "unpack requires a buffer" in str(exc))
    )


def _why_unreadable(exc: BaseException) -> str:
    """The reader's exception of a corrupt or foreign log, as a few words."""
    if cut_short(exc):
        # mcap's: a record runs past the file's end, or its length is garbage
        return "the file ends inside a record, or is damaged: a recording cut short?"
    if "Bag index looks damaged" in str(exc):  # a ROS 1 bag's index past its end
        first = str(exc).splitlines()[0]
        return f"{first}: a recording cut short? rosbag reindex rebuilds its index"
    if isinstance(exc, AttributeError) and "'NoneType'" in str(exc):  # JSON null
        return "a message with a null field"
    if isinstance(exc, KeyError) and exc.args and isinstance(exc.args[0], int):
        # the MCAP reader's: a record names a channel or schema the file does not hold
        missing = exc.args[0]
        return f"a record names channel or schema {missing}, which the file does not hold: damaged?"
    if isinstance(exc, KeyError):  # a JSON message without a field
        return f"a message without the field {exc.args[0]!r}" if exc.args else "a missing field"
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _mcap_reader(fh: Any) -> tuple[Any, Any]:
    """``(reader, summary)`` of the open MCAP file ``fh``: the seeking reader and the
    file's summary (None where it has none), or, where the file is cut short (its end is
    no footer: a recorder that stopped), a reader of its records in order up to the cut,
    and None."""
    from mcap.reader import NonSeekingReader, make_reader

    try:
        summary = make_reader(fh).get_summary()
    except Exception as exc:
        # a file shorter than a footer: the seek to where it would start fails (EINVAL)
        shorter = isinstance(exc, OSError) and exc.errno == errno.EINVAL
        if not (cut_short(exc) or shorter):
            raise
        fh.seek(0)
        return NonSeekingReader(fh, validate_crcs=True), None
    fh.seek(0)
    # the chunks' CRCs checked: a damaged record in an uncompressed chunk would otherwise
    # end the chunk's messages there, without a word
    return make_reader(fh, validate_crcs=True), summary


def _mcap_messages(reader: Any, topics: list[str] | None = None) -> Any:
    """``reader``'s messages (of ``topics``): in log-time order from a seeking reader, in
    the file's order from one that reads up to a cut (it would read to the cut before
    giving the first, to sort them)."""
    from mcap.reader import NonSeekingReader

    in_order = not isinstance(reader, NonSeekingReader)
    return reader.iter_messages(topics=topics, log_time_order=in_order)


def _mcap_topics(path: Path) -> dict[str, str]:
    """An MCAP file's topics: topic -> schema name ("" for a channel without one), from
    its summary, or (the summary is optional) from its messages read once (up to a
    cut, in a file cut short)."""
    with path.open("rb") as fh:
        summary = _mcap_reader(fh)[1]
    if summary is not None:
        schemas = summary.schemas
        return {
            ch.topic: (schemas[ch.schema_id].name if ch.schema_id in schemas else "")
            for ch in summary.channels.values()
        }
    topics: dict[str, str] = {}
    with path.open("rb") as fh:
        try:
            for schema, channel, _ in _mcap_messages(_mcap_reader(fh)[0]):
                topics.setdefault(channel.topic, schema.name if schema is not None else "")
        except Exception as exc:  # a file cut short: the topics up to the cut
            if not (cut_short(exc) and topics):
                raise
    return topics


def _iter_mcap(path: Path, topic: str | None) -> tuple[str, Iterator[tuple[int, Any]]]:
    require("mcap", "robot", f"reading the MCAP file {path}")
    require("rosbags", "robot", f"reading the MCAP file {path}")
    from rosbags.typesys import Stores, get_typestore

    name = _pick_topic(path, _mcap_topics(path), topic)
    fh = path.open("rb")
    reader = _mcap_reader(fh)[0]
    store = get_typestore(Stores.ROS2_HUMBLE)
    # ROS 1's messages (an MCAP converted from a ROS 1 bag, `mcap convert run.bag`)
    ros1_store = get_typestore(Stores.ROS1_NOETIC)

    def gen() -> Iterator[tuple[int, Any]]:
        try:
            for schema, channel, message in _mcap_messages(reader, [name]):
                if channel.message_encoding in ("cdr", "ros1"):
                    msgtype = schema.name if schema is not None else IMU_TYPES[0]
                    if msgtype == "sensor_msgs/Imu":
                        msgtype = IMU_TYPES[0]
                    if channel.message_encoding == "cdr":
                        yield message.log_time, store.deserialize_cdr(message.data, msgtype)
                    else:
                        yield message.log_time, ros1_store.deserialize_ros1(message.data, msgtype)
                elif channel.message_encoding == "json":
                    yield message.log_time, json.loads(message.data)
                else:
                    raise InputError(
                        f"{path}: topic {name}: message encoding "
                        f"{channel.message_encoding!r} is not supported (cdr, ros1 or json)"
                    )
        finally:
            fh.close()

    return name, gen()


def _refuse_empty(path: Path) -> None:
    """A one-line :class:`InputError` for a log file of 0 bytes (any kind of log)."""
    if path.is_file() and path.stat().st_size == 0:
        raise InputError(f"{path}: the robot log is empty (0 bytes): a recorder that never wrote?")


def log_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """The topics of a bag or MCAP file: topic -> message type ("" when an MCAP
    channel has no schema)."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    _refuse_empty(p)
    try:
        storage = _single_mcap(p)
        if storage is not None:
            require("mcap", "robot", f"reading the MCAP file {p}")
            return _mcap_topics(storage)
        require("rosbags", "robot", f"reading the ROS bag {p}")
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        bag = _bag_folder(p)
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            return {c.topic: c.msgtype for c in reader.connections}
    except (InputError, MissingExtraError):  # said in one line already
        raise
    except Exception as exc:  # a corrupt or foreign file: one line, no traceback
        raise InputError(f"{p}: cannot read robot log ({_why_unreadable(exc)})") from None


def read_imu_log(
    path: str | os.PathLike[str], topic: str | None = None, skip_bad: bool = False
) -> ImuLog:
    """Read the ``sensor_msgs/msg/Imu`` samples of ``topic`` from a bag or MCAP file
    (``topic`` may be omitted when the log has exactly one Imu topic). An MCAP file cut
    short (a recorder that stopped) is an error, or with ``skip_bad`` read up to the
    cut, which ``cut`` says."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    _refuse_empty(p)
    at = 0  # the message being read (from 1): named where one cannot be read
    done = 0  # the messages read whole
    cut = ""  # where a file cut short was read up to
    stamps: list[int] = []
    numbers: list[int] = []  # the message number (from 1) of each one kept
    offsets: list[int] = []  # header stamp minus log time, ns, of the messages kept
    rows: list[tuple[list[float], list[float], list[float]]] = []
    skipped: list[str] = []
    # messages whose stamp did not pass the one before, (number from 0, log time in ns,
    # row, place of their line in skipped): the log's times where most messages are so
    stale: list[tuple[int, int, tuple[list[float], list[float], list[float]], int]] = []
    by_log_time = False  # the stamps do not advance: every message kept by its log time
    # header stamps where the messages have them; the log's times only where none has
    # (a zero stamp among others is not on their clock: left out, counted)
    unstamped: list[tuple[int, int, Any]] = []  # before the first stamped message
    stamped = False
    name = topic or ""
    frames: dict[str, int] = {}  # each frame_id and the message (from 1) it came first in
    late = 0  # messages left out as their time did not pass the one kept before them
    reordered = 0  # messages logged late, put in their place by their stamps
    # a clock that stepped back (skip_bad): its messages are left out until their times
    # pass the last one kept, none put among the messages before the step
    stepped_back = False
    # a message stamped at or before the last one kept waits for the next message: where
    # that one goes on past the last one kept, the waiting one alone was delivered late
    # (put in its place by its stamp); where it does not (a clock that stepped back, a
    # counter that wrapped), the waiting one is left out, and so is each message of the
    # same run back
    waiting: list[tuple[int, int, tuple[list[float], list[float], list[float]], int]] = []
    run_back = False  # a waiting message was left out, and no message kept since

    def keep(
        i: int,
        ns: int,
        row: tuple[list[float], list[float], list[float]],
        log_ns: int,
        delivered_late: bool = False,
    ) -> None:
        # (a message delivered late: the next one confirmed the last one kept's time)
        if not delivered_late and len(stamps) > 1 and stamps[-2] < ns <= stamps[-1]:
            ahead = (stamps[-1] - stamps[-2]) / 1e9
            if ahead > STAMP_JUMP_AHEAD_S:  # the last one kept jumped ahead of both
                skipped.append(
                    f"message {numbers[-1]}: time {stamps[-1]} ns jumps {ahead:.3g} s ahead "
                    "of the messages around it"
                )
                for kept in (stamps, numbers, offsets, rows):
                    kept.pop()
        nonlocal late, reordered, stepped_back
        if stamps and ns <= stamps[-1]:
            back = (stamps[-1] - ns) / 1e9
            if back > MAX_STAMP_STEP_BACK_S and not skip_bad:
                raise InputError(
                    f"{p}: topic {name}: message {i + 1}: the time steps back by {back:.3g} s (a "
                    "sensor clock that restarted?): the log is not one recording; cut it "
                    "there, or --skip-bad leaves out the messages until the times pass the "
                    "last one"
                )
            stepped_back = stepped_back or back > MAX_STAMP_STEP_BACK_S
            place = bisect.bisect_left(stamps, ns)
            if delivered_late and not stepped_back and stamps[place] != ns:
                # logged after a message stamped later: its stamp says when it was taken,
                # so it goes in its place
                for kept, value in ((stamps, ns), (numbers, i + 1), (offsets, ns - log_ns)):
                    kept.insert(place, value)
                rows.insert(place, row)
                reordered += 1
                return
            if not by_log_time:
                stale.append((i, log_ns, row, len(skipped)))
            skipped.append(f"message {i + 1}: time {ns} ns does not increase")
            late += 1
            return
        stepped_back = False
        stamps.append(ns)
        numbers.append(i + 1)
        offsets.append(ns - log_ns)
        rows.append(row)

    def offer(
        i: int, ns: int, row: tuple[list[float], list[float], list[float]], log_ns: int
    ) -> None:
        """A stamped message, in the log's order (see ``waiting``)."""
        nonlocal run_back
        if waiting:
            alone = not run_back and bool(stamps) and ns > stamps[-1]
            keep(*waiting.pop(), delivered_late=alone)
            run_back = not alone
        if stamps and ns <= stamps[-1]:
            waiting.append((i, ns, row, log_ns))
        else:
            keep(i, ns, row, log_ns)
            run_back = False

    try:
        storage = _single_mcap(p)
        if storage is not None:
            name, messages = _iter_mcap(storage, topic)
        else:
            name, messages = _iter_rosbags(p, topic)

        for i, (log_ns, msg) in enumerate(messages):
            at = i + 1
            frames.setdefault(_frame_id(msg), at)
            try:
                header_ns = _header_ns(msg)
            except ValueError as exc:
                raise InputError(f"{p}: topic {name}: message {i + 1}: {exc}") from None
            if header_ns <= 0:
                if stamped:
                    skipped.append(f"message {i + 1}: header stamp is zero (the others' clock)")
                else:
                    unstamped.append((i, int(log_ns), _row(msg)))
                done = at
                continue
            if not stamped:
                stamped = True
                skipped += [f"message {j + 1}: header stamp is zero (the others' clock)"
                            for j, _, _ in unstamped]  # fmt: skip
                unstamped = []
            offer(i, header_ns, _row(msg), int(log_ns))
            done = at
    except (InputError, MissingExtraError):  # said in one line already
        raise
    except Exception as exc:  # a corrupt or foreign file: one line, no traceback
        # where the read failed: a message that cannot be read, or, for a file cut
        # short, after the last message read whole (the cut may lie past every message,
        # in the file's index)
        where = ""
        if at:
            where = f"after message {done}" if cut_short(exc) else f"message {done + 1}"
            where = f"topic {name}: {where}: "
        if not (skip_bad and cut_short(exc) and (stamps or unstamped)):
            hint = ""
            if cut_short(exc) and skip_bad:
                # a chunked MCAP's messages are read chunk by chunk: those in the chunk
                # that the cut ends are lost with it
                hint = (
                    "; no message could be read before the cut (the messages of a chunk "
                    "that the cut ends are lost with it)"
                )
            elif cut_short(exc) and at:  # messages came whole before the cut
                hint = "; --skip-bad reads it up to the cut"
            raise InputError(
                f"{p}: {where}cannot read robot log ({_why_unreadable(exc)}{hint})"
            ) from None
        cut = f"the file ends inside a record after message {done}: read up to there"
    if waiting:  # the last message, stamped before the one kept before it: no next one
        keep(*waiting.pop())
    for i, log_ns, row in unstamped:  # no message (up to a cut) has a stamp: the log's times
        keep(i, log_ns, row, log_ns)
    stale_stamps = 0
    if stamped and len(stale) > len(stamps):
        # most stamps do not pass the one before (a driver that sets header.stamp once,
        # or never after its start): they are no clock, and the log's times are
        by_log_time, stale_stamps = True, len(stale)
        logged = [(n - 1, s - o, r) for n, s, o, r in zip(numbers, stamps, offsets, rows)]
        logged += [(i, log_ns, row) for i, log_ns, row, _ in stale]
        said = {at for *_, at in stale}  # their lines in skipped go: they are kept now
        skipped[:] = [line for at, line in enumerate(skipped) if at not in said]
        for kept in (stamps, numbers, offsets, rows):
            kept.clear()
        late = reordered = 0
        for i, log_ns, row in sorted(logged, key=lambda m: m[0]):
            keep(i, log_ns, row, log_ns)
        stamped = False
    if not stamps:
        raise InputError(f"{p}: topic {name} has no messages")
    if late > len(stamps):  # neither clock orders the messages: no recording to estimate
        zero = "" if stamped or stale_stamps else " (all zero)"
        raise InputError(
            f"{p}: topic {name}: neither the header stamps{zero} nor the log's times "
            f"advance ({late} of {late + len(stamps)} messages at or before the time of the one "
            "before): the messages have no times to estimate on; write the log with "
            "header stamps or log times that advance"
        )
    offset = float(np.median(offsets)) / 1e9
    if abs(offset) > STAMP_CLOCK_OFFSET_S:
        warnings.warn(
            f"{p}: topic {name}: the header stamps are {abs(offset):.4g} s "
            f"{'ahead of' if offset > 0 else 'behind'} the log's times (median; a sensor's "
            "own clock?): the estimates keep the stamps' clock, so an MCAP estimate (-o "
            ".mcap) does not line up with the log's other topics in a viewer",
            UnitWarning,
            stacklevel=2,
        )
    named = {f: i for f, i in frames.items() if f}
    if len(named) > 1:
        (first, _), (second, at_msg) = list(named.items())[:2]
        warnings.warn(
            f"{p}: topic {name}: header.frame_id changes from {first!r} to {second!r} at "
            f"message {at_msg} ({len(named)} frames in all): another sensor's messages on "
            "this topic? Its messages are read as one IMU's",
            FrameWarning,
            stacklevel=2,
        )
    stamp = "header.stamp must be ROS time (sec, and nanosec in ns)"
    ns = np.array(stamps, dtype=np.int64)
    if stamped:  # each second's stamps bunched after its start: nanosec read in microseconds
        within = ns % 1_000_000_000
        span = float(ns[-1] - ns[0]) / 1e9
        if span >= MICROSECOND_NANOSEC_SPAN_S and within.min() < within.max() < 1_000_000:
            raise InputError(
                f"{p}: topic {name}: every header stamp of its {len(stamps)} messages over "
                f"{span:.3g} s lies within 1 ms after its whole second: microseconds in "
                f"nanosec? {stamp}"
            )
    t0 = stamps[0]
    t = (ns - t0) / 1e9
    check_time_steps(
        f"{p}: topic {name}", "header stamps advance", t,
        f"{stamp}: milliseconds in sec?", f"{stamp}: microseconds in nanosec?",
    )  # fmt: skip
    arr = [np.array([r[k] for r in rows], dtype=float) for k in range(3)]
    no_gyro = bool(np.isnan(arr[1]).all())  # every message marks its rates absent
    return ImuLog(
        topic=name,
        t=t,
        t0_ns=t0,
        acc=arr[0],
        gyr=None if no_gyro else arr[1],
        orientation=arr[2],
        skipped=skipped,
        clock="header stamps" if stamped else "log times",
        cut=cut,
        stamp_offset_s=offset,
        frames=tuple(named),
        numbers=np.array(numbers, dtype=np.int64),
        stale_stamps=stale_stamps,
        reordered=reordered,
    )


#: A header stamp further back than this from the last one kept (s) is a clock that
#: restarted, not a message out of order: an error (``skip_bad``: left out, as the
#: messages out of order are).
MAX_STAMP_STEP_BACK_S = 1.0
#: A kept message whose stamp lies more than this (s) after the one before it, where the
#: next one falls back between the two, jumped ahead alone (a stamp's glitch): it is left
#: out, counted, and the messages after it are kept.
STAMP_JUMP_AHEAD_S = 0.1
#: Header stamps whose median distance from the log's own times exceeds this (s) are on
#: another clock than the log's (a sensor's boot clock): said once, since an MCAP
#: estimate keeps the stamps' clock.
STAMP_CLOCK_OFFSET_S = 1.0


def tilt_from_quaternion(q: FloatArray) -> FloatArray:
    """``(roll, pitch)`` (n, 2) rad from sensor-to-world quaternions ``(w, x, y, z)``."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w, x, y, z = q.T
    up = np.stack([2 * (x * z - w * y), 2 * (w * x + y * z), w * w - x * x - y * y + z * z], -1)
    return tilt_from_accelerometer(up)
