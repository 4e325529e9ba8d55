"""One planner node with one scene, and the client that times its answers.

:class:`Session` starts ``planner_node`` (the shipped ``planner.yaml`` with the scene's
workspace, delta, gamma, eta and start as overrides) in its own namespace, sends it the scene's
obstacles once, warms it up, then sends goals one at a time: each goal waits for the plan that
ends at it and for the diagnostics of that plan, so goals never queue up behind each other.
"""

from pathlib import Path
import time
from typing import Any, Dict, Optional

import numpy as np

from uav_global_planner.core.io.scene import Scene
from uav_global_planner.ros import conversions as conv
from uav_global_planner_tools.latency_bench.client import BenchClient, BenchError
from uav_global_planner_tools.processes import (find_config, NodeProcess, NodeProcessError,
                                                planner_command, ros_environment,
                                                scene_parameters)

# Goals sent (and not counted) before the measured ones: the first plans load code paths.
WARM_UP_GOALS = 4
# A plan must end within this distance of the goal it answers [m] (it ends exactly there).
_GOAL_MATCH_M = 1e-6
# Diagnostics print positions with 4 decimals [m].
_DIAG_MATCH_M = 2e-4


def _parse_point(text: Optional[str]) -> Optional[np.ndarray]:
    """``[x, y, z]`` of a diagnostics value, or None."""
    if not text:
        return None
    try:
        values = [float(v) for v in text.strip('[] ').split(',')]
    except ValueError:
        return None
    return np.array(values) if len(values) == 3 else None


def _float(values: Dict[str, str], key: str) -> Optional[float]:
    try:
        number = float(values[key])
    except (KeyError, ValueError):
        return None
    return number if np.isfinite(number) else None


def alternate_goal(scene: Scene) -> np.ndarray:
    """A second free goal of ``scene``, far from its start and goal, to alternate with.

    The first of a fixed list of points (as fractions of the workspace) that keeps a clearance
    of gamma + 2 delta and lies at least a third of the workspace diagonal from the start and
    the goal; deterministic for a given scene.

    Raises
    ------
    BenchError
        When no candidate is free.
    """
    config = scene.config
    lo = np.asarray(config.bounds_min, dtype=np.float64)
    hi = np.asarray(config.bounds_max, dtype=np.float64)
    fractions = [(a, b, c) for c in (0.5, 0.3, 0.7, 0.15, 0.85)
                 for a, b in ((0.15, 0.85), (0.85, 0.15), (0.15, 0.15), (0.85, 0.85),
                              (0.5, 0.9), (0.9, 0.5), (0.1, 0.5), (0.5, 0.1))]
    candidates = lo + np.array(fractions) * (hi - lo)
    clearance = scene.obstacles.distance(candidates)
    far = np.linalg.norm(hi - lo) / 3.0
    for point, free in zip(candidates, clearance):
        if (free >= config.safety_margin + 2.0 * config.resolution
                and np.linalg.norm(point - scene.start) >= far
                and np.linalg.norm(point - scene.goal) >= far):
            return point
    raise BenchError(f'no free alternate goal found in scene {scene.name!r}')


class Session:
    """One planner node with one scene, and the client talking to it.

    Parameters
    ----------
    scene : Scene
    domain_id : int
    namespace : str
        Namespace of the node (and of the client's topics).
    log_dir : Path
        ``ROS_LOG_DIR`` of the node.
    timeout_s : float
        Longest wait for the node to start or to answer [s].
    """

    def __init__(self, scene: Scene, domain_id: int, namespace: str, log_dir: Path,
                 timeout_s: float) -> None:
        self.scene = scene
        self.timeout_s = timeout_s
        # First, so that a scene without a second goal starts nothing.
        self.goals = (np.asarray(scene.goal, dtype=np.float64), alternate_goal(scene))
        self.client = BenchClient(domain_id, namespace)
        parameters = {**scene_parameters(scene), 'start': [float(v) for v in scene.start]}
        self.node = NodeProcess(
            planner_command(namespace=namespace, parameters=parameters,
                            params_file=find_config()),
            ros_environment(domain_id, log_dir))
        self.startup_s: Optional[float] = None
        self.goal_index = 0
        self.algorithm: Optional[str] = None  # as last reported by the node

    def close(self) -> Optional[int]:
        """Stop the node and the client; the node's exit code (negative when it was killed)."""
        try:
            code: Optional[int] = self.node.stop()
        except NodeProcessError:
            code = self.node.process.returncode
        self.client.close()
        return code

    def start(self) -> float:
        """Wait for the node, send the obstacles and warm up; return the start-up time [s]."""
        try:
            self.startup_s = self.node.wait_ready(self.timeout_s)
        except NodeProcessError as error:
            raise BenchError(str(error)) from None
        if not self.client.wait_matched(self.timeout_s):
            raise BenchError(f'planner topics not matched within {self.timeout_s} s:\n'
                             f'{self.node.tail()}')
        scene = self.scene
        stamp_ns = self.client.node.get_clock().now().nanoseconds
        markers = conv.obstacle_input_markers(scene.obstacles, scene.frame_id, stamp_ns)
        cloud = scene.obstacles.points if len(scene.obstacles.points) else None
        expected = len(conv.combine_obstacles(
            conv.apply_marker_array({}, markers, scene.frame_id, float('inf')), cloud))
        self.client.obstacles_pub.publish(markers)
        if cloud is not None:
            self.client.cloud_pub.publish(conv.points_to_cloud(cloud, scene.frame_id, stamp_ns))
        # Until a plan reports every obstacle, the obstacles may still be on their way.
        for _ in range(20):
            outcome = self.send_goal()
            if outcome['obstacles'] == expected:
                break
            time.sleep(0.1)
        else:
            raise BenchError(f'the node never planned with all {expected} obstacles')
        for _ in range(WARM_UP_GOALS - 1):
            self.send_goal()
        return self.startup_s

    def set_algorithm(self, algorithm: str) -> None:
        """Switch the ``algorithm`` parameter and wait for the replan it causes."""
        client = self.client
        _, diags_before = client.mark()
        client.set_parameter('algorithm', algorithm, self.timeout_s)
        if algorithm == self.algorithm:
            return  # no change, no replan
        self.algorithm = algorithm
        # The node replans its active goal by itself; let that finish before timing goals.
        if client.wait(lambda: any(values.get('algorithm') == algorithm for values in
                                   client.plan_diagnostics(diags_before)),
                       self.timeout_s) is None:
            raise BenchError(f'no replan after switching to {algorithm}:\n{self.node.tail()}')

    def send_goal(self) -> Dict[str, Any]:
        """Publish the next goal; wait for its plan and diagnostics.

        Returns
        -------
        dict
            ``latency_s`` until the plan was deserialised (None when no plan came),
            ``bytes_s`` until its bytes arrived, ``status``, ``algorithm``, ``obstacles`` (count
            the node planned with), ``node_search_s``, ``node_smoothing_s``, ``poses`` and
            ``kind`` (0 for the scene's goal, 1 for the alternate one).
        """
        kind = self.goal_index % 2
        goal = self.goals[kind]
        self.goal_index += 1
        client = self.client
        frame = self.scene.frame_id
        msg = conv.pose_stamped(goal, frame, client.node.get_clock().now().nanoseconds)
        plans_before, diags_before = client.mark()
        sent = time.perf_counter()
        client.goal_pub.publish(msg)

        def answered() -> Optional[Dict[str, str]]:
            for values in client.plan_diagnostics(diags_before):
                point = _parse_point(values.get('goal'))
                if point is not None and np.linalg.norm(point - goal) <= _DIAG_MATCH_M:
                    return values
            return None

        values = client.wait(answered, self.timeout_s)
        if values is None:
            raise BenchError(f'no answer to goal {goal.tolist()} within {self.timeout_s} s:\n'
                             f'{self.node.tail()}')
        self.algorithm = values.get('algorithm')
        outcome = {'status': values.get('status'), 'latency_s': None, 'bytes_s': None,
                   'poses': None, 'kind': kind,
                   'obstacles': int(_float(values, 'obstacles') or 0),
                   'node_search_s': _float(values, 'planning_time_s'),
                   'node_smoothing_s': _float(values, 'smoothing_time_s'),
                   'algorithm': values.get('algorithm')}
        if outcome['status'] != 'ok':
            return outcome

        def received() -> Optional[tuple]:
            for arrived, path, decoded in client.plans.items[plans_before:]:
                if len(path.poses) and np.linalg.norm(
                        conv.path_to_points(path)[-1] - goal) <= _GOAL_MATCH_M:
                    return arrived, decoded, len(path.poses)
            return None

        # The plan goes out before the diagnostics, but topics are not ordered with each other.
        arrival = client.wait(received, 5.0)
        if arrival is not None:
            outcome['bytes_s'] = arrival[0] - sent
            outcome['latency_s'] = arrival[1] - sent
            outcome['poses'] = arrival[2]
        return outcome
