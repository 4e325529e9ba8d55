"""Flight time and wall time of the time parameterisation, against a jerk-limited optimum.

Run inside the project's environment (copp-py is the optional extra 'bench')::

    source scripts/venv.sh && python benchmarks/bench_timing.py [--quick] [--inner] [--box]

The default run takes about a minute and a half on two cores (town400's copp solves most of
it). Two tables:

1. **Flight time.** On the certified smoothed curve of each shipped scene (``paper_medium``,
   ``paper_high``, ``town400``; the curve ``Planner.plan`` times), the flight time of our
   reference (:func:`~uav_global_planner.core.path.timing.time_parameterize`, rest to rest, no
   tracking speed cap) against the time-optimal reference on the same curve under the same
   limits, computed by copp-py, at the default limits and at the '8 m/s' limits. Target:
   ours / copp <= 1.15.
2. **Wall time** of ``time_parameterize`` on random certified curves of 50 and 500 cubic pieces
   through a sparse field of spheres. Targets: <= 50 ms and <= 200 ms.

How copp's problem is set
-------------------------
copp solves for ``a = (ds/dt)^2`` and ``b = d2s/dt2`` on a grid of stations along the curve
and keeps its limits at the stations. They are ``--spacing`` apart (twice that on curves
longer than 100 m), closer in turns (a tenth of the radius of curvature), graded down to 1 mm
at both ends (a rest-to-rest start takes a stretch of constant path jerk over the first
interval, which costs time unless that interval is short) and paired 0.5 mm either side of
every knot (where a spline's curvature peaks and its derivative jumps). The curve's
derivatives by arc length at each station (unit tangent ``T``, curvature vector ``K``, its
derivative ``K'``; ENU map frame) give copp's rows:

* speed, first order ``a <= amax``: ``|v_h| = sqrt(a) |T_h| <= v_h``, likewise for z: exact.
* acceleration ``K a + T b``, second-order rows ``e . (K a + T b) <= limit``: one per unit vector
  ``e`` of a regular 16-gon in the xy plane for the horizontal norm, and +-z for the vertical.
* jerk ``sqrt(a) (K' a + 3 K b + T c)`` with ``c = d3s/dt3 / (ds/dt)``, third-order rows
  ``sqrt(a) e . (K' a + 3 K b + T c) <= max_jerk``, one per direction ``e`` of {-1, 0, 1}^3
  (26), for the norm of the jerk vector.

copp's rows are linear (its high-level model is per-axis boxes), so a norm limit becomes a
polytope. The *outer* one has every facet tangent to the disc or ball: it contains the norm
limit, so copp's optimum on it is a lower bound of the true optimum (up to discretisation),
and ours / that is the figure held to the target. Two upper bounds: *feas.*, copp's outer
profile slowed down uniformly (times x k divides speeds by k, accelerations by k^2, jerks by
k^3) until it keeps the exact limits at dense samples; and with ``--inner``, copp's optimum on
the polytopes shrunk into the disc and ball. ``--box`` takes per-axis boxes instead of the
polygon and the 26 directions: copp's own per-axis model, a wider bracket.

Each stretch between two stop points of the curve (polyline corners) is solved rest to rest,
as the planner flies it. TOPP2 (reachability analysis, speed and acceleration only) seeds the
linearisation of the jerk rows; TOPP3-SOCP (Clarabel, one thread) is then solved again around
its own profile until the flight time changes by less than 1e-4 (at most 5 solves). Peaks are
taken on copp's continuous profile (``b`` linear in ``s`` between stations, constant path jerk
in the stationary end intervals) at 8 samples per station interval, not only at the stations.
"""

import argparse
from dataclasses import dataclass, replace
import importlib
import inspect
import itertools
import math
from pathlib import Path
import time
from typing import Any, Callable, List, Optional, Sequence, Tuple
from unittest import mock

import numpy as np
from scipy.ndimage import maximum_filter1d
from scipy.spatial import HalfspaceIntersection

from uav_global_planner.core import planner as planner_module
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.core.path.curve import PathCurve
from uav_global_planner.core.path.smoothing import smooth_path, SmoothedPath
from uav_global_planner.core.path.timing import time_parameterize
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import Trajectory

SCENES = ('paper_medium', 'paper_high', 'town400')
PIECE_COUNTS = (50, 500)
#: Wall-time targets of time_parameterize by piece count [s].
WALL_TARGETS_S = {50: 0.050, 500: 0.200}
#: Target on (our flight time) / (copp's optimum) [-].
RATIO_TARGET = 1.15
#: Budget of one scene plan [s]: the benchmark times the timing, not the planning.
PLAN_BUDGET_S = 300.0
#: Knot spacing of the random curves [m] (the planner's default at delta = 0.5 m).
KNOT_SPACING_M = 1.0
#: copp's stations are at most this fraction of the radius of curvature apart [-].
TURN_FRACTION = 0.1


@dataclass(frozen=True)
class Limits:
    """A set of motion limits (norms of the horizontal part, magnitudes of the vertical one).

    Attributes
    ----------
    name : str
    speed_horizontal, speed_vertical : float
        [m/s]
    accel_horizontal, accel_vertical : float
        [m/s^2]
    jerk : float
        Limit on the norm of the jerk vector [m/s^3].
    """

    name: str
    speed_horizontal: float
    speed_vertical: float
    accel_horizontal: float
    accel_vertical: float
    jerk: float


DEFAULT_LIMITS = Limits('default', 2.0, 1.0, 1.0, 0.5, 10.0)
FAST_LIMITS = Limits('8 m/s', 8.0, 3.0, 4.0, 2.0, 10.0)
LIMIT_SETS = (DEFAULT_LIMITS, FAST_LIMITS)


@dataclass(frozen=True)
class Peaks:
    """Largest values of a trajectory's motion.

    Attributes
    ----------
    speed_horizontal, speed_vertical : float
        [m/s]
    accel_horizontal, accel_vertical : float
        [m/s^2]
    jerk : float
        Norm of the jerk vector [m/s^3].
    """

    speed_horizontal: float
    speed_vertical: float
    accel_horizontal: float
    accel_vertical: float
    jerk: float


@dataclass(frozen=True)
class Facets:
    """Unit vectors whose rows ``e . x <= limit`` stand in for a norm limit in copp.

    Attributes
    ----------
    name : str
    horizontal : numpy.ndarray, shape (H, 3)
        Unit vectors in the xy plane, for the horizontal acceleration norm.
    jerk : numpy.ndarray, shape (D, 3)
        Unit vectors for the norm of the jerk vector.
    horizontal_inner, jerk_inner : float
        Factors (<= 1) that shrink each polytope into the unit disc or ball: the largest norm
        of a vertex of ``{x : e . x <= 1}`` is 1 / factor.
    """

    name: str
    horizontal: np.ndarray
    jerk: np.ndarray
    horizontal_inner: float
    jerk_inner: float


def make_facets(kind: str = 'polygon', sides: int = 16) -> Facets:
    """The polytopes for copp's rows.

    Parameters
    ----------
    kind : str
        ``'polygon'``: a regular ``sides``-gon for the horizontal acceleration and the 26
        directions of {-1, 0, 1}^3 for the jerk; ``'box'``: per-axis boxes (4 and 6 rows).
    sides : int
        Sides of the horizontal polygon, >= 3.
    """
    if kind == 'box':
        horizontal = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                               [0.0, -1.0, 0.0]])
        jerk = np.vstack([np.eye(3), -np.eye(3)])
    elif kind == 'polygon':
        if sides < 3:
            raise ValueError(f'sides must be >= 3, got {sides}')
        angle = 2.0 * np.pi * np.arange(sides) / sides
        horizontal = np.stack([np.cos(angle), np.sin(angle), np.zeros(sides)], axis=1)
        jerk = np.array([v for v in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(v)])
        jerk /= np.linalg.norm(jerk, axis=1)[:, None]
    else:
        raise ValueError(f"kind must be 'polygon' or 'box', got {kind!r}")
    return Facets(kind, horizontal, jerk, 1.0 / _vertex_radius(horizontal[:, :2]),
                  1.0 / _vertex_radius(jerk))


def _vertex_radius(directions: np.ndarray) -> float:
    """Largest norm of a vertex of the polytope ``{x : e . x <= 1 for every row e}``."""
    halfspaces = np.hstack([directions, -np.ones((len(directions), 1))])
    polytope = HalfspaceIntersection(halfspaces, np.zeros(directions.shape[1]))
    return float(np.max(np.linalg.norm(polytope.intersections, axis=1)))


# ---------------------------------------------------------------------------------------------
# Curves


def piece_count(curve: PathCurve) -> int:
    """Number of cubic pieces (splines and straight segments) of a curve."""
    return len(curve.piece_start_m) - 1


def scene_curve(name: str) -> Tuple[SmoothedPath, PlannerConfig]:
    """The certified smoothed curve that ``Planner.plan`` builds for a shipped scene.

    Parameters
    ----------
    name : str
        Shipped scene name (or a scene file path).

    Returns
    -------
    SmoothedPath
        The curve the planner timed.
    PlannerConfig
        The scene's settings (with a planning budget large enough for a first, compiling run).
    """
    scene = load_scene(find_scene(name))
    config = replace(scene.config, max_planning_time=PLAN_BUDGET_S)
    planner = Planner(config, scene.obstacles)
    caught: List[SmoothedPath] = []

    def keep(*args: Any, **kwargs: Any) -> SmoothedPath:
        smoothed = smooth_path(*args, **kwargs)
        caught.append(smoothed)
        return smoothed

    # The planner does not return its SmoothedPath: the spy keeps the one it timed (the last
    # one built, after a fallback re-plan too).
    with mock.patch.object(planner_module, 'smooth_path', keep):
        result = planner.plan(scene.start, scene.goal, via=scene.via)
    if not result.ok or not caught:
        raise RuntimeError(f'{name}: planning failed: {result.message}')
    return caught[-1], config


def random_curve(pieces: int, seed: int = 0, resolution: float = 0.5,
                 safety_margin: float = 0.2) -> SmoothedPath:
    """A certified curve of exactly ``pieces`` cubic pieces through a sparse field of spheres.

    A random polyline (legs of 3 to 8 m, turns up to 75 degrees, climbs up to 20 degrees, ENU
    map frame) gets one knot per metre of leg (``knot_spacing`` 1 m, as the planner's default
    at delta = 0.5 m); spheres of radius 1 to 3 m are scattered around it, at least 2 m off it,
    and :func:`~uav_global_planner.core.path.smoothing.smooth_path` certifies the curve against
    them.

    Parameters
    ----------
    pieces : int
        Cubic pieces wanted, >= 1.
    seed : int
        Seed of the random layout.
    resolution, safety_margin : float
        delta and gamma of the certification [m].

    Raises
    ------
    RuntimeError
        When a repair added knots, so the piece count is not the one asked for.
    """
    if pieces < 1:
        raise ValueError(f'pieces must be >= 1, got {pieces}')
    rng = np.random.default_rng(seed)
    points = [np.array([0.0, 0.0, 10.0])]
    heading = rng.uniform(-np.pi, np.pi)
    left = pieces
    while left:
        # A leg of length L gets ceil(L / knot spacing) pieces; the last one is cut to fit.
        length = rng.uniform(3.0, 8.0)
        if math.ceil(length / KNOT_SPACING_M) >= left:
            length = (left - 0.5) * KNOT_SPACING_M
        left -= math.ceil(length / KNOT_SPACING_M)
        heading += rng.uniform(-1.0, 1.0) * np.radians(75.0)
        climb = rng.uniform(-1.0, 1.0) * np.radians(20.0)
        if points[-1][2] < 4.0:
            climb = abs(climb)
        direction = np.array([np.cos(heading) * np.cos(climb), np.sin(heading) * np.cos(climb),
                              np.sin(climb)])
        points.append(points[-1] + length * direction)
    polyline = np.array(points)
    low, high = polyline.min(axis=0) - 10.0, polyline.max(axis=0) + 10.0
    centers = rng.uniform(low, high, size=(max(4, pieces // 2), 3))
    radii = rng.uniform(1.0, 3.0, size=len(centers))
    keep = _segment_distance(centers, polyline) >= radii + 2.0
    obstacles = ObstacleSet([Sphere(c, r) for c, r in zip(centers[keep], radii[keep])])
    smoothed = smooth_path(polyline, obstacles, safety_margin, resolution, shortcut=False,
                           knot_spacing=KNOT_SPACING_M)
    if piece_count(smoothed.curve) != pieces:
        raise RuntimeError(f'the random curve has {piece_count(smoothed.curve)} pieces, not '
                           f'{pieces} (seed {seed}): a repair added knots')
    return smoothed


def _segment_distance(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Distance from each point to a polyline [m]."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    rel = points[:, None, :] - a[None, :, :]
    frac = np.clip(np.sum(rel * ab, axis=2) / np.sum(ab * ab, axis=1), 0.0, 1.0)
    nearest = a[None, :, :] + frac[:, :, None] * ab[None, :, :]
    return np.min(np.linalg.norm(points[:, None, :] - nearest, axis=2), axis=1)


# ---------------------------------------------------------------------------------------------
# Our reference


def timing_call(limits: Limits,
                config: PlannerConfig = PlannerConfig()) -> Callable[[SmoothedPath], Trajectory]:
    """``time_parameterize`` with these limits, rest to rest, as its signature takes them.

    The jerk-limited one takes a ``MotionLimits`` (``limits``; tilt, thrust and yaw rate from
    the config) and returns a result holding the trajectory; the one before it takes the four
    speed and acceleration limits and returns the trajectory. No speed cap and no moving start
    are passed: copp's problem has neither.

    Raises
    ------
    TypeError
        For a signature this benchmark does not know.
    """
    parameters = inspect.signature(time_parameterize).parameters
    if 'limits' in parameters:
        motion_limits = importlib.import_module('uav_global_planner.core.path.motion_limits')
        motion = replace(motion_limits.MotionLimits.from_config(config),
                         speed_horizontal=limits.speed_horizontal,
                         speed_vertical=limits.speed_vertical,
                         accel_horizontal=limits.accel_horizontal,
                         accel_vertical=limits.accel_vertical, jerk=limits.jerk)
        extra = {'yaw_mode': config.yaw_mode} if 'yaw_mode' in parameters else {}
        return lambda smoothed: time_parameterize(smoothed, motion, **extra).trajectory
    if 'max_speed_horizontal' in parameters:
        values = (limits.speed_horizontal, limits.speed_vertical, limits.accel_horizontal,
                  limits.accel_vertical)
        return lambda smoothed: time_parameterize(smoothed, *values)
    raise TypeError(f'time_parameterize{inspect.signature(time_parameterize)}: a signature '
                    'this benchmark does not know')


def jerk_limited() -> bool:
    """Whether the installed ``time_parameterize`` takes a jerk limit (by its signature)."""
    parameters = inspect.signature(time_parameterize).parameters
    return 'limits' in parameters or 'max_jerk' in parameters


def trajectory_peaks(trajectory: Trajectory) -> Tuple[Peaks, bool]:
    """Peaks of our trajectory, and whether they are exact.

    The trajectory's own ``peaks`` (every 10 ms of its continuous reference) where it has
    them; otherwise
    from its samples, the jerk as finite differences of the sampled accelerations (an
    indication only: the acceleration of that reference jumps).
    """
    own = getattr(trajectory, 'peaks', None)
    if callable(own):
        own = own()
    # A trajectory without its continuous reference would interpolate its samples.
    if own is not None and getattr(trajectory, 'reference', None) is not None:
        return Peaks(float(own.speed_horizontal), float(own.speed_vertical),
                     float(own.accel_horizontal), float(own.accel_vertical),
                     float(own.jerk)), True
    velocity, accel = trajectory.velocities, trajectory.accelerations
    dt = np.diff(trajectory.times)
    jerk = np.linalg.norm(np.diff(accel, axis=0), axis=1) / np.where(dt > 0, dt, np.inf)
    return Peaks(float(np.max(np.hypot(velocity[:, 0], velocity[:, 1]))),
                 float(np.max(np.abs(velocity[:, 2]))),
                 float(np.max(np.hypot(accel[:, 0], accel[:, 1]))),
                 float(np.max(np.abs(accel[:, 2]))),
                 float(np.max(jerk)) if len(jerk) else 0.0), False


def wall_time(smoothed: SmoothedPath, call: Callable[[SmoothedPath], Trajectory],
              budget_s: float = 2.0, most_runs: int = 50) -> Tuple[float, float, int]:
    """Wall time of ``call(smoothed)`` (see :func:`timing_call`).

    Returns
    -------
    first_s : float
        The first call [s] (it may load or compile kernels).
    median_s : float
        Median of the later calls [s], repeated until ``budget_s`` or ``most_runs``.
    runs : int
        Number of later calls.
    """
    started = time.perf_counter()
    call(smoothed)
    first = time.perf_counter() - started
    times: List[float] = []
    while len(times) < most_runs and (sum(times) < budget_s or len(times) < 3):
        started = time.perf_counter()
        call(smoothed)
        times.append(time.perf_counter() - started)
    return first, float(np.median(times)), len(times)


# ---------------------------------------------------------------------------------------------
# copp's reference


@dataclass(frozen=True)
class CoppSection:
    """copp's profile over one rest-to-rest stretch of the curve.

    Attributes
    ----------
    s : numpy.ndarray, shape (n,)
        Station arc lengths on the curve [m].
    a, b : numpy.ndarray, shape (n,)
        ``(ds/dt)^2`` [m^2/s^2] and ``d2s/dt2`` [m/s^2] at the stations.
    num_stationary : tuple of int
        Stationary end intervals (start, end): constant path jerk from or to rest.
    duration_s : float
        Flight time over the stretch [s].
    """

    s: np.ndarray
    a: np.ndarray
    b: np.ndarray
    num_stationary: Tuple[int, int]
    duration_s: float


@dataclass(frozen=True)
class CoppReference:
    """copp's time-optimal reference on a whole curve.

    Attributes
    ----------
    duration_s : float
        Jerk-limited (TOPP3) flight time [s].
    second_order_s : float
        Flight time without the jerk limit (TOPP2) [s]: a lower bound of any reference within
        the speed and acceleration limits, up to discretisation.
    solve_s : float
        Wall time of all copp calls [s].
    stations : int
    rounds : int
        Most TOPP3 solves of one stretch.
    exceed : float
        Largest violation of a copp row that copp reports on its own stations (<= 0: none).
    sections : tuple of CoppSection
    """

    duration_s: float
    second_order_s: float
    solve_s: float
    stations: int
    rounds: int
    exceed: float
    sections: Tuple[CoppSection, ...]


def station_grid(start: float, end: float, spacing: float, knots: Sequence[float] = (),
                 curvature: Optional[Callable[[np.ndarray], np.ndarray]] = None,
                 first: float = 1e-3, growth: float = 1.5) -> np.ndarray:
    """Stations from ``start`` to ``end`` [m] for copp.

    At most ``spacing`` apart, and at most :data:`TURN_FRACTION` of the radius of curvature
    in turns (``curvature(s)`` gives the curvature [1/m] at arc lengths ``s``); graded down to
    ``first`` at both ends (steps growing by ``growth``); and a pair ``first`` / 2 either side
    of every knot in between, where the curvature of a cubic spline peaks and its derivative
    jumps. copp keeps its limits at the stations only.
    """
    length = end - start
    steps: List[float] = []
    step = first
    while step < spacing and 4.0 * (sum(steps) + step) < length:
        steps.append(step)
        step *= growth
    head = np.r_[0.0, np.cumsum(steps)]
    middle = length - 2.0 * head[-1]
    if curvature is None or middle <= spacing:
        count = max(2, int(math.ceil(middle / spacing - 1e-9)))
        inside = head[-1] + middle * np.arange(1, count) / count
    else:
        # Local step: the largest curvature within one spacing either side sets it.
        fine = np.linspace(head[-1], length - head[-1],
                           int(math.ceil(4.0 * middle / spacing)) + 1)
        kappa = maximum_filter1d(np.asarray(curvature(start + fine)), size=9, mode='nearest')
        allowed = np.minimum(spacing, TURN_FRACTION / np.maximum(kappa, 1e-12))
        marks = [float(head[-1])]
        while marks[-1] < fine[-1]:
            index = min(int(np.searchsorted(fine, marks[-1])), len(fine) - 1)
            marks.append(marks[-1] + float(allowed[index]))
        # Stretched evenly so that the last mark falls on the end of the middle part.
        marks_arr = head[-1] + (np.asarray(marks) - head[-1]) * middle / (marks[-1] - head[-1])
        inside = marks_arr[1:-1]
    local = np.asarray(knots, dtype=np.float64) - start
    local = local[(local > head[-1] + 0.5 * spacing)
                  & (local < length - head[-1] - 0.5 * spacing)]
    if len(local) and len(inside):
        gap = np.min(np.abs(inside[:, None] - local[None, :]), axis=1)
        near = gap < 0.3 * np.minimum(spacing, np.r_[np.diff(inside), spacing])
        inside = np.sort(np.r_[inside[~near], local - 0.5 * first, local + 0.5 * first])
    return start + np.r_[head, inside, length - head[::-1]]


def arc_derivatives3(curve: PathCurve, s: np.ndarray, start: float, end: float
                     ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points [m], unit tangents, curvature vectors [1/m] and their derivatives [1/m^2] at
    arc lengths ``s`` of the stretch ``[start, end]`` of a curve.

    ``PathCurve.derivatives3`` where the curve has it; otherwise the last one by central
    differences of the curvature vector (one-sided at the stretch's ends, 0.1 mm steps).
    """
    exact = getattr(curve, 'derivatives3', None)
    if exact is not None:
        point, tangent, curvature, third = exact(s)
        return point, tangent, curvature, third
    tangent, curvature = curve.derivatives(s)
    step = 1e-4
    low = np.maximum(s - step, start)
    high = np.minimum(s + step, end - 1e-9)
    third = (curve.derivatives(high)[1] - curve.derivatives(low)[1]) / (high - low)[:, None]
    return curve.evaluate(s), tangent, curvature, third


def _rows(curve: PathCurve, s: np.ndarray, end: float, limits: Limits, facets: Facets,
          inner: bool):
    """The curve's derivatives at the stations and copp's rows for them."""
    import copp_py as copp

    at = np.minimum(s, end - 1e-9)
    point, tangent, curvature, third = arc_derivatives3(curve, at, float(s[0]), end)
    count = len(s)
    robot = copp.Robot(3, capacity=count)
    robot.append_s(s - s[0])
    robot.set_q(point, tangent, curvature, 0, dddq=third)
    with np.errstate(divide='ignore'):
        amax = np.minimum(limits.speed_horizontal ** 2 / np.sum(tangent[:, :2] ** 2, axis=1),
                          limits.speed_vertical ** 2 / tangent[:, 2] ** 2)
    constraints = robot.constraints
    constraints.add_constraint_1st(np.minimum(amax, 1e12)[:, None], 0)
    h_scale = facets.horizontal_inner if inner else 1.0
    j_scale = facets.jerk_inner if inner else 1.0
    accel_dirs = np.vstack([facets.horizontal, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
    accel_max = np.r_[np.full(len(facets.horizontal), limits.accel_horizontal * h_scale),
                      limits.accel_vertical, limits.accel_vertical]
    constraints.add_constraint_2nd(np.ascontiguousarray(curvature @ accel_dirs.T),
                                   np.ascontiguousarray(tangent @ accel_dirs.T),
                                   np.tile(accel_max, (count, 1)), 0)
    jerk_dirs = facets.jerk
    constraints.add_constraint_3rd(np.ascontiguousarray(third @ jerk_dirs.T),
                                   np.ascontiguousarray(3.0 * curvature @ jerk_dirs.T),
                                   np.ascontiguousarray(tangent @ jerk_dirs.T),
                                   np.zeros((count, len(jerk_dirs))),
                                   np.full((count, len(jerk_dirs)), limits.jerk * j_scale), 0)
    return robot


def copp_reference(curve: PathCurve, limits: Limits, facets: Facets, inner: bool,
                   spacing: float = 0.1, most_rounds: int = 5,
                   rtol: float = 1e-4) -> CoppReference:
    """copp's time-optimal jerk-limited reference on ``curve``, rest to rest at every stop.

    Parameters
    ----------
    curve : PathCurve
    limits : Limits
    facets : Facets
        Polytopes for the acceleration and jerk norms.
    inner : bool
        Shrink them into the norm balls (conservative) instead of around them (optimistic).
    spacing : float
        Largest station spacing [m] (:func:`station_grid`).
    most_rounds : int
        Most TOPP3 solves per stretch (each linearised around the previous profile).
    rtol : float
        Relative change of the flight time that ends the rounds.

    Raises
    ------
    copp_py.CoppError
        When copp finds no profile.
    """
    import copp_py as copp

    stops = np.unique(np.r_[0.0, curve.stop_arc_length_m, curve.length_m])
    stops = stops[(stops >= 0.0) & (stops <= curve.length_m)]
    sections: List[CoppSection] = []
    solve = 0.0
    second_order = 0.0
    stations = 0
    rounds = 0
    exceed = -math.inf
    topp2_options = copp.solver.topp2_ra.Options()
    # One thread: the planner's timing is single-threaded, and the machine is shared.
    options = copp.solver.topp3_socp.Options(
        clarabel_settings=copp.clarabel.ClarabelSettings(max_threads=1))
    for start, end in zip(stops[:-1], stops[1:]):
        if end - start <= 1e-9:
            continue
        s = station_grid(float(start), float(end), spacing, curve.piece_start_m,
                         lambda at: np.linalg.norm(curve.derivatives(at)[1], axis=1))
        robot = _rows(curve, s, float(end), limits, facets, inner)
        local = s - s[0]
        started = time.perf_counter()
        problem2 = copp.solver.topp2_ra.Problem(robot.constraints, idx_s_interval=(0, len(s) - 1),
                                                a_boundary=(0.0, 0.0))
        a2 = copp.solver.topp2_ra.solve(problem2, topp2_options)
        second_order += copp.interpolation.s_to_t_topp2(local, a2, 0.0)[0]
        a_lin, b_lin = np.maximum(a2, 0.0), None
        duration = math.inf
        for round_ in range(1, most_rounds + 1):
            problem3 = copp.solver.topp3_socp.Problem(
                robot.constraints, a_lin, a_boundary=(0.0, 0.0), b_boundary=(0.0, 0.0),
                num_stationary_max=1, b_linearization=b_lin)
            profile = copp.solver.topp3_socp.solve(problem3, options)
            profile.force_positive_a(local)
            previous, duration = duration, copp.interpolation.s_to_t_topp3(local, profile)[0]
            a_lin, b_lin = profile.a, profile.b
            if abs(previous - duration) <= rtol * duration:
                break
        solve += time.perf_counter() - started
        rounds = max(rounds, round_)
        stations += len(s)
        exceed = max(exceed, *robot.constraints.exceed_topp3(profile))
        sections.append(CoppSection(s, profile.a, profile.b, profile.num_stationary, duration))
    return CoppReference(sum(x.duration_s for x in sections), second_order, solve, stations,
                         rounds, exceed, tuple(sections))


def copp_motion(curve: PathCurve, section: CoppSection,
                per_interval: int = 8) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity [m/s], acceleration [m/s^2] and jerk [m/s^3] of copp's continuous profile.

    Sampled ``per_interval`` times per station interval (ends included), each shape (M, 3),
    from copp's model: on a regular interval ``b`` is linear in ``s`` (``c = db/ds`` constant,
    ``a`` quadratic); on a stationary end interval the path jerk is constant from or to rest.
    """
    s, a, b = section.s, section.a, section.b
    head, tail = section.num_stationary
    last = len(s) - 1
    unit = np.linspace(0.0, 1.0, per_interval + 1)
    parts = []  # (arc length, ds/dt, d2s/dt2, d3s/dt3) of every sample
    for k in range(head, last - tail):
        ds = s[k + 1] - s[k]
        c = (b[k + 1] - b[k]) / ds
        x = ds * unit
        speed = np.sqrt(np.maximum(a[k] + 2.0 * b[k] * x + c * x * x, 0.0))
        parts.append((s[k] + x, speed, b[k] + c * x, c * speed))
    for first, far, sign in ((0, head, 1.0), (last, last - tail, -1.0)):
        if first == far:
            continue
        # s = j t^3 / 6 from rest over [s_first, s_far], reached at t = 3 |ds| / (ds/dt).
        length = abs(s[far] - s[first])
        t_far = 3.0 * length / math.sqrt(a[far])
        jerk = 6.0 * length / t_far ** 3
        t = np.cbrt(6.0 * length * unit / jerk)
        parts.append((s[first] + sign * length * unit, 0.5 * jerk * t * t, sign * jerk * t,
                      np.full(len(t), jerk)))
    arc, sd, sdd, sddd = (np.concatenate(p) for p in zip(*parts))
    _, tangent, curvature, third = arc_derivatives3(curve, np.minimum(arc, s[-1] - 1e-9),
                                                    float(s[0]), float(s[-1]))
    velocity = tangent * sd[:, None]
    accel = curvature * (sd * sd)[:, None] + tangent * sdd[:, None]
    jerk_vec = (third * (sd ** 3)[:, None] + 3.0 * curvature * (sd * sdd)[:, None]
                + tangent * sddd[:, None])
    return velocity, accel, jerk_vec


def _peaks(velocity: np.ndarray, accel: np.ndarray, jerk: np.ndarray) -> Peaks:
    return Peaks(float(np.max(np.hypot(velocity[:, 0], velocity[:, 1]))),
                 float(np.max(np.abs(velocity[:, 2]))),
                 float(np.max(np.hypot(accel[:, 0], accel[:, 1]))),
                 float(np.max(np.abs(accel[:, 2]))),
                 float(np.max(np.linalg.norm(jerk, axis=1))))


def copp_peaks(curve: PathCurve, reference: CoppReference, per_interval: int = 8) -> Peaks:
    """Peaks of copp's continuous reference over the whole curve (see :func:`copp_motion`)."""
    velocity, accel, jerk = (np.concatenate(parts) for parts in zip(
        *(copp_motion(curve, section, per_interval) for section in reference.sections)))
    return _peaks(velocity, accel, jerk)


def slow_down(peaks: Peaks, limits: Limits) -> float:
    """Smallest factor (>= 1) on every time that brings these peaks within the limits.

    Flying the same path ``k`` times slower divides speeds by ``k``, accelerations by ``k^2``
    and jerks by ``k^3``, and keeps rest-to-rest ends at rest.
    """
    return max(1.0, peaks.speed_horizontal / limits.speed_horizontal,
               peaks.speed_vertical / limits.speed_vertical,
               math.sqrt(peaks.accel_horizontal / limits.accel_horizontal),
               math.sqrt(peaks.accel_vertical / limits.accel_vertical),
               math.pow(peaks.jerk / limits.jerk, 1.0 / 3.0))


def feasible_duration(curve: PathCurve, reference: CoppReference, limits: Limits,
                      per_interval: int = 8) -> float:
    """Flight time of copp's reference slowed down, stretch by stretch, to keep the exact
    norm limits at dense samples [s]: an upper bound of the optimum (up to that sampling)."""
    total = 0.0
    for section in reference.sections:
        peaks = _peaks(*copp_motion(curve, section, per_interval))
        total += slow_down(peaks, limits) * section.duration_s
    return total


# ---------------------------------------------------------------------------------------------
# Tables


@dataclass(frozen=True)
class FlightRow:
    """One line of the flight-time table: one curve, one set of limits.

    Attributes
    ----------
    scene, limits : str
    pieces : int
    length_m : float
    ours_s : float
        Our flight time [s].
    ours_peaks : Peaks
    ours_peaks_exact : bool
        False when the peaks come from the samples (see :func:`trajectory_peaks`).
    ours_wall_s : float
        Wall time of our time parameterisation, one call [s].
    copp : CoppReference or None
        copp's optimum with the outer polytopes (None when copp failed).
    copp_peaks : Peaks or None
        Its peaks at dense samples.
    copp_feasible_s : float
        Its flight time slowed down to keep the exact limits (:func:`feasible_duration`) [s].
    copp_inner_s : float
        copp's optimum with the inner polytopes [s]; NaN when not computed.
    failure : str
    """

    scene: str
    limits: str
    pieces: int
    length_m: float
    ours_s: float
    ours_peaks: Peaks
    ours_peaks_exact: bool
    ours_wall_s: float
    copp: Optional[CoppReference] = None
    copp_peaks: Optional[Peaks] = None
    copp_feasible_s: float = math.nan
    copp_inner_s: float = math.nan
    failure: str = ''

    @property
    def ratio(self) -> float:
        """Ours / copp's outer optimum, a lower bound of the true optimum: the target's
        figure [-]."""
        return self.ours_s / self.copp.duration_s if self.copp else math.nan

    @property
    def ratio_feasible(self) -> float:
        """Ours / copp's slowed-down reference, an upper bound of the true optimum [-]."""
        return self.ours_s / self.copp_feasible_s


def flight_row(name: str, smoothed: SmoothedPath, config: PlannerConfig, limits: Limits,
               facets: Facets, spacing: float, inner: bool = False) -> FlightRow:
    """Our reference and copp's optimum on one curve under one set of limits.

    ``inner`` also solves with the inner polytopes (twice the copp time).
    """
    import copp_py as copp

    call = timing_call(limits, config)
    started = time.perf_counter()
    trajectory = call(smoothed)
    wall = time.perf_counter() - started
    peaks, exact = trajectory_peaks(trajectory)
    row = FlightRow(Path(name).stem, limits.name, piece_count(smoothed.curve), smoothed.length_m,
                    trajectory.duration_s, peaks, exact, wall)
    try:
        reference = copp_reference(smoothed.curve, limits, facets, False, spacing)
        inner_s = (copp_reference(smoothed.curve, limits, facets, True, spacing).duration_s
                   if inner else math.nan)
    except copp.CoppError as error:
        return replace(row, failure=f'copp failed: {error}')
    return replace(row, copp=reference, copp_peaks=copp_peaks(smoothed.curve, reference),
                   copp_feasible_s=feasible_duration(smoothed.curve, reference, limits),
                   copp_inner_s=inner_s)


def _verdict(ratio: float) -> str:
    if not jerk_limited():
        return '(no jerk limit)'
    if ratio < 1.0 - 0.02:
        # Faster than the optimum's lower bound: one of the two breaks a limit.
        return 'BELOW THE OPTIMUM'
    return 'ok' if ratio <= RATIO_TARGET else 'MISSED'


def print_flight_table(rows: Sequence[FlightRow]) -> None:
    """The flight-time table, one line per scene and limits."""
    print(f'{"scene":<13} {"limits":<8} {"pieces":>6} {"length":>7} {"ours":>7} '
          f'{"copp":>7} {"feas.":>7} {"inner":>7} {"ratio":>6} {"feas.":>6} {"2nd o.":>7} | '
          f'{"jerk":>6} {"acc_h":>5} {"acc_v":>5} | {"jerk":>6} {"acc_h":>5} {"acc_v":>5} | '
          f'{"solve":>6} {"stations":>8}')
    print(f'{"":<13} {"":<8} {"":>6} {"[m]":>7} {"[s]":>7} {"[s]":>7} {"[s]":>7} {"[s]":>7} '
          f'{"[-]":>6} {"[-]":>6} {"[s]":>7} | {"ours: [m/s^3], [m/s^2]":>18} | '
          f'{"copp: [m/s^3], [m/s^2]":>18} | {"[s]":>6}')
    for row in rows:
        mark = '' if row.ours_peaks_exact else '~'
        ours = (f'{mark + format(row.ours_peaks.jerk, ".2f"):>6} '
                f'{row.ours_peaks.accel_horizontal:>5.2f} {row.ours_peaks.accel_vertical:>5.2f}')
        head = (f'{row.scene:<13} {row.limits:<8} {row.pieces:>6} {row.length_m:>7.1f} '
                f'{row.ours_s:>7.2f}')
        if row.copp is None or row.copp_peaks is None:
            print(f'{head} {row.failure}')
            continue
        reference, cp = row.copp, row.copp_peaks
        inner = '-' if math.isnan(row.copp_inner_s) else f'{row.copp_inner_s:.2f}'
        verdict = _verdict(row.ratio)
        print(f'{head} {reference.duration_s:>7.2f} {row.copp_feasible_s:>7.2f} {inner:>7} '
              f'{row.ratio:>6.3f} {row.ratio_feasible:>6.3f} {reference.second_order_s:>7.2f} | '
              f'{ours} | {cp.jerk:>6.2f} {cp.accel_horizontal:>5.2f} {cp.accel_vertical:>5.2f} | '
              f'{reference.solve_s:>6.2f} {reference.stations:>8}  {verdict}')


def print_wall_table(curves: Sequence[Tuple[int, SmoothedPath]], limits: Sequence[Limits],
                     budget_s: float) -> None:
    """The wall-time table of ``time_parameterize``, one line per curve and limits."""
    print(f'{"pieces":>6} {"length [m]":>10} {"samples":>7} {"limits":<8} '
          f'{"first [ms]":>10} {"median [ms]":>11} {"runs":>5} {"target [ms]":>11}')
    for pieces, smoothed in curves:
        for entry in limits:
            first, median, runs = wall_time(smoothed, timing_call(entry), budget_s)
            target = WALL_TARGETS_S.get(pieces)
            verdict = ('' if target is None else
                       f'{target * 1e3:>11.0f} {"ok" if median <= target else "MISSED"}')
            print(f'{pieces:>6} {smoothed.length_m:>10.1f} {len(smoothed.positions):>7} '
                  f'{entry.name:<8} {first * 1e3:>10.2f} {median * 1e3:>11.2f} {runs:>5} '
                  f'{verdict}')


def main() -> None:
    """Print both tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scenes', nargs='*', default=list(SCENES),
                        help='shipped scene names or scene files (default: %(default)s)')
    parser.add_argument('--pieces', nargs='*', type=int, default=list(PIECE_COUNTS),
                        help='piece counts of the wall-time curves (default: %(default)s)')
    parser.add_argument('--spacing', type=float, default=0.1,
                        help='copp station spacing [m] on curves up to 100 m (default: '
                        '%(default)s); twice that on longer ones')
    parser.add_argument('--box', action='store_true',
                        help="per-axis boxes for copp's norm limits instead of polytopes")
    parser.add_argument('--inner', action='store_true',
                        help='also solve with the inner polytopes (twice the copp time)')
    parser.add_argument('--wall-budget', type=float, default=2.0,
                        help='repeat each wall-time case for about this long [s]')
    parser.add_argument('--quick', action='store_true',
                        help='paper_medium and a 50-piece curve only')
    args = parser.parse_args()
    if args.quick:
        args.scenes, args.pieces = ['paper_medium'], [50]
    import copp_py as copp

    facets = make_facets('box' if args.box else 'polygon')
    print(f'copp-py {copp.version()}: TOPP2-RA seed, then TOPP3-SOCP (Clarabel, 1 thread)\n'
          f'stations {args.spacing:g} m apart (x2 past 100 m), closer in turns, graded to 1 mm '
          'at the ends, a pair at every knot')
    shape = {'polygon': 'polytopes', 'box': 'per-axis boxes'}[facets.name]
    print(f"copp's norm limits as {shape}: horizontal acceleration "
          f'{len(facets.horizontal)} rows (inner x {facets.horizontal_inner:.3f}), jerk '
          f'{len(facets.jerk)} rows (inner x {facets.jerk_inner:.3f})')
    print(f'time_parameterize is {"" if jerk_limited() else "NOT "}jerk-limited (by its '
          'signature)')
    rows = []
    planned = []
    for name in args.scenes:
        started = time.perf_counter()
        smoothed, config = scene_curve(name)
        planned.append(f'{Path(name).stem} {time.perf_counter() - started:.1f} s')
        spacing = args.spacing * (2.0 if smoothed.length_m > 100.0 else 1.0)
        for limits in LIMIT_SETS:
            rows.append(flight_row(name, smoothed, config, limits, facets, spacing, args.inner))
    print(f'\nFlight time (planned: {", ".join(planned)})')
    print_flight_table(rows)
    print('copp: its optimum with the outer polytopes, a lower bound of the true one (up to '
          'discretisation)\n'
          'feas.: that reference slowed down to keep the exact limits at dense samples, an upper '
          'bound\n'
          'inner: its optimum with the inner polytopes (--inner), another upper bound\n'
          f'ratio: ours / copp, target <= {RATIO_TARGET:g} (held only to a jerk-limited '
          'reference); feas.: ours / feas.\n'
          '2nd o.: copp without the jerk limit (TOPP2); solve: copp wall time of the outer '
          'reference\n'
          'peaks: ~ = from our samples (finite differences of accelerations); copp at 8 '
          'samples per station interval')
    print('\nWall time of time_parameterize ('
          + ', '.join(f'target {p} pieces <= {t * 1e3:.0f} ms' for p, t in WALL_TARGETS_S.items())
          + ')')
    curves = [(pieces, random_curve(pieces, seed=pieces)) for pieces in args.pieces]
    print_wall_table(curves, LIMIT_SETS, args.wall_budget)


if __name__ == '__main__':
    main()
