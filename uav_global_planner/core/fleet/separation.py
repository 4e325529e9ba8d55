"""Certified separation between two timed trajectories, in continuous time.

A :class:`Flight` is a plan's exact timed reference
(:class:`~uav_global_planner.core.path.reference.TimedReference`: a curve ``c(s)`` parameterised by
arc length, flown with a piecewise polynomial arc length ``s(t)``) placed at a departure on the
batch clock, optionally flown slower along the same curve. It is in the airspace from its departure
to its arrival.

Two flights conflict when, at one instant of the time both are flying, their horizontal
distance is below ``horizontal_m`` and their vertical distance below ``vertical_m`` of the
:class:`Envelope`.

**The bound.** ``|c'(s)| = 1``, so ``|c(s) - c(m)| <= |s - m|``, and ``s(t)`` never decreases:
over a time interval ``[t0, t1]`` the flight stays in the ball of radius
``r = (s(t1) - s(t0)) / 2`` around ``c((s(t0) + s(t1)) / 2)``. With the centres ``a``, ``b``
and radii ``ra``, ``rb`` of two flights, every horizontal distance over the interval is at
least ``|a_xy - b_xy| - ra - rb`` and every vertical one at least ``|a_z - b_z| - ra - rb``
(:func:`distance_bounds`); a small allowance for rounding (:data:`ROUNDING_M`) is taken off.

The same bound holds with any exactly evaluated curve point as the centre, the radius being
the arc length from it to the farther end. A flight keeps a table of exact values (arc lengths
every :data:`TABLE_DT_S` of its reference's time, curve points every :data:`TABLE_DS_M` of arc
length, :func:`table_balls`): bounds from the table need no curve evaluation and are as
certain, looser by up to those steps.

**The check** (:func:`first_conflict`) splits the common flying time into intervals, drops
those whose bound proves them apart, tests the others' midpoints for a violation (an upper
bound of both distances below the envelope: a proven conflict, with its instant and
distances) and halves the rest: from the tables down to a table step, then from exact
evaluations down to the tolerance. A stretch still undecided then counts as a conflict
(``proven=False``): the check never calls a conflicting pair apart.
"""

from dataclasses import dataclass, replace
import math
from typing import Any, Dict, List, Optional, Tuple
import weakref

import numpy as np

from uav_global_planner.core.checks import check_number, check_positive

#: Allowance for rounding in the arc lengths and curve points [m].
ROUNDING_M = 1e-6

#: Length of the first intervals of the check [s]; they are halved where needed.
FIRST_INTERVAL_S = 4.0

#: Intervals handled at once by the check (memory bound of one step).
_BLOCK = 2048


@dataclass(frozen=True)
class Envelope:
    """The separation every pair of flights keeps.

    Attributes
    ----------
    horizontal_m, vertical_m : float
        [m], > 0.
    """

    horizontal_m: float
    vertical_m: float


@dataclass(frozen=True, eq=False)
class Flight:
    """A timed reference flown from a departure on the batch clock.

    Attributes
    ----------
    mission, vehicle : str
        Names of the mission and of the vehicle flying it.
    reference : TimedReference
        The exact reference (``curve`` and ``arc``), times from 0 [s].
    departure_s : float
        Departure on the batch clock [s].
    time_scale : float
        Speed factor in (0, 1]: the reference's time at batch time ``t`` is
        ``(t - departure_s) * time_scale`` (the same curve, every speed times the factor).
    layer_m : float
        Altitude offset of the plan it comes from [m] (0 for the base plan); a label.
    """

    mission: str
    vehicle: str
    reference: Any
    departure_s: float
    time_scale: float = 1.0
    layer_m: float = 0.0

    @property
    def duration_s(self) -> float:
        """Flight time [s]."""
        return float(self.reference.duration_s) / self.time_scale

    @property
    def start_s(self) -> float:
        """Departure on the batch clock [s]."""
        return float(self.departure_s)

    @property
    def end_s(self) -> float:
        """Arrival on the batch clock [s]."""
        return float(self.departure_s) + self.duration_s

    def local_times(self, times: Any) -> np.ndarray:
        """The reference's times [s] at batch times ``times`` [s], clamped to the flight."""
        t = np.asarray(times, dtype=np.float64).reshape(-1)
        return np.clip((t - self.departure_s) * self.time_scale, 0.0,
                       float(self.reference.duration_s))

    def arc_lengths(self, times: Any) -> np.ndarray:
        """Arc length flown [m] at batch times ``times`` [s] (clamped to the flight)."""
        return self.reference.arc.evaluate(self.local_times(times))[0]

    def points(self, arc_lengths: np.ndarray) -> np.ndarray:
        """Points of the curve at arc lengths [m], shape (N, 3)."""
        return self.reference.curve.evaluate(np.asarray(arc_lengths, dtype=np.float64))

    def positions(self, times: Any) -> np.ndarray:
        """Positions [m] (ENU) at batch times ``times`` [s], shape (N, 3); before the departure
        the start, after the arrival the goal."""
        return self.points(self.arc_lengths(times))

    def sample(self, step_s: float) -> Tuple[np.ndarray, np.ndarray]:
        """Batch times every ``step_s`` seconds from departure, arrival included, and the
        positions there [s], [m] shape (N, 3)."""
        step_s = check_positive('step_s', step_s, 's')
        count = int(math.floor(self.duration_s / step_s + 1e-9))
        times = self.start_s + np.arange(count + 1) * step_s
        if times[-1] < self.end_s:
            times = np.r_[times, self.end_s]
        return times, self.positions(times)

    def delayed(self, delay_s: float) -> 'Flight':
        """The same flight departing ``delay_s`` seconds later."""
        return replace(self, departure_s=float(self.departure_s) + float(delay_s))

    def slowed(self, factor: float) -> 'Flight':
        """The same curve flown with every speed times ``factor`` in (0, 1]."""
        factor = check_number('speed factor', factor, 0.0, 1.0, low_open=True, convert=True)
        return replace(self, time_scale=self.time_scale * float(factor))

    @property
    def speed_factor(self) -> float:
        """The speed factor of the flight (its ``time_scale``)."""
        return float(self.time_scale)

    def prepare(self) -> 'Flight':
        """Build the reference's table of exact values now (:func:`table_balls`) and keep it
        with this flight, so that it travels in the flight's pickle; returns the flight."""
        self._tabled()
        return self

    def _tabled(self) -> '_Table':
        table = self.__dict__.get('_table')
        if table is None:
            table = _table(self.reference)
            object.__setattr__(self, '_table', table)
        elif self.reference not in _TABLES:
            _TABLES[self.reference] = table
        return table


@dataclass(frozen=True, eq=False)
class Conflict:
    """Two flights closer than the envelope at one instant, or the same vehicle twice.

    Attributes
    ----------
    first, second : str
        The missions (the candidate first, the reserved one second).
    kind : str
        ``'separation'``, or ``'vehicle'`` when one vehicle would fly both at once.
    time_s : float
        An instant of the conflict on the batch clock [s].
    horizontal_m, vertical_m : float
        Horizontal and vertical distance at that instant [m].
    proven : bool
        True when the distances at ``time_s`` violate the envelope; False for a stretch
        shorter than the tolerance that could not be proven apart.
    first_position, second_position : numpy.ndarray, shape (3,)
        The vehicles' positions at ``time_s`` [m].
    """

    first: str
    second: str
    kind: str
    time_s: float
    horizontal_m: float
    vertical_m: float
    proven: bool
    first_position: np.ndarray
    second_position: np.ndarray

    def to_dict(self) -> Dict[str, Any]:
        """The conflict as JSON-ready values."""
        return {'first': self.first, 'second': self.second, 'kind': self.kind,
                'time_s': self.time_s, 'horizontal_m': self.horizontal_m,
                'vertical_m': self.vertical_m, 'proven': self.proven,
                'first_position': [float(v) for v in self.first_position],
                'second_position': [float(v) for v in self.second_position]}


@dataclass(frozen=True, eq=False)
class _Table:
    """Exact values of a reference at regular steps, for bounds without curve evaluations.

    ``arc[k]`` is the arc length at the reference's time ``min(k * dt, duration)``;
    ``points[j]`` the curve point at arc length ``nodes[j] = min(j * ds, length)``.
    """

    dt: float
    arc: np.ndarray
    ds: float
    nodes: np.ndarray
    points: np.ndarray


#: Time step [s] and arc-length step [m] of the tables.
TABLE_DT_S = 0.1
TABLE_DS_M = 0.5

_TABLES: 'weakref.WeakKeyDictionary[Any, _Table]' = weakref.WeakKeyDictionary()


def _table(reference: Any) -> _Table:
    """The table of a reference (built once, kept while the reference lives)."""
    table = _TABLES.get(reference)
    if table is None:
        duration = float(reference.duration_s)
        times = np.r_[np.arange(int(math.ceil(duration / TABLE_DT_S))) * TABLE_DT_S, duration]
        arc = np.maximum.accumulate(reference.arc.evaluate(times)[0])
        length = float(max(arc[-1], 0.0))
        nodes = np.r_[np.arange(int(math.ceil(length / TABLE_DS_M))) * TABLE_DS_M, length]
        table = _Table(TABLE_DT_S, arc, TABLE_DS_M, nodes,
                       reference.curve.evaluate(nodes).reshape(-1, 3))
        _TABLES[reference] = table
    return table


def table_balls(flight: 'Flight', t0: np.ndarray,
                t1: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Centre [m] shape (N, 3) and radius [m] of a ball holding the flight over each
    ``[t0[i], t1[i]]`` (a point of time when they are equal), from its table.

    The arc length never decreases, so over the interval it lies between the tabled values
    at the table times around it; the centre is the tabled curve point nearest the middle of
    that range, the radius the arc length from it to the farther end.
    """
    table = flight._tabled()
    last = len(table.arc) - 1
    tau0 = flight.local_times(t0) / table.dt
    tau1 = flight.local_times(t1) / table.dt
    i0 = np.clip(np.floor(tau0).astype(np.int64), 0, max(last - 1, 0))
    i1 = np.clip(np.ceil(tau1).astype(np.int64), min(1, last), last)
    s0, s1 = table.arc[i0], table.arc[i1]
    j = np.clip(np.rint(0.5 * (s0 + s1) / table.ds).astype(np.int64), 0, len(table.nodes) - 1)
    node = table.nodes[j]
    return table.points[j], np.maximum(node - s0, s1 - node) + ROUNDING_M


def _balls(flight: 'Flight', t0: np.ndarray, t1: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Centre [m] shape (N, 3) and radius [m] of a ball holding the flight over each
    ``[t0[i], t1[i]]``, from exact evaluations of the reference."""
    s = flight.arc_lengths(np.r_[t0, t1])
    s0, s1 = s[:len(t0)], s[len(t0):]
    return flight.points(0.5 * (s0 + s1)), 0.5 * np.abs(s1 - s0) + ROUNDING_M


def _gaps(a: 'Flight', b: 'Flight', t0: np.ndarray, t1: np.ndarray,
          exact: bool) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal and vertical distance of the balls' centres [m], and the sum of radii."""
    balls = _balls if exact else table_balls
    ca, ra = balls(a, t0, t1)
    cb, rb = balls(b, t0, t1)
    gap = ca - cb
    return np.hypot(gap[:, 0], gap[:, 1]), np.abs(gap[:, 2]), ra + rb


def distance_bounds(a: 'Flight', b: 'Flight', t0: Any, t1: Any,
                    exact: bool = True) -> Tuple[np.ndarray, np.ndarray]:
    """Certified lower bounds of the horizontal and vertical distance between two flights.

    Parameters
    ----------
    a, b : Flight
    t0, t1 : array_like, shape (N,)
        Interval ends on the batch clock [s], ``t0 <= t1``, within both flights' times.
    exact : bool
        From exact evaluations of the references (True), or from their tables (tabled arc
        lengths every :data:`TABLE_DT_S` and curve points every :data:`TABLE_DS_M`, each an
        exact value: the bound is as certain, and looser by up to those steps).

    Returns
    -------
    tuple of numpy.ndarray, shape (N,)
        For each interval, a number at most the smallest horizontal distance over it, and one
        at most the smallest vertical distance [m] (possibly negative).
    """
    lo = np.asarray(t0, dtype=np.float64).reshape(-1)
    hi = np.asarray(t1, dtype=np.float64).reshape(-1)
    horizontal, vertical, radius = _gaps(a, b, lo, hi, exact)
    return horizontal - radius, vertical - radius


def _conflict(a: Flight, b: Flight, time_s: float, proven: bool, kind: str) -> Conflict:
    pa = a.positions(time_s)[0]
    pb = b.positions(time_s)[0]
    return Conflict(first=a.mission, second=b.mission, kind=kind, time_s=float(time_s),
                    horizontal_m=float(np.hypot(*(pa[:2] - pb[:2]))),
                    vertical_m=float(abs(pa[2] - pb[2])), proven=proven, first_position=pa,
                    second_position=pb)


def common_window(a: Flight, b: Flight) -> Optional[Tuple[float, float]]:
    """The batch time both flights are flying [s], None when they do not meet in time."""
    lo = max(a.start_s, b.start_s)
    hi = min(a.end_s, b.end_s)
    return (lo, hi) if hi >= lo else None


def first_conflict(a: Flight, b: Flight, envelope: Envelope,
                   tolerance_s: float = 1e-3) -> Optional[Conflict]:
    """A conflict between two flights, or None when they are proven apart at every instant.

    Parameters
    ----------
    a, b : Flight
        The candidate and a reserved flight.
    envelope : Envelope
    tolerance_s : float
        Stretches shorter than this [s] that are neither proven apart nor shown in conflict
        count as a conflict (``proven=False``).

    Returns
    -------
    Conflict or None
        The same vehicle flying both at once (even for an instant) is a ``'vehicle'``
        conflict at the start of the common time. Otherwise the first conflict the halving
        meets, the earliest stretches first (a deterministic choice, not always the earliest
        instant of conflict).
    """
    window = common_window(a, b)
    if window is None:
        return None
    lo, hi = window
    if a.vehicle == b.vehicle:
        return _conflict(a, b, lo, True, 'vehicle')
    h_sep, v_sep = float(envelope.horizontal_m), float(envelope.vertical_m)
    count = max(1, int(math.ceil((hi - lo) / FIRST_INTERVAL_S)))
    edges = lo + (hi - lo) * np.arange(count + 1) / count
    edges[-1] = hi
    # Tables first: intervals narrower than a table step that they leave open go to the
    # exact evaluation.
    narrow = TABLE_DT_S / min(a.time_scale, b.time_scale)
    hard: List[np.ndarray] = []
    found = _scan(a, b, h_sep, v_sep, [(edges[:-1], edges[1:])], False, narrow, hard)
    if found is None and hard:
        both = np.concatenate(hard)
        found = _scan(a, b, h_sep, v_sep, [(both[:, 0], both[:, 1])], True, tolerance_s, None)
    if found is None:
        return None
    time_s, proven = found
    return _conflict(a, b, time_s, proven, 'separation')


def _scan(a: Flight, b: Flight, h_sep: float, v_sep: float,
          pending: List[Tuple[np.ndarray, np.ndarray]], exact: bool, shortest: float,
          hard: Optional[List[np.ndarray]]) -> Optional[Tuple[float, bool]]:
    """Halve the pending intervals until each is proven apart, or one holds a proven conflict
    (its instant, True) or (``hard`` None) one shorter than ``shortest`` stays open (its
    middle, False); with ``hard`` given, open intervals shorter than ``shortest`` go there."""
    while pending:
        t0, t1 = pending.pop()
        horizontal, vertical, radius = _gaps(a, b, t0, t1, exact)
        open_ = (horizontal - radius < h_sep) & (vertical - radius < v_sep)
        if not open_.any():
            continue
        t0, t1 = t0[open_], t1[open_]
        middle = 0.5 * (t0 + t1)
        horizontal, vertical, radius = _gaps(a, b, middle, middle, exact)
        hit = (horizontal + radius < h_sep) & (vertical + radius < v_sep)
        if hit.any():
            return float(middle[np.argmax(hit)]), True
        short = (t1 - t0) < shortest
        if short.any():
            if hard is None:
                return float(middle[np.argmax(short)]), False
            hard.append(np.stack([t0[short], t1[short]], axis=1))
            t0, t1, middle = t0[~short], t1[~short], middle[~short]
        halves = np.stack([np.stack([t0, middle], axis=1), np.stack([middle, t1], axis=1)],
                          axis=1).reshape(-1, 2)
        # Latest blocks first on the stack, so the earliest stretch is handled next.
        for first in range(((len(halves) - 1) // _BLOCK) * _BLOCK, -1, -_BLOCK):
            block = halves[first:first + _BLOCK]
            pending.append((block[:, 0], block[:, 1]))
    return None
