"""ROS-side performance figures of ``planner_node``: goal-to-plan latency, start-up, memory.

``python -m uav_global_planner_tools.latency_bench [--json]`` (also ``uav-plan bench --ros``)
starts ``planner_node`` as a child process for each scene (``config/planner.yaml`` with the
scene's bounds, delta, gamma, eta and start given as ``-p`` overrides, as ``uav-demo`` does)
and talks to it over DDS like any client:

start-up
    From just before the process is spawned until its ready log line
    (:data:`~uav_global_planner.ros.names.READY_TEXT`; the node logs it after declaring its
    parameters, creating its topics, loading the compiled kernels and building the empty grid,
    right before it spins; the tests wait for the same line).
latency
    The scene's obstacles go out once as a transient-local ``MarkerArray``; after a few warm-up
    goals, ``--goals`` goals alternate between the scene's goal and another free point, so each
    one is a real replan. The latency of a goal runs from just before ``publish`` on
    ``goal_pose`` until the ``plan`` message ending at that goal has arrived in the client and
    been deserialised into a Python ``nav_msgs/Path``; the time until its bytes arrived is
    reported too (the difference is the Python client's own deserialisation, a few
    milliseconds for a few hundred poses, which a C++ client hardly pays). The next goal is
    sent once the node has also published the diagnostics of the plan, its last output, so
    goals never queue up behind each other.
memory
    For ``--memory-scene`` (default ``dense60_fine``), the node plans the scene with each
    algorithm in turn (switched with the ``algorithm`` parameter over the parameter services);
    the peak is ``VmHWM`` of ``/proc/<pid>/status``, the true high-water mark of the node
    process's resident memory.

Each node runs in its own namespace, in a ROS domain no other process on this machine uses
(or the one of ``--domain-id``), with discovery limited to this machine, so the benchmark
neither disturbs nor sees other ROS systems. Figures only: nothing here asserts a speed.

The modules: :mod:`.client` (the benchmark's rclpy node), :mod:`.session` (one node, one scene,
one goal at a time), :mod:`.measure` (the figures), :mod:`.report` (their tables), :mod:`.cli`
(the command) and :mod:`.uav_plan_bench` (the figures of ``uav-plan bench --ros``).
"""
