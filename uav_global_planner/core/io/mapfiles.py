"""Occupied points from map files: PCD, PLY, LAS/LAZ, OctoMap ``.bt`` and ``.npy``.

Each format is read by the field's own library (:mod:`~uav_global_planner.core.io.map_readers`),
an optional extra imported only when a file of that format is loaded (``pip install
uav_global_planner[maps]`` installs them all):

========== ============================== ===================================================
suffix     pip package                    what becomes an obstacle point
========== ============================== ===================================================
``.pcd``   ``pypcd4``                     every point (fields x, y, z), ASCII or binary
``.ply``   ``plyfile``                    every vertex (x, y, z); meshes are refused
``.las``   ``laspy``                      every point, scaled and offset to metres
``.laz``   ``laspy`` and ``lazrs``        the same, compressed
``.bt``    ``octomap-python``             the centre of every occupied leaf cell
``.npy``   (numpy)                        every row of an (N, 3) array
========== ============================== ===================================================

Coordinates are taken as metres in the planning frame. Points with NaN or infinite coordinates
(organised clouds mark missing returns so) are dropped and counted.

What a load read, and maps that cannot be right
-----------------------------------------------
Every load gives a :class:`MapReport` per file: the points (or OctoMap cells) read, those
dropped and why (non-finite coordinates, outside the planning bounds, merged by downsampling),
those kept, their x/y/z extent and the file's resolution where it has one. A map that cannot be
what its user meant is refused with :class:`~uav_global_planner.core.errors.InvalidInputError`
rather than planned as open air: a file with no points, one whose points are all non-finite,
one whose points all lie outside the planning bounds (a map in another frame or unit), a
resolution finer than delta / 100 (an OctoMap's stored resolution, or the downsampling cell) and
a non-finite number in the header (a PCD viewpoint, LAS scales, offsets and extent, an OctoMap
resolution).

A point farther than ``reach`` plus the file's margin outside the bounds cannot come within
``reach`` of any location inside them, so with ``reach`` = gamma it cannot block anything the
planner may fly through: such points are dropped when the caller gives the bounds (the clearance
reported is then that to the points kept).

Conservative margins
--------------------
A point set stands for an occupied region within :attr:`MapPoints.margin_m` of its points: every
occupied location of the source lies within that distance of some point. A path that keeps
clearance ``gamma + margin_m`` from the points therefore keeps ``gamma`` from the source, since
the distance to the source is at least the distance to the points minus ``margin_m``.

- PCD, PLY, LAS/LAZ and ``.npy`` points are the obstacles themselves: margin 0.
- An OctoMap leaf is a cube of side ``s`` (the tree resolution, or a multiple of it for pruned
  leaves, which are split into cells of the tree resolution); its centre lies within
  ``s * sqrt(3) / 2`` of every point of the cube, the margin of a ``.bt`` file.
- Voxel downsampling with cell ``c`` keeps one point per occupied cell, the cell's centre (the
  point of a cube that is nearest to its farthest corner), so it adds ``c * sqrt(3) / 2``.
"""

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from uav_global_planner.core.checks import check_file, check_number
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.map_readers import finite_header, MAP_SUFFIXES, READERS
from uav_global_planner.core.map.grid import HALF_CELL_DIAGONAL
from uav_global_planner.core.map.obstacles import ObstacleSet, PointSet

PathLike = Union[str, Path]
#: A file's resolution (OctoMap cells, downsampling cell) may not be finer than the grid
#: spacing delta divided by this.
MIN_RESOLUTION_FRACTION = 100.0


@dataclass(frozen=True)
class MapReport:
    """What one map file load read, dropped and kept.

    ``points_read = dropped_non_finite + dropped_outside_bounds + dropped_downsampled
    + points_kept``.

    Attributes
    ----------
    file : str
        The file read.
    format : str
        Its format (``'PCD'``, ``'PLY'``, ``'LAS'``, ``'LAZ'``, ``'OctoMap binary'``,
        ``'NumPy .npy'``).
    points_read : int
        Points in the file (OctoMap: occupied cells of the tree resolution).
    dropped_non_finite : int
        Points with a NaN or infinite coordinate, dropped.
    outside_bounds : int
        Finite points farther than the reach outside the planning bounds (0 when no bounds were
        given).
    dropped_outside_bounds : int
        Of those, the ones dropped (all of them, or none when the caller keeps them).
    dropped_downsampled : int
        Points merged into the centres of downsampling cells (counted out: the cell centres kept
        stand for them).
    points_kept : int
        Points that become obstacles.
    extent_min, extent_max : tuple of float or None
        Smallest and largest x, y, z of the points kept [m], map frame (None when none is kept).
    resolution_m : float or None
        The file's own resolution [m] (an OctoMap's cell side); None for point formats.
    downsample_m : float or None
        Downsampling cell side [m]; None for none.
    margin_m : float
        Every occupied location of the file lies within this distance of a point kept [m].
    """

    file: str
    format: str
    points_read: int
    dropped_non_finite: int = 0
    outside_bounds: int = 0
    dropped_outside_bounds: int = 0
    dropped_downsampled: int = 0
    points_kept: int = 0
    extent_min: Optional[Tuple[float, float, float]] = None
    extent_max: Optional[Tuple[float, float, float]] = None
    resolution_m: Optional[float] = None
    downsample_m: Optional[float] = None
    margin_m: float = 0.0

    def as_dict(self) -> Dict[str, object]:
        """The report as plain JSON values (the extents as [x, y, z] lists or None)."""
        return {'file': self.file, 'format': self.format, 'points_read': self.points_read,
                'dropped_non_finite': self.dropped_non_finite,
                'outside_bounds': self.outside_bounds,
                'dropped_outside_bounds': self.dropped_outside_bounds,
                'dropped_downsampled': self.dropped_downsampled,
                'points_kept': self.points_kept,
                'extent_min': None if self.extent_min is None else list(self.extent_min),
                'extent_max': None if self.extent_max is None else list(self.extent_max),
                'resolution_m': self.resolution_m, 'downsample_m': self.downsample_m,
                'margin_m': self.margin_m}

    def dropped_text(self) -> str:
        """The dropped points and why, in words (``'none'`` when nothing was dropped)."""
        parts = []
        if self.dropped_non_finite:
            parts.append(f'{self.dropped_non_finite} non-finite')
        if self.dropped_outside_bounds:
            parts.append(f'{self.dropped_outside_bounds} outside the bounds')
        if self.dropped_downsampled:
            parts.append(f'{self.dropped_downsampled} merged by downsampling')
        return ', '.join(parts) or 'none'

    def extent_text(self) -> str:
        """``x [lo, hi] y [lo, hi] z [lo, hi] m`` of the points kept (``'none'``: no point)."""
        if self.extent_min is None or self.extent_max is None:
            return 'none'
        return ' '.join(f'{axis} [{lo:.3f}, {hi:.3f}]' for axis, lo, hi
                        in zip('xyz', self.extent_min, self.extent_max)) + ' m'

    def summary(self) -> str:
        """One line: the file, points read, dropped (why), kept, extent and resolution."""
        text = (f'{self.file}: {self.points_read} points read, dropped {self.dropped_text()}, '
                f'{self.points_kept} kept')
        if self.outside_bounds > self.dropped_outside_bounds:
            text += f' ({self.outside_bounds - self.dropped_outside_bounds} outside the bounds)'
        text += f', extent {self.extent_text()}'
        if self.resolution_m is not None:
            text += f', resolution {self.resolution_m:g} m'
        if self.downsample_m is not None:
            text += f', downsampled to {self.downsample_m:g} m cells'
        return text


@dataclass(frozen=True, eq=False)
class MapPoints:
    """Occupied points read from one or more map files.

    Attributes
    ----------
    points : numpy.ndarray, shape (N, 3)
        Finite float64 positions [m] in the planning frame; N may be 0.
    margin_m : float
        Every occupied location of the source lies within this distance of a point [m] (0 for
        plain point files; see the module notes).
    source : str
        The file (or files, comma-separated) the points come from.
    read_points : int
        Points (or OctoMap cells) in the file(s), before dropping and downsampling.
    dropped_non_finite : int
        Points with NaN or infinite coordinates that were dropped.
    reports : tuple of MapReport
        One per file, in the order read.
    """

    points: np.ndarray
    margin_m: float
    source: str
    read_points: int
    dropped_non_finite: int = 0
    reports: Tuple[MapReport, ...] = ()

    def obstacle(self) -> PointSet:
        """The points as a :class:`PointSet` obstacle."""
        return PointSet(self.points)


def downsample_margin(cell: float) -> float:
    """Margin [m] that voxel downsampling with cells of side ``cell`` [m] adds: c * sqrt(3) / 2."""
    return float(cell) * HALF_CELL_DIAGONAL


def voxel_downsample(points: np.ndarray, cell: float) -> np.ndarray:
    """One point per occupied cell of side ``cell``: the centre of the cell.

    The cells tile space from the origin of the frame, ``[k * cell, (k + 1) * cell)`` per axis.
    Every input point lies within ``cell * sqrt(3) / 2`` of the centre of its cell
    (:func:`downsample_margin`).

    Parameters
    ----------
    points : numpy.ndarray, shape (N, 3)
        Finite positions [m].
    cell : float
        Cell side [m], > 0.

    Returns
    -------
    numpy.ndarray, shape (M, 3), M <= N
        Cell centres [m], sorted by cell index (deterministic).

    Raises
    ------
    InvalidInputError
        For a cell that is not a finite number > 0.
    """
    size = _cell_size(cell, 'downsample')
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) == 0:
        return pts.copy()
    index = np.floor(pts / size).astype(np.int64)
    low = index.min(axis=0)
    span = index.max(axis=0) - low + 1
    if float(np.prod(span.astype(np.float64))) < 2.0 ** 62:
        # One int64 key per cell: a 1-D unique is several times faster than unique rows.
        shifted = index - low
        keys = (shifted[:, 0] * span[1] + shifted[:, 1]) * span[2] + shifted[:, 2]
        # Sort and compare neighbours: np.unique takes many times longer on a million keys.
        keys.sort()
        unique = keys[np.concatenate(([True], keys[1:] != keys[:-1]))]
        cells = np.stack(np.unravel_index(unique, tuple(int(s) for s in span)), axis=-1) + low
    else:
        cells = np.unique(index, axis=0)
    return (cells.astype(np.float64) + 0.5) * size


def _cell_size(value, name: str) -> float:
    return check_number(name, value, 0.0, low_open=True, accepted='a cell size > 0 m',
                        convert=True)


#: Bounds of the planning workspace: (min corner, max corner), each x, y, z [m].
Bounds = Tuple[Sequence[float], Sequence[float]]


def load_map_points(path: PathLike, downsample: Optional[float] = None, *,
                    bounds: Optional[Bounds] = None, reach: float = 0.0,
                    drop_outside: bool = True,
                    resolution: Optional[float] = None) -> MapPoints:
    """Read the occupied points of a map file, check them and report what was read.

    Parameters
    ----------
    path : str or Path
        A ``.pcd``, ``.ply``, ``.las``, ``.laz``, ``.bt`` or ``.npy`` file (by suffix, any case).
    downsample : float, optional
        Cell side [m]: keep one point, the cell centre, per occupied cell
        (:func:`voxel_downsample`); the margin grows by ``downsample * sqrt(3) / 2``.
    bounds : (min, max), optional
        The planning bounds [m], map frame. A point farther than ``reach`` plus the file's
        margin outside them (per axis) is outside; a map whose points are all outside is
        refused.
    reach : float
        Clearance the planner keeps [m] (gamma without the map's margin), >= 0.
    drop_outside : bool
        Drop the points outside the bounds (True), or only count them (for a caller whose
        bounds may change while it holds the map).
    resolution : float, optional
        The grid spacing delta [m]: a file resolution or downsampling cell finer than
        delta / :data:`MIN_RESOLUTION_FRACTION` is refused.

    Returns
    -------
    MapPoints
        With one :class:`MapReport` in ``reports``.

    Raises
    ------
    MissingDependencyError
        When the format's library is not installed; the message names the pip package.
    InvalidInputError
        For an unknown suffix, a missing or unreadable file, a corrupt or truncated one, and a
        map that cannot be right (see the module notes); the message starts with the file
        name, says what was found and what to do.
    """
    file = Path(path)
    cell = None if downsample is None else _cell_size(downsample, 'downsample')
    finest = _finest_resolution(resolution)
    if cell is not None and cell < finest:
        raise InvalidInputError(
            f'{file}: the downsampling cell {cell:g} m is finer than delta / '
            f'{MIN_RESOLUTION_FRACTION:g} = {finest:g} m (a unit mistake?); use a cell of about '
            'delta, or no downsampling')
    check_file(file, 'map file')
    suffix = file.suffix.lower()
    if suffix not in READERS:
        raise InvalidInputError(f'{file}: unknown map file type {file.suffix or "(none)"!r}; '
                                f'supported: {", ".join(MAP_SUFFIXES)}')
    name, reader = READERS[suffix]
    try:
        points, margin, read = reader(file)
    except (InvalidInputError, MemoryError):
        raise
    except OSError as error:
        raise InvalidInputError(f'{file}: cannot read map file '
                                f'({error.strerror or error})') from None
    except Exception as error:  # noqa: BLE001 - each library has its own error types
        # Corrupt and truncated files surface as the libraries' own exceptions (ValueError,
        # struct errors, parse errors, pydantic validation errors, ...): name the file.
        raise InvalidInputError(f'{file}: not a valid {name} file, or truncated '
                                f'({_describe(error)})') from None
    own = None
    if suffix == '.bt':
        # The margin of an OctoMap is its cell's half diagonal (see the module notes).
        own = margin / HALF_CELL_DIAGONAL
        finite_header(file, 'OctoMap', {'resolution': [own]})
        if own < finest:
            raise InvalidInputError(
                f'{file}: the OctoMap resolution {own:g} m is finer than delta / '
                f'{MIN_RESOLUTION_FRACTION:g} = {finest:g} m: a map in millimetres or a '
                'corrupt header; check the unit the map was written in, or plan with a finer '
                'delta')
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if read == 0:
        what = 'occupied cells' if suffix == '.bt' else 'points'
        raise InvalidInputError(
            f'{file}: no points: the {name} file holds 0 {what}, and an empty map '
            'would be planned as open air; check that this is the intended map, or leave the '
            'file out to plan without it')
    finite = np.all(np.isfinite(points), axis=1)
    dropped = int(len(points) - np.count_nonzero(finite))
    if dropped == len(points):
        raise InvalidInputError(
            f'{file}: no usable points: all {dropped} points of the {name} file have NaN or '
            'infinite coordinates, and an empty map would be planned as open air; check the '
            'file (an organised cloud with no returns?), or leave it out to plan without it')
    if dropped:
        points = points[finite]
    outside, points = _outside_bounds(file, points, bounds, reach, margin, drop_outside)
    count = len(points)
    if cell is not None:
        points = voxel_downsample(points, cell)
        margin += downsample_margin(cell)
    points = np.ascontiguousarray(points, dtype=np.float64)
    report = MapReport(
        file=str(file), format=name, points_read=int(read), dropped_non_finite=dropped,
        outside_bounds=outside, dropped_outside_bounds=outside if drop_outside else 0,
        dropped_downsampled=int(count - len(points)), points_kept=len(points),
        extent_min=_corner(points.min(axis=0)), extent_max=_corner(points.max(axis=0)),
        resolution_m=own, downsample_m=cell, margin_m=float(margin))
    return MapPoints(points=points, margin_m=float(margin), source=str(file), read_points=read,
                     dropped_non_finite=dropped, reports=(report,))


def _finest_resolution(resolution: Optional[float]) -> float:
    """The finest file resolution or downsampling cell accepted with grid spacing
    ``resolution`` [m] (0 when there is none)."""
    if resolution is None:
        return 0.0
    delta = float(resolution)
    if not math.isfinite(delta) or delta <= 0.0:
        raise InvalidInputError(f'resolution must be a finite number > 0 m, got {resolution!r}')
    return delta / MIN_RESOLUTION_FRACTION


def _corner(values: np.ndarray) -> Tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def _outside_bounds(file: Path, points: np.ndarray, bounds: Optional[Bounds], reach: float,
                    margin: float, drop: bool) -> Tuple[int, np.ndarray]:
    """How many finite ``points`` lie farther than ``reach + margin`` outside ``bounds`` (per
    axis), and the points without them when ``drop``; refuse a map that is all outside."""
    if bounds is None:
        return 0, points
    lo = np.asarray(bounds[0], dtype=np.float64).reshape(3)
    hi = np.asarray(bounds[1], dtype=np.float64).reshape(3)
    slack = float(reach) + float(margin)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and math.isfinite(slack)
            and slack >= 0.0):
        raise InvalidInputError(f'bounds and reach must be finite (reach >= 0), got '
                                f'{lo.tolist()}, {hi.tolist()} and {reach!r}')
    inside = np.all((points >= lo - slack) & (points <= hi + slack), axis=1)
    outside = int(len(points) - np.count_nonzero(inside))
    if outside == len(points):
        extent = ' '.join(f'{axis} [{a:.6g}, {b:.6g}]' for axis, a, b
                          in zip('xyz', points.min(axis=0), points.max(axis=0)))
        raise InvalidInputError(
            f'{file}: all {outside} usable points lie outside the planning bounds '
            f'{lo.tolist()} .. {hi.tolist()} (by more than {slack:g} m): the points span '
            f'{extent} m. Is the map in another frame or unit (UTM or geodetic coordinates, '
            'millimetres)? Transform it into the planning frame, or set bounds that cover it')
    if drop and outside:
        points = points[inside]
    return outside, points


def _describe(error: Exception) -> str:
    """One line about a library's exception: its type and first line, or the header fields a
    validating reader (pypcd4 uses pydantic) found missing or wrong."""
    name = type(error).__name__
    problems = getattr(error, 'errors', None)
    if callable(problems):
        try:
            fields = sorted({'.'.join(str(part) for part in item.get('loc', ())) or '?'
                             for item in problems()})
            return f'{name}: bad or missing header field(s) {", ".join(fields)}'
        except Exception:  # noqa: BLE001 - fall back to the text below
            pass
    text = str(error).strip()
    return f'{name}: {text.splitlines()[0]}' if text else name


def load_map_files(paths: Iterable[PathLike], downsample: Optional[float] = None, *,
                   bounds: Optional[Bounds] = None, reach: float = 0.0,
                   resolution: Optional[float] = None) -> MapPoints:
    """Read several map files into one point set (each as :func:`load_map_points`, points
    outside the bounds dropped).

    The margin is the largest of the files' margins; ``reports`` holds one report per file.
    """
    maps = [load_map_points(path, downsample, bounds=bounds, reach=reach,
                            resolution=resolution) for path in paths]
    if not maps:
        return MapPoints(points=np.empty((0, 3)), margin_m=0.0, source='', read_points=0)
    reports: List[MapReport] = [report for m in maps for report in m.reports]
    return MapPoints(points=np.concatenate([m.points for m in maps]),
                     margin_m=max(m.margin_m for m in maps),
                     source=', '.join(m.source for m in maps),
                     read_points=sum(m.read_points for m in maps),
                     dropped_non_finite=sum(m.dropped_non_finite for m in maps),
                     reports=tuple(reports))


def load_prior_map(map_file: str, downsample: float = 0.0, *, bounds: Optional[Bounds] = None,
                   reach: float = 0.0, resolution: Optional[float] = None) -> Optional[MapPoints]:
    """The static prior map of the planner node, from its ``map_file`` parameter.

    The points outside ``bounds`` are counted but kept (the node's bounds may change while it
    runs); a map whose points all lie outside is refused.

    Parameters
    ----------
    map_file : str
        Path of a map file; empty (or only blanks) for none.
    downsample : float
        Cell side [m] of the voxel downsampling; 0 for none.
    bounds, reach, resolution
        As for :func:`load_map_points`.

    Returns
    -------
    MapPoints or None
        None when ``map_file`` is empty.

    Raises
    ------
    InvalidInputError
        As :func:`load_map_points`; the message starts with the file name.
    """
    if not isinstance(map_file, str):
        raise InvalidInputError(f'map_file must be a path (a string), got {map_file!r}')
    if not map_file.strip():
        return None
    cell = None if downsample == 0.0 else downsample
    return load_map_points(Path(map_file.strip()).expanduser(), cell, bounds=bounds,
                           reach=reach, drop_outside=False, resolution=resolution)


def with_prior_map(obstacles: ObstacleSet, prior: Optional[MapPoints]) -> ObstacleSet:
    """``obstacles`` plus the points of a prior map (unchanged when ``prior`` is None)."""
    if prior is None or len(prior.points) == 0:
        return obstacles
    return ObstacleSet([*obstacles.items, prior.obstacle()])
