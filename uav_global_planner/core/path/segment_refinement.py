"""The clearance certificate's refinement of straight segments, as one compiled loop.

:func:`~uav_global_planner.core.path.clearance.certify_samples` refines every interval of a
batch in rounds of array operations, one distance query per round: right for any obstacle set
(point clouds and height fields are queried outside compiled code), but each round costs some
forty array operations, and shortcutting certifies a few small batches per kept vertex. When the
obstacles are shapes only (spheres, boxes, prisms, cylinders, fences: every query a compiled
loop), :func:`refine_lines` does the same refinement of straight segments in a single compiled
call, interval by interval, and stops a segment at its first definite violation.

Same certificate, same decisions: an interval is accepted when ``(d(a) + d(b) - |ab|) / 2 >=
gamma``, refused when it is below and the interval is shorter than ``finest`` or would need more
than ``max_pieces`` pieces, and otherwise cut into the same children, whose samples are the same
points with the same capped distances (the very kernels of
:meth:`~uav_global_planner.core.map.obstacles.ObstacleSet.distance`). A segment is clear when no
interval of its subdivision is refused and no sample is below gamma, whichever order the
intervals are visited in, so the verdicts and the certified bounds equal those of the rounds.
"""

import math
from typing import Optional, Tuple

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.spatial_index import (_min_gap_all, _min_gap_indexed,
                                                       BRUTE_FORCE_SHAPES)

# Most children an interval is cut into (as in certify_samples).
MAX_SUBDIVISION = 32


def shape_tables(obstacles: ObstacleSet, cap: float) -> Optional[Tuple]:
    """The arguments of the compiled capped query of ``obstacles``, or None when they hold
    points or height fields (queried outside compiled code).

    The tuple: kind, prm, verts, vstart, then the lattice (always, origin, cell, dims, start,
    items) and whether to use it, as :meth:`ObstacleSet.distance` chooses for ``cap``.
    """
    if len(obstacles.points) or obstacles.height_fields or not len(obstacles.shape_kind):
        return None
    kind, prm = obstacles.shape_kind, obstacles.shape_params
    verts, vstart = obstacles.shape_vertices, obstacles.shape_vstart
    if len(kind) > BRUTE_FORCE_SHAPES:
        index = obstacles._index(cap)    # the set's own lattice, built once per reach
        return (kind, prm, verts, vstart, index.always, index.origin, index.cell, index.dims,
                index._start, index._items, True)
    empty = np.zeros(0, dtype=np.int64)
    return (kind, prm, verts, vstart, empty, np.zeros(3), 1.0, np.ones(3, dtype=np.int64),
            np.zeros(2, dtype=np.int64), empty, False)


@njit
def _capped(points, cap, kind, prm, verts, vstart, always, origin, cell, dims, start, items,
            indexed, out):  # pragma: no cover - compiled
    """``ObstacleSet.distance(points, cap)`` of a set of shapes only, into ``out``."""
    if indexed:
        _min_gap_indexed(points, kind, prm, verts, vstart, always, origin, cell, dims, start,
                         items, cap, out)
    else:
        out[:] = np.inf
        _min_gap_all(points, kind, prm, verts, vstart, out)
    for n in range(out.shape[0]):
        if out[n] > cap:
            out[n] = cap


@njit
def _refine(a, direction, ta, tb, pa, pb, da, db, gamma, finest, max_pieces, cap, kind, prm,
            verts, vstart, always, origin, cell, dims, start, items,
            indexed):  # pragma: no cover - compiled
    """Certify the interval ``[ta, tb]`` of the segment ``a + t * direction`` (ends ``pa``,
    ``pb`` [m] at distances ``da``, ``db`` [m]); returns (clear, smallest accepted bound [m])."""
    best = math.inf
    # Intervals left: parameters, end positions, end distances.
    stack = [(ta, tb, pa[0], pa[1], pa[2], pb[0], pb[1], pb[2], da, db)]
    while len(stack):
        t0, t1, x0, y0, z0, x1, y1, z1, d0, d1 = stack.pop()
        dx = x1 - x0
        dy = y1 - y0
        dz = z1 - z0
        # Summed in the order of numpy's einsum over three columns (certify_samples): same bits.
        chord = math.sqrt((dx * dx + dz * dz) + dy * dy)
        bound = 0.5 * (d0 + d1 - chord)
        if bound >= gamma:
            best = min(best, bound)
            continue
        slack = d0 + d1 - 2.0 * gamma
        if chord <= finest or slack * max_pieces < chord:
            return False, best
        parts = MAX_SUBDIVISION
        if slack > 0.0:
            cut = math.ceil(chord / slack)
            if math.isfinite(cut):
                parts = int(min(max(cut, 2.0), float(MAX_SUBDIVISION)))
        taus = np.empty(parts + 1)
        points = np.empty((parts - 1, 3))
        taus[0] = t0
        taus[parts] = t1
        for j in range(1, parts):
            t = t0 + (t1 - t0) * (j / parts)
            taus[j] = t
            points[j - 1, 0] = a[0] + t * direction[0]
            points[j - 1, 1] = a[1] + t * direction[1]
            points[j - 1, 2] = a[2] + t * direction[2]
        dist = np.empty(parts - 1)
        _capped(points, cap, kind, prm, verts, vstart, always, origin, cell, dims, start, items,
                indexed, dist)
        for j in range(parts - 1):
            if dist[j] < gamma or dist[j] <= 0.0:
                return False, best
        # Children, the first on top of the stack (visited along the segment).
        for j in range(parts - 1, -1, -1):
            if j == 0:
                px, py, pz, e0 = x0, y0, z0, d0
            else:
                px, py, pz = points[j - 1, 0], points[j - 1, 1], points[j - 1, 2]
                e0 = dist[j - 1]
            if j == parts - 1:
                qx, qy, qz, e1 = x1, y1, z1, d1
            else:
                qx, qy, qz, e1 = points[j, 0], points[j, 1], points[j, 2], dist[j]
            stack.append((taus[j], taus[j + 1], px, py, pz, qx, qy, qz, e0, e1))
    return True, best


@njit
def _refine_all(p0, p1, piece, tau, pos, dist, first, gamma, finest, max_pieces, cap, kind,
                prm, verts, vstart, always, origin, cell, dims, start, items, indexed,
                violated, certified):  # pragma: no cover - compiled
    for g in range(piece.shape[0]):
        if dist[g] < gamma or dist[g] <= 0.0:
            violated[piece[g]] = True
    for g in range(piece.shape[0]):
        s = piece[g]
        if not first[g] or violated[s]:
            continue
        direction = p1[s] - p0[s]
        clear, best = _refine(p0[s], direction, tau[g], tau[g + 1], pos[g], pos[g + 1],
                              dist[g], dist[g + 1], gamma, finest, max_pieces, cap, kind, prm,
                              verts, vstart, always, origin, cell, dims, start, items, indexed)
        if best < certified[s]:
            certified[s] = best
        if not clear:
            violated[s] = True


def refine_lines(p0: np.ndarray, p1: np.ndarray, piece: np.ndarray, tau: np.ndarray,
                 pos: np.ndarray, dist: np.ndarray, first: np.ndarray, gamma: float,
                 finest: float, max_pieces: int, cap: float,
                 tables: Tuple) -> Tuple[np.ndarray, np.ndarray]:
    """Certify the straight segments ``p0[i] -> p1[i]`` from their first samples.

    Parameters
    ----------
    p0, p1 : numpy.ndarray, shape (C, 3)
        Segment ends [m].
    piece, tau, pos, dist, first
        The first samples, as for
        :func:`~uav_global_planner.core.path.clearance.certify_samples` (``tau`` in [0, 1],
        ``pos = p0 + tau * (p1 - p0)``, ``dist`` capped at ``cap``).
    gamma, finest, max_pieces, cap
        As for :func:`~uav_global_planner.core.path.clearance.certify_samples`.
    tables : tuple
        :func:`shape_tables` of the obstacles for ``cap``.

    Returns
    -------
    violated : numpy.ndarray of bool, shape (C,)
    certified : numpy.ndarray, shape (C,)
        Smallest accepted bound of each segment [m] (meaningless where violated).
    """
    violated = np.zeros(len(p0), dtype=bool)
    certified = np.full(len(p0), np.inf)
    _refine_all(np.ascontiguousarray(p0, dtype=np.float64),
                np.ascontiguousarray(p1, dtype=np.float64), piece.astype(np.int64), tau, pos,
                dist, first, float(gamma), float(finest), float(max_pieces), float(cap),
                *tables, violated, certified)
    return violated, certified
