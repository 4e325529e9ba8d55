"""Scene files: the shipped scenes load, and every malformed file names its key path."""

import copy

from helpers.documents import changed
import numpy as np
import pytest
import yaml

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import find_scene, load_scene, parse_scene, shipped_scenes
from uav_global_planner.core.map.obstacles import Box, PointSet, Sphere

VALID = {
    'frame_id': 'map',
    'bounds': {'min': [-2.0, -2.0, 0.0], 'max': [2.0, 2.0, 3.0]},
    'resolution': 0.25,
    'safety_margin': 0.2,
    'adaptive_threshold': 1.5,
    'start': [-1.5, -1.5, 0.5],
    'goal': [1.5, 1.5, 2.5],
    'obstacles': [
        {'type': 'sphere', 'center': [0.0, 0.0, 1.5], 'radius': 0.5},
        {'type': 'box', 'min': [1.0, -1.0, 0.0], 'max': [1.5, 0.0, 1.0]},
        {'type': 'points', 'points': [[-1.0, 1.0, 1.0], [-1.0, 1.1, 1.0]]},
    ],
}


def test_shipped_scenes_load():
    names = [path.stem for path in shipped_scenes()]
    assert names == ['airspace_demo', 'city1km', 'dense60_fine', 'dense60_mid', 'paper_high',
                     'paper_medium', 'town400', 'wall_gap']
    medium = load_scene(find_scene('paper_medium'))
    assert len(medium.obstacles) == 7
    assert medium.config.resolution == 0.5
    assert medium.config.safety_margin == 0.2
    assert medium.config.adaptive_threshold == 1.5
    assert np.array_equal(medium.start, [0.0, -5.0, 0.0])
    assert np.array_equal(medium.goal, [10.0, 5.0, 10.0])
    assert len(load_scene(find_scene('paper_high')).obstacles) == 15


def test_all_three_obstacle_types_parse():
    scene = parse_scene(copy.deepcopy(VALID))
    kinds = [type(item) for item in scene.obstacles.items]
    assert kinds == [Sphere, Box, PointSet]
    assert scene.obstacles.points.shape == (2, 3)


@pytest.mark.parametrize('path, value, message', [
    (('resolution',), KeyError, 'resolution: missing required key'),
    (('goal',), KeyError, 'goal: missing required key'),
    (('bounds', 'max'), KeyError, 'bounds.max: missing required key'),
    (('resolution',), 'fine', "resolution: must be a number, got 'fine'"),
    (('resolution',), -0.5, 'resolution: must be in'),
    (('safety_margin',), True, 'safety_margin: must be a number'),
    (('start',), [0.0, 0.0], 'start: must be a list of three numbers'),
    (('goal', 2), float('nan'), r'goal\[2\]: must be finite'),
    (('bounds', 'min', 0), 5.0, 'bounds.min must be below bounds.max'),
    (('speed',), 3, 'scene: unknown key.*speed'),
    (('bounds', 'centre'), [0, 0, 0], 'bounds: unknown key.*centre'),
    (('obstacles',), {'type': 'sphere'}, 'obstacles: must be a list'),
    (('obstacles', 0, 'type'), 'cone', r"obstacles\[0\].type: unknown obstacle type 'cone'"),
    (('obstacles', 0, 'radius'), KeyError, r'obstacles\[0\].radius: missing required key'),
    (('obstacles', 0, 'radius'), 0.0, r'obstacles\[0\].radius: must be > 0 m'),
    (('obstacles', 0, 'radius'), '1', r'obstacles\[0\].radius: must be a number'),
    (('obstacles', 0, 'colour'), 'red', r'obstacles\[0\]: unknown key.*colour'),
    (('obstacles', 1, 'max'), [1.0, -1.0, 1.0], r'obstacles\[1\]: min must be below max'),
    (('obstacles', 2, 'points'), [[0, 0, 0], [1, 1]],
     r'obstacles\[2\].points\[1\]: must be a list of three numbers'),
    (('obstacles', 2, 'points'), 7, r'obstacles\[2\].points: must be a list'),
    (('obstacles', 1), 'box', r'obstacles\[1\]: must be a mapping'),
    (('frame_id',), '', 'frame_id: must be a non-empty string'),
])
def test_malformed_scene_names_the_key_path(path, value, message):
    with pytest.raises(InvalidInputError, match=message):
        parse_scene(changed(VALID, path, value))


def test_empty_file_and_non_yaml_file(tmp_path):
    empty = tmp_path / 'empty.yaml'
    empty.write_text('')
    with pytest.raises(InvalidInputError, match='empty: the scene file is empty'):
        load_scene(empty)
    broken = tmp_path / 'broken.yaml'
    broken.write_text('bounds: {min: [0, 0, 0]\nresolution: [')
    with pytest.raises(InvalidInputError, match='not valid YAML'):
        load_scene(broken)
    listing = tmp_path / 'list.yaml'
    listing.write_text(yaml.safe_dump([1, 2, 3]))
    with pytest.raises(InvalidInputError, match='list: must be a mapping'):
        load_scene(listing)
    with pytest.raises(InvalidInputError, match='cannot read scene file'):
        load_scene(tmp_path / 'missing.yaml')
    with pytest.raises(InvalidInputError, match='no such scene file or shipped scene'):
        find_scene('no_such_scene')
