"""Reading the track files the simulated vehicles write (``--track FILE``), and its figures.

One JSON object per line, ``t`` the wall-clock time (``time.time()``) [s], values in the map
frame ENU:

- ``{"kind": "state", "t", "p": [x, y, z], "v": [vx, vy, vz], "offboard": bool}`` every
  physics step;
- ``{"kind": "setpoint", "t", "p", "v", "a", "yaw"}`` every setpoint received (converted from
  NED by the vehicle's own conversion);
- ``{"kind": "event", "t", "text"}`` mode changes.

A file read while the vehicle still writes may end in a partial line; it is skipped.
"""

from dataclasses import dataclass
import json
from pathlib import Path
from typing import List, Optional, Tuple, Union

import numpy as np


@dataclass(frozen=True, eq=False)
class Track:
    """A vehicle's track (ENU map frame, wall-clock times [s]).

    Attributes
    ----------
    times : numpy.ndarray, shape (N,)
    positions, velocities : numpy.ndarray, shape (N, 3)
        [m], [m/s].
    offboard : numpy.ndarray of bool, shape (N,)
        Whether the vehicle flew the setpoints at each step.
    setpoint_times : numpy.ndarray, shape (M,)
    setpoint_positions, setpoint_velocities : numpy.ndarray, shape (M, 3)
        As received (NaN where not controlled).
    events : list of (float, str)
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    offboard: np.ndarray
    setpoint_times: np.ndarray
    setpoint_positions: np.ndarray
    setpoint_velocities: np.ndarray
    events: List[Tuple[float, str]]

    def between(self, start: float, end: float = np.inf) -> 'Track':
        """The part of the track with ``start <= t <= end``."""
        s = (self.times >= start) & (self.times <= end)
        p = (self.setpoint_times >= start) & (self.setpoint_times <= end)
        return Track(self.times[s], self.positions[s], self.velocities[s], self.offboard[s],
                     self.setpoint_times[p], self.setpoint_positions[p],
                     self.setpoint_velocities[p],
                     [e for e in self.events if start <= e[0] <= end])


def read_track(path: Union[str, Path]) -> Track:
    """Read a track file (complete lines only)."""
    states, setpoints, events = [], [], []
    with open(path, encoding='utf-8') as stream:
        for line in stream:
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue
            kind = record.get('kind')
            if kind == 'state':
                states.append((record['t'], *record['p'], *record['v'],
                               float(record['offboard'])))
            elif kind == 'setpoint':
                setpoints.append((record['t'], *record['p'], *record['v']))
            elif kind == 'event':
                events.append((float(record['t']), str(record['text'])))
    s = np.asarray(states, dtype=np.float64).reshape(-1, 8)
    p = np.asarray(setpoints, dtype=np.float64).reshape(-1, 7)
    return Track(s[:, 0], s[:, 1:4], s[:, 4:7], s[:, 7] > 0.5, p[:, 0], p[:, 1:4], p[:, 4:7],
                 events)


class TrackTail:
    """The newest state of a track file being written, reading only what was added.

    Parameters
    ----------
    path : str or Path
    """

    def __init__(self, path: Union[str, Path]) -> None:
        self.path = Path(path)
        self._offset = 0
        self._partial = ''
        self.position: Optional[np.ndarray] = None
        self.velocity: Optional[np.ndarray] = None

    def update(self) -> bool:
        """Read the lines added since the last call; True when a state is known."""
        if not self.path.is_file():
            return False
        with open(self.path, encoding='utf-8') as stream:
            stream.seek(self._offset)
            text = stream.read()
            self._offset = stream.tell()
        lines = (self._partial + text).split('\n')
        self._partial = lines.pop()
        for line in reversed(lines):
            if '"kind": "state"' not in line:
                continue
            record = json.loads(line)
            self.position = np.asarray(record['p'], dtype=np.float64)
            self.velocity = np.asarray(record['v'], dtype=np.float64)
            break
        return self.position is not None


def first_hold_setpoint(track: Track, after: float, still_mps: float = 1e-3,
                        settle: int = 3, moving_mps: float = 0.05) -> float:
    """Wall-clock time of the first hold setpoint after ``after`` that follows a moving one:
    zero velocity and the same position as the next ``settle`` setpoints, right after a
    setpoint of more than ``moving_mps`` (NaN when there is none) [s]."""
    t, pos, vel = track.setpoint_times, track.setpoint_positions, track.setpoint_velocities
    speeds = np.linalg.norm(np.nan_to_num(vel), axis=1)
    for i in np.flatnonzero(t > after):
        if i + settle >= len(t):
            break
        if i == 0 or speeds[i - 1] <= moving_mps:
            continue
        window = slice(i, i + settle + 1)
        if np.all(speeds[window] <= still_mps) and np.allclose(pos[window], pos[i], atol=1e-4):
            return float(t[i])
    return float('nan')


def odometry_rate(track: Track, start: float = -np.inf, end: float = np.inf) -> float:
    """Steps (odometry samples) per second between ``start`` and ``end`` [Hz]."""
    t = track.times[(track.times >= start) & (track.times <= end)]
    return float((len(t) - 1) / (t[-1] - t[0])) if len(t) > 1 else 0.0
