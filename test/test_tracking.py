"""The vehicle in the margin: the planning margin, and the reference slowing where the room
left for its tracking error is short."""

import numpy as np
import pytest

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.path.tracking import (MIN_TRACKING_SPEED, tracking_error,
                                                   TRACKING_ERROR_AT_REST,
                                                   TRACKING_ERROR_PER_SPEED, tracking_speed_cap)
from uav_global_planner.core.planner import Planner

# A corridor between two boxes, 2.4 m wide, which the straight path flies along.
WALLS = ObstacleSet([Box([-1.0, 1.2, 0.0], [21.0, 3.0, 6.0]),
                     Box([-1.0, -3.0, 0.0], [21.0, -1.2, 6.0])])


def config(**changes) -> PlannerConfig:
    base = PlannerConfig(bounds_min=(-2.0, -4.0, 0.0), bounds_max=(22.0, 4.0, 6.0),
                         resolution=0.25, safety_margin=0.3, max_speed_horizontal=8.0,
                         max_accel_horizontal=4.0, algorithm='octile')
    return validate_config(base).with_changes(**changes)


def test_the_cap_fits_the_predicted_error_in_the_room_left():
    cfg = config(vehicle_radius=0.25, tracking_margin=0.2)
    points = np.array([[5.0, 0.0, 3.0], [5.0, 0.5, 3.0], [5.0, 0.62, 3.0]])
    cap = tracking_speed_cap(points, WALLS, cfg)
    room = WALLS.distance(points) - 0.3 - 0.25
    expected = np.maximum((room - TRACKING_ERROR_AT_REST) / TRACKING_ERROR_PER_SPEED,
                          MIN_TRACKING_SPEED)
    # Where the room is short of the error at the top speed (8 m/s) the cap is exact and its
    # predicted error is the room; elsewhere it does not bind.
    short = room < tracking_error(8.0)
    assert short.tolist() == [False, True, True]
    assert cap[short] == pytest.approx(expected[short])
    assert np.all(cap[~short] >= 8.0)
    above = short & (cap > MIN_TRACKING_SPEED)
    assert tracking_error(cap[above]) == pytest.approx(room[above])
    # Far from everything the cap does not bind (the capped distance suffices).
    far = tracking_speed_cap(np.array([[5.0, 0.0, 3.0]]), ObstacleSet([Sphere([50, 50, 3],
                                                                              1.0)]), cfg)
    assert far[0] >= 8.0


def test_the_body_keeps_gamma_and_the_reference_slows_where_the_room_is_short():
    cfg = config(vehicle_radius=0.25, tracking_margin=0.1)
    assert cfg.planning_margin == pytest.approx(0.65)
    result = Planner(cfg, WALLS).plan([0.0, 0.0, 3.0], [20.0, 0.0, 3.0])
    assert result.ok, result.message
    assert result.planning_margin == pytest.approx(0.65)
    trajectory = result.trajectory
    state = trajectory.state_at(np.linspace(0.0, trajectory.duration_s, 4000))
    assert WALLS.distance(state.position).min() >= 0.65 - 1e-9
    speed = np.linalg.norm(trajectory.velocities, axis=1)
    cap = tracking_speed_cap(trajectory.positions, WALLS, cfg)
    assert np.all(speed <= cap * (1 + 1e-9))
    # The corridor leaves 1.2 - 0.55 = 0.65 m of room: the cap (57 m/s) does not bind, and
    # the same plan without a tracking margin flies as fast.
    free = Planner(config(vehicle_radius=0.25), WALLS).plan([0.0, 0.0, 3.0], [20.0, 0.0, 3.0])
    assert free.duration_s == pytest.approx(result.duration_s, rel=1e-6)


def test_a_narrow_corridor_slows_the_reference_to_fit_the_error():
    # 1.36 m wide: with gamma 0.3 and radius 0.25 the room is 0.13 m on the centre line,
    # within the 0.1 m tracking margin plus a little.
    walls = ObstacleSet([Box([-1.0, 0.68, 0.0], [21.0, 3.0, 6.0]),
                         Box([-1.0, -3.0, 0.0], [21.0, -0.68, 6.0])])
    cfg = config(vehicle_radius=0.25, tracking_margin=0.1)
    result = Planner(cfg, walls).plan([0.0, 0.0, 3.0], [20.0, 0.0, 3.0])
    assert result.ok, result.message
    speed = np.linalg.norm(result.trajectory.velocities, axis=1)
    room = 0.68 - 0.3 - 0.25
    assert speed.max() <= (room - TRACKING_ERROR_AT_REST) / TRACKING_ERROR_PER_SPEED + 1e-9
    wide = Planner(config(vehicle_radius=0.25), walls).plan([0.0, 0.0, 3.0], [20.0, 0.0, 3.0])
    assert wide.trajectory.peaks().speed_horizontal > speed.max() + 1.0
