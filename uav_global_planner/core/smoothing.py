"""Line-of-sight shortcutting and cubic-spline smoothing that provably keeps the safety margin.

The search returns a chain of grid nodes, each with obstacle clearance > gamma. This module turns
it into a curve a quadcopter can fly, in three steps:

1. **Shortcutting** (:func:`shortcut_path`): from each kept node, jump to the farthest later node
   whose straight segment is certified to keep clearance >= gamma. Where not even the next node
   is visible (the raw edge dips below gamma, see below), a detour vertex pushed off the obstacle
   is inserted if its two segments certify. The result is the *shortcut polyline*.
2. **Smoothing**: a C2 cubic spline (:class:`scipy.interpolate.CubicSpline`, not-a-knot ends like
   MATLAB's ``spline``) through the polyline vertices, passing exactly through start and goal. In
   ``'chord'`` mode extra knots are placed on the polyline segments, at most ``knot_spacing``
   (default max(2 delta, 1 m)) apart, so the spline hugs the certified polyline and rounds its
   corners; a spline through a few far-apart vertices bulges out (longer and less safe).
3. **Verification and repair**: the clearance of the *whole continuous curve* is certified (see
   below). Each knot interval that breaks the margin (or leaves ``bounds``) gets more knots, taken
   on the polyline, and the spline is fitted again; when a violating interval is shorter than
   delta / 4, its polyline segment is used straight instead (the last resort), with stops at its
   ends. The knots are taken on the shortcut polyline rather than at the raw nodes between its
   vertices because those lie up to about delta beside it, on the grid's staircase: pinning the
   spline to them makes it wiggle, whereas knots on the certified segments make the spline
   converge to them. (With ``shortcut=False`` the polyline *is* the raw path.) A curve that breaks
   the margin is never returned: :class:`~uav_global_planner.core.errors.NoValidPathError` is
   raised instead, with the reason.

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

The curve is sampled no coarser than ``delta / 20`` (:data:`CHECK_SPACING_FRACTION`) and every
interval whose bound is below gamma is subdivided, down to ``delta * 1e-5``
(:data:`FINEST_SPACING_FRACTION`). A curve is accepted only when the bound is >= gamma on every
interval, so **every point of the returned continuous curve has clearance >= gamma**, up to
floating-point rounding. The price: a curve whose true clearance exceeds gamma by less than about
``delta * 1e-5 / 2`` somewhere is treated as violating. With gamma = 0 the bound still rejects any
curve that enters or touches an obstacle. Shortcut segments are certified the same way.

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
(:mod:`uav_global_planner.core.timing`) brings the speed to 0 there. Everywhere else the curve is
C2 (as a function of arc length too, since its speed never vanishes in practice).

An optional ``bounds`` box (for example the grid bounds, whose floor is the ground) is enforced
exactly as well: the extrema of each cubic piece are found analytically.
"""

from dataclasses import dataclass
import math
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np
from scipy.interpolate import CubicSpline

from uav_global_planner.core.clearance import (Certificate, certificate_cap, certify_pieces,
                                               check_margins,
                                               CHECK_SPACING_FRACTION, FINEST_SPACING_FRACTION,
                                               Pieces, SampleGrid, SEGMENT_SPACING,
                                               segments_clear)
from uav_global_planner.core.config import SMOOTHING_MODES
from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.grid import as_point, positive_number
from uav_global_planner.core.obstacles import ObstacleSet
from uav_global_planner.core.result import polyline_length, RepairedStretch

#: First sampling of shortcut candidate segments [m] (the engine's segment spacing).
SHORTCUT_SPACING = SEGMENT_SPACING
#: A shortcut past the next node must keep gamma plus this many delta: it bounds the work of
#: certifying a jump to (length / slack) intervals where the farthest visible node grazes.
SHORTCUT_SLACK_FRACTION = 0.02
#: Default largest knot spacing of ``'chord'`` splines along the shortcut polyline: this many
#: delta, but at least :data:`DEFAULT_KNOT_SPACING_MIN`. It sets how widely corners are rounded:
#: wider means lower curvature and faster flight, but more bulging and repairs.
DEFAULT_KNOT_SPACING_FACTOR = 2.0
#: Lower limit of the default knot spacing [m] (corners rounded over about a metre).
DEFAULT_KNOT_SPACING_MIN = 1.0
#: Violating knot intervals shorter than this (times delta) are straightened, not split.
MIN_KNOT_GAP_FRACTION = 0.25
#: Largest lower bound on clearance of the raw polyline below gamma, as a fraction of delta.
POLYLINE_DEFICIT_FACTOR = math.sqrt(3.0) / 2.0

# Consecutive waypoints closer than this are merged [m]; the chord parameter needs a gap.
_DUPLICATE_TOLERANCE = 1e-9
# Tolerance on leaving the bounds box [m]: nodes may sit on its faces.
_BOUNDS_TOLERANCE = 1e-9
# Junctions whose tangents differ by less than this (1 - cos of the angle) are smooth.
_SMOOTH_JUNCTION = 1e-12
# Output samples closer than this to a via-point are dropped in its favour [m].
_VIA_SAMPLE_GAP = 1e-6
# Up to this many nodes ahead are all certified in one batch (exact farthest visible).
_SHORTCUT_BATCH = 64
# Nodes this close ahead are all certified in the first batch of a long path.
_SHORTCUT_NEAR = 16
# Powers of two certified per batch when galloping ahead.
_GALLOP_BATCH = 4
# Nodes certified per narrowing round of the shortcut search (one batch each).
_SHORTCUT_PROBES = 8
# Upper bound on repair rounds; each round halves knot gaps or straightens polyline gaps.
_MAX_REPAIR_ROUNDS = 200


def _dedupe(path: np.ndarray) -> np.ndarray:
    """Drop waypoints that repeat their predecessor; the first and last stay exact."""
    if len(path) < 2:
        return path
    step = np.linalg.norm(np.diff(path, axis=0), axis=1)
    keep = np.r_[True, step > _DUPLICATE_TOLERANCE]
    out = path[keep].copy()
    out[-1] = path[-1]
    if len(out) > 1 and np.linalg.norm(out[-1] - out[-2]) <= _DUPLICATE_TOLERANCE:
        out = np.delete(out, -2, axis=0)
    return out


def _far_visible(path: np.ndarray, anchor: int, obstacles: ObstacleSet, gamma: float,
                 spacing: float, finest: float,
                 checkpoint: Optional[Callable[[], None]] = None) -> Tuple[int, float]:
    """A far node visible from ``path[anchor]``, with its segment's certified bound.

    With at most :data:`_SHORTCUT_BATCH` nodes ahead, all are certified in one batch and the
    farthest visible wins. Otherwise node offsets 1, 2, 4, ... (and the last node) are certified
    a few at a time, going farther while the farthest so far is visible; between the
    farthest visible one and the next, up to :data:`_SHORTCUT_PROBES` evenly spaced nodes are
    certified per round until two neighbours are left. Work and memory are bounded by a few
    times the length of the jump found, not by the number of nodes ahead (visibility along a
    path is not monotone, so this finds a far visible node, not always the farthest).

    Returns
    -------
    tuple of (int, float)
        The node's index, or ``anchor`` when not even the next node is visible; and the bound
        [m] (-inf then).
    """
    n = len(path)
    ahead = n - 1 - anchor
    slack = SHORTCUT_SLACK_FRACTION * finest / FINEST_SPACING_FRACTION
    if ahead <= _SHORTCUT_BATCH:
        # Few nodes ahead: certify them all at once and take the farthest visible.
        offsets = np.arange(1, ahead + 1)
    else:
        # Every near node (most jumps of a winding path end there, found in one batch), then
        # powers of two.
        offsets = np.unique(np.r_[np.arange(1, _SHORTCUT_NEAR + 1),
                                  2 ** np.arange(int(math.log2(ahead)) + 1), ahead])

    def visible(offs: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        ends = path[anchor + offs]
        starts = np.repeat(path[anchor][None, :], len(offs), axis=0)
        # A jump past the next node must clear gamma with some slack: the farthest visible
        # node is by nature a grazing one, and certifying a segment that grazes the margin by
        # a micrometre takes (length / micrometre) intervals. The next node is checked
        # against gamma itself, as before.
        clear, bound = segments_clear(starts, ends, obstacles, gamma + slack, spacing, finest,
                                      checkpoint)
        next_node = offs == 1
        if next_node.any() and not clear[next_node].all():
            clear[next_node], bound[next_node] = segments_clear(
                starts[next_node], ends[next_node], obstacles, gamma, spacing, finest,
                checkpoint)
        return clear, bound

    # Offsets in batches of a few powers of two, farther only while the farthest so far is
    # visible: the work follows the jump found, not the length of the path ahead.
    clear = np.zeros(len(offsets), dtype=bool)
    bound = np.full(len(offsets), -math.inf)
    first = 0
    while first < len(offsets):
        if ahead <= _SHORTCUT_BATCH:
            last = len(offsets)
        elif first == 0:
            last = min(_SHORTCUT_NEAR + _GALLOP_BATCH, len(offsets))
        else:
            last = min(first + _GALLOP_BATCH, len(offsets))
        clear[first:last], bound[first:last] = visible(offsets[first:last])
        if not clear[last - 1]:
            break
        first = last
    seen = np.flatnonzero(clear)
    if not len(seen):
        return anchor, -math.inf
    k = int(seen[-1])
    lo, lo_bound = int(offsets[k]), float(bound[k])
    hi = int(offsets[k + 1]) if k + 1 < len(offsets) else lo
    while hi - lo > 1:
        probes = np.unique(np.linspace(lo, hi, _SHORTCUT_PROBES + 2).astype(np.int64)[1:-1])
        probes = probes[(probes > lo) & (probes < hi)]
        clear, bound = visible(probes)
        seen = np.flatnonzero(clear)
        if len(seen):
            k = int(seen[-1])
            lo, lo_bound = int(probes[k]), float(bound[k])
            later = probes[k + 1:]
            hi = int(later[0]) if len(later) else hi
        else:
            hi = int(probes[0])
    return anchor + lo, lo_bound


def _shortcut(path: np.ndarray, obstacles: ObstacleSet, gamma: float, delta: float,
              box: Optional[Tuple[np.ndarray, np.ndarray]] = None,
              checkpoint: Optional[Callable[[], None]] = None
              ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Greedy far-visible shortcutting, with detours around raw edges that dip below gamma.

    Returns
    -------
    vertices : numpy.ndarray, shape (K, 3)
        Kept waypoints [m], the exact first and last included; a detour vertex (not a node) is
        added where not even the next node is visible.
    certified : numpy.ndarray of bool, shape (K - 1,)
        True where the segment is certified >= gamma; False only for a raw edge that dips below
        gamma and could not be detoured.
    bound : numpy.ndarray, shape (K - 1,)
        Certified clearance bound of each certified segment [m] (-inf otherwise).
    """
    n = len(path)
    if obstacles.is_empty():
        return path[[0, n - 1]], np.array([True]), np.array([np.inf])
    vertices = [path[0]]
    certified = []
    bounds = []
    anchor = 0
    spacing = SHORTCUT_SPACING
    finest = delta * FINEST_SPACING_FRACTION
    while anchor < n - 1:
        if checkpoint is not None:
            checkpoint()
        best, best_bound = _far_visible(path, anchor, obstacles, gamma, spacing, finest,
                                        checkpoint)
        if best > anchor:
            certified.append(True)
            bounds.append(best_bound)
            anchor = best
        else:
            detour = _detour(path[anchor], path[anchor + 1], obstacles, gamma, delta, box)
            if detour is None:
                certified.append(False)
                bounds.append(-np.inf)
            else:
                vertices.append(detour[0])
                certified.extend([True, True])
                bounds.extend(detour[1:])
            anchor += 1
        vertices.append(path[anchor])
    return np.asarray(vertices), np.asarray(certified), np.asarray(bounds)


def _detour(a: np.ndarray, b: np.ndarray, obstacles: ObstacleSet, gamma: float, delta: float,
            box: Optional[Tuple[np.ndarray, np.ndarray]]):
    """A vertex beside the edge ``a -> b`` whose two segments certify >= gamma, or None.

    The raw edge between two free nodes may dip below gamma (by < delta * sqrt(3) / 2). Its
    closest point to the obstacles is pushed along the clearance gradient (made normal to the
    edge) by 1, 2, 4, 8 and 16 times the deficit plus delta / 20; the smallest push whose two
    segments certify wins.

    Returns
    -------
    tuple of (numpy.ndarray (3,), float, float) or None
        Detour vertex [m] and the certified bounds of its two segments [m].
    """
    step = delta * CHECK_SPACING_FRACTION
    length = float(np.linalg.norm(b - a))
    count = max(int(math.ceil(length / step)), 2)
    samples = a + np.linspace(0.0, 1.0, count + 1)[:, None] * (b - a)
    # Capped: exact wherever it is near gamma, which is all the detour looks at.
    cap = certificate_cap(gamma, step)
    clearance = obstacles.distance(samples, cap)
    worst = samples[int(np.argmin(clearance))]
    deficit = gamma - float(np.min(clearance))
    probe = 1e-4 * delta
    offsets = np.vstack([np.eye(3), -np.eye(3)]) * probe
    around = obstacles.distance(worst + offsets, cap)
    gradient = (around[:3] - around[3:]) / (2.0 * probe)
    direction = (b - a) / length
    gradient -= np.dot(gradient, direction) * direction
    norm = float(np.linalg.norm(gradient))
    if deficit <= 0.0 or norm < 1e-6:
        return None
    pushes = (max(deficit, 0.0) + step) * np.array([1.0, 2.0, 4.0, 8.0, 16.0])
    middles = worst + pushes[:, None] * (gradient / norm)
    if box is not None:
        middles = middles[np.all((middles >= box[0]) & (middles <= box[1]), axis=1)]
    if not len(middles):
        return None
    starts = np.vstack([np.repeat(a[None, :], len(middles), axis=0), middles])
    ends = np.vstack([middles, np.repeat(b[None, :], len(middles), axis=0)])
    clear, bound = segments_clear(starts, ends, obstacles, gamma, SHORTCUT_SPACING,
                                  delta * FINEST_SPACING_FRACTION)
    both = np.flatnonzero(clear[:len(middles)] & clear[len(middles):])
    if not len(both):
        return None
    k = int(both[0])
    return middles[k], float(bound[k]), float(bound[len(middles) + k])


def _kept_indices(points: np.ndarray, path: np.ndarray, keep: Sequence[int]) -> np.ndarray:
    """``keep`` (indices of ``points``) as indices of the deduplicated ``path``."""
    if not len(keep):
        return np.zeros(0, dtype=np.int64)
    wanted = np.asarray(keep, dtype=np.int64)
    if np.any((wanted < 0) | (wanted >= len(points))):
        raise InvalidInputError(f'keep indices must lie in [0, {len(points) - 1}], got '
                                f'{wanted.tolist()}')
    # _dedupe keeps the first of each run of equal waypoints (and the exact last point).
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    new_index = np.cumsum(np.r_[True, step > _DUPLICATE_TOLERANCE]) - 1
    return np.unique(np.clip(new_index[wanted], 0, len(path) - 1))


def _vertex_indices(vertices: np.ndarray, path: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Indices in ``vertices`` of the ``path`` waypoints ``kept`` (which shortcutting keeps)."""
    if not len(kept):
        return np.zeros(0, dtype=np.int64)
    hits = [np.flatnonzero(np.all(vertices == path[k], axis=1)) for k in kept]
    return np.asarray([int(h[0]) for h in hits if len(h)], dtype=np.int64)


def _shortcut_legs(path: np.ndarray, keep: np.ndarray, obstacles: ObstacleSet, gamma: float,
                   delta: float, box: Optional[Tuple[np.ndarray, np.ndarray]],
                   checkpoint: Optional[Callable[[], None]]
                   ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_shortcut` on each stretch between kept waypoints, joined at them."""
    cuts = np.unique(np.r_[0, keep, len(path) - 1])
    vertices: List[np.ndarray] = []
    certified: List[np.ndarray] = []
    bounds: List[np.ndarray] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        leg_vertices, leg_certified, leg_bound = _shortcut(path[a:b + 1], obstacles, gamma,
                                                           delta, box, checkpoint)
        vertices.append(leg_vertices if not vertices else leg_vertices[1:])
        certified.append(leg_certified)
        bounds.append(leg_bound)
    return np.vstack(vertices), np.concatenate(certified), np.concatenate(bounds)


def shortcut_path(path, obstacles: ObstacleSet, safety_margin: float,
                  resolution: float) -> np.ndarray:
    """Greedy line-of-sight shortcutting of a node path.

    From the start, repeatedly jump to the farthest later node whose straight segment has
    clearance >= gamma, certified on the whole segment (not only at samples) by the 1-Lipschitz
    bound of the module docstring: samples every 0.25 m, refined adaptively down to
    ``delta * 1e-5``, all candidate segments of one anchor in a single distance query per round.
    Where not even the next node is visible (that raw edge dips below gamma), a detour vertex is
    inserted beside the edge if its two segments certify; otherwise the edge is kept as it is.
    Every other segment of the result keeps clearance >= gamma everywhere.

    Parameters
    ----------
    path : array_like, shape (N, 3)
        Node path [m], start first.
    obstacles : ObstacleSet
    safety_margin : float
        gamma [m], >= 0.
    resolution : float
        delta [m], > 0; sets the sampling of the certificate.

    Returns
    -------
    numpy.ndarray, shape (K, 3)
        A subsequence of ``path`` (plus any detour vertices) with its exact first and last
        points; consecutive duplicates are dropped.
    """
    points = _as_path(path)
    gamma, delta = check_margins(safety_margin, resolution, 'safety_margin')
    points = _dedupe(points)
    if len(points) < 3:
        return points.copy()
    vertices, _, _ = _shortcut(points, obstacles, gamma, delta)
    return vertices


class PathCurve:
    """The final continuous curve: a chain of cubic pieces, evaluated by arc length.

    Attributes
    ----------
    length_m : float
        Arc length [m].
    piece_start_m : numpy.ndarray, shape (P + 1,)
        Arc length at the start of each piece, then the total length [m].
    stop_arc_length_m : numpy.ndarray
        Arc lengths of the points where the curve is not C2 (polyline corners, junctions) and
        the time parameterisation stops, start and goal included [m].
    """

    def __init__(self, pieces: Pieces, iv_piece: np.ndarray, iv_ta: np.ndarray,
                 iv_tb: np.ndarray, iv_sa: np.ndarray, iv_sb: np.ndarray,
                 piece_start_m: np.ndarray, stop_arc_length_m: np.ndarray) -> None:
        self._pieces = pieces
        self._iv = (iv_piece, iv_ta, iv_tb, iv_sa, iv_sb)
        self.piece_start_m = piece_start_m
        self.length_m = float(piece_start_m[-1])
        self.stop_arc_length_m = stop_arc_length_m

    def _locate(self, s) -> Tuple[np.ndarray, np.ndarray]:
        iv_piece, iv_ta, iv_tb, iv_sa, iv_sb = self._iv
        target = np.clip(np.asarray(s, dtype=np.float64).ravel(), 0.0, self.length_m)
        j = np.clip(np.searchsorted(iv_sa, target, side='right') - 1, 0, len(iv_sa) - 1)
        span = iv_sb[j] - iv_sa[j]
        with np.errstate(divide='ignore', invalid='ignore'):
            frac = np.where(span > 0, (target - iv_sa[j]) / span, 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        piece = iv_piece[j]
        tau = iv_ta[j] + (iv_tb[j] - iv_ta[j]) * frac
        # Newton steps on the arc length (the parameter speed may vary within an interval).
        for _ in range(4):
            reached = iv_sa[j] + self._pieces.speed_integral(piece, iv_ta[j], tau)
            speed = np.linalg.norm(self._pieces.first(piece, tau), axis=1)
            with np.errstate(divide='ignore', invalid='ignore'):
                correction = np.where(speed > 0, (target - reached) / speed, 0.0)
            tau = np.clip(tau + correction, iv_ta[j], iv_tb[j])
            if np.all(np.abs(correction) * speed <= 1e-13 * max(self.length_m, 1.0)):
                break
        return piece, tau

    def pieces_after(self, s: float) -> Pieces:
        """The cubic pieces that reach beyond arc length ``s`` [m] (all of them for s <= 0)."""
        keep = np.flatnonzero(self.piece_start_m[1:] >= s)
        if not len(keep):
            keep = np.array([len(self.piece_start_m) - 2])
        return Pieces(self._pieces.coef[:, keep, :], self._pieces.h[keep],
                      linear=self._pieces.linear)

    def evaluate(self, s) -> np.ndarray:
        """Points of the curve at arc lengths ``s`` [m], shape (M, 3).

        The points lie exactly on the curve, at arc length ``s`` to rounding.
        """
        piece, tau = self._locate(s)
        return self._pieces.position(piece, tau)

    def derivatives(self, s) -> Tuple[np.ndarray, np.ndarray]:
        """Unit tangent dc/ds and curvature vector d2c/ds2 [1/m] at arc lengths ``s``.

        At a stop point the piece after it is used.
        """
        piece, tau = self._locate(s)
        return _arc_derivatives(self._pieces.first(piece, tau), self._pieces.second(piece, tau))


def _arc_derivatives(d1: np.ndarray, d2: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Tangent and curvature vector w.r.t. arc length from parameter derivatives."""
    speed = np.linalg.norm(d1, axis=1)
    speed = np.where(speed > 0, speed, np.nan)
    tangent = d1 / speed[:, None]
    along = np.sum(d2 * tangent, axis=1)
    normal = (d2 - along[:, None] * tangent) / (speed ** 2)[:, None]
    return tangent, normal


@dataclass(frozen=True, eq=False)
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
        Sample indices where the speed must be 0: the start, the goal, and every point where the
        curve is not C1 (polyline corners, junctions of polyline and spline stretches).
    knots : numpy.ndarray, shape (P + 1, 3)
        Waypoints the final curve passes through, in order [m].
    length_m : float
        Arc length of the curve [m].
    min_clearance_m : float
        Smallest clearance found among the verification samples (spacing <= delta / 20, finer
        near obstacles) [m]; +inf without obstacles.
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


def _as_path(path) -> np.ndarray:
    try:
        points = np.asarray(path, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError('path must be an (N, 3) array of numbers') from None
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise InvalidInputError(f'path must have shape (N, 3) with N >= 1, got {points.shape}')
    if not np.all(np.isfinite(points)):
        raise InvalidInputError('path must be finite; found NaN or inf')
    return points


@dataclass
class _Layout:
    """Current shape of the curve over the shortcut polyline.

    Knots are points of the shortcut polyline, named by their polyline arc length sigma [m]; every
    vertex is a knot. A gap (polyline segment) is either covered by the spline or drawn straight.
    """

    vertices: np.ndarray    # (K, 3) shortcut polyline [m]
    sigma: np.ndarray       # (K,) polyline arc length at each vertex [m]
    certified: np.ndarray   # (K - 1,) segment certified >= gamma
    bound: np.ndarray       # (K - 1,) its certified clearance bound [m]
    line: np.ndarray        # (K - 1,) gap drawn as a straight segment
    knots: np.ndarray       # sorted sigma of every knot [m]

    def points(self, sigma: np.ndarray) -> np.ndarray:
        """Polyline points at arc lengths ``sigma`` [m]; vertices exactly."""
        gap = np.clip(np.searchsorted(self.sigma, sigma, side='right') - 1, 0,
                      len(self.sigma) - 2)
        length = self.sigma[gap + 1] - self.sigma[gap]
        frac = (sigma - self.sigma[gap]) / length
        out = self.vertices[gap] + frac[:, None] * (self.vertices[gap + 1] - self.vertices[gap])
        at_vertex = np.searchsorted(self.sigma, sigma)
        exact = (at_vertex < len(self.sigma)) & (
            self.sigma[np.minimum(at_vertex, len(self.sigma) - 1)] == sigma)
        out[exact] = self.vertices[at_vertex[exact]]
        return out

    def gap_of(self, sigma: np.ndarray) -> np.ndarray:
        """Gap holding the piece that starts at ``sigma``."""
        return np.clip(np.searchsorted(self.sigma, sigma, side='right') - 1, 0,
                       len(self.sigma) - 2)


@dataclass
class _Chain:
    """Pieces of the current curve with what the repair needs to know about each."""

    pieces: Pieces
    sig: np.ndarray         # (P, 2) polyline arc length of each piece's end knots [m]
    gap: np.ndarray         # (P,) polyline gap holding the piece
    span: np.ndarray        # (P,) span number (maximal run of spline gaps, or one line gap)
    line: np.ndarray        # (P,) straight piece
    trusted: np.ndarray     # (P,) certified shortcut segment: no need to certify again


def _build_chain(layout: _Layout, mode: str) -> _Chain:
    """Fit one spline per run of spline gaps and one straight piece per polyline gap."""
    sigma = layout.sigma
    coefs, hs, sigs, gaps, spans, lines, trusted = [], [], [], [], [], [], []
    gap = 0
    span = 0
    count = len(sigma) - 1
    while gap < count:
        if layout.line[gap]:
            a, b = layout.vertices[gap], layout.vertices[gap + 1]
            length = sigma[gap + 1] - sigma[gap]
            c = np.zeros((4, 1, 3))
            c[2, 0] = (b - a) / length
            c[3, 0] = a
            coefs.append(c)
            hs.append([length])
            sigs.append([[sigma[gap], sigma[gap + 1]]])
            gaps.append([gap])
            lines.append([True])
            trusted.append([bool(layout.certified[gap])])
            spans.append([span])
            gap += 1
        else:
            end = gap
            while end < count and not layout.line[end]:
                end += 1
            lo = np.searchsorted(layout.knots, sigma[gap], side='left')
            hi = np.searchsorted(layout.knots, sigma[end], side='right')
            knots = layout.knots[lo:hi]
            points = layout.points(knots)
            if mode == 'index':
                t = np.arange(len(knots), dtype=np.float64)
            else:
                # Knots lie on the polyline and every vertex is a knot, so the chord between
                # consecutive knots is their sigma difference.
                t = knots - knots[0]
            spline = CubicSpline(t, points, bc_type='not-a-knot')
            pieces = len(knots) - 1
            coefs.append(spline.c)
            hs.append(np.diff(t))
            sigs.append(np.stack([knots[:-1], knots[1:]], axis=1))
            gaps.append(layout.gap_of(knots[:-1]))
            lines.append(np.zeros(pieces, dtype=bool))
            trusted.append(np.zeros(pieces, dtype=bool))
            spans.append(np.full(pieces, span))
            gap = end
        span += 1
    return _Chain(Pieces(np.concatenate(coefs, axis=1), np.concatenate(hs).astype(np.float64)),
                  np.concatenate(sigs).astype(np.float64), np.concatenate(gaps).astype(np.int64),
                  np.concatenate(spans).astype(np.int64), np.concatenate(lines).astype(bool),
                  np.concatenate(trusted).astype(bool))


def _bounds_violations(pieces: Pieces, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Pieces leaving the box [lo, hi], found exactly from the extrema of each cubic."""
    c0, c1, c2, c3 = pieces.coef
    h = pieces.h[:, None]
    # Stationary points of c0 t^3 + c1 t^2 + c2 t + c3 solve 3 c0 t^2 + 2 c1 t + c2 = 0. The
    # stable form q = -(b + sign(b) sqrt(disc)) / 2, roots c / q and q / a: the textbook formula
    # loses the root near -c / b to cancellation when c0 is rounding noise (a parabola, as
    # not-a-knot splines through three knots are), and the curve's extremum goes unseen.
    a, b, c = 3.0 * c0, 2.0 * c1, c2
    disc = b * b - 4.0 * a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    q = -0.5 * (b + np.where(b < 0.0, -root, root))
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        r1 = np.where(q != 0.0, c / q, 0.0)
        r2 = np.where(a != 0.0, q / a, 0.0)
    r1 = np.clip(np.nan_to_num(r1), 0.0, h)
    r2 = np.clip(np.nan_to_num(r2), 0.0, h)
    lows = np.full(c0.shape, np.inf)
    highs = np.full(c0.shape, -np.inf)
    for t in (np.zeros_like(h), h, r1, r2):
        value = ((c0 * t + c1) * t + c2) * t + c3
        lows = np.minimum(lows, value)
        highs = np.maximum(highs, value)
    return np.any((lows < lo - _BOUNDS_TOLERANCE) | (highs > hi + _BOUNDS_TOLERANCE), axis=1)


@dataclass
class _Check:
    grid: SampleGrid
    cert: Certificate
    violated: np.ndarray    # (P,) bool: clearance or bounds


def _check_chain(chain: _Chain, obstacles: ObstacleSet, gamma: float, delta: float,
                 bounds: Optional[Tuple[np.ndarray, np.ndarray]],
                 checkpoint: Optional[Callable[[], None]] = None) -> _Check:
    """Sample, certify and bounds-check every piece of the chain."""
    grid, cert = certify_pieces(chain.pieces, obstacles, gamma, delta, skip=chain.trusted,
                                checkpoint=checkpoint)
    violated = cert.violated.copy()
    if bounds is not None:
        violated |= _bounds_violations(chain.pieces, *bounds)
    return _Check(grid, cert, violated)


def _no_path(layout: _Layout, gap: int, clearance: float, gamma: float,
             delta: float) -> NoValidPathError:
    deficit = POLYLINE_DEFICIT_FACTOR * delta
    a = np.round(layout.vertices[gap], 4).tolist()
    b = np.round(layout.vertices[gap + 1], 4).tolist()
    where = ('touches or crosses an obstacle' if clearance <= 0.0
             else f'comes within {clearance:.4f} m of an obstacle')
    return NoValidPathError(
        f'no curve through the waypoints keeps the safety margin {gamma:g} m: the straight '
        f'segment from {a} to {b} {where}, and no spline there keeps the margin either (a '
        'grid polyline between free nodes is only guaranteed clearance > gamma - '
        f'delta*sqrt(3)/2 = {gamma - deficit:.4f} m, and misses obstacles thinner than the '
        f'grid); plan on a grid inflated by gamma + delta*sqrt(3)/2 = {gamma + deficit:.4f} m '
        'instead')


def smooth_path(raw_path, obstacles: ObstacleSet, safety_margin: float, resolution: float, *,
                shortcut: bool = True, mode: str = 'chord', sample_spacing: float = 0.1,
                index_step: float = 0.1, knot_spacing: Optional[float] = None,
                bounds: Optional[Tuple[np.ndarray, np.ndarray]] = None,
                keep: Sequence[int] = (),
                checkpoint: Optional[Callable[[], None]] = None) -> SmoothedPath:
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
        Grid spacing delta [m], > 0: verification samples are <= delta / 20 apart.
    shortcut : bool
        Shortcut the path first (:func:`shortcut_path`).
    mode : str
        ``'chord'``, ``'index'`` or ``'none'`` (see the module docstring).
    sample_spacing : float
        Output sample spacing along the curve for ``'chord'`` and ``'none'`` [m], > 0.
    index_step : float
        Output parameter step of the ``'index'`` spline per knot interval [-], in (0, 1].
    knot_spacing : float, optional
        Largest knot spacing along the shortcut polyline for ``'chord'`` [m], > 0; defaults to
        the larger of :data:`DEFAULT_KNOT_SPACING_FACTOR` * delta and
        :data:`DEFAULT_KNOT_SPACING_MIN`. Sets how widely corners are rounded.
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

    Returns
    -------
    SmoothedPath

    Raises
    ------
    InvalidInputError
        For malformed arguments.
    NoValidPathError
        When a waypoint violates the margin, or no curve through the waypoints keeping the margin
        can be built; the message says where and suggests the conservative re-plan.
    """
    points = _as_path(raw_path)
    gamma, delta = check_margins(safety_margin, resolution, 'safety_margin')
    if mode not in SMOOTHING_MODES:
        raise InvalidInputError(
            f'smoothing mode must be one of {", ".join(SMOOTHING_MODES)}, got {mode!r}')
    spacing = positive_number('sample_spacing', sample_spacing)
    step = positive_number('index_step', index_step)
    if step > 1.0:
        raise InvalidInputError(f'index_step must be in (0, 1], got {step}')
    if knot_spacing is None:
        knot_spacing = max(DEFAULT_KNOT_SPACING_FACTOR * delta, DEFAULT_KNOT_SPACING_MIN)
    knot_gap = positive_number('knot_spacing', knot_spacing)
    box = _check_bounds(points, bounds)
    path = _dedupe(points)
    # Capped: exact below gamma plus the slack, enough for the test and its message.
    clearance = np.asarray(obstacles.distance(path, certificate_cap(gamma, delta)))
    if np.any(clearance < gamma):
        index = int(np.argmin(clearance))
        raise NoValidPathError(
            f'waypoint {index} {np.round(path[index], 4).tolist()} has clearance '
            f'{clearance[index]:.4f} m, inside the safety margin {gamma:g} m')
    if len(path) == 1:
        return _single_point(path, obstacles, mode)

    if shortcut:
        vertices, certified, bound = _shortcut_legs(path, _kept_indices(points, path, keep),
                                                    obstacles, gamma, delta, box, checkpoint)
    else:
        vertices = path
        certified = np.zeros(len(path) - 1, dtype=bool)
        bound = np.full(len(path) - 1, -np.inf)
    sigma = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(vertices, axis=0), axis=1))]
    knots = sigma
    if mode == 'chord':
        # Extra knots on long segments keep the spline near the certified polyline and round
        # only the corners; a spline through sparse knots bulges far out (longer, less safe).
        parts = np.maximum(np.ceil(np.diff(sigma) / knot_gap), 1).astype(np.int64)
        owner = np.repeat(np.arange(len(parts)), parts)
        local = np.arange(len(owner)) - (np.cumsum(parts) - parts)[owner]
        knots = np.r_[sigma[owner] + np.diff(sigma)[owner] * (local / parts[owner]), sigma[-1]]
        knots[np.cumsum(parts) - parts] = sigma[:-1]
    layout = _Layout(vertices, sigma, certified, bound,
                     np.full(len(vertices) - 1, mode == 'none'), knots)
    events: List[Tuple[float, float, str, float]] = []
    for _ in range(_MAX_REPAIR_ROUNDS):
        if checkpoint is not None:
            checkpoint()
        chain = _build_chain(layout, mode)
        check = _check_chain(chain, obstacles, gamma, delta, box, checkpoint)
        bad = np.flatnonzero(check.violated)
        if not len(bad):
            break
        _repair(layout, chain, check, bad, events, obstacles, gamma, delta, box)
    else:  # pragma: no cover - each round halves a knot gap or straightens a polyline gap
        raise NoValidPathError('smoothing repair did not converge')
    if checkpoint is not None:
        checkpoint()
    via_sigma = sigma[_vertex_indices(vertices, path, _kept_indices(points, path, keep))]
    return _assemble(path, layout, chain, check, events, mode, spacing, step, via_sigma)


def _check_bounds(points: np.ndarray, bounds) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    if bounds is None:
        return None
    lo = as_point(bounds[0], 'bounds min')
    hi = as_point(bounds[1], 'bounds max')
    outside = np.any((points < lo - _BOUNDS_TOLERANCE) | (points > hi + _BOUNDS_TOLERANCE), axis=1)
    if outside.any():
        index = int(np.flatnonzero(outside)[0])
        raise InvalidInputError(f'waypoint {index} {points[index].tolist()} lies outside the '
                                f'bounds {lo.tolist()} .. {hi.tolist()}')
    return lo, hi


def _repair(layout: _Layout, chain: _Chain, check: _Check, bad: np.ndarray, events: list,
            obstacles: ObstacleSet, gamma: float, delta: float,
            box: Optional[Tuple[np.ndarray, np.ndarray]]) -> None:
    """Split each violating spline piece with polyline knots, or straighten its gap.

    A piece longer than the default knot spacing is cut into pieces of at most that length (one
    round instead of many halvings); a shorter one is halved; one shorter than
    ``MIN_KNOT_GAP_FRACTION * delta``, or whose new knot would itself be inside the margin
    (possible on an uncertified raw edge), has its whole polyline gap straightened. Splits use
    ``DEFAULT_KNOT_SPACING_FACTOR * delta``, the scale of the clearance the shortcut leaves.
    A piece that only leaves the bounds over a gap lying on a face of the bounds (a stretch
    along the ground) is straightened at once: any bend there points out of the box on one side,
    so more knots would only take more rounds to reach the same straight segment.
    """
    straighten = {}
    split = []
    longest = DEFAULT_KNOT_SPACING_FACTOR * delta
    for p in bad:
        gap = int(chain.gap[p])
        before = float(check.cert.piece_min[p])
        if chain.line[p]:
            # Only an uncertified segment (a raw edge) can break the margin when straight, and
            # nothing between its two waypoints can help.
            raise _no_path(layout, gap, before, gamma, delta)
        a, b = chain.sig[p]
        if not check.cert.violated[p] and _on_bounds_face(layout, gap, box):
            straighten[gap] = min(before, straighten.get(gap, np.inf))
        elif b - a > MIN_KNOT_GAP_FRACTION * delta:
            parts = max(2, int(math.ceil((b - a) / longest)))
            split.append((p, a + (b - a) * np.arange(1, parts) / parts))
        else:
            straighten[gap] = min(before, straighten.get(gap, np.inf))
    split = [(p, new) for p, new in split if int(chain.gap[p]) not in straighten]
    if split:
        # A knot inside the margin could never be certified: straighten that gap at once.
        owners = np.concatenate([np.full(len(new), p) for p, new in split])
        added = np.concatenate([new for _, new in split])
        inside = np.atleast_1d(obstacles.distance(layout.points(added),
                                                  certificate_cap(gamma, delta))) < gamma
        for p in np.unique(owners[inside]):
            gap = int(chain.gap[p])
            straighten[gap] = min(float(check.cert.piece_min[p]), straighten.get(gap, np.inf))
        keep = np.array([int(chain.gap[p]) not in straighten for p in owners], dtype=bool)
        for p in np.unique(owners[keep]):
            a, b = chain.sig[p]
            events.append((float(a), float(b), 'knots', float(check.cert.piece_min[p])))
        layout.knots = np.union1d(layout.knots, added[keep])
    for gap, before in straighten.items():
        a, b = layout.sigma[gap], layout.sigma[gap + 1]
        layout.line[gap] = True
        inside = (layout.knots > a) & (layout.knots < b)
        layout.knots = layout.knots[~inside]
        events.append((float(a), float(b), 'polyline', before))


def _on_bounds_face(layout: _Layout, gap: int,
                    box: Optional[Tuple[np.ndarray, np.ndarray]]) -> bool:
    """True when both ends of polyline gap ``gap`` lie on the same face of the bounds box."""
    if box is None:
        return False
    ends = layout.vertices[gap:gap + 2]
    on_low = np.all(np.abs(ends - box[0]) <= _BOUNDS_TOLERANCE, axis=0)
    on_high = np.all(np.abs(ends - box[1]) <= _BOUNDS_TOLERANCE, axis=0)
    return bool(np.any(on_low | on_high))


def _single_point(path: np.ndarray, obstacles: ObstacleSet, mode: str) -> SmoothedPath:
    point = path[:1].copy()
    clearance = float(obstacles.distance(point)[0])
    zeros = np.zeros((1, 3))
    coef = np.zeros((4, 1, 3))
    coef[3, 0] = point[0]
    curve = PathCurve(Pieces(coef, np.ones(1)), np.zeros(1, dtype=np.int64), np.zeros(1),
                      np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(2), np.zeros(1))
    return SmoothedPath(point, point, 0.0, mode, point, np.zeros(1), zeros, zeros, zeros,
                        np.zeros(1), np.zeros(1, dtype=np.int64), point, 0.0, clearance,
                        point[0].copy(), clearance, (), np.zeros((0, 2)), np.zeros((0, 2)),
                        curve)


def _span_samples(chain: _Chain, grid: SampleGrid, mode: str, spacing: float,
                  step: float, via_sigma: np.ndarray) -> Tuple[list, list]:
    """Output samples of every span as (piece, tau) arrays, both span ends included.

    Knots at ``via_sigma`` (polyline arc lengths of via-points) are samples too, so the sampled
    path passes through every via-point exactly.
    """
    pieces = chain.pieces
    out_piece, out_tau = [], []
    ia = np.flatnonzero(grid.first)
    bounds = np.flatnonzero(np.r_[True, chain.span[1:] != chain.span[:-1], True])
    for first, stop in zip(bounds[:-1], bounds[1:]):
        p0, p1 = int(first), int(stop) - 1
        if mode == 'index' and not chain.line[p0]:
            knots = p1 - p0 + 2
            # Parameter = knot number, in steps of index_step, the last knot exactly.
            count = int(math.ceil((knots - 1) / step - 1e-9))
            t = np.minimum(np.arange(count + 1) * step, knots - 1.0)
            t[-1] = knots - 1.0
            local = np.minimum(np.floor(t), knots - 2).astype(np.int64)
            piece = p0 + local
            tau = (t - local) * pieces.h[piece]
        elif mode == 'index':
            count = max(2, int(math.ceil(1.0 / step - 1e-9)))
            piece = np.full(count + 1, p0)
            tau = pieces.h[p0] * np.arange(count + 1) / count
        else:
            # Arc length: evenly spaced targets located in the span's verification intervals.
            span_iv = ia[(grid.piece[ia] >= p0) & (grid.piece[ia] <= p1)]
            sa, sb = grid.s[span_iv], grid.s[span_iv + 1]
            start, end = sa[0], sb[-1]
            count = max(2, int(math.ceil((end - start) / spacing - 1e-9)))
            target = start + (end - start) * np.arange(1, count) / count
            j = np.clip(np.searchsorted(sa, target, side='right') - 1, 0, len(sa) - 1)
            frac = np.clip((target - sa[j]) / (sb[j] - sa[j]), 0.0, 1.0)
            ta, tb = grid.tau[span_iv[j]], grid.tau[span_iv[j] + 1]
            piece = np.r_[p0, grid.piece[span_iv[j]], p1]
            tau = np.r_[0.0, ta + (tb - ta) * frac, pieces.h[p1]]
            vias = np.arange(p0 + 1, p1 + 1)
            vias = vias[np.isin(chain.sig[vias, 0], via_sigma)]
            if len(vias):
                # Targets within a micrometre of a via-point would make a zero-length step.
                via_s = grid.s[np.flatnonzero(grid.first & (grid.tau == 0.0))][vias]
                near = np.any(np.abs(target[:, None] - via_s[None, :]) < _VIA_SAMPLE_GAP, axis=1)
                keep = np.r_[True, ~near, True]
                piece = np.r_[piece[keep], vias]
                tau = np.r_[tau[keep], np.zeros(len(vias))]
                order = np.lexsort((tau, piece))
                piece, tau = piece[order], tau[order]
        out_piece.append(piece)
        out_tau.append(tau)
    return out_piece, out_tau


def _arc_length_at(pieces: Pieces, grid: SampleGrid, piece: np.ndarray,
                   tau: np.ndarray) -> np.ndarray:
    """Arc length of points (piece, tau) [m], from the nearest verification sample below."""
    ia = np.flatnonzero(grid.first)
    key_grid = grid.piece[ia] + grid.tau[ia] / pieces.h[grid.piece[ia]]
    key = piece + tau / pieces.h[piece]
    j = np.clip(np.searchsorted(key_grid, key, side='right') - 1, 0, len(ia) - 1)
    # A point at tau = h of its piece must integrate on its own piece, not the next one.
    own = grid.piece[ia[j]] != piece
    while own.any():
        j[own] -= 1
        own = grid.piece[ia[j]] != piece
    base = ia[j]
    return grid.s[base] + pieces.speed_integral(piece, grid.tau[base], tau)


def _assemble(path: np.ndarray, layout: _Layout, chain: _Chain, check: _Check, events: list,
              mode: str, spacing: float, step: float, via_sigma: np.ndarray) -> SmoothedPath:
    pieces = chain.pieces
    grid = check.grid
    span_piece, span_tau = _span_samples(chain, grid, mode, spacing, step, via_sigma)
    # Concatenate spans; each junction sample is kept once (as the end of the earlier span).
    piece = np.concatenate([span_piece[0]] + [p[1:] for p in span_piece[1:]])
    tau = np.concatenate([span_tau[0]] + [t[1:] for t in span_tau[1:]])
    junction = np.cumsum([len(p) - 1 for p in span_piece])[:-1]
    positions = pieces.position(piece, tau)
    tangent_in, curvature_vec = _arc_derivatives(pieces.first(piece, tau),
                                                 pieces.second(piece, tau))
    tangent_out = tangent_in.copy()
    arc = _arc_length_at(pieces, grid, piece, tau)
    stops = [0]
    for k, index in enumerate(junction):
        nxt = np.array([span_piece[k + 1][0]])
        t_out, k_out = _arc_derivatives(pieces.first(nxt, np.zeros(1)),
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
                      grid.s[ia + 1], piece_start, arc[np.asarray(stops)])
    knot_sigma = np.r_[chain.sig[:, 0], chain.sig[-1, 1]]
    certified = np.where(chain.trusted, layout.bound[chain.gap], check.cert.certified)
    tangent_max, curvature_max = _interval_maxima(pieces, grid, arc, tangent_in, tangent_out,
                                                  curvature_vec)
    return SmoothedPath(
        raw_path=path, shortcut_path=layout.vertices.copy(),
        shortcut_length_m=polyline_length(layout.vertices), mode=mode, positions=positions,
        arc_length=arc, tangents=tangent_out, incoming_tangents=tangent_in,
        curvature_vectors=curvature_vec, curvature=np.linalg.norm(curvature_vec, axis=1),
        stop_points=np.asarray(stops), knots=layout.points(knot_sigma),
        length_m=float(grid.s[-1]), min_clearance_m=check.cert.min_clearance,
        min_clearance_point=check.cert.min_point, certified_clearance_m=float(np.min(certified)),
        repaired_stretches=_stretches(events, knot_sigma, piece_start),
        interval_tangent_max=tangent_max, interval_curvature_max=curvature_max, curve=curve)


def _components(vectors: np.ndarray) -> np.ndarray:
    """Horizontal norm and vertical magnitude of each row, shape (M, 2)."""
    return np.stack([np.hypot(vectors[:, 0], vectors[:, 1]), np.abs(vectors[:, 2])], axis=1)


def _interval_maxima(pieces: Pieces, grid: SampleGrid, arc: np.ndarray, tangent_in: np.ndarray,
                     tangent_out: np.ndarray, curvature: np.ndarray):
    """Largest horizontal and vertical tangent and curvature components over each interval.

    Taken over the interval's two ends (one-sided at stop points) and every verification sample
    strictly inside it (spacing <= delta / 20).
    """
    tangent_max = np.maximum(_components(tangent_out[:-1]), _components(tangent_in[1:]))
    curvature_max = np.maximum(_components(curvature[:-1]), _components(curvature[1:]))
    j = np.searchsorted(arc, grid.s, side='right') - 1
    inside = (j >= 0) & (j < len(arc) - 1)
    inside[inside] &= (grid.s[inside] > arc[j[inside]]) & (grid.s[inside] < arc[j[inside] + 1])
    if inside.any():
        t, k = _arc_derivatives(pieces.first(grid.piece[inside], grid.tau[inside]),
                                pieces.second(grid.piece[inside], grid.tau[inside]))
        np.maximum.at(tangent_max, j[inside], _components(t))
        np.maximum.at(curvature_max, j[inside], _components(k))
    return tangent_max, curvature_max


def _stretches(events: list, knot_sigma: np.ndarray,
               knot_s: np.ndarray) -> Tuple[RepairedStretch, ...]:
    """Merge repair events (polyline sigma intervals) into arc-length intervals of the curve."""
    if not events:
        return ()
    spans = []
    for a, b, method, before in events:
        lo = knot_s[max(np.searchsorted(knot_sigma, a, side='right') - 1, 0)]
        hi = knot_s[min(np.searchsorted(knot_sigma, b, side='left'), len(knot_s) - 1)]
        spans.append((float(lo), float(hi), method, before))
    spans.sort()
    merged = [list(spans[0])]
    for lo, hi, method, before in spans[1:]:
        last = merged[-1]
        if lo <= last[1]:
            last[1] = max(last[1], hi)
            last[2] = 'polyline' if 'polyline' in (last[2], method) else last[2]
            last[3] = min(last[3], before)
        else:
            merged.append([lo, hi, method, before])
    return tuple(RepairedStretch(lo, hi, method, before) for lo, hi, method, before in merged)
