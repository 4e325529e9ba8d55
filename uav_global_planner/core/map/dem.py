"""Digital elevation models (DEM): terrain heights read from a file into a height field.

A DEM becomes a :class:`~uav_global_planner.core.map.terrain.HeightField` in the map frame (ENU:
x east, y north, z up [m]) whose lattice covers the x/y extent of the planning bounds. Three
formats are read:

GeoTIFF (``.tif``, ``.tiff``)
    Through rasterio (``pip install rasterio``, or this package's ``terrain`` extra), the
    field's reader of georeferenced rasters; band 1 holds the elevations [m], its nodata value
    (and NaN) marks holes. The raster needs a CRS and a geotransform.

    *With a geodetic origin* (the scene's ``geodetic_origin``), the DEM is resampled onto a
    regular ENU lattice over the bounds, at a spacing no larger than the DEM's own (the bounds'
    extent divided into whole cells): every lattice node ``(x, y)`` is converted to latitude and
    longitude with :mod:`uav_global_planner.core.io.geodesy` (pymap3d), then to the DEM's CRS with
    ``rasterio.warp.transform``, and the elevation there is interpolated bilinearly between the
    four surrounding pixel centres. The height in the map frame is ``z = elevation - h0(x, y)``,
    with ``h0(x, y)`` the altitude of the map point ``(x, y, 0)``: the origin's ``alt_amsl``
    plus the drop of the ellipsoid below the tangent plane (``r**2 / (2 R)``, 8 cm at 1 km), so
    a mission written from the map frame puts every point at its planned height above the DEM.
    Elevations are taken as AMSL, as SRTM, Copernicus and national DEMs give them (see the
    notes on AMSL in :mod:`~uav_global_planner.core.io.geodesy`).

    *Without a geodetic origin*, the raster's CRS must be projected in metres (UTM, a national
    grid) and the map frame is that CRS: map x, y are its easting and northing, z the elevation.
    The DEM is resampled in the same way, straight through its geotransform.

ESRI ASCII grid (``.asc``) and NumPy arrays (``.npy``)
    Lattices in the map frame itself: x, y and the heights are map-frame coordinates [m] (use a
    GeoTIFF for georeferenced data). An ``.asc`` file's header (``ncols``, ``nrows``,
    ``xllcorner`` or ``xllcenter``, ``yllcorner`` or ``yllcenter``, ``cellsize`` or ``dx`` and
    ``dy``, optional ``nodata_value``) places its cells, rows running from north to south. An
    ``.npy`` file holds a plain 2D array ``heights[j, i]`` at ``origin + (i dx, j dy)``, the
    ``origin`` and ``spacing`` being given beside the file (the scene key ``terrain: {file,
    origin: [x, y], spacing: [dx, dy]}``); NaN marks holes. Both are cut to the smallest window
    of their own nodes that covers the bounds, without resampling.

Refusals (:class:`~uav_global_planner.core.errors.InvalidInputError`, naming the file): a hole
(nodata) where the bounds need a height, a header or a lattice that is not finite, a spacing
<= 0, a DEM that does not cover the bounds' x/y extent (its pixel centres must surround it), a
GeoTIFF without a CRS, and a geographic or non-metric CRS without a geodetic origin.
"""

from dataclasses import dataclass
import importlib
import math
from pathlib import Path
from types import ModuleType
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from uav_global_planner.core.checks import check_number
from uav_global_planner.core.errors import InvalidInputError, MissingDependencyError
from uav_global_planner.core.io.geodesy import enu_to_geodetic, GeodeticOrigin
from uav_global_planner.core.map.terrain import HeightField

#: File suffixes read as DEMs, by format.
GEOTIFF_SUFFIXES = ('.tif', '.tiff')
DEM_SUFFIXES = GEOTIFF_SUFFIXES + ('.asc', '.npy')

#: The pip extra that brings rasterio.
TERRAIN_EXTRA = 'terrain'

# Slack of the coverage test, in pixels or lattice cells: bounds on a node are covered.
_COVER_SLACK = 1e-9
# Metres per degree of latitude on the WGS84 ellipsoid's mean radius, for the spacing only.
_EARTH_RADIUS_M = 6_371_008.8

_PathLike = Union[str, Path]


@dataclass(frozen=True)
class TerrainSource:
    """Where the terrain comes from: the scene key ``terrain`` or ``uav-plan --terrain``.

    Attributes
    ----------
    file : pathlib.Path
        The DEM file (``.tif``, ``.tiff``, ``.asc``, ``.npy``).
    origin : tuple of float, optional
        Map-frame x, y of ``heights[0, 0]`` of an ``.npy`` file [m].
    spacing : tuple of float, optional
        Lattice spacing dx, dy of an ``.npy`` file [m], > 0.
    """

    file: Path
    origin: Optional[Tuple[float, float]] = None
    spacing: Optional[Tuple[float, float]] = None


def _pair(value: Any, path: str) -> Tuple[float, float]:
    if isinstance(value, (str, bytes)) or not hasattr(value, '__len__') or len(value) != 2:
        raise InvalidInputError(f'{path}: must be two numbers [x, y] [m], got {value!r}')
    numbers = [check_number(f'{path}[{axis}]:', item) for axis, item in enumerate(value)]
    return numbers[0], numbers[1]


def parse_terrain(value: Any, folder: Optional[Path] = None,
                  path: str = 'terrain') -> TerrainSource:
    """The scene key ``terrain: {file: ..., origin: [x, y], spacing: [dx, dy]}``.

    Parameters
    ----------
    value : Any
        The key's YAML value.
    folder : pathlib.Path, optional
        Folder a relative ``file`` starts from (the scene file's folder).
    path : str
        Key path in messages.

    Raises
    ------
    InvalidInputError
        Naming the key path: unknown keys, a missing or empty file name, an ``origin`` or
        ``spacing`` that is not two finite numbers, a spacing <= 0, ``origin`` and ``spacing``
        missing for an ``.npy`` file or given for another format.
    """
    if not isinstance(value, dict):
        raise InvalidInputError(f'{path}: must be a mapping {{file: ..., origin: [x, y], '
                                f'spacing: [dx, dy]}}, got {type(value).__name__}')
    unknown = sorted(str(key) for key in value if key not in ('file', 'origin', 'spacing'))
    if unknown:
        raise InvalidInputError(f'{path}: unknown key(s) {", ".join(unknown)}; allowed: file, '
                                'origin, spacing')
    file = value.get('file')
    if not isinstance(file, str) or not file.strip():
        raise InvalidInputError(f'{path}.file: must be a file name, got {file!r}')
    location = Path(file).expanduser()
    if not location.is_absolute() and folder is not None:
        location = folder / location
    origin = _pair(value['origin'], f'{path}.origin') if 'origin' in value else None
    spacing = _pair(value['spacing'], f'{path}.spacing') if 'spacing' in value else None
    if spacing is not None and min(spacing) <= 0.0:
        raise InvalidInputError(f'{path}.spacing: must be > 0 m on both axes, got '
                                f'{list(spacing)}')
    is_npy = location.suffix.lower() == '.npy'
    if is_npy and (origin is None or spacing is None):
        raise InvalidInputError(f'{path}: an .npy terrain needs origin: [x, y] and spacing: '
                                '[dx, dy] [m] (the map-frame position of heights[0, 0] and the '
                                'lattice spacing)')
    if not is_npy and (origin is not None or spacing is not None):
        raise InvalidInputError(f'{path}: origin and spacing are for .npy files only; '
                                f'{location.name} places itself')
    return TerrainSource(location, origin, spacing)


def load_dem(source: Union[TerrainSource, _PathLike], lo_xy: Sequence[float],
             hi_xy: Sequence[float], geodetic_origin: Optional[GeodeticOrigin] = None,
             label: str = 'terrain') -> HeightField:
    """Read a DEM into a height field over the x/y extent ``[lo_xy, hi_xy]`` of the map frame.

    Parameters
    ----------
    source : TerrainSource or path
        The file (a bare path for ``.tif``, ``.tiff`` and ``.asc``).
    lo_xy, hi_xy : sequence of float, shape (2,)
        x/y extent the lattice must cover (the planning bounds) [m], map frame.
    geodetic_origin : GeodeticOrigin, optional
        WGS84 position of the map frame's origin; places a GeoTIFF (see the module notes).
    label : str
        Label of the height field.

    Returns
    -------
    HeightField
        ``side='below'``: the solid is the ground, z <= height.

    Raises
    ------
    InvalidInputError
        For a file that cannot be read or is refused (see the module notes), naming it.
    MissingDependencyError
        For a GeoTIFF when rasterio is not installed (naming the ``terrain`` extra), or a
        geodetic origin when pymap3d is not.
    """
    if not isinstance(source, TerrainSource):
        source = TerrainSource(Path(source))
    file = Path(source.file)
    lo = np.asarray(lo_xy, dtype=np.float64).reshape(2)
    hi = np.asarray(hi_xy, dtype=np.float64).reshape(2)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
        raise InvalidInputError(f'{file}: the extent to cover must be finite with min below max, '
                                f'got {lo.tolist()} and {hi.tolist()}')
    suffix = file.suffix.lower()
    if suffix not in DEM_SUFFIXES:
        raise InvalidInputError(f'{file}: not a terrain file: the formats are '
                                f'{", ".join(DEM_SUFFIXES)}')
    if not file.is_file():
        raise InvalidInputError(f'{file}: no such terrain file')
    if suffix in GEOTIFF_SUFFIXES:
        return _geotiff(file, lo, hi, geodetic_origin, label)
    if suffix == '.asc':
        origin, spacing, heights = _read_asc(file)
    else:
        if source.origin is None or source.spacing is None:
            raise InvalidInputError(f'{file}: an .npy terrain needs its origin [x, y] and '
                                    'spacing [dx, dy] [m] (the scene key terrain: {file, '
                                    'origin, spacing})')
        origin, spacing, heights = _read_npy(file, source.origin, source.spacing)
    return _crop(file, origin, spacing, heights, lo, hi, label)


# ------------------------------------------------------------------------ map-frame lattices

def _read_npy(file: Path, origin: Sequence[float], spacing: Sequence[float]
              ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    try:
        array = np.load(file, allow_pickle=False)
    except (OSError, ValueError) as error:
        raise InvalidInputError(f'{file}: not a plain NumPy array file ({error})') from None
    if not isinstance(array, np.ndarray) or array.ndim != 2 or array.dtype.kind not in 'iuf':
        raise InvalidInputError(f'{file}: a terrain .npy file must hold a 2D array of numbers '
                                f'heights[j, i], got {getattr(array, "shape", "?")} of '
                                f'{getattr(array, "dtype", "?")}')
    xy = np.asarray(origin, dtype=np.float64).reshape(2)
    if not np.all(np.isfinite(xy)):
        raise InvalidInputError(f'{file}: the lattice origin must be finite, got {xy.tolist()}')
    return xy, _spacing(file, spacing), array.astype(np.float64)


def _spacing(file: Path, spacing: Sequence[float]) -> np.ndarray:
    step = np.asarray(spacing, dtype=np.float64).reshape(2)
    if not np.all(np.isfinite(step)) or np.any(step <= 0.0):
        raise InvalidInputError(f'{file}: the spacing must be finite and > 0 m, got '
                                f'{step.tolist()}')
    return step


def _read_asc(file: Path) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An ESRI ASCII grid: origin (centre of the south-west cell), spacing, heights[j, i] from
    south to north, NaN for nodata."""
    try:
        lines = file.read_text(encoding='ascii').splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise InvalidInputError(f'{file}: cannot read this ASCII grid ({error})') from None
    header: Dict[str, str] = {}
    row = 0
    for row, line in enumerate(lines):
        words = line.split()
        if len(words) != 2 or not words[0][:1].isalpha():
            break
        header[words[0].lower()] = words[1]
    else:
        row = len(lines)
    numbers: Dict[str, float] = {}
    for key, text in header.items():
        numbers[key] = check_number(f'{file}: header {key}', text, convert=True)
    for key in ('ncols', 'nrows'):
        if key not in numbers:
            raise InvalidInputError(f'{file}: not an ESRI ASCII grid: no {key} in the header')
        if numbers[key] != int(numbers[key]) or numbers[key] < 2:
            raise InvalidInputError(f'{file}: header {key} must be an integer >= 2, got '
                                    f'{header[key]}')
    ncols, nrows = int(numbers['ncols']), int(numbers['nrows'])
    if 'cellsize' in numbers:
        spacing = np.array([numbers['cellsize'], numbers['cellsize']])
    elif 'dx' in numbers and 'dy' in numbers:
        spacing = np.array([numbers['dx'], numbers['dy']])
    else:
        raise InvalidInputError(f'{file}: not an ESRI ASCII grid: no cellsize in the header')
    if np.any(spacing <= 0.0):
        raise InvalidInputError(f'{file}: header cellsize must be > 0 m, got {spacing.tolist()}')
    origin = np.empty(2)
    for axis, name in enumerate('xy'):
        if f'{name}llcenter' in numbers:
            origin[axis] = numbers[f'{name}llcenter']
        elif f'{name}llcorner' in numbers:
            origin[axis] = numbers[f'{name}llcorner'] + spacing[axis] / 2.0
        else:
            raise InvalidInputError(f'{file}: not an ESRI ASCII grid: no {name}llcorner or '
                                    f'{name}llcenter in the header')
    try:
        values = np.array(' '.join(lines[row:]).split(), dtype=np.float64)
    except ValueError as error:
        raise InvalidInputError(f'{file}: the cells of this ASCII grid are not numbers '
                                f'({error})') from None
    if values.size != ncols * nrows:
        raise InvalidInputError(f'{file}: the header announces {nrows} x {ncols} cells, the '
                                f'file holds {values.size}')
    heights = values.reshape(nrows, ncols)[::-1]
    if 'nodata_value' in numbers:
        heights = np.where(heights == numbers['nodata_value'], np.nan, heights)
    return origin, spacing, np.ascontiguousarray(heights)


def _crop(file: Path, origin: np.ndarray, spacing: np.ndarray, heights: np.ndarray,
          lo: np.ndarray, hi: np.ndarray, label: str) -> HeightField:
    """The smallest window of the lattice's own nodes that covers ``[lo, hi]``."""
    shape = np.array(heights.shape[::-1])  # nx, ny
    if np.any(shape < 2):
        raise InvalidInputError(f'{file}: a terrain needs at least 2 x 2 heights, got '
                                f'{heights.shape[0]} x {heights.shape[1]}')
    first = np.floor((lo - origin) / spacing + _COVER_SLACK).astype(np.int64)
    last = np.ceil((hi - origin) / spacing - _COVER_SLACK).astype(np.int64)
    if np.any(first < 0) or np.any(last > shape - 1):
        top = origin + (shape - 1) * spacing
        raise InvalidInputError(
            f'{file}: the terrain does not cover the bounds: its nodes span x '
            f'[{origin[0]:g}, {top[0]:g}] and y [{origin[1]:g}, {top[1]:g}] m, the bounds x '
            f'[{lo[0]:g}, {hi[0]:g}] and y [{lo[1]:g}, {hi[1]:g}] m')
    last = np.maximum(last, first + 1)
    window = heights[first[1]:last[1] + 1, first[0]:last[0] + 1]
    _refuse_holes(file, window, origin + first * spacing, spacing)
    return HeightField(origin + first * spacing, spacing.copy(),
                       np.ascontiguousarray(window, dtype=np.float64), 'below', label)


def _refuse_holes(file: Path, heights: np.ndarray, origin: np.ndarray,
                  spacing: np.ndarray) -> None:
    holes = ~np.isfinite(heights)
    if np.any(holes):
        j, i = np.argwhere(holes)[0]
        x, y = origin + np.array([i, j]) * spacing
        raise InvalidInputError(
            f'{file}: the terrain has {int(holes.sum())} hole(s) (nodata) inside the bounds, '
            f'the first near x {x:.1f}, y {y:.1f} m in the map frame; fill them or move the '
            'bounds')


# ------------------------------------------------------------------------------- GeoTIFF

def rasterio_module() -> ModuleType:
    """rasterio, imported when a GeoTIFF is read.

    Raises
    ------
    MissingDependencyError
        Naming the pip package and the ``terrain`` extra.
    """
    try:
        return importlib.import_module('rasterio')
    except ImportError:
        raise MissingDependencyError(
            "reading GeoTIFF terrain needs the Python package 'rasterio', which is not "
            f'installed: pip install rasterio (or pip install '
            f'uav_global_planner[{TERRAIN_EXTRA}])') from None


def _node_axes(lo: np.ndarray, hi: np.ndarray, step: np.ndarray
               ) -> Tuple[np.ndarray, np.ndarray]:
    """A regular lattice over ``[lo, hi]``: whole cells no larger than ``step``."""
    counts = np.maximum(np.ceil((hi - lo) / step - _COVER_SLACK).astype(np.int64), 1) + 1
    return (np.linspace(lo[0], hi[0], int(counts[0])),
            np.linspace(lo[1], hi[1], int(counts[1])))


def _geotiff(file: Path, lo: np.ndarray, hi: np.ndarray,
             geodetic_origin: Optional[GeodeticOrigin], label: str) -> HeightField:
    rasterio = rasterio_module()
    importlib.import_module('rasterio.warp')
    try:
        with rasterio.open(file) as dataset:
            crs, transform = dataset.crs, dataset.transform
            band = dataset.read(1, masked=True)
    except rasterio.errors.RasterioIOError as error:
        raise InvalidInputError(f'{file}: cannot read this GeoTIFF ({error})') from None
    if crs is None:
        raise InvalidInputError(f'{file}: this GeoTIFF has no CRS, so it cannot be placed on '
                                'the map')
    coefficients = np.array([transform.a, transform.b, transform.c, transform.d, transform.e,
                             transform.f], dtype=np.float64)
    if not np.all(np.isfinite(coefficients)) or abs(transform.determinant) == 0.0:
        raise InvalidInputError(f'{file}: the geotransform must be finite and invertible, got '
                                f'{coefficients.tolist()}')
    values = np.ma.filled(band.astype(np.float64), np.nan)
    if min(values.shape) < 2:
        raise InvalidInputError(f'{file}: a terrain needs at least 2 x 2 pixels, got '
                                f'{values.shape[0]} x {values.shape[1]}')
    pixel = np.array([math.hypot(transform.a, transform.d),
                      math.hypot(transform.b, transform.e)])
    if geodetic_origin is None:
        if crs.is_geographic or not crs.is_projected:
            raise InvalidInputError(
                f'{file}: its CRS ({crs.to_string()}) is not a projected one in metres, and the '
                'scene has no geodetic_origin to place it: give the scene a geodetic_origin')
        unit, factor = _linear_units(file, crs, rasterio)
        if not math.isclose(factor, 1.0):
            raise InvalidInputError(f'{file}: its CRS ({crs.to_string()}) is in {unit}, not '
                                    'metres; give the scene a geodetic_origin to place it')
        xs, ys = _node_axes(lo, hi, pixel)
        grid_x, grid_y = np.meshgrid(xs, ys)
        crs_x, crs_y = grid_x.ravel(), grid_y.ravel()
        base = np.zeros(grid_x.size)
    else:
        if crs.is_geographic:
            metres = math.radians(1.0) * _EARTH_RADIUS_M
            step = pixel * np.array([metres * math.cos(math.radians(geodetic_origin.lat)),
                                     metres])
        else:
            step = pixel * _linear_units(file, crs, rasterio)[1]
        xs, ys = _node_axes(lo, hi, step)
        grid_x, grid_y = np.meshgrid(xs, ys)
        enu = np.column_stack([grid_x.ravel(), grid_y.ravel(), np.zeros(grid_x.size)])
        lat, lon, base = enu_to_geodetic(enu, geodetic_origin)
        crs_x, crs_y = (np.asarray(c, dtype=np.float64)
                        for c in rasterio.warp.transform('EPSG:4326', crs, lon, lat))
    elevation = _bilinear(file, values, ~transform, crs_x, crs_y)
    heights = (elevation - base).reshape(grid_x.shape)
    return HeightField(np.array([xs[0], ys[0]]), np.array([xs[1] - xs[0], ys[1] - ys[0]]),
                       np.ascontiguousarray(heights), 'below', label)


def _linear_units(file: Path, crs: Any, rasterio: ModuleType) -> Tuple[str, float]:
    """The name of a projected CRS's linear unit and its length in metres."""
    try:
        unit, factor = crs.linear_units_factor
    except rasterio.errors.CRSError as error:
        raise InvalidInputError(f'{file}: its CRS ({crs.to_string()}) has no linear unit '
                                f'({error})') from None
    return str(unit), float(factor)


def _bilinear(file: Path, values: np.ndarray, inverse: Any, xs: np.ndarray,
              ys: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of the raster between pixel centres at CRS positions."""
    cols = inverse.a * xs + inverse.b * ys + inverse.c
    rows = inverse.d * xs + inverse.e * ys + inverse.f
    # Pixel (row r, column c) covers [c, c + 1) x [r, r + 1): its centre is at c + 0.5.
    u = np.asarray(cols, dtype=np.float64) - 0.5
    v = np.asarray(rows, dtype=np.float64) - 0.5
    nrows, ncols = values.shape
    outside = ((u < -_COVER_SLACK) | (u > ncols - 1 + _COVER_SLACK) | (v < -_COVER_SLACK)
               | (v > nrows - 1 + _COVER_SLACK) | ~np.isfinite(u) | ~np.isfinite(v))
    if np.any(outside):
        raise InvalidInputError(
            f'{file}: the terrain does not cover the bounds: {int(outside.sum())} of '
            f'{outside.size} lattice nodes over the bounds lie outside its pixel centres '
            f'({ncols} x {nrows} pixels)')
    i = np.clip(np.floor(u).astype(np.int64), 0, ncols - 2)
    j = np.clip(np.floor(v).astype(np.int64), 0, nrows - 2)
    fu = np.clip(u - i, 0.0, 1.0)
    fv = np.clip(v - j, 0.0, 1.0)
    corners = np.stack([values[j, i], values[j, i + 1], values[j + 1, i],
                        values[j + 1, i + 1]])
    holes = ~np.all(np.isfinite(corners), axis=0)
    if np.any(holes):
        raise InvalidInputError(
            f'{file}: the terrain has holes (nodata) inside the bounds: {int(holes.sum())} '
            'lattice nodes over the bounds touch a nodata pixel; fill them or move the bounds')
    return ((1.0 - fv) * ((1.0 - fu) * corners[0] + fu * corners[1])
            + fv * ((1.0 - fu) * corners[2] + fu * corners[3]))
