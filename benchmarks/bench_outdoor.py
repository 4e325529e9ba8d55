"""Prints per-stage times and peak memory of the planner on the outdoor scenes, beside targets.

The benchmark is installed with the tools (:mod:`uav_global_planner_tools.outdoor_bench`, where
its cases and options are described); this script runs it from a source checkout::

    source scripts/venv.sh && python benchmarks/bench_outdoor.py [--only NAME] [--json]

``uav-plan bench --outdoor [CASE ...]`` runs the same, wherever the package is installed.
"""

import sys

from uav_global_planner_tools.outdoor_bench import main

if __name__ == '__main__':
    sys.exit(main())
