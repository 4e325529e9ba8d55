"""Following the planner's plan in force: a setpoint at any time, or a hold, with its reasons.

Pure logic (no ROS): the transport (a ROS 2 node speaking ``px4_msgs``, or MAVLink) hands in
what arrives and calls :meth:`Follower.step` at the setpoint rate. Everything here is in the map
frame, ENU (REP 103/105); :mod:`uav_global_planner.core.frames` converts to NED for the vehicle.

The plan in force is the planner's timed ``trajectory`` (``MultiDOFJointTrajectory``): points
at ``header.stamp + time_from_start`` with position, heading, velocity, yaw rate and
acceleration. Between points the position is a cubic Hermite interpolation of positions and
velocities, the velocity one of velocities and accelerations, the acceleration and the yaw rate
are linear; after the last point the goal is held with zero velocity. The message carries no
jerk, so the jerk setpoint is NaN ("not set", as ``TrajectorySetpoint`` reads it).

Handover: a plan stamped ahead (a replan in flight) takes over at its stamp; until then the
plan before it is flown. A newer plan drops every plan still waiting for its stamp.

Holds (the setpoint stays at the last safe position, zero velocity and acceleration, the last
heading, zero yaw rate), each with its reason:

- the plan is withdrawn (an empty ``trajectory``, or an empty ``plan`` after the ``plan`` of the
  trajectory in force): at once, and until a new plan arrives;
- the plan stream is lost (no publisher of the plan for ``plan_timeout_s``);
- the odometry is stale (none for ``odometry_timeout_s``) or refused (non-finite, outside the
  frame or far outside the bounds);
- the plan's setpoint lies outside the fence.

The last safe position is the last setpoint sent (already inside the bounds and the fence), or,
before any, the vehicle's position clamped into the bounds. A plan is taken up (the first one,
a different one, or the plan in force after a hold) only when its setpoint now is within
``resume_distance_m`` of the setpoint sent or of the vehicle: the setpoint never jumps. Until
then the follower holds, waiting for a plan from where the vehicle is (the planner plans from
the odometry the follower feeds back). Every setpoint is clamped into the map bounds
(components of velocity and acceleration pushing outwards on a clamped axis are zeroed).
"""

from dataclasses import dataclass, field
import math
from typing import Callable, List, Optional, Set, Tuple

import numpy as np

from uav_global_planner.core.errors import InvalidInputError

#: Reasons of a hold, as they appear on /diagnostics.
NO_PLAN = 'no plan yet'
WITHDRAWN = 'plan withdrawn (empty plan)'
PLAN_LOST = 'plan stream lost'
ODOMETRY_STALE = 'odometry stale'
ODOMETRY_MISSING = 'no odometry yet'
ODOMETRY_REFUSED = 'odometry refused'
OUTSIDE_FENCE = 'setpoint outside the fence'
WAITING = 'waiting for a plan from here'

#: Plan stamps remembered as withdrawn (by an empty ``plan``); older ones are forgotten.
_WITHDRAWN_MEMORY = 64


@dataclass(frozen=True)
class PlanSamples:
    """The ``trajectory`` message as arrays, in the map frame (ENU).

    Attributes
    ----------
    stamp_ns : int
        Header stamp: the plan's time zero [ns].
    frame_id : str
    times : numpy.ndarray, shape (N,)
        Time from the stamp of each point [s], non-decreasing, N >= 1.
    positions, velocities, accelerations : numpy.ndarray, shape (N, 3)
        [m], [m/s], [m/s^2].
    yaws, yaw_rates : numpy.ndarray, shape (N,)
        Heading about +z from +x [rad] and its rate [rad/s].
    """

    stamp_ns: int
    frame_id: str
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    yaws: np.ndarray
    yaw_rates: np.ndarray

    def __post_init__(self) -> None:
        count = len(self.times)
        if count < 1:
            raise InvalidInputError('trajectory: a plan needs at least one point')
        checks = (('times', self.times, (count,)), ('positions', self.positions, (count, 3)),
                  ('velocities', self.velocities, (count, 3)),
                  ('accelerations', self.accelerations, (count, 3)),
                  ('yaws', self.yaws, (count,)), ('yaw_rates', self.yaw_rates, (count,)))
        for name, values, shape in checks:
            array = np.asarray(values, dtype=np.float64)
            if array.shape != shape:
                raise InvalidInputError(f'trajectory {name}: shape {array.shape}, expected '
                                        f'{shape}')
            if not np.all(np.isfinite(array)):
                raise InvalidInputError(f'trajectory {name}: non-finite values')
            object.__setattr__(self, name, array)
        if np.any(np.diff(self.times) < 0.0):
            raise InvalidInputError('trajectory times (time_from_start): not in order')

    @property
    def duration_s(self) -> float:
        """Time from the stamp to the last point [s]."""
        return float(self.times[-1])

    def sample(self, t: float) -> 'Setpoint':
        """The reference at ``t`` seconds after the stamp (clamped to [times[0], end])."""
        times = self.times
        if t >= times[-1] or len(times) == 1:
            return Setpoint(self.positions[-1].copy(), np.zeros(3), np.zeros(3),
                            float(self.yaws[-1]), 0.0)
        t = max(t, float(times[0]))
        k = int(np.searchsorted(times, t, side='right')) - 1
        k = min(max(k, 0), len(times) - 2)
        dt = float(times[k + 1] - times[k])
        if dt <= 0.0:
            return Setpoint(self.positions[k + 1].copy(), self.velocities[k + 1].copy(),
                            self.accelerations[k + 1].copy(), float(self.yaws[k + 1]),
                            float(self.yaw_rates[k + 1]))
        u = (t - float(times[k])) / dt
        p0, p1 = self.positions[k], self.positions[k + 1]
        v0, v1 = self.velocities[k], self.velocities[k + 1]
        a0, a1 = self.accelerations[k], self.accelerations[k + 1]
        position = _hermite(p0, v0, p1, v1, u, dt)
        velocity = _hermite(v0, a0, v1, a1, u, dt)
        acceleration = a0 + u * (a1 - a0)
        step = math.remainder(float(self.yaws[k + 1] - self.yaws[k]), 2.0 * math.pi)
        yaw = math.remainder(float(self.yaws[k]) + u * step, 2.0 * math.pi)
        rate = float(self.yaw_rates[k] + u * (self.yaw_rates[k + 1] - self.yaw_rates[k]))
        return Setpoint(position, velocity, acceleration, yaw, rate)


def _hermite(y0: np.ndarray, d0: np.ndarray, y1: np.ndarray, d1: np.ndarray, u: float,
             dt: float) -> np.ndarray:
    """Cubic Hermite value at ``u`` in [0, 1] of values ``y`` and time derivatives ``d``."""
    u2, u3 = u * u, u * u * u
    return ((2 * u3 - 3 * u2 + 1) * y0 + (u3 - 2 * u2 + u) * dt * d0
            + (-2 * u3 + 3 * u2) * y1 + (u3 - u2) * dt * d1)


@dataclass(frozen=True)
class Setpoint:
    """A setpoint in the map frame (ENU).

    Attributes
    ----------
    position, velocity, acceleration : numpy.ndarray, shape (3,)
        [m], [m/s], [m/s^2].
    yaw : float
        Heading about +z from +x [rad].
    yaw_rate : float
        [rad/s].
    jerk : numpy.ndarray, shape (3,)
        [m/s^3]; NaN: not set (the trajectory message carries none).
    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: float
    yaw_rate: float
    jerk: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))


@dataclass(frozen=True)
class Command:
    """What to send now: a setpoint, and whether it is a hold and why.

    Attributes
    ----------
    setpoint : Setpoint
    holding : bool
    reasons : tuple of str
        The hold's reasons (empty when following).
    plan_stamp_ns : int or None
        Stamp of the plan in force (None: none).
    clamped : bool
        The plan's setpoint was moved into the bounds.
    """

    setpoint: Setpoint
    holding: bool
    reasons: Tuple[str, ...]
    plan_stamp_ns: Optional[int]
    clamped: bool = False


@dataclass(frozen=True)
class FollowerSettings:
    """Settings of the follower.

    Attributes
    ----------
    frame_id : str
        The planner's map frame; a plan in another frame is refused.
    bounds_min, bounds_max : tuple of 3 float
        The map bounds [m] (ENU); every setpoint is clamped into them.
    odometry_timeout_s : float
        Odometry older than this holds [s], > 0.
    plan_timeout_s : float
        No plan publisher for this long holds [s], > 0.
    resume_distance_m : float
        A plan is taken up only where its setpoint is this close to the setpoint sent or to
        the vehicle [m], >= 0.
    odometry_margin_m : float
        Odometry farther than this outside the bounds is refused as out of frame [m], >= 0.
    """

    frame_id: str = 'map'
    bounds_min: Tuple[float, float, float] = (-10.0, -10.0, 0.0)
    bounds_max: Tuple[float, float, float] = (10.0, 10.0, 15.0)
    odometry_timeout_s: float = 0.5
    plan_timeout_s: float = 2.0
    resume_distance_m: float = 0.5
    odometry_margin_m: float = 5.0

    def __post_init__(self) -> None:
        low = np.asarray(self.bounds_min, dtype=np.float64)
        high = np.asarray(self.bounds_max, dtype=np.float64)
        if low.shape != (3,) or high.shape != (3,):
            raise InvalidInputError('bounds.min and bounds.max need 3 values each')
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low < high)):
            raise InvalidInputError(f'bounds.min {low.tolist()} must be finite and below '
                                    f'bounds.max {high.tolist()} on every axis')
        for name in ('odometry_timeout_s', 'plan_timeout_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidInputError(f'{name} must be a positive number of seconds, got '
                                        f'{value}')
        for name in ('resume_distance_m', 'odometry_margin_m'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InvalidInputError(f'{name} must be a non-negative distance [m], got '
                                        f'{value}')
        if not self.frame_id.strip():
            raise InvalidInputError('frame_id must not be empty')


@dataclass(frozen=True)
class VehicleState:
    """The vehicle's state as the autopilot reports it, converted to the map frame.

    Attributes
    ----------
    position : numpy.ndarray, shape (3,)
        [m], ENU map frame.
    orientation : numpy.ndarray, shape (4,) or None
        FLU body to ENU, (x, y, z, w); None when unknown.
    velocity : numpy.ndarray, shape (3,) or None
        [m/s], ENU map frame; None when unknown.
    angular_velocity : numpy.ndarray, shape (3,) or None
        [rad/s], FLU body frame; None when unknown.
    refused : str
        Why the sample cannot be used ('' when it can); the other fields are then meaningless.
    """

    position: np.ndarray
    orientation: Optional[np.ndarray] = None
    velocity: Optional[np.ndarray] = None
    angular_velocity: Optional[np.ndarray] = None
    refused: str = ''


@dataclass
class _Odometry:
    position: Optional[np.ndarray] = None
    received_ns: Optional[int] = None
    refused: str = ''


class Follower:
    """The plan in force sampled into setpoints, and the hold decisions.

    Not thread-safe: one caller (or a lock around every call).

    Parameters
    ----------
    settings : FollowerSettings
    fence : callable, optional
        ``fence(position)`` is True when the ENU position [m] lies inside the fence and outside
        every exclusion zone; None: no fence beyond the bounds.
    """

    def __init__(self, settings: FollowerSettings,
                 fence: Optional[Callable[[np.ndarray], bool]] = None) -> None:
        self.settings = settings
        self._fence = fence
        self._low = np.asarray(settings.bounds_min, dtype=np.float64)
        self._high = np.asarray(settings.bounds_max, dtype=np.float64)
        self._current: Optional[PlanSamples] = None
        self._pending: List[PlanSamples] = []
        self._withdrawn = False
        self._withdrawn_stamps: List[int] = []
        self._plan_stamps: Set[int] = set()
        self._odometry = _Odometry()
        self._planner_seen_ns: Optional[int] = None
        self._hold: Optional[Setpoint] = None
        self._flown_stamp: Optional[int] = None
        self._last: Optional[Setpoint] = None

    # ----------------------------------------------------------------------------------
    # Inputs
    # ----------------------------------------------------------------------------------

    def on_trajectory(self, plan: Optional[PlanSamples], now_ns: int) -> None:
        """A ``trajectory`` message: a plan, or None for an empty one (withdrawn).

        Raises
        ------
        InvalidInputError
            For a plan in another frame than ``settings.frame_id``; nothing changes.
        """
        if plan is None:
            self._withdraw(now_ns)
            return
        if plan.frame_id.strip().lstrip('/') != self.settings.frame_id.strip().lstrip('/'):
            raise InvalidInputError(
                f'trajectory in frame {plan.frame_id!r}, the follower flies frame_id '
                f'{self.settings.frame_id!r}: refused (the plan in force is unchanged)')
        if plan.stamp_ns in self._withdrawn_stamps:
            return      # its plan was withdrawn already; the trajectory came late
        self._pending = [plan]
        self._withdrawn = False
        self._promote(now_ns)

    def on_plan_path(self, stamp_ns: int, empty: bool, now_ns: int) -> None:
        """A ``plan`` message (``nav_msgs/Path``): an empty one withdraws every plan whose
        ``plan`` came before it, whichever order the trajectories arrive in."""
        if not empty:
            self._plan_stamps.add(int(stamp_ns))
            if len(self._plan_stamps) > _WITHDRAWN_MEMORY:
                self._plan_stamps.discard(min(self._plan_stamps))
            return
        withdrawn = self._plan_stamps
        self._plan_stamps = set()
        self._withdrawn_stamps = (self._withdrawn_stamps + sorted(withdrawn))[
            -_WITHDRAWN_MEMORY:]
        in_force = [p for p in ([self._current] + self._pending) if p is not None]
        if any(p.stamp_ns in withdrawn for p in in_force):
            self._withdraw(now_ns)

    def on_odometry(self, position: Optional[np.ndarray], now_ns: int,
                    refused: str = '') -> None:
        """The vehicle's position (ENU, map frame) [m] at ``now_ns``, or a refused sample.

        Parameters
        ----------
        position : numpy.ndarray, shape (3,), optional
            None with ``refused`` naming why (wrong frame, unknown frame...).
        refused : str
            Why the transport refused the sample; '' for a usable one.
        """
        if not refused and position is not None:
            p = np.asarray(position, dtype=np.float64).reshape(-1)
            margin = self.settings.odometry_margin_m
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                refused = f'non-finite position {p.tolist()}'
            elif np.any(p < self._low - margin) or np.any(p > self._high + margin):
                refused = (f'position {np.round(p, 3).tolist()} is more than {margin} m outside '
                           f'the bounds of frame {self.settings.frame_id!r} (wrong frame?)')
            else:
                self._odometry = _Odometry(p.copy(), int(now_ns), '')
                return
        self._odometry.refused = refused or 'no position'

    def on_planner_presence(self, present: bool, now_ns: int) -> None:
        """Whether a publisher of the plan exists at ``now_ns``."""
        if present or self._planner_seen_ns is None:
            self._planner_seen_ns = int(now_ns)

    # ----------------------------------------------------------------------------------
    # The setpoint
    # ----------------------------------------------------------------------------------

    def step(self, now_ns: int) -> Optional[Command]:
        """The command at ``now_ns``; None when there is no safe position to send at all
        (neither a setpoint sent before nor an odometry position)."""
        self._promote(now_ns)
        reasons = self._hold_conditions(now_ns)
        plan = self._current
        target: Optional[Setpoint] = None
        clamped = False
        if plan is not None and not self._withdrawn:
            target = plan.sample((now_ns - plan.stamp_ns) * 1e-9)
            target, clamped = self._clamped(target)
            if self._fence is not None and not self._fence(target.position):
                reasons.append(OUTSIDE_FENCE)
        elif not self._withdrawn:
            reasons.append(NO_PLAN)
        if self._withdrawn:
            reasons.insert(0, WITHDRAWN)
        if (not reasons and target is not None and plan is not None
                and (self._hold is not None or plan.stamp_ns != self._flown_stamp)):
            # Taking up a plan (the first, another one, or after a hold): only where its
            # setpoint now is near the setpoint sent or the vehicle, never with a jump.
            references = [p for p in (
                None if self._hold is None else self._hold.position,
                None if self._last is None else self._last.position,
                self._odometry.position) if p is not None]
            gap = min((float(np.linalg.norm(target.position - p)) for p in references),
                      default=0.0)
            if gap > self.settings.resume_distance_m:
                # Constant text (no distance): the reasons change only when the state does.
                reasons.append(f'{WAITING}: the plan in force is more than resume_distance '
                               f'{self.settings.resume_distance_m} m from the setpoint and the '
                               'vehicle')
            else:
                self._hold = None
                self._flown_stamp = plan.stamp_ns
        if reasons or target is None:
            hold = self._hold_setpoint()
            if hold is None:
                return None
            return Command(hold, True, tuple(reasons), plan.stamp_ns if plan else None)
        self._last = target
        return Command(target, False, (), plan.stamp_ns if plan else None, clamped)

    def hold_reasons(self, now_ns: int) -> Tuple[str, ...]:
        """Why the follower holds at ``now_ns`` (empty: it follows); changes nothing."""
        reasons = self._hold_conditions(now_ns)
        if self._withdrawn:
            reasons.insert(0, WITHDRAWN)
        return tuple(reasons)

    # ----------------------------------------------------------------------------------

    def _withdraw(self, now_ns: int) -> None:
        self._current = None
        self._pending = []
        self._withdrawn = True
        self._hold_setpoint()

    def _promote(self, now_ns: int) -> None:
        """The newest plan whose stamp has come takes over from the one in force."""
        while self._pending and self._pending[0].stamp_ns <= now_ns:
            self._current = self._pending.pop(0)

    def _hold_conditions(self, now_ns: int) -> List[str]:
        reasons = []
        s = self.settings
        if (self._planner_seen_ns is not None
                and now_ns - self._planner_seen_ns > s.plan_timeout_s * 1e9):
            reasons.append(PLAN_LOST)
        odometry = self._odometry
        if odometry.refused:
            reasons.append(f'{ODOMETRY_REFUSED}: {odometry.refused}')
        elif odometry.received_ns is None:
            reasons.append(ODOMETRY_MISSING)
        elif now_ns - odometry.received_ns > s.odometry_timeout_s * 1e9:
            reasons.append(f'{ODOMETRY_STALE} (none for more than odometry_timeout '
                           f'{s.odometry_timeout_s} s)')
        return reasons

    def _hold_setpoint(self) -> Optional[Setpoint]:
        """The hold setpoint, latched when the hold begins."""
        if self._hold is None:
            if self._last is not None:
                position, yaw = self._last.position, self._last.yaw
            elif self._odometry.position is not None:
                position, yaw = self._odometry.position, float('nan')
            else:
                return None
            position = np.clip(position, self._low, self._high)
            self._hold = Setpoint(position.copy(), np.zeros(3), np.zeros(3), yaw, 0.0)
        return self._hold

    def _clamped(self, target: Setpoint) -> Tuple[Setpoint, bool]:
        position = np.clip(target.position, self._low, self._high)
        low_side = target.position < self._low
        high_side = target.position > self._high
        if not (np.any(low_side) or np.any(high_side)):
            return target, False
        velocity = target.velocity.copy()
        acceleration = target.acceleration.copy()
        outward_v = (low_side & (velocity < 0.0)) | (high_side & (velocity > 0.0))
        outward_a = (low_side & (acceleration < 0.0)) | (high_side & (acceleration > 0.0))
        velocity[outward_v] = 0.0
        acceleration[outward_a] = 0.0
        return Setpoint(position, velocity, acceleration, target.yaw, target.yaw_rate), True
