"""Missions an autopilot flies on its own: certified waypoints, QGroundControl ``.plan`` and WPL.

A ground station (QGroundControl, Mission Planner) uploads a mission to the autopilot (PX4,
ArduPilot), which then flies it in AUTO mode without a companion computer. The autopilot does not
follow the smoothed curve: it flies **straight legs** between waypoints and **turns early**, as
soon as it is within the acceptance radius R of a waypoint. This package chooses waypoints for
which that behaviour keeps the clearance, and writes them in the two mission file formats.

What is certified
-----------------
The required clearance is ``m = gamma + a``: the planner's safety margin plus a tracking
allowance ``a`` for what the autopilot adds (cross-track error, overshoot, wind). Keeping ``m``
along the nominal path means that every point within ``a`` of it keeps ``gamma`` (the obstacle
distance is 1-Lipschitz). Every yes/no below comes from the clearance engine
(:func:`~uav_global_planner.core.path.clearance.certify_segments`), which certifies whole segments,
not samples:

* **Legs.** Each straight leg between consecutive mission positions keeps ``m``.
* **Turn regions.** At a waypoint ``P`` between legs from ``P0`` and to ``P1``, the autopilot
  switches legs anywhere inside the acceptance radius and then heads for the next leg. With
  ``A = P + R (P0 - P) / |P0 - P|`` (where it enters the acceptance radius on the incoming leg)
  and ``B = P + R (P1 - P) / |P1 - P|`` (where it has joined the outgoing leg at the latest),
  every such turn that does not swing outwards stays in the triangle ``A P B``; the straight cut
  ``A -> B`` is its extreme. The whole filled triangle is certified (:func:`certify_triangle`):
  it is cut into ``k**2`` congruent triangles, the ``3 k`` cutting lines are certified to keep
  ``m + r / k`` (``r``: the triangle's inradius, ``r / k <= 1 cm``), and every point of a small
  triangle is within its inradius ``r / k`` of its edges, so the whole region keeps ``m``; an
  obstacle point inside the triangle, clear of all three sides, is caught. Outward swings are
  what the tracking allowance covers.
* **Leg lengths.** No leg is shorter than R, and a leg with a turn at both ends is at least 2 R
  long, so that ``A`` and ``B`` lie on the legs and neighbouring turn regions do not overlap.
* **The ground.** Waypoints are at least ``min_height`` (default ``m``) above the bounds' floor;
  legs and turns between points above a plane stay above it. A ground or terrain among the
  obstacles (:mod:`uav_global_planner.core.map.ground`: ``ground: floor``, a DEM, and the AGL band
  above it) is certified like every obstacle, so every leg and turn keeps ``m`` from the
  terrain and stays inside ``[min_agl, max_agl]`` above it; only the take-off climb and a
  landing descent, straight up and down through the ground's margin, are certified against
  the other obstacles alone.
* **Take-off.** When the start is on the ground (within ``ground_tolerance`` of the floor) the
  mission begins with ``NAV_TAKEOFF``: a vertical climb at the start, certified like a leg, to
  the highest clear height up to ``takeoff_height`` (lower ones are tried when the first turn
  fails under an overhang); the take-off point is the first turn, the climb its incoming leg.
  The start is then home, the reference of every altitude. From a start in the air the mission
  begins with a waypoint at the start, and home is the ground below it (the terrain's height
  there when the obstacles hold one, else the bounds' floor).
* **Altitudes.** Every position item is written in ``MAV_FRAME_GLOBAL_RELATIVE_ALT``: metres
  above home, as QGroundControl, PX4 and ArduPilot fly missions without anything else. Over
  terrain this is still the frame to use: the terrain frame (``MAV_FRAME_GLOBAL_TERRAIN_ALT``)
  needs terrain data on the autopilot and makes it follow its own terrain model between
  waypoints, not the straight legs certified here against the DEM; with altitudes relative to
  home, every leg flown is the certified segment.
* **The end.** ``loiter``: the vehicle holds at the goal (``NAV_LOITER_UNLIM``). ``land``: a
  vertical descent from the goal to the floor (``NAV_LAND``), certified, the goal being a turn.
  ``rtl``: ``NAV_RETURN_TO_LAUNCH`` as PX4 and ArduPilot fly it: climb at the goal to
  ``max(goal, home + rtl_altitude)``, straight back above home, descend to home; all three legs
  and their turns are certified, so ``rtl_altitude`` must equal the autopilot's
  (``RTL_RETURN_ALT`` on PX4, ``RTL_ALT`` on ArduPilot) and no rally points are written.
* **Rounding.** Files store latitude and longitude to 1e-7 deg (the MAVLink integer resolution,
  about 1 cm) and altitudes to 1 mm, which moves a stored point by at most 8 mm and a turn
  triangle's corners by at most 16 mm. The search certifies ``m`` plus a 2 cm slack, and the
  final certificate is computed again, at ``m``, on the positions converted back from the
  rounded file values: the reported clearance is the clearance of what is written.

Modules
-------
=================  ==========================================================================
``build``          :func:`build_mission`, :func:`mission_from_plan`: a plan to certified items
``waypoints``      the waypoint search over the plan's candidate points
``certify``        turn triangles and the filled-triangle certificate (:func:`certify_triangle`)
``ends``           the take-off climb and the end actions (``loiter``, ``land``, ``rtl``)
``fences``         the 2D autopilot geofence (:func:`fences_of_airspace`), in WGS84
``stored``         rounding to the stored decimals, and stored positions read back
``model``          MAVLink numbers, :class:`MissionItem`, :class:`GeoFence`, :class:`Mission`
``settings``       :class:`MissionSettings`
``qgc_plan``       the QGroundControl ``.plan`` file (:func:`plan_document`, :func:`plan_text`)
``wpl``            the ``QGC WPL 110`` file (:func:`wpl_text`)
``files``          the format of a path, the text in a format, writing the file
=================  ==========================================================================

Every public name is importable from this package.
"""

from uav_global_planner.core.mission.build import build_mission, mission_from_plan
from uav_global_planner.core.mission.certify import (certify_triangle, TURN_CELL_INRADIUS,
                                                     turn_triangle)
from uav_global_planner.core.mission.fences import fences_of_airspace
from uav_global_planner.core.mission.files import (format_from_path, FORMATS, mission_text,
                                                   write_mission)
from uav_global_planner.core.mission.model import (FenceCircle, FencePolygon, GeoFence,
                                                   MAV_AUTOPILOT, MAV_CMD_DO_CHANGE_SPEED,
                                                   MAV_CMD_NAV_LAND, MAV_CMD_NAV_LOITER_UNLIM,
                                                   MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                                   MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_WAYPOINT,
                                                   MAV_FRAME_GLOBAL,
                                                   MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                                   MAV_FRAME_MISSION, MAV_TYPE_QUADROTOR,
                                                   Mission, MissionItem, POSITION_COMMANDS,
                                                   SPEED_TYPE_CLIMB, SPEED_TYPE_DESCENT,
                                                   SPEED_TYPE_GROUND,
                                                   UncertifiableMissionError)
from uav_global_planner.core.mission.qgc_plan import plan_document, plan_text
from uav_global_planner.core.mission.settings import END_ACTIONS, FIRMWARES, MissionSettings
from uav_global_planner.core.mission.stored import (ALTITUDE_DECIMALS, LATLON_DECIMALS,
                                                    PARAM_DECIMALS, ROUNDING_SLACK)
from uav_global_planner.core.mission.wpl import wpl_text

__all__ = [
    'ALTITUDE_DECIMALS', 'build_mission', 'certify_triangle', 'END_ACTIONS', 'FenceCircle',
    'FencePolygon', 'fences_of_airspace', 'FIRMWARES', 'format_from_path', 'FORMATS',
    'GeoFence', 'LATLON_DECIMALS', 'MAV_AUTOPILOT', 'MAV_CMD_DO_CHANGE_SPEED',
    'MAV_CMD_NAV_LAND', 'MAV_CMD_NAV_LOITER_UNLIM', 'MAV_CMD_NAV_RETURN_TO_LAUNCH',
    'MAV_CMD_NAV_TAKEOFF', 'MAV_CMD_NAV_WAYPOINT', 'MAV_FRAME_GLOBAL',
    'MAV_FRAME_GLOBAL_RELATIVE_ALT', 'MAV_FRAME_MISSION', 'MAV_TYPE_QUADROTOR', 'Mission',
    'mission_from_plan', 'mission_text', 'MissionItem', 'MissionSettings', 'PARAM_DECIMALS',
    'plan_document', 'plan_text', 'POSITION_COMMANDS', 'ROUNDING_SLACK', 'SPEED_TYPE_CLIMB',
    'SPEED_TYPE_DESCENT', 'SPEED_TYPE_GROUND', 'TURN_CELL_INRADIUS', 'turn_triangle',
    'UncertifiableMissionError', 'wpl_text', 'write_mission',
]
