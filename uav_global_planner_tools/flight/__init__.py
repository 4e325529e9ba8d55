"""Closed-loop flight of planned trajectories in RotorPy, the field's multirotor simulator.

A planned trajectory promises a margin on the reference; what the vehicle's body keeps is
measured here, in closed loop: RotorPy 3.0.0's multirotor model flown by its ``SE3Control``
geometric controller at 500 Hz, in still air or Dryden turbulence.

- :mod:`~uav_global_planner_tools.flight.fly`: :func:`fly` and its :class:`FlightReport`
  (body clearance, tracking error, rotor saturation, tilt, flown time).
- :mod:`~uav_global_planner_tools.flight.vehicles`: the Hummingbird that RotorPy ships and a
  quadrotor from PX4 SIH's parameter defaults, with their body radius.
- :mod:`~uav_global_planner_tools.flight.wind`: Dryden turbulence (MIL-F-8785C low altitude),
  exact for any step.
- :mod:`~uav_global_planner_tools.flight.reference`: the trajectory as flat outputs.
- :mod:`~uav_global_planner_tools.flight.planning`: planner settings for a vehicle's size.
- :mod:`~uav_global_planner_tools.flight.error_model`: a tracking-error model fitted to flights.

``benchmarks/bench_flight.py`` flies the shipped scenes with both vehicles. RotorPy is the
optional extra ``flight`` (``requirements.txt`` pins it); it is imported only when a flight
starts or the Hummingbird's parameters are read.
"""

from uav_global_planner_tools.flight.fly import FlightReport, fly
from uav_global_planner_tools.flight.vehicles import hummingbird, px4_sih_quadx, Vehicle
from uav_global_planner_tools.flight.wind import DrydenTurbulence, DrydenWind

__all__ = ['FlightReport', 'fly', 'hummingbird', 'px4_sih_quadx', 'Vehicle',
           'DrydenTurbulence', 'DrydenWind']
