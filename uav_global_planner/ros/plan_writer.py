"""The serialised plan messages the node publishes, and the start-up check that picks the writer.

The node publishes ``plan``, ``unsmoothed_plan`` and ``trajectory`` as serialised bytes
(``Publisher.publish`` sends bytes as they are). :mod:`~uav_global_planner.ros.cdr` writes them
straight from the arrays, milliseconds faster per plan than building message objects; rclpy's
own serialisation of the :mod:`~uav_global_planner.ros.conversions` messages is the reference.
:func:`startup_plan_writer` runs once when the node starts: it serialises a small fixed plan both
ways and compares what rclpy reads back. Only when every message matches are the CDR bytes used;
otherwise it logs an error naming the mismatch and the node serialises with rclpy (slower, never
wrong): a new rmw or message definition cannot make the node publish garbage.
"""

import threading
from typing import Any, Callable, List, Optional, Sequence

from nav_msgs.msg import Path
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from uav_global_planner.core.result import PlanResult, Trajectory
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros import cdr
from uav_global_planner.ros import conversions as conv

#: Serialiser of one plan message: (result, frame_id, stamp_ns, goal_orientation) -> bytes.
# (result, frame_id, stamp_ns, goal_orientation, **options such as sample_period) -> bytes
Serialise = Callable[..., bytes]


class PlanWriter:
    """Bytes of the three plan messages, written by CDR from arrays or by rclpy from objects.

    Parameters
    ----------
    use_cdr : bool
        Write with :mod:`~uav_global_planner.ros.cdr` (fast) rather than rclpy.
    """

    def __init__(self, use_cdr: bool) -> None:
        self.use_cdr = bool(use_cdr)
        self.plan_path: Serialise
        self.unsmoothed_path: Serialise
        self.trajectory: Serialise
        if self.use_cdr:
            self.plan_path = cdr.serialized_plan_path
            self.unsmoothed_path = cdr.serialized_unsmoothed_path
            self.trajectory = cdr.serialized_trajectory
        else:
            self.plan_path = _by_rclpy(conv.plan_to_path)
            self.unsmoothed_path = _by_rclpy(conv.plan_to_unsmoothed_path)
            self.trajectory = _by_rclpy(conv.plan_to_trajectory)


def _by_rclpy(build: Callable[..., Any]) -> Serialise:
    def serialise(result: PlanResult, frame_id: str, stamp_ns: int,
                  goal_orientation: Optional[Sequence[float]] = None, **options: Any) -> bytes:
        return serialize_message(build(result, frame_id, stamp_ns, goal_orientation, **options))
    return serialise


def check_plan() -> PlanResult:
    """A small fixed plan: a climb (vertical headings), a turn and a stop, odd stamps."""
    positions = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.5], [0.75, 0.25, 1.5],
                          [1.5, 1.25, 1.75], [1.5, 2.0, 2.0]])
    times = np.array([0.0, 0.37, 1.123456789, 1.9, 2.5])
    velocities = np.gradient(positions, times, axis=0)
    yaws = np.array([0.0, 0.3, -2.9, 3.1, 1.0])
    trajectory = Trajectory(times=times, positions=positions, velocities=velocities,
                            accelerations=np.gradient(velocities, times, axis=0),
                            yaws=yaws, yaw_rates=np.gradient(yaws, times))
    return PlanResult(status=PlanStatus.OK, message='check', algorithm='check',
                      start=positions[0], goal=positions[-1], path=positions[[0, 2, 4]],
                      trajectory=trajectory)


def plan_writer_mismatches(writer: PlanWriter) -> List[str]:
    """What rclpy reads back differently from ``writer``'s bytes of :func:`check_plan`.

    Each message is compared with the :mod:`~uav_global_planner.ros.conversions` message of the
    same arguments, for two frames (the padding after a string depends on its length), with and
    without a goal orientation.

    Returns
    -------
    list of str
        One line per mismatching message; empty when all match.
    """
    result = check_plan()
    problems = []
    cases = [('plan', writer.plan_path, conv.plan_to_path, Path),
             ('unsmoothed_plan', writer.unsmoothed_path, conv.plan_to_unsmoothed_path, Path),
             ('trajectory', writer.trajectory, conv.plan_to_trajectory,
              MultiDOFJointTrajectory)]
    for frame, stamp_ns, orientation in (('map', 1_700_000_000_123_456_789, None),
                                         ('uav1/odom', 7, (0.0, 0.0, 0.6, 0.8))):
        for topic, write, build, msg_type in cases:
            expected = build(result, frame, stamp_ns, orientation)
            try:
                got = deserialize_message(write(result, frame, stamp_ns, orientation), msg_type)
            except Exception as error:  # noqa: B902 - any failure to read back is a mismatch
                problems.append(f'{topic} (frame {frame!r}): not readable ({error})')
                continue
            if got != expected:
                problems.append(f'{topic} (frame {frame!r}): reads back as a different message')
    return problems


_lock = threading.Lock()
_checked: Optional[PlanWriter] = None


def startup_plan_writer(logger: Any = None) -> PlanWriter:
    """The process's plan writer: CDR when its bytes read back right, else rclpy.

    The check (:func:`plan_writer_mismatches`) runs on the first call only; later calls return
    the same writer.

    Parameters
    ----------
    logger : rclpy logger, optional
        Told of a mismatch (``error``), or that the CDR writer is in use (``debug``).
    """
    global _checked
    with _lock:
        if _checked is None:
            problems = plan_writer_mismatches(PlanWriter(use_cdr=True))
            _checked = PlanWriter(use_cdr=not problems)
            if logger is not None and problems:
                logger.error('the fast CDR plan serialisation does not match that of rclpy ('
                             + '; '.join(problems) + '); publishing plans serialised by rclpy '
                             'instead (a few milliseconds slower per plan)')
            elif logger is not None:
                logger.debug('plan messages serialised by the CDR writer (checked against '
                             'rclpy)')
        return _checked
