"""Replans in flight through real processes: a new plan continues the plan in force.

A planner node runs as a process on the paper_medium scene with a 5 m/s horizontal speed limit.
The test side plays the flight stack: it streams odometry at 50 Hz (position, heading and the
twist in the body frame) of a vehicle that flies the newest ``trajectory`` from its header
stamp on, and switches to a new trajectory at the new header stamp. A new goal (on
``goal_pose`` or as a Nav2 ComputePathToPose) while the vehicle is at speed must give a plan
whose first state (position, velocity, acceleration at its stamp) is the old plan's state at
that stamp, to 1 cm, 0.05 m/s and 0.2 m/s^2. The old plan's state is read from its own
message, interpolated between its points (0.05 s apart).
"""

import threading
import time
from typing import Dict, Iterator, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.action import ActionClient
from scipy.spatial.transform import Rotation
from std_msgs.msg import Header
from trajectory_msgs.msg import MultiDOFJointTrajectory

from ros_harness import (LATCHED_QOS, PlannerClient, pose_msg, READY_TEXT, RosClient,
                         RUN_NAMESPACE, start_planner, STARTUP_TIMEOUT_S, unique_domain_id)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.nav2_client import ExecutorCalls, get_result, send_goal

pytestmark = pytest.mark.ros

SCENE = load_scene(find_scene('paper_medium'))
NS = 1_000_000_000
POSITION_TOL = 0.01
VELOCITY_TOL = 0.05
ACCEL_TOL = 0.2
#: The flight: a hover at HOVER, then goals at speed.
HOVER = np.array([-8.0, -8.0, 3.0])
FIRST_GOAL = np.array([8.0, 8.0, 3.0])
FAST = {'max_speed_horizontal': 5.0, 'max_accel_horizontal': 3.0, 'plan_without_map': True}
FLIGHT = f'{RUN_NAMESPACE}/flight'
ODOMETRY_PERIOD_S = 0.02


class Reference:
    """A ``trajectory`` message as a function of ROS time: position, velocity, acceleration.

    Positions are interpolated by cubic Hermite (with the velocities), velocities and
    accelerations linearly; beyond the ends the end points hold.
    """

    def __init__(self, msg: MultiDOFJointTrajectory) -> None:
        self.stamp_ns = conv.time_to_ns(msg.header.stamp)
        points = msg.points
        self.times = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
                               for p in points])
        self.positions = np.array([[p.transforms[0].translation.x, p.transforms[0].translation.y,
                                    p.transforms[0].translation.z] for p in points])
        self.quaternions = np.array([[p.transforms[0].rotation.x, p.transforms[0].rotation.y,
                                      p.transforms[0].rotation.z, p.transforms[0].rotation.w]
                                     for p in points])
        self.velocities = np.array([[p.velocities[0].linear.x, p.velocities[0].linear.y,
                                     p.velocities[0].linear.z] for p in points])
        self.accelerations = np.array([[p.accelerations[0].linear.x,
                                        p.accelerations[0].linear.y,
                                        p.accelerations[0].linear.z] for p in points])

    def state(self, at_ns: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration and quaternion at ROS time ``at_ns``."""
        t = float(np.clip((at_ns - self.stamp_ns) / NS, self.times[0], self.times[-1]))
        j = int(np.clip(np.searchsorted(self.times, t, side='right') - 1, 0,
                        len(self.times) - 2))
        h = self.times[j + 1] - self.times[j]
        u = (t - self.times[j]) / h
        h00, h10 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u
        h01, h11 = -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2
        position = (h00 * self.positions[j] + h10 * h * self.velocities[j]
                    + h01 * self.positions[j + 1] + h11 * h * self.velocities[j + 1])

        def linear(values: np.ndarray) -> np.ndarray:
            return (1.0 - u) * values[j] + u * values[j + 1]
        return (position, linear(self.velocities), linear(self.accelerations),
                self.quaternions[j if u < 0.5 else j + 1])

    def speed_time(self, speed: float) -> Optional[float]:
        """First time from the start [s] the reference flies at ``speed`` [m/s] or more."""
        fast = np.flatnonzero(np.linalg.norm(self.velocities, axis=1) >= speed)
        return float(self.times[fast[0]]) if len(fast) else None


class FlightStack:
    """Streams the odometry of a vehicle that flies the newest trajectory from its stamp.

    Before any trajectory (or with ``hold``) it hovers at a fixed point with zero twist.
    """

    def __init__(self, planner: PlannerClient, trajectories, hover: np.ndarray) -> None:
        self.planner = planner
        self.trajectories = trajectories
        self.hover = hover
        self.references: Dict[int, Reference] = {}
        self.following = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5.0)

    def reference(self, stamp_ns: int, timeout_s: float = 10.0) -> Reference:
        """The trajectory message stamped ``stamp_ns``, as a Reference."""
        msg = self.trajectories.wait_for(
            lambda m: conv.time_to_ns(m.header.stamp) == stamp_ns and len(m.points) > 1,
            timeout_s, what=f'the trajectory stamped {stamp_ns}')
        if stamp_ns not in self.references:
            self.references[stamp_ns] = Reference(msg)
        return self.references[stamp_ns]

    def flown(self, now_ns: int) -> Optional[Reference]:
        """The trajectory the vehicle flies at ``now_ns``: the newest one already stamped."""
        candidates = [m for m in self.trajectories.messages if len(m.points) > 1
                      and conv.time_to_ns(m.header.stamp) <= now_ns]
        if not self.following or not candidates:
            return None
        newest = max(candidates, key=lambda m: conv.time_to_ns(m.header.stamp))
        return self.reference(conv.time_to_ns(newest.header.stamp))

    def _run(self) -> None:
        client = self.planner.client
        while not self._stop.is_set():
            now = client.now_ns()
            reference = self.flown(now)
            if reference is None:
                position, velocity, quaternion = self.hover, np.zeros(3), np.array([0, 0, 0, 1.])
            else:
                position, velocity, _, quaternion = reference.state(now)
            msg = Odometry()
            msg.header = Header(frame_id='map', stamp=conv.time_from_ns(now))
            msg.child_frame_id = 'base_link'
            msg.pose.pose = pose_msg(position, 'map', quaternion).pose
            # The twist in the body frame, as flight stacks give it.
            body = Rotation.from_quat(quaternion).inv().apply(velocity)
            msg.twist.twist.linear.x, msg.twist.twist.linear.y = float(body[0]), float(body[1])
            msg.twist.twist.linear.z = float(body[2])
            self.planner.publish('odom', msg)
            time.sleep(ODOMETRY_PERIOD_S)


@pytest.fixture(scope='module')
def flight() -> Iterator[Tuple[PlannerClient, FlightStack]]:
    domain_id = unique_domain_id()
    process = start_planner(domain_id, wait=False, namespace=FLIGHT, parameters=FAST)
    client = None
    stack = None
    try:
        process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id, 'takeover_test_client')
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        planner = PlannerClient(client, FLIGHT, diagnostics, process)
        trajectories = client.record(MultiDOFJointTrajectory, planner.prefix + 'trajectory',
                                     LATCHED_QOS)
        planner.set_obstacles(conv.obstacle_input_markers(SCENE.obstacles, 'map', 0, ns='scene'),
                              len(SCENE.obstacles))
        stack = FlightStack(planner, trajectories, HOVER)
        stack.start()
        yield planner, stack
    finally:
        if stack is not None:
            stack.stop()
        if client is not None:
            client.close()
        process.kill()


def wait_plan(planner: PlannerClient, mark: int, reason: str, timeout_s: float = 30.0,
              event_reason: Optional[str] = None) -> Dict[str, str]:
    values = planner.wait_diag(mark, 'plan', timeout_s,
                               check=lambda v: v['reason'] == (event_reason or reason))
    assert values['status'] == 'ok', values
    return values


def vector(text: str) -> np.ndarray:
    """A vector of the diagnostics ('[x, y, z]')."""
    return np.array([float(v) for v in text.strip('[]').split(',')])


def assert_continues(old: Reference, new: Reference, values: Dict[str, str]) -> None:
    """The new plan's first state is the old plan's state at the new plan's stamp."""
    # What the node predicted is what the new plan starts with (4 decimals on /diagnostics),
    # within the handover tolerances: the timing may start a hair slower where the new curve
    # needs it to keep the limits, and says so (handover_velocity_error).
    assert np.linalg.norm(vector(values['takeover_velocity']) - new.velocities[0]) \
        <= VELOCITY_TOL
    assert np.linalg.norm(vector(values['takeover_acceleration']) - new.accelerations[0]) \
        <= ACCEL_TOL
    position, velocity, acceleration, _ = old.state(new.stamp_ns)
    assert new.times[0] == 0.0
    assert np.linalg.norm(new.positions[0] - position) <= POSITION_TOL, \
        (new.positions[0], position)
    assert np.linalg.norm(new.velocities[0] - velocity) <= VELOCITY_TOL, \
        (new.velocities[0], velocity)
    assert np.linalg.norm(new.accelerations[0] - acceleration) <= ACCEL_TOL, \
        (new.accelerations[0], acceleration)


def fly_until_fast(planner: PlannerClient, reference: Reference, speed: float) -> None:
    """Wait until the vehicle flies ``reference`` at ``speed`` [m/s] or more."""
    t = reference.speed_time(speed)
    assert t is not None, f'the plan never reaches {speed} m/s'
    remaining = (reference.stamp_ns + int((t + 0.1) * NS) - planner.client.now_ns()) / NS
    if remaining > 0:
        time.sleep(remaining)


def test_a_new_goal_at_speed_continues_the_plan_in_force(flight) -> None:
    planner, stack = flight
    time.sleep(0.5)    # hovering odometry has arrived
    # From rest, as always: zero velocity at the start, stamped when published.
    mark = planner.diagnostics.mark()
    planner.publish('goal_pose', pose_msg(FIRST_GOAL))
    first = wait_plan(planner, mark, 'new goal')
    assert first['takeover'] == 'rest', first
    old = stack.reference(first['_stamp'])
    assert np.allclose(old.positions[0], HOVER) and np.allclose(old.velocities[0], 0.0)
    # The heading starts at the hovering vehicle's (yaw 0, from its odometry) and turns to the
    # direction of travel (45 degrees) at the yaw-rate limit, rather than jumping there.
    yaws = 2.0 * np.arctan2(old.quaternions[:, 2], old.quaternions[:, 3])
    assert abs(yaws[0]) < 1e-9
    assert yaws[len(yaws) // 2] == pytest.approx(np.pi / 4, abs=1e-3)
    steps = np.abs(np.angle(np.exp(1j * np.diff(yaws))))
    assert steps.max() <= 0.785 * float(np.max(np.diff(old.times))) * (1 + 1e-6)
    stack.following = True
    fly_until_fast(planner, old, 3.0)

    # A new goal at speed, off to the side: the next plan starts on the old one.
    mark = planner.diagnostics.mark()
    sent_ns = planner.client.now_ns()
    planner.publish('goal_pose', pose_msg([8.0, -6.0, 5.0]))
    second = wait_plan(planner, mark, 'new goal')
    assert second['takeover'] == 'plan_in_force', second
    assert 'takeover_problem' not in second, second
    new = stack.reference(second['_stamp'])
    assert new.stamp_ns > sent_ns
    assert int(second['takeover_plan_stamp']) == old.stamp_ns
    _, velocity, _, _ = old.state(new.stamp_ns)
    assert np.linalg.norm(velocity) >= 3.0, velocity
    assert_continues(old, new, second)
    assert np.linalg.norm(new.positions[-1] - [8.0, -6.0, 5.0]) <= 1e-6


def test_a_nav2_request_at_speed_continues_the_plan_in_force(flight) -> None:
    planner, stack = flight
    try:
        from nav2_msgs.action import ComputePathToPose
    except ImportError:  # pragma: no cover - the venv builds it
        pytest.skip('nav2_msgs is not importable')
    node = planner.client.node
    calls = ExecutorCalls(node)
    action = ActionClient(node, ComputePathToPose, planner.prefix + 'compute_path_to_pose')
    assert action.wait_for_server(timeout_sec=20.0)
    # The vehicle flies the newest plan: go somewhere far, then ask Nav2 at speed.
    mark = planner.diagnostics.mark()
    planner.publish('goal_pose', pose_msg([-8.0, 8.0, 4.0]))
    values = wait_plan(planner, mark, 'new goal')
    old = stack.reference(values['_stamp'])
    stack.following = True
    fly_until_fast(planner, old, 2.0)
    mark = planner.diagnostics.mark()
    handle = send_goal(calls, action, ComputePathToPose.Goal(goal=pose_msg([4.0, 9.0, 6.0])),
                       20.0)
    assert handle.accepted
    response = get_result(calls, handle, 60.0)
    assert response.result.error_code == 0, response.result.error_msg
    values = wait_plan(planner, mark, 'compute_path_to_pose request')
    assert values['takeover'] == 'plan_in_force', values
    path = response.result.path
    stamp_ns = conv.time_to_ns(path.header.stamp)
    assert stamp_ns == values['_stamp']
    new = stack.reference(stamp_ns)
    assert_continues(old, new, values)
    assert np.linalg.norm(conv.path_to_points(path)[0] - new.positions[0]) <= 1e-6


def test_without_a_plan_in_force_the_odometry_twist_is_continued(flight) -> None:
    planner, stack = flight
    # A vehicle flown by hand (no plan in force followed): constant velocity, heading 90 deg,
    # its twist in the body frame.
    stack.following = False
    heading = Rotation.from_euler('z', 90.0, degrees=True)
    velocity = np.array([1.5, -1.0, 0.2])     # planning frame
    start_ns = planner.client.now_ns()
    origin = np.array([-6.0, 0.0, 6.0])

    def manual(now_ns: int):
        return origin + (now_ns - start_ns) / NS * velocity

    stack.hover = origin
    stop = threading.Event()

    def stream() -> None:
        while not stop.is_set():
            now = planner.client.now_ns()
            msg = Odometry()
            msg.header = Header(frame_id='map', stamp=conv.time_from_ns(now))
            msg.child_frame_id = 'base_link'
            msg.pose.pose = pose_msg(manual(now), 'map', heading.as_quat()).pose
            body = heading.inv().apply(velocity)
            msg.twist.twist.linear.x, msg.twist.twist.linear.y = float(body[0]), float(body[1])
            msg.twist.twist.linear.z = float(body[2])
            planner.publish('odom', msg)
            time.sleep(ODOMETRY_PERIOD_S)
    stack.stop()
    sender = threading.Thread(target=stream, daemon=True)
    sender.start()
    try:
        time.sleep(0.5)
        mark = planner.diagnostics.mark()
        planner.publish('goal_pose', pose_msg([6.0, 6.0, 6.0]))
        values = wait_plan(planner, mark, 'new goal')
        assert values['takeover'] == 'odometry', values
        new = stack.reference(values['_stamp'])
        assert np.linalg.norm(new.velocities[0] - velocity) <= VELOCITY_TOL, new.velocities[0]
        assert np.linalg.norm(new.accelerations[0]) <= ACCEL_TOL, new.accelerations[0]
        # Its position is the odometry's moved on at its velocity to the stamp (the transport
        # delay of the odometry is the only error).
        assert np.linalg.norm(new.positions[0] - manual(new.stamp_ns)) <= 0.05
    finally:
        stop.set()
        sender.join(5.0)
