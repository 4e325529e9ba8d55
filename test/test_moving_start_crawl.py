"""Plans that start from a moving state never crawl: moving takeovers near an obstacle.

A replan in flight continues the vehicle's motion (:mod:`uav_global_planner.core.path.handover`):
the curve leaves along the velocity for a braking distance and then turns towards the goal,
which may lie behind the vehicle, so the curve may turn back on itself within micrometres (a
near-cusp). The reference must slow down there and go on. Criterion: before its end, the
reference's speed is never below 1 cm/s for 5 s in a row (a stop at a corner takes a fraction
of a second, a turn back at a near-cusp up to about 3 s; the crawl this guards against lasted
minutes, at 1 mm/s).
"""

import itertools
import math

import numpy as np
import pytest

from uav_global_planner.core import Planner, PlannerConfig
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.path.timing import check_limits, longest_crawl

#: The box the vehicle flies at [m] (ENU), 1 m wide.
CENTER = np.array([0.0, 0.0, 2.5])
#: The closed loop's margins: gamma 0.5 m, the vehicle's radius and 0.3 m for tracking.
CONFIG = PlannerConfig(bounds_min=(-20.0, -20.0, 0.0), bounds_max=(20.0, 20.0, 8.0),
                       safety_margin=0.5, vehicle_radius=0.41, tracking_margin=0.3,
                       max_planning_time=60.0)


@pytest.fixture(scope='module')
def planner() -> Planner:
    return Planner(CONFIG, ObstacleSet([Box(CENTER - 0.5, CENTER + 0.5)]))


@pytest.mark.parametrize('distance, bearing',
                         list(itertools.product((6.0, 9.0), (-0.3, 0.0))))
def test_no_moving_takeover_crawls(planner, distance, bearing):
    """At 2 m/s towards the box (or 0.3 rad beside it), ``distance`` from its centre; goals 2 m and
    6 m back beside the start."""
    start = CENTER + [-distance, 0.0, 0.0]
    velocity = 2.0 * np.array([math.cos(bearing), math.sin(bearing), 0.0])
    limits = MotionLimits.from_config(CONFIG)
    for back in (2.0, 6.0):
        result = planner.plan(start, start + [-back, 1.0, 0.0], start_velocity=velocity)
        assert result.ok, result.message
        trajectory = result.trajectory
        assert longest_crawl(trajectory) < 5.0, (distance, bearing, back)
        assert check_limits(trajectory, limits, step_s=0.01) == []
        # The curve keeps its certified clearance, and the reference starts at the start.
        assert result.min_clearance_m >= CONFIG.planning_margin
        assert np.linalg.norm(trajectory.state_at(0.0).position[0] - start) < 1e-6
