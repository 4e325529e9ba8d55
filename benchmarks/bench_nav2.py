"""Prints the round-trip figures of planner_node's Nav2 interfaces beside its topic latency.

Run inside the project's environment (nav2_msgs built by scripts/venv.sh)::

    source scripts/venv.sh && python benchmarks/bench_nav2.py [--goals N] [--json] [scene ...]

For each scene (default: the paper scenes) one ``planner_node`` is started with the scene's
workspace and obstacles, as ``benchmarks/bench_ros.py`` does, and one client process talks to it:

topic
    ``goal_pose`` published until the ``plan`` ending at that goal has been deserialised (the
    latency of ``bench_ros.py``).
action
    ``ComputePathToPose`` with rclpy's ``ActionClient``: from just before ``send_goal_async``
    until the result (with its path) has arrived; the same two goals alternate as for the topic.
5 legs
    One ``ComputePathThroughPoses`` through four via-points to the goal (one continuous, timed
    flight) beside five ``ComputePathToPose`` goals planned leg after leg (each from the end of
    the previous one, ``use_start``), which make five flights that stop at every via-point:
    round trip, path length and flight time of each.

Figures only: nothing here asserts a speed. Exit code 0 when every request succeeded.
"""

import argparse
import json
import os
from pathlib import Path
import sys
import tempfile
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
from rclpy.action import ActionClient

from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.core.result import polyline_length
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.nav2_client import ExecutorCalls, round_trip
from uav_global_planner_tools.domains import choose_domain_id
from uav_global_planner_tools.latency_bench.measure import summary as _summary
from uav_global_planner_tools.latency_bench.session import BenchError, Session as _Session

try:
    from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
except ImportError as error:
    sys.exit(f'bench_nav2: nav2_msgs is not importable ({error}); source scripts/venv.sh, '
             'which builds it')

DEFAULT_SCENES = ('paper_medium', 'paper_high')
DEFAULT_GOALS = 30
DEFAULT_LEG_RUNS = 10
_SUCCEEDED = 4  # action_msgs/GoalStatus.STATUS_SUCCEEDED


def via_points(scene: Scene, count: int = 4) -> np.ndarray:
    """``count`` free via-points spread over the workspace (clearance >= gamma + 2 delta), in a
    fixed order; deterministic for a scene."""
    config = scene.config
    lo = np.asarray(config.bounds_min, dtype=float)
    hi = np.asarray(config.bounds_max, dtype=float)
    fractions = [(0.2, 0.2, 0.3), (0.2, 0.8, 0.5), (0.5, 0.85, 0.7), (0.8, 0.3, 0.6),
                 (0.3, 0.5, 0.4), (0.7, 0.7, 0.3), (0.5, 0.2, 0.8), (0.85, 0.85, 0.5),
                 (0.15, 0.5, 0.7), (0.6, 0.5, 0.2)]
    candidates = lo + np.array(fractions) * (hi - lo)
    free = scene.obstacles.distance(candidates) >= config.safety_margin + 2 * config.resolution
    chosen = candidates[free][:count]
    if len(chosen) < count:
        raise BenchError(f'fewer than {count} free via-points in scene {scene.name!r}')
    return chosen


def _pose(point: Sequence[float], frame: str):
    return conv.pose_stamped(point, frame, 0)


def _flight(response) -> Dict[str, float]:
    """Length [m] and flight time [s] of a result path."""
    path = response.result.path
    points = conv.path_to_points(path)
    if len(points) < 2:
        return {'length_m': float('nan'), 'flight_s': float('nan')}
    stamps = [conv.time_to_ns(pose.header.stamp) for pose in path.poses]
    return {'length_m': polyline_length(points), 'flight_s': (stamps[-1] - stamps[0]) * 1e-9}


def measure(scene_name: str, goals: int, leg_runs: int, domain_id: int, log_dir: Path,
            timeout_s: float, index: int) -> Dict[str, Any]:
    scene = load_scene(find_scene(scene_name))
    session = _Session(scene, domain_id, f'/uav_nav2_bench_{os.getpid()}_{index}', log_dir,
                       timeout_s)
    failures: List[str] = []
    try:
        startup = session.start()
        topic = []
        for _ in range(goals):
            outcome = session.send_goal()
            if outcome['latency_s'] is None:
                failures.append(f'topic goal: {outcome["status"]}')
            else:
                topic.append(outcome['latency_s'])
        node = session.client.node
        to_pose = ActionClient(node, ComputePathToPose, 'compute_path_to_pose')
        through = ActionClient(node, ComputePathThroughPoses, 'compute_path_through_poses')
        if not (to_pose.wait_for_server(timeout_sec=timeout_s)
                and through.wait_for_server(timeout_sec=timeout_s)):
            raise BenchError('the action servers did not come up')
        frame = scene.frame_id
        calls = ExecutorCalls(node)

        def _round_trip(client, goal, timeout):
            seconds, response = round_trip(calls, client, goal, timeout)
            if response is None:
                raise BenchError('goal rejected')
            return seconds, response
        # Warm-up of the action path (first goals load code paths on both sides).
        for kind in range(4):
            _round_trip(to_pose, ComputePathToPose.Goal(
                goal=_pose(session.goals[kind % 2], frame)), timeout_s)
        action = []
        for number in range(goals):
            goal = ComputePathToPose.Goal(goal=_pose(session.goals[number % 2], frame))
            seconds, response = _round_trip(to_pose, goal, timeout_s)
            if response.status != _SUCCEEDED:
                failures.append(f'action goal: {response.result.error_msg}')
            action.append(seconds)

        stops = np.vstack([via_points(scene), np.asarray(scene.goal, dtype=float)[None, :]])
        start = np.asarray(scene.start, dtype=float)
        one, five = [], []
        one_flight: Dict[str, float] = {}
        five_flight = {'length_m': 0.0, 'flight_s': 0.0}
        for run in range(leg_runs):
            goal = ComputePathThroughPoses.Goal(goals=[_pose(p, frame) for p in stops],
                                                start=_pose(start, frame), use_start=True)
            seconds, response = _round_trip(through, goal, timeout_s)
            if response.status != _SUCCEEDED:
                failures.append(f'5-leg goal: {response.result.error_msg}')
            one.append(seconds)
            one_flight = _flight(response)
            total = 0.0
            leg_start = start
            flights = {'length_m': 0.0, 'flight_s': 0.0}
            for stop in stops:
                goal = ComputePathToPose.Goal(goal=_pose(stop, frame),
                                              start=_pose(leg_start, frame), use_start=True)
                seconds, response = _round_trip(to_pose, goal, timeout_s)
                if response.status != _SUCCEEDED:
                    failures.append(f'single leg: {response.result.error_msg}')
                total += seconds
                for key, value in _flight(response).items():
                    flights[key] += value
                leg_start = stop
            five.append(total)
            five_flight = flights
    finally:
        code = session.close()
    return {
        'scene': scene.name, 'startup_s': startup, 'goals': goals,
        'topic_latency': _summary(topic), 'action_round_trip': _summary(action),
        'five_legs': {'runs': leg_runs, 'via_points': stops[:-1].tolist(),
                      'through_poses': {'round_trip': _summary(one), **one_flight},
                      'five_single_plans': {'round_trip': _summary(five), **five_flight}},
        'failures': failures, 'exit_code': code,
    }


def _ms(value: Optional[float]) -> str:
    return '-' if value is None else f'{value:.1f}'


def format_report(results: List[Dict[str, Any]]) -> str:
    lines = ['| scene | topic median [ms] | topic p90 [ms] | action median [ms] | '
             'action p90 [ms] |', '|---|---|---|---|---|']
    for r in results:
        lines.append(f'| {r["scene"]} | {_ms(r["topic_latency"]["median_ms"])} | '
                     f'{_ms(r["topic_latency"]["p90_ms"])} | '
                     f'{_ms(r["action_round_trip"]["median_ms"])} | '
                     f'{_ms(r["action_round_trip"]["p90_ms"])} |')
    lines += ['', '| scene | request | round trip median [ms] | p90 [ms] | length [m] | '
              'flight [s] |', '|---|---|---|---|---|---|']
    for r in results:
        legs = r['five_legs']
        for label, key in (('1 x ComputePathThroughPoses (5 legs)', 'through_poses'),
                           ('5 x ComputePathToPose', 'five_single_plans')):
            part = legs[key]
            lines.append(f'| {r["scene"]} | {label} | {_ms(part["round_trip"]["median_ms"])} | '
                         f'{_ms(part["round_trip"]["p90_ms"])} | {part["length_m"]:.2f} | '
                         f'{part["flight_s"]:.2f} |')
    for r in results:
        if r['failures']:
            lines.append(f'{r["scene"]}: failures: {sorted(set(r["failures"]))}')
    return '\n'.join(lines)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('scenes', nargs='*', default=list(DEFAULT_SCENES))
    parser.add_argument('--goals', type=int, default=DEFAULT_GOALS,
                        help='measured goals per scene for the topic and the action')
    parser.add_argument('--leg-runs', type=int, default=DEFAULT_LEG_RUNS,
                        help='repetitions of the 5-leg comparison')
    parser.add_argument('--domain-id', type=int, default=None)
    parser.add_argument('--timeout', type=float, default=120.0, help='per request [s]')
    parser.add_argument('--json', action='store_true', help='one JSON object')
    args = parser.parse_args(argv)
    if args.goals < 1 or args.leg_runs < 1:
        parser.error('--goals and --leg-runs must be >= 1')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    domain_id = choose_domain_id(args.domain_id)
    results = []
    with tempfile.TemporaryDirectory(prefix='uav_nav2_bench_') as log_dir:
        for index, scene in enumerate(args.scenes):
            try:
                results.append(measure(scene, args.goals, args.leg_runs, domain_id,
                                       Path(log_dir), args.timeout, index))
            except BenchError as error:
                print(f'bench_nav2: {scene}: {error}', file=sys.stderr)
                return 1
    if args.json:
        print(json.dumps({'results': results, 'cpu_count': os.cpu_count()}, indent=1))
    else:
        print(format_report(results))
    return 0 if all(not r['failures'] for r in results) else 1


if __name__ == '__main__':
    sys.exit(main())
