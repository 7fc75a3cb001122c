"""Helpers for the robot-log tests: ``sensor_msgs/msg/Imu`` messages for bags and MCAP
files written with ``rosbags`` (ROS 1 and ROS 2 type stores)."""

from __future__ import annotations

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
