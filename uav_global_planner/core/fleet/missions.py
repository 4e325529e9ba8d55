"""A fleet's missions and the deconfliction settings, from YAML or a mapping, validated.

A batch file::

    scene: city1km            # optional: the map the missions fly over
    now_s: 0.0                # optional: the batch clock's present [s]
    bounds: {min: [x, y, z], max: [x, y, z]}   # optional: the map's bounds [m]
    settings: {horizontal_separation: 30.0, vertical_separation: 10.0, ...}
    missions:
      - {name: m1, vehicle: uav1, departure_s: 0.0, start: [x, y, z], goal: [x, y, z],
         via: [[x, y, z]], priority: 0}

Coordinates are in the map's ENU frame [m]; departures in seconds on the batch clock. A bad
setting is an :class:`~uav_global_planner.core.errors.InvalidInputError` naming it (the batch
cannot be deconflicted without it); a bad mission is a :class:`MissionError` naming the mission
and the setting, and the rest of the batch goes on.
"""

from dataclasses import dataclass, field, fields
import math
from pathlib import Path
from typing import Any, cast, Dict, List, Mapping, Optional, Sequence, Set, Tuple, Union

import numpy as np
import yaml

from uav_global_planner.core.checks import (check_non_negative, check_number, check_point,
                                            check_positive, integer_refusal, number_refusal)
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.fleet.separation import Envelope

_YAML_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
_TOP_KEYS = {'scene', 'now_s', 'bounds', 'settings', 'missions'}
_MISSION_KEYS = {'name', 'vehicle', 'departure_s', 'start', 'goal', 'via', 'priority'}

Bounds = Tuple[Sequence[float], Sequence[float]]


@dataclass(frozen=True, eq=False)
class Mission:
    """One vehicle's flight request.

    Attributes
    ----------
    name : str
        Unique in the batch.
    vehicle : str
        The vehicle that flies it.
    departure_s : float
        Earliest departure on the batch clock [s].
    start, goal : numpy.ndarray, shape (3,)
        [m], ENU map frame.
    via : numpy.ndarray, shape (V, 3)
        Via-points in order [m].
    priority : int
        Larger is planned first.
    """

    name: str
    vehicle: str
    departure_s: float
    start: np.ndarray
    goal: np.ndarray
    via: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    priority: int = 0

    def order_key(self) -> Tuple[int, float, str]:
        """The fleet order: priority (larger first), then departure, then name."""
        return (-int(self.priority), float(self.departure_s), self.name)


#: The settings of :class:`FleetSettings` that must be > 0, and their units.
_POSITIVE_SETTINGS = {'horizontal_separation': 'm', 'vertical_separation': 'm',
                      'delay_step_s': 's', 'time_tolerance_s': 's', 'index_cell_m': 'm',
                      'index_cell_z_m': 'm', 'index_cell_s': 's'}


@dataclass(frozen=True)
class FleetSettings:
    """Separation and resolution settings of a batch.

    Attributes
    ----------
    horizontal_separation, vertical_separation : float
        The envelope [m], > 0: two flights conflict when, at one instant, both their
        horizontal and their vertical distance are below these.
    max_delay_s : float
        Largest delay of a departure [s], >= 0.
    delay_step_s : float
        Delays tried are multiples of this [s], > 0.
    altitude_layers : tuple of float
        Altitude offsets tried in order [m], each nonzero: the mission is replanned through
        its start, via-points and goal raised by the offset.
    speed_factors : tuple of float
        Speed factors tried in order, each in (0, 1): the same curve flown slower.
    time_tolerance_s : float
        Certification resolution [s], > 0: a stretch shorter than this that can be proven
        neither apart nor in conflict counts as a conflict.
    index_cell_m, index_cell_z_m, index_cell_s : float
        Cell sizes of the space-time index [m], [m], [s], > 0.
    """

    horizontal_separation: float = 30.0
    vertical_separation: float = 10.0
    max_delay_s: float = 300.0
    delay_step_s: float = 10.0
    altitude_layers: Tuple[float, ...] = (10.0, 20.0)
    speed_factors: Tuple[float, ...] = (0.8, 0.6)
    time_tolerance_s: float = 1e-3
    index_cell_m: float = 100.0
    index_cell_z_m: float = 50.0
    index_cell_s: float = 30.0

    def __post_init__(self) -> None:
        for name, unit in _POSITIVE_SETTINGS.items():
            object.__setattr__(self, name, check_positive(f'settings.{name}', getattr(self, name),
                                                          unit, convert=False))
        object.__setattr__(self, 'max_delay_s', check_non_negative(
            'settings.max_delay_s', self.max_delay_s, 's', convert=False))
        layers = _number_tuple(self.altitude_layers, 'altitude_layers')
        if any(layer == 0.0 for layer in layers):
            raise InvalidInputError('settings.altitude_layers must be nonzero offsets [m]')
        factors = _number_tuple(self.speed_factors, 'speed_factors', 0.0, 1.0)
        object.__setattr__(self, 'altitude_layers', layers)
        object.__setattr__(self, 'speed_factors', factors)

    @property
    def envelope(self) -> Envelope:
        """The separation envelope [m]."""
        return Envelope(self.horizontal_separation, self.vertical_separation)

    def delays(self) -> np.ndarray:
        """Delays tried, 0 first [s]."""
        count = int(math.floor(self.max_delay_s / self.delay_step_s + 1e-9))
        return np.arange(count + 1) * self.delay_step_s


@dataclass(frozen=True)
class MissionError:
    """Why one mission of a batch was refused.

    Attributes
    ----------
    mission : str
        The mission's name (or ``missions[i]`` when it has none).
    setting : str
        The offending key.
    message : str
    """

    mission: str
    setting: str
    message: str

    def __str__(self) -> str:
        return f'{self.mission}: {self.setting}: {self.message}'


@dataclass(frozen=True, eq=False)
class MissionBatch:
    """A loaded batch.

    Attributes
    ----------
    missions : tuple of Mission
        The valid missions, in file order.
    errors : tuple of MissionError
        The refused ones.
    settings : FleetSettings
    now_s : float
        The batch clock's present [s]; a departure before it is refused.
    scene : str or None
        The scene named by the file.
    bounds : tuple of numpy.ndarray or None
        Map bounds (min, max) [m] the missions were checked against.
    """

    missions: Tuple[Mission, ...]
    errors: Tuple[MissionError, ...]
    settings: FleetSettings
    now_s: float = 0.0
    scene: Optional[str] = None
    bounds: Optional[Tuple[np.ndarray, np.ndarray]] = None


def _number_tuple(values: Any, name: str, low: float = -math.inf,
                  high: float = math.inf) -> Tuple[float, ...]:
    """``values`` as a tuple of finite numbers, each in the open range (low, high)."""
    if isinstance(values, (str, bytes)) or not isinstance(values, (list, tuple, np.ndarray)):
        raise InvalidInputError(f'settings.{name} must be a list of numbers, got {values!r}')
    return tuple(check_number(f'settings.{name}[{index}]', value, low, high, low_open=True,
                              high_open=True) for index, value in enumerate(values))


def _point(value: Any, what: str) -> np.ndarray:
    """A point of three numbers [m]; text and true/false are no coordinates."""
    if not _is_numbers(value):
        raise InvalidInputError(f'{what} must be three numbers [x, y, z], got {value!r}')
    return check_point(what, value)


def _is_numbers(value: Any) -> bool:
    try:
        array = np.asarray(value)
    except (ValueError, TypeError):
        return False
    return array.dtype.kind in 'iuf'


def settings_from_mapping(data: Any) -> FleetSettings:
    """:class:`FleetSettings` from a mapping; unknown keys are refused by name."""
    if data is None:
        return FleetSettings()
    if not isinstance(data, Mapping):
        raise InvalidInputError(f'settings must be a mapping, got {type(data).__name__}')
    known = {f.name for f in fields(FleetSettings)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InvalidInputError(f'settings: unknown key(s) {unknown}; known: {sorted(known)}')
    values = dict(data)
    for key in ('altitude_layers', 'speed_factors'):
        if key in values and isinstance(values[key], list):
            values[key] = tuple(values[key])
    return FleetSettings(**values)


def _mission(entry: Any, index: int) -> Mission:
    """One mission from a mapping; raises MissionError."""
    label = f'missions[{index}]'
    if not isinstance(entry, Mapping):
        raise _Refused(label, 'mission', f'must be a mapping, got {type(entry).__name__}')
    name = entry.get('name')
    if not isinstance(name, str) or not name:
        raise _Refused(label, 'name', f'must be a non-empty string, got {name!r}')
    unknown = sorted(set(entry) - _MISSION_KEYS)
    if unknown:
        raise _Refused(name, unknown[0], f'unknown key; known: {sorted(_MISSION_KEYS)}')
    vehicle = entry.get('vehicle')
    if not isinstance(vehicle, str) or not vehicle:
        raise _Refused(name, 'vehicle', f'must be a non-empty string, got {vehicle!r}')
    departure = entry.get('departure_s')
    priority = entry.get('priority', 0)
    for key, reason in (('departure_s', number_refusal(departure)),
                        ('priority', integer_refusal(priority))):
        if reason is not None:
            raise _Refused(name, key, reason)
    points = {}
    for key in ('start', 'goal'):
        if key not in entry:
            raise _Refused(name, key, 'is required')
        try:
            points[key] = _point(entry[key], key)
        except ValueError as error:
            raise _Refused(name, key, str(error)) from None
    via_value = entry.get('via', [])
    try:
        via = np.array([_point(p, 'each via-point') for p in via_value]).reshape(-1, 3)
    except (ValueError, TypeError) as error:
        raise _Refused(name, 'via', str(error)) from None
    return Mission(name=name, vehicle=vehicle, departure_s=float(cast(float, departure)),
                   start=points['start'], goal=points['goal'], via=via, priority=int(priority))


class _Refused(Exception):
    def __init__(self, mission: str, setting: str, message: str) -> None:
        super().__init__(message)
        self.error = MissionError(mission, setting, message)


def check_missions(missions: Sequence[Mission], *, bounds: Optional[Bounds] = None,
                   now_s: Optional[float] = None, settings: Optional[FleetSettings] = None
                   ) -> Tuple[Tuple[Mission, ...], Tuple[MissionError, ...]]:
    """Split missions into the valid ones and the errors of the others.

    Refused: a duplicate name; a departure before ``now_s``; a start, via-point or goal
    outside ``bounds``; the same vehicle departing twice at one instant; with ``settings``,
    two vehicles departing at one instant from starts within the separation envelope of each
    other. In each case the mission later in :func:`fleet_order` is refused, so the outcome
    does not depend on the order given. A vehicle flying two
    missions whose flights would overlap in time is not refused here (their durations are not
    known yet): resolution treats it as a conflict.

    Parameters
    ----------
    missions : sequence of Mission
    bounds : (array_like, array_like), optional
        Map bounds min and max [m] (ENU).
    now_s : float, optional
        The batch clock's present [s].
    settings : FleetSettings, optional
        The envelope of the check of vehicles overlapping at departure; without it that check
        is not made.
    """
    valid: List[Mission] = []
    errors: List[MissionError] = []
    names: Set[str] = set()
    departures: Dict[Tuple[str, float], str] = {}
    low = high = None
    if bounds is not None:
        low = np.asarray(bounds[0], dtype=np.float64)
        high = np.asarray(bounds[1], dtype=np.float64)
    for mission in fleet_order(missions):
        error = None
        if mission.name in names:
            error = MissionError(mission.name, 'name', 'appears twice in the batch')
        elif now_s is not None and mission.departure_s < now_s:
            error = MissionError(mission.name, 'departure_s',
                                 f'{mission.departure_s:g} s is in the past (now is '
                                 f'{now_s:g} s)')
        elif low is not None and high is not None:
            labelled = [('start', mission.start)]
            labelled += [(f'via[{i}]', p) for i, p in enumerate(mission.via)]
            labelled += [('goal', mission.goal)]
            for label, point in labelled:
                if np.any(point < low) or np.any(point > high):
                    error = MissionError(mission.name, label,
                                         f'{np.round(point, 3).tolist()} is outside the map '
                                         f'{low.tolist()}..{high.tolist()}')
                    break
        slot = (mission.vehicle, mission.departure_s)
        if error is None and slot in departures:
            error = MissionError(mission.name, 'vehicle',
                                 f'{mission.vehicle} already departs at {mission.departure_s:g}'
                                 f' s in mission {departures[slot]}')
        if error is None and settings is not None:
            error = _overlap(mission, valid, settings)
        names.add(mission.name)
        if error is None:
            departures[slot] = mission.name
            valid.append(mission)
        else:
            errors.append(error)
    kept = {id(mission) for mission in valid}
    return tuple(m for m in missions if id(m) in kept), tuple(errors)


def _overlap(mission: Mission, earlier: Sequence[Mission],
             settings: FleetSettings) -> Optional[MissionError]:
    """The error of a mission departing with another from within the envelope."""
    for other in earlier:
        gap = mission.start - other.start
        if (other.departure_s == mission.departure_s
                and math.hypot(gap[0], gap[1]) < settings.horizontal_separation
                and abs(gap[2]) < settings.vertical_separation):
            return MissionError(mission.name, 'start',
                                f'vehicle {mission.vehicle} would overlap vehicle '
                                f'{other.vehicle} of mission {other.name} at departure '
                                f'{mission.departure_s:g} s (starts '
                                f'{math.hypot(gap[0], gap[1]):.2f} m apart horizontally, '
                                f'{abs(gap[2]):.2f} m vertically)')
    return None


def load_missions(source: Union[str, Path, Mapping[str, Any]], *,
                  bounds: Optional[Bounds] = None,
                  now_s: Optional[float] = None) -> MissionBatch:
    """Load and check a batch of missions.

    Parameters
    ----------
    source : str, pathlib.Path or mapping
        A YAML file, or its content.
    bounds : (array_like, array_like), optional
        Map bounds [m]; overrides the file's ``bounds``.
    now_s : float, optional
        The batch clock's present [s]; overrides the file's ``now_s`` (default 0).

    Returns
    -------
    MissionBatch
        Valid missions, and one :class:`MissionError` per refused mission.

    Raises
    ------
    InvalidInputError
        For an unreadable file, a missing ``missions`` list or bad settings (named).
    """
    if isinstance(source, Mapping):
        data: Any = source
        origin = 'missions'
    else:
        origin = str(source)
        try:
            data = yaml.load(Path(source).read_text(), Loader=_YAML_LOADER)
        except OSError as error:
            raise InvalidInputError(f'{origin}: cannot read: {error}') from None
        except yaml.YAMLError as error:
            raise InvalidInputError(f'{origin}: not valid YAML: {error}') from None
    if not isinstance(data, Mapping):
        raise InvalidInputError(f'{origin}: must be a mapping with a missions list')
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise InvalidInputError(f'{origin}: unknown key(s) {unknown}; known: {sorted(_TOP_KEYS)}')
    entries = data.get('missions')
    if not isinstance(entries, list):
        raise InvalidInputError(f'{origin}: missions must be a list')
    settings = settings_from_mapping(data.get('settings'))
    if now_s is None:
        now_s = data.get('now_s', 0.0)
    now_s = check_number(f'{origin}: now_s', now_s)
    scene = data.get('scene')
    if scene is not None and not isinstance(scene, str):
        raise InvalidInputError(f'{origin}: scene must be a string, got {scene!r}')
    if bounds is None and data.get('bounds') is not None:
        box = data['bounds']
        try:
            file_bounds = (_point(box['min'], 'bounds.min'), _point(box['max'], 'bounds.max'))
        except (KeyError, TypeError, ValueError) as error:
            raise InvalidInputError(f'{origin}: bounds must be {{min: [x, y, z], '
                                    f'max: [x, y, z]}}: {error}') from None
        bounds = (file_bounds[0].tolist(), file_bounds[1].tolist())
    parsed: List[Mission] = []
    errors: List[MissionError] = []
    for index, entry in enumerate(entries):
        try:
            parsed.append(_mission(entry, index))
        except _Refused as refused:
            errors.append(refused.error)
    valid, refused_more = check_missions(parsed, bounds=bounds, now_s=float(now_s),
                                         settings=settings)
    box_out = None
    if bounds is not None:
        box_out = (np.asarray(bounds[0], dtype=np.float64), np.asarray(bounds[1], np.float64))
    return MissionBatch(missions=valid, errors=tuple(errors) + refused_more, settings=settings,
                        now_s=float(now_s), scene=scene, bounds=box_out)


def fleet_order(missions: Sequence[Mission]) -> List[Mission]:
    """Missions in the order they are resolved: priority (larger first), departure, name."""
    return sorted(missions, key=Mission.order_key)


def batch_to_plan(missions: Union[MissionBatch, Sequence[Mission]],
                  settings: Optional[FleetSettings], bounds: Optional[Bounds] = None
                  ) -> Tuple[List[Mission], Tuple[MissionError, ...], FleetSettings]:
    """The missions to plan in :func:`fleet_order`, the refused ones and the settings in force.

    Parameters
    ----------
    missions : MissionBatch or sequence of Mission
        A loaded batch (its errors and settings come along) or plain missions.
    settings : FleetSettings, optional
        Overrides the batch's settings; the defaults for a plain sequence.
    bounds : (array_like, array_like), optional
        Map bounds min and max [m] (ENU); missions outside them are refused.

    Returns
    -------
    (list of Mission, tuple of MissionError, FleetSettings)
        The valid missions in resolution order, the batch's errors then those found here,
        and the settings.
    """
    errors: Tuple[MissionError, ...] = ()
    if isinstance(missions, MissionBatch):
        errors = missions.errors
        settings = missions.settings if settings is None else settings
        candidates: Sequence[Mission] = missions.missions
    else:
        candidates = missions
    settings = FleetSettings() if settings is None else settings
    valid, refused = check_missions(candidates, bounds=bounds)
    return fleet_order(valid), errors + refused, settings
