"""The plan in force of the planner node: releasing a plan, re-checking it, withdrawing it.

A part of :class:`~uav_global_planner.ros.planner_node.PlannerNode`.

:meth:`PlanInForce.release` is the one gate every plan passes before anyone sees it, whoever asked
(``goal_pose``, both Nav2 actions, ``GetPlan``): under the release lock it certifies the plan's
curve against the newest map the node holds when that map is newer than the one the plan was
certified on, then latches it on ``plan``, ``unsmoothed_plan`` and ``trajectory`` (or only
serialises it, for a query) or refuses it with the reason. The map intake installs a new map under
the same lock (:meth:`PlanInForce.install_map`), after re-checking the plan in force against it
(ahead of the vehicle first) and withdrawing it with empty messages and an ERROR status when the
map makes it collide. So a plan handed to a client is in force (when published) and clear of the
newest map at that moment; a map after that withdraws it on ``plan`` like any other.
``export_mission`` reads the plan in force through :meth:`PlanInForce.plan_for_export`, under the
same lock.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import threading
from typing import Callable, Dict, Iterator, Optional, Tuple, TypeVar

from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Path
import numpy as np
from rclpy.node import Node
from trajectory_msgs.msg import MultiDOFJointTrajectory

from uav_global_planner.core.map.live_map import LiveMap
from uav_global_planner.core.planner import certify_plan, ClearanceVerdict
from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.node_state import InForce
from uav_global_planner.ros.plan_writer import PlanWriter
from uav_global_planner.ros.qos import LATCHED_QOS
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import Settlement, Takeover, TakeoverPredictor

T = TypeVar('T')

#: Length of the curve ahead of the vehicle certified first when a map arrives [m].
_CHECK_AHEAD_M = 30.0


@dataclass(frozen=True, eq=False)
class Release:
    """What :meth:`PlanInForce.release` decided for one plan.

    Attributes
    ----------
    data : bytes or None
        The serialised ``nav_msgs/Path`` handed to the client; None when refused.
    refusal : str
        Why the plan was refused ('' when released).
    checked_version : int
        Version of the newest map the plan is certified against.
    """

    data: Optional[bytes]
    refusal: str
    checked_version: int

    @property
    def released(self) -> bool:
        """True when the plan went out."""
        return self.data is not None


@dataclass(frozen=True, eq=False)
class ExportablePlan:
    """The plan in force as :meth:`PlanInForce.plan_for_export` hands it to the mission export.

    Attributes
    ----------
    result : PlanResult
    frame_id : str
    stamp_ns : int
        Its header stamp [ns]: the same plan is still in force while this stamp is.
    live : LiveMap
        The newest map, which the plan's curve ahead of the vehicle keeps gamma from.
    """

    result: PlanResult
    frame_id: str
    stamp_ns: int
    live: LiveMap


class PlanInForce:
    """Publishing, checking and withdrawing the latched plan.

    Its re-entrant lock, ``_release_lock``, guards the plan in force (``_in_force``, and
    ``_latched``: the plan latched on ``plan``), the ``plan``, ``unsmoothed_plan`` and
    ``trajectory`` publishers, and the installation of a new map (:meth:`install_map`), so
    that no plan goes out unchecked against a map installed meanwhile. It is taken before the
    planning inputs' condition when both are held.

    Parameters
    ----------
    node : rclpy.node.Node
        Gets the ``plan``, ``unsmoothed_plan`` and ``trajectory`` publishers.
    inputs : PlanningInputs
        The newest map, the vehicle's position and the settings in force.
    diagnostics : NodeDiagnostics
    plan_writer : PlanWriter
        Serialises plans (CDR bytes, checked once per process).
    takeover : TakeoverPredictor
        Settles the takeover of plans made in flight.
    """

    def __init__(self, node: Node, inputs: PlanningInputs, diagnostics: NodeDiagnostics,
                 plan_writer: PlanWriter, takeover: TakeoverPredictor) -> None:
        self._node = node
        self._log = node.get_logger()
        self._inputs = inputs
        self._diagnostics = diagnostics
        self._plan_writer = plan_writer
        self._takeover = takeover
        self._release_lock = threading.RLock()
        # The plan latched on ``plan`` (None: none, or withdrawn) and the plan in force.
        self._latched: Optional[PlanResult] = None
        self._in_force: Optional[InForce] = None
        self._plan_pub = node.create_publisher(Path, 'plan', LATCHED_QOS)
        self._unsmoothed_pub = node.create_publisher(Path, 'unsmoothed_plan', LATCHED_QOS)
        self._trajectory_pub = node.create_publisher(MultiDOFJointTrajectory, 'trajectory',
                                                     LATCHED_QOS)

    @contextmanager
    def held(self) -> Iterator[None]:
        """Hold the release lock: no map is installed and no plan released or withdrawn
        meanwhile (the worker holds it from a plan's last check to its release)."""
        with self._release_lock:
            yield

    def current(self) -> Optional[InForce]:
        """The plan in force (None: none)."""
        with self._release_lock:
            return self._in_force

    def latched(self) -> Optional[PlanResult]:
        """The plan latched on ``plan`` (None: none, or withdrawn)."""
        with self._release_lock:
            return self._latched

    def install_map(self, live: LiveMap, recheck: bool,
                    install: Callable[[Optional[InForce]], None]) -> None:
        """Install a new map: under the release lock, check the plan in force against ``live``
        (``recheck``: its obstacles changed) and withdraw it if it collides, then call
        ``install(withdrawn plan or None)``, which hands the map to the worker. No plan is
        released between the check and the installation (:meth:`release` certifies against
        the map installed)."""
        with self._release_lock:
            withdrawn = self._recheck_in_force(live) if recheck else None
            install(withdrawn)

    def settle_takeover(self, takeover: Takeover, result: PlanResult) -> Settlement:
        """How a successful plan from ``takeover`` goes out now: its stamp, and why it should
        not (the worker, just before publishing)."""
        with self._release_lock:
            vehicle = self._inputs.vehicle_position()
            distance = self._inputs.current_settings().start_replan_distance
            return self._takeover.settle(takeover, result.trajectory, self._in_force, vehicle,
                                         distance)

    def _latch(self, result: PlanResult, frame: str, stamp_ns: int,
               orientation: Tuple[float, ...], start_source: StartSource, checked_version: int,
               goal_serial: Optional[int] = None) -> bytes:
        """Publish and latch a plan checked against map ``checked_version`` (the newest: the
        caller holds the release lock, see :meth:`release`); return the serialised ``plan``."""
        # Serialised from the arrays: the messages of conv.plan_to_path and friends, without
        # building hundreds of message objects (milliseconds per plan).
        writer = self._plan_writer
        period = self._inputs.current_settings().trajectory_sample_period
        with self._release_lock:
            plan = writer.plan_path(result, frame, stamp_ns, orientation)
            self._plan_pub.publish(plan)
            self._unsmoothed_pub.publish(
                writer.unsmoothed_path(result, frame, stamp_ns, orientation))
            self._trajectory_pub.publish(writer.trajectory(result, frame, stamp_ns, orientation,
                                                           sample_period=period))
            self._latched = result
            # A plan stamped ahead (a replan in flight) takes over at its stamp: until then
            # the vehicle flies the one before, which a replan meanwhile must continue.
            previous = self._in_force
            now_ns = self._node.get_clock().now().nanoseconds
            if previous is not None and (stamp_ns <= now_ns or previous.frame_id != frame):
                previous = None
            if previous is not None and previous.stamp_ns <= now_ns:
                previous.previous = None
            self._in_force = InForce(result, frame, stamp_ns, start_source, checked_version,
                                     goal_serial, previous)
        # Only a plan for the active goal is replanned once the vehicle's position arrives.
        self._inputs.set_in_force_source(start_source if goal_serial is not None else None)
        return plan

    def newest_map_verdict(self, result: PlanResult, checked_version: int,
                           position: Optional[np.ndarray]
                           ) -> Tuple[Optional[ClearanceVerdict], LiveMap]:
        """The newest map the node holds, and ``result``'s certificate against it when it is
        newer than map ``checked_version`` (None when it is that map). ``position``: where the
        vehicle is, when the plan starts there (only the curve ahead of it matters); None
        certifies the whole curve. Holds the release lock, so no map is installed meanwhile."""
        with self._release_lock:
            newest = self._inputs.newest_map()
            if newest.version == checked_version:
                return None, newest
            return self._certify_on(result, newest, position), newest

    def release(self, result: PlanResult, checked_version: int, frame_id: str, stamp_ns: int,
                orientation: Tuple[float, ...], *, publish: bool,
                position: Optional[np.ndarray] = None,
                start_source: StartSource = StartSource.REQUEST,
                goal_serial: Optional[int] = None) -> Release:
        """The gate of every plan: certify against the newest map, then publish or refuse.

        Parameters
        ----------
        result : PlanResult
            A successful plan, certified on map ``checked_version``.
        checked_version : int
        frame_id : str
        stamp_ns : int
            The plan's time 0 [ns] (its header stamp).
        orientation : tuple of float
            Quaternion (x, y, z, w) of the last pose.
        publish : bool
            Latch the plan on ``plan``, ``unsmoothed_plan`` and ``trajectory`` (it becomes the
            plan in force); False only serialises it (a ``GetPlan`` query).
        position : numpy.ndarray, optional
            The vehicle's position [m] when the plan starts there: a newer map is certified
            from there on. None: the whole curve.
        start_source : StartSource
        goal_serial : int, optional
            The ``goal_pose`` goal the plan answers (None: a Nav2 request).

        Returns
        -------
        Release
        """
        with self._release_lock:
            verdict, newest = self.newest_map_verdict(result, checked_version, position)
            if verdict is not None and not verdict.clear:
                where = ('' if verdict.blocked_at is None
                         else f' near {np.round(verdict.blocked_at, 3).tolist()}')
                return Release(None, (
                    f'a map that arrived while planning (version {newest.version}; planned on '
                    f'{checked_version}) makes the path collide{where}; ask again'),
                    newest.version)
            if publish:
                data = self._latch(result, frame_id, stamp_ns, orientation, start_source,
                                   newest.version, goal_serial)
            else:
                data = self._plan_writer.plan_path(result, frame_id, stamp_ns, orientation)
            return Release(data, '', newest.version)

    def plan_for_export(self) -> Tuple[Optional[ExportablePlan], str]:
        """The plan in force and the newest map it keeps clear of, or (None, why not)."""
        with self._release_lock:
            in_force = self._in_force
            if in_force is None:
                return None, ('no plan in force (none was published on plan yet, or it was '
                              'withdrawn)')
            verdict, newest = self.newest_map_verdict(in_force.result, in_force.checked_version,
                                                      self._inputs.vehicle_position())
            if verdict is not None:
                in_force.checked_version = newest.version
                if not verdict.clear:
                    # The intake withdraws it as it installs such a map; never exported.
                    return None, 'the newest map makes the plan in force collide'
            return ExportablePlan(in_force.result, in_force.frame_id, in_force.stamp_ns,
                                  newest), ''

    def while_in_force(self, stamp_ns: int, action: Callable[[], T]) -> Tuple[bool, Optional[T]]:
        """Run ``action`` while the plan stamped ``stamp_ns`` [ns] is in force (under the publish
        lock: no map is installed and no plan released meanwhile); (False, None) without
        running it when that plan was withdrawn or replaced."""
        with self._release_lock:
            if self._in_force is None or self._in_force.stamp_ns != stamp_ns:
                return False, None
            return True, action()

    def _certify_on(self, result: PlanResult, live: LiveMap,
                    position: Optional[np.ndarray]) -> ClearanceVerdict:
        """The certificate of ``result``'s curve (from ``position`` on) against ``live``: the
        clearance engine, the near stretch first. The unknown space, which no map changes,
        was certified when the plan was made."""
        return certify_plan(result, live.obstacles, result.planning_margin, result.resolution,
                            position, ahead_m=_CHECK_AHEAD_M)

    def _recheck_in_force(self, live: LiveMap) -> Optional[InForce]:
        """Certify the plan in force against a new map at once (ahead of the vehicle first);
        withdraw it there and then if the map makes it collide. Returns the withdrawn plan."""
        with self._release_lock:
            in_force = self._in_force
            if in_force is None or in_force.checked_version >= live.version:
                return None
            verdict = self._certify_on(in_force.result, live, self._inputs.vehicle_position())
            in_force.checked_version = live.version
            if verdict.clear:
                return None
            self.withdraw(in_force.frame_id, 'the new map makes it collide', verdict, live)
            return in_force

    def withdraw(self, frame: str, why: str, verdict: Optional[ClearanceVerdict],
                 live: Optional[LiveMap] = None) -> None:
        """Withdraw the plan in force (if any) with empty messages and an ERROR status."""
        with self._release_lock:
            if self._in_force is None:
                return
            in_force = self._in_force
            stamp_ns = self._node.get_clock().now().nanoseconds
            self.withdraw_plan(frame, stamp_ns, log=False)  # logged below, with the reason
        where = ''
        values: Dict[str, object] = {'event': 'plan_withdrawn', 'status': 'withdrawn',
                                     'plan_withdrawn': True, 'reason': why,
                                     'plan_stamp': in_force.stamp_ns}
        if verdict is not None and verdict.blocked_at is not None:
            where = (f' near {np.round(verdict.blocked_at, 3).tolist()}, '
                     f'{verdict.blocked_ahead_m:.1f} m ahead')
            values['blocked_at'] = verdict.blocked_at
            values['blocked_ahead_m'] = verdict.blocked_ahead_m
        if live is not None:
            values['obstacles_version'] = live.version
        text = (f'plan in force withdrawn (empty plan and trajectory published: hold position): '
                f'{why}{where}')
        self._log.error(text)
        values.update(self._diagnostics.settings_values(self._inputs.current_settings()))
        values['message'] = text
        self._diagnostics.publish(stamp_ns, DiagnosticStatus.ERROR, text, values)

    def withdraw_plan(self, frame: str, stamp_ns: int, log: bool = True) -> None:
        """Replace the latched plan, unsmoothed plan and trajectory by empty ones."""
        with self._release_lock:
            empty = np.empty((0, 3))
            self._plan_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
            self._unsmoothed_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
            self._trajectory_pub.publish(conv.empty_trajectory(frame, stamp_ns))
            self._latched = None
            self._in_force = None
        self._inputs.set_in_force_source(None)
        if log:
            self._log.warning('withdrew the plan in force (published an empty plan and '
                              'trajectory): it no longer keeps gamma from the obstacles')
