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


def keep_last(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    """A ``KEEP_LAST`` profile: every profile of the planner's topics is one.

    Parameters
    ----------
    depth : int
        Messages kept per publisher or subscription, >= 1.
    reliable : bool
        RELIABLE, else BEST_EFFORT.
    latched : bool
        TRANSIENT_LOCAL (late subscribers get the last ``depth`` messages), else VOLATILE.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=(ReliabilityPolicy.RELIABLE if reliable
                                   else ReliabilityPolicy.BEST_EFFORT),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                  else DurabilityPolicy.VOLATILE))


#: Latched outputs: a late subscriber (RViz, a controller started later) gets the last plan.
LATCHED_QOS = keep_last(1, latched=True)
#: Obstacle markers: a map-like topic; a late-starting or restarted planner still gets the
#: published markers. Depth 100 keeps a map sent as up to 100 incremental arrays, when the
#: publisher keeps as many.
OBSTACLES_QOS = keep_last(100, latched=True)
#: Occupied-space clouds, the default: reliable, so large clouds arrive; only the newest
#: matters (the node keeps the latest one and drops any it had no time for).
CLOUD_QOS = keep_last(1)
#: Clouds from best-effort sensor publishers (``cloud_qos_reliability: best_effort``).
CLOUD_BEST_EFFORT_QOS = keep_last(1, reliable=False)
#: Commands (goal, start pose): reliable, as RViz publishes them; latest wins anyway.
COMMAND_QOS = keep_last(5)
#: Sensor streams (odometry): best effort matches reliable and best-effort publishers, and only
#: the newest sample matters.
SENSOR_QOS = keep_last(1, reliable=False)
#: /diagnostics as diagnostic_aggregator expects it.
DIAGNOSTICS_QOS = keep_last(10)
#: Listeners that must not miss a burst (tools and tests reading diagnostics or plans).
MONITOR_QOS = keep_last(50)

#: ``cloud_qos_reliability`` values and their subscription profiles.
CLOUD_QOS_BY_RELIABILITY = {'reliable': CLOUD_QOS, 'best_effort': CLOUD_BEST_EFFORT_QOS}
