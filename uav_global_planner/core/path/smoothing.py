"""Line-of-sight shortcutting and cubic-spline smoothing that provably keeps the safety margin.

The search returns a chain of grid nodes, each with obstacle clearance > gamma. This module turns
it into a curve a quadcopter can fly, in three steps:

1. **Shortcutting** (:mod:`~uav_global_planner.core.path.shortcut`): from each kept node, jump to
   the farthest later node whose straight segment is certified to keep clearance >= gamma.
   Where not even the next node is visible (the raw edge dips below gamma, see below), a detour
   vertex pushed off the obstacle is inserted if its two segments certify. The result is the
   *shortcut polyline*.
2. **Smoothing**: a C2 cubic spline
   (:func:`~uav_global_planner.core.path.piecewise.cubic_spline`, not-a-knot ends like MATLAB's
   ``spline``) through the polyline vertices, passing exactly through start and goal. In
   ``'chord'`` mode extra knots are placed on the polyline segments, at most ``knot_spacing``
   (default max(2 delta, 1 m)) apart, so the spline hugs the certified polyline and rounds its
   corners; a spline through a few far-apart vertices bulges out (longer and less safe).
3. **Verification and repair** (:mod:`~uav_global_planner.core.path.repair`): the clearance of the
   *whole continuous curve* is certified (see below). Each knot interval that breaks the margin (or
   leaves ``bounds``) gets more knots, taken on the polyline, and the spline is fitted again; when
   a violating interval is shorter than delta / 4, its polyline segment is used straight instead
   (the last resort), with stops at its ends. The knots are taken on the shortcut polyline rather
   than at the raw nodes between its vertices because those lie up to about delta beside it, on the
   grid's staircase: pinning the spline to them makes it wiggle, whereas knots on the certified
   segments make the spline converge to them. (With ``shortcut=False`` the polyline *is* the raw
   path.) A curve that breaks the margin is never returned:
   :class:`~uav_global_planner.core.errors.NoValidPathError` is raised instead, with the reason.

This module assembles the accepted curve into a :class:`SmoothedPath` (samples, tangents,
curvatures, stop points, the :class:`~uav_global_planner.core.path.curve.PathCurve` evaluator);
:func:`smooth_path` is the entry point.

Parameterisations
-----------------
``'index'``
    The paper's choice: the spline parameter is the node number and the curve is sampled at
    parameter steps of ``index_step`` (0.1, as ``spline(1:N, P, 1:0.1:N)``). Every knot interval
    gets the same parameter length whatever its length in metres, so when node spacing varies
    (always, after shortcutting: segments of 0.5 m next to segments of 10 m) the curve speeds up
    and slows down between samples, the samples bunch up on short segments, and the spline
    overshoots beside long ones, which costs clearance and repairs.
``'chord'`` (default)
    The parameter is the cumulative chord length between knots, which approximates arc length,
    so the curve follows the geometry of the node chain without the overshoot; it is sampled
    every ``sample_spacing`` metres of arc length.
``'none'``
    No spline: the (shortcut) polyline itself, sampled every ``sample_spacing`` metres, with a
    stop at every corner.

Clearance guarantee
-------------------
``ObstacleSet.distance`` d is 1-Lipschitz (each term is the exact Euclidean distance to a closed
set: a solid ball, a solid box or a finite point set). For a curve piece between samples ``a`` and
``b`` at parameter distance ``dt``, every curve point lies within ``e = dt**2 / 8 * max|c''|`` of
the chord ``ab`` (linear-interpolation error bound; ``|c''|`` is linear on a cubic piece, so its
maximum is at an end), and every chord point ``q`` has ``d(q) >= (d(a) + d(b) - |ab|) / 2``. Hence
the certified bound::

    d(c(t)) >= (d(a) + d(b) - |ab|) / 2 - e       for every t in [t_a, t_b].

The curve is sampled no coarser than ``delta / 20`` (:data:`CHECK_SPACING_FRACTION`; on grids
finer than 0.1 m every 5 mm, :data:`MIN_CHECK_SPACING`, so the work follows the curve's length,
not the grid's resolution) and every interval whose bound is below gamma is subdivided, down to
``delta * 1e-5`` (:data:`FINEST_SPACING_FRACTION`). A curve is accepted only when the bound is
>= gamma on every interval, so **every point of the returned continuous curve has clearance >=
gamma**, up to floating-point rounding. The price: a curve whose true clearance exceeds gamma by
less than about ``delta * 1e-5 / 2`` somewhere is treated as violating. With gamma = 0 the bound
still rejects any curve that enters or touches an obstacle. Shortcut segments are certified the
same way.

The raw polyline is not safe by itself
--------------------------------------
Consecutive grid nodes are at most ``delta * sqrt(3)`` apart, so every point of a segment between
two nodes lies within ``delta * sqrt(3) / 2`` of one of them, and the 1-Lipschitz property gives
only ``d > gamma - delta * sqrt(3) / 2`` on the raw polyline; it can dip below gamma (for example a
diagonal edge passing an obstacle edge). A path searched on a grid inflated by
``gamma + delta * sqrt(3) / 2`` therefore has a polyline with clearance > gamma everywhere, and the
repair, whose last resort is that polyline, then always succeeds (unless a waypoint or segment
comes within about ``delta * 1e-5`` of the margin, below what the certificate resolves).

Corners
-------
Where the repair falls back to a polyline, the curve is only C0 at the polyline corners and where
a polyline stretch meets a spline stretch. Those samples are listed in
:attr:`SmoothedPath.stop_points` (with the start and the goal) and the time parameterisation
(:mod:`uav_global_planner.core.path.timing`) brings the speed to 0 there. Everywhere else the curve
is C2 (as a function of arc length too, since its speed never vanishes in practice).

An optional ``bounds`` box (for example the grid bounds, whose floor is the ground) is enforced
exactly as well: the extrema of each cubic piece are found analytically.

Continuing a motion
-------------------
A replan in flight starts where the vehicle will be, moving: ``start_tangent`` and
``start_curvature`` give the unit tangent T and the curvature vector K (d2c/ds2, normal to T) the
curve must start with, so that position, velocity and acceleration continue without a jump (the
time parameterisation supplies the speed). Three things change:

- **Lead-in.** The start's osculating circle (tangent T, curvature K), at most a quarter turn of
  it, is sampled every knot gap over ``start_lead_in`` metres (default one knot gap; about the
  braking distance is right for a fast vehicle); the chords that certify (and stay inside the
  bounds) become the first vertices of the polyline, kept by shortcutting. So the curve leaves
  along the motion instead of being pulled at once towards a node path that may point
  elsewhere.
- **Clamped first run.** The spline of the first run of spline gaps starts with
  ``c'(0) = v T`` and ``c''(0) = v**2 K`` (v the parameter speed of its first knot interval: 1 in
  ``'chord'`` mode), and ends not-a-knot. Those are three conditions at the start, one more than
  a cubic spline has room for, so its first knot after the start is not interpolated but placed
  where the conditions put it (:func:`~uav_global_planner.core.path.repair.start_spline`); the
  curve stays C2 there and everywhere else it was.
- **No stop at the start.** The start is left out of :attr:`SmoothedPath.stop_points`.

The result is certified and repaired as any curve. When the repair has to straighten the first
gap, or no certified curve can be built this way (after a second try with the default
lead-in), the curve is made from rest as without start conditions, and
:attr:`SmoothedPath.start_kept` is False: the conditions are never dropped silently. In
``'none'`` mode only a straight start (K = 0) can be kept.
"""

from dataclasses import dataclass, replace
import math
from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.checks import check_point, check_positive
from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path.clearance import (certificate_cap, check_margins,
                                                    FINEST_SPACING_FRACTION, Pieces,
                                                    SEGMENT_SPACING, segments_clear)
from uav_global_planner.core.path.curve import (arc_derivatives, arc_length_at, interval_maxima,
                                                PathCurve, span_samples)
from uav_global_planner.core.path.repair import (BOUNDS_TOLERANCE, Chain, Check,
                                                 DEFAULT_KNOT_SPACING_FACTOR,
                                                 DEFAULT_KNOT_SPACING_MIN, initial_layout, Layout,
                                                 MIN_KNOT_GAP_FRACTION, repair_curve, RepairEvent)
from uav_global_planner.core.path.shortcut import (as_waypoints, dedupe_waypoints, kept_indices,
                                                   shortcut_legs, vertex_indices)
from uav_global_planner.core.result import polyline_length, RepairedStretch, RepairMethod
from uav_global_planner.core.settings import check_setting

#: Largest turn of the start's osculating circle the lead-in follows [rad].
LEAD_IN_MAX_TURN = math.pi / 2.0
#: The curve's unit tangent and curvature vector [1/m] at the start must equal those asked for
#: to this (relative) tolerance, or the start conditions count as not kept.
START_TOLERANCE = 1e-9

# Junctions whose tangents differ by less than this (1 - cos of the angle) are smooth.
_SMOOTH_JUNCTION = 1e-12
# A start curvature below this [1/m] is straight (a polyline can keep it).
_STRAIGHT_START = 1e-12


@dataclass(frozen=True, eq=False, kw_only=True)
class SmoothedPath:
    """The verified smoothed curve and its samples.

    Attributes
    ----------
    raw_path : numpy.ndarray, shape (N, 3)
        Waypoints given (consecutive duplicates dropped) [m].
    shortcut_path : numpy.ndarray, shape (K, 3)
        Waypoints after shortcutting [m] (``raw_path`` when shortcutting is off).
    shortcut_length_m : float
        Length of the ``shortcut_path`` polyline [m].
    mode : str
        ``'chord'``, ``'index'`` or ``'none'``.
    positions : numpy.ndarray, shape (M, 3)
        Samples of the final curve [m]; the first is the start and the last the goal, exactly.
    arc_length : numpy.ndarray, shape (M,)
        Arc length of each sample from the start [m], strictly increasing.
    tangents : numpy.ndarray, shape (M, 3)
        Unit tangent dc/ds leaving each sample [-].
    incoming_tangents : numpy.ndarray, shape (M, 3)
        Unit tangent arriving at each sample [-]; differs from ``tangents`` only at stop points.
    curvature_vectors : numpy.ndarray, shape (M, 3)
        d2c/ds2, pointing to the centre of curvature [1/m] (one-sided at stop points).
    curvature : numpy.ndarray, shape (M,)
        Norm of ``curvature_vectors`` [1/m].
    stop_points : numpy.ndarray of int
        Sample indices where the speed must be 0: the start (unless the curve continues a
        motion, :attr:`start_kept`), the goal, and every point where the curve is not C1
        (polyline corners, junctions of polyline and spline stretches).
    knots : numpy.ndarray, shape (P + 1, 3)
        Waypoints the final curve passes through, in order [m].
    length_m : float
        Arc length of the curve [m].
    min_clearance_m : float
        Smallest clearance found among the verification samples (spacing <= max(delta / 20,
        5 mm), finer near obstacles) [m]; +inf without obstacles.
    min_clearance_point : numpy.ndarray, shape (3,)
        Where it was found [m].
    certified_clearance_m : float
        Rigorous lower bound on the clearance of the whole continuous curve [m], >= gamma.
    repaired_stretches : tuple of RepairedStretch
        Stretches that broke the margin before repair, with arc-length intervals on this curve.
    interval_tangent_max : numpy.ndarray, shape (M - 1, 2)
        Largest horizontal norm and vertical magnitude of the unit tangent over each interval
        between samples [-] (ends and verification samples inside).
    interval_curvature_max : numpy.ndarray, shape (M - 1, 2)
        The same for the curvature vector [1/m]; the time parameterisation uses both so that the
        limits hold between samples too.
    curve : PathCurve
        Evaluator of the continuous curve by arc length.
    start_kept : bool or None
        None when no start conditions were given (the start is a stop point). True when the
        curve continues the motion given: its unit tangent and curvature vector at arc length 0
        are ``start_tangent`` and ``start_curvature`` and the start is no stop point. False
        when they were given but no certified curve could keep them: the curve then starts
        from rest (the start is a stop point), as without them.
    """

    raw_path: np.ndarray
    shortcut_path: np.ndarray
    shortcut_length_m: float
    mode: str
    positions: np.ndarray
    arc_length: np.ndarray
    tangents: np.ndarray
    incoming_tangents: np.ndarray
    curvature_vectors: np.ndarray
    curvature: np.ndarray
    stop_points: np.ndarray
    knots: np.ndarray
    length_m: float
    min_clearance_m: float
    min_clearance_point: np.ndarray
    certified_clearance_m: float
    repaired_stretches: Tuple[RepairedStretch, ...]
    interval_tangent_max: np.ndarray
    interval_curvature_max: np.ndarray
    curve: PathCurve
    start_kept: Optional[bool] = None


def smooth_path(raw_path, obstacles: ObstacleSet, safety_margin: float, resolution: float, *,
                shortcut: bool = True, mode: str = 'chord', sample_spacing: float = 0.1,
                index_step: float = 0.1, knot_spacing: Optional[float] = None,
                bounds: Optional[Tuple[np.ndarray, np.ndarray]] = None,
                keep: Sequence[int] = (),
                checkpoint: Optional[Callable[[], None]] = None,
                start_tangent: Optional[np.ndarray] = None,
                start_curvature: Optional[np.ndarray] = None,
                start_lead_in: Optional[float] = None,
                start_lead_in_path: Optional[np.ndarray] = None) -> SmoothedPath:
    """Shortcut, smooth and verify a node path; the returned curve keeps clearance >= gamma.

    Parameters
    ----------
    raw_path : array_like, shape (N, 3)
        Waypoints [m], start first: the grid node path, possibly with the exact start and goal
        added. Every waypoint must have clearance >= gamma.
    obstacles : ObstacleSet
    safety_margin : float
        gamma [m], >= 0.
    resolution : float
        Grid spacing delta [m], > 0: verification samples are <= max(delta / 20, 5 mm) apart.
    shortcut : bool
        Shortcut the path first (:func:`~uav_global_planner.core.path.shortcut.shortcut_path`).
    mode : str
        ``'chord'``, ``'index'`` or ``'none'`` (see the module docstring).
    sample_spacing : float
        Output sample spacing along the curve for ``'chord'`` and ``'none'`` [m], > 0.
    index_step : float
        Output parameter step of the ``'index'`` spline per knot interval [-], in (0, 1].
    knot_spacing : float, optional
        Largest knot spacing along the shortcut polyline for ``'chord'`` [m], > 0; defaults to
        the larger of :data:`~uav_global_planner.core.path.repair.DEFAULT_KNOT_SPACING_FACTOR` *
        delta and :data:`~uav_global_planner.core.path.repair.DEFAULT_KNOT_SPACING_MIN`. Sets how
        widely corners are rounded.
    bounds : tuple of two array_like of shape (3,), optional
        Box ``(min, max)`` [m] the curve must stay inside (for example the grid bounds, whose
        floor is the ground); not enforced when None.
    keep : sequence of int
        Indices of ``raw_path`` waypoints that shortcutting must keep (via-points): the curve
        passes through each exactly, as a knot, and does not stop there unless a repair has to
        straighten the stretch on both sides.
    checkpoint : callable, optional
        Called between shortcut jumps and repair rounds; it raises to abandon the work (a
        cancelled request, an exhausted time budget).
    start_tangent : array_like, shape (3,), optional
        Direction of travel at the start (ENU, any positive length; normalised): the curve
        continues a motion instead of starting from rest. Its unit tangent dc/ds at arc length
        0 is this direction, and the start is no stop point (see "Continuing a motion" in the
        module docstring).
    start_curvature : array_like, shape (3,), optional
        Curvature vector d2c/ds2 at arc length 0 [1/m] (ENU), with ``start_tangent`` only; its
        part along the tangent is dropped. Default zero.
    start_lead_in : float, optional
        Arc length the curve follows the start's osculating circle before it heads for the path
        [m], > 0, with ``start_tangent`` only; default the knot spacing. About the braking
        distance ``v**2 / (2 a)`` of the vehicle, so that it can slow down for the turns after.
    start_lead_in_path : array_like, shape (N, 3), optional
        Points the lead-in follows instead of the osculating circle [m], from the start on (the
        plan in force's own curve ahead, which its speed already fits), with ``start_tangent``
        only; taken every knot spacing up to ``start_lead_in`` metres along them.

    Returns
    -------
    SmoothedPath
        With ``start_tangent``, :attr:`SmoothedPath.start_kept` says whether the start
        conditions were kept.

    Raises
    ------
    InvalidInputError
        For malformed arguments.
    NoValidPathError
        When a waypoint violates the margin, or no curve through the waypoints keeping the margin
        can be built; the message says where and suggests the conservative re-plan.
    """
    points = as_waypoints(raw_path)
    gamma, delta = check_margins(safety_margin, resolution, 'safety_margin')
    # The settings are checked by their table entries (core/settings.py).
    mode = check_setting('smoothing', mode, 'smoothing mode')
    spacing = check_setting('sample_spacing', sample_spacing)
    step = check_setting('index_step', index_step)
    if knot_spacing is None:
        knot_spacing = max(DEFAULT_KNOT_SPACING_FACTOR * delta, DEFAULT_KNOT_SPACING_MIN)
    knot_gap = check_positive('knot_spacing', knot_spacing)
    start = _start_conditions(start_tangent, start_curvature)
    if start_lead_in is not None and start is None:
        raise InvalidInputError('start_lead_in needs start_tangent')
    lead_in = (knot_gap if start_lead_in is None
               else check_positive('start_lead_in', start_lead_in))
    guide = None
    if start_lead_in_path is not None:
        if start is None:
            raise InvalidInputError('start_lead_in_path needs start_tangent')
        guide = as_waypoints(start_lead_in_path)
    box = _check_bounds(points, bounds)
    path = dedupe_waypoints(points)
    # Capped: exact below gamma plus the slack, enough for the test and its message.
    clearance = np.asarray(obstacles.distance(path, certificate_cap(gamma, delta)))
    if np.any(clearance < gamma):
        index = int(np.argmin(clearance))
        raise NoValidPathError(
            f'waypoint {index} {np.round(path[index], 4).tolist()} has clearance '
            f'{clearance[index]:.4f} m, inside the safety margin {gamma:g} m')
    if len(path) == 1:
        return _single_point(path, obstacles, mode, start is not None)
    job = _Job(path, kept_indices(points, path, keep), obstacles, gamma, delta, box, shortcut,
               mode, knot_gap, spacing, step, checkpoint, guide)
    if start is None:
        return _smooth(job)
    # The motion is continued when a certified curve can keep it (with the lead-in asked for,
    # else the default one); otherwise the curve starts from rest and says so.
    for length in dict.fromkeys((lead_in, min(lead_in, knot_gap))):
        try:
            smoothed = _smooth(job, start, length)
        except NoValidPathError:
            continue
        if smoothed.start_kept:
            return smoothed
    return replace(_smooth(job), start_kept=False)


class _Job(NamedTuple):
    """What one smoothing attempt of :func:`smooth_path` works on."""

    path: np.ndarray                # deduplicated waypoints [m]
    keep: np.ndarray                # indices of ``path`` shortcutting keeps (via-points)
    obstacles: ObstacleSet
    gamma: float                    # margin [m]
    delta: float                    # resolution [m]
    box: Optional[Tuple[np.ndarray, np.ndarray]]
    shortcut: bool
    mode: str
    knot_gap: float                 # largest knot spacing [m]
    spacing: float                  # output sample spacing [m]
    step: float                     # index-mode parameter step [-]
    checkpoint: Optional[Callable[[], None]]
    guide: Optional[np.ndarray] = None    # points the lead-in follows [m]


def _smooth(job: _Job, start: Optional[Tuple[np.ndarray, np.ndarray]] = None,
            lead_in: float = 0.0) -> SmoothedPath:
    """Shortcut, fit, certify and repair once; from rest, or continuing ``start`` (unit
    tangent, curvature vector [1/m]) along a lead-in of ``lead_in`` [m]."""
    path, keep = job.path, job.keep
    forced = keep
    if start is not None:
        arc = _lead_in(path[0], start, lead_in, job)
        if len(arc):
            # The lead-in vertices are kept, so shortcutting cannot cut the start direction.
            path = np.vstack([path[:1], arc, path[1:]])
            keep = keep + len(arc)
            forced = np.r_[np.arange(1, len(arc) + 1), keep]
    if job.shortcut:
        vertices, certified, bound = shortcut_legs(path, forced, job.obstacles, job.gamma,
                                                   job.delta, job.box, job.checkpoint)
    else:
        vertices = path
        certified = np.zeros(len(path) - 1, dtype=bool)
        bound = np.full(len(path) - 1, -np.inf)
    spline_start = None if start is None or job.mode == 'none' else start
    layout = initial_layout(vertices, certified, bound, job.mode, job.knot_gap, spline_start)
    chain, check, events = repair_curve(layout, job.mode, job.obstacles, job.gamma, job.delta,
                                        job.box, job.checkpoint)
    if job.checkpoint is not None:
        job.checkpoint()
    via_sigma = layout.sigma[vertex_indices(vertices, path, keep)]
    kept: Optional[bool] = None
    if start is not None:
        # A repair that straightened the first gap has lost the curvature; a polyline keeps
        # only a straight start.
        kept = (not chain.line[0] if job.mode != 'none'
                else float(np.linalg.norm(start[1])) <= _STRAIGHT_START)
    return _assemble(job.path, layout, chain, check, events, job.mode, job.spacing, job.step,
                     via_sigma, start if kept else None, kept)


def _start_conditions(tangent, curvature) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """The unit tangent and the curvature vector normal to it, checked; None without them."""
    if tangent is None:
        if curvature is not None:
            raise InvalidInputError('start_curvature needs start_tangent')
        return None
    direction = check_point('start_tangent', tangent)
    norm = float(np.linalg.norm(direction))
    if not norm > 0.0:
        raise InvalidInputError('start_tangent must be a nonzero vector, got '
                                f'{direction.tolist()}')
    direction = direction / norm
    if curvature is None:
        return direction, np.zeros(3)
    bend = check_point('start_curvature', curvature)
    return direction, bend - float(np.dot(bend, direction)) * direction


def _along(points: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``s`` [m] along the polyline ``points`` (clamped to its end)."""
    chord = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    s = np.minimum(s, chord[-1])
    s = s[np.r_[True, np.diff(s) > 0.0]] if len(s) else s
    return np.stack([np.interp(s, chord, points[:, k]) for k in range(3)], axis=1)


def _lead_in(origin: np.ndarray, start: Tuple[np.ndarray, np.ndarray], length: float,
             job: _Job) -> np.ndarray:
    """Vertices of the lead-in: the osculating circle of the start, sampled every knot gap.

    At most :data:`LEAD_IN_MAX_TURN` of the circle is taken. The chords from the start are
    certified to keep gamma (and the box); the lead-in ends before the first one that does not.
    When not even the first does, one chord of half the length is tried, and so on down to a
    quarter of delta.

    Returns
    -------
    numpy.ndarray, shape (k, 3)
        The vertices after the start [m], k >= 0.
    """
    tangent, curvature = start
    kappa = float(np.linalg.norm(curvature))
    if kappa > 0.0 and job.guide is None:
        length = min(length, LEAD_IN_MAX_TURN / kappa)
    count = max(int(math.ceil(length / job.knot_gap - 1e-9)), 1)
    while length >= MIN_KNOT_GAP_FRACTION * job.delta:
        s = length * np.arange(1, count + 1) / count
        if job.guide is not None:
            arc = _along(np.vstack([origin, job.guide]), s)
        elif kappa * length <= 1e-9:
            arc = origin + s[:, None] * tangent
        else:
            normal = curvature / kappa
            arc = (origin + (np.sin(kappa * s) / kappa)[:, None] * tangent
                   + ((1.0 - np.cos(kappa * s)) / kappa)[:, None] * normal)
        good = np.ones(len(arc), dtype=bool)
        if job.box is not None:
            good &= np.all((arc >= job.box[0]) & (arc <= job.box[1]), axis=1)
        if not job.obstacles.is_empty():
            ends = np.vstack([origin, arc])
            clear, _ = segments_clear(ends[:-1], ends[1:], job.obstacles, job.gamma,
                                      SEGMENT_SPACING, job.delta * FINEST_SPACING_FRACTION,
                                      job.checkpoint)
            good &= clear
        usable = len(arc) if good.all() else int(np.argmin(good))
        if usable:
            return arc[:usable]
        length = 0.5 * float(s[0])
        count = 1
    return np.zeros((0, 3))


def _check_bounds(points: np.ndarray, bounds) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    if bounds is None:
        return None
    lo = check_point('bounds min', bounds[0])
    hi = check_point('bounds max', bounds[1])
    outside = np.any((points < lo - BOUNDS_TOLERANCE) | (points > hi + BOUNDS_TOLERANCE), axis=1)
    if outside.any():
        index = int(np.flatnonzero(outside)[0])
        raise InvalidInputError(f'waypoint {index} {points[index].tolist()} lies outside the '
                                f'bounds {lo.tolist()} .. {hi.tolist()}')
    return lo, hi


def _single_point(path: np.ndarray, obstacles: ObstacleSet, mode: str,
                  moving: bool) -> SmoothedPath:
    point = path[:1].copy()
    clearance = float(obstacles.distance(point)[0])
    zeros = np.zeros((1, 3))
    coef = np.zeros((4, 1, 3))
    coef[3, 0] = point[0]
    curve = PathCurve(Pieces(coef, np.ones(1)), np.zeros(1, dtype=np.int64), np.zeros(1),
                      np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(2), np.zeros(1))
    return SmoothedPath(
        raw_path=point, shortcut_path=point, shortcut_length_m=0.0, mode=mode, positions=point,
        arc_length=np.zeros(1), tangents=zeros, incoming_tangents=zeros, curvature_vectors=zeros,
        curvature=np.zeros(1), stop_points=np.zeros(1, dtype=np.int64), knots=point,
        length_m=0.0, min_clearance_m=clearance, min_clearance_point=point[0].copy(),
        certified_clearance_m=clearance, repaired_stretches=(),
        interval_tangent_max=np.zeros((0, 2)), interval_curvature_max=np.zeros((0, 2)),
        curve=curve, start_kept=False if moving else None)


def _assemble(path: np.ndarray, layout: Layout, chain: Chain, check: Check,
              events: List[RepairEvent], mode: str, spacing: float, step: float,
              via_sigma: np.ndarray, start: Optional[Tuple[np.ndarray, np.ndarray]],
              kept: Optional[bool]) -> SmoothedPath:
    """The accepted chain as a :class:`SmoothedPath`; ``start`` (unit tangent, curvature
    vector) when the curve continues a motion, checked here, and ``kept`` as reported."""
    pieces = chain.pieces
    grid = check.grid
    span_piece, span_tau = span_samples(chain, grid, mode, spacing, step, via_sigma)
    # Concatenate spans; each junction sample is kept once (as the end of the earlier span).
    piece = np.concatenate([span_piece[0]] + [p[1:] for p in span_piece[1:]])
    tau = np.concatenate([span_tau[0]] + [t[1:] for t in span_tau[1:]])
    junction = np.cumsum([len(p) - 1 for p in span_piece])[:-1]
    positions = pieces.position(piece, tau)
    tangent_in, curvature_vec = arc_derivatives(pieces.first(piece, tau),
                                                pieces.second(piece, tau))
    tangent_out = tangent_in.copy()
    arc = arc_length_at(pieces, grid, piece, tau)
    if start is not None:
        tangent, bend = start
        kept = bool(np.linalg.norm(tangent_in[0] - tangent) <= START_TOLERANCE
                    and np.linalg.norm(curvature_vec[0] - bend)
                    <= START_TOLERANCE * (1.0 + float(np.linalg.norm(bend))))
    stops = [] if kept else [0]
    for k, index in enumerate(junction):
        nxt = np.array([span_piece[k + 1][0]])
        t_out, k_out = arc_derivatives(pieces.first(nxt, np.zeros(1)),
                                       pieces.second(nxt, np.zeros(1)))
        tangent_out[index] = t_out[0]
        both_lines = chain.line[span_piece[k][-1]] and chain.line[nxt[0]]
        turn = 1.0 - float(np.dot(tangent_in[index], t_out[0]))
        if both_lines and turn <= _SMOOTH_JUNCTION:
            curvature_vec[index] = k_out[0]
        else:
            stops.append(int(index))
        positions[index] = layout.points(chain.sig[nxt, 0])[0]
    stops.append(len(positions) - 1)
    positions[0] = path[0]
    positions[-1] = path[-1]
    arc[0] = 0.0

    piece_start = np.r_[grid.s[grid.first & (grid.tau == 0.0)], grid.s[-1]]
    ia = np.flatnonzero(grid.first)
    curve = PathCurve(pieces, grid.piece[ia], grid.tau[ia], grid.tau[ia + 1], grid.s[ia],
                      grid.s[ia + 1], piece_start, arc[np.asarray(stops, dtype=np.int64)])
    knot_sigma = np.r_[chain.sig[:, 0], chain.sig[-1, 1]]
    knots = layout.points(knot_sigma)
    if layout.start is not None and len(chain.span) > 1 and chain.span[1] == chain.span[0]:
        # The clamped first run leaves its first knot after the start free (repair.start_spline).
        knots[1] = pieces.position(np.zeros(1, dtype=np.int64), pieces.h[:1])[0]
    certified = np.where(chain.trusted, layout.bound[chain.gap], check.cert.certified)
    tangent_max, curvature_max = interval_maxima(pieces, grid, arc, tangent_in, tangent_out,
                                                 curvature_vec)
    min_point = check.cert.min_point
    if min_point is None:  # a certificate of a whole curve always reports its nearest point
        raise RuntimeError('the clearance certificate reported no minimum point')
    return SmoothedPath(
        raw_path=path, shortcut_path=layout.vertices.copy(),
        shortcut_length_m=polyline_length(layout.vertices), mode=mode, positions=positions,
        arc_length=arc, tangents=tangent_out, incoming_tangents=tangent_in,
        curvature_vectors=curvature_vec, curvature=np.linalg.norm(curvature_vec, axis=1),
        stop_points=np.asarray(stops, dtype=np.int64), knots=knots,
        length_m=float(grid.s[-1]), min_clearance_m=check.cert.min_clearance,
        min_clearance_point=min_point, certified_clearance_m=float(np.min(certified)),
        repaired_stretches=_stretches(events, knot_sigma, piece_start),
        interval_tangent_max=tangent_max, interval_curvature_max=curvature_max, curve=curve,
        start_kept=kept)


def _stretches(events: List[RepairEvent], knot_sigma: np.ndarray,
               knot_s: np.ndarray) -> Tuple[RepairedStretch, ...]:
    """Merge repair events (polyline sigma intervals) into arc-length intervals of the curve."""
    if not events:
        return ()
    spans: List[Tuple[float, float, RepairMethod, float]] = []
    for event in events:
        lo = knot_s[max(int(np.searchsorted(knot_sigma, event.start_sigma, side='right')) - 1, 0)]
        hi = knot_s[min(int(np.searchsorted(knot_sigma, event.end_sigma, side='left')),
                        len(knot_s) - 1)]
        spans.append((float(lo), float(hi), event.method, event.clearance_before))
    spans.sort()
    merged = [spans[0]]
    for lo, hi, method, before in spans[1:]:
        last_lo, last_hi, last_method, last_before = merged[-1]
        if lo <= last_hi:
            if method is RepairMethod.POLYLINE:
                last_method = RepairMethod.POLYLINE
            merged[-1] = (last_lo, max(last_hi, hi), last_method, min(last_before, before))
        else:
            merged.append((lo, hi, method, before))
    return tuple(RepairedStretch(start_m=lo, end_m=hi, method=method, clearance_before_m=before)
                 for lo, hi, method, before in merged)
