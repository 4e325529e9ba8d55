"""Takeover predictions of replans in flight (ros/takeover.py), without a ROS graph."""

from typing import List

from nav_msgs.msg import Odometry
import numpy as np
import pytest

from uav_global_planner.core.result import PlanResult, Trajectory
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_state import InForce
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import (FIRST_LATENCY_S, LATENCY_WINDOW, odometry_velocity,
                                             PUBLISH_MARGIN_S, TakeoverKind, TakeoverPredictor)

NS = 1_000_000_000
ACCEL = np.array([1.0, 0.5, 0.0])


class Clock:
    """A settable clock [ns]."""

    def __init__(self, now_ns: int = 100 * NS) -> None:
        self.now_ns = now_ns

    def __call__(self) -> int:
        return self.now_ns

    def advance(self, seconds: float) -> None:
        self.now_ns += int(round(seconds * NS))


def accelerating(duration_s: float = 10.0) -> Trajectory:
    """Uniform acceleration ACCEL from (0, 0, 2) at 1 m/s along +x, sampled every 10 ms."""
    t = np.linspace(0.0, duration_s, int(duration_s * 100) + 1)
    v0 = np.array([1.0, 0.0, 0.0])
    positions = np.array([0.0, 0.0, 2.0]) + np.outer(t, v0) + 0.5 * np.outer(t ** 2, ACCEL)
    velocities = v0 + np.outer(t, ACCEL)
    return Trajectory(times=t, positions=positions, velocities=velocities,
                      accelerations=np.tile(ACCEL, (len(t), 1)))


def in_force(trajectory: Trajectory, stamp_ns: int) -> InForce:
    result = PlanResult(status=PlanStatus.OK, message='test', algorithm='astar',
                        start=trajectory.positions[0], goal=trajectory.positions[-1],
                        path=trajectory.positions[[0, -1]], trajectory=trajectory)
    return InForce(result, 'map', stamp_ns, StartSource.ODOM, 0)


def flying(clock: Clock, plan: InForce, predictor: TakeoverPredictor) -> np.ndarray:
    """Odometry of a vehicle on the plan now; returns its position."""
    state = plan.result.trajectory.state_at((clock() - plan.stamp_ns) / NS)
    predictor.on_odometry(state.position[0], state.velocity[0], 0.0)
    return state.position[0]


def test_expected_latency_is_a_high_percentile_plus_the_margin():
    predictor = TakeoverPredictor(Clock())
    assert predictor.expected_latency_s() == pytest.approx(FIRST_LATENCY_S + PUBLISH_MARGIN_S)
    for seconds in [0.1] * 18 + [0.3, 0.4]:
        predictor.record_latency(seconds)
    expected = float(np.percentile([0.1] * 18 + [0.3, 0.4], 90)) + PUBLISH_MARGIN_S
    assert predictor.expected_latency_s() == pytest.approx(expected)
    # Only the newest ones count; nonsense is ignored.
    for _ in range(LATENCY_WINDOW):
        predictor.record_latency(0.2)
    predictor.record_latency(float('nan'))
    predictor.record_latency(-1.0)
    assert predictor.expected_latency_s() == pytest.approx(0.2 + PUBLISH_MARGIN_S)


def test_a_vehicle_on_the_plan_in_force_continues_it_from_the_takeover_time():
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    predictor.record_latency(0.3)
    plan = in_force(accelerating(), clock() - 2 * NS)
    position = flying(clock, plan, predictor)
    takeover = predictor.predict(position, StartSource.ODOM, plan)
    assert takeover.kind is TakeoverKind.PLAN_IN_FORCE and takeover.moving
    assert takeover.latency_s == pytest.approx(0.3 + PUBLISH_MARGIN_S)
    assert takeover.stamp_ns == clock() + int(round(takeover.latency_s * NS))
    t = (takeover.stamp_ns - plan.stamp_ns) / NS
    state = plan.result.trajectory.state_at(t)
    assert np.allclose(takeover.position, state.position[0])
    assert np.allclose(takeover.velocity, [1.0 + t, 0.5 * t, 0.0])
    assert np.allclose(takeover.acceleration, ACCEL)
    assert takeover.in_force is plan
    values = takeover.values()
    assert values['takeover'] == 'plan_in_force'
    assert values['takeover_plan_time_s'] == pytest.approx(t)


def test_a_vehicle_off_the_plan_uses_its_odometry_and_a_still_one_starts_from_rest():
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    plan = in_force(accelerating(), clock() - 2 * NS)
    # Standing where the plan started (a vehicle that never took off): from rest, as before.
    predictor.on_odometry(np.array([0.0, 0.0, 2.0]), np.zeros(3), 0.0)
    rest = predictor.predict(np.array([0.0, 0.0, 2.0]), StartSource.ODOM, plan)
    assert rest.kind is TakeoverKind.REST and not rest.moving
    assert rest.stamp_ns == clock() and np.allclose(rest.position, [0.0, 0.0, 2.0])
    # On the plan's track but much slower than it: not following it; moving on odometry.
    here = plan.result.trajectory.state_at(2.0).position[0]
    velocity = np.array([0.0, 1.0, 0.0])
    predictor.on_odometry(here, velocity, 0.7)
    clock.advance(0.1)
    moving = predictor.predict(here, StartSource.ODOM, plan)
    assert moving.kind is TakeoverKind.ODOMETRY
    dt = (moving.stamp_ns - (clock() - int(0.1 * NS))) / NS
    assert np.allclose(moving.position, here + dt * velocity)
    assert np.allclose(moving.velocity, velocity) and np.allclose(moving.acceleration, 0.0)
    assert moving.yaw == pytest.approx(0.7)
    # A start that is no vehicle (start_pose, the parameter) never moves.
    for source in (StartSource.START_POSE, StartSource.PARAMETER):
        assert predictor.predict(here, source, plan).kind is TakeoverKind.REST
    # A plan that has come to its end: nothing to continue.
    stopped = in_force(Trajectory(times=np.array([0.0, 1.0]), positions=np.zeros((2, 3)),
                                  velocities=np.zeros((2, 3)), accelerations=np.zeros((2, 3))),
                       clock() - 5 * NS)
    predictor.on_odometry(np.zeros(3), np.zeros(3), 0.0)
    assert predictor.predict(np.zeros(3), StartSource.ODOM, stopped).kind is TakeoverKind.REST


def continuation(plan: InForce, stamp_ns: int, velocity_error: float = 0.0) -> Trajectory:
    """A new plan whose t = 0 is ``stamp_ns`` and that continues ``plan`` exactly (plus a
    velocity error along y)."""
    base = plan.result.trajectory
    t = np.linspace(0.0, 3.0, 301)
    state = base.state_at((stamp_ns - plan.stamp_ns) / NS + t)
    return Trajectory(times=t, positions=state.position,
                      velocities=state.velocity + [0.0, velocity_error, 0.0],
                      accelerations=state.acceleration)


def test_settling_a_plan_on_time_late_or_not_continuing():
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    plan = in_force(accelerating(), clock() - 2 * NS)
    takeover = predictor.predict(flying(clock, plan, predictor), StartSource.ODOM, plan)
    latency = takeover.latency_s
    new = continuation(plan, takeover.stamp_ns)
    # Ready before the takeover time: published stamped with it.
    clock.advance(0.5 * latency)
    settled = predictor.settle(takeover, new, plan, None, 2.0)
    assert settled.stamp_ns == takeover.stamp_ns and not settled.problem
    assert settled.jump is not None and settled.jump.within and settled.jump.late_s < 0
    # Late, but the new plan continues the old one: the jump at the switch is tiny.
    clock.advance(latency)
    settled = predictor.settle(takeover, new, plan, None, 2.0)
    assert not settled.problem and settled.jump.late_s > 0
    # Late, and the plans part after the takeover time: planned again.
    parting = Trajectory(times=new.times, positions=new.positions,
                         velocities=new.velocities,
                         accelerations=new.accelerations + [0.0, 2.0, 0.0])
    settled = predictor.settle(takeover, parting, plan, None, 2.0)
    assert settled.retry and 'after its takeover time' in settled.problem
    assert settled.values()['takeover_jump_accel_mps2'] == pytest.approx(2.0)
    # The plan in force was replaced meanwhile: planned again.
    other = in_force(accelerating(), plan.stamp_ns)
    assert predictor.settle(takeover, new, other, None, 2.0).retry
    # The vehicle left the prediction: planned again.
    far = predictor.settle(takeover, new, plan, np.array([50.0, 0.0, 2.0]), 2.0)
    assert far.retry and 'from where it was predicted' in far.problem
    # On time but not continuing (the curve could not keep the state): said, not retried.
    clock.now_ns = takeover.predicted_ns
    settled = predictor.settle(takeover, continuation(plan, takeover.stamp_ns, 0.3), plan,
                               None, 2.0)
    assert settled.problem and not settled.retry
    assert 'does not continue the motion' in settled.problem
    # Every settle measured a latency.
    assert predictor.expected_latency_s() > latency - PUBLISH_MARGIN_S


def test_a_plan_that_cannot_continue_the_odometry_is_planned_again():
    """No plan in force (withdrawn: a follower holds and the vehicle brakes): a plan whose
    curve could not keep the odometry's motion is planned again from the newest odometry,
    never published as if the vehicle would reach its start."""
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    velocity = np.array([2.0, 0.0, 0.0])
    predictor.on_odometry(np.array([0.0, 0.0, 2.0]), velocity, 0.0)
    takeover = predictor.predict(np.array([0.0, 0.0, 2.0]), StartSource.ODOM, None)
    assert takeover.kind is TakeoverKind.ODOMETRY and takeover.moving
    t = np.linspace(0.0, 3.0, 301)
    at_rest = Trajectory(times=t, positions=np.tile(takeover.position, (t.size, 1)),
                         velocities=np.zeros((t.size, 3)), accelerations=np.zeros((t.size, 3)))
    clock.now_ns = takeover.predicted_ns
    settled = predictor.settle(takeover, at_rest, None, None, 0.0)
    assert settled.retry and 'does not continue the motion' in settled.problem
    assert 'planned again from the newest odometry' in settled.problem
    # The same plan continuing the motion goes out as it is.
    moving = Trajectory(times=t, positions=takeover.position + np.outer(t, velocity),
                        velocities=np.tile(velocity, (t.size, 1)),
                        accelerations=np.zeros((t.size, 3)))
    settled = predictor.settle(takeover, moving, None, None, 0.0)
    assert not settled.problem and not settled.retry


def test_a_plan_from_rest_is_planned_again_once_the_vehicle_moves():
    """A vehicle at rest when a replan starts may take up the plan in force meanwhile: the
    plan from where it stood is then behind it, and a follower taking it up would step back.
    Newer odometry that shows it moving sends the plan back for a takeover of its motion."""
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    start = np.array([0.0, 0.0, 2.0])
    plan = in_force(accelerating(), clock())
    predictor.on_odometry(start, np.zeros(3), 0.0)
    takeover = predictor.predict(start, StartSource.ODOM, plan)
    assert takeover.kind is TakeoverKind.REST
    t = np.linspace(0.0, 3.0, 301)
    from_rest = Trajectory(times=t, positions=start + 0.5 * np.outer(t ** 2, ACCEL),
                           velocities=np.outer(t, ACCEL), accelerations=np.tile(ACCEL, (301, 1)))
    # Still at rest (or no newer odometry) when the plan is ready: published as it is.
    clock.advance(0.3)
    assert predictor.settle(takeover, from_rest, plan, start, 2.0).problem == ''
    predictor.on_odometry(start, np.array([0.01, 0.0, 0.0]), 0.0)
    assert predictor.settle(takeover, from_rest, plan, start, 2.0).problem == ''
    # Flying the plan in force by then: planned again, and the new prediction continues it.
    clock.advance(0.1)
    moved = flying(clock, plan, predictor)
    settled = predictor.settle(takeover, from_rest, plan, moved, 2.0)
    assert settled.retry and 'started moving' in settled.problem
    assert predictor.predict(moved, StartSource.ODOM, plan).kind is TakeoverKind.PLAN_IN_FORCE
    # A start that is no vehicle (a request's start, the parameter) is not the vehicle's.
    requested = predictor.predict(start, StartSource.PARAMETER, plan)
    assert requested.kind is TakeoverKind.REST
    assert not predictor.settle(requested, from_rest, plan, moved, 2.0).retry


def test_plan_arguments_follow_the_planner_signature():
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    plan = in_force(accelerating(), clock() - 2 * NS)
    takeover = predictor.predict(flying(clock, plan, predictor), StartSource.ODOM, plan)
    calls: List[dict] = []

    def full(start, goal, *, start_velocity=None, start_acceleration=None, start_yaw=None):
        calls.append(dict(start_velocity=start_velocity, start_acceleration=start_acceleration))

    def old(start, goal, *, cancel=None):
        pass
    arguments = takeover.plan_arguments(full)
    assert set(arguments) == {'start_velocity', 'start_acceleration'}    # no yaws: no yaw
    assert np.allclose(arguments['start_velocity'], takeover.velocity)
    assert takeover.plan_arguments(old) == {}
    assert predictor.at_rest(np.zeros(3)).plan_arguments(full) == {}


def odometry(child: str, yaw: float, velocity, frame: str = 'map') -> Odometry:
    msg = Odometry()
    msg.header.frame_id = frame
    msg.child_frame_id = child
    x, y, z, w = conv.yaw_quaternion(yaw)
    msg.pose.pose.orientation.x, msg.pose.pose.orientation.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = z, w
    msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z = velocity
    return msg


def test_odometry_velocity_in_the_planning_frame():
    # The twist is in the body frame (child_frame_id): rotated by the heading.
    body = odometry('base_link', np.pi / 2, (2.0, 0.0, 0.5))
    assert np.allclose(odometry_velocity(body, 'map'), [0.0, 2.0, 0.5])
    assert np.allclose(odometry_velocity(odometry('', np.pi, (1.0, 0.0, 0.0)), 'map'),
                       [-1.0, 0.0, 0.0])
    # A twist given in the planning frame itself is used as it is.
    assert np.allclose(odometry_velocity(odometry('/map', np.pi / 2, (2.0, 0.0, 0.5)), 'map'),
                       [2.0, 0.0, 0.5])
    with pytest.raises(conv.InputRejected, match="frame 'odom'"):
        odometry_velocity(odometry('base_link', 0.0, (1.0, 0.0, 0.0), 'odom'), 'map')
    with pytest.raises(conv.InputRejected, match='twist must be finite'):
        odometry_velocity(odometry('base_link', 0.0, (float('nan'), 0.0, 0.0)), 'map')


def test_a_plan_stamped_ahead_is_flown_only_from_its_stamp():
    """Until a replan takes over, the vehicle flies the plan before it: a replan meanwhile
    continues that one."""
    clock = Clock()
    predictor = TakeoverPredictor(clock)
    predictor.record_latency(0.2)
    first = in_force(accelerating(), clock() - 2 * NS)
    position = flying(clock, first, predictor)
    stopped = Trajectory(times=np.array([0.0, 1.0]), positions=np.zeros((2, 3)) + 50.0,
                         velocities=np.zeros((2, 3)), accelerations=np.zeros((2, 3)))
    later = in_force(stopped, clock() + 5 * NS)
    later.previous = first
    assert later.flown_at(clock()) is first and later.flown_at(clock() + 6 * NS) is later
    takeover = predictor.predict(position, StartSource.ODOM, later)
    assert takeover.kind is TakeoverKind.PLAN_IN_FORCE
    t = (takeover.stamp_ns - first.stamp_ns) / NS
    assert np.allclose(takeover.position, first.result.trajectory.state_at(t).position[0])
    assert takeover.in_force is later
    assert np.allclose(takeover.flown_at(takeover.stamp_ns)[0], takeover.position)
