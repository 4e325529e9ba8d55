"""The planning worker of the planner node: the only thread that touches the Planner.

A part of :class:`~uav_global_planner.ros.planner_node.PlannerNode`. The worker takes a
snapshot of the settings, map, start and goal when a plan begins (whatever arrives meanwhile is
coalesced into at most one follow-up plan), plans, and publishes only a plan that keeps gamma
from the newest map and still starts where the vehicle is (a plan made in flight starts where
the vehicle will be when it takes over, and is stamped with that time:
:mod:`~uav_global_planner.ros.takeover`); the Nav2 interfaces run their
requests on it too (:meth:`~uav_global_planner.ros.node_plan_inputs.PlanningInputs.submit`).
"""

from dataclasses import replace
import threading
import time
import traceback
from typing import Any, Callable, Dict, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
from rclpy.node import Node

from uav_global_planner.core.budget import PlanStage
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.live_map import LiveMap, warm_up_changes
from uav_global_planner.core.map.unknown_space import unknown_from_map_files, UnknownSpace
from uav_global_planner.core.planner import ClearanceVerdict, Planner
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.search.start_admission import Admission, admit, explain, GOAL, START
from uav_global_planner.core.status import NAV2_CODE_BY_STATUS, NAV2_UNKNOWN, PlanStatus
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import describe
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_in_force import PlanInForce
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.node_state import Goal, Snapshot
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import (FOLLOW_DISTANCE_M, Settlement, START_REFUSALS,
                                             Takeover, TakeoverPredictor)

#: Consecutive plans dropped because the vehicle moved away from their start while they were
#: computed; after that many the plan is published anyway (with a note), so a slow plan behind
#: a fast vehicle still gives one.
_MAX_DRIFT_REPLANS = 3
#: A newer goal cancels a running plan only once it has run this long [s]: a plan of tens of
#: milliseconds ends and is published, so goals streamed faster than plans take still get
#: plans (each plan then takes the newest goal); a long plan gives way at once after it.
PREEMPT_GRACE_S = 0.25

#: Outcomes that may change when the obstacles change, so a failed goal is retried then.
_RETRY_ON_OBSTACLES = (PlanStatus.NO_VALID_PATH, PlanStatus.TIMEOUT, PlanStatus.START_OCCUPIED,
                       PlanStatus.GOAL_OCCUPIED)


class PlanningWorker:
    """The worker thread and its plans: the only thread that touches the :class:`Planner`.

    No lock of its own: its state (the planner, the outcome of the last plan, the replan it owes
    itself, the map applied to the planner) belongs to the worker thread. Its inputs are the
    :class:`~uav_global_planner.ros.node_plan_inputs.PlanningInputs`, on whose condition it
    waits for work; it publishes through the plan in force's gate.

    Parameters
    ----------
    node : rclpy.node.Node
        The node's clock and logger.
    inputs : PlanningInputs
    in_force : PlanInForce
    intake : MapIntake
        The map sources' state reported with a plan.
    diagnostics : NodeDiagnostics
    planner : Planner
        The worker's from now on.
    takeover : TakeoverPredictor
    unknown_file : str
        The OctoMap ``map_file`` whose unknown space the planner holds ('' for none): read
        again for new bounds.
    unknown_bounds : tuple
        The bounds (min, max) [m] that unknown space was read for.
    """

    def __init__(self, node: Node, inputs: PlanningInputs, in_force: PlanInForce,
                 intake: MapIntake, diagnostics: NodeDiagnostics, planner: Planner,
                 takeover: TakeoverPredictor, unknown_file: str,
                 unknown_bounds: Tuple[Tuple[float, ...], Tuple[float, ...]]) -> None:
        self._node = node
        self._log = node.get_logger()
        self._inputs = inputs
        self._in_force = in_force
        self._intake = intake
        self._diagnostics = diagnostics
        self._planner = planner
        self._takeover = takeover
        self._unknown_file = unknown_file
        self._unknown_bounds = unknown_bounds
        # Outcome of the last plan attempt and the goal it was for.
        self._last_result: Optional[PlanResult] = None
        self._last_goal_serial = -1
        # Why the active goal must be planned again although nothing flagged it.
        self._replan_reason: Optional[str] = None
        # The map applied to the planner, and whether the planner searches its mask.
        self._applied_map: Optional[LiveMap] = None
        self._grid_from_map = False
        # Plans dropped in a row because the vehicle left their start while they were computed.
        self._drift_replans = 0
        self._thread = threading.Thread(target=self._run_worker, name='planner-worker',
                                        daemon=True)

    def start(self) -> None:
        """Give the planner the map at start-up, compile the kernels and build the grid (and
        load those of a map change, which the first new obstacle would otherwise wait for),
        then start the worker thread."""
        live = self._inputs.newest_map()
        self._grid_from_map = self._planner.set_map(live.obstacles, live.blocked,
                                                    live.grid_key)
        self._applied_map = live
        self._planner.warm_up()
        try:
            warm_up_changes(self._inputs.current_settings().config)
        except Exception as error:  # noqa: B902 - a warm-up only saves time later; never fatal
            self._log.warning(f'could not load the kernels of a map change ahead ({error}); '
                              'the first one loads them')
        self._thread.start()

    def stop(self, timeout_s: float) -> None:
        """Wait at most ``timeout_s`` [s] for the worker thread to end (the planning inputs
        were told the node stops: a running plan is cancelled within milliseconds)."""
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def grid_shape(self) -> Tuple[int, ...]:
        """The planner's grid shape (cells; read at start-up, before the thread runs)."""
        return tuple(self._planner.grid.shape)

    def _take_snapshot(self) -> Optional[Snapshot]:
        """Wait for work; copy what the next step needs and clear the change flags."""
        return self._inputs.take_snapshot(self._applied_map)

    def _follow_bounds(self, config: PlannerConfig) -> None:
        """The unknown space of an OctoMap ``map_file`` within new bounds (read again from the
        file; all of the bounds when it can no longer be read)."""
        bounds = (tuple(config.bounds_min), tuple(config.bounds_max))
        if not self._unknown_file or bounds == self._unknown_bounds:
            return
        try:
            unknown = unknown_from_map_files([self._unknown_file], *bounds)
        except InvalidInputError as error:
            self._log.error(f'map_file: unknown space for the new bounds: {error}; all of the '
                            'bounds count as unknown')
            unknown = UnknownSpace(np.array(bounds[0])[None, :], np.array(bounds[1])[None, :],
                                   self._unknown_file)
        self._unknown_bounds = bounds
        self._planner.set_unknown(unknown)

    def _run_worker(self) -> None:
        """Planning thread: the only thread that touches the Planner."""
        while True:
            snapshot = self._take_snapshot()
            if snapshot is None:
                return
            try:
                self._step(snapshot)
                self._run_jobs(snapshot)
            except Exception as error:  # noqa: BLE001 - a bug must not kill the planner
                if self._inputs.is_stopping():
                    return  # publishers are gone during shutdown; nothing left to report
                self._log.error(f'planning step failed: {error!r}\n{traceback.format_exc()}')
                values = {'event': 'plan', 'status': 'error', 'status_code': NAV2_UNKNOWN,
                          'reason': repr(error)}
                values.update(self._diagnostics.settings_values(snapshot.settings))
                try:
                    self._diagnostics.publish(self._node.get_clock().now().nanoseconds,
                                              DiagnosticStatus.ERROR,
                                              f'planning failed: {error!r}', values)
                except Exception:  # noqa: BLE001 - shutting down
                    return

    def _apply_map(self, snap: Snapshot) -> None:
        """Give the planner the snapshot's settings and map (its mask when it fits them)."""
        config_changed = snap.settings_changed and snap.settings.config != self._planner.config
        grid_changed = config_changed and (snap.settings.config.grid_key()
                                           != self._planner.config.grid_key())
        if config_changed:
            self._planner.set_config(snap.settings.config)
            if grid_changed:
                self._follow_bounds(snap.settings.config)
        live = snap.map
        if live is not None and (live is not self._applied_map or grid_changed):
            # The map's mask when it fits the settings; else the planner inflates its own at
            # the next plan (the intake is still building the one for the new settings).
            self._grid_from_map = self._planner.set_map(live.obstacles, live.blocked,
                                                        live.grid_key, live.fallback)
            self._applied_map = live

    def _step(self, snap: Snapshot) -> None:
        """Apply changed settings/map to the planner, then plan if something requires it."""
        self._apply_map(snap)
        goal = snap.goal
        if goal is None:
            return
        # A goal not attempted yet (normally goal_changed; also after a failed step).
        reason: Optional[str]
        if goal.serial != self._last_goal_serial:
            reason = 'new goal'
        elif self._replan_reason is not None:
            reason = self._replan_reason
        elif snap.settings_changed:
            reason = 'parameters changed'
        elif snap.replan_reason is not None:
            reason = snap.replan_reason
        elif snap.obstacles_changed and snap.settings.replan_on_obstacle_change:
            reason = self._obstacle_replan_reason(snap)
            if reason is None:
                return
        else:
            return
        self._plan(snap, goal, reason)

    def _obstacle_replan_reason(self, snap: Snapshot) -> Optional[str]:
        """Why new obstacles require a replan of the active goal, or None if they do not.

        The plan in force is re-checked by the intake as each map arrives (and withdrawn and
        replanned from there if it collides); here only a failed goal is retried.
        """
        last = self._last_result
        if last is None:
            return None
        if not last.ok:
            return 'obstacles changed' if last.status in _RETRY_ON_OBSTACLES else None
        in_force = self._in_force.current()
        if in_force is not None and in_force.result is last:
            return None
        if self._clear_ahead(last, snap):
            return None
        return 'obstacles changed and the current path is no longer clear'

    def _clear_ahead(self, result: PlanResult, snap: Snapshot,
                     obstacles: Optional[Any] = None) -> bool:
        """True when the curve of ``result`` still ahead of the vehicle is certified to keep
        gamma from ``obstacles`` (default: the planner's), by the clearance engine."""
        return self._verdict_ahead(result, snap, obstacles).clear

    @staticmethod
    def _plan_position(snap: Snapshot) -> Optional[np.ndarray]:
        """Where the vehicle was when ``snap`` was taken (None: only the start parameter is
        known): a plan from there is certified ahead of it."""
        return snap.start if snap.start_source != StartSource.PARAMETER else None

    def _verdict_ahead(self, result: PlanResult, snap: Snapshot,
                       obstacles: Optional[Any] = None) -> ClearanceVerdict:
        # Only the part still ahead of the vehicle matters.
        verdict = self._planner.plan_is_clear(result, self._plan_position(snap), obstacles)
        if not verdict.clear and verdict.blocked_at is not None:
            self._log.warning('the plan is blocked near '
                              f'{np.round(verdict.blocked_at, 3).tolist()}')
        return verdict

    def _cancel_test(self, goal: Goal, settings: NodeSettings) -> Callable[[], bool]:
        """A cancel test for the plan of ``goal``: true once a newer goal (after
        :data:`PREEMPT_GRACE_S` of planning), changed settings or shutdown makes the plan
        pointless (checked every few milliseconds by the planner)."""
        began = time.monotonic()

        def cancelled() -> bool:
            now, newer = self._inputs.cancel_state(goal, settings)
            if now:
                return True
            return newer and time.monotonic() - began >= PREEMPT_GRACE_S
        return cancelled

    def _report_progress(self, goal: Goal, settings: NodeSettings, stage: PlanStage,
                         elapsed_s: float, budget_s: float) -> None:
        """Progress callback of a long plan: which stage it is in, on the log and /diagnostics."""
        limit = f' of {budget_s:g} s' if budget_s > 0 else ''
        text = f'planning: {stage.value} after {elapsed_s:.1f} s{limit}'
        self._log.info(text)
        values: Dict[str, object] = {
            'event': 'progress', 'status': 'planning', 'stage': stage.value,
            'elapsed_s': elapsed_s, 'budget_s': budget_s, 'goal': goal.position}
        values.update(self._diagnostics.settings_values(settings))
        self._diagnostics.publish(self._node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.OK, text, values)

    def _admitted(self, point: np.ndarray, which: str, settings: NodeSettings) -> Admission:
        """The start (goal) to plan from (to), moved to free space by at most
        ``start_tolerance``
        (:func:`~uav_global_planner.core.search.start_admission.admit`): a landed
        vehicle, below the floor or within gamma of the ground it stands on, is lifted straight
        up (its take-off leg); a goal on the ground likewise (its landing leg)."""
        return admit(self._planner, point, which, settings.start_tolerance,
                     'the start_tolerance parameter')

    def predict_takeover(self, snap: Snapshot,
                         request_start: Optional[np.ndarray] = None) -> Takeover:
        """The start state of a plan beginning now (worker only; see ros/takeover.py).

        A request's own start counts as the vehicle when it lies within
        :data:`~uav_global_planner.ros.takeover.FOLLOW_DISTANCE_M` of the vehicle's newest
        odometry position; anywhere else the plan starts there from rest.
        """
        start, source = self._inputs.vehicle()
        if start is None:
            start, source = snap.start, snap.start_source
        in_force = self._in_force.current()
        if request_start is not None and (
                source != StartSource.ODOM
                or float(np.linalg.norm(request_start - start)) > FOLLOW_DISTANCE_M):
            return self._takeover.at_rest(request_start)
        return self._takeover.predict(start, source, in_force)

    def _plan_from(self, takeover: Takeover, start: np.ndarray, goal: Goal,
                   settings: NodeSettings) -> Tuple[PlanResult, Takeover, str]:
        """Plan ``goal`` from the takeover state (from ``start`` at rest when it is none); a
        predicted state the planner refuses as a start is replaced by a start from rest."""
        planner = self._planner
        result = planner.plan(
            takeover.position if takeover.moving else start, goal.position,
            cancel=self._cancel_test(goal, settings),
            progress=lambda *report: self._report_progress(goal, settings, *report),
            **takeover.plan_arguments(planner.plan))
        if not (takeover.moving and result.status in START_REFUSALS):
            return result, takeover, ''
        note = (f'the predicted takeover state at {np.round(takeover.position, 3).tolist()} '
                f'cannot start a plan ({result.message}); planned from rest instead')
        self._log.warning(note)
        takeover = takeover.from_rest(start)
        result = planner.plan(
            start, goal.position, cancel=self._cancel_test(goal, settings),
            progress=lambda *report: self._report_progress(goal, settings, *report))
        return result, takeover, note

    def _plan(self, snap: Snapshot, goal: Goal, reason: str) -> None:
        settings = snap.settings
        self._replan_reason = None
        takeover = self.predict_takeover(snap)
        admitted = self._admitted(snap.start, START, settings)
        landing = self._admitted(goal.position, GOAL, settings)
        fallback_builds = self._planner.fallback_builds
        result, takeover, takeover_note = self._plan_from(
            takeover, admitted.point, replace(goal, position=landing.point), settings)
        if takeover.moving:
            # The plan starts at the predicted state, not at snap.start.
            admitted = Admission(START, snap.start, snap.start)
        result = explain(result, (admitted, landing))
        start_note = admitted.note
        for note in (admitted.note, landing.note):
            if note:
                self._log.info(note)
        if self._planner.fallback_builds != fallback_builds and self._grid_from_map:
            # This map needed the conservative grid: from now on the intake keeps it up to
            # date too, so later plans do not inflate it (a second or so on a large map).
            self._intake.keep_fallback_grid()
        if result.status is PlanStatus.CANCELED:
            self._cancelled(snap, goal, result)
            return
        checked = (snap.obstacles_version, snap.obstacles_stamp_ns)
        frame = settings.frame_id
        drift_note = ''
        settlement: Optional[Settlement] = None
        in_force = self._in_force
        with in_force.held():
            # No map is installed while the release lock is held (see PlanInForce.release).
            newest_stamp_ns = self._inputs.map_stamps()[0]
            vehicle = self._inputs.vehicle_position()
            goal_current = self._inputs.goal_is(goal)
            if result.ok:
                # A map arrived while planning: publish only a plan that keeps gamma from it
                # too; otherwise plan again on it at once.
                verdict, newest = in_force.newest_map_verdict(result, checked[0],
                                                              self._plan_position(snap))
                if verdict is not None and not verdict.clear:
                    self._discard(snap, goal, newest.version, newest_stamp_ns)
                    return
                checked = (newest.version, newest_stamp_ns)
            if (result.ok and not takeover.moving and vehicle is not None
                    and snap.start_source != StartSource.PARAMETER):
                moved = float(np.linalg.norm(vehicle - snap.start))
                limit = settings.start_replan_distance
                if limit > 0.0 and moved > limit and goal_current:
                    if self._drift_replans < _MAX_DRIFT_REPLANS:
                        self._drift_replans += 1
                        self._drifted(snap, goal, moved)
                        return
                    drift_note = (f'the vehicle moved {moved:.2f} m from the start while '
                                  f'planning ({_MAX_DRIFT_REPLANS} replans in a row); published')
            if result.ok:
                # Also from rest: it measures the latency, and a vehicle that started moving
                # meanwhile (flying the plan in force) is planned for again from its motion.
                settlement = in_force.settle_takeover(takeover, result)
                if settlement.problem and settlement.retry and goal_current:
                    if self._drift_replans < _MAX_DRIFT_REPLANS:
                        self._drift_replans += 1
                        self._retake(snap, goal, settlement)
                        return
                    settlement = replace(settlement, problem=(
                        f'{settlement.problem} ({_MAX_DRIFT_REPLANS} replans in a row); '
                        'published'))
            stamp_ns = (settlement.stamp_ns if settlement is not None
                        else self._node.get_clock().now().nanoseconds)
            self._last_result, self._last_goal_serial = result, goal.serial
            if result.ok:
                self._drift_replans = 0
                orientation = tuple(float(v) for v in goal.orientation)
                in_force.release(result, checked[0], frame, stamp_ns, orientation, publish=True,
                                 position=self._plan_position(snap),
                                 start_source=snap.start_source, goal_serial=goal.serial)
            withdrawn = False
            latched = in_force.latched()
            if (not result.ok and latched is not None
                    and not self._clear_ahead(latched, snap)):
                # The latched plan now collides and nothing replaces it: a controller, even one
                # that subscribes later, must not fly it. Empty messages withdraw it.
                in_force.withdraw_plan(frame, stamp_ns)
                withdrawn = True
        takeover_problem = settlement.problem if settlement is not None else ''
        if result.ok:
            level = DiagnosticStatus.WARN if takeover_problem else DiagnosticStatus.OK
            continued = ''
            if takeover.moving:
                continued = (f', continuing the {takeover.kind.value.replace("_", " ")} from '
                             f'{takeover.latency_s:.3f} s ahead')
            self._log.info(
                f'plan ({reason}): {result.smoothed_length_m:.2f} m smoothed, '
                f'{result.expanded_nodes} nodes expanded in {result.planning_time_s:.3f} s, '
                f'min clearance {result.min_clearance_m:.3f} m, start from {snap.start_source}'
                + continued)
            if takeover_problem:
                self._log.warning(f'plan ({reason}): {takeover_problem}')
        else:
            level = DiagnosticStatus.ERROR
            self._log.warning(f'no plan ({reason}): {result.status.value} '
                              f'(code {NAV2_CODE_BY_STATUS[result.status]}): {result.message}')
        map_values = self._intake.map_values(snap.map)
        message = result.message
        if takeover_problem:
            message += f'; takeover: {takeover_problem}'
        if result.ok and map_values['map_refused']:
            # The map holds older data of a source whose newest message was refused: say so.
            level = DiagnosticStatus.WARN
            message += f'; map incomplete: {map_values["map_refused"]}'
        values = conv.plan_diagnostic_values(result, snap.start_source, {
            'reason': reason, 'plan_withdrawn': withdrawn, 'obstacles': len(snap.obstacles),
            'obstacles_version': snap.obstacles_version,
            'obstacles_stamp': snap.obstacles_stamp_ns, 'obstacles_checked_version': checked[0],
            'obstacles_checked_stamp': checked[1], 'frame_id': frame,
            'message': message, 'start_adjusted': bool(start_note),
            'requested_start': snap.start,
            'geofence': describe(self._inputs.airspace(), snap.settings.geofence_file),
            'climb_weight': snap.settings.config.climb_weight,
            'descent_weight': snap.settings.config.descent_weight})
        if start_note:
            values['start_note'] = start_note
        if landing.adjusted:
            values.update(landing.values())
        if snap.map is not None:
            # Whether the plan searched the intake's mask (built off the planning thread, for
            # the gamma below) or inflated its own (grid_build_time_s).
            values['grid_from_map'] = self._grid_from_map
            values['map_grid_gamma_m'] = float(snap.map.grid_key[3])
            values['map_mask_full'] = snap.map.update.full
            values['map_mask_time_s'] = snap.map.update.time_s
        if drift_note:
            values['note'] = drift_note
        values.update(takeover.values())
        if settlement is not None:
            values.update(settlement.values())
        if takeover_note:
            values['takeover_note'] = takeover_note
        for key in ('handover_velocity_error', 'handover_accel_error'):
            if hasattr(result, key):
                values[key] = getattr(result, key)
        values.update(map_values)
        self._diagnostics.publish(stamp_ns, level, f'{result.status.value}: {message}',
                                  values)

    def _cancelled(self, snap: Snapshot, goal: Goal, result: PlanResult) -> None:
        """A plan stopped by a newer goal, new settings or shutdown: nothing is published but
        an OK status (``event: plan_cancelled``); the newer request is served next."""
        if self._inputs.is_stopping():
            return
        if self._inputs.goal_is(goal):
            # Same goal, new settings: plan it again with them.
            self._replan_reason = 'parameters changed while planning'
        self._log.info(f'plan cancelled: {result.message}')
        values: Dict[str, object] = {'event': 'plan_cancelled', 'status': result.status.value,
                                     'reason': result.message, 'goal': goal.position}
        values.update(self._diagnostics.settings_values(snap.settings))
        self._diagnostics.publish(self._node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.OK, f'plan cancelled: {result.message}',
                                  values)

    def _discard(self, snap: Snapshot, goal: Goal, version: int, stamp_ns: int) -> None:
        """Drop a plan that collides with obstacles received while it was computed.

        Nothing is published but a WARN status (``event: plan_discarded``); the goal is planned
        again on the new obstacles right away (their arrival has woken the worker already).
        """
        text = (f'plan discarded: obstacles (version {version}) arrived while planning '
                f'(on version {snap.obstacles_version}) and the new plan does not keep gamma '
                'from them; planning again')
        self._drop_plan(snap, goal, 'obstacles changed while planning and collided with the plan',
                        text, {'obstacles_version': snap.obstacles_version,
                               'obstacles_stamp': snap.obstacles_stamp_ns,
                               'obstacles_checked_version': version,
                               'obstacles_checked_stamp': stamp_ns, 'goal': goal.position})

    def _drop_plan(self, snap: Snapshot, goal: Goal, reason: str, text: str,
                   extra: Dict[str, Any]) -> None:
        """Forget the plan computed for ``goal`` (it is planned again, for ``reason``), log
        ``text`` and publish it as a WARN status (``event: plan_discarded``) with the values
        ``extra`` and the settings of ``snap``."""
        self._last_result, self._last_goal_serial = None, goal.serial
        self._replan_reason = reason
        self._log.info(text)
        values = {'event': 'plan_discarded', 'status': 'discarded', 'reason': text, **extra}
        values.update(self._diagnostics.settings_values(snap.settings))
        self._diagnostics.publish(self._node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.WARN, text, values)

    def _drifted(self, snap: Snapshot, goal: Goal, moved_m: float) -> None:
        """Drop a plan whose start the vehicle left while it was computed; plan again from
        where the vehicle is now (``event: plan_discarded``, WARN)."""
        text = (f'plan discarded: the vehicle moved {moved_m:.2f} m from its start while it was '
                f'computed (start_replan_distance {snap.settings.start_replan_distance} m); '
                'planning again from the newest position')
        reason = 'the vehicle moved away from the start while planning'
        self._drop_plan(snap, goal, reason, text, {'goal': goal.position, 'start': snap.start})
        # Nothing else may wake the worker: ask for the replan explicitly.
        self._inputs.request_replan(reason)
        self._replan_reason = None

    def _retake(self, snap: Snapshot, goal: Goal, settlement: Settlement) -> None:
        """Drop a plan that cannot take over as predicted (late, the plan in force replaced,
        the vehicle off the prediction); plan again from a newer prediction
        (``event: plan_discarded``, WARN)."""
        text = f'plan discarded: {settlement.problem}; planning again from a newer prediction'
        extra: Dict[str, Any] = {'goal': goal.position}
        extra.update(settlement.values())
        reason = 'the predicted takeover did not hold'
        self._drop_plan(snap, goal, reason, text, extra)
        # Nothing else may wake the worker: ask for the replan explicitly.
        self._inputs.request_replan(reason)
        self._replan_reason = None

    def _run_jobs(self, snapshot: Snapshot) -> None:
        for job in self._inputs.take_jobs():
            job(self._planner, snapshot)
