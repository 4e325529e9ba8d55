"""The error a refused message raises, with the Nav2 result code the node reports."""

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.status import NAV2_UNKNOWN


class InputRejected(InvalidInputError):
    """A message the node refuses, with the Nav2 result code to report.

    Parameters
    ----------
    message : str
        Human-readable reason, naming the offending field.
    code : int
        Nav2 ``ComputePathToPose`` result code (``NAV2_TF_ERROR`` for a wrong frame,
        ``NAV2_UNKNOWN`` for malformed content).
    """

    def __init__(self, message: str, code: int = NAV2_UNKNOWN) -> None:
        super().__init__(message)
        self.code = int(code)
