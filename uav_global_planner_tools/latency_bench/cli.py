"""The command ``python -m uav_global_planner_tools.latency_bench``: measure, then print.

Exit code 0 when every goal got its plan, 1 otherwise or when the node failed, 2 for bad
arguments.
"""

import argparse
import json
import sys
from typing import List, Optional

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import find_scene
from uav_global_planner_tools.domains import choose_domain_id
from uav_global_planner_tools.latency_bench.client import BenchError
from uav_global_planner_tools.latency_bench.measure import run
from uav_global_planner_tools.latency_bench.report import format_ros_report
from uav_global_planner_tools.processes import localhost_discovery

#: Scenes whose latency is measured when none are named.
DEFAULT_SCENES = ('paper_medium', 'paper_high')
#: Scene whose peak memory is measured by default.
DEFAULT_MEMORY_SCENE = 'dense60_fine'
#: Goals per latency scene by default.
DEFAULT_GOALS = 50


def _parse(argv: Optional[List[str]]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='python -m uav_global_planner_tools.latency_bench',
        description='ROS-side figures of planner_node: goal-to-plan latency, start-up time '
                    'and peak memory.')
    parser.add_argument('scenes', nargs='*', default=list(DEFAULT_SCENES),
                        help='scenes whose latency is measured (default: '
                             f'{" ".join(DEFAULT_SCENES)})')
    parser.add_argument('--goals', type=int, default=DEFAULT_GOALS,
                        help=f'measured goals per scene (default {DEFAULT_GOALS})')
    parser.add_argument('--memory-scene', default=DEFAULT_MEMORY_SCENE,
                        help=f'scene of the peak-memory figure (default {DEFAULT_MEMORY_SCENE})')
    parser.add_argument('--no-memory', action='store_true', help='skip the memory figure')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS domain (default: one that no process on this machine uses, '
                             'never $ROS_DOMAIN_ID)')
    parser.add_argument('--timeout', type=float, default=180.0, metavar='S',
                        help='give up after S seconds without an answer (default 180; the '
                             'first run compiles the search kernels)')
    parser.add_argument('--json', action='store_true', help='print one JSON document')
    return parser.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point: measure, then print a table (or JSON with ``--json``); the exit code."""
    options = _parse(argv)
    if options.goals < 1:
        print('latency_bench: --goals must be >= 1', file=sys.stderr)
        return 2
    try:
        domain_id = choose_domain_id(options.domain_id)
    except RuntimeError as error:
        print(f'latency_bench: {error}', file=sys.stderr)
        return 1
    localhost_discovery()  # for the client in this process
    memory_scene = None if options.no_memory else options.memory_scene
    try:
        for name in [*options.scenes, *([memory_scene] if memory_scene else [])]:
            find_scene(name)
        figures = run(options.scenes, options.goals, memory_scene, domain_id, options.timeout)
    except InvalidInputError as error:
        print(f'latency_bench: {error}', file=sys.stderr)
        return 2
    except BenchError as error:
        print(f'latency_bench: {error}', file=sys.stderr)
        return 1
    if options.json:
        print(json.dumps(figures))
    else:
        print(format_ros_report(figures))
    complete = all(s['plans_received'] == s['goals'] for s in figures['scenes'])
    if figures['memory'] is not None:
        complete = complete and all(r['status'] == 'ok' for r in figures['memory']['algorithms'])
    return 0 if complete else 1
