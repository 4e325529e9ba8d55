"""Flight time and an energy estimate of a timed trajectory, from a point-mass quadcopter model.

The model
---------
The vehicle is a point of mass ``m`` [kg] that needs the hover power ``P_h`` [W] to stay in the
air, plus the power to lift its weight when it climbs::

    P(t) = P_h + m * g * max(v_z(t), 0)         E = integral of P(t) dt over the flight

so ``E = P_h * T + m * g * H_up``, with ``T`` the flight time [s] and ``H_up`` the total height
climbed [m] (the sum of every rise of the curve, not the net one). ``H_up`` is summed over the
trajectory's samples, which is exact where the height does not turn between two samples (the
timed trajectory samples every few centimetres).

Its limits, said plainly:

* No aerodynamic drag and no forward-flight power curve: a real multicopter's power first falls
  with airspeed (translational lift) and then rises (profile and parasitic drag), by tens of
  percent at cruise speed. Here level flight costs hover power at any speed.
* No wind, no acceleration power (the kinetic energy is small beside hover: 1.5 kg at 2 m/s is
  3 J, a sixtieth of a second of hover at 180 W), and no rotor, motor, ESC or battery
  efficiency beyond what ``P_h`` (measured at the battery) already includes.
* Descending recovers nothing and saves nothing: power stays ``P_h`` (a real descent needs
  somewhat less, except in the vortex-ring state of a fast vertical descent).
* ``P_h`` is taken as constant: it grows with payload and air density altitude
  (``P_h ~ (m g)^1.5 / sqrt(2 rho A)`` by momentum theory).

Use it to compare plans of one vehicle with each other (the climb term is what the energy-aware
cost, :mod:`uav_global_planner.core.search.grid_search`, trades against distance), not as a
battery budget.
"""

from dataclasses import dataclass
import math
from typing import Any

import numpy as np

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.result import Trajectory
from uav_global_planner.core.settings import SETTINGS_BY_NAME

#: Standard gravity [m/s^2].
GRAVITY = 9.80665
#: Defaults of :class:`VehicleModel`: a 1.5 kg quadcopter hovering on 180 W (the settings
#: ``vehicle_mass`` and ``hover_power`` of :mod:`uav_global_planner.core.settings`).
DEFAULT_MASS_KG = float(SETTINGS_BY_NAME['vehicle_mass'].default)
DEFAULT_HOVER_POWER_W = float(SETTINGS_BY_NAME['hover_power'].default)


@dataclass(frozen=True)
class VehicleModel:
    """Parameters of the point-mass quadcopter model.

    Attributes
    ----------
    mass : float
        Take-off mass m [kg], as the setting ``vehicle_mass`` accepts.
    hover_power : float
        Electrical power to hover P_h [W], as the setting ``hover_power`` accepts.
    """

    mass: float = DEFAULT_MASS_KG
    hover_power: float = DEFAULT_HOVER_POWER_W

    def __post_init__(self) -> None:
        # Checked by the settings table, named by the scene key path (vehicle.mass).
        for name, attribute in (('vehicle_mass', 'mass'), ('hover_power', 'hover_power')):
            entry = SETTINGS_BY_NAME[name]
            object.__setattr__(self, attribute,
                               entry.check_key(getattr(self, attribute), str(entry.scene_key)))


@dataclass(frozen=True)
class EnergyEstimate:
    """Flight time and energy of one trajectory.

    Attributes
    ----------
    flight_time_s : float
        T [s].
    energy_j : float
        E = hover + climb [J].
    hover_energy_j : float
        P_h * T [J].
    climb_energy_j : float
        m * g * H_up [J].
    climb_m : float
        H_up, the total height climbed [m].
    """

    flight_time_s: float
    energy_j: float
    hover_energy_j: float
    climb_energy_j: float
    climb_m: float

    @property
    def energy_wh(self) -> float:
        """E in watt-hours [Wh]."""
        return self.energy_j / 3600.0

    @property
    def mean_power_w(self) -> float:
        """E / T [W]; the hover power for a zero-length flight."""
        return self.energy_j / self.flight_time_s if self.flight_time_s > 0.0 else math.nan


def estimate_energy(trajectory: Trajectory, vehicle: VehicleModel = VehicleModel()
                    ) -> EnergyEstimate:
    """Flight time and energy of ``trajectory`` for ``vehicle`` (see the module notes).

    Parameters
    ----------
    trajectory : Trajectory
        A timed trajectory (``times`` [s], ``positions`` [m], z up).
    vehicle : VehicleModel

    Raises
    ------
    InvalidInputError
        When ``trajectory`` is not a :class:`Trajectory` or ``vehicle`` not a
        :class:`VehicleModel`.
    """
    if not isinstance(trajectory, Trajectory):
        raise InvalidInputError(
            f'trajectory must be a Trajectory, got {type(trajectory).__name__}')
    if not isinstance(vehicle, VehicleModel):
        raise InvalidInputError(f'vehicle must be a VehicleModel, got {type(vehicle).__name__}')
    duration = trajectory.duration_s
    heights = np.asarray(trajectory.positions, dtype=np.float64).reshape(-1, 3)[:, 2]
    climb = float(np.sum(np.maximum(np.diff(heights), 0.0))) if len(heights) > 1 else 0.0
    hover = vehicle.hover_power * duration
    lift = vehicle.mass * GRAVITY * climb
    return EnergyEstimate(flight_time_s=duration, energy_j=hover + lift, hover_energy_j=hover,
                          climb_energy_j=lift, climb_m=climb)


def parse_vehicle(data: Any, path: str = 'vehicle') -> VehicleModel:
    """The :class:`VehicleModel` of a scene's ``vehicle`` mapping (``{mass, hover_power}``,
    both optional); None gives the defaults.

    Raises
    ------
    InvalidInputError
        Naming the key path, e.g. ``vehicle.mass: must be in (0.0, 1000.0], got -1.0``.
    """
    if data is None:
        return VehicleModel()
    if not isinstance(data, dict):
        raise InvalidInputError(f'{path}: must be a mapping, got {type(data).__name__}')
    unknown = sorted(str(key) for key in data if key not in ('mass', 'hover_power'))
    if unknown:
        raise InvalidInputError(f'{path}: unknown key(s) {", ".join(unknown)}; allowed: '
                                'hover_power, mass')
    try:
        return VehicleModel(**data)
    except InvalidInputError as error:
        message = str(error)
        if path != 'vehicle' and message.startswith('vehicle.'):
            message = path + message[len('vehicle'):]
        raise InvalidInputError(message) from None
