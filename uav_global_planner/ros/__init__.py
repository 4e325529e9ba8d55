"""ROS 2 layer: message conversions, the planner node, the scene publisher and the demo.

:mod:`uav_global_planner.ros.conversions` and :mod:`uav_global_planner.ros.cdr` only need the
message packages; everything else here needs ``rclpy``. The core (:mod:`uav_global_planner.core`)
never imports this package.
"""
