"""One settings table feeds every consumer: validate_config, the node, scene files, uav-plan.

Each test feeds the four consumers the same value and compares what they answer:

* ``config``: :func:`validate_config` of a :class:`PlannerConfig` with the field set;
* ``node``: :func:`settings_from_parameters` (the node's validation of a set request) and the
  ``ParameterDescriptor`` it declares (:func:`descriptor`), without spinning a node;
* ``scene``: :func:`parse_scene` of a scene document with the key set at its key path;
* ``cli``: the ``uav-plan plan`` argument parser given the flag.

A refusal must read the same everywhere: ``<name> <reason>`` (``<key path>: <reason>`` in a
scene file, ``argument --flag: <name> <reason>`` on the command line).

The tables the documentation shows are made from the same table by ``docs/gen_tables.py``.
"""

import copy
from dataclasses import replace
import math
import re
from typing import Any, Dict, List, Optional, Tuple

import pytest

from uav_global_planner.cli.main import _parser, _UsageError
from uav_global_planner.core import settings as table
from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import parse_scene
from uav_global_planner.core.settings import INT64_MAX, Kind, PLANNER_SETTINGS, Setting

parameters = pytest.importorskip('uav_global_planner.ros.parameters')

# Bounds small enough that no resolution in the table makes a grid over any max_voxels
# (a node count is a cross-field rule, not the range this file is about).
_TINY_MIN, _TINY_MAX = [0.0, 0.0, 0.0], [1.0e-6, 1.0e-6, 1.0e-6]


def _scene_document() -> Dict[str, Any]:
    return {'bounds': {'min': list(_TINY_MIN), 'max': list(_TINY_MAX)}, 'resolution': 0.5,
            'safety_margin': 0.0, 'adaptive_threshold': 1.5, 'start': [0.0, 0.0, 0.0],
            'goal': [1.0e-6, 1.0e-6, 1.0e-6]}


def _base_config() -> PlannerConfig:
    return PlannerConfig(bounds_min=tuple(_TINY_MIN), bounds_max=tuple(_TINY_MAX))


def _node_values() -> Dict[str, Any]:
    values = {spec.name: parameters.parameter_default(spec)
              for spec in parameters.parameter_specs()}
    values['bounds.min'], values['bounds.max'] = list(_TINY_MIN), list(_TINY_MAX)
    return values


# ------------------------------------------------------------------------------ consumers

def _config_says(entry: Setting, value: Any) -> Optional[str]:
    """validate_config's refusal of ``value`` for ``entry`` (None: accepted)."""
    try:
        validate_config(replace(_base_config(), **{str(entry.field): value}))
    except InvalidInputError as error:
        return str(error)
    return None


def _node_says(entry: Setting, value: Any) -> Optional[str]:
    try:
        parameters.settings_from_parameters({**_node_values(), entry.name: value})
    except InvalidInputError as error:
        return str(error)
    return None


def _scene_says(entry: Setting, value: Any) -> Optional[str]:
    document = _scene_document()
    head, _, tail = str(entry.scene_key).partition('.')
    if tail:
        document.setdefault(head, {})[tail] = copy.deepcopy(value)
    else:
        document[head] = copy.deepcopy(value)
    try:
        parse_scene(document)
    except InvalidInputError as error:
        return str(error)
    return None


def _cli_says(entry: Setting, text: str) -> Optional[str]:
    """The argparse refusal of ``--flag=text`` (None: accepted)."""
    try:
        # --flag=WORD: argparse takes a separate '-1e-09' for an option.
        _parser().parse_args(['plan', 'scene.yaml', f'{entry.flag}={text}'])
    except _UsageError as error:
        return error.reason
    return None


def _consumers(entry: Setting) -> List[str]:
    names = []
    if entry.field:
        names.append('config')
    if entry.node:
        names.append('node')
    if entry.scene_key:
        names.append('scene')
    if entry.flag and entry.kind in (Kind.FLOAT, Kind.INT, Kind.CHOICE, Kind.WORD_OR_NUMBER):
        names.append('cli')
    return names


def _as_typed(entry: Setting, value: Any) -> Optional[str]:
    """``value`` as a command-line word, or None when no word parses to it: a word that is
    not a number is argparse's own "invalid float value" (``test_cli.py``), not a range."""
    if entry.kind is Kind.CHOICE or (entry.kind is Kind.WORD_OR_NUMBER
                                     and isinstance(value, str)):
        return value if isinstance(value, str) else None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    if entry.kind is Kind.INT:
        return str(value) if isinstance(value, int) else None
    return repr(float(value))


def _answers(entry: Setting, value: Any) -> Dict[str, Optional[str]]:
    """Each consumer's refusal of ``value`` (None where it is accepted)."""
    answers = {}
    for consumer in _consumers(entry):
        if consumer == 'config':
            answers[consumer] = _config_says(entry, value)
        elif consumer == 'node':
            answers[consumer] = _node_says(entry, value)
        elif consumer == 'scene':
            answers[consumer] = _scene_says(entry, value)
        elif _as_typed(entry, value) is not None:
            answers[consumer] = _cli_says(entry, str(_as_typed(entry, value)))
    return answers


def _expected_message(consumer: str, entry: Setting, words: str) -> str:
    """``words`` (``[0] must be ...`` or `` must be ...``) as ``consumer`` says it."""
    if consumer == 'scene':
        where, reason = words.split(' ', 1)
        return f'{entry.scene_key}{where}: {reason}'
    if consumer == 'cli':
        return f'argument {entry.flag}: {entry.name}{words}'
    return f'{entry.name}{words}'


# ------------------------------------------------------------------------------ boundaries

def _boundaries(entry: Setting) -> Tuple[List[Any], List[Tuple[Any, str]]]:
    """Values at the edges of what ``entry`` accepts: (accepted, [(refused, words)]), the
    words written out here from the entry's range, not taken from the code under test."""
    if entry.kind is Kind.FLOAT:
        low, high = float(entry.low), float(entry.high)
        bracket = '(' if entry.low_open else '['
        in_range = f'in {bracket}{low}, {high}]'
        below = low if entry.low_open else low - max(abs(low), 1.0) * 1e-9
        above = high + max(abs(high), 1.0) * 1e-9
        inside = low + (high - low) * 1e-6 if entry.low_open else low
        return [inside, high, (low + high) / 2], [
            (below, f' must be {in_range}, got {below}'),
            (above, f' must be {in_range}, got {above}'),
            (math.nan, ' must be finite, got nan'), (math.inf, ' must be finite, got inf'),
            ('one', " must be a number, got 'one'"), (True, ' must be a number, got True')]
    if entry.kind is Kind.INT:
        low = int(entry.low)
        high = INT64_MAX if entry.high is None else int(entry.high)
        words = f'>= {low}' if entry.high is None else f'in [{low}, {high}]'
        return [low, high], [
            (low - 1, f' must be {words}, got {low - 1}'),
            (high + 1, f' must be {words}, got {high + 1}'),
            (2.0, ' must be an integer, got 2.0'), (True, ' must be an integer, got True')]
    if entry.kind is Kind.CHOICE:
        words = 'one of ' + ', '.join(entry.choices)
        return list(entry.choices), [
            (entry.choices[0].upper(), f' must be {words}, got {entry.choices[0].upper()!r}'),
            ('', f" must be {words}, got ''"), (None, f' must be {words}, got None')]
    if entry.kind is Kind.BOOL:
        return [True, False], [(1, ' must be true or false, got 1'),
                               ('yes', " must be true or false, got 'yes'")]
    if entry.kind is Kind.POINT:
        return [list(entry.default)], [
            ([1.0, 2.0], ' must be three numbers [x, y, z], got [1.0, 2.0]'),
            ([math.nan, 0.0, 0.0], '[0] must be finite, got nan'),
            ([0.0, 'a', 0.0], "[1] must be a number, got 'a'")]
    if entry.kind is Kind.WORD_OR_NUMBER:
        low, high = float(entry.low), float(entry.high)
        words = f'{", ".join(entry.choices)} or a number in [{low}, {high}]'
        above = high + max(abs(high), 1.0) * 1e-9
        return [*entry.choices, low, high, str(high)], [
            (entry.choices[0].upper(), f' must be {words}, got {entry.choices[0].upper()!r}'),
            (above, f' must be {words}, got {above}'),
            (math.nan, f' must be {words}, got nan'), (True, f' must be {words}, got True')]
    if entry.kind is Kind.TEXT:
        refused = [(7, f' must be {entry.accepted}, got 7')]
        if entry.non_empty:
            refused.append(('/', f" must be {entry.accepted}, got '/'"))
        return [entry.default, 'a_name'], refused
    return [list(entry.default)], [('any', f" must be {entry.accepted}, got 'any'")]


def _cross_field_safe(entry: Setting, value: Any) -> bool:
    """False for values that break a cross-field rule on the test's bounds."""
    if entry.name in ('bounds.min', 'bounds.max'):
        return False  # the default corners are not below/above the tiny bounds' other corner
    if entry.name in ('min_agl', 'max_agl') and value > 0.0:
        return False  # a height band above a ground the scene does not have
    if entry.name == 'ground' and value not in entry.choices:
        return float(value) < _TINY_MAX[2]  # a flat ground above the bounds is refused
    # The geofence band: floor below the default ceiling (120 m), ceiling above the floor (0).
    return not ((entry.name == 'geofence_floor' and value >= 120.0)
                or (entry.name == 'geofence_ceiling' and value <= 0.0))


@pytest.mark.parametrize('entry', PLANNER_SETTINGS + parameters.NODE_SETTINGS,
                         ids=lambda entry: entry.name)
def test_every_consumer_accepts_and_refuses_the_same_boundary_values(entry):
    accepted, refused = _boundaries(entry)
    for value in accepted:
        if _cross_field_safe(entry, value):
            assert _answers(entry, value) == {name: None for name in _answers(entry, value)}, (
                entry.name, value)
    for value, words in refused:
        answers = _answers(entry, value)
        assert answers, entry.name
        for consumer, message in answers.items():
            assert message == _expected_message(consumer, entry, words), (consumer, value)


def test_bounds_are_accepted_alike_by_every_consumer():
    entry = table.SETTINGS_BY_NAME['bounds.max']
    assert _answers(entry, [1.0, 1.0, 1.0]) == {'config': None, 'node': None, 'scene': None}
    assert _answers(entry, [1, 2, 3]) == {'config': None, 'node': None, 'scene': None}


def test_adaptive_threshold_2e6_is_refused_everywhere():
    # Once accepted by validate_config and uav-plan but refused by the node's range.
    entry = table.SETTINGS_BY_NAME['adaptive_threshold']
    words = ' must be in [0.0, 1000000.0], got 2000000.0'
    answers = _answers(entry, 2.0e6)
    assert set(answers) == {'config', 'node', 'scene', 'cli'}
    for consumer, message in answers.items():
        assert message == _expected_message(consumer, entry, words), consumer
    span = parameters.descriptor(entry).floating_point_range[0]
    assert (span.from_value, span.to_value) == (0.0, 1.0e6)


# ------------------------------------------------------------------------------ one change

def _narrowed(monkeypatch, name: str, **changes: Any) -> Setting:
    entry = replace(table.SETTINGS_BY_NAME[name], **changes)
    monkeypatch.setitem(table.SETTINGS_BY_NAME, name, entry)
    return entry


def _plan_help(capsys) -> str:
    """``uav-plan plan --help`` without its line breaks (argparse wraps at any blank or
    hyphen, so all whitespace is removed)."""
    with pytest.raises(SystemExit):
        _parser().parse_args(['plan', '--help'])
    return _squeezed(capsys.readouterr().out)


def _squeezed(text: str) -> str:
    return re.sub(r'\s+', '', text)


def test_a_changed_range_is_followed_by_all_four_consumers(monkeypatch, capsys):
    before = table.SETTINGS_BY_NAME['safety_margin']
    assert _answers(before, 3.5) == {'config': None, 'node': None, 'scene': None, 'cli': None}
    entry = _narrowed(monkeypatch, 'safety_margin', high=3.0)
    words = ' must be in [0.0, 3.0], got 3.5'
    answers = _answers(entry, 3.5)
    assert answers == {consumer: _expected_message(consumer, entry, words)
                       for consumer in ('config', 'node', 'scene', 'cli')}
    assert _answers(entry, 3.0) == {'config': None, 'node': None, 'scene': None, 'cli': None}
    # What users read follows too: the descriptor's range and words, and uav-plan --help.
    described = parameters.descriptor(
        next(s for s in parameters.parameter_specs() if s.name == 'safety_margin'))
    span = described.floating_point_range[0]
    assert (span.from_value, span.to_value) == (0.0, 3.0)
    assert described.additional_constraints == 'in [0.0, 3.0] m'
    assert _squeezed('Accepted: in [0.0, 3.0] m.') in _plan_help(capsys)


def test_a_changed_integer_range_is_followed(monkeypatch):
    entry = _narrowed(monkeypatch, 'max_expansions', low=10, high=1000)
    assert _answers(entry, 5) == {'config': 'max_expansions must be in [10, 1000], got 5',
                                  'node': 'max_expansions must be in [10, 1000], got 5',
                                  'scene': 'planner.max_expansions: must be in [10, 1000], got 5'}
    span = parameters.descriptor(entry).integer_range[0]
    assert (span.from_value, span.to_value) == (10, 1000)


def test_a_changed_choice_list_is_followed(monkeypatch):
    smoothing = _narrowed(monkeypatch, 'smoothing', choices=('chord', 'none'))
    for consumer, message in _answers(smoothing, 'index').items():
        assert message == _expected_message(
            consumer, smoothing, " must be one of chord, none, got 'index'"), consumer


def test_a_changed_node_setting_is_followed_by_the_node(monkeypatch):
    name = 'max_obstacle_size'
    entry = replace(parameters.NODE_SETTINGS_BY_NAME[name], high=10.0)
    assert _node_says(entry, 20.0) is None
    monkeypatch.setitem(parameters.NODE_SETTINGS_BY_NAME, name, entry)
    assert _node_says(entry, 20.0) == 'max_obstacle_size must be in (0.0, 10.0], got 20.0'
    described = parameters.descriptor(
        next(s for s in parameters.parameter_specs() if s.name == name))
    assert described.floating_point_range[0].to_value == 10.0


# ------------------------------------------------------------------------------ same words

def test_descriptors_and_help_text_say_the_table_words(capsys):
    shown = _plan_help(capsys)
    for spec in parameters.parameter_specs():
        described = parameters.descriptor(spec)
        assert described.name == spec.name
        assert described.description == spec.summary
        assert described.additional_constraints == spec.constraints
        assert described.read_only == spec.read_only
        assert bool(described.floating_point_range) == (spec.kind is Kind.FLOAT)
        assert bool(described.integer_range) == (spec.kind is Kind.INT)
        if spec.flag:
            assert _squeezed(f'{spec.flag} ') in shown, spec.name
            assert _squeezed(f'{spec.summary} Accepted: {spec.constraints}.') in shown, spec.name
    # Units are shown wherever a number has one.
    assert '[m]' in parameters.SPECS_BY_NAME['resolution'].summary
    assert parameters.SPECS_BY_NAME['max_planning_time'].constraints == 'in [0.0, 1000000.0] s'


def test_the_existing_flags_keep_their_names():
    flags = {entry.flag for entry in PLANNER_SETTINGS if entry.flag}
    assert {'--resolution', '--safety-margin', '--adaptive-threshold', '--smoothing',
            '--no-shortcut', '--max-planning-time', '--max-voxels', '--search-weight',
            '--map-downsample', '--max-jerk', '--max-tilt', '--max-thrust-to-weight',
            '--max-yaw-rate', '--yaw-mode', '--vehicle-radius', '--tracking-margin'} <= flags
    args = _parser().parse_args(['plan', 'scene.yaml', '--no-shortcut', '--max-voxels', '7',
                                 '--map-downsample', '0.5'])
    assert (args.shortcut, args.max_voxels, args.map_downsample) == (False, 7, 0.5)
    args = _parser().parse_args(['plan', 'scene.yaml'])
    assert (args.shortcut, args.max_voxels, args.safety_margin) == (None, None, None)


def test_every_config_field_has_one_entry_and_its_default():
    fields = [entry.field for entry in PLANNER_SETTINGS if entry.field]
    assert sorted(fields) == sorted(PlannerConfig.__dataclass_fields__)
    config = PlannerConfig()
    for entry in PLANNER_SETTINGS:
        if entry.field:
            assert getattr(config, entry.field) == entry.default, entry.name
    assert validate_config(config) == config


def test_the_node_validates_every_parameter_it_declares():
    names = [spec.name for spec in parameters.PARAMETER_SPECS]
    assert len(names) == len(set(names))
    assert {entry.name for entry in PLANNER_SETTINGS} <= set(names)
    for name in names:
        values = _node_values()
        del values[name]
        with pytest.raises(KeyError, match=re.escape(repr(name))):
            parameters.settings_from_parameters(values)
    assert set(parameters.STARTUP_ONLY) == {'map_file', 'map_downsample',
                                            'cloud_qos_reliability', 'terrain_file'}
