"""Where the start of a plan came from, as the node reports it (``start_source``)."""

from enum import StrEnum


class StartSource(StrEnum):
    """Origin of a plan's start position; the value is the text of the diagnostics."""

    #: The ``start`` parameter (no vehicle position received yet).
    PARAMETER = 'parameter'
    #: The latest ``odom`` message (the vehicle's position).
    ODOM = 'odom'
    #: The latest ``start_pose`` message.
    START_POSE = 'start_pose'
    #: The start given in a Nav2 planning request.
    REQUEST = 'request'
