"""A simulated PX4 vehicle and a MAVLink peer vehicle, for closing the setpoint follower's loop.

- :mod:`~uav_global_planner_tools.px4_sim.vehicle`: the simulated multirotor (RotorPy's
  ``Multirotor`` flown by its ``SE3Control``) under an autopilot's offboard logic, in real time.
- :mod:`~uav_global_planner_tools.px4_sim.ned`: its own ENU/FLU <-> NED/FRD conversion.
- :mod:`~uav_global_planner_tools.px4_sim.dds_vehicle`: the vehicle as PX4's uXRCE-DDS bridge
  shows it (``px4_msgs`` on ``/fmu/...``), a process of its own.
- :mod:`~uav_global_planner_tools.px4_sim.mavlink_vehicle`: the vehicle as a MAVLink autopilot
  (pymavlink on UDP), a process of its own.
- :mod:`~uav_global_planner_tools.px4_sim.track`: reading the track files both write.
"""
