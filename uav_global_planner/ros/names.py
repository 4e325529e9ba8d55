"""What other processes rely on when they start ``planner_node``: its name and its ready line.

A module of its own, without rclpy, so that the tools and the tests read these names without
importing the node.
"""

#: Name of the node unless remapped with ``--ros-args -r __node:=...``.
NODE_NAME = 'global_planner'

#: Logged once the kernels are compiled and the node takes requests; the tools and the tests
#: wait for a log line that contains it.
READY_TEXT = 'planner ready'

#: Module of the planner node, for ``python -m``.
NODE_MODULE = 'uav_global_planner.ros.planner_node'

#: Module of the scene publisher, for ``python -m``.
SCENE_PUBLISHER_MODULE = 'uav_global_planner.ros.scene_publisher'
