"""ENU/FLU <-> NED/FRD conversions (uav_global_planner.core.frames).

The expected values follow the conventions the module names: REP 103/105 for ROS (ENU map,
FLU body, yaw counter-clockwise from east) and the PX4 User Guide, "ROS 2 User Guide", section
"ROS 2 & PX4 Frame Conventions", with the ``px4_msgs`` field comments (NED local frame, FRD body,
``VehicleOdometry.q`` from FRD body to NED in (w, x, y, z), ``TrajectorySetpoint.yaw`` a
heading: 0 north, clockwise).
"""

import math

import numpy as np
import pytest

from uav_global_planner.core import frames


def _quaternion_yaw_xyzw(yaw: float) -> np.ndarray:
    return np.array([0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)])


def test_vectors_round_trip_bit_for_bit():
    rng = np.random.default_rng(3)
    vectors = rng.normal(scale=100.0, size=(1000, 3))
    assert np.array_equal(frames.ned_to_enu(frames.enu_to_ned(vectors)), vectors)
    assert np.array_equal(frames.frd_to_flu(frames.flu_to_frd(vectors)), vectors)
    as_float32 = vectors.astype(np.float32)    # as px4_msgs carries them
    back = frames.ned_to_enu(frames.enu_to_ned(as_float32).astype(np.float32))
    assert np.array_equal(back.astype(np.float32), as_float32)


def test_a_climb_north_east_as_px4_expects():
    # ENU: 3 m east, 4 m north, 10 m up, climbing at 1 m/s while flying north at 2 m/s.
    assert frames.enu_to_ned([3.0, 4.0, 10.0]).tolist() == [4.0, 3.0, -10.0]
    assert frames.enu_to_ned([0.0, 2.0, 1.0]).tolist() == [2.0, 0.0, -1.0]     # vz < 0: up
    # Gravity-compensating acceleration up is negative z in NED.
    assert frames.enu_to_ned([0.0, 0.0, 9.81]).tolist() == [0.0, 0.0, -9.81]
    # A body rate yawing left (FLU +z) is a negative FRD z rate.
    assert frames.flu_to_frd([0.1, 0.2, 0.3]).tolist() == [0.1, -0.2, -0.3]


@pytest.mark.parametrize('yaw_enu, yaw_ned', [
    (0.0, 0.5 * math.pi),            # facing east: PX4 heading 90 deg
    (0.5 * math.pi, 0.0),            # facing north (a 90 deg yaw from east): heading 0
    (math.pi, -0.5 * math.pi),       # facing west: heading -90 deg (270)
    (-0.5 * math.pi, -math.pi),      # facing south: heading 180 deg
])
def test_yaw_as_px4_expects(yaw_enu, yaw_ned):
    assert frames.yaw_enu_to_ned(yaw_enu) == pytest.approx(yaw_ned, abs=1e-15)
    q_ned = frames.quaternion_enu_flu_to_ned_frd(_quaternion_yaw_xyzw(yaw_enu))
    # The PX4 quaternion of a pure heading psi is (cos psi/2, 0, 0, sin psi/2), up to sign.
    expected = np.array([math.cos(0.5 * yaw_ned), 0.0, 0.0, math.sin(0.5 * yaw_ned)])
    assert min(np.max(np.abs(q_ned - expected)), np.max(np.abs(q_ned + expected))) < 1e-15


def test_yaw_rate_and_nan_yaw():
    assert frames.yaw_rate_enu_to_ned(0.4) == -0.4
    assert frames.yaw_rate_ned_to_enu(frames.yaw_rate_enu_to_ned(0.4)) == 0.4
    assert math.isnan(frames.yaw_enu_to_ned(float('nan')))


def test_quaternion_maps_body_axes_as_the_frames_do():
    """Rotating a body vector in ROS, then converting, equals converting, then rotating."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        body_flu = rng.normal(size=3)
        world_ned = frames.enu_to_ned(frames.rotate_xyzw(q, body_flu))
        q_ned_wxyz = frames.quaternion_enu_flu_to_ned_frd(q)
        q_ned_xyzw = np.r_[q_ned_wxyz[1:], q_ned_wxyz[0]]
        via_px4 = frames.rotate_xyzw(q_ned_xyzw, frames.flu_to_frd(body_flu))
        assert np.allclose(via_px4, world_ned, atol=1e-12)


def test_quaternion_and_yaw_round_trip_to_rounding():
    rng = np.random.default_rng(7)
    for _ in range(500):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q = -q if q[3] < 0 else q
        back = frames.quaternion_ned_frd_to_enu_flu(frames.quaternion_enu_flu_to_ned_frd(q))
        assert np.max(np.abs(back - q)) <= 4e-16
        yaw = float(rng.uniform(-math.pi, math.pi))
        assert abs(frames.yaw_ned_to_enu(frames.yaw_enu_to_ned(yaw)) - yaw) <= 1e-15


def test_yaw_of_quaternion_and_bad_shapes():
    assert frames.yaw_of_quaternion_xyzw(_quaternion_yaw_xyzw(1.0)) == pytest.approx(1.0)
    with pytest.raises(ValueError, match='3 components'):
        frames.enu_to_ned([1.0, 2.0])
    with pytest.raises(ValueError, match='4 components'):
        frames.quaternion_enu_flu_to_ned_frd([0.0, 0.0, 1.0])
