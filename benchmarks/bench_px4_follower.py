"""Prints the setpoint follower's stream jitter under load and its withdrawal -> hold latency.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_px4_follower.py [--seconds 30]

Three processes on this machine, each in the benchmark's own ROS domain with localhost
discovery: ``planner_node`` (config/planner.yaml), ``setpoint_follower`` (PX4 transport, 50 Hz)
and this one, which plays the vehicle (``VehicleOdometry`` in NED at 100 Hz, at the last
setpoint and its velocity: perfect tracking) and loads the planner with a new
``obstacle_cloud`` of 20 000 points every 100 ms (10 Hz) while the vehicle flies a plan to a
goal. The planner runs with ``replan_on_obstacle_change: false``: each cloud is taken in and
the plan in force certified against it (the load), and the plan flown stays the planner's.
``--realtime-priority N`` starts the follower with ``realtime_priority: N`` (its setpoint
thread in SCHED_FIFO).

Figures:

- jitter, at the receiver: how much later than 20 ms after the one before each
  ``TrajectorySetpoint`` arrives here: p50, p99 and worst [ms] (target: p99 <= 5 ms late), and
  the ticks missed; the send -> arrival delay (DDS on loopback, and this process's own
  scheduling); and, at the sender, the follower's own tick lateness against its 50 Hz schedule
  over its last 500 ticks (``tick_late_*_ms`` of its /diagnostics);
- withdrawal -> hold: from just before an empty ``plan`` + ``trajectory`` are published (as the
  planner withdraws a plan) to the arrival of the first hold setpoint (zero velocity) [ms]
  (target: <= 20 ms), over repeated withdrawals of a plan being flown, under the same load.

Figures only: nothing here asserts.
"""

import argparse
import math
import sys
import threading
import time
from typing import Dict, List, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
import numpy as np
from px4_msgs.msg import TrajectorySetpoint, VehicleOdometry
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory

from uav_global_planner.core import frames
from uav_global_planner.core.result import PlanResult, Trajectory
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros import px4_names
from uav_global_planner.ros.background_node import BackgroundNode
from uav_global_planner.ros.follower_node import NODE_MODULE, READY_TEXT as FOLLOWER_READY
from uav_global_planner.ros.names import READY_TEXT as PLANNER_READY
from uav_global_planner.ros.qos import CLOUD_QOS, COMMAND_QOS, DIAGNOSTICS_QOS, LATCHED_QOS
from uav_global_planner_tools.domains import free_domain_id
from uav_global_planner_tools.processes import (find_config, localhost_discovery, NodeProcess,
                                                planner_command, ros_environment)

PERIOD_S = 0.02
CLOUD_POINTS = 20_000


class Bench:
    """The vehicle, the cloud load and the recorders, on one background node."""

    def __init__(self, domain: int) -> None:
        localhost_discovery()
        self.bg = BackgroundNode('bench_px4_follower', domain)
        node = self.bg.node
        self.lock = threading.Lock()
        self.arrivals: List[Tuple[float, int, np.ndarray, np.ndarray]] = []
        self.delays_ms: List[float] = []
        self.follower_status: Dict[str, str] = {}
        node.create_subscription(DiagnosticArray, '/diagnostics', self._diagnostics,
                                 DIAGNOSTICS_QOS)
        node.create_subscription(TrajectorySetpoint, px4_names.TRAJECTORY_SETPOINT,
                                 self._setpoint, px4_names.PX4_BRIDGE_READER_QOS)
        self.odometry = node.create_publisher(VehicleOdometry, px4_names.VEHICLE_ODOMETRY,
                                              px4_names.PX4_BRIDGE_WRITER_QOS)
        self.cloud = node.create_publisher(PointCloud2, 'obstacle_cloud', CLOUD_QOS)
        self.goal = node.create_publisher(PoseStamped, 'goal_pose', COMMAND_QOS)
        self.plan = node.create_publisher(Path, 'plan', LATCHED_QOS)
        self.trajectory = node.create_publisher(MultiDOFJointTrajectory, 'trajectory',
                                                LATCHED_QOS)
        self.vehicle_ned = frames.enu_to_ned([0.0, -5.0, 1.0])
        self.vehicle_velocity_ned = np.zeros(3)
        self.stop = threading.Event()
        self.threads = [threading.Thread(target=self._vehicle, daemon=True),
                        threading.Thread(target=self._clouds, daemon=True)]
        self.load = threading.Event()

    def _diagnostics(self, msg: DiagnosticArray) -> None:
        for status, values in conv.diagnostic_values(msg):
            if status.name.endswith(': setpoint follower') and 'tick_late_p99_ms' in values:
                with self.lock:
                    self.follower_status = values

    def _setpoint(self, msg: TrajectorySetpoint) -> None:
        now = time.monotonic()
        delay_ms = (time.time_ns() - int(msg.timestamp) * 1000) * 1e-6
        position = np.asarray(msg.position, dtype=np.float64)
        with self.lock:
            self.arrivals.append((now, int(msg.timestamp), position,
                                  np.asarray(msg.velocity, dtype=np.float64)))
            self.delays_ms.append(delay_ms)
            if np.all(np.isfinite(position)):
                self.vehicle_ned = position
                self.vehicle_velocity_ned = np.nan_to_num(self.arrivals[-1][3])

    def _vehicle(self) -> None:
        while not self.stop.is_set():
            msg = VehicleOdometry()
            msg.pose_frame = VehicleOdometry.POSE_FRAME_NED
            with self.lock:
                msg.position = self.vehicle_ned.astype(np.float32)
                msg.velocity = self.vehicle_velocity_ned.astype(np.float32)
            msg.q = np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32)
            msg.velocity_frame = VehicleOdometry.VELOCITY_FRAME_NED
            self.odometry.publish(msg)
            time.sleep(0.01)

    def _clouds(self) -> None:
        # Built ahead, so that this process spends its time receiving, not building clouds:
        # occupied points east of the route, a different cloud every time (cycled).
        rng = np.random.default_rng(1)
        clouds = [conv.points_to_cloud(
            rng.uniform([6.0, -9.0, 0.0], [9.5, 9.0, 14.0], size=(CLOUD_POINTS, 3)), 'map', 0)
            for _ in range(16)]
        count = 0
        next_time = time.monotonic()
        while not self.stop.is_set():
            if self.load.is_set():
                cloud = clouds[count % len(clouds)]
                cloud.header.stamp = self.bg.node.get_clock().now().to_msg()
                self.cloud.publish(cloud)
                count += 1
            next_time += 0.1
            time.sleep(max(0.0, next_time - time.monotonic()))

    def start(self) -> None:
        for thread in self.threads:
            thread.start()

    def close(self) -> None:
        self.stop.set()
        for thread in self.threads:
            thread.join(2.0)
        self.bg.close()


def line_plan(start: np.ndarray, velocity: np.ndarray, duration: float) -> PlanResult:
    times = np.arange(0.0, duration + 1e-9, 0.05)
    positions = start + times[:, None] * velocity
    trajectory = Trajectory(times=times, positions=positions,
                            velocities=np.tile(velocity, (len(times), 1)),
                            accelerations=np.zeros_like(positions), yaws=np.zeros(len(times)),
                            yaw_rates=np.zeros(len(times)))
    return PlanResult(status=PlanStatus.OK, message='', algorithm='bench', start=positions[0],
                      goal=positions[-1], path=positions[[0, -1]], trajectory=trajectory)


def lateness_ms(arrivals) -> Tuple[np.ndarray, int]:
    """How much later than 20 ms after the one before each setpoint arrives [ms] (0 when on
    time or early), and the ticks missed (the elapsed send time holds more ticks than came)."""
    times = np.array([a[0] for a in arrivals])
    stamps = np.array([a[1] for a in arrivals], dtype=np.float64) * 1e-6
    late = np.maximum(np.diff(times) - PERIOD_S, 0.0)
    missed = max(int(round((stamps[-1] - stamps[0]) / PERIOD_S)) + 1 - len(times), 0)
    return late * 1e3, missed


def stats(values: np.ndarray) -> str:
    return (f'p50 {np.percentile(values, 50):6.2f}  p99 {np.percentile(values, 99):6.2f}  '
            f'max {np.max(values):6.2f}')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=30.0, help='jitter window [s]')
    parser.add_argument('--withdrawals', type=int, default=20)
    parser.add_argument('--realtime-priority', type=int, default=0,
                        help='realtime_priority parameter of the follower (0: off)')
    parser.add_argument('--no-load', action='store_true', help='no clouds (a baseline)')
    parser.add_argument('--verbose', action='store_true', help='print the last lines of the nodes')
    args = parser.parse_args(argv)
    domain = free_domain_id()
    params = {'replan_on_obstacle_change': False, 'start': [0.0, -5.0, 1.0]}
    planner = NodeProcess(planner_command(None, params, find_config()), ros_environment(domain))
    follower = NodeProcess([sys.executable, '-m', NODE_MODULE, '--ros-args', '--params-file',
                            str(find_config()), '-p',
                            f'realtime_priority:={args.realtime_priority}'],
                           ros_environment(domain))
    bench = None
    try:
        planner.wait_for_output(PLANNER_READY, 300.0)
        follower.wait_for_output(FOLLOWER_READY, 120.0)
        bench = Bench(domain)
        bench.start()
        time.sleep(2.0)
        if args.no_load:
            bench.cloud.publish(conv.points_to_cloud(np.array([[9.0, 9.0, 9.0]]), 'map',
                                                     bench.bg.node.get_clock().now().nanoseconds))
        else:
            bench.load.set()
        time.sleep(1.5)                      # the first clouds are the planner's map
        goal = PoseStamped()
        goal.header.frame_id = 'map'
        goal.pose.position.x, goal.pose.position.y, goal.pose.position.z = 0.0, 8.0, 6.0
        goal.pose.orientation.w = 1.0
        bench.goal.publish(goal)
        time.sleep(1.0)
        with bench.lock:
            bench.arrivals.clear()
            bench.delays_ms.clear()
        time.sleep(args.seconds)
        with bench.lock:
            window = list(bench.arrivals)
            delays = np.array(bench.delays_ms)
            status = dict(bench.follower_status)
        late, missed = lateness_ms(window)
        travelled = np.linalg.norm(window[-1][2] - window[0][2])
        load = 'no load' if args.no_load else f'a 10 Hz cloud load ({CLOUD_POINTS} points)'
        print(f'setpoint stream under {load} on the planner, '
              f'{len(window)} setpoints in {args.seconds:.0f} s, setpoint moved {travelled:.1f} m')
        print(f'  arrival later than 20 ms after the previous [ms]: {stats(late)}  '
              f'(target p99 <= 5)  '
              f'missed ticks {missed}')
        print(f'  send -> arrival delay [ms]: {stats(delays)}')
        if status:
            print(f'  follower tick lateness (last 500 ticks) [ms]: '
                  f'p50 {float(status["tick_late_p50_ms"]):6.2f}  '
                  f'p99 {float(status["tick_late_p99_ms"]):6.2f}  '
                  f'max {float(status["tick_late_max_ms"]):6.2f}')
        latencies = []
        for k in range(args.withdrawals):
            with bench.lock:
                start = frames.ned_to_enu(bench.vehicle_ned)
            stamp = bench.bg.node.get_clock().now().nanoseconds
            result = line_plan(start, np.array([0.0, 0.0, 0.0]) + [0.0, 0.5, 0.0], 5.0)
            bench.plan.publish(conv.plan_to_path(result, 'map', stamp))
            bench.trajectory.publish(conv.plan_to_trajectory(result, 'map', stamp))
            time.sleep(0.6 + 0.013 * k)          # withdrawals spread over the tick phase
            with bench.lock:
                mark = len(bench.arrivals)
            stamp = bench.bg.node.get_clock().now().nanoseconds
            sent = time.monotonic()
            bench.plan.publish(conv.points_to_path(np.empty((0, 3)), 'map', stamp))
            bench.trajectory.publish(conv.empty_trajectory('map', stamp))
            deadline = sent + 1.0
            found = math.nan
            while time.monotonic() < deadline and math.isnan(found):
                with bench.lock:
                    for arrival in bench.arrivals[mark:]:
                        if np.allclose(arrival[3], 0.0):
                            found = (arrival[0] - sent) * 1e3
                            break
                time.sleep(0.002)
            latencies.append(found)
            time.sleep(0.3)
        values = np.array(latencies)
        ok = values[np.isfinite(values)]
        print(f'withdrawal (empty plan) -> hold setpoint, {len(ok)}/{len(values)} seen')
        if len(ok):
            print(f'  latency [ms]: {stats(ok)}  (target <= 20)')
    finally:
        if '--verbose' in sys.argv:
            print(planner.tail(30))
            print(follower.tail(30))
        if bench is not None:
            bench.close()
        for process in (follower, planner):
            try:
                process.stop()
            except Exception:  # noqa: BLE001 - clean-up of a benchmark
                process.kill()
    return 0


if __name__ == '__main__':
    sys.exit(main())
