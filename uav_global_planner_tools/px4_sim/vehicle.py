"""A simulated multirotor with an autopilot's offboard logic: RotorPy's vehicle and controller.

:class:`SimulatedVehicle` is what the DDS vehicle (:mod:`.dds_vehicle`) and the MAVLink peer
(:mod:`.mavlink_vehicle`) share; it has no transport and imports no rclpy.

- Physics: RotorPy 3.0.0's ``Multirotor`` (rigid body, rotor lag, rotor drag) with the
  parameters of PX4's SIH quadrotor
  (:func:`~uav_global_planner_tools.flight.vehicles.px4_sih_quadx`: 1 kg, 50 ms motor lag),
  integrated with a fixed explicit midpoint (second-order Runge-Kutta)
  step of ``1 / rate_hz`` on RotorPy's own state derivative (``Multirotor._s_dot_fn``): two
  evaluations per step where RotorPy's adaptive ``step`` (scipy RK45) takes six or more and
  its set-up, which keeps the loop in real time beside the planner on a small machine. The
  step (8 ms at 125 Hz) is a sixth of the motor lag. Rotor commands are clipped to the rotor
  limits and the attitude quaternion re-normalised after each step, as ``Multirotor.step``
  does.
- Position controller: RotorPy's ``SE3Control`` (geometric tracking on SE(3), Lee, Leok and
  McClamroch) stands in for PX4's multicopter position and attitude controllers, fed every
  step with the setpoint in force converted to ENU by :mod:`.ned` (never the follower's code).
- Offboard logic, as PX4's (user guide "Offboard Mode"): the vehicle follows setpoints only in
  offboard mode, and stays there only while the offboard heartbeat (``OffboardControlMode``
  with a control flag set, or for MAVLink the setpoint stream itself) arrives at >= 2 Hz; a gap
  longer than ``stream_timeout_s`` (0.5 s) is PX4's offboard-loss failsafe: the vehicle holds
  the position where it was (nav state ``AUTO_LOITER``). The mode changes on request
  (``VEHICLE_CMD_DO_SET_MODE`` with PX4's custom main mode 6), which is refused while no
  heartbeat streams, as PX4 refuses it; with ``auto_offboard`` (the default of the
  processes) an operator's switch is simulated: offboard is entered whenever the heartbeat has
  streamed for ``auto_offboard_after_s``. The vehicle starts armed, hovering at its start
  position (taking off is not simulated); it never disarms in the air.
- Setpoints (NED, PX4 ``TrajectorySetpoint`` semantics): NaN leaves a quantity uncontrolled:
  NaN velocity, acceleration or jerk is no feed-forward; NaN yaw keeps the current heading; a
  NaN position with a finite velocity flies that velocity from where the vehicle is.
"""

from dataclasses import dataclass
import json
import math
import time
from typing import Any, Callable, Dict, IO, List, Optional, Sequence

import numpy as np

from uav_global_planner_tools.flight.vehicles import px4_sih_quadx, Vehicle
from uav_global_planner_tools.px4_sim import ned

#: Offboard heartbeat gap that triggers the failsafe hold [s]: PX4 needs >= 2 Hz.
STREAM_TIMEOUT_S = 0.5

#: PX4 nav states (``VehicleStatus.NAVIGATION_STATE_*``) the simulated vehicle reports.
NAV_STATE_AUTO_LOITER = 4
NAV_STATE_OFFBOARD = 14


@dataclass(frozen=True)
class NedSetpoint:
    """A setpoint as received (PX4 ``TrajectorySetpoint`` semantics, NaN = not controlled).

    Attributes
    ----------
    received_s : float
        ``time.monotonic()`` at reception [s].
    position, velocity, acceleration, jerk : numpy.ndarray, shape (3,)
        NED [m], [m/s], [m/s^2], [m/s^3].
    yaw : float
        NED heading [rad] (0 north, clockwise).
    yaw_rate : float
        About down [rad/s].
    """

    received_s: float
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    yaw: float
    yaw_rate: float


def _zero_nan(v: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(v), v, 0.0)


class SimulatedVehicle:
    """One simulated multirotor under an offboard-capable autopilot (ENU inside, NED outside).

    Parameters
    ----------
    start_enu : sequence of 3 floats
        Where it hovers at start, map frame ENU [m].
    yaw_enu : float
        Heading at start, ENU [rad].
    rate_hz : float
        Physics and controller rate [Hz] (one odometry sample per step).
    vehicle : Vehicle, optional
        RotorPy parameters; PX4's SIH quadrotor by default.
    stream_timeout_s : float
        Heartbeat gap that ends offboard control [s].
    auto_offboard : bool
        Enter offboard whenever the heartbeat has streamed for ``auto_offboard_after_s``.
    auto_offboard_after_s : float
        [s].
    track : file, optional
        Text file that receives one JSON line per step and per received setpoint (wall-clock
        time ``t`` [s], ENU values), for the tests and the benchmark.

    Raises
    ------
    ValueError
        For a non-finite start, a rate outside (0, 1000] Hz or a non-positive timeout.
    """

    def __init__(self, start_enu: Sequence[float], yaw_enu: float = 0.0, rate_hz: float = 125.0,
                 vehicle: Optional[Vehicle] = None, stream_timeout_s: float = STREAM_TIMEOUT_S,
                 auto_offboard: bool = True, auto_offboard_after_s: float = 0.5,
                 track: Optional[IO[str]] = None) -> None:
        start = np.asarray(start_enu, dtype=np.float64).reshape(3)
        if not (np.all(np.isfinite(start)) and math.isfinite(yaw_enu)):
            raise ValueError(f'start {list(start)} / yaw {yaw_enu}: must be finite')
        if not (0.0 < rate_hz <= 1000.0):
            raise ValueError(f'rate {rate_hz} Hz: must be in (0, 1000]')
        if not stream_timeout_s > 0.0:
            raise ValueError(f'stream timeout {stream_timeout_s} s: must be > 0')
        from rotorpy.controllers import quadrotor_control  # type: ignore[import-untyped]
        from rotorpy.vehicles.multirotor import Multirotor  # type: ignore[import-untyped]
        self.vehicle = vehicle or px4_sih_quadx()
        self.params = self.vehicle.quad_params()
        self.dt = 1.0 / rate_hz
        self.state: Dict[str, np.ndarray] = {
            'x': start.copy(), 'v': np.zeros(3),
            'q': np.array([0.0, 0.0, math.sin(yaw_enu / 2.0), math.cos(yaw_enu / 2.0)]),
            'w': np.zeros(3), 'wind': np.zeros(3),
            'rotor_speeds': np.full(self.vehicle.num_rotors, self.vehicle.hover_rotor_speed)}
        self._model = Multirotor(self.params, initial_state=self.state,
                                 control_abstraction='cmd_motor_speeds', aero=True)
        self._pack, self._unpack = Multirotor._pack_state, Multirotor._unpack_state
        self._controller = quadrotor_control.SE3Control(self.params)
        self._speed_limits = (float(self.params['rotor_speed_min']),
                              float(self.params['rotor_speed_max']))
        self.stream_timeout_s = float(stream_timeout_s)
        self.auto_offboard = bool(auto_offboard)
        self.auto_offboard_after_s = float(auto_offboard_after_s)
        self.armed = True
        self.nav_state = NAV_STATE_AUTO_LOITER
        self.hold_position = start.copy()
        self.hold_yaw = float(yaw_enu)
        self.setpoint: Optional[NedSetpoint] = None
        self.last_heartbeat_s = -math.inf
        self._stream_since_s = math.inf
        self.time_s = 0.0
        self.steps = 0
        self.setpoints_received = 0
        self.heartbeats_received = 0
        self.commands_received = 0
        self.events: List[str] = []
        self._track = track
        self._track_lines = 0

    # ---------------------------------------------------------------- inputs (any thread)

    def receive_heartbeat(self, now_s: float, controls: bool = True) -> None:
        """An offboard heartbeat at ``now_s`` (monotonic) [s]; ``controls`` False (no control
        flag set) does not count, as in PX4."""
        if not controls:
            return
        if now_s - self.last_heartbeat_s > self.stream_timeout_s:
            self._stream_since_s = now_s
        self.last_heartbeat_s = now_s
        self.heartbeats_received += 1

    def receive_setpoint(self, now_s: float, position: Sequence[float],
                         velocity: Sequence[float], acceleration: Sequence[float],
                         jerk: Sequence[float], yaw: float, yaw_rate: float) -> None:
        """A setpoint in NED (PX4 ``TrajectorySetpoint`` semantics) at ``now_s`` [s]."""
        def vector(v: Sequence[float]) -> np.ndarray:
            return np.asarray(v, dtype=np.float64).reshape(3)

        sp = NedSetpoint(now_s, vector(position), vector(velocity), vector(acceleration),
                         vector(jerk), float(yaw), float(yaw_rate))
        self.setpoint = sp
        self.setpoints_received += 1
        if self._track is not None:
            self._write({'kind': 'setpoint', 't': time.time(),
                         'p': ned.vector_ned_to_enu(sp.position).tolist(),
                         'v': ned.vector_ned_to_enu(sp.velocity).tolist(),
                         'a': ned.vector_ned_to_enu(sp.acceleration).tolist(),
                         'yaw': ned.heading_ned_to_enu(sp.yaw)})

    def request_offboard(self, now_s: float) -> bool:
        """``VEHICLE_CMD_DO_SET_MODE`` to offboard: accepted only while the heartbeat streams
        and a setpoint is there (PX4 refuses the switch otherwise)."""
        self.commands_received += 1
        if not self._streaming(now_s) or self.setpoint is None:
            self._event('offboard refused: no offboard heartbeat or no setpoint yet')
            return False
        self._enter_offboard('offboard requested')
        return True

    def request_arm(self, arm: bool) -> bool:
        """``VEHICLE_CMD_COMPONENT_ARM_DISARM``: arming is acknowledged (it is armed); disarming
        in the air is refused."""
        self.commands_received += 1
        return bool(arm)

    # ---------------------------------------------------------------- the loop

    def _streaming(self, now_s: float) -> bool:
        return now_s - self.last_heartbeat_s <= self.stream_timeout_s

    def _event(self, text: str) -> None:
        self.events.append(f'{self.time_s:.3f} {text}')
        if self._track is not None:
            self._write({'kind': 'event', 't': time.time(), 'text': text})

    def _enter_offboard(self, why: str) -> None:
        if self.nav_state != NAV_STATE_OFFBOARD:
            self.nav_state = NAV_STATE_OFFBOARD
            self._event(f'offboard: {why}')

    def _enter_hold(self, why: str) -> None:
        if self.nav_state != NAV_STATE_AUTO_LOITER:
            self.nav_state = NAV_STATE_AUTO_LOITER
            self.hold_position = self.state['x'].copy()
            self.hold_yaw = self.yaw_enu
            self._event(f'hold: {why}')

    @property
    def in_offboard(self) -> bool:
        """Whether setpoints are flown."""
        return self.nav_state == NAV_STATE_OFFBOARD

    def _flat_output(self) -> Dict[str, Any]:
        """The reference SE3Control tracks this step (ENU)."""
        sp = self.setpoint
        if not self.in_offboard or sp is None:
            return {'x': self.hold_position, 'x_dot': np.zeros(3), 'x_ddot': np.zeros(3),
                    'x_dddot': np.zeros(3), 'x_ddddot': np.zeros(3), 'yaw': self.hold_yaw,
                    'yaw_dot': 0.0, 'yaw_ddot': 0.0}
        position = ned.vector_ned_to_enu(sp.position)
        velocity = ned.vector_ned_to_enu(_zero_nan(sp.velocity))
        if not np.all(np.isfinite(position)):
            position = self.state['x'].copy()
        yaw = ned.heading_ned_to_enu(sp.yaw)
        if not math.isfinite(yaw):
            yaw = self.hold_yaw
        else:
            self.hold_yaw = yaw
        yaw_rate = ned.heading_rate_ned_to_enu(sp.yaw_rate) if math.isfinite(sp.yaw_rate) else 0.0
        return {'x': position, 'x_dot': velocity,
                'x_ddot': ned.vector_ned_to_enu(_zero_nan(sp.acceleration)),
                'x_dddot': ned.vector_ned_to_enu(_zero_nan(sp.jerk)), 'x_ddddot': np.zeros(3),
                'yaw': yaw, 'yaw_dot': yaw_rate, 'yaw_ddot': 0.0}

    def step(self, now_s: float) -> None:
        """Decide the mode at ``now_s`` (monotonic) [s] and fly one step of ``dt``."""
        streaming = self._streaming(now_s)
        if self.in_offboard and not streaming:
            self._enter_hold('offboard heartbeat lost (failsafe, hold position)')
        elif (not self.in_offboard and self.auto_offboard and streaming
              and self.setpoint is not None
              and now_s - self._stream_since_s >= self.auto_offboard_after_s):
            self._enter_offboard('heartbeat streaming (operator switch)')
        command = self._controller.update(self.time_s, self.state, self._flat_output())
        speeds = np.clip(np.asarray(command['cmd_motor_speeds'], dtype=np.float64),
                         *self._speed_limits)
        self.state = self._midpoint(self.state, speeds)
        self.time_s += self.dt
        self.steps += 1
        if self._track is not None:
            self._write({'kind': 'state', 't': time.time(), 'p': self.state['x'].tolist(),
                         'v': self.state['v'].tolist(), 'offboard': self.in_offboard})

    def _midpoint(self, state: Dict[str, np.ndarray], speeds: np.ndarray) -> Dict[str, np.ndarray]:
        s = self._pack(state)
        f = self._model._s_dot_fn
        h = self.dt
        k1 = f(0.0, s, speeds)
        k2 = f(0.5 * h, s + 0.5 * h * k1, speeds)
        out = self._unpack(s + h * k2)
        out['q'] = out['q'] / np.linalg.norm(out['q'])
        out['rotor_speeds'] = np.clip(out['rotor_speeds'], *self._speed_limits)
        out['wind'] = state['wind']
        return out

    # ---------------------------------------------------------------- outputs

    @property
    def yaw_enu(self) -> float:
        """Heading of the body's forward axis, ENU [rad]."""
        r = ned.matrix_from_quaternion_xyzw(self.state['q'])
        return math.atan2(r[1, 0], r[0, 0])

    def odometry_ned(self) -> Dict[str, np.ndarray]:
        """Position and velocity in NED [m, m/s], attitude FRD in NED (w, x, y, z), body rates
        FRD [rad/s], as PX4's ``VehicleOdometry`` carries them."""
        return {'position': ned.vector_enu_to_ned(self.state['x']),
                'velocity': ned.vector_enu_to_ned(self.state['v']),
                'q': ned.attitude_enu_flu_to_ned_frd(self.state['q']),
                'angular_velocity': ned.body_flu_to_frd(self.state['w'])}

    def _write(self, record: Dict[str, Any]) -> None:
        assert self._track is not None
        self._track.write(json.dumps(record) + '\n')
        self._track_lines += 1
        if self._track_lines % 25 == 0:
            self._track.flush()

    def flush(self) -> None:
        """Flush the track file."""
        if self._track is not None:
            self._track.flush()


def run_realtime(dt: float, step: Callable[[float], None], should_stop: Callable[[], bool],
                 max_behind_s: float = 0.2) -> Dict[str, float]:
    """Call ``step(now_s)`` every ``dt`` seconds of the monotonic clock until ``should_stop()``.

    ``step`` advances the simulation by one physics step (``SimulatedVehicle.step``) and sends
    what the vehicle sends. Steps that fall behind the clock are caught up at once (several in
    a row); when more than ``max_behind_s`` behind, the schedule restarts from now instead and
    the gap is counted as an overrun.

    Returns
    -------
    dict
        ``steps``, ``overruns`` and ``late_max_s``, the largest lag of a step [s].
    """
    next_s = time.monotonic()
    steps, overruns, late_max = 0, 0, 0.0
    while not should_stop():
        now = time.monotonic()
        late = now - next_s
        if late > max_behind_s:
            overruns += 1
            next_s = now
        late_max = max(late_max, late)
        while next_s <= time.monotonic():
            step(next_s)
            steps += 1
            next_s += dt
        pause = next_s - time.monotonic()
        if pause > 0.0:
            time.sleep(pause)
    return {'steps': float(steps), 'overruns': float(overruns), 'late_max_s': late_max}
