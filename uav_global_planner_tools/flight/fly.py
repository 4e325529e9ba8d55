"""Fly a planned trajectory in RotorPy and measure what the vehicle's body really keeps.

:func:`fly` drives RotorPy's ``Multirotor`` (rigid body, rotor lag and aerodynamics, RotorPy
3.0.0) with its ``SE3Control`` geometric controller (Lee, Leok and McClamroch) step by step:
every control period (500 Hz by default) the controller reads the true state and the
reference's flat outputs (position, velocity, acceleration, jerk, yaw, yaw rate:
:mod:`uav_global_planner_tools.flight.reference`) and commands rotor speeds, which the vehicle
holds for one period (``Multirotor.step``, as RotorPy's own ``simulate`` loop calls it, with
scipy's RK45 told ``first_step = period``, which spares it an initial step-size estimate).
The vehicle starts at rest and level at the reference's start, its rotors at hover speed, and
flies for the trajectory's duration plus ``hold_s`` at the goal.

Only RotorPy's vehicle and controller modules are imported: ``rotorpy.wind.dryden_winds``
imports torch at import time (see :mod:`uav_global_planner_tools.flight.wind` for the gusts
used instead), and nothing else of RotorPy is needed.

Figures of one flight (:class:`FlightReport`), every control step:

- body clearance: exact distance from the vehicle's centre to the obstacles
  (:meth:`uav_global_planner.core.map.obstacles.ObstacleSet.distance`, uncapped) minus the
  vehicle's radius (arms and rotors). Between two steps (2 ms) the vehicle moves at most
  ``speed * 2 ms`` (16 mm at 8 m/s), so the continuous minimum lies at most half that below
  the sampled one. The ground is not an obstacle.
- tracking error: ``|position - reference position|``, its maximum and RMS; and the path
  deviation, the distance from the vehicle to the nearest point of the reference's path
  whenever it was flown (the 2 ms samples of the reference, at most 16 mm apart at 8 m/s),
  which leaves out the lag along the path: it is what the clearance depends on.
- saturation time: the time during which any rotor command is at or beyond the rotor's
  minimum or maximum speed (RotorPy clips it there).
- peak tilt: largest angle between the body's thrust axis and the vertical.
- flown time: the trajectory's duration plus the vehicle's arrival delay, the time between
  the reference and the vehicle first coming within ``arrival_radius_m`` of the goal (NaN when
  the vehicle never does).
"""

from dataclasses import dataclass
import math
from typing import Any, Optional, Protocol

import numpy as np
from scipy.spatial import cKDTree

from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner_tools.flight.reference import flat_output, reference_at, trajectory_of
from uav_global_planner_tools.flight.vehicles import GRAVITY, Vehicle


class WindProfile(Protocol):
    """RotorPy's wind interface: the wind at a time and position, ENU [m/s]."""

    def update(self, t: float, position: np.ndarray) -> np.ndarray:
        ...


@dataclass(frozen=True, eq=False, kw_only=True)
class FlightReport:
    """What one closed-loop flight did (ENU planning frame).

    Attributes
    ----------
    vehicle : str
        Name of the vehicle.
    wind : str
        The wind it flew in (``still`` or a description).
    vehicle_radius_m : float
        Radius of the body with its rotors [m].
    completed : bool
        False when the flight was stopped: non-finite state, or more than ``divergence_m``
        from the reference.
    planned_time_s, flown_time_s : float
        Duration of the trajectory, and duration plus the arrival delay [s] (NaN when the
        vehicle never came within ``arrival_radius_m`` of the goal).
    min_body_clearance_m : float
        Smallest distance from the body (centre minus radius) to the obstacles [m].
    min_body_clearance_point : numpy.ndarray, shape (3,)
        Vehicle centre at that moment [m].
    min_body_clearance_time_s : float
        [s].
    reference_body_clearance_m : float
        The same for a body on the reference itself [m]: what a perfect tracker keeps.
    tracking_error_max_m, tracking_error_rms_m : float
        Of ``|position - reference position|`` [m].
    path_deviation_max_m : float
        Largest distance from the vehicle to the reference's path [m].
    saturation_time_s : float
        Time with any rotor command at its minimum or maximum speed [s].
    peak_tilt_deg : float
        [deg].
    peak_thrust_to_weight : float
        Largest collective rotor thrust over weight [-].
    wind_rms_mps : numpy.ndarray, shape (3,)
        RMS of the wind about its mean along east, north and up over the flight [m/s].
    times : numpy.ndarray, shape (N,)
        Control step times [s].
    positions, reference_positions : numpy.ndarray, shape (N, 3)
        Vehicle centre and reference [m].
    reference_velocities, reference_accelerations : numpy.ndarray, shape (N, 3)
        [m/s], [m/s^2].
    errors, path_deviation, body_clearance, tilt_deg : numpy.ndarray, shape (N,)
        Tracking error [m], path deviation [m], body clearance [m], tilt [deg] at each step.
    saturated : numpy.ndarray of bool, shape (N,)
        Whether a rotor command was at a limit at each step.
    """

    vehicle: str
    wind: str
    vehicle_radius_m: float
    completed: bool
    planned_time_s: float
    flown_time_s: float
    min_body_clearance_m: float
    min_body_clearance_point: np.ndarray
    min_body_clearance_time_s: float
    reference_body_clearance_m: float
    tracking_error_max_m: float
    tracking_error_rms_m: float
    path_deviation_max_m: float
    saturation_time_s: float
    peak_tilt_deg: float
    peak_thrust_to_weight: float
    wind_rms_mps: np.ndarray
    times: np.ndarray
    positions: np.ndarray
    reference_positions: np.ndarray
    reference_velocities: np.ndarray
    reference_accelerations: np.ndarray
    errors: np.ndarray
    path_deviation: np.ndarray
    body_clearance: np.ndarray
    tilt_deg: np.ndarray
    saturated: np.ndarray


def _initial_state(vehicle: Vehicle, position: np.ndarray, yaw: float) -> dict:
    return {'x': np.array(position, dtype=float), 'v': np.zeros(3),
            'q': np.array([0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)]),
            'w': np.zeros(3), 'wind': np.zeros(3),
            'rotor_speeds': np.full(vehicle.num_rotors, vehicle.hover_rotor_speed)}


def _wind_profile(wind: Any, seed: int) -> Optional[WindProfile]:
    """A wind spec with ``generator(seed)`` (DrydenTurbulence) or a profile with ``update``."""
    if wind is None:
        return None
    if hasattr(wind, 'generator'):
        return wind.generator(seed)
    if hasattr(wind, 'update'):
        return wind
    raise TypeError(f'wind must have generator(seed) or update(t, position), got {wind!r}')


def _describe(wind: Any) -> str:
    if wind is None:
        return 'still'
    describe = getattr(wind, 'describe', None)
    return describe() if callable(describe) else type(wind).__name__


def _first_within(points: np.ndarray, goal: np.ndarray, radius: float,
                  times: np.ndarray) -> float:
    inside = np.flatnonzero(np.linalg.norm(points - goal, axis=1) <= radius)
    return float(times[inside[0]]) if len(inside) else math.nan


def fly(trajectory_like: Any, obstacles: ObstacleSet, vehicle: Vehicle, wind: Any = None,
        seed: int = 0, *, control_rate_hz: float = 500.0, hold_s: float = 2.0,
        arrival_radius_m: float = 0.25, divergence_m: float = 20.0) -> FlightReport:
    """Fly a trajectory in RotorPy with SE3Control and measure the flight.

    Parameters
    ----------
    trajectory_like : Trajectory or PlanResult
        The timed reference (ENU planning frame).
    obstacles : ObstacleSet
        What the body must keep clear of [m].
    vehicle : Vehicle
        :func:`~uav_global_planner_tools.flight.vehicles.hummingbird`,
        :func:`~uav_global_planner_tools.flight.vehicles.px4_sih_quadx` or another.
    wind : DrydenTurbulence, wind profile or None
        ``None`` for still air; an object with ``generator(seed)`` (a
        :class:`~uav_global_planner_tools.flight.wind.DrydenTurbulence`), or one with RotorPy's
        ``update(t, position)`` interface, ENU [m/s].
    seed : int
        Seed of the wind's realisation.
    control_rate_hz : float
        Controller and simulation step rate [Hz], > 0.
    hold_s : float
        Time flown at the goal after the trajectory ends [s], >= 0.
    arrival_radius_m : float
        Distance to the goal that counts as arrived, for the flown time [m], > 0.
    divergence_m : float
        Tracking error at which the flight is stopped as lost [m], > 0.

    Returns
    -------
    FlightReport

    Raises
    ------
    ValueError
        For a failed plan, a trajectory of fewer than two samples or invalid settings.
    ImportError
        When RotorPy is not installed (``pip install rotorpy==3.0.0``).
    """
    if not (math.isfinite(control_rate_hz) and control_rate_hz > 0.0):
        raise ValueError(f'control rate must be > 0 Hz, got {control_rate_hz}')
    if not (math.isfinite(hold_s) and hold_s >= 0.0):
        raise ValueError(f'hold time must be >= 0 s, got {hold_s}')
    if not (arrival_radius_m > 0.0 and divergence_m > 0.0):
        raise ValueError('arrival radius and divergence distance must be > 0 m')
    from rotorpy.controllers.quadrotor_control import SE3Control  # type: ignore[import-untyped]
    from rotorpy.vehicles.multirotor import Multirotor  # type: ignore[import-untyped]

    trajectory = trajectory_of(trajectory_like)
    duration = float(trajectory.duration_s)
    dt = 1.0 / control_rate_hz
    steps = int(math.ceil((duration + hold_s) / dt - 1e-9))
    reference = reference_at(trajectory, np.arange(steps + 1) * dt)
    params = vehicle.quad_params()
    state = _initial_state(vehicle, reference.position[0], float(reference.yaw[0]))
    model = Multirotor(params, initial_state=state, control_abstraction='cmd_motor_speeds',
                       aero=True, integrator_kwargs={'method': 'RK45', 'first_step': dt})
    controller = SE3Control(params)
    profile = _wind_profile(wind, seed)
    speed_min, speed_max = float(params['rotor_speed_min']), float(params['rotor_speed_max'])

    positions = np.full((steps + 1, 3), np.nan)
    tilt_cos = np.ones(steps + 1)
    thrust = np.zeros(steps + 1)
    saturated = np.zeros(steps + 1, dtype=bool)
    winds = np.zeros((steps + 1, 3))
    completed = True
    last = steps
    for k in range(steps + 1):
        t = k * dt
        if profile is not None:
            state['wind'] = np.asarray(profile.update(t, state['x']), dtype=float)
        x, q = state['x'], state['q']
        if not np.all(np.isfinite(x)):
            completed, last = False, k - 1
            break
        positions[k] = x
        winds[k] = state['wind']
        tilt_cos[k] = 1.0 - 2.0 * (q[0] ** 2 + q[1] ** 2)
        thrust[k] = params['k_eta'] * float(np.sum(state['rotor_speeds'] ** 2))
        if np.linalg.norm(x - reference.position[k]) > divergence_m:
            completed, last = False, k
            break
        command = controller.update(t, state, flat_output(reference, k))
        speeds = np.asarray(command['cmd_motor_speeds'])
        saturated[k] = bool(np.any(speeds <= speed_min) or np.any(speeds >= speed_max))
        if k < steps:
            state = model.step(state, command, dt)

    flown = slice(0, last + 1)
    times = reference.time[flown]
    positions = positions[flown]
    ref_positions = reference.position[flown]
    errors = np.linalg.norm(positions - ref_positions, axis=1)
    deviation, _ = cKDTree(reference.position).query(positions)
    radius = vehicle.radius_m
    body = np.asarray(obstacles.distance(positions), dtype=float) - radius
    reference_body = np.asarray(obstacles.distance(ref_positions), dtype=float) - radius
    closest = int(np.argmin(body))
    tilt = np.degrees(np.arccos(np.clip(tilt_cos[flown], -1.0, 1.0)))
    goal = reference.position[-1]
    arrival = (_first_within(positions, goal, arrival_radius_m, times)
               - _first_within(reference.position, goal, arrival_radius_m, reference.time))
    wind_flown = winds[flown]
    return FlightReport(
        vehicle=vehicle.name, wind=_describe(wind), vehicle_radius_m=radius,
        completed=completed, planned_time_s=duration,
        flown_time_s=duration + arrival if completed else math.nan,
        min_body_clearance_m=float(body[closest]),
        min_body_clearance_point=positions[closest].copy(),
        min_body_clearance_time_s=float(times[closest]),
        reference_body_clearance_m=float(np.min(reference_body)),
        tracking_error_max_m=float(np.max(errors)),
        tracking_error_rms_m=float(np.sqrt(np.mean(errors ** 2))),
        path_deviation_max_m=float(np.max(deviation)),
        # Each command holds for one step; the last one is never applied.
        saturation_time_s=float(np.count_nonzero(saturated[:steps]) * dt),
        peak_tilt_deg=float(np.max(tilt)),
        peak_thrust_to_weight=float(np.max(thrust[flown]) / (vehicle.mass_kg * GRAVITY)),
        wind_rms_mps=np.std(wind_flown, axis=0),
        times=times, positions=positions, reference_positions=ref_positions,
        reference_velocities=reference.velocity[flown],
        reference_accelerations=reference.acceleration[flown],
        errors=errors, path_deviation=np.asarray(deviation, dtype=float),
        body_clearance=body, tilt_deg=tilt, saturated=saturated[flown])
