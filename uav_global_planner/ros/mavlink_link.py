"""The follower's MAVLink side: ``SET_POSITION_TARGET_LOCAL_NED`` out, the vehicle's state in.

For ArduPilot (guided mode) and PX4 or MAVSDK peers that speak MAVLink 2 (``common`` dialect)
over UDP. ``udpout:HOST:PORT`` sends to the autopilot's address (as pymavlink's connection
strings do); the autopilot answers to the address the datagrams come from.

Conventions (MAVLink common message set):

- ``SET_POSITION_TARGET_LOCAL_NED`` in ``MAV_FRAME_LOCAL_NED`` (x north, y east, z down [m]),
  velocity [m/s] and acceleration [m/s^2] in the same frame, ``yaw`` a heading (0 north,
  clockwise) [rad] and ``yaw_rate`` about down [rad/s]; ``type_mask`` bits set mark fields to
  ignore (a NaN yaw sets ``POSITION_TARGET_TYPEMASK_YAW_IGNORE``: keep the heading);
- ``LOCAL_POSITION_NED``: position and velocity in ``MAV_FRAME_LOCAL_NED``, no attitude;
- ``ODOMETRY``: ``frame_id`` must be ``MAV_FRAME_LOCAL_NED`` (a ``MAV_FRAME_LOCAL_FRD`` pose has
  an arbitrary heading reference and is refused), ``q`` from the body FRD frame to ``frame_id``
  (w, x, y, z), velocity and rates in ``child_frame_id`` (``MAV_FRAME_BODY_FRD``, or
  ``MAV_FRAME_LOCAL_NED`` for a world-frame velocity).

The follower sends a ``HEARTBEAT`` as an onboard controller once a second. Nothing here arms or
switches modes. No rclpy here: the node uses it from its setpoint thread and a reader thread.
"""

import math
import socket
import threading
import time
from typing import Callable, Optional, Tuple

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from uav_global_planner.core import frames
from uav_global_planner.core.follower import Command, VehicleState

#: The connection strings this link takes.
URL_FORMAT = 'udpout:HOST:PORT'

#: ``type_mask`` of a full setpoint: position, velocity, acceleration, yaw and yaw rate used.
TYPE_MASK_ALL = 0

#: The MAVLink system id of the follower (as a companion computer's) and its component.
SOURCE_SYSTEM = 1
SOURCE_COMPONENT = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER


def parse_url(url: str) -> Tuple[str, int]:
    """``(host, port)`` of ``udpout:HOST:PORT``.

    Raises
    ------
    ValueError
        Naming ``--mavlink`` and the expected form.
    """
    kind, _, rest = url.partition(':')
    host, _, port = rest.rpartition(':')
    if kind != 'udpout' or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f'--mavlink {url!r}: expected {URL_FORMAT} (for example '
                         'udpout:127.0.0.1:14550)')
    return host, int(port)


def state_from_local_position(msg) -> VehicleState:
    """A ``LOCAL_POSITION_NED`` message as a :class:`VehicleState` (ENU)."""
    position = frames.ned_to_enu([msg.x, msg.y, msg.z])
    velocity = frames.ned_to_enu([msg.vx, msg.vy, msg.vz])
    return VehicleState(position=position,
                        velocity=velocity if np.all(np.isfinite(velocity)) else None)


def state_from_odometry(msg) -> VehicleState:
    """An ``ODOMETRY`` message as a :class:`VehicleState` (ENU, FLU body), or refused."""
    position = frames.ned_to_enu([msg.x, msg.y, msg.z])
    if msg.frame_id != mavlink2.MAV_FRAME_LOCAL_NED:
        return VehicleState(position=position, refused=(
            f'ODOMETRY frame_id {msg.frame_id} is not MAV_FRAME_LOCAL_NED '
            f'({mavlink2.MAV_FRAME_LOCAL_NED}); a pose in another frame is not in the map frame'))
    q = np.asarray(msg.q, dtype=np.float64)
    orientation = (frames.quaternion_ned_frd_to_enu_flu(q) if np.all(np.isfinite(q))
                   and abs(float(np.linalg.norm(q)) - 1.0) < 1e-3 else None)
    velocity: Optional[np.ndarray] = None
    raw = np.array([msg.vx, msg.vy, msg.vz], dtype=np.float64)
    if np.all(np.isfinite(raw)):
        if msg.child_frame_id == mavlink2.MAV_FRAME_LOCAL_NED:
            velocity = frames.ned_to_enu(raw)
        elif msg.child_frame_id == mavlink2.MAV_FRAME_BODY_FRD and orientation is not None:
            velocity = frames.rotate_xyzw(orientation, frames.frd_to_flu(raw))
    rates = np.array([msg.rollspeed, msg.pitchspeed, msg.yawspeed], dtype=np.float64)
    return VehicleState(position=position, orientation=orientation, velocity=velocity,
                        angular_velocity=(frames.frd_to_flu(rates)
                                          if np.all(np.isfinite(rates)) else None))


class MavlinkLink:
    """UDP MAVLink 2 link to one autopilot: setpoints out, its state in (on a thread).

    Parameters
    ----------
    url : str
        ``udpout:HOST:PORT`` of the autopilot.
    on_state : callable
        Called with each :class:`VehicleState` from ``LOCAL_POSITION_NED`` or ``ODOMETRY``
        (from the reader thread).
    target_system, target_component : int
        The autopilot's ids (taken from its ``HEARTBEAT`` once one arrives).
    """

    name = 'mavlink'

    def __init__(self, url: str, on_state: Callable[[VehicleState], None],
                 target_system: int = 1, target_component: int = 1) -> None:
        self.address = parse_url(url)
        self._on_state = on_state
        self.target_system = int(target_system)
        self.target_component = int(target_component)
        self._mav = mavlink2.MAVLink(None, srcSystem=SOURCE_SYSTEM, srcComponent=SOURCE_COMPONENT)
        self._send_lock = threading.Lock()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.settimeout(0.2)
        self._boot = time.monotonic()
        self._last_heartbeat = -math.inf
        self.autopilot_seen = False
        self._closed = False
        self._send(self._heartbeat())        # so that the peer learns where to answer
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _heartbeat(self):
        return self._mav.heartbeat_encode(mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
                                          mavlink2.MAV_AUTOPILOT_INVALID, 0, 0,
                                          mavlink2.MAV_STATE_ACTIVE)

    def _send(self, msg) -> None:
        with self._send_lock:
            data = msg.pack(self._mav)
            try:
                self._sock.sendto(data, self.address)
            except OSError:
                pass        # the peer is not there yet (ICMP refused): the next one tries again

    def send(self, command: Command, now_ns: int) -> None:
        """Send ``command`` as ``SET_POSITION_TARGET_LOCAL_NED`` (and a heartbeat each second)."""
        now = time.monotonic()
        if now - self._last_heartbeat >= 1.0:
            self._last_heartbeat = now
            self._send(self._heartbeat())
        sp = command.setpoint
        p = frames.enu_to_ned(sp.position)
        v = frames.enu_to_ned(sp.velocity)
        a = frames.enu_to_ned(sp.acceleration)
        mask = TYPE_MASK_ALL
        yaw = frames.yaw_enu_to_ned(sp.yaw)
        if not math.isfinite(yaw):
            mask |= mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
            yaw = 0.0
        msg = self._mav.set_position_target_local_ned_encode(
            int((now - self._boot) * 1000.0) & 0xFFFFFFFF, self.target_system,
            self.target_component, mavlink2.MAV_FRAME_LOCAL_NED, mask,
            float(p[0]), float(p[1]), float(p[2]), float(v[0]), float(v[1]), float(v[2]),
            float(a[0]), float(a[1]), float(a[2]), yaw,
            frames.yaw_rate_enu_to_ned(sp.yaw_rate))
        self._send(msg)

    def _read(self) -> None:
        while not self._closed:
            try:
                data, _ = self._sock.recvfrom(65535)
            except socket.timeout:
                continue
            except OSError:
                time.sleep(0.05)        # closed (the loop ends) or a transient error
                continue
            try:
                messages = self._mav.parse_buffer(data) or []
            except mavlink2.MAVError:
                continue
            for msg in messages:
                kind = msg.get_type()
                if kind == 'HEARTBEAT' and msg.type != mavlink2.MAV_TYPE_GCS:
                    if not self.autopilot_seen:
                        self.target_system = msg.get_srcSystem()
                        self.target_component = msg.get_srcComponent()
                    self.autopilot_seen = True
                elif kind == 'LOCAL_POSITION_NED':
                    self._on_state(state_from_local_position(msg))
                elif kind == 'ODOMETRY':
                    self._on_state(state_from_odometry(msg))

    def close(self) -> None:
        """Stop the reader and close the socket."""
        self._closed = True
        self._reader.join(1.0)
        self._sock.close()
