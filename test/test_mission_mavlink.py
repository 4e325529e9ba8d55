"""Exported missions read by real MAVLink software: pymavlink and MAVSDK (C++ core, Python 4.x).

* pymavlink's ``mavwp.MAVWPLoader`` (MAVProxy's loader) reads the ``QGC WPL 110`` file.
* MAVSDK's ``MissionRaw.import_qgroundcontrol_mission`` reads the ``.plan`` file, offline: a
  ``raw://`` connection fed one HEARTBEAT (packed by pymavlink) gives it a PX4 or an ArduPilot
  autopilot, which decides how it imports (ArduPilot gets the planned home as item 0).
* A mission upload and download against MAVSDK's ``MissionRawServer`` over UDP on 127.0.0.1, in
  a child process with a timeout (every MAVSDK wait in it is bounded as well).
"""

import json
import math
import socket
import subprocess
import sys
import textwrap

from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.mission_raw import MissionRaw
import numpy as np
from pymavlink import mavwp
from pymavlink.dialects.v20 import common as mavlink2
import pytest

from uav_global_planner.core.io.geodesy import GeodeticOrigin
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.mission import (build_mission, FenceCircle, FencePolygon,
                                             MissionSettings, plan_text, wpl_text)
from uav_global_planner.core.planner import Planner

ORIGIN = GeodeticOrigin(-35.363261, 149.165230, 584.0)     # southern and eastern hemisphere
MAV_AUTOPILOT_PX4 = 12
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_FRAME_GLOBAL_INT = 5
MAV_MISSION_TYPE_FENCE = 1
MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001
MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION = 5004
FENCE_POLYGON = [[-9.5, -9.5], [9.5, -9.5], [9.5, 9.5], [-9.5, 9.5]]
FENCE_CIRCLE = ([-6.0, 6.0], 1.5)


@pytest.fixture(scope='module')
def plan_result():
    scene = load_scene(find_scene('paper_high'))
    planner = Planner(scene.config.with_changes(max_planning_time=0.0), scene.obstacles)
    result = planner.plan(scene.start, scene.goal)
    assert result.ok, result.message
    return scene, result


def mission_for(plan_result, firmware, end='land'):
    scene, result = plan_result
    return build_mission(
        result.smoothed_path, scene.obstacles, scene.config, ORIGIN,
        MissionSettings(firmware=firmware, end=end), raw_path=result.path,
        fence_polygons=[FencePolygon(FENCE_POLYGON)],
        fence_circles=[FenceCircle(FENCE_CIRCLE[0], FENCE_CIRCLE[1], inclusion=False)])


def same_float(a, b, tol):
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= tol


# --------------------------------------------------------------------------------------------
# pymavlink
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('firmware', ['ardupilot', 'px4'])
def test_pymavlink_loads_every_field_of_the_wpl_file(plan_result, firmware, tmp_path):
    mission = mission_for(plan_result, firmware)
    file = tmp_path / 'mission.waypoints'
    file.write_text(wpl_text(mission))
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(file)) == len(mission.items) + 1
    home = loader.wp(0)
    assert (home.seq, home.current, home.frame, home.command) == (0, 1, 0, 16)
    assert [home.x, home.y, home.z] == pytest.approx(list(mission.home), abs=1e-6)
    for seq, item in enumerate(mission.items, start=1):
        wp = loader.wp(seq)
        assert (wp.seq, wp.current, wp.frame, wp.command, wp.autocontinue) == (
            seq, 0, item.frame, item.command, 1)
        loaded = [wp.param1, wp.param2, wp.param3, wp.param4, wp.x, wp.y, wp.z]
        assert all(same_float(a, b, 1e-6) for a, b in zip(loaded, item.params)), (
            seq, loaded, item.params)


# --------------------------------------------------------------------------------------------
# MAVSDK: offline import of the .plan
# --------------------------------------------------------------------------------------------

def heartbeat(autopilot):
    """One HEARTBEAT of a quadrotor autopilot (system 1, component 1), packed by pymavlink."""
    class Sink:
        def write(self, data):
            pass
    link = mavlink2.MAVLink(Sink(), srcSystem=1, srcComponent=1)
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR, autopilot, 0, 0, mavlink2.MAV_STATE_STANDBY, 3).pack(link)


def import_plan(path, autopilot):
    """MAVSDK's import of a .plan file, as the given autopilot would get it."""
    with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
        sdk.add_any_connection('raw://')
        # Nothing is listening on the raw link: drop what MAVSDK sends.
        sdk.subscribe_raw_bytes_to_be_sent(lambda data: None)
        sdk.pass_received_raw_bytes(heartbeat(autopilot))
        system = sdk.first_autopilot(5.0)
        assert system is not None, 'MAVSDK did not take the heartbeat'
        return MissionRaw(system).import_qgroundcontrol_mission(str(path))


def assert_items_equal(imported, mission):
    assert len(imported) == len(mission.items)
    for seq, (got, item) in enumerate(zip(imported, mission.items)):
        assert (got.seq, got.command, got.frame, got.autocontinue) == (
            seq, item.command, item.frame, 1)
        assert got.current == (1 if seq == 0 else 0)
        params = [got.param1, got.param2, got.param3, got.param4]
        # float32 in MAVLink: 1e-6 relative is its resolution.
        assert all(same_float(a, b, 1e-6 * max(1.0, abs(b))) for a, b in
                   zip(params, item.params[:4])), (seq, params, item.params)
        if item.frame == 2:     # MAV_FRAME_MISSION: no position
            assert (got.x, got.y) == (0, 0)
            continue
        assert abs(got.x * 1e-7 - item.params[4]) <= 1e-7
        assert abs(got.y * 1e-7 - item.params[5]) <= 1e-7
        assert got.z == pytest.approx(item.params[6], abs=1e-4)


def assert_fence_equal(fence_items, mission):
    polygon, inclusion = mission.fence.polygons[0]
    center, radius, circle_inclusion = mission.fence.circles[0]
    assert inclusion and not circle_inclusion
    assert len(fence_items) == len(polygon) + 1
    for got, (lat, lon) in zip(fence_items, polygon):
        assert got.command == MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
        assert got.mission_type == MAV_MISSION_TYPE_FENCE
        assert got.param1 == len(polygon)
        assert abs(got.x * 1e-7 - lat) <= 1e-7 and abs(got.y * 1e-7 - lon) <= 1e-7
    circle = fence_items[-1]
    assert circle.command == MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
    assert circle.param1 == pytest.approx(radius)
    assert abs(circle.x * 1e-7 - center[0]) <= 1e-7 and abs(circle.y * 1e-7 - center[1]) <= 1e-7


def test_mavsdk_imports_the_plan_for_px4(plan_result, tmp_path):
    mission = mission_for(plan_result, 'px4')
    file = tmp_path / 'px4.plan'
    file.write_text(plan_text(mission))
    data = import_plan(file, MAV_AUTOPILOT_PX4)
    assert_items_equal(data.mission_items, mission)
    assert_fence_equal(data.geofence_items, mission)
    assert data.rally_items == []


def test_mavsdk_imports_the_plan_for_ardupilot_with_home_first(plan_result, tmp_path):
    mission = mission_for(plan_result, 'ardupilot')
    file = tmp_path / 'ardupilot.plan'
    file.write_text(plan_text(mission))
    data = import_plan(file, MAV_AUTOPILOT_ARDUPILOTMEGA)
    home, items = data.mission_items[0], data.mission_items[1:]
    assert (home.seq, home.frame, home.command) == (0, MAV_FRAME_GLOBAL_INT, 16)
    assert abs(home.x * 1e-7 - mission.home[0]) <= 1e-7
    assert abs(home.y * 1e-7 - mission.home[1]) <= 1e-7
    assert home.z == pytest.approx(mission.home[2], abs=1e-3)
    for item in items:
        item.seq -= 1
    assert_items_equal(items, mission)
    assert_fence_equal(data.geofence_items, mission)


def test_mavsdk_refuses_a_plan_without_its_version_fields(plan_result, tmp_path):
    # The check can fail: the same document with mission.version changed is refused.
    document = json.loads(plan_text(mission_for(plan_result, 'px4')))
    document['mission']['version'] = 3
    file = tmp_path / 'bad.plan'
    file.write_text(json.dumps(document))
    with pytest.raises(Exception, match='FAILED_TO_PARSE_QGC_PLAN'):
        import_plan(file, MAV_AUTOPILOT_PX4)


# --------------------------------------------------------------------------------------------
# MAVSDK: upload and download against MissionRawServer on the loopback interface
# --------------------------------------------------------------------------------------------

ROUND_TRIP = textwrap.dedent("""
    import json, sys, threading
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionRaw
    from mavsdk.plugins.mission_raw_server import MissionRawServer

    plan_file, port = sys.argv[1], int(sys.argv[2])
    fields = ('seq', 'frame', 'command', 'current', 'autocontinue', 'param1', 'param2',
              'param3', 'param4', 'x', 'y', 'z', 'mission_type')

    def plain(items):
        return [{k: getattr(i, k) for k in fields} for i in items]

    vehicle = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
    vehicle.add_any_connection(f'udpin://127.0.0.1:{port}')
    server = MissionRawServer(vehicle.server_component(0))
    received, arrived = {}, threading.Event()

    def on_mission(result, plan, user_data):
        received['result'] = int(result)
        received['items'] = plain(plan.mission_items)
        arrived.set()

    server.subscribe_incoming_mission(on_mission)
    station = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    station.add_any_connection(f'udpout://127.0.0.1:{port}')
    system = station.first_autopilot(10.0)
    if system is None:
        sys.exit('no autopilot heartbeat within 10 s')
    mission_raw = MissionRaw(system)
    items = mission_raw.import_qgroundcontrol_mission(plan_file).mission_items
    mission_raw.upload_mission(items)
    if not arrived.wait(10.0):
        sys.exit('the server got no mission within 10 s')
    downloaded = mission_raw.download_mission()
    print(json.dumps({'uploaded': plain(items), 'received': received['items'],
                      'server_result': received['result'], 'downloaded': plain(downloaded)}))
    station.destroy()
    vehicle.destroy()
""")


def free_udp_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def equal_items(a, b):
    return all(a[k] == b[k] or (isinstance(a[k], float) and math.isnan(a[k])
                                and math.isnan(b[k])) for k in a)


def test_mission_round_trip_through_mavsdk_mission_raw_server(plan_result, tmp_path):
    mission = mission_for(plan_result, 'px4', end='loiter')
    file = tmp_path / 'upload.plan'
    file.write_text(plan_text(mission))
    run = subprocess.run([sys.executable, '-c', ROUND_TRIP, str(file), str(free_udp_port())],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert report['server_result'] == 1                         # SUCCESS
    uploaded, received, downloaded = (report[k] for k in ('uploaded', 'received', 'downloaded'))
    assert len(uploaded) == len(mission.items)
    assert all(equal_items(a, b) for a, b in zip(uploaded, received)), (uploaded, received)
    assert all(equal_items(a, b) for a, b in zip(uploaded, downloaded)), (uploaded, downloaded)
    assert len(received) == len(downloaded) == len(uploaded)
    # And what went over the link is the file's mission.
    for got, item in zip(downloaded, mission.items):
        assert (got['command'], got['frame']) == (item.command, item.frame)
        if item.frame != 2:
            assert abs(got['x'] * 1e-7 - item.params[4]) <= 1e-7
            assert abs(got['y'] * 1e-7 - item.params[5]) <= 1e-7
            assert got['z'] == pytest.approx(item.params[6], abs=1e-4)
    positions = np.array([[g['x'], g['y']] for g in downloaded if g['frame'] != 2])
    assert len(positions) == mission.waypoint_count
