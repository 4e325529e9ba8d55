"""Replans in flight: the state where a new plan takes over from the plan in force.

A plan made while the vehicle flies another must continue it without a jump. When planning
begins, :class:`TakeoverPredictor` predicts the takeover time ``t_k = now + expected latency``
(the time the new plan will be published), and the state the vehicle will have then:

``plan_in_force``
    The start comes from ``odom``, a plan is in force, the vehicle follows it (its newest
    position within :data:`FOLLOW_DISTANCE_M` of where the plan has it now and, when the
    odometry carries a twist, its velocity within :data:`FOLLOW_SPEED_ERROR_MPS` plus
    :data:`FOLLOW_SPEED_FRACTION` of the plan's speed of the plan's velocity), and the plan still
    moves at ``t_k`` (at least :data:`HANDOVER_MIN_SPEED`): the plan's position, velocity,
    acceleration and heading at ``t_k`` (:meth:`Trajectory.state_at
    <uav_global_planner.core.result.Trajectory.state_at>`, the plan's time being counted from
    its header stamp).
``odometry``
    Otherwise, when the newest odometry reports a speed of at least
    :data:`HANDOVER_MIN_SPEED`: its linear velocity in the planning frame
    (:func:`odometry_velocity`), zero acceleration, and its position moved on at that velocity
    to ``t_k``.
``rest``
    Otherwise the plan starts at rest from the start, as a plan always did.

The new plan starts from that state (``Planner.plan(..., start_velocity, start_acceleration,
start_yaw)``) and its messages are stamped ``t_k``: a follower that switches at the header stamp
sees one continuous reference. A plan from rest is stamped when it is published, as before.

The expected latency is the :data:`LATENCY_PERCENTILE` th percentile of the last
:data:`LATENCY_WINDOW` measured latencies (from the prediction to the moment the plan is
published: planning, the checks against a newer map and serialising included), plus
:data:`PUBLISH_MARGIN_S` for publishing and delivery; :data:`FIRST_LATENCY_S` before any plan was
measured.

When the plan is ready, :meth:`TakeoverPredictor.settle` compares it with what the vehicle flies
until the switch, at the switch: at ``t_k``, or at once when ``t_k`` has passed (a plan later
than predicted). Within :data:`POSITION_TOLERANCE_M`, :data:`VELOCITY_TOLERANCE_MPS` and
:data:`ACCEL_TOLERANCE_MPS2` it is published as it is; a late plan beyond them is made again
from a newer prediction (the node allows a few such replans in a row, then publishes with a WARN
naming the jump); a plan that could not keep the state (not late) is published with a WARN
naming the jump. The measured latency joins the estimate either way.
"""

from collections import deque
from dataclasses import dataclass, field
from enum import StrEnum
import inspect
import math
import threading
from typing import Any, Callable, Deque, Dict, Optional, Tuple

import numpy as np

from uav_global_planner.core.path.handover import HANDOVER_MIN_SPEED
from uav_global_planner.core.result import ReferenceState, Trajectory
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.conversions.poses import rotation_matrix
from uav_global_planner.ros.node_state import InForce
from uav_global_planner.ros.start_source import StartSource


#: Measured latencies the estimate is taken from (the newest ones).
LATENCY_WINDOW = 20
#: Percentile of the measured latencies taken as the expected planning latency [%].
LATENCY_PERCENTILE = 90.0
#: Added to it for publishing and delivering the plan [s].
PUBLISH_MARGIN_S = 0.05
#: Expected latency before any plan was measured [s].
FIRST_LATENCY_S = 0.5
#: Largest expected latency [s]: a plan predicted that far ahead is about a different flight.
MAX_LATENCY_S = 10.0

#: A vehicle within this distance of where the plan in force has it now follows that plan [m].
FOLLOW_DISTANCE_M = 2.0
#: ... when its odometry velocity differs from the plan's by at most this [m/s] ...
FOLLOW_SPEED_ERROR_MPS = 0.5
#: ... plus this fraction of the plan's speed [-].
FOLLOW_SPEED_FRACTION = 0.3

#: Largest jump at the switch from the flown reference to the new plan: position [m],
#: velocity [m/s], acceleration [m/s^2].
POSITION_TOLERANCE_M = 0.01
VELOCITY_TOLERANCE_MPS = 0.05
ACCEL_TOLERANCE_MPS2 = 0.2

#: Outcomes of a plan from a predicted state that a plan from rest at the vehicle may avoid.
START_REFUSALS = (PlanStatus.START_OCCUPIED, PlanStatus.START_OUTSIDE_MAP)

_NS = 1_000_000_000


class TakeoverKind(StrEnum):
    """Where the start state of a plan comes from; the value is the diagnostics text."""

    PLAN_IN_FORCE = 'plan_in_force'
    ODOMETRY = 'odometry'
    REST = 'rest'


@dataclass(frozen=True, eq=False)
class OdometryMotion:
    """The newest odometry: position [m], velocity [m/s] (planning frame), heading [rad] and
    when it arrived (node clock [ns]); velocity None when the twist was not finite."""

    position: np.ndarray
    velocity: Optional[np.ndarray]
    yaw: float
    received_ns: int


@dataclass(frozen=True, eq=False)
class SwitchJump:
    """How far the new plan is from what the vehicle flies, at the switch.

    Attributes
    ----------
    late_s : float
        How long before publishing the takeover time passed [s]; <= 0 when on time.
    position_m, velocity_mps, accel_mps2 : float
        Norms of the differences at the switch [m], [m/s], [m/s^2].
    """

    late_s: float
    position_m: float
    velocity_mps: float
    accel_mps2: float

    @property
    def within(self) -> bool:
        """True when every difference is within its tolerance."""
        return (self.position_m <= POSITION_TOLERANCE_M
                and self.velocity_mps <= VELOCITY_TOLERANCE_MPS
                and self.accel_mps2 <= ACCEL_TOLERANCE_MPS2)

    def describe(self) -> str:
        return (f'{self.position_m:.3f} m, {self.velocity_mps:.3f} m/s, '
                f'{self.accel_mps2:.3f} m/s^2')


@dataclass(frozen=True, eq=False)
class Takeover:
    """The predicted start of a plan.

    Attributes
    ----------
    kind : TakeoverKind
    predicted_ns : int
        When the prediction was made (node clock) [ns].
    stamp_ns : int
        Takeover time ``t_k``: the new plan's header stamp (node clock) [ns]; for a plan from
        rest, the prediction time (the plan is then stamped when published).
    position, velocity, acceleration : numpy.ndarray, shape (3,)
        State at ``t_k`` [m], [m/s], [m/s^2] (planning frame, ENU).
    yaw : float or None
        Heading at ``t_k`` [rad] (ENU), when known.
    latency_s : float
        Expected latency used [s].
    in_force : InForce or None
        The plan continued (``plan_in_force`` only).
    odometry : OdometryMotion or None
        The odometry extrapolated (``odometry``), or the odometry that showed the vehicle at
        rest (``rest`` from the vehicle's position).
    path : numpy.ndarray or None, shape (N, 3)
        The plan in force's reference positions after ``t_k`` [m] (``plan_in_force`` only):
        the new curve follows them for its lead-in.
    """

    kind: TakeoverKind
    predicted_ns: int
    stamp_ns: int
    position: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw: Optional[float] = None
    latency_s: float = 0.0
    in_force: Optional[InForce] = None
    odometry: Optional[OdometryMotion] = None
    path: Optional[np.ndarray] = None

    @property
    def moving(self) -> bool:
        """True unless the plan starts from rest."""
        return self.kind is not TakeoverKind.REST

    def from_rest(self, start: np.ndarray) -> 'Takeover':
        """The same prediction, but a start from rest at ``start`` [m] instead."""
        return Takeover(TakeoverKind.REST, self.predicted_ns, self.predicted_ns,
                        np.asarray(start, dtype=np.float64))

    def flown_at(self, at_ns: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the vehicle flies at ``at_ns`` until the switch: position, velocity and
        acceleration of the plan in force, or of the odometry at constant velocity."""
        if self.in_force is not None:
            plan = self.in_force.flown_at(at_ns)
            if plan.result.trajectory is not None:
                state = plan.result.trajectory.state_at((at_ns - plan.stamp_ns) / _NS)
                return state.position[0], state.velocity[0], state.acceleration[0]
        dt = (at_ns - self.stamp_ns) / _NS
        return self.position + dt * self.velocity, self.velocity, np.zeros(3)

    def plan_arguments(self, plan: Callable[..., Any]) -> Dict[str, Any]:
        """Keyword arguments of ``plan`` (``Planner.plan``) for this start state; from rest only
        the vehicle's heading (the heading profile turns from it instead of jumping), and
        nothing a planner does not take."""
        accepted = inspect.signature(plan).parameters
        if not self.moving:
            if self.yaw is None or 'start_yaw' not in accepted:
                return {}
            return {'start_yaw': float(self.yaw)}
        values: Dict[str, Any] = {'start_velocity': self.velocity.copy(),
                                  'start_acceleration': self.acceleration.copy()}
        if self.yaw is not None:
            values['start_yaw'] = float(self.yaw)
        if self.path is not None and len(self.path):
            values['start_path'] = self.path.copy()
        return {name: value for name, value in values.items() if name in accepted}

    def values(self) -> Dict[str, object]:
        """Diagnostics key values of the prediction."""
        out: Dict[str, object] = {'takeover': self.kind.value}
        if self.moving:
            out.update({'takeover_stamp': self.stamp_ns,
                        'takeover_latency_s': self.latency_s,
                        'takeover_velocity': self.velocity,
                        'takeover_acceleration': self.acceleration})
        if self.in_force is not None:
            out['takeover_plan_stamp'] = self.in_force.stamp_ns
            out['takeover_plan_time_s'] = (self.stamp_ns - self.in_force.stamp_ns) / _NS
        return out


@dataclass(frozen=True, eq=False)
class Settlement:
    """What to do with a plan made from a takeover prediction.

    Attributes
    ----------
    stamp_ns : int
        Header stamp to publish it with [ns].
    jump : SwitchJump or None
        At the switch (moving starts only).
    problem : str
        Empty when the plan can go out as it is; else why not.
    retry : bool
        Whether planning again from a newer prediction can help (a late plan, a replaced
        plan in force, a vehicle that left the predicted track).
    """

    stamp_ns: int
    jump: Optional[SwitchJump] = None
    problem: str = ''
    retry: bool = False

    def values(self) -> Dict[str, object]:
        """Diagnostics key values of the outcome."""
        if self.jump is None:
            return {}
        jump = self.jump
        out: Dict[str, object] = {
            'takeover_late_s': max(jump.late_s, 0.0),
            'takeover_jump_position_m': jump.position_m,
            'takeover_jump_velocity_mps': jump.velocity_mps,
            'takeover_jump_accel_mps2': jump.accel_mps2}
        if self.problem:
            out['takeover_problem'] = self.problem
        return out


def odometry_velocity(msg: Any, expected_frame: str, what: str = 'odom') -> np.ndarray:
    """Linear velocity [m/s] of a ``nav_msgs/Odometry`` in the planning frame.

    The twist of an Odometry is given in ``child_frame_id``. When that names the header frame
    (the planning frame), it is used as it is; otherwise it is the body frame whose pose the
    message gives, and the velocity is rotated by the pose's orientation (an empty
    ``child_frame_id`` counts as the body frame, as REP 105's ``base_link``).

    Raises
    ------
    InputRejected
        For a wrong header frame or non-finite numbers.
    """
    conv.check_frame(msg.header.frame_id, expected_frame, what)
    velocity = conv.point_to_array(msg.twist.twist.linear, f'{what} twist')
    if conv.normalize_frame(msg.child_frame_id) == conv.normalize_frame(msg.header.frame_id):
        return velocity
    quaternion = conv.quaternion_to_array(msg.pose.pose.orientation, what)
    return rotation_matrix(quaternion.tolist()) @ velocity


class TakeoverPredictor:
    """Latency estimate, newest odometry and the takeover predictions of one node.

    Thread-safe: the executor gives it odometry, the planning worker predicts and settles.

    Parameters
    ----------
    clock_ns : callable
        The node's clock [ns] (ROS time, as the plan stamps).
    """

    def __init__(self, clock_ns: Callable[[], int]) -> None:
        self._clock_ns = clock_ns
        self._lock = threading.Lock()
        # Guarded by _lock.
        self._latencies: Deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._odometry: Optional[OdometryMotion] = None

    def on_odometry(self, position: np.ndarray, velocity: Optional[np.ndarray],
                    yaw: float) -> None:
        """Keep the newest odometry (planning frame); ``velocity`` None when unknown."""
        motion = OdometryMotion(np.asarray(position, dtype=np.float64).copy(),
                                None if velocity is None else np.asarray(velocity, float).copy(),
                                float(yaw), self._clock_ns())
        with self._lock:
            self._odometry = motion

    def forget_odometry(self) -> None:
        """Drop the odometry (the planning frame changed)."""
        with self._lock:
            self._odometry = None

    def record_latency(self, seconds: float) -> None:
        """Add one measured latency (prediction to publishing) [s]."""
        if math.isfinite(seconds) and seconds >= 0.0:
            with self._lock:
                self._latencies.append(float(seconds))

    def expected_latency_s(self) -> float:
        """Expected latency of the next plan [s] (see the module docstring)."""
        with self._lock:
            measured = list(self._latencies)
        base = (float(np.percentile(measured, LATENCY_PERCENTILE)) if measured
                else FIRST_LATENCY_S)
        return min(base + PUBLISH_MARGIN_S, MAX_LATENCY_S)

    def at_rest(self, start: np.ndarray) -> Takeover:
        """A start from rest at ``start`` [m], as a plan always started."""
        now = self._clock_ns()
        return Takeover(TakeoverKind.REST, now, now, np.asarray(start, dtype=np.float64))

    def predict(self, start: np.ndarray, source: StartSource,
                in_force: Optional[InForce]) -> Takeover:
        """The start state of a plan beginning now.

        Parameters
        ----------
        start : numpy.ndarray, shape (3,)
            The node's start [m]: the vehicle's newest position for ``source`` ``odom``.
        source : StartSource
        in_force : InForce or None
            The plan in force (None: none, or withdrawn).
        """
        with self._lock:
            odometry = self._odometry
        now = self._clock_ns()
        latency = self.expected_latency_s()
        stamp = now + int(round(latency * _NS))
        if source != StartSource.ODOM or odometry is None:
            return Takeover(TakeoverKind.REST, now, now, np.asarray(start, dtype=np.float64))
        here = _state_on(in_force, now)
        there = _state_on(in_force, stamp)
        if (in_force is not None and here is not None and there is not None
                and _follows(odometry, start, here.position[0], here.velocity[0])):
            velocity = there.velocity[0]
            if float(np.linalg.norm(velocity)) >= HANDOVER_MIN_SPEED:
                flown = in_force.flown_at(stamp).result.trajectory
                yaw = (float(there.yaw[0]) if flown is not None and flown.yaws is not None
                       else None)
                ahead = _positions_after(in_force, stamp)
                return Takeover(TakeoverKind.PLAN_IN_FORCE, now, stamp,
                                there.position[0].copy(), velocity.copy(),
                                there.acceleration[0].copy(), yaw, latency, in_force,
                                path=ahead)
        velocity = odometry.velocity
        if velocity is not None and float(np.linalg.norm(velocity)) >= HANDOVER_MIN_SPEED:
            position = odometry.position + (stamp - odometry.received_ns) / _NS * velocity
            return Takeover(TakeoverKind.ODOMETRY, now, stamp, position, velocity.copy(),
                            np.zeros(3), odometry.yaw, latency, odometry=odometry)
        return Takeover(TakeoverKind.REST, now, now, np.asarray(start, dtype=np.float64),
                        yaw=odometry.yaw, odometry=odometry)

    def settle(self, takeover: Takeover, trajectory: Optional[Trajectory],
               in_force_now: Optional[InForce], vehicle: Optional[np.ndarray],
               replan_distance_m: float) -> Settlement:
        """Decide how a successful plan from ``takeover`` goes out, now; record the latency.

        Parameters
        ----------
        trajectory : Trajectory or None
            The new plan's.
        in_force_now : InForce or None
            The plan in force now.
        vehicle : numpy.ndarray of shape (3,) or None
            The vehicle's newest position [m].
        replan_distance_m : float
            ``start_replan_distance`` [m]: a vehicle farther than this from where it is
            predicted to be has left the prediction (0: not checked).
        """
        now = self._clock_ns()
        self.record_latency((now - takeover.predicted_ns) / _NS)
        if not takeover.moving or trajectory is None:
            started = self._started_since(takeover) if trajectory is not None else None
            if started is not None:
                # A plan from where the vehicle stood is behind it once it flies (the plan in
                # force it just took up): a follower would step back to the start.
                return Settlement(now, None, (
                    f'the vehicle started moving ({started:.2f} m/s) while a plan from rest at '
                    f'{np.round(takeover.position, 3).tolist()} was computed'), retry=True)
            return Settlement(now)
        switch = max(now, takeover.stamp_ns)
        flown = takeover.flown_at(switch)
        new = trajectory.state_at((switch - takeover.stamp_ns) / _NS)
        jump = SwitchJump(
            late_s=(now - takeover.stamp_ns) / _NS,
            position_m=float(np.linalg.norm(new.position[0] - flown[0])),
            velocity_mps=float(np.linalg.norm(new.velocity[0] - flown[1])),
            accel_mps2=float(np.linalg.norm(new.acceleration[0] - flown[2])))
        if takeover.kind is TakeoverKind.PLAN_IN_FORCE and in_force_now is not takeover.in_force:
            return Settlement(takeover.stamp_ns, jump, 'the plan in force changed while this '
                              'one was computed', retry=True)
        if vehicle is not None and replan_distance_m > 0.0:
            off = float(np.linalg.norm(vehicle - takeover.flown_at(now)[0]))
            if off > replan_distance_m:
                return Settlement(takeover.stamp_ns, jump, f'the vehicle is {off:.2f} m from '
                                  'where it was predicted to be (start_replan_distance '
                                  f'{replan_distance_m:g} m)', retry=True)
        if jump.within:
            return Settlement(takeover.stamp_ns, jump)
        if jump.late_s > 0.0:
            return Settlement(takeover.stamp_ns, jump, (
                f'the plan was ready {jump.late_s:.3f} s after its takeover time (expected '
                f'latency {takeover.latency_s:.3f} s); switching to it now jumps by '
                f'{jump.describe()}'), retry=True)
        problem = (f'the plan does not continue the motion at its takeover time: it differs by '
                   f'{jump.describe()} (the curve could not keep the start state)')
        if takeover.kind is TakeoverKind.ODOMETRY:
            # No plan of ours is in force: the vehicle flies on its own or brakes to a
            # follower's hold, so the constant-velocity guess goes stale within a second, and a
            # plan from a point the vehicle never reaches would leave the follower waiting for
            # one from where it is. Plan again from the newest odometry (it converges: a
            # braking vehicle soon starts from rest).
            return Settlement(takeover.stamp_ns, jump, problem + '; planned again from the '
                              'newest odometry', retry=True)
        return Settlement(takeover.stamp_ns, jump, problem)

    def _started_since(self, takeover: Takeover) -> Optional[float]:
        """The vehicle's speed [m/s] when odometry newer than that which showed it at rest
        for ``takeover`` (a start from rest at the vehicle) shows it moving; else None."""
        at_rest = takeover.odometry
        if takeover.kind is not TakeoverKind.REST or at_rest is None:
            return None
        with self._lock:
            odometry = self._odometry
        if (odometry is None or odometry.received_ns <= at_rest.received_ns
                or odometry.velocity is None):
            return None
        speed = float(np.linalg.norm(odometry.velocity))
        return speed if speed >= HANDOVER_MIN_SPEED else None


#: How far ahead the plan in force's reference is handed to the planner, and how densely
#: [s]: longer than any lead-in (a braking distance) it follows.
_AHEAD_S = 15.0
_AHEAD_STEP_S = 0.05


def _positions_after(in_force: InForce, at_ns: int) -> Optional[np.ndarray]:
    """Reference positions of the plan flown after ``at_ns`` [m], or None."""
    plan = in_force.flown_at(at_ns)
    trajectory = plan.result.trajectory
    if trajectory is None or not len(trajectory.times):
        return None
    start = (at_ns - plan.stamp_ns) / _NS
    times = start + np.arange(1, int(_AHEAD_S / _AHEAD_STEP_S) + 1) * _AHEAD_STEP_S
    times = times[times <= trajectory.duration_s]
    if not len(times):
        return None
    return trajectory.state_at(times).position


def _state_on(in_force: Optional[InForce], at_ns: int) -> Optional[ReferenceState]:
    """The state of the plan flown at ``at_ns`` (a plan in force, or the one it replaces
    until its stamp), or None without one."""
    if in_force is None:
        return None
    plan = in_force.flown_at(at_ns)
    trajectory = plan.result.trajectory
    if trajectory is None or not len(trajectory.times):
        return None
    return trajectory.state_at((at_ns - plan.stamp_ns) / _NS)


def _follows(odometry: OdometryMotion, position: np.ndarray, plan_position: np.ndarray,
             plan_velocity: np.ndarray) -> bool:
    """Whether the vehicle flies the plan: near its position, and at its velocity when the
    odometry tells the velocity."""
    if float(np.linalg.norm(position - plan_position)) > FOLLOW_DISTANCE_M:
        return False
    if odometry.velocity is None:
        return True
    allowed = FOLLOW_SPEED_ERROR_MPS + FOLLOW_SPEED_FRACTION * float(np.linalg.norm(plan_velocity))
    return float(np.linalg.norm(odometry.velocity - plan_velocity)) <= allowed
