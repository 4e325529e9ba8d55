"""Client side of the Nav2 interfaces for processes that spin their node on another thread.

rclpy's ``ActionClient`` (Jazzy) registers the future of a goal or result request only after
the request has gone out. When the node is spun on a background thread (the package's
:class:`~uav_global_planner.ros.background_node.BackgroundNode`, the tests), a fast answer can be
taken by that thread in between and is dropped ("Ignoring unexpected goal response"), and the
caller waits forever. :class:`ExecutorCalls` runs such calls on the spinning thread itself, where
sending and receiving cannot interleave; :func:`round_trip` uses it for one action goal.

A program that spins in its own thread (``rclpy.spin_until_future_complete``, as
``nav2_simple_commander`` does) needs none of this.
"""

import queue
import threading
import time
from typing import Any, Callable, List, Tuple

from rclpy.action import ActionClient
from rclpy.node import Node


class ExecutorCalls:
    """Runs callables on the thread that spins ``node``.

    Parameters
    ----------
    node : rclpy.node.Node
        A node spun by an executor on another thread.
    """

    def __init__(self, node: Node) -> None:
        self._calls: 'queue.SimpleQueue[Tuple[Callable[[], Any], list, threading.Event]]' = (
            queue.SimpleQueue())
        # Triggering a guard condition is the thread-safe way to wake the executor.
        self._guard = node.create_guard_condition(self._run)

    def _run(self) -> None:
        while True:
            try:
                call, box, done = self._calls.get_nowait()
            except queue.Empty:
                return
            try:
                box.append((True, call()))
            except Exception as error:  # noqa: BLE001 - raised again in the caller's thread
                box.append((False, error))
            done.set()

    def __call__(self, call: Callable[[], Any], timeout_s: float = 10.0) -> Any:
        """Run ``call()`` on the executor thread; return its value (or raise its exception).

        Raises
        ------
        TimeoutError
            When the executor does not run it within ``timeout_s``.
        """
        box: List[Tuple[bool, Any]] = []
        done = threading.Event()
        self._calls.put((call, box, done))
        self._guard.trigger()
        if not done.wait(timeout_s):
            raise TimeoutError(f'the executor did not run the call within {timeout_s} s')
        ok, value = box[0]
        if not ok:
            raise value
        return value


def wait_done(future, timeout_s: float) -> float:
    """Wait for an rclpy future completed by the executor thread; return the completion time
    (``time.perf_counter`` in the done callback).

    Raises
    ------
    TimeoutError
    """
    done = threading.Event()
    stamp: List[float] = []

    def finished(_) -> None:
        stamp.append(time.perf_counter())
        done.set()
    future.add_done_callback(finished)
    if not done.wait(timeout_s):
        raise TimeoutError(f'no answer within {timeout_s} s')
    return stamp[0]


def send_goal(calls: ExecutorCalls, client: ActionClient, goal, timeout_s: float = 30.0):
    """Send an action goal; return its goal handle (accepted or not)."""
    future = calls(lambda: client.send_goal_async(goal))
    wait_done(future, timeout_s)
    return future.result()


def get_result(calls: ExecutorCalls, handle, timeout_s: float = 60.0):
    """The result response (``status``, ``result``) of an accepted goal."""
    future = calls(handle.get_result_async)
    wait_done(future, timeout_s)
    return future.result()


def round_trip(calls: ExecutorCalls, client: ActionClient, goal,
               timeout_s: float = 60.0) -> Tuple[float, Any]:
    """Send ``goal`` and wait for its result.

    Returns
    -------
    tuple
        Seconds from just before sending until the result arrived, and the result response
        (``status``, ``result``); a rejected goal gives (seconds, None).
    """
    sent = time.perf_counter()
    accepted = calls(lambda: client.send_goal_async(goal))
    wait_done(accepted, timeout_s)
    handle = accepted.result()
    if not handle.accepted:
        return time.perf_counter() - sent, None
    result = calls(handle.get_result_async)
    arrived = wait_done(result, timeout_s)
    return arrived - sent, result.result()
