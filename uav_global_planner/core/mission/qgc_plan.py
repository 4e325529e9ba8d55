"""The QGroundControl ``.plan`` file (JSON) of a mission."""

import json
import math
from typing import Any, Dict, Optional

from uav_global_planner.core.mission.model import MAV_AUTOPILOT, MAV_TYPE_QUADROTOR, Mission


def _json_number(value: float) -> Optional[float]:
    return None if math.isnan(value) else value


def plan_document(mission: Mission, ground_station: str = 'uav_global_planner') -> Dict[str, Any]:
    """The QGroundControl ``.plan`` document (JSON-ready dictionary) of a mission.

    Layout of QGroundControl's plan-file format: ``fileType`` "Plan", ``version`` 1; ``mission``
    version 2 with ``firmwareType`` (MAV_AUTOPILOT), ``vehicleType`` 2 (quadrotor),
    ``cruiseSpeed``/``hoverSpeed`` [m/s], ``plannedHomePosition`` [lat, lon, m AMSL] and
    ``SimpleItem`` items (7 params each, ``null`` for NaN, ``doJumpId`` from 1); ``geoFence``
    version 2 (polygons clockwise, circles; each version 1); ``rallyPoints`` version 2.
    """
    items = []
    for number, item in enumerate(mission.items, start=1):
        items.append({'type': 'SimpleItem', 'command': item.command, 'frame': item.frame,
                      'autoContinue': item.auto_continue, 'doJumpId': number,
                      'params': [_json_number(p) for p in item.params]})
    fence = mission.fence
    return {
        'fileType': 'Plan',
        'version': 1,
        'groundStation': ground_station,
        'mission': {
            'version': 2,
            'firmwareType': MAV_AUTOPILOT[mission.settings.firmware],
            'vehicleType': MAV_TYPE_QUADROTOR,
            'globalPlanAltitudeMode': 1,   # relative to home, as every item's frame 3
            'cruiseSpeed': mission.speed_horizontal,
            'hoverSpeed': mission.speed_horizontal,
            'plannedHomePosition': list(mission.home),
            'items': items,
        },
        'geoFence': {
            'version': 2,
            'polygons': [{'version': 1, 'inclusion': inclusion,
                          'polygon': [list(vertex) for vertex in vertices]}
                         for vertices, inclusion in fence.polygons],
            'circles': [{'version': 1, 'inclusion': inclusion,
                         'circle': {'center': list(center), 'radius': radius}}
                        for center, radius, inclusion in fence.circles],
        },
        'rallyPoints': {'version': 2, 'points': []},
    }


def plan_text(mission: Mission, ground_station: str = 'uav_global_planner') -> str:
    """The ``.plan`` file's text (JSON, indented as QGroundControl writes it)."""
    return json.dumps(plan_document(mission, ground_station), indent=4, allow_nan=False) + '\n'
