"""The planner facade: one object that owns the grid and answers planning requests.

It keeps the inflated grid and the search workspace between requests and rebuilds them only when
the bounds, delta, gamma or the obstacles change. :meth:`Planner.plan` never raises a planning
failure: it returns a :class:`~uav_global_planner.core.result.PlanResult` whose ``status`` says
what happened, so the ROS node and the command-line tool report failures the same way.

Not thread-safe: call it from one thread at a time.

One module, though long (about 850 lines): the facade's plan, its legs through via-points, the
budget and the fallback grid are one sequence of stages over one grid and one set of
workspaces.
"""

from dataclasses import dataclass, replace
import math
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.budget import PlanBudget, PlanStage, ProgressCallback
from uav_global_planner.core.config import ALGORITHMS, PlannerConfig, validate_config
from uav_global_planner.core.errors import (GoalOccupiedError, GoalOutsideMapError,
                                            InvalidInputError, NoValidPathError, PlanningError,
                                            StartOccupiedError, StartOutsideMapError)
from uav_global_planner.core.map.grid import as_point, HALF_CELL_DIAGONAL, VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask, Mask
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.sparse_grid import first_free_node
from uav_global_planner.core.map.unknown_space import UnknownSpace
from uav_global_planner.core.map.zone_checks import check_endpoint
from uav_global_planner.core.path.clearance import certify_pieces, certify_polyline, Pieces
from uav_global_planner.core.path.energy import estimate_energy, VehicleModel
from uav_global_planner.core.path.handover import Handover
from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.path.smoothing import smooth_path, SmoothedPath
from uav_global_planner.core.path.timing import time_parameterize
from uav_global_planner.core.path.tracking import tracking_speed_cap
from uav_global_planner.core.result import LegResult, PlanResult, polyline_length, Trajectory
from uav_global_planner.core.search.bounded import bounded_search
from uav_global_planner.core.search.grid_search import SearchWorkspace
from uav_global_planner.core.status import PlanStatus


# Relative room, in cells, kept between an endpoint and the safety margin.
_ENDPOINT_TOLERANCE = 1e-5

# Points closer than this to their snapped node are taken as the node itself [m].
_SNAP_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False, kw_only=True)
class ClearanceVerdict:
    """Outcome of :meth:`Planner.plan_is_clear`.

    Attributes
    ----------
    clear : bool
        True when the checked curve is certified to keep gamma.
    blocked_at : numpy.ndarray of shape (3,), or None
        Where the closest approach of a failing stretch was sampled [m]; None when clear.
    blocked_ahead_m : float
        Arc length from the vehicle (or the start) to the beginning of the failing stretch
        [m]; NaN when clear.
    """

    clear: bool
    blocked_at: Optional[np.ndarray]
    blocked_ahead_m: float = math.nan


class _InflatedGrid:
    """A grid and its blocked mask for one safety margin."""

    def __init__(self, grid: VoxelGrid, obstacles: ObstacleSet, margin: float,
                 blocked: Optional[Mask] = None,
                 checkpoint: Optional[Callable[[], None]] = None) -> None:
        started = time.perf_counter()
        self.grid = grid
        self.margin = margin
        # A mask built elsewhere (a live map, off the planning thread) costs the plan nothing;
        # one built here calls ``checkpoint`` (a plan's budget) between pieces of the build.
        self.blocked = (blocked_mask(grid, obstacles, margin, checkpoint=checkpoint)
                        if blocked is None else blocked)
        self.build_time_s = time.perf_counter() - started
        # Reported by the first plan that uses this grid, whether that plan or warm_up() built it.
        self.reported = blocked is not None

    def unreported_build_time(self) -> float:
        """The build time [s] the first time it is asked for, 0 after that."""
        if self.reported:
            return 0.0
        self.reported = True
        return self.build_time_s


class Planner:
    """Plans safe, smooth, timed paths through a static set of obstacles.

    Parameters
    ----------
    config : PlannerConfig
        Settings; validated here.
    obstacles : ObstacleSet
        Obstacles in the planning frame [m].
    unknown : UnknownSpace, optional
        Space the map never observed (:mod:`uav_global_planner.core.map.unknown_space`); with
        ``config.unknown_space`` occupied its boxes join the obstacles (:attr:`obstacles`).
        Every plan reports the length of its curve inside it.

    Raises
    ------
    InvalidInputError
        For invalid settings or obstacles that are not an :class:`ObstacleSet`.
    """

    def __init__(self, config: PlannerConfig = PlannerConfig(),
                 obstacles: Optional[ObstacleSet] = None, *,
                 unknown: Optional[UnknownSpace] = None) -> None:
        self._config = validate_config(config)
        if obstacles is not None and not isinstance(obstacles, ObstacleSet):
            # Checked here, not at the first plan: there it would escape plan() as an
            # AttributeError.
            raise InvalidInputError('obstacles must be an ObstacleSet')
        self._unknown = _checked_unknown(unknown)
        # The obstacles as given, and with the unknown boxes where they count as solid.
        self._given = obstacles if obstacles is not None else ObstacleSet()
        self._obstacles = self._with_unknown(self._given)
        self._solid_cache: Tuple[Optional[ObstacleSet], Optional[ObstacleSet]] = (None, None)
        # The grid nodes in unknown space, for the cost policy: (grid, layout, mask).
        self._unknown_mask: Optional[Tuple[VoxelGrid, str, Mask]] = None
        self._inflated: Optional[_InflatedGrid] = None
        self._fallback: Optional[_InflatedGrid] = None
        # One search workspace (per-node arrays) serves both grids: on large grids a second one
        # would double the memory.
        self._workspace: Optional[SearchWorkspace] = None
        #: How many times a plan inflated the conservative fallback grid itself.
        self.fallback_builds = 0

    @property
    def config(self) -> PlannerConfig:
        """The settings in force."""
        return self._config

    @property
    def obstacles(self) -> ObstacleSet:
        """The obstacles in force (with the unknown boxes when unknown space is occupied)."""
        return self._obstacles

    @property
    def unknown(self) -> Optional[UnknownSpace]:
        """The unknown space in force, None when the map says nothing about it."""
        return self._unknown

    def set_unknown(self, unknown: Optional[UnknownSpace]) -> None:
        """Replace the unknown space; the grid is re-inflated at the next plan when its boxes
        are obstacles."""
        self._unknown = _checked_unknown(unknown)
        self._recompose()

    def _unknown_is_solid(self, config: Optional[PlannerConfig] = None) -> bool:
        config = self._config if config is None else config
        return (config.unknown_space == 'occupied' and self._unknown is not None
                and not self._unknown.is_empty())

    def _with_unknown(self, obstacles: ObstacleSet) -> ObstacleSet:
        """``obstacles`` plus the unknown boxes when unknown space is occupied."""
        if not self._unknown_is_solid():
            return obstacles
        assert self._unknown is not None
        return ObstacleSet([*obstacles.items, *self._unknown.boxes()])

    def solid(self, obstacles: Optional[ObstacleSet] = None) -> ObstacleSet:
        """What a curve must keep gamma from: the planner's obstacles, or ``obstacles`` (a
        newer map) with the unknown boxes when unknown space is occupied."""
        return self._solid(obstacles)

    def _solid(self, obstacles: Optional[ObstacleSet]) -> ObstacleSet:
        """The planner's obstacles, or ``obstacles`` with the unknown boxes (kept for the
        last set asked for: building a set of many boxes costs time)."""
        if obstacles is None or obstacles is self._given:
            return self._obstacles
        if not self._unknown_is_solid():
            return obstacles
        given, solid = self._solid_cache
        if given is not obstacles or solid is None:
            solid = self._with_unknown(obstacles)
            self._solid_cache = (obstacles, solid)
        return solid

    def _recompose(self) -> None:
        self._obstacles = self._with_unknown(self._given)
        self._solid_cache = (None, None)
        self._invalidate()

    @property
    def grid(self) -> VoxelGrid:
        """The voxel grid for the current settings (built on first use)."""
        return self._primary().grid

    @property
    def blocked(self) -> Mask:
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
        solid = self._unknown_is_solid()
        self._config = config
        if self._unknown_is_solid() != solid:
            self._recompose()

    def set_obstacles(self, obstacles: ObstacleSet) -> None:
        """Replace the obstacles; the grid is re-inflated at the next plan."""
        if not isinstance(obstacles, ObstacleSet):
            raise InvalidInputError('obstacles must be an ObstacleSet')
        self._given = obstacles
        self._recompose()

    def set_map(self, obstacles: ObstacleSet, blocked: Optional[Mask],
                grid_key: Optional[tuple] = None,
                fallback: Optional[Mask] = None) -> bool:
        """Replace the obstacles together with their inflated mask, built elsewhere.

        Parameters
        ----------
        obstacles : ObstacleSet
        blocked : numpy.ndarray of bool, optional
            Occupancy of every node for ``obstacles`` and ``grid_key`` (see
            :func:`~uav_global_planner.core.map.inflation.blocked_mask`); the planner reads it and
            never writes it, and the caller must not change it while the planner may use it.
        grid_key : tuple, optional
            :meth:`PlannerConfig.grid_key` the mask was built for.
        fallback : numpy.ndarray of bool, optional
            The mask of the same obstacles for :func:`fallback_margin` (the conservative grid
            of a plan whose smoothing fails); built by the plan when it needs it if None.

        Returns
        -------
        bool
            True when the mask is used; False when it does not fit the settings in force (or
            is None, or the unknown boxes are obstacles, which the mask does not cover), and
            the grid is then inflated at the next plan, as after :meth:`set_obstacles`.
        """
        self.set_obstacles(obstacles)
        if blocked is None or grid_key != self._config.grid_key() or self._unknown_is_solid():
            return False
        grid = self._make_grid()
        if tuple(blocked.shape) != tuple(grid.shape) or blocked.dtype != np.bool_:
            return False
        self._inflated = _InflatedGrid(grid, obstacles, self._config.planning_margin, blocked)
        if (fallback is not None and tuple(fallback.shape) == tuple(grid.shape)
                and fallback.dtype == np.bool_):
            self._fallback = _InflatedGrid(grid, obstacles, fallback_margin(self._config),
                                           fallback)
        return True

    def warm_up(self, budget: Optional[PlanBudget] = None,
                algorithms: Sequence[str] = ALGORITHMS) -> None:
        """Compile the search kernels and build the grid, so the first real plan is fast.

        Parameters
        ----------
        budget : PlanBudget, optional
            The request this prepares (passed on to :meth:`plan`): the grid build counts
            against it, as its stage ``grid build``.
        algorithms : sequence of str
            The searches whose kernels are compiled (or loaded from the cache): all by
            default; a process that plans with one algorithm loads that one's only.

        Raises
        ------
        PlanningTimeoutError, PlanningCancelledError
            When ``budget`` runs out (or is cancelled) during the build; the grid is then
            not kept, and a :meth:`plan` with the same budget reports the timeout.
        """
        if budget is not None:
            budget.enter(PlanStage.GRID)
        inflated = self._primary(None if budget is None else budget.check)
        first = first_free_node(inflated.blocked)  # without a copy of the grid
        if first is None:
            return
        node = inflated.grid.unravel(first)
        for algorithm in algorithms:
            self._search(inflated, node, node, algorithm)

    def path_is_clear(self, positions, obstacles: Optional[ObstacleSet] = None) -> bool:
        """True when the polyline through ``positions`` is certified to keep gamma everywhere.

        Parameters
        ----------
        positions : array_like, shape (M, 3)
            Polyline vertices [m].
        obstacles : ObstacleSet, optional
            Checked against these instead of the planner's (with the unknown boxes when
            unknown space is occupied).
        """
        obstacles = self._solid(obstacles)
        return certify_polyline(obstacles, positions, self._config.planning_margin,
                                self._config.resolution).clear

    def plan_is_clear(self, result: PlanResult, position=None,
                      obstacles: Optional[ObstacleSet] = None) -> 'ClearanceVerdict':
        """Certify that the curve of a plan still keeps gamma, from ``position`` on.

        Parameters
        ----------
        result : PlanResult
            A successful plan (with its ``curve``).
        position : array_like, shape (3,), optional
            Where the vehicle is [m]: only the curve beyond the nearest of its samples is
            checked (the stretch already flown no longer matters). The whole curve when None.
        obstacles : ObstacleSet, optional
            Checked against these instead of the planner's (for example a map that arrived
            while the plan was computed), with the unknown boxes when unknown space is
            occupied.

        Returns
        -------
        ClearanceVerdict
        """
        obstacles = self._solid(obstacles)
        return certify_plan(result, obstacles, self._config.planning_margin,
                            self._config.resolution, position)

    def plan(self, start, goal, algorithm: Optional[str] = None, *, via=(),
             cancel: Optional[Callable[[], bool]] = None,
             progress: Optional[ProgressCallback] = None, start_velocity=None,
             start_acceleration=None, start_yaw: Optional[float] = None,
             start_path=None, budget: Optional[PlanBudget] = None) -> PlanResult:
        """Plan from ``start`` to ``goal``, through ``via`` in order.

        Parameters
        ----------
        start, goal : array_like, shape (3,)
            Positions in the planning frame [m]; each snaps to its nearest grid node, and the
            smoothed curve begins and ends exactly at the given points.
        algorithm : str, optional
            Heuristic name; defaults to ``config.algorithm``.
        via : sequence of array_like of shape (3,)
            Via-points [m]: the curve passes through each exactly, in order, without stopping
            unless the geometry demands it; one search per leg.
        cancel : callable, optional
            Polled every few milliseconds; True stops the plan with status ``canceled``.
        progress : callable, optional
            ``progress(stage, elapsed_s, budget_s)``, called once the plan has run 1 s, at each
            stage change and every second (see :mod:`uav_global_planner.core.budget`).
        start_velocity, start_acceleration : array_like, shape (3,), optional
            The vehicle's state at ``start`` when it is moving [m/s], [m/s^2] (ENU): the curve
            leaves ``start`` along the velocity with the curvature that the acceleration's
            normal part needs, and the reference starts with that speed and tangential
            acceleration, so a replan continues the motion without a jump. From rest (the
            default, or a speed below :data:`HANDOVER_MIN_SPEED`) the plan starts at rest.
        start_yaw : float, optional
            Heading at the start [rad] (ENU); the heading profile turns from it.
        start_path : array_like, shape (N, 3), optional
            Where the plan in force goes on from ``start`` [m] (its reference positions ahead):
            with a moving start the new curve follows it for a braking distance first, so the
            vehicle's speed fits the curve it flies next.
        budget : PlanBudget, optional
            A budget that began earlier, for a request that built the grid first
            (:meth:`warm_up` with it); it replaces ``cancel``, ``progress`` and
            ``config.max_planning_time``.

        Returns
        -------
        PlanResult
            ``status`` is ``ok`` or names the failure; ``message`` explains it. The whole
            request (grid build, searches, smoothing, timing) is bounded by
            ``config.max_planning_time``; running out gives ``timeout`` naming the stage.
        """
        config = self._config
        if budget is None:
            budget = PlanBudget(config.max_planning_time, cancel, progress)
        name = config.algorithm if algorithm is None else algorithm
        start_point = _point_or_nan(start)
        goal_point = _point_or_nan(goal)
        base: Dict[str, Any] = dict(algorithm=str(name), start=start_point, goal=goal_point,
                                    resolution=config.resolution,
                                    safety_margin=config.safety_margin,
                                    adaptive_threshold=config.adaptive_threshold,
                                    planning_margin=config.planning_margin)
        legs: List[LegResult] = []
        try:
            handover = Handover.of(start_velocity, start_acceleration, start_yaw, start_path)
            base.update(start_velocity=handover.velocity,
                        start_acceleration=handover.acceleration)
            return self._plan(start, goal, via, name, base, budget, legs, handover)
        except PlanningError as error:
            message = str(error)
            if isinstance(error, NoValidPathError) and self._unknown_is_solid():
                assert self._unknown is not None
                message += (f'; {self._unknown.volume_m3:.1f} m^3 the map never observed '
                            'count as an obstacle (unknown_space occupied): unknown_space cost '
                            'or free may find a path through it')
            return PlanResult(status=error.status, message=message, **base,
                              expanded_nodes=error.expanded_nodes
                              + sum(leg.expanded_nodes for leg in legs),
                              legs=tuple(legs), failed_leg=getattr(error, 'leg', -1),
                              total_time_s=budget.elapsed_s)

    def _plan(self, start, goal, via, name: str, base: dict, budget: PlanBudget,
              legs: List[LegResult], handover: 'Handover') -> PlanResult:
        config = self._config
        if name not in ALGORITHMS:
            raise InvalidInputError(
                f'algorithm must be one of {", ".join(ALGORITHMS)}, got {name!r}')
        start_point = as_point(start, 'start')
        goal_point = as_point(goal, 'goal')
        via_points = _via_points(via)
        budget.enter(PlanStage.GRID)
        inflated = self._primary(budget.check)
        build_time = inflated.unreported_build_time()
        # The search memory belongs to the grid: made (or pointed at a new grid) here, so the
        # search time is the search's (the plan's total time counts it).
        self._workspace_for(inflated)
        budget.check()
        stops = np.vstack([start_point[None, :], via_points, goal_point[None, :]])
        nodes = self._check_stops(inflated, stops)

        budget.enter(PlanStage.SEARCH)
        search_started = time.perf_counter()
        paths, expanded = self._search_legs(inflated, nodes, name, budget, legs)
        search_time = time.perf_counter() - search_started
        budget.enter(PlanStage.SMOOTHING)
        smoothing_started = time.perf_counter()
        waypoints, keep = _waypoints(paths, stops)
        try:
            smoothed = self._smooth(waypoints, keep, budget, handover)
        except NoValidPathError as first_error:
            # The grid path hugs the inflated obstacles so closely that no curve through it keeps
            # gamma: plan once more on the conservative grid, whose polyline provably does.
            budget.enter(PlanStage.GRID)
            fallback = self._conservative(budget.check)
            budget.check()
            try:
                nodes = self._check_stops(fallback, stops)
            except (StartOccupiedError, GoalOccupiedError) as error:
                # The endpoint keeps gamma (checked on the primary grid): only the wider margin
                # of the fallback grid blocks it, so the request is not "occupied".
                which = 'start' if isinstance(error, StartOccupiedError) else 'goal'
                raise NoValidPathError(
                    f'{first_error}; and the grid inflated for edge clearance (gamma + '
                    f'delta*sqrt(3)/2 = {fallback.margin:.4f} m) blocks the {which} node',
                    expanded_nodes=expanded) from None
            budget.enter(PlanStage.SEARCH)
            legs.clear()
            try:
                paths, expanded = self._search_legs(fallback, nodes, name, budget, legs)
            except NoValidPathError:
                raise NoValidPathError(f'{first_error}; and no path exists on the grid '
                                       'inflated for edge clearance',
                                       expanded_nodes=expanded) from None
            budget.enter(PlanStage.SMOOTHING)
            waypoints, keep = _waypoints(paths, stops)
            smoothed = self._smooth(waypoints, keep, budget, handover)
            build_time += fallback.unreported_build_time()
        budget.enter(PlanStage.TIMING)
        timing = time_parameterize(
            smoothed, MotionLimits.from_config(config),
            start=handover.motion_on(smoothed), speed_cap=self._tracking_cap(smoothed),
            yaw_mode=config.yaw_mode, initial_yaw=handover.yaw)
        trajectory = timing.trajectory
        velocity_error, accel_error = handover.error(trajectory)
        budget.check()
        smoothing_time = time.perf_counter() - smoothing_started
        path = np.vstack([paths[0]] + [p[1:] for p in paths[1:]])
        legs[:] = _timed_legs(legs, trajectory, stops)
        repaired = len(smoothed.repaired_stretches)
        unknown_m = (0.0 if self._unknown is None
                     else self._unknown.length_inside(trajectory.positions))
        message = (f'path of {polyline_length(path):.3f} m over {len(path)} nodes, '
                   f'{expanded} nodes expanded; smoothed {smoothed.length_m:.3f} m, '
                   f'min clearance {smoothed.min_clearance_m:.3f} m'
                   + (f', {len(via_points)} via-point(s)' if len(via_points) else '')
                   + (f', {repaired} stretch(es) repaired' if repaired else '')
                   + (f', {unknown_m:.3f} m through unknown space' if unknown_m > 0.0 else ''))
        return PlanResult(
            status=PlanStatus.OK, message=message, **base, path=path,
            path_length_m=polyline_length(path), cost=sum(leg.cost for leg in legs),
            expanded_nodes=expanded, planning_time_s=search_time, grid_build_time_s=build_time,
            shortcut_path=smoothed.shortcut_path, shortcut_length_m=smoothed.shortcut_length_m,
            trajectory=trajectory, smoothed_length_m=smoothed.length_m,
            min_clearance_m=smoothed.min_clearance_m,
            min_clearance_point=smoothed.min_clearance_point,
            repaired_stretches=tuple(smoothed.repaired_stretches),
            smoothing_time_s=smoothing_time, via=via_points, legs=tuple(legs),
            curve=smoothed.curve, total_time_s=budget.elapsed_s,
            handover_velocity_error=velocity_error, handover_accel_error=accel_error,
            unknown_length_m=unknown_m,
            energy=estimate_energy(trajectory, VehicleModel(config.vehicle_mass,
                                                            config.hover_power)))

    def _check_stops(self, inflated: _InflatedGrid, stops: np.ndarray) -> np.ndarray:
        """Grid nodes of the start, the via-points and the goal, each checked."""
        nodes = [None] * len(stops)
        nodes[0], nodes[-1] = self._check_endpoints(inflated, stops[0], stops[-1])
        for number in range(1, len(stops) - 1):
            try:
                nodes[number] = self._check_endpoints(inflated, stops[0], stops[number])[1]
            except (GoalOutsideMapError, GoalOccupiedError) as error:
                text = str(error).replace('goal', f'via-point {number} (end of leg {number - 1})',
                                          1)
                failure = type(error)(text)
                failure.leg = number - 1  # type: ignore[union-attr]
                raise failure from None
        return np.asarray(nodes)

    def _search_legs(self, inflated: _InflatedGrid, nodes: np.ndarray, name: str,
                     budget: PlanBudget, legs: List[LegResult]):
        """One search per leg; node paths [m] and the total number of expanded nodes."""
        grid = inflated.grid
        paths = []
        expanded = 0
        for number in range(len(nodes) - 1):
            try:
                found = self._search(inflated, nodes[number], nodes[number + 1], name, budget)
            except PlanningError as error:
                if len(nodes) > 2:
                    error.leg = number  # type: ignore[attr-defined]
                    error.args = (f'leg {number}: {error}',)
                error.expanded_nodes += expanded
                raise
            expanded += found.expanded_nodes
            path = grid.index_to_world(found.path_indices)
            legs.append(LegResult(index=number, path_length_m=polyline_length(path),
                                  expanded_nodes=found.expanded_nodes, cost=found.cost_m))
            paths.append(path)
        return paths, expanded

    def _workspace_for(self, inflated: _InflatedGrid) -> SearchWorkspace:
        """The search workspace, made for ``inflated``'s grid or pointed at it."""
        if self._workspace is None or self._workspace.shape != inflated.grid.shape:
            self._workspace = SearchWorkspace(inflated.blocked)
        elif self._workspace.blocked is not inflated.blocked:
            self._workspace.set_blocked(inflated.blocked)
        return self._workspace

    def _search(self, inflated: _InflatedGrid, start_node, goal_node, algorithm: str,
                budget: Optional[PlanBudget] = None):
        config = self._config
        workspace = self._workspace_for(inflated)
        if algorithm == 'bounded':
            return bounded_search(workspace, start_node, goal_node, config.resolution,
                                  config.adaptive_threshold, config.bound,
                                  config.max_expansions, climb_weight=config.climb_weight,
                                  descent_weight=config.descent_weight,
                                  checkpoint=None if budget is None else budget.check,
                                  unknown=self._unknown_nodes(inflated),
                                  unknown_cost=config.unknown_cost)
        return workspace.search(start_node, goal_node, algorithm, config.resolution,
                                config.adaptive_threshold, config.max_expansions,
                                weight=config.search_weight, climb_weight=config.climb_weight,
                                descent_weight=config.descent_weight,
                                checkpoint=None if budget is None else budget.check,
                                unknown=self._unknown_nodes(inflated),
                                unknown_cost=config.unknown_cost)

    def _unknown_is_charged(self) -> bool:
        """True when unknown space costs unknown_cost per metre (policy cost, some unknown
        space, a rate above 0)."""
        return (self._config.unknown_space == 'cost' and self._config.unknown_cost > 0.0
                and self._unknown is not None and not self._unknown.is_empty())

    def _unknown_nodes(self, inflated: _InflatedGrid) -> Optional[Mask]:
        """The grid nodes in unknown space (in the layout of ``inflated.blocked``) when the
        search charges for them, else None; built once per grid."""
        if not self._unknown_is_charged():
            return None
        assert self._unknown is not None
        layout = 'dense' if isinstance(inflated.blocked, np.ndarray) else 'sparse'
        cached = self._unknown_mask
        if cached is None or cached[0] is not inflated.grid or cached[1] != layout:
            # Distance 0: the nodes inside a box or on its faces.
            mask = blocked_mask(inflated.grid, self._unknown.obstacles, 0.0, layout=layout)
            cached = self._unknown_mask = (inflated.grid, layout, mask)
        return cached[2]

    def _tracking_cap(self, smoothed: SmoothedPath) -> Optional[np.ndarray]:
        """Speed cap at each sample that keeps the predicted tracking error in the room
        left, or None without a tracking margin."""
        config = self._config
        if not config.tracking_margin > 0.0:
            return None
        return tracking_speed_cap(smoothed.positions, self._obstacles, config)

    def _smooth(self, waypoints: np.ndarray, keep: Sequence[int] = (),
                budget: Optional[PlanBudget] = None, handover: Optional['Handover'] = None):
        config = self._config
        grid = self._primary().grid
        tangent, curvature, lead_in, guide = (
            (None, None, None, None) if handover is None
            else handover.curve_start(MotionLimits.from_config(config)))

        def smooth(shortcut: bool) -> SmoothedPath:
            return smooth_path(waypoints, self._obstacles, config.planning_margin,
                               config.resolution, shortcut=shortcut, mode=config.smoothing,
                               sample_spacing=config.sample_spacing,
                               index_step=config.index_step,
                               bounds=(grid.bounds_min, grid.bounds_max), keep=keep,
                               start_tangent=tangent, start_curvature=curvature,
                               start_lead_in=lead_in, start_lead_in_path=guide,
                               checkpoint=None if budget is None else budget.check)

        smoothed = smooth(config.shortcut)
        if config.shortcut and self._unknown_is_charged():
            # Shortcuts see obstacles, not the cost of unknown space: when they fly more of it
            # than the searched path (by more than a cell), the curve follows the path's nodes.
            assert self._unknown is not None
            if self._unknown.length_inside(smoothed.positions) > (
                    self._unknown.length_inside(waypoints) + config.resolution):
                smoothed = smooth(False)
        return smoothed

    def _check_endpoints(self, inflated: _InflatedGrid, start: np.ndarray, goal: np.ndarray):
        grid = inflated.grid
        gamma = self._config.planning_margin
        if not grid.contains(start):
            raise StartOutsideMapError(
                f'start {start.tolist()} is outside the bounds {grid.bounds_min.tolist()} .. '
                f'{grid.bounds_max.tolist()}')
        if not grid.contains(goal):
            raise GoalOutsideMapError(
                f'goal {goal.tolist()} is outside the bounds {grid.bounds_min.tolist()} .. '
                f'{grid.bounds_max.tolist()}')
        self._check_unknown(start, goal)
        for which, point in (('start', start), ('goal', goal)):  # names the fence or zone
            check_endpoint(self._obstacles, point, which, gamma,
                           _ENDPOINT_TOLERANCE * self._config.resolution)
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

    def _check_unknown(self, start: np.ndarray, goal: np.ndarray) -> None:
        """Refuse an endpoint in unknown space, or within gamma of it, when it is occupied."""
        if not self._unknown_is_solid():
            return
        assert self._unknown is not None
        gamma = self._config.planning_margin
        room = _ENDPOINT_TOLERANCE * self._config.resolution
        distances = self._unknown.distance(np.stack([start, goal]), cap=gamma + 1.0)
        for which, point, distance, error in (
                ('start', start, float(distances[0]), StartOccupiedError),
                ('goal', goal, float(distances[1]), GoalOccupiedError)):
            if distance - room > gamma:
                continue
            where = ('in unknown space' if distance <= 0.0 else
                     f'{distance:.3f} m from unknown space, within the safety margin '
                     f'({gamma} m)')
            raise error(
                f'{which} {point.tolist()} is {where}: space the map never observed '
                f'({self._unknown.source or "the map"}), an obstacle with unknown_space '
                'occupied (the default); observe it first, move the ' + which
                + ', or set unknown_space to free to fly through unobserved space')

    def _node_clearance(self, grid: VoxelGrid, node: np.ndarray) -> float:
        return float(self._obstacles.distance(grid.index_to_world(node)))

    def _primary(self, checkpoint: Optional[Callable[[], None]] = None) -> _InflatedGrid:
        """The grid and its mask, built on first use; ``checkpoint`` as for
        :func:`~uav_global_planner.core.map.inflation.blocked_mask` (what it raises leaves no
        grid)."""
        if self._inflated is None:
            self._inflated = _InflatedGrid(self._make_grid(), self._obstacles,
                                           self._config.planning_margin, checkpoint=checkpoint)
        return self._inflated

    def _conservative(self, checkpoint: Optional[Callable[[], None]] = None) -> _InflatedGrid:
        if self._fallback is None:
            self._fallback = _InflatedGrid(self._primary(checkpoint).grid, self._obstacles,
                                           fallback_margin(self._config), checkpoint=checkpoint)
            self.fallback_builds += 1
        return self._fallback

    def _make_grid(self) -> VoxelGrid:
        config = self._config
        return VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution,
                                     config.max_voxels)

    def _invalidate(self) -> None:
        self._inflated = None
        self._fallback = None
        self._unknown_mask = None


def _checked_unknown(unknown: Optional[UnknownSpace]) -> Optional[UnknownSpace]:
    if unknown is not None and not isinstance(unknown, UnknownSpace):
        raise InvalidInputError('unknown must be an UnknownSpace or None')
    return unknown


def fallback_margin(config: PlannerConfig) -> float:
    """Margin of the conservative fallback grid [m]: gamma + delta * sqrt(3) / 2, on which the
    raw polyline itself keeps gamma."""
    # A segment between two 26-neighbour nodes lies within delta * sqrt(3) / 2 of one of them
    # and the obstacle distance is 1-Lipschitz, so on a grid inflated by this much the raw
    # polyline itself keeps clearance >= gamma.
    return config.planning_margin + HALF_CELL_DIAGONAL * config.resolution


def certify_plan(result: PlanResult, obstacles: ObstacleSet, safety_margin: float,
                 resolution: float, position=None,
                 ahead_m: Optional[float] = None) -> ClearanceVerdict:
    """Certify that the curve of a plan keeps ``safety_margin`` from ``obstacles``.

    The clearance engine's certificate over the continuous curve (see
    :mod:`uav_global_planner.core.path.clearance`); thread-safe, as the obstacle sets are.

    Parameters
    ----------
    result : PlanResult
        A successful plan (with its ``curve``); other results are clear.
    obstacles : ObstacleSet
    safety_margin, resolution : float
        gamma and delta [m] to certify with (normally the plan's own).
    position : array_like, shape (3,), optional
        Where the vehicle is [m]: only the curve beyond the nearest of the plan's samples is
        checked (the stretch already flown no longer matters). The whole curve when None.
    ahead_m : float, optional
        Check the first ``ahead_m`` metres beyond ``position`` on their own first, and the rest
        only if they are clear: a block near the vehicle is found in the time of a short check.

    Returns
    -------
    ClearanceVerdict
    """
    curve = result.curve
    if curve is None or obstacles.is_empty():
        return ClearanceVerdict(clear=True, blocked_at=None)
    arc = 0.0
    if position is not None and result.trajectory is not None:
        samples = result.trajectory.positions
        nearest = int(np.argmin(np.linalg.norm(samples - as_point(position, 'position'),
                                               axis=1)))
        # The chord sum is at most the arc length: checking from there is conservative.
        arc = polyline_length(samples[:nearest + 1])
    pieces = curve.pieces_after(arc)
    # The pieces kept, in curve order, and where each begins along the curve.
    starts = curve.piece_start_m[:-1][curve.piece_start_m[1:] >= arc]
    if len(starts) != len(pieces):
        starts = np.full(len(pieces), curve.piece_start_m[-2])
    batches = [np.arange(len(pieces))]
    if ahead_m is not None and len(pieces) > 1:
        near = int(np.count_nonzero(starts < arc + float(ahead_m)))
        if 0 < near < len(pieces):
            batches = [np.arange(near), np.arange(near, len(pieces))]
    for batch in batches:
        part = Pieces(pieces.coef[:, batch, :], pieces.h[batch], linear=pieces.linear)
        _, cert = certify_pieces(part, obstacles, safety_margin, resolution)
        if cert.violated.any():
            piece = int(np.flatnonzero(cert.violated)[0])
            where = cert.piece_worst[piece] if cert.piece_worst is not None else None
            return ClearanceVerdict(
                clear=False, blocked_at=None if where is None else np.asarray(where),
                blocked_ahead_m=max(float(starts[batch[piece]]) - arc, 0.0))
    return ClearanceVerdict(clear=True, blocked_at=None)


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


def _via_points(via) -> np.ndarray:
    """Via-points as an (V, 3) array [m], each checked."""
    if via is None:
        return np.empty((0, 3))
    points = [as_point(point, f'via-point {number + 1}') for number, point in enumerate(via)]
    return np.asarray(points).reshape(-1, 3)


def _waypoints(paths: Sequence[np.ndarray], stops: np.ndarray) -> Tuple[np.ndarray, List[int]]:
    """Waypoints through every leg's node path and the exact stops; indices of the via-points.

    Each via-point follows its node (the end of one leg and the start of the next); the
    smoothing keeps it and passes through it exactly.
    """
    if len(paths) == 1:
        return _with_exact_endpoints(paths[0], stops[0], stops[-1]), []
    points: List[np.ndarray] = []
    keep: List[int] = []
    if np.linalg.norm(paths[0][0] - stops[0]) > _SNAP_TOLERANCE:
        points.append(stops[0])
    for number, path in enumerate(paths):
        points.extend(path if number == 0 else path[1:])
        target = stops[number + 1]
        if np.linalg.norm(points[-1] - target) > _SNAP_TOLERANCE:
            points.append(target)
        if number < len(paths) - 1:
            keep.append(len(points) - 1)
    return np.asarray(points), keep


def _timed_legs(legs: Sequence[LegResult], trajectory: Trajectory,
                stops: np.ndarray) -> List[LegResult]:
    """The legs with the smoothed length and flight time between their stops."""
    samples = trajectory.positions
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(samples, axis=0), axis=1))]
    marks = [0]
    for stop in stops[1:-1]:
        # Via-points are samples of the curve; the nearest after the previous mark is it.
        later = samples[marks[-1]:]
        marks.append(marks[-1] + int(np.argmin(np.linalg.norm(later - stop, axis=1))))
    marks.append(len(samples) - 1)
    return [replace(leg, smoothed_length_m=float(arc[marks[k + 1]] - arc[marks[k]]),
                    duration_s=float(trajectory.times[marks[k + 1]] - trajectory.times[marks[k]]))
            for k, leg in enumerate(legs)]
