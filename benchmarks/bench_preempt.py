"""Prints how fast a newer goal preempts a long plan of planner_node, over real topics.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_preempt.py [--rounds N] [--json]

A planner_node process plans on a 6.1 M-node grid (delta 0.1 m, Dijkstra: multi-second
searches). Each round sends a far goal, waits until the node reports that the plan is running
(``event: progress`` on /diagnostics), then sends a near goal and measures, on the client's
clock, the time until the node reports the long plan cancelled (``event: plan_cancelled``) and
until the near goal's plan arrives. Both include the DDS round trip. Figures only.
"""

import argparse
import json
from pathlib import Path
import sys
import tempfile
import threading
import time
from typing import Dict, List, Optional

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
import numpy as np

from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode
from uav_global_planner.ros.qos import COMMAND_QOS, MONITOR_QOS
from uav_global_planner_tools.domains import choose_domain_id
from uav_global_planner_tools.processes import (NodeProcess, NodeProcessError, planner_command,
                                                ros_environment)

REPO = Path(__file__).resolve().parents[1]
NAMESPACE = '/preempt_bench'
FAR, NEAR = (9.0, 9.0, 14.0), (-2.0, -7.0, 1.0)


class _Diagnostics:
    """Key values of the planner's /diagnostics entries, with their arrival time [s]."""

    def __init__(self) -> None:
        self.entries: List[Dict[str, str]] = []
        self.changed = threading.Condition()

    def __call__(self, msg: DiagnosticArray) -> None:
        arrived = time.monotonic()
        for status in msg.status:
            if status.name.startswith(NAMESPACE):
                values = {kv.key: kv.value for kv in status.values}
                values['_arrived'] = str(arrived)
                with self.changed:
                    self.entries.append(values)
                    self.changed.notify_all()

    def wait(self, after: int, event: str, timeout_s: float) -> Dict[str, str]:
        deadline = time.monotonic() + timeout_s
        with self.changed:
            while True:
                for values in self.entries[after:]:
                    if values.get('event') == event:
                        return values
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f'no {event} diagnostics within {timeout_s} s')
                self.changed.wait(left)


def _start_node(domain_id: int, log_dir: str) -> NodeProcess:
    node = NodeProcess(
        planner_command(namespace=NAMESPACE, params_file=REPO / 'config' / 'planner.yaml',
                        parameters={'resolution': 0.1, 'algorithm': 'dijkstra',
                                    'max_planning_time': 60.0,
                                    # Open air: no map source is published.
                                    'plan_without_map': True}),
        ros_environment(domain_id, Path(log_dir)))
    try:
        node.wait_ready(120.0)
    except NodeProcessError:
        node.kill()
        raise
    return node


def measure(rounds: int, domain_id: int) -> Dict[str, Optional[float]]:
    """Cancel and replacement latencies [ms] over ``rounds`` preemptions (median, max)."""
    with tempfile.TemporaryDirectory() as log_dir:
        process = _start_node(domain_id, log_dir)
        client = BackgroundNode('preempt_bench_client', domain_id)
        try:
            diagnostics = _Diagnostics()
            client.node.create_subscription(DiagnosticArray, '/diagnostics', diagnostics,
                                            MONITOR_QOS)
            goals = client.node.create_publisher(PoseStamped, f'{NAMESPACE}/goal_pose',
                                                 COMMAND_QOS)
            deadline = time.monotonic() + 20.0
            while goals.get_subscription_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            cancel_ms, replace_ms = [], []
            for _ in range(rounds):
                mark = len(diagnostics.entries)
                goals.publish(conv.pose_stamped(FAR, 'map', 0))
                diagnostics.wait(mark, 'progress', 30.0)
                mark = len(diagnostics.entries)
                sent = time.monotonic()
                goals.publish(conv.pose_stamped(NEAR, 'map', 0))
                cancelled = diagnostics.wait(mark, 'plan_cancelled', 30.0)
                planned = diagnostics.wait(mark, 'plan', 30.0)
                cancel_ms.append(1e3 * (float(cancelled['_arrived']) - sent))
                replace_ms.append(1e3 * (float(planned['_arrived']) - sent))
        finally:
            client.close()
            process.stop()
    return {'rounds': rounds,
            'cancel_median_ms': float(np.median(cancel_ms)), 'cancel_max_ms': max(cancel_ms),
            'replaced_median_ms': float(np.median(replace_ms)),
            'replaced_max_ms': max(replace_ms)}


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rounds', type=int, default=10)
    parser.add_argument('--domain-id', type=int)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args(argv)
    figures = measure(args.rounds, choose_domain_id(args.domain_id))
    if args.json:
        print(json.dumps(figures))
    else:
        print(f'newer goal -> long plan cancelled: median {figures["cancel_median_ms"]:.1f} ms, '
              f'max {figures["cancel_max_ms"]:.1f} ms (target <= 50 ms)')
        print(f'newer goal -> its plan: median {figures["replaced_median_ms"]:.1f} ms, '
              f'max {figures["replaced_max_ms"]:.1f} ms ({figures["rounds"]} rounds)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
