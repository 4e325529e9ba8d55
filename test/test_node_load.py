"""The planner node under load: goals at 100 Hz and obstacle updates at 20 Hz for 30 s.

Setting: config/planner.yaml (the paper's delta 0.5 m, gamma 0.2 m, eta 1.5 m) and the
paper_medium spheres, plus two spheres that circle through the middle of the workspace, so that
many plans are invalidated by the next obstacle set. Goals cycle over five reachable points;
each goal carries its number in its heading, which the node puts on the last pose of its plan.

Every obstacle set is a complete MarkerArray (DELETEALL, then every marker) whose markers are
stamped with the publication time; the node reports the stamp of the set a plan was computed
against as ``obstacles_stamp`` in the plan's diagnostics. What is checked, for the plans
published after the warm-up plan (in the order received):

1. Safety against the sets the node knew: a plan names the set it was computed against
   (``obstacles_stamp``) and the newest set the node had when it published the plan
   (``obstacles_checked_stamp``; the node drops a plan that collides with obstacles received
   while it was computed, and plans again). Both must be sets the test published, and the plan
   keeps clearance >= gamma from both; it starts at the start and ends at the goal of its
   heading.
2. No going back: the sets named by successive plans never get older.
3. Freshness: a plan is computed against a set at least as new as every set published more than
   ``FRESH_SLACK_S`` before the plan started (plan stamp minus the reported grid, search and
   smoothing times), and at least as new as the set the previous plan was checked against (the
   node had that one before it began the next plan). A planner that kept planning on an old
   map fails this.
4. Replanning: while a plan is the newest one received, every set published meanwhile (and the
   set current when it arrived) either leaves it clear by gamma, or the plan is replaced (by a
   newer plan, or withdrawn). The last plan has no successor, so it must be clear of every set
   current while it was in force, including the final one: two seconds of obstacle updates
   without goals end the test, and then the node is given until it has settled (its newest
   plan clear of the final set, or ``SETTLE_TIMEOUT_S``). How long invalid plans stayed in
   force is printed, not bounded: speed is measured by benchmarks/bench_live_maps.py.
5. The last plan ends at the last goal sent.
6. Parameter services: every ``get_parameters`` sent every 0.5 s is answered (the round trips
   are printed; ``PARAM_TIMEOUT_S`` only tells a hung service from a slow one).
7. Memory: the node's RSS grows by at most 20 MB from the end of the warm-up (5 s) to the end.

The figures are printed (``pytest -s``) and are in the output of a failed test.
"""

from dataclasses import dataclass
import math
import statistics
import threading
import time
from typing import Dict, List

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
import numpy as np
import psutil
import pytest
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (assert_clean_exit, diagnostics_of, marker, marker_array, min_clearance,
                         MONITOR_QOS, NODE_NAME, OBSTACLES_QOS, pose_msg, RosClient, RUN_NAMESPACE,
                         start_planner, unique_domain_id, wait_until)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.qos import keep_last

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = f'{RUN_NAMESPACE}/load'
FQN = f'{NAMESPACE}/{NODE_NAME}'
SCENE = load_scene(find_scene('paper_medium'))
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GAMMA, DELTA = 0.2, 0.5
GOALS = np.array([[8.0, 8.0, 8.0], [-8.0, 8.0, 10.0], [8.0, -8.0, 6.0], [-7.0, -8.0, 12.0],
                  [3.0, 9.0, 3.0]])
LOAD_S = 30.0
TAIL_S = 2.0
WARM_UP_S = 5.0
GOAL_PERIOD_S = 0.01
OBSTACLE_EVERY = 5  # goal ticks per obstacle set: 20 Hz
PARAM_EVERY = 50  # goal ticks per parameter poll: every 0.5 s
MOVING_RADIUS = 1.0
ORBIT_PERIOD_S = 4.0
# Heading of goal i: YAW_BASE + i * YAW_STEP (i < 3000 stays below pi).
YAW_BASE, YAW_STEP = -3.0, 0.002
FRESH_SLACK_S = 0.5
# Waits for the end of the run; a node that needs longer has hung (not a speed target) [s].
SETTLE_TIMEOUT_S = 30.0
PARAM_TIMEOUT_S = 15.0
RSS_BOUND_MB = 20.0
TOL = 1e-6

PLAN_QOS = keep_last(200, latched=True)
DIAGNOSTICS_QOS = keep_last(1000)


def moving_centers(t: float) -> np.ndarray:
    """Centres (2, 3) [m] of the two circling spheres at time ``t`` [s] after the start."""
    angle = 2.0 * math.pi * t / ORBIT_PERIOD_S
    return np.array([
        [1.0 + 3.5 * math.cos(angle), 1.0 + 3.5 * math.sin(angle), 6.0 + math.sin(2 * angle)],
        [1.0 - 3.5 * math.cos(angle), 1.0 - 3.5 * math.sin(angle), 3.0],
    ])


def obstacle_set(t: float) -> ObstacleSet:
    """The obstacles the test publishes at time ``t``."""
    return ObstacleSet(list(SCENE.obstacles.items)
                       + [Sphere(center, MOVING_RADIUS) for center in moving_centers(t)])


def obstacle_message(t: float, stamp_ns: int) -> MarkerArray:
    """The complete obstacle set at ``t`` as one MarkerArray, every marker stamped."""
    clear = Marker(action=Marker.DELETEALL)
    scene = conv.obstacle_input_markers(SCENE.obstacles, 'map', stamp_ns, ns='scene')
    moving = [marker('moving', number, Marker.SPHERE, center, [2.0 * MOVING_RADIUS] * 3)
              for number, center in enumerate(moving_centers(t))]
    msg = marker_array(clear, *scene.markers[1:], *moving)
    for item in msg.markers:
        item.header = Header(frame_id='map', stamp=conv.time_from_ns(stamp_ns))
    return msg


def goal_yaw(number: int) -> float:
    return YAW_BASE + number * YAW_STEP


def goal_number(orientation) -> int:
    yaw = conv.quaternion_yaw((orientation.x, orientation.y, orientation.z, orientation.w))
    return int(round((yaw - YAW_BASE) / YAW_STEP))


@dataclass
class Received:
    """One plan as received: receipt time, stamp, points and the goal number of its heading."""

    received: float
    stamp_ns: int
    points: np.ndarray
    goal: int


class Collector:
    """Test-side subscriptions that keep only what the checks need (not whole messages)."""

    def __init__(self, client: RosClient) -> None:
        self._lock = threading.Lock()
        self.plans: List[Received] = []
        # Receipt times of empty plans: the node withdrew the plan in force (a newer set made
        # it collide) before its replacement was ready.
        self.withdrawals: List[float] = []
        self.diagnostics: Dict[int, Dict[str, str]] = {}
        self.discarded = 0
        client.node.create_subscription(Path, f'{NAMESPACE}/plan', self._on_plan, PLAN_QOS)
        client.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                        DIAGNOSTICS_QOS)

    def _on_plan(self, msg: Path) -> None:
        now = time.monotonic()
        if not msg.poses:
            with self._lock:
                self.withdrawals.append(now)
            return
        plan = Received(now, conv.time_to_ns(msg.header.stamp), conv.path_to_points(msg),
                        goal_number(msg.poses[-1].pose.orientation))
        with self._lock:
            self.plans.append(plan)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        values = diagnostics_of(FQN, msg)
        if values is None:
            return
        with self._lock:
            if values.get('event') == 'plan':
                self.diagnostics[conv.time_to_ns(msg.header.stamp)] = values
            elif values.get('event') == 'plan_discarded':
                self.discarded += 1

    def snapshot(self):
        with self._lock:
            return list(self.plans), dict(self.diagnostics), self.discarded

    def withdrawn(self) -> List[float]:
        with self._lock:
            return list(self.withdrawals)


class ParameterPoller:
    """``get_parameters`` round trips, sent without blocking the load loop."""

    def __init__(self, client: RosClient) -> None:
        self._client = AsyncParameterClient(client.node, FQN)
        wait_until(self._client.services_are_ready, 15.0, 'parameter services')
        self._lock = threading.Lock()
        self.sent: List[float] = []
        self.round_trips: Dict[int, float] = {}

    def poll(self) -> None:
        with self._lock:
            number = len(self.sent)
            self.sent.append(time.monotonic())
        future = self._client.get_parameters(['safety_margin'])
        future.add_done_callback(lambda _, number=number: self._done(number))

    def _done(self, number: int) -> None:
        with self._lock:
            self.round_trips[number] = time.monotonic() - self.sent[number]

    def worst(self) -> float:
        """Largest round trip [s]; unanswered polls count with their age."""
        now = time.monotonic()
        with self._lock:
            return max((self.round_trips.get(n, now - sent) for n, sent in enumerate(self.sent)),
                       default=0.0)

    def answered(self) -> int:
        with self._lock:
            return len(self.round_trips)


@dataclass
class PublishedSet:
    stamp_ns: int
    published: float  # monotonic
    obstacles: ObstacleSet


def test_goals_at_100_hz_and_obstacles_at_20_hz_for_30_s() -> None:
    # Preconditions of the scenario: start and goals stay clear of every obstacle set.
    for t in np.arange(0.0, ORBIT_PERIOD_S, 0.01):
        clearance = obstacle_set(t).distance(np.vstack([START, GOALS]))
        assert np.all(clearance > GAMMA + DELTA), (t, clearance)

    domain_id = unique_domain_id()
    process = start_planner(domain_id, namespace=NAMESPACE)
    client = RosClient(domain_id, 'load_client')
    poll_client = RosClient(domain_id, 'load_param_client')
    try:
        node_process = psutil.Process(process.process.pid)
        collector = Collector(client)
        goal_pub = client.publisher(PoseStamped, f'{NAMESPACE}/goal_pose', MONITOR_QOS)
        obstacles_pub = client.publisher(MarkerArray, f'{NAMESPACE}/obstacles', OBSTACLES_QOS)
        poller = ParameterPoller(poll_client)

        # Warm-up plan on the first set, so the node has its map before the load begins.
        sets: List[PublishedSet] = []
        began = time.monotonic()

        def publish_set() -> None:
            now, stamp_ns = time.monotonic(), time.time_ns()
            obstacles_pub.publish(obstacle_message(now - began, stamp_ns))
            sets.append(PublishedSet(stamp_ns, now, obstacle_set(now - began)))

        publish_set()

        def warmed_up() -> bool:
            # Topics are not ordered with respect to each other: the goal may overtake the
            # obstacles, so it is resent until a plan on the first set shows.
            if any(v.get('obstacles_stamp') == str(sets[0].stamp_ns)
                   for v in collector.snapshot()[1].values()):
                return True
            goal_pub.publish(pose_msg(GOALS[0], orientation=conv.yaw_quaternion(goal_yaw(0))))
            return False
        wait_until(warmed_up, 20.0, 'the warm-up plan on the first obstacle set', 0.2)
        load_start_ns = time.time_ns()

        goal_sent: Dict[int, float] = {}
        rss: Dict[str, float] = {}
        tick, number = 0, 0
        started = time.monotonic()
        while True:
            now = time.monotonic()
            elapsed = now - started
            if elapsed >= LOAD_S + TAIL_S:
                break
            if elapsed < LOAD_S:
                number += 1
                goal = GOALS[number % len(GOALS)]
                goal_pub.publish(pose_msg(goal, orientation=conv.yaw_quaternion(
                    goal_yaw(number))))
                goal_sent[number] = time.monotonic()
            if tick % OBSTACLE_EVERY == 0:
                publish_set()
            if tick % PARAM_EVERY == 0:
                poller.poll()
            if 'warm' not in rss and elapsed >= WARM_UP_S:
                rss['warm'] = node_process.memory_info().rss / 2 ** 20
            tick += 1
            time.sleep(max(0.0, started + tick * GOAL_PERIOD_S - time.monotonic()))
        last_goal = number

        def settled() -> bool:
            # The newest plan is clear of the final set and was not withdrawn since.
            plans = collector.snapshot()[0]
            return bool(plans) and not [t for t in collector.withdrawn()
                                        if t > plans[-1].received] and min_clearance(
                plans[-1].points, sets[-1].obstacles, 0.02) >= GAMMA - TOL
        try:
            wait_until(settled, SETTLE_TIMEOUT_S, 'a plan clear of the final obstacle set', 0.1)
        except AssertionError:
            pass  # check 4 reports the plan left in force
        rss['end'] = node_process.memory_info().rss / 2 ** 20
        deadline = time.monotonic() + PARAM_TIMEOUT_S  # unanswered polls fail check 6
        while poller.answered() < len(poller.sent) and time.monotonic() < deadline:
            time.sleep(0.05)
        plans, diagnostics, discarded = collector.snapshot()
        withdrawals = collector.withdrawn()
    finally:
        client.close()
        poll_client.close()
        try:
            assert_clean_exit(process, process.stop())
        finally:
            process.kill()

    _check(plans, diagnostics, discarded, sets, goal_sent, last_goal, load_start_ns, poller,
           rss, withdrawals)


def _check(plans: List[Received], diagnostics: Dict[int, Dict[str, str]], discarded: int,
           sets: List[PublishedSet], goal_sent: Dict[int, float], last_goal: int,
           load_start_ns: int, poller: ParameterPoller, rss: Dict[str, float],
           withdrawals: List[float]) -> None:
    """Checks 1-7 of the module docstring; prints the figures first. A plan is in force
    until the next plan or an empty one (a withdrawal) arrives."""
    plans = [plan for plan in plans if plan.stamp_ns >= load_start_ns]
    events = {stamp: values for stamp, values in diagnostics.items() if stamp >= load_start_ns}
    by_stamp = {published.stamp_ns: index for index, published in enumerate(sets)}
    first_plan: Dict[int, Received] = {}
    for plan in plans:
        first_plan.setdefault(plan.goal, plan)
    latencies = sorted(plan.received - goal_sent[goal] for goal, plan in first_plan.items()
                       if goal in goal_sent)
    obstacle_replans = sum('obstacles' in v['reason'] for v in events.values())
    failed = [v for v in events.values() if v['status'] != 'ok']

    # Check 4 first, as it also gives figures: which plans were in force while a newer set
    # made them collide, and for how long.
    def clear(plan: Received, index: int) -> bool:
        return min_clearance(plan.points, sets[index].obstacles, 0.02) >= GAMMA - TOL

    publication = [published.published for published in sets]
    problems: List[str] = []
    stale_on_arrival, worst_in_force, oldest_unused_s = 0, 0.0, 0.0
    computed: Dict[int, int] = {}
    checked: Dict[int, int] = {}
    for number, plan in enumerate(plans):
        values = events.get(plan.stamp_ns)
        if values is None:
            problems.append(f'plan {plan.stamp_ns}: no diagnostics received')
            continue
        index = by_stamp.get(int(values['obstacles_stamp']))
        newest = by_stamp.get(int(values['obstacles_checked_stamp']))
        if index is None or newest is None:
            problems.append(f'plan {plan.stamp_ns}: unknown obstacle set {values}')
            continue
        computed[number], checked[number] = index, newest
        started_ns = plan.stamp_ns - int(1e9 * _busy_s(values))
        if index + 1 < len(sets) and sets[index + 1].stamp_ns <= started_ns:
            oldest_unused_s = max(oldest_unused_s, 1e-9 * (started_ns - sets[index + 1].stamp_ns))
        following = plans[number + 1].received if number + 1 < len(plans) else math.inf
        following = min([following] + [t for t in withdrawals if t > plan.received])
        # The set current at arrival, and every set published while the plan was the newest.
        current = int(np.searchsorted(publication, plan.received, side='right')) - 1
        until = int(np.searchsorted(publication, following, side='left'))
        for later in range(max(current, newest + 1), until):
            if clear(plan, later):
                continue
            if later == current:
                stale_on_arrival += 1
            since = max(publication[later], plan.received)
            in_force = following - since
            if math.isinf(in_force):
                problems.append(
                    f'plan {plan.stamp_ns} (on set {index}) collides with set {later} and was '
                    'never replaced')
            else:
                worst_in_force = max(worst_in_force, in_force)
            break

    figures = {
        'goals sent': last_goal,
        'plans done (ok)': sum(v['status'] == 'ok' for v in events.values()),
        'plans received': len(plans),
        'goals planned': len(first_plan),
        'goals coalesced': last_goal - len(first_plan),
        'replans for obstacles': obstacle_replans,
        'plans discarded (collided with a set received while planning)': discarded,
        'plans withdrawn (empty plan before the replacement)': len(withdrawals),
        'obstacle sets published': len(sets),
        'plans invalid on arrival (newer set)': stale_on_arrival,
        'longest invalid plan in force [s]': round(worst_in_force, 3),
        'newest set unused at a plan start, longest [ms]': round(1e3 * oldest_unused_s, 1),
        'goal->plan latency median [ms]': round(1e3 * statistics.median(latencies), 1)
        if latencies else None,
        'goal->plan latency max [ms]': round(1e3 * latencies[-1], 1) if latencies else None,
        'param round trip max [ms]': round(1e3 * poller.worst(), 1),
        'param polls': len(poller.sent),
        'node RSS after warm-up [MB]': round(rss.get('warm', math.nan), 1),
        'node RSS at the end [MB]': round(rss.get('end', math.nan), 1),
    }
    summary = '\n'.join(f'  {name}: {value}' for name, value in figures.items())
    print(f'\nload test figures:\n{summary}')

    assert plans, f'no plans received\n{summary}'
    assert not failed, f'failed plans: {failed[:3]}\n{summary}'
    # 1. Safety against the set the plan was computed on and the newest one at publication.
    for number, index in computed.items():
        plan = plans[number]
        assert clear(plan, index), f'plan {plan.stamp_ns} collides with its own set {index}'
        assert clear(plan, checked[number]), (
            f'plan {plan.stamp_ns} collides with set {checked[number]}, which the node had '
            'when it published the plan')
        assert np.allclose(plan.points[0], START), plan.points[0]
        assert np.allclose(plan.points[-1], GOALS[plan.goal % len(GOALS)]), plan.goal
    # 2. Never an older set than the previous plan's.
    indices = [computed[number] for number in sorted(computed)]
    assert indices == sorted(indices), f'a plan used an older obstacle set\n{summary}'
    # 3. Freshness.
    for number, index in computed.items():
        values = events[plans[number].stamp_ns]
        started_ns = plans[number].stamp_ns - int(1e9 * (_busy_s(values) + FRESH_SLACK_S))
        known = [i for i, published in enumerate(sets) if published.stamp_ns <= started_ns]
        assert not known or index >= known[-1], (
            f'plan {plans[number].stamp_ns} used set {index} although set {known[-1]} was '
            f'published {FRESH_SLACK_S} s before it started\n{summary}')
        if number - 1 in checked:
            assert index >= checked[number - 1], (
                f'plan {plans[number].stamp_ns} used set {index} although the previous plan '
                f'was checked against set {checked[number - 1]}\n{summary}')
    # 4. Replanning.
    assert not problems, '\n'.join(problems[:10]) + f'\n{summary}'
    # 5. The last goal is planned.
    assert plans[-1].goal == last_goal, f'last plan for goal {plans[-1].goal}\n{summary}'
    assert np.allclose(plans[-1].points[-1], GOALS[last_goal % len(GOALS)])
    # 6. Parameter services.
    assert poller.answered() == len(poller.sent), (
        f'{len(poller.sent) - poller.answered()} parameter requests unanswered\n{summary}')
    # 7. Memory.
    growth = rss['end'] - rss['warm']
    assert growth <= RSS_BOUND_MB, f'RSS grew by {growth:.1f} MB\n{summary}'


def _busy_s(values: Dict[str, str]) -> float:
    """Grid, search and smoothing time of a plan [s]: its stamp minus this is its start."""
    return sum(float(values[key]) for key in
               ('planning_time_s', 'grid_build_time_s', 'smoothing_time_s'))


def test_goal_heading_encodes_the_goal_number() -> None:
    """The goal number survives the quaternion round trip the node makes."""
    for number in (0, 1, 1499, 2999):
        q = np.array(conv.yaw_quaternion(goal_yaw(number)))
        q = q / np.linalg.norm(q)
        msg = pose_msg([0.0, 0.0, 0.0], orientation=q)
        assert goal_number(msg.pose.orientation) == number
