"""Helpers for the robot-log tests: ``sensor_msgs/msg/Imu`` messages for bags and MCAP
files written with ``rosbags`` (ROS 1 and ROS 2 type stores)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

IMU = "sensor_msgs/msg/Imu"
T0_NS = 1_700_000_000_123_456_789  # an absolute ROS time, as a real bag has


def imu_msg(
    store: Any,
    ns: int,
    acc: np.ndarray,
    gyr: np.ndarray,
    ros1: bool = False,
    quat: np.ndarray | None = None,
    no_gyro: bool = False,
    no_accel: bool = False,
) -> Any:
    """An Imu message; ``quat`` ``(w, x, y, z)`` the orientation (None: none, REP 145);
    ``no_gyro``: its rates marked absent (``angular_velocity_covariance[0] = -1``);
    ``no_accel``: its acceleration marked absent (``linear_acceleration_covariance``)."""
    T = store.types
    stamp = T["builtin_interfaces/msg/Time"](sec=int(ns // 10**9), nanosec=int(ns % 10**9))
    header = (
        T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="imu")
        if ros1
        else T["std_msgs/msg/Header"](stamp=stamp, frame_id="imu")
    )
    vec = T["geometry_msgs/msg/Vector3"]
    cov = np.zeros(9)
    w, x, y, z = (1.0, 0.0, 0.0, 0.0) if quat is None else map(float, quat)
    return T[IMU](
        header=header,
        orientation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        orientation_covariance=np.array([-1.0] + [0.0] * 8) if quat is None else cov,
        angular_velocity=vec(x=gyr[0], y=gyr[1], z=gyr[2]),
        angular_velocity_covariance=np.array([-1.0] + [0.0] * 8) if no_gyro else cov,
        linear_acceleration=vec(x=acc[0], y=acc[1], z=acc[2]),
        linear_acceleration_covariance=np.array([-1.0] + [0.0] * 8) if no_accel else cov,
    )


def write_ros2_bag_of_csv(csv: Path, bag: Path) -> list[str]:
    """The raw CSV recording ``csv`` of two IMUs (``t`` then ``ax..gz`` of each) as a ROS 2
    bag folder ``bag``, one ``sensor_msgs/msg/Imu`` topic per IMU at ``T0_NS`` plus each
    time; returns the ``--topic`` options that read it in the CSV's IMU order."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    raw = np.loadtxt(csv, delimiter=",", skiprows=1)
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(bag, version=9) as w:
        topics = [w.add_connection(f"/imu{k}", IMU, typestore=store) for k in (1, 2)]
        for row in raw:
            ns = T0_NS + round(row[0] * 1e9)
            for k, conn in enumerate(topics):
                acc, gyr = row[1 + 6 * k : 4 + 6 * k], row[4 + 6 * k : 7 + 6 * k]
                w.write(conn, ns, store.serialize_cdr(imu_msg(store, ns, acc, gyr), IMU))
    return ["--topic", "/imu1", "--topic", "/imu2"]


def csv_and_ros2_bag(lines: list[str], folder: Path) -> list[tuple[str, Path, list[str]]]:
    """The raw CSV ``lines`` of two IMUs (a header, then rows) written to ``folder`` as a
    CSV file and as a ROS 2 bag folder (:func:`write_ros2_bag_of_csv`): ``(name, source,
    options)`` of each, the options being those that read it in the CSV's IMU order."""
    csv = folder / "readings.csv"
    csv.write_text("\n".join(lines) + "\n")
    bag = folder / "bag"
    return [("csv", csv, []), ("bag", bag, write_ros2_bag_of_csv(csv, bag))]
