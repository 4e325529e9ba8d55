"""The planner facade: one object that owns the grid and answers planning requests.

It keeps the inflated grid and the search workspace between requests and rebuilds them only when
the bounds, delta, gamma or the obstacles change. :meth:`Planner.plan` never raises a planning
failure: it returns a :class:`~uav_global_planner.core.result.PlanResult` whose ``status`` says
what happened, so the ROS node and the command-line tool report failures the same way.

Not thread-safe: call it from one thread at a time.
"""

import math
import time
from typing import Optional

import numpy as np

from uav_global_planner.core.config import ALGORITHMS, PlannerConfig, validate_config
from uav_global_planner.core.errors import (GoalOccupiedError, GoalOutsideMapError,
                                            InvalidInputError, NoValidPathError,
                                            PlanningError, StartOccupiedError,
                                            StartOutsideMapError)
from uav_global_planner.core.grid import as_point, VoxelGrid
from uav_global_planner.core.inflation import blocked_mask
from uav_global_planner.core.obstacles import ObstacleSet
from uav_global_planner.core.result import PlanResult, polyline_length
from uav_global_planner.core.search import SearchWorkspace
from uav_global_planner.core.smoothing import smooth_path
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.core.timing import time_parameterize

# Extra inflation of the fallback grid: a segment between two 26-neighbour nodes lies within
# delta * sqrt(3) / 2 of one of them and the obstacle distance is 1-Lipschitz, so on a grid
# inflated by gamma + delta * sqrt(3) / 2 the raw polyline itself keeps clearance >= gamma.
_LIPSCHITZ_FACTOR = math.sqrt(3.0) / 2.0

# Relative room, in cells, kept between an endpoint and the safety margin.
_ENDPOINT_TOLERANCE = 1e-5

# Points closer than this to their snapped node are taken as the node itself [m].
_SNAP_TOLERANCE = 1e-9


class _InflatedGrid:
    """A grid and its blocked mask for one safety margin."""

    def __init__(self, grid: VoxelGrid, obstacles: ObstacleSet, margin: float) -> None:
        started = time.perf_counter()
        self.grid = grid
        self.margin = margin
        self.blocked = blocked_mask(grid, obstacles, margin)
        self.build_time_s = time.perf_counter() - started


class Planner:
    """Plans safe, smooth, timed paths through a static set of obstacles.

    Parameters
    ----------
    config : PlannerConfig
        Settings; validated here.
    obstacles : ObstacleSet
        Obstacles in the planning frame [m].

    Raises
    ------
    InvalidInputError
        For invalid settings or obstacles that are not an :class:`ObstacleSet`.
    """

    def __init__(self, config: PlannerConfig = PlannerConfig(),
                 obstacles: Optional[ObstacleSet] = None) -> None:
        self._config = validate_config(config)
        if obstacles is not None and not isinstance(obstacles, ObstacleSet):
            # Checked here, not at the first plan: there it would escape plan() as an
            # AttributeError.
            raise InvalidInputError('obstacles must be an ObstacleSet')
        self._obstacles = obstacles if obstacles is not None else ObstacleSet()
        self._inflated: Optional[_InflatedGrid] = None
        self._fallback: Optional[_InflatedGrid] = None
        # One search workspace (per-node arrays) serves both grids: on large grids a second one
        # would double the memory.
        self._workspace: Optional[SearchWorkspace] = None

    @property
    def config(self) -> PlannerConfig:
        """The settings in force."""
        return self._config

    @property
    def obstacles(self) -> ObstacleSet:
        """The obstacles in force."""
        return self._obstacles

    @property
    def grid(self) -> VoxelGrid:
        """The voxel grid for the current settings (built on first use)."""
        return self._primary().grid

    @property
    def blocked(self) -> np.ndarray:
        """Occupancy of every node for the current settings, shape ``grid.shape``."""
        return self._primary().blocked

    def set_config(self, config: PlannerConfig) -> None:
        """Replace the settings; the grid is rebuilt at the next plan if delta, gamma or the
        bounds changed.

        Raises
        ------
        InvalidInputError
            When the settings are invalid; the previous ones stay in force.
        """
        config = validate_config(config)
        if config.grid_key() != self._config.grid_key() or (
                config.max_voxels != self._config.max_voxels):
            self._invalidate()
        self._config = config

    def set_obstacles(self, obstacles: ObstacleSet) -> None:
        """Replace the obstacles; the grid is re-inflated at the next plan."""
        if not isinstance(obstacles, ObstacleSet):
            raise InvalidInputError('obstacles must be an ObstacleSet')
        self._obstacles = obstacles
        self._invalidate()

    def warm_up(self) -> None:
        """Compile the search kernels and build the grid, so the first real plan is fast."""
        inflated = self._primary()
        free = np.flatnonzero(~inflated.blocked.reshape(-1))
        if len(free) == 0:
            return
        node = inflated.grid.unravel(free[0])
        for algorithm in ALGORITHMS:
            self._search(inflated, node, node, algorithm)

    def path_is_clear(self, positions) -> bool:
        """True when the polyline through ``positions`` keeps clearance >= gamma everywhere.

        Parameters
        ----------
        positions : array_like, shape (M, 3)
            Polyline vertices [m], checked on a sampling no coarser than delta / 20.
        """
        points = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        if len(points) == 0 or self._obstacles.is_empty():
            return True
        dense = densify(points, self._config.resolution / 20.0)
        return bool(np.min(self._obstacles.distance(dense)) >= self._config.safety_margin)

    def plan(self, start, goal, algorithm: Optional[str] = None) -> PlanResult:
        """Plan from ``start`` to ``goal``.

        Parameters
        ----------
        start, goal : array_like, shape (3,)
            Positions in the planning frame [m]; each snaps to its nearest grid node, and the
            smoothed curve begins and ends exactly at the given points.
        algorithm : str, optional
            Heuristic name; defaults to ``config.algorithm``.

        Returns
        -------
        PlanResult
            ``status`` is ``ok`` or names the failure; ``message`` explains it.
        """
        config = self._config
        name = config.algorithm if algorithm is None else algorithm
        start_point = _point_or_nan(start)
        goal_point = _point_or_nan(goal)
        base = dict(algorithm=str(name), start=start_point, goal=goal_point,
                    resolution=config.resolution, safety_margin=config.safety_margin,
                    adaptive_threshold=config.adaptive_threshold)
        try:
            return self._plan(start, goal, name, base)
        except PlanningError as error:
            return PlanResult(status=error.status, message=str(error), **base,
                              expanded_nodes=error.expanded_nodes)

    def _plan(self, start, goal, name: str, base: dict) -> PlanResult:
        config = self._config
        if name not in ALGORITHMS:
            raise InvalidInputError(
                f'algorithm must be one of {", ".join(ALGORITHMS)}, got {name!r}')
        start_point = as_point(start, 'start')
        goal_point = as_point(goal, 'goal')
        build_time = 0.0 if self._inflated is not None else math.nan
        inflated = self._primary()
        if math.isnan(build_time):
            build_time = inflated.build_time_s
        grid = inflated.grid
        start_node, goal_node = self._check_endpoints(inflated, start_point, goal_point)

        found = self._search(inflated, start_node, goal_node, name)
        path = grid.index_to_world(found.path_indices)
        smoothing_started = time.perf_counter()
        waypoints = _with_exact_endpoints(path, start_point, goal_point)
        try:
            smoothed = self._smooth(waypoints)
        except NoValidPathError as first_error:
            # The grid path hugs the inflated obstacles so closely that no curve through it keeps
            # gamma: plan once more on the conservative grid, whose polyline provably does.
            fallback = self._conservative()
            try:
                start_node, goal_node = self._check_endpoints(fallback, start_point, goal_point)
            except (StartOccupiedError, GoalOccupiedError) as error:
                # The endpoint keeps gamma (checked on the primary grid): only the wider margin
                # of the fallback grid blocks it, so the request is not "occupied".
                which = 'start' if isinstance(error, StartOccupiedError) else 'goal'
                raise NoValidPathError(
                    f'{first_error}; and the grid inflated for edge clearance (gamma + '
                    f'delta*sqrt(3)/2 = {fallback.margin:.4f} m) blocks the {which} node',
                    expanded_nodes=found.expanded_nodes) from None
            try:
                found = self._search(fallback, start_node, goal_node, name)
            except NoValidPathError:
                raise NoValidPathError(f'{first_error}; and no path exists on the grid '
                                       'inflated for edge clearance',
                                       expanded_nodes=found.expanded_nodes) from None
            path = grid.index_to_world(found.path_indices)
            waypoints = _with_exact_endpoints(path, start_point, goal_point)
            smoothed = self._smooth(waypoints)
            build_time += fallback.build_time_s
        trajectory = time_parameterize(smoothed, config.max_speed_horizontal,
                                       config.max_speed_vertical, config.max_accel_horizontal,
                                       config.max_accel_vertical)
        smoothing_time = time.perf_counter() - smoothing_started
        repaired = len(smoothed.repaired_stretches)
        message = (f'path of {polyline_length(path):.3f} m over {len(path)} nodes, '
                   f'{found.expanded_nodes} nodes expanded; smoothed {smoothed.length_m:.3f} m, '
                   f'min clearance {smoothed.min_clearance_m:.3f} m'
                   + (f', {repaired} stretch(es) repaired' if repaired else ''))
        return PlanResult(
            status=PlanStatus.OK, message=message, **base, path=path,
            path_length_m=polyline_length(path), expanded_nodes=found.expanded_nodes,
            planning_time_s=found.search_time_s, grid_build_time_s=build_time,
            shortcut_path=smoothed.shortcut_path, shortcut_length_m=smoothed.shortcut_length_m,
            trajectory=trajectory, smoothed_length_m=smoothed.length_m,
            min_clearance_m=smoothed.min_clearance_m,
            min_clearance_point=smoothed.min_clearance_point,
            repaired_stretches=tuple(smoothed.repaired_stretches),
            smoothing_time_s=smoothing_time)

    def _search(self, inflated: _InflatedGrid, start_node, goal_node, algorithm: str):
        config = self._config
        if self._workspace is None or self._workspace.shape != inflated.grid.shape:
            self._workspace = SearchWorkspace(inflated.blocked)
        elif self._workspace.blocked is not inflated.blocked:
            self._workspace.set_blocked(inflated.blocked)
        return self._workspace.search(start_node, goal_node, algorithm, config.resolution,
                                      config.adaptive_threshold, config.max_expansions,
                                      config.max_planning_time)

    def _smooth(self, waypoints: np.ndarray):
        config = self._config
        grid = self._primary().grid
        return smooth_path(waypoints, self._obstacles, config.safety_margin, config.resolution,
                           shortcut=config.shortcut, mode=config.smoothing,
                           sample_spacing=config.sample_spacing, index_step=config.index_step,
                           bounds=(grid.bounds_min, grid.bounds_max))

    def _check_endpoints(self, inflated: _InflatedGrid, start: np.ndarray, goal: np.ndarray):
        grid = inflated.grid
        gamma = self._config.safety_margin
        if not grid.contains(start):
            raise StartOutsideMapError(
                f'start {start.tolist()} is outside the bounds {grid.bounds_min.tolist()} .. '
                f'{grid.bounds_max.tolist()}')
        if not grid.contains(goal):
            raise GoalOutsideMapError(
                f'goal {goal.tolist()} is outside the bounds {grid.bounds_min.tolist()} .. '
                f'{grid.bounds_max.tolist()}')
        start_node = grid.world_to_index(start)
        goal_node = grid.world_to_index(goal)
        # The smoothed curve must keep gamma with a little room for rounding (the clearance
        # check of smoothing needs it), so endpoints that close to the margin count as occupied.
        # (The messages give the true clearance: with the room taken off, an endpoint inside an
        # obstacle would read "its clearance is -0.000 m".)
        true_clearances = self._obstacles.distance(np.stack([start, goal]))
        clearances = true_clearances - _ENDPOINT_TOLERANCE * self._config.resolution
        if inflated.blocked[tuple(start_node)] or clearances[0] <= gamma:
            raise StartOccupiedError(
                f'start {start.tolist()} is within the safety margin: its clearance is '
                f'{min(true_clearances[0], self._node_clearance(grid, start_node)):.3f} m, '
                f'gamma is {gamma} m')
        if inflated.blocked[tuple(goal_node)] or clearances[1] <= gamma:
            raise GoalOccupiedError(
                f'goal {goal.tolist()} is within the safety margin: its clearance is '
                f'{min(true_clearances[1], self._node_clearance(grid, goal_node)):.3f} m, '
                f'gamma is {gamma} m')
        return start_node, goal_node

    def _node_clearance(self, grid: VoxelGrid, node: np.ndarray) -> float:
        return float(self._obstacles.distance(grid.index_to_world(node)))

    def _primary(self) -> _InflatedGrid:
        if self._inflated is None:
            self._inflated = _InflatedGrid(self._make_grid(), self._obstacles,
                                           self._config.safety_margin)
        return self._inflated

    def _conservative(self) -> _InflatedGrid:
        if self._fallback is None:
            config = self._config
            margin = config.safety_margin + _LIPSCHITZ_FACTOR * config.resolution
            self._fallback = _InflatedGrid(self._primary().grid, self._obstacles, margin)
        return self._fallback

    def _make_grid(self) -> VoxelGrid:
        config = self._config
        return VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution,
                                     config.max_voxels)

    def _invalidate(self) -> None:
        self._inflated = None
        self._fallback = None


def densify(points: np.ndarray, spacing: float) -> np.ndarray:
    """Polyline vertices plus evenly spaced points on every segment, no gap above ``spacing``.

    Parameters
    ----------
    points : numpy.ndarray, shape (M, 3)
        Vertices [m].
    spacing : float
        Largest distance between consecutive output points [m].
    """
    if len(points) < 2:
        return points
    segments = np.diff(points, axis=0)
    counts = np.maximum(np.ceil(np.linalg.norm(segments, axis=1) / spacing), 1).astype(int)
    fractions = np.concatenate([np.arange(n) / n for n in counts])
    owners = np.repeat(np.arange(len(segments)), counts)
    return np.vstack([points[owners] + fractions[:, None] * segments[owners], points[-1:]])


def _point_or_nan(value) -> np.ndarray:
    try:
        return as_point(value, 'point')
    except InvalidInputError:
        return np.full(3, np.nan)


def _with_exact_endpoints(path: np.ndarray, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """The node path with the exact start and goal added where they are off the nodes.

    A goal equal to the start (within the snap tolerance) is a single-point plan at the start:
    adding both to an off-node path would make a there-and-back curve through the node with a
    zero-length closing segment, which no spline can be fitted to.
    """
    if np.linalg.norm(goal - start) <= _SNAP_TOLERANCE:
        return start[None, :].copy()
    parts = []
    if np.linalg.norm(path[0] - start) > _SNAP_TOLERANCE:
        parts.append(start[None, :])
    parts.append(path)
    if np.linalg.norm(path[-1] - goal) > _SNAP_TOLERANCE:
        parts.append(goal[None, :])
    return np.vstack(parts) if len(parts) > 1 else path
