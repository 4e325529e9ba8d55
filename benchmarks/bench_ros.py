"""Prints the ROS-side figures of planner_node: goal-to-plan latency, start-up, peak memory.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_ros.py [--goals N] [--json] [scene ...]

A thin wrapper of ``python -m uav_global_planner_tools.latency_bench`` (same options; also part of
``uav-plan bench --ros``). Figures only: no assertion on speed.
"""

import sys

from uav_global_planner_tools.latency_bench.cli import main

if __name__ == '__main__':
    sys.exit(main())
