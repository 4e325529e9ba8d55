"""The node's terrain: the ``terrain_file`` parameter read into a digital elevation model.

The file is a DEM read by :func:`uav_global_planner.core.map.dem.load_dem` over the x/y extent of
the bounds: a GeoTIFF (``.tif``, ``.tiff``; placed with the ``geodetic_origin`` parameter of
the map frame when it is set, else its CRS must be projected in metres and is the map frame)
or an ESRI ASCII grid (``.asc``, in the map frame). An ``.npy`` lattice, which needs an origin
and a spacing beside the file, is refused with the formats to use instead. The terrain is the
ground: it replaces the ``ground`` parameter, and ``min_agl`` and ``max_agl`` follow it
(:mod:`uav_global_planner.ros.ground_source`).

The file is named once, at start-up; it is read again when the bounds' x/y extent or
``geodetic_origin`` change (the lattice covers the bounds and is placed by the origin). A file
that cannot be read or is refused by the loader makes a :class:`TerrainState` with the reason:
the node keeps running, reports it in its map status and refuses goals.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.dem import load_dem
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner.ros.mission_service import origin_from_value

#: The parameter naming the DEM file.
TERRAIN_PARAMETER = 'terrain_file'

#: The suffixes ``terrain_file`` accepts.
NODE_TERRAIN_SUFFIXES = ('.tif', '.tiff', '.asc')


@dataclass(frozen=True, eq=False)
class TerrainState:
    """The terrain in force, or why ``terrain_file`` was refused.

    Attributes
    ----------
    file : str
        The ``terrain_file`` value ('' = no terrain).
    key : tuple
        What the terrain was read for (:func:`terrain_key`).
    field : HeightField, optional
        The terrain over the bounds (side ``'below'``, label ``'terrain'``); None without a
        file or when refused.
    refusal : str
        Why the file was refused ('' when it was not).
    """

    file: str = ''
    key: Tuple[Any, ...] = ()
    field: Optional[HeightField] = None
    refusal: str = ''


def terrain_key(file: str, config: PlannerConfig, origin_value: Any) -> Tuple[Any, ...]:
    """What the terrain depends on: the file, the bounds' x/y extent [m] and the geodetic origin
    value (None when not set); a change means reading the file again."""
    origin = None if origin_value is None else tuple(float(v) for v in origin_value)
    return (file.strip(), tuple(float(v) for v in config.bounds_min[:2]),
            tuple(float(v) for v in config.bounds_max[:2]), origin)


def read_terrain(file: str, config: PlannerConfig, origin_value: Any) -> TerrainState:
    """Read ``terrain_file`` over the bounds of ``config``.

    Parameters
    ----------
    file : str
        The parameter's value ('' = no terrain).
    config : PlannerConfig
        The bounds the lattice must cover.
    origin_value : sequence of float or None
        The ``geodetic_origin`` parameter ([lat deg, lon deg, alt m AMSL]) or None.

    Returns
    -------
    TerrainState
        With the height field, or with the reason the file was refused (never raises for a
        file: an unreadable, uncovering or holed DEM, a missing rasterio, an ``.npy`` file).
    """
    key = terrain_key(file, config, origin_value)
    name = file.strip()
    if not name:
        return TerrainState(key=key)
    try:
        field = _load(Path(name).expanduser(), config, origin_value)
    except InvalidInputError as error:
        return TerrainState(name, key, None, str(error))
    return TerrainState(name, key, field)


def _load(path: Path, config: PlannerConfig, origin_value: Any) -> HeightField:
    suffix = path.suffix.lower()
    if suffix == '.npy':
        raise InvalidInputError(
            f'{path}: an .npy terrain needs its map-frame origin and spacing, which a '
            'parameter cannot give beside the file: write it as a GeoTIFF or an ESRI ASCII '
            'grid (.asc), which place themselves')
    if suffix not in NODE_TERRAIN_SUFFIXES:
        raise InvalidInputError(f'{path}: not a terrain file: the formats are '
                                f'{", ".join(NODE_TERRAIN_SUFFIXES)}')
    origin = origin_from_value(origin_value)
    return load_dem(path, config.bounds_min[:2], config.bounds_max[:2], origin)


def terrain_values(state: Optional[TerrainState]) -> Dict[str, object]:
    """The terrain's key values for the map status on ``/diagnostics`` (empty without a
    ``terrain_file``)."""
    if state is None or not state.file:
        return {}
    if state.refusal:
        return {'terrain_file_status': 'refused', 'terrain_file': state.file,
                'terrain_file_refused': state.refusal}
    field = state.field
    assert field is not None
    lo, hi = field.extent
    heights = np.asarray(field.heights)
    return {'terrain_file_status': 'ok', 'terrain_file': state.file,
            'terrain_extent_min': np.array(lo[:2], dtype=np.float64),
            'terrain_extent_max': np.array(hi[:2], dtype=np.float64),
            'terrain_spacing_m': np.array(field.spacing, dtype=np.float64),
            'terrain_height_min_m': float(heights.min()),
            'terrain_height_max_m': float(heights.max())}


def describe_terrain(state: TerrainState) -> str:
    """One line for the log: the file, its lattice and its heights."""
    if state.field is None:
        return f'terrain {state.file}: refused ({state.refusal})' if state.refusal else ''
    field = state.field
    ny, nx = np.asarray(field.heights).shape
    return (f'terrain {state.file}: {nx} x {ny} heights every {field.spacing[0]:g} x '
            f'{field.spacing[1]:g} m, {float(np.min(field.heights)):.1f} to '
            f'{float(np.max(field.heights)):.1f} m')
