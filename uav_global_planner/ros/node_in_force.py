"""The plan in force of the planner node: releasing a plan, re-checking it, withdrawing it.

A mixin of :class:`~uav_global_planner.ros.planner_node.PlannerNode`.

:meth:`PlanInForce.release` is the one gate every plan passes before anyone sees it, whoever
asked (``goal_pose``, both Nav2 actions, ``GetPlan``): under the publish lock it certifies the
plan's curve against the newest map the node holds when that map is newer than the one the plan
was certified on, then latches it on ``plan``, ``unsmoothed_plan`` and ``trajectory`` (or only
serialises it, for a query) or refuses it with the reason. The map intake installs a new map
under the same lock, after re-checking the plan in force against it (ahead of the vehicle first)
and withdrawing it with empty messages and an ERROR status when the map makes it collide. So a
plan handed to a client is in force (when published) and clear of the newest map at that
moment; a map after that withdraws it on ``plan`` like any other. ``export_mission`` reads the
plan in force through :meth:`PlanInForce.plan_for_export`, under the same lock.
"""

from dataclasses import dataclass
from typing import Callable, Dict, Optional, Tuple, TypeVar

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np

from uav_global_planner.core.map.live_map import LiveMap
from uav_global_planner.core.planner import certify_plan, ClearanceVerdict
from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_attributes import NodeAttributes
from uav_global_planner.ros.node_state import InForce
from uav_global_planner.ros.start_source import StartSource

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


class PlanInForce(NodeAttributes):
    """Publishing, checking and withdrawing the latched plan.

    Owns ``_in_force`` and ``_latched`` (guarded by ``_publish_lock``).
    """

    def _latch(self, result: PlanResult, frame: str, stamp_ns: int,
               orientation: Tuple[float, ...], start_source: StartSource, checked_version: int,
               goal_serial: Optional[int] = None) -> bytes:
        """Publish and latch a plan checked against map ``checked_version`` (the newest: the
        caller holds the publish lock, see :meth:`release`); return the serialised ``plan``."""
        # Serialised from the arrays: the messages of conv.plan_to_path and friends, without
        # building hundreds of message objects (milliseconds per plan).
        writer = self._plan_writer
        period = self._current_settings().trajectory_sample_period
        with self._publish_lock:
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
            now_ns = self.node.get_clock().now().nanoseconds
            if previous is not None and (stamp_ns <= now_ns or previous.frame_id != frame):
                previous = None
            if previous is not None and previous.stamp_ns <= now_ns:
                previous.previous = None
            self._in_force = InForce(result, frame, stamp_ns, start_source, checked_version,
                                     goal_serial, previous)
        with self._wake:
            # Only a plan for the active goal is replanned once the vehicle's position arrives.
            self._in_force_source = start_source if goal_serial is not None else None
        return plan

    def newest_map_verdict(self, result: PlanResult, checked_version: int,
                           position: Optional[np.ndarray]
                           ) -> Tuple[Optional[ClearanceVerdict], LiveMap]:
        """The newest map the node holds, and ``result``'s certificate against it when it is
        newer than map ``checked_version`` (None when it is that map). ``position``: where the
        vehicle is, when the plan starts there (only the curve ahead of it matters); None
        certifies the whole curve. Holds the publish lock, so no map is installed meanwhile."""
        with self._publish_lock:
            with self._wake:
                newest = self._map
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
        with self._publish_lock:
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
        with self._publish_lock:
            in_force = self._in_force
            if in_force is None:
                return None, ('no plan in force (none was published on plan yet, or it was '
                              'withdrawn)')
            verdict, newest = self.newest_map_verdict(in_force.result, in_force.checked_version,
                                                      self._vehicle_position())
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
        with self._publish_lock:
            if self._in_force is None or self._in_force.stamp_ns != stamp_ns:
                return False, None
            return True, action()

    def _vehicle_position(self) -> Optional[np.ndarray]:
        """The vehicle's position [m] (None: only the start parameter is known)."""
        with self._wake:
            return self._start if self._start_source != StartSource.PARAMETER else None

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
        with self._publish_lock:
            in_force = self._in_force
            if in_force is None or in_force.checked_version >= live.version:
                return None
            verdict = self._certify_on(in_force.result, live, self._vehicle_position())
            in_force.checked_version = live.version
            if verdict.clear:
                return None
            self._withdraw_in_force(in_force.frame_id, 'the new map makes it collide', verdict,
                                    live)
            return in_force

    def _withdraw_in_force(self, frame: str, why: str, verdict: Optional[ClearanceVerdict],
                           live: Optional[LiveMap] = None) -> None:
        """Withdraw the plan in force (if any) with empty messages and an ERROR status."""
        with self._publish_lock:
            if self._in_force is None:
                return
            in_force = self._in_force
            stamp_ns = self.node.get_clock().now().nanoseconds
            self._withdraw_plan(frame, stamp_ns, log=False)  # logged below, with the reason
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
        values.update(self._settings_values(self._current_settings()))
        values['message'] = text
        self._publish_diagnostics(stamp_ns, DiagnosticStatus.ERROR, text, values)

    def _withdraw_plan(self, frame: str, stamp_ns: int, log: bool = True) -> None:
        """Replace the latched plan, unsmoothed plan and trajectory by empty ones."""
        with self._publish_lock:
            empty = np.empty((0, 3))
            self._plan_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
            self._unsmoothed_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
            self._trajectory_pub.publish(conv.empty_trajectory(frame, stamp_ns))
            self._latched = None
            self._in_force = None
        with self._wake:
            self._in_force_source = None
        if log:
            self._log.warning('withdrew the plan in force (published an empty plan and '
                              'trajectory): it no longer keeps gamma from the obstacles')
