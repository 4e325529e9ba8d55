"""``uav-demo``: the whole ROS pipeline in one command.

Starts ``planner_node`` with ``config/planner.yaml`` (plus the scene's bounds, delta, gamma and
eta) and ``scene_publisher`` as child processes, receives the plan over ROS like any client,
prints a one-screen summary and writes a 3D plot of the scene with the received paths.

It runs in a ROS domain of its own, one that no other process on this machine uses (never the
``ROS_DOMAIN_ID`` of the shell), with discovery limited to this machine, so it never pushes its
scene into someone else's planner nor hears another one. ``--domain-id N`` picks the domain and
``--join-domain`` joins ``$ROS_DOMAIN_ID``, for watching the demo from other ROS tools.
"""

import argparse
from pathlib import Path
import sys
import tempfile
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Path as PathMsg
import numpy as np

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode
from uav_global_planner.ros.names import NODE_NAME
from uav_global_planner.ros.qos import LATCHED_QOS, MONITOR_QOS
from uav_global_planner_tools.domains import choose_domain_id, environment_domain_id
from uav_global_planner_tools.processes import (find_config, localhost_discovery, NodeProcess,
                                                NodeProcessError, planner_command,
                                                ros_environment, scene_parameters,
                                                scene_publisher_command)

DEFAULT_SCENE = 'paper_medium'
_NODE_FQN = '/' + NODE_NAME


# After the first plan, wait this long for replans (obstacles arriving after the goal) [s].
_SETTLE_S = 1.0


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


def _wait(condition: Callable[[], bool], children: Dict[str, NodeProcess],
          timeout_s: float) -> bool:
    """Poll ``condition`` until true (True), a child exits or the timeout passes (False)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        if any(child.process.poll() is not None for child in children.values()):
            return False
        time.sleep(0.1)
    return bool(condition())


def _path_for_stamp(paths: List[PathMsg], stamp_ns: int) -> Optional[PathMsg]:
    for msg in reversed(paths):
        if conv.time_to_ns(msg.header.stamp) == stamp_ns:
            return msg
    return None


def _summary(scene: Scene, values: Dict[str, str], plan: Optional[PathMsg],
             unsmoothed: Optional[PathMsg], domain: str, plot: str) -> str:
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
        f'  ROS domain        : {domain}, localhost only; frame {v("frame_id")!r}',
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
    domain = parser.add_mutually_exclusive_group()
    domain.add_argument('--domain-id', type=int, default=None, metavar='N',
                        help='run in ROS domain N (default: a domain that no other process on '
                             'this machine uses, never $ROS_DOMAIN_ID)')
    domain.add_argument('--join-domain', action='store_true',
                        help='run in $ROS_DOMAIN_ID (0 when unset), beside the ROS nodes there')
    return parser.parse_args(argv)


def choose_domain(options: argparse.Namespace) -> Tuple[int, str]:
    """The demo's ROS domain and how it was chosen (for the summary).

    Raises
    ------
    RuntimeError
        When every safe domain id is in use.
    """
    if options.domain_id is not None:
        return options.domain_id, f'{options.domain_id} (--domain-id)'
    if options.join_domain:
        joined = environment_domain_id() or 0
        return joined, f'{joined} (joined $ROS_DOMAIN_ID)'
    own = choose_domain_id()
    return own, f'{own} (its own, free on this machine)'


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
    try:
        domain_id, domain = choose_domain(options)
    except RuntimeError as error:
        print(f'uav-demo: {error}', file=sys.stderr)
        return 1
    output = options.output or Path(f'uav_demo_{scene.name}.png')
    log_dir = Path(tempfile.mkdtemp(prefix='uav_demo_'))
    env = ros_environment(domain_id, log_dir / 'ros')
    localhost_discovery()  # for the listener in this process

    print(f'uav-demo: starting planner_node and scene_publisher (domain {domain_id}, logs in '
          f'{log_dir}) ...', flush=True)
    started = time.monotonic()
    children: Dict[str, NodeProcess] = {}
    listener: Optional[_Listener] = None
    try:
        children['planner_node'] = NodeProcess(
            planner_command(parameters=scene_parameters(scene), params_file=config_path), env,
            log_dir / 'planner_node.log')
        listener = _Listener(domain_id)
        # The scene (and so the goal) goes out only once this listener can hear the planner.
        ready = _wait(listener.planner_discovered, children, options.timeout)
        if ready:
            children['scene_publisher'] = NodeProcess(
                scene_publisher_command(str(scene_path)), env, log_dir / 'scene_publisher.log')
            remaining = options.timeout - (time.monotonic() - started)
            ready = _wait(lambda: bool(listener.diagnostics), children, remaining)
        if not ready:
            print(f'uav-demo: no plan within {options.timeout} s', file=sys.stderr)
            for name, child in children.items():
                state = child.process.poll()
                status = 'running' if state is None else f'exited with {state}'
                print(f'  {name}, {status} ({child.log_path}):\n{child.tail(15)}',
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
        print(_summary(scene, values, plan, unsmoothed, domain, plot))
        print(f'  wall time         : {time.monotonic() - started:.1f} s', flush=True)
        return 0 if values.get('status') == 'ok' and plan is not None else 1
    except KeyboardInterrupt:
        print('uav-demo: interrupted', file=sys.stderr)
        return 130
    finally:
        for name, child in reversed(list(children.items())):
            try:
                child.stop(timeout_s=10.0)
            except NodeProcessError:
                print(f'uav-demo: {name} had to be killed ({child.log_path})', file=sys.stderr)
        if listener is not None:
            listener.close()


if __name__ == '__main__':
    sys.exit(main())
