"""Prints the figures of the closed loop planner -> setpoint follower -> simulated vehicle.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_px4_closed_loop.py [--repeats 3]
        [--transports px4 mavlink] [--json]

Each flight (:func:`uav_global_planner_tools.px4_sim.closed_loop.fly_closed_loop`): four
processes in a ROS domain of their own (``scene_publisher`` with town400, ``planner_node``,
``setpoint_follower``, the simulated vehicle: RotorPy with PX4 SIH's quadrotor, 125 Hz, real
time), a goal 27 m down town400's streets, a 1 m box dropped on the route 10 m ahead of the
vehicle once it has flown 6 m, in still air. Per flight:

- flown body clearance: least distance from the vehicle's true positions (every physics
  step) to the buildings and the box, minus its radius (0.41 m) [m]; target >= gamma (0.5 m);
- time to goal: from the goal's publication to the vehicle at rest within 0.5 m of it [s]
  (includes the planner waiting for town400's map and the hold and replan);
- withdrawal latency: box published -> the planner's ``plan_withdrawn`` diagnostics here [ms];
- hold latency seen by the vehicle: box published -> the first hold setpoint (zero velocity,
  position held) the vehicle receives [ms], over the whole chain (planner, follower, transport);
- odometry rate: the vehicle's steps per second of wall-clock time during the flight [Hz].

Figures only: nothing here asserts.
"""

import argparse
import json
import math
import sys
from typing import Dict, List

import numpy as np

from uav_global_planner_tools.px4_sim.closed_loop import ClosedLoopSettings, fly_closed_loop


def _row(transport: str, run: int, report) -> Dict[str, object]:
    return {'transport': transport, 'run': run, 'reached': report.reached_goal,
            'clearance_m': report.min_body_clearance_m, 'gamma_m': report.gamma,
            'time_to_goal_s': report.time_to_goal_s,
            'withdrawal_ms': report.withdrawal_latency_s * 1e3,
            'hold_at_vehicle_ms': report.hold_latency_s * 1e3,
            'odometry_hz': report.odometry_rate_hz, 'notes': report.notes,
            'phases_s': report.phases}


def main(argv: List[str] = None) -> int:
    """Fly, print a table (or JSON); exit status 0."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--repeats', type=int, default=2, help='flights per transport')
    parser.add_argument('--transports', nargs='+', default=['px4', 'mavlink'],
                        choices=['px4', 'mavlink'])
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    options = parser.parse_args(argv)
    rows = []
    for transport in options.transports:
        for run in range(options.repeats):
            report = fly_closed_loop(ClosedLoopSettings(transport=transport))
            rows.append(_row(transport, run, report))
            if not options.json:
                print(report.summary(), flush=True)
                for note in report.notes:
                    print(f'  note: {note}', flush=True)
    if options.json:
        print(json.dumps(rows, indent=2, default=float))
        return 0
    print()
    print('closed loop, town400, box dropped on the route, still air (medians; worst clearance)')
    print(f'{"transport":<10}{"flights":>8}{"reached":>8}{"clear. min":>11}{"gamma":>7}'
          f'{"to goal s":>10}{"withdraw ms":>12}{"hold@veh ms":>12}{"odom Hz":>9}')
    for transport in options.transports:
        mine = [r for r in rows if r['transport'] == transport]

        def median(key: str) -> float:
            values = [float(r[key]) for r in mine if math.isfinite(float(r[key]))]
            return float(np.median(values)) if values else math.nan

        clearances = [float(r['clearance_m']) for r in mine
                      if math.isfinite(float(r['clearance_m']))]
        print(f'{transport:<10}{len(mine):>8}{sum(bool(r["reached"]) for r in mine):>8}'
              f'{min(clearances) if clearances else math.nan:>11.3f}'
              f'{float(mine[0]["gamma_m"]):>7.2f}{median("time_to_goal_s"):>10.1f}'
              f'{median("withdrawal_ms"):>12.0f}{median("hold_at_vehicle_ms"):>12.0f}'
              f'{median("odometry_hz"):>9.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
