"""The start-up check of the plan writer: CDR bytes are used only when rclpy reads them right."""

from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from uav_global_planner.ros import cdr
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.plan_writer import (check_plan, plan_writer_mismatches, PlanWriter,
                                                startup_plan_writer)


def test_cdr_and_rclpy_writers_both_pass_the_check():
    assert plan_writer_mismatches(PlanWriter(use_cdr=True)) == []
    assert plan_writer_mismatches(PlanWriter(use_cdr=False)) == []


def test_the_check_plan_exercises_headings_and_stamps():
    trajectory = deserialize_message(
        PlanWriter(use_cdr=True).trajectory(check_plan(), 'map', 7, None), MultiDOFJointTrajectory)
    yaws = [conv.quaternion_yaw([t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w])
            for point in trajectory.points for t in point.transforms]
    assert len(set(round(yaw, 9) for yaw in yaws)) >= 3    # a climb, then two headings
    assert trajectory.points[2].time_from_start.nanosec == 123_456_789


def test_a_wrong_message_is_named():
    writer = PlanWriter(use_cdr=True)
    writer.trajectory = (lambda result, frame, stamp_ns, orientation:
                         cdr.serialized_trajectory(result, frame, stamp_ns + 1, orientation))
    problems = plan_writer_mismatches(writer)
    assert len(problems) == 2 and all(p.startswith('trajectory') for p in problems)


def test_unreadable_bytes_are_named():
    writer = PlanWriter(use_cdr=True)
    writer.plan_path = (lambda result, frame, stamp_ns, orientation:
                        cdr.serialized_plan_path(result, frame, stamp_ns, orientation)[:40])
    problems = plan_writer_mismatches(writer)
    assert problems and all('plan (frame' in p and 'not readable' in p for p in problems)


class _Log:
    def __init__(self):
        self.errors, self.debugs = [], []

    def error(self, text):
        self.errors.append(text)

    def debug(self, text):
        self.debugs.append(text)


def test_startup_picks_the_cdr_writer_once():
    log = _Log()
    first = startup_plan_writer(log)
    assert first.use_cdr and not log.errors
    assert startup_plan_writer(log) is first
