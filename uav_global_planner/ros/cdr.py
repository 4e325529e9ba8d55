"""The planner's large output messages, serialised straight from numpy arrays.

Building a ``nav_msgs/Path`` of a few hundred poses out of rclpy message objects costs several
milliseconds (six Python objects and a dozen checked setters per pose), and publishing it costs
another millisecond to convert the objects to C structures. The functions here write the same
messages directly in their wire format, little-endian CDR (XCDR1, the encoding rmw implementations
use on the wire), with one numpy record per pose, in a small fraction of that time;
``Publisher.publish`` sends such bytes as they are.

Every function produces exactly the message of its counterpart in
:mod:`~uav_global_planner.ros.conversions`: both take the poses, headings and stamps from the
same functions (:func:`~uav_global_planner.ros.conversions.poses.pose_array`,
:func:`~uav_global_planner.ros.conversions.plans.pose_stamps_ns`), the tests compare both after
deserialisation, and the node checks once at start-up that rclpy reads these bytes back as the
same messages (:mod:`~uav_global_planner.ros.plan_writer`). No ``rclpy`` here.
"""

from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros.conversions.plans import (path_samples, pose_stamps_ns,
                                                      require_trajectory, trajectory_points,
                                                      TRAJECTORY_SAMPLE_PERIOD)
from uav_global_planner.ros.conversions.poses import pose_array
from uav_global_planner.ros.conversions.stamps import seconds_to_ns

# Encapsulation header of little-endian plain CDR.
_ENCAPSULATION = b'\x00\x01\x00\x00'

# Field kinds of a record: numpy format and CDR alignment.
_KINDS = {'u4': ('<u4', 4), 'i4': ('<i4', 4), 'f8': ('<f8', 8)}

#: A record field: (name, kind), kind one of 'u4', 'i4', 'f8', or (name, bytes) for raw bytes
#: without alignment (the characters of a string after its length).
Field = Tuple[str, Union[str, bytes]]


class _Writer:
    """Accumulates a CDR stream; offsets (and so alignment) count from after the header."""

    def __init__(self) -> None:
        self._parts: List[bytes] = [_ENCAPSULATION]
        self.offset = 0

    def _append(self, data: bytes) -> None:
        self._parts.append(data)
        self.offset += len(data)

    def _align(self, alignment: int) -> None:
        padding = -self.offset % alignment
        if padding:
            self._append(bytes(padding))

    def u32(self, value: int) -> None:
        self._align(4)
        self._append(int(value).to_bytes(4, 'little'))

    def time(self, stamp_ns: int) -> None:
        """``builtin_interfaces/Time`` (or ``Duration``) of integer nanoseconds."""
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        self._align(4)
        self._append(sec.to_bytes(4, 'little', signed=True) + nanosec.to_bytes(4, 'little'))

    def string(self, text: str) -> None:
        data = text.encode('utf-8') + b'\x00'
        self.u32(len(data))
        self._append(data)

    def records(self, fields: Sequence[Field], columns: dict, count: int) -> None:
        """``count`` records of ``fields``; ``columns`` maps each numeric field to its values.

        The padding inside a record depends on where it starts; records are written in runs
        that start at the same alignment, each run as one numpy structured array.
        """
        done = 0
        while done < count:
            dtype = _record_dtype(fields, self.offset)
            # A record whose size keeps the alignment is followed by records laid out alike.
            run = count - done if dtype.itemsize % 8 == 0 else 1
            array = np.zeros(run, dtype=dtype)
            for name, kind in fields:
                if isinstance(kind, bytes):
                    array[name] = np.frombuffer(kind, dtype=f'V{len(kind)}')[0]
                else:
                    array[name] = columns[name][done:done + run]
            self._append(array.tobytes())
            done += run

    def bytes(self) -> bytes:
        return b''.join(self._parts)


def _record_dtype(fields: Sequence[Field], start: int) -> np.dtype:
    """Structured dtype of one record starting at stream offset ``start``, CDR padding
    included."""
    names, formats, offsets = [], [], []
    offset = start
    for name, kind in fields:
        if isinstance(kind, bytes):
            fmt, alignment = f'V{len(kind)}', 1
        else:
            fmt, alignment = _KINDS[kind]
        offset += -offset % alignment
        names.append(name)
        formats.append(fmt)
        offsets.append(offset - start)
        offset += np.dtype(fmt).itemsize
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                     'itemsize': offset - start})


def _string_fields(prefix: str, text: str) -> List[Field]:
    """Record fields of a constant string: its length (with the NUL) and its bytes."""
    data = text.encode('utf-8') + b'\x00'
    return [(f'{prefix}_len', 'u4'), (f'{prefix}_chars', data)]


def _split_ns(stamps_ns: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """(sec, nanosec) of integer nanoseconds, as ``time_from_ns`` splits them.

    Raises
    ------
    OverflowError
        When a second count does not fit the int32 of ``builtin_interfaces/Time`` (numpy would
        wrap it silently).
    """
    sec, nanosec = np.divmod(stamps_ns.astype(np.int64), 1_000_000_000)
    if len(sec) and (sec.min() < -2 ** 31 or sec.max() >= 2 ** 31):
        raise OverflowError(f'time stamps of {int(sec.max())} s do not fit in int32 seconds')
    return sec, nanosec


_POSE_FIELDS = ('x', 'y', 'z', 'qx', 'qy', 'qz', 'qw')


def serialized_path(points: np.ndarray, frame_id: str, stamp_ns: int,
                    times: Optional[np.ndarray] = None,
                    goal_orientation: Optional[Sequence[float]] = None) -> bytes:
    """CDR bytes of :func:`conversions.points_to_path` with the same arguments."""
    poses = pose_array(points, goal_orientation)
    count = len(poses)
    sec, nanosec = _split_ns(pose_stamps_ns(stamp_ns, count, times))
    columns = {'sec': sec, 'nanosec': nanosec,
               'frame_len': np.full(count, len(frame_id.encode('utf-8')) + 1)}
    for index, name in enumerate(_POSE_FIELDS):
        columns[name] = poses[:, index]
    fields: List[Field] = [('sec', 'i4'), ('nanosec', 'u4'), *_string_fields('frame', frame_id)]
    fields += [(name, 'f8') for name in _POSE_FIELDS]
    writer = _Writer()
    writer.time(stamp_ns)
    writer.string(frame_id)
    writer.u32(count)
    writer.records(fields, columns, count)
    return writer.bytes()


def serialized_plan_path(result: PlanResult, frame_id: str, stamp_ns: int,
                         goal_orientation: Optional[Sequence[float]] = None) -> bytes:
    """CDR bytes of :func:`conversions.plan_to_path`."""
    points, times = path_samples(result, True)
    return serialized_path(points, frame_id, stamp_ns, times, goal_orientation)


def serialized_unsmoothed_path(result: PlanResult, frame_id: str, stamp_ns: int,
                               goal_orientation: Optional[Sequence[float]] = None) -> bytes:
    """CDR bytes of :func:`conversions.plan_to_unsmoothed_path`."""
    points, times = path_samples(result, False)
    return serialized_path(points, frame_id, stamp_ns, times, goal_orientation)


def serialized_trajectory(result: PlanResult, frame_id: str, stamp_ns: int,
                          goal_orientation: Optional[Sequence[float]] = None,
                          joint_name: str = 'base_link',
                          sample_period: float = TRAJECTORY_SAMPLE_PERIOD) -> bytes:
    """CDR bytes of :func:`conversions.plan_to_trajectory`."""
    points = trajectory_points(require_trajectory(result), sample_period, goal_orientation)
    count = len(points['times'])
    sec, nanosec = _split_ns(seconds_to_ns(points['times']))
    ones = np.ones(count, dtype=np.uint32)
    columns = {'n_transforms': ones, 'n_velocities': ones, 'n_accelerations': ones,
               'sec': sec, 'nanosec': nanosec}
    zeros = np.zeros(count)
    for index, axis in enumerate('xyz'):
        columns[f't{axis}'] = points['positions'][:, index]
        columns[f'v{axis}'] = points['velocities'][:, index]
        columns[f'a{axis}'] = points['accelerations'][:, index]
        # Angular acceleration stays zero; the angular velocity is the yaw rate about z.
        columns[f'w{axis}'] = columns[f'b{axis}'] = zeros
    columns['wz'] = points['yaw_rates']
    for index, name in enumerate(('qx', 'qy', 'qz', 'qw')):
        columns[name] = points['quaternions'][:, index]
    fields: List[Field] = [('n_transforms', 'u4')]
    fields += [(name, 'f8') for name in ('tx', 'ty', 'tz', 'qx', 'qy', 'qz', 'qw')]
    fields += [('n_velocities', 'u4')]
    fields += [(name, 'f8') for name in ('vx', 'vy', 'vz', 'wx', 'wy', 'wz')]
    fields += [('n_accelerations', 'u4')]
    fields += [(name, 'f8') for name in ('ax', 'ay', 'az', 'bx', 'by', 'bz')]
    fields += [('sec', 'i4'), ('nanosec', 'u4')]
    writer = _Writer()
    writer.time(stamp_ns)
    writer.string(frame_id)
    writer.u32(1)
    writer.string(joint_name)
    writer.u32(count)
    writer.records(fields, columns, count)
    return writer.bytes()
