"""The plain-text ``QGC WPL 110`` file of a mission (Mission Planner, QGroundControl, MAVProxy).
"""

import math

from uav_global_planner.core.mission.model import (MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL,
                                                   Mission, MissionItem)


def _wpl_number(value: float) -> str:
    # Fixed-point with one decimal more than stored: parses back to the very same double.
    return 'nan' if math.isnan(value) else f'{value:.8f}'


def wpl_text(mission: Mission) -> str:
    """The ``QGC WPL 110`` text of a mission (Mission Planner, QGroundControl, MAVProxy).

    Tab-separated, 12 fields a line: index, current, frame, command, param1..4, latitude,
    longitude, altitude, autocontinue. Line 0 is home (frame 0, altitude AMSL), as Mission
    Planner writes it; the items follow from index 1.
    """
    lines = ['QGC WPL 110']
    lat, lon, alt = mission.home
    home = MissionItem(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL,
                       (0.0, 0.0, 0.0, 0.0, lat, lon, alt), True)
    for index, item in enumerate((home,) + mission.items):
        fields = [str(index), '1' if index == 0 else '0', str(item.frame), str(item.command)]
        fields += [_wpl_number(p) for p in item.params]
        fields.append('1' if item.auto_continue else '0')
        lines.append('\t'.join(fields))
    return '\n'.join(lines) + '\n'
