"""Missions an autopilot flies on its own: certified waypoints, QGroundControl ``.plan`` and WPL.

A ground station (QGroundControl, Mission Planner) uploads a mission to the autopilot (PX4,
ArduPilot), which then flies it in AUTO mode without a companion computer. The autopilot does not
follow the smoothed curve: it flies **straight legs** between waypoints and **turns early**, as
soon as it is within the acceptance radius R of a waypoint. This module chooses waypoints for
which that behaviour keeps the clearance, and writes them in the two mission file formats.

What is certified
-----------------
The required clearance is ``m = gamma + a``: the planner's safety margin plus a tracking
allowance ``a`` for what the autopilot adds (cross-track error, overshoot, wind). Keeping ``m``
along the nominal path means that every point within ``a`` of it keeps ``gamma`` (the obstacle
distance is 1-Lipschitz). Every yes/no below comes from the clearance engine
(:func:`~uav_global_planner.core.clearance.certify_segments`), which certifies whole segments,
not samples:

* **Legs.** Each straight leg between consecutive mission positions keeps ``m``.
* **Turn regions.** At a waypoint ``P`` between legs from ``P0`` and to ``P1``, the autopilot
  switches legs anywhere inside the acceptance radius and then heads for the next leg. With
  ``A = P + R (P0 - P) / |P0 - P|`` (where it enters the acceptance radius on the incoming leg)
  and ``B = P + R (P1 - P) / |P1 - P|`` (where it has joined the outgoing leg at the latest),
  every such turn that does not swing outwards stays in the triangle ``A P B``; the straight cut
  ``A -> B`` is its extreme. The whole filled triangle is certified (:func:`certify_triangle`):
  it is cut into ``k**2`` congruent triangles, the ``3 k`` cutting lines are certified to keep
  ``m + r / k`` (``r``: the triangle's inradius, ``r / k <= 1 cm``), and every point of a small
  triangle is within its inradius ``r / k`` of its edges, so the whole region keeps ``m``; an
  obstacle point inside the triangle, clear of all three sides, is caught. Outward swings are
  what the tracking allowance covers.
* **Leg lengths.** No leg is shorter than R, and a leg with a turn at both ends is at least 2 R
  long, so that ``A`` and ``B`` lie on the legs and neighbouring turn regions do not overlap.
* **The ground.** Waypoints are at least ``min_height`` (default ``m``) above the bounds' floor;
  legs and turns between points above a plane stay above it.
* **Take-off.** When the start is on the ground (within ``ground_tolerance`` of the floor) the
  mission begins with ``NAV_TAKEOFF``: a vertical climb at the start, certified like a leg, to
  the highest clear height up to ``takeoff_height`` (lower ones are tried when the first turn
  fails under an overhang); the take-off point is the first turn, the climb its incoming leg.
  The start is then home, the reference of every altitude. From a start in the air the mission
  begins with a waypoint at the start, and home is the floor below it.
* **The end.** ``loiter``: the vehicle holds at the goal (``NAV_LOITER_UNLIM``). ``land``: a
  vertical descent from the goal to the floor (``NAV_LAND``), certified, the goal being a turn.
  ``rtl``: ``NAV_RETURN_TO_LAUNCH`` as PX4 and ArduPilot fly it: climb at the goal to
  ``max(goal, home + rtl_altitude)``, straight back above home, descend to home; all three legs
  and their turns are certified, so ``rtl_altitude`` must equal the autopilot's
  (``RTL_RETURN_ALT`` on PX4, ``RTL_ALT`` on ArduPilot) and no rally points are written.
* **Rounding.** Files store latitude and longitude to 1e-7 deg (the MAVLink integer resolution,
  about 1 cm) and altitudes to 1 mm, which moves a stored point by at most 8 mm and a turn
  triangle's corners by at most 16 mm. The search certifies ``m`` plus a 2 cm slack, and the
  final certificate is computed again, at ``m``, on the positions converted back from the
  rounded file values: the reported clearance is the clearance of what is written.

Choosing the waypoints
----------------------
Candidates are points of the plan in force: samples of the smoothed curve (every ``delta / 2``
of arc length) and the raw grid path's nodes, ordered by their position along the curve. The
plan keeps only ``gamma`` and a turn cuts inside its corner, so copies of the candidates near
obstacles are pushed up the distance gradient to ``m`` and to ``m + R/4, R/2, R`` (in an alley
too narrow for that, to its middle). From each waypoint the search takes the farthest candidate
whose leg, turn region and leg length pass, and backtracks a few waypoints when it gets stuck.
Where the straight legs are visible along the route in order (what usually holds), this gives
the fewest waypoints among the candidates. Via-points are never skipped. When no certified
mission exists (a passage narrower than about ``2 m`` plus the turns' room, the goal closer than
``m`` to an obstacle, a blocked climb or end action) :class:`UncertifiableMissionError` says
where.

Fences
------
The map's airspace (:mod:`uav_global_planner.core.airspace`: inclusion fences, exclusion zones)
keeps the clearance like any obstacle when it is in the obstacle set, as a scene file's
``geofence`` puts it. It is also written as the ``.plan`` ``geoFence`` (WGS84, polygons
clockwise), with :class:`FencePolygon` and :class:`FenceCircle` given directly: autopilot fences
are 2D, so an exclusion zone whose footprint the mission flies over or under is left out (and
named in :attr:`GeoFence.skipped`) instead of being written as a fence the mission breaches.
Without fences the ``geoFence`` is empty (version 2, no polygons, no circles).
"""

from dataclasses import dataclass, field
import json
import math
from pathlib import Path
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
from scipy.spatial import cKDTree

from uav_global_planner.core.airspace import (Airspace, BoxZone, Cylinder, InclusionCircle,
                                              InclusionFence, Prism)
from uav_global_planner.core.clearance import certify_segments
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError, PlanningError
from uav_global_planner.core.geodesy import enu_to_geodetic, geodetic_to_enu, GeodeticOrigin
from uav_global_planner.core.obstacles import ObstacleSet
from uav_global_planner.core.status import PlanStatus

# MAVLink numbers (common.xml).
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_LOITER_UNLIM = 17
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
MAV_TYPE_QUADROTOR = 2
#: ``firmwareType`` of the ``.plan`` file: MAV_AUTOPILOT values.
MAV_AUTOPILOT = {'px4': 12, 'ardupilot': 3}
#: DO_CHANGE_SPEED speed types.
SPEED_TYPE_GROUND = 1
SPEED_TYPE_CLIMB = 2
SPEED_TYPE_DESCENT = 3

END_ACTIONS = ('loiter', 'land', 'rtl')
FIRMWARES = ('px4', 'ardupilot')
#: Mission file formats: QGroundControl's JSON ``.plan`` and the plain-text ``QGC WPL 110``.
FORMATS = ('qgc', 'wpl')
#: Commands with a position (the mission's "waypoints" in the answer of the export service).
POSITION_COMMANDS = (MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LOITER_UNLIM, MAV_CMD_NAV_LAND,
                     MAV_CMD_NAV_TAKEOFF)

#: Decimal places stored: latitude/longitude (MAVLink's 1e-7 deg integers), altitudes, params.
LATLON_DECIMALS = 7
ALTITUDE_DECIMALS = 3
PARAM_DECIMALS = 6
#: Slack kept above the required clearance while choosing, so that rounding to the stored
#: decimals (at most 8 mm at a point, 16 mm at a turn triangle's corner) cannot take a leg or a
#: turn below it [m].
ROUNDING_SLACK = 0.02
#: Largest inradius of the small triangles of a certified turn region [m].
TURN_CELL_INRADIUS = 0.01
_MAX_TURN_SUBDIVISION = 400
#: Candidates ahead of a waypoint that are all checked at once; beyond, a gallop and bisection.
_FULL_SCAN = 256
#: Budget of the waypoint search, in leg or turn certifications.
_SEARCH_BUDGET = 20000
#: Alternatives tried after a waypoint, and how many waypoints the search may take back.
_OPTIONS_PER_WAYPOINT = 16
_BACKTRACK_WAYPOINTS = 4
#: Take-off heights tried, the highest clear one first.
_TAKEOFF_ALTERNATIVES = 4
_PUSH_ITERATIONS = 40
#: Extra clearance of the pushed-off candidate copies, in acceptance radii.
_OFFSET_LAYERS = (0.0, 0.25, 0.5, 1.0)


class UncertifiableMissionError(PlanningError):
    """No mission keeps the required clearance along the plan (says where and why)."""

    status = PlanStatus.NO_VALID_PATH


@dataclass(frozen=True)
class MissionSettings:
    """How the mission is built.

    Attributes
    ----------
    acceptance_radius : float
        R [m]: the autopilot's waypoint acceptance radius (PX4 ``NAV_ACC_RAD``, ArduPilot
        ``WPNAV_RADIUS``; also written as each waypoint's param 2). > 0.
    tracking_allowance : float
        a [m]: extra clearance for the autopilot's tracking error, >= 0. Legs and turn regions
        keep gamma + a.
    takeoff_height : float
        Height of the take-off climb above the start [m], >= R (PX4 raises takeoffs below
        ``MIS_TAKEOFF_ALT``, 2.5 m by default, to it: keep this at least as high).
    end : str
        ``loiter`` (hold at the goal), ``land`` (descend at the goal) or ``rtl`` (return home).
    rtl_altitude : float
        Return altitude above home [m] for ``rtl`` (must equal the autopilot's).
    firmware : str
        ``px4`` or ``ardupilot``: the ``.plan`` firmwareType, the yaw convention (PX4: NaN keeps
        the heading mode; ArduPilot: 0) and the speed items (ArduPilot also takes climb and
        descent speeds).
    ground_tolerance : float or None
        The start is on the ground when it is at most this far above the bounds' floor [m];
        None: the grid resolution delta.
    min_height : float or None
        Lowest height of waypoints above the bounds' floor (the ground) [m]; None: the required
        clearance gamma + tracking allowance. The goal and via-points stay where they are.
    """

    acceptance_radius: float = 1.0
    tracking_allowance: float = 0.1
    takeoff_height: float = 2.5
    end: str = 'loiter'
    rtl_altitude: float = 15.0
    firmware: str = 'px4'
    ground_tolerance: Optional[float] = None
    min_height: Optional[float] = None

    def __post_init__(self) -> None:
        _number('acceptance_radius', self.acceptance_radius, 0.0, 1000.0, low_open=True)
        _number('tracking_allowance', self.tracking_allowance, 0.0, 100.0)
        _number('takeoff_height', self.takeoff_height, 0.0, 10000.0, low_open=True)
        _number('rtl_altitude', self.rtl_altitude, 0.0, 10000.0, low_open=True)
        if self.takeoff_height < self.acceptance_radius:
            raise InvalidInputError(
                f'takeoff_height must be >= acceptance_radius ({self.acceptance_radius} m), got '
                f'{self.takeoff_height} m: the take-off point is a turn')
        if self.end not in END_ACTIONS:
            raise InvalidInputError(
                f'end must be one of {", ".join(END_ACTIONS)}, got {self.end!r}')
        if self.firmware not in FIRMWARES:
            raise InvalidInputError(
                f'firmware must be one of {", ".join(FIRMWARES)}, got {self.firmware!r}')
        if self.ground_tolerance is not None:
            _number('ground_tolerance', self.ground_tolerance, 0.0, 1000.0)
        if self.min_height is not None:
            _number('min_height', self.min_height, 0.0, 10000.0)


def _number(name: str, value: Any, low: float, high: float, low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidInputError(f'{name} must be a number, got {value!r}')
    number = float(value)
    if not math.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {number}')
    if (number <= low if low_open else number < low) or number > high:
        raise InvalidInputError(
            f'{name} must be in {"(" if low_open else "["}{low}, {high}], got {number}')
    return number


@dataclass(frozen=True, eq=False)
class FencePolygon:
    """A polygonal geofence in the map frame.

    Attributes
    ----------
    vertices : numpy.ndarray, shape (K, 2)
        x, y of the corners [m], K >= 3.
    inclusion : bool
        True: stay inside; False: stay outside.
    """

    vertices: np.ndarray
    inclusion: bool = True

    def __post_init__(self) -> None:
        vertices = np.asarray(self.vertices, dtype=np.float64)
        if vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3:
            raise InvalidInputError(f'fence polygon needs (K >= 3, 2) vertices [m], got shape '
                                    f'{vertices.shape}')
        if not np.all(np.isfinite(vertices)):
            raise InvalidInputError('fence polygon vertices must be finite')
        object.__setattr__(self, 'vertices', vertices)


@dataclass(frozen=True, eq=False)
class FenceCircle:
    """A circular geofence in the map frame.

    Attributes
    ----------
    center : numpy.ndarray, shape (2,)
        x, y [m].
    radius : float
        [m], > 0.
    inclusion : bool
        True: stay inside; False: stay outside.
    """

    center: np.ndarray
    radius: float
    inclusion: bool = True

    def __post_init__(self) -> None:
        center = np.asarray(self.center, dtype=np.float64).reshape(-1)
        if center.shape != (2,) or not np.all(np.isfinite(center)):
            raise InvalidInputError(f'fence circle center must be two finite numbers [m], got '
                                    f'{self.center!r}')
        _number('fence circle radius', self.radius, 0.0, 1.0e7, low_open=True)
        object.__setattr__(self, 'center', center)
        object.__setattr__(self, 'radius', float(self.radius))


@dataclass(frozen=True)
class MissionItem:
    """One MAVLink mission item, as both file formats store it.

    Attributes
    ----------
    command : int
        MAV_CMD.
    frame : int
        MAV_FRAME (3 = global, altitude relative to home; 2 = mission, no position).
    params : tuple of float
        param1..4, latitude [deg], longitude [deg], altitude [m above home]; NaN where a param is
        left to the autopilot (written as ``null`` in ``.plan`` files). Rounded to the stored
        decimals, so every writer stores exactly these numbers.
    auto_continue : bool
    """

    command: int
    frame: int
    params: Tuple[float, ...]
    auto_continue: bool = True

    @property
    def has_position(self) -> bool:
        """True for items that fly to a position (take-off, waypoint, loiter, land)."""
        return self.command in POSITION_COMMANDS


@dataclass(frozen=True, eq=False)
class GeoFence:
    """Geofences in WGS84, as written to the ``.plan`` file.

    Attributes
    ----------
    polygons : tuple of (tuple of (lat, lon), bool)
        Vertices [deg] in clockwise order, and the inclusion flag.
    circles : tuple of ((lat, lon), radius, bool)
        Centre [deg], radius [m], inclusion flag.
    skipped : tuple of str
        Exclusion zones of the airspace not written, with the reason: the mission flies over or
        under them inside their footprint, which a 2D autopilot fence would call a breach.
    """

    polygons: Tuple[Tuple[Tuple[Tuple[float, float], ...], bool], ...] = ()
    circles: Tuple[Tuple[Tuple[float, float], float, bool], ...] = ()
    skipped: Tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Mission:
    """A certified mission in the map frame and in WGS84.

    Attributes
    ----------
    items : tuple of MissionItem
        The mission, first item first (no home item: writers add it where the format has one).
    home : tuple of float
        Planned home position (lat [deg], lon [deg], alt [m AMSL]): the take-off point, to
        which every item altitude is relative.
    home_enu : numpy.ndarray, shape (3,)
        Home in the map frame [m], as stored (after rounding).
    origin : GeodeticOrigin
    settings : MissionSettings
    flight_path : numpy.ndarray, shape (P, 3)
        The nominal path the autopilot flies, in the map frame [m], from the stored (rounded)
        positions: home or the start, the take-off point, the waypoints, and the end (descent,
        or the return legs of ``rtl``). Its segments are the certified legs.
    turn_regions : numpy.ndarray, shape (T, 3, 3)
        The certified turn triangles ``(A, P, B)`` [m].
    safety_margin_m : float
        gamma [m].
    required_clearance_m : float
        gamma + tracking allowance [m]: what every leg and turn region keeps.
    certified_clearance_m : float
        Smallest certified lower bound over the legs and turn regions [m], >= the required
        clearance (capped a little above it by the engine).
    speed_horizontal, speed_vertical : float
        Speeds written to the speed items [m/s] (the plan's timing limits).
    fence : GeoFence
    """

    items: Tuple[MissionItem, ...]
    home: Tuple[float, float, float]
    home_enu: np.ndarray
    origin: GeodeticOrigin
    settings: MissionSettings
    flight_path: np.ndarray
    turn_regions: np.ndarray
    safety_margin_m: float
    required_clearance_m: float
    certified_clearance_m: float
    speed_horizontal: float
    speed_vertical: float
    fence: GeoFence = field(default_factory=GeoFence)

    @property
    def waypoint_count(self) -> int:
        """Items that fly to a position (take-off, waypoints, loiter, land)."""
        return sum(item.has_position for item in self.items)

    @property
    def legs(self) -> np.ndarray:
        """The certified straight legs, shape (L, 2, 3) [m]."""
        path = self.flight_path
        return np.stack([path[:-1], path[1:]], axis=1)


# --------------------------------------------------------------------------------------------
# Certification helpers (all through the clearance engine)
# --------------------------------------------------------------------------------------------

def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _triangle_lines(a: np.ndarray, b: np.ndarray, c: np.ndarray,
                    k: int) -> Tuple[np.ndarray, np.ndarray]:
    """The 3 k segments of the k-subdivision of triangle abc (its sides included)."""
    s = np.arange(k + 1) / k
    ab, ac = b - a, c - a
    # Parallel to bc: from a + s ab to a + s ac, s = 1/k .. 1.
    p0 = [a + s[1:, None] * ab]
    p1 = [a + s[1:, None] * ac]
    # Parallel to ac (i fixed) and to ab (j fixed), s = 0 .. (k - 1)/k.
    p0.append(a + s[:-1, None] * ab)
    p1.append(a + s[:-1, None] * ab + (1.0 - s[:-1, None]) * ac)
    p0.append(a + s[:-1, None] * ac)
    p1.append(a + s[:-1, None] * ac + (1.0 - s[:-1, None]) * ab)
    return np.concatenate(p0), np.concatenate(p1)


def certify_triangle(obstacles: ObstacleSet, a, b, c, margin: float, resolution: float,
                     known_sides: float = -math.inf) -> Tuple[bool, float]:
    """Certify that the whole (filled) triangle abc keeps ``margin`` from the obstacles.

    The triangle is cut into ``k**2`` triangles congruent to ``abc / k``; the ``3 k`` cutting
    lines are certified to keep ``margin + r / k`` (``r``: the inradius of abc), and every point
    of the triangle is within ``r / k`` of a cutting line, so by the 1-Lipschitz obstacle
    distance it keeps ``margin``. ``k`` is chosen so that ``r / k <= TURN_CELL_INRADIUS``.

    Parameters
    ----------
    obstacles : ObstacleSet
    a, b, c : array_like, shape (3,)
        Corners [m].
    margin, resolution : float
        Required clearance and the engine's length scale delta [m].
    known_sides : float
        A clearance the sides ``ab`` and ``bc`` are already certified to keep [m] (for a turn
        region: the legs); they are not certified again when it suffices.

    Returns
    -------
    clear : bool
    bound : float
        Certified lower bound on the clearance of the triangle [m] (-inf when not clear).
    """
    a, b, c = (np.asarray(p, dtype=np.float64) for p in (a, b, c))
    perimeter = np.linalg.norm(b - a) + np.linalg.norm(c - b) + np.linalg.norm(a - c)
    area2 = np.linalg.norm(np.cross(b - a, c - a))
    inradius = area2 / perimeter if perimeter > 0.0 else 0.0
    k = int(min(max(math.ceil(inradius / TURN_CELL_INRADIUS), 1), _MAX_TURN_SUBDIVISION))
    extra = inradius / k
    starts, ends = _triangle_lines(a, b, c, k)
    if known_sides >= margin + extra:
        # Lines 0 .. k-1 are parallel to bc (the last one is bc), k .. 2k-1 parallel to ac
        # (the first is ac), 2k .. 3k-1 parallel to ab (the first is ab).
        keep = np.ones(len(starts), dtype=bool)
        keep[[k - 1, 2 * k]] = False
        starts, ends = starts[keep], ends[keep]
    cert = certify_segments(obstacles, starts, ends, margin + extra, resolution)
    if not np.all(cert.clear):
        return False, -math.inf
    bound = float(np.min(cert.bound)) - extra
    if known_sides >= margin + extra:
        bound = min(bound, known_sides - extra)
    return True, bound


def turn_triangle(before: np.ndarray, corner: np.ndarray, after: np.ndarray,
                  radius: float) -> np.ndarray:
    """The turn region ``(A, P, B)`` at ``corner`` for acceptance radius ``radius`` [m].

    ``A`` is ``radius`` back along the incoming leg (from ``before``), ``B`` ``radius`` along the
    outgoing leg (to ``after``); both legs must be at least ``radius`` long.
    """
    corner = np.asarray(corner, dtype=np.float64)
    a = corner + radius * _unit(np.asarray(before, dtype=np.float64) - corner)
    b = corner + radius * _unit(np.asarray(after, dtype=np.float64) - corner)
    return np.stack([a, corner, b])


# --------------------------------------------------------------------------------------------
# Waypoint search
# --------------------------------------------------------------------------------------------

@dataclass
class _Node:
    position: np.ndarray
    before: Optional[np.ndarray]     # incoming leg start: the node is a turn when set
    candidate: int                   # candidate index, -1 for the first node
    progress: float


class _Search:
    """Depth-first farthest-first search of certified waypoints over the candidates."""

    def __init__(self, obstacles: ObstacleSet, candidates: np.ndarray, progress: np.ndarray,
                 mandatory: np.ndarray, margin: float, resolution: float, radius: float,
                 after_goal: Optional[np.ndarray]) -> None:
        self.obstacles = obstacles
        self.candidates = candidates
        self.progress = progress
        self.mandatory = mandatory          # sorted candidate indices that cannot be skipped
        self.margin = margin
        self.leg_margin = margin + TURN_CELL_INRADIUS
        self.resolution = resolution
        self.radius = radius
        self.goal = len(candidates) - 1
        self.after_goal = after_goal        # first point flown after the goal (a turn), or None
        self.budget = _SEARCH_BUDGET
        self.farthest = 0.0

    def _spend(self, amount: int = 1) -> None:
        self.budget -= amount
        if self.budget < 0:
            raise _SearchExhausted()

    def _legs_clear(self, origin: np.ndarray, indices: np.ndarray) -> np.ndarray:
        # Legs keep a turn cell's inradius more than the turns, so that the turn triangles'
        # sides, which lie on the legs, need no second certificate.
        self._spend()
        ends = self.candidates[indices]
        starts = np.broadcast_to(origin, ends.shape)
        return certify_segments(self.obstacles, starts, ends, self.leg_margin,
                                self.resolution).clear

    def _window(self, node: _Node) -> Tuple[int, int]:
        lo = int(np.searchsorted(self.progress, node.progress, side='right'))
        lo = max(lo, node.candidate + 1)
        ahead = self.mandatory[self.mandatory >= lo]
        hi = int(ahead[0]) if len(ahead) else self.goal
        return lo, hi

    def _clear_batches(self, node: _Node) -> Iterator[np.ndarray]:
        """Candidates with a certified leg from ``node``, farthest first, in batches (lazily)."""
        lo, hi = self._window(node)
        if lo > hi:
            return
        if hi - lo + 1 <= _FULL_SCAN:
            indices = np.arange(lo, hi + 1)
            yield indices[self._legs_clear(node.position, indices)][::-1]
            return
        # Gallop outwards, then bisect between the farthest clear and the next blocked one.
        offsets = np.unique(np.r_[(2 ** np.arange(int(math.log2(hi - lo)) + 1)) - 1, hi - lo])
        tested = lo + offsets
        clear = self._legs_clear(node.position, tested)
        known = dict(zip(tested.tolist(), clear.tolist()))
        clear_tested = tested[clear]
        below = hi
        if len(clear_tested):
            best = int(clear_tested[-1])
            later = tested[tested > best]
            blocked = int(later[0]) if len(later) else None
            while blocked is not None and blocked - best > 1:
                mid = (best + blocked) // 2
                ok = bool(self._legs_clear(node.position, np.array([mid]))[0])
                known[mid] = ok
                best, blocked = (mid, blocked) if ok else (best, mid)
            yield np.array([best])
            below = best - 1
        # Everything else below, in descending batches.
        while below >= lo:
            batch = np.arange(max(lo, below - _FULL_SCAN + 1), below + 1)[::-1]
            todo = np.array([j for j in batch.tolist() if j not in known], dtype=np.int64)
            if len(todo):
                for j, ok in zip(todo.tolist(), self._legs_clear(node.position, todo).tolist()):
                    known[j] = ok
            yield np.array([j for j in batch.tolist() if known[j]], dtype=np.int64)
            below = int(batch[-1]) - 1

    def _options(self, node: _Node) -> Iterator[int]:
        """Next waypoints from ``node`` that pass every check, farthest first (lazily)."""
        radius = self.radius
        for batch in self._clear_batches(node):
            if not len(batch):
                continue
            targets = self.candidates[batch]
            lengths = np.linalg.norm(targets - node.position, axis=1)
            final = batch == self.goal
            turns = int(node.before is not None) + (~final | (self.after_goal is not None))
            keep = lengths >= radius * np.maximum(turns, 1)
            if node.before is not None and np.any(keep):
                # The cut A -> B first, for the whole batch: most turns that fail, fail there,
                # and one segment is far cheaper than the subdivided triangle.
                self._spend()
                a = node.position + radius * _unit(node.before - node.position)
                b = node.position + radius * (targets[keep] - node.position) / lengths[keep, None]
                cut = certify_segments(self.obstacles, np.broadcast_to(a, b.shape), b,
                                       self.margin, self.resolution).clear
                keep[np.flatnonzero(keep)[~cut]] = False
            for j in batch[keep].tolist():
                target = self.candidates[j]
                if node.before is not None and not self._turn_clear(
                        node.before, node.position, target, radius):
                    continue
                if j == self.goal and self.after_goal is not None:
                    after = self.after_goal
                    r = min(radius, float(np.linalg.norm(after - target)))
                    if not self._turn_clear(node.position, target, after, r):
                        continue
                yield j

    def _turn_clear(self, before: np.ndarray, corner: np.ndarray, after: np.ndarray,
                    radius: float) -> bool:
        self._spend()
        tri = turn_triangle(before, corner, after, radius)
        return certify_triangle(self.obstacles, *tri, self.margin, self.resolution,
                                known_sides=self.leg_margin)[0]

    def run(self, first: _Node) -> List[_Node]:
        """Depth-first search from ``first`` to the goal; backtracks at most a few waypoints."""
        chain = [first]
        stack = [self._options(first)]
        tried = [0]
        deepest = 0
        while stack:
            self.farthest = max(self.farthest, chain[-1].progress)
            if chain[-1].candidate == self.goal:
                return chain
            choice = next(stack[-1], None) if tried[-1] < _OPTIONS_PER_WAYPOINT else None
            if choice is None:
                if len(chain) <= deepest - _BACKTRACK_WAYPOINTS:
                    break
                stack.pop()
                chain.pop()
                tried.pop()
                continue
            tried[-1] += 1
            node = _Node(self.candidates[choice], chain[-1].position, choice,
                         float(self.progress[choice]))
            chain.append(node)
            stack.append(self._options(node))
            tried.append(0)
            deepest = max(deepest, len(chain))
        raise _SearchExhausted()


class _SearchExhausted(Exception):
    pass


def _push_off(points: np.ndarray, obstacles: ObstacleSet, target: float, max_shift: float,
              lo: np.ndarray, hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Move points closer than ``target`` to an obstacle up the distance gradient.

    Damped steps (a fraction of the missing clearance, at most ``max_step``) climb away from the
    nearest obstacle and, between two obstacles, settle on the ridge midway instead of bouncing
    between them: where ``target`` is out of reach (an alley narrower than twice it), the point
    ends near the middle, the best place there is. Returns the moved points (at most
    ``max_shift`` from where they started) and their clearances [m].
    """
    moved = points.copy()
    # Distances capped a little above the target: exact where it matters, and a capped query
    # reads only the obstacles near the point.
    cap = target + 1.0
    dist = obstacles.distance(moved, cap)
    todo = np.flatnonzero(dist < target)
    h = 1e-4
    max_step = max(max_shift / 4.0, 1e-3)
    for _ in range(_PUSH_ITERATIONS):
        if not len(todo):
            break
        p = moved[todo]
        grad = np.zeros_like(p)
        for axis in range(3):
            offset = np.zeros(3)
            offset[axis] = h
            ahead = obstacles.distance(p + offset, cap)
            grad[:, axis] = (ahead - obstacles.distance(p - offset, cap)) / (2.0 * h)
        norm = np.linalg.norm(grad, axis=1)
        usable = norm > 1e-6
        gap = target - obstacles.distance(p, cap)
        length = np.minimum(0.6 * gap + 2e-3, max_step)
        shift = np.where(usable[:, None],
                         grad * (length / np.where(usable, norm, 1.0))[:, None], 0.0)
        moved[todo] = np.clip(p + shift, lo, hi)
        far = np.linalg.norm(moved[todo] - points[todo], axis=1) > max_shift
        todo = todo[(obstacles.distance(moved[todo], cap) < target) & usable & ~far]
    far = np.linalg.norm(moved - points, axis=1) > max_shift
    moved[far] = points[far]
    return moved, obstacles.distance(moved, cap)


def _offset_layers(points: np.ndarray, progress: np.ndarray, fixed: np.ndarray,
                   obstacles: ObstacleSet, margin: float, radius: float, shift: float,
                   lo: np.ndarray, hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keep the candidates that keep ``margin``, and add pushed-off copies near obstacles.

    A turn cuts inside its corner by up to about ``R``, so waypoints near an obstacle need more
    room than a leg does: for each of :data:`_OFFSET_LAYERS` a copy of every candidate below
    ``margin + f R`` is pushed towards that clearance (by at most ``shift + f R``; in a passage
    too narrow for it, to the passage's middle) and kept if it keeps ``margin``. Copies sort
    just before their original, so the search tries the original first.
    """
    dist = obstacles.distance(points, margin + radius + 1.0)
    keep = fixed | (dist >= margin)
    out = [(points[keep], progress[keep], fixed[keep], np.zeros(int(keep.sum())))]
    for rank, fraction in enumerate(_OFFSET_LAYERS, start=1):
        target = margin + fraction * radius
        select = ~fixed & (dist < target)
        if not np.any(select):
            continue
        moved, clearance = _push_off(points[select], obstacles, target,
                                     shift + fraction * radius, lo, hi)
        # Also those that stopped short of the target on a ridge: the middle of a narrow alley.
        ok = (clearance >= margin) & (np.linalg.norm(moved - points[select], axis=1) > 1e-3)
        count = int(ok.sum())
        out.append((moved[ok], progress[select][ok], np.zeros(count, dtype=bool),
                    np.full(count, float(rank))))
    points, progress, fixed, rank = (np.concatenate(column) for column in zip(*out))
    order = np.lexsort((-rank, progress))
    return points[order], progress[order], fixed[order]


def _candidates(smoothed: np.ndarray, raw: np.ndarray, via: np.ndarray, spacing: float
                ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Candidate points, their progress along the curve (sample index) and the fixed ones."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(smoothed, axis=0), axis=1))]
    marks = np.floor(arc / spacing)
    keep = np.r_[True, marks[1:] != marks[:-1]]
    keep[-1] = True
    tree = cKDTree(smoothed)
    points = [smoothed[keep]]
    progress = [np.flatnonzero(keep).astype(np.float64)]
    fixed = [np.zeros(int(keep.sum()), dtype=bool)]
    fixed[0][[0, -1]] = True
    last = len(smoothed) - 1
    if len(raw):
        _, nearest = tree.query(raw)
        inner = (nearest > 0) & (nearest < last)
        points.append(raw[inner])
        # Just after the curve sample they are nearest to, so the sample comes first.
        progress.append(nearest[inner] + 0.25)
        fixed.append(np.zeros(int(inner.sum()), dtype=bool))
    if len(via):
        _, nearest = tree.query(via)
        points.append(via)
        progress.append(nearest.astype(np.float64) + 0.5)
        fixed.append(np.ones(len(via), dtype=bool))
    points = np.concatenate(points)
    progress = np.concatenate(progress)
    fixed = np.concatenate(fixed)
    # The start and the goal stay first and last.
    progress[0], progress[int(keep.sum()) - 1] = -1.0, last + 1.0
    order = np.argsort(progress, kind='stable')
    return points[order], progress[order], fixed[order]


# --------------------------------------------------------------------------------------------
# Building the mission
# --------------------------------------------------------------------------------------------

def _as_path(value: Any, name: str, allow_empty: bool = False) -> np.ndarray:
    try:
        points = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name} must be an (N, 3) array of numbers [m]') from None
    if points.size == 0 and allow_empty:
        return np.empty((0, 3))
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise InvalidInputError(f'{name} must have shape (N, 3), got {points.shape}')
    if not np.all(np.isfinite(points)):
        raise InvalidInputError(f'{name} must be finite; found NaN or inf')
    return points


def _yaw(settings: MissionSettings) -> float:
    # PX4 turns to the given yaw (0 = north) unless it is NaN; ArduCopter ignores the field.
    return math.nan if settings.firmware == 'px4' else 0.0


def _round(value: float, decimals: int) -> float:
    return value if math.isnan(value) else round(float(value), decimals) + 0.0


def _item(command: int, frame: int, p1: float = 0.0, p2: float = 0.0, p3: float = 0.0,
          p4: float = 0.0, lat: float = 0.0, lon: float = 0.0, alt: float = 0.0) -> MissionItem:
    params = tuple(_round(p, PARAM_DECIMALS) for p in (p1, p2, p3, p4)) + (
        _round(lat, LATLON_DECIMALS), _round(lon, LATLON_DECIMALS), _round(alt, ALTITUDE_DECIMALS))
    return MissionItem(int(command), int(frame), params, True)


class _Geo:
    """Rounded WGS84 values of map-frame points, and the map-frame points they stand for."""

    def __init__(self, origin: GeodeticOrigin, home: np.ndarray) -> None:
        self.origin = origin
        lat, lon, alt = enu_to_geodetic(home[None], origin)
        self.home = (_round(lat[0], LATLON_DECIMALS), _round(lon[0], LATLON_DECIMALS),
                     _round(alt[0], ALTITUDE_DECIMALS))

    def stored(self, points: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude, longitude [deg] and altitude above home [m], rounded as stored."""
        lat, lon, alt = enu_to_geodetic(points, self.origin)
        return (np.round(lat, LATLON_DECIMALS), np.round(lon, LATLON_DECIMALS),
                np.round(alt - self.home[2], ALTITUDE_DECIMALS))

    def back(self, lat: np.ndarray, lon: np.ndarray, rel: np.ndarray) -> np.ndarray:
        """Map-frame positions of stored values [m]."""
        return geodetic_to_enu(lat, lon, np.asarray(rel) + self.home[2], self.origin)


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (
        a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])


def _segments_meet(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> bool:
    """True when any 2D segment ``p0[i] p1[i]`` meets any ``q0[j] q1[j]`` (touching counts)."""
    a, b = p0[:, None], p1[:, None]
    c, d = q0[None], q1[None]
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    proper = (d1 * d2 < 0.0) & (d3 * d4 < 0.0)
    if np.any(proper):
        return True

    def on(o, e, x, side):
        lo, hi = np.minimum(o, e), np.maximum(o, e)
        return (side == 0.0) & np.all((x >= lo - 1e-12) & (x <= hi + 1e-12), axis=-1)
    return bool(np.any(on(c, d, a, d1) | on(c, d, b, d2) | on(a, b, c, d3) | on(a, b, d, d4)))


def _inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd test of 2D points against a simple polygon."""
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddle = (y0 > y) != (y1 > y)
    with np.errstate(divide='ignore', invalid='ignore'):
        at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return np.sum(straddle & (x < at), axis=1) % 2 == 1


def _footprint_crossed(polygon: np.ndarray, legs: np.ndarray, turns: np.ndarray) -> bool:
    """True when the 2D footprint of the flight (legs and turn triangles) meets the polygon."""
    edges0, edges1 = polygon, np.roll(polygon, -1, axis=0)
    starts, ends = legs[:, 0, :2], legs[:, 1, :2]
    if len(turns):
        # A turn triangle's sides on the legs are legs already; its cut A -> B is not.
        starts = np.vstack([starts, turns[:, 0, :2]])
        ends = np.vstack([ends, turns[:, 2, :2]])
    if _segments_meet(starts, ends, edges0, edges1):
        return True
    if np.any(_inside_polygon(legs[:, 0, :2], polygon)):
        return True
    return any(np.any(_inside_polygon(polygon[:1], tri[:, :2])) for tri in turns)


def _circle_polygon(center: np.ndarray, radius: float, count: int = 64) -> np.ndarray:
    """A polygon around a circle (circumscribed), for the footprint test."""
    angles = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
    scale = radius / math.cos(math.pi / count)
    return center + scale * np.c_[np.cos(angles), np.sin(angles)]


def fences_of_airspace(airspace: Airspace, legs: np.ndarray = np.empty((0, 2, 3)),
                       turns: np.ndarray = np.empty((0, 3, 3))
                       ) -> Tuple[List[FencePolygon], List[FenceCircle], List[str]]:
    """The 2D autopilot fences of an airspace, for a mission flying ``legs`` and ``turns``.

    Inclusion fences become inclusion polygons and circles; prisms, boxes and cylinders become
    exclusion polygons and circles (their footprints). Autopilot fences are 2D (PX4 and
    ArduPilot take the height limit from parameters), so an exclusion zone whose footprint the
    mission flies over or under is skipped (named in the third list) rather than written as a
    fence the mission would breach; the mission keeps its clearance from it all the same.
    """
    polygons: List[FencePolygon] = []
    circles: List[FenceCircle] = []
    skipped: List[str] = []
    for fence in airspace.inclusions:
        if isinstance(fence, InclusionFence):
            polygons.append(FencePolygon(fence.polygon, inclusion=True))
        elif isinstance(fence, InclusionCircle):
            circles.append(FenceCircle(fence.center, fence.radius, inclusion=True))
    for zone in airspace.exclusions:
        if isinstance(zone, Cylinder):
            footprint = _circle_polygon(zone.center, zone.radius)
        elif isinstance(zone, Prism):
            footprint = zone.polygon
        elif isinstance(zone, BoxZone):
            (x0, y0), (x1, y1) = zone.min[:2], zone.max[:2]
            footprint = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        else:
            continue
        if len(legs) and _footprint_crossed(footprint, legs, turns):
            skipped.append(f'{zone.label}: the mission flies over or under it')
            continue
        if isinstance(zone, Cylinder):
            circles.append(FenceCircle(zone.center, zone.radius, inclusion=False))
        else:
            polygons.append(FencePolygon(footprint, inclusion=False))
    return polygons, circles, skipped


def _fence(polygons: Sequence[FencePolygon], circles: Sequence[FenceCircle],
           origin: GeodeticOrigin, skipped: Sequence[str] = ()) -> GeoFence:
    out_polygons = []
    for polygon in polygons:
        xy = polygon.vertices
        signed = 0.5 * float(np.sum(xy[:, 0] * np.roll(xy[:, 1], -1)
                                    - np.roll(xy[:, 0], -1) * xy[:, 1]))
        if signed > 0.0:   # counter-clockwise seen from above (x east, y north): reverse
            xy = xy[::-1]
        lat, lon, _ = enu_to_geodetic(np.c_[xy, np.zeros(len(xy))], origin)
        out_polygons.append((tuple((_round(a, LATLON_DECIMALS), _round(b, LATLON_DECIMALS))
                                   for a, b in zip(lat, lon)), bool(polygon.inclusion)))
    out_circles = []
    for circle in circles:
        lat, lon, _ = enu_to_geodetic(np.r_[circle.center, 0.0][None], origin)
        out_circles.append(((_round(lat[0], LATLON_DECIMALS), _round(lon[0], LATLON_DECIMALS)),
                            _round(circle.radius, ALTITUDE_DECIMALS), bool(circle.inclusion)))
    return GeoFence(tuple(out_polygons), tuple(out_circles), tuple(skipped))


def build_mission(smoothed_path: Any, obstacles: ObstacleSet, config: PlannerConfig,
                  origin: GeodeticOrigin, settings: MissionSettings = MissionSettings(), *,
                  raw_path: Any = (), via: Any = (),
                  fence_polygons: Sequence[FencePolygon] = (),
                  fence_circles: Sequence[FenceCircle] = (),
                  airspace: Optional[Airspace] = None) -> Mission:
    """Choose certified waypoints along a plan and make the mission items.

    Parameters
    ----------
    smoothed_path : array_like, shape (M, 3)
        Samples of the plan's smoothed curve, start first and goal last [m] (map frame).
    obstacles : ObstacleSet
        The obstacles the mission must keep clear of (map frame).
    config : PlannerConfig
        Bounds (the floor is the ground), gamma, delta, and the speed limits of the plan.
    origin : GeodeticOrigin
        WGS84 position of the map frame's origin.
    settings : MissionSettings
    raw_path : array_like, shape (N, 3), optional
        The plan's raw grid path: more candidate waypoints.
    via : array_like, shape (V, 3), optional
        Via-points the mission must fly through (never skipped).
    fence_polygons, fence_circles : sequences
        Geofences to write with the mission (not part of the certificate; see the module notes).
    airspace : Airspace, optional
        The fences and zones of the map (:mod:`uav_global_planner.core.airspace`), written as
        the mission's 2D geofence (:func:`fences_of_airspace`). For the certificate they must be
        in ``obstacles`` as well, as a scene file's ``geofence`` puts them.

    Returns
    -------
    Mission

    Raises
    ------
    InvalidInputError
        For malformed input (shapes, NaN, a path outside the bounds).
    UncertifiableMissionError
        When no mission keeps gamma + allowance: names the place and the reason.
    MissingDependencyError
        When pymap3d is not installed.
    """
    if not isinstance(obstacles, ObstacleSet):
        raise InvalidInputError('obstacles must be an ObstacleSet')
    if not isinstance(settings, MissionSettings):
        raise InvalidInputError('settings must be a MissionSettings')
    smoothed = _as_path(smoothed_path, 'smoothed_path')
    raw = _as_path(raw_path, 'raw_path', allow_empty=True)
    via_points = _as_path(via, 'via', allow_empty=True)
    lo = np.asarray(config.bounds_min, dtype=np.float64)
    hi = np.asarray(config.bounds_max, dtype=np.float64)
    slack_bounds = 1e-6 * max(1.0, float(np.max(hi - lo)))
    if np.any(smoothed < lo - slack_bounds) or np.any(smoothed > hi + slack_bounds):
        raise InvalidInputError('smoothed_path leaves the bounds of the config: not a plan of '
                                'this map')
    gamma = float(config.safety_margin)
    delta = float(config.resolution)
    radius = float(settings.acceptance_radius)
    # Rounded to a nanometre so that 0.2 + 0.1 reads 0.3 in every report.
    required = round(gamma + float(settings.tracking_allowance), 9)
    search_margin = required + ROUNDING_SLACK
    # Legs (and so every waypoint) keep a turn cell's inradius more: see _Search._legs_clear.
    leg_margin = search_margin + TURN_CELL_INRADIUS
    start, goal = smoothed[0], smoothed[-1]
    if np.linalg.norm(goal - start) < radius:
        raise InvalidInputError(
            f'start and goal are {np.linalg.norm(goal - start):.3f} m apart, less than the '
            f'acceptance radius {radius} m: nothing to fly')
    floor = float(lo[2])
    tolerance = delta if settings.ground_tolerance is None else float(settings.ground_tolerance)
    min_height = required if settings.min_height is None else float(settings.min_height)
    on_ground = float(start[2]) - floor <= tolerance
    home = start.copy() if on_ground else np.array([start[0], start[1], floor])

    goal_clearance = float(obstacles.distance(goal))
    if goal_clearance < leg_margin:
        raise UncertifiableMissionError(
            f'the goal {np.round(goal, 3).tolist()} is {goal_clearance:.3f} m from an obstacle; '
            f'the mission needs gamma + tracking allowance = {required:.3f} m (plus '
            f'{ROUNDING_SLACK} m for rounding): lower tracking_allowance or move the goal')
    for n, point in enumerate(via_points):
        clearance = float(obstacles.distance(point))
        if clearance < leg_margin:
            raise UncertifiableMissionError(
                f'via-point {n} {np.round(point, 3).tolist()} is {clearance:.3f} m from an '
                f'obstacle; the mission needs {required:.3f} m')

    # The first node: the take-off point (a turn whose incoming leg is the climb), or the start.
    if on_ground:
        heights = _takeoff_heights(obstacles, start, hi, settings, leg_margin, required, delta,
                                   max(radius, floor + min_height - float(start[2])))
        firsts = [_Node(start + np.array([0.0, 0.0, h]), start, -1, -1.0) for h in heights]
    else:
        firsts = [_Node(start, None, -1, -1.0)]

    spacing = max(delta / 2.0, 1e-3)
    points, progress, fixed = _candidates(smoothed, raw, via_points, spacing)
    # The ground is kept at the clearance too: waypoints (not the goal or via-points) are
    # lifted to ``min_height`` above the floor; straight legs and turn triangles between points
    # above it stay above it.
    raised = lo.copy()
    raised[2] = min(floor + min_height, float(hi[2]))
    points[~fixed, 2] = np.maximum(points[~fixed, 2], raised[2])
    points, progress, fixed = _offset_layers(points, progress, fixed, obstacles, leg_margin,
                                             radius, settings.tracking_allowance + delta, raised,
                                             hi)
    mandatory = np.flatnonzero(fixed)[1:]       # the vias and the goal; not the start
    if progress[0] < 0.0:                       # the start is where the first node is
        points, progress, fixed = points[1:], progress[1:], fixed[1:]
        mandatory = mandatory - 1
    progress = np.maximum(progress, 0.0)

    end_points = _end_points(goal, home, floor, hi, settings)
    _check_end(obstacles, goal, end_points, search_margin, required, delta, radius)
    search = _Search(obstacles, points, progress, mandatory, search_margin, delta, radius,
                     end_points[0] if len(end_points) else None)
    chain = None
    # The highest clear take-off first; a lower one where the turn under an overhang fails.
    for first in firsts:
        try:
            chain = search.run(first)
            break
        except _SearchExhausted:
            continue
    if chain is None:
        where = smoothed[min(int(max(search.farthest, 0.0)), len(smoothed) - 1)]
        raise UncertifiableMissionError(
            f'no certified waypoints past {np.round(where, 3).tolist()} (the plan there is '
            f'{float(obstacles.distance(where)):.3f} m from an obstacle): straight legs, turns '
            f'within acceptance radius {radius} m and legs >= that radius cannot keep gamma + '
            f'tracking allowance = {required:.3f} m; lower tracking_allowance or '
            'acceptance_radius, or plan with a larger safety_margin')

    nominal = [home] if on_ground else []
    nominal += [node.position for node in chain]
    nominal = np.array(nominal)
    geo = _Geo(origin, home)
    return _assemble(nominal, end_points, on_ground, geo, obstacles, config, settings, required,
                     (fence_polygons, fence_circles, airspace))


def _takeoff_heights(obstacles: ObstacleSet, start: np.ndarray, hi: np.ndarray,
                     settings: MissionSettings, margin: float, required: float,
                     delta: float, lowest: float) -> List[float]:
    """Clear take-off climb heights between ``lowest`` and ``takeoff_height``, highest first.

    ``lowest`` is the acceptance radius (the take-off point is a turn) or the minimum height,
    whichever is higher. A climb clear to some height is clear to every lower one; the highest
    clear height of a ladder ``delta / 4`` apart comes first, then up to
    :data:`_TAKEOFF_ALTERNATIVES` lower ones spread down to ``lowest``.
    """
    top = min(max(settings.takeoff_height, lowest), float(hi[2] - start[2]))
    if top < lowest:
        raise UncertifiableMissionError(
            f'the take-off climb needs {lowest:.3f} m of height above the start (the acceptance '
            f'radius, or the minimum height), but the map ends {hi[2] - start[2]:.3f} m above it')
    steps = max(int(math.ceil((top - lowest) / (delta / 4.0))), 0)
    heights = np.linspace(top, lowest, steps + 1) if steps else np.array([top])
    ends = start + np.c_[np.zeros((len(heights), 2)), heights]
    clear = certify_segments(obstacles, np.broadcast_to(start, ends.shape), ends, margin,
                             delta).clear
    if not np.any(clear):
        raise UncertifiableMissionError(
            f'the take-off climb from {np.round(start, 3).tolist()} does not keep '
            f'{required:.3f} m from the obstacles even to {lowest:.3f} m above it (the start '
            f'itself is {float(obstacles.distance(start)):.3f} m from one)')
    usable = heights[int(np.argmax(clear)):]
    picks = np.unique(np.round(np.linspace(0, len(usable) - 1,
                                           min(len(usable), _TAKEOFF_ALTERNATIVES))))
    return [float(usable[int(i)]) for i in picks]


def _check_end(obstacles: ObstacleSet, goal: np.ndarray, end_points: np.ndarray,
               margin: float, required: float, delta: float, radius: float) -> None:
    """Certify the legs and the fixed turns flown after the goal (land, rtl)."""
    if not len(end_points):
        return
    path = np.vstack([goal[None], end_points])
    legs = certify_segments(obstacles, path[:-1], path[1:], margin + TURN_CELL_INRADIUS, delta)
    if not np.all(legs.clear):
        bad = int(np.flatnonzero(~legs.clear)[0])
        raise UncertifiableMissionError(
            f'the end of the mission flies {np.round(path[bad], 3).tolist()} -> '
            f'{np.round(path[bad + 1], 3).tolist()}, which does not keep {required:.3f} m from '
            'the obstacles; choose another end action (loiter holds at the goal)')
    for n in range(1, len(path) - 1):
        r = min(radius, float(np.linalg.norm(path[n] - path[n - 1])),
                float(np.linalg.norm(path[n + 1] - path[n])))
        if not certify_triangle(obstacles, *turn_triangle(path[n - 1], path[n], path[n + 1], r),
                                margin, delta, known_sides=margin + TURN_CELL_INRADIUS)[0]:
            raise UncertifiableMissionError(
                f'the turn of the end action at {np.round(path[n], 3).tolist()} does not keep '
                f'{required:.3f} m from the obstacles; choose another end action')


def _end_points(goal: np.ndarray, home: np.ndarray, floor: float, hi: np.ndarray,
                settings: MissionSettings) -> np.ndarray:
    """Map-frame points flown after the goal by the end action."""
    if settings.end == 'land':
        return np.array([[goal[0], goal[1], floor]]) if goal[2] > floor else np.empty((0, 3))
    if settings.end == 'rtl':
        top = max(float(goal[2]), float(home[2]) + settings.rtl_altitude)
        if top > hi[2] + 1e-9:
            raise UncertifiableMissionError(
                f'the return altitude {top - home[2]:.3f} m above home reaches z = {top:.3f} m, '
                f'above the map (bounds max z {hi[2]} m), where no obstacles are known')
        points = []
        if top > goal[2]:
            points.append([goal[0], goal[1], top])
        points += [[home[0], home[1], top], home.tolist()]
        return np.array(points)
    return np.empty((0, 3))


def _assemble(nominal: np.ndarray, end_points: np.ndarray, on_ground: bool, geo: _Geo,
              obstacles: ObstacleSet, config: PlannerConfig, settings: MissionSettings,
              required: float, fences: Tuple[Sequence[FencePolygon], Sequence[FenceCircle],
                                             Optional[Airspace]]) -> Mission:
    """Round to the stored values, certify what is stored and make the items."""
    radius = settings.acceptance_radius
    yaw = _yaw(settings)
    lat, lon, rel = geo.stored(nominal)
    count = len(nominal)
    if on_ground:
        # Home and the take-off point share the start's horizontal position, as flown.
        lat[1], lon[1] = lat[0], lon[0]
    stored = geo.back(lat, lon, rel)
    home_enu = geo.back(np.array([geo.home[0]]), np.array([geo.home[1]]), np.zeros(1))[0]
    if on_ground:
        stored[0] = home_enu
    # The end action flies from the stored goal and returns to the stored home; the files hold
    # no positions of their own for it (LAND takes the goal's, RTL none).
    if len(end_points):
        end_points = _end_points(stored[-1], home_enu, float(config.bounds_min[2]),
                                 np.asarray(config.bounds_max, dtype=np.float64), settings)
    path = np.vstack([stored, end_points])
    # Drop repeated points (an end descent of length 0, a return already at altitude).
    keep = np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9]
    flight = path[keep]

    # Turns: every interior point of the flight path, except the loiter goal at the end.
    turns = []
    for n in range(1, len(flight) - 1):
        before, corner, after = flight[n - 1], flight[n], flight[n + 1]
        r = min(radius, float(np.linalg.norm(before - corner)),
                float(np.linalg.norm(after - corner)))
        turns.append(turn_triangle(before, corner, after, r))
    turns = np.array(turns).reshape(-1, 3, 3)

    delta = config.resolution
    legs = certify_segments(obstacles, flight[:-1], flight[1:], required, delta)
    bounds = [np.min(legs.bound)] if len(legs.bound) else []
    if not np.all(legs.clear):
        bad = int(np.flatnonzero(~legs.clear)[0])
        raise UncertifiableMissionError(
            f'the stored leg {np.round(flight[bad], 3).tolist()} -> '
            f'{np.round(flight[bad + 1], 3).tolist()} does not keep {required:.3f} m')
    for tri in turns:
        ok, bound = certify_triangle(obstacles, *tri, required, delta)
        if not ok:
            raise UncertifiableMissionError(
                f'the turn at {np.round(tri[1], 3).tolist()} does not keep {required:.3f} m '
                'from the obstacles')
        bounds.append(bound)
    certified = float(min(bounds)) if bounds else math.inf
    polygons, circles, airspace = fences
    skipped: List[str] = []
    if airspace is not None:
        extra_polygons, extra_circles, skipped = fences_of_airspace(
            airspace, np.stack([flight[:-1], flight[1:]], axis=1), turns)
        polygons, circles = list(polygons) + extra_polygons, list(circles) + extra_circles
    fence = _fence(polygons, circles, geo.origin, skipped)

    items: List[MissionItem] = []
    first_wp = 1 if on_ground else 0
    if on_ground:
        items.append(_item(MAV_CMD_NAV_TAKEOFF, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0, 0.0, 0.0,
                           yaw, lat[1], lon[1], rel[1]))
        first_wp = 2
    vh, vz = float(config.max_speed_horizontal), float(config.max_speed_vertical)
    items.append(_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, SPEED_TYPE_GROUND, vh, -1.0))
    if settings.firmware == 'ardupilot':
        items.append(_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, SPEED_TYPE_CLIMB, vz,
                           -1.0))
        items.append(_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, SPEED_TYPE_DESCENT, vz,
                           -1.0))
    last = count - 1
    for n in range(first_wp, count):
        if n == last and settings.end == 'loiter':
            items.append(_item(MAV_CMD_NAV_LOITER_UNLIM, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0, 0.0,
                               0.0, yaw, lat[n], lon[n], rel[n]))
        else:
            items.append(_item(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0, radius,
                               0.0, yaw, lat[n], lon[n], rel[n]))
    if settings.end == 'land':
        items.append(_item(MAV_CMD_NAV_LAND, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0, 0.0, 0.0, yaw,
                           lat[last], lon[last], 0.0))
    elif settings.end == 'rtl':
        items.append(_item(MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_FRAME_MISSION))
    return Mission(items=tuple(items), home=geo.home, home_enu=home_enu, origin=geo.origin,
                   settings=settings, flight_path=flight, turn_regions=turns,
                   safety_margin_m=float(config.safety_margin), required_clearance_m=required,
                   certified_clearance_m=certified, speed_horizontal=vh, speed_vertical=vz,
                   fence=fence)


def mission_from_plan(result: Any, obstacles: ObstacleSet, config: PlannerConfig,
                      origin: GeodeticOrigin, settings: MissionSettings = MissionSettings(),
                      **fences: Any) -> Mission:
    """:func:`build_mission` for a :class:`~uav_global_planner.core.result.PlanResult`.

    Raises
    ------
    InvalidInputError
        When the plan did not succeed.
    """
    if not getattr(result, 'ok', False):
        raise InvalidInputError(f'no plan to export: the plan failed '
                                f'({getattr(result, "status", "?")})')
    return build_mission(result.smoothed_path, obstacles, config, origin, settings,
                         raw_path=result.path, via=getattr(result, 'via', ()), **fences)


# --------------------------------------------------------------------------------------------
# Writers
# --------------------------------------------------------------------------------------------

def _json_number(value: float) -> Optional[float]:
    return None if math.isnan(value) else value


def plan_document(mission: Mission, ground_station: str = 'uav_global_planner') -> Dict[str, Any]:
    """The QGroundControl ``.plan`` document (JSON-ready dictionary) of a mission.

    Layout of QGroundControl's plan-file format: ``fileType`` "Plan", ``version`` 1; ``mission``
    version 2 with ``firmwareType`` (MAV_AUTOPILOT), ``vehicleType`` 2 (quadrotor),
    ``cruiseSpeed``/``hoverSpeed`` [m/s], ``plannedHomePosition`` [lat, lon, m AMSL] and
    ``SimpleItem`` items (7 params each, ``null`` for NaN, ``doJumpId`` from 1); ``geoFence``
    version 2 (polygons clockwise, circles; each version 1); ``rallyPoints`` version 2.
    """
    items = []
    for number, item in enumerate(mission.items, start=1):
        items.append({'type': 'SimpleItem', 'command': item.command, 'frame': item.frame,
                      'autoContinue': item.auto_continue, 'doJumpId': number,
                      'params': [_json_number(p) for p in item.params]})
    fence = mission.fence
    return {
        'fileType': 'Plan',
        'version': 1,
        'groundStation': ground_station,
        'mission': {
            'version': 2,
            'firmwareType': MAV_AUTOPILOT[mission.settings.firmware],
            'vehicleType': MAV_TYPE_QUADROTOR,
            'globalPlanAltitudeMode': 1,   # relative to home, as every item's frame 3
            'cruiseSpeed': mission.speed_horizontal,
            'hoverSpeed': mission.speed_horizontal,
            'plannedHomePosition': list(mission.home),
            'items': items,
        },
        'geoFence': {
            'version': 2,
            'polygons': [{'version': 1, 'inclusion': inclusion,
                          'polygon': [list(vertex) for vertex in vertices]}
                         for vertices, inclusion in fence.polygons],
            'circles': [{'version': 1, 'inclusion': inclusion,
                         'circle': {'center': list(center), 'radius': radius}}
                        for center, radius, inclusion in fence.circles],
        },
        'rallyPoints': {'version': 2, 'points': []},
    }


def plan_text(mission: Mission, ground_station: str = 'uav_global_planner') -> str:
    """The ``.plan`` file's text (JSON, indented as QGroundControl writes it)."""
    return json.dumps(plan_document(mission, ground_station), indent=4, allow_nan=False) + '\n'


def _wpl_number(value: float) -> str:
    # Fixed-point with one decimal more than stored: parses back to the very same double.
    return 'nan' if math.isnan(value) else f'{value:.8f}'


def wpl_text(mission: Mission) -> str:
    """The ``QGC WPL 110`` text of a mission (Mission Planner, QGroundControl, MAVProxy).

    Tab-separated, 12 fields a line: index, current, frame, command, param1..4, latitude,
    longitude, altitude, autocontinue. Line 0 is home (frame 0, altitude AMSL), as Mission
    Planner writes it; the items follow from index 1.
    """
    lines = ['QGC WPL 110']
    lat, lon, alt = mission.home
    home = MissionItem(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL,
                       (0.0, 0.0, 0.0, 0.0, lat, lon, alt), True)
    for index, item in enumerate((home,) + mission.items):
        fields = [str(index), '1' if index == 0 else '0', str(item.frame), str(item.command)]
        fields += [_wpl_number(p) for p in item.params]
        fields.append('1' if item.auto_continue else '0')
        lines.append('\t'.join(fields))
    return '\n'.join(lines) + '\n'


def mission_text(mission: Mission, file_format: str) -> str:
    """The file text in ``file_format`` (``qgc`` or ``wpl``)."""
    if file_format == 'qgc':
        return plan_text(mission)
    if file_format == 'wpl':
        return wpl_text(mission)
    raise InvalidInputError(f'format must be one of {", ".join(FORMATS)}, got {file_format!r}')


def format_from_path(path: Union[str, Path]) -> str:
    """``qgc`` for ``*.plan``, ``wpl`` for ``*.waypoints``/``*.txt``/``*.wpl``.

    Raises
    ------
    InvalidInputError
        For any other extension.
    """
    suffix = Path(path).suffix.lower()
    if suffix == '.plan':
        return 'qgc'
    if suffix in ('.waypoints', '.txt', '.wpl', '.mission'):
        return 'wpl'
    raise InvalidInputError(f'{path}: cannot tell the mission format from the extension '
                            f'{suffix!r}; use .plan (QGroundControl) or .waypoints (QGC WPL 110)')


def write_mission(mission: Mission, path: Union[str, Path], file_format: str) -> Path:
    """Write the mission file (UTF-8); returns the absolute path written."""
    text = mission_text(mission, file_format)
    target = Path(path).expanduser().resolve()
    try:
        target.write_text(text, encoding='utf-8')
    except OSError as error:
        raise InvalidInputError(f'{target}: cannot write mission file ({error.strerror})') \
            from None
    return target
