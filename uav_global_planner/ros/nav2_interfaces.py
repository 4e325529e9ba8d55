"""Nav2's planner interfaces on the planner node: two actions and the ``GetPlan`` service.

=============================== ========================================= ====================
name (relative)                 type                                      answers with
=============================== ========================================= ====================
``compute_path_to_pose``        nav2_msgs/action/ComputePathToPose        path, codes 200-208
``compute_path_through_poses``  nav2_msgs/action/ComputePathThroughPoses  path, codes 300-309
``get_plan``                    nav_msgs/srv/GetPlan                      path (empty: failed)
=============================== ========================================= ====================

:class:`PlannerInterfaces` composes with the planner node, as tf2_ros's helpers do: it takes the
node (a :class:`PlanHost`) and creates its servers on it. Every request is planned by the node's
planning worker, the only thread that touches the planner
(:class:`~uav_global_planner.core.planner.Planner`): a request is a job handed to
:meth:`PlanHost.submit`; when the worker has run it, it queues the outcome and triggers a guard
condition, whose callback (on the executor thread) completes the future the action or service
coroutine awaits. So the executor never blocks on a plan, and
cancel requests, topics and parameters are served while one runs.

Semantics, as Nav2's planner server:

- ``use_start`` false: plan from the node's current start (the latest ``odom``/``start_pose``,
  else the ``start`` parameter); true: from ``start``. While the vehicle flies (odometry
  moving, along the plan in force or not), an action's plan continues its motion as the node's
  own plans do: it starts from the predicted state at the takeover time and is stamped with it
  (:mod:`~uav_global_planner.ros.takeover`); a ``start`` within
  :data:`~uav_global_planner.ros.takeover.FOLLOW_DISTANCE_M` of the vehicle counts as the
  vehicle. ``get_plan`` answers a query: from rest, as before.
- ``planner_id``: '' is the ``algorithm`` parameter; an algorithm name picks that heuristic;
  anything else is ``INVALID_PLANNER`` (201 / 301).
- The result's ``path`` is the smoothed, timed path (as on ``plan``, which a successful action
  plan is also published on, with ``unsmoothed_plan`` and ``trajectory``), ``planning_time`` the
  time the worker spent on the request, ``error_code``/``error_msg`` the outcome.
- ComputePathThroughPoses plans one continuous trajectory through ``goals[:-1]`` (passed exactly)
  to ``goals[-1]``; an empty list is ``NO_VIAPOINTS_GIVEN`` (309); a failing leg is named in
  ``error_msg``.
- Cancel: the running plan stops and the goal ends CANCELED. A new goal on the same action
  preempts the running one, which ends ABORTED with ``error_code`` 0 and ``error_msg`` saying so
  (as Nav2, which aborts it with an empty result).
- ``get_plan``: ``start`` is used when its frame is set, otherwise the current start. With
  ``tolerance`` > 0 and an occupied goal, the nearest free grid node within ``tolerance`` of it is
  planned to, and the log says so. Failures give an empty path, with the reason in the log and
  on ``/diagnostics``. GetPlan answers are not published on ``plan`` (a query, not a command).

Without nav2_msgs (a venv whose set-up could not build it) the action servers are off, the node
logs that once with the reason, and ``get_plan`` and the topics work as before.

One module, though long (about 670 lines): the three servers share the request queue to the
planning worker, the frame and tolerance checks and the error-code mapping.
"""

from dataclasses import dataclass, field
import math
import queue
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Protocol, Set, Tuple

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
import numpy as np
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.task import Future

from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.search.start_admission import admit, explain, nearest_free_node, START
from uav_global_planner.core.status import (NAV2_CODE_BY_STATUS, NAV2_INVALID_PLANNER,
                                            NAV2_NONE, NAV2_UNKNOWN, PlanStatus)
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import Settlement, START_REFUSALS, Takeover

try:
    from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
    #: Why the action servers are off (None: they are on).
    NAV2_UNAVAILABLE: Optional[str] = None
except ImportError as _error:  # the venv's set-up could not build nav2_msgs
    ComputePathThroughPoses = ComputePathToPose = None
    NAV2_UNAVAILABLE = f'nav2_msgs is not importable ({_error})'

TO_POSE_ACTION = 'compute_path_to_pose'
THROUGH_POSES_ACTION = 'compute_path_through_poses'
GET_PLAN_SERVICE = 'get_plan'

#: Offset of ComputePathThroughPoses' codes from ComputePathToPose's (UNKNOWN 300 vs 200).
THROUGH_POSES_OFFSET = 100
#: ComputePathThroughPoses: the goal list is empty.
NAV2_NO_VIAPOINTS_GIVEN = 309

#: Plans of one request made again because they could not take over as predicted (late, the
#: plan in force replaced, the vehicle off the prediction); the last one is published anyway,
#: with a WARN naming the jump.
MAX_TAKEOVER_REPLANS = 2

#: ``error_msg`` of a goal that a newer goal on the same action replaced.
PREEMPTED_TEXT = 'preempted by a newer goal'


class InvalidPlannerIdError(InvalidInputError):
    """A goal's ``planner_id`` names no algorithm of the planner (Nav2's INVALID_PLANNER)."""


class PlanHost(Protocol):
    """What :class:`PlannerInterfaces` needs from the planner node.

    :class:`~uav_global_planner.ros.planner_node.PlannerNode` provides it.
    """

    node: Node

    def submit(self, job: Callable[[Any, Any], None]) -> None:
        """Run ``job(planner, snapshot)`` on the planning worker once the pending settings and
        obstacles are applied; return at once. ``snapshot`` carries ``settings`` (frame_id and
        the planner config), ``start`` [m], ``start_source`` and ``obstacles_version``."""

    def release(self, result: PlanResult, checked_version: int, frame_id: str, stamp_ns: int,
                orientation: Tuple[float, ...], *, publish: bool,
                position: Optional[np.ndarray] = None) -> Any:
        """On the worker: the gate of every plan
        (:meth:`~uav_global_planner.ros.node_in_force.PlanInForce.release`): certify
        ``result`` (certified on map ``checked_version``) against the newest map, then latch it
        on ``plan``, ``unsmoothed_plan`` and ``trajectory`` (``publish``) or only serialise it;
        the returned :class:`~uav_global_planner.ros.node_in_force.Release` holds the bytes of
        ``plan`` or why it was refused."""

    def plan_for_export(self) -> Tuple[Any, str]:
        """On the worker: the plan in force and the newest map it keeps clear of
        (:class:`~uav_global_planner.ros.node_in_force.ExportablePlan`), or (None, why not)."""

    def while_in_force(self, stamp_ns: int, action: Callable[[], Any]) -> Tuple[bool, Any]:
        """Run ``action`` while the plan stamped ``stamp_ns`` is still in force (nothing is
        released or withdrawn meanwhile); (False, None) when it was withdrawn or replaced."""

    def publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                            values: Mapping[str, object]) -> None:
        """Publish one status of the node on ``/diagnostics``."""

    def current_settings(self) -> Any:
        """The node's settings in force (``frame_id``, ``config``)."""

    def map_refusal(self) -> str:
        """Why no request may be planned for want of a usable map file ('' when none)."""

    def predict_takeover(self, snapshot: Any, request_start: Optional[np.ndarray]) -> Takeover:
        """On the worker: the state a plan beginning now starts from (the vehicle's predicted
        state when it flies, else rest at the start; a request's start near the vehicle counts
        as the vehicle)."""

    def settle_takeover(self, takeover: Takeover, result: PlanResult) -> Settlement:
        """On the worker, just before publishing: the stamp of a successful plan from
        ``takeover``, and why it should not go out as it is."""


# --------------------------------------------------------------------------------------------
# ROS-free helpers
# --------------------------------------------------------------------------------------------

def resolve_planner_id(planner_id: str, default: str) -> str:
    """The algorithm a goal's ``planner_id`` asks for.

    Parameters
    ----------
    planner_id : str
        '' for the node's ``algorithm`` parameter, or one of the algorithm names.
    default : str
        The ``algorithm`` parameter.

    Raises
    ------
    InvalidPlannerIdError
        Naming the valid ids.
    """
    if planner_id == '':
        return default
    if planner_id in ALGORITHMS:
        return planner_id
    raise InvalidPlannerIdError(
        f'planner_id {planner_id!r} is not a planner of this node; use "" (the algorithm '
        f'parameter, now {default!r}) or one of: {", ".join(ALGORITHMS)}')


def result_code(status: PlanStatus, through_poses: bool) -> int:
    """Nav2 ``error_code`` of a plan outcome: ComputePathToPose's, or + 100 for
    ComputePathThroughPoses (NONE stays 0)."""
    code = NAV2_CODE_BY_STATUS[status]
    return code + THROUGH_POSES_OFFSET if through_poses and code != NAV2_NONE else code


# --------------------------------------------------------------------------------------------
# Requests between the executor and the planning worker
# --------------------------------------------------------------------------------------------

@dataclass(eq=False)
class _Request:
    """One planning request on its way through the worker.

    ``future`` is completed on the executor thread only; the worker sets ``outcome``.
    """

    kind: str
    goal: np.ndarray
    orientation: np.ndarray
    frame_id: str
    algorithm: str
    start: Optional[np.ndarray] = None
    via: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    tolerance: float = 0.0
    publish: bool = True
    cancel: threading.Event = field(default_factory=threading.Event)
    preempted: bool = False
    future: Future = field(default_factory=Future)
    outcome: Optional['_Outcome'] = None


@dataclass(frozen=True, eq=False)
class _Outcome:
    """What the worker made of a request."""

    result: Optional[PlanResult]
    status: PlanStatus
    message: str
    planning_time_s: float
    path: Optional[Path] = None
    goal_used: Optional[np.ndarray] = None


class _Refused(Exception):
    """A goal refused before planning, with its Nav2 code (ComputePathToPose numbering)."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class PlannerInterfaces:
    """Nav2's ComputePathToPose / ComputePathThroughPoses actions and nav_msgs GetPlan.

    Parameters
    ----------
    host : PlanHost
        The planner node; its rclpy node gets the servers.
    """

    def __init__(self, host: PlanHost) -> None:
        self._host = host
        node = host.node
        self._node = node
        self._log = node.get_logger()
        self._finished: 'queue.SimpleQueue[_Request]' = queue.SimpleQueue()
        self._lock = threading.Lock()
        # Guarded by _lock: the newest request of each action, and the requests by goal id.
        self._active: Dict[str, _Request] = {}
        self._by_goal: Dict[bytes, _Request] = {}
        # Guarded by _lock: every request handed to the worker and not yet answered.
        self._pending: Set[_Request] = set()
        # One reentrant group for every entity here: a coroutine callback keeps its callback
        # group busy while it awaits the worker, and in the node's default (mutually exclusive)
        # group that would stall every topic and parameter callback of the node for the whole
        # plan. The executor is single-threaded, so nothing here runs concurrently anyway.
        self._group = ReentrantCallbackGroup()
        # rclpy futures do not wake the executor when completed from another thread; the worker
        # triggers this guard condition instead, and its callback completes them.
        self._guard = node.create_guard_condition(self._complete_finished, self._group)
        self._service = node.create_service(GetPlan, GET_PLAN_SERVICE, self._on_get_plan,
                                            callback_group=self._group)
        self._servers: List[ActionServer] = []
        if NAV2_UNAVAILABLE is not None:
            self._log.warning(
                f'Nav2 action servers {TO_POSE_ACTION} and {THROUGH_POSES_ACTION} are off: '
                f'{NAV2_UNAVAILABLE}. In the venv of the project, scripts/build_interfaces.sh '
                'builds it; on a ROS 2 install, install nav2_msgs (ros-jazzy-nav2-msgs). The '
                f'topics and {GET_PLAN_SERVICE} are served.')
            return
        for action_type, name, execute in (
                (ComputePathToPose, TO_POSE_ACTION, self._execute_to_pose),
                (ComputePathThroughPoses, THROUGH_POSES_ACTION, self._execute_through_poses)):
            self._servers.append(ActionServer(
                node, action_type, name, execute_callback=execute,
                goal_callback=lambda request: GoalResponse.ACCEPT,
                handle_accepted_callback=lambda handle, name=name: self._accepted(handle, name),
                cancel_callback=self._cancel_requested,
                callback_group=self._group))

    @property
    def actions_available(self) -> bool:
        """True when the two action servers run."""
        return bool(self._servers)

    def destroy(self) -> None:
        """Cancel the requests still planned, then destroy the servers (before the node)."""
        with self._lock:
            pending = list(self._pending)
        for request in pending:
            request.cancel.set()
        for server in self._servers:
            server.destroy()
        self._servers = []
        self._node.destroy_service(self._service)
        self._node.destroy_guard_condition(self._guard)

    # ---------------------------------------------------------------------------- actions

    def _accepted(self, goal_handle, action: str) -> None:
        """A goal was accepted: it replaces (preempts) the running goal of the same action."""
        request = _Request(kind=action, goal=np.zeros(3), orientation=np.zeros(4),
                           frame_id='', algorithm='')
        with self._lock:
            previous = self._active.get(action)
            self._active[action] = request
            self._by_goal[bytes(goal_handle.goal_id.uuid)] = request
        if previous is not None and not previous.future.done():
            previous.preempted = True
            previous.cancel.set()
        goal_handle.execute()

    def _cancel_requested(self, goal_handle) -> CancelResponse:
        with self._lock:
            request = self._by_goal.get(bytes(goal_handle.goal_id.uuid))
        if request is not None:
            request.cancel.set()
        return CancelResponse.ACCEPT

    # rclpy awaits an execute callback only when it is itself a coroutine function.
    async def _execute_to_pose(self, goal_handle):
        return await self._execute(goal_handle, TO_POSE_ACTION)

    async def _execute_through_poses(self, goal_handle):
        return await self._execute(goal_handle, THROUGH_POSES_ACTION)

    async def _execute(self, goal_handle, action: str):
        key = bytes(goal_handle.goal_id.uuid)
        with self._lock:
            request = self._by_goal[key]
        through = action == THROUGH_POSES_ACTION
        action_type = ComputePathThroughPoses if through else ComputePathToPose
        result = action_type.Result()
        try:
            try:
                self._fill_action_request(request, goal_handle.request, through)
            except _Refused as refused:
                return self._finish_refused(goal_handle, request, result, refused, through)
            outcome = await self._submit(request)
        finally:
            with self._lock:
                self._by_goal.pop(key, None)
                if self._active.get(action) is request:
                    del self._active[action]
        result.planning_time = conv.duration_from_seconds(outcome.planning_time_s)
        if outcome.status is PlanStatus.OK:
            result.path = outcome.path
            result.error_code = NAV2_NONE
            goal_handle.succeed()
            return result
        if request.preempted:
            # Nav2 aborts a preempted goal with an empty result (error_code 0).
            result.error_code, result.error_msg = NAV2_NONE, PREEMPTED_TEXT
            goal_handle.abort()
            return result
        if outcome.status is PlanStatus.CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
            return result
        result.error_code = result_code(outcome.status, through)
        result.error_msg = outcome.message
        goal_handle.abort()
        return result

    def _finish_refused(self, goal_handle, request: _Request, result, refused: _Refused,
                        through: bool):
        code = refused.code
        if through and code != NAV2_NONE and code < NAV2_NO_VIAPOINTS_GIVEN:
            code += THROUGH_POSES_OFFSET
        result.error_code, result.error_msg = code, str(refused)
        self._log.warning(f'{request.kind} goal refused (code {code}): {refused}')
        self._report_refusal(request.kind, code, str(refused))
        request.future.set_result(None)
        goal_handle.abort()
        return result

    def _fill_action_request(self, request: _Request, goal, through: bool) -> None:
        """Check a goal (frames, numbers, planner_id) and fill ``request`` from it.

        Raises
        ------
        _Refused
            With ComputePathToPose's code (TF_ERROR, UNKNOWN, INVALID_PLANNER) or
            NO_VIAPOINTS_GIVEN.
        """
        settings = self._host.current_settings()
        frame = settings.frame_id
        if through:
            poses = list(goal.goals)
            if not poses:
                raise _Refused('no poses given: goals is empty', NAV2_NO_VIAPOINTS_GIVEN)
        else:
            poses = [goal.goal]
        positions = []
        for number, pose in enumerate(poses):
            what = f'goals[{number}]' if through else 'goal'
            positions.append(self._pose(pose, frame, what))
        request.goal = positions[-1][0]
        request.orientation = positions[-1][1]
        request.via = (np.array([p for p, _ in positions[:-1]]) if len(positions) > 1
                       else np.empty((0, 3)))
        request.frame_id = frame
        if goal.use_start:
            request.start = self._pose(goal.start, frame, 'start')[0]
        try:
            request.algorithm = resolve_planner_id(goal.planner_id, settings.config.algorithm)
        except InvalidPlannerIdError as error:
            raise _Refused(str(error), NAV2_INVALID_PLANNER) from None

    @staticmethod
    def _pose(msg: PoseStamped, frame: str, what: str) -> Tuple[np.ndarray, np.ndarray]:
        try:
            return conv.pose_stamped_to_pose(msg, frame, what)
        except conv.InputRejected as error:
            raise _Refused(str(error), error.code) from None
        except InvalidInputError as error:
            raise _Refused(str(error), NAV2_UNKNOWN) from None

    # ---------------------------------------------------------------------------- GetPlan

    async def _on_get_plan(self, request_msg, response):
        settings = self._host.current_settings()
        frame = settings.frame_id
        response.plan = conv.points_to_path(np.empty((0, 3)), frame,
                                            self._node.get_clock().now().nanoseconds)
        request = _Request(kind=GET_PLAN_SERVICE, goal=np.zeros(3), orientation=np.zeros(4),
                           frame_id=frame, algorithm=settings.config.algorithm, publish=False)
        try:
            request.goal, request.orientation = self._pose(request_msg.goal, frame, 'goal')
            if request_msg.start.header.frame_id:
                request.start = self._pose(request_msg.start, frame, 'start')[0]
            tolerance = float(request_msg.tolerance)
            if not math.isfinite(tolerance) or tolerance < 0.0:
                raise _Refused(f'tolerance must be a finite number >= 0 m, got {tolerance}',
                               NAV2_UNKNOWN)
            request.tolerance = tolerance
        except _Refused as refused:
            self._log.warning(f'{GET_PLAN_SERVICE} refused (code {refused.code}): {refused}; '
                              'answering with an empty path')
            self._report_refusal(GET_PLAN_SERVICE, refused.code, str(refused))
            return response
        outcome = await self._submit(request)
        if outcome.status is PlanStatus.OK and outcome.path is not None:
            response.plan = outcome.path
        return response

    # ---------------------------------------------------------------------------- worker side

    def _submit(self, request: _Request) -> Future:
        """Hand ``request`` to the planning worker; the future completes with its outcome."""
        with self._lock:
            self._pending.add(request)
        self._host.submit(lambda planner, snapshot: self._run(request, planner, snapshot))
        return request.future

    def _run(self, request: _Request, planner, snapshot) -> None:
        """On the planning worker: plan one request, publish, report, hand the outcome back."""
        try:
            outcome = self._plan(request, planner, snapshot)
        except Exception as error:  # noqa: BLE001 - the client must get an answer
            self._log.error(f'{request.kind} request failed: {error!r}')
            outcome = _Outcome(None, PlanStatus.INVALID_INPUT, f'internal error: {error!r}', 0.0)
        request.outcome = outcome
        self._finished.put(request)
        try:
            self._guard.trigger()
        except Exception:  # noqa: BLE001 - the node is being destroyed; nobody waits
            pass

    def _plan(self, request: _Request, planner, snapshot) -> _Outcome:
        if request.cancel.is_set():
            text = PREEMPTED_TEXT if request.preempted else 'cancelled before planning'
            return _Outcome(None, PlanStatus.CANCELED, text, 0.0)
        refusal = self._host.map_refusal()
        if refusal:
            # Planning without the map file asked for would fly through what it holds.
            return _Outcome(None, PlanStatus.INVALID_INPUT, refusal, 0.0)
        if request.start is not None:
            start, source = request.start, StartSource.REQUEST
        else:
            start, source = snapshot.start, snapshot.start_source
        # The node's own admission: a landed vehicle's start is lifted off the ground, one a
        # little inside the margin moved, by at most start_tolerance.
        admitted = admit(planner, start, START, snapshot.settings.start_tolerance,
                         'the start_tolerance parameter')
        start = admitted.point
        started = time.perf_counter()
        settlement: Optional[Settlement] = None
        for attempt in range(MAX_TAKEOVER_REPLANS + 1):
            # A published plan continues the vehicle's motion (ros/takeover.py); a GetPlan
            # query starts from rest, as it always did.
            takeover = (self._host.predict_takeover(snapshot, request.start) if request.publish
                        else None)
            result, takeover, takeover_note = self._plan_from(request, planner, snapshot, start,
                                                              takeover)
            if takeover is not None and result.ok:
                # Also from rest: it measures the latency.
                settlement = self._host.settle_takeover(takeover, result)
                if (settlement.problem and settlement.retry and attempt < MAX_TAKEOVER_REPLANS
                        and not request.cancel.is_set()):
                    self._report_retake(request, settlement)
                    continue
            break
        if takeover is None or not takeover.moving:
            result = explain(result, (admitted,))
            takeover_note = '; '.join(n for n in (admitted.note, takeover_note) if n)
        goal_used = request.goal
        note = takeover_note
        if result.status is PlanStatus.GOAL_OCCUPIED and request.tolerance > 0.0:
            result, goal_used, note = self._plan_within_tolerance(request, planner, start,
                                                                  result)
        elapsed = time.perf_counter() - started
        stamp_ns = (settlement.stamp_ns if settlement is not None
                    else self._node.get_clock().now().nanoseconds)
        frame = snapshot.settings.frame_id
        path = None
        if result.ok:
            # Certified against the map it was planned on; a client gets it only when the
            # newest map keeps it clear too and (published) it is in force: the node's gate.
            position = (snapshot.start if request.start is None
                        and snapshot.start_source != StartSource.PARAMETER else None)
            released = self._host.release(
                result, snapshot.obstacles_version, frame, stamp_ns,
                tuple(float(v) for v in request.orientation), publish=request.publish,
                position=position)
            if released.released:
                path = deserialize_message(released.data, Path)
            else:
                result = result.refused(PlanStatus.NO_VALID_PATH, released.refusal)
        message = result.message
        failed_leg = getattr(result, 'failed_leg', -1)
        if failed_leg >= 0 and 'leg' not in message:
            message = f'leg {failed_leg}: {message}'
        extra: Dict[str, object] = {} if takeover is None else takeover.values()
        if settlement is not None:
            extra.update(settlement.values())
            if settlement.problem:
                message += f'; takeover: {settlement.problem}'
        self._report(request, result, source, stamp_ns, elapsed, note, message, extra)
        return _Outcome(result, result.status, message, elapsed, path, goal_used)

    def _plan_from(self, request: _Request, planner, snapshot, start: np.ndarray,
                   takeover: Optional[Takeover]
                   ) -> Tuple[PlanResult, Optional[Takeover], str]:
        """Plan a request from the takeover state (from ``start`` at rest when there is none);
        a predicted state the planner refuses as a start is replaced by ``start`` at rest."""
        moving = takeover is not None and takeover.moving
        result = planner.plan(
            takeover.position if takeover is not None and moving else start, request.goal,
            request.algorithm, via=request.via, cancel=request.cancel.is_set,
            progress=lambda *report: self._progress(request, snapshot, *report),
            **(takeover.plan_arguments(planner.plan) if takeover is not None else {}))
        if not (takeover is not None and moving and result.status in START_REFUSALS):
            return result, takeover, ''
        note = (f'the predicted takeover state at {np.round(takeover.position, 3).tolist()} '
                f'cannot start a plan ({result.message}); planned from rest instead')
        self._log.warning(f'{request.kind} request: {note}')
        result = planner.plan(
            start, request.goal, request.algorithm, via=request.via,
            cancel=request.cancel.is_set,
            progress=lambda *report: self._progress(request, snapshot, *report))
        return result, takeover.from_rest(start), note

    def _report_retake(self, request: _Request, settlement: Settlement) -> None:
        """A request's plan that cannot take over as predicted: dropped, planned again."""
        text = (f'{request.kind} request: plan discarded: {settlement.problem}; planning again '
                'from a newer prediction')
        self._log.info(text)
        values: Dict[str, object] = {'event': 'plan_discarded', 'status': 'discarded',
                                     'reason': text, 'goal': request.goal}
        values.update(settlement.values())
        self._host.publish_diagnostics(self._node.get_clock().now().nanoseconds,
                                       DiagnosticStatus.WARN, text, values)

    def _plan_within_tolerance(self, request: _Request, planner, start,
                               first: PlanResult) -> Tuple[PlanResult, np.ndarray, str]:
        """GetPlan with tolerance: plan to the nearest free node near an occupied goal."""
        config = planner.config
        node = nearest_free_node(planner.grid, planner.obstacles, config.planning_margin,
                                 request.goal, request.tolerance)
        if node is None:
            note = (f'goal {request.goal.tolist()} is occupied and no free node lies within the '
                    f'tolerance of {request.tolerance} m')
            return first, request.goal, note
        distance = float(np.linalg.norm(node - request.goal))
        note = (f'goal {request.goal.tolist()} is occupied ({first.message}); planning to the '
                f'nearest free node {node.tolist()}, {distance:.3f} m away (tolerance '
                f'{request.tolerance} m)')
        self._log.info(f'{GET_PLAN_SERVICE}: {note}')
        result = planner.plan(start, node, request.algorithm, cancel=request.cancel.is_set)
        return result, node, note

    def _progress(self, request: _Request, snapshot, stage, elapsed_s: float,
                  budget_s: float) -> None:
        """Progress of a long plan (after 1 s, then every second): on the log and
        ``/diagnostics`` (``event: progress``), as the node reports its own plans."""
        limit = f' of {budget_s:g} s' if budget_s > 0 else ''
        text = f'{request.kind} request: {stage.value} after {elapsed_s:.1f} s{limit}'
        self._log.info(text)
        settings = snapshot.settings
        values = {'event': 'progress', 'status': 'planning', 'stage': stage.value,
                  'elapsed_s': elapsed_s, 'budget_s': budget_s, 'goal': request.goal,
                  'reason': f'{request.kind} request', 'algorithm': request.algorithm,
                  'frame_id': settings.frame_id}
        self._host.publish_diagnostics(self._node.get_clock().now().nanoseconds,
                                       DiagnosticStatus.OK, text, values)

    def _report(self, request: _Request, result: PlanResult, source: StartSource, stamp_ns: int,
                elapsed_s: float, note: str, message: str,
                extra: Optional[Mapping[str, object]] = None) -> None:
        reason = f'{request.kind} request'
        through = request.kind == THROUGH_POSES_ACTION
        code = result_code(result.status, through)
        legs = len(request.via) + 1
        if result.ok:
            level = DiagnosticStatus.OK
            self._log.info(
                f'{reason}: {result.smoothed_length_m:.2f} m smoothed'
                + (f' through {legs - 1} via-point(s)' if legs > 1 else '')
                + f', {result.expanded_nodes} nodes expanded, {elapsed_s:.3f} s, min clearance '
                f'{result.min_clearance_m:.3f} m' + (f'; {note}' if note else ''))
        elif result.status is PlanStatus.CANCELED:
            level = DiagnosticStatus.WARN
            self._log.info(f'{reason} {PREEMPTED_TEXT if request.preempted else "cancelled"}')
        else:
            level = DiagnosticStatus.ERROR
            self._log.warning(f'{reason} failed: {result.status.value} (code {code}): {message}'
                              + (f'; {note}' if note else ''))
        values = conv.plan_diagnostic_values(result, source, {
            'reason': reason, 'status_code': code, 'message': message,
            'request_time_s': elapsed_s, 'via_points': len(request.via),
            'failed_leg': getattr(result, 'failed_leg', -1), 'frame_id': request.frame_id})
        if request.tolerance > 0.0:
            values['tolerance_m'] = request.tolerance
        if note:
            values['note'] = note
        values.update(extra or {})
        if result.ok and 'takeover_problem' in values:
            level = DiagnosticStatus.WARN
        self._host.publish_diagnostics(stamp_ns, level, f'{result.status.value}: {message}',
                                       values)

    def _report_refusal(self, kind: str, code: int, text: str) -> None:
        values = {'event': 'plan', 'status': 'rejected', 'status_code': code,
                  'reason': f'{kind} request', 'message': text}
        self._host.publish_diagnostics(self._node.get_clock().now().nanoseconds,
                                       DiagnosticStatus.ERROR, f'rejected: {text}', values)

    def _complete_finished(self) -> None:
        """Guard-condition callback (executor thread): complete the finished requests."""
        while True:
            try:
                request = self._finished.get_nowait()
            except queue.Empty:
                return
            with self._lock:
                self._pending.discard(request)
            if not request.future.done():
                request.future.set_result(request.outcome)
