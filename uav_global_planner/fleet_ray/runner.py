"""A fleet planned on Ray, with the same result as the serial reference for any number of workers.

:func:`plan_fleet_ray` runs :func:`~uav_global_planner.core.fleet.run_fleet`'s work on planner
actors:

1. the map is inflated once and put into the object store (:mod:`.shared_map`);
2. the base plans, pure functions of the map and the mission, are computed in parallel;
3. resolutions run ahead of their turn, each against the book as it is when it starts
   (speculation), and are committed strictly in the fleet order through the sharded airspace
   (:mod:`.airspace`). A resolution is committed when no flight committed after its book
   version meets its footprint (and none of the same vehicle overlaps it in time): it is then
   exactly what the serial runner computes. Otherwise it is refused as stale and the mission
   is resolved again against the current book, which nothing can change before it commits.

The outcome, the flights and their order therefore do not depend on the number of workers; the
workers only change how much runs at once.
"""

from dataclasses import dataclass, field
import math
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.fleet import (FleetResult, FleetSettings, Mission, MissionBatch,
                                           MissionError, MissionOutcome, ReservationBook)
from uav_global_planner.core.fleet.missions import batch_to_plan
from uav_global_planner.core.io.scene import Scene
from uav_global_planner.fleet_ray.airspace import make_airspace, ShardLayout
from uav_global_planner.fleet_ray.planner_actor import make_planners, Speculation
from uav_global_planner.fleet_ray.session import import_ray, ray_session
from uav_global_planner.fleet_ray.shared_map import build_shared_map

ray = import_ray()

Progress = Callable[[int, int, MissionOutcome], None]


@dataclass
class RunStats:
    """Where the time of a run went.

    Attributes
    ----------
    workers : int
    nodes : int
        Ray nodes alive.
    map_build_s, map_put_s : float
        Inflating the map on the driver, and putting it into the object store [s].
    map_bytes : int
        Bytes of the masks in the object store.
    zero_copy : bool
        Every planner reads the masks from shared memory without a copy.
    actors_ready_s : float
        Starting the actors until each has its planner [s].
    plan_s : float
        From the first task sent to the last commit [s].
    wall_s : float
        The whole run, from the map build on [s].
    base_plans, resolutions, stale : int
        Tasks run: base plans, resolutions (speculative ones and repeats included), and
        resolutions refused as stale at their commit.
    worker_busy_s : list of float
        Time each actor spent planning and resolving [s].
    commit_s : float
        Time the driver spent committing in order (the airspace round trips) [s].
    head_wait_s : float
        Time the driver waited with the next mission to commit not resolved yet [s].
    redo_s : float
        Actor time of the resolutions repeated after a stale commit [s]: work that nothing
        runs beside, as the commits wait for it.
    airspace_busy_s : list of float
        Time each airspace shard spent checking and filing [s].
    """

    workers: int = 0
    nodes: int = 0
    map_build_s: float = 0.0
    map_put_s: float = 0.0
    map_bytes: int = 0
    zero_copy: bool = False
    actors_ready_s: float = 0.0
    plan_s: float = 0.0
    wall_s: float = 0.0
    base_plans: int = 0
    resolutions: int = 0
    stale: int = 0
    worker_busy_s: List[float] = field(default_factory=list)
    commit_s: float = 0.0
    head_wait_s: float = 0.0
    redo_s: float = 0.0
    airspace_busy_s: List[float] = field(default_factory=list)


@dataclass(frozen=True, eq=False)
class FleetRun:
    """A fleet planned on Ray.

    Attributes
    ----------
    result : FleetResult
        As :func:`~uav_global_planner.core.fleet.run_fleet` gives it.
    stats : RunStats
    """

    result: FleetResult
    stats: RunStats


def default_layout(scene: Scene) -> ShardLayout:
    """2 x 2 area tiles over the map and 10 min time windows, on 4 shards."""
    config = scene.config
    return ShardLayout(xy_min=(float(config.bounds_min[0]), float(config.bounds_min[1])),
                       xy_max=(float(config.bounds_max[0]), float(config.bounds_max[1])),
                       tiles=2, window_s=600.0, shards=4)


def plan_fleet_ray(scene: Scene, missions: Union[MissionBatch, Sequence[Mission]],
                   settings: Optional[FleetSettings] = None, *, workers: int = 2,
                   address: Optional[str] = None, progress: Optional[Progress] = None,
                   layout: Optional[ShardLayout] = None,
                   temp_dir: Optional[str] = None) -> FleetRun:
    """Plan and deconflict a batch on Ray.

    Parameters
    ----------
    scene : Scene
        The map, with its ground applied (:func:`~uav_global_planner.core.io.scene.with_ground`).
    missions : MissionBatch or sequence of Mission
        As for :func:`~uav_global_planner.core.fleet.run_fleet`.
    settings : FleetSettings, optional
        Overrides the batch's settings.
    workers : int
        Planner actors, one CPU each, >= 1.
    address : str, optional
        A Ray cluster to join; None starts an embedded local one (or uses the Ray already
        running in this process).
    progress : callable, optional
        ``progress(done, total, outcome)`` after each commit, in the fleet order.
    layout : ShardLayout, optional
        How the airspace is sharded (:func:`default_layout` by default).
    temp_dir : str, optional
        Folder of the embedded cluster's files (see :func:`~.session.ray_session`).

    Returns
    -------
    FleetRun

    Raises
    ------
    InvalidInputError
        For ``workers`` < 1, or a cluster with fewer CPUs than workers.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InvalidInputError(f'workers must be an integer >= 1, got {workers!r}')
    with ray_session(address, num_cpus=workers, temp_dir=temp_dir) as info:
        if info.cpus < workers:
            raise InvalidInputError(f'--workers {workers}: the cluster has {info.cpus:g} CPUs')
        stats = RunStats(workers=workers, nodes=info.nodes)
        result = _plan(scene, missions, settings, workers, progress,
                       layout or default_layout(scene), stats)
        return FleetRun(result=result, stats=stats)


def _batch(scene: Scene, missions: Union[MissionBatch, Sequence[Mission]],
           settings: Optional[FleetSettings]
           ) -> Tuple[List[Mission], Tuple[MissionError, ...], FleetSettings]:
    """The missions to plan in the fleet order, the refused ones and the settings, as
    run_fleet finds them."""
    return batch_to_plan(missions, settings, (scene.config.bounds_min, scene.config.bounds_max))


class _Schedule:
    """The driver's view of the work: what each mission has, what each actor runs."""

    def __init__(self, count: int, actors: Sequence[Any], window: int) -> None:
        self.count = count
        self.actors = list(actors)
        self.window = window
        self.base: List[Any] = [None] * count           # base plan refs, once sent
        self.base_ready = [False] * count
        self.next_base = 0                              # next mission to send a base plan for
        self.resolving = [False] * count                # a resolution is running
        self.speculation: List[Optional[Speculation]] = [None] * count
        self.redo = [False] * count                     # resolved again after a stale commit
        self.flight: List[Any] = [None] * count        # the accepted flight's ref, if any
        self.running: Dict[Any, Tuple[int, str, int]] = {}   # ref -> (actor, kind, mission)
        self.idle = set(range(len(actors)))
        self.sent: List[int] = [0] * len(actors)        # book version each actor will have

    def waiting_for_resolution(self, head: int) -> Optional[int]:
        """The first mission from ``head`` on, within the window, whose base plan is ready
        and that has neither a resolution nor one running."""
        for index in range(head, min(self.count, head + self.window)):
            if (self.base_ready[index] and not self.resolving[index]
                    and self.speculation[index] is None):
                return index
        return None


def _plan(scene: Scene, missions: Union[MissionBatch, Sequence[Mission]],
          settings: Optional[FleetSettings], workers: int, progress: Optional[Progress],
          layout: ShardLayout, stats: RunStats) -> FleetResult:
    started = time.perf_counter()
    ordered, errors, settings = _batch(scene, missions, settings)
    shared = build_shared_map(scene)
    stats.map_build_s = time.perf_counter() - started
    put_started = time.perf_counter()
    shared_ref = ray.put(shared)
    stats.map_put_s = time.perf_counter() - put_started
    stats.map_bytes = shared.nbytes
    del shared
    ready_started = time.perf_counter()
    actors = make_planners(shared_ref, settings, workers)
    airspace = make_airspace(layout)
    try:
        stats.zero_copy = all(ray.get([actor.zero_copy.remote() for actor in actors]))
        stats.actors_ready_s = time.perf_counter() - ready_started

        plan_started = time.perf_counter()
        schedule = _Schedule(len(ordered), actors, window=max(4, 4 * workers))
        flights: List[Tuple[int, Any]] = []             # (sequence number, flight ref)
        spans: List[Tuple[str, float, float]] = []      # vehicle, start, end of each flight
        outcomes: List[MissionOutcome] = []
        accepted_flights = []
        head = 0

        def dispatch() -> None:
            for actor_id in sorted(schedule.idle):
                index = schedule.waiting_for_resolution(head)
                if index is not None:
                    version = len(flights)
                    news = [item for item in flights if item[0] >= schedule.sent[actor_id]]
                    ref, schedule.flight[index] = actors[actor_id].resolve.options(
                        num_returns=2).remote(index, ordered[index], schedule.base[index],
                                              version, news)
                    schedule.sent[actor_id] = version
                    schedule.resolving[index] = True
                    schedule.running[ref] = (actor_id, 'resolve', index)
                    stats.resolutions += 1
                elif schedule.next_base < schedule.count:
                    index = schedule.next_base
                    schedule.next_base += 1
                    ref = actors[actor_id].base_plan.remote(ordered[index])
                    schedule.base[index] = ref
                    schedule.running[ref] = (actor_id, 'base', index)
                    stats.base_plans += 1
                else:
                    continue
                schedule.idle.discard(actor_id)

        while head < len(ordered):
            dispatch()
            wait_started = time.perf_counter()
            done, _ = ray.wait(list(schedule.running), num_returns=1)
            if schedule.speculation[head] is None:
                stats.head_wait_s += time.perf_counter() - wait_started
            for ref in done:
                actor_id, kind, index = schedule.running.pop(ref)
                schedule.idle.add(actor_id)
                if kind == 'base':
                    schedule.base_ready[index] = True
                else:
                    schedule.resolving[index] = False
                    speculation = ray.get(ref)
                    schedule.speculation[index] = speculation
                    if schedule.redo[index]:
                        stats.redo_s += speculation.worker_s
            # Commit in the fleet order as far as resolutions are there.
            commit_started = time.perf_counter()
            while head < len(ordered) and schedule.speculation[head] is not None:
                speculation = schedule.speculation[head]
                assert speculation is not None
                resolution = speculation.resolution
                version = len(flights)
                handle = None
                ok = not _vehicle_overlap(spans, speculation, resolution.mission.vehicle)
                if ok:
                    handle = schedule.flight[head] if resolution.accepted else None
                    outcome = airspace.commit(version, speculation.footprint, speculation.seen,
                                              speculation.boxes, handle, wait=False)
                    ok = outcome.committed
                if not ok:
                    stats.stale += 1
                    schedule.speculation[head] = None       # resolved again at the current version
                    schedule.redo[head] = True
                    break
                if resolution.accepted:
                    flight = resolution.flight
                    assert flight is not None
                    flights.append((version, handle))
                    spans.append((flight.vehicle, flight.start_s, flight.end_s))
                    accepted_flights.append(flight)
                outcomes.append(MissionOutcome.of(resolution))
                schedule.speculation[head] = None
                head += 1
                if progress is not None:
                    progress(len(outcomes), len(ordered), outcomes[-1])
            stats.commit_s += time.perf_counter() - commit_started
        stats.plan_s = time.perf_counter() - plan_started
        stats.worker_busy_s = list(ray.get([actor.busy_s.remote() for actor in actors]))
        airspace.settle()
        stats.airspace_busy_s = airspace.busy_s()
    finally:
        # The actors end with the run, whatever happened (a Ray kept running for other
        # runs would keep them otherwise).
        for handle in [*actors, *airspace.shards]:
            ray.kill(handle)
    stats.wall_s = time.perf_counter() - started
    return FleetResult(outcomes=tuple(outcomes), errors=errors,
                       book=ReservationBook(settings, accepted_flights), settings=settings)


def _vehicle_overlap(spans: Sequence[Tuple[str, float, float]], speculation: Speculation,
                     vehicle: str) -> bool:
    """True when a flight committed since the speculation's version is flown by the same
    vehicle within the time span of the candidates it checked."""
    start, end = speculation.window
    if not math.isfinite(start):
        return False
    return any(name == vehicle and begin <= end and finish >= start
               for name, begin, finish in spans[speculation.seen:])
