"""The simulated vehicle's own ENU/FLU <-> NED/FRD conversion, written apart from the follower's.

The closed loop checks the follower's conversion (``uav_global_planner.core.frames``) against
a vehicle that converts back with independent code; so this module is written from the
conventions themselves and never imports the follower's. As rotation matrices, not as the
follower's component swaps:

- World frames. ENU (REP 103: x east, y north, z up) is the planner's map frame; NED (x north,
  y east, z down) is PX4's local frame and MAVLink's ``MAV_FRAME_LOCAL_NED``, with the same
  origin (the map origin is the vehicle's local origin). A vector maps by
  ``v_ned = M @ v_enu`` with ``M`` the matrix whose rows are the NED axes written in ENU:
  north = (0, 1, 0), east = (1, 0, 0), down = (0, 0, -1). ``M`` is symmetric and its own
  inverse.
- Body frames. FLU (REP 103: x forward, y left, z up) and FRD (PX4, MAVLink: x forward,
  y right, z down): ``v_frd = B @ v_flu`` with ``B = diag(1, -1, -1)``.
- Attitude. ``R_enu_flu`` takes FLU body vectors into ENU; then
  ``R_ned_frd = M @ R_enu_flu @ B``. Quaternions are Hamilton, as in both conventions:
  ROS writes (x, y, z, w), PX4's ``q`` and MAVLink's ``q`` write (w, x, y, z).
- Heading. ENU yaw: angle of the forward axis from east, counter-clockwise (REP 103); NED yaw
  (PX4 ``TrajectorySetpoint.yaw``, MAVLink ``yaw``): from north, clockwise. Both are read off
  the forward axis, so ``yaw_ned = atan2(east, north)`` of the forward axis whose ENU heading
  is ``yaw_enu``; a yaw rate about up is minus the one about down.
"""

import math

import numpy as np
from numpy.typing import ArrayLike

#: NED axes written in ENU, as rows: ``v_ned = ENU_TO_NED @ v_enu`` (and back, it is an
#: involution).
ENU_TO_NED = np.array([[0.0, 1.0, 0.0],
                       [1.0, 0.0, 0.0],
                       [0.0, 0.0, -1.0]])

#: FLU -> FRD body axes (and back).
FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])


def vector_enu_to_ned(v: ArrayLike) -> np.ndarray:
    """A position, velocity, acceleration or jerk from ENU to NED [same units]."""
    return ENU_TO_NED @ np.asarray(v, dtype=np.float64)


def vector_ned_to_enu(v: ArrayLike) -> np.ndarray:
    """A position, velocity, acceleration or jerk from NED to ENU [same units]."""
    return ENU_TO_NED.T @ np.asarray(v, dtype=np.float64)


def body_flu_to_frd(v: ArrayLike) -> np.ndarray:
    """A body-frame vector (angular velocity [rad/s], velocity [m/s]) from FLU to FRD."""
    return FLU_TO_FRD @ np.asarray(v, dtype=np.float64)


def body_frd_to_flu(v: ArrayLike) -> np.ndarray:
    """A body-frame vector from FRD to FLU."""
    return FLU_TO_FRD.T @ np.asarray(v, dtype=np.float64)


def matrix_from_quaternion_xyzw(q: ArrayLike) -> np.ndarray:
    """Rotation matrix of a Hamilton unit quaternion (x, y, z, w)."""
    x, y, z, w = (float(c) for c in np.asarray(q, dtype=np.float64).reshape(4))
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def quaternion_wxyz_from_matrix(r: np.ndarray) -> np.ndarray:
    """Hamilton unit quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method)."""
    trace = float(r[0, 0] + r[1, 1] + r[2, 2])
    if trace > 0.0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif r[1, 1] > r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s]
    out = np.asarray(q, dtype=np.float64)
    out /= np.linalg.norm(out)
    return -out if out[0] < 0.0 else out


def attitude_enu_flu_to_ned_frd(q_xyzw: ArrayLike) -> np.ndarray:
    """Attitude of an FLU body in ENU (ROS, x y z w) as an FRD body in NED (PX4, w x y z)."""
    r_ned_frd = ENU_TO_NED @ matrix_from_quaternion_xyzw(q_xyzw) @ FLU_TO_FRD
    return quaternion_wxyz_from_matrix(r_ned_frd)


def heading_enu_to_ned(yaw_enu: float) -> float:
    """ENU yaw (from east, counter-clockwise) as NED yaw (from north, clockwise), in (-pi, pi]
    [rad]; NaN stays NaN."""
    if not math.isfinite(yaw_enu):
        return math.nan
    forward_enu = np.array([math.cos(yaw_enu), math.sin(yaw_enu), 0.0])
    north, east, _ = ENU_TO_NED @ forward_enu
    return math.atan2(east, north)


def heading_ned_to_enu(yaw_ned: float) -> float:
    """NED yaw (from north, clockwise) as ENU yaw (from east, counter-clockwise) [rad]; NaN
    stays NaN."""
    if not math.isfinite(yaw_ned):
        return math.nan
    forward_ned = np.array([math.cos(yaw_ned), math.sin(yaw_ned), 0.0])
    east, north, _ = ENU_TO_NED.T @ forward_ned
    return math.atan2(north, east)


def heading_rate_ned_to_enu(yaw_rate_ned: float) -> float:
    """Yaw rate about down [rad/s] as yaw rate about up."""
    return -float(yaw_rate_ned)
