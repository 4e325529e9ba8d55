"""Typed planning failures, one class per failure a caller must tell apart.

Each class carries the :class:`~uav_global_planner.core.status.PlanStatus` it maps to, so a
caller can either ``except`` the precise class or read ``error.status``.
"""

from typing import ClassVar

from uav_global_planner.core.status import PlanStatus


class PlanningError(Exception):
    """Base class of every failure the planner reports to its caller.

    Parameters
    ----------
    message : str
        What went wrong, naming the offending input.
    expanded_nodes : int
        Nodes the search expanded before failing (0 when it did not run).
    """

    status: ClassVar[PlanStatus] = PlanStatus.INVALID_INPUT

    def __init__(self, message: str = '', expanded_nodes: int = 0) -> None:
        super().__init__(message)
        self.expanded_nodes = int(expanded_nodes)


class InvalidInputError(PlanningError, ValueError):
    """Malformed input: non-finite numbers, wrong shapes, inconsistent settings."""

    status = PlanStatus.INVALID_INPUT


class MissingDependencyError(InvalidInputError):
    """An optional extra (for example a map file format's library) is not installed; the
    message names the pip package."""

    status = PlanStatus.INVALID_INPUT


class StartOutsideMapError(PlanningError):
    """The start lies outside the planning bounds."""

    status = PlanStatus.START_OUTSIDE_MAP


class GoalOutsideMapError(PlanningError):
    """The goal lies outside the planning bounds."""

    status = PlanStatus.GOAL_OUTSIDE_MAP


class StartOccupiedError(PlanningError):
    """The start node is within the safety margin of an obstacle."""

    status = PlanStatus.START_OCCUPIED


class GoalOccupiedError(PlanningError):
    """The goal node is within the safety margin of an obstacle."""

    status = PlanStatus.GOAL_OCCUPIED


class NoValidPathError(PlanningError):
    """The search exhausted every reachable node (or no safe smooth path exists)."""

    status = PlanStatus.NO_VALID_PATH


class PlanningTimeoutError(PlanningError):
    """A stage of the plan (grid build, search, smoothing, timing) ran out of its budget."""

    status = PlanStatus.TIMEOUT


class PlanningCancelledError(PlanningError):
    """The request was cancelled (a newer request, changed settings, shutdown)."""

    status = PlanStatus.CANCELED
