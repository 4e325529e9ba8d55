"""Simple polygons in x-y: the outline of a prism zone or an inclusion fence, validated.

:func:`checked_polygon` refuses what no fence or zone can be: fewer than three distinct
vertices, coinciding consecutive vertices, a zero area, an edge folding back onto the previous
one, and any two edges that cross or touch (a self-intersecting polygon), naming the vertices
or edges at fault.
"""

from typing import Any

import numpy as np

from uav_global_planner.core.errors import InvalidInputError

#: Most vertices of one polygon: validation compares every pair of edges.
MAX_POLYGON_VERTICES = 4096


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles (a, b, c), broadcast [m^2]."""
    return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))


def _on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """For collinear a, b, p: whether p lies on the closed segment ab."""
    return ((np.minimum(a[..., 0], b[..., 0]) <= p[..., 0])
            & (p[..., 0] <= np.maximum(a[..., 0], b[..., 0]))
            & (np.minimum(a[..., 1], b[..., 1]) <= p[..., 1])
            & (p[..., 1] <= np.maximum(a[..., 1], b[..., 1])))


def checked_polygon(value: Any, name: str = 'polygon') -> np.ndarray:
    """A simple polygon as an (V, 2) float array [m], or a message naming the problem.

    A closing vertex equal to the first is dropped. Refused: fewer than three distinct
    vertices, consecutive vertices that coincide, a zero area, an edge folding back onto the
    previous one, and any two edges that cross or touch (a self-intersecting polygon).

    Raises
    ------
    InvalidInputError
        Starting with ``name``.
    """
    try:
        points = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name}: must be a list of [x, y] pairs') from None
    if points.ndim != 2 or points.shape[1] != 2:
        raise InvalidInputError(f'{name}: must be a list of [x, y] pairs, got shape '
                                f'{tuple(points.shape)}')
    if not np.all(np.isfinite(points)):
        raise InvalidInputError(f'{name}: vertices must be finite; found NaN or inf')
    if len(points) > 1 and np.array_equal(points[0], points[-1]):
        points = points[:-1]
    count = len(points)
    if count < 3:
        raise InvalidInputError(f'{name}: needs at least 3 distinct vertices, got {count}')
    if count > MAX_POLYGON_VERTICES:
        raise InvalidInputError(f'{name}: has {count} vertices; at most '
                                f'{MAX_POLYGON_VERTICES} are supported')
    nxt = np.roll(points, -1, axis=0)
    same = np.flatnonzero(np.all(points == nxt, axis=1))
    if len(same):
        k = int(same[0])
        raise InvalidInputError(f'{name}: vertices {k} and {(k + 1) % count} coincide '
                                f'({points[k].tolist()})')
    # All vertices on one line (to rounding): no area whatever the order.
    extent = float(np.max(np.ptp(points, axis=0)))
    far = int(np.argmax(np.linalg.norm(points - points[0], axis=1)))
    spread = float(np.max(np.abs(_orientation(points[0], points[far], points))))
    if spread <= 1e-12 * extent * extent:
        raise InvalidInputError(f'{name}: is degenerate: its vertices lie on one line')
    # An edge folding back onto the previous one: the turn at the shared vertex is a reversal.
    prev = np.roll(points, 1, axis=0)
    turn = _orientation(prev, points, nxt)
    back = np.einsum('ij,ij->i', prev - points, nxt - points)
    folded = np.flatnonzero((turn == 0.0) & (back > 0.0))
    if len(folded):
        k = int(folded[0])
        raise InvalidInputError(f'{name}: is self-intersecting: edges {(k - 1) % count} and {k} '
                                f'fold back onto each other at vertex {k} '
                                f'{points[k].tolist()}')
    # Every pair of edges that share no vertex must not meet at all.
    first, second = np.triu_indices(count, 2)
    keep = ~((first == 0) & (second == count - 1))
    first, second = first[keep], second[keep]
    a, b, c, d = points[first], nxt[first], points[second], nxt[second]
    o1, o2 = _orientation(a, b, c), _orientation(a, b, d)
    o3, o4 = _orientation(c, d, a), _orientation(c, d, b)
    meet = ((np.sign(o1) * np.sign(o2) < 0) & (np.sign(o3) * np.sign(o4) < 0))
    meet |= (o1 == 0) & _on_segment(a, b, c)
    meet |= (o2 == 0) & _on_segment(a, b, d)
    meet |= (o3 == 0) & _on_segment(c, d, a)
    meet |= (o4 == 0) & _on_segment(c, d, b)
    crossing = np.flatnonzero(meet)
    if len(crossing):
        k = int(crossing[0])
        raise InvalidInputError(f'{name}: is self-intersecting: edges {int(first[k])} and '
                                f'{int(second[k])} cross or touch')
    area = 0.5 * float(np.sum(points[:, 0] * nxt[:, 1] - nxt[:, 0] * points[:, 1]))
    if abs(area) <= 1e-12 * extent * extent:
        raise InvalidInputError(f'{name}: is degenerate: its area is {abs(area):.3g} m^2')
    points = np.ascontiguousarray(points)
    points.setflags(write=False)
    return points
