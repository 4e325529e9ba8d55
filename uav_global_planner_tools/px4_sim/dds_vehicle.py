"""The simulated vehicle as PX4's uXRCE-DDS bridge shows it: ``px4_msgs`` on ``/fmu/...``.

Run it as a process of its own::

    python -m uav_global_planner_tools.px4_sim.dds_vehicle --start X Y Z [--yaw RAD]
        [--rate 125] [--namespace NS] [--track FILE] [--no-auto-offboard]

``--start`` is the map-frame (ENU) position it hovers at; the map origin is its NED local
origin. It speaks exactly the topics and QoS of PX4 v1.16's bridge
(:mod:`uav_global_planner.ros.px4_names`):

- reads ``/fmu/in/offboard_control_mode`` (the heartbeat), ``/fmu/in/trajectory_setpoint``
  (NED) and ``/fmu/in/vehicle_command`` (``DO_SET_MODE`` to offboard, ``ARM_DISARM``, answered
  on ``/fmu/out/vehicle_command_ack``), with the bridge's reader QoS (best effort, volatile);
- publishes ``/fmu/out/vehicle_odometry`` (NED position and velocity, FRD body attitude and
  rates) every physics step, so at ``--rate`` (>= 100 Hz), and
  ``/fmu/out/vehicle_status_v1`` at 5 Hz (arming state, nav state: ``OFFBOARD`` or
  ``AUTO_LOITER`` when holding), with the bridge's writer QoS (best effort, transient local).

The offboard logic and the physics are those of
:class:`~uav_global_planner_tools.px4_sim.vehicle.SimulatedVehicle`.
It prints :data:`READY_TEXT` once its topics exist and a summary line (steps, odometry rate,
real-time overruns) when stopped with SIGINT.
"""

import argparse
import math
import signal
import sys
import threading
import time
from typing import Dict, List, Optional

import numpy as np
from px4_msgs.msg import (OffboardControlMode, TrajectorySetpoint, VehicleCommand,
                          VehicleCommandAck, VehicleOdometry, VehicleStatus)
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args, try_shutdown

from uav_global_planner.ros import px4_names
from uav_global_planner_tools.px4_sim.vehicle import run_realtime, SimulatedVehicle

#: Printed once the vehicle's topics exist.
READY_TEXT = 'simulated px4 vehicle ready'

#: Node name.
NODE_NAME = 'px4_sim'

#: PX4's custom main mode "offboard" (``px4_custom_mode.h``), param2 of ``DO_SET_MODE``.
CUSTOM_MAIN_MODE_OFFBOARD = 6

#: VehicleStatus rate [Hz], as PX4's bridge limits it.
STATUS_RATE_HZ = 5.0


class DdsVehicle:
    """The node's publishers and subscriptions around one :class:`SimulatedVehicle`."""

    def __init__(self, node, sim: SimulatedVehicle, namespace: str = '') -> None:
        self.node = node
        self.sim = sim
        self._lock = threading.Lock()
        self._boot = time.monotonic()
        topic = px4_names.px4_topic
        reader, writer = px4_names.PX4_BRIDGE_READER_QOS, px4_names.PX4_BRIDGE_WRITER_QOS
        self.odometry_pub = node.create_publisher(
            VehicleOdometry, topic(px4_names.VEHICLE_ODOMETRY, namespace), writer)
        self.status_pub = node.create_publisher(
            VehicleStatus, topic(px4_names.VEHICLE_STATUS, namespace), writer)
        self.ack_pub = node.create_publisher(
            VehicleCommandAck, topic(px4_names.VEHICLE_COMMAND_ACK, namespace), writer)
        node.create_subscription(OffboardControlMode,
                                 topic(px4_names.OFFBOARD_CONTROL_MODE, namespace),
                                 self._heartbeat, reader)
        node.create_subscription(TrajectorySetpoint,
                                 topic(px4_names.TRAJECTORY_SETPOINT, namespace),
                                 self._setpoint, reader)
        node.create_subscription(VehicleCommand, topic(px4_names.VEHICLE_COMMAND, namespace),
                                 self._command, reader)
        self._next_status_s = 0.0
        self.odometry_sent = 0

    def _timestamp_us(self, now_s: float) -> int:
        return max(0, int((now_s - self._boot) * 1e6))

    def _heartbeat(self, msg: OffboardControlMode) -> None:
        controls = bool(msg.position or msg.velocity or msg.acceleration or msg.attitude
                        or msg.body_rate or msg.thrust_and_torque or msg.direct_actuator)
        with self._lock:
            self.sim.receive_heartbeat(time.monotonic(), controls)

    def _setpoint(self, msg: TrajectorySetpoint) -> None:
        with self._lock:
            self.sim.receive_setpoint(time.monotonic(), msg.position, msg.velocity,
                                      msg.acceleration, msg.jerk, msg.yaw, msg.yawspeed)

    def _command(self, msg: VehicleCommand) -> None:
        now = time.monotonic()
        with self._lock:
            if msg.command == VehicleCommand.VEHICLE_CMD_DO_SET_MODE:
                wanted = int(round(msg.param2)) == CUSTOM_MAIN_MODE_OFFBOARD
                accepted = wanted and self.sim.request_offboard(now)
            elif msg.command == VehicleCommand.VEHICLE_CMD_COMPONENT_ARM_DISARM:
                accepted = self.sim.request_arm(msg.param1 > 0.5)
            else:
                self.sim.commands_received += 1
                accepted = False
        self.node.get_logger().info(f'vehicle command {msg.command} '
                                    f'{"accepted" if accepted else "refused"}')
        ack = VehicleCommandAck()
        ack.timestamp = self._timestamp_us(now)
        ack.command = msg.command
        ack.result = (VehicleCommandAck.VEHICLE_CMD_RESULT_ACCEPTED if accepted
                      else VehicleCommandAck.VEHICLE_CMD_RESULT_TEMPORARILY_REJECTED)
        ack.target_system, ack.target_component = msg.source_system, msg.source_component
        self.ack_pub.publish(ack)

    def step(self, now_s: float) -> None:
        """One physics step, then its odometry (and the status when due)."""
        with self._lock:
            self.sim.step(now_s)
            odometry = self.sim.odometry_ned()
            offboard = self.sim.in_offboard
            nav_state = self.sim.nav_state
        stamp = self._timestamp_us(now_s)
        msg = VehicleOdometry()
        msg.timestamp = msg.timestamp_sample = stamp
        msg.pose_frame = VehicleOdometry.POSE_FRAME_NED
        msg.position = odometry['position'].astype(np.float32)
        msg.q = odometry['q'].astype(np.float32)
        msg.velocity_frame = VehicleOdometry.VELOCITY_FRAME_NED
        msg.velocity = odometry['velocity'].astype(np.float32)
        msg.angular_velocity = odometry['angular_velocity'].astype(np.float32)
        msg.position_variance = np.full(3, 1e-4, dtype=np.float32)
        msg.orientation_variance = np.full(3, 1e-6, dtype=np.float32)
        msg.velocity_variance = np.full(3, 1e-4, dtype=np.float32)
        self.odometry_pub.publish(msg)
        self.odometry_sent += 1
        if now_s >= self._next_status_s:
            self._next_status_s = now_s + 1.0 / STATUS_RATE_HZ
            status = VehicleStatus()
            status.timestamp = stamp
            status.arming_state = (VehicleStatus.ARMING_STATE_ARMED if self.sim.armed
                                   else VehicleStatus.ARMING_STATE_DISARMED)
            status.nav_state = nav_state
            status.nav_state_user_intention = (VehicleStatus.NAVIGATION_STATE_OFFBOARD
                                               if offboard else nav_state)
            status.vehicle_type = VehicleStatus.VEHICLE_TYPE_ROTARY_WING
            status.system_type = 2      # MAV_TYPE_QUADROTOR
            status.system_id, status.component_id = 1, 1
            status.pre_flight_checks_pass = True
            self.status_pub.publish(status)


def parse_args(argv: Optional[List[str]] = None) -> argparse.Namespace:
    """Command-line options (ROS arguments removed)."""
    parser = argparse.ArgumentParser(
        description='A simulated PX4 vehicle on the uXRCE-DDS topics (RotorPy, real time).')
    parser.add_argument('--start', type=float, nargs=3, required=True, metavar=('X', 'Y', 'Z'),
                        help='hover position at start, map frame ENU [m]')
    parser.add_argument('--yaw', type=float, default=0.0, help='heading at start, ENU [rad]')
    parser.add_argument('--rate', type=float, default=125.0,
                        help='physics and odometry rate [Hz] (default 125)')
    parser.add_argument('--namespace', default='', help="the bridge's namespace (default none)")
    parser.add_argument('--track', default=None, help='JSON-lines track file to write')
    parser.add_argument('--no-auto-offboard', action='store_true',
                        help='enter offboard only on VEHICLE_CMD_DO_SET_MODE')
    parser.add_argument('--stream-timeout', type=float, default=0.5,
                        help='offboard heartbeat gap that triggers the hold [s] (default 0.5)')
    return parser.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> int:
    """Run the vehicle until SIGINT; exit status 0, or 2 for bad options."""
    args = remove_ros_args(sys.argv if argv is None else argv)[1:]
    options = parse_args(args)
    if not (math.isfinite(options.rate) and options.rate >= 100.0):
        print(f'--rate {options.rate}: must be >= 100 Hz (PX4 streams odometry at 100 Hz)',
              file=sys.stderr)
        return 2
    track = open(options.track, 'w', encoding='utf-8') if options.track else None
    try:
        sim = SimulatedVehicle(options.start, options.yaw, options.rate,
                               stream_timeout_s=options.stream_timeout,
                               auto_offboard=not options.no_auto_offboard, track=track)
    except ValueError as error:
        print(f'px4_sim: {error}', file=sys.stderr)
        return 2
    # SIGINT and SIGTERM stop the physics first, then the node: no publisher outlives its
    # context.
    rclpy.init(args=sys.argv if argv is None else argv,
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(NODE_NAME)
    vehicle = DdsVehicle(node, sim, options.namespace)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    result: Dict[str, float] = {}

    def physics() -> None:
        result.update(run_realtime(sim.dt, vehicle.step, stop.is_set))
        sim.flush()

    thread = threading.Thread(target=physics, daemon=True)
    started = time.monotonic()
    thread.start()
    node.get_logger().info(f'{READY_TEXT}: hovering at {list(options.start)} (ENU), '
                           f'odometry at {options.rate:g} Hz')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass
    finally:
        stop.set()
        thread.join(2.0)
        elapsed = time.monotonic() - started
        print(f'px4_sim: {sim.steps} steps in {elapsed:.1f} s, odometry '
              f'{vehicle.odometry_sent / max(elapsed, 1e-9):.1f} Hz, overruns '
              f'{result.get("overruns", math.nan):.0f}, late max '
              f'{result.get("late_max_s", math.nan):.3f} s, '
              f'setpoints {sim.setpoints_received}, commands {sim.commands_received}',
              flush=True)
        for event in sim.events:
            print(f'px4_sim event: {event}', flush=True)
        executor.shutdown()
        node.destroy_node()
        try_shutdown()
        if track is not None:
            track.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
