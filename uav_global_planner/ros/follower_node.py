"""The setpoint follower node: the planner's plan in force streamed to PX4 or a MAVLink autopilot.

Start (PX4 over uXRCE-DDS, or ``--mavlink udpout:HOST:PORT`` for ArduPilot or MAVSDK peers)::

    setpoint_follower --ros-args --params-file config/planner.yaml
    setpoint_follower --mavlink udpout:127.0.0.1:14550 --ros-args --params-file ...

The planner's ``planner.yaml`` applies to every node (``/**``), so the follower takes the same
``frame_id``, ``bounds`` and ``geofence_file``. Topics (relative, so namespaces work):

===============================  ================================  ============================
name                             type                              notes
===============================  ================================  ============================
``trajectory`` (in)              trajectory_msgs/MultiDOFJoint...  the timed plan (ENU); empty:
                                                                   withdrawn, hold at once
``plan`` (in)                    nav_msgs/Path                     empty: withdrawn
``odom`` (out)                   nav_msgs/Odometry                 the vehicle's odometry, ENU
                                                                   map frame, FLU child
``/diagnostics`` (out)           diagnostic_msgs/DiagnosticArray   following or holding, why
``/fmu/in/trajectory_setpoint``  px4_msgs/TrajectorySetpoint       NED; with
``/fmu/in/offboard_control_mode`` px4_msgs/OffboardControlMode     the offboard heartbeat
``/fmu/out/vehicle_odometry``    px4_msgs/VehicleOdometry          NED/FRD, refused otherwise
===============================  ================================  ============================

Parameters (read at start-up; a change later is refused): ``setpoint_rate`` [Hz] (50),
``odometry_timeout`` [s] (0.5), ``plan_timeout`` [s] (2.0; no ``trajectory`` publisher for this
long holds), ``resume_distance`` [m] (0.5), ``arm_and_offboard`` (false: never arms nor switches
modes), ``px4_namespace`` (''), ``frame_id``, ``bounds.min``/``bounds.max`` [m] and
``geofence_file`` (with ``geofence_floor``, ``geofence_ceiling``, ``geodetic_origin``) as the
planner's, ``mavlink_target_system``/``mavlink_target_component``.

The setpoints run on a thread of their own at ``setpoint_rate`` (absolute schedule, so late ticks
do not accumulate); a withdrawal sends a hold setpoint at once, from the callback that reads
it. The logic is :class:`~uav_global_planner.core.follower.Follower`; ``realtime_priority``
puts the setpoint thread in SCHED_FIFO, which keeps it on time on a busy computer.
"""

import argparse
import math
import os
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry, Path
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.utilities import ok, remove_ros_args
from trajectory_msgs.msg import MultiDOFJointTrajectory

from uav_global_planner.core import frames
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.follower import (Command, Follower, FollowerSettings, NO_PLAN,
                                              PlanSamples,
                                              VehicleState, WAITING, WITHDRAWN)
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import airspace_from_values, describe
from uav_global_planner.ros.node_main import EXIT_BAD_SETTINGS, run_node
from uav_global_planner.ros.qos import DIAGNOSTICS_QOS, keep_last, LATCHED_QOS
from uav_global_planner.ros.trajectory_reader import read_path_header, read_trajectory

#: Name of the node unless remapped.
NODE_NAME = 'setpoint_follower'
#: Module of the node, for ``python -m``.
NODE_MODULE = 'uav_global_planner.ros.follower_node'
#: Logged once the follower streams (the tools and tests wait for it).
READY_TEXT = 'setpoint follower ready'
#: Odometry to the planner: reliable (it connects to best-effort and reliable subscriptions).
ODOM_QOS = keep_last(5)
#: Period of the planner-presence check and of the periodic diagnostics [s].
_PRESENCE_PERIOD_S = 0.2
_DIAGNOSTICS_PERIOD_S = 1.0

#: Parameters: name -> (default, description).
PARAMETERS: Dict[str, Tuple[Any, str]] = {
    'setpoint_rate': (50.0, 'Setpoint stream rate [Hz], 2 to 500.'),
    'odometry_timeout': (0.5, 'Odometry older than this holds [s].'),
    'plan_timeout': (2.0, 'No publisher of trajectory for this long holds [s].'),
    'resume_distance': (0.5, 'A plan is taken up only this close to the setpoint or vehicle '
                        '[m].'),
    'odometry_margin': (5.0, 'Odometry farther outside the bounds is refused [m].'),
    'arm_and_offboard': (False, 'Switch PX4 to offboard and arm it; false: never.'),
    'px4_namespace': ('', 'Namespace of the PX4 bridge (uxrce_dds_client -n).'),
    'realtime_priority': (0, 'SCHED_FIFO priority of the setpoint thread, 1 to 99 (needs '
                          'CAP_SYS_NICE); 0: the default scheduler.'),
    'frame_id': ('map', 'The planner frame (ENU).'),
    'child_frame_id': ('base_link', 'Body frame (FLU) of the odom published for the planner.'),
    'bounds.min': ([-10.0, -10.0, 0.0], 'Map bounds, lower corner [m]: setpoints stay in.'),
    'bounds.max': ([10.0, 10.0, 15.0], 'Map bounds, upper corner [m].'),
    'geofence_file': ('', 'Geofence (as the planner reads it): setpoints stay inside.'),
    'geofence_floor': (0.0, 'Floor of a .plan geofence [m].'),
    'geofence_ceiling': (120.0, 'Ceiling of a .plan geofence [m].'),
    'mavlink_target_system': (1, 'MAVLink autopilot system id (until its HEARTBEAT says).'),
    'mavlink_target_component': (1, 'MAVLink autopilot component id.'),
}


def plan_from_message(msg: MultiDOFJointTrajectory) -> Optional[PlanSamples]:
    """Arrays (ENU) of a ``trajectory`` message; None for an empty one (withdrawn).

    Raises
    ------
    InvalidInputError
        For points without a transform, or non-finite or unordered values.
    """
    points = msg.points
    if not points:
        return None
    count = len(points)
    times = np.empty(count)
    positions = np.empty((count, 3))
    quaternions = np.empty((count, 4))
    velocities = np.zeros((count, 3))
    accelerations = np.zeros((count, 3))
    rates = np.zeros(count)
    for i, point in enumerate(points):
        if not point.transforms:
            raise InvalidInputError(f'trajectory point {i}: no transform')
        t = point.transforms[0]
        times[i] = point.time_from_start.sec + point.time_from_start.nanosec * 1e-9
        positions[i] = (t.translation.x, t.translation.y, t.translation.z)
        quaternions[i] = (t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w)
        if point.velocities:
            v = point.velocities[0]
            velocities[i] = (v.linear.x, v.linear.y, v.linear.z)
            rates[i] = v.angular.z
        if point.accelerations:
            a = point.accelerations[0].linear
            accelerations[i] = (a.x, a.y, a.z)
    qx, qy, qz, qw = quaternions.T
    yaws = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return PlanSamples(stamp_ns=conv.time_to_ns(msg.header.stamp),
                       frame_id=msg.header.frame_id, times=times, positions=positions,
                       velocities=velocities, accelerations=accelerations, yaws=yaws,
                       yaw_rates=rates)


def _corner(value: Any, name: str) -> Tuple[float, float, float]:
    values = [float(v) for v in value]
    if len(values) != 3:
        raise InvalidInputError(f'{name} needs 3 values [m], got {values}')
    return values[0], values[1], values[2]


def odometry_message(state: VehicleState, frame_id: str, child_frame_id: str,
                     stamp_ns: int) -> Odometry:
    """``nav_msgs/Odometry`` (pose in the ENU map frame, twist in the FLU body frame)."""
    msg = Odometry()
    msg.header.frame_id = frame_id
    msg.header.stamp = conv.time_from_ns(stamp_ns)
    msg.child_frame_id = child_frame_id
    p = state.position
    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = (
        float(p[0]), float(p[1]), float(p[2]))
    q = state.orientation if state.orientation is not None else np.array([0.0, 0.0, 0.0, 1.0])
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in q)
    if state.velocity is not None and state.orientation is not None:
        body = frames.rotate_xyzw_inverse(state.orientation, state.velocity)
    else:
        body = np.full(3, np.nan)      # unknown: the planner ignores a non-finite twist
    lin = msg.twist.twist.linear
    lin.x, lin.y, lin.z = (float(v) for v in body)
    if state.angular_velocity is not None:
        ang = msg.twist.twist.angular
        ang.x, ang.y, ang.z = (float(v) for v in state.angular_velocity)
    return msg


class SetpointFollower:
    """The follower node: plan in, setpoints out over PX4 or MAVLink, odometry back.

    Parameters
    ----------
    mavlink_url : str, optional
        ``udpout:HOST:PORT``: the MAVLink transport; None: PX4 over ROS 2.
    **node_options
        Passed to :class:`rclpy.node.Node`.

    Raises
    ------
    InvalidInputError
        For invalid start-up parameters (naming the parameter).
    """

    def __init__(self, mavlink_url: Optional[str] = None, **node_options: Any) -> None:
        self.node = Node(NODE_NAME, **node_options)
        self._log = self.node.get_logger()
        values = self._declare()
        self.rate_hz = float(values['setpoint_rate'])
        if not (math.isfinite(self.rate_hz) and 2.0 <= self.rate_hz <= 500.0):
            raise InvalidInputError(f'setpoint_rate must be 2 to 500 Hz, got {self.rate_hz}')
        settings = FollowerSettings(
            frame_id=str(values['frame_id']),
            bounds_min=_corner(values['bounds.min'], 'bounds.min'),
            bounds_max=_corner(values['bounds.max'], 'bounds.max'),
            odometry_timeout_s=float(values['odometry_timeout']),
            plan_timeout_s=float(values['plan_timeout']),
            resume_distance_m=float(values['resume_distance']),
            odometry_margin_m=float(values['odometry_margin']))
        airspace = airspace_from_values({**values, 'geodetic_origin': values['geodetic_origin']
                                         or None})
        self._fence_text = describe(airspace, str(values['geofence_file']))
        fence: Optional[Callable[[np.ndarray], bool]] = None
        if len(airspace):
            shapes = airspace.with_obstacles()

            def inside(position: np.ndarray) -> bool:
                return bool(shapes.distance(np.asarray(position).reshape(1, 3))[0] > 0.0)
            inside(np.asarray(settings.bounds_min))      # compile before the first setpoint
            fence = inside
        self.settings = settings
        self._priority = int(values['realtime_priority'])
        if not 0 <= self._priority <= 99:
            raise InvalidInputError(f'realtime_priority must be 0 to 99, got {self._priority}')
        self._follower = Follower(settings, fence)
        self._child_frame = str(values['child_frame_id'])
        self._lock = threading.Lock()
        # One tick at a time: the setpoint thread's, or one sent at once on a withdrawal.
        self._tick_lock = threading.Lock()
        self._stop = threading.Event()
        self._odom_pub = self.node.create_publisher(Odometry, 'odom', ODOM_QOS)
        self._diag_pub = self.node.create_publisher(DiagnosticArray, '/diagnostics',
                                                    DIAGNOSTICS_QOS)
        self.node.create_subscription(MultiDOFJointTrajectory, 'trajectory', self._trajectory,
                                      LATCHED_QOS, raw=True)
        # Only the stamp and the emptiness of a plan matter here: read from the bytes.
        self.node.create_subscription(Path, 'plan', self._plan, LATCHED_QOS, raw=True)
        self._trajectory_topic = self.node.resolve_topic_name('trajectory')
        self.transport: Any
        if mavlink_url is not None:
            from uav_global_planner.ros.mavlink_link import MavlinkLink
            self.transport = MavlinkLink(mavlink_url, self._vehicle_state,
                                         int(values['mavlink_target_system']),
                                         int(values['mavlink_target_component']))
            where = f'MAVLink {mavlink_url}'
        else:
            from uav_global_planner.ros.px4_link import Px4Link
            self.transport = Px4Link(self.node, self._vehicle_state,
                                     str(values['px4_namespace']),
                                     bool(values['arm_and_offboard']))
            where = 'PX4 (uXRCE-DDS, px4_msgs)'
        if mavlink_url is not None and values['arm_and_offboard']:
            self._log.warning('arm_and_offboard is for PX4 over ROS 2; over MAVLink the '
                              'follower never arms nor switches modes')
        self.node.add_on_set_parameters_callback(self._refuse_changes)
        self._where = where
        self._last_reasons: Optional[Tuple[str, ...]] = None
        self._last_diag = 0.0
        self._last_refusal = ''
        self.sent = 0
        self.lateness_s: List[float] = []
        self._thread = threading.Thread(target=self._run, name='setpoints', daemon=True)
        self._log.info(f'{READY_TEXT}: {self.rate_hz:g} Hz to {where}, frame '
                       f'{settings.frame_id!r}, bounds {list(settings.bounds_min)} to '
                       f'{list(settings.bounds_max)}, {self._fence_text}')

    def _declare(self) -> Dict[str, Any]:
        values: Dict[str, Any] = {}
        for name, (default, text) in PARAMETERS.items():
            values[name] = self.node.declare_parameter(
                name, default, ParameterDescriptor(description=text)).value
        values['geodetic_origin'] = self.node.declare_parameter(
            'geodetic_origin', None, ParameterDescriptor(
                description='WGS84 origin of the map frame, for a .plan geofence_file.',
                dynamic_typing=True)).value
        return values

    def _refuse_changes(self, parameters: List[Any]) -> SetParametersResult:
        names = ', '.join(p.name for p in parameters)
        return SetParametersResult(successful=False, reason=(
            f'{names}: the follower reads its parameters at start-up only; restart it to '
            'change them (nothing changed)'))

    def start(self) -> None:
        """Start the setpoint thread."""
        self._thread.start()

    def close(self) -> None:
        """Stop the setpoint thread and the transport."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self.transport.close()
        self.node.destroy_node()

    # ------------------------------------------------------------------------------------
    # Inputs (executor thread; the MAVLink reader thread for its vehicle states)
    # ------------------------------------------------------------------------------------

    def _now_ns(self) -> int:
        return self.node.get_clock().now().nanoseconds

    def _trajectory(self, data: bytes) -> None:
        now = self._now_ns()
        try:
            try:
                plan = read_trajectory(data)
            except ValueError:      # not the planner's layout: build the message (slower)
                plan = plan_from_message(deserialize_message(data, MultiDOFJointTrajectory))
            with self._lock:
                self._follower.on_trajectory(plan, now)
        except InvalidInputError as error:
            self._refused('trajectory_refused', f'refused trajectory: {error}')
            return
        if plan is None:
            self._tick()            # hold at once, not at the next tick
            self._log.warning('plan withdrawn (empty trajectory): holding position')

    def _plan(self, data: bytes) -> None:
        try:
            stamp_ns, empty = read_path_header(data)
        except (ValueError, UnicodeDecodeError):
            self._refused('plan_refused', 'refused plan: not a readable nav_msgs/Path')
            return
        with self._lock:
            self._follower.on_plan_path(stamp_ns, empty, self._now_ns())
            withdrawn = empty and WITHDRAWN in self._follower.hold_reasons(self._now_ns())
        if withdrawn:
            self._tick()

    def _vehicle_state(self, state: VehicleState) -> None:
        now = self._now_ns()
        refused = state.refused
        if not refused and not np.all(np.isfinite(state.position)):
            refused = f'non-finite position {np.asarray(state.position).tolist()}'
        with self._lock:
            self._follower.on_odometry(None if refused else state.position, now, refused)
            accepted = not refused and not any(
                r.startswith('odometry refused') for r in self._follower.hold_reasons(now))
        if accepted:
            try:
                self._odom_pub.publish(odometry_message(state, self.settings.frame_id,
                                                        self._child_frame, now))
            except Exception:  # noqa: B902 - MAVLink reader thread while the context shuts down
                if ok(context=self.node.context):
                    raise
                return
        elif refused and refused != self._last_refusal:
            self._refused('odometry_refused', f'refused odometry: {refused}')
        self._last_refusal = refused

    def _refused(self, event: str, text: str) -> None:
        self._log.error(f'{text} (the follower keeps running)')
        self._publish_diagnostics(event, DiagnosticStatus.ERROR, text, {})

    # ------------------------------------------------------------------------------------
    # The setpoint thread
    # ------------------------------------------------------------------------------------

    def _realtime(self) -> None:
        """Put the setpoint thread in SCHED_FIFO at ``realtime_priority`` (when set)."""
        if not self._priority:
            return
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self._priority))
            self._log.info(f'setpoint thread scheduled SCHED_FIFO {self._priority}')
        except (OSError, AttributeError) as error:
            self._log.warning(f'realtime_priority {self._priority}: not granted ({error}); '
                              'the setpoint thread keeps the default scheduler')

    def _run(self) -> None:
        self._realtime()
        period = 1.0 / self.rate_hz
        next_tick = time.monotonic()
        next_presence = next_tick
        while not self._stop.is_set():
            now = time.monotonic()
            if now < next_tick and self._stop.wait(next_tick - now):
                return
            now = time.monotonic()
            self.lateness_s.append(now - next_tick)
            if len(self.lateness_s) > 100_000:
                del self.lateness_s[:50_000]
            next_tick += period
            if now - next_tick > period:          # fell far behind: do not burst
                next_tick = now + period
            try:
                if now >= next_presence:
                    next_presence = now + _PRESENCE_PERIOD_S
                    present = self.node.count_publishers(self._trajectory_topic) > 0
                    with self._lock:
                        self._follower.on_planner_presence(present, self._now_ns())
                self._tick()
            except Exception:  # noqa: B902 - the context shut down under the thread (SIGINT)
                if ok(context=self.node.context):
                    raise
                return

    def _tick(self) -> None:
        """Send the setpoint of now (and the diagnostics when the reasons change)."""
        with self._tick_lock:
            now_ns = self._now_ns()
            with self._lock:
                command = self._follower.step(now_ns)
            if command is None:
                reasons: Tuple[str, ...] = ('no position to hold: no odometry and no setpoint '
                                            'yet',)
            else:
                self.transport.send(command, now_ns)
                self.sent += 1
                reasons = command.reasons
            changed = reasons != self._last_reasons
            if changed or time.monotonic() - self._last_diag >= _DIAGNOSTICS_PERIOD_S:
                self._report(command, reasons, changed)

    def _report(self, command: Optional[Command], reasons: Tuple[str, ...],
                changed: bool) -> None:
        holding = command is None or command.holding
        if changed:
            if holding:
                self._log.warning('holding position: ' + '; '.join(reasons))
            elif self._last_reasons is not None:
                self._log.info('following the plan in force')
        self._last_reasons = reasons
        serious = any(not r.startswith((NO_PLAN, WAITING)) for r in reasons)
        level = (DiagnosticStatus.OK if not holding else
                 DiagnosticStatus.ERROR if serious else DiagnosticStatus.WARN)
        values: Dict[str, object] = {
            'mode': 'holding' if holding else 'following',
            'hold_reasons': '; '.join(reasons), 'transport': self._where,
            'setpoints_sent': self.sent}
        recent = np.asarray(self.lateness_s[-500:]) * 1e3
        if len(recent):
            values['tick_late_p50_ms'] = float(np.percentile(recent, 50))
            values['tick_late_p99_ms'] = float(np.percentile(recent, 99))
            values['tick_late_max_ms'] = float(np.max(recent))
        if command is not None:
            values['setpoint_enu'] = command.setpoint.position
            values['clamped'] = command.clamped
            values['plan_stamp'] = command.plan_stamp_ns if command.plan_stamp_ns else ''
        text = ('holding position: ' + '; '.join(reasons)) if holding else 'following the plan'
        self._publish_diagnostics('hold' if holding else 'follow', level, text, values)

    def _publish_diagnostics(self, event: str, level: bytes, text: str,
                             values: Dict[str, object]) -> None:
        self._last_diag = time.monotonic()
        values = {'event': event, **values}
        self._diag_pub.publish(conv.diagnostic_array(
            self._now_ns(), f'{self.node.get_fully_qualified_name()}: setpoint follower',
            self.node.get_fully_qualified_name(), level, text, values))


def parse_arguments(argv: List[str]) -> argparse.Namespace:
    """The follower's own arguments (ROS arguments removed)."""
    parser = argparse.ArgumentParser(prog='setpoint_follower', description=(
        'Stream the plan in force of the planner as setpoints to PX4 (ROS 2, px4_msgs) or, '
        'with --mavlink, to a MAVLink autopilot.'))
    parser.add_argument('--mavlink', metavar='udpout:HOST:PORT', default=None,
                        help='stream SET_POSITION_TARGET_LOCAL_NED over MAVLink instead of PX4 '
                        'topics')
    return parser.parse_args(argv)


def main(args: Optional[List[str]] = None) -> int:
    """Entry point of ``setpoint_follower``: run until SIGINT/SIGTERM.

    Returns
    -------
    int
        0 after a clean shutdown; :data:`EXIT_BAD_SETTINGS` for invalid parameters or arguments.
    """
    argv = sys.argv if args is None else args
    own = parse_arguments(remove_ros_args(argv)[1:])
    if own.mavlink is not None:
        from uav_global_planner.ros.mavlink_link import parse_url
        try:
            parse_url(own.mavlink)
        except ValueError as error:
            print(f'setpoint_follower: {error}', file=sys.stderr)
            return EXIT_BAD_SETTINGS
    # The setpoint thread must get the interpreter within a millisecond of its tick.
    sys.setswitchinterval(0.0005)
    return run_node('setpoint_follower', lambda: SetpointFollower(own.mavlink), argv)


if __name__ == '__main__':
    sys.exit(main())
