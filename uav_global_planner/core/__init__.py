"""The ROS-free planning core: grid, inflation, search, smoothing, timing and the facade.

Nothing here imports rclpy or message types, so the core runs and is tested without ROS.
"""
