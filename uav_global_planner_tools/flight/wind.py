"""Dryden turbulence at low altitude, discretised exactly for any time step.

Why not RotorPy's own: ``rotorpy.wind.dryden_winds`` (RotorPy 3.0.0) imports
``rotorpy.wind.dryden_utils``, which imports torch at import time, so it cannot even be
imported without torch. And its gust filter (a Tustin discretisation of the second-order
Dryden form, driven by one uniform number in [-1, 1] per step, not scaled with the step) gives
an RMS that shrinks with the square root of the step: asked for 4 m/s at 2 ms (its default
altitude 2 m, airspeed 1 m/s), the same recursion gives about 0.055 m/s.

The model here (MIL-F-8785C, the low-altitude forms also in MIL-HDBK-1797), altitude ``h`` in
feet, 10 ft <= h <= 1000 ft (clamped)::

    L_w = h,    L_u = L_v = h / (0.177 + 0.000823 h)^1.2               (scale lengths)
    sigma_w / sigma_u = sigma_w / sigma_v = (0.177 + 0.000823 h)^0.4   (intensities)
    H_u(s) ~ 1 / (1 + T_u s),    H_v(s) ~ (1 + sqrt(3) T_v s) / (1 + T_v s)^2,
    H_w(s) ~ (1 + sqrt(3) T_w s) / (1 + T_w s)^2,    T_i = L_i / V

``u`` is along the mean wind (+x when there is none), ``v`` across it, ``w`` vertical; ``V`` is
the speed at which the frozen turbulence field passes the vehicle (mean wind plus airspeed).
The named intensity is the horizontal RMS ``sigma_u = sigma_v``; ``sigma_w`` follows from the
altitude (about 0.53 of it at 10 m).

Each shaping filter is a linear system ``dx = A x dt + B dW`` (one state for u, two each for v
and w) whose output gain is set from the stationary covariance ``P`` (``A P + P A^T + B B^T =
0``) so that the output variance is exactly ``sigma^2``, whatever the conventions of the
spectra. Over a step ``dt`` the state moves exactly as ``x' = e^(A dt) x + n`` with ``n``
Gaussian of covariance ``Q = integral_0^dt e^(A s) B B^T e^(A^T s) ds`` (Van Loan's matrix
exponential), and the first state is drawn from ``P``: the sampled process has the named RMS
from the first sample on, at 2 ms or at any other step.
"""

from dataclasses import dataclass
import math
from typing import Dict, Optional, Tuple

import numpy as np
from scipy.linalg import expm, solve_continuous_lyapunov

_FT = 0.3048              # [m]
_LOW_ALTITUDE_FT = (10.0, 1000.0)


def low_altitude_scales(altitude_m: float) -> Tuple[np.ndarray, float]:
    """MIL-F-8785C low-altitude scale lengths and the vertical-to-horizontal intensity ratio.

    Parameters
    ----------
    altitude_m : float
        Height above ground [m], clamped to 10-1000 ft (3.05-304.8 m), the forms' range.

    Returns
    -------
    lengths : numpy.ndarray, shape (3,)
        ``L_u, L_v, L_w`` [m].
    vertical_ratio : float
        ``sigma_w / sigma_u`` [-].
    """
    h_ft = min(max(altitude_m / _FT, _LOW_ALTITUDE_FT[0]), _LOW_ALTITUDE_FT[1])
    base = 0.177 + 0.000823 * h_ft
    horizontal_ft = h_ft / base ** 1.2
    lengths = np.array([horizontal_ft, horizontal_ft, h_ft]) * _FT
    return lengths, float(base ** 0.4)


@dataclass(frozen=True)
class DrydenTurbulence:
    """A Dryden turbulence field: what to fly through (:meth:`generator` makes one run of it).

    Attributes
    ----------
    intensity : float
        Horizontal RMS of the gusts, ``sigma_u = sigma_v`` [m/s], >= 0.
    altitude_m : float
        Height for the scale lengths and the vertical intensity [m].
    airspeed : float
        ``V``, the speed of the frozen field past the vehicle [m/s], > 0.
    mean_wind : tuple of float
        Steady wind added to the gusts, ENU [m/s]; its horizontal direction is ``u``'s.
    """

    intensity: float = 4.0
    altitude_m: float = 10.0
    airspeed: float = 5.0
    mean_wind: Tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.intensity) and self.intensity >= 0.0):
            raise ValueError(f'intensity must be >= 0 m/s, got {self.intensity}')
        if not (math.isfinite(self.airspeed) and self.airspeed > 0.0):
            raise ValueError(f'airspeed must be > 0 m/s, got {self.airspeed}')
        if not (math.isfinite(self.altitude_m) and self.altitude_m > 0.0):
            raise ValueError(f'altitude must be > 0 m, got {self.altitude_m}')
        if len(self.mean_wind) != 3 or not np.all(np.isfinite(self.mean_wind)):
            raise ValueError(f'mean wind must be three finite numbers, got {self.mean_wind}')

    @property
    def sigmas(self) -> np.ndarray:
        """RMS of the u, v and w gusts [m/s], shape (3,)."""
        ratio = low_altitude_scales(self.altitude_m)[1]
        return self.intensity * np.array([1.0, 1.0, ratio])

    @property
    def time_constants(self) -> np.ndarray:
        """``T = L / V`` of the u, v and w filters [s], shape (3,)."""
        return low_altitude_scales(self.altitude_m)[0] / self.airspeed

    def describe(self) -> str:
        """Short text for tables, such as ``dryden 4 m/s``."""
        mean = float(np.linalg.norm(self.mean_wind))
        text = f'dryden {self.intensity:g} m/s'
        return text + (f' + {mean:g} m/s mean' if mean > 0.0 else '')

    def generator(self, seed: int = 0) -> 'DrydenWind':
        """One realisation of the field, reproducible from ``seed``."""
        return DrydenWind(self, seed)


def _shaping_filters(turbulence: DrydenTurbulence) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous model of the three gusts: ``A`` (5, 5), ``B`` (5, 3) and output ``C`` (3, 5).

    The output gains make each gust's stationary RMS exactly its sigma.
    """
    t_u, t_v, t_w = turbulence.time_constants
    a = np.zeros((5, 5))
    b = np.zeros((5, 3))
    c = np.zeros((3, 5))
    a[0, 0] = -1.0 / t_u
    b[0, 0] = 1.0
    c[0, 0] = 1.0
    for axis, (first, tau) in enumerate(((1, t_v), (3, t_w)), start=1):
        # (1 + sqrt(3) tau s) / (1 + tau s)^2 in controllable canonical form.
        a[first, first + 1] = 1.0
        a[first + 1, first] = -1.0 / tau ** 2
        a[first + 1, first + 1] = -2.0 / tau
        b[first + 1, axis] = 1.0
        c[axis, first] = 1.0 / tau ** 2
        c[axis, first + 1] = math.sqrt(3.0) / tau
    covariance = solve_continuous_lyapunov(a, -b @ b.T)
    unit_rms = np.sqrt(np.einsum('ij,jk,ik->i', c, covariance, c))
    c *= (turbulence.sigmas / unit_rms)[:, None]
    return a, b, c


def _step_matrices(a: np.ndarray, b: np.ndarray, dt: float) -> Tuple[np.ndarray, np.ndarray]:
    """Exact transition ``e^(A dt)`` and a square root of the step's noise covariance."""
    n = len(a)
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n] = -a
    block[:n, n:] = b @ b.T
    block[n:, n:] = a.T
    exponential = expm(block * dt)
    transition = exponential[n:, n:].T
    noise = transition @ exponential[:n, n:]
    noise = 0.5 * (noise + noise.T)
    values, vectors = np.linalg.eigh(noise)
    return transition, vectors * np.sqrt(np.clip(values, 0.0, None))


def _to_enu(turbulence: DrydenTurbulence, gusts: np.ndarray) -> np.ndarray:
    """Gusts (..., 3) in (u, v, w) to ENU wind with the mean added [m/s]."""
    mean = np.asarray(turbulence.mean_wind, dtype=float)
    heading = math.atan2(mean[1], mean[0]) if np.hypot(mean[0], mean[1]) > 0.0 else 0.0
    cos_h, sin_h = math.cos(heading), math.sin(heading)
    east = cos_h * gusts[..., 0] - sin_h * gusts[..., 1]
    north = sin_h * gusts[..., 0] + cos_h * gusts[..., 1]
    return np.stack([east, north, gusts[..., 2]], axis=-1) + mean


class DrydenWind:
    """One realisation of a :class:`DrydenTurbulence`, sampled as the simulation advances.

    It has RotorPy's wind-profile interface, ``update(t, position)``; the gusts do not depend
    on the position (a frozen field passing at the constant speed ``V``).

    Parameters
    ----------
    turbulence : DrydenTurbulence
    seed : int
        Seed of the normal draws (``numpy.random.default_rng``).
    """

    def __init__(self, turbulence: DrydenTurbulence, seed: int = 0) -> None:
        self.turbulence = turbulence
        self._a, self._b, self._c = _shaping_filters(turbulence)
        self._rng = np.random.default_rng(seed)
        covariance = solve_continuous_lyapunov(self._a, -self._b @ self._b.T)
        self._state = np.linalg.cholesky(covariance) @ self._rng.standard_normal(5)
        self._time: Optional[float] = None
        self._steps: Dict[float, Tuple[np.ndarray, np.ndarray]] = {}

    def update(self, t: float, position: Optional[np.ndarray] = None) -> np.ndarray:
        """Wind at time ``t`` [s], ENU [m/s], shape (3,); times must not decrease.

        The first call gives the initial (stationary) state, whatever ``t``; each later call
        advances exactly by the time since the previous one.
        """
        if self._time is not None:
            dt = float(t) - self._time
            if dt < 0.0:
                raise ValueError(f'wind time went back from {self._time} s to {t} s')
            if dt > 0.0:
                key = round(dt, 12)
                if key not in self._steps:
                    self._steps[key] = _step_matrices(self._a, self._b, dt)
                transition, noise = self._steps[key]
                self._state = transition @ self._state + noise @ self._rng.standard_normal(5)
        self._time = float(t)
        return _to_enu(self.turbulence, self._c @ self._state)


def dryden_series(turbulence: DrydenTurbulence, dt: float, steps: int, seed: int = 0,
                  streams: int = 1) -> np.ndarray:
    """Independent realisations of the wind every ``dt`` seconds, computed side by side.

    Stream 0 equals what :class:`DrydenWind` with the same seed gives at ``0, dt, 2 dt, ...``
    when ``streams == 1``.

    Parameters
    ----------
    turbulence : DrydenTurbulence
    dt : float
        Step [s], > 0.
    steps : int
        Samples per stream, >= 1.
    seed : int
    streams : int
        Number of independent realisations, >= 1.

    Returns
    -------
    numpy.ndarray, shape (streams, steps, 3)
        ENU wind [m/s].
    """
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f'dt must be > 0 s, got {dt}')
    if steps < 1 or streams < 1:
        raise ValueError(f'steps and streams must be >= 1, got {steps} and {streams}')
    a, b, c = _shaping_filters(turbulence)
    transition, noise = _step_matrices(a, b, dt)
    rng = np.random.default_rng(seed)
    root = np.linalg.cholesky(solve_continuous_lyapunov(a, -b @ b.T))
    if streams == 1:
        state = (root @ rng.standard_normal(5))[None, :]
    else:
        state = rng.standard_normal((streams, 5)) @ root.T
    gusts = np.empty((streams, steps, 3))
    for k in range(steps):
        if k:
            draws = rng.standard_normal(5) if streams == 1 else rng.standard_normal((streams, 5))
            state = state @ transition.T + np.atleast_2d(draws) @ noise.T
        gusts[:, k] = state @ c.T
    return _to_enu(turbulence, gusts)
