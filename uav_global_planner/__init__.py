"""3D global path planner for quadcopters.

``uav_global_planner.core`` is the ROS-free planning core (numpy/scipy), ``uav_global_planner.ros``
holds the rclpy node and message conversions, and ``uav_global_planner.cli`` the ``uav-plan``
command-line tool; ros and cli import the core and never each other. ``config`` (package data)
holds the shipped ``planner.yaml`` and scenes. The tools built on all three (``uav-demo``, the
ROS benchmark) are the separate package ``uav_global_planner_tools``.
"""

__version__ = '0.1.0'
