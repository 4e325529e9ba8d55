"""The simulated vehicle's own frame conversion, offboard logic and MAVLink peer (no ROS, ~6 s).

The conversion is checked against the conventions' definitions (REP 103 for ENU/FLU, PX4's
user guide "ROS 2 User Guide, ROS 2 / PX4 frame conventions" for NED/FRD) and against the
follower's independent module, so that the closed loop compares two implementations.
"""

import math
import socket
import threading
import time

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2
import pytest

from uav_global_planner.core import frames
from uav_global_planner_tools.px4_sim import ned
from uav_global_planner_tools.px4_sim.mavlink_vehicle import MavlinkVehicle
from uav_global_planner_tools.px4_sim.vehicle import (NAV_STATE_OFFBOARD, run_realtime,
                                                      SimulatedVehicle)

NAN3 = [math.nan] * 3


def test_positions_and_headings_as_px4_defines_them():
    # 1 m east, 2 m north, 3 m up is north 2, east 1, down -3.
    assert ned.vector_enu_to_ned([1.0, 2.0, 3.0]).tolist() == [2.0, 1.0, -3.0]
    assert ned.vector_ned_to_enu([2.0, 1.0, -3.0]).tolist() == [1.0, 2.0, 3.0]
    # Facing north: ENU yaw 90 deg, NED yaw 0; facing east: ENU 0, NED 90 deg.
    assert ned.heading_enu_to_ned(math.pi / 2) == pytest.approx(0.0, abs=1e-12)
    assert ned.heading_enu_to_ned(0.0) == pytest.approx(math.pi / 2)
    assert ned.heading_ned_to_enu(ned.heading_enu_to_ned(0.7)) == pytest.approx(0.7)
    assert math.isnan(ned.heading_enu_to_ned(math.nan))
    # A climb at 1 m/s is -1 m/s down; a left turn (yaw rate up) is a negative rate about down.
    assert ned.vector_enu_to_ned([0.0, 0.0, 1.0])[2] == -1.0
    assert ned.heading_rate_ned_to_enu(-0.5) == 0.5


def test_attitude_of_a_level_body_facing_north():
    # ENU yaw 90 deg (facing north), level: in NED/FRD the body is the NED frame itself.
    q_enu = [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    assert np.allclose(ned.attitude_enu_flu_to_ned_frd(q_enu), [1.0, 0.0, 0.0, 0.0])
    # Facing east: a 90 deg turn about down.
    east = ned.attitude_enu_flu_to_ned_frd([0.0, 0.0, 0.0, 1.0])
    assert np.allclose(east, [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])


@pytest.mark.parametrize('seed', range(5))
def test_agrees_with_the_followers_conversion(seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=3)
    assert np.allclose(ned.vector_enu_to_ned(v), frames.enu_to_ned(v))
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    ours = ned.attitude_enu_flu_to_ned_frd(q)
    theirs = np.asarray(frames.quaternion_enu_flu_to_ned_frd(q), dtype=float)
    assert min(np.linalg.norm(ours - theirs), np.linalg.norm(ours + theirs)) < 1e-9
    yaw = rng.uniform(-math.pi, math.pi)
    assert math.remainder(ned.heading_enu_to_ned(yaw) - frames.yaw_enu_to_ned(yaw),
                          2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def _fly(sim: SimulatedVehicle, seconds: float, t0: float, setpoint=None,
         heartbeat: bool = True) -> float:
    t = t0
    for _ in range(int(round(seconds / sim.dt))):
        if heartbeat:
            sim.receive_heartbeat(t)
        if setpoint is not None:
            sim.receive_setpoint(t, ned.vector_enu_to_ned(setpoint), NAN3, NAN3, NAN3,
                                 math.nan, math.nan)
        sim.step(t)
        t += sim.dt
    return t


def test_flies_setpoints_in_offboard_and_holds_when_the_heartbeat_stops():
    pytest.importorskip('rotorpy')
    sim = SimulatedVehicle([0.0, 0.0, 2.0], rate_hz=125.0)
    t = _fly(sim, 0.3, 0.0)           # heartbeat without a setpoint: not offboard
    assert sim.nav_state != NAV_STATE_OFFBOARD
    t = _fly(sim, 4.0, t, setpoint=[2.0, 1.0, 3.0])
    assert sim.in_offboard
    assert np.linalg.norm(sim.state['x'] - [2.0, 1.0, 3.0]) < 0.1
    odometry = sim.odometry_ned()
    assert np.allclose(odometry['position'], [1.0, 2.0, -3.0], atol=0.1)
    # The heartbeat stops: after 0.5 s the failsafe holds where the vehicle is, and a setpoint
    # that comes without a heartbeat is not flown.
    t = _fly(sim, 0.6, t, heartbeat=False)
    assert not sim.in_offboard
    assert 'heartbeat lost' in sim.events[-1]
    t = _fly(sim, 2.0, t, setpoint=[10.0, 1.0, 3.0], heartbeat=False)
    assert np.linalg.norm(sim.state['x'] - [2.0, 1.0, 3.0]) < 0.1, 'flew without a heartbeat'


def test_offboard_request_needs_the_heartbeat():
    pytest.importorskip('rotorpy')
    sim = SimulatedVehicle([0.0, 0.0, 2.0], auto_offboard=False)
    assert not sim.request_offboard(0.0)
    sim.receive_heartbeat(0.0)
    sim.receive_setpoint(0.0, [0.0, 0.0, -2.0], NAN3, NAN3, NAN3, math.nan, math.nan)
    assert sim.request_offboard(0.1)
    with pytest.raises(ValueError, match='rate'):
        SimulatedVehicle([0.0, 0.0, 2.0], rate_hz=0.0)


def test_mavlink_peer_answers_with_its_state_and_flies_local_ned_targets():
    pytest.importorskip('rotorpy')
    sim = SimulatedVehicle([1.0, 2.0, 3.0], rate_hz=125.0)
    peer = MavlinkVehicle(sim, ('127.0.0.1', 0), telemetry_rate_hz=50.0)
    stop = threading.Event()
    physics = threading.Thread(target=run_realtime, args=(sim.dt, peer.step, stop.is_set))
    physics.start()
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(0.05)
    received = {}
    try:
        def target(frame: int):
            # 1 m north of the start (ENU y + 1), yaw ignored.
            return mav.set_position_target_local_ned_encode(
                0, 1, 1, frame, mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE,
                3.0, 1.0, -3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        sock.sendto(target(mavlink2.MAV_FRAME_BODY_NED).pack(mav), peer.address)
        for _ in range(60):                     # 3 s at 20 Hz
            sock.sendto(target(mavlink2.MAV_FRAME_LOCAL_NED).pack(mav), peer.address)
            until = time.monotonic() + 0.05
            while time.monotonic() < until:
                try:
                    data, _ = sock.recvfrom(65535)
                except socket.timeout:
                    break
                for msg in mav.parse_buffer(data) or []:
                    received[msg.get_type()] = msg
    finally:
        stop.set()
        physics.join()
        peer.close()
        sock.close()
    assert peer.ignored_frames == 1
    assert received['HEARTBEAT'].autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
    odometry = received['ODOMETRY']
    assert (odometry.frame_id, odometry.child_frame_id) == (mavlink2.MAV_FRAME_LOCAL_NED,
                                                            mavlink2.MAV_FRAME_BODY_FRD)
    local = received['LOCAL_POSITION_NED']
    assert sim.in_offboard
    # Flying from north 2 towards north 3 (ENU y), east 1, down -3.
    assert 2.0 < local.x <= 3.2 and abs(local.y - 1.0) < 0.1 and abs(local.z + 3.0) < 0.1
