"""Planner actors: each plans missions on the shared map and resolves them against its own
copy of the reservation book.

An actor is built with the object reference of the :class:`~uav_global_planner.fleet_ray.
shared_map.SharedMap`; Ray hands it the masks as read-only views of the object store's shared
memory, so no actor builds or copies the grid. It keeps a :class:`~uav_global_planner.core.
fleet.ReservationBook` that follows the committed flights in commit order: each resolution
request carries the references of the flights committed since the actor last looked, which the
actor adds before resolving. A resolution records every candidate flight it checked against the
book (its footprint), which the airspace uses to tell whether flights committed meanwhile could
have changed it.
"""

from dataclasses import dataclass, replace
import time
from typing import Any, cast, Dict, List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.fleet import (Conflict, FleetSettings, Flight, flight_boxes,
                                           Mission, plan_mission, ReservationBook, Resolution,
                                           resolve)
from uav_global_planner.core.result import PlanResult
from uav_global_planner.fleet_ray.airspace import inflate
from uav_global_planner.fleet_ray.session import import_ray
from uav_global_planner.fleet_ray.shared_map import planner_from_map, SharedMap

ray = import_ray()


class RecordingBook:
    """A reservation book that notes every flight it is asked about.

    Parameters
    ----------
    book : ReservationBook
    """

    def __init__(self, book: ReservationBook) -> None:
        self._book = book
        #: The candidate flights checked, in the order asked.
        self.asked: List[Flight] = []

    @property
    def settings(self) -> FleetSettings:
        """The book's settings."""
        return self._book.settings

    @property
    def version(self) -> int:
        """The book's version."""
        return self._book.version

    def conflicts_with(self, flight: Flight, first_only: bool = False) -> List[Conflict]:
        """:meth:`ReservationBook.conflicts_with`, noting ``flight``."""
        self.asked.append(flight)
        return self._book.conflicts_with(flight, first_only=first_only)


def footprint(flights: Sequence[Flight], settings: FleetSettings, chunk_s: float) -> np.ndarray:
    """Boxes of the flights inflated by the separation envelope, shape (n, 8).

    Flights that differ only in their departure (the delays of one candidate) share their boxes,
    shifted in time; the times are widened by a microsecond for the rounding of the shift.
    """
    relative: Dict[Tuple[int, float], np.ndarray] = {}
    parts = []
    for flight in flights:
        key = (id(flight.reference), flight.time_scale)
        boxes = relative.get(key)
        if boxes is None:
            boxes = flight_boxes(flight, chunk_s)
            boxes[:, :2] -= flight.start_s
            relative[key] = boxes
        shifted = boxes.copy()
        shifted[:, :2] += flight.start_s
        parts.append(shifted)
    if not parts:
        return np.empty((0, 8))
    out = inflate(np.vstack(parts), settings.horizontal_separation,
                  settings.vertical_separation)
    out[:, 0] -= 1e-6
    out[:, 1] += 1e-6
    return out


@dataclass(frozen=True, eq=False)
class Speculation:
    """A resolution made against the book at some version, with what it looked at.

    Attributes
    ----------
    index : int
        The mission's place in the fleet order.
    resolution : Resolution
    seen : int
        The book version it was made against.
    footprint : numpy.ndarray, shape (n, 8)
        Inflated boxes of every candidate flight it checked.
    window : tuple of float
        Earliest start and latest end of those candidates [s] (for the same vehicle's flights).
    boxes : numpy.ndarray, shape (m, 8), or None
        The accepted flight's own boxes; None when rejected.
    worker_s : float
        Time the actor spent on it [s].
    """

    index: int
    resolution: Resolution
    seen: int
    footprint: np.ndarray
    window: Tuple[float, float]
    boxes: Optional[np.ndarray]
    worker_s: float


class PlannerActor:
    """Plans and resolves missions on the shared map (run as a Ray actor).

    Parameters
    ----------
    shared : SharedMap
        Passed as an object reference, so Ray maps it in without a copy.
    settings : FleetSettings
    """

    def __init__(self, shared: SharedMap, settings: FleetSettings) -> None:
        self._shared = shared
        self._planner = planner_from_map(shared)
        self._settings = settings
        self._book = ReservationBook(settings)
        self._busy_s = 0.0

    def zero_copy(self) -> bool:
        """True when the masks are read-only views of memory this actor does not own (the
        object store's), not copies."""
        mask = self._shared.blocked
        arrays: List[np.ndarray] = ([mask] if isinstance(mask, np.ndarray)
                                    else [mask.table, mask.pool])
        return all(not a.flags.writeable and not a.flags.owndata for a in arrays)

    def busy_s(self) -> float:
        """Time spent planning and resolving [s]."""
        return self._busy_s

    def base_plan(self, mission: Mission) -> PlanResult:
        """The mission's plan at its own altitude (:func:`plan_mission`)."""
        started = time.perf_counter()
        result = plan_mission(self._planner, mission, 0.0)
        self._busy_s += time.perf_counter() - started
        return result

    def resolve(self, index: int, mission: Mission, base: PlanResult, seen: int,
                new_flights: Sequence[Any]) -> Tuple[Speculation, Optional[Flight]]:
        """Resolve a mission against the book at version ``seen``.

        Called with ``num_returns=2``: the speculation, and the accepted flight on its own (None
        when rejected), so the driver hands the flight's reference to the airspace and the other
        actors without fetching and putting it again.

        Parameters
        ----------
        index : int
            Its place in the fleet order.
        mission : Mission
        base : PlanResult
            Its base plan (an object reference when sent).
        seen : int
            The book version to resolve against.
        new_flights : sequence of (int, ObjectRef)
            Sequence numbers and references of the flights committed since this actor's book
            version, up to ``seen``.

        Raises
        ------
        RuntimeError
            When the flights sent do not bring the book to ``seen``.
        """
        started = time.perf_counter()
        pending = [ref for seq, ref in sorted(new_flights, key=lambda item: item[0])
                   if seq >= self._book.version]
        for flight in (ray.get(pending) if pending else []):
            self._book.add(flight, expected_version=self._book.version)
        if self._book.version != seen:
            raise RuntimeError(f'book at version {self._book.version}, asked for {seen}')
        recording = RecordingBook(self._book)
        # resolve reads the book through conflicts_with only (its documented contract).
        resolution = resolve(mission, base, cast(ReservationBook, recording), self._settings,
                             plan_layer=lambda m, layer: plan_mission(self._planner, m, layer))
        chunk_s = self._book.index.chunk_s
        asked = recording.asked
        window = ((min(f.start_s for f in asked), max(f.end_s for f in asked)) if asked
                  else (np.inf, -np.inf))
        flight = resolution.flight if resolution.accepted else None
        if flight is not None:
            # Its table of exact values, built here once, travels with it to the other actors.
            flight.prepare()
        speculation = Speculation(
            index=index, resolution=resolution, seen=seen,
            footprint=footprint(asked, self._settings, chunk_s), window=window,
            boxes=None if flight is None else flight_boxes(flight, chunk_s), worker_s=0.0)
        spent = time.perf_counter() - started
        self._busy_s += spent
        return replace(speculation, worker_s=spent), flight

    def book_version(self) -> int:
        """The version of this actor's copy of the book."""
        return self._book.version


def make_planners(shared_ref: Any, settings: FleetSettings, count: int) -> List[Any]:
    """Start ``count`` planner actors, one CPU each, on the map behind ``shared_ref``."""
    remote = ray.remote(num_cpus=1)(PlannerActor)
    return [remote.remote(shared_ref, settings) for _ in range(count)]
