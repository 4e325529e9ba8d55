"""Readers of ROS messages that only the tests need."""

from builtin_interfaces.msg import Duration


def duration_to_seconds(duration: Duration) -> float:
    """Seconds of a ``builtin_interfaces/Duration``."""
    return float(duration.sec) + float(duration.nanosec) * 1e-9
