"""Map files: every format written by its own library, read back, and planned around.

Also: corrupt and truncated files name the file, a missing library names its pip package, voxel
downsampling keeps its stated margin, scene files take ``points_file`` obstacles and
``max_voxels``, and ``uav-plan`` takes ``--map`` and ``--max-voxels``.
"""

import json
import math
from pathlib import Path
import re
import shutil
import subprocess
import sys

import laspy
import numpy as np
import octomap
from plyfile import PlyData, PlyElement
from pypcd4 import Encoding, PointCloud
import pytest
from scipy.spatial import cKDTree
import yaml

from uav_global_planner.cli.main import main as uav_plan_main
from uav_global_planner.core.errors import InvalidInputError, MissingDependencyError
from uav_global_planner.core.io import scene as scene_module
from uav_global_planner.core.io.mapfiles import (downsample_margin, load_map_files,
                                                 load_map_points, load_prior_map, voxel_downsample,
                                                 with_prior_map)
from uav_global_planner.core.io.scene import load_scene, parse_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.core.planner import densify, Planner

GAMMA = 0.3
OCTOMAP_RESOLUTION = 0.1
# A wall across the straight line from start to goal, open only beyond y = 7 m: a path must go
# around its end.
START = [2.0, 2.0, 1.0]
GOAL = [8.0, 2.0, 1.0]


def wall_points() -> np.ndarray:
    """Points of a wall at x = 5 m, y 0..7 m, z 0..4 m, 0.1 m apart [m]."""
    y, z = np.meshgrid(np.arange(0.0, 7.05, 0.1), np.arange(0.0, 4.05, 0.1), indexing='ij')
    return np.column_stack([np.full(y.size, 5.0), y.ravel(), z.ravel()])


def _float32_vertices(points: np.ndarray) -> np.ndarray:
    vertex = np.empty(len(points), dtype=[('x', 'f4'), ('y', 'f4'), ('z', 'f4')])
    vertex['x'], vertex['y'], vertex['z'] = points.T
    return vertex


def write_pcd(points: np.ndarray, file: Path, encoding=Encoding.BINARY) -> None:
    PointCloud.from_xyz_points(points.astype(np.float32)).save(file, encoding=encoding)


def write_ply(points: np.ndarray, file: Path, text: bool = False) -> None:
    PlyData([PlyElement.describe(_float32_vertices(points), 'vertex')], text=text).write(str(file))


def write_las(points: np.ndarray, file: Path) -> None:
    header = laspy.LasHeader(point_format=3, version='1.2')
    header.offsets = np.floor(points.min(axis=0))
    header.scales = np.array([0.001, 0.001, 0.001])
    data = laspy.LasData(header)
    data.x, data.y, data.z = points.T
    data.write(str(file))


def write_bt(points: np.ndarray, file: Path) -> None:
    tree = octomap.OcTree(OCTOMAP_RESOLUTION)
    for point in points:
        tree.updateNode(point, True)
    assert tree.writeBinary(str(file).encode())


# Writer, and how far a point read back may be from the one written [m].
WRITERS = {
    'pcd': (write_pcd, 1e-5),
    'pcd_ascii': (lambda p, f: write_pcd(p, f, Encoding.ASCII), 1e-5),
    'pcd_compressed': (lambda p, f: write_pcd(p, f, Encoding.BINARY_COMPRESSED), 1e-5),
    'ply': (write_ply, 1e-5),
    'ply_ascii': (lambda p, f: write_ply(p, f, text=True), 1e-5),
    'las': (write_las, 1e-3),
    'laz': (write_las, 1e-3),
    'npy': (lambda p, f: np.save(f, p), 0.0),
}
SUFFIX = {'pcd_ascii': 'pcd', 'pcd_compressed': 'pcd', 'ply_ascii': 'ply'}


def map_file(kind: str, folder: Path, points: np.ndarray) -> Path:
    """Write ``points`` as a ``kind`` file (a key of WRITERS, or 'bt') into ``folder``."""
    file = folder / f'wall_{kind}.{SUFFIX.get(kind, kind)}'
    (write_bt if kind == 'bt' else WRITERS[kind][0])(points, file)
    return file


def scene_document(obstacles: list) -> dict:
    return {'bounds': {'min': [0.0, 0.0, 0.0], 'max': [10.0, 10.0, 4.0]}, 'resolution': 0.25,
            'safety_margin': GAMMA, 'adaptive_threshold': 1.5, 'start': START, 'goal': GOAL,
            'obstacles': obstacles}


def write_scene(folder: Path, obstacles: list, **extra) -> Path:
    file = folder / 'scene.yaml'
    file.write_text(yaml.safe_dump({**scene_document(obstacles), **extra}))
    return file


def min_distance(samples: np.ndarray, points: np.ndarray) -> float:
    return float(np.min(cKDTree(points).query(samples)[0]))


def min_distance_to_cubes(samples: np.ndarray, centres: np.ndarray, side: float) -> float:
    """Exact distance from the samples to the union of axis-aligned cubes [m]."""
    best = math.inf
    for first in range(0, len(samples), 256):
        chunk = samples[first:first + 256, None, :]
        excess = np.maximum(np.abs(chunk - centres[None, :, :]) - side / 2.0, 0.0)
        best = min(best, float(np.min(np.sqrt(np.sum(excess ** 2, axis=-1)))))
    return best


def plan_scene(file: Path):
    scene = load_scene(file)
    result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal, 'octile')
    assert result.ok, result.message
    return scene, result, densify(result.smoothed_path, 0.01)


# --------------------------------------------------------------------------------------------
# Every format: read back what its library wrote, then plan around it
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('kind', sorted(WRITERS))
def test_points_written_by_the_library_read_back(tmp_path, kind):
    points = wall_points()
    loaded = load_map_points(map_file(kind, tmp_path, points))
    assert loaded.points.dtype == np.float64 and loaded.points.shape == points.shape
    assert np.max(np.abs(loaded.points - points)) <= WRITERS[kind][1] + 1e-12
    assert loaded.margin_m == 0.0 and loaded.read_points == len(points)


@pytest.mark.parametrize('kind', sorted(WRITERS))
def test_planning_around_a_map_file_keeps_clearance(tmp_path, kind):
    points = wall_points()
    file = map_file(kind, tmp_path, points)
    scene, result, samples = plan_scene(
        write_scene(tmp_path, [{'type': 'points_file', 'path': file.name}]))
    assert scene.config.safety_margin == GAMMA and scene.map_margin_m == 0.0
    # Around the end of the wall, not through it: the straight line is 6 m.
    assert result.smoothed_length_m > 10.0
    assert min_distance(samples, points) >= GAMMA - WRITERS[kind][1] - 1e-9


def test_octomap_occupied_cells_are_read_and_planned_around_with_their_margin(tmp_path):
    points = wall_points()
    file = map_file('bt', tmp_path, points)
    loaded = load_map_points(file)
    margin = OCTOMAP_RESOLUTION * math.sqrt(3.0) / 2.0
    assert loaded.margin_m == pytest.approx(margin)
    # Every occupied point lies in a cell whose centre was read, so within the margin of it.
    assert np.max(cKDTree(loaded.points).query(points)[0]) <= margin + 1e-9
    assert np.max(np.abs(loaded.points / OCTOMAP_RESOLUTION % 1.0 - 0.5)) < 1e-6
    scene, result, samples = plan_scene(
        write_scene(tmp_path, [{'type': 'points_file', 'path': file.name}]))
    # gamma grows by the cells' margin, so the path keeps gamma from the occupied cubes.
    assert scene.config.safety_margin == pytest.approx(GAMMA + margin)
    assert scene.map_margin_m == pytest.approx(margin)
    assert result.smoothed_length_m > 10.0
    assert min_distance_to_cubes(samples, loaded.points, OCTOMAP_RESOLUTION) >= GAMMA - 1e-9


def test_pruned_octomap_leaves_are_split_into_cells(tmp_path):
    # A solid 1.6 m cube is pruned into one leaf by writeBinary; it must come back as 16^3 cells.
    steps = (np.arange(16) + 0.5) * OCTOMAP_RESOLUTION
    block = np.stack(np.meshgrid(steps, steps, steps, indexing='ij'), axis=-1).reshape(-1, 3)
    file = tmp_path / 'block.bt'
    write_bt(block, file)
    tree = octomap.OcTree(OCTOMAP_RESOLUTION)
    assert tree.readBinary(str(file).encode())
    assert tree.getNumLeafNodes() < 100, 'the block was not pruned: the test proves nothing'
    loaded = load_map_points(file)
    assert len(loaded.points) == len(block)
    assert np.max(cKDTree(loaded.points).query(block)[0]) < 1e-9


# --------------------------------------------------------------------------------------------
# Corrupt and truncated files, missing libraries, wrong contents
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('kind', sorted(WRITERS) + ['bt'])
@pytest.mark.parametrize('damage', ['truncated', 'header_only', 'garbage'])
def test_corrupt_or_truncated_file_names_the_file(tmp_path, kind, damage):
    file = map_file(kind, tmp_path, wall_points())
    data = file.read_bytes()
    if damage == 'truncated':
        file.write_bytes(data[:len(data) // 2])
    elif damage == 'header_only':
        file.write_bytes(data[:40])
    else:
        file.write_bytes(bytes(np.random.default_rng(1).integers(0, 256, 4000, dtype=np.uint8)))
    with pytest.raises(InvalidInputError) as raised:
        load_map_points(file)
    message = str(raised.value)
    assert message.startswith(f'{file}: ')
    assert 'truncated' in message or 'not a valid' in message


def test_ascii_pcd_cut_at_a_line_end_is_refused(tmp_path):
    file = map_file('pcd_ascii', tmp_path, wall_points())
    lines = file.read_text().splitlines(keepends=True)
    file.write_text(''.join(lines[:len(lines) // 2]))
    with pytest.raises(InvalidInputError, match='truncated PCD file: the header announces 2911'):
        load_map_points(file)


@pytest.mark.parametrize('suffix, module, package', [
    ('pcd', 'pypcd4', 'pypcd4'), ('ply', 'plyfile', 'plyfile'), ('las', 'laspy', 'laspy'),
    ('bt', 'octomap', 'octomap-python')])
def test_missing_library_names_its_pip_package(tmp_path, monkeypatch, suffix, module, package):
    file = map_file('bt' if suffix == 'bt' else suffix, tmp_path, wall_points())
    # A None entry makes the import fail as if the package were not installed.
    monkeypatch.setitem(sys.modules, module, None)
    with pytest.raises(MissingDependencyError, match=f'pip install {package}'):
        load_map_points(file)


def test_laz_without_a_backend_names_lazrs(tmp_path):
    file = map_file('laz', tmp_path, wall_points())
    # laspy looks for its LAZ backends when it is imported: a fresh process without them.
    code = ('import sys\n'
            "sys.modules['lazrs'] = sys.modules['laszip'] = None\n"
            'from uav_global_planner.core.io.mapfiles import load_map_points\n'
            f'load_map_points({str(file)!r})\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode != 0
    assert 'MissingDependencyError' in run.stderr and 'pip install lazrs' in run.stderr
    assert str(file) in run.stderr


def test_wrong_contents_are_refused_with_the_reason(tmp_path):
    mesh = tmp_path / 'mesh.ply'
    vertex = _float32_vertices(np.eye(3))
    face = np.array([([0, 1, 2],)], dtype=[('vertex_indices', 'i4', (3,))])
    PlyData([PlyElement.describe(vertex, 'vertex'), PlyElement.describe(face, 'face')]).write(
        str(mesh))
    with pytest.raises(InvalidInputError, match='is a mesh .1 faces.*sample the surface'):
        load_map_points(mesh)
    flat = tmp_path / 'flat.pcd'
    PointCloud.from_points(np.zeros((4, 2), dtype=np.float32), ('x', 'y'),
                           (np.float32, np.float32)).save(flat)
    with pytest.raises(InvalidInputError, match='flat.pcd: this PCD file has no z field'):
        load_map_points(flat)
    pairs = tmp_path / 'pairs.npy'
    np.save(pairs, np.zeros((5, 2)))
    with pytest.raises(InvalidInputError, match=r'an \(N, 3\) array .* got shape \(5, 2\)'):
        load_map_points(pairs)
    words = tmp_path / 'words.npy'
    np.save(words, np.array([['a', 'b', 'c']]))
    with pytest.raises(InvalidInputError, match='must hold numbers'):
        load_map_points(words)
    with pytest.raises(InvalidInputError, match=r"unknown map file type '\.xyz'; supported"):
        (tmp_path / 'cloud.xyz').write_text('0 0 0\n')
        load_map_points(tmp_path / 'cloud.xyz')
    with pytest.raises(InvalidInputError, match='missing.las: cannot read map file .no such'):
        load_map_points(tmp_path / 'missing.las')


def test_non_finite_points_are_dropped_and_counted(tmp_path):
    points = wall_points()
    points[::10, 1] = np.nan
    points[5, 2] = np.inf
    file = tmp_path / 'holes.npy'
    np.save(file, points)
    loaded = load_map_points(file)
    assert loaded.dropped_non_finite == len(points[::10]) + 1
    assert len(loaded.points) == len(points) - loaded.dropped_non_finite
    assert np.all(np.isfinite(loaded.points))


def test_every_load_reports_read_dropped_kept_and_extent(tmp_path):
    points = wall_points()
    holes = np.vstack([points, [[np.nan, 1.0, 1.0], [1.0, np.inf, 1.0]],
                       [[40.0, 2.0, 1.0], [5.0, 2.0, -3.0]]])
    file = tmp_path / 'wall.npy'
    np.save(file, holes)
    bounds = ([0.0, 0.0, 0.0], [10.0, 10.0, 4.0])
    loaded = load_map_points(file, 0.5, bounds=bounds, reach=GAMMA, resolution=0.25)
    (report,) = loaded.reports
    assert report.file == str(file) and report.format == 'NumPy .npy'
    assert report.points_read == len(holes)
    assert report.dropped_non_finite == 2
    # 40 m is far beyond the bounds; z = -3 m lies more than gamma below the floor.
    assert report.outside_bounds == report.dropped_outside_bounds == 2
    assert report.dropped_downsampled == len(points) - len(loaded.points)
    assert report.points_kept == len(loaded.points)
    assert report.points_read == (report.dropped_non_finite + report.dropped_outside_bounds
                                  + report.dropped_downsampled + report.points_kept)
    assert np.allclose(report.extent_min, loaded.points.min(axis=0))
    assert np.allclose(report.extent_max, loaded.points.max(axis=0))
    assert report.downsample_m == 0.5 and report.resolution_m is None
    assert report.margin_m == loaded.margin_m == pytest.approx(downsample_margin(0.5))
    assert json.loads(json.dumps(report.as_dict()))['points_kept'] == report.points_kept
    assert ('dropped 2 non-finite, 2 outside the bounds, '
            f'{report.dropped_downsampled} merged by downsampling') in report.summary()
    # Without bounds nothing is outside; the prior map of the node counts but keeps them.
    assert load_map_points(file).reports[0].outside_bounds == 0
    prior = load_prior_map(str(file), bounds=bounds, reach=GAMMA)
    assert prior.reports[0].outside_bounds == 2 and prior.reports[0].dropped_outside_bounds == 0
    assert len(prior.points) == len(points) + 2
    assert '(2 outside the bounds)' in prior.reports[0].summary()
    # An OctoMap reports its resolution; several files report one each, in order.
    octo = map_file('bt', tmp_path, points)
    both = load_map_files([file, octo], bounds=bounds, reach=GAMMA, resolution=0.25)
    assert [r.file for r in both.reports] == [str(file), str(octo)]
    assert both.reports[1].resolution_m == pytest.approx(OCTOMAP_RESOLUTION)
    assert sum(r.points_kept for r in both.reports) == len(both.points)


def test_a_point_just_within_reach_of_the_bounds_is_kept(tmp_path):
    """A point that may come within gamma (plus the map's margin) of the bounds can matter."""
    file = tmp_path / 'edge.npy'
    np.save(file, np.array([[5.0, 5.0, 2.0], [10.0 + GAMMA - 1e-9, 5.0, 2.0],
                            [10.0 + GAMMA + 1e-6, 5.0, 2.0]]))
    loaded = load_map_points(file, bounds=([0.0, 0.0, 0.0], [10.0, 10.0, 4.0]), reach=GAMMA)
    assert len(loaded.points) == 2 and loaded.reports[0].dropped_outside_bounds == 1


# --------------------------------------------------------------------------------------------
# Voxel downsampling and its margin
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('cell', [0.05, 0.3, 1.0, 7.0])
def test_downsampling_keeps_every_point_within_its_margin(cell):
    points = np.random.default_rng(2).uniform(-20.0, 30.0, size=(20_000, 3))
    kept = voxel_downsample(points, cell)
    assert len(kept) <= len(points)
    assert len(np.unique(np.floor(kept / cell), axis=0)) == len(kept), 'two points in a cell'
    # Cell centres, one for each occupied cell.
    assert np.max(np.abs(kept / cell % 1.0 - 0.5)) < 1e-6
    assert len(kept) == len(np.unique(np.floor(points / cell), axis=0))
    assert np.max(cKDTree(kept).query(points)[0]) <= downsample_margin(cell) + 1e-9


def test_downsampling_refuses_a_bad_cell():
    for cell, words in ((0.0, 'a cell size > 0 m, got 0.0'), (-1.0, 'a cell size > 0 m, got -1.0'),
                        (math.nan, 'finite, got nan'), (math.inf, 'finite, got inf'),
                        (True, 'a number, got True'), ('big', "a number, got 'big'")):
        with pytest.raises(InvalidInputError, match=f'^downsample must be {re.escape(words)}$'):
            voxel_downsample(np.zeros((3, 3)), cell)


def test_downsampled_map_keeps_gamma_from_the_original_points(tmp_path):
    points = wall_points()
    file = map_file('las', tmp_path, points)
    cell = 0.4
    scene, result, samples = plan_scene(write_scene(
        tmp_path, [{'type': 'points_file', 'path': file.name, 'downsample': cell}]))
    margin = cell * math.sqrt(3.0) / 2.0
    assert scene.map_margin_m == pytest.approx(margin)
    assert scene.config.safety_margin == pytest.approx(GAMMA + margin)
    assert len(scene.obstacles.points) < len(points) / 4
    assert min_distance(samples, points) >= GAMMA - 1e-3


# --------------------------------------------------------------------------------------------
# Scene files: points_file, relative paths, max_voxels, the C loader
# --------------------------------------------------------------------------------------------

def test_relative_paths_start_from_the_scene_folder(tmp_path, monkeypatch):
    maps = tmp_path / 'maps'
    maps.mkdir()
    file = map_file('npy', maps, wall_points())
    scene_file = write_scene(tmp_path, [{'type': 'points_file', 'path': f'maps/{file.name}'}])
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert len(load_scene(scene_file).obstacles.points) == len(wall_points())
    # An absolute path works from anywhere, too.
    absolute = write_scene(elsewhere, [{'type': 'points_file', 'path': str(file)}])
    assert len(load_scene(absolute).obstacles.points) == len(wall_points())


@pytest.mark.parametrize('entry, message', [
    ({'type': 'points_file'}, r'obstacles\[0\].path: missing required key'),
    ({'type': 'points_file', 'path': 3}, r'obstacles\[0\].path: must be a file name'),
    ({'type': 'points_file', 'path': 'gone.pcd'},
     r'obstacles\[0\].path: .*gone.pcd: cannot read map file \(no such file\)'),
    ({'type': 'points_file', 'path': 'wall.npy', 'downsample': 0.0},
     r'obstacles\[0\].downsample: must be a cell size > 0 m'),
    ({'type': 'points_file', 'path': 'wall.npy', 'downsample': 'fine'},
     r'obstacles\[0\].downsample: must be a number'),
    ({'type': 'points_file', 'path': 'wall.npy', 'colour': 'red'},
     r'obstacles\[0\]: unknown key\(s\) colour'),
])
def test_bad_points_file_entries_name_the_key(tmp_path, entry, message):
    np.save(tmp_path / 'wall.npy', wall_points())
    with pytest.raises(InvalidInputError, match=message):
        load_scene(write_scene(tmp_path, [entry]))


def test_corrupt_map_in_a_scene_names_the_key_and_the_file(tmp_path):
    file = map_file('ply', tmp_path, wall_points())
    file.write_bytes(file.read_bytes()[:300])
    with pytest.raises(InvalidInputError,
                       match=rf'obstacles\[0\].path: {file}: not a valid PLY file, or truncated'):
        load_scene(write_scene(tmp_path, [{'type': 'points_file', 'path': file.name}]))


def test_max_voxels_in_a_scene_file(tmp_path):
    document = scene_document([])
    assert parse_scene({**document, 'max_voxels': 30000}).config.max_voxels == 30000
    # 41 x 41 x 17 = 28577 nodes: the refusal names the key and how to raise it.
    with pytest.raises(InvalidInputError, match='exceeds max_voxels = 1000; .*raise max_voxels '
                       r'\(scene key max_voxels, uav-plan --max-voxels N'):
        parse_scene({**document, 'max_voxels': 1000})
    for value in (1.5e8, True, '100'):
        with pytest.raises(InvalidInputError, match='max_voxels: must be an integer'):
            parse_scene({**document, 'max_voxels': value})
    with pytest.raises(InvalidInputError, match='max_voxels: must be >= 1, got 0'):
        parse_scene({**document, 'max_voxels': 0})


def test_scene_files_load_with_the_c_yaml_loader_when_available():
    if getattr(yaml, '__with_libyaml__', False):
        assert scene_module._YAML_LOADER is yaml.CSafeLoader
    else:
        assert scene_module._YAML_LOADER is yaml.SafeLoader


def test_inline_points_still_parse_and_are_checked(tmp_path):
    file = write_scene(tmp_path, [{'type': 'points', 'points': wall_points().tolist()}])
    assert np.array_equal(load_scene(file).obstacles.points, wall_points())
    # A tag the safe loaders refuse is still refused by the C loader.
    (tmp_path / 'tagged.yaml').write_text('bounds: !!python/object:object {}\n')
    with pytest.raises(InvalidInputError, match='not valid YAML'):
        load_scene(tmp_path / 'tagged.yaml')


# --------------------------------------------------------------------------------------------
# The node's prior map
# --------------------------------------------------------------------------------------------

def test_prior_map_combines_with_live_obstacles(tmp_path):
    assert load_prior_map('') is None and load_prior_map('   ') is None
    file = map_file('pcd', tmp_path, wall_points())
    prior = load_prior_map(str(file))
    live = ObstacleSet([Sphere([1.0, 8.0, 1.0], 0.5)])
    combined = with_prior_map(live, prior)
    assert len(combined.points) == len(wall_points())
    assert combined.distance(np.array([1.0, 8.0, 1.0])) == 0.0
    assert combined.distance(np.array([5.0, 3.0, 2.0])) < 1e-6
    assert with_prior_map(live, None) is live
    assert len(load_prior_map(str(file), downsample=1.0).points) < len(wall_points())
    with pytest.raises(InvalidInputError, match='map_file must be a path'):
        load_prior_map(None)
    both = load_map_files([file, map_file('bt', tmp_path, wall_points())])
    assert both.margin_m == pytest.approx(OCTOMAP_RESOLUTION * math.sqrt(3.0) / 2.0)


# --------------------------------------------------------------------------------------------
# uav-plan: --map, --map-downsample, --max-voxels, points_file, grid_build_time_s
# --------------------------------------------------------------------------------------------

def uav_plan(*args, cwd=None):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    return subprocess.run([executable, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def test_cli_map_option_plans_around_the_file(tmp_path):
    points = wall_points()
    file = map_file('laz', tmp_path, points)
    scene_file = write_scene(tmp_path, [])
    free = json.loads(uav_plan('plan', str(scene_file), '--json').stdout)
    assert free['status'] == 'ok' and free['smoothed_length_m'] < 6.5
    run = uav_plan('plan', str(scene_file), '--json', '--algorithm', 'octile', '--map', str(file))
    assert run.returncode == 0, run.stdout + run.stderr
    result = json.loads(run.stdout)
    assert result['status'] == 'ok' and result['smoothed_length_m'] > 10.0
    assert min_distance(densify(np.array(result['smoothed_path']), 0.01), points) >= GAMMA - 2e-3
    # Two maps and downsampling: gamma grows by the downsampling margin.
    other = map_file('npy', tmp_path, points + [0.0, 0.0, 0.0])
    run = uav_plan('plan', str(scene_file), '--json', '--map', str(file), '--map', str(other),
                   '--map-downsample', '0.5')
    result = json.loads(run.stdout)
    assert result['status'] == 'ok', result['message']
    assert result['safety_margin'] == pytest.approx(GAMMA + 0.5 * math.sqrt(3.0) / 2.0)


def test_cli_points_file_scene_and_a_corrupt_map(tmp_path):
    file = map_file('ply', tmp_path, wall_points())
    scene_file = write_scene(tmp_path, [{'type': 'points_file', 'path': file.name}])
    run = uav_plan('plan', str(scene_file), '--json', cwd=str(Path('/')))
    assert run.returncode == 0, run.stdout + run.stderr
    assert json.loads(run.stdout)['smoothed_length_m'] > 10.0
    broken = tmp_path / 'broken.pcd'
    broken.write_bytes(b'# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\n')
    run = uav_plan('plan', str(scene_file), '--json', '--map', str(broken))
    assert run.returncode == 2
    result = json.loads(run.stdout)
    assert result['status'] == 'invalid_input'
    assert result['message'].startswith(f'--map: {broken}: not a valid PCD file')
    human = uav_plan('plan', str(scene_file), '--map', str(broken))
    assert human.returncode == 2 and str(broken) in human.stderr
    run = uav_plan('plan', str(scene_file), '--map-downsample', '0.5')
    assert run.returncode == 2 and '--map-downsample needs at least one --map' in run.stderr


def test_cli_text_and_json_say_what_each_map_file_read(tmp_path, capsys):
    """Points read, dropped (why), kept and the extent, for the scene's points_file and for
    every --map, in the JSON and in the text summary (in-process: the console script's main)."""
    points = wall_points()
    scene_map = map_file('ply', tmp_path, points)
    extra = tmp_path / 'extra.npy'
    np.save(extra, np.vstack([points + [0.0, 0.0, 0.0], [[np.nan, 0.0, 0.0]],
                              [[500.0, 0.0, 0.0]]]))
    scene_file = write_scene(tmp_path, [{'type': 'points_file', 'path': scene_map.name}])
    code = uav_plan_main(['plan', str(scene_file), '--json', '--map', str(extra),
                          '--algorithm', 'octile'])
    result = json.loads(capsys.readouterr().out)
    assert code == 0, result['message']
    first, second = result['map_files']
    assert first['file'] == str(scene_map) and first['format'] == 'PLY'
    assert first['points_read'] == first['points_kept'] == len(points)
    assert first['dropped_non_finite'] == first['dropped_outside_bounds'] == 0
    assert first['extent_min'] == pytest.approx(points.min(axis=0).tolist(), abs=1e-5)
    assert first['extent_max'] == pytest.approx(points.max(axis=0).tolist(), abs=1e-5)
    assert second['file'] == str(extra) and second['points_read'] == len(points) + 2
    assert second['dropped_non_finite'] == 1 and second['dropped_outside_bounds'] == 1
    assert second['points_kept'] == len(points)
    code = uav_plan_main(['plan', str(scene_file), '--map', str(extra), '--algorithm', 'octile'])
    text = capsys.readouterr().out
    assert code == 0, text
    lines = [line for line in text.splitlines() if line.startswith('map file ')]
    assert lines == [f'map file {scene_map}: {len(points)} points read, dropped none, '
                     f'{len(points)} kept, extent x [5.000, 5.000] y [0.000, 7.000] '
                     'z [0.000, 4.000] m',
                     f'map file {extra}: {len(points) + 2} points read, dropped 1 non-finite, '
                     f'1 outside the bounds, {len(points)} kept, extent x [5.000, 5.000] '
                     'y [0.000, 7.000] z [0.000, 4.000] m']
    # A refused map: exit code 2, the message on stderr, nothing planned.
    empty = tmp_path / 'empty.npy'
    np.save(empty, np.empty((0, 3)))
    code = uav_plan_main(['plan', str(scene_file), '--map', str(empty)])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ''
    assert f'uav-plan: error: --map: {empty}: no points' in captured.err


def test_cli_max_voxels_option(tmp_path):
    # 41 x 41 x 17 = 28577 nodes.
    scene_file = write_scene(tmp_path, [], max_voxels=1000)
    run = uav_plan('plan', str(scene_file), '--json')
    assert run.returncode == 2
    assert 'exceeds max_voxels = 1000' in json.loads(run.stdout)['message']
    assert 'uav-plan --max-voxels' in json.loads(run.stdout)['message']
    run = uav_plan('plan', str(scene_file), '--json', '--max-voxels', '30000')
    assert run.returncode == 0, run.stdout
    run = uav_plan('plan', str(scene_file), '--json', '--max-voxels', '28000')
    assert 'exceeds max_voxels = 28000' in json.loads(run.stdout)['message']


def test_cli_reports_the_real_grid_build_time(tmp_path):
    scene_file = write_scene(tmp_path, [{'type': 'points', 'points': wall_points().tolist()}])
    result = json.loads(uav_plan('plan', str(scene_file), '--json').stdout)
    assert result['status'] == 'ok'
    assert result['grid_build_time_s'] > 0.0, 'the grid built before the plan was not reported'
