"""Deterministic resolution of one mission against the reservation book.

In order, the first option clear of every reserved flight is taken:

1. the base plan at the earliest departure (accepted as planned);
2. the base plan delayed by ``delay_step_s``, ``2 delay_step_s``, ... up to ``max_delay_s``;
3. each altitude layer in turn (the mission replanned through its start, via-points and goal
   raised by the offset: climb at the start, fly the layer, descend at the goal), at each
   delay from 0;
4. each speed factor in turn (the base curve flown slower: every speed times the factor, so
   every limit the plan proves still holds), at each delay from 0;
5. otherwise the mission is rejected, with the reason.

:func:`resolve` reads nothing but its arguments, and the book only through its flights in
order: its result is a function of the mission, its base plan, the plans of its layers, the
book's flights and the settings, whoever computes it.
"""

from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.fleet.book import ReservationBook
from uav_global_planner.core.fleet.missions import FleetSettings, Mission
from uav_global_planner.core.fleet.separation import Conflict, Flight
from uav_global_planner.core.result import PlanResult

#: ``plan(mission, layer_m)``: the plan of ``mission`` raised by ``layer_m`` metres
#: (:func:`plan_mission` with a planner of the map); 0 gives the base plan.
PlanFunction = Callable[[Mission, float], PlanResult]


def mission_request(mission: Mission, layer_m: float = 0.0
                    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start, goal and via-points [m] to plan for ``mission`` in the layer ``layer_m`` [m].

    The base request (``layer_m == 0``) is the mission's own; a layer adds via-points above
    the start, above each via-point and above the goal.
    """
    if layer_m == 0.0:
        return mission.start, mission.goal, mission.via
    up = np.array([0.0, 0.0, float(layer_m)])
    via = np.vstack([mission.start + up, mission.via.reshape(-1, 3) + up, mission.goal + up])
    return mission.start, mission.goal, via


def plan_mission(planner: Any, mission: Mission, layer_m: float = 0.0) -> PlanResult:
    """Plan ``mission`` (in the layer ``layer_m`` [m]) with ``planner``
    (:class:`~uav_global_planner.core.planner.Planner` of the map).

    A pure function of the map, the planner's settings and the mission: the base plans of a
    batch may be computed in any order, by any number of workers.
    """
    start, goal, via = mission_request(mission, layer_m)
    return planner.plan(start, goal, via=[tuple(point) for point in via])


@dataclass(frozen=True)
class ResolutionStep:
    """One option tried.

    Attributes
    ----------
    action : str
        ``'plan'``, ``'delay'``, ``'layer'`` or ``'speed'``.
    delay_s : float
        Delay of the departure [s].
    layer_m : float
        Altitude offset [m].
    speed_factor : float
        Speed factor [-].
    clear : bool
        True when the option was clear of every reserved flight.
    conflict : Conflict or None
        The first conflict of the option; None when clear or when it had no plan.
    message : str
        What happened, in words.
    """

    action: str
    delay_s: float
    layer_m: float
    speed_factor: float
    clear: bool
    conflict: Optional[Conflict]
    message: str

    def to_dict(self) -> Dict[str, Any]:
        """The step as JSON-ready values."""
        return {'action': self.action, 'delay_s': self.delay_s, 'layer_m': self.layer_m,
                'speed_factor': self.speed_factor, 'clear': self.clear,
                'conflict': None if self.conflict is None else self.conflict.to_dict(),
                'message': self.message}


@dataclass(frozen=True, eq=False)
class Resolution:
    """How a mission was resolved.

    Attributes
    ----------
    mission : Mission
    accepted : bool
    reason : str
        How it was accepted, or why it was rejected.
    flight : Flight or None
        The accepted flight.
    plan : PlanResult or None
        The plan the flight flies (the base plan or a layer's); None when rejected.
    steps : tuple of ResolutionStep
        The options tried, in order.
    conflicts : tuple of Conflict
        Every conflict of the base plan at the earliest departure with the reserved flights.
    """

    mission: Mission
    accepted: bool
    reason: str
    flight: Optional[Flight]
    plan: Optional[PlanResult]
    steps: Tuple[ResolutionStep, ...]
    conflicts: Tuple[Conflict, ...]


def _usable(plan: Optional[PlanResult]) -> bool:
    return (plan is not None and plan.ok and plan.trajectory is not None
            and plan.trajectory.reference is not None)


def _describe(conflict: Optional[Conflict]) -> str:
    if conflict is None:
        return 'clear'
    if conflict.kind == 'vehicle':
        return f'vehicle also flies {conflict.second} at {conflict.time_s:.1f} s'
    word = 'conflict' if conflict.proven else 'unproven separation'
    return (f'{word} with {conflict.second} at {conflict.time_s:.3f} s '
            f'(horizontal {conflict.horizontal_m:.1f} m, vertical {conflict.vertical_m:.1f} m)')


def resolve(mission: Mission, base: Optional[PlanResult], book: ReservationBook,
            settings: FleetSettings, plan_layer: Optional[PlanFunction] = None) -> Resolution:
    """Resolve ``mission`` against the flights in ``book``.

    Parameters
    ----------
    mission : Mission
    base : PlanResult or None
        Its base plan (:func:`plan_mission` with ``layer_m = 0``); a failed plan rejects it.
    book : ReservationBook
        The flights reserved before it, read only through
        :meth:`~ReservationBook.conflicts_with` (with the book's envelope and tolerance) and
        ``settings``; not changed.
    settings : FleetSettings
        The resolution options (delays, layers, speed factors); its envelope and tolerance
        must be the book's.
    plan_layer : PlanFunction, optional
        Plans the altitude layers; without it the layers are skipped.

    Returns
    -------
    Resolution

    Raises
    ------
    InvalidInputError
        When ``settings`` and the book's settings disagree on the envelope or tolerance.
    """
    ours, books = settings, book.settings
    if ours.envelope != books.envelope or ours.time_tolerance_s != books.time_tolerance_s:
        raise InvalidInputError(
            f'settings: separation {ours.envelope} and time_tolerance_s '
            f'{ours.time_tolerance_s} differ from those of the reservation book: '
            f'{books.envelope}, {books.time_tolerance_s}')
    steps: List[ResolutionStep] = []
    if not _usable(base):
        message = 'no plan' if base is None else \
            f'no plan: {base.status.value}: {base.message}'
        steps.append(ResolutionStep('plan', 0.0, 0.0, 1.0, False, None, message))
        return Resolution(mission, False, message, None, None, tuple(steps), ())
    assert base is not None and base.trajectory is not None
    flight = Flight(mission.name, mission.vehicle, base.trajectory.reference,
                    float(mission.departure_s))
    conflicts = tuple(book.conflicts_with(flight))
    delays = settings.delays()

    def attempt(action: str, candidate: Flight, delay: float) -> bool:
        if delay or action != 'plan':
            found = book.conflicts_with(candidate, first_only=True)
        else:
            found = list(conflicts[:1])
        conflict = found[0] if found else None
        steps.append(ResolutionStep(action, float(delay), candidate.layer_m,
                                    candidate.speed_factor, conflict is None, conflict,
                                    _describe(conflict)))
        return conflict is None

    def accepted(candidate: Flight, plan: PlanResult, reason: str) -> Resolution:
        return Resolution(mission, True, reason, candidate, plan, tuple(steps), conflicts)

    if attempt('plan', flight, 0.0):
        return accepted(flight, base, 'accepted as planned')
    for delay in delays[1:]:
        if attempt('delay', flight.delayed(delay), delay):
            return accepted(flight.delayed(delay), base, f'delayed by {delay:g} s')
    for layer in settings.altitude_layers:
        if plan_layer is None:
            steps.append(ResolutionStep('layer', 0.0, layer, 1.0, False, None,
                                        'no planner for altitude layers'))
            continue
        plan = plan_layer(mission, layer)
        if not _usable(plan):
            steps.append(ResolutionStep('layer', 0.0, layer, 1.0, False, None,
                                        f'no plan in layer {layer:+g} m: {plan.status.value}: '
                                        f'{plan.message}'))
            continue
        assert plan.trajectory is not None
        raised = Flight(mission.name, mission.vehicle, plan.trajectory.reference,
                        float(mission.departure_s), layer_m=float(layer))
        for delay in delays:
            if attempt('layer', raised.delayed(delay), delay):
                return accepted(raised.delayed(delay), plan,
                                f'altitude layer {layer:+g} m'
                                + (f', delayed by {delay:g} s' if delay else ''))
    for factor in settings.speed_factors:
        slow = flight.slowed(factor)
        for delay in delays:
            if attempt('speed', slow.delayed(delay), delay):
                return accepted(slow.delayed(delay), base,
                                f'speed factor {factor:g}'
                                + (f', delayed by {delay:g} s' if delay else ''))
    first = conflicts[0] if conflicts else None
    names = sorted({conflict.second for conflict in conflicts})
    reason = (f'rejected: {_describe(first)}'
              + (f' (conflicts with {", ".join(names)})' if len(names) > 1 else '')
              + f'; no delay up to {settings.max_delay_s:g} s'
              + (f', altitude layer ({", ".join(f"{x:+g}" for x in settings.altitude_layers)}'
                 ' m)' if settings.altitude_layers else '')
              + (f', speed factor ({", ".join(f"{x:g}" for x in settings.speed_factors)})'
                 if settings.speed_factors else '')
              + ' clears it')
    return Resolution(mission, False, reason, None, None, tuple(steps), conflicts)
