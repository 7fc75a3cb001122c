"""An estimate MCAP read by the ``mcap`` package alone, as Foxglove and a user's script
read it: the ``/continuum/estimate`` fields are the estimate CSV's columns, and the
poses of ``/continuum/tip`` and ``/continuum/backbone`` are the estimate's."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.io.mcap_estimates import read_estimate_table_mcap

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"


def _messages(path: Path) -> tuple[dict[str, Any], dict[str, list[tuple[int, dict[str, Any]]]]]:
    """The schemas by name and every topic's ``(log_time, message)``, decoded as JSON."""
    from mcap.reader import make_reader

    schemas: dict[str, Any] = {}
    topics: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    with path.open("rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages():
            schemas[schema.name] = json.loads(schema.data)
            topics.setdefault(channel.topic, []).append(
                (message.log_time, json.loads(message.data))
            )
    return schemas, topics


def _first_rows(src: Path, dst: Path, n: int) -> Path:
    with src.open(newline="") as fh:
        rows = list(csv.reader(fh))[: n + 1]
    with dst.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return dst


def test_a_robust_estimate_mcap_carries_the_outlier_flags(tmp_path: Path) -> None:
    """``--loss`` writes the CSV's ``outlier`` column; the MCAP's estimate messages carry
    the same flags (in their schema too), and its reader keeps them out of the outputs."""
    with (DATA / "rod_planar.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))[:120]
    rows[60]["roll"] = str(float(rows[60]["roll"]) + 0.8)  # two readings far off
    rows[90]["pitch"] = str(float(rows[90]["pitch"]) - 0.6)
    meas = tmp_path / "glitch.csv"
    with meas.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "roll", "pitch"])
        w.writerows([r["t"], r["roll"], r["pitch"]] for r in rows)
    for out in ("e.csv", "e.mcap"):
        assert main(["estimate", str(meas), "-o", str(tmp_path / out), "--loss", "welsch"]) == 0
    with (tmp_path / "e.csv").open(newline="") as fh:
        flags = np.array(
            [int(r["outlier"]) for r in csv.DictReader(ln for ln in fh if ln[0] != "#")]
        )
    assert flags.sum() == 2
    schemas, topics = _messages(tmp_path / "e.mcap")
    fields = list(schemas["continuum_mhe.Estimate"]["properties"])
    assert fields[-3:] == ["outlier", "status", "solve_ms"]
    sent = [msg["outlier"] for _, msg in topics["/continuum/estimate"]]
    assert sent == flags.tolist()
    table = read_estimate_table_mcap(tmp_path / "e.mcap")
    assert table.names == ("x", "y", "z", "theta", "phi")
    assert table.outlier is not None and (table.outlier == flags.astype(bool)).all()


def _swing_twist(q: np.ndarray) -> tuple[float, float, float]:
    """``(theta, phi, psi)`` of a relative rotation ``q = R(theta, phi) Rz(psi)``."""
    t = q[:, 2]
    theta = math.atan2(math.hypot(t[0], t[1]), t[2])
    phi = math.atan2(-t[1], -t[0])
    psi = 2 * math.atan2(q[1, 0] - q[0, 1], 1 + q[0, 0] + q[1, 1] + q[2, 2])
    return theta, phi, psi


def _rotation(pose: dict[str, Any]) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    o = pose["orientation"]
    return np.asarray(Rotation.from_quat([o["x"], o["y"], o["z"], o["w"]]).as_matrix())


def _position(pose: dict[str, Any]) -> np.ndarray:
    return np.array([pose["position"][c] for c in "xyz"])


def test_a_tendon_estimate_mcap_poses_are_the_estimates(tmp_path: Path) -> None:
    """A tendon robot's sections are not arcs: its tip pose is the estimated tip, the
    backbone passes through every estimated section end, and each section's end frame
    is the one below turned by the section's ``theta_k, phi_k`` and twist ``psi_k``."""
    meas = _first_rows(DATA / "tendon" / "force-08_raw.csv", tmp_path / "m.csv", 60)
    tensions = DATA / "tendon" / "force-08_tensions.csv"
    out = tmp_path / "e.mcap"
    args = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(tensions)]
    assert main([*args, "-o", str(out)]) == 0
    _, topics = _messages(out)
    estimates = dict(topics["/continuum/estimate"])
    tips = dict(topics["/continuum/tip"])
    loaded = 0
    for ns, msg in topics["/continuum/backbone"]:
        row = estimates[ns]
        poses = msg["poses"]
        assert len(poses) == 21
        tip = np.array([row[c] for c in "xyz"])
        np.testing.assert_allclose(_position(tips[ns]["pose"]), tip, rtol=0, atol=1e-12)
        np.testing.assert_allclose(_position(poses[-1]), tip, rtol=0, atol=1e-12)
        below = np.eye(3)
        for k in (1, 2):
            end = poses[10 * k]
            want = [row[f"{c}_{k}"] for c in "xyz"]
            np.testing.assert_allclose(_position(end), want, rtol=0, atol=1e-12)
            theta, phi, psi = _swing_twist(below.T @ _rotation(end))
            assert theta == pytest.approx(row[f"theta_{k}"], abs=1e-7)
            if row[f"theta_{k}"] > 1e-3:
                assert math.remainder(phi - row[f"phi_{k}"], math.tau) == pytest.approx(0, abs=1e-5)
            assert psi == pytest.approx(row[f"psi_{k}"], abs=1e-7)
            below = _rotation(end)
        loaded += abs(row["psi_1"]) > 1e-3
    assert loaded  # the twist is seen: the frames are not the arcs'


def _imu_log(src: Path, path: Path, t0_ns: int, n: int) -> Path:
    """The first ``n`` rows of a two-IMU raw CSV as an MCAP robot log, one
    ``sensor_msgs/msg/Imu`` topic per IMU (``/imu1``, ``/imu2``), stamped from ``t0_ns``."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    imu = "sensor_msgs/msg/Imu"
    msgdef, _ = store.generate_msgdef(imu, ros_version=2)
    types = store.types
    with src.open(newline="") as fh:
        rows = list(csv.DictReader(fh))[:n]
    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start()
        sid = w.register_schema(name=imu, encoding="ros2msg", data=msgdef.encode())
        cids = [w.register_channel(f"/imu{k}", "cdr", sid) for k in (1, 2)]
        for row in rows:
            ns = t0_ns + round(float(row["t"]) * 1e9)
            for k, cid in zip((1, 2), cids):
                vec = types["geometry_msgs/msg/Vector3"]
                msg = types[imu](
                    header=types["std_msgs/msg/Header"](
                        stamp=types["builtin_interfaces/msg/Time"](
                            sec=ns // 10**9, nanosec=ns % 10**9
                        ),
                        frame_id=f"imu{k}",
                    ),
                    orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=np.array([-1.0] + [0.0] * 8),
                    angular_velocity=vec(*(float(row[f"g{c}_{k}"]) for c in "xyz")),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=vec(*(float(row[f"a{c}_{k}"]) for c in "xyz")),
                    linear_acceleration_covariance=np.zeros(9),
                )
                data = bytes(store.serialize_cdr(msg, imu))
                w.add_message(cid, log_time=ns, data=data, publish_time=ns)
        w.finish()
    return path


def test_an_estimate_mcap_of_a_robot_log_records_its_t0_ns(tmp_path: Path) -> None:
    """The estimate CSV of a robot log has a ``t0_ns`` line; the MCAP's metadata record
    holds the same ``t0_ns``, and every message is stamped ``t0_ns + t``."""
    from mcap.reader import make_reader

    t0 = 1_733_400_000_123_456_789
    log = _imu_log(DATA / "rod2" / "planar-s_raw.csv", tmp_path / "log.mcap", t0, 40)
    args = ["estimate", str(log), "--robot", "two-section", "--topic", "/imu1", "--topic", "/imu2"]
    for out in ("e.csv", "e.mcap"):
        assert main([*args, "--method", "ekf", "-o", str(tmp_path / out)]) == 0
    lines = [ln for ln in (tmp_path / "e.csv").read_text().splitlines() if ln.startswith("#")]
    assert f"# t0_ns = {t0}" in lines
    with (tmp_path / "e.mcap").open("rb") as fh:
        notes = {
            k: v
            for record in make_reader(fh).iter_metadata()
            if record.name == "continuum-mhe"
            for k, v in record.metadata.items()
        }
    assert int(notes["t0_ns"]) == t0
    _, topics = _messages(tmp_path / "e.mcap")
    assert [ns for ns, _ in topics["/continuum/estimate"]] == [
        int(notes["t0_ns"]) + round(msg["t"] * 1e9) for _, msg in topics["/continuum/estimate"]
    ]
    # the options replay from the MCAP as from the CSV
    assert (
        main([*args[:2], "--config", str(tmp_path / "e.mcap"), "-o", str(tmp_path / "r.csv")]) == 0
    )
