"""Every planner setting in one table: name, type, unit, accepted values, default, description.

:data:`PLANNER_SETTINGS` is the one source of truth for the settings of the planning core. Four
consumers are built from it, so they accept exactly the same values and say the same words:

- :func:`uav_global_planner.core.config.validate_config` checks each :class:`PlannerConfig`
  field with :meth:`Setting.check`, and :class:`PlannerConfig` takes its defaults from here;
- the scene files (:mod:`uav_global_planner.core.io.scene`) read each setting at its
  :attr:`Setting.scene_key` and refuse it with :meth:`Setting.check_key`;
- ``uav-plan`` (:mod:`uav_global_planner.cli.main`) makes its flags from
  :attr:`Setting.flag`, checks their values with :meth:`Setting.refusal` and shows
  :meth:`Setting.help_text`;
- the planner node (:mod:`uav_global_planner.ros.parameters`) declares one parameter per
  setting with :attr:`Setting.summary` as description, :attr:`Setting.constraints`,
  :attr:`Setting.read_only` and the range of :attr:`Setting.low` and :attr:`Setting.high`,
  and validates values with :meth:`Setting.check`.

A refusal reads ``<name> must be <accepted>, got <value>`` (``<key path>: must be ...`` in a
scene file, as every scene error starts with its key path), where ``<accepted>`` is
:attr:`Setting.accepted`, the words the help text and the parameter descriptor show.

Settings of the node alone (frames, QoS, topics: words the core does not know) live in a table
of the same :class:`Setting` type in :mod:`uav_global_planner.ros.parameters`, so they are
checked, described and refused in the same words without the core naming ROS concepts.
"""

from dataclasses import dataclass
from enum import Enum
import math
from typing import Any, Dict, Iterable, Optional, Tuple

import numpy as np

from uav_global_planner.core.checks import integer_refusal, number_refusal, NUMBER_TYPES
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.grid import DEFAULT_MAX_VOXELS

#: Largest value of an integer setting: a ROS 2 integer parameter is a signed 64-bit number.
INT64_MAX = 2 ** 63 - 1

#: Search heuristics, by the names users type.
ALGORITHMS = ('dijkstra', 'astar', 'adaptive', 'octile', 'weighted', 'bounded')

#: Spline parameterisations: chord length sampled in metres, or the paper's node index.
SMOOTHING_MODES = ('chord', 'index', 'none')

#: Heading of the timed reference: along the horizontal velocity, kept as at the start, or
#: towards the goal.
YAW_MODES = ('velocity', 'fixed', 'goal')

#: What the planner does with space a map never observed (:mod:`.unknown_space`): an obstacle,
#: open air, or open air at a cost per metre.
UNKNOWN_SPACE_MODES = ('occupied', 'free', 'cost')

#: The words of the ``ground`` setting besides a height: no ground, or flat ground at the
#: bounds' floor.
GROUND_WORDS = ('none', 'floor')


class Kind(Enum):
    """Value type of a setting."""

    FLOAT = 'float'
    INT = 'integer'
    BOOL = 'bool'
    CHOICE = 'choice'
    POINT = 'point'
    TEXT = 'text'
    NAMES = 'names'
    WORD_OR_NUMBER = 'word or number'


@dataclass(frozen=True)
class Setting:
    """One setting: what it is, what it accepts, and where users meet it.

    Attributes
    ----------
    name : str
        Name in messages and the node's parameter name (``bounds.min``).
    kind : Kind
        Value type.
    default : Any
        Default value (also fixes the node parameter's type).
    label : str
        Short noun phrase with the paper's symbol, e.g. ``'grid spacing delta'``.
    description : str
        What it does, one sentence or two, without the unit or the range.
    unit : str
        SI unit (``'m'``, ``'s'``, ``'m/s'``, ...); empty for dimensionless numbers.
    low, high : float
        Accepted range of a number (:attr:`upper` for ``high``); ``high`` None means up to
        :data:`INT64_MAX` for an integer, no upper limit for a float. Numbers are finite.
    low_open : bool
        The range excludes ``low``.
    choices : tuple of str
        Accepted words of a :attr:`Kind.CHOICE` setting, or the words a
        :attr:`Kind.WORD_OR_NUMBER` setting takes besides a number in its range.
    accepts : str
        Accepted values in words, for text settings (and to replace the generated words).
    non_empty : bool
        A text setting refuses a value of blanks and slashes only (an empty frame name).
    rule : str
        A cross-field rule checked elsewhere, shown beside the accepted values.
    field : str, optional
        The :class:`~uav_global_planner.core.config.PlannerConfig` field it sets.
    scene_key : str, optional
        Key path in a scene file (``'cost.climb_weight'``); None when scenes do not set it.
    scene_required : bool
        A scene file must give it.
    flag : str, optional
        ``uav-plan`` option (``'--safety-margin'``); None when there is none.
    node : bool
        The planner node declares it as a parameter.
    read_only : bool
        The node reads it at start-up only (a read-only parameter).
    """

    name: str
    kind: Kind
    default: Any
    label: str
    description: str
    unit: str = ''
    low: float = 0.0
    high: Optional[float] = None
    low_open: bool = False
    choices: Tuple[str, ...] = ()
    accepts: str = ''
    non_empty: bool = False
    rule: str = ''
    field: Optional[str] = None
    scene_key: Optional[str] = None
    scene_required: bool = False
    flag: Optional[str] = None
    node: bool = True
    read_only: bool = False

    @property
    def upper(self) -> float:
        """The upper end of the range: :attr:`high`, else :data:`INT64_MAX` for an integer
        and +inf for a float."""
        if self.high is not None:
            return self.high
        return float(INT64_MAX) if self.kind is Kind.INT else math.inf

    # ------------------------------------------------------------------------ words

    @property
    def accepted(self) -> str:
        """The accepted values in words, as refusals, help text and descriptors show them."""
        if self.accepts:
            return self.accepts
        if self.kind is Kind.FLOAT:
            bracket = '(' if self.low_open else '['
            return f'in {bracket}{float(self.low)}, {float(self.upper)}]'
        if self.kind is Kind.INT:
            if self.high is None:
                return f'>= {int(self.low)}'
            return f'in [{int(self.low)}, {int(self.upper)}]'
        if self.kind is Kind.CHOICE:
            return f'one of {", ".join(self.choices)}'
        if self.kind is Kind.BOOL:
            return 'true or false'
        if self.kind is Kind.POINT:
            return 'three numbers [x, y, z]'
        if self.kind is Kind.WORD_OR_NUMBER:
            return (f'{", ".join(self.choices)} or a number in [{float(self.low)}, '
                    f'{float(self.upper)}]')
        return 'a string'

    @property
    def unit_text(self) -> str:
        """``' [m]'``, ``' [-]'`` for a dimensionless number, empty for words and switches."""
        if self.unit:
            return f' [{self.unit}]'
        return ' [-]' if self.kind in (Kind.FLOAT, Kind.INT) else ''

    @property
    def summary(self) -> str:
        """Label, unit and description: the node parameter's description."""
        return f'{self.label[0].upper()}{self.label[1:]}{self.unit_text}. {self.description}'

    @property
    def constraints(self) -> str:
        """Accepted values with the unit and the cross-field rule, e.g. ``in (0.0, 100.0] m``."""
        text = self.accepted
        if self.unit and self.kind in (Kind.FLOAT, Kind.INT, Kind.POINT, Kind.WORD_OR_NUMBER):
            text += f' {self.unit}'
        if self.rule:
            text += f'; {self.rule}'
        return text

    def help_text(self) -> str:
        """``uav-plan --help`` text: summary, accepted values and default (``%`` escaped)."""
        default = 'unset' if self.default is None else format_value(self.default)
        if self.scene_key:
            default = f"the scene's value, else {default}"
        return f'{self.summary} Accepted: {self.constraints}. Default: {default}.'.replace(
            '%', '%%')

    # ------------------------------------------------------------------------ checks

    def refusal(self, value: Any) -> Optional[Tuple[str, str]]:
        """Why ``value`` is refused, or None when it is accepted.

        Returns
        -------
        tuple of str or None
            ``(where, reason)``: ``where`` is ``''`` or the item of a point (``'[2]'``),
            ``reason`` reads ``must be ..., got ...``.
        """
        kind = self.kind
        if kind is Kind.FLOAT:
            return _float_refusal(value, self)
        if kind is Kind.INT:
            high = INT64_MAX if self.high is None else int(self.upper)
            reason = integer_refusal(value, int(self.low), high, self.accepted)
            return None if reason is None else ('', reason)
        if kind is Kind.BOOL:
            if not isinstance(value, (bool, np.bool_)):
                return '', f'must be {self.accepted}, got {value!r}'
            return None
        if kind is Kind.CHOICE:
            if not isinstance(value, str) or value not in self.choices:
                return '', f'must be {self.accepted}, got {value!r}'
            return None
        if kind is Kind.POINT:
            if (isinstance(value, (str, bytes)) or not hasattr(value, '__len__')
                    or len(value) != 3):
                return '', f'must be {self.accepted}, got {value!r}'
            for axis, item in enumerate(value):
                reason = number_refusal(item)
                if reason is not None:
                    return f'[{axis}]', reason
            return None
        if kind is Kind.WORD_OR_NUMBER:
            return _word_or_number_refusal(value, self)
        if kind is Kind.TEXT:
            if not isinstance(value, str) or (self.non_empty and not value.strip('/ ')):
                return '', f'must be {self.accepted}, got {value!r}'
            return None
        if (isinstance(value, (str, bytes)) or not hasattr(value, '__iter__')
                or not all(isinstance(item, str) for item in value)):
            return '', f'must be {self.accepted}, got {value!r}'
        return None

    def normalise(self, value: Any) -> Any:
        """An accepted value in its canonical Python type (float, int, bool, tuple, str)."""
        if self.kind is Kind.FLOAT:
            return float(value)
        if self.kind is Kind.INT:
            return int(value)
        if self.kind is Kind.BOOL:
            return bool(value)
        if self.kind is Kind.POINT:
            return tuple(float(item) for item in value)
        if self.kind is Kind.NAMES:
            return tuple(str(item) for item in value)
        if self.kind is Kind.WORD_OR_NUMBER:
            return value if value in self.choices else float(value)
        return value

    def check(self, value: Any, label: Optional[str] = None) -> Any:
        """``value`` normalised, or :class:`InvalidInputError` ``<label> must be ..., got ...``.

        Parameters
        ----------
        value : Any
        label : str, optional
            Name used in the message; :attr:`name` by default.
        """
        problem = self.refusal(value)
        if problem is not None:
            where, reason = problem
            raise InvalidInputError(f'{label or self.name}{where} {reason}')
        return self.normalise(value)

    def check_key(self, value: Any, path: str) -> Any:
        """As :meth:`check`, for a scene file: the message starts with the key path,
        ``<path>: must be ..., got ...``."""
        problem = self.refusal(value)
        if problem is not None:
            where, reason = problem
            raise InvalidInputError(f'{path}{where}: {reason}')
        return self.normalise(value)


def _float_refusal(value: Any, setting: Setting) -> Optional[Tuple[str, str]]:
    reason = number_refusal(value, float(setting.low), float(setting.upper),
                            low_open=setting.low_open, accepted=setting.accepted)
    return None if reason is None else ('', reason)


def _word_or_number_refusal(value: Any, setting: Setting) -> Optional[Tuple[str, str]]:
    """A word of ``setting.choices`` or a finite number in range; a number may come as text
    (a string parameter of the node, a command-line word)."""
    if isinstance(value, str):
        if value in setting.choices:
            return None
        try:
            number = float(value)
        except ValueError:
            return '', f'must be {setting.accepted}, got {value!r}'
    elif isinstance(value, bool) or not isinstance(value, NUMBER_TYPES):
        return '', f'must be {setting.accepted}, got {value!r}'
    else:
        number = float(value)
    if not math.isfinite(number) or not setting.low <= number <= setting.upper:
        return '', f'must be {setting.accepted}, got {number}'
    return None


def format_value(value: Any) -> str:
    """A default as users type it: ``0.5``, ``true``, ``[-10.0, -10.0, 0.0]``, ``''``."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (tuple, list)):
        return '[' + ', '.join(repr(item) if isinstance(item, str) else format_value(item)
                               for item in value) + ']'
    if isinstance(value, str):
        return repr(value) if not value else value
    return str(value)


def _speed_limit(name: str, axis: str, what: str, unit: str, default: float) -> Setting:
    return Setting(name, Kind.FLOAT, default, f'{axis} {what} limit',
                   'The time parameterisation keeps the timed trajectory within it.', unit,
                   0.0, 1000.0, low_open=True, field=name, scene_key=f'planner.{name}')


#: Every setting of the planning core, in the order they are checked and documented.
PLANNER_SETTINGS: Tuple[Setting, ...] = (
    Setting('bounds.min', Kind.POINT, (-10.0, -10.0, 0.0), 'workspace minimum corner',
            'Minimum corner (x, y, z) of the planning bounds (paper eq. 4), in the planning '
            'frame.', 'm', rule='below bounds.max on every axis', field='bounds_min',
            scene_key='bounds.min', scene_required=True),
    Setting('bounds.max', Kind.POINT, (10.0, 10.0, 15.0), 'workspace maximum corner',
            'Maximum corner (x, y, z) of the planning bounds (paper eq. 4), in the planning '
            'frame.', 'm', rule='above bounds.min on every axis', field='bounds_max',
            scene_key='bounds.max', scene_required=True),
    Setting('resolution', Kind.FLOAT, 0.5, 'grid spacing delta',
            'Node spacing of the voxel grid (paper eq. 5); smaller is finer and slower.', 'm',
            0.0, 100.0, low_open=True, rule='the node count must stay <= max_voxels',
            field='resolution', scene_key='resolution', scene_required=True,
            flag='--resolution'),
    Setting('safety_margin', Kind.FLOAT, 0.2, 'safety margin gamma',
            'Nodes within gamma of an obstacle are blocked and the smoothed path keeps '
            'clearance >= gamma (paper eqs. 8-10).', 'm', 0.0, 100.0, field='safety_margin',
            scene_key='safety_margin', scene_required=True, flag='--safety-margin'),
    Setting('adaptive_threshold', Kind.FLOAT, 1.5, 'heuristic switch distance eta',
            'The adaptive heuristic is Manhattan beyond eta and Euclidean within it (paper '
            'eq. 12).', 'm', 0.0, 1.0e6, field='adaptive_threshold',
            scene_key='adaptive_threshold', scene_required=True, flag='--adaptive-threshold'),
    Setting('algorithm', Kind.CHOICE, 'adaptive', 'search heuristic',
            'One of dijkstra (none), astar (Euclidean), adaptive (paper eq. 12, Manhattan beyond '
            'eta), octile (optimal, fewest expansions), weighted (cost <= search_weight x '
            'optimum) or bounded (cost <= bound x optimum, proven per query).',
            choices=ALGORITHMS, field='algorithm'),
    Setting('search_weight', Kind.FLOAT, 1.05, 'suboptimality bound w',
            "The weighted algorithm's path costs at most w times the optimum.", '', 1.0, 10.0,
            field='search_weight', scene_key='planner.search_weight', flag='--search-weight'),
    Setting('bound', Kind.FLOAT, 1.05, 'certified suboptimality bound w',
            "The bounded algorithm's path costs at most w times the optimum, proven for each "
            'query by a lower bound from the search.', '', 1.0, 10.0, field='bound',
            scene_key='planner.bound', flag='--bound'),
    Setting('max_expansions', Kind.INT, 0, 'search budget in expanded nodes',
            '0 = no limit; exceeding it reports TIMEOUT (207).', '', 0,
            field='max_expansions', scene_key='planner.max_expansions'),
    Setting('max_planning_time', Kind.FLOAT, 5.0, 'time budget of a whole plan',
            'Grid build, search, smoothing and timing; 0 = no limit. Exceeding it reports '
            'TIMEOUT (207) naming the stage.', 's', 0.0, 1.0e6, field='max_planning_time',
            scene_key='planner.max_planning_time', flag='--max-planning-time'),
    Setting('max_voxels', Kind.INT, DEFAULT_MAX_VOXELS, 'largest accepted grid node count',
            'So that a typo in resolution or bounds cannot exhaust memory (paper eq. 7).', '',
            1, field='max_voxels', scene_key='max_voxels',
            flag='--max-voxels'),
    Setting('shortcut', Kind.BOOL, True, 'shortcutting',
            'Drop grid nodes where the straight segment keeps clearance >= gamma before '
            'smoothing.', field='shortcut', scene_key='planner.shortcut', flag='--no-shortcut'),
    Setting('smoothing', Kind.CHOICE, 'chord', 'cubic-spline parameterisation',
            'One of chord (arc length, sampled every sample_spacing metres), index (the node '
            'index of the paper, step index_step) or none.', choices=SMOOTHING_MODES,
            field='smoothing', scene_key='planner.smoothing', flag='--smoothing'),
    Setting('sample_spacing', Kind.FLOAT, 0.1, 'sample spacing',
            'Spacing of the smoothed samples along the curve for chord smoothing.', 'm', 0.0,
            10.0, low_open=True, field='sample_spacing', scene_key='planner.sample_spacing'),
    Setting('index_step', Kind.FLOAT, 0.1, 'node-index step',
            "Parameter step of the paper's node-index spline for index smoothing.", '', 0.0,
            1.0, low_open=True, field='index_step', scene_key='planner.index_step'),
    _speed_limit('max_speed_horizontal', 'horizontal', 'speed', 'm/s', 2.0),
    _speed_limit('max_speed_vertical', 'vertical', 'speed', 'm/s', 1.0),
    _speed_limit('max_accel_horizontal', 'horizontal', 'acceleration', 'm/s^2', 1.0),
    _speed_limit('max_accel_vertical', 'vertical', 'acceleration', 'm/s^2', 0.5),
    Setting('max_jerk', Kind.FLOAT, 10.0, 'jerk limit',
            'Largest norm of the jerk of the timed reference; its acceleration is continuous.',
            'm/s^3', 0.0, 1.0e4, low_open=True, field='max_jerk', scene_key='planner.max_jerk',
            flag='--max-jerk'),
    Setting('max_tilt', Kind.FLOAT, 35.0, 'tilt limit',
            'Largest tilt of the collective thrust the reference asks for (its acceleration '
            'plus gravity) from the vertical.', 'deg', 0.0, 89.0, low_open=True,
            field='max_tilt', scene_key='vehicle.max_tilt', flag='--max-tilt'),
    Setting('max_thrust_to_weight', Kind.FLOAT, 2.0, 'thrust-to-weight limit',
            'Largest collective thrust of the reference over the weight; keep it below the '
            "vehicle's real ratio by the headroom its attitude control needs.", '', 1.0, 100.0,
            low_open=True, field='max_thrust_to_weight',
            scene_key='vehicle.max_thrust_to_weight', flag='--max-thrust-to-weight'),
    Setting('max_yaw_rate', Kind.FLOAT, 0.785, 'yaw-rate limit',
            'Largest yaw rate of the heading profile.', 'rad/s', 0.0, 100.0, low_open=True,
            field='max_yaw_rate', scene_key='vehicle.max_yaw_rate', flag='--max-yaw-rate'),
    Setting('yaw_mode', Kind.CHOICE, 'velocity', 'heading profile',
            'One of velocity (along the horizontal direction of travel), fixed (the heading '
            'at the start) or goal (towards the goal).', choices=YAW_MODES, field='yaw_mode',
            scene_key='planner.yaw_mode', flag='--yaw-mode'),
    Setting('vehicle_radius', Kind.FLOAT, 0.0, 'vehicle radius',
            'Radius of a sphere around the body and rotors; the body, not the centre, keeps '
            'gamma (obstacles are inflated by gamma + vehicle_radius + tracking_margin).',
            'm', 0.0, 100.0, field='vehicle_radius', scene_key='vehicle.radius',
            flag='--vehicle-radius'),
    Setting('tracking_margin', Kind.FLOAT, 0.0, 'tracking margin',
            'Room kept for the tracking error of the vehicle around the reference; where the '
            'curve leaves less room, the reference slows so its predicted error fits.', 'm',
            0.0, 100.0, field='tracking_margin', scene_key='vehicle.tracking_margin',
            flag='--tracking-margin'),
    Setting('start_tolerance', Kind.FLOAT, 0.5, 'start tolerance',
            'A start or goal below the floor or the ground by at most this distance, or within '
            'the safety margin of the ground, is lifted straight up to the lowest free height '
            '(its take-off or landing leg); a start outside the bounds or within the safety '
            'margin of another obstacle by at most this distance is moved to the nearest free '
            'point. The plan says so; about delta. 0 = never.', 'm', 0.0, 100.0,
            field='start_tolerance', scene_key='planner.start_tolerance',
            flag='--start-tolerance'),
    Setting('climb_weight', Kind.FLOAT, 1.0, 'climb weight',
            'Energy-aware step cost: a climbing grid step costs its length plus (weight - 1) '
            "times its rise; 1 gives the paper's geometric length (eq. 15).", '', 0.0, 100.0,
            field='climb_weight', scene_key='cost.climb_weight'),
    Setting('descent_weight', Kind.FLOAT, 1.0, 'descent weight',
            'As climb_weight for descending steps; below 1 makes descending cheaper.', '', 0.0,
            100.0, field='descent_weight', scene_key='cost.descent_weight'),
    Setting('unknown_space', Kind.CHOICE, 'occupied', 'unknown-space policy',
            'Space the map never observed (OctoMap unknown cells, outside the known_volume '
            'of a scene): occupied (an obstacle the margin is kept from; a start or goal in '
            'it is refused), free (flown through) or cost (flown through at unknown_cost extra '
            'per metre, weighed against detours by the search). Every plan reports its length '
            'in unknown space.', choices=UNKNOWN_SPACE_MODES, field='unknown_space',
            scene_key='unknown_space', flag='--unknown-space'),
    Setting('unknown_cost', Kind.FLOAT, 10.0, 'cost per metre through unknown space',
            'Extra search cost per metre flown through unknown space with unknown_space cost: '
            'a detour of up to this many metres per metre of unknown space avoided is taken.',
            '', 0.0, 1.0e6, field='unknown_cost', scene_key='unknown_cost',
            flag='--unknown-cost'),
    Setting('vehicle_mass', Kind.FLOAT, 1.5, 'take-off mass m',
            'Vehicle mass of the energy estimate of every plan.', 'kg', 0.0, 1000.0,
            low_open=True, field='vehicle_mass', scene_key='vehicle.mass'),
    Setting('hover_power', Kind.FLOAT, 180.0, 'hover power P_h',
            'Electrical power to hover, of the energy estimate of every plan.', 'W', 0.0, 1.0e6,
            low_open=True, field='hover_power', scene_key='vehicle.hover_power'),
    Setting('ground', Kind.WORD_OR_NUMBER, 'none', 'ground',
            'The ground the planning margin is kept from where the scene has no terrain: none '
            '(the bounds floor is only a wall of the grid), floor (flat ground at bounds.min '
            'z) or a height in the map frame; a terrain, when given, is the ground.', 'm',
            -1.0e5, 1.0e5, choices=GROUND_WORDS, field='ground', scene_key='ground',
            flag='--ground'),
    Setting('min_agl', Kind.FLOAT, 0.0, 'lowest height above ground',
            'The whole curve stays at least this high above the ground or terrain under it; '
            '0 = off.', 'm', 0.0, 1.0e4, rule='below max_agl when both are on',
            field='min_agl', scene_key='min_agl', flag='--min-agl'),
    Setting('max_agl', Kind.FLOAT, 0.0, 'highest height above ground',
            'The whole curve stays at most this high above the ground or terrain under it '
            '(120 m in most jurisdictions); 0 = off.', 'm', 0.0, 1.0e4,
            rule='above min_agl when both are on', field='max_agl', scene_key='max_agl',
            flag='--max-agl'),
    Setting('map_downsample', Kind.FLOAT, 0.0, 'map downsampling cell',
            'One point (the cell centre) per occupied cell of the map files; 0 = none. gamma '
            'grows by the map margin (cell*sqrt(3)/2) so paths keep gamma from the map as '
            'read.', 'm', 0.0, 100.0, flag='--map-downsample', read_only=True),
)


def by_name(table: Iterable[Setting]) -> Dict[str, Setting]:
    """The settings of ``table`` keyed by :attr:`Setting.name`."""
    return {setting.name: setting for setting in table}


#: :data:`PLANNER_SETTINGS` by name, in the same order. Every consumer reads the settings
#: through this mapping when it runs (never a copy taken at import), so replacing an entry
#: here changes what all of them accept.
SETTINGS_BY_NAME: Dict[str, Setting] = by_name(PLANNER_SETTINGS)


def planner_settings() -> Tuple[Setting, ...]:
    """The settings of the planning core in force, in table order."""
    return tuple(SETTINGS_BY_NAME.values())


def setting(name: str) -> Setting:
    """The setting called ``name`` in :data:`SETTINGS_BY_NAME`."""
    return SETTINGS_BY_NAME[name]


def check_setting(name: str, value: Any, label: Optional[str] = None) -> Any:
    """``value`` checked and normalised by the setting ``name`` (see :meth:`Setting.check`)."""
    return SETTINGS_BY_NAME[name].check(value, label)
