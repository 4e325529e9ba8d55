"""The plan in force of the planner node: latching it, re-checking it, withdrawing it.

A mixin of :class:`~uav_global_planner.ros.planner_node.PlannerNode`. The plan latched on
``plan``, ``unsmoothed_plan`` and ``trajectory`` is certified against every new map (ahead of
the vehicle first) and withdrawn at once, with empty messages and an ERROR status, when the map
makes it collide. Everything here holds the publish lock, so no plan goes out unchecked
against a map published meanwhile.
"""

from typing import Dict, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np

from uav_global_planner.core.live_map import LiveMap
from uav_global_planner.core.planner import certify_plan, ClearanceVerdict
from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_state import InForce
from uav_global_planner.ros.start_source import StartSource

#: Length of the curve ahead of the vehicle certified first when a map arrives [m].
_CHECK_AHEAD_M = 30.0


class PlanInForce:
    """Publishing, checking and withdrawing the latched plan.

    Owns ``_in_force`` and ``_latched`` (guarded by ``_publish_lock``).
    """

    def _latch(self, result: PlanResult, frame: str, stamp_ns: int,
               orientation: Tuple[float, ...], start_source: StartSource, checked_version: int,
               goal_serial: Optional[int] = None) -> bytes:
        """Publish and latch a plan checked against map ``checked_version``; return the
        serialised ``plan``. A newer map published meanwhile is re-checked by the intake as
        soon as the publish lock is free."""
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

    def publish_plan(self, result: PlanResult, frame_id: str, stamp_ns: int,
                     orientation: Tuple[float, ...]) -> Optional[bytes]:
        """Worker only: publish and latch a successful plan on ``plan``, ``unsmoothed_plan`` and
        ``trajectory``; return the serialised ``plan`` message, or None when a map newer than
        the planner's made it collide and it was withdrawn at once (nothing to hand a client).
        The plan is the plan in force from then on: re-checked against every new map."""
        applied = self._applied_map.version if self._applied_map is not None else -1
        with self._publish_lock:
            plan = self._latch(result, frame_id, stamp_ns, orientation,
                               StartSource.REQUEST, applied)
            with self._wake:
                newest = self._map
            if newest.version > applied and self._recheck_in_force(newest) is not None:
                return None
        return plan

    def _recheck_in_force(self, live: LiveMap) -> Optional[InForce]:
        """Certify the plan in force against a new map at once (ahead of the vehicle first);
        withdraw it there and then if the map makes it collide. Returns the withdrawn plan."""
        with self._publish_lock:
            in_force = self._in_force
            if in_force is None or in_force.checked_version >= live.version:
                return None
            with self._wake:
                position = self._start if self._start_source != StartSource.PARAMETER else None
            result = in_force.result
            verdict = certify_plan(result, live.obstacles, result.planning_margin,
                                   result.resolution, position, ahead_m=_CHECK_AHEAD_M)
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
