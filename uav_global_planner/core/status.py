"""Outcome codes of a planning request, and their Nav2 ComputePathToPose equivalents."""

from enum import Enum


class PlanStatus(str, Enum):
    """Outcome of one planning request; the value is the string used in JSON and diagnostics."""

    OK = 'ok'
    START_OUTSIDE_MAP = 'start_outside_map'
    GOAL_OUTSIDE_MAP = 'goal_outside_map'
    START_OCCUPIED = 'start_occupied'
    GOAL_OCCUPIED = 'goal_occupied'
    NO_VALID_PATH = 'no_valid_path'
    TIMEOUT = 'timeout'
    CANCELED = 'canceled'
    INVALID_INPUT = 'invalid_input'


#: Nav2 ``ComputePathToPose`` result codes (nav2_msgs/action/ComputePathToPose).
NAV2_NONE = 0
NAV2_UNKNOWN = 200
NAV2_INVALID_PLANNER = 201
NAV2_TF_ERROR = 202
NAV2_START_OUTSIDE_MAP = 203
NAV2_GOAL_OUTSIDE_MAP = 204
NAV2_START_OCCUPIED = 205
NAV2_GOAL_OCCUPIED = 206
NAV2_TIMEOUT = 207
NAV2_NO_VALID_PATH = 208

NAV2_CODE_BY_STATUS = {
    PlanStatus.OK: NAV2_NONE,
    PlanStatus.START_OUTSIDE_MAP: NAV2_START_OUTSIDE_MAP,
    PlanStatus.GOAL_OUTSIDE_MAP: NAV2_GOAL_OUTSIDE_MAP,
    PlanStatus.START_OCCUPIED: NAV2_START_OCCUPIED,
    PlanStatus.GOAL_OCCUPIED: NAV2_GOAL_OCCUPIED,
    PlanStatus.NO_VALID_PATH: NAV2_NO_VALID_PATH,
    PlanStatus.TIMEOUT: NAV2_TIMEOUT,
    # Nav2 reports a cancelled request through the action's goal status, not an error code.
    PlanStatus.CANCELED: NAV2_UNKNOWN,
    PlanStatus.INVALID_INPUT: NAV2_UNKNOWN,
}
