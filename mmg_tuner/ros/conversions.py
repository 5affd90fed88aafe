"""Model frame <-> ROS messages (REP-103/105: map ENU, base_link FLU).

x_E (north) = y_map, y_E (east) = x_map, psi = pi/2 - yaw; u = twist.x, v = -twist.y,
r = -twist.angular.z (conventions.md).
"""
from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry


def stamp_from_seconds(t: float) -> Time:
    sec = int(math.floor(t))
    return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)


def seconds_from_stamp(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def odometry_from_state(state: np.ndarray, t: float, frame_id: str = 'map',
                        child_frame_id: str = 'base_link', msg: Odometry | None = None
                        ) -> Odometry:
    """Odometry of a model-frame state; pass msg to refill a preallocated message (cheaper
    than building one per tick in a 50 Hz loop)."""
    x, y, psi, u, v, r = (float(a) for a in state)
    yaw = math.pi / 2 - psi
    if msg is None:
        msg = Odometry()
        msg.header.frame_id = frame_id
        msg.child_frame_id = child_frame_id
    sec = math.floor(t)
    msg.header.stamp.sec = int(sec)
    msg.header.stamp.nanosec = int(round((t - sec) * 1e9)) % 1_000_000_000
    msg.pose.pose.position.x = y
    msg.pose.pose.position.y = x
    msg.pose.pose.orientation.z = math.sin(yaw / 2)
    msg.pose.pose.orientation.w = math.cos(yaw / 2)
    msg.twist.twist.linear.x = u
    msg.twist.twist.linear.y = -v
    msg.twist.twist.angular.z = -r
    return msg


def state_from_odometry(msg: Odometry) -> np.ndarray:
    q = msg.pose.pose.orientation
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
    p, tw = msg.pose.pose.position, msg.twist.twist
    return np.array([p.y, p.x, math.pi / 2 - yaw, tw.linear.x, -tw.linear.y, -tw.angular.z])
