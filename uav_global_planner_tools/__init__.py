"""Tools built on the planner: ``uav-demo`` and the ROS latency benchmark.

They use the planning core (:mod:`uav_global_planner.core`), the command-line tool's plots and
tables (:mod:`uav_global_planner.cli`) and the node (:mod:`uav_global_planner.ros`); nothing in
``uav_global_planner`` imports this package. :mod:`uav_global_planner_tools.processes` starts
ROS processes, isolated on this machine, for the tools and the tests alike.
"""
