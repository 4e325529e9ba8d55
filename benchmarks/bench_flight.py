"""Flies the planner's trajectories in RotorPy and prints what the vehicle's body keeps.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_flight.py [--scenes paper_medium town400]
        [--vehicles hummingbird px4_sih] [--limits default 8mps] [--winds still dryden4]
        [--margin-still 0.1] [--margin-wind 0.6] [--seed 0] [--json]

Every combination of the chosen legs, vehicles, limits and winds is planned with the core
planner and flown once with RotorPy's SE3Control at 500 Hz
(:func:`uav_global_planner_tools.flight.fly.fly`). Legs: the shipped scene's own start and goal,
except town400, where a 27 m stretch of its crossing (three passes within 0.53 m of buildings)
is flown. Limits: the scene's (``default``), or ``8mps`` (max_speed_horizontal 8,
max_accel_horizontal 4, max_speed_vertical 3, max_accel_vertical 2). Winds: still air, or
Dryden turbulence of 4 m/s horizontal RMS (``dryden4``: MIL-F-8785C low altitude at the leg's
mean height, field speed 5 m/s; :mod:`uav_global_planner_tools.flight.wind`). Each plan is made
with the vehicle's radius (arms and rotors) as ``vehicle_radius`` and the wind's tracking
margin (``--margin-still``, ``--margin-wind``) as ``tracking_margin``
(:mod:`uav_global_planner_tools.flight.planning`).

Columns: gamma [m]; the smallest body clearance flown (centre distance minus the vehicle's
radius) and that of the reference itself [m]; tracking error max / RMS [m]; the largest
distance to the reference's path [m] (the error without the lag along it); time with a rotor
command at a speed limit [s]; peak tilt [deg] and thrust-to-weight; flown / planned time [s]
(flown: the duration plus the vehicle's delay in coming within 1 m of the goal); the
reference's peak speed [m/s] and acceleration [m/s^2]. Then error models fitted per vehicle,
wind and error (:mod:`uav_global_planner_tools.flight.error_model`). A flight takes about 1.5
s per second flown on a 2-core machine (RotorPy integrates each 2 ms step with scipy's RK45),
the whole matrix about ten minutes. Figures only: nothing here asserts.
"""

import argparse
from dataclasses import dataclass
import json
import math
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.cli.report import format_table
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.core.planner import Planner
from uav_global_planner_tools.flight.error_model import fit_tracking_error
from uav_global_planner_tools.flight.fly import FlightReport, fly
from uav_global_planner_tools.flight.planning import config_for_vehicle
from uav_global_planner_tools.flight.reference import reference_at
from uav_global_planner_tools.flight.vehicles import Vehicle, VEHICLES
from uav_global_planner_tools.flight.wind import DrydenTurbulence

#: Legs: scene name -> (start, goal) [m], None for the scene's own.
LEGS: Dict[str, Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]]] = {
    'paper_medium': None,
    'paper_high': None,
    'wall_gap': None,
    'town400': ((-81.8, -79.0, 2.0), (-62.7, -60.9, 2.0)),
}

LIMITS: Dict[str, Dict[str, float]] = {
    'default': {},
    '8mps': {'max_speed_horizontal': 8.0, 'max_accel_horizontal': 4.0,
             'max_speed_vertical': 3.0, 'max_accel_vertical': 2.0},
}

WINDS = ('still', 'dryden4')

#: Distance to the goal that counts as arrived, for the flown time [m]: gusts of 4 m/s RMS
#: keep the vehicles tens of centimetres off the goal.
ARRIVAL_RADIUS = 1.0


@dataclass(frozen=True)
class Row:
    """One flight of the matrix."""

    scene: str
    vehicle: str
    limits: str
    wind: str
    gamma: float
    report: FlightReport
    peak_speed: float
    peak_accel: float


def plan_config(scene: Scene, vehicle: Vehicle, limits: str, margin: float) -> PlannerConfig:
    """The scene's settings with the limits, the vehicle's radius and the tracking margin."""
    config = scene.config.with_changes(max_planning_time=0.0, **LIMITS[limits])
    return config_for_vehicle(config, vehicle.radius_m, margin)


def fly_matrix(scenes: Sequence[str], vehicles: Sequence[str], limits: Sequence[str],
               winds: Sequence[str], margins: Dict[str, float], seed: int) -> List[Row]:
    """Plan and fly every combination; prints one line per flight as it goes.

    Each wind gets its own plan: the tracking margin it is planned with is ``margins[wind]``.
    """
    rows = []
    for name in scenes:
        scene = load_scene(find_scene(name))
        leg = LEGS.get(name)
        start, goal = (scene.start, scene.goal) if leg is None else map(np.array, leg)
        for vehicle_name in vehicles:
            vehicle = VEHICLES[vehicle_name]()
            for limit in limits:
                for wind_name in winds:
                    config = plan_config(scene, vehicle, limit, margins[wind_name])
                    result = Planner(config, scene.obstacles).plan(start, goal)
                    if not result.ok:
                        print(f'{name} {vehicle_name} {limit} {wind_name}: no plan '
                              f'({result.message})')
                        continue
                    times = np.linspace(0.0, result.duration_s, 2000)
                    ref = reference_at(result, times)
                    peak_speed = float(np.max(np.linalg.norm(ref.velocity, axis=1)))
                    peak_accel = float(np.max(np.linalg.norm(ref.acceleration, axis=1)))
                    altitude = float(np.mean(ref.position[:, 2]))
                    wind = (DrydenTurbulence(4.0, altitude_m=max(altitude, 0.1))
                            if wind_name == 'dryden4' else None)
                    started = time.perf_counter()
                    report = fly(result, scene.obstacles, vehicle, wind=wind, seed=seed,
                                 arrival_radius_m=ARRIVAL_RADIUS)
                    row = Row(name, vehicle_name, limit, wind_name,
                              float(scene.config.safety_margin), report, peak_speed, peak_accel)
                    rows.append(row)
                    print(f'flown {name} {vehicle_name} {limit} {wind_name} (tracking margin '
                          f'{margins[wind_name]} m): {report.times[-1]:.1f} s of flight in '
                          f'{time.perf_counter() - started:.0f} s', flush=True)
    return rows


def _cell(value: float, digits: int = 3) -> str:
    return '-' if not math.isfinite(value) else f'{value:.{digits}f}'


def table(rows: Sequence[Row]) -> str:
    """The flights as a text table."""
    return format_table(
        ['scene', 'vehicle', 'limits', 'wind', 'gamma', 'body clr', 'ref body clr',
         'track max/RMS', 'path dev', 'sat [s]', 'tilt', 'T/W', 'flown/planned [s]', 'v pk',
         'a pk'],
        [[r.scene, r.vehicle, r.limits, r.wind, f'{r.gamma:.2f}',
          _cell(r.report.min_body_clearance_m), _cell(r.report.reference_body_clearance_m),
          f'{r.report.tracking_error_max_m:.3f}/{r.report.tracking_error_rms_m:.3f}',
          f'{r.report.path_deviation_max_m:.3f}',
          f'{r.report.saturation_time_s:.3f}', f'{r.report.peak_tilt_deg:.1f}',
          f'{r.report.peak_thrust_to_weight:.2f}',
          f'{_cell(r.report.flown_time_s, 2)}/{r.report.planned_time_s:.2f}'
          + ('' if r.report.completed else ' LOST'),
          f'{r.peak_speed:.2f}', f'{r.peak_accel:.2f}'] for r in rows])


def models(rows: Sequence[Row]) -> List[dict]:
    """Error models per vehicle, wind and error: on speed, and on speed and acceleration."""
    fitted = []
    for vehicle in sorted({r.vehicle for r in rows}):
        for wind in sorted({r.wind for r in rows}):
            reports = [r.report for r in rows if r.vehicle == vehicle and r.wind == wind
                       and r.report.completed]
            if not reports:
                continue
            for quantity in ('errors', 'path_deviation'):
                error = 'tracking' if quantity == 'errors' else 'path deviation'
                entry: Dict[str, Any] = {'vehicle': vehicle, 'wind': wind, 'error': error}
                for terms, with_accel in (('v', False), ('va', True)):
                    model = fit_tracking_error(reports, with_accel=with_accel,
                                               quantity=quantity)
                    entry[terms] = {'e0_m': model.e0_m, 'k_v_s': model.k_v_s,
                                    'k_a_s2': model.k_a_s2,
                                    'bound_offset_m': model.bound_offset_m,
                                    'rms_residual_m': model.rms_residual_m}
                    entry['windows'] = model.windows
                fitted.append(entry)
    return fitted


def model_table(fitted: Sequence[dict]) -> str:
    """The fitted models as a text table."""
    return format_table(
        ['vehicle', 'wind', 'error', 'e0', 'k_v', '+bound', '|', 'e0', 'k_v', 'k_a', '+bound',
         'RMS resid', 'windows'],
        [[m['vehicle'], m['wind'], m['error'], f'{m["v"]["e0_m"]:.3f}',
          f'{m["v"]["k_v_s"]:.3f}', f'{m["v"]["bound_offset_m"]:.3f}', '|',
          f'{m["va"]["e0_m"]:.3f}', f'{m["va"]["k_v_s"]:.3f}', f'{m["va"]["k_a_s2"]:.3f}',
          f'{m["va"]["bound_offset_m"]:.3f}', f'{m["va"]["rms_residual_m"]:.3f}',
          str(m['windows'])] for m in fitted])


def main() -> None:
    """Fly the chosen matrix and print the table and the fitted models."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scenes', nargs='+', default=['paper_medium', 'town400'],
                        choices=sorted(LEGS))
    parser.add_argument('--vehicles', nargs='+', default=sorted(VEHICLES),
                        choices=sorted(VEHICLES))
    parser.add_argument('--limits', nargs='+', default=list(LIMITS), choices=list(LIMITS))
    parser.add_argument('--winds', nargs='+', default=list(WINDS), choices=WINDS)
    parser.add_argument('--margin-still', type=float, default=0.1,
                        help='tracking_margin of the still-air plans [m] (default 0.1: the '
                        'still-air fit of core/path/tracking.py)')
    parser.add_argument('--margin-wind', type=float, default=0.6,
                        help='tracking_margin of the plans flown in turbulence [m] (default '
                        '0.6: the path deviation of the Hummingbird in 4 m/s RMS)')
    parser.add_argument('--seed', type=int, default=0, help='seed of the turbulence')
    parser.add_argument('--json', action='store_true', help='print JSON instead of tables')
    args = parser.parse_args()
    margins = {'still': args.margin_still, 'dryden4': args.margin_wind}
    rows = fly_matrix(args.scenes, args.vehicles, args.limits, args.winds, margins, args.seed)
    fitted = models(rows)
    if args.json:
        print(json.dumps({'flights': [
            {'scene': r.scene, 'vehicle': r.vehicle, 'limits': r.limits, 'wind': r.wind,
             'gamma_m': r.gamma, 'vehicle_radius_m': r.report.vehicle_radius_m,
             'body_clearance_min_m': r.report.min_body_clearance_m,
             'reference_body_clearance_m': r.report.reference_body_clearance_m,
             'tracking_error_max_m': r.report.tracking_error_max_m,
             'tracking_error_rms_m': r.report.tracking_error_rms_m,
             'path_deviation_max_m': r.report.path_deviation_max_m,
             'wind_rms_mps': r.report.wind_rms_mps.tolist(),
             'saturation_s': r.report.saturation_time_s,
             'peak_tilt_deg': r.report.peak_tilt_deg,
             'peak_thrust_to_weight': r.report.peak_thrust_to_weight,
             'flown_time_s': r.report.flown_time_s, 'planned_time_s': r.report.planned_time_s,
             'completed': r.report.completed, 'peak_speed_mps': r.peak_speed,
             'peak_accel_mps2': r.peak_accel} for r in rows],
            'tracking_error_models': fitted}, indent=2))
        return
    print()
    print(table(rows))
    print('\nError models, fitted on 1 s windows (speed [m/s] and accel [m/s^2]: the '
          "reference's largest over the window and 0.5 s before):\n"
          '  max error ~= e0 + k_v * speed  (left)  or  e0 + k_v * speed + k_a * accel  (right); '
          '+bound: added to e0 to cover every window')
    print(model_table(fitted))


if __name__ == '__main__':
    main()
