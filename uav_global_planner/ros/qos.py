"""QoS profiles of the planner's topics, shared by the node, its tools and its tests.

Explicit everywhere, because the defaults do not fit latched maps and plans. A publisher and a
subscriber only connect when their profiles are compatible: in particular an ``obstacles``
publisher must be transient local like the node's subscription.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


#: Latched outputs: a late subscriber (RViz, a controller started later) gets the last plan.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Obstacle markers: a map-like topic; a late-starting planner still gets the published markers.
#: Depth 10 keeps several incremental arrays of a publisher with a deeper history.
OBSTACLES_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                           reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Commands (goal, start pose): reliable, as RViz publishes them; latest wins anyway.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Sensor streams (odometry, clouds): best effort matches reliable and best-effort publishers,
#: and only the newest sample matters.
SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)
#: /diagnostics as diagnostic_aggregator expects it.
DIAGNOSTICS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
#: Listeners that must not miss a burst (tools and tests reading diagnostics or plans).
MONITOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
