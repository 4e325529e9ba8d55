"""A fleet on Ray: the same reservations as the serial runner for 1 and 2 workers, version-checked
commits, the map read zero-copy, and ``uav-plan fleet`` end to end.

Ray runs on this machine (an embedded local cluster with 2 CPUs, its files in a temporary
folder, token authentication with a token in the environment only).
"""

import itertools
import json
import math
import os
import secrets
import shutil
import subprocess
import tempfile

import numpy as np
import pytest
import yaml

ray = pytest.importorskip('ray')

from uav_global_planner.core.fleet import (FleetSettings, Mission, run_fleet)  # noqa: E402
from uav_global_planner.core.io.scene import load_scene, with_ground  # noqa: E402
from uav_global_planner.core.planner import Planner  # noqa: E402
from uav_global_planner.fleet_ray import (make_airspace, plan_fleet_ray, ray_session,  # noqa: E402
                                          ShardLayout)

#: A small town: 240 x 240 x 50 m at 1 m, four buildings, the ground a floor.
SCENE = {
    'description': 'four buildings for fleet tests', 'frame_id': 'map',
    'bounds': {'min': [-120.0, -120.0, 0.0], 'max': [120.0, 120.0, 50.0]},
    'resolution': 1.0, 'safety_margin': 1.0, 'adaptive_threshold': 1.5, 'ground': 'floor',
    'start': [-100.0, -100.0, 5.0], 'goal': [100.0, 100.0, 5.0],
    'obstacles': [{'type': 'box', 'min': [-60.0, -60.0, 0.0], 'max': [-30.0, -30.0, 30.0]},
                  {'type': 'box', 'min': [30.0, -60.0, 0.0], 'max': [60.0, -30.0, 20.0]},
                  {'type': 'box', 'min': [-60.0, 30.0, 0.0], 'max': [-30.0, 60.0, 25.0]},
                  {'type': 'box', 'min': [30.0, 30.0, 0.0], 'max': [60.0, 60.0, 35.0]}]}

SETTINGS = {'horizontal_separation': 20.0, 'vertical_separation': 8.0, 'max_delay_s': 30.0,
            'delay_step_s': 10.0, 'altitude_layers': [15.0], 'speed_factors': [0.7]}


def _mission(name, vehicle, departure, start, goal, priority=0):
    return {'name': name, 'vehicle': vehicle, 'departure_s': departure, 'start': start,
            'goal': goal, 'priority': priority}


#: Crossings (delays), a head-on pair (an altitude layer), a vehicle asked to fly twice at once
#: (rejected), a goal inside a building (no plan), and followers on one street.
MISSIONS = [
    _mission('a-east', 'v1', 0.0, [-100.0, 0.0, 5.0], [100.0, 0.0, 5.0]),
    _mission('b-north', 'v2', 0.0, [0.0, -100.0, 5.0], [0.0, 100.0, 5.0]),
    _mission('c-west', 'v3', 5.0, [100.0, 10.0, 5.0], [-100.0, 10.0, 5.0]),
    _mission('d-head-on-1', 'v4', 10.0, [-100.0, 90.0, 5.0], [100.0, 90.0, 5.0]),
    _mission('e-head-on-2', 'v5', 10.0, [100.0, 90.0, 5.0], [-100.0, 90.0, 5.0]),
    _mission('f-twice', 'v1', 20.0, [-100.0, -90.0, 5.0], [100.0, -90.0, 5.0]),
    _mission('g-into-building', 'v6', 0.0, [-100.0, -100.0, 5.0], [45.0, 45.0, 10.0]),
    _mission('h-follow', 'v7', 0.0, [-90.0, -10.0, 5.0], [90.0, -10.0, 5.0]),
    _mission('i-follow', 'v8', 3.0, [-90.0, -20.0, 5.0], [90.0, -20.0, 5.0]),
    _mission('j-urgent', 'v9', 30.0, [0.0, 100.0, 5.0], [0.0, -100.0, 5.0], priority=1),
]


@pytest.fixture(scope='module')
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp('fleet') / 'town.yaml'
    path.write_text(yaml.safe_dump(SCENE), encoding='utf-8')
    loaded = load_scene(path)
    return with_ground(loaded, loaded.terrain)


@pytest.fixture(scope='module')
def missions():
    return [Mission(m['name'], m['vehicle'], m['departure_s'], np.array(m['start']),
                    np.array(m['goal']), priority=m['priority']) for m in MISSIONS]


@pytest.fixture(scope='module')
def settings():
    return FleetSettings(**{k: tuple(v) if isinstance(v, list) else v
                            for k, v in SETTINGS.items()})


@pytest.fixture(scope='module')
def local_ray():
    """Ray on this machine for the module: 2 CPUs, files under a short temporary folder."""
    folder = tempfile.mkdtemp(prefix='ray', dir='/tmp')
    try:
        with ray_session(num_cpus=2, temp_dir=folder) as info:
            yield info
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope='module')
def serial(scene, missions, settings):
    planner = Planner(scene.config, scene.obstacles, unknown=scene.unknown)
    return run_fleet(planner, missions, settings)


def _same(a, b):
    """Two outcomes are the same: decision, reason, steps, conflicts, and the flight itself."""
    assert (a.name, a.vehicle, a.accepted, a.reason) == (b.name, b.vehicle, b.accepted, b.reason)
    assert (math.isnan(a.departure_s) and math.isnan(b.departure_s)
            or a.departure_s == b.departure_s), a.name
    assert (a.layer_m, a.speed_factor) == (b.layer_m, b.speed_factor), a.name
    assert [s.to_dict() for s in a.steps] == [s.to_dict() for s in b.steps], a.name
    assert [c.to_dict() for c in a.conflicts] == [c.to_dict() for c in b.conflicts], a.name
    assert (a.flight is None) == (b.flight is None), a.name
    if a.flight is not None:
        times_a, points_a = a.flight.sample(0.5)
        times_b, points_b = b.flight.sample(0.5)
        assert np.array_equal(times_a, times_b) and np.array_equal(points_a, points_b), a.name


def _pairwise_violations(flights, horizontal, vertical, step_s=0.01):
    """Instants, every ``step_s`` seconds, at which two flights are within both separations:
    an independent check of the positions, not of the certificate."""
    found = []
    for a, b in itertools.combinations(flights, 2):
        start, end = max(a.start_s, b.start_s), min(a.end_s, b.end_s)
        if start > end:
            continue
        times = np.arange(start, end + step_s, step_s)
        times = times[times <= end]
        gap = a.positions(times) - b.positions(times)
        close = (np.hypot(gap[:, 0], gap[:, 1]) < horizontal) & (np.abs(gap[:, 2]) < vertical)
        if close.any():
            found.append((a.mission, b.mission, float(times[np.argmax(close)])))
    return found


def test_the_batch_exercises_every_resolution(serial):
    reasons = {o.name: o.reason for o in serial.outcomes}
    assert reasons['a-east'] == 'accepted as planned'
    assert any(o.reason.startswith('delayed') for o in serial.accepted), reasons
    assert any(o.layer_m for o in serial.accepted), reasons
    assert serial.outcomes[0].name == 'j-urgent'  # priority first, then departure
    rejected = {o.name: o.reason for o in serial.rejected}
    assert 'g-into-building' in rejected and 'no plan' in rejected['g-into-building']
    assert 'f-twice' in rejected and 'vehicle' in rejected['f-twice']


def test_ray_gives_the_serial_reservations_for_1_and_2_workers(
        local_ray, scene, missions, settings, serial):
    """Decisions, reasons, steps, conflicts and flights bit for bit as the serial runner's,
    the map read from the object store without a copy, and no two flights ever within both
    separations (checked every 10 ms, independently of the certificate)."""
    layout = ShardLayout(xy_min=(-120.0, -120.0), xy_max=(120.0, 120.0), tiles=2,
                         window_s=60.0, shards=2)
    for workers in (1, 2):
        run = plan_fleet_ray(scene, missions, settings, workers=workers, layout=layout)
        assert [o.name for o in run.result.outcomes] == [o.name for o in serial.outcomes]
        for ours, reference in zip(run.result.outcomes, serial.outcomes):
            _same(ours, reference)
        assert [f.mission for f in run.result.book.flights] == [
            f.mission for f in serial.book.flights]
        stats = run.stats
        assert stats.zero_copy, 'the planners copied the map instead of reading it in place'
        assert stats.base_plans == len(missions)
        assert stats.resolutions == len(missions) + stats.stale
        assert _pairwise_violations(run.result.book.flights, settings.horizontal_separation,
                                    settings.vertical_separation) == []


def _boxes(x0, x1, t0=0.0, t1=60.0):
    return np.array([[t0, t1, x0, -5.0, 0.0, x1, 5.0, 10.0]])


def test_two_workers_never_take_the_same_volume(local_ray):
    """Racing commits made against the same version: of two into one volume exactly one is
    filed, and the loser is told which flight beat it; disjoint volumes both go in."""
    layout = ShardLayout(xy_min=(-100.0, -100.0), xy_max=(100.0, 100.0), tiles=2,
                         window_s=30.0, shards=2)
    airspace = make_airspace(layout)

    @ray.remote
    def commit(client, seq, boxes):
        # The footprint of a resolution is its candidates' boxes inflated by the envelope.
        footprint = boxes + np.array([0, 0, -20, -20, -8, 20, 20, 8])
        return client.commit(seq, footprint, 0, boxes, f'flight {seq}')

    # Both overlap x in [-10, 10], across the tile border at x = 0.
    outcomes = ray.get([commit.remote(airspace, 0, _boxes(-30.0, 5.0)),
                        commit.remote(airspace, 0, _boxes(-5.0, 30.0))])
    assert sorted(o.committed for o in outcomes) == [False, True]
    loser = next(o for o in outcomes if not o.committed)
    assert loser.stale == (0,)
    assert [seq for seq, _ in airspace.flights_since(0)] == [0]
    # Far apart in space (and so in every shard they touch), both are filed.
    outcomes = ray.get([commit.remote(airspace, 1, _boxes(-90.0, -70.0, 100.0, 120.0)),
                        commit.remote(airspace, 1, _boxes(70.0, 90.0, 100.0, 120.0))])
    assert [o.committed for o in outcomes] == [True, True]
    # A commit against version 0 that meets the first flight is refused even much later.
    late = airspace.commit(3, _boxes(0.0, 1.0) + np.array([0, 0, -20, -20, -8, 20, 20, 8]), 0,
                           _boxes(0.0, 1.0), 'late')
    assert not late.committed and late.stale == (0,)
    for shard in airspace.shards:
        ray.kill(shard)


def _uav_plan(*args, cwd):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    env = dict(os.environ, RAY_AUTH_MODE='token', RAY_AUTH_TOKEN=secrets.token_hex(32),
               RAY_TMPDIR=tempfile.mkdtemp(prefix='ray', dir='/tmp'))
    try:
        return subprocess.run([executable, *args], capture_output=True, text=True, cwd=cwd,
                              timeout=300, env=env)
    finally:
        shutil.rmtree(env['RAY_TMPDIR'], ignore_errors=True)


def test_uav_plan_fleet_end_to_end(tmp_path):
    (tmp_path / 'town.yaml').write_text(yaml.safe_dump(SCENE), encoding='utf-8')
    batch = {'scene': 'town.yaml', 'now_s': 1.0, 'settings': SETTINGS,
             'missions': [
                 _mission('first', 'v1', 2.0, [-100.0, 0.0, 5.0], [100.0, 0.0, 5.0]),
                 _mission('twice', 'v1', 20.0, [-100.0, -90.0, 5.0], [100.0, -90.0, 5.0]),
                 _mission('cross', 'v2', 2.0, [0.0, -100.0, 5.0], [0.0, 100.0, 5.0]),
                 _mission('head-on-1', 'v4', 10.0, [-100.0, 90.0, 5.0], [100.0, 90.0, 5.0]),
                 _mission('head-on-2', 'v5', 10.0, [100.0, 90.0, 5.0], [-100.0, 90.0, 5.0]),
                 _mission('outside', 'v20', 5.0, [-100.0, 0.0, 5.0], [400.0, 0.0, 5.0]),
                 _mission('past', 'v21', 0.0, [-100.0, 50.0, 5.0], [100.0, 50.0, 5.0])]}
    (tmp_path / 'batch.yaml').write_text(yaml.safe_dump(batch), encoding='utf-8')
    done = _uav_plan('fleet', 'batch.yaml', '--workers', '2', '--out', 'out', '--quiet',
                     '--origin', '47.3977,8.5456,488.0', cwd=tmp_path)
    assert done.returncode == 1, done.stderr  # a rejected and two refused missions
    report = json.loads((tmp_path / 'out' / 'report.json').read_text())
    refused = {e['mission']: e['setting'] for e in report['errors']}
    assert set(refused) == {'outside', 'past'}, report['errors']
    entries = {m['name']: m for m in report['missions']}
    assert set(entries) == {'first', 'twice', 'cross', 'head-on-1', 'head-on-2'}
    assert not entries['twice']['accepted'] and 'vehicle' in entries['twice']['reason']
    assert entries['head-on-2']['layer_m'] == 15.0, entries['head-on-2']['reason']
    accepted = [m for m in report['missions'] if m['accepted']]
    assert len(accepted) == 4
    for entry in accepted:
        assert entry['plan_file'] and (tmp_path / 'out' / entry['plan_file']).is_file()
        plan = json.loads((tmp_path / 'out' / entry['plan_file']).read_text())
        assert plan['fileType'] == 'Plan' and plan['mission']['items']
        times, positions = np.array(entry['times']), np.array(entry['positions'])
        assert len(times) == len(positions) > 10 and times[0] == entry['departure_s']
    # Anyone can check the separation from the report alone.
    for a, b in itertools.combinations(accepted, 2):
        common = np.intersect1d(np.round(a['times'], 6), np.round(b['times'], 6))
        pa = np.array(a['positions'])[np.isin(np.round(a['times'], 6), common)]
        pb = np.array(b['positions'])[np.isin(np.round(b['times'], 6), common)]
        gap = pa - pb
        assert not np.any((np.hypot(gap[:, 0], gap[:, 1]) < 20.0) & (np.abs(gap[:, 2]) < 8.0))
    html = (tmp_path / 'out' / 'fleet.html').read_text()
    assert '"sliders"' in html and 'Plotly.addFrames' in html
    assert 'accepted' in done.stdout and 'refused outside' in done.stdout


def test_uav_plan_fleet_refuses_bad_options(tmp_path):
    (tmp_path / 'batch.yaml').write_text(yaml.safe_dump({'missions': []}), encoding='utf-8')
    done = _uav_plan('fleet', 'batch.yaml', '--workers', '0', cwd=tmp_path)
    assert done.returncode == 2 and '--workers' in done.stderr
    done = _uav_plan('fleet', 'batch.yaml', cwd=tmp_path)
    assert done.returncode == 2 and 'no scene' in done.stderr
    # A cluster address nobody answers on is refused at once, not retried for minutes.
    (tmp_path / 'town.yaml').write_text(yaml.safe_dump(SCENE), encoding='utf-8')
    done = _uav_plan('fleet', 'batch.yaml', '--scene', 'town.yaml', '--address', '127.0.0.1:1',
                     cwd=tmp_path)
    assert done.returncode == 2 and '--address 127.0.0.1:1' in done.stderr, done.stderr
    assert not (tmp_path / 'batch_fleet').exists()
