"""Unknown space: what an OctoMap never observed, and what each ``unknown_space`` policy does.

Real ``.bt`` files are written with the OctoMap bindings: a scan of an L-shaped corridor (free
cells above an occupied floor) whose inside corner is a room nobody looked into, and a ray-cast
scan from one sensor position. The boxes of :mod:`uav_global_planner.core.map.unknown_space` must
cover exactly what the tree does not know (``tree.search`` finds no node there); with ``free``
the plan cuts through the room, with ``occupied`` (the default) it keeps the margin from it, and
with ``cost`` it goes around when the detour costs less than ``unknown_cost`` per metre saved.
"""

import json
import math
from pathlib import Path

import numpy as np
import octomap
import pytest
import yaml

from uav_global_planner.cli.main import main
from uav_global_planner.cli.report import format_summary, result_to_dict
from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import load_scene, parse_scene
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.core.map.unknown_space import (combine, known_volume_unknown, merge_boxes,
                                                       octomap_unknown, octree_unknown,
                                                       UnknownSpace)
from uav_global_planner.core.planner import densify, Planner
from uav_global_planner.core.search.grid_search import SearchWorkspace
from uav_global_planner.core.status import PlanStatus

RESOLUTION = 0.2
BOUNDS = ([0.0, 0.0, 0.0], [12.0, 8.0, 4.0])
START = [1.0, 1.0, 1.5]
GOAL = [11.0, 7.0, 1.5]
# Observed: a corridor along x (y in [0, 2]) and one along y (x in [10, 12]), 3 m high with an
# occupied floor; the rest of the bounds (the room x < 10, y > 2, and everything above 3 m) is
# unknown. The straight line from START to GOAL crosses the room.
CORRIDORS = (((0.0, 0.0), (12.0, 2.0)), ((10.0, 0.0), (12.0, 8.0)))


def _cells(lo, hi) -> np.ndarray:
    axes = [np.arange(low + RESOLUTION / 2, high, RESOLUTION) for low, high in zip(lo, hi)]
    return np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)


def write_corridor_scan(file: Path) -> None:
    tree = octomap.OcTree(RESOLUTION)
    for (x0, y0), (x1, y1) in CORRIDORS:
        for point in _cells((x0, y0, RESOLUTION), (x1, y1, 3.0)):
            tree.updateNode(point, False)
        for point in _cells((x0, y0, 0.0), (x1, y1, RESOLUTION)):
            tree.updateNode(point, True)
    tree.updateInnerOccupancy()
    assert tree.writeBinary(str(file).encode())


def scene_document(**extra) -> dict:
    """The scene of these tests (BOUNDS, START, GOAL [m]) with the keys ``extra``."""
    return {'bounds': {'min': BOUNDS[0], 'max': BOUNDS[1]}, 'resolution': 0.25,
            'safety_margin': 0.2, 'adaptive_threshold': 1.5, 'start': START, 'goal': GOAL,
            **extra}


def plan_scene(scene, algorithm: str = 'octile'):
    """The plan from the scene's start to its goal, around or through its unknown space."""
    return Planner(scene.config, scene.obstacles, unknown=scene.unknown).plan(
        scene.start, scene.goal, algorithm)


def write_scene(folder: Path, **extra) -> Path:
    write_corridor_scan(folder / 'scan.bt')
    document = scene_document(obstacles=[{'type': 'points_file', 'path': 'scan.bt'}], **extra)
    file = folder / 'scene.yaml'
    file.write_text(yaml.safe_dump(document))
    return file


def is_unknown(tree, point: np.ndarray) -> bool:
    """True where the tree has no node: its search result is a null node."""
    node = tree.search(point)
    if node is None:
        return True
    try:
        node.getOccupancy()
    except octomap.NullPointerException:
        return True
    return False


def known_leaf_volume(tree, lo, hi) -> float:
    total = 0.0
    for leaf in tree.begin_leafs():
        centre = np.array([leaf.getX(), leaf.getY(), leaf.getZ()])
        half = leaf.getSize() / 2.0
        extent = np.minimum(centre + half, hi) - np.maximum(centre - half, lo)
        total += float(np.prod(np.maximum(extent, 0.0)))
    return total


def ray_scan() -> 'octomap.OcTree':
    """A scan from one sensor position: rays to a cloud of wall and ceiling points, pruned."""
    rng = np.random.default_rng(7)
    tree = octomap.OcTree(0.1)

    def uniform(low, high, count=3000):
        return rng.uniform(low, high, count)

    walls = np.vstack([
        np.column_stack([uniform(-3, 3), np.full(3000, 2.5), uniform(0, 2.5)]),
        np.column_stack([np.full(3000, 3.2), uniform(-2, 2.5), uniform(0, 2.5)]),
        np.column_stack([uniform(-3, 3), uniform(-2, 2.5), np.full(3000, 0.0)]),
    ])
    tree.insertPointCloud(walls, np.array([0.0, 0.0, 1.2]))
    tree.updateInnerOccupancy()
    return tree


# --------------------------------------------------------------------------------------------
# The boxes are exactly the unknown space
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('which', ['corridors', 'ray scan'])
def test_boxes_are_the_complement_of_the_known_leaves(tmp_path, which):
    if which == 'corridors':
        write_corridor_scan(tmp_path / 'scan.bt')
        tree = octomap.OcTree(0.1)
        assert tree.readBinary(str(tmp_path / 'scan.bt').encode())
        lo, hi = np.array(BOUNDS[0]) - 1.0, np.array(BOUNDS[1]) + 1.0
    else:
        tree = ray_scan()
        lo, hi = np.array([-4.0, -3.0, -1.0]), np.array([4.0, 3.5, 3.0])
    unknown = octree_unknown(tree, lo, hi)
    assert 0 < len(unknown)
    assert np.all(unknown.mins >= lo) and np.all(unknown.maxs <= hi)
    points = np.random.default_rng(3).uniform(lo, hi, (20000, 3))
    truth = np.array([is_unknown(tree, point) for point in points])
    assert 0.05 < truth.mean() < 0.95
    assert np.array_equal(unknown.contains(points), truth)
    # Disjoint and complete: unknown and known volumes add up to the bounds.
    total = float(np.prod(hi - lo))
    assert unknown.volume_m3 + known_leaf_volume(tree, lo, hi) == pytest.approx(total, rel=1e-9)


def test_space_outside_the_root_cube_is_unknown():
    # At 1 mm cells the tree spans +-32.768 m: bounds reaching 40 m go beyond it.
    tree = octomap.OcTree(0.001)
    tree.updateNode(np.array([0.0005, 0.0005, 0.0005]), True)
    tree.updateInnerOccupancy()
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([40.0, 1.0, 1.0])
    unknown = octree_unknown(tree, lo, hi)
    assert unknown.contains(np.array([[35.0, 0.0, 0.0], [32.9, 0.5, 0.5]])).all()
    assert not unknown.contains(np.array([0.0005, 0.0005, 0.0005]))
    assert unknown.volume_m3 == pytest.approx(41.0 * 4.0 - 1e-9, rel=1e-9)


def test_an_empty_tree_leaves_everything_unknown():
    unknown = octree_unknown(octomap.OcTree(0.1), *BOUNDS)
    assert len(unknown) == 1 and unknown.volume_m3 == pytest.approx(12.0 * 8.0 * 4.0)


def test_merging_keeps_the_union_and_lowers_the_count():
    cells = _cells((0.0, 0.0, 0.0), (2.0, 1.0, 0.6))
    mins, maxs = cells - RESOLUTION / 2, cells + RESOLUTION / 2
    # Cells on the lattice, so shared faces are equal floats.
    mins, maxs = np.round(mins, 9), np.round(maxs, 9)
    merged_lo, merged_hi = merge_boxes(mins, maxs)
    assert len(merged_lo) == 1
    assert np.allclose(merged_lo[0], [0.0, 0.0, 0.0])
    assert np.allclose(merged_hi[0], [2.0, 1.0, 0.6])


def test_length_inside_clips_segments_and_counts_a_shared_face_once():
    space = UnknownSpace(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
                         np.array([[1.0, 1.0, 1.0], [2.0, 1.0, 1.0]]))
    line = np.array([[-1.0, 0.5, 0.5], [3.0, 0.5, 0.5]])
    assert space.length_inside(line) == pytest.approx(2.0)
    # Along the face y = 1 shared by nothing above: the face is the boxes' upper side.
    assert space.length_inside(np.array([[-1.0, 1.0, 0.5], [3.0, 1.0, 0.5]])) == 0.0
    # Along the face y = 0, the boxes' lower side: counted once per box.
    assert space.length_inside(np.array([[-1.0, 0.0, 0.5], [3.0, 0.0, 0.5]])) == \
        pytest.approx(2.0)
    diagonal = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    assert space.length_inside(diagonal) == pytest.approx(math.sqrt(3.0))


def test_known_volume_leaves_its_complement_unknown():
    unknown = known_volume_unknown([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]],
                                   [[6.0, 2.0, 4.0], [12.0, 8.0, 4.0]], *BOUNDS)
    assert unknown.volume_m3 == pytest.approx(12 * 8 * 4 - 6 * 2 * 4 - 7 * 8 * 4 + 1 * 2 * 4)
    assert unknown.contains(np.array([2.0, 5.0, 1.0]))
    assert not unknown.contains(np.array([[1.0, 1.0, 1.0], [11.0, 7.0, 1.0]])).any()
    # Two sources: unknown only where neither observed.
    other = known_volume_unknown([[0.0, 2.0, 0.0]], [[4.0, 8.0, 4.0]], *BOUNDS)
    both = combine([None, unknown, other])
    assert both is not None and both.volume_m3 == pytest.approx(0.0 + 1 * 6 * 4)


# --------------------------------------------------------------------------------------------
# The policies
# --------------------------------------------------------------------------------------------

def plan(file: Path, **overrides):
    scene = load_scene(file, overrides=overrides)
    return scene, plan_scene(scene)


def test_free_cuts_through_the_unobserved_room(tmp_path):
    scene, result = plan(write_scene(tmp_path), unknown_space='free')
    assert result.ok, result.message
    assert scene.unknown is not None and scene.unknown.source.endswith('scan.bt')
    assert result.unknown_length_m > 3.0
    assert 'through unknown space' in result.message
    assert f'{result.unknown_length_m:.3f} m in unknown space' in format_summary(result)


def test_occupied_is_the_default_and_keeps_the_margin_from_unknown_space(tmp_path):
    assert PlannerConfig().unknown_space == 'occupied'
    scene, result = plan(write_scene(tmp_path))
    assert result.ok, result.message
    assert result.unknown_length_m == 0.0
    samples = densify(result.smoothed_path, 0.01)
    assert float(np.min(scene.unknown.distance(samples))) >= scene.config.planning_margin - 1e-9
    # Around the corner of the corridors: longer than the straight line through the room.
    assert result.smoothed_length_m > 14.0
    assert result_to_dict(result)['unknown_length_m'] == 0.0


def test_a_start_in_unknown_space_is_refused_naming_it_and_the_setting(tmp_path):
    scene, result = plan(write_scene(tmp_path, start=[4.0, 5.0, 1.5]))
    assert result.status is PlanStatus.START_OCCUPIED
    assert 'in unknown space' in result.message and 'unknown_space' in result.message
    scene, result = plan(write_scene(tmp_path, goal=[4.0, 1.9, 1.5]))
    assert result.status is PlanStatus.GOAL_OCCUPIED
    assert 'from unknown space' in result.message and 'unknown_space' in result.message


@pytest.mark.parametrize('algorithm', ['octile', 'adaptive'])
def test_cost_weighs_a_detour_against_metres_in_unknown_space(tmp_path, algorithm):
    file = write_scene(tmp_path)
    lengths = {}
    for rate in (0.0, 0.05, 10.0):
        scene = load_scene(file, overrides={'unknown_space': 'cost', 'unknown_cost': rate})
        result = plan_scene(scene, algorithm)
        assert result.ok, result.message
        lengths[rate] = result.unknown_length_m
    # Free of charge it is the free plan; cheap, it still cuts the room; dear, it goes around
    # (the corner detour is about 3.3 m for about 8.6 m of unknown space).
    _, free = plan(file, unknown_space='free')
    assert lengths[0.0] == pytest.approx(free.unknown_length_m)
    assert lengths[0.05] > 3.0
    assert lengths[10.0] < 0.1


def test_search_charges_steps_between_unknown_nodes_in_both_layouts():
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [9.0, 2.0, 2.0], 1.0, 10 ** 6)
    unknown = UnknownSpace(np.array([[2.5, -1.0, -1.0]]), np.array([[6.5, 3.0, 3.0]]))
    start, goal = np.array([0, 1, 1]), np.array([9, 1, 1])
    for layout in ('dense', 'sparse'):
        blocked = blocked_mask(grid, ObstacleSet(), 0.0, layout=layout)
        nodes = blocked_mask(grid, unknown.obstacles, 0.0, layout=layout)
        workspace = SearchWorkspace(blocked)
        plain = workspace.search(start, goal, 'dijkstra', 1.0, 1.5)
        charged = workspace.search(start, goal, 'dijkstra', 1.0, 1.5, unknown=nodes,
                                   unknown_cost=2.0)
        # Nodes 3 to 6 are unknown: three whole steps and two half steps, 4 m at 2 per metre.
        assert plain.cost_m == pytest.approx(9.0)
        assert charged.cost_m == pytest.approx(9.0 + 4.0 * 2.0)
        with pytest.raises(InvalidInputError, match='unknown_cost must be'):
            workspace.search(start, goal, 'dijkstra', 1.0, 1.5, unknown=nodes, unknown_cost=-1)


def test_cost_plans_normally_without_unknown_space():
    config = validate_config(PlannerConfig(unknown_space='cost'))
    planner = Planner(config, ObstacleSet([Sphere([0.0, 0.0, 5.0], 1.0)]))
    result = planner.plan([-5.0, 0.0, 5.0], [5.0, 0.0, 5.0])
    assert result.ok and result.unknown_length_m == 0.0


def test_the_policy_can_change_on_a_planner(tmp_path):
    scene = load_scene(write_scene(tmp_path), overrides={'unknown_space': 'free'})
    planner = Planner(scene.config, scene.obstacles, unknown=scene.unknown)
    assert planner.plan(scene.start, scene.goal, 'octile').unknown_length_m > 3.0
    planner.set_config(scene.config.with_changes(unknown_space='occupied'))
    assert len(planner.obstacles) == len(scene.obstacles) + len(scene.unknown)
    assert planner.plan(scene.start, scene.goal, 'octile').unknown_length_m == 0.0
    planner.set_unknown(None)
    assert planner.obstacles is scene.obstacles


def test_known_volume_of_a_scene(tmp_path):
    document = scene_document(known_volume=[{'min': [0.0, 0.0, 0.0], 'max': [12.0, 2.0, 4.0]},
                                            {'min': [10.0, 0.0, 0.0], 'max': [12.0, 8.0, 4.0]}])
    result = plan_scene(parse_scene(document))
    assert result.ok and result.unknown_length_m == 0.0
    result = plan_scene(parse_scene({**document, 'unknown_space': 'free'}))
    assert result.ok and result.unknown_length_m > 3.0
    with pytest.raises(InvalidInputError, match=r'known_volume\[0\]: min must be below max'):
        parse_scene({**document, 'known_volume': [{'min': [1, 1, 1], 'max': [0, 2, 2]}]})
    with pytest.raises(InvalidInputError, match='unknown_space: must be one of'):
        parse_scene({**document, 'unknown_space': 'maybe'})


def test_no_path_through_unobserved_space_says_which_setting_opens_it():
    # Two observed halves with an unobserved slab between them.
    result = plan_scene(parse_scene(scene_document(
        known_volume=[{'min': [0.0, 0.0, 0.0], 'max': [5.0, 8.0, 4.0]},
                      {'min': [6.0, 0.0, 0.0], 'max': [12.0, 8.0, 4.0]}])))
    assert result.status is PlanStatus.NO_VALID_PATH
    assert '32.0 m^3 the map never observed' in result.message
    assert 'unknown_space cost or free may find a path' in result.message


def test_command_line_reports_the_length_and_takes_the_flags(tmp_path, capsys):
    file = write_scene(tmp_path)
    assert main(['plan', str(file), '--algorithm', 'octile', '--json',
                 '--unknown-space', 'free']) == 0
    free = json.loads(capsys.readouterr().out)
    assert free['unknown_length_m'] > 3.0
    assert main(['plan', str(file), '--algorithm', 'octile', '--json']) == 0
    assert json.loads(capsys.readouterr().out)['unknown_length_m'] == 0.0
    assert main(['plan', str(file), '--unknown-space', 'maybe']) == 2
    assert 'unknown_space must be one of' in capsys.readouterr().err


def test_a_map_given_on_the_command_line_brings_its_unknown_space(tmp_path, capsys):
    write_corridor_scan(tmp_path / 'scan.bt')
    file = tmp_path / 'plain.yaml'
    file.write_text(yaml.safe_dump(scene_document()))
    assert main(['plan', str(file), '--json', '--map', str(tmp_path / 'scan.bt'),
                 '--unknown-space', 'free']) == 0
    assert json.loads(capsys.readouterr().out)['unknown_length_m'] > 3.0
    assert octomap_unknown(tmp_path / 'scan.bt', *BOUNDS).volume_m3 > 100.0


def test_node_diagnostics_carry_the_length(tmp_path):
    pytest.importorskip('diagnostic_msgs')
    from uav_global_planner.ros.conversions import plan_diagnostic_values
    _, result = plan(write_scene(tmp_path), unknown_space='free')
    values = plan_diagnostic_values(result, 'parameter')
    assert values['unknown_length_m'] == result.unknown_length_m > 3.0


@pytest.mark.ros
def test_the_node_keeps_out_of_the_unknown_space_of_an_octomap_map_file(tmp_path):
    pytest.importorskip('rclpy')
    from diagnostic_msgs.msg import DiagnosticArray
    from ros_harness import (PlannerClient, RosClient, RUN_NAMESPACE, start_planner,
                             unique_domain_id)
    from uav_global_planner.ros import conversions as conv
    write_corridor_scan(tmp_path / 'scan.bt')
    domain_id = unique_domain_id()
    namespace = f'{RUN_NAMESPACE}/unknown'
    client = RosClient(domain_id)
    process = start_planner(domain_id, namespace=namespace, parameters={
        'map_file': str(tmp_path / 'scan.bt'), 'bounds.min': BOUNDS[0],
        'bounds.max': BOUNDS[1], 'resolution': 0.25, 'safety_margin': 0.2, 'start': START})
    try:
        planner = PlannerClient(client, namespace, client.record(DiagnosticArray,
                                                                 '/diagnostics'), process)
        values, path = planner.plan_to(GOAL)
        assert values['status'] == 'ok', values
        assert float(values['unknown_length_m']) == 0.0, values
        unknown = octomap_unknown(tmp_path / 'scan.bt', *BOUNDS)
        points = densify(conv.path_to_points(path), 0.01)
        assert float(np.min(unknown.distance(points))) >= 0.2 - 1e-6
        (result,) = planner.params.set({'unknown_space': 'free'})
        assert result.successful, result.reason
        values, path = planner.plan_to(GOAL)
        assert values['status'] == 'ok', values
        assert float(values['unknown_length_m']) > 3.0, values
        # A larger workspace: the space added beyond the old bounds is unknown too.
        results = planner.params.set({'unknown_space': 'occupied',
                                      'bounds.max': [14.0, 8.0, 4.0]})
        assert all(result.successful for result in results), results
        values, path = planner.plan_to([13.0, 1.0, 1.5])
        assert values['status'] == 'goal_occupied', values
        assert 'unknown space' in values['message'], values
    finally:
        client.close()
        process.kill()
