"""Certified turn regions: the turn triangle at a waypoint and the filled-triangle certificate.

Every yes/no goes through the clearance engine
(:func:`~uav_global_planner.core.path.clearance.certify_segments`), which certifies whole segments,
not samples.
"""

import math
from typing import Tuple

import numpy as np

from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path.clearance import certify_segments

#: Largest inradius of the small triangles of a certified turn region [m].
TURN_CELL_INRADIUS = 0.01
_MAX_TURN_SUBDIVISION = 400


def unit_vector(vector: np.ndarray) -> np.ndarray:
    """``vector`` divided by its length (not zero)."""
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
    inradius = float(area2 / perimeter) if perimeter > 0.0 else 0.0
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
    a = corner + radius * unit_vector(np.asarray(before, dtype=np.float64) - corner)
    b = corner + radius * unit_vector(np.asarray(after, dtype=np.float64) - corner)
    return np.stack([a, corner, b])
