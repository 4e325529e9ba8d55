"""The ROS figures of ``uav-plan bench --ros``, registered as its ``ros`` entry point.

``uav-plan`` is the ROS-free command-line tool: it never imports this package (nor rclpy). setup.py
registers :func:`ros_figures` in the entry-point group ``uav_global_planner.bench``, and
``uav-plan bench --ros`` calls what it finds there. The benchmark itself runs in a child process
(``python -m uav_global_planner_tools.latency_bench --json``), so the rclpy contexts and the
nodes it starts stay out of the process that measured the core.
"""

import json
import subprocess
import sys
from typing import Any, Dict, Sequence, Tuple

from uav_global_planner_tools.latency_bench.report import format_ros_report


def ros_figures(options: Sequence[str] = ()) -> Tuple[Dict[str, Any], str]:
    """Run the ROS benchmark with ``options`` (its arguments, e.g. ``['--goals', '20']``);
    return its JSON document (:func:`~uav_global_planner_tools.latency_bench.measure.run`) and
    the same as text tables. A failed run (ROS missing, the node not answering) raises
    RuntimeError with the benchmark's output, as :func:`uav_global_planner.cli.bench.
    measure_ros` promises.
    """
    run = subprocess.run([sys.executable, '-m', 'uav_global_planner_tools.latency_bench',
                          '--json', *options], capture_output=True, text=True, check=False)
    try:
        figures = json.loads(run.stdout)
    except ValueError:
        raise RuntimeError(f'ROS benchmark failed (exit code {run.returncode}):\n'
                           f'{run.stderr.strip()}') from None
    return figures, format_ros_report(figures)
