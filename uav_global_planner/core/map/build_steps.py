"""How an inflation build is cut into pieces: checkpoints between them, chunks, threads.

A build (:func:`~uav_global_planner.core.map.inflation.blocked_mask`) calls its checkpoint
between bounded pieces of work, milliseconds apart, so that a plan's time budget can stop it;
the block-sparse build and the dense passes over point clouds run their pieces on a few threads
(the compiled kernels release the interpreter lock).
"""

from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
import os
import threading
from typing import Callable, Optional, Sequence

import numpy as np

#: Compiled visits between two checkpoints of the stamping of a sparse cloud: some 30 ms.
STAMP_CHUNK = 1 << 24
#: Most threads a build stamps on.
THREADS = 4
# How often a build on several threads calls its checkpoint [s].
_POLL_S = 0.01


#: ``checkpoint()``: called between bounded pieces of a build, milliseconds apart; whatever it
#: raises stops the build (a plan's time budget: :meth:`~uav_global_planner.core.budget.
#: PlanBudget.check`).
Checkpoint = Optional[Callable[[], None]]


def cpu_count() -> int:
    """Processors this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def run_tasks(tasks: Sequence, run: Callable, checkpoint: Checkpoint, workers: int) -> None:
    """``run(task)`` for every task, on ``workers`` threads (the kernels release the
    interpreter lock) when it is 2 or more, calling ``checkpoint()`` between tasks (every
    :data:`_POLL_S` from this thread when there are workers). What a task or the checkpoint
    raises is raised here, once the other threads have finished the task in hand.
    """
    if workers < 2:
        for task in tasks:
            if checkpoint is not None:
                checkpoint()
            run(task)
        return
    stop = threading.Event()

    def part(chosen: Sequence) -> None:
        for task in chosen:
            if stop.is_set():
                return
            run(task)

    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(part, tasks[w::workers]) for w in range(workers)]
        try:
            while True:
                done, pending = wait(futures, timeout=_POLL_S, return_when=FIRST_EXCEPTION)
                for future in done:
                    future.result()
                if not pending:
                    return
                if checkpoint is not None:
                    checkpoint()
        except BaseException:
            stop.set()
            raise


def in_chunks(ranges: np.ndarray, checkpoint: Checkpoint):
    """The item numbers of ``ranges`` (B, 2, 3 index ranges) in runs whose ranges hold about
    :data:`STAMP_CHUNK` nodes together (one item at least), ``checkpoint()`` before each;
    all at once without a checkpoint."""
    if checkpoint is None:
        yield np.arange(len(ranges), dtype=np.int64)
        return
    sides = np.maximum(ranges[:, 1] - ranges[:, 0] + 1, 0).astype(np.float64)
    total = np.cumsum(np.prod(sides, axis=1))
    begin = 0
    while begin < len(ranges):
        checkpoint()
        done = float(total[begin - 1]) if begin else 0.0
        end = max(int(np.searchsorted(total, done + STAMP_CHUNK, side='right')), begin + 1)
        yield np.arange(begin, end, dtype=np.int64)
        begin = end
