"""Times and durations: ``builtin_interfaces`` messages and integer nanoseconds."""

from builtin_interfaces.msg import Duration, Time
import numpy as np


def time_from_ns(stamp_ns: int) -> Time:
    """``builtin_interfaces/Time`` of a time in integer nanoseconds (>= 0)."""
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def time_to_ns(stamp: Time) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def seconds_to_ns(seconds) -> np.ndarray:
    """Integer nanoseconds (int64) of time spans [s], each rounded to the nearest ns.

    Rounded one by one as Python floats, so every message of a plan, built from objects or
    written as bytes, carries the very same stamps.
    """
    return np.array([int(round(float(t) * 1e9)) for t in np.asarray(seconds).ravel().tolist()],
                    dtype=np.int64)


def duration_from_seconds(seconds: float) -> Duration:
    """``builtin_interfaces/Duration`` of a non-negative time span [s]."""
    sec, nanosec = divmod(int(seconds_to_ns(seconds)[0]), 1_000_000_000)
    return Duration(sec=sec, nanosec=nanosec)
