"""3D global path planner for quadcopters.

``uav_global_planner.core`` is the ROS-free planning core (numpy/scipy), ``uav_global_planner.ros``
holds the rclpy node and message conversions, and ``uav_global_planner.cli`` the ``uav-plan``
command-line tool.
"""

__version__ = '0.1.0'
