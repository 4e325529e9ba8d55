"""``uav-demo``: the whole ROS pipeline in one command.

Starts ``planner_node`` with ``config/planner.yaml`` (plus the scene's bounds, delta, gamma and
eta) and ``scene_publisher`` as child processes, receives the plan over ROS like any client,
prints a one-screen summary and writes a 3D plot of the scene with the received paths.

It runs in its own ROS domain unless ``ROS_DOMAIN_ID`` or ``--domain-id`` says otherwise, with
discovery limited to this machine, so it never disturbs (or is disturbed by) other ROS systems.
"""

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Dict, List, Optional, Sequence

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Path as PathMsg
import numpy as np

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.scene import find_scene, load_scene, Scene
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode, choose_domain_id
from uav_global_planner.ros.qos import LATCHED_QOS, MONITOR_QOS

DEFAULT_SCENE = 'paper_medium'
_NODE_FQN = '/global_planner'
_PACKAGE = 'uav_global_planner'


# After the first plan, wait this long for replans (obstacles arriving after the goal) [s].
_SETTLE_S = 1.0


def find_config(name: str = 'planner.yaml') -> Path:
    """A file of the package's ``config`` folder: the source tree first, then the ament share.

    Raises
    ------
    FileNotFoundError
    """
    candidates = [Path(__file__).resolve().parents[2] / 'config' / name]
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(_PACKAGE)) / 'config' / name)
    except Exception:  # noqa: BLE001 - no ament index in a plain venv; the source tree serves
        pass
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f'{name} not found in {", ".join(str(c) for c in candidates)}')


def _scene_overrides(scene: Scene) -> List[str]:
    """``-p`` arguments that make the node use the scene's workspace and paper parameters."""
    config = scene.config

    def floats(values: Sequence[float]) -> str:
        return '[' + ', '.join(repr(float(v)) for v in values) + ']'

    return ['-p', f'frame_id:={scene.frame_id}',
            '-p', f'bounds.min:={floats(config.bounds_min)}',
            '-p', f'bounds.max:={floats(config.bounds_max)}',
            '-p', f'resolution:={float(config.resolution)!r}',
            '-p', f'safety_margin:={float(config.safety_margin)!r}',
            '-p', f'adaptive_threshold:={float(config.adaptive_threshold)!r}']


class _Child:
    """A child process whose output goes to a log file."""

    def __init__(self, name: str, command: List[str], env: Dict[str, str],
                 log_dir: Path) -> None:
        self.name = name
        self.log_path = log_dir / f'{name}.log'
        self._log = open(self.log_path, 'w', encoding='utf-8')
        self.process = subprocess.Popen(command, env=env, stdout=self._log,
                                        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                        start_new_session=True)

    def tail(self, lines: int = 15) -> str:
        text = self.log_path.read_text(encoding='utf-8', errors='replace').splitlines()
        return '\n'.join(f'    {line}' for line in text[-lines:])

    def stop(self) -> Optional[int]:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(10.0)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()
        return self.process.returncode


class _Listener:
    """Collects the planner's plans and diagnostics on the demo's own rclpy context."""

    def __init__(self, domain_id: int) -> None:
        self._background = BackgroundNode('uav_demo', domain_id)
        self.node = self._background.node
        self.lock = threading.Condition()
        self.plans: List[PathMsg] = []
        self.unsmoothed: List[PathMsg] = []
        self.diagnostics: List[tuple] = []
        node = self.node
        node.create_subscription(PathMsg, 'plan', self._store(self.plans), LATCHED_QOS)
        node.create_subscription(PathMsg, 'unsmoothed_plan', self._store(self.unsmoothed),
                                 LATCHED_QOS)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                 MONITOR_QOS)

    def _store(self, target: list):
        def callback(msg) -> None:
            with self.lock:
                target.append(msg)
                self.lock.notify_all()
        return callback

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status, values in conv.diagnostic_values(msg):
            if status.name.startswith(f'{_NODE_FQN}: ') and values.get('event') == 'plan':
                with self.lock:
                    self.diagnostics.append((conv.time_to_ns(msg.header.stamp), values))
                    self.lock.notify_all()

    def wait(self, predicate, timeout_s: float) -> bool:
        with self.lock:
            return self.lock.wait_for(predicate, timeout_s)

    def planner_discovered(self) -> bool:
        """True once the planner's plan and diagnostics publishers are known here, so the
        (volatile) diagnostics of the first plan cannot be missed."""
        return (self.node.count_publishers('/plan') > 0
                and self.node.count_publishers('/diagnostics') > 0)

    def close(self) -> None:
        self._background.close()


def _wait(condition, children: List['_Child'], timeout_s: float) -> bool:
    """Poll ``condition`` until true (True), a child exits or the timeout passes (False)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        if any(child.process.poll() is not None for child in children):
            return False
        time.sleep(0.1)
    return bool(condition())


def _path_for_stamp(paths: List[PathMsg], stamp_ns: int) -> Optional[PathMsg]:
    for msg in reversed(paths):
        if conv.time_to_ns(msg.header.stamp) == stamp_ns:
            return msg
    return None


def _summary(scene: Scene, values: Dict[str, str], plan: Optional[PathMsg],
             unsmoothed: Optional[PathMsg], domain_id: int, plot: str) -> str:
    """The one-screen report."""
    def v(key: str) -> str:
        return values.get(key, '?')

    def num(key: str, spec: str = '.3f', scale: float = 1.0) -> str:
        """A numeric value re-formatted for reading ('?' when absent or not a number)."""
        try:
            return format(float(values[key]) * scale, spec)
        except (KeyError, ValueError):
            return '?'

    lines = [
        f'uav_global_planner demo: scene {scene.name!r}',
        f'  {scene.description}' if scene.description else None,
        f'  ROS domain        : {domain_id} (localhost only), frame {v("frame_id")!r}',
        f'  status            : {v("status")} (Nav2 code {v("status_code")})',
        f'  start -> goal     : {v("start")} -> {v("goal")}',
        f'  start source      : {v("start_source")}',
        f'  algorithm         : {v("algorithm")}, delta {num("resolution_m", "g")} m, '
        f'gamma {num("safety_margin_m", "g")} m, eta {num("adaptive_threshold_m", "g")} m',
        f'  obstacles         : {v("obstacles")}',
        f'  expanded nodes    : {v("expanded_nodes")}',
        f'  times             : search {num("planning_time_s", ".2f", 1e3)} ms, grid build '
        f'{num("grid_build_time_s", ".2f", 1e3)} ms, smoothing and timing '
        f'{num("smoothing_time_s", ".2f", 1e3)} ms',
    ]
    if v('status') == 'ok':
        lines.append(f'  length            : grid path {num("path_length_m")} m, smoothed '
                     f'{num("smoothed_length_m")} m, flight time {num("duration_s", ".2f")} s')
        measured = 'n/a'
        if plan is not None and len(plan.poses) > 0:
            from uav_global_planner.core.planner import densify
            points = conv.path_to_points(plan)
            clearance = scene.obstacles.distance(densify(points, 0.01))
            measured = f'{float(np.min(clearance)):.4f}'
        lines.append(f'  min clearance     : {num("min_clearance_m", ".4f")} m reported, '
                     f'{measured} m measured on the received path (gamma '
                     f'{num("safety_margin_m", "g")} m)')
        lines.append(f'  received          : plan {len(plan.poses) if plan else 0} poses, '
                     f'unsmoothed_plan {len(unsmoothed.poses) if unsmoothed else 0} poses')
    else:
        lines.append(f'  reason            : {v("message")}')
    lines.append(f'  plot              : {plot}')
    return '\n'.join(line for line in lines if line is not None)


def _plot(scene: Scene, plan: Optional[PathMsg], unsmoothed: Optional[PathMsg],
          output: Path) -> str:
    """Write the 3D plot if the plotting module is there; return what to report."""
    try:
        from uav_global_planner.cli.plotting import plot_scene_paths
    except ImportError as error:
        return f'skipped (plotting unavailable: {error})'
    paths = {}
    if unsmoothed is not None:
        paths['grid path raw'] = conv.path_to_points(unsmoothed)
    if plan is not None:
        paths['smoothed plan'] = conv.path_to_points(plan)
    written = plot_scene_paths(scene, paths, output,
                               title=f'{scene.name}: plan received over ROS')
    return str(written)


def _parse(argv: Optional[List[str]]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='uav-demo',
        description='Start planner_node and scene_publisher, receive the plan over ROS, print '
                    'a summary and plot it.')
    parser.add_argument('--scene', default=DEFAULT_SCENE,
                        help=f'scene file or shipped scene name (default {DEFAULT_SCENE})')
    parser.add_argument('--output', type=Path, default=None,
                        help='PNG to write (default uav_demo_<scene>.png in the current folder)')
    parser.add_argument('--timeout', type=float, default=180.0, metavar='S',
                        help='give up after S seconds without a plan (default 180; the first '
                             'run compiles the search kernels)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS domain (default: $ROS_DOMAIN_ID, else one derived from the '
                             'process id)')
    return parser.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``uav-demo``.

    Returns
    -------
    int
        0 when a plan was received, 1 when planning failed or timed out, 2 for bad arguments.
    """
    options = _parse(argv)
    try:
        scene_path = find_scene(options.scene)
        scene = load_scene(scene_path)
        config_path = find_config('planner.yaml')
    except (InvalidInputError, FileNotFoundError) as error:
        print(f'uav-demo: {error}', file=sys.stderr)
        return 2
    domain_id = choose_domain_id(options.domain_id)
    output = options.output or Path(f'uav_demo_{scene.name}.png')
    log_dir = Path(tempfile.mkdtemp(prefix='uav_demo_'))
    env = dict(os.environ)
    env.update({'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
                'PYTHONUNBUFFERED': '1', 'RCUTILS_COLORIZED_OUTPUT': '0'})
    env.setdefault('ROS_LOG_DIR', str(log_dir / 'ros'))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

    print(f'uav-demo: starting planner_node and scene_publisher (domain {domain_id}, logs in '
          f'{log_dir}) ...', flush=True)
    started = time.monotonic()
    children: List[_Child] = []
    listener: Optional[_Listener] = None
    try:
        children.append(_Child('planner_node', [
            sys.executable, '-m', 'uav_global_planner.ros.planner_node', '--ros-args',
            '--params-file', str(config_path), *_scene_overrides(scene)], env, log_dir))
        listener = _Listener(domain_id)
        # The scene (and so the goal) goes out only once this listener can hear the planner.
        ready = _wait(listener.planner_discovered, children, options.timeout)
        if ready:
            children.append(_Child('scene_publisher', [
                sys.executable, '-m', 'uav_global_planner.ros.scene_publisher',
                str(scene_path)], env, log_dir))
            remaining = options.timeout - (time.monotonic() - started)
            ready = _wait(lambda: bool(listener.diagnostics), children, remaining)
        if not ready:
            print(f'uav-demo: no plan within {options.timeout} s', file=sys.stderr)
            for child in children:
                state = child.process.poll()
                status = 'running' if state is None else f'exited with {state}'
                print(f'  {child.name}, {status} ({child.log_path}):\n{child.tail()}',
                      file=sys.stderr)
            return 1
        # Obstacles may reach the node after the goal; it then replans by itself.
        time.sleep(_SETTLE_S)
        with listener.lock:
            stamp_ns, values = listener.diagnostics[-1]
        plan = unsmoothed = None
        if values.get('status') == 'ok':
            listener.wait(lambda: _path_for_stamp(listener.plans, stamp_ns) is not None
                          and _path_for_stamp(listener.unsmoothed, stamp_ns) is not None, 10.0)
            with listener.lock:
                plan = _path_for_stamp(listener.plans, stamp_ns)
                unsmoothed = _path_for_stamp(listener.unsmoothed, stamp_ns)
        plot = _plot(scene, plan, unsmoothed, output)
        print(_summary(scene, values, plan, unsmoothed, domain_id, plot))
        print(f'  wall time         : {time.monotonic() - started:.1f} s', flush=True)
        return 0 if values.get('status') == 'ok' and plan is not None else 1
    except KeyboardInterrupt:
        print('uav-demo: interrupted', file=sys.stderr)
        return 130
    finally:
        for child in reversed(children):
            child.stop()
        if listener is not None:
            listener.close()


if __name__ == '__main__':
    sys.exit(main())
