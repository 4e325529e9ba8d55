"""Line-of-sight shortcutting of a grid-node path, every kept segment certified.

The first step of :mod:`uav_global_planner.core.path.smoothing`: from each kept node, jump to a far
later node whose straight segment is certified (by
:func:`~uav_global_planner.core.path.clearance.segments_clear`, on the whole segment, not only at
samples) to keep clearance >= gamma. Where not even the next node is visible (the raw edge dips
below gamma, by less than ``delta * sqrt(3) / 2``), a detour vertex pushed off the obstacle is
inserted if its two segments certify. The result is the *shortcut polyline* the spline follows.

Also here: the checks and clean-up of the waypoint chain both steps share (shape, finiteness,
consecutive duplicates, indices of kept via-points).
"""

import math
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.checks import check_path
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path.clearance import (certificate_cap, check_margins,
                                                    CHECK_SPACING_FRACTION,
                                                    FINEST_SPACING_FRACTION, SEGMENT_SPACING,
                                                    segments_clear)

#: First sampling of shortcut candidate segments [m] (the engine's segment spacing).
SHORTCUT_SPACING = SEGMENT_SPACING
#: A shortcut past the next node must keep gamma plus this many delta: it bounds the work of
#: certifying a jump to (length / slack) intervals where the farthest visible node grazes.
SHORTCUT_SLACK_FRACTION = 0.02
#: ... and at least this much [m] (0.02 delta at delta = 0.1 m): on finer grids the work of a
#: grazing jump then follows its length, not the grid's resolution.
MIN_SHORTCUT_SLACK = 0.002
#: Consecutive waypoints closer than this are merged [m]; the chord parameter needs a gap.
DUPLICATE_TOLERANCE = 1e-9

# A jump past the next node is refused when certifying one of its first intervals would take
# more than this many pieces (a segment along an obstacle face barely above gamma plus the
# slack would otherwise take its length over that excess): a shorter jump is taken instead.
_JUMP_MAX_PIECES = 256
# Up to this many nodes ahead are all certified in one batch (exact farthest visible).
_SHORTCUT_BATCH = 64
# Nodes this close ahead are all certified in the first batch of a long path.
_SHORTCUT_NEAR = 16
# Powers of two certified per batch when galloping ahead.
_GALLOP_BATCH = 4
# Nodes certified per narrowing round of the shortcut search (one batch each).
_SHORTCUT_PROBES = 8


def dedupe_waypoints(path: np.ndarray) -> np.ndarray:
    """Drop waypoints that repeat their predecessor; the first and last stay exact."""
    if len(path) < 2:
        return path
    step = np.linalg.norm(np.diff(path, axis=0), axis=1)
    keep = np.r_[True, step > DUPLICATE_TOLERANCE]
    out = path[keep].copy()
    out[-1] = path[-1]
    if len(out) > 1 and np.linalg.norm(out[-1] - out[-2]) <= DUPLICATE_TOLERANCE:
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
    slack = max(SHORTCUT_SLACK_FRACTION * finest / FINEST_SPACING_FRACTION, MIN_SHORTCUT_SLACK)
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
                                      checkpoint, max_pieces=_JUMP_MAX_PIECES)
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


def kept_indices(points: np.ndarray, path: np.ndarray, keep: Sequence[int]) -> np.ndarray:
    """``keep`` (indices of ``points``) as indices of the deduplicated ``path``."""
    if not len(keep):
        return np.zeros(0, dtype=np.int64)
    wanted = np.asarray(keep, dtype=np.int64)
    if np.any((wanted < 0) | (wanted >= len(points))):
        raise InvalidInputError(f'keep indices must lie in [0, {len(points) - 1}], got '
                                f'{wanted.tolist()}')
    # dedupe_waypoints keeps the first of each run of equal waypoints (and the exact last point).
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    new_index = np.cumsum(np.r_[True, step > DUPLICATE_TOLERANCE]) - 1
    return np.unique(np.clip(new_index[wanted], 0, len(path) - 1))


def vertex_indices(vertices: np.ndarray, path: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Indices in ``vertices`` of the ``path`` waypoints ``kept`` (which shortcutting keeps)."""
    if not len(kept):
        return np.zeros(0, dtype=np.int64)
    hits = [np.flatnonzero(np.all(vertices == path[k], axis=1)) for k in kept]
    return np.asarray([int(h[0]) for h in hits if len(h)], dtype=np.int64)


def shortcut_legs(path: np.ndarray, keep: np.ndarray, obstacles: ObstacleSet, gamma: float,
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
    ``delta * 1e-5``, all candidate segments of one anchor in one batch (a single distance query
    per round, or one compiled call for obstacles that are shapes only).
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
    points = as_waypoints(path)
    gamma, delta = check_margins(safety_margin, resolution, 'safety_margin')
    points = dedupe_waypoints(points)
    if len(points) < 3:
        return points.copy()
    vertices, _, _ = _shortcut(points, obstacles, gamma, delta)
    return vertices


def as_waypoints(path) -> np.ndarray:
    """``path`` as a finite float64 array of shape (N, 3), N >= 1 [m].

    Raises
    ------
    InvalidInputError
        For another shape, non-numbers, NaN or inf.
    """
    return check_path('path', path)
