"""From a node path to a flyable timed reference.

``shortcut`` and ``repair`` (fewer turns, certified), ``clearance`` (the certified distance of
segments and curves), ``curve`` and ``smoothing`` (the cubic spline, eq. 13, certified to keep the
margin), ``motion_limits``, ``timing``, ``reference``, ``yaw`` and ``handover`` (the timed
reference, from rest or from the vehicle's current state), ``tracking`` (the tracking allowance)
and ``energy`` (the energy cost).
"""
