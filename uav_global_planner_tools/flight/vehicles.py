"""Vehicles flown in the closed-loop check: RotorPy parameter sets with their body size.

Two vehicles, each as a :class:`Vehicle` holding the parameter dictionary that RotorPy's
``Multirotor`` and ``SE3Control`` read (``quad_params``, SI units, FLU body axes, z up) and the
radius of the disc that holds the arms and the rotors, the part of the body that must keep the
safety margin:

- :func:`hummingbird`: the AscTec Hummingbird that RotorPy 3.0.0 ships
  (``rotorpy/vehicles/hummingbird_params.py``), read from the installed package and copied,
  so RotorPy's own module is never modified. 0.5 kg, arm 0.17 m, rotor radius 0.10 m, so a
  radius of 0.27 m; thrust-to-weight about 10 (rotor speed up to 1500 rad/s).
- :func:`px4_sih_quadx`: the quadrotor of PX4's SIH simulator (``simulator_sih``), derived here
  from the defaults of its parameters (``sih_params.yaml``):

  ============  =========  ==================================================================
  PX4 param     default    used as
  ============  =========  ==================================================================
  SIH_MASS      1.0 kg     ``mass``
  SIH_IXX/IYY   0.025      ``Ixx``, ``Iyy`` [kg m^2]
  SIH_IZZ       0.030      ``Izz`` [kg m^2] (cross terms 0, as in PX4)
  SIH_T_MAX     5.0 N      thrust of one rotor at full speed: ``k_eta = T_MAX / w_max^2``
  SIH_Q_MAX     0.1 N m    torque of one rotor at full speed: ``k_m = Q_MAX / w_max^2``
  SIH_L_ROLL    0.2 m      rotors at +-0.2 m across (y) ...
  SIH_L_PITCH   0.2 m      ... and +-0.2 m along (x): 0.283 m from the centre
  SIH_T_TAU     0.05 s     ``tau_m``, the motor time constant
  SIH_KDV       1.0 N s/m  linear drag: rotor drag ``k_d = k_z = KDV / (4 w_hover)``
  SIH_KDW       0.025      angular damping: not a RotorPy parameter (see below)
  ============  =========  ==================================================================

  SIH's motors are PX4's quad X (1 front right and 2 rear left spin counter-clockwise, 3 front
  left and 4 rear right clockwise), in SIH's order and with the yaw torque signs of its
  moment equation. SIH models thrust as ``T_MAX * u`` with the throttle ``u`` in [0, 1]
  lagged by ``SIH_T_TAU``; RotorPy models ``k_eta * w^2`` with the rotor speed lagged by
  ``tau_m``. Both reach the same full thrust, and for small changes the thrust follows the
  command with the same time constant. SIH has no rotor speed: a full speed of 1000 rad/s is
  assumed (only the ratio ``k_eta * w_max^2`` matters to the forces). SIH's drag is
  ``-KDV * v`` on the whole vehicle; RotorPy's linear drag is the rotor drag ``-w k_d v`` of
  each rotor, so ``k_d`` is chosen to give exactly KDV at hover (it grows with thrust) and the
  quadratic frame drag is set to 0. The same rotor drag damps rotations by about
  ``KDV * 0.2^2 = 0.04 N m s`` in roll and pitch, where SIH has ``KDW = 0.025``. SIH has no
  propeller size: 10-inch propellers (radius 0.127 m), the common size for this 1 kg class
  and 0.4 m between neighbouring motors, give a vehicle radius of 0.41 m. Full thrust 20 N
  against 9.81 N of weight: thrust-to-weight 2.04, hover at 49 % throttle.

  RotorPy's ``SE3Control`` takes its attitude gains from the parameter dictionary
  (``kp_att``, ``kd_att``; its position gains are fixed). With a 50 ms motor lag the attitude
  loop is ``tau s^3 + s^2 + kd s + kp``: RotorPy's default gains (310, 57) leave it a damping
  ratio of 0.22; the gains here (90 s^-2, 18 s^-1) give 0.41 with the slowest pole at
  6.6 s^-1. Flown on one 8 m/s paper_medium plan, both tracked alike (0.30 m at most) and
  RotorPy's gains held a rotor at a speed limit for 0.26 s against 0.09 s with these (at steps
  of the reference's yaw rate, which SIH's small yaw torque cannot follow).

Nothing here imports RotorPy except :func:`hummingbird`, which reads its parameter file.
"""

from dataclasses import dataclass
import math
from typing import Any, Callable, Dict, Mapping

import numpy as np

#: Gravity as RotorPy's vehicle model uses it [m/s^2].
GRAVITY = 9.81


@dataclass(frozen=True, eq=False)
class Vehicle:
    """A multirotor for RotorPy and the size of its body.

    Attributes
    ----------
    name : str
        Short name, as the benchmark prints it.
    params : Mapping[str, Any]
        RotorPy ``quad_params`` [SI units; rotor positions in the FLU body frame]. Use
        :meth:`quad_params` for a copy to hand to RotorPy.
    rotor_radius_m : float
        Propeller radius [m].
    description : str
        Where the parameters come from.
    """

    name: str
    params: Mapping[str, Any]
    rotor_radius_m: float
    description: str

    @property
    def mass_kg(self) -> float:
        """Take-off mass [kg]."""
        return float(self.params['mass'])

    @property
    def arm_length_m(self) -> float:
        """Distance from the centre of mass to the farthest rotor axis [m]."""
        return max(float(np.linalg.norm(np.asarray(r, dtype=float)))
                   for r in self.params['rotor_pos'].values())

    @property
    def radius_m(self) -> float:
        """Radius of the body with its rotors, arm plus propeller [m]."""
        return self.arm_length_m + self.rotor_radius_m

    @property
    def num_rotors(self) -> int:
        """Number of rotors."""
        return int(self.params['num_rotors'])

    @property
    def hover_rotor_speed(self) -> float:
        """Rotor speed that carries the weight, all rotors alike [rad/s]."""
        return math.sqrt(self.mass_kg * GRAVITY / (self.num_rotors * self.params['k_eta']))

    @property
    def thrust_to_weight(self) -> float:
        """Full collective thrust over weight [-]."""
        full = self.num_rotors * self.params['k_eta'] * self.params['rotor_speed_max'] ** 2
        return float(full / (self.mass_kg * GRAVITY))

    def quad_params(self) -> Dict[str, Any]:
        """A deep copy of :attr:`params` (arrays copied), as RotorPy's classes take it."""
        copy: Dict[str, Any] = {}
        for key, value in self.params.items():
            if isinstance(value, Mapping):
                copy[key] = {k: np.array(v, dtype=float) for k, v in value.items()}
            elif isinstance(value, np.ndarray):
                copy[key] = value.copy()
            else:
                copy[key] = value
        return copy


def hummingbird() -> Vehicle:
    """The AscTec Hummingbird as RotorPy 3.0.0 ships it (``hummingbird_params.quad_params``).

    Raises
    ------
    ImportError
        When RotorPy is not installed (``pip install rotorpy==3.0.0``).
    """
    from rotorpy.vehicles.hummingbird_params import quad_params  # type: ignore[import-untyped]
    params = Vehicle('hummingbird', quad_params, 0.0, '').quad_params()
    return Vehicle(name='hummingbird', params=params,
                   rotor_radius_m=float(params['rotor_radius']),
                   description='AscTec Hummingbird, RotorPy 3.0.0 hummingbird_params')


# PX4 SIH defaults (src/modules/simulation/simulator_sih/sih_params.yaml).
_SIH_MASS = 1.0          # [kg]
_SIH_IXX = 0.025         # [kg m^2]
_SIH_IYY = 0.025         # [kg m^2]
_SIH_IZZ = 0.030         # [kg m^2]
_SIH_T_MAX = 5.0         # [N] one rotor at full speed
_SIH_Q_MAX = 0.1         # [N m] one rotor at full speed
_SIH_L_ROLL = 0.2        # [m]
_SIH_L_PITCH = 0.2       # [m]
_SIH_KDV = 1.0           # [N/(m/s)]
_SIH_T_TAU = 0.05        # [s]
# Assumptions where SIH has no parameter.
_SIH_ROTOR_SPEED_MAX = 1000.0   # [rad/s]
_SIH_ROTOR_RADIUS = 0.127       # [m], a 10-inch propeller


def px4_sih_quadx() -> Vehicle:
    """PX4's SIH quadrotor (quad X) from the defaults of its ``SIH_*`` parameters.

    See the module docstring for the mapping and the assumptions.
    """
    k_eta = _SIH_T_MAX / _SIH_ROTOR_SPEED_MAX ** 2
    k_m = _SIH_Q_MAX / _SIH_ROTOR_SPEED_MAX ** 2
    hover_speed = math.sqrt(_SIH_MASS * GRAVITY / (4 * k_eta))
    rotor_drag = _SIH_KDV / (4 * hover_speed)
    x, y = _SIH_L_PITCH, _SIH_L_ROLL
    params: Dict[str, Any] = {
        'mass': _SIH_MASS, 'Ixx': _SIH_IXX, 'Iyy': _SIH_IYY, 'Izz': _SIH_IZZ,
        'Ixy': 0.0, 'Iyz': 0.0, 'Ixz': 0.0,
        'num_rotors': 4,
        'rotor_radius': _SIH_ROTOR_RADIUS,
        # PX4 quad X order, FLU body axes: front right, rear left, front left, rear right.
        'rotor_pos': {'r1': np.array([x, -y, 0.0]), 'r2': np.array([-x, y, 0.0]),
                      'r3': np.array([x, y, 0.0]), 'r4': np.array([-x, -y, 0.0])},
        # Torque on the body about +z (up): counter-clockwise rotors (1, 2) push it clockwise.
        'rotor_directions': np.array([-1, -1, 1, 1]),
        'rI': np.zeros(3),
        'c_Dx': 0.0, 'c_Dy': 0.0, 'c_Dz': 0.0,
        'k_eta': k_eta, 'k_m': k_m,
        'k_d': rotor_drag, 'k_z': rotor_drag, 'k_h': 0.0, 'k_flap': 0.0,
        'tau_m': _SIH_T_TAU,
        'rotor_speed_min': 0.0, 'rotor_speed_max': _SIH_ROTOR_SPEED_MAX,
        'motor_noise_std': 0.0,
        'kp_att': 90.0, 'kd_att': 18.0,
    }
    return Vehicle(name='px4_sih', params=params, rotor_radius_m=_SIH_ROTOR_RADIUS,
                   description='PX4 SIH quad X, from the SIH_* parameter defaults')


#: The vehicles by name.
VEHICLES: Dict[str, Callable[[], Vehicle]] = {'hummingbird': hummingbird,
                                              'px4_sih': px4_sih_quadx}
