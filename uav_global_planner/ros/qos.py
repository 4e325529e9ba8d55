"""QoS profiles of the planner's topics, shared by the node, its tools and its tests.

Explicit everywhere, because the defaults do not fit latched maps, large clouds and plans.

The compatibility rule of ROS 2 (DDS "requested vs offered"): a publisher and a subscription
connect only when what the publisher offers is at least what the subscription requests, policy
by policy. Reliability: a RELIABLE subscription needs a RELIABLE publisher; a BEST_EFFORT
subscription takes either. Durability: a TRANSIENT_LOCAL subscription needs a TRANSIENT_LOCAL
publisher; a VOLATILE one takes either. An incompatible pair does not connect at all (no data,
no error on the data path; rclpy logs "New publisher discovered ... incompatible QoS"), so:

- ``obstacles`` (markers): the node requests RELIABLE + TRANSIENT_LOCAL with depth 100, so a
  publisher must be transient local (a volatile one does not connect); a (re)started node gets
  the last ``min(publisher depth, 100)`` arrays, so a map sent as incremental arrays survives a
  restart when the publisher keeps that many (``KEEP_LAST`` with depth >= the number of arrays).
- ``obstacle_cloud``: RELIABLE, keep last 1 by default (:data:`CLOUD_QOS`): a large cloud (tens
  of MB, hundreds of DDS fragments) arrives whole, where best effort loses most of them to one
  lost fragment. A best-effort sensor publisher does not connect to it; for those set the
  node's ``cloud_qos_reliability`` parameter to ``best_effort`` (:data:`CLOUD_BEST_EFFORT_QOS`),
  which takes both kinds of publishers, at the price of lost clouds.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


#: Latched outputs: a late subscriber (RViz, a controller started later) gets the last plan.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Obstacle markers: a map-like topic; a late-starting or restarted planner still gets the
#: published markers. Depth 100 keeps a map sent as up to 100 incremental arrays, when the
#: publisher keeps as many.
OBSTACLES_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                           reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Occupied-space clouds, the default: reliable, so large clouds arrive; only the newest
#: matters (the node keeps the latest one and drops any it had no time for).
CLOUD_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: Clouds from best-effort sensor publishers (``cloud_qos_reliability: best_effort``).
CLOUD_BEST_EFFORT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                                   reliability=ReliabilityPolicy.BEST_EFFORT,
                                   durability=DurabilityPolicy.VOLATILE)
#: Commands (goal, start pose): reliable, as RViz publishes them; latest wins anyway.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Sensor streams (odometry): best effort matches reliable and best-effort publishers, and only
#: the newest sample matters.
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

#: ``cloud_qos_reliability`` values and their subscription profiles.
CLOUD_QOS_BY_RELIABILITY = {'reliable': CLOUD_QOS, 'best_effort': CLOUD_BEST_EFFORT_QOS}
