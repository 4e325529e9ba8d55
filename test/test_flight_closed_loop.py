"""Closed-loop flight of planned trajectories in RotorPy (uav_global_planner_tools.flight).

A short still-air flight on a shipped scene, a hover of PX4's SIH quadrotor beside an obstacle,
and the Dryden generator's intensity at the simulator's 2 ms step. Each flight is a few
seconds of simulated time (RotorPy integrates each 2 ms step with scipy's RK45).
"""

import math

import numpy as np
import pytest

from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import Trajectory
from uav_global_planner_tools.flight.fly import fly
from uav_global_planner_tools.flight.planning import config_for_vehicle
from uav_global_planner_tools.flight.vehicles import GRAVITY, hummingbird, px4_sih_quadx
from uav_global_planner_tools.flight.wind import dryden_series, DrydenTurbulence, DrydenWind

# Room kept for tracking error in the flight below [m]: the body keeps gamma as long as the
# vehicle stays within it of the reference's path.
ALLOWANCE = 0.1

# Bound of the Hummingbird's tracking error at the default limits (2 m/s): about 0.06 s times
# the speed, the lag behind the reference that rotor drag costs a controller without integral
# action (benchmarks/bench_flight.py), so 0.12-0.14 m.
TRACKING_BOUND = 0.2


def test_still_air_flight_keeps_the_body_clear_of_a_shipped_scene():
    pytest.importorskip('rotorpy')  # requirements.txt installs it; this only names it
    scene = load_scene(find_scene('paper_medium'))
    vehicle = hummingbird()
    gamma = scene.config.safety_margin
    config = config_for_vehicle(scene.config, vehicle.radius_m, ALLOWANCE)
    # 4.5 m along the largest sphere, under it, at the scene's default limits.
    result = Planner(config, scene.obstacles).plan([0.0, -5.7, 1.0], [4.5, -5.7, 1.0])
    assert result.ok, result.message
    report = fly(result, scene.obstacles, vehicle, hold_s=0.5)

    assert report.completed
    # The body passes within 0.25 m of gamma: a flight that strays by more than the allowance
    # and that (or a body clearance measured from the centre) would break it.
    assert report.reference_body_clearance_m < gamma + ALLOWANCE + 0.15
    # Measured with the exact distances: the reference's body clearance at 2 ms steps is the
    # certified curve's clearance minus the radius.
    assert report.reference_body_clearance_m == pytest.approx(
        result.min_clearance_m - vehicle.radius_m, abs=2e-3)
    assert report.min_body_clearance_m >= gamma
    assert report.path_deviation_max_m < ALLOWANCE
    assert report.tracking_error_max_m < TRACKING_BOUND
    assert report.path_deviation_max_m <= report.tracking_error_max_m + 1e-9
    assert 0.0 < report.tracking_error_rms_m < report.tracking_error_max_m
    assert report.saturation_time_s == 0.0
    assert report.peak_tilt_deg < getattr(config, 'max_tilt', 35.0)
    assert report.flown_time_s == pytest.approx(report.planned_time_s, abs=0.5)


def test_px4_sih_quad_hovers_beside_an_obstacle():
    pytest.importorskip('rotorpy')
    vehicle = px4_sih_quadx()
    # SIH: 4 x 5 N against 1 kg; hover at 49 % of full thrust.
    assert vehicle.thrust_to_weight == pytest.approx(4 * 5.0 / GRAVITY, rel=1e-9)
    assert 1.5 < vehicle.thrust_to_weight < 3.0
    hover = vehicle.hover_rotor_speed / vehicle.params['rotor_speed_max']
    assert hover ** 2 == pytest.approx(1.0 / vehicle.thrust_to_weight, rel=1e-9)
    assert vehicle.radius_m == pytest.approx(math.hypot(0.2, 0.2) + 0.127, abs=1e-9)

    # One second at [0, 0, 2], 1 m from the surface of a sphere.
    times = np.linspace(0.0, 1.0, 11)
    here = np.tile([0.0, 0.0, 2.0], (len(times), 1))
    still = Trajectory(times=times, positions=here, velocities=np.zeros_like(here),
                       accelerations=np.zeros_like(here))
    obstacles = ObstacleSet([Sphere(center=np.array([2.5, 0.0, 2.0]), radius=1.5)])
    report = fly(still, obstacles, vehicle, hold_s=0.0)

    assert report.completed
    assert report.tracking_error_max_m < 1e-3
    assert report.peak_tilt_deg < 0.1
    assert report.peak_thrust_to_weight == pytest.approx(1.0, abs=0.01)
    assert report.saturation_time_s == 0.0
    assert report.min_body_clearance_m == pytest.approx(1.0 - vehicle.radius_m, abs=1e-3)


def test_dryden_gusts_have_the_named_rms_at_the_simulator_step():
    turbulence = DrydenTurbulence(intensity=4.0, altitude_m=10.0, airspeed=5.0)
    dt = 0.002
    # Independent stationary streams: 2000 x 5 s at 2 ms, so several time constants of the
    # vertical gust (2 s) and about 900 independent stretches of the horizontal ones (13 s).
    wind = dryden_series(turbulence, dt, 2500, seed=7, streams=2000)
    rms = np.sqrt(np.mean(wind ** 2, axis=(0, 1)))
    assert rms[:2] == pytest.approx([4.0, 4.0], rel=0.1)
    # MIL-F-8785C at 10 m: sigma_w / sigma_u = (0.177 + 0.000823 h[ft])^0.4.
    assert rms[2] == pytest.approx(4.0 * (0.177 + 0.000823 * 10.0 / 0.3048) ** 0.4, rel=0.1)
    # After 5 s of steps alone (not the initial draw), still the named intensity.
    assert np.sqrt(np.mean(wind[:, -1, :2] ** 2)) == pytest.approx(4.0, rel=0.1)
    # Correlated as Dryden's u filter says: e^-1 after one time constant.
    lag = int(round(turbulence.time_constants[2] / dt))
    w = wind[:, :, 2]
    correlation = np.mean(w[:, :-lag] * w[:, lag:]) / np.mean(w ** 2)
    # (1 + sqrt(3) T s) / (1 + T s)^2 has autocorrelation (1 - tau / (2 T)) e^(-tau / T).
    assert correlation == pytest.approx(0.5 * math.exp(-1.0), abs=0.05)

    # The simulation's generator is the same process, step by step.
    generator = DrydenWind(turbulence, seed=3)
    stepped = np.array([generator.update(k * dt, np.zeros(3)) for k in range(50)])
    np.testing.assert_allclose(stepped, dryden_series(turbulence, dt, 50, seed=3)[0],
                               atol=1e-12)
