"""``python -m uav_global_planner_tools.latency_bench``: see :mod:`.cli`."""

import sys

from uav_global_planner_tools.latency_bench.cli import main

if __name__ == '__main__':
    sys.exit(main())
