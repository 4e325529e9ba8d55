"""One closed-loop flight: planner -> setpoint follower -> simulated vehicle -> odometry back.

:func:`fly_closed_loop` runs, each in a process of its own and in a ROS domain of its own
(localhost discovery, temporary logs, as :mod:`uav_global_planner_tools.processes` starts every
node): ``scene_publisher`` (a shipped scene's obstacles), ``planner_node`` (the scene's
workspace, planning for the vehicle's radius plus a tracking margin), ``setpoint_follower``
(PX4 over ``px4_msgs``, or ``--mavlink udpout:``) and the simulated vehicle
(:mod:`.dds_vehicle` or :mod:`.mavlink_vehicle`, writing its track). This process sends the
goal, waits until the vehicle has flown part of the plan, drops a box on the route ahead of it
(a ``MarkerArray`` on ``obstacles``), and waits for the vehicle at the goal. The planner starts
from the vehicle's odometry as the follower feeds it back; nothing here touches the vehicle.

Figures (:class:`ClosedLoopReport`), from the vehicle's own track (its true positions, every
physics step): the flown body clearance (distance from the vehicle's centre to the scene's
obstacles and the box, minus the vehicle's radius; the ground is not an obstacle), the time
from the goal to the arrival, the hold latency seen by the vehicle (from the box's publication
to the first hold setpoint the vehicle receives: zero velocity, position held), the planner's
own withdrawal latency, and the vehicle's odometry rate.
"""

from dataclasses import dataclass, field
import math
from pathlib import Path
import socket
import sys
import tempfile
import threading
import time
from typing import Any, Dict, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path as PathMsg
import numpy as np
from visualization_msgs.msg import Marker, MarkerArray

from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode
from uav_global_planner.ros.names import NODE_NAME, READY_TEXT as PLANNER_READY
from uav_global_planner.ros.qos import (COMMAND_QOS, DIAGNOSTICS_QOS, LATCHED_QOS, OBSTACLES_QOS,
                                        SENSOR_QOS)
from uav_global_planner_tools.domains import choose_domain_id
from uav_global_planner_tools.flight.vehicles import px4_sih_quadx
from uav_global_planner_tools.processes import (find_config, localhost_discovery, NodeProcess,
                                                planner_command, ros_environment,
                                                scene_parameters, scene_publisher_command,
                                                wait_until)
from uav_global_planner_tools.px4_sim import dds_vehicle, mavlink_vehicle
from uav_global_planner_tools.px4_sim.track import (first_hold_setpoint, odometry_rate,
                                                    read_track, Track, TrackTail)

#: Module and ready line of the follower (read here, so this module does not import it).
FOLLOWER_MODULE = 'uav_global_planner.ros.follower_node'
FOLLOWER_READY = 'setpoint follower ready'

#: The default leg: 27 m of town400's streets, three passes within 0.6 m of buildings.
TOWN_START = (-81.8, -79.0, 2.0)
TOWN_GOAL = (-62.7, -60.9, 2.0)


@dataclass(frozen=True)
class ClosedLoopSettings:
    """What to fly.

    Attributes
    ----------
    transport : str
        ``'px4'`` (uXRCE-DDS topics) or ``'mavlink'`` (UDP on loopback).
    scene : str
        Shipped scene name or file.
    start, goal : tuple of 3 floats
        Map frame ENU [m]; the vehicle starts hovering at ``start``.
    tracking_margin : float
        Room the planner keeps for the vehicle's tracking error [m].
    box_edge : float
        Edge of the box dropped on the route [m]; 0 drops none.
    drop_after_m : float
        Distance flown along the plan before the box drops [m].
    box_ahead_m : float
        Distance along the plan from the vehicle to the box's centre [m].
    arrival_radius : float
        Distance to the goal that counts as arrived [m].
    timeout_s : float
        Longest wait for the arrival after the goal [s].
    rate_hz : float
        The vehicle's physics and odometry rate [Hz].
    """

    transport: str = 'px4'
    scene: str = 'town400'
    start: Tuple[float, float, float] = TOWN_START
    goal: Tuple[float, float, float] = TOWN_GOAL
    tracking_margin: float = 0.3
    box_edge: float = 1.0
    drop_after_m: float = 6.0
    box_ahead_m: float = 10.0
    arrival_radius: float = 0.5
    timeout_s: float = 120.0
    rate_hz: float = 125.0


@dataclass(eq=False)
class ClosedLoopReport:
    """What one closed-loop flight did (ENU map frame; times [s], distances [m])."""

    settings: ClosedLoopSettings
    gamma: float
    vehicle_radius: float
    reached_goal: bool = False
    time_to_goal_s: float = math.nan
    min_body_clearance_m: float = math.nan
    min_body_clearance_point: Optional[np.ndarray] = None
    box_center: Optional[np.ndarray] = None
    withdrawn: bool = False
    replaced: bool = False
    withdrawal_latency_s: float = math.nan
    hold_latency_s: float = math.nan
    odometry_rate_hz: float = math.nan
    offboard_at_goal: bool = False
    goal_time: float = math.nan
    drop_time: float = math.nan
    track: Optional[Track] = None
    logs: Dict[str, str] = field(default_factory=dict)
    phases: Dict[str, float] = field(default_factory=dict)
    notes: List[str] = field(default_factory=list)

    def summary(self) -> str:
        """One line of figures."""
        return (f'{self.settings.transport}: reached {self.reached_goal} in '
                f'{self.time_to_goal_s:.1f} s, body clearance {self.min_body_clearance_m:.3f} m '
                f'(gamma {self.gamma:g}), withdrawn {self.withdrawn} after '
                f'{self.withdrawal_latency_s * 1e3:.0f} ms, hold at the vehicle after '
                f'{self.hold_latency_s * 1e3:.0f} ms, '
                f'replaced {self.replaced}, odometry {self.odometry_rate_hz:.1f} Hz; phases '
                + ', '.join(f'{name} {seconds:.1f} s' for name, seconds in self.phases.items()))


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(('127.0.0.1', 0))
        return int(sock.getsockname()[1])


def _arc_lengths(points: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


class _Client:
    """This process's node: goal and box out, plans and the planner's diagnostics in."""

    def __init__(self, domain: int) -> None:
        localhost_discovery()
        self.background = BackgroundNode('closed_loop_client', domain)
        node = self.background.node
        self._lock = threading.Lock()
        self.diagnostics: List[Tuple[float, Dict[str, str], int]] = []
        self.plans: List[PathMsg] = []
        node.create_subscription(DiagnosticArray, '/diagnostics', self._diag, DIAGNOSTICS_QOS)
        node.create_subscription(PathMsg, '/plan', self._plan, LATCHED_QOS)
        self.odometry_seen = threading.Event()
        node.create_subscription(Odometry, '/odom', lambda _: self.odometry_seen.set(),
                                 SENSOR_QOS)
        self.goal_pub = node.create_publisher(PoseStamped, '/goal_pose', COMMAND_QOS)
        self.obstacle_pub = node.create_publisher(MarkerArray, '/obstacles', OBSTACLES_QOS)
        self.prefix = f'/{NODE_NAME}: '

    def _diag(self, msg: DiagnosticArray) -> None:
        now = time.time()
        for status, values in conv.diagnostic_values(msg):
            if status.name.startswith(self.prefix):
                values = dict(values)
                values['_message'] = status.message
                with self._lock:
                    self.diagnostics.append((now, values, conv.time_to_ns(msg.header.stamp)))

    def _plan(self, msg: PathMsg) -> None:
        with self._lock:
            self.plans.append(msg)

    def events(self, event: str, after: float) -> List[Tuple[float, Dict[str, str], int]]:
        """Diagnostics of ``event`` stamped at or after the wall-clock time ``after`` [s] (the
        stamp, not the arrival: the node repeats its last status now and then)."""
        after_ns = int(after * 1e9)
        with self._lock:
            return [d for d in self.diagnostics if d[2] >= after_ns and d[1].get('event') == event]

    def newest_plan(self) -> Optional[PathMsg]:
        """The newest non-empty plan received."""
        with self._lock:
            return next((msg for msg in reversed(self.plans) if msg.poses), None)

    def plan_stamped(self, stamp_ns: int) -> Optional[PathMsg]:
        with self._lock:
            for msg in reversed(self.plans):
                if conv.time_to_ns(msg.header.stamp) == stamp_ns and msg.poses:
                    return msg
        return None

    def close(self) -> None:
        self.background.close()


def _box_marker(center: np.ndarray, edge: float, frame_id: str) -> MarkerArray:
    marker = Marker()
    marker.header.frame_id = frame_id
    marker.ns, marker.id, marker.type, marker.action = 'dropped_box', 0, Marker.CUBE, Marker.ADD
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = (
        float(c) for c in center)
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = float(edge)
    marker.color.a = 1.0
    array = MarkerArray()
    array.markers = [marker]
    return array


def _stop(process: NodeProcess) -> None:
    try:
        process.stop(timeout_s=10.0)
    except RuntimeError:
        process.kill()


def fly_closed_loop(settings: ClosedLoopSettings = ClosedLoopSettings(),
                    log_dir: Optional[Path] = None,
                    domain_id: Optional[int] = None) -> ClosedLoopReport:
    """Fly ``settings`` in closed loop; see the module docstring.

    ``log_dir`` receives every process's log and the vehicle's track (default: a new temporary
    folder); ``domain_id`` is the ROS domain of the flight (default: a free one that is not
    ``$ROS_DOMAIN_ID``).

    Returns the report even when the flight fails part-way (``reached_goal`` False, the reason
    in ``notes``); raises only for bad settings.
    """
    if settings.transport not in ('px4', 'mavlink'):
        raise ValueError(f"transport {settings.transport!r}: expected 'px4' or 'mavlink'")
    scene = load_scene(find_scene(settings.scene))
    vehicle = px4_sih_quadx()
    report = ClosedLoopReport(settings, gamma=float(scene.config.safety_margin),
                              vehicle_radius=vehicle.radius_m)
    log_dir = Path(log_dir or tempfile.mkdtemp(prefix='uav_px4_closed_loop_'))
    track_path = log_dir / 'track.jsonl'
    domain = choose_domain_id(domain_id)
    env = ros_environment(domain, log_dir / 'ros')
    params = dict(scene_parameters(scene), vehicle_radius=vehicle.radius_m,
                  tracking_margin=settings.tracking_margin)
    start = [f'{v:g}' for v in settings.start]
    children: Dict[str, NodeProcess] = {}
    follower_command = [sys.executable, '-m', FOLLOWER_MODULE]
    if settings.transport == 'px4':
        vehicle_command = [sys.executable, '-m', dds_vehicle.__name__, '--start', *start,
                           '--rate', f'{settings.rate_hz:g}', '--track', str(track_path)]
        vehicle_ready = dds_vehicle.READY_TEXT
    else:
        port = _free_udp_port()
        vehicle_command = [sys.executable, '-m', mavlink_vehicle.__name__, '--listen',
                           f'127.0.0.1:{port}', '--start', *start, '--rate',
                           f'{settings.rate_hz:g}', '--track', str(track_path)]
        vehicle_ready = mavlink_vehicle.READY_TEXT
        follower_command += ['--mavlink', f'udpout:127.0.0.1:{port}']
    follower_command += ['--ros-args', '--params-file', str(find_config())]
    for name in ('frame_id', 'bounds.min', 'bounds.max'):
        value = params[name]
        text = '[' + ', '.join(repr(float(v)) for v in value) + ']' if isinstance(
            value, list) else str(value)
        follower_command += ['-p', f'{name}:={text}']
    client = None
    launched = time.monotonic()
    try:
        children['planner'] = NodeProcess(planner_command(parameters=params,
                                                          params_file=find_config()),
                                          env, log_dir / 'planner.log')
        children['scene'] = NodeProcess(scene_publisher_command(
            str(find_scene(settings.scene)), options=('--no-start', '--no-goal')), env,
            log_dir / 'scene_publisher.log')
        children['vehicle'] = NodeProcess(vehicle_command, env, log_dir / 'vehicle.log')
        children['follower'] = NodeProcess(follower_command, env, log_dir / 'follower.log')
        client = _Client(domain)
        children['vehicle'].wait_for_output(vehicle_ready, 60.0)
        children['planner'].wait_for_output(PLANNER_READY, 120.0)
        children['follower'].wait_for_output(FOLLOWER_READY, 60.0)
        report.phases['start'] = time.monotonic() - launched
        _fly(settings, scene, client, track_path, report)
    except (TimeoutError, RuntimeError) as error:
        report.notes.append(str(error))
    finally:
        if client is not None:
            client.close()
        stopping = time.monotonic()
        threads = [threading.Thread(target=_stop, args=(process,))
                   for process in children.values()]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        report.logs = {name: process.output for name, process in children.items()}
        report.phases['stop'] = time.monotonic() - stopping
    if track_path.is_file():
        _measure(report, scene.obstacles, read_track(track_path))
    return report


def _fly(settings: ClosedLoopSettings, scene: Scene, client: _Client, track_path: Path,
         report: ClosedLoopReport) -> None:
    """Goal, drop, arrival; fills the report's timings."""
    goal = np.asarray(settings.goal, dtype=np.float64)
    # The planner starts from the vehicle: the goal goes out once the follower feeds odometry.
    wait_until(client.odometry_seen.is_set, 30.0, 'odometry from the follower on /odom')
    goal_sent = report.goal_time = time.time()
    here = np.asarray(settings.start, dtype=np.float64)

    def plan_from_here(sent: float) -> Optional[PathMsg]:
        # A plan answering the goal that starts at the vehicle (the planner may first answer
        # from its start parameter, before the odometry reaches it, then plan again from it).
        for _, values, stamp in client.events('plan', sent):
            msg = client.plan_stamped(stamp) if values.get('status') == 'ok' else None
            if msg is not None and np.linalg.norm(conv.path_to_points(msg)[0] - here) < 1.5:
                return msg
        return None

    # The goal, again each 2 s until a plan answers it (the map may still be on its way).
    plan = None
    deadline = time.monotonic() + 60.0
    while plan is None:
        sent = time.time()
        client.goal_pub.publish(conv.pose_stamped(goal.tolist(), scene.frame_id, 0))
        try:
            plan = wait_until(lambda: plan_from_here(sent), 2.0,
                              'a plan from the vehicle to the goal')
        except TimeoutError:
            if time.monotonic() > deadline:
                raise
    report.phases['first plan'] = time.time() - goal_sent
    points = conv.path_to_points(plan)
    arc = _arc_lengths(points)

    def follow_newest() -> None:
        nonlocal points, arc
        newest = client.newest_plan()
        if newest is not None:
            points = conv.path_to_points(newest)
            arc = _arc_lengths(points)

    tail = TrackTail(track_path)

    def flown() -> float:
        if not tail.update():
            return 0.0
        nearest = int(np.argmin(np.linalg.norm(points - tail.position, axis=1)))
        return float(arc[nearest])

    if settings.box_edge > 0.0:
        wait_until(lambda: flown() >= settings.drop_after_m, 60.0,
                   f'the vehicle {settings.drop_after_m:g} m along the plan', 0.1)
        follow_newest()          # the plan in force now (the planner may have replanned)
        along = min(flown() + settings.box_ahead_m, arc[-1] - 3.0)
        center = np.array([np.interp(along, arc, points[:, i]) for i in range(3)])
        report.box_center = center
        drop = report.drop_time = time.time()
        client.obstacle_pub.publish(_box_marker(center, settings.box_edge, scene.frame_id))
        report.notes.append(f'box dropped at {center.round(2).tolist()} ({along:.1f} m along)')
        withdrawn = wait_until(lambda: client.events('plan_withdrawn', drop), 10.0,
                               'the withdrawal of the plan in force')
        report.withdrawn = True
        report.withdrawal_latency_s = withdrawn[0][0] - drop
        replaced = wait_until(lambda: next((d for d in client.events('plan', drop)
                                            if d[1].get('status') == 'ok'), None), 30.0,
                              'the replacement plan')
        report.replaced = replaced is not None

    def arrived() -> bool:
        if not tail.update():
            return False
        assert tail.position is not None and tail.velocity is not None
        return bool(np.linalg.norm(tail.position - goal) <= settings.arrival_radius
                    and np.linalg.norm(tail.velocity) < 0.3)

    try:
        wait_until(arrived, settings.timeout_s, 'the vehicle at the goal', 0.1)
    except TimeoutError as error:
        where = None if tail.position is None else tail.position.round(2).tolist()
        raise TimeoutError(f'{error}; the vehicle was last at {where}') from None
    report.reached_goal = True
    report.time_to_goal_s = time.time() - goal_sent
    report.phases['flight'] = report.time_to_goal_s - report.phases['first plan']
    track = read_track(track_path)
    report.offboard_at_goal = bool(track.offboard[-1]) if len(track.offboard) else False


def _measure(report: ClosedLoopReport, scene_obstacles: ObstacleSet, track: Track) -> None:
    """Clearance, hold latency and odometry rate from the vehicle's track."""
    report.track = track
    items: List[Any] = list(scene_obstacles.items)
    if report.box_center is not None:
        half = report.settings.box_edge / 2.0
        items.append(Box(report.box_center - half, report.box_center + half))
    obstacles = ObstacleSet(items)
    flight = track.between(report.goal_time if math.isfinite(report.goal_time) else -np.inf)
    if len(flight.positions):
        body = np.asarray(obstacles.distance(flight.positions), dtype=np.float64)
        body -= report.vehicle_radius
        closest = int(np.argmin(body))
        report.min_body_clearance_m = float(body[closest])
        report.min_body_clearance_point = flight.positions[closest].copy()
        report.odometry_rate_hz = odometry_rate(flight)
    drop = report.drop_time
    if math.isfinite(drop):
        hold = first_hold_setpoint(track, drop)
        report.hold_latency_s = hold - drop
