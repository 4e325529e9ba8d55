"""The follower's PX4 side over ROS 2 (uXRCE-DDS bridge, ``px4_msgs``): setpoints out, odometry in.

Out, every tick: ``OffboardControlMode`` (position control; the heartbeat offboard mode needs at
>= 2 Hz) and ``TrajectorySetpoint`` (NED position, velocity and acceleration feed-forward,
jerk NaN: not set, heading and yaw rate), as PX4's offboard examples stream them. In:
``VehicleOdometry`` (NED pose, FRD body). Topic names and QoS: :mod:`.px4_names`.

Arming and the switch to offboard mode (``VehicleCommand``) happen only when the node's
``arm_and_offboard`` parameter is true; otherwise this link has no ``VehicleCommand`` publisher
at all.
"""

import math
from typing import Callable, Optional

import numpy as np
from px4_msgs.msg import (OffboardControlMode, TrajectorySetpoint, VehicleCommand,
                          VehicleOdometry, VehicleStatus)
from rclpy.node import Node

from uav_global_planner.core import frames
from uav_global_planner.core.follower import Command, VehicleState
from uav_global_planner.ros import px4_names

#: PX4's custom main mode "offboard" (``px4_custom_mode.h``), param2 of ``DO_SET_MODE``.
PX4_CUSTOM_MAIN_MODE_OFFBOARD = 6.0

#: Setpoints streamed before the switch to offboard is asked for (PX4 refuses it without).
_SETPOINTS_BEFORE_OFFBOARD = 10


def state_from_vehicle_odometry(msg: VehicleOdometry) -> VehicleState:
    """A ``VehicleOdometry`` as a :class:`VehicleState` (ENU map frame, FLU body), or refused.

    Only ``POSE_FRAME_NED`` is the map frame; ``POSE_FRAME_FRD`` has an arbitrary heading
    reference and is refused, as is an unknown frame.
    """
    position = frames.ned_to_enu(np.asarray(msg.position, dtype=np.float64))
    if msg.pose_frame != VehicleOdometry.POSE_FRAME_NED:
        names = {VehicleOdometry.POSE_FRAME_FRD: 'POSE_FRAME_FRD (arbitrary heading reference)',
                 VehicleOdometry.POSE_FRAME_UNKNOWN: 'POSE_FRAME_UNKNOWN'}
        name = names.get(msg.pose_frame, str(msg.pose_frame))
        return VehicleState(position=position, refused=(
            f'VehicleOdometry pose_frame {name} is not POSE_FRAME_NED: not the map frame'))
    q = np.asarray(msg.q, dtype=np.float64)
    orientation = (frames.quaternion_ned_frd_to_enu_flu(q) if np.all(np.isfinite(q))
                   and abs(float(np.linalg.norm(q)) - 1.0) < 1e-3 else None)
    velocity: Optional[np.ndarray] = None
    raw = np.asarray(msg.velocity, dtype=np.float64)
    if np.all(np.isfinite(raw)):
        if msg.velocity_frame == VehicleOdometry.VELOCITY_FRAME_NED:
            velocity = frames.ned_to_enu(raw)
        elif (msg.velocity_frame == VehicleOdometry.VELOCITY_FRAME_BODY_FRD
              and orientation is not None):
            velocity = frames.rotate_xyzw(orientation, frames.frd_to_flu(raw))
    rates = np.asarray(msg.angular_velocity, dtype=np.float64)
    return VehicleState(position=position, orientation=orientation, velocity=velocity,
                        angular_velocity=(frames.frd_to_flu(rates)
                                          if np.all(np.isfinite(rates)) else None))


def trajectory_setpoint(command: Command, timestamp_us: int) -> TrajectorySetpoint:
    """The ``TrajectorySetpoint`` (NED) of a follower command (ENU)."""
    sp = command.setpoint
    msg = TrajectorySetpoint()
    msg.timestamp = int(timestamp_us)
    msg.position = frames.enu_to_ned(sp.position).astype(np.float32)
    msg.velocity = frames.enu_to_ned(sp.velocity).astype(np.float32)
    msg.acceleration = frames.enu_to_ned(sp.acceleration).astype(np.float32)
    msg.jerk = frames.enu_to_ned(sp.jerk).astype(np.float32)
    msg.yaw = float(frames.yaw_enu_to_ned(sp.yaw))
    msg.yawspeed = float(frames.yaw_rate_enu_to_ned(sp.yaw_rate)) if math.isfinite(
        sp.yaw_rate) else float('nan')
    return msg


class Px4Link:
    """Publishers and subscriptions of one PX4 vehicle on ``node``.

    Parameters
    ----------
    node : rclpy.node.Node
    on_state : callable
        Called with each :class:`VehicleState` from ``VehicleOdometry`` (executor thread).
    namespace : str
        The bridge's namespace ('' = ``/fmu/...``).
    arm_and_offboard : bool
        Ask PX4 to switch to offboard and arm (``VehicleCommand``) once setpoints stream.
    """

    name = 'px4'

    def __init__(self, node: Node, on_state: Callable[[VehicleState], None],
                 namespace: str = '', arm_and_offboard: bool = False) -> None:
        self._node = node
        self._on_state = on_state
        topic = px4_names.px4_topic
        self._setpoint_pub = node.create_publisher(
            TrajectorySetpoint, topic(px4_names.TRAJECTORY_SETPOINT, namespace),
            px4_names.PX4_IN_QOS)
        self._mode_pub = node.create_publisher(
            OffboardControlMode, topic(px4_names.OFFBOARD_CONTROL_MODE, namespace),
            px4_names.PX4_IN_QOS)
        node.create_subscription(VehicleOdometry, topic(px4_names.VEHICLE_ODOMETRY, namespace),
                                 self._odometry, px4_names.PX4_OUT_QOS)
        self._command_pub = None
        self.armed_offboard = False
        self._sent = 0
        self._last_request_ns = 0
        if arm_and_offboard:
            self._command_pub = node.create_publisher(
                VehicleCommand, topic(px4_names.VEHICLE_COMMAND, namespace),
                px4_names.PX4_IN_QOS)
            node.create_subscription(VehicleStatus, topic(px4_names.VEHICLE_STATUS, namespace),
                                     self._status, px4_names.PX4_OUT_QOS)

    def _odometry(self, msg: VehicleOdometry) -> None:
        self._on_state(state_from_vehicle_odometry(msg))

    def _status(self, msg: VehicleStatus) -> None:
        self.armed_offboard = (msg.arming_state == VehicleStatus.ARMING_STATE_ARMED
                               and msg.nav_state == VehicleStatus.NAVIGATION_STATE_OFFBOARD)

    def send(self, command: Command, now_ns: int) -> None:
        """Publish the heartbeat and the setpoint of ``command``."""
        timestamp_us = now_ns // 1000
        mode = OffboardControlMode()
        mode.timestamp = timestamp_us
        mode.position = True
        self._mode_pub.publish(mode)
        self._setpoint_pub.publish(trajectory_setpoint(command, timestamp_us))
        self._sent += 1
        if (self._command_pub is not None and not self.armed_offboard
                and self._sent >= _SETPOINTS_BEFORE_OFFBOARD
                and now_ns - self._last_request_ns >= 1_000_000_000):
            self._last_request_ns = now_ns
            self._vehicle_command(VehicleCommand.VEHICLE_CMD_DO_SET_MODE, timestamp_us,
                                  1.0, PX4_CUSTOM_MAIN_MODE_OFFBOARD)
            self._vehicle_command(VehicleCommand.VEHICLE_CMD_COMPONENT_ARM_DISARM, timestamp_us,
                                  1.0)
            self._node.get_logger().info('asked PX4 for offboard mode and to arm '
                                         '(arm_and_offboard is true)')

    def _vehicle_command(self, command: int, timestamp_us: int, param1: float = 0.0,
                         param2: float = 0.0) -> None:
        assert self._command_pub is not None
        msg = VehicleCommand()
        msg.timestamp = timestamp_us
        msg.command = command
        msg.param1, msg.param2 = float(param1), float(param2)
        msg.target_system, msg.target_component = 1, 1
        msg.source_system, msg.source_component = 1, 1
        msg.from_external = True
        self._command_pub.publish(msg)

    def close(self) -> None:
        """Nothing to release beyond the node's own entities."""
