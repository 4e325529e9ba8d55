"""Closed loop in real processes: planner -> setpoint follower -> simulated vehicle -> back.

For each transport (PX4 over ``px4_msgs`` topics, MAVLink over UDP on loopback), four processes
in a ROS domain of their own: ``scene_publisher`` (town400's 400 buildings), ``planner_node``,
``setpoint_follower`` and the simulated vehicle (RotorPy's multirotor with PX4 SIH's parameters,
flown by ``SE3Control`` from the NED setpoints its own conversion turns back into ENU,
real time). The goal is 27 m down town400's streets; the planner starts from the odometry the
follower feeds back. Once the vehicle has flown 6 m, a 1 m box lands on the route 10 m ahead:
the planner withdraws the plan, the follower holds, the vehicle receives the hold, and then the
replacement plan is flown to the goal. The body clearance is measured on the vehicle's true
track (every physics step) against the buildings and the box. About 45 s per transport.

:mod:`uav_global_planner_tools.px4_sim.closed_loop` runs the flight; benchmarks/
bench_px4_closed_loop.py prints its figures (latencies, time to goal).
"""

import math
import re

import numpy as np
import pytest

from ros_harness import unique_domain_id
from uav_global_planner_tools.px4_sim.closed_loop import (ClosedLoopReport, ClosedLoopSettings,
                                                          fly_closed_loop)

pytest.importorskip('rotorpy')   # requirements.txt installs it; this only names it
pytest.importorskip('px4_msgs')  # scripts/build_interfaces.sh builds it into the venv


def _explain(report: ClosedLoopReport) -> str:
    tails = '\n'.join(f'--- {name}\n' + '\n'.join(log.splitlines()[-15:])
                      for name, log in report.logs.items())
    return f'{report.summary()}\nnotes: {report.notes}\n{tails}'


def _check(report: ClosedLoopReport) -> None:
    why = _explain(report)
    print(report.summary())
    assert report.reached_goal, why
    # The planner planned from the vehicle's odometry, fed back by the follower.
    assert 'start from odom' in report.logs['planner'], why
    # The box: withdrawn at once, the vehicle received a hold setpoint, then the replacement.
    assert report.withdrawn and report.replaced, why
    assert 'plan in force withdrawn' in report.logs['planner'], why
    assert 'plan withdrawn' in report.logs['follower'], why
    assert math.isfinite(report.hold_latency_s) and report.hold_latency_s > 0.0, why
    track = report.track
    assert track is not None
    hold_seen = report.drop_time + report.hold_latency_s
    after_hold = track.between(hold_seen + 0.5)
    assert np.any(np.linalg.norm(after_hold.setpoint_velocities[:, :2], axis=1) > 0.5), (
        'the replacement plan was never flown\n' + why)
    # Still air: the body kept gamma from the buildings and from the box, all the way.
    assert report.min_body_clearance_m >= report.gamma, why
    # The vehicle flew the setpoints (offboard) to the end, and nobody armed or switched it.
    assert report.offboard_at_goal, why
    # At least PX4's odometry rate (100 Hz), measured over the flight.
    assert report.odometry_rate_hz >= 100.0, why


def test_px4_closed_loop_holds_for_the_box_and_reaches_the_goal(tmp_path):
    report = fly_closed_loop(ClosedLoopSettings(transport='px4'), tmp_path,
                             unique_domain_id())
    _check(report)
    summary = re.search(r'commands (\d+)', report.logs['vehicle'])
    assert summary is not None and summary.group(1) == '0', 'a vehicle command was sent'


def test_mavlink_closed_loop_holds_for_the_box_and_reaches_the_goal(tmp_path):
    report = fly_closed_loop(ClosedLoopSettings(transport='mavlink'), tmp_path,
                             unique_domain_id())
    _check(report)
    assert 'other frames 0' in report.logs['vehicle'], report.logs['vehicle']
