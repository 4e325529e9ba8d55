"""Fitting the spline over the shortcut polyline, certifying it, and repairing it until it holds.

The third step of :mod:`uav_global_planner.core.path.smoothing`. The curve is described by a
:class:`Layout` over the shortcut polyline: knots named by their polyline arc length sigma, and
for each polyline gap whether the spline covers it or it is drawn straight. :func:`build_chain`
fits one C2 not-a-knot cubic spline
(:func:`~uav_global_planner.core.path.piecewise.cubic_spline`) per run of spline gaps and one
straight piece per straight gap (the run at the start of a curve that continues a motion is
clamped to the given tangent and curvature instead, :func:`start_spline`);
:func:`check_chain` certifies the clearance of every piece
(:func:`~uav_global_planner.core.path.clearance.certify_pieces`) and checks the bounds box exactly.
:func:`repair_curve` repeats both, adding polyline knots to each violating piece (or, for a
piece shorter than ``delta / 4``, drawing its polyline gap straight) until no piece violates.
"""

from dataclasses import dataclass
import math
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Tuple

import numpy as np

from uav_global_planner.core.errors import NoValidPathError
from uav_global_planner.core.map.grid import HALF_CELL_DIAGONAL
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path.clearance import (Certificate, certificate_cap, certify_pieces,
                                                    Pieces, SampleGrid)
from uav_global_planner.core.path.piecewise import (cubic_spline, PiecewisePolynomial,
                                                    stationary_points)
from uav_global_planner.core.result import RepairMethod

#: Default largest knot spacing of ``'chord'`` splines along the shortcut polyline: this many
#: delta, but at least :data:`DEFAULT_KNOT_SPACING_MIN`. It sets how widely corners are rounded:
#: wider means lower curvature and faster flight, but more bulging and repairs.
DEFAULT_KNOT_SPACING_FACTOR = 2.0
#: Lower limit of the default knot spacing [m] (corners rounded over about a metre).
DEFAULT_KNOT_SPACING_MIN = 1.0
#: Violating knot intervals shorter than this (times delta) are straightened, not split.
MIN_KNOT_GAP_FRACTION = 0.25
#: Tolerance on leaving the bounds box [m]: nodes may sit on its faces.
BOUNDS_TOLERANCE = 1e-9

# Upper bound on repair rounds; each round halves knot gaps or straightens polyline gaps.
_MAX_REPAIR_ROUNDS = 200


class RepairEvent(NamedTuple):
    """One repair of the curve over a stretch of the shortcut polyline."""

    start_sigma: float              # polyline arc length where the stretch starts [m]
    end_sigma: float                # and ends [m]
    method: RepairMethod
    clearance_before: float         # smallest sampled clearance before the repair [m]


@dataclass
class Layout:
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
    # Unit tangent and curvature vector [1/m] the curve must start with (None: free start).
    start: Optional[Tuple[np.ndarray, np.ndarray]] = None

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
class Chain:
    """Pieces of the current curve with what the repair needs to know about each."""

    pieces: Pieces
    sig: np.ndarray         # (P, 2) polyline arc length of each piece's end knots [m]
    gap: np.ndarray         # (P,) polyline gap holding the piece
    span: np.ndarray        # (P,) span number (maximal run of spline gaps, or one line gap)
    line: np.ndarray        # (P,) straight piece
    trusted: np.ndarray     # (P,) certified shortcut segment: no need to certify again


def build_chain(layout: Layout, mode: str) -> Chain:
    """Fit one spline per run of spline gaps and one straight piece per polyline gap."""
    sigma = layout.sigma
    # Per span: arrays (spline runs) or one-item lists (straight gaps), joined at the end.
    coefs: List[Any] = []
    hs: List[Any] = []
    sigs: List[Any] = []
    gaps: List[Any] = []
    spans: List[Any] = []
    lines: List[Any] = []
    trusted: List[Any] = []
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
            if gap == 0 and layout.start is not None:
                # Parameter speed of the first knot interval (1 for chord, its length for index).
                speed = (knots[1] - knots[0]) / (t[1] - t[0])
                tangent, curvature = layout.start
                coefs.append(start_spline(t, points, speed * tangent, speed ** 2 * curvature))
            else:
                coefs.append(cubic_spline(t, points))
            pieces = len(knots) - 1
            hs.append(np.diff(t))
            sigs.append(np.stack([knots[:-1], knots[1:]], axis=1))
            gaps.append(layout.gap_of(knots[:-1]))
            lines.append(np.zeros(pieces, dtype=bool))
            trusted.append(np.zeros(pieces, dtype=bool))
            spans.append(np.full(pieces, span))
            gap = end
        span += 1
    return Chain(Pieces(np.concatenate(coefs, axis=1), np.concatenate(hs).astype(np.float64)),
                 np.concatenate(sigs).astype(np.float64), np.concatenate(gaps).astype(np.int64),
                 np.concatenate(spans).astype(np.int64), np.concatenate(lines).astype(bool),
                 np.concatenate(trusted).astype(bool))


def start_spline(t: np.ndarray, points: np.ndarray, first: np.ndarray,
                 second: np.ndarray) -> np.ndarray:
    """Coefficients of a C2 cubic spline that starts with given first and second derivatives.

    The spline passes through ``points[0]`` with ``c'(t[0]) = first`` and ``c''(t[0]) =
    second``, through every later point but ``points[1]``, and ends not-a-knot, as the other
    runs do. Three conditions at the start and one at the end leave one point free: the first
    knot after the start (on a straight lead-in along the start tangent it moves by about the
    bend the curvature asks for over one knot interval). With two knots the spline is the one
    cubic of the four conditions (start point, both derivatives, end point).

    The spline is linear in its data, so the free knot is found exactly: fit with the knot where
    it lies, then move it by the missing second derivative over the weight of that knot on
    c''(t[0]) (one more such step removes the rounding).

    Parameters
    ----------
    t : numpy.ndarray, shape (n,)
        Strictly increasing knot parameters, n >= 2.
    points : numpy.ndarray, shape (n, 3)
        Knot points [m]; ``points[1]`` is only the first guess when n >= 3.
    first, second : numpy.ndarray, shape (3,)
        dc/dt [m / unit] and d2c/dt2 [m / unit^2] at ``t[0]``.

    Returns
    -------
    numpy.ndarray, shape (4, n - 1, 3)
        Coefficients, highest power first.
    """
    origin = points[0]
    local = points - origin    # fitted near the origin: no rounding from large coordinates
    if len(t) == 2:
        h = t[1] - t[0]
        coef = np.zeros((4, 1, 3))
        coef[3, 0] = origin
        coef[2, 0] = first
        coef[1, 0] = 0.5 * second
        coef[0, 0] = (local[1] - first * h - 0.5 * second * h * h) / h ** 3
        return coef
    unit = np.zeros(len(t))
    unit[1] = 1.0
    weight = 2.0 * cubic_spline(t, unit, start_derivative=np.zeros(()))[1, 0]
    local = local.copy()
    for _ in range(2):
        local[1] += (second - 2.0 * cubic_spline(t, local, first)[1, 0]) / weight
    coef = cubic_spline(t, local, first)
    coef[3] += origin
    return coef


def _bounds_violations(pieces: Pieces, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Pieces leaving the box [lo, hi], found exactly from the extrema of each cubic.

    The chain is one :class:`~uav_global_planner.core.path.piecewise.PiecewisePolynomial` over
    the cumulative parameter; each piece's extrema per axis are its end values and its values at
    its stationary points (:func:`~uav_global_planner.core.path.piecewise.stationary_points`,
    with the cancellation-free quadratic formula: the stationary point of a not-a-knot
    parabola, whose cubic coefficient is rounding noise, is found). The chain is continuous, so
    a piece's end value is the next piece's start value (to rounding, far below the tolerance).
    """
    breaks = np.r_[0.0, np.cumsum(pieces.h)]
    chain = PiecewisePolynomial(pieces.coef, breaks)
    at_breaks = chain(breaks)
    lows = np.minimum(at_breaks[:-1], at_breaks[1:])
    highs = np.maximum(at_breaks[:-1], at_breaks[1:])
    roots, axes = stationary_points(pieces.coef, breaks)
    if len(roots):
        piece = np.clip(np.searchsorted(breaks, roots, side='right') - 1, 0, len(pieces) - 1)
        values = chain(roots)[np.arange(len(roots)), axes]
        np.minimum.at(lows, (piece, axes), values)
        np.maximum.at(highs, (piece, axes), values)
    return np.any((lows < lo - BOUNDS_TOLERANCE) | (highs > hi + BOUNDS_TOLERANCE), axis=1)


@dataclass
class Check:
    grid: SampleGrid
    cert: Certificate
    violated: np.ndarray    # (P,) bool: clearance or bounds


def check_chain(chain: Chain, obstacles: ObstacleSet, gamma: float, delta: float,
                bounds: Optional[Tuple[np.ndarray, np.ndarray]],
                checkpoint: Optional[Callable[[], None]] = None) -> Check:
    """Sample, certify and bounds-check every piece of the chain."""
    grid, cert = certify_pieces(chain.pieces, obstacles, gamma, delta, skip=chain.trusted,
                                checkpoint=checkpoint)
    violated = cert.violated.copy()
    if bounds is not None:
        violated |= _bounds_violations(chain.pieces, *bounds)
    return Check(grid, cert, violated)


def _no_path(layout: Layout, gap: int, clearance: float, gamma: float,
             delta: float) -> NoValidPathError:
    # Largest deficit of the raw polyline's clearance below gamma.
    deficit = HALF_CELL_DIAGONAL * delta
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


def _repair(layout: Layout, chain: Chain, check: Check, bad: np.ndarray,
            events: List[RepairEvent], obstacles: ObstacleSet, gamma: float, delta: float,
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
    piece_min = check.cert.piece_min
    assert piece_min is not None    # certify_pieces always reports the sampled minima
    straighten: Dict[int, float] = {}
    split = []
    longest = DEFAULT_KNOT_SPACING_FACTOR * delta
    for p in bad:
        gap = int(chain.gap[p])
        before = float(piece_min[p])
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
            straighten[gap] = min(float(piece_min[p]), straighten.get(gap, np.inf))
        keep = np.array([int(chain.gap[p]) not in straighten for p in owners], dtype=bool)
        for p in np.unique(owners[keep]):
            a, b = chain.sig[p]
            events.append(RepairEvent(float(a), float(b), RepairMethod.KNOTS,
                                      float(piece_min[p])))
        layout.knots = np.union1d(layout.knots, added[keep])
    for gap, before in straighten.items():
        a, b = layout.sigma[gap], layout.sigma[gap + 1]
        layout.line[gap] = True
        inside = (layout.knots > a) & (layout.knots < b)
        layout.knots = layout.knots[~inside]
        events.append(RepairEvent(float(a), float(b), RepairMethod.POLYLINE, before))


def _on_bounds_face(layout: Layout, gap: int,
                    box: Optional[Tuple[np.ndarray, np.ndarray]]) -> bool:
    """True when both ends of polyline gap ``gap`` lie on the same face of the bounds box."""
    if box is None:
        return False
    ends = layout.vertices[gap:gap + 2]
    on_low = np.all(np.abs(ends - box[0]) <= BOUNDS_TOLERANCE, axis=0)
    on_high = np.all(np.abs(ends - box[1]) <= BOUNDS_TOLERANCE, axis=0)
    return bool(np.any(on_low | on_high))


def initial_layout(vertices: np.ndarray, certified: np.ndarray, bound: np.ndarray, mode: str,
                   knot_gap: float,
                   start: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> Layout:
    """The layout before any repair: every gap covered by the spline (straight for ``'none'``).

    Parameters
    ----------
    vertices : numpy.ndarray, shape (K, 3)
        Shortcut polyline [m].
    certified, bound : numpy.ndarray, shape (K - 1,)
        Whether each segment is certified >= gamma, and its certified bound [m].
    mode : str
        ``'chord'``, ``'index'`` or ``'none'``.
    knot_gap : float
        Largest knot spacing along the polyline for ``'chord'`` [m], > 0.
    start : tuple of two numpy.ndarray of shape (3,), optional
        Unit tangent and curvature vector (normal to it) [1/m] the spline must start with.
    """
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
    return Layout(vertices, sigma, certified, bound, np.full(len(vertices) - 1, mode == 'none'),
                  knots, start)


def repair_curve(layout: Layout, mode: str, obstacles: ObstacleSet, gamma: float, delta: float,
                 box: Optional[Tuple[np.ndarray, np.ndarray]],
                 checkpoint: Optional[Callable[[], None]] = None
                 ) -> Tuple[Chain, Check, List[RepairEvent]]:
    """Fit, certify and repair until every piece keeps gamma and stays inside ``box``.

    ``layout`` is changed in place (knots added, gaps straightened).

    Returns
    -------
    chain : Chain
        The accepted curve.
    check : Check
        Its certificate and verification samples.
    events : list of RepairEvent
        The repairs made, in order.

    Raises
    ------
    NoValidPathError
        When a straight, uncertified raw edge breaks the margin (nothing can repair it).
    """
    events: List[RepairEvent] = []
    for _ in range(_MAX_REPAIR_ROUNDS):
        if checkpoint is not None:
            checkpoint()
        chain = build_chain(layout, mode)
        check = check_chain(chain, obstacles, gamma, delta, box, checkpoint)
        bad = np.flatnonzero(check.violated)
        if not len(bad):
            return chain, check, events
        _repair(layout, chain, check, bad, events, obstacles, gamma, delta, box)
    # Not reached in practice: each round halves a knot gap or straightens a polyline gap.
    raise NoValidPathError('smoothing repair did not converge')  # pragma: no cover
