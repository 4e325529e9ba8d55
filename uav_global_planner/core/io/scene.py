"""Scene files: YAML descriptions of a workspace, its obstacles, a start and a goal.

Format (every key below is required except ``description``, ``frame_id`` and ``obstacles``)::

    frame_id: map
    bounds: {min: [-10.0, -10.0, 0.0], max: [10.0, 10.0, 15.0]}
    resolution: 0.5          # delta [m]
    safety_margin: 0.2       # gamma [m]
    adaptive_threshold: 1.5  # eta [m]
    start: [0.0, -5.0, 0.0]
    goal: [10.0, 5.0, 10.0]
    obstacles:
      - {type: sphere, center: [2.3, -2.9, 2.1], radius: 2.35}
      - {type: box, min: [1.0, 1.0, 0.0], max: [2.0, 3.0, 4.0]}
      - {type: points, points: [[0.0, 0.0, 1.0], [0.1, 0.0, 1.0]]}
      - {type: points_file, path: maps/site.las, downsample: 0.2}   # downsample optional
    geodetic_origin: {lat: 47.3977, lon: 8.5456, alt_amsl: 488.0}   # optional: WGS84 of x=y=z=0
    geofence:                                   # optional, see core/map/airspace.py
      inclusion: {polygon: [[x, y], ...], floor: 0.0, ceiling: 120.0}
      exclusion:
        - {type: prism, polygon: [[x, y], ...], floor: 0.0, ceiling: 60.0}
        - {type: cylinder, center: [x, y], radius: 30.0, floor: 0.0, ceiling: 200.0}
        - {type: box, min: [x, y, z], max: [x, y, z]}
    cost: {climb_weight: 1.0, descent_weight: 1.0}   # optional, the energy-aware step cost
    known_volume: [{min: [x, y, z], max: [x, y, z]}]  # optional: outside them is unknown
    unknown_space: occupied  # optional: occupied (default), free or cost; map/unknown_space.py
    vehicle: {mass: 1.5, hover_power: 180.0}         # optional [kg], [W], see core/path/energy.py
    planner: {smoothing: chord, max_speed_horizontal: 2.0}   # optional, any key listed below
    ground: floor            # optional: none (default), floor or a height [m]; core/map/ground.py
    terrain: {file: dem.tif}  # optional DEM (.tif, .asc; .npy with origin, spacing); map/dem.py
    min_agl: 10.0            # optional height band above the ground [m], 0 = off
    max_agl: 120.0

``max_voxels`` (an integer) raises or lowers the grid's node cap. Which settings a scene may
give, and where, is the ``scene_key`` of each entry of the settings table
(:data:`uav_global_planner.core.settings.PLANNER_SETTINGS`): the keys above, and under
``planner:`` search_weight, max_expansions, max_planning_time, shortcut, smoothing,
sample_spacing, index_step, start_tolerance and the four speed and acceleration limits. Each is
checked by the table, so a scene accepts exactly what the node and ``uav-plan`` accept. A
``points_file`` path is resolved against the scene file's folder; its formats and margins
are those of :mod:`uav_global_planner.core.io.mapfiles`. A map's margin (OctoMap cells,
downsampling: every occupied location lies within it of a point) is added to the safety margin,
so the planner keeps gamma from what the file describes; :attr:`Scene.map_margin_m` says how
much was added.

Unknown keys or obstacle types, missing keys and wrong types raise
:class:`~uav_global_planner.core.errors.InvalidInputError` whose message starts with the key path,
for example ``obstacles[2].radius: must be a number > 0 m``.
"""

from dataclasses import dataclass, field, replace
from importlib import resources
import math
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Set, Tuple, Union

import numpy as np
import yaml

from uav_global_planner.core.checks import check_number
from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import GeodeticOrigin
from uav_global_planner.core.io.geofence import parse_geofence
from uav_global_planner.core.io.mapfiles import load_map_points, MapReport
from uav_global_planner.core.io.text_files import parse_text_file
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.dem import load_dem, parse_terrain
from uav_global_planner.core.map.ground import ground_obstacles
from uav_global_planner.core.map.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner.core.map.unknown_space import scene_unknown, UnknownSpace
from uav_global_planner.core.path.energy import VehicleModel
from uav_global_planner.core.settings import planner_settings, Setting

# Top-level keys that are scene data, not settings; the settings' keys come from the table.
_DATA_KEYS = ('description', 'frame_id', 'start', 'goal', 'obstacles', 'geodetic_origin', 'via',
              'geofence', 'terrain', 'known_volume')
_OBSTACLE_KEYS = {'sphere': ('center', 'radius'), 'box': ('min', 'max'), 'points': ('points',),
                  'points_file': ('path',)}
_OPTIONAL_OBSTACLE_KEYS = {'points_file': ('downsample',)}

# libyaml's parser where PyYAML was built with it: several times faster on inline point lists.
_YAML_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)

#: The shipped configuration (planner.yaml, scenes/) in a source checkout, beside the package.
_SOURCE_CONFIG = Path(__file__).resolve().parents[3] / 'config'


@dataclass(frozen=True, eq=False)
class Scene:
    """A parsed scene file.

    Attributes
    ----------
    name : str
        File name without extension.
    description : str
    frame_id : str
        Frame of every coordinate in the file.
    config : PlannerConfig
        Default planner settings with the scene's bounds, delta, gamma and eta.
    start, goal : numpy.ndarray, shape (3,)
        [m]
    obstacles : ObstacleSet
    map_margin_m : float
        Largest margin of the scene's map files [m], already added to
        ``config.safety_margin``; an override of gamma adds it again.
    geodetic_origin : GeodeticOrigin or None
        WGS84 latitude, longitude [deg] and AMSL altitude [m] of the frame's origin (key
        ``geodetic_origin: {lat, lon, alt_amsl}``); None when the scene has none.
    via : numpy.ndarray, shape (V, 3)
        Via-points between start and goal, in order [m] (key ``via: [[x, y, z], ...]``).
    airspace : Airspace
        The ``geofence`` key's fences and zones, already in ``obstacles``.
    vehicle : VehicleModel
        The ``vehicle`` key's mass and hover power, for energy estimates.
    terrain : HeightField or None
        The ``terrain`` key's DEM over the bounds (:mod:`uav_global_planner.core.map.dem`).
    ground : tuple of HeightField
        The ground (the terrain, or the flat ground of ``config.ground``), the AGL floor and
        the AGL ceiling (:func:`uav_global_planner.core.map.ground.ground_obstacles`), already in
        ``obstacles``.
    map_reports : tuple of MapReport
        What each map file (``points_file`` obstacles, in order) read, dropped and kept.
    unknown : UnknownSpace or None
        Space the scene's OctoMap files never observed and space outside its
        ``known_volume`` boxes (:mod:`uav_global_planner.core.map.unknown_space`), within the
        bounds; None when it declares neither. What the planner does with it is
        ``config.unknown_space``.
    """

    name: str
    description: str
    frame_id: str
    config: PlannerConfig
    start: np.ndarray
    goal: np.ndarray
    obstacles: ObstacleSet
    map_margin_m: float = 0.0
    geodetic_origin: Optional[GeodeticOrigin] = None
    via: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    airspace: Airspace = field(default_factory=Airspace)
    vehicle: VehicleModel = field(default_factory=VehicleModel)
    terrain: Optional[HeightField] = None
    ground: Tuple[HeightField, ...] = ()
    map_reports: Tuple[MapReport, ...] = ()
    unknown: Optional[UnknownSpace] = None


def _fail(path: str, reason: str) -> InvalidInputError:
    return InvalidInputError(f'{path}: {reason}')


def _number(value: Any, path: str, low: float = -math.inf, **range_words: Any) -> float:
    """:func:`~uav_global_planner.core.checks.check_number` of a value at key ``path``."""
    return check_number(f'{path}:', value, low, **range_words)


def _vector(value: Any, path: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3:
        raise _fail(path, f'must be a list of three numbers [x, y, z], got {value!r}')
    return np.array([_number(item, f'{path}[{axis}]') for axis, item in enumerate(value)])


def _mapping(value: Any, path: str, allowed: set) -> dict:
    if not isinstance(value, dict):
        raise _fail(path, f'must be a mapping, got {type(value).__name__}')
    unknown = sorted(str(key) for key in value if key not in allowed)
    if unknown:
        raise _fail(path, f'unknown key(s) {", ".join(unknown)}; allowed: '
                    f'{", ".join(sorted(allowed))}')
    return value


def _require(mapping: dict, key: str, path: str) -> Any:
    if key not in mapping:
        raise _fail(f'{path}.{key}' if path else key, 'missing required key')
    return mapping[key]


def _obstacle(entry: Any, path: str, folder: Optional[Path] = None,
              config: Optional[PlannerConfig] = None,
              reports: Optional[List[MapReport]] = None) -> Tuple[Obstacle, float]:
    """One obstacle and its margin [m] (non-zero only for map files, see mapfiles); a map
    file is checked against ``config`` and its report appended to ``reports``."""
    if not isinstance(entry, dict):
        raise _fail(path, f'must be a mapping with a type, got {type(entry).__name__}')
    kind = _require(entry, 'type', path)
    if kind not in _OBSTACLE_KEYS:
        raise _fail(f'{path}.type', f'unknown obstacle type {kind!r}; allowed: '
                    f'{", ".join(_OBSTACLE_KEYS)}')
    _mapping(entry, path, {'type', *_OBSTACLE_KEYS[kind], *_OPTIONAL_OBSTACLE_KEYS.get(kind, ())})
    values = {key: _require(entry, key, path) for key in _OBSTACLE_KEYS[kind]}
    if kind == 'points_file':
        return _points_file(entry, values['path'], path, folder, config, reports)
    if kind == 'sphere':
        center = _vector(values['center'], f'{path}.center')
        radius = _number(values['radius'], f'{path}.radius', 0.0, low_open=True, unit='m')
        return Sphere(center, radius), 0.0
    if kind == 'box':
        lo = _vector(values['min'], f'{path}.min')
        hi = _vector(values['max'], f'{path}.max')
        if np.any(lo >= hi):
            raise _fail(path, f'min must be below max on every axis, got min {lo.tolist()} '
                        f'and max {hi.tolist()}')
        return Box(lo, hi), 0.0
    points = values['points']
    if not isinstance(points, list):
        raise _fail(f'{path}.points', 'must be a list of [x, y, z] triples')
    return PointSet(np.array([_vector(p, f'{path}.points[{n}]') for n, p in enumerate(points)])
                    .reshape(-1, 3)), 0.0


def _points_file(entry: dict, file: Any, path: str, folder: Optional[Path],
                 config: Optional[PlannerConfig] = None,
                 reports: Optional[List[MapReport]] = None) -> Tuple[PointSet, float]:
    if not isinstance(file, str) or not file.strip():
        raise _fail(f'{path}.path', f'must be a file name, got {file!r}')
    downsample = entry.get('downsample')
    if downsample is not None:
        downsample = _number(downsample, f'{path}.downsample', 0.0, low_open=True,
                             accepted='a cell size > 0 m')
    location = Path(file).expanduser()
    if not location.is_absolute() and folder is not None:
        location = folder / location
    try:
        if config is None:
            loaded = load_map_points(location, downsample)
        else:
            # gamma as asked (the map margins are added after the files are read).
            loaded = load_map_points(location, downsample,
                                     bounds=(config.bounds_min, config.bounds_max),
                                     reach=config.safety_margin, resolution=config.resolution)
    except InvalidInputError as error:
        raise type(error)(f'{path}.path: {error}') from None
    if reports is not None:
        reports.extend(loaded.reports)
    return loaded.obstacle(), loaded.margin_m


def _scene_settings() -> List[Setting]:
    """The settings a scene file may give, in table order."""
    return [entry for entry in planner_settings() if entry.scene_key and entry.field]


def _setting_values(top: dict, overridden: Set[str]) -> dict:
    """The scene's settings as PlannerConfig fields, each checked by its table entry.

    Sections (``bounds``, ``cost``, ``vehicle``, ``planner``) must be mappings of known keys;
    settings in ``overridden`` are replaced by command-line values, so they are not checked.
    """
    entries = _scene_settings()
    sections: Dict[str, Set[str]] = {}
    for entry in entries:
        head, _, tail = str(entry.scene_key).partition('.')
        if tail:
            sections.setdefault(head, set()).add(tail)
    required = {str(e.scene_key).partition('.')[0] for e in entries if e.scene_required}
    for head, keys in sections.items():
        # An optional section left empty (``cost:``) gives nothing; a required one must be there.
        if top.get(head) is not None or (head in top and head in required):
            _mapping(top[head], head, keys)
    values = {}
    for entry in entries:
        path = str(entry.scene_key)
        head, _, tail = path.partition('.')
        holder = top.get(head) if tail else top
        key = tail or head
        if not isinstance(holder, dict) or key not in holder:
            if entry.scene_required:
                _require(holder if isinstance(holder, dict) else {}, key, head if tail else '')
            continue
        if entry.field not in overridden:
            values[entry.field] = entry.check_key(holder[key], path)
    return values


def _allowed_top_keys() -> Set[str]:
    return {*_DATA_KEYS, *(str(e.scene_key).partition('.')[0] for e in _scene_settings())}


def _required_top_keys() -> List[str]:
    keys = [str(e.scene_key).partition('.')[0] for e in _scene_settings() if e.scene_required]
    return list(dict.fromkeys(keys + ['start', 'goal']))


def parse_scene(data: Any, name: str = 'scene', base: PlannerConfig = PlannerConfig(),
                folder: Optional[Path] = None,
                overrides: Optional[Mapping[str, Any]] = None,
                terrain_file: Optional[Union[str, Path]] = None) -> Scene:
    """Validate a scene already loaded from YAML.

    Parameters
    ----------
    data : Any
        The YAML document.
    name : str
        Name used in messages and reports.
    base : PlannerConfig
        Settings the scene does not define (algorithm, budgets, smoothing, limits).
    folder : Path, optional
        Folder that relative ``points_file`` paths start from; the working directory if None.
    overrides : mapping of str to Any, optional
        :class:`PlannerConfig` fields that replace the scene's own (command-line options), applied
        before validation, so an override can lift a cap the scene's values exceed.
    terrain_file : str or Path, optional
        A DEM (GeoTIFF or ``.asc``, :mod:`uav_global_planner.core.map.dem`) that replaces the
        scene's ``terrain`` key (``uav-plan --terrain``); refusals start with ``--terrain``.

    Raises
    ------
    InvalidInputError
        Naming the key path of the first problem.
    """
    if data is None:
        raise _fail(name, 'the scene file is empty')
    top = _mapping(data, name, _allowed_top_keys())
    for key in _required_top_keys():
        _require(top, key, '')
    frame_id = top.get('frame_id', 'map')
    if not isinstance(frame_id, str) or not frame_id:
        raise _fail('frame_id', f'must be a non-empty string, got {frame_id!r}')
    description = top.get('description', '')
    if not isinstance(description, str):
        raise _fail('description', 'must be a string')
    entries = top.get('obstacles')
    if entries is None:  # the key left out, or left empty: no obstacles
        entries = []
    if not isinstance(entries, list):
        raise _fail('obstacles', f'must be a list, got {type(entries).__name__}')
    overrides = dict(overrides or {})
    config = replace(base, **_setting_values(top, set(overrides)))
    config = replace(config, **overrides)
    # Settings first: a wrong resolution is reported before any map file is read.
    config = validate_config(config)
    start, goal = _vector(top['start'], 'start'), _vector(top['goal'], 'goal')
    via_entries = top.get('via') or []
    if not isinstance(via_entries, list):
        raise _fail('via', f'must be a list of [x, y, z], got {type(via_entries).__name__}')
    via = np.array([_vector(v, f'via[{n}]') for n, v in enumerate(via_entries)]).reshape(-1, 3)
    reports: List[MapReport] = []
    parsed = [_obstacle(e, f'obstacles[{n}]', folder, config, reports)
              for n, e in enumerate(entries)]
    obstacles: List[Obstacle] = [obstacle for obstacle, _ in parsed]
    margin = max((m for _, m in parsed), default=0.0)
    if margin > 0.0:
        config = validate_config(replace(config, safety_margin=config.safety_margin + margin))
    airspace = parse_geofence(top.get('geofence'))
    vehicle = VehicleModel(config.vehicle_mass, config.hover_power)
    origin = None
    if top.get('geodetic_origin') is not None:
        keys = _mapping(top['geodetic_origin'], 'geodetic_origin', {'lat', 'lon', 'alt_amsl'})
        origin = GeodeticOrigin(*(_number(_require(keys, key, 'geodetic_origin'),
                                          f'geodetic_origin.{key}')
                                  for key in ('lat', 'lon', 'alt_amsl')))
    terrain = None
    if terrain_file is not None:
        terrain = _terrain({'file': str(terrain_file)}, config, origin, None, '--terrain')
    elif top.get('terrain') is not None:
        terrain = _terrain(top['terrain'], config, origin, folder)
    scene = Scene(name=name, description=description, frame_id=frame_id, config=config,
                  start=start, goal=goal,
                  obstacles=ObstacleSet(obstacles + list(airspace.shapes())),
                  map_margin_m=margin, geodetic_origin=origin, via=via, airspace=airspace,
                  vehicle=vehicle, map_reports=tuple(reports))
    scene = replace(scene, unknown=_unknown_space(top, entries, folder, config))
    return with_ground(scene, terrain)


def _unknown_space(top: dict, entries: list, folder: Optional[Path],
                   config: PlannerConfig) -> Optional[UnknownSpace]:
    """The scene's unknown space: outside ``known_volume``, and the OctoMap files' unknown
    cells (the entries are valid obstacles already)."""
    files = []
    for entry in entries:
        if entry.get('type') == 'points_file':
            location = Path(entry['path']).expanduser()
            files.append(location if location.is_absolute() or folder is None
                         else folder / location)
    return scene_unknown(top.get('known_volume'), files, config.bounds_min, config.bounds_max)


def _terrain(value: Any, config: PlannerConfig, origin: Optional[GeodeticOrigin],
             folder: Optional[Path], path: str = 'terrain') -> HeightField:
    """The ``terrain`` key's DEM as a height field over the bounds' x/y extent."""
    source = parse_terrain(value, folder, path)
    try:
        return load_dem(source, config.bounds_min[:2], config.bounds_max[:2], origin)
    except InvalidInputError as error:
        where = f'{path}.file' if path == 'terrain' else path
        raise type(error)(f'{where}: {error}') from None


def with_ground(scene: Scene, terrain: Optional[HeightField] = None) -> Scene:
    """``scene`` with its ground, AGL floor and AGL ceiling made again from its config and
    ``terrain`` (:func:`uav_global_planner.core.map.ground.ground_obstacles`), replacing its own:
    after a change of the planning margin or of the terrain.

    Parameters
    ----------
    scene : Scene
    terrain : HeightField, optional
        The terrain (pass ``scene.terrain`` to keep the scene's own); None for none.

    Raises
    ------
    InvalidInputError
        For a height band without a ground, or a flat ground above the bounds.
    """
    own = {id(shape) for shape in scene.ground}
    others = [item for item in scene.obstacles.items if id(item) not in own]
    config = scene.config
    shapes = ground_obstacles(config, terrain)
    if not own and not shapes:
        return replace(scene, terrain=terrain)
    return replace(scene, obstacles=ObstacleSet(others + list(shapes)), terrain=terrain,
                   ground=shapes)


def load_scene(path: Union[str, Path], base: PlannerConfig = PlannerConfig(),
               overrides: Optional[Mapping[str, Any]] = None,
               terrain_file: Optional[Union[str, Path]] = None) -> Scene:
    """Read and validate a scene file (``base``, ``overrides`` and ``terrain_file`` as in
    :func:`parse_scene`).

    Raises
    ------
    InvalidInputError
        For an unreadable file, a file that is not UTF-8 text, text that is not YAML, or any
        invalid key (named by its path).
    """
    file = Path(path)
    data = parse_text_file(
        file, 'scene file', lambda text: yaml.load(text, Loader=_YAML_LOADER),  # noqa: S506
        yaml.YAMLError, 'not valid YAML',
        not_text='not a text file, so not a scene file ({reason} at byte {start})')
    return parse_scene(data, name=file.stem, base=base, folder=file.resolve().parent,
                       overrides=overrides, terrain_file=terrain_file)


def shipped_config_dirs() -> List[Path]:
    """Folders that may hold the shipped configuration (``planner.yaml``, ``scenes/``).

    The package data of an installed package (``pip install``, ``colcon build``: setup.py ships
    ``config/`` as ``uav_global_planner/config``), found with :mod:`importlib.resources`, then
    the ``config`` folder of a source checkout. The ament share copy is not needed for either.
    """
    folders = []
    data = resources.files('uav_global_planner') / 'config'
    if isinstance(data, Path) and data.is_dir():
        folders.append(data)
    folders.append(_SOURCE_CONFIG)
    return folders


def shipped_scene_dirs() -> List[Path]:
    """Folders that may hold the shipped scenes, in the order of :func:`shipped_config_dirs`."""
    return [folder / 'scenes' for folder in shipped_config_dirs()]


def find_scene(name_or_path: Union[str, Path]) -> Path:
    """Resolve a scene file path, or the name of a shipped scene such as ``paper_medium``.

    A shipped scene is found by its bare name only. Text that names a path (it holds a folder
    separator or ends in ``.yaml`` / ``.yml``) is a file that must exist: a mistyped path is
    refused, never replaced by a shipped scene of the same name.

    Raises
    ------
    InvalidInputError
        When the file does not exist (or is a folder), or the name is no shipped scene; the
        message lists the shipped scenes.
    """
    candidate = Path(name_or_path)
    if candidate.is_file():
        return candidate
    text = str(name_or_path)
    if any(sep in text for sep in ('/', '\\')) or candidate.suffix in ('.yaml', '.yml'):
        if candidate.is_dir():
            raise InvalidInputError(f'{text}: is a folder, not a scene file')
        shipped = [path for path in shipped_scenes() if path.stem == candidate.stem]
        hint = (f'; the shipped scene of that name is given by its name alone: '
                f'{candidate.stem}' if shipped else '')
        raise InvalidInputError(f'{text}: no such scene file{hint}')
    for folder in shipped_scene_dirs():
        shipped_file = folder / f'{text}.yaml'
        if shipped_file.is_file():
            return shipped_file
    names = ', '.join(path.stem for path in shipped_scenes())
    raise InvalidInputError(f'{text}: no such scene file or shipped scene (shipped scenes: '
                            f'{names})')


def shipped_scenes() -> List[Path]:
    """Every shipped scene file, sorted by name."""
    for folder in shipped_scene_dirs():
        if folder.is_dir():
            return sorted(folder.glob('*.yaml'))
    return []
