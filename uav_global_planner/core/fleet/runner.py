"""Serial fleet planning: every mission planned, then resolved in the fleet order.

This is the reference a parallel runner must reproduce: missions are resolved in
:func:`~uav_global_planner.core.fleet.missions.fleet_order` (priority, departure, name), each
against the flights accepted before it, with
:func:`~uav_global_planner.core.fleet.resolve.resolve`.
"""

from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from uav_global_planner.core.fleet.book import ReservationBook
from uav_global_planner.core.fleet.missions import (batch_to_plan, FleetSettings, Mission,
                                                    MissionBatch, MissionError)
from uav_global_planner.core.fleet.resolve import (plan_mission, PlanFunction, Resolution,
                                                   ResolutionStep, resolve)
from uav_global_planner.core.fleet.separation import Conflict, Flight
from uav_global_planner.core.result import PlanResult


@dataclass(frozen=True, eq=False)
class MissionOutcome:
    """What became of one mission.

    Attributes
    ----------
    name, vehicle : str
    accepted : bool
    reason : str
    requested_departure_s, departure_s : float
        Earliest departure asked for and departure used [s] (NaN when rejected).
    layer_m, speed_factor : float
        Altitude layer [m] and speed factor of the accepted flight.
    steps : tuple of ResolutionStep
    conflicts : tuple of Conflict
        Conflicts of its base plan with the flights accepted before it.
    flight : Flight or None
    plan : PlanResult or None
        The plan it flies (a layer's plan when moved to a layer).
    """

    name: str
    vehicle: str
    accepted: bool
    reason: str
    requested_departure_s: float
    departure_s: float
    layer_m: float
    speed_factor: float
    steps: Tuple[ResolutionStep, ...]
    conflicts: Tuple[Conflict, ...]
    flight: Optional[Flight]
    plan: Optional[PlanResult]

    @classmethod
    def of(cls, resolution: Resolution) -> 'MissionOutcome':
        """The outcome of a resolution."""
        flight = resolution.flight
        mission = resolution.mission
        return cls(name=mission.name, vehicle=mission.vehicle, accepted=resolution.accepted,
                   reason=resolution.reason, requested_departure_s=mission.departure_s,
                   departure_s=flight.departure_s if flight else float('nan'),
                   layer_m=flight.layer_m if flight else 0.0,
                   speed_factor=flight.speed_factor if flight else 1.0,
                   steps=resolution.steps, conflicts=resolution.conflicts, flight=flight,
                   plan=resolution.plan)

    def to_dict(self, step_s: float = 1.0) -> Dict[str, Any]:
        """JSON-ready values; an accepted mission's trajectory as ``times`` [s, batch clock]
        and ``positions`` [m] every ``step_s`` seconds."""
        out: Dict[str, Any] = {
            'name': self.name, 'vehicle': self.vehicle, 'accepted': self.accepted,
            'reason': self.reason, 'requested_departure_s': self.requested_departure_s,
            'departure_s': None if not self.accepted else self.departure_s,
            'layer_m': self.layer_m, 'speed_factor': self.speed_factor,
            'conflicts': [c.to_dict() for c in self.conflicts],
            'steps': [s.to_dict() for s in self.steps]}
        if self.flight is not None:
            times, positions = self.flight.sample(step_s)
            out['times'] = times.tolist()
            out['positions'] = positions.tolist()
        return out


@dataclass(frozen=True, eq=False)
class FleetResult:
    """A batch deconflicted.

    Attributes
    ----------
    outcomes : tuple of MissionOutcome
        In the fleet order.
    errors : tuple of MissionError
        Missions refused before planning.
    book : ReservationBook
        The accepted flights.
    settings : FleetSettings
    """

    outcomes: Tuple[MissionOutcome, ...]
    errors: Tuple[MissionError, ...]
    book: ReservationBook
    settings: FleetSettings

    @property
    def accepted(self) -> Tuple[MissionOutcome, ...]:
        """The accepted missions."""
        return tuple(o for o in self.outcomes if o.accepted)

    @property
    def rejected(self) -> Tuple[MissionOutcome, ...]:
        """The rejected missions (planned but not resolved, or without a plan)."""
        return tuple(o for o in self.outcomes if not o.accepted)

    @property
    def conflicts(self) -> Tuple[Conflict, ...]:
        """Every conflict found between a base plan and the flights accepted before it."""
        return tuple(c for o in self.outcomes for c in o.conflicts)

    def to_dict(self, step_s: float = 1.0) -> Dict[str, Any]:
        """The whole result as JSON-ready values (see :meth:`MissionOutcome.to_dict`)."""
        s = self.settings
        return {'settings': {'horizontal_separation': s.horizontal_separation,
                             'vertical_separation': s.vertical_separation,
                             'max_delay_s': s.max_delay_s, 'delay_step_s': s.delay_step_s,
                             'altitude_layers': list(s.altitude_layers),
                             'speed_factors': list(s.speed_factors),
                             'time_tolerance_s': s.time_tolerance_s},
                'errors': [{'mission': e.mission, 'setting': e.setting, 'message': e.message}
                           for e in self.errors],
                'missions': [o.to_dict(step_s) for o in self.outcomes]}


def run_fleet(planner: Any, missions: Union[MissionBatch, Sequence[Mission]],
              settings: Optional[FleetSettings] = None, *,
              base_plans: Optional[Mapping[str, PlanResult]] = None,
              plan_layer: Optional[PlanFunction] = None,
              progress: Optional[Callable[[int, int, MissionOutcome], None]] = None
              ) -> FleetResult:
    """Plan and deconflict a batch, one mission after the other.

    Parameters
    ----------
    planner : Planner or None
        :class:`~uav_global_planner.core.planner.Planner` of the map; its bounds refuse the
        missions outside the map. May be None when ``base_plans`` holds every plan and
        ``plan_layer`` is given (or no layers are wanted).
    missions : MissionBatch or sequence of Mission
        A batch brings its settings and the errors of its refused missions.
    settings : FleetSettings, optional
        Overrides the batch's settings; the defaults for a plain sequence.
    base_plans : mapping of str to PlanResult, optional
        Base plans already computed (:func:`plan_mission` with ``layer_m = 0``), by mission
        name; the others are planned here.
    plan_layer : PlanFunction, optional
        Plans the altitude layers; by default :func:`plan_mission` with ``planner``.
    progress : callable, optional
        ``progress(done, total, outcome)`` after each mission.

    Returns
    -------
    FleetResult
    """
    bounds = None
    if planner is not None:
        bounds = (planner.config.bounds_min, planner.config.bounds_max)
    ordered, errors, settings = batch_to_plan(missions, settings, bounds)
    plans = dict(base_plans or {})
    if plan_layer is None and planner is not None:
        def plan_layer(mission: Mission, layer_m: float) -> PlanResult:
            return plan_mission(planner, mission, layer_m)
    book = ReservationBook(settings)
    outcomes: List[MissionOutcome] = []
    for mission in ordered:
        base = plans.get(mission.name)
        if base is None and planner is not None:
            base = plan_mission(planner, mission)
        resolution = resolve(mission, base, book, settings, plan_layer)
        if resolution.accepted:
            assert resolution.flight is not None
            book.add(resolution.flight)
        outcome = MissionOutcome.of(resolution)
        outcomes.append(outcome)
        if progress is not None:
            progress(len(outcomes), len(ordered), outcome)
    return FleetResult(outcomes=tuple(outcomes), errors=errors, book=book, settings=settings)
