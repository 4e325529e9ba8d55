"""The time budget, cancellation and progress of one planning request.

A :class:`PlanBudget` is handed to every stage of a plan (grid build, search, smoothing,
timing). Each stage calls :meth:`PlanBudget.check` between bounded pieces of work, a few
milliseconds apart; the check raises
:class:`~uav_global_planner.core.errors.PlanningCancelledError` when the caller's cancel test
says so (the pattern of Nav2's ``cancel_checker``) and
:class:`~uav_global_planner.core.errors.PlanningTimeoutError`, naming the stage, when the budget
is spent. A plan that runs longer than :data:`REPORT_AFTER_S` reports its stage through the
``progress`` callback, at each stage change and every :data:`REPORT_EVERY_S`.

The budget counts wall time less the time numba spends compiling kernels or loading them from
its cache meanwhile (:func:`~uav_global_planner.core.jit.one_off_seconds`): a first run after an
install compiles them once (they are kept on disk), every new process loads them once, and
that one-off cost says nothing about the plan.
"""

from enum import Enum
import math
import time
from typing import Callable, Optional

from uav_global_planner.core.errors import PlanningCancelledError, PlanningTimeoutError
from uav_global_planner.core.jit import one_off_seconds

#: A plan reports progress once it has run this long [s].
REPORT_AFTER_S = 1.0
#: ... and then at most this often within a stage [s].
REPORT_EVERY_S = 1.0


class PlanStage(str, Enum):
    """Stages of a plan, in order; the value is the name used in messages."""

    GRID = 'grid build'
    SEARCH = 'search'
    SMOOTHING = 'smoothing'
    TIMING = 'timing'


#: ``progress(stage, elapsed_s, budget_s)``: budget_s is 0 when there is no limit.
ProgressCallback = Callable[[PlanStage, float, float], None]


class PlanBudget:
    """Wall-clock budget, cancel test and progress reports of one request.

    Parameters
    ----------
    max_time_s : float
        Budget of the whole request [s]; 0 means no limit.
    cancel : callable, optional
        Returns True when the request must stop.
    progress : callable, optional
        :data:`ProgressCallback`, called from the planning thread.
    """

    def __init__(self, max_time_s: float = 0.0, cancel: Optional[Callable[[], bool]] = None,
                 progress: Optional[ProgressCallback] = None) -> None:
        self.max_time_s = float(max_time_s)
        self._cancel = cancel
        self._progress = progress
        self.started = time.perf_counter()
        self._compiled_before = one_off_seconds()
        self.stage = PlanStage.GRID
        self._last_report = -math.inf

    @property
    def elapsed_s(self) -> float:
        """Time since the request began, less kernel compilation and loading meanwhile [s]."""
        compiling = one_off_seconds() - self._compiled_before
        return time.perf_counter() - self.started - compiling

    def enter(self, stage: PlanStage) -> None:
        """Begin ``stage``, reporting it when the plan is already long; then :meth:`check`."""
        if stage is not self.stage:
            self.stage = stage
            self._last_report = -math.inf
        self.check()

    def check(self) -> None:
        """Raise when the request is cancelled or out of time; report progress when due.

        Raises
        ------
        PlanningCancelledError
            When ``cancel()`` is true.
        PlanningTimeoutError
            When the budget is spent; the message names the stage that ran out.
        """
        if self._cancel is not None and self._cancel():
            raise PlanningCancelledError(
                f'plan cancelled during {self.stage.value} after {self.elapsed_s:.3f} s')
        elapsed = self.elapsed_s
        if self.max_time_s > 0.0 and elapsed >= self.max_time_s:
            raise PlanningTimeoutError(
                f'{self.stage.value} ran out of the planning time budget (max_planning_time = '
                f'{self.max_time_s:g} s) after {elapsed:.3f} s')
        if (self._progress is not None and elapsed >= REPORT_AFTER_S
                and elapsed - self._last_report >= REPORT_EVERY_S):
            self._last_report = elapsed
            self._progress(self.stage, elapsed, self.max_time_s)
