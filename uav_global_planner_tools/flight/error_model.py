"""A tracking-error model fitted to flights, for choosing a tracking allowance.

Each flight is cut into windows of ``window_s`` seconds. For each window the largest tracking
error is paired with the largest reference speed and acceleration over the window and the
``lag_s`` seconds before it (the error follows its cause by about the position loop's time
constant). A non-negative least-squares fit of ::

    max error ~= e0 + k_v * speed + k_a * accel

over all windows gives the typical error (``with_accel=False`` fits speed alone, ``k_a = 0``);
``bound_offset_m``, the largest amount by which a window exceeded the fit, raises e0 so that the
bound covers every window flown. The model is
per vehicle and per wind: a planner takes ``bound(peak speed, peak accel)`` of its limits as its
tracking allowance for that vehicle and weather.
"""

from dataclasses import dataclass
import math
from typing import Any, Sequence

import numpy as np
from scipy.optimize import nnls


@dataclass(frozen=True)
class TrackingErrorModel:
    """``max error ~= e0_m + k_v_s * speed + k_a_s2 * accel`` over a window of flight.

    Attributes
    ----------
    e0_m : float
        Error at rest [m] (wind, settling).
    k_v_s : float
        Error per unit speed [m per m/s = s].
    k_a_s2 : float
        Error per unit acceleration [m per m/s^2 = s^2].
    bound_offset_m : float
        Added to ``e0_m`` for a bound of every window flown [m], >= 0.
    rms_residual_m : float
        RMS of the fit's residuals [m].
    windows : int
        Windows the fit used.
    """

    e0_m: float
    k_v_s: float
    k_a_s2: float
    bound_offset_m: float
    rms_residual_m: float
    windows: int

    def predict(self, speed: float, accel: float) -> float:
        """Typical largest error at this speed [m/s] and acceleration [m/s^2], in [m]."""
        return self.e0_m + self.k_v_s * speed + self.k_a_s2 * accel

    def bound(self, speed: float, accel: float) -> float:
        """Largest error seen at this speed and acceleration, by the fit [m]."""
        return self.predict(speed, accel) + self.bound_offset_m


def error_windows(report: Any, window_s: float = 1.0, lag_s: float = 0.5,
                  quantity: str = 'errors') -> np.ndarray:
    """Per window of a flight: largest error [m], speed [m/s] and acceleration [m/s^2].

    Parameters
    ----------
    report : FlightReport
    quantity : str
        The report's per-step error to model: ``errors`` (tracking error) or
        ``path_deviation`` (distance to the reference's path).
    window_s : float
        Window length [s], > 0.
    lag_s : float
        How far before a window its speed and acceleration are looked at too [s], >= 0.

    Returns
    -------
    numpy.ndarray, shape (W, 3)
        Columns error, speed, acceleration; windows shorter than half ``window_s`` at the end
        are dropped.
    """
    if not (window_s > 0.0 and lag_s >= 0.0):
        raise ValueError(f'window must be > 0 s and lag >= 0 s, got {window_s} and {lag_s}')
    if quantity not in ('errors', 'path_deviation'):
        raise ValueError(f'quantity must be errors or path_deviation, got {quantity!r}')
    times = np.asarray(report.times)
    error = np.asarray(getattr(report, quantity))
    speed = np.linalg.norm(report.reference_velocities, axis=1)
    accel = np.linalg.norm(report.reference_accelerations, axis=1)
    rows = []
    start = float(times[0])
    while start + 0.5 * window_s <= times[-1]:
        inside = (times >= start) & (times < start + window_s)
        cause = (times >= start - lag_s) & (times < start + window_s)
        rows.append((float(np.max(error[inside])), float(np.max(speed[cause])),
                     float(np.max(accel[cause]))))
        start += window_s
    return np.array(rows).reshape(-1, 3)


def fit_tracking_error(reports: Sequence[Any], window_s: float = 1.0, lag_s: float = 0.5,
                       with_accel: bool = True, quantity: str = 'errors') -> TrackingErrorModel:
    """Fit :class:`TrackingErrorModel` to the windows of some flights (FlightReport).

    ``with_accel=False`` fits ``e0 + k_v * speed`` alone; ``quantity`` as in
    :func:`error_windows`.

    Raises
    ------
    ValueError
        When the flights give fewer than three windows.
    """
    data = np.concatenate([error_windows(r, window_s, lag_s, quantity) for r in reports]) \
        if reports else np.empty((0, 3))
    if len(data) < 3:
        raise ValueError(f'need at least three windows of flight to fit, got {len(data)}')
    design = np.column_stack([np.ones(len(data)), data[:, 1],
                              data[:, 2] if with_accel else np.zeros(len(data))])
    coefficients, _ = nnls(design, data[:, 0])
    residuals = data[:, 0] - design @ coefficients
    return TrackingErrorModel(e0_m=float(coefficients[0]), k_v_s=float(coefficients[1]),
                              k_a_s2=float(coefficients[2]),
                              bound_offset_m=float(max(0.0, np.max(residuals))),
                              rms_residual_m=float(math.sqrt(np.mean(residuals ** 2))),
                              windows=len(data))
