"""Fleet deconfliction core: certified separation, the index, resolution, bad input.

Plans come from the real planner on a small walled map (a building in the middle): eight
routes across it, and the same routes raised into the altitude layers. The separation of
accepted flights is checked independently, pairwise, at every 10 ms of the batch clock.
"""

import json
import math
import pickle
import subprocess
import sys
from typing import Dict, List, Tuple

from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.fleet import (common_window, distance_bounds, Envelope,
                                           first_conflict, fleet_order, FleetSettings, Flight,
                                           load_missions, Mission, plan_mission,
                                           ReservationBook, resolve, run_fleet, StaleBookError)
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.core.planner import Planner

FUZZ = settings(derandomize=True, database=None, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])

STEP_S = 0.01
LAYERS = (8.0, 16.0)
ROUTES = 8
CONFIG = PlannerConfig(bounds_min=(-60.0, -60.0, 0.0), bounds_max=(60.0, 60.0, 30.0),
                       resolution=2.0, safety_margin=1.0, max_speed_horizontal=8.0,
                       max_speed_vertical=3.0, max_accel_horizontal=3.0,
                       max_accel_vertical=2.0)


def _route(index: int) -> Tuple[np.ndarray, np.ndarray]:
    angle = 2.0 * math.pi * index / ROUTES
    start = np.array([50.0 * math.cos(angle), 50.0 * math.sin(angle), 4.0])
    goal = np.array([-50.0 * math.cos(angle + 0.3), -50.0 * math.sin(angle + 0.3), 4.0])
    return start, goal


def _mission(name: str, route: int, departure: float, priority: int = 0,
             vehicle: str = '') -> Mission:
    start, goal = _route(route)
    return Mission(name=name, vehicle=vehicle or f'v-{name}', departure_s=departure,
                   start=start, goal=goal, priority=priority)


class Plans:
    """Plans of the routes (by route, layer), made once."""

    def __init__(self) -> None:
        obstacles = ObstacleSet([Box((-8.0, -8.0, 0.0), (8.0, 8.0, 12.0))])
        self.planner = Planner(CONFIG, obstacles)
        self.cache: Dict[Tuple[int, float], object] = {}

    def route_of(self, mission: Mission) -> int:
        return next(r for r in range(ROUTES) if np.allclose(_route(r)[0], mission.start))

    def plan(self, mission: Mission, layer_m: float = 0.0):
        key = (self.route_of(mission), float(layer_m))
        if key not in self.cache:
            self.cache[key] = plan_mission(self.planner, mission, layer_m)
        return self.cache[key]

    def base(self, missions: List[Mission]) -> Dict[str, object]:
        return {m.name: self.plan(m) for m in missions}


@pytest.fixture(scope='module')
def plans() -> Plans:
    made = Plans()
    for route in range(ROUTES):
        mission = _mission('probe', route, 0.0)
        for layer in (0.0, *LAYERS):
            assert made.plan(mission, layer).ok
    return made


_DENSE: Dict[Tuple[int, float], np.ndarray] = {}


def _dense(flight: Flight) -> np.ndarray:
    """Positions every 10 ms of the batch clock from the departure (a multiple of 10 ms)."""
    key = (id(flight.reference), flight.time_scale)
    if key not in _DENSE:
        count = int(math.floor(flight.duration_s / STEP_S + 1e-9)) + 1
        _DENSE[key] = flight.positions(flight.start_s + np.arange(count) * STEP_S)
    return _DENSE[key]


def _dense_violation(a: Flight, b: Flight, envelope: Envelope) -> bool:
    """An independent check at every 10 ms both fly: any instant inside the envelope?"""
    first = int(round(max(a.start_s, b.start_s) / STEP_S))
    last = int(round(min(a.end_s, b.end_s) / STEP_S))
    if last < first:
        return False
    ia = int(round(a.start_s / STEP_S))
    ib = int(round(b.start_s / STEP_S))
    pa, pb = _dense(a), _dense(b)
    last = min(last, ia + len(pa) - 1, ib + len(pb) - 1)
    if last < first:
        return False
    gap = pa[first - ia:last - ia + 1] - pb[first - ib:last - ib + 1]
    inside = ((np.hypot(gap[:, 0], gap[:, 1]) < envelope.horizontal_m)
              & (np.abs(gap[:, 2]) < envelope.vertical_m))
    return bool(inside.any())


def _flight(plans: Plans, route: int, departure: float, scale: float = 1.0,
            layer: float = 0.0, name: str = '') -> Flight:
    mission = _mission(name or f'r{route}', route, departure)
    plan = plans.plan(mission, layer)
    return Flight(mission.name, mission.vehicle, plan.trajectory.reference, departure,
                  scale, layer)


# --- certified separation -----------------------------------------------------------------

@settings(FUZZ, max_examples=60)
@given(ra=st.integers(0, ROUTES - 1), rb=st.integers(0, ROUTES - 1),
       da=st.integers(0, 4000), db=st.integers(0, 4000),
       scale=st.sampled_from([1.0, 0.8, 0.6]), layer=st.sampled_from([0.0, *LAYERS]),
       horizontal=st.floats(2.0, 30.0), vertical=st.floats(1.0, 10.0))
def test_certified_check_agrees_with_dense_check(plans, ra, rb, da, db, scale, layer,
                                                 horizontal, vertical):
    a = _flight(plans, ra, da * STEP_S, name='a')
    b = _flight(plans, rb, db * STEP_S, scale, layer, name='b')
    envelope = Envelope(horizontal, vertical)
    conflict = first_conflict(a, b, envelope)
    if _dense_violation(a, b, envelope):
        assert conflict is not None
    if conflict is not None and conflict.proven:
        assert conflict.horizontal_m < horizontal and conflict.vertical_m < vertical
        assert max(a.start_s, b.start_s) <= conflict.time_s <= min(a.end_s, b.end_s)


@settings(FUZZ, max_examples=40)
@given(ra=st.integers(0, ROUTES - 1), rb=st.integers(0, ROUTES - 1),
       db=st.integers(0, 3000), scale=st.sampled_from([1.0, 0.7]),
       width=st.sampled_from([0.05, 0.4, 3.0, 20.0]), exact=st.booleans())
def test_distance_bounds_hold_at_every_sample(plans, ra, rb, db, scale, width, exact):
    a = _flight(plans, ra, 0.0)
    b = _flight(plans, rb, db * STEP_S, scale)
    lo, hi = max(a.start_s, b.start_s), min(a.end_s, b.end_s)
    if hi - lo < width:
        return
    edges = np.arange(lo, hi - width, width)
    h_low, v_low = distance_bounds(a, b, edges, edges + width, exact=exact)
    for t0, h, v in zip(edges[::7], h_low[::7], v_low[::7]):
        times = np.linspace(t0, t0 + width, 41)
        gap = a.positions(times) - b.positions(times)
        assert np.all(np.hypot(gap[:, 0], gap[:, 1]) >= h - 1e-9)
        assert np.all(np.abs(gap[:, 2]) >= v - 1e-9)


def test_curves_are_parameterised_by_arc_length(plans):
    # The bound rests on |c(s) - c(m)| <= |s - m| and on s(t) never decreasing.
    for route in range(ROUTES):
        for layer in (0.0, LAYERS[1]):
            reference = plans.plan(_mission('a', route, 0.0), layer).trajectory.reference
            curve = reference.curve
            s = np.sort(np.r_[np.linspace(0.0, curve.length_m, 4001),
                              np.random.default_rng(route).uniform(0.0, curve.length_m, 500)])
            points = curve.evaluate(s)
            for lag in (1, 7, 50):
                chord = np.linalg.norm(points[lag:] - points[:-lag], axis=1)
                assert np.all(chord <= s[lag:] - s[:-lag] + 1e-9)
            # Long straight stretches: the chord equals the arc (no slack hidden in the
            # parameterisation).
            assert np.max(chord / (s[lag:] - s[:-lag])) > 0.999
            arc = reference.arc.evaluate(np.linspace(0.0, reference.duration_s, 20001))[0]
            assert np.all(np.diff(arc) >= -1e-9)


def test_a_close_pass_is_proven_apart_or_called_a_conflict(plans):
    # One route flown twice, 3 s apart: the closest horizontal approach is about 12.13 m.
    a = _flight(plans, 2, 0.0, name='a')
    b = Flight('b', 'vb', a.reference, 3.0)
    times = np.arange(b.start_s, a.end_s, 0.0005)
    gap = a.positions(times) - b.positions(times)
    closest = float(np.hypot(gap[:, 0], gap[:, 1]).min())
    assert 12.05 < closest < 12.2
    assert first_conflict(a, b, Envelope(closest - 0.05, 5.0)) is None
    # Closer to the envelope than the tolerance can prove: a conflict, never apart.
    unproven = first_conflict(a, b, Envelope(closest - 0.001, 5.0))
    assert unproven is not None
    assert not unproven.proven or unproven.horizontal_m < closest - 0.001
    proven = first_conflict(a, b, Envelope(closest + 0.05, 5.0))
    assert proven is not None and proven.proven and proven.horizontal_m < closest + 0.05


def test_same_vehicle_cannot_fly_two_missions_at_once(plans):
    a = _flight(plans, 0, 0.0, name='a')
    b = Flight('b', a.vehicle, a.reference, a.end_s - 1.0)
    far = Envelope(1e-3, 1e-3)
    assert first_conflict(a, b, far).kind == 'vehicle'
    assert first_conflict(a, b.delayed(1.5), far) is None


# --- index and book -----------------------------------------------------------------------

@settings(FUZZ, max_examples=25)
@given(entries=st.lists(st.tuples(st.integers(0, ROUTES - 1), st.integers(0, 60),
                                  st.sampled_from([0.0, *LAYERS])), min_size=2, max_size=8),
       probe=st.tuples(st.integers(0, ROUTES - 1), st.integers(0, 60)))
def test_index_never_hides_a_conflict(plans, entries, probe):
    fleet = FleetSettings(horizontal_separation=10.0, vertical_separation=4.0,
                          index_cell_m=20.0, index_cell_z_m=10.0, index_cell_s=8.0)
    book = ReservationBook(fleet)
    for i, (route, departure, layer) in enumerate(entries):
        book.add(_flight(plans, route, float(departure), layer=layer, name=f'f{i}'))
    candidate = _flight(plans, probe[0], float(probe[1]), name='probe')
    near = set(book.candidates(candidate))
    for key, flight in enumerate(book.flights):
        if first_conflict(candidate, flight, fleet.envelope) is not None:
            assert key in near
    found = {c.second for c in book.conflicts_with(candidate)}
    brute = {f.mission for f in book.flights
             if first_conflict(candidate, f, fleet.envelope) is not None}
    assert found == brute


def test_book_versions_refuse_a_stale_add(plans):
    book = ReservationBook(FleetSettings())
    assert book.add(_flight(plans, 0, 0.0, name='a'), expected_version=0) == 1
    with pytest.raises(StaleBookError) as stale:
        book.add(_flight(plans, 1, 0.0, name='b'), expected_version=0)
    copied = pickle.loads(pickle.dumps(stale.value))
    assert (copied.expected, copied.actual, str(copied)) == (0, 1, str(stale.value))
    assert book.version == 1
    assert book.add(_flight(plans, 1, 0.0, name='b'), expected_version=1) == 2
    assert [f.mission for f in book.since(1)] == ['b']
    assert [f.mission for f in book.copy().flights] == ['a', 'b']


# --- resolution ---------------------------------------------------------------------------

@st.composite
def _batches(draw):
    count = draw(st.integers(2, 7))
    # Some vehicles fly several missions.
    missions = [_mission(f'm{i}', draw(st.integers(0, ROUTES - 1)),
                         draw(st.integers(0, 60)) * 0.5, draw(st.integers(0, 2)),
                         draw(st.sampled_from(['', '', 'va', 'vb'])))
                for i in range(count)]
    fleet = FleetSettings(
        horizontal_separation=draw(st.sampled_from([4.0, 10.0, 20.0])),
        vertical_separation=draw(st.sampled_from([2.0, 5.0])),
        max_delay_s=draw(st.sampled_from([0.0, 10.0, 30.0])), delay_step_s=5.0,
        altitude_layers=draw(st.sampled_from([(), LAYERS[:1], LAYERS])),
        speed_factors=draw(st.sampled_from([(), (0.7,), (0.8, 0.5)])))
    return missions, fleet


def _run(plans: Plans, missions: List[Mission], fleet: FleetSettings):
    return run_fleet(plans.planner, missions, fleet, base_plans=plans.base(missions),
                     plan_layer=plans.plan)


def _summary(outcome):
    return (outcome.name, outcome.reason, outcome.accepted and outcome.departure_s)


@settings(FUZZ, max_examples=30)
@given(batch=_batches())
def test_accepted_missions_keep_separation_at_every_instant(plans, batch):
    missions, fleet = batch
    result = _run(plans, missions, fleet)
    refused = {e.mission for e in result.errors}
    assert all(e.setting == 'vehicle' for e in result.errors)
    assert [o.name for o in result.outcomes] == \
        [m.name for m in fleet_order(missions) if m.name not in refused]
    accepted = [o.flight for o in result.accepted]
    for i, a in enumerate(accepted):
        for b in accepted[i + 1:]:
            assert not _dense_violation(a, b, fleet.envelope), (a.mission, b.mission)
            assert first_conflict(a, b, fleet.envelope) is None
            if a.vehicle == b.vehicle:
                assert common_window(a, b) is None
    for outcome in result.outcomes:
        assert outcome.reason
        if outcome.accepted:
            delay = outcome.departure_s - outcome.requested_departure_s
            assert 0.0 <= delay <= fleet.max_delay_s
    # The input order does not matter, and the report is JSON.
    again = _run(plans, list(reversed(missions)), fleet)
    assert [_summary(o) for o in again.outcomes] == [_summary(o) for o in result.outcomes]
    assert {e.mission for e in again.errors} == refused
    json.dumps(result.to_dict(step_s=5.0))


@settings(FUZZ, max_examples=20)
@given(route=st.integers(0, ROUTES - 1), departure=st.integers(0, 40),
       factors=st.sampled_from([(), (0.9,), (0.8, 0.5)]), priority=st.integers(-1, 1))
def test_unresolvable_conflict_is_rejected(plans, route, departure, factors, priority):
    # The same route at the same departure: both at one point at the departure, whatever
    # the speed; with no delay and no layer nothing can separate them.
    fleet = FleetSettings(max_delay_s=0.0, altitude_layers=(), speed_factors=factors)
    first = _mission('first', route, float(departure), priority=priority)
    second = _mission('second', route, float(departure), priority=priority)
    result = _run(plans, [second, first], fleet)
    by_name = {o.name: o for o in result.outcomes}
    assert by_name['first'].accepted
    assert not by_name['second'].accepted
    assert 'first' in by_name['second'].reason
    assert by_name['second'].flight is None
    assert by_name['second'].conflicts[0].second == 'first'


def test_resolution_order_delay_then_layer_then_speed(plans):
    tight = FleetSettings(horizontal_separation=10.0, vertical_separation=5.0,
                          max_delay_s=5.0, delay_step_s=5.0, altitude_layers=LAYERS,
                          speed_factors=(0.5,))
    book = ReservationBook(tight)
    book.add(_flight(plans, 3, 0.0, name='reserved'))

    def outcome(route, departure, **changes):
        mission = _mission(f'm{route}', route, departure)
        fleet = FleetSettings(**{**tight.__dict__, **changes})
        return resolve(mission, plans.plan(mission), book, fleet, plans.plan)

    with pytest.raises(InvalidInputError, match='separation'):
        outcome(0, 0.0, horizontal_separation=11.0)

    raised = outcome(0, 0.0)
    assert raised.accepted and raised.flight.layer_m == LAYERS[0]
    assert [s.action for s in raised.steps] == ['plan', 'delay', 'layer']
    assert raised.conflicts[0].second == 'reserved' and raised.conflicts[0].proven
    assert raised.plan is plans.plan(_mission('m0', 0, 0.0), LAYERS[0])
    # The same mission against a copy of the book: the same answer (a pure function).
    again = resolve(raised.mission, plans.plan(raised.mission), book.copy(), tight, plans.plan)
    assert again.reason == raised.reason
    assert again.flight.departure_s == raised.flight.departure_s
    assert book.version == 1
    delayed = outcome(3, 0.0, max_delay_s=60.0)
    assert delayed.accepted and delayed.reason.startswith('delayed by')
    assert delayed.flight.departure_s > 0.0
    slow = outcome(4, 0.0, max_delay_s=0.0, altitude_layers=(), speed_factors=(0.8, 0.6))
    assert slow.accepted and slow.flight.speed_factor == 0.6
    assert [s.action for s in slow.steps] == ['plan', 'speed', 'speed']


def test_failed_plan_rejects_with_its_message(plans):
    inside = Mission('wall', 'v', 0.0, np.array([0.0, 0.0, 4.0]), np.array([40.0, 0.0, 4.0]))
    result = run_fleet(plans.planner, [inside], FleetSettings())
    assert not result.outcomes[0].accepted
    assert 'no plan' in result.outcomes[0].reason


# --- bad input ----------------------------------------------------------------------------

def _entry(name, **overrides):
    entry = {'name': name, 'vehicle': f'v-{name}', 'departure_s': 10.0,
             'start': [-40.0, -40.0, 4.0], 'goal': [40.0, 40.0, 4.0]}
    entry.update(overrides)
    return entry


def test_bad_missions_are_reported_and_the_rest_goes_on(tmp_path):
    bounds = (CONFIG.bounds_min, CONFIG.bounds_max)
    data = {'now_s': 5.0, 'settings': {'horizontal_separation': 12.0},
            'missions': [_entry('good'), _entry('past', departure_s=1.0),
                         _entry('outside', goal=[400.0, 0.0, 4.0]),
                         _entry('twin', vehicle='v-good'),
                         _entry('nan', start=[float('nan'), 0.0, 4.0]),
                         _entry('good'), _entry('extra', speed=3.0),
                         _entry('via', via=[[0.0, 0.0, 90.0]]), _entry('late', departure_s=40),
                         _entry('x-beside', start=[-35.0, -40.0, 6.0]),
                         _entry('x-apart', start=[-20.0, -40.0, 6.0])]}
    batch = load_missions(data, bounds=bounds)
    assert [m.name for m in batch.missions] == ['good', 'late', 'x-apart']
    assert batch.settings.horizontal_separation == 12.0
    errors = {(e.mission, e.setting) for e in batch.errors}
    assert errors == {('past', 'departure_s'), ('outside', 'goal'), ('twin', 'vehicle'),
                      ('nan', 'start'), ('good', 'name'), ('extra', 'speed'),
                      ('via', 'via[0]'), ('x-beside', 'start')}
    assert all(str(e).startswith(e.mission) for e in batch.errors)
    path = tmp_path / 'missions.yaml'
    path.write_text(json.dumps({**data, 'bounds': {'min': list(CONFIG.bounds_min),
                                                   'max': list(CONFIG.bounds_max)}}))
    assert [m.name for m in load_missions(path).missions] == ['good', 'late', 'x-apart']


@pytest.mark.parametrize('key, value', [('horizontal_separation', 0.0),
                                        ('vertical_separation', -1.0),
                                        ('horizontal_separation', float('nan')),
                                        ('max_delay_s', float('inf')),
                                        ('speed_factors', [1.5]),
                                        ('altitude_layers', [0.0]),
                                        ('colour', 1)])
def test_bad_settings_name_the_setting(key, value):
    with pytest.raises(InvalidInputError, match=key):
        load_missions({'settings': {key: value}, 'missions': [_entry('a')]})


def test_unreadable_batches_are_clear_errors(tmp_path):
    with pytest.raises(InvalidInputError, match='missions must be a list'):
        load_missions({'missions': {}})
    bad = tmp_path / 'bad.yaml'
    bad.write_text('missions: [\n')
    with pytest.raises(InvalidInputError, match='not valid YAML'):
        load_missions(bad)
    with pytest.raises(InvalidInputError, match='cannot read'):
        load_missions(tmp_path / 'absent.yaml')


def test_run_fleet_refuses_missions_outside_the_planner_map(plans):
    good = _mission('good', 1, 0.0)
    outside = Mission('outside', 'v2', 0.0, np.array([500.0, 0.0, 4.0]), good.goal)
    result = run_fleet(plans.planner, [outside, good], FleetSettings(),
                       base_plans=plans.base([good]), plan_layer=plans.plan)
    assert [o.name for o in result.accepted] == ['good']
    assert [(e.mission, e.setting) for e in result.errors] == [('outside', 'start')]


# --- what a parallel runner relies on ----------------------------------------------------

def test_plans_do_not_depend_on_earlier_plans(plans):
    planner = Planner(CONFIG, plans.planner.obstacles)
    mission = _mission('m', 5, 0.0)
    first = plan_mission(planner, mission)
    plan_mission(planner, _mission('other', 1, 0.0), LAYERS[1])
    again = plan_mission(planner, mission)
    for plan in (again, plans.plan(mission)):
        assert np.array_equal(plan.trajectory.positions, first.trajectory.positions)
        assert np.array_equal(plan.trajectory.times, first.trajectory.times)


def test_flights_and_outcomes_survive_pickling(plans):
    missions = [_mission(f'm{i}', i, 0.0) for i in range(4)]
    fleet = FleetSettings(horizontal_separation=10.0, vertical_separation=5.0)
    seen = []
    result = run_fleet(plans.planner, missions, fleet, base_plans=plans.base(missions),
                       plan_layer=plans.plan,
                       progress=lambda done, total, o: seen.append((done, total, o.name)))
    assert seen == [(i + 1, 4, o.name) for i, o in enumerate(result.outcomes)]
    report = json.loads(json.dumps(result.to_dict(step_s=0.5)))
    for entry, outcome in zip(report['missions'], result.outcomes):
        assert entry['times'][0] == outcome.departure_s
        assert entry['times'][-1] == pytest.approx(outcome.flight.end_s)
        assert np.allclose(entry['positions'][-1], outcome.flight.reference.curve.evaluate(
            [outcome.flight.reference.curve.length_m])[0])
    copies = [pickle.loads(pickle.dumps(o.flight.prepare())) for o in result.accepted]
    assert all('_table' in flight.__dict__ for flight in copies)
    book = ReservationBook(fleet, copies[:-1])
    assert book.conflicts_with(copies[-1]) == []
    outcome = pickle.loads(pickle.dumps(result.outcomes[-1]))
    assert outcome.reason == result.outcomes[-1].reason
    times = np.array([outcome.departure_s + 1.0])
    original = result.outcomes[-1].flight
    assert np.allclose(outcome.flight.positions(times), original.positions(times))


def test_fleet_core_imports_neither_ray_nor_rclpy():
    code = ('import sys\n'
            'import uav_global_planner.core.fleet\n'
            "leaked = [m for m in sys.modules if m.split('.')[0] in ('ray', 'rclpy')]\n"
            'sys.exit(1 if leaked else 0)\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
