"""The clearance engine: certified answers to "does this keep >= gamma everywhere?".

Every yes/no safety decision of the project goes through this module (shortcutting, the spline
certificate and its repair, the fallback, the node's replan / discard / withdraw decisions, the
mission export): a segment or curve piece is *clear* only when a rigorous lower bound on its
clearance is >= the margin over the whole of it, never because some samples were.

The bound
---------
The obstacle distance d is 1-Lipschitz (each term is the exact Euclidean distance to a closed
set). For a curve piece between samples ``a`` and ``b`` at parameter distance ``dt``, every curve
point lies within ``e = dt**2 / 8 * max|c''|`` of the chord ``ab`` (``|c''|`` is linear on a
cubic piece, so its maximum is at an end), and every chord point ``q`` has
``d(q) >= (d(a) + d(b) - |ab|) / 2``. Hence, on the whole piece between the samples::

    d(c(t)) >= (d(a) + d(b) - |ab|) / 2 - e.

The inequality holds as well for any lower bound d' <= d in place of d, which is what makes the
engine fast: distances are asked with a *cap* (:meth:`ObstacleSet.distance`), exact below it and
the cap above, so a query reads only the obstacles within the cap of it (a lattice over shapes,
a KD-tree over points). Intervals whose bound is below gamma are subdivided, down to
``delta * 1e-5`` (:data:`FINEST_SPACING_FRACTION`); a sample below gamma, or touching an obstacle,
is a definite violation.

Cost: samples no coarser than the given spacing along the queried geometry, each a capped
lookup, plus refinement only where the bound is tight. Memory follows the queried length.
Straight segments among obstacles that are shapes only are refined in one compiled call
(:mod:`~uav_global_planner.core.path.segment_refinement`, the same bound and the same verdicts).

The module is somewhat over 500 lines on purpose: the certificate, the pieces it evaluates and
the segment and polyline checks built on it are the one implementation of every safety
decision, kept together so that no second, weaker check can grow beside it.
"""

from dataclasses import dataclass
import math
from typing import Callable, Optional, Tuple

import numpy as np

from uav_global_planner.core.checks import check_non_negative, check_path, check_positive
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path import arc_length
from uav_global_planner.core.path.segment_refinement import refine_lines, shape_tables

#: Coarsest verification sampling of curves, as a fraction of delta (delta / 20).
CHECK_SPACING_FRACTION = 1.0 / 20.0
#: Finest first sampling of curves [m] (delta / 20 at delta = 0.1 m): on finer grids the samples
#: stay this far apart, so their number follows the curve's length, not the grid's resolution.
#: The certificate refines wherever its bound needs it, so it is exact at any first spacing;
#: what the spacing sets is how close the sampled smallest clearance (the report) comes to the
#: true one, within half a spacing.
MIN_CHECK_SPACING = 0.005
#: Finest subdivision of the clearance certificate, as a fraction of delta.
FINEST_SPACING_FRACTION = 1e-5
#: First sampling of straight segments [m]. The certificate refines it wherever needed, so this
#: only trades distance evaluations far from obstacles against refinement rounds; it is absolute
#: because the work it saves scales with obstacle sizes, not with delta.
SEGMENT_SPACING = 0.25
#: Distances are capped at gamma plus this many sample spacings, and at least
#: :data:`MIN_CAP_SLACK`: far from obstacles two capped ends then certify an interval at once.
CAP_SPACINGS = 8.0
#: Smallest slack of the distance cap above gamma [m].
MIN_CAP_SLACK = 1.0
# An interval needing more pieces than this to certify is refused (see certify_samples).
_MAX_PIECES = 1024
# Reported smallest clearances farther than this are computed without a cap [m].
_WIDEST_REPORT_CAP = 256.0


def check_spacing(delta: float) -> float:
    """First spacing of the verification samples of a curve on a grid of spacing ``delta``
    [m]: ``delta / 20`` (:data:`CHECK_SPACING_FRACTION`), at least :data:`MIN_CHECK_SPACING`."""
    return max(delta * CHECK_SPACING_FRACTION, MIN_CHECK_SPACING)


def certificate_cap(gamma: float, spacing: float) -> float:
    """Distance cap for certifying samples ``spacing`` apart against margin ``gamma`` [m].

    Any cap above ``gamma + spacing / 2`` certifies free space without refinement; a larger one
    makes the reported smallest clearances exact more often, at the price of longer lookups.
    """
    return gamma + max(CAP_SPACINGS * spacing, MIN_CAP_SLACK)


# Most children an interval is cut into per refinement round of the certificate.
_MAX_SUBDIVISION = 32
# Gauss-Legendre rule for arc lengths: exact to rounding on the short verification intervals
# (the error term scales with the tenth power of the length). Every arc length is integrated with
# it from a verification sample, so labels agree bit for bit where intervals meet.
GAUSS = {5: np.polynomial.legendre.leggauss(5)}


@dataclass(frozen=True, eq=False)
class Pieces:
    """Chain of cubic pieces ``p(tau) = c0 tau^3 + c1 tau^2 + c2 tau + c3``, ``tau in [0, h]``.

    The coefficients are those of a
    :class:`~uav_global_planner.core.path.piecewise.PiecewisePolynomial`, but the engine
    evaluates them by piece and local parameter, not by the chain's global parameter: the bend
    bound of an interval needs ``|c''|`` of *its own* piece at both ends, and at a shared end
    the chain would give the next piece's (one-sided values decide the certificate there).

    Attributes
    ----------
    coef : numpy.ndarray, shape (4, P, 3)
        Coefficients, highest power first [m / unit^k].
    h : numpy.ndarray, shape (P,)
        Parameter length of each piece [parameter units].
    """

    coef: np.ndarray
    h: np.ndarray
    linear: bool = False    # every piece straight: c0 = c1 = 0

    def __len__(self) -> int:
        return len(self.h)

    def position(self, piece: np.ndarray, tau: np.ndarray) -> np.ndarray:
        if self.linear:
            return self.coef[3, piece] + tau[:, None] * self.coef[2, piece]
        c = self.coef[:, piece, :]
        x = tau[:, None]
        return ((c[0] * x + c[1]) * x + c[2]) * x + c[3]

    def first(self, piece: np.ndarray, tau: np.ndarray) -> np.ndarray:
        c = self.coef[:3, piece, :]
        x = tau[:, None]
        return (3.0 * c[0] * x + 2.0 * c[1]) * x + c[2]

    def second(self, piece: np.ndarray, tau: np.ndarray) -> np.ndarray:
        c = self.coef[:2, piece, :]
        return 6.0 * c[0] * tau[:, None] + 2.0 * c[1]

    def speed_integral(self, piece: np.ndarray, tau0: np.ndarray, tau1: np.ndarray,
                       order: int = 5) -> np.ndarray:
        """Arc length from ``tau0`` to ``tau1`` on each piece [m] (Gauss-Legendre rule, a
        compiled loop: :mod:`~uav_global_planner.core.path.arc_length`)."""
        nodes, weights = GAUSS[order]
        return arc_length.speed_integral(self.coef, piece, tau0, tau1, nodes, weights)


def line_pieces(p0: np.ndarray, p1: np.ndarray) -> Pieces:
    """Straight segments ``p0 -> p1`` as cubic pieces over ``tau in [0, 1]``."""
    coef = np.zeros((4, len(p0), 3))
    coef[2] = p1 - p0
    coef[3] = p0
    return Pieces(coef, np.ones(len(p0)), linear=True)


@dataclass
class Certificate:
    """Outcome of :func:`certify_samples`, per piece and overall."""

    violated: np.ndarray          # (P,) bool: bound below gamma somewhere on the piece
    certified: np.ndarray         # (P,) smallest certified lower bound on accepted intervals [m]
    piece_min: Optional[np.ndarray] = None     # (P,) smallest sampled clearance [m]
    piece_worst: Optional[np.ndarray] = None   # (P, 3) where it was sampled [m]
    min_clearance: float = math.inf            # smallest sampled clearance overall [m]
    min_point: Optional[np.ndarray] = None     # (3,) where [m]


def certify_samples(pieces: Pieces, piece: np.ndarray, tau: np.ndarray, pos: np.ndarray,
                    curv: Optional[np.ndarray], dist: np.ndarray, first: np.ndarray,
                    obstacles: ObstacleSet, gamma: float, finest: float,
                    skip: Optional[np.ndarray] = None, stats: bool = True,
                    cap: float = math.inf,
                    checkpoint: Optional[Callable[[], None]] = None,
                    max_pieces: int = _MAX_PIECES) -> Certificate:
    """Certify clearance >= gamma on every interval between consecutive samples of a piece.

    Parameters
    ----------
    pieces : Pieces
    piece, tau : numpy.ndarray, shape (G,)
        Samples, sorted by piece then tau; each piece's first and last sample are its ends.
    pos, dist : numpy.ndarray, shapes (G, 3) and (G,)
        Position [m] and clearance [m] of each sample.
    curv : numpy.ndarray, shape (G,), or None
        ``|c''|`` at each sample [m / unit^2]; None for straight pieces.
    first : numpy.ndarray of bool, shape (G,)
        True where a sample starts an interval (every sample but a piece's last).
    gamma : float
        Required clearance [m].
    finest : float
        Intervals whose spatial size (chord plus twice the bend bound) is below this [m] are not
        subdivided further: if their bound is still below gamma the piece is violated.
    skip : numpy.ndarray of bool, shape (P,), optional
        Pieces already certified elsewhere: sampled for the statistics only.
    stats : bool
        Also report the smallest sampled clearances (per piece and overall) and where.
    cap : float
        Distance cap of the new samples' queries [m] (see :func:`certificate_cap`); ``dist``
        may be capped the same way. Capped distances are lower bounds, so the certificate holds.
    checkpoint : callable, optional
        Called before every refinement round; it raises to abandon the work.
    max_pieces : int
        An interval whose end clearances leave so little room above gamma that certifying it
        would take more than this many pieces is refused (counted as violated). Refusing is
        always safe; a caller that only looks for a good segment among many (shortcutting) can
        refuse sooner.

    Notes
    -----
    Each round evaluates every new sample in a single ``ObstacleSet.distance`` call. A sample
    below gamma, or touching an obstacle (d = 0 is also every point inside one, which matters
    for gamma = 0), is a definite violation that no refinement can help.
    """
    count = len(pieces)
    certified = np.full(count, np.inf)
    bad_sample = (dist < gamma) | (dist <= 0.0)
    violated = np.zeros(count, dtype=bool)
    violated[piece[bad_sample]] = True
    samples = [(piece, dist, pos)] if stats else []
    ia = np.flatnonzero(first)
    live = ~violated[piece[ia]]
    if skip is not None:
        live &= ~skip[piece[ia]]
    ia = ia[live]
    ib = ia + 1
    p, ta, tb, pa, pb, da, db = piece[ia], tau[ia], tau[ib], pos[ia], pos[ib], dist[ia], dist[ib]
    ka: Optional[np.ndarray] = None
    kb: Optional[np.ndarray] = None
    if curv is not None:
        ka, kb = curv[ia], curv[ib]
    while len(p):
        if checkpoint is not None:
            checkpoint()
        chord = np.sqrt(np.einsum('ij,ij->i', pb - pa, pb - pa))
        size = chord
        bound = 0.5 * (da + db - chord)
        if ka is not None and kb is not None:
            bend = (tb - ta) ** 2 / 8.0 * np.maximum(ka, kb)
            bound -= bend
            size = chord + 2.0 * bend
        ok = bound >= gamma
        np.minimum.at(certified, p[ok], bound[ok])
        # Hopeless too: an interval whose ends clear gamma by so little that certifying it
        # would take more than _MAX_PIECES pieces (a curve grazing the margin by a hair along
        # metres would otherwise take millions). Refused, it is repaired or re-planned with
        # room, as a violation is.
        slack_all = da + db - 2.0 * gamma
        violated[p[~ok & ((size <= finest) | (slack_all * max_pieces < size))]] = True
        refine = np.flatnonzero(~ok & ~violated[p])
        if not len(refine):
            break
        # Cut so that the children's chords fit the slack left by the end clearances; a tangent
        # approach (slack -> 0) gets the maximum cut and converges geometrically.
        slack = da[refine] + db[refine] - 2.0 * gamma
        with np.errstate(divide='ignore', invalid='ignore'):
            parts = np.ceil(size[refine] / slack)
        parts = np.where(np.isfinite(parts) & (slack > 0), parts, _MAX_SUBDIVISION)
        parts = np.clip(parts, 2, _MAX_SUBDIVISION).astype(np.int64)
        # Nodes of the subdivision: parts + 1 per interval, ends copied, interior evaluated.
        group = np.repeat(np.arange(len(refine)), parts + 1)
        local = np.arange(len(group)) - (np.cumsum(parts + 1) - (parts + 1))[group]
        total = parts[group]
        src = refine[group]
        node_tau = ta[src] + (tb[src] - ta[src]) * (local / total)
        node_piece = p[src]
        head = local == 0
        inner = ~head & (local < total)
        node_pos = np.where(head[:, None], pa[src], pb[src])
        node_dist = np.where(head, da[src], db[src])
        ip, it = node_piece[inner], node_tau[inner]
        new_pos = pieces.position(ip, it)
        new_dist = obstacles.distance(new_pos, cap)
        node_pos[inner] = new_pos
        node_dist[inner] = new_dist
        if stats:
            samples.append((ip, new_dist, new_pos))
        violated[ip[(new_dist < gamma) | (new_dist <= 0.0)]] = True
        keep = (local < total) & ~violated[node_piece]
        a = np.flatnonzero(keep)
        b = a + 1
        p, ta, tb = node_piece[a], node_tau[a], node_tau[b]
        pa, pb, da, db = node_pos[a], node_pos[b], node_dist[a], node_dist[b]
        if ka is not None and kb is not None:
            node_curv = np.where(head, ka[src], kb[src])
            node_curv[inner] = np.linalg.norm(pieces.second(ip, it), axis=1)
            ka, kb = node_curv[a], node_curv[b]
    if skip is not None:
        violated &= ~skip
    cert = Certificate(violated, certified)
    if stats:
        all_piece = np.concatenate([x[0] for x in samples])
        all_dist = np.concatenate([x[1] for x in samples])
        all_pos = np.concatenate([x[2] for x in samples])
        order = np.lexsort((all_dist, all_piece))
        firsts = order[np.r_[True, all_piece[order][1:] != all_piece[order][:-1]]]
        cert.piece_min = np.full(count, np.inf)
        cert.piece_worst = np.full((count, 3), np.nan)
        cert.piece_min[all_piece[firsts]] = all_dist[firsts]
        cert.piece_worst[all_piece[firsts]] = all_pos[firsts]
        best = int(np.argmin(all_dist))
        cert.min_clearance = float(all_dist[best])
        cert.min_point = all_pos[best].copy()
    return cert


def segments_clear(p0: np.ndarray, p1: np.ndarray, obstacles: ObstacleSet, gamma: float,
                   spacing: float, finest: float,
                   checkpoint: Optional[Callable[[], None]] = None,
                   max_pieces: int = _MAX_PIECES) -> Tuple[np.ndarray, np.ndarray]:
    """Certify straight segments ``p0[i] -> p1[i]`` in one batch (``max_pieces`` as for
    :func:`certify_samples`).

    Returns
    -------
    clear : numpy.ndarray of bool, shape (C,)
        True where clearance >= gamma is certified on the whole segment.
    bound : numpy.ndarray, shape (C,)
        Certified lower bound on the clearance of each clear segment [m].
    """
    pieces = line_pieces(p0, p1)
    lengths = np.linalg.norm(p1 - p0, axis=1)
    counts = np.maximum(np.ceil(lengths / spacing), 1).astype(np.int64)
    piece = np.repeat(np.arange(len(p0)), counts + 1)
    offsets = np.cumsum(counts + 1) - (counts + 1)
    local = np.arange(len(piece)) - offsets[piece]
    tau = local / counts[piece]
    pos = pieces.position(piece, tau)
    cap = certificate_cap(gamma, spacing)
    dist = obstacles.distance(pos, cap)
    first = local < counts[piece]
    tables = shape_tables(obstacles, cap) if JIT_ENABLED else None
    if tables is not None:
        # Shapes only: the same refinement in one compiled call (segment_refinement).
        violated, certified = refine_lines(p0, p1, piece, tau, pos, dist, first, gamma, finest,
                                           max_pieces, cap, tables)
        return ~violated, certified
    cert = certify_samples(pieces, piece, tau, pos, None, dist, first, obstacles, gamma, finest,
                           stats=False, cap=cap, checkpoint=checkpoint, max_pieces=max_pieces)
    return ~cert.violated, cert.certified


@dataclass
class SampleGrid:
    """Verification samples of a chain: every piece from tau = 0 to tau = h."""

    piece: np.ndarray
    tau: np.ndarray
    pos: np.ndarray
    first: np.ndarray       # sample starts an interval
    s: np.ndarray           # arc length of each sample [m]


def sample_pieces(pieces: Pieces, spacing: float) -> SampleGrid:
    """Samples with chords <= ``spacing`` on every piece, and their arc lengths."""
    count = len(pieces)
    all_pieces = np.arange(count)
    # Parameter speed at the ends and at the Gauss nodes of each piece: the sample count follows
    # the fastest stretch, so the chords fit at once (the loop below is only a safety net).
    frac = np.r_[0.0, 0.5 * (GAUSS[5][0] + 1.0), 1.0]
    d1 = pieces.first(np.repeat(all_pieces, len(frac)), (pieces.h[:, None] * frac).ravel())
    speed = np.sqrt(np.einsum('ij,ij->i', d1, d1)).reshape(count, len(frac))
    parts = np.maximum(np.ceil(1.05 * pieces.h * speed.max(axis=1) / spacing), 1)
    parts = parts.astype(np.int64)
    for _ in range(8):
        piece = np.repeat(all_pieces, parts + 1)
        offsets = np.cumsum(parts + 1) - (parts + 1)
        local = np.arange(len(piece)) - offsets[piece]
        tau = pieces.h[piece] * (local / parts[piece])
        pos = pieces.position(piece, tau)
        first = local < parts[piece]
        ia = np.flatnonzero(first)
        step = pos[ia + 1] - pos[ia]
        chords = np.sqrt(np.einsum('ij,ij->i', step, step))
        worst = np.zeros(count)
        np.maximum.at(worst, piece[ia], chords)
        coarse = worst > spacing
        if not coarse.any():
            break
        # Uneven parameter speed inside a piece: refine the offending pieces proportionally.
        parts[coarse] = np.ceil(parts[coarse] * worst[coarse] / spacing * 1.05).astype(np.int64)
    steps = pieces.speed_integral(piece[ia], tau[ia], tau[ia + 1])
    # Each piece's first sample repeats the previous piece's last one: same arc length.
    increments = np.zeros(len(piece))
    increments[ia + 1] = steps
    return SampleGrid(piece, tau, pos, first, np.cumsum(increments))


def certify_pieces(pieces: Pieces, obstacles: ObstacleSet, gamma: float, delta: float,
                   skip: Optional[np.ndarray] = None,
                   checkpoint: Optional[Callable[[], None]] = None
                   ) -> Tuple[SampleGrid, Certificate]:
    """Certify clearance >= gamma along a chain of cubic pieces.

    Parameters
    ----------
    pieces : Pieces
    obstacles : ObstacleSet
    gamma : float
        Margin [m], >= 0.
    delta : float
        Grid spacing [m], > 0: samples are no more than :func:`check_spacing` apart (delta / 20,
        at least 5 mm) and intervals are subdivided down to ``delta * 1e-5``.
    skip : numpy.ndarray of bool, shape (P,), optional
        Pieces certified elsewhere (sampled for the statistics only).
    checkpoint : callable, optional
        Called between rounds of the work; it raises to abandon it.

    Returns
    -------
    grid : SampleGrid
        The verification samples.
    cert : Certificate
        ``violated`` per piece; ``min_clearance`` and ``min_point`` are exact (the smallest true
        clearance among the samples), ``piece_min`` exact wherever it is below the cap.
    """
    spacing = check_spacing(delta)
    grid = sample_pieces(pieces, spacing)
    if checkpoint is not None:
        checkpoint()
    curv = None if pieces.linear else np.linalg.norm(pieces.second(grid.piece, grid.tau), axis=1)
    cap = certificate_cap(gamma, spacing)
    dist = obstacles.distance(grid.pos, cap)
    cert = certify_samples(pieces, grid.piece, grid.tau, grid.pos, curv, dist, grid.first,
                           obstacles, gamma, delta * FINEST_SPACING_FRACTION, skip=skip,
                           cap=cap, checkpoint=checkpoint)
    if cert.min_clearance >= cap and not obstacles.is_empty():
        # Every sample is farther than the cap: ask again with wider caps, for the report.
        wider = cap
        exact = dist
        while np.min(exact) >= wider and wider < _WIDEST_REPORT_CAP:
            wider *= 4.0
            exact = obstacles.distance(grid.pos, wider)
        if np.min(exact) >= wider:
            exact = np.asarray(obstacles.distance(grid.pos))
        best = int(np.argmin(exact))
        cert.min_clearance = float(exact[best])
        cert.min_point = grid.pos[best].copy()
    return grid, cert


@dataclass(frozen=True, eq=False)
class SegmentCertificate:
    """Outcome of :func:`certify_segments`.

    Attributes
    ----------
    clear : numpy.ndarray of bool, shape (N,)
        True where clearance >= the margin is certified on the whole segment.
    bound : numpy.ndarray, shape (N,)
        Certified lower bound on each clear segment's clearance [m] (capped: at most the
        margin plus the cap's slack); meaningless where not clear.
    """

    clear: np.ndarray
    bound: np.ndarray


@dataclass(frozen=True, eq=False)
class PolylineCertificate:
    """Outcome of :func:`certify_polyline`.

    Attributes
    ----------
    clear : bool
        True when every segment is certified clear.
    first_blocked : int
        Index of the first segment that is not certified (-1 when clear); segment ``i`` joins
        points ``i`` and ``i + 1``.
    bound : float
        Smallest certified clearance bound over the segments when clear [m] (+inf without
        obstacles or segments); -inf when not clear.
    """

    clear: bool
    first_blocked: int
    bound: float


def check_margins(margin: float, resolution: float,
                  margin_name: str = 'margin') -> Tuple[float, float]:
    """``(gamma, delta)`` as floats, checked: gamma finite and >= 0, delta finite and > 0 [m].

    Raises
    ------
    InvalidInputError
        Naming the argument (``margin_name`` for gamma) and the value.
    """
    return (check_non_negative(margin_name, margin, 'm'),
            check_positive('resolution', resolution, 'm'))


def _points(value, name: str) -> np.ndarray:
    """``value`` as rows of three numbers [m]; 3 N numbers in any shape are N rows."""
    try:
        rows = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return check_path(name, value)  # refused, naming what it got
    return check_path(name, rows.reshape(-1, 3) if rows.size % 3 == 0 else rows,
                      allow_empty=True)


def certify_segments(obstacles: ObstacleSet, starts, ends, margin: float,
                     resolution: float) -> SegmentCertificate:
    """Certify that straight segments ``starts[i] -> ends[i]`` keep ``margin`` everywhere.

    Parameters
    ----------
    obstacles : ObstacleSet
    starts, ends : array_like, shape (N, 3)
        Segment ends [m].
    margin : float
        Required clearance gamma [m], >= 0. With 0 a segment touching an obstacle is refused.
    resolution : float
        Length scale delta [m], > 0: intervals are subdivided down to ``delta * 1e-5``.

    Returns
    -------
    SegmentCertificate
    """
    gamma, delta = check_margins(margin, resolution)
    p0 = _points(starts, 'starts')
    p1 = _points(ends, 'ends')
    if p0.shape != p1.shape:
        raise InvalidInputError(f'starts and ends must have the same shape, got {p0.shape} '
                                f'and {p1.shape}')
    if len(p0) == 0:
        return SegmentCertificate(np.zeros(0, dtype=bool), np.zeros(0))
    if obstacles.is_empty():
        return SegmentCertificate(np.ones(len(p0), dtype=bool), np.full(len(p0), np.inf))
    clear, bound = segments_clear(p0, p1, obstacles, gamma, SEGMENT_SPACING,
                                  delta * FINEST_SPACING_FRACTION)
    return SegmentCertificate(clear, bound)


def certify_polyline(obstacles: ObstacleSet, points, margin: float,
                     resolution: float) -> PolylineCertificate:
    """Certify that the polyline through ``points`` keeps ``margin`` along its whole length.

    Parameters
    ----------
    obstacles : ObstacleSet
    points : array_like, shape (M, 3)
        Vertices [m]; a single point is checked as a point.
    margin, resolution : float
        As for :func:`certify_segments` [m].

    Returns
    -------
    PolylineCertificate
    """
    gamma, delta = check_margins(margin, resolution)
    vertices = _points(points, 'points')
    if len(vertices) == 0 or obstacles.is_empty():
        return PolylineCertificate(True, -1, math.inf)
    if len(vertices) == 1:
        d = float(obstacles.distance(vertices[0]))
        ok = d >= gamma and d > 0.0
        return PolylineCertificate(ok, -1 if ok else 0, d if ok else -math.inf)
    cert = certify_segments(obstacles, vertices[:-1], vertices[1:], gamma, delta)
    blocked = np.flatnonzero(~cert.clear)
    if len(blocked):
        return PolylineCertificate(False, int(blocked[0]), -math.inf)
    return PolylineCertificate(True, -1, float(np.min(cert.bound)))
