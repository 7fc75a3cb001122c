"""ROS 1 / ROS 2 bags and MCAP files through ``estimate``: the same estimates as the
equivalent raw CSV; MCAP output readable and equal to the CSV output."""

from __future__ import annotations

import csv
import json
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cli_helpers import figures_drawn_small
from robot_log_helpers import IMU, T0_NS, imu_msg
from scipy.spatial.transform import Rotation

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io.csv_files import UnitWarning
from continuum_mhe.io.mcap_estimates import read_estimates_mcap
from continuum_mhe.io.robot_logs import read_imu_log, tilt_from_quaternion
from continuum_mhe.io.state_tables import read_states
from continuum_mhe.model.direct import raw_imu_readings
from continuum_mhe.model.imu import tilt, tilt_from_accelerometer
from continuum_mhe.simulation.scenarios import simulate


@pytest.fixture(scope="module")
def recording() -> dict[str, Any]:
    rec = simulate("paper3d", duration=3.0, dt=0.02, noise_deg=0.0)
    acc, gyr = raw_imu_readings(rec.t, rec.truth[:, 3], rec.truth[:, 4], 0.2)
    rng = np.random.default_rng(3)
    acc = acc + rng.normal(size=acc.shape) * 0.2
    gyr = gyr + rng.normal(size=gyr.shape) * 0.01
    stamps = T0_NS + np.round(rec.t * 1e9).astype(np.int64)
    return {"stamps": stamps, "acc": acc, "gyr": gyr, "truth": rec.truth}


def write_ros2_bag(path: Path, rec: dict[str, Any], topic: str = "/tip/imu") -> Path:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=9) as w:
        conn = w.add_connection(topic, IMU, typestore=store)
        other = w.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        w.write(
            other,
            int(rec["stamps"][0]),
            store.serialize_cdr(
                store.types["std_msgs/msg/String"](data="hello"), "std_msgs/msg/String"
            ),
        )
        quats = rec.get("quat", [None] * len(rec["stamps"]))
        no_accel = rec.get("no_accel", np.zeros(len(rec["stamps"]), dtype=bool))
        for ns, a, g, q, na in zip(rec["stamps"], rec["acc"], rec["gyr"], quats, no_accel):
            msg = imu_msg(store, int(ns), a, g, quat=q, no_accel=bool(na))
            w.write(conn, int(ns), store.serialize_cdr(msg, IMU))
    return path


def write_ros1_bag(path: Path, rec: dict[str, Any], topic: str = "/tip/imu") -> Path:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conn = w.add_connection(topic, IMU, typestore=store)
        for ns, a, g in zip(rec["stamps"], rec["acc"], rec["gyr"]):
            w.write(conn, int(ns), store.serialize_ros1(imu_msg(store, int(ns), a, g, True), IMU))
    return path


def write_mcap(
    path: Path,
    rec: dict[str, Any],
    topic: str = "/tip/imu",
    headers: np.ndarray | None = None,
    no_gyro: bool = False,
    summary: bool = True,
) -> Path:
    """An MCAP of ``rec``'s Imu messages, logged at their stamps; ``headers``: other
    header stamps, ns; ``no_gyro``: every message's rates marked absent; without
    ``summary``, no summary section (it is optional in MCAP)."""
    from mcap.writer import CompressionType, IndexType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    msgdef, _ = store.generate_msgdef(IMU, ros_version=2)
    with path.open("wb") as fh:
        bare = {} if summary else {
            "index_types": IndexType.NONE, "repeat_channels": False, "repeat_schemas": False,
            "use_chunking": False, "use_statistics": False, "use_summary_offsets": False,
        }  # fmt: skip
        w = Writer(fh, compression=CompressionType.NONE, **bare)
        w.start()
        sid = w.register_schema(name=IMU, encoding="ros2msg", data=msgdef.encode())
        cid = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        stamps = rec["stamps"] if headers is None else headers
        for ns, h, a, g in zip(rec["stamps"], stamps, rec["acc"], rec["gyr"]):
            msg = imu_msg(store, int(h), a, g, no_gyro=no_gyro)
            data = bytes(store.serialize_cdr(msg, IMU))
            w.add_message(cid, log_time=int(ns), data=data, publish_time=int(ns))
        w.finish()
    return path


def write_ros1_mcap(path: Path, rec: dict[str, Any], topic: str = "/tip/imu") -> Path:
    """An MCAP of ``rec``'s Imu messages in ROS 1's encoding, as ``mcap convert run.bag``
    writes a ROS 1 bag's (schema ``sensor_msgs/Imu``, encoding ``ros1msg``)."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    msgdef, _ = store.generate_msgdef(IMU, ros_version=1)
    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start(profile="ros1")
        sid = w.register_schema(name="sensor_msgs/Imu", encoding="ros1msg", data=msgdef.encode())
        cid = w.register_channel(topic=topic, message_encoding="ros1", schema_id=sid)
        for ns, a, g in zip(rec["stamps"], rec["acc"], rec["gyr"]):
            data = bytes(store.serialize_ros1(imu_msg(store, int(ns), a, g, True), IMU))
            w.add_message(cid, log_time=int(ns), data=data, publish_time=int(ns))
        w.finish()
    return path


def write_raw_csv(path: Path, rec: dict[str, Any]) -> Path:
    t = (rec["stamps"] - rec["stamps"][0]) / 1e9
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "ax", "ay", "az", "gx", "gy", "gz"])
        for row in zip(t, rec["acc"], rec["gyr"]):
            w.writerow(
                [
                    repr(float(row[0])),
                    *map(repr, map(float, row[1])),
                    *map(repr, map(float, row[2])),
                ]
            )
    return path


def _estimate(inp: Path, out: Path, *extra: str) -> None:
    assert main(["estimate", str(inp), "-o", str(out), *extra]) == 0


def _states(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return read_states(path)


@pytest.mark.parametrize("kind", ["ros2", "ros1", "mcap", "ros1-mcap"])
@pytest.mark.parametrize("model", ["tilt", "direct"])
def test_log_gives_same_estimates_as_csv(
    tmp_path: Path, recording: dict[str, Any], kind: str, model: str
) -> None:
    writer = {
        "ros2": write_ros2_bag, "ros1": write_ros1_bag, "mcap": write_mcap,
        "ros1-mcap": write_ros1_mcap,
    }[kind]  # fmt: skip
    name = {"ros2": "bag2", "ros1": "run.bag", "mcap": "run.mcap", "ros1-mcap": "r1.mcap"}[kind]
    log = writer(tmp_path / name, recording)
    csv_in = write_raw_csv(tmp_path / "raw.csv", recording)
    opts = ["--method", "ekf", "--imu-model", model]
    _estimate(csv_in, tmp_path / "from_csv.csv", *opts)
    _estimate(log, tmp_path / "from_log.csv", *opts, "--topic", "/tip/imu")
    t_c, x_c, s_c = _states(tmp_path / "from_csv.csv")
    t_l, x_l, s_l = _states(tmp_path / "from_log.csv")
    assert len(t_c) == len(recording["stamps"])
    np.testing.assert_array_equal(t_l, t_c)
    np.testing.assert_allclose(x_l, x_c, rtol=0, atol=1e-12)
    assert list(s_l) == list(s_c)
    # and the estimates are good: tip within a few mm of the truth
    tip_err = np.linalg.norm(x_l[:, :3] - recording["truth"][:, :3], axis=1)
    assert np.mean(tip_err) < 5e-3


def test_log_reader_times_and_topic_choice(tmp_path: Path, recording: dict[str, Any]) -> None:
    bag = write_ros2_bag(tmp_path / "bag2", recording)
    log = read_imu_log(bag)  # only one Imu topic: picked without --topic
    assert log.topic == "/tip/imu"
    assert log.t0_ns == T0_NS
    assert log.t[0] == 0.0 and np.all(np.diff(log.t) > 0)
    np.testing.assert_allclose(log.t[-1], 3.0, atol=1e-9)
    np.testing.assert_array_equal(log.acc, recording["acc"])
    assert np.all(np.isnan(log.orientation))  # covariance -1: no orientation


def test_estimate_writes_mcap_matching_csv(tmp_path: Path, recording: dict[str, Any]) -> None:
    from mcap.reader import make_reader

    bag = write_mcap(tmp_path / "in.mcap", recording)
    _estimate(bag, tmp_path / "est.csv", "--method", "ekf")
    _estimate(bag, tmp_path / "est.mcap", "--method", "ekf")
    t_c, x_c, s_c = read_states(tmp_path / "est.csv")
    t_m, x_m, s_m = read_estimates_mcap(tmp_path / "est.mcap")
    np.testing.assert_allclose(t_m, t_c, atol=1e-9)
    np.testing.assert_allclose(x_m, x_c, rtol=1e-9, atol=1e-12)
    assert list(s_m) == list(s_c)
    with (tmp_path / "est.mcap").open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name for s in summary.schemas.values()}
        assert {"foxglove.PoseInFrame", "foxglove.PosesInFrame"} <= schemas
        tips = list(reader.iter_messages(topics=["/continuum/tip"]))
    assert len(tips) == len(t_c)
    # the pose's log time is the bag's absolute time, so it lines up with other topics
    assert tips[0][2].log_time == T0_NS
    pose = json.loads(tips[-1][2].data)
    assert pose["frame_id"] == "continuum_base"
    np.testing.assert_allclose([pose["pose"]["position"][k] for k in "xyz"], x_c[-1, :3], atol=1e-9)


def test_an_estimate_mcap_with_an_unknown_status_is_one_line(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """An estimate MCAP whose third estimate says 'OK' (another tool's, or edited), as the
    CSV reader does: one line naming the file, the message and the vocabulary, exit 2."""
    from mcap.reader import make_reader

    from continuum_mhe.io.mcap_estimates import mcap_estimate_writer
    from continuum_mhe.model.descriptions import pcc_outputs

    est, edited = tmp_path / "est.mcap", tmp_path / "edited.mcap"
    _estimate(write_mcap(tmp_path / "in.mcap", recording), est, "--method", "ekf")
    with est.open("rb") as src, edited.open("wb") as dst:
        writer = mcap_estimate_writer(dst, pcc_outputs(1))
        seen = 0
        for seq, (_, channel, message) in enumerate(make_reader(src).iter_messages()):
            msg = json.loads(message.data)
            if channel.topic == "/continuum/estimate":
                seen += 1
                if seen == 3:
                    assert msg["status"] == "ok"
                    msg["status"] = "OK"
            writer.add(channel.topic, message.log_time, msg, seq)
        writer.finish()
    assert len(read_estimates_mcap(est)[0]) == len(recording["stamps"])  # unedited: read
    with pytest.raises(InputError) as info:
        read_estimates_mcap(edited)
    assert str(info.value).startswith(f"{edited}: message 3: status 'OK' is not one of ok, ")
    out = tmp_path / "v.rrd"
    capsys.readouterr()
    assert main(["view", str(edited), "--save", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "message 3: status 'OK'" in err, err
    assert not out.exists()
    # a missing file, a folder, a file cut after its magic: InputError, not OSError
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(est.read_bytes()[:8])
    tiny = tmp_path / "tiny.mcap"  # shorter than the magic: the reader's struct.error
    tiny.write_bytes(b"hello\n")
    tail_cut = tmp_path / "tail_cut.mcap"  # cut inside a record near its end: said so
    tail_cut.write_bytes(est.read_bytes()[:-500])
    zeroed = tmp_path / "zeroed.mcap"  # 64 bytes zeroed inside its compressed chunk
    data = bytearray(est.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = bytes(64)
    zeroed.write_bytes(bytes(data))
    for path, why in ((tmp_path / "none.mcap", "no such file"), (tmp_path, "a folder"),
                      (cut, "cannot read it as an estimate MCAP"),
                      (tail_cut, "cannot read it as an estimate MCAP \\(the file ends "
                                 "inside a record, or is damaged: cut short\\?\\)$"),
                      (tiny, "cannot read it as an estimate MCAP \\(too short"),
                      (zeroed, "cannot read it as an estimate MCAP \\(a compressed chunk "
                               "is damaged: ")):  # fmt: skip
        with pytest.raises(InputError, match=f"^{re.escape(str(path))}: {why}"):
            read_estimates_mcap(path)
    png = str(tmp_path / "t.png")
    unread = [["evaluate", str(tiny), str(tiny)], ["plot", str(tiny), "-o", png],
              ["evaluate", str(zeroed), str(tiny)], ["plot", str(zeroed), "-o", png]]  # fmt: skip
    for argv in unread:
        assert main(argv) == 2
        assert capsys.readouterr().err.count("\n") == 1


def test_an_imu_log_cut_short_says_where_in_one_line(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """An MCAP whose cut lies past its messages (in its index), one shorter than its
    footer, and a ROS 2 bag folder without metadata.yaml (a recorder killed): each is one
    line that says where, exit status 2, nothing written (not a message the topic does
    not have, "message 151" of 150, without the topic, nor the operating system's
    "[Errno 22] Invalid argument"); the bag folder's line names the readable file it
    holds."""
    whole = write_mcap(tmp_path / "whole.mcap", recording)
    n = len(recording["stamps"])
    index_cut = tmp_path / "index_cut.mcap"
    index_cut.write_bytes(whole.read_bytes()[:-10])
    with pytest.raises(InputError) as info:
        read_imu_log(index_cut)
    assert str(info.value).startswith(
        f"{index_cut}: topic /tip/imu: after message {n}: cannot read robot log (the file "
        "ends inside a record, or is damaged: a recording cut short?; --skip-bad reads it "
        "up to the cut)"
    ), info.value
    assert len(read_imu_log(index_cut, skip_bad=True).t) == n
    short = tmp_path / "short.mcap"
    short.write_bytes(whole.read_bytes()[:30])
    with pytest.raises(InputError) as info:
        read_imu_log(short)
    assert str(info.value) == (
        f"{short}: cannot read robot log (the file ends inside a record, or is damaged: a "
        "recording cut short?)"
    )
    folder = tmp_path / "killed_bag"
    folder.mkdir()
    (folder / "killed_bag_0.mcap").write_bytes(whole.read_bytes())
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(folder), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert (
        err
        == (
            f"continuum-mhe: error: {folder}: is a directory without metadata.yaml, expected a "
            "CSV file or a ROS 2 bag folder; it holds killed_bag_0.mcap: give the file itself "
            "(a recorder that stopped?)\n"
        )
        and not out.exists()
    ), err


def _wxyz(r: Rotation) -> np.ndarray:
    """scipy's quaternions are ``(x, y, z, w)``; the Imu message's order is ``(w, x, y, z)``."""
    return np.roll(r.as_quat(), 1, axis=-1)


def test_tilt_from_quaternion_matches_imu_model() -> None:
    q = np.array([[np.cos(0.2), np.sin(0.2), 0.0, 0.0]])  # roll 0.4 rad about x
    np.testing.assert_allclose(tilt_from_quaternion(q), [[0.4, 0.0]], atol=1e-12)
    np.testing.assert_allclose(tilt(0.4, np.pi / 2), [0.4, 0.0], atol=1e-12)


def test_tilt_from_quaternion_with_roll_pitch_and_yaw() -> None:
    """Known answers: the sensor-to-world rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` gives
    back ``(roll, pitch)`` whatever the yaw; and for any rotation the tilt is that of the
    accelerometer at rest, which reads world up (+z) in the sensor frame."""
    rng = np.random.default_rng(11)
    n = 200
    roll = rng.uniform(-3.0, 3.0, n)
    pitch = rng.uniform(-1.5, 1.5, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    r = Rotation.from_euler("ZYX", np.stack([yaw, pitch, roll], -1))
    q = _wxyz(r)
    np.testing.assert_allclose(tilt_from_quaternion(q), np.stack([roll, pitch], -1), atol=1e-12)
    # a quaternion and its negative are the same rotation
    np.testing.assert_allclose(tilt_from_quaternion(-q), tilt_from_quaternion(q), atol=1e-12)
    r = Rotation.random(n, random_state=12)
    up_in_sensor = r.inv().apply([0.0, 0.0, 1.0])
    np.testing.assert_allclose(
        tilt_from_quaternion(_wxyz(r)), tilt_from_accelerometer(up_in_sensor), atol=1e-12
    )


def test_estimate_orientation_equals_the_tilt_csv(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """``estimate --orientation`` on a bag whose orientation has the truth's roll and
    pitch (and a yaw) gives the estimates of the tilt CSV of those angles; the bag's
    noisy accelerometer is not used."""
    truth = recording["truth"]
    rp = tilt(truth[:, 3], truth[:, 4])
    yaw = np.linspace(-2.0, 2.0, len(rp))
    r = Rotation.from_euler("ZYX", np.stack([yaw, rp[:, 1], rp[:, 0]], -1))
    bag = write_ros2_bag(tmp_path / "bag2", {**recording, "quat": _wxyz(r)})
    t = (recording["stamps"] - recording["stamps"][0]) / 1e9
    tilt_csv = tmp_path / "tilt.csv"
    with tilt_csv.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "roll", "pitch"])
        w.writerows([repr(float(a)), repr(float(b)), repr(float(c))] for a, (b, c) in zip(t, rp))
    _estimate(tilt_csv, tmp_path / "from_csv.csv", "--method", "ekf")
    _estimate(bag, tmp_path / "from_bag.csv", "--method", "ekf", "--orientation")
    _estimate(bag, tmp_path / "from_acc.csv", "--method", "ekf")
    t_c, x_c, s_c = _states(tmp_path / "from_csv.csv")
    t_b, x_b, s_b = _states(tmp_path / "from_bag.csv")
    assert len(t_c) == len(t)
    np.testing.assert_array_equal(t_b, t_c)
    np.testing.assert_allclose(x_b, x_c, rtol=0, atol=1e-9)
    assert list(s_b) == list(s_c)
    # the accelerometer's noise gives other estimates: --orientation reads the orientation
    _, x_a, _ = _states(tmp_path / "from_acc.csv")
    assert np.max(np.abs(x_a - x_c)) > 1e-4


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--topic", "/nope"], "no topic '/nope'"),
        (["--topic", "/chatter"], "expected sensor_msgs/msg/Imu"),
        (["--orientation"], "carries no orientation"),
    ],
)
def test_log_errors_are_one_line(
    tmp_path: Path,
    recording: dict[str, Any],
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    needle: str,
) -> None:
    bag = write_ros2_bag(tmp_path / "bag2", recording)
    assert main(["estimate", str(bag), "-o", str(tmp_path / "e.csv"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("continuum-mhe: error: ") and needle in err
    assert "\n" not in err
    assert not (tmp_path / "e.csv").exists()


def test_corrupt_log_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "junk.mcap"
    bad.write_bytes(b"not an mcap file at all")
    assert main(["estimate", str(bad), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("continuum-mhe: error: ") and "\n" not in err


def test_a_damaged_record_in_an_uncompressed_chunk_is_said_not_read_past(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """One byte of an uncompressed MCAP damaged (the opcode of its fourth message): the
    chunk's CRC says so in one line, exit 2, nothing written; the reader without the
    check would end the chunk's messages there and estimate the rest without a word."""
    import struct

    good = write_mcap(tmp_path / "run.mcap", recording)
    data = bytearray(good.read_bytes())
    data[data.find(struct.pack("<Q", int(recording["stamps"][3]))) - 15] = 0
    bad = tmp_path / "damaged.mcap"
    bad.write_bytes(bytes(data))
    out = tmp_path / "e.csv"
    assert main(["estimate", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad}: cannot read robot log (crc validation" in err
    assert not out.exists()
    assert main(["estimate", str(good), "-o", str(out)]) == 0


def test_a_log_named_without_its_suffix_is_read_as_the_log_it_is(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """An MCAP file saved without ``.mcap`` gives the estimates of the same file named
    ``.mcap``, and a ROS 1 bag named ``.bag.active`` (a recording that did not finish) is
    said to be one in one line; neither is read as a CSV file ("contains a NUL byte")."""
    named = write_mcap(tmp_path / "run.mcap", recording)
    bare = tmp_path / "run_mcap"
    bare.write_bytes(named.read_bytes())
    _estimate(named, tmp_path / "a.csv")
    _estimate(bare, tmp_path / "b.csv")
    np.testing.assert_array_equal(_states(tmp_path / "a.csv")[1], _states(tmp_path / "b.csv")[1])
    active = tmp_path / "run.bag.active"
    active.write_bytes(write_ros1_bag(tmp_path / "r.bag", recording).read_bytes())
    capsys.readouterr()
    assert main(["estimate", str(active), "--method", "ekf", "-o", str(tmp_path / "c.csv")]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"continuum-mhe: error: {active}: a ROS 1 bag whose name does not end in .bag: a "
        "recording that did not finish (.bag.active)? rosbag reindex it, then give it named "
        "NAME.bag\n"
    )
    assert not (tmp_path / "c.csv").exists()


@pytest.mark.parametrize("name", ["empty.mcap", "empty.bag", "empty.db3"])
def test_an_empty_log_is_named_empty(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    """A 0-byte log (a recorder that never wrote) is said to be empty, whatever its kind,
    not cut short or damaged."""
    empty = tmp_path / name
    empty.touch()
    out = tmp_path / "e.csv"
    assert main(["estimate", str(empty), "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {empty}: the robot log is empty (0 bytes): a recorder that "
        "never wrote?\n"
    )
    assert not out.exists()


def test_log_gyro_in_deg_s_is_one_line(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """sensor_msgs/Imu's angular velocity is rad/s: a log in deg/s is named as such, an
    error where the estimate uses the gyro (the direct model: the default for a log with
    gyros, or chosen), a warning where it does not (``--imu-model tilt``: tilt from the
    accelerometer)."""
    degs = {**recording, "gyr": np.degrees(recording["gyr"]) + 6.0}  # and an uncalibrated bias
    bag = write_ros2_bag(tmp_path / "bag2", degs)
    out = tmp_path / "e.csv"
    for model in ([], ["--imu-model", "direct"]):
        assert main(["estimate", str(bag), "-o", str(out), *model]) == 2
        err = capsys.readouterr().err.strip()
        assert "topic /tip/imu: gyro magnitude is about" in err and "deg/s? give rad/s" in err
        assert "\n" not in err
        assert not out.exists()
    with pytest.warns(UnitWarning) as seen:
        assert main(["estimate", str(bag), "-o", str(out), "--imu-model", "tilt"]) == 0
    warned = [str(w.message) for w in seen if "deg/s?" in str(w.message)]
    assert len(warned) == 1 and "topic /tip/imu: gyro magnitude is about" in warned[0]
    assert warned[0].endswith("these options do not use the gyro, so the estimate is unaffected")
    assert out.exists()


def test_a_nan_in_a_log_message_is_refused_as_in_a_csv(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """A message whose acceleration (or angular rate) holds a NaN is one line naming the
    topic and the message, exit 2, nothing written, as a CSV's nan field is; with
    --skip-bad it is a dropout."""
    acc = recording["acc"].copy()
    acc[49, 1] = np.nan
    bag = write_ros2_bag(tmp_path / "bag2", {**recording, "acc": acc})
    out = tmp_path / "e.csv"
    assert main(["estimate", str(bag), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "topic /tip/imu: the message at t = " in err
    assert "(message 50): linear_acceleration is [" in err and "nan" in err
    assert err.endswith("(a dropout; --skip-bad keeps it, skip_bad=True in Python)\n")
    assert not out.exists()
    assert main(["estimate", str(bag), "-o", str(out), "--skip-bad"]) == 0
    assert "dropout: 1" in capsys.readouterr().err


def test_a_zero_acceleration_in_a_log_message_is_refused_as_in_a_csv(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """A message whose linear_acceleration is zero (no gravity direction: a driver's
    placeholder) is one line naming the topic and the message, exit 2, nothing written,
    as a CSV row's zero acceleration is; with --skip-bad it is a dropout, counted in the
    run's line with the first such message, as a CSV's bad rows are."""
    acc = recording["acc"].copy()
    acc[[59, 60]] = 0.0
    bag = write_ros2_bag(tmp_path / "bag2", {**recording, "acc": acc})
    table = write_raw_csv(tmp_path / "raw.csv", {**recording, "acc": acc})
    out = tmp_path / "e.csv"
    assert main(["estimate", str(table), "-o", str(out)]) == 2
    assert "acceleration is zero (no gravity direction)" in capsys.readouterr().err
    assert main(["estimate", str(bag), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "topic /tip/imu: the message at t = 1.18 s" in err
    assert "(message 60): linear_acceleration is zero (|a| 0 m/s^2: no gravity direction)" in err
    assert err.endswith("(a dropout; --skip-bad keeps it, skip_bad=True in Python)\n")
    assert not out.exists()
    assert main(["estimate", str(bag), "-o", str(out), "--skip-bad"]) == 0
    err = capsys.readouterr().err
    assert "dropout: 2" in err
    assert "bad rows: 2 sample(s) with a bad value, read as a dropout of its IMU; first: " in err
    assert "topic /tip/imu: message 60: linear_acceleration is zero" in err
    from_table = tmp_path / "t.csv"
    assert main(["estimate", str(table), "-o", str(from_table), "--skip-bad"]) == 0
    capsys.readouterr()
    np.testing.assert_array_equal(_states(out)[1], _states(from_table)[1])


def test_accelerations_marked_absent_are_dropouts_as_nan_fields(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """A message whose ``linear_acceleration_covariance[0]`` is -1 (REP 145: absent) has
    no acceleration, whatever its field holds (a driver's placeholder of 0, 0, 9.81 is
    not read as gravity, which would make the IMU look frozen): named in one line, or
    with --skip-bad a dropout; marked in every message, the topic is refused in one
    line."""
    acc = recording["acc"].copy()
    acc[10:12] = [0.0, 0.0, 9.81]
    no_accel = np.zeros(len(acc), dtype=bool)
    no_accel[10:12] = True
    bag = write_ros2_bag(tmp_path / "bag2", {**recording, "acc": acc, "no_accel": no_accel})
    out = tmp_path / "e.csv"
    assert main(["estimate", str(bag), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(message 11): linear_acceleration is absent (NaN, or " in err
    assert "marked absent: linear_acceleration_covariance[0] = -1)" in err and not out.exists()
    assert main(["estimate", str(bag), "-o", str(out), "--skip-bad"]) == 0
    assert "dropout: 2" in capsys.readouterr().err
    every = write_ros2_bag(
        tmp_path / "every", {**recording, "no_accel": np.ones(len(acc), dtype=bool)}
    )
    assert main(["estimate", str(every), "-o", str(out), "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "linear_acceleration is zero or absent " in err
    assert "in every message: no reading of gravity to estimate from" in err


def test_orientation_missing_in_some_messages_is_named_or_a_dropout(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """``--orientation`` on a log whose messages 50 to 54 carry no orientation (a zero
    quaternion; a filter still starting marks it -1): one line naming the first (not
    the whole log refused as having none, --skip-bad or not); with --skip-bad five
    dropouts."""
    truth = recording["truth"]
    rp = tilt(truth[:, 3], truth[:, 4])
    quat = _wxyz(Rotation.from_euler("ZYX", np.stack([0 * rp[:, 0], rp[:, 1], rp[:, 0]], -1)))
    quat[49:54] = 0.0
    bag = write_ros2_bag(tmp_path / "bag2", {**recording, "quat": quat})
    out = tmp_path / "e.csv"
    assert main(["estimate", str(bag), "-o", str(out), "--orientation"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(message 50) has no orientation" in err
    assert "5 such): --skip-bad keeps them as dropouts" in err and not out.exists()
    assert main(["estimate", str(bag), "-o", str(out), "--orientation", "--skip-bad"]) == 0
    assert "dropout: 5" in capsys.readouterr().err


def test_orientation_skips_the_accelerometer_unit_check(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """estimate --orientation reads a log whose accelerations are in g, as it reads only
    the orientation (docs/hardware.md says the check is skipped there). The raw readings
    are still checked where they are used ('the values look like g')."""
    rp = tilt(recording["truth"][:, 3], recording["truth"][:, 4])
    quat = _wxyz(Rotation.from_euler("ZYX", np.stack([0 * rp[:, 0], rp[:, 1], rp[:, 0]], -1)))
    in_g = {**recording, "acc": recording["acc"] / 9.80665, "quat": quat}
    bag = write_ros2_bag(tmp_path / "bag2", in_g)
    out = tmp_path / "e.csv"
    assert main(["estimate", str(bag), "-o", str(out), "--method", "ekf", "--orientation"]) == 0
    assert out.exists()
    out.unlink()
    assert main(["estimate", str(bag), "-o", str(out), "--method", "ekf", "--overwrite"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    said = "topic /tip/imu: accelerometer magnitude is about 1.00: the values look like g"
    assert said in err[-1]
    assert not out.exists()


@pytest.mark.parametrize(
    ("robot", "needs"),
    [((), ""), (("--robot", "two-section"), " (a robot with 2 IMUs needs one per IMU)")],
)
def test_a_log_without_an_imu_topic_says_so_and_lists_its_topics(
    robot: tuple[str, ...], needs: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log without an Imu topic: one line saying so, listing its topics (not 'pass
    --topic', which cannot help, nor for a two-IMU robot 'pass one --topic per IMU'
    alone)."""
    from mcap.writer import CompressionType, Writer

    log = tmp_path / "odd.mcap"
    with log.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start()
        sid = w.register_schema(name="std_msgs/msg/String", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/chatter", message_encoding="json", schema_id=sid)
        w.add_message(cid, log_time=T0_NS, data=b'{"data": "hi"}', publish_time=T0_NS)
        w.finish()
    out = tmp_path / "e.csv"
    assert main(["estimate", str(log), "-o", str(out), *robot]) == 2
    assert capsys.readouterr().err.strip() == (
        f"continuum-mhe: error: {log}: the log has no sensor_msgs/msg/Imu topic; its topics: "
        f"/chatter (std_msgs/msg/String){needs}"
    )
    assert not out.exists()


@pytest.mark.parametrize(
    ("scale", "says"),
    [
        (1e-3, "advance by a median of 2e-05 s per sample (5e+04 samples per second); "
               "header.stamp must be ROS time (sec, and nanosec in ns): microseconds in nanosec?"),
        (1e3, "advance by a median of 20 s per sample; header.stamp must be ROS time (sec, and "
              "nanosec in ns): milliseconds in sec?"),
    ],
)  # fmt: skip
def test_log_stamps_in_another_unit_warn_as_a_csv_t_does(
    tmp_path: Path, recording: dict[str, Any], scale: float, says: str
) -> None:
    """Header stamps 1000 times too small (or too large) warn by the rule that warns of
    a CSV t in milliseconds (check_time_steps); 50 Hz stamps do not."""
    stamps = T0_NS + np.round((recording["stamps"] - T0_NS) * scale).astype(np.int64)
    log = write_mcap(tmp_path / "x.mcap", {**recording, "stamps": stamps})
    with pytest.warns(UnitWarning) as seen:
        read_imu_log(log)
    assert [str(w.message) for w in seen] == [f"{log}: topic /tip/imu: header stamps {says}"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_imu_log(write_mcap(tmp_path / "ok.mcap", recording))  # 50 Hz: no warning


def test_stamps_in_bursts_are_said_as_bursts_not_as_a_unit(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """A driver that stamps readings in batches of four (0.1 ms apart, then 80 ms): the
    median step is that of 10 kHz, but the mean step 20 ms; the warning says the samples
    come stamped in bursts, not that the stamps are in microseconds (a unit to fix that
    would make the times wrong)."""
    n = len(recording["stamps"])
    k = np.arange(n)
    stamps = T0_NS + (k // 4) * 80_000_000 + (k % 4) * 100_000
    log = write_mcap(tmp_path / "burst.mcap", {**recording, "stamps": stamps})
    with pytest.warns(UnitWarning) as seen:
        read_imu_log(log)
    (said,) = [str(w.message) for w in seen]
    assert "come stamped in bursts" in said and "microseconds" not in said


def test_microseconds_in_nanosec_are_refused_naming_them(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """A driver that writes microseconds into ``header.stamp.nanosec``: each second's
    stamps lie within 1 ms after its start (a median step of 20 us, a mean one of 20
    ms), which is no burst of readings but a unit: refused in one line naming it, and
    nothing written. Whole-second stamps with a true fraction are read."""
    ns = recording["stamps"]
    headers = ns // 10**9 * 10**9 + ns % 10**9 // 1000
    log = write_mcap(tmp_path / "us.mcap", recording, headers=headers)
    out = tmp_path / "e.csv"
    assert main(["estimate", str(log), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1
        and "microseconds in nanosec?" in err
        and "151 messages over 3 s" in err
    )
    assert not out.exists()
    assert len(read_imu_log(write_mcap(tmp_path / "ok.mcap", recording)).t) == len(ns)


@pytest.mark.parametrize("model", ["tilt", "direct"])
def test_a_one_imu_log_takes_the_robot_file_s_mounting_and_gyro_bias(
    tmp_path: Path, recording: dict[str, Any], model: str
) -> None:
    """The robot file's ``mount_rpy`` and ``gyro_bias`` apply to a bag's single Imu
    topic as to the same readings in a CSV."""
    robot = tmp_path / "robot.toml"
    robot.write_text(
        "[[section]]\nlength = 0.2\n\n[[imu]]\nsection = 1\nat = 1.0\n"
        "mount_rpy = [4.0, -3.0, 0.0]\ngyro_bias = [0.01, -0.02, 0.005]\n"
    )
    log = write_mcap(tmp_path / "run.mcap", recording)
    csv_in = write_raw_csv(tmp_path / "raw.csv", recording)
    opts = ["--method", "ekf", "--imu-model", model, "--robot", str(robot)]
    _estimate(csv_in, tmp_path / "from_csv.csv", *opts)
    _estimate(log, tmp_path / "from_log.csv", *opts)
    _estimate(log, tmp_path / "unmounted.csv", "--method", "ekf", "--imu-model", model)
    _, x_c, _ = _states(tmp_path / "from_csv.csv")
    _, x_l, _ = _states(tmp_path / "from_log.csv")
    _, x_u, _ = _states(tmp_path / "unmounted.csv")
    np.testing.assert_allclose(x_l, x_c, rtol=0, atol=1e-12)
    assert np.abs(x_u - x_c).max() > 1e-3  # the mounting changes the estimate


def test_write_estimates_mcap_checks_the_section_lengths(tmp_path: Path) -> None:
    """The library's MCAP writer names wrong section lengths in one UserError (not
    CasADi's shape mismatch or Python's 'not iterable'), millimetres too, and writes
    nothing; the right ones write a file whose estimates read back."""
    from continuum_mhe import make_estimator, make_formulation, simulate_robot
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.mcap_estimates import write_estimates_mcap
    from continuum_mhe.io.robot_file import read_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=0.5)
    series = make_estimator("ekf", make_formulation("bend", robot)).run(rec.t, rec.z)
    out = tmp_path / "e.mcap"
    for lengths, why in (([0.2], "lengths has 1 section length"),
                         (0.2, "lengths must be the 2 section length"),
                         ([160, 140], "millimetres")):  # fmt: skip
        with pytest.raises(UserError, match=why):
            write_estimates_mcap(out, series, lengths)  # type: ignore[arg-type]
        assert not out.exists()
    write_estimates_mcap(out, series, robot.lengths)
    t, values, _ = read_estimates_mcap(out)
    np.testing.assert_allclose(t, series.t)
    # the estimate channel's schema is the one of these outputs: every field of every
    # message is declared, with the outputs' units
    from mcap.reader import make_reader

    with out.open("rb") as fh:
        reader = make_reader(fh)
        schema = next(
            json.loads(sc.data) for sc in reader.get_summary().schemas.values()
            if sc.name == "continuum_mhe.Estimate"
        )  # fmt: skip
        fields = [
            set(json.loads(m.data))
            for _, ch, m in reader.iter_messages(topics=["/continuum/estimate"])
        ]
    names = [o.name for o in series.outputs]
    declared = schema["properties"]
    assert list(declared) == ["t", *names, *(f"std_{n}" for n in names), "status", "solve_ms"]
    assert declared["theta_2"]["description"] == "rad" and declared["x_1"]["description"] == "m"
    assert all(f == set(declared) for f in fields) and len(fields) == len(series.t)


def test_a_zero_stamp_among_others_is_left_out_not_put_on_the_log_clock(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Header stamps on a device clock (1000 s since boot) logged on the Unix clock: one
    zero stamp is left out and counted (not taken as the log's time, which would count
    every later message as going back and drop the whole log, exit 0); where every
    stamp is zero the log's times are the samples'."""
    boot = recording["stamps"] - recording["stamps"][0] + 1000 * 10**9
    headers = boot.copy()
    headers[100] = 0
    log = read_imu_log(write_mcap(tmp_path / "z.mcap", recording, headers=headers))
    n = len(recording["stamps"])
    assert len(log.t) == n - 1 and log.skipped == [
        "message 101: header stamp is zero (the others' clock)"  # counted from 1
    ]
    np.testing.assert_allclose(log.t, np.delete((boot - boot[0]) / 1e9, 100), atol=1e-9)
    zeros = np.zeros_like(boot)
    log = read_imu_log(write_mcap(tmp_path / "all.mcap", recording, headers=zeros))
    assert len(log.t) == n and log.t0_ns == recording["stamps"][0]
    assert log.clock == "log times"  # and estimate says so
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(tmp_path / "all.mcap"), "--method", "ekf", "-o", str(out)]) == 0
    said = "every header stamp is zero: t from the log's times (when each message was logged)"
    notes = [ln for ln in capsys.readouterr().err.splitlines() if said in ln]
    assert len(notes) == 1 and notes[0].startswith("continuum-mhe: note: "), notes


def test_stamps_that_do_not_advance_give_the_log_times_and_are_said(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """A driver that sets header.stamp once (every stamp the same, non-zero): most stamps
    not passing the one before are no clock: the log's times are the samples', every
    message kept (not every message but the first dropped as not increasing, an
    estimate of one row, exit 0), and estimate says so in one note. A few stamps
    out of order among advancing ones are still left out and counted."""
    n = len(recording["stamps"])
    same = np.full_like(recording["stamps"], recording["stamps"][0] + 5 * 10**9)
    log = read_imu_log(write_mcap(tmp_path / "same.mcap", recording, headers=same))
    assert len(log.t) == n and log.clock == "log times" and log.stale_stamps == n - 1
    assert log.skipped == [] and log.stamp_offset_s == 0.0
    np.testing.assert_allclose(
        log.t, (recording["stamps"] - recording["stamps"][0]) / 1e9, atol=1e-9
    )
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(tmp_path / "same.mcap"), "--method", "ekf", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"the header stamps do not advance ({n - 1} messages at or before" in err
    assert "ahead of the log's times" not in err
    assert len(_states(out)[1]) == n
    few = recording["stamps"].copy()
    few[[50, 51]] = few[49]  # two stamps repeated
    log = read_imu_log(write_mcap(tmp_path / "few.mcap", recording, headers=few))
    assert log.clock == "header stamps" and len(log.t) == n - 2
    assert [s.split(":")[0] for s in log.skipped] == ["message 51", "message 52"]


def test_stamps_in_milliseconds_are_named_in_the_refusal(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Header stamps whose ``sec`` holds milliseconds step by 1,000 times the period:
    every sample restarts the estimator after a gap, and the one-line refusal names the
    stamps' unit (not --gap-reset alone)."""
    s0 = recording["stamps"][0]
    in_ms = s0 + (recording["stamps"] - s0) * 1000
    log_path = write_mcap(tmp_path / "ms.mcap", recording, headers=in_ms)
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(log_path), "--method", "ekf", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {log_path}: "), err
    assert err[0].endswith(
        "header.stamp must be ROS time (sec, and nanosec in ns): milliseconds in sec? "
        "(else raise --gap-reset, or 0: never); nothing written"
    ), err
    assert not out.exists()


def test_rates_marked_absent_are_no_gyro(tmp_path: Path, recording: dict[str, Any]) -> None:
    """Messages whose ``angular_velocity_covariance[0]`` is -1 (REP 145) carry no rates:
    the log reads as an accelerometer alone (the tilt model), as the CSV without gyro
    columns does (the zeros are not taken as rates, 30 mm off)."""
    log_path = write_mcap(tmp_path / "ng.mcap", recording, no_gyro=True)
    assert read_imu_log(log_path).gyr is None
    t = (recording["stamps"] - recording["stamps"][0]) / 1e9
    csv_in = tmp_path / "acc.csv"
    with csv_in.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "ax", "ay", "az"])
        for row in zip(t, recording["acc"]):
            w.writerow([repr(float(row[0])), *map(repr, map(float, row[1]))])
    _estimate(csv_in, tmp_path / "from_csv.csv", "--method", "ekf")
    _estimate(log_path, tmp_path / "from_log.csv", "--method", "ekf")
    np.testing.assert_allclose(
        _states(tmp_path / "from_log.csv")[1], _states(tmp_path / "from_csv.csv")[1], atol=1e-12
    )


def test_an_mcap_without_its_optional_summary_is_read(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """The summary section is optional in MCAP: a log without one is not refused as an
    unfinished recording; its topics come from its messages, and the samples are the
    same as the summarised file's. A file cut inside a record says so."""
    from mcap.reader import make_reader

    bare = write_mcap(tmp_path / "bare.mcap", recording, summary=False)
    with bare.open("rb") as fh:
        assert make_reader(fh).get_summary() is None
    full = read_imu_log(write_mcap(tmp_path / "full.mcap", recording))
    got = read_imu_log(bare)
    np.testing.assert_array_equal(got.t, full.t)
    np.testing.assert_array_equal(got.acc, full.acc)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bare.read_bytes()[: bare.stat().st_size // 2])
    with pytest.raises(InputError, match="the file ends inside a record.*--skip-bad reads it"):
        read_imu_log(cut)
    # with skip_bad: up to the cut (a recorder that stopped), the same samples, said
    kept = read_imu_log(cut, skip_bad=True)
    n = len(kept.t)
    assert 0.3 * len(full.t) < n < 0.6 * len(full.t)
    np.testing.assert_array_equal(kept.t, full.t[:n])
    np.testing.assert_array_equal(kept.acc, full.acc[:n])
    assert kept.skipped == [] and kept.cut == (  # counted from 1, as skipped ones are
        f"the file ends inside a record after message {n}: read up to there"
    )


def test_a_db3_path_is_read_only_as_the_bag_its_metadata_lists(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """A .db3 named by its path is its folder's bag: another .db3 in that folder (not read
    as the metadata's bag, another file's samples, exit 0) and a .db3 without its
    metadata.yaml (not the reader's riddle) are each one line."""
    import shutil

    bag = write_ros2_bag(tmp_path / "bag2", recording)
    (own,) = sorted(bag.glob("*.db3"))
    assert len(read_imu_log(own).t) == len(recording["stamps"])  # its own: read
    other = bag / "other.db3"
    shutil.copy(own, other)
    with pytest.raises(InputError, match=r"metadata\.yaml describes another bag of that folder"):
        read_imu_log(other)
    lone = tmp_path / "lone"
    lone.mkdir()
    shutil.copy(own, lone / "run.db3")
    with pytest.raises(InputError, match=r"needs the metadata\.yaml that rosbag2 wrote") as err:
        read_imu_log(lone / "run.db3")
    assert str(err.value).endswith("a recorder that stopped? ros2 bag reindex writes it")


def test_pair_tolerance_on_one_imu_s_topic_is_refused(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """--pair-tolerance pairs several topics' samples: on one IMU's topic it is refused
    like the other options that do nothing here, not ignored silently. An estimate MCAP is
    an options file, as an estimate CSV is: its options note (a missing one: one line)."""
    log = write_mcap(tmp_path / "run.mcap", recording)
    out = tmp_path / "e.csv"
    assert main(["estimate", str(log), "--pair-tolerance", "0.01", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--pair-tolerance does not apply to one IMU's topic" in err
    est = tmp_path / "est.mcap"
    assert main(["estimate", str(log), "--config", str(est), "-o", str(out)]) == 2
    assert "est.mcap: cannot read the options file (no such file)" in capsys.readouterr().err
    assert not out.exists()
    assert main(["estimate", str(log), "--method", "ekf", "--freeze", "0.5", "-o", str(est)]) == 0
    capsys.readouterr()
    assert main(["estimate", str(log), "--config", str(est), "-o", str(out)]) == 0
    options = [ln for ln in out.read_text().splitlines() if ln.startswith("# options = ")]
    assert len(options) == 1 and 'method = "ekf"' in options[0] and "freeze = 0.5" in options[0]
    assert main(["estimate", str(log), "--config", str(log), "-o", str(out), "--overwrite"]) == 2
    assert "no 'options' note in its continuum-mhe metadata" in capsys.readouterr().err


def test_an_unreadable_message_is_named_by_its_position(tmp_path: Path) -> None:
    """A JSON message without a field, with a null one, or with a value that is not a
    number (``true`` is not read as 1.0): the one line says which message and what is
    wrong with it."""
    import json as json_module

    from mcap.writer import CompressionType, Writer

    def log(path: Path, bad: dict[str, Any]) -> Path:
        good = {"header": {"stamp": {"sec": 1, "nanosec": 0}},
                "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.81},
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0}}  # fmt: skip
        with path.open("wb") as fh:
            w = Writer(fh, compression=CompressionType.NONE)
            w.start()
            sid = w.register_schema(name="sensor_msgs/msg/Imu", encoding="jsonschema", data=b"{}")
            cid = w.register_channel(topic="/imu", message_encoding="json", schema_id=sid)
            for k in range(5):
                msg = dict(good, header={"stamp": {"sec": 1 + k, "nanosec": 0}})
                if k == 3:
                    msg = {**msg, **bad}
                    msg = {key: v for key, v in msg.items() if v != "drop"}
                data = json_module.dumps(msg).encode()
                w.add_message(cid, log_time=k + 1, data=data, publish_time=k + 1)
            w.finish()
        return path

    for bad, why in (({"linear_acceleration": "drop"}, "without the field 'linear_acceleration'"),
                     ({"linear_acceleration": None}, "a message with a null field"),
                     ({"angular_velocity": {"x": 0.0, "y": 0.0, "z": True}},
                      "its angular_velocity.z is true, not a number"),
                     ({"linear_acceleration": {"x": "0.5", "y": 0.0, "z": 9.81}},
                      'its linear_acceleration.x is "0.5", not a number'),
                     ({"orientation": {"w": 1.0, "x": None, "y": 0.0, "z": 0.0}},
                      "its orientation.x is null, not a number")):  # fmt: skip
        path = log(tmp_path / "j.mcap", bad)
        start = re.escape(f"{path}: topic /imu: message 4: cannot read robot log (")
        with pytest.raises(InputError, match=start + ".*" + re.escape(why)):
            read_imu_log(path)


def test_stamps_on_another_clock_than_the_log_s_warn(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """Header stamps on a sensor's boot clock (1000 s since boot) in a log on the Unix
    clock: one warning naming the offset (an MCAP estimate keeps the stamps' clock and
    would not line up with the log's other topics); stamps 20 ms after the log's times
    (a driver's latency) say nothing."""
    boot = recording["stamps"] - recording["stamps"][0] + 1000 * 10**9
    with pytest.warns(UnitWarning) as seen:
        read_imu_log(write_mcap(tmp_path / "boot.mcap", recording, headers=boot))
    said = [str(w.message) for w in seen]
    assert (
        len(said) == 1
        and "topic /tip/imu: the header stamps are 1.7e+09 s behind the log's" in said[0]
    )
    assert "an MCAP estimate (-o .mcap) does not line up with the log's other topics" in said[0]
    late = recording["stamps"] + 20_000_000
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_imu_log(write_mcap(tmp_path / "late.mcap", recording, headers=late))


def test_a_clock_that_steps_back_is_refused_unless_skip_bad(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """Stamps that step back by 2 s at message 101 (a sensor clock that restarted): an
    error naming the message and the step, not the rest of the log silently dropped (or
    joined across the jump); with ``skip_bad`` the messages until the times pass the
    last one kept (here the other 51) are left out and counted, none put among the
    messages before the step. One message stamped 1 ms before the one logged before it
    (delivered late) is put in its place by its stamp; one stamped as the one before it
    is left out and counted."""
    headers = recording["stamps"].copy()
    headers[100:] -= 2 * 10**9
    path = write_mcap(tmp_path / "back.mcap", recording, headers=headers)
    with pytest.raises(InputError) as info:
        read_imu_log(path)
    assert str(info.value) == (
        f"{path}: topic /tip/imu: message 101: the time steps back by 1.98 s (a sensor clock "
        "that restarted?): the log is not one recording; cut it there, or --skip-bad leaves "
        "out the messages until the times pass the last one"
    )
    log = read_imu_log(path, skip_bad=True)
    assert len(log.skipped) == 51 and log.skipped[0].startswith("message 101: time ")
    jitter = recording["stamps"].copy()
    jitter[50] = jitter[49] - 1_000_000
    log = read_imu_log(write_mcap(tmp_path / "jitter.mcap", recording, headers=jitter))
    assert log.skipped == [] and log.reordered == 1 and len(log.t) == len(jitter)
    assert list(log.numbers[48:52]) == [49, 51, 50, 52]
    np.testing.assert_array_equal(log.acc[49], recording["acc"][50])
    twice = recording["stamps"].copy()
    twice[50] = twice[49]
    log = read_imu_log(write_mcap(tmp_path / "twice.mcap", recording, headers=twice))
    assert log.skipped == [f"message 51: time {int(twice[50])} ns does not increase"]
    assert log.reordered == 0 and len(log.t) == len(twice) - 1
    # a clock that steps back by 0.49 s (under the restart's 1 s): its messages are left
    # out until the times pass the last one kept, none put among those before; a stamp
    # that wraps every 0.655 s is no clock: the log's times
    step = recording["stamps"].copy()
    step[100:] -= 490_000_000
    log = read_imu_log(write_mcap(tmp_path / "step.mcap", recording, headers=step))
    assert log.reordered == 0 and len(log.skipped) == 24 and np.all(np.diff(log.t) > 0)
    wrap = T0_NS + (recording["stamps"] - T0_NS) % 655_000_000
    log = read_imu_log(write_mcap(tmp_path / "wrap.mcap", recording, headers=wrap))
    assert log.clock == "log times" and log.reordered == 0 and len(log.t) == len(wrap)


def test_a_ros2_bag_stored_as_mcap_cut_short_is_read_up_to_the_cut_with_skip_bad(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """A ROS 2 bag folder whose storage is MCAP (rosbag2's default) reads as its MCAP
    file does: whole, the same samples as the SQLite bag; cut short (a recorder that
    was killed), one line saying so and that --skip-bad reads up to the cut, and with
    it the messages before the cut."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    bag = tmp_path / "bag_mcap"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/tip/imu", IMU, typestore=store)
        for ns, a, g in zip(recording["stamps"], recording["acc"], recording["gyr"]):
            w.write(conn, int(ns), store.serialize_cdr(imu_msg(store, int(ns), a, g), IMU))
    whole = read_imu_log(bag)
    sqlite = read_imu_log(write_ros2_bag(tmp_path / "bag_db3", recording))
    np.testing.assert_array_equal(whole.t, sqlite.t)
    np.testing.assert_array_equal(whole.acc, sqlite.acc)
    (storage,) = bag.glob("*.mcap")
    data = storage.read_bytes()
    storage.write_bytes(data[: len(data) - 40])  # the footer and end magic lost
    with pytest.raises(InputError, match=r"--skip-bad reads it up to the cut\)$"):
        read_imu_log(bag)
    cut = read_imu_log(bag, skip_bad=True)
    assert 0 < len(cut.t) <= len(whole.t) and cut.cut.startswith("the file ends inside a record")
    np.testing.assert_array_equal(cut.acc, whole.acc[: len(cut.t)])


def test_an_orientation_only_imu_is_told_to_use_orientation(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """An IMU whose messages give an orientation and a zero linear acceleration (an
    orientation-only driver): one line naming the topic and --orientation, not "every
    sample is a dropout"; with --orientation it is estimated."""
    n = len(recording["stamps"])
    quat = [np.array([1.0, 0.0, 0.0, 0.0])] * n
    rec = {**recording, "acc": np.zeros((n, 3)), "quat": quat}
    bag = write_ros2_bag(tmp_path / "orient", rec)
    out = tmp_path / "e.csv"
    assert main(["estimate", str(bag), "-o", str(out), "--method", "ekf"]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {bag}: topic /tip/imu: linear_acceleration is zero or absent "
        "in every message while its orientation is given (an orientation-only IMU): "
        "--orientation reads its roll and pitch\n"
    )
    assert not out.exists()
    assert main(["estimate", str(bag), "-o", str(out), "--method", "ekf", "--orientation"]) == 0


def test_a_message_whose_rates_are_marked_absent_among_others_names_the_flag(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Messages 51 on with their rates marked absent (REP 145) among messages with rates:
    the refusal names the flag, not NaN values the file does not hold."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    msgdef, _ = store.generate_msgdef(IMU, ros_version=2)
    path = tmp_path / "some.mcap"
    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start()
        sid = w.register_schema(name=IMU, encoding="ros2msg", data=msgdef.encode())
        cid = w.register_channel(topic="/tip/imu", message_encoding="cdr", schema_id=sid)
        rows = zip(recording["stamps"], recording["acc"], recording["gyr"])
        for i, (ns, a, g) in enumerate(rows):
            msg = imu_msg(store, int(ns), a, g, no_gyro=i >= 50)
            w.add_message(cid, log_time=int(ns), data=bytes(store.serialize_cdr(msg, IMU)),
                          publish_time=int(ns))  # fmt: skip
        w.finish()
    assert main(["estimate", str(path), "-o", str(tmp_path / "e.csv"), "--method", "ekf"]) == 2
    err = capsys.readouterr().err
    assert "(message 51): angular_velocity is absent (NaN, or marked absent: " in err
    assert "angular_velocity_covariance[0] = -1) (a dropout; --skip-bad keeps it" in err


def test_a_bag_folder_is_read_as_its_mcap_only_where_its_metadata_lists_it_alone(
    tmp_path: Path,
) -> None:
    """The folder's one MCAP file is read directly only where ``metadata.yaml`` lists
    that file alone and no compression; a bag compressed by rosbag2, or one whose
    metadata lists more files (a split bag with a part missing), is left to rosbags."""
    from continuum_mhe.io.robot_logs import _single_mcap

    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(b"")
    meta = bag / "metadata.yaml"
    head = "rosbag2_bagfile_information:\n  storage_identifier: mcap\n"
    meta.write_text(head + "  compression_mode: ''\n  relative_file_paths:\n  - bag_0.mcap\n")
    assert _single_mcap(bag) == bag / "bag_0.mcap"
    meta.write_text(head + "  compression_mode: MESSAGE\n  relative_file_paths:\n  - bag_0.mcap\n")
    assert _single_mcap(bag) is None
    meta.write_text(
        head + "  compression_mode: ''\n  relative_file_paths:\n  - bag_0.mcap\n  - bag_1.mcap\n"
    )
    assert _single_mcap(bag) is None
    meta.unlink()
    assert _single_mcap(bag) is None


def test_json_stamps_of_ros_1_fractional_seconds_and_nanoseconds_in_sec(tmp_path: Path) -> None:
    """A JSON message's header stamp as ROS 1 writes it through rosbridge (``secs``,
    ``nsecs``) and as a fractional ``sec`` are read to the nanosecond (the fractional one
    not cut to whole seconds, which would leave all but a few messages out as not
    increasing);
    nanoseconds in ``sec`` (an int64 overflow, exit 70) are refused in one line naming
    the message."""
    t0 = 1_700_000_000
    times = [t0 + 0.02 * k for k in range(6)]

    def log(path: Path, stamp: Any) -> Path:
        headers = [{"stamp": stamp(k)} for k in range(len(times))]
        return _json_imu_mcap(path, headers, [round(tk * 1e9) for tk in times])

    ros1 = log(tmp_path / "ros1.mcap", lambda k: {"secs": t0, "nsecs": 20_000_000 * k})
    frac = log(tmp_path / "frac.mcap", lambda k: {"sec": times[k]})
    for path in (ros1, frac):
        got = read_imu_log(path)
        assert got.skipped == [] and got.clock == "header stamps"
        np.testing.assert_allclose(got.t, 0.02 * np.arange(6), atol=1e-6)
    ns = log(tmp_path / "ns.mcap", lambda k: {"sec": round(times[k] * 1e9), "nanosec": 0})
    with pytest.raises(InputError, match=re.escape(
        f"{ns}: topic /imu: message 1: its header.stamp.sec is 1.7e+18: nanoseconds in sec?"
    )):  # fmt: skip
        read_imu_log(ns)


def test_a_topic_whose_frame_changes_is_said(tmp_path: Path) -> None:
    """A topic whose messages name another ``header.frame_id`` from message 4 on
    (another sensor's messages on it) is not read as one IMU's without a word: one
    warning names the two frames and the message. One frame throughout, or none, says
    nothing."""
    from continuum_mhe.io.robot_logs import FrameWarning

    def log(path: Path, frame: Any) -> Path:
        ns = [T0_NS + 20_000_000 * k for k in range(8)]
        headers = [{"stamp": {"sec": v // 10**9, "nanosec": v % 10**9}, "frame_id": frame(k)}
                   for k, v in enumerate(ns)]  # fmt: skip
        return _json_imu_mcap(path, headers, ns)

    switched = log(tmp_path / "switch.mcap", lambda k: "imu1" if k < 3 else "imu2")
    with pytest.warns(FrameWarning) as seen:
        got = read_imu_log(switched)
    assert [str(w.message) for w in seen] == [
        f"{switched}: topic /imu: header.frame_id changes from 'imu1' to 'imu2' at message 4 "
        "(2 frames in all): another sensor's messages on this topic? Its messages are read "
        "as one IMU's"
    ]
    assert got.frames == ("imu1", "imu2") and len(got.t) == 8
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_imu_log(log(tmp_path / "one.mcap", lambda k: "imu1")).frames == ("imu1",)
        assert read_imu_log(log(tmp_path / "none.mcap", lambda k: "")).frames == ()


def test_a_record_naming_a_missing_channel_is_not_called_a_missing_field() -> None:
    """The MCAP reader's ``KeyError`` of a damaged record (a channel or schema id the
    file does not hold) is not worded as a JSON message without a field ("a message
    without the field 16571"); a JSON message's missing field keeps its wording."""
    from continuum_mhe.io.robot_logs import _why_unreadable

    assert _why_unreadable(KeyError(16571)) == (
        "a record names channel or schema 16571, which the file does not hold: damaged?"
    )
    assert _why_unreadable(KeyError("header")) == "a message without the field 'header'"


def _json_imu_mcap(path: Path, headers: list[dict[str, Any]], log_ns: list[int]) -> Path:
    """An MCAP file of one JSON ``sensor_msgs/msg/Imu`` topic ``/imu``: an IMU at rest,
    level, one message per header, logged at ``log_ns``."""
    import json as json_module

    from mcap.writer import CompressionType, Writer

    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start()
        sid = w.register_schema(name="sensor_msgs/msg/Imu", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/imu", message_encoding="json", schema_id=sid)
        for header, ns in zip(headers, log_ns):
            msg = {"header": header,
                   "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.81},
                   "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0}}  # fmt: skip
            w.add_message(cid, log_time=ns, data=json_module.dumps(msg).encode(), publish_time=ns)
        w.finish()
    return path


def test_a_cut_inside_the_only_chunk_says_why_nothing_before_it_is_read(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """An MCAP file whose one chunk holds every message, cut inside that chunk: with
    --skip-bad nothing can be read, and the line says that a chunk's messages are lost
    with the chunk the cut ends (not "no whole message before the cut" of a file with a
    hundred messages before it)."""
    log = write_mcap(tmp_path / "chunked.mcap", recording)
    data = log.read_bytes()
    log.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"no message could be read before the cut \(the "
                       r"messages of a chunk that the cut ends are lost with it\)\)$"):  # fmt: skip
        read_imu_log(log, skip_bad=True)


@pytest.mark.parametrize("ahead_s", [5.0, 0.5])
def test_one_stamp_that_jumps_ahead_is_left_out_alone(
    tmp_path: Path, recording: dict[str, Any], ahead_s: float
) -> None:
    """Message 51 stamped ``ahead_s`` after its neighbours (a stamp's glitch): the glitch
    alone is left out, counted, and every other message kept (the next message not
    blamed as a clock that restarted, exit 2, nor, with a smaller jump, the ten good
    messages after it left out and the bad one kept)."""
    stamps = recording["stamps"].copy()
    stamps[50] = stamps[49] + int(ahead_s * 1e9)
    log = read_imu_log(write_mcap(tmp_path / "glitch.mcap", recording, headers=stamps))
    assert log.skipped == [
        f"message 51: time {int(stamps[50])} ns jumps {(stamps[50] - stamps[49]) / 1e9:.3g} s "
        "ahead of the messages around it"
    ]
    keep = np.delete(np.arange(len(stamps)), 50)
    np.testing.assert_array_equal(log.numbers, keep + 1)
    np.testing.assert_allclose(log.t, (stamps[keep] - stamps[0]) / 1e9)


def test_load_input_checks_the_first_readings_against_the_robots_mounting(
    tmp_path: Path, recording: dict[str, Any]
) -> None:
    """The library's reader checks the mounting as ``estimate`` does, a robot log
    included, and names the Robot's field, not the command line's option: a hanging
    robot's log and CSV (the recording turned upside down) on a robot described z-up are
    refused; on the robot as it hangs they are read."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    upside_down = np.array([1.0, -1.0, -1.0])  # turned by pi about x
    hanging = dict(
        recording, acc=recording["acc"] * upside_down, gyr=recording["gyr"] * upside_down
    )
    log = write_mcap(tmp_path / "hanging.mcap", hanging)
    table = write_raw_csv(tmp_path / "hanging.csv", hanging)
    sections, imus = (Section(0.2, theta_max=3.0),), (ImuPlacement(0),)
    for path in (log, table):
        up = make_formulation("bend", Robot(sections, imus))
        with pytest.raises(InputError) as refused:
            load_input(path, InputOptions(), up)
        message = str(refused.value)
        assert "\n" not in message and "--mounting" not in message, message
        assert message.endswith(
            'make the Robot with mounting="z-down" (or set mounting = "z-down" in its robot file)'
        ), message
        down = make_formulation("bend", Robot(sections, imus, mounting="z-down"))
        assert len(load_input(path, InputOptions(), down).t) == len(recording["stamps"])


def test_a_tendon_robots_log_without_tensions_is_told_to_give_them_with_inputs(
    recording: dict[str, Any], tmp_path: Path
) -> None:
    """A robot log of a tendon robot without --inputs: the one line names --inputs alone,
    not the recording's tension columns, which a log's Imu topics do not carry (a CSV
    recording keeps the columns' hint)."""
    from continuum_mhe.errors import InputError
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import _tensions
    from continuum_mhe.io.robot_file import read_robot

    robot = read_robot("tendon-two-section")
    log = write_mcap(tmp_path / "run.mcap", recording)
    with pytest.raises(InputError) as caught:
        _tensions(InputOptions(), robot, "tendon-two-section", log)
    said = str(caught.value)
    assert "--inputs TENSIONS.csv" in said and "a robot log's topics do not carry them" in said
    assert "recording's columns" not in said
    csv_path = write_raw_csv(tmp_path / "run.csv", recording)
    with pytest.raises(InputError, match="or as the recording's columns tension_1"):
        _tensions(InputOptions(), robot, "tendon-two-section", csv_path)


def test_a_logs_tensions_stamped_since_1970_are_taken_on_its_clock(
    recording: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tendon robot's log (its tip IMU alone) with tensions stamped on the log's own
    clock (seconds since 1970, as a tension topic exported beside the IMU's has them):
    taken on the log's clock, t = 0 at the first sample's stamp, and said in a note; the
    samples equal those with the same tensions counted from that stamp (to the
    float64 resolution of times since 1970, 2.4e-7 s). The estimate's t0_ns is the
    log's, and ``plot`` and ``view`` take the tensions on that clock as well."""
    from dataclasses import replace

    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.registry import make_formulation

    log = write_mcap(tmp_path / "run.mcap", recording)
    robot = read_robot("tendon-two-section")
    f = make_formulation("bend", replace(robot, imus=robot.imus[1:]))
    t = np.arange(0.0, 3.2, 0.02)
    tensions = 0.1 + 0.05 * np.sin(t)[:, None] * np.ones((1, robot.n_tendons))
    header = "t," + ",".join(f"tension_{i + 1}" for i in range(robot.n_tendons))
    files = {}
    for name, t0 in (("counted.csv", 0), ("epoch.csv", T0_NS)):
        ns = t0 + np.round(t * 1e9).astype(np.int64)  # written to the nanosecond
        rows = [
            f"{n // 10**9}.{n % 10**9:09d}," + ",".join(f"{v:.6f}" for v in row)
            for n, row in zip(ns.tolist(), tensions)
        ]
        files[name] = tmp_path / name
        files[name].write_text(header + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    counted = load_input(log, InputOptions(tensions=str(files["counted.csv"])), f)
    epoch = load_input(log, InputOptions(tensions=str(files["epoch.csv"])), f)
    assert counted.t0_ns == epoch.t0_ns == T0_NS
    np.testing.assert_allclose(epoch.z, counted.z, rtol=0, atol=1e-4)
    assert np.array_equal(epoch.t, counted.t)
    assert epoch.notes == (
        f"{files['epoch.csv']}: its times, since 1970, are taken on the log's clock: t = 0 "
        "at the first sample's stamp, 1700000000.123456789 s",
    )
    assert not counted.notes
    # the command line: estimate with them, then plot and view the estimate with the
    # tensions its options line names, taken on the log's clock (its t0_ns) as estimate
    # took them
    from continuum_mhe.io.robot_file import shipped_robots

    robot_file = tmp_path / "tip.toml"  # the shipped robot with its tip IMU alone
    text = shipped_robots()["tendon-two-section"].read_text()
    assert "[[imu]]\nsection = 1\n" in text
    robot_file.write_text(text.replace("[[imu]]\nsection = 1\n", "", 1))
    est = tmp_path / "est.csv"
    _estimate(log, est, "--robot", str(robot_file), "--inputs", str(files["epoch.csv"]))
    fig = tmp_path / "est.png"
    capsys.readouterr()
    with pytest.MonkeyPatch.context() as m:  # what plot says, not what it draws
        figures_drawn_small(m)
        assert main(["plot", str(est), "-o", str(fig)]) == 0
    assert fig.read_bytes()[:4] == b"\x89PNG"
    assert "are taken on the log's clock" in capsys.readouterr().err
    assert main(["view", str(est), "--save", str(tmp_path / "est.rrd")]) == 0
    assert "are taken on the log's clock" in capsys.readouterr().err
    # tensions that end halfway: view's refusal is its one line, without its notes
    half = tmp_path / "half.csv"
    lines = files["counted.csv"].read_text().splitlines()
    half.write_text("\n".join(lines[: len(lines) // 2]) + "\n")
    rrd = tmp_path / "half.rrd"
    assert main(["view", str(est), "--inputs", str(half), "--save", str(rrd)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the tensions must cover the recording" in err, err
    assert not rrd.exists()


def test_an_options_files_topics_give_way_to_the_command_line_and_to_a_csv(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """An options file is a profile: ``--topic`` on the command line replaces the file's
    topics (it does not add to them), and a profile's log options (``topic``,
    ``pair-tolerance``, ``orientation``) and ``degrees`` leave a CSV recording as the
    command line without them reads it; given on the command line they are refused
    there."""
    log = write_mcap(tmp_path / "run.mcap", recording)
    csv_in = write_raw_csv(tmp_path / "raw.csv", recording)
    est = tmp_path / "est.mcap"
    _estimate(log, est, "--method", "ekf", "--topic", "/tip/imu")
    again = tmp_path / "again.csv"
    _estimate(log, again, "--config", str(est), "--topic", "/tip/imu")
    profile = tmp_path / "profile.toml"
    profile.write_text(
        'method = "ekf"\ntopic = ["/tip/imu"]\npair-tolerance = 0.004\norientation = false\n'
        "degrees = true\n"
    )
    plain = tmp_path / "plain.csv"
    _estimate(csv_in, plain, "--method", "ekf")
    for config in (est, profile):
        out = tmp_path / f"csv_{config.stem}.csv"
        _estimate(csv_in, out, "--config", str(config))
        np.testing.assert_array_equal(_states(out)[1], _states(plain)[1])
    np.testing.assert_array_equal(_states(again)[1], _states(plain)[1])
    capsys.readouterr()
    assert (
        main(["estimate", str(csv_in), "--topic", "/tip/imu", "-o", str(tmp_path / "x.csv")]) == 2
    )
    assert "--topic does not apply to this input" in capsys.readouterr().err


def test_messages_delivered_late_are_put_in_place_by_their_stamps(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Every tenth message logged 20 ms late (after the next one, its header stamp
    true): the estimate equals the one of the log in order, and a note counts them. At
    10 Hz a message logged after the next one (100 ms ahead of the one before it) is put
    in its place too, not taken for a glitch of the one logged before it."""
    n = len(recording["stamps"])
    order = np.arange(n)
    for k in range(5, n - 1, 10):
        order[k], order[k + 1] = order[k + 1], order[k]
    late = {
        **recording,
        "acc": recording["acc"][order],
        "gyr": recording["gyr"][order],
    }
    log = write_mcap(tmp_path / "late.mcap", late, headers=recording["stamps"][order])
    in_order = write_mcap(tmp_path / "in_order.mcap", recording)
    _estimate(in_order, tmp_path / "a.csv", "--method", "ekf")
    capsys.readouterr()
    _estimate(log, tmp_path / "b.csv", "--method", "ekf")
    swapped = len(range(5, n - 1, 10))
    assert f"{swapped} message(s) logged after one stamped later" in capsys.readouterr().err
    t_a, x_a, s_a = _states(tmp_path / "a.csv")
    t_b, x_b, s_b = _states(tmp_path / "b.csv")
    np.testing.assert_array_equal(t_b, t_a)
    np.testing.assert_array_equal(x_b, x_a)
    assert list(s_b) == list(s_a)
    slow = {**recording, "stamps": T0_NS + np.arange(n, dtype=np.int64) * 100_000_000}
    order = np.arange(n)
    order[50], order[51] = 51, 50
    swapped = {**slow, "acc": slow["acc"][order], "gyr": slow["gyr"][order]}
    log = read_imu_log(write_mcap(tmp_path / "slow.mcap", swapped, headers=slow["stamps"][order]))
    assert log.reordered == 1 and log.skipped == [] and len(log.t) == n
    np.testing.assert_array_equal(log.acc, slow["acc"])


@pytest.mark.parametrize("suffix", [".csv", ".mcap"])
def test_a_truth_on_the_logs_clock_is_pointed_to_the_estimates_t0(
    tmp_path: Path, recording: dict[str, Any], capsys: pytest.CaptureFixture[str], suffix: str
) -> None:
    """A truth (motion capture) on the log's clock, seconds since 1970, that starts 2 s
    before the IMUs: ``evaluate`` refuses the times that do not overlap and names the
    ``--truth-shift`` of the estimate's ``t0_ns`` (its line, or its MCAP's note), which
    compares them, not a shift that takes the two to start together."""
    log = write_mcap(tmp_path / "run.mcap", recording)
    est = tmp_path / f"e{suffix}"
    assert main(["estimate", str(log), "--length", "0.2", "-o", str(est)]) == 0
    t = (recording["stamps"] - T0_NS) * 1e-9
    early = np.arange(-100, 0) * 0.02
    truth_t = np.concatenate([early, t]) + T0_NS * 1e-9
    truth = np.vstack([np.repeat(recording["truth"][:1], 100, axis=0), recording["truth"]])
    names = "t,x,y,z,theta,phi"
    rows = [f"{tv:.6f}," + ",".join(f"{v:.9g}" for v in row) for tv, row in zip(truth_t, truth)]
    (tmp_path / "mocap.csv").write_text(names + "\n" + "\n".join(rows) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(tmp_path / "mocap.csv"), "--length", "0.2"]) == 2
    err = capsys.readouterr().err
    shift = T0_NS / 1e9
    assert f"(its t0_ns): a truth on that clock compares with --truth-shift {shift!r}" in err
    argv = ["evaluate", str(est), str(tmp_path / "mocap.csv"), "--length", "0.2"]
    assert main([*argv, "--truth-shift", repr(shift)]) == 0
    out = capsys.readouterr().out
    mean = float(re.search(r"tip error mean\s+([0-9.]+) mm", out).group(1))  # type: ignore[union-attr]
    assert mean < 5.0, out
