"""The px4_msgs messages this environment provides are PX4 v1.16's, hash for hash.

In the project's venv they come from ``interfaces/px4_msgs`` (PX4's own .msg files of px4_msgs
tag ``v1.16.2``, whose message definitions equal those of ``v1.16.0`` and ``v1.16.1``), built by
``scripts/build_interfaces.sh``; in a PX4 workspace from PX4's px4_msgs. A ROS 2 Jazzy node
(and PX4's uXRCE-DDS agent or Zenoh bridge) only matches a topic when the RIHS01 type hashes
agree, so the compiled C type support is asked for its hashes and they are compared with those of
public builds of PX4's px4_msgs.

Where the reference hashes come from (transcribed by hand):

- every value below: the generated C sources of px4_msgs in a public colcon workspace built
  against ROS 2 Jazzy, yubinkim0/common_packages, commit
  ffe7ccd92141b9c8bb6a3afc35943df6e765e50a,
  ``build_jazzy/px4_msgs/rosidl_generator_c/px4_msgs/msg/detail/<type>__description.c`` (the
  ``*_get_type_hash`` byte arrays). Its VehicleStatus source text carries
  ``MESSAGE_VERSION = 1`` and the field list of PX4 v1.16, which differs from v1.15's;
- VehicleStatus again: PX4's own documentation, PX4/PX4-Autopilot
  ``docs/en/middleware/zenoh.md`` (commit 0090c24b995f48ca801625665e019e1bc2745306), whose
  ``ros2 topic info -v /fmu/out/vehicle_status`` output shows the hash PX4's firmware itself
  announces for the type.

Of the messages used, only VehicleStatus and VehicleLocalPosition changed their fields between
PX4 v1.15 and v1.16; the others have had the same fields from v1.15 to v1.17, so their hashes
are those of every release in that range.
"""

import re
from typing import Dict

from helpers.interface_packages import assert_build_is_current, hash_differences
import pytest
from rclpy.qos import qos_check_compatible, QoSCompatibility

from uav_global_planner.ros import px4_names

try:
    import px4_msgs
    from px4_msgs.msg import (OffboardControlMode, TrajectorySetpoint, VehicleCommand,
                              VehicleCommandAck, VehicleLocalPosition, VehicleOdometry,
                              VehicleStatus)
except ImportError as error:  # pragma: no cover - the message is the point
    raise ImportError(
        f'px4_msgs is not importable ({error}): in the venv, scripts/venv.sh builds it with '
        'scripts/build_interfaces.sh; in a ROS workspace, build px4_msgs release/1.16'
    ) from None

#: RIHS01 hashes of PX4 v1.16's px4_msgs (see above).
PX4_V1_16_TYPE_HASHES: Dict[str, str] = {
    'px4_msgs/msg/OffboardControlMode':
        'RIHS01_e87463f252f320d2f197d1feadd643b8645e5ef53a2b158dccfdf11372e00f9f',
    'px4_msgs/msg/TrajectorySetpoint':
        'RIHS01_9a7deb0cb7db5e52b441169a284b90188c4efdf06b302d55cb1db33ca0358c1a',
    'px4_msgs/msg/VehicleCommand':
        'RIHS01_1f0ab537807e2e20e04826633ea2c52e5431bea8eb0187152ff23bd07f1dd30b',
    'px4_msgs/msg/VehicleCommandAck':
        'RIHS01_36038d69f9db90980fb8fe154f27f22dffed0c35e530b32413cf0456aa8a29e2',
    'px4_msgs/msg/VehicleLocalPosition':
        'RIHS01_690ad535169297241c696494adbd98bbdc45566645026fe7963513a29a1bf144',
    'px4_msgs/msg/VehicleOdometry':
        'RIHS01_4295b96ad312084aa35c84bdcec65ba2f57eb4f6a293d57d52d95acbe99ff817',
    'px4_msgs/msg/VehicleStatus':
        'RIHS01_828bddbb7d4c2aa6ad93757955f6893be1ec5d8f11885ec7715bcdd76b5226c9',
}


def test_built_message_hashes_equal_px4_v1_16():
    wrong = hash_differences(px4_msgs, PX4_V1_16_TYPE_HASHES)
    assert not wrong, f'type hashes differ from PX4 v1.16 (built, expected): {wrong}'


def test_setpoint_and_odometry_fields_are_px4s():
    assert TrajectorySetpoint.get_fields_and_field_types() == {
        'timestamp': 'uint64', 'position': 'float[3]', 'velocity': 'float[3]',
        'acceleration': 'float[3]', 'jerk': 'float[3]', 'yaw': 'float', 'yawspeed': 'float'}
    fields = VehicleOdometry.get_fields_and_field_types()
    assert list(fields)[:6] == ['timestamp', 'timestamp_sample', 'pose_frame', 'position', 'q',
                                'velocity_frame']
    # Constants are not part of the type hash, so the frames the follower relies on are checked.
    assert (VehicleOdometry.POSE_FRAME_NED, VehicleOdometry.VELOCITY_FRAME_NED) == (1, 1)
    assert VehicleStatus.NAVIGATION_STATE_OFFBOARD == 14
    assert VehicleStatus.ARMING_STATE_ARMED == 2
    assert VehicleCommand.VEHICLE_CMD_COMPONENT_ARM_DISARM == 400
    assert VehicleCommand.VEHICLE_CMD_DO_SET_MODE == 176


def test_topic_names_carry_the_message_versions():
    # PX4 v1.16 names a topic <name>_v<N> when its message has MESSAGE_VERSION N > 0.
    assert VehicleStatus.MESSAGE_VERSION == 1
    assert px4_names.VEHICLE_STATUS.endswith(f'_v{VehicleStatus.MESSAGE_VERSION}')
    for topic, message in ((px4_names.VEHICLE_ODOMETRY, VehicleOdometry),
                           (px4_names.VEHICLE_LOCAL_POSITION, VehicleLocalPosition),
                           (px4_names.VEHICLE_COMMAND_ACK, VehicleCommandAck),
                           (px4_names.TRAJECTORY_SETPOINT, TrajectorySetpoint),
                           (px4_names.VEHICLE_COMMAND, VehicleCommand)):
        assert message.MESSAGE_VERSION == 0
        assert re.search(r'_v\d+$', topic) is None, topic
    assert not hasattr(OffboardControlMode, 'MESSAGE_VERSION')  # not versioned in v1.16


def test_qos_profiles_connect_to_px4s_bridge():
    # Subscriptions to /fmu/out against what PX4's bridge offers, and publishers to /fmu/in
    # against what it requests.
    # (A WARNING only says liveliness is left to the middleware's default on both sides.)
    out = qos_check_compatible(px4_names.PX4_BRIDGE_WRITER_QOS, px4_names.PX4_OUT_QOS)
    assert out[0] != QoSCompatibility.ERROR, out
    into = qos_check_compatible(px4_names.PX4_IN_QOS, px4_names.PX4_BRIDGE_READER_QOS)
    assert into[0] != QoSCompatibility.ERROR, into
    # The reason for best effort: a reliable subscription never hears PX4.
    from uav_global_planner.ros.qos import keep_last
    refused = qos_check_compatible(px4_names.PX4_BRIDGE_WRITER_QOS, keep_last(5))
    assert refused[0] == QoSCompatibility.ERROR


def test_namespaced_topics():
    assert px4_names.px4_topic(px4_names.VEHICLE_ODOMETRY, 'px4_1') == (
        '/px4_1/fmu/out/vehicle_odometry')
    assert px4_names.px4_topic(px4_names.TRAJECTORY_SETPOINT) == '/fmu/in/trajectory_setpoint'
    with pytest.raises(ValueError, match='namespace'):
        px4_names.px4_topic(px4_names.VEHICLE_ODOMETRY, 'bad name')


def test_build_script_returns_at_once_when_nothing_changed():
    assert_build_is_current('px4_msgs')
