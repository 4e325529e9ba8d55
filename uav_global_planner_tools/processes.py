"""ROS processes started from Python: their command line, their environment and their lifetime.

``uav-demo``, the ROS latency benchmark and the tests start ``planner_node`` and
``scene_publisher`` the same way:

- :func:`ros_environment` gives the child its ROS domain, discovery limited to this machine
  (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, no static peers) and a temporary
  ``ROS_LOG_DIR``;
- :func:`planner_command` and :func:`scene_publisher_command` build the command lines, with
  :func:`scene_parameters` giving the node a scene's workspace;
- :class:`NodeProcess` runs the child with its output read line by line on a thread, waits for
  a line (the node's ready line :data:`READY_TEXT` above all) and stops it with SIGINT;
- :func:`wait_until` polls for what a process should have done.

Nothing here imports rclpy: the processes do.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

from uav_global_planner.core.io.scene import Scene, shipped_config_dirs
from uav_global_planner.ros.names import NODE_MODULE, READY_TEXT, SCENE_PUBLISHER_MODULE


class NodeProcessError(RuntimeError):
    """A child process exited, stayed silent or ignored SIGINT; the message holds its output."""


def find_config(name: str = 'planner.yaml') -> Path:
    """A shipped configuration file (``planner.yaml`` by default), installed or in the checkout.

    Raises
    ------
    FileNotFoundError
    """
    candidates = [folder / name for folder in shipped_config_dirs()]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f'{name} not found in {", ".join(str(c) for c in candidates)}')


def ros_environment(domain_id: int, log_dir: Optional[Path] = None) -> Dict[str, str]:
    """Environment of a child: this one plus its own domain, localhost discovery and logs.

    Parameters
    ----------
    domain_id : int
        ``ROS_DOMAIN_ID`` of the child.
    log_dir : Path, optional
        ``ROS_LOG_DIR``; default a new temporary folder.
    """
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_STATIC_PEERS', None)
    env['ROS_LOG_DIR'] = str(log_dir) if log_dir is not None else tempfile.mkdtemp(
        prefix='uav_planner_roslog_')
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env


def localhost_discovery() -> None:
    """Limit the rclpy contexts of this process to this machine, as :func:`ros_environment`
    does for a child (rclpy reads the variables when a context starts)."""
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_STATIC_PEERS', None)


def _yaml_value(value: Any) -> str:
    """``value`` written as a ``-p name:=value`` override reads it back."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_yaml_value(v) for v in value) + ']'
    return str(value)


def scene_parameters(scene: Scene) -> Dict[str, Any]:
    """Node parameters that make ``planner_node`` plan in ``scene``'s workspace.

    The frame, the bounds [m], delta, gamma and eta [m] of the scene; its start and goal are
    left to whoever sends them.
    """
    config = scene.config
    return {'frame_id': scene.frame_id,
            'bounds.min': [float(v) for v in config.bounds_min],
            'bounds.max': [float(v) for v in config.bounds_max],
            'resolution': float(config.resolution),
            'safety_margin': float(config.safety_margin),
            'adaptive_threshold': float(config.adaptive_threshold)}


def planner_command(namespace: Optional[str] = None,
                    parameters: Optional[Mapping[str, Any]] = None,
                    params_file: Optional[Path] = None,
                    executable: Optional[str] = None) -> List[str]:
    """Command line of a planner node.

    Parameters
    ----------
    namespace : str, optional
        ROS namespace, for example ``'/uav1'``.
    parameters : mapping, optional
        ``-p name:=value`` overrides, after the parameters file.
    params_file : Path, optional
        ``--params-file``, for example :func:`find_config`.
    executable : str, optional
        An installed ``planner_node`` script; default ``python -m`` on the node's module.
    """
    command = [executable] if executable else [sys.executable, '-m', NODE_MODULE]
    command.append('--ros-args')
    if params_file is not None:
        command += ['--params-file', str(params_file)]
    if namespace:
        command += ['-r', f'__ns:={namespace}']
    for name, value in (parameters or {}).items():
        command += ['-p', f'{name}:={_yaml_value(value)}']
    return command


def scene_publisher_command(scene: str, namespace: Optional[str] = None,
                            options: Sequence[str] = ()) -> List[str]:
    """Command line of a ``scene_publisher`` for ``scene`` (a file or a shipped scene name).

    ``options`` are the publisher's own, for example ``('--no-start', '--no-goal')``.
    """
    command = [sys.executable, '-m', SCENE_PUBLISHER_MODULE, str(scene), *options,
               '--ros-args']
    if namespace:
        command += ['-r', f'__ns:={namespace}']
    return command


class NodeProcess:
    """A child process whose merged stdout and stderr are read, line by line, on a thread.

    Parameters
    ----------
    command : sequence of str
    env : mapping
        Full environment of the child (see :func:`ros_environment`).
    log_path : Path, optional
        Also write every line there, as it comes.

    Attributes
    ----------
    process : subprocess.Popen
    launched_at : float
        ``time.monotonic()`` just before the child was spawned [s].
    """

    def __init__(self, command: Sequence[str], env: Mapping[str, str],
                 log_path: Optional[Path] = None) -> None:
        self.command = list(command)
        self.log_path = log_path
        self._lines: List[str] = []
        self._times: List[float] = []
        self._changed = threading.Condition()
        self._log = open(log_path, 'w', encoding='utf-8') if log_path is not None else None
        self.launched_at = time.monotonic()
        self.process = subprocess.Popen(
            self.command, env=dict(env), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL, text=True, bufsize=1,
            # A session of its own: Ctrl-C in the terminal reaches only the parent, which then
            # stops the child cleanly.
            start_new_session=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            now = time.monotonic()
            if self._log is not None:
                self._log.write(line)
                self._log.flush()
            with self._changed:
                self._lines.append(line.rstrip('\n'))
                self._times.append(now)
                self._changed.notify_all()
        if self._log is not None:
            self._log.close()
        with self._changed:
            self._changed.notify_all()

    @property
    def output(self) -> str:
        """Everything the process printed so far."""
        with self._changed:
            return self.output_unlocked()

    def output_unlocked(self) -> str:
        """:attr:`output` for a caller that holds the lock."""
        return '\n'.join(self._lines)

    def tail(self, count: int = 20) -> str:
        """The last ``count`` lines, indented."""
        with self._changed:
            return '\n'.join(f'    {line}' for line in self._lines[-count:])

    def mark(self) -> int:
        """Number of lines so far; pass it as ``after`` to look only at newer ones."""
        with self._changed:
            return len(self._lines)

    def _wait_line(self, text: str, timeout_s: float, after: int) -> int:
        deadline = time.monotonic() + timeout_s
        with self._changed:
            index = after
            while True:
                while index < len(self._lines):
                    if text in self._lines[index]:
                        return index
                    index += 1
                if self.process.poll() is not None and not self._reader.is_alive():
                    raise NodeProcessError(
                        f'{self.command[0]} exited with {self.process.returncode} before '
                        f'printing {text!r}:\n{self.output_unlocked()}')
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise NodeProcessError(
                        f'no {text!r} within {timeout_s} s:\n{self.output_unlocked()}')
                self._changed.wait(min(remaining, 0.2))

    def wait_for_output(self, text: str, timeout_s: float, after: int = 0) -> str:
        """Wait for a line containing ``text`` (at index >= ``after``) and return it.

        Raises
        ------
        NodeProcessError
            When the process exits first or no such line comes within ``timeout_s`` [s].
        """
        index = self._wait_line(text, timeout_s, after)
        with self._changed:
            return self._lines[index]

    def wait_ready(self, timeout_s: float) -> float:
        """Wait for the node's ready line; the seconds from spawning to that line.

        Raises
        ------
        NodeProcessError
        """
        index = self._wait_line(READY_TEXT, timeout_s, 0)
        with self._changed:
            return self._times[index] - self.launched_at

    def status_kb(self) -> Dict[str, int]:
        """Memory lines of ``/proc/<pid>/status`` (``VmHWM``, ``VmRSS``, ...) [kB]; empty once
        the process is gone."""
        values: Dict[str, int] = {}
        try:
            text = Path(f'/proc/{self.process.pid}/status').read_text(encoding='ascii')
        except OSError:
            return values
        for line in text.splitlines():
            key, _, rest = line.partition(':')
            parts = rest.split()
            if key.startswith('Vm') and len(parts) == 2 and parts[1] == 'kB':
                values[key] = int(parts[0])
        return values

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 15.0) -> int:
        """Send ``sig`` and wait for the exit; kill the process after ``timeout_s`` [s].

        Returns
        -------
        int
            The exit code.

        Raises
        ------
        NodeProcessError
            When the process had to be killed (it is gone all the same).
        """
        if self.process.poll() is None:
            self.process.send_signal(sig)
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
                self._reader.join(5.0)
                raise NodeProcessError(f'{self.command[0]} ignored signal {sig} for '
                                       f'{timeout_s} s:\n{self.output}') from None
        self._reader.join(5.0)
        return self.process.returncode

    def kill(self) -> None:
        """Kill the process if it still runs (clean-up after a failure)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self._reader.join(5.0)


class WaitTimeout(AssertionError, TimeoutError):
    """What :func:`wait_until` raises: a test's failed expectation and a timeout at once."""


def wait_until(predicate: Callable[[], Any], timeout_s: float, what: str,
               period_s: float = 0.02) -> Any:
    """Poll ``predicate`` until it returns something truthy; return that.

    ``predicate`` is asked once more after the deadline, so a value that arrived while the
    poller slept is not lost on a loaded machine.

    Parameters
    ----------
    predicate : callable
        Returns the value waited for, or something falsy while there is none.
    timeout_s : float
        Longest wait on the monotonic clock [s].
    what : str
        What is waited for, for the message.
    period_s : float
        Poll period [s].

    Raises
    ------
    WaitTimeout
        After ``timeout_s``, naming ``what`` and the wall-clock span waited.
    """
    started_wall = time.time()
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            value = predicate()
            if value:
                return value
            raise WaitTimeout(f'timed out after {timeout_s:g} s waiting for {what} (wall clock '
                              f'{started_wall:.3f} to {time.time():.3f})')
        time.sleep(period_s)
