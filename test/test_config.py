"""Planner settings: one validation used by the node and the command-line tool."""

from dataclasses import replace

import pytest

from uav_global_planner.core.config import config_from_mapping, PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError


def test_defaults_are_the_papers_values():
    config = validate_config(PlannerConfig())
    assert config.resolution == 0.5
    assert config.safety_margin == 0.2
    assert config.adaptive_threshold == 1.5
    assert config.bounds_min == (-10.0, -10.0, 0.0)
    assert config.bounds_max == (10.0, 10.0, 15.0)


@pytest.mark.parametrize('changes, message', [
    ({'resolution': 0.0}, r'resolution must be in \(0.0, 100.0\]'),
    ({'resolution': float('nan')}, 'resolution must be finite'),
    ({'safety_margin': -0.1}, r'safety_margin must be in \[0.0'),
    ({'adaptive_threshold': 'far'}, 'adaptive_threshold must be a number'),
    ({'algorithm': 'bfs'},
     'algorithm must be one of dijkstra, astar, adaptive, octile, weighted, bounded, got'),
    ({'smoothing': 'bezier'}, 'smoothing must be one of chord, index, none'),
    ({'max_expansions': -1}, 'max_expansions must be >= 0'),
    ({'max_expansions': 2.5}, 'max_expansions must be an integer'),
    ({'max_planning_time': -1.0}, 'max_planning_time must be in'),
    ({'max_speed_vertical': 0.0}, 'max_speed_vertical must be in'),
    ({'bounds_min': (0.0, 0.0, 20.0)}, 'bounds.min must be below bounds.max'),
    ({'bounds_max': (1.0, 1.0)}, 'bounds.max must be three numbers'),
    ({'resolution': 0.01}, 'exceeds max_voxels'),
    ({'max_voxels': 1000}, 'exceeds max_voxels = 1000'),
    ({'shortcut': 'yes'}, 'shortcut must be true or false'),
])
def test_invalid_settings_name_the_field(changes, message):
    with pytest.raises(InvalidInputError, match=message):
        validate_config(replace(PlannerConfig(), **changes))


def test_with_changes_keeps_the_original():
    config = PlannerConfig()
    changed = config.with_changes(safety_margin=0.5)
    assert changed.safety_margin == 0.5
    assert config.safety_margin == 0.2


def test_integer_values_are_accepted_as_floats():
    config = validate_config(replace(PlannerConfig(), resolution=1, bounds_min=(-10, -10, 0)))
    assert isinstance(config.resolution, float)
    assert config.bounds_min == (-10.0, -10.0, 0.0)


def test_unknown_keys_are_refused():
    with pytest.raises(InvalidInputError, match='unknown setting.*speed'):
        config_from_mapping({'speed': 2.0})
