"""The setpoint follower node in a real process, over real topics (PX4) and real UDP (MAVLink).

The test plays the vehicle: it publishes ``VehicleOdometry`` as PX4's bridge does (NED, best
effort) or answers over MAVLink with ``LOCAL_POSITION_NED`` / ``ODOMETRY``, and it plays the
planner by publishing ``plan`` and ``trajectory`` messages as the planner node writes them
(:func:`uav_global_planner.ros.conversions.plan_to_trajectory` of a plan).
"""

from contextlib import contextmanager
import math
import socket
import threading
import time
from typing import Iterator, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry, Path
import numpy as np
from px4_msgs.msg import TrajectorySetpoint, VehicleCommand, VehicleOdometry
from pymavlink.dialects.v20 import common as mavlink2
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from ros_harness import (assert_clean_exit, LATCHED_QOS, MONITOR_QOS, NodeProcess,
                         ros_environment, RosClient, STARTUP_TIMEOUT_S, unique_domain_id,
                         wait_until)
from uav_global_planner.core import frames
from uav_global_planner.core.result import PlanResult, Trajectory
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros import px4_names
from uav_global_planner.ros.follower_node import NODE_MODULE, plan_from_message, READY_TEXT
from uav_global_planner.ros.qos import DIAGNOSTICS_QOS
from uav_global_planner.ros.trajectory_reader import read_path_header, read_trajectory

BOUNDS = {'bounds.min': [-10.0, -10.0, 0.0], 'bounds.max': [10.0, 10.0, 15.0]}


def line_plan(start, velocity, duration=6.0, period=0.05) -> PlanResult:
    """A straight plan at constant velocity (ENU), as a planner result."""
    times = np.arange(0.0, duration + 1e-9, period)
    positions = np.asarray(start) + times[:, None] * np.asarray(velocity)
    velocities = np.tile(np.asarray(velocity, dtype=float), (len(times), 1))
    yaw = math.atan2(velocity[1], velocity[0])
    trajectory = Trajectory(times=times, positions=positions, velocities=velocities,
                            accelerations=np.zeros_like(positions), yaws=np.full(len(times), yaw),
                            yaw_rates=np.zeros(len(times)))
    return PlanResult(status=PlanStatus.OK, message='', algorithm='test', start=positions[0],
                      goal=positions[-1], path=positions[[0, -1]], trajectory=trajectory)


def follower_command(parameters, mavlink=None):
    import sys
    command = [sys.executable, '-m', NODE_MODULE]
    if mavlink:
        command += ['--mavlink', mavlink]
    command.append('--ros-args')
    for name, value in parameters.items():
        text = (('[' + ', '.join(repr(float(v)) for v in value) + ']')
                if isinstance(value, list) else str(value).lower() if isinstance(value, bool)
                else repr(value) if isinstance(value, float) else str(value))
        command += ['-p', f'{name}:={text}']
    return command


@contextmanager
def running_follower(parameters, client_name: str, domain: Optional[int] = None
                     ) -> Iterator[Tuple[NodeProcess, RosClient]]:
    """A follower node (PX4 topics), ready, and a client in its domain; both are ended on
    leaving."""
    domain = unique_domain_id() if domain is None else domain
    node = NodeProcess(follower_command(parameters), ros_environment(domain))
    client = RosClient(domain, client_name)
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        yield node, client
    finally:
        client.close()
        node.kill()


def record_setpoints(client: RosClient):
    """A recording of the PX4 setpoints the follower sends."""
    return client.record(TrajectorySetpoint, px4_names.TRAJECTORY_SETPOINT,
                         px4_names.PX4_BRIDGE_READER_QOS)


class Planner:
    """The test's stand-in for the planner's latched outputs."""

    def __init__(self, client: RosClient) -> None:
        self.client = client
        self.plan = client.node.create_publisher(Path, 'plan', LATCHED_QOS)
        self.trajectory = client.node.create_publisher(MultiDOFJointTrajectory, 'trajectory',
                                                       LATCHED_QOS)

    def publish(self, result: PlanResult, stamp_ns: int) -> None:
        self.plan.publish(conv.plan_to_path(result, 'map', stamp_ns))
        self.trajectory.publish(conv.plan_to_trajectory(result, 'map', stamp_ns))

    def withdraw(self) -> float:
        stamp_ns = self.client.now_ns()
        sent = time.monotonic()
        self.plan.publish(conv.points_to_path(np.empty((0, 3)), 'map', stamp_ns))
        self.trajectory.publish(conv.empty_trajectory('map', stamp_ns))
        return sent


class Px4Vehicle:
    """Publishes VehicleOdometry (NED) at 50 Hz from a thread, as PX4's bridge would."""

    def __init__(self, client: RosClient, position_enu) -> None:
        self.pub = client.node.create_publisher(VehicleOdometry, px4_names.VEHICLE_ODOMETRY,
                                                px4_names.PX4_BRIDGE_WRITER_QOS)
        self.position_enu = np.asarray(position_enu, dtype=float)
        self.velocity_enu = np.zeros(3)
        self.pose_frame = VehicleOdometry.POSE_FRAME_NED
        self.running = True
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop:
            if self.running:
                msg = VehicleOdometry()
                msg.pose_frame = self.pose_frame
                msg.position = frames.enu_to_ned(self.position_enu).astype(np.float32)
                msg.q = np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32)
                msg.velocity_frame = VehicleOdometry.VELOCITY_FRAME_NED
                msg.velocity = frames.enu_to_ned(self.velocity_enu).astype(np.float32)
                self.pub.publish(msg)
            time.sleep(0.02)

    def close(self) -> None:
        self._stop = True
        self._thread.join(2.0)


@pytest.mark.parametrize('frame', ['map', 'a', 'uav1/odom', 'abcd'])
def test_bytes_read_as_rclpy_reads_them(frame):
    """The fast reader of the planner's messages agrees with rclpy's objects, value for value
    (the padding of the points depends on the length of the frame id)."""
    result = line_plan([1.0, -2.0, 3.0], [0.3, -0.2, 0.1], duration=7.3)
    data = serialize_message(conv.plan_to_trajectory(result, frame, 1_700_000_000_123_456_789))
    fast = read_trajectory(data)
    slow = plan_from_message(deserialize_message(data, MultiDOFJointTrajectory))
    assert (fast.stamp_ns, fast.frame_id) == (slow.stamp_ns, slow.frame_id)
    for name in ('times', 'positions', 'velocities', 'accelerations', 'yaws', 'yaw_rates'):
        assert np.array_equal(getattr(fast, name), getattr(slow, name)), name
    assert read_trajectory(serialize_message(conv.empty_trajectory(frame, 5))) is None
    path = serialize_message(conv.plan_to_path(result, frame, 1_700_000_000_000_000_007))
    assert read_path_header(path) == (1_700_000_000_000_000_007, False)
    empty = serialize_message(conv.points_to_path(np.empty((0, 3)), frame, 9))
    assert read_path_header(empty) == (9, True)
    # Points of another shape (no accelerations) are left to rclpy.
    msg = conv.plan_to_trajectory(result, frame, 5)
    msg.points[3].accelerations = []
    with pytest.raises(ValueError):
        read_trajectory(serialize_message(msg))


def diag_of(msg: DiagnosticArray):
    for status, values in conv.diagnostic_values(msg):
        if status.name.endswith(': setpoint follower'):
            return status, values
    return None


@pytest.fixture
def px4_follower(tmp_path):
    """A follower process (PX4 transport), the test client, a vehicle and a planner stand-in."""
    fence = tmp_path / 'fence.yaml'
    fence.write_text('geofence:\n  exclusion:\n'
                     '  - {type: box, min: [3.0, -10.0, 0.0], max: [10.0, 10.0, 15.0]}\n')
    with running_follower({**BOUNDS, 'odometry_timeout': 0.5, 'geofence_file': str(fence)},
                          'follower_test') as (node, client):
        setpoints = record_setpoints(client)
        commands = client.record(VehicleCommand, px4_names.VEHICLE_COMMAND,
                                 px4_names.PX4_BRIDGE_READER_QOS)
        odom = client.record(Odometry, 'odom', MONITOR_QOS)
        diagnostics = client.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
        vehicle = Px4Vehicle(client, [0.0, 0.0, 1.0])
        setpoints.wait_for(timeout_s=20.0, what='a first setpoint (a hold where the vehicle is)')
        yield {'node': node, 'client': client, 'setpoints': setpoints, 'commands': commands,
               'odom': odom, 'diagnostics': diagnostics, 'vehicle': vehicle,
               'planner': Planner(client)}
        vehicle.close()
        assert_clean_exit(node, node.stop())


def wait_diag(diagnostics, check, after=0, timeout_s=10.0, what='diagnostics'):
    msg = diagnostics.wait_for(lambda m: diag_of(m) is not None and check(*diag_of(m)),
                               timeout_s, after, what)
    return diag_of(msg)


def test_px4_follows_then_holds_at_once_when_withdrawn_and_never_arms(px4_follower):
    f = px4_follower
    first = f['setpoints'].wait_for(timeout_s=20.0, what='a setpoint')
    # Before any plan: a hold where the vehicle is (ENU (0, 0, 1) is NED (0, 0, -1)).
    assert np.allclose(first.position, [0.0, 0.0, -1.0])
    assert np.allclose(first.velocity, 0.0) and math.isnan(first.yaw)
    back = f['odom'].wait_for(what='odometry for the planner')
    assert back.header.frame_id == 'map' and back.child_frame_id == 'base_link'
    assert back.pose.pose.position.z == pytest.approx(1.0)
    # A plan east at 1 m/s, climbing at 0.5 m/s: NED x grows along north (0), y along east, z
    # falls; the heading 0 (east in ENU) is 90 deg in NED.
    stamp = f['client'].now_ns()
    f['planner'].publish(line_plan([0.0, 0.0, 1.0], [1.0, 0.0, 0.5]), stamp)
    mark = f['setpoints'].mark()
    flying = f['setpoints'].wait_for(lambda m: m.position[1] > 0.5, 10.0, mark, 'flying east')
    assert flying.velocity[1] == pytest.approx(1.0, abs=1e-6)
    assert flying.velocity[2] == pytest.approx(-0.5, abs=1e-6)
    assert flying.yaw == pytest.approx(math.pi / 2, abs=1e-6)
    assert math.isnan(flying.jerk[0])
    # Withdrawn: the setpoint stops at once and stays.
    mark = f['setpoints'].mark()
    f['planner'].withdraw()
    hold = f['setpoints'].wait_for(lambda m: np.allclose(m.velocity, 0.0), 2.0, mark, 'a hold')
    time.sleep(0.5)
    later = f['setpoints'].messages[-10:]
    assert all(np.array_equal(m.position, hold.position) for m in later)
    status, values = wait_diag(f['diagnostics'], lambda s, v: 'plan withdrawn' in s.message)
    assert values['mode'] == 'holding' and int.from_bytes(status.level, 'little') == 2
    # Fence: the exclusion zone from x = 3 m east; a new plan flies into it and stops short.
    f['planner'].publish(line_plan(frames.ned_to_enu(hold.position), [2.0, 0.0, 0.0]),
                         f['client'].now_ns())
    wait_diag(f['diagnostics'], lambda s, v: 'outside the fence' in s.message, timeout_s=10.0)
    time.sleep(0.3)
    assert max(m.position[1] for m in f['setpoints'].messages) < 3.0      # NED y is east
    # The plan stream lost: no publisher of trajectory for plan_timeout (2 s) holds too.
    f['client'].node.destroy_publisher(f['planner'].trajectory)
    wait_diag(f['diagnostics'], lambda s, v: 'plan stream lost' in s.message, timeout_s=10.0)
    # Never armed, never asked for a mode: no command, not even a publisher of them.
    assert f['commands'].messages == []
    assert f['client'].node.count_publishers(px4_names.VEHICLE_COMMAND) == 0


def test_px4_stale_nan_and_out_of_frame_odometry_hold(px4_follower):
    f = px4_follower
    stamp = f['client'].now_ns()
    f['planner'].publish(line_plan([0.0, 0.0, 1.0], [0.5, 0.0, 0.0], duration=30.0), stamp)
    f['setpoints'].wait_for(lambda m: m.velocity[1] > 0.4, 20.0, 0, 'following')
    # Stale: the vehicle stops reporting.
    f['vehicle'].running = False
    mark = f['diagnostics'].mark()
    status, values = wait_diag(f['diagnostics'], lambda s, v: 'odometry stale' in s.message,
                               mark, what='odometry stale')
    assert int.from_bytes(status.level, 'little') == 2 and 'odometry_timeout' in status.message
    setpoint_mark = f['setpoints'].mark()
    time.sleep(0.3)
    held = f['setpoints'].messages[setpoint_mark:]
    assert len(held) >= 10 and all(np.allclose(m.velocity, 0.0) for m in held)
    # NaN odometry: refused, never forwarded to the planner, and the follower holds.
    f['vehicle'].position_enu = np.array([np.nan, 0.0, 1.0])
    f['vehicle'].running = True
    wait_diag(f['diagnostics'], lambda s, v: 'non-finite' in s.message, mark,
              what='NaN refused')
    odom_mark = f['odom'].mark()
    time.sleep(0.3)
    assert f['odom'].messages[odom_mark:] == []
    # An FRD pose frame (arbitrary heading) is not the map frame: refused too.
    f['vehicle'].position_enu = np.array([0.5, 0.0, 1.0])
    f['vehicle'].pose_frame = VehicleOdometry.POSE_FRAME_FRD
    wait_diag(f['diagnostics'], lambda s, v: 'POSE_FRAME_FRD' in s.message, mark,
              what='FRD refused')
    assert f['setpoints'].messages[-1].velocity[1] == 0.0
    assert 'Traceback' not in f['node'].output


def test_bounds_hold_the_setpoints_and_bad_parameters_exit_with_a_reason():
    with running_follower({'bounds.min': [-1.0, -1.0, 0.0], 'bounds.max': [1.0, 1.0, 2.0]},
                          'follower_bounds') as (node, client):
        setpoints = record_setpoints(client)
        vehicle = Px4Vehicle(client, [0.0, 0.0, 1.0])
        setpoints.wait_for(timeout_s=20.0, what='a hold where the vehicle is')
        # Stamped 2 s ahead: the follower takes it up at its stamp, where it starts at the
        # hold (a plan that arrives late under load would already be more than resume_distance
        # away, and rightly not taken up).
        Planner(client).publish(line_plan([0.0, 0.0, 1.0], [2.0, -2.0, 2.0], duration=3.0),
                                client.now_ns() + 2_000_000_000)
        corner = setpoints.wait_for(
            lambda m: np.allclose(frames.ned_to_enu(np.asarray(m.position)), [1.0, -1.0, 2.0]),
            timeout_s=30.0, what='the setpoint clamped into the corner of the bounds')
        assert corner is not None
        positions = np.array([m.position for m in setpoints.messages])
        enu = frames.ned_to_enu(positions)
        assert np.all(enu >= np.array([-1.0, -1.0, 0.0]) - 1e-6)
        assert np.all(enu <= np.array([1.0, 1.0, 2.0]) + 1e-6)
        vehicle.close()
        assert_clean_exit(node, node.stop())
    bad = NodeProcess(follower_command({'bounds.min': [0.0, 0.0, 5.0],
                                        'bounds.max': [1.0, 1.0, 2.0]}),
                      ros_environment(unique_domain_id()))
    assert bad.process.wait(60.0) == 2
    assert 'bounds.min' in bad.output


def _udp_peer():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(('127.0.0.1', 0))
    sock.settimeout(0.1)
    return sock


def test_mavlink_streams_local_ned_and_holds_when_withdrawn():
    sock = _udp_peer()
    port = sock.getsockname()[1]
    domain = unique_domain_id()
    node = NodeProcess(follower_command(BOUNDS, mavlink=f'udpout:127.0.0.1:{port}'),
                       ros_environment(domain))
    client = RosClient(domain, 'follower_mavlink')
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    received = []
    state = {'stop': False, 'frame': mavlink2.MAV_FRAME_LOCAL_NED, 'peer': None,
             'local': False}

    def vehicle():
        while not state['stop']:
            try:
                data, peer = sock.recvfrom(65535)
                state['peer'] = peer
                for msg in mav.parse_buffer(data) or []:
                    if msg.get_type() == 'SET_POSITION_TARGET_LOCAL_NED':
                        received.append(msg)
            except socket.timeout:
                pass
            if state['peer'] is not None:
                if state['local']:
                    state_msg = mav.local_position_ned_encode(0, 2.0, 0.0, -1.5, 0.0, 0.0, 0.0)
                else:
                    state_msg = mav.odometry_encode(
                        0, state['frame'], mavlink2.MAV_FRAME_BODY_FRD, 0.0, 0.0, -1.0,
                        [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, [math.nan] * 21,
                        [math.nan] * 21)
                out = [mav.heartbeat_encode(mavlink2.MAV_TYPE_QUADROTOR,
                                            mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4),
                       state_msg]
                for msg in out:
                    sock.sendto(msg.pack(mav), state['peer'])
    thread = threading.Thread(target=vehicle, daemon=True)
    thread.start()
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        diagnostics = client.record(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
        odom = client.record(Odometry, 'odom', MONITOR_QOS)
        wait_until(lambda: received, 20.0, 'SET_POSITION_TARGET_LOCAL_NED')
        assert odom.wait_for(what='odom from ODOMETRY').pose.pose.position.z == pytest.approx(1.0)
        first = received[-1]
        assert first.coordinate_frame == mavlink2.MAV_FRAME_LOCAL_NED
        assert first.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
        assert (first.x, first.y, first.z) == pytest.approx((0.0, 0.0, -1.0))
        planner = Planner(client)
        planner.publish(line_plan([0.0, 0.0, 1.0], [0.0, 1.0, 0.0]), client.now_ns())
        # North in ENU is +x in NED, heading 0.
        wait_until(lambda: received[-1].x > 0.5, 10.0, 'flying north')
        assert received[-1].vx == pytest.approx(1.0) and received[-1].yaw == pytest.approx(0.0)
        assert received[-1].type_mask == 0
        planner.withdraw()
        wait_until(lambda: received[-1].vx == 0.0, 2.0, 'a hold')
        x = received[-1].x
        time.sleep(0.3)
        assert received[-1].x == x
        # ODOMETRY in MAV_FRAME_LOCAL_FRD: refused, with a diagnostic naming why.
        state['frame'] = mavlink2.MAV_FRAME_LOCAL_FRD
        wait_diag(diagnostics, lambda s, v: 'MAV_FRAME_LOCAL_NED' in s.message,
                  what='LOCAL_FRD refused')
        # LOCAL_POSITION_NED (2 m north, 1.5 m up) is taken: odometry for the planner again.
        mark = odom.mark()
        state['local'] = True
        back = odom.wait_for(lambda m: m.pose.pose.position.y > 1.0, 10.0, mark,
                             'odom from LOCAL_POSITION_NED')
        assert (back.pose.pose.position.x, back.pose.pose.position.y,
                back.pose.pose.position.z) == pytest.approx((0.0, 2.0, 1.5))
        state['stop'] = True
        assert_clean_exit(node, node.stop())
    finally:
        state['stop'] = True
        thread.join(2.0)
        sock.close()
        client.close()
        node.kill()


def test_real_planner_replan_in_flight_is_flown_without_a_jump():
    """planner_node -> follower -> a vehicle that is where the setpoint is: a new goal in
    flight is planned from the state of the plan in force and stamped ahead; the follower
    switches at that stamp without a jump in position or velocity."""
    from ros_harness import start_planner
    from geometry_msgs.msg import PoseStamped
    domain = unique_domain_id()
    planner = start_planner(domain, parameters={'plan_without_map': True,
                                                'start': [0.0, -8.0, 2.0]})
    node = NodeProcess(follower_command(BOUNDS), ros_environment(domain))
    client = RosClient(domain, 'follower_handover')
    vehicle = None
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        setpoints = record_setpoints(client)
        trajectories = client.record(MultiDOFJointTrajectory, 'trajectory', LATCHED_QOS)
        vehicle = Px4Vehicle(client, [0.0, -8.0, 2.0])

        def track(msg):       # a vehicle exactly where the setpoint is, as fast
            vehicle.position_enu = frames.ned_to_enu(np.asarray(msg.position, dtype=float))
            vehicle.velocity_enu = frames.ned_to_enu(np.asarray(msg.velocity, dtype=float))
        client.node.create_subscription(TrajectorySetpoint, px4_names.TRAJECTORY_SETPOINT,
                                        track, px4_names.PX4_BRIDGE_READER_QOS)
        goal_pub = client.publisher(PoseStamped, 'goal_pose', MONITOR_QOS)

        def goal(position):
            msg = PoseStamped()
            msg.header.frame_id = 'map'
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = position
            msg.pose.orientation.w = 1.0
            goal_pub.publish(msg)
        goal((0.0, 8.0, 2.0))
        trajectories.wait_for(lambda m: len(m.points) > 0, 30.0, what='a plan')
        mark = setpoints.mark()
        setpoints.wait_for(lambda m: m.velocity[0] > 1.0, 20.0, mark, 'flying north')
        replans = trajectories.mark()
        goal((6.0, 6.0, 5.0))
        second = trajectories.wait_for(lambda m: len(m.points) > 0, 30.0, replans,
                                       'the plan of the new goal')
        switch_ns = conv.time_to_ns(second.header.stamp)
        wait_until(lambda: setpoints.messages[-1].timestamp * 1000 > switch_ns + 1e9, 20.0,
                   'setpoints past the switch')
        flown = [m for m in setpoints.messages[mark:]]
        positions = np.array([m.position for m in flown], dtype=float)
        velocities = np.array([m.velocity for m in flown], dtype=float)
        stamps = np.array([m.timestamp for m in flown], dtype=np.int64) * 1000
        # No hold, and no jump: between setpoints (50 Hz; a busy machine may drop or delay
        # some) the setpoint moves no faster than the speed limits (2 m/s horizontal, 1 m/s
        # vertical) allow; the velocity changes smoothly through the switch.
        assert np.all(np.isfinite(positions))
        steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
        dt = np.diff(stamps) * 1e-9
        assert np.all(dt > 0.0)
        excess = steps - np.hypot(2.0, 1.0) * dt
        assert np.max(excess) < 0.02, (np.max(excess), dt[np.argmax(excess)])
        at = int(np.searchsorted(stamps, switch_ns))
        around = slice(max(at - 3, 0), at + 3)
        assert np.max(np.linalg.norm(np.diff(velocities[around], axis=0), axis=1)) < 0.3
        # After the switch the setpoints are the replan's reference at their time.
        times = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                          for p in second.points])
        points = np.array([[p.transforms[0].translation.x, p.transforms[0].translation.y,
                            p.transforms[0].translation.z] for p in second.points])
        later = [conv.time_to_ns(m.header.stamp) for m in trajectories.messages[replans:]
                 if conv.time_to_ns(m.header.stamp) > switch_ns]
        after = (stamps > switch_ns + 100_000_000) & (stamps < min(later, default=2 ** 63 - 1))
        assert np.count_nonzero(after) > 20
        for stamp, position in zip(stamps[after], positions[after]):
            t = (stamp - switch_ns) * 1e-9
            expected = [np.interp(t, times, points[:, k]) for k in range(3)]
            assert np.linalg.norm(frames.ned_to_enu(position) - expected) < 0.05
        vehicle.close()
        vehicle = None
        assert_clean_exit(node, node.stop())
        assert_clean_exit(planner, planner.stop())
    finally:
        if vehicle is not None:
            vehicle.close()
        client.close()
        node.kill()
        planner.kill()


def test_arms_and_asks_for_offboard_only_when_told_and_stops_once_in_it():
    from px4_msgs.msg import VehicleStatus
    domain = unique_domain_id()
    node = NodeProcess(follower_command({**BOUNDS, 'arm_and_offboard': True}),
                       ros_environment(domain))
    client = RosClient(domain, 'follower_arming')
    vehicle = None
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        commands = client.record(VehicleCommand, px4_names.VEHICLE_COMMAND,
                                 px4_names.PX4_BRIDGE_READER_QOS)
        status_pub = client.node.create_publisher(VehicleStatus, px4_names.VEHICLE_STATUS,
                                                  px4_names.PX4_BRIDGE_WRITER_QOS)
        vehicle = Px4Vehicle(client, [0.0, 0.0, 1.0])
        commands.wait_for(lambda m: m.command == VehicleCommand.VEHICLE_CMD_COMPONENT_ARM_DISARM,
                          20.0, what='an arm command')
        modes = [m for m in commands.messages
                 if m.command == VehicleCommand.VEHICLE_CMD_DO_SET_MODE]
        assert modes and modes[0].param1 == 1.0 and modes[0].param2 == 6.0     # PX4 offboard
        arm = [m for m in commands.messages
               if m.command == VehicleCommand.VEHICLE_CMD_COMPONENT_ARM_DISARM][0]
        assert arm.param1 == 1.0 and arm.from_external
        status = VehicleStatus()
        status.arming_state = VehicleStatus.ARMING_STATE_ARMED
        status.nav_state = VehicleStatus.NAVIGATION_STATE_OFFBOARD
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            status_pub.publish(status)
            time.sleep(0.05)
        mark = commands.mark()
        for _ in range(30):
            status_pub.publish(status)
            time.sleep(0.05)
        assert commands.messages[mark:] == []        # in offboard and armed: asks no more
        vehicle.close()
        vehicle = None
        assert_clean_exit(node, node.stop())
    finally:
        if vehicle is not None:
            vehicle.close()
        client.close()
        node.kill()
