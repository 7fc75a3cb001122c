"""One ``sensor_msgs/msg/Imu`` topic per IMU in ROS 2 bags and MCAP files: samples
paired by header stamp (mutual nearest, within the tolerance), unpairable samples
counted per topic, and the estimates equal to those of the multi-IMU raw CSV holding the
paired samples; a topic count that does not match the robot is one line."""

from __future__ import annotations

import csv
import math
import re
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robot_log_helpers import IMU, T0_NS, imu_msg

from continuum_mhe.benchmark.harness import raw_imu_recording
from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io.imu_topics import (
    TopicClockWarning,
    fill_outages,
    pair_stamps,
    read_imu_topics,
)
from continuum_mhe.io.raw_imu import raw_columns
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table

TOPICS = ("/imu1", "/imu2")
G = 9.80665
DT_NS = 20_000_000


def test_pair_stamps_known_answers() -> None:
    ref = np.array([0, 10, 20, 30, 40], dtype=np.int64)
    other = np.array([1, 12, 19, 33, 45, 50], dtype=np.int64)
    idx = pair_stamps([ref, other], 3)  # 40-45 too far; 50 is nobody's nearest
    assert [list(i) for i in idx] == [[0, 1, 2, 3, 4], [0, 1, 2, 3, -1]]
    # two samples of IMU 1 want the same sample of IMU 2: only its nearest gets it
    idx = pair_stamps([np.array([0, 4]), np.array([3])], 5)
    assert [list(i) for i in idx] == [[0, 1], [-1, 0]]
    # three topics: each paired on its own (-1: a dropout of that IMU at that sample)
    idx = pair_stamps([ref, other, np.array([0, 21, 31], dtype=np.int64)], 3)
    assert [list(i) for i in idx] == [[0, 1, 2, 3, 4], [0, 1, 2, 3, -1], [0, -1, 1, 2, -1]]


def test_samples_that_lose_their_nearest_pair_with_a_free_one_in_order() -> None:
    """Two IMUs about half a period apart: a sample of IMU 1 whose nearest sample of IMU
    2 is another's (mutual nearest fails) pairs with the free one between its
    neighbours' partners, within the tolerance, the order kept."""
    ref = np.array([0, 20, 40, 60], dtype=np.int64)
    other = np.array([9, 31, 49, 71], dtype=np.int64)
    # 20's nearest (31 and 9 tie: the later) is 40's nearest: 20 takes 31, which is free
    assert [list(i) for i in pair_stamps([ref, other], 12)] == [[0, 1, 2, 3], [0, 1, 2, 3]]
    # within the tolerance only: 20 and 31 are 11 apart, as are 60 and 71 (mutual nearest)
    assert [list(i) for i in pair_stamps([ref, other], 10)] == [[0, 1, 2, 3], [0, -1, 2, -1]]
    # the tolerance is the largest difference taken, by either rule
    assert [list(i) for i in pair_stamps([ref, other], 11)] == [[0, 1, 2, 3], [0, 1, 2, 3]]
    # not across a pair: 1's partner lies between 0 and 2's, none is free there
    assert [list(i) for i in pair_stamps([np.array([0, 4]), np.array([3])], 5)] == [[0, 1], [-1, 0]]


def test_two_imus_sampling_out_of_phase_are_said_so(
    streams: dict[str, Any], tmp_path: Path
) -> None:
    """IMU 2 stamped 9 ms (+- 2 ms) after IMU 1 at 50 Hz: within the default tolerance
    (half the period) many of its samples find no partner; the pairing note says its
    stamps lie that far from IMU 1's and that a larger --pair-tolerance pairs more, and
    one does (a topic's own few strays are not said so)."""
    imu1 = streams["imu"][0]
    rng = np.random.default_rng(5)
    stamps = imu1["stamps"] + 9_000_000 + rng.integers(-2_000_000, 2_000_000, len(imu1["stamps"]))
    late = [imu1, {"stamps": stamps, "acc": imu1["acc"], "gyr": imu1["gyr"]}]
    log = write_mcap_topics(tmp_path / "phase.mcap", late)
    paired = read_imu_topics(log, TOPICS, 2)
    assert paired.unpaired[1] > 0.1 * paired.read[1]
    assert paired.report().endswith(
        "; /imu2's stamps lie a median 8.74 ms from /imu1's: the IMUs sample out of phase, "
        "and a larger --pair-tolerance pairs more of their readings (each taken at IMU 1's "
        "time, up to that far from its own)"
    ), paired.report()
    wide = read_imu_topics(log, TOPICS, 2, tolerance_s=0.019)
    assert wide.unpaired[1] * 4 < paired.unpaired[1]
    assert (
        "out of phase"
        not in read_imu_topics(
            write_mcap_topics(tmp_path / "in_phase.mcap", streams["imu"]), TOPICS, 2
        ).report()
    )
    # a topic twice as fast, in phase: every sample of IMU 1 has a partner, its extra
    # samples are left over, half a period from IMU 1's; not out of phase
    n = len(imu1["stamps"])
    twice = {
        "stamps": imu1["stamps"][0] + np.arange(2 * n, dtype=np.int64) * (DT_NS // 2),
        "acc": np.repeat(imu1["acc"], 2, axis=0),
        "gyr": np.repeat(imu1["gyr"], 2, axis=0),
    }
    log = write_mcap_topics(tmp_path / "twice.mcap", [imu1, twice])
    faster = read_imu_topics(log, TOPICS, 2)
    assert faster.unpaired[1] > 0.1 * faster.read[1] and "out of phase" not in faster.report()


def test_fill_outages_known_answers() -> None:
    """IMU 1 silent from 20 to 60 (period 10, tolerance 4): IMU 2's samples there fill
    the outage, thinned to IMU 1's rate where IMU 2 is faster, none closer than 0.75 of
    a period to a sample taken before; a third topic fills only where IMU 1 and IMU 2
    leave an outage; no fill takes a partner from one of IMU 1's samples; a topic that
    starts before IMU 1 fills the time before IMU 1's first sample."""
    ref = np.array([0, 10, 20, 60, 70], dtype=np.int64)
    assert list(fill_outages([ref, ref + 1], 10, 4)) == list(ref)  # no outage
    other = np.array([1, 11, 21, 31, 41, 51, 61], dtype=np.int64)
    assert list(fill_outages([ref, other], 10, 4)) == [0, 10, 20, 31, 41, 51, 60, 70]
    fast = np.arange(0, 75, 5, dtype=np.int64) + 1  # 1, 6, ..., 71: twice IMU 1's rate
    assert list(fill_outages([ref, fast], 10, 4)) == [0, 10, 20, 31, 41, 51, 60, 70]
    # IMU 2 silent from 35 on: IMU 3 fills the rest, not beside IMU 2's 31 or IMU 1's 60
    imu2 = np.array([1, 11, 21, 31, 61], dtype=np.int64)
    imu3 = np.array([2, 12, 22, 33, 43, 53, 62], dtype=np.int64)
    assert list(fill_outages([ref, imu2, imu3], 10, 4)) == [0, 10, 20, 31, 43, 60, 70]
    # IMU 1 stops at 70, IMU 2 goes on: its samples after are taken (an open outage);
    # one sample of IMU 2 within the outage's 1.5 periods after IMU 1's last is not
    later = np.array([1, 11, 21, 61, 71, 81, 91, 101], dtype=np.int64)
    assert list(fill_outages([ref, later], 10, 4)) == [0, 10, 20, 60, 70, 81, 91, 101]
    assert list(fill_outages([ref, later[:6]], 10, 4)) == list(ref)
    # IMU 2 stops at 81 (too soon to fill), IMU 3 goes on to 112 and fills from 82 on
    imu3 = np.array([2, 12, 22, 62, 72, 82, 92, 102, 112], dtype=np.int64)
    filled = fill_outages([ref, later[:6], imu3], 10, 4)
    assert list(filled) == [0, 10, 20, 60, 70, 82, 92, 102, 112]
    # IMU 1 starts after IMU 2: IMU 2's samples before are taken, but not one nearer
    # than 0.75 periods to IMU 1's first (IMU 2 sampling just ahead of IMU 1 adds none);
    # IMU 3 starting earlier still fills before IMU 2's first
    ref = np.array([0, 10, 20, 30], dtype=np.int64)
    early = np.array([-29, -19, -9, 1, 11, 21, 31], dtype=np.int64)
    assert list(fill_outages([ref, early], 10, 4)) == [-29, -19, -9, 0, 10, 20, 30]
    assert list(fill_outages([ref, early + 4], 10, 4)) == [-25, -15, 0, 10, 20, 30]
    assert list(fill_outages([ref, ref - 2], 10, 4)) == list(ref)
    earlier = np.array([-48, -38, -28, -18, -8, 2, 12, 22, 32], dtype=np.int64)
    filled = fill_outages([ref, early, earlier], 10, 4)
    assert list(filled) == [-48, -38, -29, -19, -9, 0, 10, 20, 30]
    # IMU 1 at 300 pairs with IMU 2's 340 (tolerance 50, period 100); IMU 3's 376 is
    # nearer to it: no fill there, and every IMU 1 sample keeps its partners
    ref = np.array([0, 100, 200, 300, 1000, 1100], dtype=np.int64)
    grid = np.arange(0, 1200, 100, dtype=np.int64)
    topics = [ref, grid + 40, grid + 76]
    filled = fill_outages(topics, 100, 50)
    assert 376 not in filled and 440 in filled
    before = pair_stamps(topics, 50)
    after = pair_stamps([filled, *topics[1:]], 50)
    at = np.searchsorted(filled, ref)
    for b, a in zip(before[1:], after[1:]):
        np.testing.assert_array_equal(a[at][b >= 0], b[b >= 0])
    # IMU 2 silent with IMU 1: IMU 3 fills, but not at 376, which would take IMU 2's 340
    # from IMU 1's 300
    imu2 = np.array([40, 140, 240, 340, 1040, 1140], dtype=np.int64)
    filled = fill_outages([ref, imu2, grid + 76], 100, 50)
    assert list(filled) == [0, 100, 200, 300, 476, 576, 676, 776, 876, 1000, 1100]


@pytest.fixture(scope="module")
def streams() -> dict[str, Any]:
    """Two IMUs of the two-section robot with their own clocks: IMU 2 stamped 1.5 ms
    (+- 1 ms jitter) after IMU 1, IMU 2 missing samples 5 and 6, IMU 1 missing sample 30
    (IMU 2's sample 30 fills it: ``timeline``, the samples' stamps), and three stray IMU
    2 samples 9 ms after an IMU 1 sample (nobody's nearest)."""
    rec = raw_imu_recording(read_robot("two-section"), 2.0)
    n = len(rec.t)
    rng = np.random.default_rng(7)
    base = T0_NS + np.arange(n, dtype=np.int64) * DT_NS
    jitter = rng.integers(-1_000_000, 1_000_000, n)
    imu = []
    for k, offset in enumerate((np.zeros(n, dtype=np.int64), 1_500_000 + jitter)):
        acc = G * rec.z[:, 6 * k : 6 * k + 3]
        gyr = rec.z[:, 6 * k + 3 : 6 * k + 6]
        imu.append({"stamps": base + offset, "acc": acc, "gyr": gyr})
    keep1 = np.ones(n, dtype=bool)
    keep1[30] = False
    keep2 = np.ones(n, dtype=bool)
    keep2[[5, 6]] = False
    imu[0] = {key: v[keep1] for key, v in imu[0].items()}
    stray = [12, 50, 80]
    imu[1] = {
        "stamps": np.concatenate([imu[1]["stamps"][keep2], base[stray] + 9_000_000]),
        "acc": np.vstack([imu[1]["acc"][keep2], imu[1]["acc"][stray]]),
        "gyr": np.vstack([imu[1]["gyr"][keep2], imu[1]["gyr"][stray]]),
    }
    order = np.argsort(imu[1]["stamps"])
    imu[1] = {key: v[order] for key, v in imu[1].items()}
    with_imu2 = np.flatnonzero(np.isin(np.arange(n), [5, 6], invert=True))
    timeline = np.sort(np.append(imu[0]["stamps"], base[30] + 1_500_000 + jitter[30]))
    return {"imu": imu, "base": base, "with_imu2": with_imu2, "strays": len(stray),
            "timeline": timeline}  # fmt: skip


def _messages(store: Any, imu: dict[str, Any]) -> list[tuple[int, bytes]]:
    """The topic's messages with their log times (``imu["log"]``, ns; its stamps where
    not given), serialised; its rates marked absent where ``imu`` says ``no_gyro``."""
    no_gyro = bool(imu.get("no_gyro", False))
    logged = imu.get("log", imu["stamps"])
    return [
        (int(t), bytes(store.serialize_cdr(imu_msg(store, int(ns), a, g, no_gyro=no_gyro), IMU)))
        for t, ns, a, g in zip(logged, imu["stamps"], imu["acc"], imu["gyr"])
    ]


def write_ros2_topics(path: Path, imus: list[dict[str, Any]]) -> Path:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=9) as w:
        conns = [w.add_connection(t, IMU, typestore=store) for t in TOPICS]
        msgs = [(ns, c, d) for c, imu in zip(conns, imus) for ns, d in _messages(store, imu)]
        for ns, conn, data in sorted(msgs, key=lambda m: m[0]):
            w.write(conn, ns, data)
    return path


def write_ros1_topics(path: Path, imus: list[dict[str, Any]]) -> Path:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conns = [w.add_connection(t, IMU, typestore=store) for t in TOPICS]
        msgs = [
            (int(ns), c, store.serialize_ros1(imu_msg(store, int(ns), a, g, True), IMU))
            for c, imu in zip(conns, imus)
            for ns, a, g in zip(imu["stamps"], imu["acc"], imu["gyr"])
        ]
        for ns, conn, data in sorted(msgs, key=lambda m: m[0]):
            w.write(conn, ns, data)
    return path


def write_mcap_topics(path: Path, imus: list[dict[str, Any]]) -> Path:
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    msgdef, _ = store.generate_msgdef(IMU, ros_version=2)
    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start()
        sid = w.register_schema(name=IMU, encoding="ros2msg", data=msgdef.encode())
        cids = [w.register_channel(topic=t, message_encoding="cdr", schema_id=sid) for t in TOPICS]
        msgs = [(ns, c, d) for c, imu in zip(cids, imus) for ns, d in _messages(store, imu)]
        for ns, cid, data in sorted(msgs, key=lambda m: m[0]):
            w.add_message(cid, log_time=ns, data=data, publish_time=ns)
        w.finish()
    return path


WRITERS = {
    "ros1": (write_ros1_topics, "x.bag"),
    "ros2": (write_ros2_topics, "bag"),
    "mcap": (write_mcap_topics, "x.mcap"),
}


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_a_wrong_topic_count_lists_the_logs_imu_topics(
    kind: str, streams: dict[str, Any], tmp_path: Path
) -> None:
    """Every log kind's topics are read for the message (ROS 1 bags type Imu without
    ``msg/``)."""
    write, name = WRITERS[kind]
    log = write(tmp_path / name, streams["imu"])
    with pytest.raises(InputError) as info:
        read_imu_topics(log, [], 2)
    assert str(info.value) == (
        f"{log}: no --topic for a robot with 2 IMUs: pass one --topic per IMU, in the robot "
        "file's order; sensor_msgs/msg/Imu topics in this log: /imu1, /imu2"
    )
    # a log with fewer Imu topics than the robot's IMUs (several IMUs on one topic, told
    # apart by their frame_id): the message says such a topic is not read
    with pytest.raises(InputError) as info:
        read_imu_topics(log, ["/imu1"], 3)
    assert str(info.value).endswith(
        "(the log has 2 Imu topic(s) for 3 IMUs: one topic carrying several IMUs' messages, "
        "told apart by header.frame_id, is not read; record one topic per IMU)"
    )


def test_topics_whose_stamps_stand_apart_from_the_log_s_clock_warn(
    streams: dict[str, Any], tmp_path: Path
) -> None:
    """IMU 2's header stamps 0.5 s ahead of the log's times, IMU 1's on them (a sensor
    with a clock of its own): paired by stamp, each pair joins readings taken 0.5 s
    apart (91 mm off on a user's log): one warning naming the topics and the offset, not
    silence. One topic delivered 20 ms later than the other says nothing."""
    ahead = [dict(streams["imu"][0]), dict(streams["imu"][1])]
    ahead[1]["log"] = ahead[1]["stamps"] - 500_000_000
    with pytest.warns(TopicClockWarning) as seen:
        read_imu_topics(write_mcap_topics(tmp_path / "ahead.mcap", ahead), TOPICS, 2)
    said = [str(w.message) for w in seen]
    assert len(said) == 1 and (
        "/imu2's header stamps are 500 ms ahead of /imu1's, against the log's own times" in said[0]
    )
    late = [dict(streams["imu"][0]), dict(streams["imu"][1])]
    late[1]["log"] = late[1]["stamps"] + 20_000_000
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_imu_topics(write_mcap_topics(tmp_path / "late.mcap", late), TOPICS, 2)


def test_a_wide_pair_tolerance_does_not_hide_clocks_apart(
    streams: dict[str, Any], tmp_path: Path
) -> None:
    """IMU 2's stamps 0.3 s ahead of the log's times, paired with ``--pair-tolerance
    0.35``: the tolerance lets the pairs join readings 0.3 s apart, and the clocks are
    said all the same (the limit is not twice the tolerance given, which would say
    nothing and leave rows `ok` 38 mm off)."""
    ahead = [dict(streams["imu"][0]), dict(streams["imu"][1])]
    ahead[1]["log"] = ahead[1]["stamps"] - 300_000_000
    with pytest.warns(TopicClockWarning, match="/imu2's header stamps are 300 ms ahead"):
        read_imu_topics(write_mcap_topics(tmp_path / "a.mcap", ahead), TOPICS, 2, 0.35)


def test_a_topic_timed_by_the_log_beside_stamped_ones_is_said(
    streams: dict[str, Any], tmp_path: Path
) -> None:
    """IMU 2's stamps all zero (timed by the log, 150 ms after its instants), IMU 1's
    stamped: the pairs join IMU 1's instants with IMU 2's arrivals, a delay the log
    cannot show; one warning names the topic."""
    mixed = [dict(streams["imu"][0]), dict(streams["imu"][1])]
    mixed[1]["log"] = mixed[1]["stamps"] + 150_000_000
    mixed[1]["stamps"] = np.zeros_like(mixed[1]["stamps"])
    with pytest.warns(TopicClockWarning) as seen:
        read_imu_topics(write_mcap_topics(tmp_path / "m.mcap", mixed), TOPICS, 2)
    said = [str(w.message) for w in seen]
    assert len(said) == 1 and "/imu2 has no header stamps (every one zero)" in said[0], said


def test_a_topic_whose_stamps_do_not_advance_is_said_so_among_stamped_ones(
    streams: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 2's driver sets header.stamp once (every stamp the same, non-zero): its topic
    is timed by the log, and the warning and the note say its stamps do not advance, not
    that they are zero, as a lone topic's note does."""
    stale = [dict(streams["imu"][0]), dict(streams["imu"][1])]
    stale[1]["log"] = stale[1]["stamps"] + 2_000_000
    stale[1]["stamps"] = np.full_like(stale[1]["stamps"], stale[1]["stamps"][0])
    path = write_mcap_topics(tmp_path / "s.mcap", stale)
    with pytest.warns(TopicClockWarning) as seen:
        paired = read_imu_topics(path, TOPICS, 2)
    said = [str(w.message) for w in seen]
    assert len(said) == 1 and "/imu2 has header stamps that do not advance" in said[0], said
    assert "every one zero" not in said[0]
    assert paired.logs[1].stale_stamps == len(stale[1]["stamps"]) - 1
    out = tmp_path / "e.csv"
    args = ["estimate", str(path), "--robot", "two-section", "--method", "ekf"]
    with pytest.warns(TopicClockWarning):
        assert main([*args, "--topic", TOPICS[0], "--topic", TOPICS[1], "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "/imu2: the header stamps do not advance" in err and "stamp is zero" not in err, err


def test_zero_of_time_is_imu_1_s_first_stamp_where_a_topic_starts_later(
    streams: dict[str, Any], tmp_path: Path
) -> None:
    """IMU 2 starting 0.16 s after IMU 1: ``t = 0`` stays at IMU 1's first stamp, where
    a tensions file counted from IMU 1's first message has it (not at the first pair's,
    which would put every later tension 0.16 s off in time, the rows `ok`); the samples before IMU
    2's first are IMU 2's dropouts."""
    late2 = {k: v[streams["imu"][1]["stamps"] >= streams["base"][8]] for k, v in
             streams["imu"][1].items()}  # fmt: skip
    log = write_mcap_topics(tmp_path / "late.mcap", [streams["imu"][0], late2])
    paired = read_imu_topics(log, TOPICS, 2)
    assert paired.t0_ns == streams["imu"][0]["stamps"][0] == T0_NS
    np.testing.assert_allclose(paired.t, (streams["timeline"] - T0_NS) / 1e9)
    first = int(np.argmax(paired.logs[1].numbers > 0))
    assert paired.t[first] == pytest.approx(0.16) and paired.dropouts[1] == first


def test_an_error_names_the_message_in_its_topic_not_the_paired_sample(
    streams: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 1's message 40 without an acceleration: two of IMU 1's samples before it have
    no partner, and the error names the message in its topic (not "sample 38", the
    paired samples' count)."""
    imus = [dict(streams["imu"][0]), streams["imu"][1]]
    acc = imus[0]["acc"].copy()
    acc[39] = np.nan
    imus[0]["acc"] = acc
    log = write_mcap_topics(tmp_path / "nan.mcap", imus)
    argv = ["estimate", str(log), "--robot", "two-section", "--method", "ekf", "-o"]
    assert main([*argv, str(tmp_path / "e.csv"), "--topic", TOPICS[0], "--topic", TOPICS[1]]) == 2
    err = capsys.readouterr().err
    assert "topic /imu1: the message at t = 0.8 s (message 40): linear_acceleration is" in err


def test_a_topic_that_pairs_nowhere_is_one_line(streams: dict[str, Any], tmp_path: Path) -> None:
    """IMU 2's stamps 10 s after IMU 1's (no sample within the tolerance): every
    sample would be IMU 2's dropout; one line names the topic and the tolerance."""
    far = [dict(streams["imu"][0]), dict(streams["imu"][1])]
    far[1]["stamps"] = far[1]["stamps"] + 10_000_000_000
    far[1]["log"] = far[1]["stamps"]
    log = write_mcap_topics(tmp_path / "far.mcap", far)
    with pytest.raises(InputError, match=r"no sample of /imu2 pairs with one of /imu1 within "
                       r"10 ms \(--pair-tolerance\)$"):  # fmt: skip
        read_imu_topics(log, TOPICS, 2)


def test_a_tolerance_of_seconds_is_said_in_seconds(streams: dict[str, Any], tmp_path: Path) -> None:
    """``--pair-tolerance 5`` is reported as "within 5 s", not "within 5e+03 ms"."""
    log = write_mcap_topics(tmp_path / "x.mcap", streams["imu"])
    assert " within 5 s; " in read_imu_topics(log, TOPICS, 2, tolerance_s=5.0).report()
    assert " within 10 ms; " in read_imu_topics(log, TOPICS, 2).report()


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_topics_pair_by_stamp_and_count_the_rest(
    kind: str, streams: dict[str, Any], tmp_path: Path
) -> None:
    write, name = WRITERS[kind]
    log = write(tmp_path / name, streams["imu"])
    paired = read_imu_topics(log, TOPICS, 2)
    assert paired.tolerance_s == pytest.approx(0.010)  # half of the 20 ms period
    imu1 = streams["imu"][0]["stamps"]  # every sample of IMU 1 is a sample, and IMU 2's
    timeline = streams["timeline"]  # sample 30 where IMU 1 has none (its outage)
    np.testing.assert_array_equal(paired.t, (timeline - imu1[0]) / 1e9)
    assert paired.t0_ns == imu1[0]
    # samples 5 and 6 have no IMU 2 partner: dropouts of IMU 2 there; sample 30 none of
    # IMU 1; IMU 2's three strays are unused
    assert paired.dropouts == (1, 2) and paired.unpaired == (0, streams["strays"])
    missing = np.isin(np.arange(len(timeline)), [5, 6])
    assert np.isnan(paired.logs[1].acc[missing]).all()
    assert np.array_equal(paired.logs[1].numbers == 0, missing)
    assert np.array_equal(paired.logs[0].numbers == 0, np.arange(len(timeline)) == 30)
    assert np.isnan(paired.logs[0].acc[30]).all()
    # every IMU 2 sample in a pair is the one stamped 1.5 +- 1 ms after IMU 1's sample
    ref = streams["base"][streams["with_imu2"]]
    i2 = np.searchsorted(streams["imu"][1]["stamps"], ref + 500_000)
    np.testing.assert_array_equal(paired.logs[1].acc[~missing], streams["imu"][1]["acc"][i2])
    assert paired.report() == (
        f"paired {len(timeline)} samples of 2 topics (/imu1, /imu2) by header stamps within "
        f"10 ms; without a partner (a dropout of that IMU): /imu1 1, /imu2 2; unpaired: "
        f"/imu1 0, /imu2 {streams['strays']}"
    )
    # a tolerance below the 0.5..2.5 ms offsets pairs fewer, and says so
    tight = read_imu_topics(log, TOPICS, 2, tolerance_s=0.0015)
    assert len(tight.t) == len(paired.t) and tight.dropouts[1] > paired.dropouts[1]
    assert tight.unpaired[1] - paired.unpaired[1] == tight.dropouts[1] - paired.dropouts[1]


def _paired_csv(path: Path, streams: dict[str, Any], pairs: Any) -> Path:
    """The multi-IMU raw CSV holding the paired samples (the reader's own format), an
    IMU's fields empty where it has no partner."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", *raw_columns(0, 2, True), *raw_columns(1, 2, True)])
        for k, t in enumerate(pairs.t):
            row = [repr(float(t))]
            for log in pairs.logs:
                values = (*log.acc[k], *log.gyr[k])
                row += ["" if math.isnan(v) else repr(float(v)) for v in values]
            w.writerow(row)
    return path


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_estimate_from_topics_equals_the_paired_csv(
    kind: str, streams: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write, name = WRITERS[kind]
    log = write(tmp_path / name, streams["imu"])
    robot = ["--robot", "two-section", "--method", "ekf", "--imu-model", "direct"]
    topics = ["--topic", TOPICS[0], "--topic", TOPICS[1]]
    assert main(["estimate", str(log), "-o", str(tmp_path / "a.csv"), *robot, *topics]) == 0
    err = capsys.readouterr().err
    assert err.count("paired ") == 1
    assert f"unpaired: /imu1 0, /imu2 {streams['strays']}" in err
    csv_in = _paired_csv(tmp_path / "p.csv", streams, read_imu_topics(log, TOPICS, 2))
    assert main(["estimate", str(csv_in), "-o", str(tmp_path / "b.csv"), *robot]) == 0
    a = read_state_table(tmp_path / "a.csv", ())
    b = read_state_table(tmp_path / "b.csv", ())
    assert len(a.t) == len(streams["timeline"])
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-9)


PLANAR_S = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2/planar-s_raw.csv"


@pytest.mark.parametrize(
    ("kind", "late"), [("mcap", (2, 0)), ("ros1", (2, 0)), ("ros2", (1, 0)), ("mcap", (0, 2))]
)
def test_a_topic_that_starts_later_leaves_t_on_the_recording_s_clock(
    kind: str, late: tuple[int, int], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped planar-s rod's first second as a log, one topic per IMU stamped at
    ``T0_NS`` plus the recording's ``t``, one topic's first messages missing (IMU 1
    starting 40 or 20 ms after IMU 2, or IMU 2 after IMU 1): ``t = 0`` is the log's first
    sample, whichever topic's, and the estimates equal those of the recording with that
    IMU's fields empty in its first rows (its ``t``, the truth's clock: IMU 1's first
    stamp put every estimate 40 ms off the truth's, silently); the line says where
    ``t = 0`` is when IMU 1 starts later."""
    lines = PLANAR_S.read_text().splitlines()[:52]
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    stamps = T0_NS + np.round(rows[:, 0] * 1e9).astype(np.int64)
    imus = [
        {"stamps": stamps[d:], "acc": rows[d:, 1 + 6 * k : 4 + 6 * k],
         "gyr": rows[d:, 4 + 6 * k : 7 + 6 * k]}
        for k, d in enumerate(late)
    ]  # fmt: skip
    write, name = WRITERS[kind]
    log = write(tmp_path / name, imus)
    table = [lines[0]]
    for i, line in enumerate(lines[1:]):
        fields = line.split(",")
        for k, d in enumerate(late):
            if i < d:
                fields[1 + 6 * k : 7 + 6 * k] = [""] * 6
        table.append(",".join(fields))
    csv_in = tmp_path / "late.csv"
    csv_in.write_text("\n".join(table) + "\n")
    robot = ["--robot", "two-section", "--method", "ekf"]
    topics = ["--topic", TOPICS[0], "--topic", TOPICS[1]]
    assert main(["estimate", str(log), "-o", str(tmp_path / "a.csv"), *robot, *topics]) == 0
    err = capsys.readouterr().err
    assert main(["estimate", str(csv_in), "-o", str(tmp_path / "b.csv"), *robot]) == 0
    a = read_state_table(tmp_path / "a.csv", ())
    b = read_state_table(tmp_path / "b.csv", ())
    assert len(a.t) == len(b.t) == len(rows)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-9)
    assert f"# t0_ns = {T0_NS}\n" in (tmp_path / "a.csv").read_text()
    missing = ", ".join(f"{topic} {d}" for topic, d in zip(TOPICS, late) if d or topic != TOPICS[0])
    assert f"without a partner (a dropout of that IMU): {missing}; " in err
    starts = f"/imu1 starts {20 * late[0]} ms after /imu2: t = 0 at /imu2's first stamp"
    assert (starts in err) == (late[0] > 0), err


def test_an_outage_of_imu_1_is_estimated_from_the_other_imus(
    streams: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 1 silent for 0.6 s (samples 40 to 69) while IMU 2 goes on at twice IMU 1's
    rate there: those 0.6 s are estimated from IMU 2 at IMU 1's rate (its samples not
    left unused, a gap in the estimate), IMU 1 missing as in a table's row with its
    fields empty (the estimates equal those of that table), and the line says so."""
    imu1, imu2 = dict(streams["imu"][0]), dict(streams["imu"][1])
    base = streams["base"]
    out = (imu1["stamps"] >= base[40]) & (imu1["stamps"] <= base[69])
    imu1 = {k: v[~out] for k, v in imu1.items()}
    extra = (imu2["stamps"] > base[40]) & (imu2["stamps"] < base[69])  # 100 Hz there
    imu2 = {k: np.concatenate([v, v[extra]]) if k != "stamps" else
            np.concatenate([v, v[extra] + 10_000_000]) for k, v in imu2.items()}  # fmt: skip
    order = np.argsort(imu2["stamps"])
    imu2 = {k: v[order] for k, v in imu2.items()}
    log = write_mcap_topics(tmp_path / "outage.mcap", [imu1, imu2])
    pairs = read_imu_topics(log, TOPICS, 2)
    inside = (pairs.t > (base[39] - T0_NS) / 1e9) & (pairs.t < (base[70] - T0_NS) / 1e9)
    assert inside.sum() == 30 and pairs.dropouts[0] == 30 + 1  # and sample 30
    assert np.median(np.diff(pairs.t[inside])) == pytest.approx(0.02, abs=2e-3)
    assert (pairs.logs[0].numbers[inside] == 0).all() and (pairs.logs[1].numbers[inside] > 0).all()
    robot = ["--robot", "two-section", "--method", "ekf", "--imu-model", "direct"]
    topics = ["--topic", TOPICS[0], "--topic", TOPICS[1]]
    assert main(["estimate", str(log), "-o", str(tmp_path / "a.csv"), *robot, *topics]) == 0
    assert (
        "without a partner (a dropout of that IMU): /imu1 31, /imu2 2; " in capsys.readouterr().err
    )
    csv_in = _paired_csv(tmp_path / "p.csv", streams, pairs)
    assert main(["estimate", str(csv_in), "-o", str(tmp_path / "b.csv"), *robot]) == 0
    a = read_state_table(tmp_path / "a.csv", ())
    b = read_state_table(tmp_path / "b.csv", ())
    assert len(a.t) == len(pairs.t) == len(imu1["stamps"]) + 31
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-9)


def test_imu_1_stopping_first_leaves_the_other_imus_estimated(
    streams: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 1 stops after sample 69 of 101 while IMU 2 goes on: the last 0.62 s are
    estimated from IMU 2 (not left out, the estimate ending with IMU 1), IMU 1
    missing as in a table's row with its fields empty (the estimates equal that
    table's), and the line counts them as IMU 1's dropouts."""
    imu1, imu2 = dict(streams["imu"][0]), dict(streams["imu"][1])
    base = streams["base"]
    imu1 = {k: v[imu1["stamps"] <= base[69]] for k, v in imu1.items()}
    log = write_mcap_topics(tmp_path / "stop.mcap", [imu1, imu2])
    pairs = read_imu_topics(log, TOPICS, 2)
    after = pairs.t > (base[69] - T0_NS) / 1e9
    tail = len(base) - 70  # IMU 2's samples 70 on (its stray one there is thinned out)
    assert after.sum() == tail and pairs.dropouts[0] == tail + 1  # and sample 30
    assert (pairs.logs[0].numbers[after] == 0).all() and (pairs.logs[1].numbers[after] > 0).all()
    robot = ["--robot", "two-section", "--method", "ekf", "--imu-model", "direct"]
    topics = ["--topic", TOPICS[0], "--topic", TOPICS[1]]
    assert main(["estimate", str(log), "-o", str(tmp_path / "a.csv"), *robot, *topics]) == 0
    assert (
        f"without a partner (a dropout of that IMU): /imu1 {tail + 1}, " in capsys.readouterr().err
    )
    csv_in = _paired_csv(tmp_path / "p.csv", streams, pairs)
    assert main(["estimate", str(csv_in), "-o", str(tmp_path / "b.csv"), *robot]) == 0
    a = read_state_table(tmp_path / "a.csv", ())
    b = read_state_table(tmp_path / "b.csv", ())
    assert len(a.t) == len(imu1["stamps"]) + tail + 1
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    ("topics", "says"),
    [
        ([], "no --topic for a robot with 2 IMUs"),
        (["/imu1"], "1 --topic for a robot with 2 IMUs"),
        (["/imu1", "/imu2", "/imu1"], "3 --topic for a robot with 2 IMUs"),
        (["/imu1", "/imu1"], "given twice"),
        (["/imu1", "/nope"], "no topic '/nope'"),
    ],
)
def test_wrong_topics_are_one_line(
    topics: list[str], says: str, streams: dict[str, Any], tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    log = write_mcap_topics(tmp_path / "x.mcap", streams["imu"])
    out = tmp_path / "e.csv"
    args = ["estimate", str(log), "-o", str(out), "--robot", "two-section"]
    assert main([*args, *(a for t in topics for a in ("--topic", t))]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("continuum-mhe: error: "), err
    assert says in err[0]
    if "for a robot with" in says:  # a wrong count lists the log's Imu topics
        assert err[0].endswith("sensor_msgs/msg/Imu topics in this log: /imu1, /imu2"), err
    assert not out.exists()
    # a one-IMU robot given two topics
    assert main(["estimate", str(log), "-o", str(out), "--topic", "/imu1", "--topic", "/imu2"]) == 2
    assert "2 --topic for a robot with 1 IMU:" in capsys.readouterr().err


def test_topics_in_the_wrong_order_warn_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A two-IMU robot whose --topic order is swapped restarts the estimator often:
    more than ORDER_RESTART_SHARE of the samples restarting it warns once that the topic
    order may not be the robot's; the right order (far fewer restarts) does not. Topics
    numbered against the order given are said before the run, from their names."""
    import warnings

    from continuum_mhe.io.imu_topics import TopicOrderWarning

    rec = raw_imu_recording(read_robot("two-section"), 10.0)
    n = len(rec.t)
    stamps = T0_NS + np.arange(n, dtype=np.int64) * DT_NS
    imus = [
        {
            "stamps": stamps,
            "acc": G * rec.z[:, 6 * k : 6 * k + 3],
            "gyr": rec.z[:, 6 * k + 3 : 6 * k + 6],
        }
        for k in range(2)
    ]
    log = write_mcap_topics(tmp_path / "x.mcap", imus)
    out = tmp_path / "e.csv"
    args = ["estimate", str(log), "-o", str(out), "--robot", "two-section", "--method", "ekf",
            "--imu-model", "direct"]  # fmt: skip
    with pytest.warns(TopicOrderWarning) as seen:
        assert main([*args, "--topic", "/imu2", "--topic", "/imu1"]) == 0
    (names, said) = [str(w.message) for w in seen if w.category is TopicOrderWarning]
    assert names == (  # before the run, from the names
        f"{log}: the topics are given as /imu2, /imu1, against the numbers in their names: "
        "the first --topic is IMU 1 of the robot file (nearest the base), the next IMU 2, "
        "...; if /imu1 is the IMU nearest the base, give it first (IMUs in the wrong order "
        "can give estimates far off that fit the readings, or a calibration written to the "
        "wrong IMU)"
    )
    assert said.startswith(f"{log}: ") and " samples (" in said
    assert said.endswith(
        "restarted the estimator (readings inconsistent with its estimate): the readings do "
        "not fit the robot; check that the --topic order (/imu2, /imu1) is the robot file's "
        "IMU order (IMU 1 nearest the base)"
    )
    wrong = int(re.search(r"reset: (\d+)", capsys.readouterr().err).group(1))
    with warnings.catch_warnings():
        warnings.simplefilter("error", TopicOrderWarning)
        assert main([*args, "--topic", "/imu1", "--topic", "/imu2", "--overwrite"]) == 0
    right = re.search(r"reset: (\d+)", capsys.readouterr().err.splitlines()[-1])
    assert right is None or int(right.group(1)) * 5 < wrong  # far fewer restarts


@pytest.mark.parametrize(
    ("topics", "numbers"),
    [
        (["/imu2/data", "/imu1/data"], [2, 1]),
        (["/robot1/imu2", "/robot1/imu1"], [2, 1]),
        (["/imu9", "/imu10"], [9, 10]),
        (["/imu_base", "/imu_tip"], None),
        (["/imu1/a2", "/imu2/a1"], None),
        (["/robot/imu_link2", "/camera1/imu"], None),
        (["/vn100/imu", "/um7/imu"], None),
    ],
)
def test_the_number_that_tells_topics_apart(topics: list[str], numbers: list[int] | None) -> None:
    """The one number position at which names that are otherwise the same differ (none
    where no single one does, or the names differ in more than their numbers): what
    the order check compares with the order given."""
    from continuum_mhe.io.imu_topics import topic_numbers

    assert topic_numbers(topics) == numbers


def test_rates_on_some_topics_only_are_refused_as_a_table_s_columns(
    tmp_path: Path, streams: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 2's topic marks its rates absent (REP 145) while IMU 1's has them: one line
    naming both topics, exit 2, nothing written (not an estimate on the tilt model without
    IMU 1's gyro), as a table with one IMU's gyro columns is refused;
    ``--imu-model tilt`` leaves the gyros out on purpose and runs."""
    imus = [streams["imu"][0], {**streams["imu"][1], "no_gyro": True}]
    log = write_mcap_topics(tmp_path / "mixed.mcap", imus)
    out = tmp_path / "e.csv"
    argv = ["estimate", str(log), "-o", str(out), "--robot", "two-section"]
    argv += [a for t in TOPICS for a in ("--topic", t)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == (
        f"continuum-mhe: error: {log}: topic {TOPICS[1]} has no angular rates "
        f"(angular_velocity_covariance[0] = -1 in every message) while {TOPICS[0]} has "
        "them: give every IMU's gyro or none (as a table's columns), or --imu-model tilt "
        "to leave the gyros out\n"
    )
    assert not out.exists()
    assert main([*argv, "--imu-model", "tilt"]) == 0


REST = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2/spatial-tendon_rest.csv"


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_calibrate_from_topics_equals_the_csv(kind: str, tmp_path: Path, capsys) -> None:
    """``calibrate --from`` a bag or MCAP file of a rest recording, one ``--topic`` per
    IMU, reports and writes the calibration of the same readings as a CSV file (the
    report's lines but the source's name equal, the robot files equal)."""
    rows = np.loadtxt(REST, delimiter=",", skiprows=1)
    stamps = T0_NS + np.round(rows[:, 0] * 1e9).astype(np.int64)
    imus = [{"stamps": stamps, "acc": rows[:, 1 + 6 * k : 4 + 6 * k],
             "gyr": rows[:, 4 + 6 * k : 7 + 6 * k]} for k in range(2)]  # fmt: skip
    writer, name = WRITERS[kind]
    log = writer(tmp_path / name, imus)
    reports = []
    for source, topics in ((REST, []), (log, ["--topic", TOPICS[0], "--topic", TOPICS[1]])):
        robot = tmp_path / f"{Path(source).stem}.toml"
        argv = ["calibrate", "--from", str(source), "--robot", "two-section", *topics]
        assert main([*argv, "--write-robot", str(robot)]) == 0
        out = capsys.readouterr().out.replace(str(source), "SOURCE")
        reports.append((out, robot.read_text()))
    assert reports[0] == reports[1]
    assert main(["calibrate", "--from", str(log), "--robot", "two-section"]) == 2
    assert "no --topic for a robot with 2 IMUs" in capsys.readouterr().err
    assert main(["calibrate", "--from", str(REST), "--topic", "/imu1"]) == 2
    assert "--topic chooses the IMUs of a ROS bag or MCAP file" in capsys.readouterr().err


@pytest.mark.parametrize("reading", ["zero", "corrupt"])
def test_calibrate_from_topics_leaves_an_impossible_reading_out_as_the_csv(
    reading: str, tmp_path: Path, capsys
) -> None:
    """``calibrate --from`` a log whose IMU 1 has one message with a zero acceleration (a
    driver's placeholder), or with a rate beyond any gyro's range (a corrupt value): that
    reading is left out of the mean and noise and said with its time, and the report and
    robot file equal those of the same readings as a CSV file (not a robot said to have
    moved, its calibration ruined by one message)."""
    rows = np.loadtxt(REST, delimiter=",", skiprows=1)
    if reading == "zero":
        rows[10, 1:4] = 0.0
    else:
        rows[10, 4] = 5e3
    table = tmp_path / "rest.csv"
    with REST.open() as fh:
        header = fh.readline().strip()
    np.savetxt(table, rows, delimiter=",", header=header, comments="", fmt="%.17g")
    stamps = T0_NS + np.round(rows[:, 0] * 1e9).astype(np.int64)
    imus = [{"stamps": stamps, "acc": rows[:, 1 + 6 * k : 4 + 6 * k],
             "gyr": rows[:, 4 + 6 * k : 7 + 6 * k]} for k in range(2)]  # fmt: skip
    log = write_mcap_topics(tmp_path / "rest.mcap", imus)
    reports = []
    for source, topics in ((table, []), (log, ["--topic", TOPICS[0], "--topic", TOPICS[1]])):
        robot = tmp_path / f"{Path(source).suffix[1:]}.toml"
        argv = ["calibrate", "--from", str(source), "--robot", "two-section", *topics]
        assert main([*argv, "--write-robot", str(robot)]) == 0
        captured = capsys.readouterr()
        assert captured.err.startswith(
            f"continuum-mhe: warning: {source}: 1 of {len(rows)} row(s) with a reading "
            f"missing, zero or beyond any IMU's range (the first at t = {rows[10, 0]:g} s): "
            "that IMU's reading is left out of its mean and noise there\n"
        )
        reports.append((captured.out.replace(str(source), "SOURCE"), robot.read_text()))
    assert reports[0] == reports[1]


def test_a_bags_metadata_file_names_the_folder(tmp_path: Path, capsys) -> None:
    """A ROS 2 bag's ``metadata.yaml`` given for the bag (not read as a CSV file without
    IMU columns): one line naming the folder, for estimate and calibrate."""
    rows = np.loadtxt(REST, delimiter=",", skiprows=1)[:50]
    stamps = T0_NS + np.round(rows[:, 0] * 1e9).astype(np.int64)
    imus = [{"stamps": stamps, "acc": rows[:, 1 + 6 * k : 4 + 6 * k],
             "gyr": rows[:, 4 + 6 * k : 7 + 6 * k]} for k in range(2)]  # fmt: skip
    bag = write_ros2_topics(tmp_path / "bag", imus)
    meta = str(bag / "metadata.yaml")
    topics = ["--topic", TOPICS[0], "--topic", TOPICS[1], "--robot", "two-section"]
    for argv in (
        ["estimate", meta, *topics, "-o", str(tmp_path / "e.csv")],
        ["calibrate", "--from", meta, *topics],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.endswith(f"the metadata file of a ROS 2 bag: give the bag's folder, {bag}")
    assert not (tmp_path / "e.csv").exists()


def test_a_missing_topic_given_out_of_number_order_is_refused_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--topic /imu3 --topic /imu1`` on a log without ``/imu3``: the refusal is the
    command's one line, without the warning that the names number the topics in another
    order (said only once the topics are read)."""
    rec = raw_imu_recording(read_robot("two-section"), 1.0)
    stamps = T0_NS + np.arange(len(rec.t), dtype=np.int64) * DT_NS
    imus = [
        {"stamps": stamps, "acc": G * rec.z[:, 6 * k : 6 * k + 3],
         "gyr": rec.z[:, 6 * k + 3 : 6 * k + 6]}
        for k in range(2)
    ]  # fmt: skip
    log = write_mcap_topics(tmp_path / "x.mcap", imus)
    out = tmp_path / "e.csv"
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        # shown on stderr as a command's warnings are outside the test runner
        warnings.showwarning = lambda m, c, f, n, file=None, line=None: sys.stderr.write(
            warnings.formatwarning(m, c, f, n, line)
        )
        status = main(["estimate", str(log), "-o", str(out), "--robot", "two-section",
                       "--topic", "/imu3", "--topic", "/imu1"])  # fmt: skip
    err = capsys.readouterr().err.splitlines()
    assert status == 2 and len(err) == 1, err
    assert err[0].startswith(f"continuum-mhe: error: {log}: no topic '/imu3'"), err
    assert not out.exists()
