"""ROS 2 layer: message conversions, the planner node and the scene publisher.

:mod:`uav_global_planner.ros.conversions` and :mod:`uav_global_planner.ros.cdr` only need the
message packages, :mod:`uav_global_planner.ros.names` nothing; everything else here needs
``rclpy``. This package imports only the core; the core (:mod:`uav_global_planner.core`) and the
command-line tool (:mod:`uav_global_planner.cli`) never import it. The demo and the ROS
benchmark are tools built on it, in :mod:`uav_global_planner_tools`.
"""
