"""The outdoor scenes: reproducible files, free endpoints, streets, and the surface cloud."""

from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner_tools import outdoor_scenes as outdoor

REPO_ROOT = Path(__file__).resolve().parents[1]


def test_shipped_files_are_what_the_generator_writes():
    run = subprocess.run([sys.executable, str(REPO_ROOT / 'tools' / 'make_scenes.py'), '--check'],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.parametrize('name, boxes, spheres, shape, margins', [
    ('town400', 400, 0, (401, 401, 81), (0.5, 1.0, 2.0)),
    ('city1km', 300, 0, (1001, 1001, 101), (1.0,)),
    ('wall_gap', 2, 1, (81, 81, 61), (0.2, 1.0, 3.0)),
])
def test_shipped_scenes_load_with_free_endpoints(name, boxes, spheres, shape, margins):
    # The file's own max_voxels admits city1km's 101 M nodes: the default base suffices.
    scene = load_scene(find_scene(name), base=PlannerConfig())
    assert len(scene.obstacles.box_mins) == boxes
    assert len(scene.obstacles.sphere_radii) == spheres
    generated = outdoor.SHIPPED[name]()
    assert generated.shape == shape
    assert np.array_equal(scene.obstacles.box_mins, generated.boxes[:, 0])
    # Free of the buildings for every margin; the towns' ground (ground: floor) is kept the
    # scene's own gamma from.
    buildings = ObstacleSet([item for item in scene.obstacles.items
                             if not isinstance(item, HeightField)])
    clearances = buildings.distance(np.stack([scene.start, scene.goal]))
    assert np.all(clearances > max(margins)), clearances
    assert scene.config.safety_margin == margins[0]
    assert [shape.label for shape in scene.ground] == (
        ['ground'] if name in ('town400', 'city1km') else [])
    assert np.all(scene.obstacles.distance(np.stack([scene.start, scene.goal])) > margins[0])


@pytest.mark.parametrize('make, street', [(outdoor.town400_boxes, 2.0),
                                          (outdoor.city1km_boxes, 8.0)])
def test_buildings_leave_streets_between_them(make, street):
    boxes = make()
    lo, hi = boxes[:, 0, :2], boxes[:, 1, :2]
    gap = np.maximum(np.maximum(lo[:, None] - hi[None], lo[None] - hi[:, None]), 0.0)
    apart = np.sqrt(np.sum(gap ** 2, axis=-1))
    np.fill_diagonal(apart, np.inf)
    # Rounding to 0.1 m may take a few centimetres off a street.
    assert apart.min() >= street - 0.1 - 1e-9
    assert np.all(boxes[:, 0, 2] == 0.0) and np.all(boxes[:, 1] > boxes[:, 0])
    assert np.array_equal(make(), boxes)


def _box_distance(points, box):
    excess = np.maximum(np.maximum(box[0] - points, points - box[1]), 0.0)
    return np.sqrt(np.sum(excess ** 2, axis=-1))


@pytest.mark.parametrize('spacing', [0.3, 0.5, 1.7])
def test_surface_cloud_covers_each_face_within_the_spacing(spacing):
    rng = np.random.default_rng(int(spacing * 10))
    boxes = np.array([[[0.0, 0.0, 0.0], [3.0, 2.2, 4.1]], [[5.0, 1.0, 1.0], [5.5, 4.0, 2.0]]])
    cloud = outdoor.surface_cloud(boxes, spacing)
    assert len(np.unique(cloud, axis=0)) == len(cloud)
    tree = cKDTree(cloud)
    for number, box in enumerate(boxes):
        mine = cloud[_box_distance(cloud, box) == 0.0]
        # On the surface, not inside: some coordinate is on a face.
        on_face = np.any((mine == box[0]) | (mine == box[1]), axis=1)
        assert on_face.all()
        # Random points on the roof and the walls (and the raised floor) have a cloud point
        # within half the lattice diagonal.
        faces = [(2, 1)] + [(axis, side) for axis in (0, 1) for side in (0, 1)]
        if box[0, 2] > 0.0:
            faces.append((2, 0))
        for axis, side in faces:
            samples = rng.uniform(box[0], box[1], (200, 3))
            samples[:, axis] = box[side, axis]
            nearest, _ = tree.query(samples)
            assert nearest.max() <= spacing * np.sqrt(2.0) / 2.0 + 1e-12, (number, axis, side)
    # The first box stands on the ground: its floor is not sampled, only the foot of its walls.
    ground = cloud[cloud[:, 2] == 0.0]
    assert len(ground) and np.all(np.any((ground[:, :2] == boxes[0, 0, :2])
                                         | (ground[:, :2] == boxes[0, 1, :2]), axis=1))


def test_cloud_town_is_about_0_8_m_points_on_the_buildings():
    cloud = outdoor.cloud_town()
    assert 0.75e6 <= len(cloud) <= 0.9e6
    assert np.array_equal(cloud, outdoor.cloud_town())
    boxes = outdoor.town400_boxes()
    sample = cloud[np.random.default_rng(0).choice(len(cloud), 2000, replace=False)]
    nearest = np.min([_box_distance(sample, box) for box in boxes], axis=0)
    assert np.all(nearest == 0.0)


@pytest.mark.parametrize('spacing, boxes', [(0.0, np.zeros((1, 2, 3))),
                                            (-1.0, np.zeros((1, 2, 3))),
                                            (0.5, np.zeros((2, 3)))])
def test_surface_cloud_refuses_bad_input(spacing, boxes):
    with pytest.raises(ValueError, match='spacing|shape'):
        outdoor.surface_cloud(boxes, spacing)
