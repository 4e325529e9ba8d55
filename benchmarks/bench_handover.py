"""Prints how well a replan in flight continues the plan in force (the handover).

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_handover.py

A plan is flown at the '5 m/s' limits (max_speed_horizontal 5, max_accel_horizontal 3) across a
shipped scene; at takeover times spread over the flight a new goal is planned from the old
reference's state there (position, velocity, acceleration, and the old reference ahead, as the
node hands them over), and the jump between the old reference and the new one at the switch
is measured: position, velocity and acceleration, against the tolerances 1 cm, 0.05 m/s and
0.2 m/s^2. New goals: the old goal itself (the same route again), one off to the side, and one
behind (a turn of more than 90 degrees). The longest crawl is the longest time a new reference
moves slower than 1 cm/s before its end (a turn back at a near-cusp of its curve takes a second
or so; minutes would be a crawl). Figures only: nothing here asserts.
"""

import argparse
from dataclasses import replace
from typing import List, Sequence, Tuple

import numpy as np

from uav_global_planner.core.config import validate_config
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.path.timing import longest_crawl
from uav_global_planner.core.planner import Planner

#: The handover tolerances [m], [m/s], [m/s^2].
TOLERANCES = (0.01, 0.05, 0.2)

#: Slower than this a reference crawls [m/s]; checked every CRAWL_STEP_S [s].
CRAWL_SPEED = 0.01
CRAWL_STEP_S = 0.01

#: First flight (start, goal) and the new goals asked in flight, per scene [m].
CASES = {
    'paper_medium': (([-8.0, -8.0, 3.0], [8.0, 8.0, 3.0]),
                     {'same goal': [8.0, 8.0, 3.0], 'to the side': [6.0, 9.0, 4.0],
                      'behind': [8.0, -6.0, 5.0]}),
    'town400': (None, {'same goal': None, 'to the side': [90.0, 20.0, 12.0],
                       'behind': [-95.0, 0.0, 30.0]}),
}


def jumps(planner: Planner, first, goal: Sequence[float],
          count: int) -> List[Tuple[float, float, float, float, float]]:
    """(takeover time, |dp|, |dv|, |da|, longest crawl [s]) at ``count`` takeover times of the
    first plan."""
    trajectory = first.trajectory
    out = []
    for fraction in np.linspace(0.1, 0.8, count):
        at = fraction * trajectory.duration_s
        state = trajectory.state_at(at)
        ahead = trajectory.state_at(at + np.arange(1, 301) * 0.05).position
        result = planner.plan(state.position[0], goal, start_velocity=state.velocity[0],
                              start_acceleration=state.acceleration[0], start_path=ahead)
        if not result.ok:
            out.append((at, np.nan, np.nan, np.nan, np.nan))
            continue
        replanned = result.trajectory
        assert replanned is not None  # an ok result carries its trajectory
        new = replanned.state_at(0.0)
        out.append((at, float(np.linalg.norm(new.position[0] - state.position[0])),
                    float(np.linalg.norm(new.velocity[0] - state.velocity[0])),
                    float(np.linalg.norm(new.acceleration[0] - state.acceleration[0])),
                    longest_crawl(replanned, CRAWL_SPEED, CRAWL_STEP_S)))
    return out


def main() -> None:
    """Print the worst jump per scene and new goal, and how many handovers kept the
    tolerances."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--count', type=int, default=12, help='takeover times per case')
    args = parser.parse_args()
    print('scene         new goal      speed at takeover [m/s]  worst |dp| [m]  |dv| [m/s]  '
          '|da| [m/s^2]  within tolerances  longest crawl [s]')
    for name, (leg, goals) in CASES.items():
        scene = load_scene(find_scene(name))
        config = validate_config(replace(scene.config, max_speed_horizontal=5.0,
                                         max_accel_horizontal=3.0, max_planning_time=0.0))
        planner = Planner(config, scene.obstacles)
        start, goal = (scene.start, scene.goal) if leg is None else leg
        first = planner.plan(start, goal)
        speeds = np.linalg.norm(first.trajectory.state_at(
            np.linspace(0.1, 0.8, args.count) * first.duration_s).velocity, axis=1)
        for label, new_goal in goals.items():
            rows = jumps(planner, first, goal if new_goal is None else new_goal, args.count)
            table = np.array([row[1:4] for row in rows])
            crawl = np.nanmax([row[4] for row in rows])
            kept = int(np.sum(np.all(table <= np.array(TOLERANCES), axis=1)))
            worst = np.nanmax(table, axis=0)
            print(f'{name:13s} {label:12s} {speeds.min():5.2f} - {speeds.max():5.2f}'
                  f'{worst[0]:22.2e} {worst[1]:11.3f} {worst[2]:13.3f} '
                  f'{kept:10d} of {len(rows)} {crawl:17.2f}')


if __name__ == '__main__':
    main()
