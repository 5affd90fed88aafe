"""
Model frame <-> ROS messages (REP-103/105: map ENU, base_link FLU).

x_E (north) = y_map, y_E (east) = x_map, psi = pi/2 - yaw; u = twist.x, v = -twist.y,
r = -twist.angular.z (conventions.md). The builders take ``msg`` to refill a preallocated
message: cheaper than building one per tick in a 50 Hz loop.
"""
from __future__ import annotations

import math
from typing import Any, Callable, TypeVar

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion, TransformStamped
from mmg_tuner.core import frames
from mmg_tuner.core.frames import enu_yaw_to_psi, psi_to_enu_yaw
from nav_msgs.msg import Odometry
import numpy as np
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

_Msg = TypeVar('_Msg', Odometry, TransformStamped)

G_MS2 = 9.80665  # [m/s^2] standard gravity: a level accelerometer at rest reads +G on z


def stamp_from_seconds(t: float) -> Time:
    sec = int(math.floor(t))
    return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)


def seconds_from_stamp(stamp: Time) -> float:
    t: float = stamp.sec + stamp.nanosec * 1e-9   # (a message is Any: no annotations)
    return t


def odometry_from_state(state: np.ndarray, t: float, frame_id: str = 'odom',
                        child_frame_id: str = 'base_link', msg: Odometry | None = None
                        ) -> Odometry:
    """
    Odometry of a model-frame state.

    Pass msg to refill a preallocated message (cheaper than building one per tick in a 50 Hz loop).
    """
    x, y, psi, u, v, r = (float(a) for a in state)
    yaw = psi_to_enu_yaw(psi)
    msg = _framed(msg, Odometry, frame_id, child_frame_id, t)
    msg.pose.pose.position.x = y
    msg.pose.pose.position.y = x
    _set_yaw(msg.pose.pose.orientation, yaw)
    msg.twist.twist.linear.x = u
    msg.twist.twist.linear.y = -v
    msg.twist.twist.angular.z = -r
    return msg


def state_from_odometry(msg: Odometry) -> np.ndarray:
    q = msg.pose.pose.orientation
    yaw = yaw_from_quaternion(q)
    p, tw = msg.pose.pose.position, msg.twist.twist
    return np.array([p.y, p.x, enu_yaw_to_psi(yaw), tw.linear.x, -tw.linear.y, -tw.angular.z])


def _stamp(header: Any, t: float) -> None:   # a std_msgs Header
    sec = math.floor(t)
    header.stamp.sec = int(sec)
    header.stamp.nanosec = int(round((t - sec) * 1e9)) % 1_000_000_000


def _framed(msg: _Msg | None, new: Callable[[], _Msg], parent: str, child: str,
            t: float) -> _Msg:
    """
    Return msg stamped t; None: a new() message from parent to child.

    A refilled message keeps the frames it was built with: only its stamp changes per tick.
    """
    if msg is None:
        msg = new()
        msg.header.frame_id = parent
        msg.child_frame_id = child
    _stamp(msg.header, t)
    return msg


def _set_yaw(q: Quaternion, yaw: float) -> None:
    """Set quaternion message q to a rotation by yaw [rad] about z (x = y = 0 as built)."""
    q.z = math.sin(yaw / 2)
    q.w = math.cos(yaw / 2)


def transform_from_state(state: np.ndarray, t: float, parent: str = 'odom',
                         child: str = 'base_link', msg: TransformStamped | None = None
                         ) -> TransformStamped:
    """
    Return the transform parent (ENU) -> child (FLU) of a model-frame state: the same pose as.

    :func:`odometry_from_state` (TF's odom -> base_link).
    """
    x, y, psi = float(state[0]), float(state[1]), float(state[2])
    yaw = psi_to_enu_yaw(psi)
    msg = _framed(msg, TransformStamped, parent, child, t)
    msg.transform.translation.x = y
    msg.transform.translation.y = x
    _set_yaw(msg.transform.rotation, yaw)
    return msg


def identity_transform(t: float, parent: str, child: str) -> TransformStamped:
    """Parent -> child with no offset (TF's static map -> odom of a simulator)."""
    msg = _framed(None, TransformStamped, parent, child, t)
    msg.transform.rotation.w = 1.0
    return msg


def navsat_fix(lat_deg: float, lon_deg: float, alt_m: float, t: float, frame_id: str,
               sigma_h_m: float, sigma_v_m: float, msg: NavSatFix | None = None) -> NavSatFix:
    """Return a GNSS fix (WGS84) with a diagonal covariance in ENU from 1-sigma noise [m]."""
    if msg is None:
        msg = NavSatFix()
        msg.status.status = NavSatStatus.STATUS_FIX
        msg.status.service = NavSatStatus.SERVICE_GPS
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    msg.header.frame_id = frame_id
    _stamp(msg.header, t)
    msg.latitude, msg.longitude, msg.altitude = float(lat_deg), float(lon_deg), float(alt_m)
    h, v = sigma_h_m * sigma_h_m, sigma_v_m * sigma_v_m
    msg.position_covariance[0], msg.position_covariance[4], msg.position_covariance[8] = h, h, v
    return msg


def imu_from_state(state: np.ndarray, accel_flu: tuple[float, float] | None, t: float,
                   frame_id: str, yaw_noise_rad: float = 0.0, gyro_noise: float = 0.0,
                   sigmas: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   msg: Imu | None = None) -> Imu:
    """
    Return an IMU sample of a model-frame state (3 DOF: level, so roll = pitch = 0).

    orientation: yaw in ENU (REP-103) plus ``yaw_noise_rad``; angular_velocity.z = -r plus
    ``gyro_noise`` [rad/s]; linear_acceleration: ``accel_flu`` (x forward, y left [m/s^2],
    the specific force of the horizontal motion) and +G on z, or covariance[0] = -1 ("not
    available") when accel_flu is None. sigmas: 1-sigma of yaw [rad], yaw rate [rad/s] and
    acceleration [m/s^2] for the covariances.
    """
    psi, r = float(state[2]), float(state[5])
    yaw = psi_to_enu_yaw(psi) + yaw_noise_rad
    if msg is None:
        msg = Imu()
    msg.header.frame_id = frame_id
    _stamp(msg.header, t)
    _set_yaw(msg.orientation, yaw)
    msg.angular_velocity.z = -r + gyro_noise
    s_yaw, s_gyro, s_acc = sigmas
    tiny = 1e-9  # roll and pitch are exactly level in a 3-DOF model
    msg.orientation_covariance[0] = msg.orientation_covariance[4] = tiny
    msg.orientation_covariance[8] = max(s_yaw * s_yaw, tiny)
    msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = tiny
    msg.angular_velocity_covariance[8] = max(s_gyro * s_gyro, tiny)
    if accel_flu is None:
        msg.linear_acceleration.x = msg.linear_acceleration.y = 0.0
        msg.linear_acceleration.z = G_MS2
        msg.linear_acceleration_covariance[0] = -1.0
    else:
        msg.linear_acceleration.x, msg.linear_acceleration.y = accel_flu
        msg.linear_acceleration.z = G_MS2
        a = max(s_acc * s_acc, tiny)
        msg.linear_acceleration_covariance[0] = a
        msg.linear_acceleration_covariance[4] = a
        msg.linear_acceleration_covariance[8] = a
    return msg


def yaw_from_quaternion(q: Any) -> float:
    """ENU yaw [rad] of a quaternion message (x, y, z, w attributes)."""
    return float(frames.yaw_from_quaternion(q.x, q.y, q.z, q.w))
