"""Terrain and ground as solids: a height field and the exact Euclidean distance to it.

A :class:`HeightField` is a lattice of surface heights in the map frame (ENU, metres). Its
surface h(x, y) is triangulated: each lattice cell is split along its diagonal from node (i, j)
to node (i + 1, j + 1), so h is continuous and linear on each triangle. The solid is

- side ``'below'``: {(x, y) in the lattice extent, z <= h(x, y)} (terrain, an AGL floor);
- side ``'above'``: {(x, y) in the lattice extent, z >= h(x, y)} (an AGL ceiling).

It exists only over the lattice's x/y extent: it is the union of triangular columns (a triangle
on top, three vertical faces, unbounded downwards; upwards for ``'above'``, which is the mirror
image in z and is evaluated as such).

The distance
------------
For a point inside the solid the distance is 0. Otherwise the nearest point of the solid lies on
its boundary: the top triangles, or the vertical walls along the lattice's outer edges (the
faces between two columns are inside the union, so the minimum over every column's top and
faces equals the minimum over the top triangles and the outer walls). So

    d(p) = min(d(p, top triangles), d(p, outer walls), u(p))

where u(p), the distance to one known point of the solid (straight below p, or below the nearest
point of the extent), is an upper bound that also limits the search: only the cells within
min(u(p), cap) horizontally of p are visited (and a cell is skipped when a lower bound of its
distance already exceeds the best found), so the cost of a query follows its cap and the local
relief, not the size of the lattice. The distance to a triangle is the distance to its plane
when the foot of the perpendicular falls inside it, else to the nearest of its edges; the
distance to a wall is the horizontal distance to it when p is below its top edge at the nearest
point, and its top edge otherwise (an edge of a top triangle). All of it is one compiled
function (:func:`_point_distance`) that serves both the distance queries and the grid
inflation's per-column limits (:func:`column_limits`), so the grid and the clearance certificate
agree to the bit. The value does not depend on the cap below it (cells are skipped only when
certainly farther than the best found), so a capped and an uncapped query agree as well.
"""

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import math
import os
from typing import Callable, Optional, Tuple

import numpy as np

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import JIT_ENABLED, njit

#: The two sides a height field's solid may lie on.
SIDES = ('below', 'above')
# Relative and absolute slack of the lower bound that lets a cell be skipped: a skipped cell's
# computed distance is then certainly above the best one, whatever the rounding, so skipping
# never changes the result (which therefore does not depend on the cap or the visit order).
_SKIP_RELATIVE = 1e-9
_SKIP_ABSOLUTE = 1e-12
# Slack of the cell ranges a query visits, in cells and relative to the coordinates: far above
# the rounding of the index arithmetic, so every cell within the reach is visited.
_RANGE_SLACK_CELLS = 1e-6
_RANGE_SLACK_RELATIVE = 1e-12
# Most threads the column limits of a large node box are computed on, and the columns of one
# piece of that work (a few milliseconds).
_THREADS = 4
_COLUMNS_PER_PIECE = 1 << 14


@dataclass(frozen=True, eq=False)
class HeightField:
    """A triangulated height field and the solid below (or above) it.

    Attributes
    ----------
    origin : numpy.ndarray, shape (2,)
        x, y of the sample ``heights[0, 0]`` in the map frame [m].
    spacing : numpy.ndarray, shape (2,)
        Sample spacing dx, dy [m], > 0.
    heights : numpy.ndarray, shape (ny, nx)
        Surface heights [m], finite, at least 2 x 2; ``heights[j, i]`` is at
        ``(origin[0] + i * dx, origin[1] + j * dy)``. Each cell is split along the diagonal
        from node (i, j) to node (i + 1, j + 1).
    side : str
        ``'below'``: the solid is z <= h(x, y) (terrain, an AGL floor); ``'above'``: the solid
        is z >= h(x, y) (an AGL ceiling).
    label : str
        Name in messages and reports.

    Raises
    ------
    InvalidInputError
        For non-finite or wrongly shaped arrays, a spacing <= 0, or an unknown side.
    """

    origin: np.ndarray
    spacing: np.ndarray
    heights: np.ndarray
    side: str = 'below'
    label: str = 'terrain'

    def __post_init__(self) -> None:
        origin = _finite_array(self.origin, 'height field origin')
        spacing = _finite_array(self.spacing, 'height field spacing')
        heights = _finite_array(self.heights, 'height field heights')
        if origin.shape != (2,):
            raise InvalidInputError(
                f'height field origin must be [x, y], got shape {tuple(origin.shape)}')
        if spacing.shape != (2,):
            raise InvalidInputError(
                f'height field spacing must be [dx, dy], got shape {tuple(spacing.shape)}')
        if not np.all(spacing > 0.0):
            raise InvalidInputError(
                f'height field spacing must be > 0 m, got {spacing.tolist()}')
        if heights.ndim != 2 or heights.shape[0] < 2 or heights.shape[1] < 2:
            raise InvalidInputError(
                'height field heights must be a 2D array of at least 2 x 2 samples, got shape '
                f'{tuple(heights.shape)}')
        if self.side not in SIDES:
            raise InvalidInputError(
                f'height field side must be one of {", ".join(SIDES)}, got {self.side!r}')
        if not isinstance(self.label, str):
            raise InvalidInputError(f'height field label must be a string, got {self.label!r}')
        far = origin + (np.asarray(heights.shape[::-1], dtype=np.float64) - 1.0) * spacing
        if not np.all(np.isfinite(far)):
            raise InvalidInputError('height field extent must be finite')
        # The solid, seen from below: 'above' is evaluated as the mirror image in z.
        surface = np.ascontiguousarray(heights if self.side == 'below' else -heights)
        for array in (origin, spacing, heights, surface):
            array.setflags(write=False)
        object.__setattr__(self, 'origin', origin)
        object.__setattr__(self, 'spacing', spacing)
        object.__setattr__(self, 'heights', heights)
        object.__setattr__(self, '_surface', surface)

    @property
    def extent(self) -> Tuple[np.ndarray, np.ndarray]:
        """The lattice's x/y extent: lower and upper corners [m], shape (2,) each."""
        count = np.asarray(self.heights.shape[::-1], dtype=np.float64) - 1.0
        return self.origin.copy(), self.origin + count * self.spacing

    @property
    def sign(self) -> float:
        """+1 for side ``'below'``, -1 for ``'above'`` (the z mirror of the evaluation)."""
        return 1.0 if self.side == 'below' else -1.0

    def height_at(self, xy) -> np.ndarray:
        """Surface height h(x, y) under points [m], NaN outside the lattice's extent.

        Parameters
        ----------
        xy : array_like, shape (..., 2) (a trailing 3rd column, z, is ignored)
            Positions [m].

        Returns
        -------
        numpy.ndarray, shape (...)
        """
        p = np.asarray(xy, dtype=np.float64)
        if p.ndim == 0 or p.shape[-1] not in (2, 3):
            raise InvalidInputError(f'height_at needs (..., 2) positions, got shape {p.shape}')
        flat = np.ascontiguousarray(p[..., :2].reshape(-1, 2))
        out = np.empty(len(flat))
        _heights_at(flat, self.heights, float(self.origin[0]), float(self.origin[1]),
                    float(self.spacing[0]), float(self.spacing[1]), out)
        return out.reshape(p.shape[:-1])

    def distance(self, points, cap: float = math.inf) -> np.ndarray:
        """Exact Euclidean distance from points to the solid [m], 0 inside it.

        Parameters
        ----------
        points : array_like, shape (3,) or (..., 3)
            Query positions [m].
        cap : float
            As :meth:`~uav_global_planner.core.map.obstacles.ObstacleSet.distance`: distances at
            or above ``cap`` (> 0) are reported as ``cap``; +inf gives every distance exactly.

        Returns
        -------
        numpy.ndarray, shape (...)
        """
        cap = float(cap)
        if not cap > 0.0:
            raise InvalidInputError(f'distance cap must be > 0 m, got {cap}')
        p = np.asarray(points, dtype=np.float64)
        if p.ndim == 0 or p.shape[-1] != 3:
            raise InvalidInputError(f'distance needs (..., 3) positions, got shape {p.shape}')
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = np.empty(len(flat))
        _distances(flat, self.surface_view(), float(self.origin[0]), float(self.origin[1]),
                   float(self.spacing[0]), float(self.spacing[1]), self.sign, cap, out)
        return out.reshape(p.shape[:-1])

    def surface_view(self) -> np.ndarray:
        """The heights as the kernels read them: negated for side ``'above'`` [m]."""
        surface: np.ndarray = getattr(self, '_surface')
        return surface


def flat_ground(height: float, lo_xy, hi_xy, side: str = 'below',
                label: str = 'ground') -> HeightField:
    """A level surface at ``height`` over the rectangle [lo_xy, hi_xy] (one 2 x 2 lattice).

    Parameters
    ----------
    height : float
        Surface height in the map frame [m].
    lo_xy, hi_xy : array_like, shape (2,)
        Corners of the extent [m], ``lo < hi`` on both axes.
    side, label : str
        As :class:`HeightField`.
    """
    lo = _finite_array(lo_xy, 'ground extent lower corner').reshape(-1)
    hi = _finite_array(hi_xy, 'ground extent upper corner').reshape(-1)
    if lo.shape != (2,) or hi.shape != (2,):
        raise InvalidInputError('ground extent corners must be [x, y] pairs')
    if not np.all(lo < hi):
        raise InvalidInputError(
            f'ground extent must have lo < hi on x and y, got {lo.tolist()} and {hi.tolist()}')
    level = _finite_array(height, 'ground height')
    if level.shape != ():
        raise InvalidInputError(f'ground height must be a number, got {height!r}')
    return HeightField(lo, hi - lo, np.full((2, 2), float(level)), side=side, label=label)


def column_limits(field: HeightField, origin: np.ndarray, delta: float, first: np.ndarray,
                  last: np.ndarray, gamma: float,
                  checkpoint: Optional[Callable[[], None]] = None) -> np.ndarray:
    """Where the nodes within gamma of the solid end, for each column of a node box.

    The grid's node (i, j, k) is at ``origin + (i, j, k) * delta`` (formed as in the inflation
    kernels). Along a column the distance to a side-``'below'`` solid never decreases with z
    (the solid is closed downwards: shifting a nearest point down by as much as the query
    moves down keeps the gap), so the nodes within gamma are the ones under a limit. It is
    searched for from a guess (the surface height plus gamma), galloping to a bracket and
    bisecting it, every node tested with :func:`_point_distance` itself (so a node is within
    gamma here iff :meth:`HeightField.distance` of its position is <= gamma); side
    ``'above'`` is the mirror image. About two distance evaluations a column.

    Parameters
    ----------
    field : HeightField
    origin : numpy.ndarray, shape (3,)
        Position of node (0, 0, 0) [m].
    delta : float
        Node spacing [m].
    first, last : numpy.ndarray of int, shape (3,)
        The node box, inclusive (non-empty).
    gamma : float
        Margin [m], >= 0.
    checkpoint : callable, optional
        Called between pieces of the work (a few milliseconds each); what it raises stops the
        work and is raised here.

    Returns
    -------
    numpy.ndarray of int64, shape (last[0] - first[0] + 1, last[1] - first[1] + 1)
        For side ``'below'``, the first k in ``first[2] .. last[2] + 1`` whose node is farther
        than gamma: nodes ``first[2] .. limit - 1`` are within gamma. For side ``'above'``, the
        first k within gamma: nodes ``limit .. last[2]`` are within gamma.
    """
    lo = np.asarray(first, dtype=np.int64)
    hi = np.asarray(last, dtype=np.int64)
    out = np.empty((int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)), dtype=np.int64)
    # Any cap above gamma decides "<= gamma" exactly and keeps each evaluation local.
    cap = float(gamma) + float(delta)
    start = np.ascontiguousarray(origin, dtype=np.float64)

    def run(rows: range) -> None:
        if len(rows):
            part = lo.copy()
            part[0] += rows.start
            _column_limits(field.surface_view(), float(field.origin[0]),
                           float(field.origin[1]), float(field.spacing[0]),
                           float(field.spacing[1]), field.sign, start, float(delta), part, hi,
                           float(gamma), cap, out[rows.start:rows.stop])

    # Pieces of about _COLUMNS_PER_PIECE columns (whole rows), the checkpoint between them; the
    # kernel releases the interpreter lock, so many pieces are shared among threads.
    rows_per_piece = max(1, _COLUMNS_PER_PIECE // max(out.shape[1], 1))
    pieces = [range(r, min(r + rows_per_piece, len(out)))
              for r in range(0, len(out), rows_per_piece)]
    workers = min(_THREADS, _cpu_count(), len(pieces) // 2) if JIT_ENABLED else 1
    if workers < 2:
        for rows in pieces:
            if checkpoint is not None:
                checkpoint()
            run(rows)
        return out
    pool = ThreadPoolExecutor(max_workers=workers)
    try:
        for done in [pool.submit(run, rows) for rows in pieces]:
            if checkpoint is not None:
                checkpoint()
            done.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return out


def _cpu_count() -> int:
    """Processors this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _finite_array(value, name: str) -> np.ndarray:
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name} must be numbers, got {value!r}') from None
    if not np.all(np.isfinite(array)):
        raise InvalidInputError(f'{name} must be finite; found NaN or inf')
    return array


# --- compiled kernels -----------------------------------------------------------------------

@njit(error_model='numpy')
def _height(hs, x0, y0, dx, dy, x, y):  # pragma: no cover - compiled
    """h(x, y) of the triangulated surface ``hs`` at a point of its extent [m]."""
    nx = hs.shape[1]
    ny = hs.shape[0]
    fu = (x - x0) / dx
    fv = (y - y0) / dy
    i = min(max(int(math.floor(fu)), 0), nx - 2)
    j = min(max(int(math.floor(fv)), 0), ny - 2)
    u = fu - i
    v = fv - j
    h00 = hs[j, i]
    if u >= v:  # triangle (i, j), (i + 1, j), (i + 1, j + 1)
        return h00 + u * (hs[j, i + 1] - h00) + v * (hs[j + 1, i + 1] - hs[j, i + 1])
    # triangle (i, j), (i, j + 1), (i + 1, j + 1)
    return h00 + v * (hs[j + 1, i] - h00) + u * (hs[j + 1, i + 1] - hs[j + 1, i])


@njit(error_model='numpy')
def _heights_at(xy, hs, x0, y0, dx, dy, out):  # pragma: no cover - compiled
    x1 = x0 + (hs.shape[1] - 1) * dx
    y1 = y0 + (hs.shape[0] - 1) * dy
    for n in range(xy.shape[0]):
        x = xy[n, 0]
        y = xy[n, 1]
        if x0 <= x <= x1 and y0 <= y <= y1:
            out[n] = _height(hs, x0, y0, dx, dy, x, y)
        else:
            out[n] = math.nan


@njit(error_model='numpy')
def _distances(points, hs, x0, y0, dx, dy, sign, cap, out):  # pragma: no cover - compiled
    for n in range(points.shape[0]):
        out[n] = _point_distance(hs, x0, y0, dx, dy, points[n, 0], points[n, 1],
                                 sign * points[n, 2], cap)


@njit(error_model='numpy')
def _segment_sq(px, py, pz, ax, ay, az, bx, by, bz):  # pragma: no cover - compiled
    """Squared distance from p to the segment ab [m^2]."""
    ex = bx - ax
    ey = by - ay
    ez = bz - az
    wx = px - ax
    wy = py - ay
    wz = pz - az
    t = (wx * ex + wy * ey + wz * ez) / (ex * ex + ey * ey + ez * ez)
    t = min(max(t, 0.0), 1.0)
    qx = wx - t * ex
    qy = wy - t * ey
    qz = wz - t * ez
    return qx * qx + qy * qy + qz * qz


@njit(error_model='numpy')
def _face_sq(x, y, z, xa, ya, za, gx, gy, idx, idy, lower):  # pragma: no cover - compiled
    """Squared distance from p to the plane z = za + gx (x - xa) + gy (y - ya) when the foot of
    the perpendicular falls in the cell's ``lower`` (0 <= v <= u <= 1) or upper
    (0 <= u <= v <= 1) triangle, in cell units u, v from corner (xa, ya) (``idx``, ``idy``:
    the inverse cell size [1/m]); -1 otherwise."""
    e = z - (za + gx * (x - xa) + gy * (y - ya))
    inv = 1.0 / (1.0 + gx * gx + gy * gy)
    s = e * inv
    u = (x + gx * s - xa) * idx
    v = (y + gy * s - ya) * idy
    if lower:
        inside = 0.0 <= v <= u <= 1.0
    else:
        inside = 0.0 <= u <= v <= 1.0
    if inside:
        return e * e * inv
    return -1.0


@njit(error_model='numpy')
def _wall_sq(perp, t, length, z, ha, hb):  # pragma: no cover - compiled
    """Squared distance to an outer wall (vertical, under the edge from height ``ha`` at t = 0
    to ``hb`` at t = ``length``) from a point ``perp`` off its plane at abscissa t and height
    z, when the nearest point is on the wall below its top edge; -1 otherwise (the top edge
    then is nearest, an edge of a top triangle)."""
    tc = min(max(t, 0.0), length)
    if z > ha + (hb - ha) * (tc / length):
        return -1.0
    dt = t - tc
    return perp * perp + dt * dt


@njit(error_model='numpy', inline='always')
def _nearer(best_sq, candidate):  # pragma: no cover - compiled
    """``candidate`` when it is a squared distance (>= 0; -1 stands for none) below
    ``best_sq``, else ``best_sq``."""
    if 0.0 <= candidate < best_sq:
        return candidate
    return best_sq


@njit(error_model='numpy')
def _cell_sq(hs, x0, y0, dx, dy, i, j, x, y, z, best_sq):  # pragma: no cover - compiled
    """Smallest squared distance from p to the two top triangles of cell (i, j) and to its
    outer walls that p is outside of, or ``best_sq`` when not smaller [m^2]."""
    nx = hs.shape[1]
    ny = hs.shape[0]
    xa = x0 + i * dx
    xb = x0 + (i + 1) * dx
    ya = y0 + j * dy
    yb = y0 + (j + 1) * dy
    h00 = hs[j, i]
    h10 = hs[j, i + 1]
    h01 = hs[j + 1, i]
    h11 = hs[j + 1, i + 1]
    if i == 0 and x < xa:
        best_sq = _nearer(best_sq, _wall_sq(xa - x, y - ya, dy, z, h00, h01))
    if i == nx - 2 and x > xb:
        best_sq = _nearer(best_sq, _wall_sq(x - xb, y - ya, dy, z, h10, h11))
    if j == 0 and y < ya:
        best_sq = _nearer(best_sq, _wall_sq(ya - y, x - xa, dx, z, h00, h10))
    if j == ny - 2 and y > yb:
        best_sq = _nearer(best_sq, _wall_sq(y - yb, x - xa, dx, z, h01, h11))
    idx = 1.0 / dx
    idy = 1.0 / dy
    lower = _face_sq(x, y, z, xa, ya, h00, (h10 - h00) * idx, (h11 - h10) * idy, idx, idy,
                     True)
    upper = _face_sq(x, y, z, xa, ya, h00, (h11 - h01) * idx, (h01 - h00) * idy, idx, idy,
                     False)
    best_sq = _nearer(_nearer(best_sq, lower), upper)
    # A foot outside its triangle: the triangle's nearest point is on one of its edges.
    if lower < 0.0 or upper < 0.0:  # the shared diagonal
        best_sq = min(best_sq, _segment_sq(x, y, z, xa, ya, h00, xb, yb, h11))
    if lower < 0.0:
        best_sq = min(best_sq, _segment_sq(x, y, z, xa, ya, h00, xb, ya, h10))
        best_sq = min(best_sq, _segment_sq(x, y, z, xb, ya, h10, xb, yb, h11))
    if upper < 0.0:
        best_sq = min(best_sq, _segment_sq(x, y, z, xa, ya, h00, xa, yb, h01))
        best_sq = min(best_sq, _segment_sq(x, y, z, xa, yb, h01, xb, yb, h11))
    return best_sq


@njit(error_model='numpy')
def _cell_range(c, r, origin, step, count):  # pragma: no cover - compiled
    """Cells (0 .. count - 2) whose span meets [c - r, c + r] on one axis, widened by a slack
    far above the rounding of the quotients (first > last when none)."""
    slack = _RANGE_SLACK_CELLS + _RANGE_SLACK_RELATIVE * (abs(c) + r + abs(origin)) / step
    low = (c - r - origin) / step - slack
    high = (c + r - origin) / step + slack
    # Clipped before the cast, so that far points cannot overflow it.
    low = min(max(low, -2.0), count + 1.0)
    high = min(max(high, -2.0), count + 1.0)
    return max(int(math.floor(low)), 0), min(int(math.floor(high)), count - 2)


@njit(error_model='numpy')
def _point_distance(hs, x0, y0, dx, dy, x, y, z, cap):  # pragma: no cover - compiled
    """Distance from (x, y, z) to the solid z <= h(x, y) over the extent of ``hs`` [m], capped
    at ``cap``; z already mirrored for side 'above'. NaN for a non-finite point."""
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return math.nan
    nx = hs.shape[1]
    ny = hs.shape[0]
    x1 = x0 + (nx - 1) * dx
    y1 = y0 + (ny - 1) * dy
    cx = min(max(x, x0), x1)
    cy = min(max(y, y0), y1)
    hc = _height(hs, x0, y0, dx, dy, cx, cy)
    if cx == x and cy == y and z <= hc:
        return 0.0
    # A point of the solid: straight below, or below the nearest point of the extent.
    ex = x - cx
    ey = y - cy
    ez = max(z - hc, 0.0)
    bound = math.sqrt(ex * ex + ey * ey + ez * ez)
    reach = min(bound, cap)
    best_sq = reach * reach
    i0, i1 = _cell_range(x, reach, x0, dx, nx)
    j0, j1 = _cell_range(y, reach, y0, dy, ny)
    for j in range(j0, j1 + 1):
        ya = y0 + j * dy
        gy = max(max(ya - y, y - (ya + dy)), 0.0)
        for i in range(i0, i1 + 1):
            xa = x0 + i * dx
            gx = max(max(xa - x, x - (xa + dx)), 0.0)
            top = max(max(hs[j, i], hs[j, i + 1]), max(hs[j + 1, i], hs[j + 1, i + 1]))
            gz = max(z - top, 0.0)
            if (gx * gx + gy * gy + gz * gz) * (1.0 - _SKIP_RELATIVE) - _SKIP_ABSOLUTE > best_sq:
                continue
            best_sq = _cell_sq(hs, x0, y0, dx, dy, i, j, x, y, z, best_sq)
    return min(math.sqrt(best_sq), bound, cap)


@njit(error_model='numpy')
def _column_test(hs, x0, y0, dx, dy, sign, x, y, oz, delta, k, gamma,
                 cap):  # pragma: no cover - compiled
    """Q(k) of a column: node k is within gamma (side 'below') or farther (side 'above'); true
    below the column's limit, false from it on."""
    z = oz + k * delta
    near = _point_distance(hs, x0, y0, dx, dy, x, y, sign * z, cap) <= gamma
    return near == (sign > 0.0)


@njit(error_model='numpy')
def _column_limits(hs, x0, y0, dx, dy, sign, origin, delta, first, last, gamma, cap,
                   out):  # pragma: no cover - compiled
    # The first k in [a, b] with Q(k) false (b = last + 1 stands for "none"): a guess from the
    # surface height (its height plus or minus gamma), a galloping search from it for a bracket
    # and a bisection inside the bracket. Q is monotone, so the guess only saves evaluations;
    # every node's answer comes from Q, that is from _point_distance.
    a = first[2]
    b = last[2] + 1
    x1 = x0 + (hs.shape[1] - 1) * dx
    y1 = y0 + (hs.shape[0] - 1) * dy
    for i in range(out.shape[0]):
        x = origin[0] + (first[0] + i) * delta
        for j in range(out.shape[1]):
            y = origin[1] + (first[1] + j) * delta
            g = a
            if x0 <= x <= x1 and y0 <= y <= y1:
                level = sign * _height(hs, x0, y0, dx, dy, x, y) + sign * gamma
                cells = (level - origin[2]) / delta
                cells = min(max(cells, a - 2.0), b + 2.0)
                g = int(math.floor(cells)) + 1 if sign > 0.0 else int(math.ceil(cells))
                g = min(max(g, a), b)
            if g < b and _column_test(hs, x0, y0, dx, dy, sign, x, y, origin[2], delta, g,
                                      gamma, cap):
                lo = g + 1
                hi = lo
                step = 1
                while hi < b and _column_test(hs, x0, y0, dx, dy, sign, x, y, origin[2],
                                              delta, hi, gamma, cap):
                    lo = hi + 1
                    step *= 2
                    hi = min(hi + step, b)
            else:
                hi = g
                lo = g - 1
                step = 1
                while lo >= a and not _column_test(hs, x0, y0, dx, dy, sign, x, y, origin[2],
                                                   delta, lo, gamma, cap):
                    hi = lo
                    step *= 2
                    lo = hi - step
                lo = max(lo + 1, a)
            while lo < hi:
                mid = (lo + hi) // 2
                if _column_test(hs, x0, y0, dx, dy, sign, x, y, origin[2], delta, mid, gamma,
                                cap):
                    lo = mid + 1
                else:
                    hi = mid
            out[i, j] = lo
