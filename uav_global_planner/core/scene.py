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

Unknown keys or obstacle types, missing keys and wrong types raise
:class:`~uav_global_planner.core.errors.InvalidInputError` whose message starts with the key path,
for example ``obstacles[2].radius: must be a number > 0 m``.
"""

from dataclasses import dataclass, replace
import math
from pathlib import Path
from typing import Any, List, Union

import numpy as np
import yaml

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere

_TOP_KEYS = {'description', 'frame_id', 'bounds', 'resolution', 'safety_margin',
             'adaptive_threshold', 'start', 'goal', 'obstacles'}
_REQUIRED_KEYS = ('bounds', 'resolution', 'safety_margin', 'adaptive_threshold', 'start', 'goal')
_OBSTACLE_KEYS = {'sphere': ('center', 'radius'), 'box': ('min', 'max'), 'points': ('points',)}

#: Folder of the scenes shipped with the package, in a source checkout.
_SOURCE_SCENES = Path(__file__).resolve().parents[2] / 'config' / 'scenes'


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
    """

    name: str
    description: str
    frame_id: str
    config: PlannerConfig
    start: np.ndarray
    goal: np.ndarray
    obstacles: ObstacleSet


def _fail(path: str, reason: str) -> InvalidInputError:
    return InvalidInputError(f'{path}: {reason}')


def _number(value: Any, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(path, f'must be a number, got {value!r}')
    if not math.isfinite(value):
        raise _fail(path, f'must be finite, got {value!r}')
    return float(value)


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


def _obstacle(entry: Any, path: str) -> Obstacle:
    if not isinstance(entry, dict):
        raise _fail(path, f'must be a mapping with a type, got {type(entry).__name__}')
    kind = _require(entry, 'type', path)
    if kind not in _OBSTACLE_KEYS:
        raise _fail(f'{path}.type', f'unknown obstacle type {kind!r}; allowed: '
                    f'{", ".join(_OBSTACLE_KEYS)}')
    _mapping(entry, path, {'type', *_OBSTACLE_KEYS[kind]})
    values = {key: _require(entry, key, path) for key in _OBSTACLE_KEYS[kind]}
    if kind == 'sphere':
        center = _vector(values['center'], f'{path}.center')
        radius = _number(values['radius'], f'{path}.radius')
        if radius <= 0.0:
            raise _fail(f'{path}.radius', f'must be > 0 m, got {radius}')
        return Sphere(center, radius)
    if kind == 'box':
        lo = _vector(values['min'], f'{path}.min')
        hi = _vector(values['max'], f'{path}.max')
        if np.any(lo >= hi):
            raise _fail(path, f'min must be below max on every axis, got min {lo.tolist()} '
                        f'and max {hi.tolist()}')
        return Box(lo, hi)
    points = values['points']
    if not isinstance(points, list):
        raise _fail(f'{path}.points', 'must be a list of [x, y, z] triples')
    return PointSet(np.array([_vector(p, f'{path}.points[{n}]') for n, p in enumerate(points)])
                    .reshape(-1, 3))


def parse_scene(data: Any, name: str = 'scene',
                base: PlannerConfig = PlannerConfig()) -> Scene:
    """Validate a scene already loaded from YAML.

    Parameters
    ----------
    data : Any
        The YAML document.
    name : str
        Name used in messages and reports.
    base : PlannerConfig
        Settings the scene does not define (algorithm, budgets, smoothing, limits).

    Raises
    ------
    InvalidInputError
        Naming the key path of the first problem.
    """
    if data is None:
        raise _fail(name, 'the scene file is empty')
    top = _mapping(data, name, _TOP_KEYS)
    for key in _REQUIRED_KEYS:
        _require(top, key, '')
    bounds = _mapping(top['bounds'], 'bounds', {'min', 'max'})
    lo = _vector(_require(bounds, 'min', 'bounds'), 'bounds.min')
    hi = _vector(_require(bounds, 'max', 'bounds'), 'bounds.max')
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
    obstacles: List[Obstacle] = [_obstacle(e, f'obstacles[{n}]') for n, e in enumerate(entries)]
    config = replace(base, bounds_min=tuple(lo), bounds_max=tuple(hi),
                     resolution=_number(top['resolution'], 'resolution'),
                     safety_margin=_number(top['safety_margin'], 'safety_margin'),
                     adaptive_threshold=_number(top['adaptive_threshold'],
                                                'adaptive_threshold'))
    return Scene(name=name, description=description, frame_id=frame_id,
                 config=validate_config(config), start=_vector(top['start'], 'start'),
                 goal=_vector(top['goal'], 'goal'), obstacles=ObstacleSet(obstacles))


def load_scene(path: Union[str, Path], base: PlannerConfig = PlannerConfig()) -> Scene:
    """Read and validate a scene file.

    Raises
    ------
    InvalidInputError
        For an unreadable file, a file that is not UTF-8 text, text that is not YAML, or any
        invalid key (named by its path).
    """
    file = Path(path)
    try:
        text = file.read_text(encoding='utf-8')
    except OSError as error:
        raise InvalidInputError(f'{file}: cannot read scene file ({error.strerror})') from None
    except UnicodeDecodeError as error:
        raise InvalidInputError(f'{file}: not a text file, so not a scene file ({error.reason} '
                                f'at byte {error.start})') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise InvalidInputError(f'{file}: not valid YAML ({error})') from None
    return parse_scene(data, name=file.stem, base=base)


def shipped_scene_dirs() -> List[Path]:
    """Folders that may hold the shipped scenes: the source tree, then the ament share folder."""
    folders = [_SOURCE_SCENES]
    try:
        from ament_index_python.packages import get_package_share_directory
        folders.append(Path(get_package_share_directory('uav_global_planner')) / 'config'
                       / 'scenes')
    except Exception:  # noqa: BLE001 - no ament index (plain venv): the source tree is enough
        pass
    return folders


def find_scene(name_or_path: Union[str, Path]) -> Path:
    """Resolve a scene file path, or the name of a shipped scene such as ``paper_medium``.

    Raises
    ------
    InvalidInputError
        When neither a file nor a shipped scene of that name exists.
    """
    candidate = Path(name_or_path)
    if candidate.is_file():
        return candidate
    stem = candidate.name[:-5] if candidate.name.endswith('.yaml') else candidate.name
    for folder in shipped_scene_dirs():
        shipped = folder / f'{stem}.yaml'
        if shipped.is_file():
            return shipped
    raise InvalidInputError(f'{name_or_path}: no such scene file or shipped scene')


def shipped_scenes() -> List[Path]:
    """Every shipped scene file, sorted by name."""
    for folder in shipped_scene_dirs():
        if folder.is_dir():
            return sorted(folder.glob('*.yaml'))
    return []
