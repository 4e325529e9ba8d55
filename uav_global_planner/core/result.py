"""Result types of the planner: frozen dataclasses with numpy fields in metres and seconds."""

from dataclasses import dataclass, field
from enum import StrEnum
import math
from typing import Any, Optional, Protocol, Tuple

import numpy as np

from uav_global_planner.core.path.motion_limits import tilt_and_thrust
from uav_global_planner.core.status import PlanStatus

_EMPTY_PATH = np.empty((0, 3))


@dataclass(frozen=True, eq=False, kw_only=True)
class ReferenceState:
    """States of the continuous timed reference at some times (ENU, planning frame).

    Attributes
    ----------
    time : numpy.ndarray, shape (N,)
        [s] from the start of the trajectory.
    position, velocity, acceleration, jerk : numpy.ndarray, shape (N, 3)
        [m], [m/s], [m/s^2], [m/s^3].
    yaw : numpy.ndarray, shape (N,)
        Heading [rad]: 0 along +x, counter-clockwise positive (ENU).
    yaw_rate : numpy.ndarray, shape (N,)
        [rad/s].
    """

    time: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    yaw: np.ndarray
    yaw_rate: np.ndarray


@dataclass(frozen=True, kw_only=True)
class TrajectoryPeaks:
    """Largest values the reference reaches, from its state every ``step_s`` seconds.

    Attributes
    ----------
    speed_horizontal, speed_vertical : float
        [m/s].
    accel_horizontal, accel_vertical : float
        [m/s^2].
    jerk : float
        Norm [m/s^3].
    tilt_deg : float
        Tilt of the collective thrust from the vertical [deg].
    thrust_to_weight : float
        Collective thrust over weight [-].
    yaw_rate : float
        [rad/s].
    step_s : float
        Time step of the states they were taken from [s].
    """

    speed_horizontal: float
    speed_vertical: float
    accel_horizontal: float
    accel_vertical: float
    jerk: float
    tilt_deg: float
    thrust_to_weight: float
    yaw_rate: float
    step_s: float


class ContinuousReference(Protocol):
    """The exact timed reference.

    See :class:`uav_global_planner.core.path.reference.TimedReference`.
    """

    @property
    def duration_s(self) -> float:
        ...

    def evaluate(self, times: np.ndarray) -> ReferenceState:
        ...


@dataclass(frozen=True, eq=False, kw_only=True)
class Trajectory:
    """Time-parameterised smoothed path: samples, and the continuous reference they come from.

    Attributes
    ----------
    times : numpy.ndarray, shape (M,)
        Time from start of each sample [s], increasing from 0.
    positions, velocities, accelerations : numpy.ndarray, shape (M, 3)
        [m], [m/s], [m/s^2] in the planning frame (ENU).
    jerks : numpy.ndarray, shape (M, 3), optional
        [m/s^3].
    yaws, yaw_rates : numpy.ndarray, shape (M,), optional
        Heading [rad] (0 along +x, counter-clockwise) and its rate [rad/s].
    reference : ContinuousReference, optional
        The exact reference, at any time (:meth:`state_at`); None for a trajectory rebuilt
        from samples, which :meth:`state_at` then interpolates.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    jerks: Optional[np.ndarray] = None
    yaws: Optional[np.ndarray] = None
    yaw_rates: Optional[np.ndarray] = None
    reference: Optional[ContinuousReference] = None

    @property
    def duration_s(self) -> float:
        """Time to fly the whole trajectory [s]."""
        return float(self.times[-1]) if len(self.times) else 0.0

    def state_at(self, times: Any) -> ReferenceState:
        """The reference at ``times`` [s] (a number or an array), clamped to [0, duration].

        Exact on the continuous reference; a trajectory without one (rebuilt from samples)
        is interpolated linearly between its samples, with zero jerk.
        """
        t = np.clip(np.asarray(times, dtype=np.float64).reshape(-1), 0.0, self.duration_s)
        if self.reference is not None:
            return self.reference.evaluate(t)
        count = len(t)
        if not len(self.times):
            empty = np.zeros((count, 3))
            return ReferenceState(time=t, position=empty, velocity=empty, acceleration=empty,
                                  jerk=empty, yaw=np.zeros(count), yaw_rate=np.zeros(count))

        def column(values: np.ndarray) -> np.ndarray:
            return np.stack([np.interp(t, self.times, values[:, k]) for k in range(3)], axis=1)

        yaws = self.yaws if self.yaws is not None else np.zeros(len(self.times))
        rates = self.yaw_rates if self.yaw_rates is not None else np.zeros(len(self.times))
        return ReferenceState(time=t, position=column(self.positions),
                              velocity=column(self.velocities),
                              acceleration=column(self.accelerations),
                              jerk=np.zeros((count, 3)), yaw=np.interp(t, self.times, yaws),
                              yaw_rate=np.interp(t, self.times, rates))

    def sampled(self, period: float) -> 'Trajectory':
        """The reference every ``period`` seconds, the last sample at the end [s].

        Raises
        ------
        ValueError
            When ``period`` is not a positive finite number.
        """
        if not (math.isfinite(period) and period > 0.0):
            raise ValueError(f'sample period must be a positive number of seconds, got {period}')
        if not len(self.times):
            return self
        duration = self.duration_s
        count = int(math.floor(duration / period + 1e-9))
        times = np.arange(count + 1) * period
        if duration - times[-1] > 1e-9 * max(1.0, duration):
            times = np.r_[times, duration]
        else:
            times[-1] = duration
        state = self.state_at(times)
        return Trajectory(times=times, positions=state.position, velocities=state.velocity,
                          accelerations=state.acceleration, jerks=state.jerk, yaws=state.yaw,
                          yaw_rates=state.yaw_rate, reference=self.reference)

    def peaks(self, step_s: float = 0.01) -> TrajectoryPeaks:
        """Largest speed, acceleration, jerk, tilt, thrust and yaw rate every ``step_s`` [s].

        The limits are kept by construction between samples too (see
        :mod:`uav_global_planner.core.path.timing`); this is what a user or a test measures.
        """
        duration = self.duration_s
        count = max(2, int(math.ceil(duration / step_s)) + 1)
        state = self.state_at(np.linspace(0.0, duration, count))
        tilt, thrust = tilt_and_thrust(state.acceleration)

        def top(values: np.ndarray) -> float:
            return float(np.max(values)) if len(values) else 0.0

        return TrajectoryPeaks(
            speed_horizontal=top(np.hypot(state.velocity[:, 0], state.velocity[:, 1])),
            speed_vertical=top(np.abs(state.velocity[:, 2])),
            accel_horizontal=top(np.hypot(state.acceleration[:, 0], state.acceleration[:, 1])),
            accel_vertical=top(np.abs(state.acceleration[:, 2])),
            jerk=top(np.linalg.norm(state.jerk, axis=1)), tilt_deg=top(tilt),
            thrust_to_weight=top(thrust), yaw_rate=top(np.abs(state.yaw_rate)),
            step_s=duration / (count - 1))


class RepairMethod(StrEnum):
    """How a stretch of the smoothed curve was repaired to keep the safety margin."""

    #: More spline knots, taken on the shortcut polyline.
    KNOTS = 'knots'
    #: The shortcut polyline itself, straight, with stops at its ends.
    POLYLINE = 'polyline'


@dataclass(frozen=True, kw_only=True)
class RepairedStretch:
    """A stretch of the smoothed curve that had to be repaired to keep the safety margin.

    Attributes
    ----------
    start_m, end_m : float
        Arc-length interval of the repaired stretch on the final curve [m].
    method : RepairMethod
        How it was repaired.
    clearance_before_m : float
        Smallest clearance of the unrepaired curve on that stretch [m].
    """

    start_m: float
    end_m: float
    method: RepairMethod
    clearance_before_m: float


@dataclass(frozen=True, kw_only=True)
class LegResult:
    """One leg of a plan through via-points: from one via-point (or the start) to the next.

    Attributes
    ----------
    index : int
        Leg number, 0 for the leg from the start.
    path_length_m : float
        Length of the leg's grid-node path [m] (NaN when it was not searched).
    smoothed_length_m : float
        Arc length of the smoothed curve over the leg [m] (NaN on failure).
    duration_s : float
        Flight time of the leg on the timed trajectory [s] (NaN on failure).
    expanded_nodes : int
        Nodes the leg's search expanded.
    cost : float
        Search cost of the leg's grid-node path [m] (its length with both climb and descent
        weights 1; NaN when it was not searched).
    """

    index: int
    path_length_m: float = float('nan')
    smoothed_length_m: float = float('nan')
    duration_s: float = float('nan')
    expanded_nodes: int = 0
    cost: float = float('nan')


@dataclass(frozen=True, eq=False, kw_only=True)
class PlanResult:
    """Everything one planning request produced; ``status`` says whether it succeeded.

    Attributes
    ----------
    status : PlanStatus
    message : str
        Human-readable reason, naming the offending input on failure.
    algorithm : str
    start, goal : numpy.ndarray, shape (3,)
        Requested start and goal [m] (NaN where the request had none usable).
    path : numpy.ndarray, shape (N, 3)
        Raw grid-node path [m], start node to goal node; empty on failure.
    path_length_m : float
        Length of ``path`` (eq. 15) [m]; NaN on failure.
    cost : float
        Search cost of ``path`` [m]: the sum of its step costs with the climb and descent
        weights of the energy-aware cost (the length when both are 1); NaN on failure.
    expanded_nodes : int
        Nodes taken off the open list by the search.
    planning_time_s : float
        Search time (eq. 14) [s].
    resolution, safety_margin, adaptive_threshold : float
        delta, gamma and eta used [m].
    grid_build_time_s : float
        Time spent building and inflating the grid for this request [s]; 0 when cached.
    shortcut_path : numpy.ndarray, shape (K, 3)
        Path after line-of-sight shortcutting [m] (equals ``path`` when shortcutting is off).
    shortcut_length_m : float
    trajectory : Trajectory or None
        Smoothed, time-parameterised path; None on failure.
    smoothed_length_m : float
    min_clearance_m : float
        Smallest distance from the smoothed curve to any obstacle [m].
    min_clearance_point : numpy.ndarray, shape (3,)
        Where that smallest distance occurs [m].
    repaired_stretches : tuple of RepairedStretch
    smoothing_time_s : float
        Time for shortcutting, smoothing, clearance check and timing [s].
    via : numpy.ndarray, shape (V, 3)
        Via-points the curve passes through exactly, in order [m].
    legs : tuple of LegResult
        One per leg (V + 1 of them) once planned; the legs searched so far on failure.
    failed_leg : int
        The leg that failed (-1 when none, or when the failure is not a leg's).
    curve : PathCurve or None
        The certified continuous curve (:class:`~uav_global_planner.core.path.curve.PathCurve`),
        for later clearance checks against new obstacles; None on failure.
    total_time_s : float
        Wall-clock time of the whole request [s].
    energy : EnergyEstimate or None
        Flight time and energy of the trajectory for the configured vehicle
        (:func:`uav_global_planner.core.path.energy.estimate_energy`); None on failure.
    planning_margin : float
        Clearance the curve keeps [m]: gamma + vehicle radius + tracking margin.
    start_velocity, start_acceleration : numpy.ndarray, shape (3,)
        The moving state the plan was asked to continue [m/s], [m/s^2]; zeros from rest.
    handover_velocity_error, handover_accel_error : float
        Norm of the difference between that state and the reference at time 0 [m/s],
        [m/s^2]; 0 when the plan continues it exactly.
    unknown_length_m : float
        Length of the smoothed curve (the polyline through its samples) inside space the map
        never observed [m] (:mod:`uav_global_planner.core.map.unknown_space`); 0 when the map
        declares none or the curve avoids it, NaN on failure. A report, not a safety check.
    """

    status: PlanStatus
    message: str
    algorithm: str
    start: np.ndarray
    goal: np.ndarray
    path: np.ndarray = field(default_factory=lambda: _EMPTY_PATH)
    path_length_m: float = float('nan')
    cost: float = float('nan')
    expanded_nodes: int = 0
    planning_time_s: float = 0.0
    resolution: float = float('nan')
    safety_margin: float = float('nan')
    adaptive_threshold: float = float('nan')
    grid_build_time_s: float = 0.0
    shortcut_path: np.ndarray = field(default_factory=lambda: _EMPTY_PATH)
    shortcut_length_m: float = float('nan')
    trajectory: Optional[Trajectory] = None
    smoothed_length_m: float = float('nan')
    min_clearance_m: float = float('nan')
    min_clearance_point: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    repaired_stretches: Tuple[RepairedStretch, ...] = ()
    smoothing_time_s: float = 0.0
    via: np.ndarray = field(default_factory=lambda: _EMPTY_PATH)
    legs: Tuple[LegResult, ...] = ()
    failed_leg: int = -1
    curve: Optional[Any] = None
    total_time_s: float = 0.0
    energy: Optional[Any] = None
    planning_margin: float = float('nan')
    start_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    start_acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))
    handover_velocity_error: float = 0.0
    handover_accel_error: float = 0.0
    unknown_length_m: float = float('nan')

    def refused(self, status: PlanStatus, message: str) -> 'PlanResult':
        """This request as a failure with ``status`` and ``message``: what a plan becomes when
        a later check (a newer map) refuses it; no path, the request's figures kept."""
        return PlanResult(status=status, message=message, algorithm=self.algorithm,
                          start=self.start, goal=self.goal, resolution=self.resolution,
                          safety_margin=self.safety_margin,
                          adaptive_threshold=self.adaptive_threshold,
                          planning_margin=self.planning_margin,
                          expanded_nodes=self.expanded_nodes, total_time_s=self.total_time_s)

    @property
    def ok(self) -> bool:
        """True when a safe path was found."""
        return self.status is PlanStatus.OK

    @property
    def smoothed_path(self) -> np.ndarray:
        """Positions of the smoothed curve [m], shape (M, 3); empty on failure."""
        return self.trajectory.positions if self.trajectory is not None else _EMPTY_PATH

    @property
    def duration_s(self) -> float:
        """Flight time of the trajectory [s]; NaN on failure."""
        return self.trajectory.duration_s if self.trajectory is not None else float('nan')


def polyline_length(points: np.ndarray) -> float:
    """Sum of segment lengths of a polyline (eq. 15) [m]; 0 for fewer than two points."""
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 2:
        return 0.0
    steps = pts[1:] - pts[:-1]
    return float(np.sqrt((steps * steps).sum(axis=1)).sum())
