"""The simulated vehicle as a MAVLink autopilot on UDP: a pymavlink peer for guided/offboard use.

Run it as a process of its own::

    python -m uav_global_planner_tools.px4_sim.mavlink_vehicle --listen 127.0.0.1:PORT
        --start X Y Z [--yaw RAD] [--rate 125] [--telemetry-rate 50] [--track FILE]

It binds ``HOST:PORT`` (a ground station or companion computer connects with
``udpout:HOST:PORT``) and answers to the address the last datagram came from, as an autopilot's
UDP link does. MAVLink 2, ``common`` message set (pymavlink), system 1, component 1
(``MAV_COMP_ID_AUTOPILOT1``):

- sends ``HEARTBEAT`` at 1 Hz as an ArduPilot copter (``MAV_TYPE_QUADROTOR``,
  ``MAV_AUTOPILOT_ARDUPILOTMEGA``, armed, custom mode 4 = ``GUIDED``), and at
  ``--telemetry-rate`` ``LOCAL_POSITION_NED`` (``MAV_FRAME_LOCAL_NED`` position and velocity)
  and ``ODOMETRY`` (``frame_id`` ``MAV_FRAME_LOCAL_NED``, ``child_frame_id``
  ``MAV_FRAME_BODY_FRD``: ``q`` from the FRD body to NED as w, x, y, z, velocity and rates in
  the body frame, covariances unknown: first element NaN);
- reads ``SET_POSITION_TARGET_LOCAL_NED`` addressed to it (or to system 0) in
  ``MAV_FRAME_LOCAL_NED``: position, velocity, acceleration, yaw, yaw rate, each taken unless
  its ``type_mask`` bit says ignore (then NaN: not controlled). Targets in other frames are
  counted and ignored.

The setpoint stream is its heartbeat, as for PX4's offboard mode over MAVLink: a gap longer
than ``--stream-timeout`` (0.5 s) makes it hold where it is, and it follows again once the
stream is back (ArduPilot keeps flying to the last position target in guided mode; the
stricter PX4 rule is the one simulated, so that a silent link is seen). Physics and the
controller: :class:`~uav_global_planner_tools.px4_sim.vehicle.SimulatedVehicle`; the map origin
is the local NED origin. Prints :data:`READY_TEXT` once the socket is bound and a summary line
at SIGINT or SIGTERM.
"""

import argparse
import math
import signal
import socket
import sys
import threading
import time
from typing import Any, List, Optional, Tuple

from pymavlink.dialects.v20 import common as mavlink2

from uav_global_planner_tools.px4_sim import ned
from uav_global_planner_tools.px4_sim.vehicle import run_realtime, SimulatedVehicle

#: Printed once the socket is bound.
READY_TEXT = 'simulated mavlink vehicle ready'

#: ArduPilot copter's GUIDED mode number (``custom_mode`` of its HEARTBEAT).
ARDUCOPTER_GUIDED = 4

SYSTEM_ID = 1
COMPONENT_ID = mavlink2.MAV_COMP_ID_AUTOPILOT1

_NAN3 = [math.nan] * 3


def parse_listen(text: str) -> Tuple[str, int]:
    """``(host, port)`` of ``HOST:PORT``.

    Raises
    ------
    ValueError
        Naming ``--listen`` and the expected form.
    """
    host, _, port = text.rpartition(':')
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f'--listen {text!r}: expected HOST:PORT, for example 127.0.0.1:14550')
    return host, int(port)


def _masked(values: List[float], mask: int, bits: List[int]) -> List[float]:
    return [math.nan if mask & bit else float(v) for v, bit in zip(values, bits)]


class MavlinkVehicle:
    """A UDP MAVLink endpoint around one :class:`SimulatedVehicle`.

    Parameters
    ----------
    sim : SimulatedVehicle
    address : (str, int)
        Where to bind.
    telemetry_rate_hz : float
        ``LOCAL_POSITION_NED`` and ``ODOMETRY`` rate [Hz].
    """

    def __init__(self, sim: SimulatedVehicle, address: Tuple[str, int],
                 telemetry_rate_hz: float = 50.0) -> None:
        self.sim = sim
        self._lock = threading.Lock()
        self._mav = mavlink2.MAVLink(None, srcSystem=SYSTEM_ID, srcComponent=COMPONENT_ID)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(address)
        self._sock.settimeout(0.2)
        self.address = self._sock.getsockname()
        self._peer: Optional[Tuple[str, int]] = None
        self._boot = time.monotonic()
        self._telemetry_period = 1.0 / telemetry_rate_hz
        self._next_telemetry = 0.0
        self._next_heartbeat = 0.0
        self.ignored_frames = 0
        self.telemetry_sent = 0
        self._closed = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _send(self, msg: Any) -> None:
        peer = self._peer
        if peer is None:
            return
        try:
            self._sock.sendto(msg.pack(self._mav), peer)
        except OSError:
            pass

    def _read(self) -> None:
        while not self._closed.is_set():
            try:
                data, sender = self._sock.recvfrom(65535)
            except socket.timeout:
                continue
            except OSError:
                if self._closed.is_set():
                    return
                time.sleep(0.05)
                continue
            self._peer = sender
            try:
                messages = self._mav.parse_buffer(data) or []
            except mavlink2.MAVError:
                continue
            for msg in messages:
                if msg.get_type() == 'SET_POSITION_TARGET_LOCAL_NED':
                    self._setpoint(msg)

    def _setpoint(self, msg: Any) -> None:
        if msg.target_system not in (0, SYSTEM_ID):
            return
        if msg.coordinate_frame != mavlink2.MAV_FRAME_LOCAL_NED:
            self.ignored_frames += 1
            return
        mask = int(msg.type_mask)
        m = mavlink2
        position = _masked([msg.x, msg.y, msg.z], mask, [
            m.POSITION_TARGET_TYPEMASK_X_IGNORE, m.POSITION_TARGET_TYPEMASK_Y_IGNORE,
            m.POSITION_TARGET_TYPEMASK_Z_IGNORE])
        velocity = _masked([msg.vx, msg.vy, msg.vz], mask, [
            m.POSITION_TARGET_TYPEMASK_VX_IGNORE, m.POSITION_TARGET_TYPEMASK_VY_IGNORE,
            m.POSITION_TARGET_TYPEMASK_VZ_IGNORE])
        acceleration = _masked([msg.afx, msg.afy, msg.afz], mask, [
            m.POSITION_TARGET_TYPEMASK_AX_IGNORE, m.POSITION_TARGET_TYPEMASK_AY_IGNORE,
            m.POSITION_TARGET_TYPEMASK_AZ_IGNORE])
        yaw = math.nan if mask & m.POSITION_TARGET_TYPEMASK_YAW_IGNORE else float(msg.yaw)
        yaw_rate = (math.nan if mask & m.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
                    else float(msg.yaw_rate))
        now = time.monotonic()
        with self._lock:
            self.sim.receive_heartbeat(now)
            self.sim.receive_setpoint(now, position, velocity, acceleration, _NAN3, yaw,
                                      yaw_rate)

    def step(self, now_s: float) -> None:
        """One physics step, then the telemetry when due."""
        with self._lock:
            self.sim.step(now_s)
            if now_s < self._next_telemetry and now_s < self._next_heartbeat:
                return
            odometry = self.sim.odometry_ned()
        if now_s >= self._next_heartbeat:
            self._next_heartbeat = max(self._next_heartbeat + 1.0, now_s)
            base_mode = (mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                         | mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
                         | mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
                         | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
            self._send(self._mav.heartbeat_encode(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode,
                ARDUCOPTER_GUIDED, mavlink2.MAV_STATE_ACTIVE))
        if now_s >= self._next_telemetry:
            # On the telemetry schedule, not one period after this step: the rate holds when
            # the period is not a multiple of the physics step.
            self._next_telemetry = max(self._next_telemetry + self._telemetry_period,
                                       now_s - self._telemetry_period)
            since_boot = now_s - self._boot
            p, v = odometry['position'], odometry['velocity']
            q = odometry['q']
            r_ned_frd = ned.matrix_from_quaternion_xyzw([q[1], q[2], q[3], q[0]])
            v_body = r_ned_frd.T @ v
            w = odometry['angular_velocity']
            self._send(self._mav.local_position_ned_encode(
                int(since_boot * 1000.0) & 0xFFFFFFFF, *(float(c) for c in p),
                *(float(c) for c in v)))
            unknown = [math.nan] + [0.0] * 20
            self._send(self._mav.odometry_encode(
                int(since_boot * 1e6), mavlink2.MAV_FRAME_LOCAL_NED, mavlink2.MAV_FRAME_BODY_FRD,
                *(float(c) for c in p), [float(c) for c in q], *(float(c) for c in v_body),
                *(float(c) for c in w), unknown, unknown, 0,
                mavlink2.MAV_ESTIMATOR_TYPE_NAIVE, 100))
            self.telemetry_sent += 1

    def close(self) -> None:
        """Stop the reader and close the socket."""
        self._closed.set()
        self._reader.join(1.0)
        self._sock.close()


def parse_args(argv: Optional[List[str]] = None) -> argparse.Namespace:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description='A simulated MAVLink autopilot (guided mode) on UDP (RotorPy, real time).')
    parser.add_argument('--listen', required=True, help='HOST:PORT to bind (UDP)')
    parser.add_argument('--start', type=float, nargs=3, required=True, metavar=('X', 'Y', 'Z'),
                        help='hover position at start, map frame ENU [m]')
    parser.add_argument('--yaw', type=float, default=0.0, help='heading at start, ENU [rad]')
    parser.add_argument('--rate', type=float, default=125.0,
                        help='physics rate [Hz] (default 125)')
    parser.add_argument('--telemetry-rate', type=float, default=50.0,
                        help='LOCAL_POSITION_NED and ODOMETRY rate [Hz] (default 50)')
    parser.add_argument('--stream-timeout', type=float, default=0.5,
                        help='setpoint gap that triggers the hold [s] (default 0.5)')
    parser.add_argument('--track', default=None, help='JSON-lines track file to write')
    return parser.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> int:
    """Run until SIGINT or SIGTERM; exit status 0, or 2 for bad options."""
    options = parse_args(argv)
    try:
        address = parse_listen(options.listen)
        if not (0.0 < options.telemetry_rate <= options.rate):
            raise ValueError(f'--telemetry-rate {options.telemetry_rate}: must be in '
                             f'(0, --rate]')
    except ValueError as error:
        print(f'mavlink_vehicle: {error}', file=sys.stderr)
        return 2
    track = open(options.track, 'w', encoding='utf-8') if options.track else None
    try:
        sim = SimulatedVehicle(options.start, options.yaw, options.rate,
                               stream_timeout_s=options.stream_timeout, track=track)
        vehicle = MavlinkVehicle(sim, address, options.telemetry_rate)
    except (ValueError, OSError) as error:
        print(f'mavlink_vehicle: {error}', file=sys.stderr)
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f'{READY_TEXT} on udp {vehicle.address[0]}:{vehicle.address[1]}, hovering at '
          f'{list(options.start)} (ENU)', flush=True)
    started = time.monotonic()
    result = run_realtime(sim.dt, vehicle.step, stop.is_set)
    sim.flush()
    elapsed = time.monotonic() - started
    vehicle.close()
    print(f'mavlink_vehicle: {sim.steps} steps in {elapsed:.1f} s, telemetry '
          f'{vehicle.telemetry_sent / max(elapsed, 1e-9):.1f} Hz, overruns '
          f'{result["overruns"]:.0f}, late max {result["late_max_s"]:.3f} s, setpoints '
          f'{sim.setpoints_received}, other frames {vehicle.ignored_frames}', flush=True)
    for event in sim.events:
        print(f'mavlink_vehicle event: {event}', flush=True)
    if track is not None:
        track.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
