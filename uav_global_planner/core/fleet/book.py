"""The reservation book: accepted flights in the order they were accepted, and their index.

Its ``version`` is the number of flights it holds; :meth:`ReservationBook.add` with an
``expected_version`` refuses to add over flights the caller has not checked against (an
optimistic lock, as a DSS does with operational intents), so a book shared by several workers
never takes two flights into one volume.
"""

from typing import Dict, Iterable, List, Optional, Tuple

import numpy as np

from uav_global_planner.core.fleet.index import SpaceTimeIndex
from uav_global_planner.core.fleet.missions import FleetSettings
from uav_global_planner.core.fleet.separation import (common_window, Conflict, Envelope,
                                                      first_conflict, Flight)


class StaleBookError(RuntimeError):
    """A flight was added against an older version of the book.

    Attributes
    ----------
    expected, actual : int
        The version the caller checked against and the book's.
    """

    def __init__(self, expected: int, actual: int) -> None:
        super().__init__(f'reservation book is at version {actual}, not {expected}: check the '
                         f'flights added since then first')
        self.expected = expected
        self.actual = actual

    def __reduce__(self) -> Tuple[type, Tuple[int, int]]:
        return (type(self), (self.expected, self.actual))


class ReservationBook:
    """Accepted flights, in order, with a space-time index.

    Parameters
    ----------
    settings : FleetSettings
        The envelope, the certification tolerance and the index cell sizes.
    flights : iterable of Flight
        Flights to take in order (without checks: they were accepted elsewhere).
    """

    def __init__(self, settings: FleetSettings, flights: Iterable[Flight] = ()) -> None:
        self.settings = settings
        self._flights: List[Flight] = []
        self._boxes: List[np.ndarray] = []
        self._by_vehicle: Dict[str, List[int]] = {}
        self._index = SpaceTimeIndex(settings.index_cell_m, settings.index_cell_z_m,
                                     settings.index_cell_s)
        for flight in flights:
            self.add(flight)

    @property
    def version(self) -> int:
        """Number of flights taken so far."""
        return len(self._flights)

    @property
    def flights(self) -> Tuple[Flight, ...]:
        """The flights in the order they were taken."""
        return tuple(self._flights)

    @property
    def index(self) -> SpaceTimeIndex:
        """The space-time index (keys are places in :attr:`flights`)."""
        return self._index

    def since(self, version: int) -> Tuple[Flight, ...]:
        """Flights taken after ``version``."""
        return tuple(self._flights[version:])

    def copy(self) -> 'ReservationBook':
        """An independent book with the same flights."""
        other = ReservationBook(self.settings)
        other._flights = list(self._flights)
        other._boxes = list(self._boxes)
        other._by_vehicle = {k: list(v) for k, v in self._by_vehicle.items()}
        other._index = SpaceTimeIndex(self._index.cell_m, self._index.cell_z_m,
                                      self._index.cell_s)
        for key, boxes in enumerate(self._boxes):
            other._index.insert(key, boxes)
        return other

    def add(self, flight: Flight, expected_version: Optional[int] = None) -> int:
        """Take a flight; returns the new version.

        Raises
        ------
        StaleBookError
            When ``expected_version`` is given and is not the book's version.
        """
        if expected_version is not None and expected_version != self.version:
            raise StaleBookError(expected_version, self.version)
        key = len(self._flights)
        boxes = self._index.boxes(flight)
        self._flights.append(flight)
        self._boxes.append(boxes)
        self._by_vehicle.setdefault(flight.vehicle, []).append(key)
        self._index.insert(key, boxes)
        return self.version

    def candidates(self, flight: Flight, envelope: Optional[Envelope] = None) -> List[int]:
        """Places of the flights that may conflict with ``flight`` (within ``envelope``, by
        default the book's): those near it in the index, and the same vehicle's flights that
        overlap it in time; sorted."""
        envelope = self.settings.envelope if envelope is None else envelope
        near = set(self._index.query(self._index.boxes(flight), envelope.horizontal_m,
                                     envelope.vertical_m))
        for key in self._by_vehicle.get(flight.vehicle, ()):
            if common_window(flight, self._flights[key]) is not None:
                near.add(key)
        return sorted(near)

    def conflicts_with(self, flight: Flight, first_only: bool = False,
                       settings: Optional[FleetSettings] = None) -> List[Conflict]:
        """Conflicts of ``flight`` with the flights in the book, in book order.

        Parameters
        ----------
        flight : Flight
            The candidate (not in the book).
        first_only : bool
            Stop at the first conflict.
        settings : FleetSettings, optional
            Envelope and certification tolerance to check with; the book's by default.
        """
        settings = self.settings if settings is None else settings
        envelope = settings.envelope
        found: List[Conflict] = []
        for key in self.candidates(flight, envelope):
            conflict = first_conflict(flight, self._flights[key], envelope,
                                      settings.time_tolerance_s)
            if conflict is not None:
                found.append(conflict)
                if first_only:
                    break
        return found

    def __len__(self) -> int:
        return len(self._flights)
