"""The node's ground and height band: the ground, min_agl and max_agl parameters.

One planner in the paper's open box with a flat ground at z = 0 and a 5 m AGL ceiling: its
plans keep gamma above the ground and stay below the ceiling at dense samples; a change of the
band at run time replans the goal in force; a band without a ground is refused.

A terrain_file: a real GeoTIFF written by rasterio (a projected CRS in metres and a
geotransform) with a ridge across the way is the ground, and a plan over it keeps the AGL band
at dense samples of the published path; bounds the terrain does not cover are refused and the
terrain stays. A terrain file the loader refuses: the node runs, says why in its log and map
status, and refuses goals with the reason.
"""

from pathlib import Path
from typing import Iterator

import numpy as np
import pytest

from ros_harness import (assert_start_file_refused, planner_session, PlannerClient, READY_TEXT,
                         RUN_NAMESPACE)
from uav_global_planner.core.map.dem import load_dem
from uav_global_planner.ros import conversions as conv

pytestmark = pytest.mark.ros

GAMMA = 0.2  # config/planner.yaml
NS = f'{RUN_NAMESPACE}/grounded'
GOAL = np.array([0.0, 8.0, 4.0])
DENSE_SAMPLES = 10_000
TOL = 1e-6


@pytest.fixture(scope='module')
def planner() -> Iterator[PlannerClient]:
    with planner_session(NS, {'plan_without_map': True, 'ground': 'floor', 'max_agl': 5.0,
                              'start': [0.0, -5.0, 1.0]}) as planner:
        yield planner


def dense_points(path_msg) -> np.ndarray:
    points = conv.path_to_points(path_msg)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    s = np.linspace(0.0, arc[-1], DENSE_SAMPLES)
    return np.stack([np.interp(s, arc, points[:, a]) for a in range(3)], axis=1)


def test_the_band_holds_and_follows_its_parameters(planner) -> None:
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok', values
    z = dense_points(path)[:, 2]
    assert z.min() >= GAMMA - TOL and z.max() <= 5.0 + TOL
    # A goal above the ceiling: within the margin of the AGL ceiling's solid.
    values, _ = planner.plan_to([0.0, 8.0, 6.0])
    assert values['status'] == 'goal_occupied', values
    # A lower ceiling at run time: the goal at 4 m is now above it and refused.
    assert planner.params.set_atomically({'max_agl': 3.0}).successful
    values, _ = planner.plan_to(GOAL)
    assert values['status'] == 'goal_occupied', values
    values, path = planner.plan_to([0.0, 8.0, 2.0])
    assert values['status'] == 'ok', values
    assert dense_points(path)[:, 2].max() <= 3.0 + TOL
    # A number is a flat ground at that height; a band without a ground is refused.
    assert planner.params.set_atomically({'ground': 0.5}).successful
    refused = planner.params.set_atomically({'ground': 'none'})
    assert not refused.successful and 'there is none' in refused.reason


# ------------------------------------------------------------------------------ terrain_file

MIN_AGL, MAX_AGL = 1.0, 5.0
BOUNDS_XY = ((-10.0, -10.0), (10.0, 10.0))  # config/planner.yaml [m]
# Linear interpolation between the path's points (0.1 m apart) against the curve [m].
CHORD_TOL = 2e-3


def ridge(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Terrain elevation [m]: a 3 m ridge along x at y = 1 m between the start and the goal,
    on a plain that undulates by 0.5 m."""
    return 1.0 + 3.0 * np.exp(-((y - 1.0) / 2.5) ** 2) + 0.5 * np.sin(x / 3.0)


def write_geotiff(path: Path, west: float, north: float, size: int) -> Path:
    """A GeoTIFF of :func:`ridge` in UTM zone 33 north (EPSG:32633, metres), 1 m pixels, the
    north-west corner at (west, north): without a geodetic origin its CRS is the map frame."""
    rasterio = pytest.importorskip('rasterio')
    affine = pytest.importorskip('affine')
    centres = np.arange(size) + 0.5
    xs, ys = np.meshgrid(west + centres, north - centres)
    with rasterio.open(path, 'w', driver='GTiff', width=size, height=size, count=1,
                       dtype='float32', crs='EPSG:32633',
                       transform=affine.Affine(1.0, 0.0, west, 0.0, -1.0, north)) as dataset:
        dataset.write(ridge(xs, ys).astype(np.float32), 1)
    return path


def test_a_terrain_file_is_the_ground_and_the_band_follows_it(tmp_path) -> None:
    dem = write_geotiff(tmp_path / 'ridge.tif', -20.0, 20.0, 40)
    # The node reads the file over the bounds the same way: the surface it plans over.
    terrain = load_dem(dem, *BOUNDS_XY)
    start = np.array([0.0, -5.0, 0.0])
    start[2] = terrain.height_at(start[None, :2])[0] + 2.0
    goal = np.array([0.0, 8.0, 0.0])
    goal[2] = terrain.height_at(goal[None, :2])[0] + 2.0
    with planner_session(f'{RUN_NAMESPACE}/terrain', {
            'plan_without_map': True, 'terrain_file': str(dem), 'min_agl': MIN_AGL,
            'max_agl': MAX_AGL, 'start': start.tolist()}) as planner:
        assert f'terrain {dem}: ' in planner.process.wait_for_output(READY_TEXT, 1.0)
        status = planner.wait_diag(0, 'map_status')
        assert status['terrain_file_status'] == 'ok' and status['terrain_file'] == str(dem)
        assert float(status['terrain_height_max_m']) == pytest.approx(
            float(np.max(terrain.heights)), abs=1e-3), status
        values, path = planner.plan_to(goal)
        assert values['status'] == 'ok', values
        dense = dense_points(path)
        agl = dense[:, 2] - terrain.height_at(dense[:, :2])
        assert agl.min() >= MIN_AGL - CHORD_TOL, agl.min()
        assert agl.max() <= MAX_AGL + CHORD_TOL, agl.max()
        # Over the ridge's crest (at least 3.5 m high everywhere): the band made it climb.
        assert terrain.height_at(dense[:, :2]).max() > 3.4
        assert dense[:, 2].max() > 3.4 + MIN_AGL
        # Bounds beyond the terrain: refused, and the terrain in force stays.
        refused = planner.params.set_atomically({'bounds.max': [25.0, 10.0, 15.0]})
        assert not refused.successful, refused
        assert 'terrain_file cannot follow' in refused.reason, refused.reason
        assert 'does not cover the bounds' in refused.reason, refused.reason
        values, path = planner.plan_to(goal)
        assert values['status'] == 'ok', values
        dense = dense_points(path)
        agl = dense[:, 2] - terrain.height_at(dense[:, :2])
        assert MIN_AGL - CHORD_TOL <= agl.min() and agl.max() <= MAX_AGL + CHORD_TOL
        # A geodetic origin places the GeoTIFF by latitude and longitude: this one (UTM
        # eastings near 0) then lies far from the map, so the origin is refused.
        refused = planner.params.set_atomically({'geodetic_origin': [47.0, 15.0, 400.0]})
        assert not refused.successful, refused
        assert 'terrain_file cannot follow' in refused.reason, refused.reason
        # Bounds it covers: read again over them, and still the ground.
        assert planner.params.set_atomically({'bounds.max': [12.0, 10.0, 15.0]}).successful
        values, path = planner.plan_to(goal)
        assert values['status'] == 'ok', values
        dense = dense_points(path)
        wider = load_dem(dem, BOUNDS_XY[0], (12.0, 10.0))
        agl = dense[:, 2] - wider.height_at(dense[:, :2])
        assert MIN_AGL - CHORD_TOL <= agl.min() and agl.max() <= MAX_AGL + CHORD_TOL


def test_a_refused_terrain_file_refuses_goals_and_the_node_runs_on(tmp_path) -> None:
    # Pixel centres from 0.5 to 4.5 m: the bounds' -10..10 m are not covered.
    small = write_geotiff(tmp_path / 'small.tif', 0.0, 5.0, 5)
    reason = 'the terrain does not cover the bounds'
    # A height band with no ground but the refused terrain: the node still starts.
    with planner_session(f'{RUN_NAMESPACE}/no_terrain', {
            'plan_without_map': True, 'terrain_file': str(small),
            'max_agl': MAX_AGL}) as planner:
        process = planner.process
        assert_start_file_refused(planner, 'terrain_file', small, reason)
        (result,) = planner.params.set({'terrain_file': ''})
        # Read-only (named at start-up): rclpy refuses it on a running node.
        assert not result.successful and 'read-only parameter: terrain_file' in result.reason
        assert process.process.poll() is None, process.output
