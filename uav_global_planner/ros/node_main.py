"""Running a node to its end: the loop shared by the package's executables.

One executor spins the node until SIGINT/SIGTERM; invalid start-up parameters end the run with
:data:`EXIT_BAD_SETTINGS` and a line on stderr naming the program; the node is closed and the
context shut down whatever happens.
"""

import signal
import sys
from typing import Callable, List, Optional, Protocol

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from uav_global_planner.core.errors import InvalidInputError

# Exit code of a run refused for its start-up parameters or arguments.
EXIT_BAD_SETTINGS = 2


class RunnableNode(Protocol):
    """What :func:`run_node` runs: a node, started once spinning begins, closed at the end."""

    node: Node

    def start(self) -> None:
        """Begin the work that needs the executor (threads, timers)."""

    def close(self) -> None:
        """Stop the work and release the node."""


def _log_compiled(node: Node) -> None:
    """Log the one-off compilation of the planner's kernels during start-up (the warm-up), if
    there was one: how long it took and where the kernels are cached for later starts."""
    # Looked up, not imported: a node that plans nothing (the follower) never loads numba.
    jit = sys.modules.get('uav_global_planner.core.jit')
    if jit is None or jit.compile_seconds() <= 0.0:
        return
    node.get_logger().info(f"compiled the planner's kernels once ({jit.compile_seconds():.1f} s),"
                           f' cached in {jit.cache_dir()}; later starts load them')


def run_node(program: str, make: Callable[[], RunnableNode],
             args: Optional[List[str]] = None) -> int:
    """Initialise rclpy, build the node with ``make()`` and spin it until shutdown.

    Parameters
    ----------
    program : str
        The executable's name, for the message of invalid parameters.
    make : callable
        Builds the node (its parameters are read here, so invalid ones are reported).
    args : list of str, optional
        Command-line arguments for ``rclpy.init``; ``sys.argv`` when None.

    Returns
    -------
    int
        0 after a clean shutdown, :data:`EXIT_BAD_SETTINGS` for invalid start-up parameters.
    """
    rclpy.init(args=args)
    runnable: Optional[RunnableNode] = None
    code = 0
    try:
        runnable = make()
        executor = SingleThreadedExecutor()
        executor.add_node(runnable.node)
        runnable.start()
        _log_compiled(runnable.node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (InvalidInputError, ParameterException) as error:
        # Invalid --params-file or -p values (out of range, wrong type, failing validation):
        # say which, and do not start.
        print(f'{program}: invalid parameters: {error}', file=sys.stderr)
        code = EXIT_BAD_SETTINGS
    except RuntimeError:
        # A message taken while SIGINT/SIGTERM shuts the context down can fail to convert;
        # that is the shutdown, not an error. Anything else still shows its traceback.
        if rclpy.ok():
            raise
    finally:
        # A second Ctrl-C during clean-up must not print a traceback.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if runnable is not None:
            runnable.close()
        rclpy.try_shutdown()
    return code
