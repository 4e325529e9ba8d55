"""The serialised plan messages the node publishes are exactly the messages of conversions.

The node publishes ``plan``, ``unsmoothed_plan`` and ``trajectory`` as CDR bytes written from the
arrays (:mod:`uav_global_planner.ros.cdr`); deserialised, they must equal, field by field and bit
for bit, the message objects :mod:`uav_global_planner.ros.conversions` builds. In-process, no
nodes.
"""

from dataclasses import replace
import math

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import Trajectory
from uav_global_planner.ros import cdr
from uav_global_planner.ros import conversions as conv

# Frames of different lengths move the alignment padding; one is not ASCII.
FRAMES = ['map', 'm', 'odom', 'world_ned', 'wörld/α']
STAMPS = [0, 123, 1_795_370_151_660_805_510]
ORIENTATIONS = [None, (0.0, 0.0, 0.0, 1.0), (0.1, -0.2, 0.3, 0.9273618495495703)]


@pytest.fixture(scope='module')
def plans():
    """Successful plans of the two paper scenes (a few hundred poses each)."""
    results = []
    for name in ('paper_medium', 'paper_high'):
        scene = load_scene(find_scene(name))
        result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal)
        assert result.ok, result.message
        results.append(result)
    return results


@pytest.mark.parametrize('frame', FRAMES)
@pytest.mark.parametrize('stamp_ns', STAMPS)
@pytest.mark.parametrize('orientation', ORIENTATIONS)
def test_plan_messages_equal_the_message_objects(plans, frame, stamp_ns, orientation):
    for result in plans:
        path = deserialize_message(cdr.serialized_plan_path(result, frame, stamp_ns,
                                                            orientation), Path)
        assert path == conv.plan_to_path(result, frame, stamp_ns, orientation)
        unsmoothed = deserialize_message(
            cdr.serialized_unsmoothed_path(result, frame, stamp_ns, orientation), Path)
        assert unsmoothed == conv.plan_to_unsmoothed_path(result, frame, stamp_ns, orientation)
        trajectory = deserialize_message(
            cdr.serialized_trajectory(result, frame, stamp_ns, orientation),
            MultiDOFJointTrajectory)
        assert trajectory == conv.plan_to_trajectory(result, frame, stamp_ns, orientation)


@pytest.mark.parametrize('joint', ['base_link', 'b', 'uav1/base_link'])
def test_trajectory_joint_name(plans, joint):
    trajectory = deserialize_message(
        cdr.serialized_trajectory(plans[0], 'map', 5, None, joint), MultiDOFJointTrajectory)
    assert trajectory.joint_names == [joint]
    assert trajectory == conv.plan_to_trajectory(plans[0], 'map', 5, None, joint)


@pytest.mark.parametrize('count', [0, 1, 2])
def test_tiny_paths(count):
    points = np.arange(3.0 * count).reshape(-1, 3)
    times = np.linspace(0.0, 1.0, count)
    for orientation in ORIENTATIONS:
        for stamps in (None, times):
            path = deserialize_message(cdr.serialized_path(points, 'map', 7, stamps,
                                                           orientation), Path)
            assert path == conv.points_to_path(points, 'map', 7, stamps, orientation)


def test_single_point_trajectory(plans):
    one = Trajectory(times=np.zeros(1), positions=np.array([[1.0, 2.0, 3.0]]),
                     velocities=np.zeros((1, 3)), accelerations=np.zeros((1, 3)))
    result = replace(plans[0], trajectory=one)
    trajectory = deserialize_message(cdr.serialized_trajectory(result, 'map', 1),
                                     MultiDOFJointTrajectory)
    assert trajectory == conv.plan_to_trajectory(result, 'map', 1)


def test_failed_plan_has_no_trajectory(plans):
    with pytest.raises(ValueError, match='no trajectory'):
        cdr.serialized_plan_path(replace(plans[0], trajectory=None), 'map', 0)


_coordinate = st.floats(-1e3, 1e3, allow_nan=False).map(lambda v: round(v, 1))


@settings(max_examples=60, deadline=None)
@given(points=arrays(np.float64, st.tuples(st.integers(0, 12), st.just(3)),
                     elements=_coordinate),
       spacing=st.floats(1e-3, 10.0), stamp_ns=st.integers(0, (2 ** 31 - 200) * 10 ** 9),
       frame=st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'),
                     min_size=1, max_size=9),
       yaw=st.none() | st.floats(-math.pi, math.pi))
def test_any_polyline(points, spacing, stamp_ns, frame, yaw):
    """Vertical stretches, repeated points, any frame name (UTF-8 without NUL, as ROS strings
    are) and stamp (int32 seconds, as ``builtin_interfaces/Time`` holds): the same message."""
    times = spacing * np.arange(len(points))
    orientation = None if yaw is None else conv.yaw_quaternion(yaw)
    path = deserialize_message(cdr.serialized_path(points, frame, stamp_ns, times,
                                                   orientation), Path)
    assert path == conv.points_to_path(points, frame, stamp_ns, times, orientation)


def test_stamps_beyond_int32_seconds_are_refused_not_wrapped():
    points = np.zeros((2, 3))
    with pytest.raises(OverflowError):
        cdr.serialized_path(points, 'map', (2 ** 31 - 1) * 10 ** 9, np.array([0.0, 2.0]))
