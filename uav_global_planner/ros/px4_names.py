"""Topic names and QoS profiles of PX4's uXRCE-DDS bridge, PX4 v1.16 (px4_msgs ``v1.16.x``).

Everything that talks to PX4 over ROS 2 (the setpoint follower, the simulated vehicle, the
tests) takes its names from here, so the PX4 release is named in one place.

Topic names
-----------
The names are those of the bridge's topic table in PX4 v1.16
(``src/modules/uxrce_dds_client/dds_topics.yaml``) under the default namespace ``/fmu``. PX4
v1.16 introduced message versioning: a message whose definition has a
``MESSAGE_VERSION`` constant greater than 0 is published on ``<topic>_v<version>`` (PX4 user
guide, "PX4 ROS 2 Message Translation Node"; version 0 adds no suffix). In v1.16 only
``VehicleStatus`` is at version 1 among the messages used here, hence
``/fmu/out/vehicle_status_v1``. A vehicle started with a namespace (``uxrce_dds_client start
-n NAME``) prefixes every name: :func:`px4_topic` does that.

QoS
---
PX4's DDS client creates its data writers (``/fmu/out/...``) best effort, transient local,
keep last, and its data readers (``/fmu/in/...``) best effort, volatile. ROS 2 connects a
subscription only when the publisher offers at least what it requests, so:

- a subscription to PX4's outputs must be BEST_EFFORT (a reliable one never connects to PX4)
  and VOLATILE requests less than PX4 offers, so it connects. It is the ``sensor_data``
  profile with depth 5, the one PX4's ROS 2 examples (px4_ros_com) subscribe with
  (:data:`PX4_OUT_QOS`).
- a publisher to PX4's inputs: PX4's best-effort, volatile readers take any publisher. Best
  effort, because a setpoint that arrives late is worse than one lost (the next one comes
  20 ms later, and a reliable writer would resend old setpoints ahead of new ones on a lossy
  link); volatile, because a setpoint must never be replayed to a late-joining reader
  (a restarted bridge would fly to a stale position). Depth 10, as PX4's offboard example
  publishes (:data:`PX4_IN_QOS`).
- :data:`PX4_BRIDGE_WRITER_QOS` is what PX4 itself offers on ``/fmu/out``; a process that
  stands in for PX4 (the simulated vehicle) publishes with it, so that its subscribers see
  exactly PX4's offer.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: The PX4 release whose topic names and message definitions (``interfaces/px4_msgs``) these are.
PX4_RELEASE = 'v1.16'

#: The bridge's default namespace (``uxrce_dds_client start`` without ``-n``).
PX4_NAMESPACE = '/fmu'

# PX4 -> ROS 2 (vehicle state; NED earth frame, FRD body frame).
#: px4_msgs/msg/VehicleOdometry, NED/FRD; MESSAGE_VERSION 0, so no suffix. Up to 100 Hz.
VEHICLE_ODOMETRY = '/fmu/out/vehicle_odometry'
#: px4_msgs/msg/VehicleLocalPosition, NED; MESSAGE_VERSION 0.
VEHICLE_LOCAL_POSITION = '/fmu/out/vehicle_local_position'
#: px4_msgs/msg/VehicleStatus; MESSAGE_VERSION 1 in v1.16, hence the ``_v1`` suffix.
VEHICLE_STATUS = '/fmu/out/vehicle_status_v1'
#: px4_msgs/msg/VehicleCommandAck; MESSAGE_VERSION 0.
VEHICLE_COMMAND_ACK = '/fmu/out/vehicle_command_ack'

# ROS 2 -> PX4 (offboard control; NED).
#: px4_msgs/msg/TrajectorySetpoint, NED; MESSAGE_VERSION 0.
TRAJECTORY_SETPOINT = '/fmu/in/trajectory_setpoint'
#: px4_msgs/msg/OffboardControlMode, the offboard heartbeat (>= 2 Hz); not versioned in v1.16.
OFFBOARD_CONTROL_MODE = '/fmu/in/offboard_control_mode'
#: px4_msgs/msg/VehicleCommand (arm, mode switch); MESSAGE_VERSION 0.
VEHICLE_COMMAND = '/fmu/in/vehicle_command'

#: PX4 drops offboard mode (failsafe) when the OffboardControlMode heartbeat is slower than
#: this, Hz (PX4 user guide, "Offboard Mode": "at least 2 Hz").
OFFBOARD_HEARTBEAT_MIN_RATE = 2.0


def _best_effort(depth: int, durability: DurabilityPolicy) -> QoSProfile:
    """Best effort, keep last ``depth``: the reliability of every PX4 bridge topic."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.BEST_EFFORT, durability=durability)


#: Subscriptions to PX4's outputs (``/fmu/out``): best effort, volatile, keep last 5.
PX4_OUT_QOS = _best_effort(5, DurabilityPolicy.VOLATILE)
#: Publishers to PX4's inputs (``/fmu/in``): best effort, volatile, keep last 10.
PX4_IN_QOS = _best_effort(10, DurabilityPolicy.VOLATILE)
#: What PX4's bridge offers on ``/fmu/out``: best effort, transient local, keep last 1.
PX4_BRIDGE_WRITER_QOS = _best_effort(1, DurabilityPolicy.TRANSIENT_LOCAL)
#: What PX4's bridge requests on ``/fmu/in``: best effort, volatile.
PX4_BRIDGE_READER_QOS = _best_effort(10, DurabilityPolicy.VOLATILE)


def px4_topic(name: str, namespace: str = '') -> str:
    """The topic ``name`` of a vehicle whose bridge runs with ``namespace``.

    Parameters
    ----------
    name : str
        One of this module's topic names (``/fmu/...``).
    namespace : str
        The bridge's namespace (``uxrce_dds_client start -n NAME``, e.g. ``'px4_1'``), or ''
        for the default (no prefix).

    Returns
    -------
    str
        ``/NAMESPACE/fmu/...``, or ``name`` itself for the default namespace.

    Raises
    ------
    ValueError
        When ``name`` is not an absolute ``/fmu/`` name or ``namespace`` is not a plain name.
    """
    if not name.startswith(PX4_NAMESPACE + '/'):
        raise ValueError(f'px4 topic {name!r} does not start with {PX4_NAMESPACE}/')
    ns = namespace.strip('/')
    if not ns:
        return name
    if not all(part.isidentifier() for part in ns.split('/')):
        raise ValueError(f'px4 namespace {namespace!r} is not a ROS name')
    return f'/{ns}{name}'
