"""What the next plan of the planner node uses: a part of the node that the worker waits on.

Every other part hands the planning worker its work through :class:`PlanningInputs`: the
settings in force (the parameter callbacks), the newest map (the map intake, under the plan in
force's release lock), the active goal and the vehicle's position (the command topics), replans
owed to the active goal, and the requests of the Nav2 interfaces and the mission export. The
worker takes a :class:`~uav_global_planner.ros.node_state.Snapshot` of them when a plan begins.
"""

import threading
from typing import Callable, List, Optional, Tuple

import numpy as np

from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.live_map import LiveMap
from uav_global_planner.core.planner import Planner
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_state import Goal, InForce, Snapshot
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.terrain_source import TerrainState

#: A request of the Nav2 interfaces or the mission export, run by the worker after a step.
Job = Callable[[Planner, Snapshot], None]


class PlanningInputs:
    """The settings, map, goal, start and requests the next plan uses.

    One condition, ``_inputs_changed``, guards every attribute; the planning worker waits on it
    for work. It is taken after the plan in force's release lock when both are held, and no
    other lock is taken while it is held.

    Parameters
    ----------
    settings : NodeSettings
        The settings at start-up.
    live : LiveMap
        The map at start-up.
    prior_refusal : str
        Why ``map_file`` was refused at start-up ('' when it was not; it is read once).
    """

    def __init__(self, settings: NodeSettings, live: LiveMap, prior_refusal: str) -> None:
        self._inputs_changed = threading.Condition()
        self._prior_refusal = prior_refusal
        self._settings = settings
        self._settings_changed = False
        # The newest map (installed by the intake under the plan in force's release lock).
        self._map = live
        self._map_changed = False
        # Header stamp of the map message that last changed the obstacles, and of the newest
        # map message taken in [ns] (0: none yet); reported with every plan.
        self._obstacles_stamp_ns = 0
        self._map_stamp_ns = 0
        self._goal: Optional[Goal] = None
        self._goal_serial = 0
        self._goal_changed = False
        # The vehicle's position [m] (None: only the start parameter) and where it came from.
        self._start: Optional[np.ndarray] = None
        self._start_source = StartSource.PARAMETER
        self._stopping = False
        # A replan the worker owes the active goal (the plan in force was withdrawn, or it
        # started at the start parameter and the vehicle's position arrived): the reason.
        self._replan_request: Optional[str] = None
        # The map the worker plans on (its mask is never rewritten while held).
        self._worker_map: Optional[LiveMap] = None
        # Start source of the plan in force; None: none in force, or not for the active goal.
        self._in_force_source: Optional[StartSource] = None
        # Serials of the map shapes (geofence, ground, band) asked for and of those the map
        # holds: the worker takes no snapshot while the map lacks shapes asked for.
        self._shapes_requested = 0
        self._shapes_applied = 0
        self._jobs: List[Job] = []
        # The geofence and the terrain_file in force (None: not read yet).
        self._airspace = Airspace()
        self._terrain: Optional[TerrainState] = None

    # ------------------------------------------------------------------------- settings

    def current_settings(self) -> NodeSettings:
        """The settings in force (any thread)."""
        with self._inputs_changed:
            return self._settings

    def replace_settings(self, settings: NodeSettings) -> bool:
        """Put ``settings`` in force from the next plan (a running plan with other settings is
        cancelled). A new frame clears the goal and the vehicle's position (data stamped in
        the old frame means nothing in the new one). Returns True when the frame changed."""
        with self._inputs_changed:
            previous = self._settings
            self._settings = settings
            frame_changed = (conv.normalize_frame(settings.frame_id)
                             != conv.normalize_frame(previous.frame_id))
            if frame_changed:
                self._goal, self._start, self._start_source = None, None, StartSource.PARAMETER
            start_matters = (self._start is None
                             and not np.array_equal(settings.start, previous.start))
            if settings.config != previous.config or start_matters:
                self._settings_changed = True
            self._inputs_changed.notify_all()
            return frame_changed

    def airspace(self) -> Airspace:
        """The geofence in force (any thread)."""
        with self._inputs_changed:
            return self._airspace

    def set_airspace(self, airspace: Airspace) -> None:
        """Put a geofence in force (the intake joins it to the map)."""
        with self._inputs_changed:
            self._airspace = airspace

    def terrain(self) -> Optional[TerrainState]:
        """The terrain_file in force (None: not read yet)."""
        with self._inputs_changed:
            return self._terrain

    def set_terrain(self, state: TerrainState) -> None:
        """Put a terrain read in force (the intake turns it into ground shapes)."""
        with self._inputs_changed:
            self._terrain = state

    def map_refusal(self) -> str:
        """Why ``map_file`` or ``terrain_file`` was refused, with what to do ('' when neither
        was): no request is planned without the map or the terrain asked for (any thread)."""
        if self._prior_refusal:
            return (f'map_file refused: {self._prior_refusal}; restart the node with a map '
                    'file that can be used, or with map_file empty')
        terrain = self.terrain()
        if terrain is not None and terrain.refusal:
            return (f'terrain_file refused: {terrain.refusal}; restart the node with a terrain '
                    'file that can be used (or set bounds or geodetic_origin it covers), or '
                    'with terrain_file empty')
        return ''

    # ---------------------------------------------------------------------------- map

    def newest_map(self) -> LiveMap:
        """The newest map installed (any thread)."""
        with self._inputs_changed:
            return self._map

    def map_stamps(self) -> Tuple[int, int]:
        """Header stamps [ns] of the map message that last changed the obstacles and of the
        newest one taken in (0: none yet)."""
        with self._inputs_changed:
            return self._obstacles_stamp_ns, self._map_stamp_ns

    def held_map(self) -> Optional[LiveMap]:
        """The map the worker plans on (the intake never rewrites its mask)."""
        with self._inputs_changed:
            return self._worker_map

    def install_map(self, live: LiveMap, stamp_ns: int, withdrawn: Optional[InForce],
                    replan_on_obstacle_change: bool, geofence_changed: bool) -> None:
        """The intake's new map, for the next plan (called under the plan in force's release
        lock, after the plan in force was checked against ``live``).

        Parameters
        ----------
        live : LiveMap
        stamp_ns : int
            Header stamp of the newest map message that changed the obstacles [ns] (0: none).
        withdrawn : InForce, optional
            The plan in force ``live`` made collide: the active goal's is planned again (when
            ``replan_on_obstacle_change``). A Nav2 request's is not: its client asks again.
        replan_on_obstacle_change : bool
        geofence_changed : bool
            A new geofence replans the active goal on the map that holds it.
        """
        with self._inputs_changed:
            if live.version != self._map.version:
                self._obstacles_stamp_ns = stamp_ns
                self._map_stamp_ns = max(self._map_stamp_ns, stamp_ns)
            self._map = live
            self._map_changed = True
            goal = self._goal
            if (withdrawn is not None and replan_on_obstacle_change and goal is not None
                    and withdrawn.goal_serial == goal.serial):
                self._replan_request = ('the plan in force was withdrawn: the new map makes it '
                                        'collide')
            if geofence_changed and goal is not None:
                self._replan_request = self._replan_request or 'the geofence changed'
            self._inputs_changed.notify_all()

    def set_start_map(self, live: LiveMap) -> None:
        """The map at start-up, with the geofence and ground shapes (before the threads)."""
        with self._inputs_changed:
            self._map = live

    def request_shapes(self) -> int:
        """A new serial of the map's own shapes (geofence, ground, band): the worker takes no
        snapshot until the intake has built a map with them (:meth:`shapes_applied`)."""
        with self._inputs_changed:
            self._shapes_requested += 1
            return self._shapes_requested

    def shapes_applied(self, serial: int) -> None:
        """The intake built a map with every shapes request up to ``serial``."""
        with self._inputs_changed:
            self._shapes_applied = max(self._shapes_applied, serial)
            self._inputs_changed.notify_all()

    # --------------------------------------------------------------------- goal and start

    def new_goal(self, position: np.ndarray, orientation: np.ndarray) -> None:
        """Make a goal the active one (the latest goal wins)."""
        with self._inputs_changed:
            self._goal_serial += 1
            self._goal = Goal(position, orientation, self._goal_serial)
            self._goal_changed = True
            self._inputs_changed.notify_all()

    def active_goal(self) -> Optional[Goal]:
        """The active goal (None: none)."""
        with self._inputs_changed:
            return self._goal

    def goal_is(self, goal: Goal) -> bool:
        """True while ``goal`` is the active goal."""
        with self._inputs_changed:
            return self._goal is not None and self._goal.serial == goal.serial

    def set_vehicle(self, position: np.ndarray, source: StartSource) -> None:
        """The vehicle's newest position [m]; a plan in force that began at the start
        parameter is made again from it."""
        with self._inputs_changed:
            self._start, self._start_source = position, source
            if self._in_force_source == StartSource.PARAMETER and self._goal is not None:
                # The plan in force began at the start parameter, not where the vehicle is.
                self._in_force_source = None
                self._replan_request = (f'the vehicle position arrived on {source}; the plan '
                                        'in force started at the start parameter')
                self._inputs_changed.notify_all()

    def vehicle(self) -> Tuple[Optional[np.ndarray], StartSource]:
        """The vehicle's position [m] (None: only the start parameter) and its source."""
        with self._inputs_changed:
            return self._start, self._start_source

    def vehicle_position(self) -> Optional[np.ndarray]:
        """The vehicle's position [m] (None: only the start parameter is known)."""
        with self._inputs_changed:
            return self._start if self._start_source != StartSource.PARAMETER else None

    def set_in_force_source(self, source: Optional[StartSource]) -> None:
        """Start source of the plan in force for the active goal (None: none in force, or a
        Nav2 request's plan)."""
        with self._inputs_changed:
            self._in_force_source = source

    # --------------------------------------------------------------------- the worker's

    def request_replan(self, reason: str) -> None:
        """Ask the worker to plan the active goal again, for ``reason``."""
        with self._inputs_changed:
            self._replan_request = reason
            self._inputs_changed.notify_all()

    def submit(self, job: Job) -> None:
        """Run ``job(planner, snapshot)`` on the worker after the pending settings and map are
        applied; returns at once."""
        with self._inputs_changed:
            self._jobs.append(job)
            self._inputs_changed.notify_all()

    def take_jobs(self) -> List[Job]:
        """The requests waiting for the worker (they are the worker's from now on)."""
        with self._inputs_changed:
            jobs, self._jobs = self._jobs, []
            return jobs

    def stop(self) -> None:
        """The node shuts down: wake the worker so that it ends."""
        with self._inputs_changed:
            self._stopping = True
            self._inputs_changed.notify_all()

    def is_stopping(self) -> bool:
        """True once the node shuts down."""
        with self._inputs_changed:
            return self._stopping

    def cancel_state(self, goal: Goal, settings: NodeSettings) -> Tuple[bool, bool]:
        """For the plan of ``goal`` with ``settings``: (cancel it now: shutdown, no goal or
        other settings; a newer goal is active)."""
        with self._inputs_changed:
            if (self._stopping or self._goal is None
                    or (self._settings_changed and self._settings.config != settings.config)):
                return True, False
            return False, self._goal.serial != goal.serial

    def take_snapshot(self, applied_map: Optional[LiveMap]) -> Optional[Snapshot]:
        """Wait for work; copy what the next step needs and clear the change flags (None: the
        node shuts down). ``applied_map``: the map the planner holds (before the first
        snapshot)."""
        with self._inputs_changed:
            self._inputs_changed.wait_for(lambda: self._stopping or (
                self._shapes_applied >= self._shapes_requested
                and (self._goal_changed or self._settings_changed or self._map_changed
                     or self._replan_request is not None or bool(self._jobs))))
            if self._stopping:
                return None
            settings = self._settings
            if self._start is not None:
                start, source = self._start, self._start_source
            else:
                start, source = settings.start, StartSource.PARAMETER
            live = self._map
            previous = self._worker_map if self._worker_map is not None else applied_map
            changed = previous is None or live.version != previous.version
            snapshot = Snapshot(
                settings=settings, settings_changed=self._settings_changed,
                obstacles=live.obstacles, obstacles_changed=changed,
                obstacles_version=live.version, obstacles_stamp_ns=self._obstacles_stamp_ns,
                goal=self._goal, goal_changed=self._goal_changed, start=start,
                start_source=source, map=live, replan_reason=self._replan_request)
            # From here on the worker reads this map's mask: the intake writes others.
            self._worker_map = live
            self._settings_changed = self._map_changed = self._goal_changed = False
            self._replan_request = None
            return snapshot
