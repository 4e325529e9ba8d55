"""Publish a scene file to the planner node: obstacles, start pose and goal.

``scene_publisher [SCENE] [options]`` publishes the scene's spheres and boxes as a MarkerArray on
``obstacles`` (reliable, transient local, so a planner started later still gets them), its point
sets as a PointCloud2 on ``obstacle_cloud`` (repeated every second, as a sensor would), and, once
a planner subscribes, the scene's start on ``start_pose`` and its goal on ``goal_pose``. It keeps
running (the obstacles stay available to late subscribers) until Ctrl-C, or exits shortly after
the goal with ``--exit-after-goal``. ``SCENE`` is a file or a shipped scene name (default
``paper_medium``).
"""

import argparse
import math
import sys
import time
from typing import List, Optional

from geometry_msgs.msg import PoseStamped
import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.qos import COMMAND_QOS, LATCHED_QOS

#: Scene published when none is named.
DEFAULT_SCENE = 'paper_medium'


_TICK_S = 0.05
_CLOUD_PERIOD_S = 1.0
_WAITING_LOG_PERIOD_S = 5.0
_START_LEAD_S = 0.3


class ScenePublisher:
    """Publishes one scene; :meth:`tick` drives it from a timer.

    Parameters
    ----------
    node : rclpy.node.Node
    scene : Scene
    send_start, send_goal : bool
        Whether to send the scene's start on ``start_pose`` and its goal on ``goal_pose``.
    settle_s : float
        Wait after the planner subscribed before sending the goal [s], so the transient-local
        obstacles reach it first.
    goal_yaw : float, optional
        Goal heading [rad]; default: the direction from start to goal.
    linger_s : float, optional
        Seconds to keep running after the goal was sent; None runs until shut down.
    """

    def __init__(self, node: Node, scene: Scene, send_start: bool = True,
                 send_goal: bool = True, settle_s: float = 1.0,
                 goal_yaw: Optional[float] = None, linger_s: Optional[float] = None) -> None:
        self.node = node
        self.scene = scene
        self._send_start = send_start
        self._send_goal = send_goal
        self._settle_s = settle_s
        self._linger_s = linger_s
        delta = np.asarray(scene.goal) - np.asarray(scene.start)
        self._goal_yaw = (goal_yaw if goal_yaw is not None
                          else math.atan2(float(delta[1]), float(delta[0])))
        self._log = node.get_logger()
        self._obstacles_pub = node.create_publisher(MarkerArray, 'obstacles', LATCHED_QOS)
        self._cloud_pub = node.create_publisher(PointCloud2, 'obstacle_cloud', COMMAND_QOS)
        self._start_pub = node.create_publisher(PoseStamped, 'start_pose', COMMAND_QOS)
        self._goal_pub = node.create_publisher(PoseStamped, 'goal_pose', COMMAND_QOS)
        self._matched_at: Optional[float] = None
        self._sent_at: Optional[float] = None
        self._start_sent: Optional[float] = None
        self._last_cloud = -math.inf
        self._last_waiting_log = time.monotonic()
        self.done = False
        markers = conv.obstacle_input_markers(scene.obstacles, scene.frame_id, self._now_ns())
        self._obstacles_pub.publish(markers)
        self._log.info(
            f'scene {scene.name!r}: {len(markers.markers) - 1} obstacle marker(s) and '
            f'{len(scene.obstacles.points)} cloud point(s) on {self._obstacles_pub.topic_name} '
            f'in frame {scene.frame_id!r}')
        self._timer = node.create_timer(_TICK_S, self.tick)

    def _now_ns(self) -> int:
        return self.node.get_clock().now().nanoseconds

    def tick(self) -> None:
        """Republish the cloud, and send start and goal once a planner listens."""
        now = time.monotonic()
        if len(self.scene.obstacles.points) and now - self._last_cloud >= _CLOUD_PERIOD_S:
            self._cloud_pub.publish(conv.points_to_cloud(
                self.scene.obstacles.points, self.scene.frame_id, self._now_ns()))
            self._last_cloud = now
        if self._sent_at is not None or not (self._send_start or self._send_goal):
            started = self._sent_at if self._sent_at is not None else now
            if self._linger_s is not None and now - started >= self._linger_s:
                self.done = True
            return
        listening = (self._goal_pub.get_subscription_count() > 0
                     and self._obstacles_pub.get_subscription_count() > 0)
        if not listening:
            self._matched_at = None
            if now - self._last_waiting_log >= _WAITING_LOG_PERIOD_S:
                self._log.info(f'waiting for a planner on {self._goal_pub.topic_name} ...')
                self._last_waiting_log = now
            return
        if self._matched_at is None:
            self._matched_at = now
        if now - self._matched_at < self._settle_s:
            return
        frame = self.scene.frame_id
        if self._send_start and not self._start_sent:
            self._start_pub.publish(conv.pose_stamped(self.scene.start, frame, self._now_ns()))
            self._log.info(f'start {np.round(self.scene.start, 3).tolist()} sent on '
                           f'{self._start_pub.topic_name}')
            self._start_sent = now
        # Topics are not ordered with respect to each other: give the start a head start, so
        # the goal is planned from it rather than from the node's start parameter.
        if self._start_sent is not None and now - self._start_sent < _START_LEAD_S:
            return
        if self._send_goal:
            self._goal_pub.publish(conv.pose_stamped(
                self.scene.goal, frame, self._now_ns(), conv.yaw_quaternion(self._goal_yaw)))
            self._log.info(f'goal {np.round(self.scene.goal, 3).tolist()} (yaw '
                           f'{math.degrees(self._goal_yaw):.1f} deg) sent on '
                           f'{self._goal_pub.topic_name}')
        self._sent_at = now


def _parse(argv: List[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='scene_publisher',
        description='Publish a scene file (obstacles, start, goal) to the planner node.')
    parser.add_argument('scene', nargs='?', default=DEFAULT_SCENE,
                        help=f'scene file or shipped scene name (default {DEFAULT_SCENE})')
    parser.add_argument('--no-start', action='store_true',
                        help='do not send the start on start_pose')
    parser.add_argument('--no-goal', action='store_true', help='do not send the goal')
    parser.add_argument('--settle', type=float, default=1.0, metavar='S',
                        help='wait S seconds after the planner subscribed before sending the '
                             'goal (default 1.0)')
    parser.add_argument('--goal-yaw', type=float, default=None, metavar='DEG',
                        help='goal heading [deg] (default: from start towards goal)')
    parser.add_argument('--exit-after-goal', type=float, default=None, metavar='S',
                        help='exit S seconds after sending the goal (default: run until '
                             'Ctrl-C, keeping the obstacles available)')
    return parser.parse_args(argv)


def main(args: Optional[List[str]] = None) -> int:
    """Entry point of ``scene_publisher``.

    Returns
    -------
    int
        0 on a clean exit, 2 for an unreadable scene or bad arguments.
    """
    argv = sys.argv if args is None else args
    options = _parse(remove_ros_args(argv)[1:])
    try:
        scene = load_scene(find_scene(options.scene))
    except InvalidInputError as error:
        print(f'scene_publisher: {error}', file=sys.stderr)
        return 2
    rclpy.init(args=argv)
    node = None
    try:
        node = Node('scene_publisher')
        yaw = None if options.goal_yaw is None else math.radians(options.goal_yaw)
        publisher = ScenePublisher(node, scene, send_start=not options.no_start,
                                   send_goal=not options.no_goal, settle_s=options.settle,
                                   goal_yaw=yaw, linger_s=options.exit_after_goal)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while rclpy.ok() and not publisher.done:
            executor.spin_once(timeout_sec=_TICK_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
