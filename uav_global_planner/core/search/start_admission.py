"""Admission of a plan's start and goal: a point a little outside free space is moved, and says so.

A landed vehicle reads a little below the floor (odometry noise), or sits within the safety
margin of the ground it stands on; a goal on the ground is where the vehicle lands. The planner
refuses such points (``start_outside_map``, ``start_occupied``, ...); :func:`admit` moves them
first, by at most one tolerance (the setting ``start_tolerance`` [m]), so the node and
``uav-plan`` plan from the same point and say the same words:

- **The ground.** A point below the floor (the bounds' lower face) or below the ground or
  terrain (the :class:`~uav_global_planner.core.map.terrain.HeightField` obstacles whose solid lies
  below their surface), by at most the tolerance, or above them but within the safety margin of
  them, is lifted straight up to the lowest height that is free. The vertical leg from the
  point to there is the take-off leg of a start (the landing leg of a goal): it must keep the
  planning margin from every obstacle other than those height fields, which the exact segment
  certificate of :func:`~uav_global_planner.core.path.clearance.certify_segments` proves; otherwise
  the point is refused.
- **Any other obstacle, and the bounds' sides and top** (starts only): a start outside the
  bounds or within the safety margin of another obstacle by at most the tolerance is moved to
  its projection into the bounds, or else to the nearest free grid node. A goal there is kept
  as asked, so the planner refuses it (Nav2's GetPlan moves goals by its own tolerance).
- **Farther than the tolerance**: refused, the refusal naming the distance and the fix, e.g.
  ``start 1.20 m below the floor; start_tolerance is 0.50 m: raise it with --start-tolerance
  or move the start``; :func:`explain` appends it to the planner's refusal.

A point is free (:func:`is_free`) when it lies inside the bounds, its grid node is not blocked
and its exact obstacle distance exceeds the planning margin by :data:`FREE_ROOM_CELLS` cells,
the room the planner's own endpoint test needs.

Every coordinate is in the planning frame (ENU map frame) [m].
"""

from dataclasses import dataclass, field, replace
import math
import threading
from typing import Any, Dict, List, Optional, Sequence, Tuple
import weakref

import numpy as np

from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import Mask
from uav_global_planner.core.map.obstacles import Obstacle, ObstacleSet
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner.core.path.clearance import certify_segments
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.settings import check_setting
from uav_global_planner.core.status import PlanStatus

__all__ = ['Admission', 'admit', 'explain', 'FREE_ROOM_CELLS', 'is_free', 'nearest_free_node',
           'START', 'GOAL']

#: Room kept between the clearance of an admitted point (or a free node) and the planning
#: margin, in cells of delta: the planner refuses endpoints at the margin within rounding
#: (1e-5 cells), so an admitted point keeps ten times that.
FREE_ROOM_CELLS = 1e-4

#: The two points a plan admits.
START = 'start'
GOAL = 'goal'

# Smallest step of the upward scan for the lowest free height, in cells: the lift exceeds the
# lowest free height by less than this.
_SCAN_STEP_CELLS = 1e-3

# Most steps of that scan (it takes one or a few over flat ground).
_MAX_SCAN_STEPS = 20_000

# Slack of the bounds' faces, in cells (as VoxelGrid.contains).
_FACE_SLACK_CELLS = 1e-9

# The planner's refusals of each point, to which a refusal of admission adds its fix.
_REFUSALS = {START: (PlanStatus.START_OUTSIDE_MAP, PlanStatus.START_OCCUPIED),
             GOAL: (PlanStatus.GOAL_OUTSIDE_MAP, PlanStatus.GOAL_OCCUPIED)}

# The legs flown straight up from a lifted start, and down to a lifted goal.
_LEGS = {START: 'take-off', GOAL: 'landing'}

# Each obstacle set's obstacles other than the ground, by set (see _without).
_OTHERS: 'weakref.WeakKeyDictionary[ObstacleSet, ObstacleSet]' = weakref.WeakKeyDictionary()
_OTHERS_LOCK = threading.Lock()


@dataclass(frozen=True, eq=False)
class Admission:
    """Where a plan starts (or ends), and what was done to the point asked for.

    Attributes
    ----------
    which : str
        :data:`START` or :data:`GOAL`.
    requested : numpy.ndarray, shape (3,)
        The point asked for [m].
    point : numpy.ndarray, shape (3,)
        The point to plan from (to) [m]; ``requested`` unless it was moved.
    note : str
        What was moved, how far and why; empty when nothing was.
    refusal : str
        Why the point could not be moved, with the distance and the fix; empty when it was
        moved, was free, or is left to the planner's own refusal.
    leg : numpy.ndarray, shape (2, 3), or None
        The vertical take-off (landing) leg, from ``requested`` up to ``point`` [m], when the
        point was lifted off the ground.
    """

    which: str
    requested: np.ndarray
    point: np.ndarray
    note: str = ''
    refusal: str = ''
    leg: Optional[np.ndarray] = field(default=None)

    @property
    def adjusted(self) -> bool:
        """True when :attr:`point` differs from :attr:`requested`."""
        return bool(self.note)

    @property
    def moved_m(self) -> float:
        """Distance from :attr:`requested` to :attr:`point` [m]."""
        return float(np.linalg.norm(self.point - self.requested))

    def values(self) -> Dict[str, Any]:
        """``<which>_adjusted``, ``requested_<which>`` and ``<which>_note`` (empty when not
        adjusted), the keys of the node's diagnostics and of ``uav-plan plan --json``."""
        return {f'{self.which}_adjusted': self.adjusted,
                f'requested_{self.which}': self.requested,
                f'{self.which}_note': self.note}


def _room(resolution: float) -> float:
    return FREE_ROOM_CELLS * resolution


def is_free(grid: VoxelGrid, blocked: Mask, obstacles: ObstacleSet, margin: float,
            point: np.ndarray) -> bool:
    """True when a plan may start or end at ``point``.

    Parameters
    ----------
    grid : VoxelGrid
    blocked : Mask
        The inflated grid's blocked nodes (``Planner.blocked``).
    obstacles : ObstacleSet
    margin : float
        Planning margin [m] (``PlannerConfig.planning_margin``).
    point : numpy.ndarray, shape (3,)
        [m]

    Returns
    -------
    bool
        Inside the bounds, on a node that is not blocked, and farther than ``margin`` plus
        :data:`FREE_ROOM_CELLS` cells from every obstacle.
    """
    if not bool(grid.contains(point)):
        return False
    if blocked[tuple(grid.world_to_index(point))]:
        return False
    if obstacles.is_empty():
        return True
    return float(obstacles.distance(point)) > margin + _room(grid.resolution)


def nearest_free_node(grid: VoxelGrid, obstacles: ObstacleSet, margin: float,
                      point: np.ndarray, tolerance: float,
                      blocked: Optional[Mask] = None) -> Optional[np.ndarray]:
    """The grid node nearest to ``point`` within ``tolerance`` that keeps the margin.

    Shells of growing Chebyshev radius around the point's node are searched until no closer
    node can follow, so the cost follows the distance to the nearest free node, not the
    tolerance.

    Parameters
    ----------
    grid : VoxelGrid
    obstacles : ObstacleSet
    margin : float
        Planning margin [m]; a node is free when its clearance exceeds it by
        :data:`FREE_ROOM_CELLS` cells.
    point : numpy.ndarray, shape (3,)
        [m], inside the bounds.
    tolerance : float
        Largest accepted distance from ``point`` [m].
    blocked : Mask, optional
        The inflated grid's blocked nodes: when given, a free node must not be one of them
        (the test of :func:`is_free`).

    Returns
    -------
    numpy.ndarray of shape (3,) or None
        The node's position [m], or None when no free node lies within ``tolerance``.
    """
    delta = grid.resolution
    center = grid.world_to_index(point)
    limit = int(math.ceil(tolerance / delta)) + 1
    shape = np.asarray(grid.shape)
    best: Optional[Tuple[float, np.ndarray]] = None
    for radius in range(limit + 1):
        # Every node of a shell of radius r is at least (r - 1) * delta from the point (the
        # point lies within half a cell of the centre node): stop once nothing closer can come.
        if best is not None and (radius - 1) * delta > best[0]:
            break
        axis = np.arange(-radius, radius + 1)
        offsets = np.stack(np.meshgrid(axis, axis, axis, indexing='ij'), -1).reshape(-1, 3)
        offsets = offsets[np.max(np.abs(offsets), axis=1) == radius]
        nodes = center + offsets
        nodes = nodes[np.all((nodes >= 0) & (nodes < shape), axis=1)]
        if len(nodes) == 0:
            continue
        points = grid.index_to_world(nodes)
        distances = np.linalg.norm(points - point, axis=1)
        near = distances <= tolerance
        if not np.any(near):
            continue
        points, distances, nodes = points[near], distances[near], nodes[near]
        if obstacles.is_empty():
            free = np.ones(len(points), dtype=bool)
        else:
            free = obstacles.distance(points) > margin + _room(delta)
        if blocked is not None:
            free &= np.array([not blocked[tuple(node)] for node in nodes], dtype=bool)
        if not np.any(free):
            continue
        index = int(np.argmin(np.where(free, distances, np.inf)))
        if best is None or distances[index] < best[0]:
            best = (float(distances[index]), points[index])
    return None if best is None else best[1].copy()


# ------------------------------------------------------------------------------ the ground

def ground_items(obstacles: ObstacleSet) -> List[HeightField]:
    """The ground and terrain of ``obstacles``: the height fields whose solid lies below their
    surface (terrain, flat ground, an AGL floor), which a take-off or landing leg may leave."""
    return [item for item in obstacles.items
            if isinstance(item, HeightField) and item.side == 'below']


def _without(obstacles: ObstacleSet, items: Sequence[HeightField]) -> ObstacleSet:
    """``obstacles`` less ``items`` (the same set when there is nothing to take away); kept
    while ``obstacles`` lives, as a map's point set makes a new set cost a KD-tree build."""
    if not items:
        return obstacles
    with _OTHERS_LOCK:
        cached = _OTHERS.get(obstacles)
    if cached is not None:
        return cached
    dropped = {id(item) for item in items}
    kept: List[Obstacle] = [item for item in obstacles.items if id(item) not in dropped]
    others = ObstacleSet(kept)
    with _OTHERS_LOCK:
        _OTHERS[obstacles] = others
    return others


def _ground_under(items: Sequence[HeightField], xy: np.ndarray) -> Tuple[float, str]:
    """Height of the lowest ground surface over ``xy`` [m] and its label (``-inf`` and ''
    where none spans it): the terrain itself, not an AGL floor above it."""
    best, label = -math.inf, ''
    for item in items:
        height = float(item.height_at(xy))
        if math.isfinite(height) and (best == -math.inf or height < best):
            best, label = height, item.label
    return best, label


def _ground_distance(items: Sequence[HeightField], point: np.ndarray) -> float:
    """Exact distance from ``point`` to the nearest ground solid [m] (+inf without one)."""
    return min((float(item.distance(point)) for item in items), default=math.inf)


# ------------------------------------------------------------------------------ admission

@dataclass(frozen=True, eq=False)
class _Space:
    """What admission reads of a planner: grid, blocked nodes, obstacles, margin."""

    grid: VoxelGrid
    blocked: Mask
    obstacles: ObstacleSet
    margin: float

    @property
    def room(self) -> float:
        return _room(self.grid.resolution)

    def free(self, point: np.ndarray) -> bool:
        return is_free(self.grid, self.blocked, self.obstacles, self.margin, point)


def admit(planner: Any, point: Any, which: str = START, tolerance: Optional[float] = None,
          flag: str = '--start-tolerance') -> Admission:
    """The point to plan from (``which='start'``) or to (``'goal'``), moved to free space by at
    most ``tolerance`` (see the module's policy).

    Parameters
    ----------
    planner : Planner
        Its grid, blocked nodes (built here if not yet), obstacles and planning margin.
    point : array_like, shape (3,)
        The point asked for [m].
    which : str
        :data:`START` or :data:`GOAL`.
    tolerance : float, optional
        [m], in [0, 100] (the setting ``start_tolerance``), 0 = never moved;
        ``planner.config.start_tolerance`` by default.
    flag : str
        How users raise the tolerance, for refusals: ``'--start-tolerance'`` on the command line,
        ``'the start_tolerance parameter'`` for the node.

    Returns
    -------
    Admission
        A point that is not finite, or not a triple, is returned as asked (the planner refuses
        it in its own words).

    Raises
    ------
    InvalidInputError
        A ``tolerance`` that is not a number in [0, 100] m.
    """
    if which not in _LEGS:
        raise ValueError(f'which must be {START!r} or {GOAL!r}, got {which!r}')
    asked = np.asarray(point, dtype=np.float64)
    if asked.shape != (3,) or not np.all(np.isfinite(asked)):
        return Admission(which, asked, asked)
    config = planner.config
    limit = float(config.start_tolerance if tolerance is None
                  else check_setting('start_tolerance', tolerance))
    space = _Space(planner.grid, planner.blocked, planner.obstacles,
                   float(config.planning_margin))
    if space.free(asked):
        return Admission(which, asked, asked)
    ground = ground_items(space.obstacles)
    others = _without(space.obstacles, ground)
    lifted = _lift(space, ground, others, asked, which, limit, flag)
    if lifted is not None:
        return lifted
    if which == GOAL:
        return Admission(which, asked, asked)
    return _nearest(space, asked, limit, flag)


def _lift(space: _Space, ground: Sequence[HeightField], others: ObstacleSet, asked: np.ndarray,
          which: str, tolerance: float, flag: str) -> Optional[Admission]:
    """The admission of a point on or under the floor or the ground; None when the point is
    not there (beside the bounds, above them, or within the margin of another obstacle)."""
    grid = space.grid
    slack = _FACE_SLACK_CELLS * grid.resolution
    low, high = grid.bounds_min, grid.bounds_max
    if (np.any(asked[:2] < low[:2] - slack) or np.any(asked[:2] > high[:2] + slack)
            or asked[2] > high[2] + slack):
        return None
    floor = float(low[2])
    base = np.array([asked[0], asked[1], max(float(asked[2]), floor)])
    if not others.is_empty() and float(others.distance(base)) <= space.margin + space.room:
        return None     # another obstacle's margin: not a take-off
    surface, label = _ground_under(ground, asked[:2])
    depth, under = floor - float(asked[2]), 'floor'
    if surface - float(asked[2]) >= depth:
        depth, under = surface - float(asked[2]), label
    near = _ground_distance(ground, asked) <= space.margin + space.room + grid.resolution
    if depth <= 0.0 and not near:
        return None     # blocked for another reason (a node of a conservative mask)
    leg = _LEGS[which]
    raise_it = f'raise it with {flag} or move the {which}'
    if depth > tolerance:
        return Admission(which, asked, asked, refusal=(
            f'{which} {depth:.2f} m below the {under}; start_tolerance is {tolerance:.2f} m: '
            f'{raise_it}'))
    if depth > 0.0:
        why = f'{depth:.3f} m below the {under}'
        if float(asked[2]) < floor:
            why += ' (outside the bounds)'
    else:
        why = f'within the safety margin ({space.margin:g} m) of the {label or "ground"}'
    if tolerance <= 0.0:
        return Admission(which, asked, asked, refusal=(
            f'{which} {_text(asked)} is {why}; start_tolerance is 0 m (never moved): '
            f'{raise_it}'))
    target = _lowest_free(space, base)
    if target is None:
        return Admission(which, asked, asked, refusal=(
            f'{which} {_text(asked)} is {why}, and no height straight above it up to the '
            f'ceiling ({float(high[2]):g} m) is free: move the {which}'))
    lift = float(target[2] - asked[2])
    if not others.is_empty():
        clear = certify_segments(others, asked[None, :], target[None, :], space.margin,
                                 grid.resolution).clear
        if not bool(clear[0]):
            return Admission(which, asked, asked, refusal=(
                f'{which} {_text(asked)} is {why}; the {leg} leg straight up {lift:.3f} m to '
                f'the lowest free height, {_text(target)}, passes within the safety margin '
                f'({space.margin:g} m) of an obstacle: move the {which}'))
    if which == START:
        done = f'lifted {lift:.3f} m straight up to {_text(target)}, the take-off leg'
    else:
        done = (f'the plan ends {lift:.3f} m straight above it, at {_text(target)}, and the '
                'landing leg goes down from there')
    return Admission(which, asked, target, note=(
        f'{which} {_text(asked)} is {why}; {done} (clear of obstacles; start_tolerance '
        f'{tolerance:g} m)'), leg=np.stack([asked, target]))


def _lowest_free(space: _Space, base: np.ndarray) -> Optional[np.ndarray]:
    """The lowest free point straight above ``base`` (inside the bounds) [m], or None.

    Scans up from ``base``: a blocked node is stepped over to the next node's half cell; a
    point whose clearance d falls short of the margin g is stepped up by g - d, as no point
    nearer than that can be free (the distance is 1-Lipschitz), and at least by
    :data:`_SCAN_STEP_CELLS` cells.
    """
    grid = space.grid
    delta = grid.resolution
    low, top = float(grid.bounds_min[2]), float(grid.bounds_max[2])
    wanted = space.margin + space.room
    step = _SCAN_STEP_CELLS * delta
    z = float(base[2])
    for _ in range(_MAX_SCAN_STEPS):
        if z > top + _FACE_SLACK_CELLS * delta:
            return None
        candidate = np.array([base[0], base[1], min(z, top)])
        node = grid.world_to_index(candidate)
        if space.blocked[tuple(node)]:
            # The next node owns heights from half a cell above this one.
            z = max(z + step, low + (float(node[2]) + 0.5) * delta + 1e-6 * delta)
            continue
        if space.obstacles.is_empty():
            return candidate
        clearance = float(space.obstacles.distance(candidate))
        if clearance > wanted:
            return candidate if space.free(candidate) else None
        z += max(wanted - clearance, step)
    return None


def _nearest(space: _Space, asked: np.ndarray, tolerance: float, flag: str) -> Admission:
    """A start beside or above the bounds, or within the margin of an obstacle other than the
    ground: its projection into the bounds, or else the nearest free node."""
    grid = space.grid
    raise_it = f'raise it with {flag} or move the start'
    clamped = np.clip(asked, grid.bounds_min, grid.bounds_max)
    outside_by = float(np.linalg.norm(asked - clamped))
    inside = bool(grid.contains(asked))
    if tolerance <= 0.0:
        return Admission(START, asked, asked)
    if outside_by > tolerance:
        return Admission(START, asked, asked, refusal=(
            f'start {outside_by:.2f} m outside the bounds; start_tolerance is '
            f'{tolerance:.2f} m: {raise_it}'))
    if space.free(clamped):
        moved: Optional[np.ndarray] = clamped
    else:
        moved = nearest_free_node(grid, space.obstacles, space.margin, clamped,
                                  max(tolerance - outside_by, 0.0) + space.room, space.blocked)
        if moved is not None and float(np.linalg.norm(moved - asked)) > tolerance + space.room:
            moved = None
    if moved is None:
        return Admission(START, asked, asked, refusal=(
            f'no free point lies within start_tolerance ({tolerance:.2f} m) of the start: '
            f'{raise_it}'))
    what = 'outside the bounds' if not inside else 'within the safety margin'
    return Admission(START, asked, moved, note=(
        f'start {_text(asked)} is {what}; moved {float(np.linalg.norm(moved - asked)):.3f} m '
        f'to {_text(moved)} (start_tolerance {tolerance:g} m)'))


def _text(point: np.ndarray) -> str:
    return str(np.round(point, 4).tolist())


def explain(result: PlanResult, admissions: Sequence[Admission]) -> PlanResult:
    """``result`` with the refusal of each admission appended to its message, where the
    planner refused that point (``start_outside_map`` or ``start_occupied`` for the start,
    the goal's alike)."""
    extra = [admission.refusal for admission in admissions
             if admission.refusal and result.status in _REFUSALS[admission.which]]
    if not extra:
        return result
    return replace(result, message='; '.join([result.message, *extra]))
