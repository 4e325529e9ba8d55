"""Result types of the planner: frozen dataclasses with numpy fields in metres and seconds."""

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Optional, Tuple

import numpy as np

from uav_global_planner.core.status import PlanStatus

_EMPTY_PATH = np.empty((0, 3))


@dataclass(frozen=True, eq=False, kw_only=True)
class Trajectory:
    """Time-parameterised smoothed path.

    Attributes
    ----------
    times : numpy.ndarray, shape (M,)
        Time from start of each sample [s], increasing from 0.
    positions, velocities, accelerations : numpy.ndarray, shape (M, 3)
        [m], [m/s], [m/s^2] in the planning frame.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    @property
    def duration_s(self) -> float:
        """Time to fly the whole trajectory [s]."""
        return float(self.times[-1]) if len(self.times) else 0.0


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
        The certified continuous curve (:class:`~uav_global_planner.core.curve.PathCurve`),
        for later clearance checks against new obstacles; None on failure.
    total_time_s : float
        Wall-clock time of the whole request [s].
    energy : EnergyEstimate or None
        Flight time and energy of the trajectory for the configured vehicle
        (:func:`uav_global_planner.core.energy.estimate_energy`); None on failure.
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
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
