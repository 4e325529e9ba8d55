"""Strategic deconfliction of a fleet's missions on one map: missions as 4D reservations.

Every mission's timed trajectory (the exact continuous reference of a plan, flown from its
departure in the batch clock) swept by a separation envelope (``horizontal_separation`` and
``vertical_separation``, a cylinder around the vehicle) is its reservation. Two flights
conflict when, at one instant, their horizontal distance is below the horizontal separation and
their vertical distance below the vertical one. A flight occupies the airspace from its
departure to its arrival only.

Public API (every name below is importable from this package; no ray, no rclpy):

``missions``
    :class:`Mission` (name, vehicle, departure_s [s, batch clock], start, via, goal [m, ENU
    map frame], priority: larger first), :class:`FleetSettings` (separations [m], delay bound
    and step [s], altitude layers [m], speed factors, certification time tolerance [s], index
    cell sizes), :class:`MissionError`, :class:`MissionBatch`,
    :func:`load_missions` (YAML path or mapping -> batch of valid missions and the errors of
    the others), :func:`check_missions`, :func:`fleet_order` (priority, departure, name).
``separation``
    :class:`Envelope`, :class:`Flight` (a timed reference placed at a departure, optionally
    slowed along the same curve; :meth:`Flight.sample` gives times and positions),
    :class:`Conflict`, :func:`first_conflict` (certified, continuous time),
    :func:`distance_bounds` (certified lower bounds of the distances over time intervals),
    :func:`common_window` (the time two flights are both flying).
``index``
    :class:`SpaceTimeIndex` (x, y, z, t cells of envelope boxes), :func:`flight_boxes`,
    :func:`box_cells`.
``book``
    :class:`ReservationBook` (accepted flights in order, ``version``, :meth:`add` with an
    expected version, :meth:`conflicts_with`, :meth:`since`), :class:`StaleBookError`.
``resolve``
    :func:`mission_request`, :func:`plan_mission` (one mission's plan: a pure function of the
    planner's map and the mission), :func:`resolve` (accept, delay, altitude layer, speed
    change, else reject: a pure function of the mission, its base plan, the book's ordered
    flights and the settings), :class:`Resolution`, :class:`ResolutionStep`.
``runner``
    :func:`run_fleet` (serial reference: plans, then resolves in :func:`fleet_order`),
    :class:`FleetResult`, :class:`MissionOutcome`.
"""

from uav_global_planner.core.fleet.book import ReservationBook, StaleBookError
from uav_global_planner.core.fleet.index import box_cells, flight_boxes, SpaceTimeIndex
from uav_global_planner.core.fleet.missions import (check_missions, fleet_order, FleetSettings,
                                                    load_missions, Mission, MissionBatch,
                                                    MissionError)
from uav_global_planner.core.fleet.resolve import (mission_request, plan_mission, PlanFunction,
                                                   Resolution, ResolutionStep, resolve)
from uav_global_planner.core.fleet.runner import FleetResult, MissionOutcome, run_fleet
from uav_global_planner.core.fleet.separation import (common_window, Conflict,
                                                      distance_bounds, Envelope, first_conflict,
                                                      Flight)

__all__ = [
    'Mission', 'FleetSettings', 'MissionError', 'MissionBatch', 'load_missions',
    'check_missions', 'fleet_order',
    'Envelope', 'Flight', 'Conflict', 'first_conflict', 'distance_bounds', 'common_window',
    'SpaceTimeIndex', 'flight_boxes', 'box_cells',
    'ReservationBook', 'StaleBookError',
    'PlanFunction', 'mission_request', 'plan_mission', 'resolve', 'Resolution',
    'ResolutionStep',
    'run_fleet', 'FleetResult', 'MissionOutcome',
]
