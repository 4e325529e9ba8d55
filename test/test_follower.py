"""The follower's pure logic (uav_global_planner.core.follower): sampling, handover and holds."""

import math

import numpy as np
import pytest

from uav_global_planner.core import follower as fl
from uav_global_planner.core.errors import InvalidInputError

S = 1_000_000_000       # one second [ns]
T0 = 100 * S            # plan stamps and clock in these tests


def accelerating_plan(stamp_ns=T0, start=(0.0, 0.0, 2.0), v0=(1.0, 0.0, 0.2),
                      accel=(0.5, 0.25, 0.0), duration=4.0, period=0.05, frame='map',
                      yaw=None):
    """Uniform acceleration, sampled as the planner's trajectory message is."""
    t = np.arange(0.0, duration + 1e-9, period)
    p0, v, a = (np.asarray(x, dtype=float) for x in (start, v0, accel))
    positions = p0 + t[:, None] * v + 0.5 * t[:, None] ** 2 * a
    velocities = v + t[:, None] * a
    yaws = np.zeros(len(t)) if yaw is None else yaw(t)
    return fl.PlanSamples(stamp_ns=stamp_ns, frame_id=frame, times=t, positions=positions,
                          velocities=velocities, accelerations=np.tile(a, (len(t), 1)),
                          yaws=yaws, yaw_rates=np.gradient(yaws, t))


def state(plan, t):
    p0, v, a = plan.positions[0], plan.velocities[0], plan.accelerations[0]
    return p0 + v * t + 0.5 * a * t * t, v + a * t


def make(bounds_min=(-50.0, -50.0, 0.0), bounds_max=(50.0, 50.0, 30.0), fence=None, **kw):
    settings = fl.FollowerSettings(bounds_min=bounds_min, bounds_max=bounds_max, **kw)
    follower = fl.Follower(settings, fence)
    follower.on_planner_presence(True, T0)
    return follower


def feed(follower, now_ns, position=(0.0, 0.0, 2.0)):
    follower.on_odometry(np.array(position), now_ns)
    follower.on_planner_presence(True, now_ns)
    return follower.step(now_ns)


def test_samples_between_points_exactly_for_uniform_acceleration():
    plan = accelerating_plan()
    follower = make()
    follower.on_trajectory(plan, T0)
    for t in (0.0, 0.013, 0.5, 1.337, 2.02, 3.999):
        now = T0 + int(round(t * S))
        command = feed(follower, now, state(plan, t)[0])
        assert not command.holding, command.reasons
        position, velocity = state(plan, (now - T0) / S)
        assert np.allclose(command.setpoint.position, position, atol=1e-9)
        assert np.allclose(command.setpoint.velocity, velocity, atol=1e-9)
        assert np.allclose(command.setpoint.acceleration, plan.accelerations[0])
        assert np.all(np.isnan(command.setpoint.jerk))      # not in the trajectory message
    # After the end: the goal, at rest, still following (not a hold).
    end = feed(follower, T0 + 10 * S, plan.positions[-1])
    assert not end.holding
    assert np.array_equal(end.setpoint.position, plan.positions[-1])
    assert np.array_equal(end.setpoint.velocity, np.zeros(3))


def test_yaw_interpolates_the_short_way_across_pi():
    plan = accelerating_plan(yaw=lambda t: np.where(t < 1.0, 3.1, -3.1), duration=2.0,
                             period=1.0)
    follower = make()
    follower.on_trajectory(plan, T0)
    command = feed(follower, T0 + S // 2, state(plan, 0.5)[0])
    assert abs(abs(command.setpoint.yaw) - math.pi) < 1e-9


def test_empty_trajectory_holds_at_once_at_the_last_setpoint_then_a_new_plan_flies():
    plan = accelerating_plan()
    follower = make()
    follower.on_trajectory(plan, T0)
    flying = feed(follower, T0 + S, state(plan, 1.0)[0])
    follower.on_trajectory(None, T0 + S + 1)
    held = follower.step(T0 + S + 2)
    assert held.holding and held.reasons[0] == fl.WITHDRAWN
    assert np.array_equal(held.setpoint.position, flying.setpoint.position)
    assert np.array_equal(held.setpoint.velocity, np.zeros(3))
    assert held.setpoint.yaw == flying.setpoint.yaw and held.setpoint.yaw_rate == 0.0
    # Still held later, wherever the old plan would be.
    assert feed(follower, T0 + 3 * S).holding
    replacement = accelerating_plan(stamp_ns=T0 + 3 * S, start=flying.setpoint.position)
    follower.on_trajectory(replacement, T0 + 3 * S)
    resumed = feed(follower, T0 + 3 * S + S // 10)
    assert not resumed.holding and resumed.plan_stamp_ns == replacement.stamp_ns


def test_empty_plan_withdraws_only_plans_published_before_it():
    first = accelerating_plan(stamp_ns=T0)
    follower = make()
    follower.on_plan_path(first.stamp_ns, False, T0)
    follower.on_trajectory(first, T0)
    feed(follower, T0 + S)
    follower.on_plan_path(T0 + S, True, T0 + S)             # withdrawal
    assert follower.step(T0 + S).reasons[0] == fl.WITHDRAWN
    # A replacement whose trajectory overtook its own plan message and the empty one.
    second = accelerating_plan(stamp_ns=T0 + 2 * S)
    follower.on_trajectory(second, T0 + 2 * S)
    follower.on_plan_path(T0 + 3 * S, True, T0 + 2 * S)      # empty: only `first` came before
    follower.on_plan_path(second.stamp_ns, False, T0 + 2 * S)
    assert not feed(follower, T0 + 2 * S + 1, second.positions[0]).holding
    # The late trajectory of a withdrawn plan is not flown.
    follower.on_plan_path(second.stamp_ns, True, T0 + 3 * S)
    follower.on_trajectory(second, T0 + 3 * S)
    assert follower.step(T0 + 3 * S).reasons[0] == fl.WITHDRAWN


def test_handover_to_a_plan_stamped_ahead_at_its_stamp():
    first = accelerating_plan(stamp_ns=T0)
    follower = make()
    follower.on_trajectory(first, T0)
    feed(follower, T0 + S // 2)
    ahead = T0 + 2 * S
    position, velocity = state(first, 2.0)
    second = accelerating_plan(stamp_ns=ahead, start=position, v0=velocity,
                               accel=(-0.5, 0.0, 0.0))
    follower.on_trajectory(second, T0 + S)
    before = feed(follower, ahead - S // 100)
    assert before.plan_stamp_ns == first.stamp_ns
    after = feed(follower, ahead + S // 100)
    assert after.plan_stamp_ns == second.stamp_ns
    jump = np.linalg.norm(after.setpoint.position - before.setpoint.position)
    assert jump < 0.1        # continues without a jump (about 2 cm travelled in 20 ms)
    # A newer plan drops one still waiting for its stamp.
    third = accelerating_plan(stamp_ns=T0 + 5 * S)
    follower.on_trajectory(accelerating_plan(stamp_ns=T0 + 4 * S), T0 + 3 * S)
    follower.on_trajectory(third, T0 + 3 * S)
    assert feed(follower, T0 + 4 * S + S // 2).plan_stamp_ns == second.stamp_ns
    assert feed(follower, T0 + 5 * S + S // 2).plan_stamp_ns == third.stamp_ns


def test_stale_odometry_holds_and_resumes_near_the_plan():
    plan = accelerating_plan(v0=(0.1, 0.0, 0.0), accel=(0.0, 0.0, 0.0), duration=20.0)
    follower = make(odometry_timeout_s=0.5, resume_distance_m=0.5)
    follower.on_trajectory(plan, T0)
    last = feed(follower, T0 + S)
    held = follower.step(T0 + S + 6 * S // 10)
    assert held.holding
    assert held.reasons[0].startswith(fl.ODOMETRY_STALE)
    assert 'odometry_timeout' in held.reasons[0]
    assert np.array_equal(held.setpoint.position, last.setpoint.position)
    # Back 1 s later: the plan moved on 0.1 m, within resume_distance, so it resumes.
    assert not feed(follower, T0 + 2 * S).holding
    # Lost for 10 s: the plan moved on 1 m, so the follower waits for a plan from here.
    feed(follower, T0 + 3 * S)
    assert follower.step(T0 + 4 * S).holding
    waiting = feed(follower, T0 + 13 * S)
    assert waiting.holding and len(waiting.reasons) == 1
    assert waiting.reasons[0].startswith(fl.WAITING) and 'resume_distance' in waiting.reasons[0]
    follower.on_trajectory(accelerating_plan(stamp_ns=T0 + 13 * S), T0 + 13 * S)
    assert not feed(follower, T0 + 13 * S + 1).holding


@pytest.mark.parametrize('position, words', [
    ((float('nan'), 0.0, 2.0), 'non-finite'),
    ((0.0, 0.0, -80.0), 'outside the bounds'),     # NED fed as ENU: 80 m "below" the ground
])
def test_bad_odometry_is_refused_and_holds(position, words):
    plan = accelerating_plan()
    follower = make()
    follower.on_trajectory(plan, T0)
    feed(follower, T0 + S)
    follower.on_odometry(np.array(position), T0 + S + 1)
    held = follower.step(T0 + S + 2)
    assert held.holding
    assert held.reasons[0].startswith(fl.ODOMETRY_REFUSED) and words in held.reasons[0]
    follower.on_odometry(None, T0 + S + 3, refused='pose_frame FRD (not NED)')
    assert 'pose_frame FRD' in follower.step(T0 + S + 4).reasons[0]


def test_lost_plan_stream_holds():
    follower = make(plan_timeout_s=1.0)
    follower.on_trajectory(accelerating_plan(duration=30.0), T0)
    assert not feed(follower, T0).holding       # taken up where the vehicle is
    feed(follower, T0 + S)
    follower.on_planner_presence(False, T0 + 2 * S)
    follower.on_odometry(np.zeros(3) + [0, 0, 2], T0 + 2 * S + S // 2)
    assert not follower.step(T0 + 2 * S).holding
    follower.on_odometry(np.zeros(3) + [0, 0, 2], T0 + 2 * S + S // 2)
    held = follower.step(T0 + 2 * S + S // 2)
    assert held.holding and held.reasons == (fl.PLAN_LOST,)


def test_setpoints_stay_within_bounds_and_fence():
    plan = accelerating_plan(start=(8.0, 0.0, 2.0), v0=(2.0, 0.0, 0.0), accel=(0.0, 0.0, 0.0))
    fence_x = 11.0

    follower = make(bounds_min=(-10.0, -10.0, 0.0), bounds_max=(10.0, 10.0, 15.0))
    follower.on_trajectory(plan, T0)
    clamped = 0
    for k in range(0, 40):
        command = feed(follower, T0 + k * S // 10, (8.0, 0.0, 2.0))
        assert command.setpoint.position[0] <= 10.0
        if command.clamped:
            clamped += 1
            assert command.setpoint.position[0] == 10.0
            assert command.setpoint.velocity[0] == 0.0
    assert clamped > 20

    fenced = make(fence=lambda p: bool(p[0] < 9.0))
    fenced.on_trajectory(accelerating_plan(start=(8.0, 0.0, 2.0), v0=(2.0, 0.0, 0.0),
                                           accel=(0.0, 0.0, 0.0)), T0)
    for k in range(0, 40):
        command = feed(fenced, T0 + k * S // 10, (8.0, 0.0, 2.0))
        assert command.setpoint.position[0] < 9.0 < fence_x
        if k > 6:
            assert command.holding and fl.OUTSIDE_FENCE in command.reasons


def test_plan_in_another_frame_is_refused_and_nothing_changes():
    follower = make()
    plan = accelerating_plan()
    follower.on_trajectory(plan, T0)
    with pytest.raises(InvalidInputError, match='frame_id'):
        follower.on_trajectory(accelerating_plan(stamp_ns=T0 + S, frame='odom'), T0 + S)
    assert feed(follower, T0 + 2 * S).plan_stamp_ns == plan.stamp_ns


def test_a_plan_away_from_the_vehicle_is_not_taken_up():
    follower = make(resume_distance_m=0.5)
    feed(follower, T0, (5.0, 5.0, 2.0))               # holding there, no plan yet
    follower.on_trajectory(accelerating_plan(), T0)
    command = feed(follower, T0 + S // 10, (5.0, 5.0, 2.0))
    assert command.holding and command.reasons[0].startswith(fl.WAITING)
    assert command.setpoint.position.tolist() == [5.0, 5.0, 2.0]
    follower.on_trajectory(accelerating_plan(stamp_ns=T0 + S, start=(5.2, 5.0, 2.0)), T0 + S)
    assert not feed(follower, T0 + S + 1, (5.0, 5.0, 2.0)).holding


def test_nothing_to_send_without_a_position_then_hold_where_the_vehicle_is():
    follower = make()
    assert follower.step(T0) is None
    command = feed(follower, T0 + 1, (1.0, 2.0, 3.0))
    assert command.holding and command.reasons == (fl.NO_PLAN,)
    assert command.setpoint.position.tolist() == [1.0, 2.0, 3.0]
    assert math.isnan(command.setpoint.yaw)          # keep the heading


def test_bad_settings_and_plans_name_the_setting():
    with pytest.raises(InvalidInputError, match='odometry_timeout_s'):
        fl.FollowerSettings(odometry_timeout_s=0.0)
    with pytest.raises(InvalidInputError, match='bounds'):
        fl.FollowerSettings(bounds_min=(0.0, 0.0, 0.0), bounds_max=(1.0, 1.0, 0.0))
    with pytest.raises(InvalidInputError, match='positions: non-finite'):
        fl.PlanSamples(0, 'map', np.zeros(1), np.full((1, 3), np.nan), np.zeros((1, 3)),
                       np.zeros((1, 3)), np.zeros(1), np.zeros(1))
