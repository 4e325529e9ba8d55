"""Ask planner_node for paths as nav2_simple_commander's BasicNavigator does.

``get_path`` and ``get_path_through_poses`` work like ``BasicNavigator.getPath`` and
``getPathThroughPoses``: send a goal to ``compute_path_to_pose`` or
``compute_path_through_poses`` with rclpy's ActionClient, spin until the result is in, and
return the ``nav_msgs/Path`` (None on failure, with the reason logged). Run it beside a planner
node in the same namespace::

    python docs/nav2_example.py [--ros-args -r __ns:=/uav1]
"""

import sys
from typing import Optional, Sequence

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
from nav_msgs.msg import Path
import rclpy
from rclpy.action import ActionClient
from rclpy.node import Node


def pose(x: float, y: float, z: float, frame_id: str = 'map') -> PoseStamped:
    """A pose in the planning frame [m]."""
    msg = PoseStamped()
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.w = 1.0
    return msg


class PathClient:
    """The two planner actions of a planner node, called synchronously."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.to_pose = ActionClient(node, ComputePathToPose, 'compute_path_to_pose')
        self.through_poses = ActionClient(node, ComputePathThroughPoses,
                                          'compute_path_through_poses')

    def _run(self, client: ActionClient, goal) -> Optional[Path]:
        if not client.wait_for_server(timeout_sec=10.0):
            self.node.get_logger().error('the planner action server is not available')
            return None
        sent = client.send_goal_async(goal)
        rclpy.spin_until_future_complete(self.node, sent)
        handle = sent.result()
        if not handle.accepted:
            self.node.get_logger().error('goal rejected')
            return None
        done = handle.get_result_async()
        rclpy.spin_until_future_complete(self.node, done)
        response = done.result()
        if response.status != GoalStatus.STATUS_SUCCEEDED:
            result = response.result
            self.node.get_logger().warning(
                f'no path: status {response.status}, error {result.error_code}: '
                f'{result.error_msg}')
            return None
        return response.result.path

    def get_path(self, start: PoseStamped, goal: PoseStamped, planner_id: str = '',
                 use_start: bool = False) -> Optional[Path]:
        """Path from ``start`` (with ``use_start``; else the planner's current start) to
        ``goal``; ``planner_id`` '' is the node's ``algorithm``, or an algorithm name."""
        return self._run(self.to_pose, ComputePathToPose.Goal(
            start=start, goal=goal, planner_id=planner_id, use_start=use_start))

    def get_path_through_poses(self, start: PoseStamped, goals: Sequence[PoseStamped],
                               planner_id: str = '', use_start: bool = False) -> Optional[Path]:
        """One continuous path through ``goals[:-1]`` (passed exactly) to ``goals[-1]``."""
        return self._run(self.through_poses, ComputePathThroughPoses.Goal(
            start=start, goals=list(goals), planner_id=planner_id, use_start=use_start))


def main() -> int:
    rclpy.init()
    node = rclpy.create_node('path_client')
    try:
        paths = PathClient(node)
        start = pose(0.0, -5.0, 0.0)
        direct = paths.get_path(start, pose(10.0, 5.0, 10.0), use_start=True)
        via = paths.get_path_through_poses(
            start, [pose(-5.0, -6.0, 3.0), pose(-5.0, 4.0, 8.0), pose(10.0, 5.0, 10.0)],
            planner_id='octile', use_start=True)
        for name, path in (('direct', direct), ('through 2 via-points', via)):
            print(f'{name}: ' + (f'{len(path.poses)} poses' if path else 'failed'))
        return 0 if direct and via else 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
