"""``uav-plan export``, run as a real process."""

import json
import shutil
import subprocess

import numpy as np
import pymap3d
from pymavlink import mavwp
import pytest

from uav_global_planner.core.io.scene import find_scene, load_scene

ORIGIN = (47.397742, 8.545594, 488.0)
ORIGIN_TEXT = ','.join(str(v) for v in ORIGIN)


def uav_plan(*args, cwd=None):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    return subprocess.run([executable, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def to_map(lat, lon, alt):
    e, n, u = pymap3d.geodetic2enu(lat, lon, alt, *ORIGIN)
    return np.array([e, n, u], dtype=float).T


def test_export_qgc_writes_a_plan_file_and_says_what_holds(tmp_path):
    target = tmp_path / 'medium.plan'
    run = uav_plan('export', 'paper_medium', '--format', 'qgc', '-o', str(target), '--origin',
                   ORIGIN_TEXT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert f'mission written to {target}' in run.stdout
    assert 'keeps >= 0.300 m (gamma 0.2 m + tracking allowance 0.1 m)' in run.stdout
    document = json.loads(target.read_text())
    assert document['fileType'] == 'Plan'
    assert document['mission']['firmwareType'] == 12
    items = document['mission']['items']
    assert items[0]['command'] == 22 and items[-1]['command'] == 17
    home = to_map(*document['mission']['plannedHomePosition'])
    assert np.allclose(home, [0.0, -5.0, 0.0], atol=0.01)


def test_export_wpl_json_summary_and_pymavlink_reads_it(tmp_path):
    target = tmp_path / 'high.waypoints'
    run = uav_plan('export', 'paper_high', '--format', 'wpl', '-o', str(target), '--origin',
                   ORIGIN_TEXT, '--end', 'land', '--json')
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads(run.stdout)
    assert summary['status'] == 'ok' and summary['format'] == 'wpl'
    assert summary['firmware'] == 'ardupilot'       # the default for Mission Planner files
    assert summary['certified_clearance_m'] >= summary['required_clearance_m'] == 0.3
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(target)) == summary['items'] + 1
    assert [loader.wp(n).command for n in range(1, loader.count())] == summary['commands']
    scene = load_scene(find_scene('paper_high'))
    path = np.array(summary['flight_path'])
    assert scene.obstacles.distance(path).min() >= 0.3


def test_export_from_a_saved_plan_json(tmp_path):
    saved = tmp_path / 'plan.json'
    run = uav_plan('plan', 'paper_high', '--algorithm', 'octile', '--json')
    assert run.returncode == 0, run.stderr
    saved.write_text(run.stdout)
    target = tmp_path / 'from_saved.plan'
    run = uav_plan('export', 'paper_high', '--from-plan', str(saved), '-o', str(target),
                   '--origin', ORIGIN_TEXT, '--json')
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads(run.stdout)
    assert summary['route'] == f'route of {saved}'
    smoothed = np.array(json.loads(saved.read_text())['smoothed_path'])
    flown = np.array(summary['flight_path'])
    # The mission follows the saved route: it ends at its goal and stays near it.
    assert np.linalg.norm(flown[-1] - smoothed[-1]) < 0.01
    gaps = np.linalg.norm(flown[:, None, :] - smoothed[None], axis=2).min(axis=1)
    assert gaps.max() < 3.0


def test_export_takes_the_origin_from_the_scene(tmp_path, scenes_dir):
    scene = tmp_path / 'located.yaml'
    scene.write_text((scenes_dir / 'paper_medium.yaml').read_text()
                     + 'geodetic_origin: {lat: 47.397742, lon: 8.545594, alt_amsl: 488.0}\n')
    target = tmp_path / 'located.plan'
    run = uav_plan('export', str(scene), '-o', str(target))
    assert run.returncode == 0, run.stdout + run.stderr
    assert json.loads(target.read_text())['mission']['plannedHomePosition'][2] == 488.0


@pytest.mark.parametrize('args, code, text', [
    (['paper_medium', '-o', 'x.plan'], 2, 'no geodetic origin'),
    (['paper_medium', '-o', 'x.kml', '--origin', ORIGIN_TEXT], 2, 'cannot tell the mission'),
    (['paper_medium', '-o', 'x.plan', '--origin', '47.4,8.5'], 2, 'LAT,LON,ALT_AMSL'),
    (['paper_medium', '-o', 'x.plan', '--origin', ORIGIN_TEXT, '--end', 'rtl'], 1,
     'no certified mission'),
    (['paper_medium', '-o', 'x.plan', '--origin', ORIGIN_TEXT, '--acceptance-radius', '0'], 2,
     'acceptance_radius must be in'),
    (['paper_medium', '-o', 'x.plan', '--origin', ORIGIN_TEXT, '--from-plan', 'missing.json'],
     2, 'cannot read plan file'),
])
def test_export_refusals(tmp_path, args, code, text):
    run = uav_plan('export', *args, cwd=tmp_path)
    assert run.returncode == code, run.stdout + run.stderr
    assert text in run.stdout + run.stderr
    assert 'Traceback' not in run.stderr
    assert not (tmp_path / 'x.plan').exists()


def test_export_of_a_failed_saved_plan_is_refused(tmp_path):
    saved = tmp_path / 'failed.json'
    saved.write_text(json.dumps({'status': 'no_valid_path', 'message': 'sealed',
                                 'smoothed_path': []}))
    run = uav_plan('export', 'paper_medium', '--from-plan', str(saved), '-o', 'x.plan',
                   '--origin', ORIGIN_TEXT, cwd=tmp_path)
    assert run.returncode == 2
    assert 'the saved plan failed (no_valid_path: sealed)' in run.stderr


def test_export_writes_the_scene_geofence(tmp_path):
    target = tmp_path / 'airspace.plan'
    run = uav_plan('export', 'airspace_demo', '-o', str(target), '--origin', ORIGIN_TEXT,
                   '--json')
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads(run.stdout)
    scene = load_scene(find_scene('airspace_demo'))
    airspace = scene.airspace
    fence = json.loads(target.read_text())['geoFence']
    assert fence['version'] == 2
    written = len(fence['polygons']) + len(fence['circles'])
    assert written + len(summary['fence_skipped']) == len(airspace.inclusions) + len(
        airspace.exclusions)
    inclusion = [p for p in fence['polygons'] if p['inclusion']]
    assert len(inclusion) == len(airspace.inclusions) == 1
    corners = to_map(*np.array(inclusion[0]['polygon']).T, np.full(len(
        inclusion[0]['polygon']), ORIGIN[2]))[:, :2]
    expected = airspace.inclusions[0].polygon
    gaps = np.linalg.norm(corners[:, None] - expected[None], axis=2)
    assert gaps.min(axis=0).max() < 0.02
    # The flown path keeps gamma + allowance from fence walls and zones (they are obstacles).
    path = np.array(summary['flight_path'])
    samples = np.concatenate([a + np.linspace(0, 1, 400)[:, None] * (b - a)
                              for a, b in zip(path[:-1], path[1:])])
    assert scene.obstacles.distance(samples).min() >= summary['required_clearance_m']
