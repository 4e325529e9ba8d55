"""ENU/FLU (ROS) <-> NED/FRD (PX4, MAVLink) conversions of positions, vectors, attitude and yaw.

Conventions and their sources:

- ROS (REP 103, "Standard Units of Measure and Coordinate Conventions"; REP 105, "Coordinate
  Frames for Mobile Platforms"): the map frame is ENU (x east, y north, z up) and the body
  frame ``base_link`` is FLU (x forward, y left, z up). Yaw is about +z (up), 0 along +x
  (east), counter-clockwise positive.
- PX4 (PX4 User Guide, "ROS 2 User Guide", section "ROS 2 & PX4 Frame Conventions"; the
  ``px4_msgs`` definitions of ``TrajectorySetpoint`` and ``VehicleOdometry``) and MAVLink
  (``MAV_FRAME_LOCAL_NED``, ``SET_POSITION_TARGET_LOCAL_NED``): the local frame is NED (x north,
  y east, z down) and the body frame is FRD (x forward, y right, z down). Yaw is about +z
  (down), 0 along north, clockwise positive (a heading). ``VehicleOdometry.q`` is the rotation
  from the FRD body frame to the NED frame, ordered (w, x, y, z).

The world maps ENU -> NED as ``(x, y, z) -> (y, x, -z)`` and the body maps FLU -> FRD as
``(x, y, z) -> (x, -y, -z)``: both are their own inverse, so a vector (position, velocity,
acceleration, jerk, angular velocity) converts back bit for bit. Hence

    q_ned_frd = q_enu_to_ned * q_enu_flu * q_flu_to_frd,
    yaw_ned = pi/2 - yaw_enu,   yaw_rate_ned = -yaw_rate_enu.

Quaternions and yaw involve sqrt(1/2) and pi/2, so their round trip is exact to rounding
(within a few units in the last place), not bit for bit.
"""

import math
from typing import Sequence, Union

import numpy as np

ArrayLike = Union[Sequence[float], np.ndarray]

#: sqrt(1/2), the components of the ENU <-> NED rotation quaternion (pi about (1, 1, 0)).
_HALF_SQRT2 = math.sqrt(0.5)


def _vectors(values: ArrayLike) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    if array.shape[-1:] != (3,):
        raise ValueError(f'expected vectors of 3 components (shape (..., 3)), got shape '
                         f'{array.shape}')
    return array


def enu_to_ned(vectors: ArrayLike) -> np.ndarray:
    """A world-frame vector from ENU to NED: ``(x, y, z) -> (y, x, -z)``.

    Positions [m], velocities [m/s], accelerations [m/s^2] and jerks [m/s^3] alike.

    Parameters
    ----------
    vectors : array_like, shape (..., 3)
        In the ENU map frame.

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        In the NED frame (the same origin).
    """
    v = _vectors(vectors)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def ned_to_enu(vectors: ArrayLike) -> np.ndarray:
    """A world-frame vector from NED to ENU: ``(x, y, z) -> (y, x, -z)`` (its own inverse)."""
    v = _vectors(vectors)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def flu_to_frd(vectors: ArrayLike) -> np.ndarray:
    """A body-frame vector from FLU (REP 103 ``base_link``) to FRD: ``(x, y, z) -> (x, -y, -z)``.

    Body velocities [m/s] and angular velocities (roll, pitch, yaw rates) [rad/s] alike.
    """
    v = _vectors(vectors)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


def frd_to_flu(vectors: ArrayLike) -> np.ndarray:
    """A body-frame vector from FRD to FLU: ``(x, y, z) -> (x, -y, -z)`` (its own inverse)."""
    v = _vectors(vectors)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


def _quaternion(values: ArrayLike) -> np.ndarray:
    q = np.asarray(values, dtype=np.float64).reshape(-1)
    if q.shape != (4,):
        raise ValueError(f'expected a quaternion of 4 components, got shape {q.shape}')
    return q


def quaternion_enu_flu_to_ned_frd(q_xyzw: ArrayLike) -> np.ndarray:
    """Attitude from ROS (FLU body to ENU, (x, y, z, w)) to PX4 (FRD body to NED, (w, x, y, z)).

    ``q_ned_frd = q_enu_to_ned * q_enu_flu * q_flu_to_frd`` with ``q_enu_to_ned`` the rotation
    by pi about (1, 1, 0)/sqrt(2) and ``q_flu_to_frd`` by pi about x, multiplied out:
    ``(w + z, x + y, x - y, w - z) / sqrt(2)`` of the ROS quaternion's components.

    Parameters
    ----------
    q_xyzw : array_like, shape (4,)
        ``geometry_msgs/Quaternion`` order.

    Returns
    -------
    numpy.ndarray, shape (4,)
        ``VehicleOdometry.q`` order (w, x, y, z), with w >= 0.
    """
    x, y, z, w = _quaternion(q_xyzw)
    q = _HALF_SQRT2 * np.array([w + z, x + y, x - y, w - z])
    return -q if q[0] < 0.0 else q


def quaternion_ned_frd_to_enu_flu(q_wxyz: ArrayLike) -> np.ndarray:
    """Attitude from PX4 (FRD body to NED, (w, x, y, z)) to ROS (FLU body to ENU, (x, y, z, w)).

    The inverse of :func:`quaternion_enu_flu_to_ned_frd`.

    Returns
    -------
    numpy.ndarray, shape (4,)
        (x, y, z, w), with w >= 0.
    """
    w_n, x_n, y_n, z_n = _quaternion(q_wxyz)
    q = _HALF_SQRT2 * np.array([x_n + y_n, x_n - y_n, w_n - z_n, w_n + z_n])
    return -q if q[3] < 0.0 else q


def wrap_angle(angle: float) -> float:
    """``angle`` [rad] wrapped into [-pi, pi)."""
    return float((angle + math.pi) % (2.0 * math.pi) - math.pi)


def yaw_enu_to_ned(yaw_enu: float) -> float:
    """Heading from ENU (0 east, counter-clockwise) to NED (0 north, clockwise) [rad].

    ``pi/2 - yaw``, wrapped into [-pi, pi). Non-finite values stay non-finite (NaN: unset, as
    ``TrajectorySetpoint.yaw`` reads it).
    """
    if not math.isfinite(yaw_enu):
        return float('nan')
    return wrap_angle(0.5 * math.pi - yaw_enu)


def yaw_ned_to_enu(yaw_ned: float) -> float:
    """Heading from NED to ENU [rad]: ``pi/2 - yaw``, wrapped into [-pi, pi) (its own inverse)."""
    if not math.isfinite(yaw_ned):
        return float('nan')
    return wrap_angle(0.5 * math.pi - yaw_ned)


def yaw_rate_enu_to_ned(rate: float) -> float:
    """Yaw rate about up (ENU) to yaw rate about down (NED) [rad/s]: the sign flips."""
    return -float(rate)


def yaw_rate_ned_to_enu(rate: float) -> float:
    """Yaw rate about down (NED) to yaw rate about up (ENU) [rad/s]: the sign flips."""
    return -float(rate)


def yaw_of_quaternion_xyzw(q_xyzw: ArrayLike) -> float:
    """Heading [rad] of a ROS (x, y, z, w) quaternion about +z of its frame (ZYX Euler yaw)."""
    x, y, z, w = _quaternion(q_xyzw)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def rotate_xyzw(q_xyzw: ArrayLike, vectors: ArrayLike) -> np.ndarray:
    """``vectors`` (shape (..., 3)) rotated by the unit quaternion ``q_xyzw`` (body -> world)."""
    x, y, z, w = _quaternion(q_xyzw)
    matrix = np.array([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)]])
    return _vectors(vectors) @ matrix.T


def rotate_xyzw_inverse(q_xyzw: ArrayLike, vectors: ArrayLike) -> np.ndarray:
    """``vectors`` rotated by the inverse of ``q_xyzw`` (world -> body)."""
    x, y, z, w = _quaternion(q_xyzw)
    return rotate_xyzw([-x, -y, -z, w], vectors)
