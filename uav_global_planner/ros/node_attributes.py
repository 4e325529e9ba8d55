"""The state the parts of the planner node share, and which lock guards each piece.

:class:`NodeAttributes` is the one base of the mixins that make up
:class:`~uav_global_planner.ros.planner_node.PlannerNode` (``ParameterHandling``,
``CommandInputs``, ``MapIntake``, ``PlanInForce``, ``PlanningWorker``, ``StatusPublishing``).
It declares, with their types, the attributes they share (assigned in ``PlannerNode.__init__``)
and the methods one of them calls on another, so that a type checker sees every use. It adds
nothing at run time: the declarations are annotations only, and the methods exist for the type
checker alone (each is implemented by one mixin or by ``PlannerNode``).

The locks (``_publish_lock`` is taken before ``_wake`` when both are held; ``_intake_cv`` is
never held with another; nothing is taken while ``_diagnostics_lock`` is held):

- ``_publish_lock`` (re-entrant): the plan in force; publishing, withdrawing and re-checking a
  plan, and installing a new map (so no plan goes out unchecked against a newer map);
- ``_wake`` (the node's condition; the worker waits on it): settings, map, goal, start and the
  change flags;
- ``_intake_cv`` (the intake's condition): the map messages waiting for the intake;
- ``_diagnostics_lock``: the ``/diagnostics`` publisher.

Attributes not named under a lock are set once in ``PlannerNode.__init__`` and only read after,
or belong to one thread (said for each).
"""

from abc import abstractmethod
import threading
from typing import (Any, Callable, Dict, Hashable, List, Mapping, Optional, Tuple,
                    TYPE_CHECKING)

import numpy as np
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.mapfiles import MapPoints
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.live_map import LiveMap, LiveMapBuilder
from uav_global_planner.core.map.obstacles import Obstacle
from uav_global_planner.core.planner import ClearanceVerdict, Planner
from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros.conversions import MarkerKey
from uav_global_planner.ros.node_state import Goal, Inbox, InForce, Snapshot, SourceState
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.plan_writer import PlanWriter
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import TakeoverPredictor
from uav_global_planner.ros.terrain_source import TerrainState

if TYPE_CHECKING:
    from uav_global_planner.ros.node_in_force import Release


class NodeAttributes:
    """What the parts of the planner node share: attributes, locks and cross-part methods."""

    # ---- Set once in __init__, read by every thread -----------------------------------------
    node: Node
    _log: RcutilsLogger
    # Latency estimate, newest odometry motion and takeover predictions (its own lock).
    _takeover: TakeoverPredictor
    _plan_writer: PlanWriter
    # The prior map (map_file) and why it was refused ('' when it was not).
    _prior: Optional[MapPoints]
    _prior_refusal: str
    _map_margin_m: float
    # Name of the node's status on /diagnostics.
    _diag_name: str
    _goal_sub: Subscription
    _obstacles_sub: Subscription
    _cloud_sub: Subscription
    _odom_sub: Subscription
    _start_sub: Subscription
    # Published only under _publish_lock.
    _plan_pub: Publisher
    _unsmoothed_pub: Publisher
    _trajectory_pub: Publisher
    # Published from the marker timer (executor) only.
    _markers_pub: Publisher
    # Published only under _diagnostics_lock.
    _diagnostics_pub: Publisher

    # ---- The locks ---------------------------------------------------------------------------
    _publish_lock: threading.RLock
    _wake: threading.Condition
    _intake_cv: threading.Condition
    _diagnostics_lock: threading.Lock

    # ---- Guarded by _publish_lock ------------------------------------------------------------
    # The plan latched on ``plan`` (None: none, or withdrawn) and the plan in force.
    _latched: Optional[PlanResult]
    _in_force: Optional[InForce]

    # ---- Guarded by _wake --------------------------------------------------------------------
    _settings: NodeSettings
    _settings_changed: bool
    # The newest map (installed by the intake, also under _publish_lock) and its change flag.
    _map: LiveMap
    _map_changed: bool
    # Header stamp of the map message that last changed the obstacles, and of the newest map
    # message taken in [ns] (0: none yet).
    _obstacles_stamp_ns: int
    _map_stamp_ns: int
    _sources: Dict[str, SourceState]
    _goal: Optional[Goal]
    _goal_serial: int
    _goal_changed: bool
    # The vehicle's position [m] (None: only the start parameter) and where it came from.
    _start: Optional[np.ndarray]
    _start_source: StartSource
    _stopping: bool
    # A replan the worker owes the active goal: the reason (None: none).
    _replan_request: Optional[str]
    # The map the worker plans on (its mask is never rewritten while held).
    _worker_map: Optional[LiveMap]
    # Start source of the plan in force; None: none in force, or not for the active goal.
    _in_force_source: Optional[StartSource]
    # Seconds of the intake's last map update: whole step, index, mask.
    _intake_times: Tuple[float, float, float]
    # Cloud stamp to its map handed to the worker [s], since the last map status.
    _cloud_latencies: List[float]
    # Serials of the map shapes (geofence, ground, band) asked for and of those the map holds.
    _geofence_requested: int
    _geofence_applied: int
    # Requests of the Nav2 interfaces and the mission export, run by the worker after a step.
    _jobs: List[Callable[[Planner, Snapshot], None]]
    # The terrain_file in force (None: not read yet): written under _wake by the executor,
    # read without it elsewhere (a reference replaced whole).
    _terrain_state: Optional[TerrainState]

    # ---- Guarded by _intake_cv ---------------------------------------------------------------
    _inbox: Inbox

    # ---- The executor's (parameter callbacks and timers) -------------------------------------
    _param_values: Dict[str, Any]
    # A terrain read by the on-set callback for values about to be set.
    _terrain_candidate: Optional[TerrainState]
    # The geofence in force: replaced whole by the executor, read by the worker and the status
    # (a reference); and the parameters it was read from (None: not read yet).
    _airspace: Airspace
    _geofence_key: Optional[Tuple[Any, ...]]
    _markers_published_key: Optional[Tuple[Any, ...]]
    _duplicates_reported: int

    # ---- The intake thread's -----------------------------------------------------------------
    # The map builder (the worker only sets its want_fallback flag).
    _builder: LiveMapBuilder
    _intake_markers: Dict[MarkerKey, Obstacle]
    _intake_geofence: Mapping[MarkerKey, Obstacle]
    _intake_ground: Mapping[MarkerKey, Obstacle]
    _ground_key: Tuple[Hashable, ...]
    _intake_frame: str

    # ---- The worker thread's -----------------------------------------------------------------
    # The planner: no other thread touches it.
    _planner: Planner
    # Outcome of the last plan attempt and the goal it was for.
    _last_result: Optional[PlanResult]
    _last_goal_serial: int
    # Why the active goal must be planned again although nothing flagged it.
    _replan_reason: Optional[str]
    # The map applied to the planner, and whether the planner searches its mask.
    _applied_map: Optional[LiveMap]
    _grid_from_map: bool
    # Plans dropped in a row because the vehicle left their start while they were computed.
    _drift_replans: int

    if TYPE_CHECKING:
        # Methods one part calls on another, implemented by the part named (or by
        # PlannerNode); declared for the type checker only.

        @abstractmethod
        def _current_settings(self) -> NodeSettings:
            """PlannerNode: the settings in force (any thread)."""

        @abstractmethod
        def map_refusal(self) -> str:
            """PlannerNode: why map_file or terrain_file was refused ('' when neither was)."""

        @abstractmethod
        def _follow_bounds(self, config: PlannerConfig) -> None:
            """PlannerNode: the unknown space of an OctoMap map_file within new bounds."""

        @abstractmethod
        def _log_terrain(self, state: TerrainState) -> None:
            """PlannerNode: log the terrain read, or why it was refused."""

        @abstractmethod
        def _map_missing(self, settings: NodeSettings) -> Optional[str]:
            """CommandInputs: why goals cannot be planned for want of a map, or None."""

        @abstractmethod
        def _refuse(self, topic: str, error: Exception, throttle: bool = False) -> None:
            """CommandInputs: log and report a refused message."""

        @abstractmethod
        def _recheck_in_force(self, live: LiveMap) -> Optional[InForce]:
            """PlanInForce: certify the plan in force against a new map; the withdrawn plan."""

        @abstractmethod
        def _withdraw_in_force(self, frame: str, why: str,
                               verdict: Optional[ClearanceVerdict],
                               live: Optional[LiveMap] = None) -> None:
            """PlanInForce: withdraw the plan in force with an ERROR status."""

        @abstractmethod
        def _withdraw_plan(self, frame: str, stamp_ns: int, log: bool = True) -> None:
            """PlanInForce: replace the latched messages by empty ones."""

        @abstractmethod
        def newest_map_verdict(self, result: PlanResult, checked_version: int,
                               position: Optional[np.ndarray]
                               ) -> Tuple[Optional[ClearanceVerdict], LiveMap]:
            """PlanInForce: the newest map and ``result``'s certificate against it."""

        @abstractmethod
        def release(self, result: PlanResult, checked_version: int, frame_id: str,
                    stamp_ns: int, orientation: Tuple[float, ...], *, publish: bool,
                    position: Optional[np.ndarray] = None,
                    start_source: StartSource = StartSource.REQUEST,
                    goal_serial: Optional[int] = None) -> 'Release':
            """PlanInForce: the gate of every plan."""

        @abstractmethod
        def _is_stopping(self) -> bool:
            """PlanningWorker: the node is shutting down."""

        @abstractmethod
        def _settings_values(self, settings: NodeSettings) -> Dict[str, object]:
            """StatusPublishing: the settings reported with a status."""

        @abstractmethod
        def _map_values(self, live: Optional[LiveMap] = None) -> Dict[str, object]:
            """StatusPublishing: the map sources' state reported with a status."""

        @abstractmethod
        def _publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                                 values: Mapping[str, object]) -> None:
            """StatusPublishing: publish one status on /diagnostics (any thread)."""
