"""The planner node: a thin rclpy layer around :class:`~uav_global_planner.core.planner.Planner`.

Topics (all relative, so namespaces work):

========================  ==============================  =======================================
name                      type                            notes
========================  ==============================  =======================================
``goal_pose`` (in)        geometry_msgs/PoseStamped       plan to it; latest goal wins
``obstacles`` (in)        visualization_msgs/MarkerArray  SPHERE/CUBE by (ns, id); transient
                                                          local, depth 100
``obstacle_cloud`` (in)   sensor_msgs/PointCloud2         occupied points, replaces the last
                                                          cloud; reliable (or best effort)
``odom`` (in)             nav_msgs/Odometry               start position (latest of odom and
``start_pose`` (in)       geometry_msgs/PoseStamped       start_pose; else the ``start``
                                                          parameter); odom's twist for replans
                                                          in flight
``plan`` (out)            nav_msgs/Path                   smoothed, time-stamped; transient local
``unsmoothed_plan`` (out) nav_msgs/Path                   grid nodes; transient local
``trajectory`` (out)      MultiDOFJointTrajectory         positions, velocities, accelerations
``planner_markers`` (out) visualization_msgs/MarkerArray  obstacles and gamma-inflated obstacles
``/diagnostics`` (out)    diagnostic_msgs/DiagnosticArray after every plan and every refused input
========================  ==============================  =======================================

Three threads share the work:

- the executor serves topics, parameters, timers and the Nav2 interfaces; map messages are
  taken as serialised bytes and only queued there (markers in order, clouds latest-wins);
- the map intake (:class:`~uav_global_planner.ros.node_intake.MapIntake`) deserialises, checks
  and indexes them, updates the inflated grid tile by tile
  (:class:`~uav_global_planner.core.map.live_map.LiveMapBuilder`, double-buffered, so a plan
  always runs on one consistent map), publishes the new map to the planning worker and
  re-checks the plan in force against it at once with the certified check (ahead of the vehicle
  first). A plan the new map makes collide is withdrawn on the spot (empty ``plan``,
  ``unsmoothed_plan`` and ``trajectory``, an ERROR ``plan_withdrawn`` on /diagnostics saying
  where it is blocked) and a replacement is planned;
- the planning worker (the only thread that touches the :class:`Planner`) takes a snapshot of
  the settings, map, start and goal when a plan begins; whatever arrives meanwhile is coalesced
  into at most one follow-up plan. A newer goal or changed settings cancel a running plan; a
  new map does not: the finished plan is checked against the newest map before it is published
  (``event: plan_discarded`` when it collides, and it is made again on that map).

A plan made while the vehicle flies the plan in force continues it: it starts from the state
the plan in force will have when the new plan is published (planning latency predicted) and is
stamped with that time, so that a follower switches without a jump
(:mod:`~uav_global_planner.ros.takeover`).

The diagnostics of a plan name the map it was computed on (``obstacles_version``, and
``obstacles_stamp``: the header stamp of the map message that last changed the obstacles), the
newest map it was checked against before publishing (``obstacles_checked_*``) and the state of
every map source (``map_sources``, ``map_refused``: a plan made while a source's newest message
was refused says so, at WARN).

The node is composed of parts, each a class constructed with the rclpy node (as tf2_ros's
listener takes the node) that creates its own subscriptions, publishers and timers through it,
owns its state and its lock (its docstring says what the lock guards) and offers the other
parts a small typed interface:

- :class:`~uav_global_planner.ros.node_plan_inputs.PlanningInputs`: what the next plan uses
  (settings, newest map, goal, start, replans owed, requests); the worker waits on its
  condition;
- :class:`~uav_global_planner.ros.node_diagnostics.NodeDiagnostics`: ``/diagnostics``;
- :class:`~uav_global_planner.ros.node_in_force.PlanInForce`: ``plan``, ``unsmoothed_plan``,
  ``trajectory`` and the one gate every plan passes (``release``);
- :class:`~uav_global_planner.ros.node_intake.MapIntake`: the map topics and the intake thread;
- :class:`~uav_global_planner.ros.node_worker.PlanningWorker`: the planner and its thread;
- :class:`~uav_global_planner.ros.node_inputs.CommandInputs`: ``goal_pose``, ``odom``,
  ``start_pose``;
- :class:`~uav_global_planner.ros.node_status.NodeStatus`: map status, markers, duplicates;
- :class:`~uav_global_planner.ros.node_reconfigure.NodeParameters`: the parameter callbacks.

Locks are taken in one order: the plan in force's release lock, then the planning inputs'
condition; nothing is taken while the intake's lock or the diagnostics publisher's lock is
held. This module
declares the parameters, builds the parts and wires them (:class:`PlannerNode`), and runs the
node (:func:`main`).
"""

import sys
from typing import Any, Callable, List, Mapping, Optional, Tuple, TypeVar

import numpy as np
from rclpy.node import Node

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.mapfiles import load_prior_map, MapPoints
from uav_global_planner.core.map.live_map import LiveMapBuilder
from uav_global_planner.core.map.unknown_space import unknown_from_map_files, UnknownSpace
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros.mission_service import MissionExportService
from uav_global_planner.ros.names import NODE_NAME, READY_TEXT
from uav_global_planner.ros.nav2_interfaces import PlannerInterfaces
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_in_force import ExportablePlan, PlanInForce, Release
from uav_global_planner.ros.node_inputs import CommandInputs
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_main import (  # noqa: F401 - importable from the node
    EXIT_BAD_SETTINGS, run_node)
from uav_global_planner.ros.node_plan_inputs import Job, PlanningInputs
from uav_global_planner.ros.node_reconfigure import NodeParameters
from uav_global_planner.ros.node_state import Snapshot
from uav_global_planner.ros.node_status import NodeStatus
from uav_global_planner.ros.node_worker import PlanningWorker
from uav_global_planner.ros.parameters import (  # noqa: F401 - importable from the node
    CLOUD_NON_FINITE_MODES, declare_parameters, MAP_SOURCES, NodeSettings, PARAMETER_SPECS,
    plain as _plain, settings_from_parameters, SPECS_BY_NAME, STARTUP_ONLY)
from uav_global_planner.ros.plan_writer import startup_plan_writer
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import Settlement, Takeover, TakeoverPredictor
from uav_global_planner.ros.terrain_source import describe_terrain

T = TypeVar('T')


class PlannerNode:
    """The planner node: its parameters, and the parts that do its work.

    Composition rather than a ``Node`` subclass: :attr:`node` is the rclpy node, each part
    is built with it. The attributes are the parts (and, read only after construction, the
    node, its logger and the map file read at start-up); the node holds no state of its own.
    It provides the parts' interface that the Nav2 interfaces and the mission export use
    (:class:`~uav_global_planner.ros.nav2_interfaces.PlanHost`).

    Parameters
    ----------
    node_name : str
    **node_options
        Passed to :class:`rclpy.node.Node` (for example ``namespace``, ``context``,
        ``parameter_overrides``).

    Raises
    ------
    InvalidInputError
        When the parameters given at start-up are invalid. A ``map_file`` that cannot be read,
        or cannot be right (no usable points, all outside the bounds, see
        :mod:`~uav_global_planner.core.io.mapfiles`), is refused instead: the node runs without it,
        reports why in the log and the map status, and refuses goals.
    """

    def __init__(self, node_name: str = NODE_NAME, **node_options: Any) -> None:
        self.node = Node(node_name, **node_options)
        node = self.node
        self._log = node.get_logger()
        # Latency estimate, newest odometry motion and takeover predictions (its own lock).
        takeover = TakeoverPredictor(lambda: node.get_clock().now().nanoseconds)
        # Checked once per process: CDR bytes only when rclpy reads them back right.
        plan_writer = startup_plan_writer(self._log)
        param_values = declare_parameters(node)
        # Validated before the map file is read: a typo elsewhere is reported first.
        first = settings_from_parameters(param_values)
        prior: Optional[MapPoints] = None
        # Why map_file was refused ('' when it was not); map_file is read once, at start-up.
        prior_refusal = ''
        # Space an OctoMap map_file never observed, within the bounds.
        unknown: Optional[UnknownSpace] = None
        try:
            prior = load_prior_map(
                first.map_file, first.map_downsample,
                bounds=(first.config.bounds_min, first.config.bounds_max),
                reach=first.config.safety_margin, resolution=first.config.resolution)
            if prior is not None:
                unknown = unknown_from_map_files([first.map_file.strip()],
                                                 first.config.bounds_min,
                                                 first.config.bounds_max)
        except InvalidInputError as error:
            prior = None
            prior_refusal = str(error)
            self._log.error(f'refused map_file: {error}; goals are refused until the node is '
                            'restarted with a map file that can be used (or none)')
        self._prior = prior
        map_margin_m = prior.margin_m if prior is not None else 0.0
        settings = settings_from_parameters(param_values, map_margin_m)
        planner = Planner(settings.config, unknown=unknown)
        # The prior map is indexed once (per grid) and joined to every map of the intake.
        builder = LiveMapBuilder(settings.config, None if prior is None else prior.points,
                                 first_version=0)

        self.inputs = PlanningInputs(settings, builder.update(), prior_refusal)
        self.diagnostics = NodeDiagnostics(node, self.inputs)
        self.in_force = PlanInForce(node, self.inputs, self.diagnostics, plan_writer, takeover)
        self.intake = MapIntake(node, self.inputs, self.in_force, self.diagnostics, builder,
                                prior_refusal, prior is not None)
        self.worker = PlanningWorker(
            node, self.inputs, self.in_force, self.intake, self.diagnostics, planner, takeover,
            first.map_file.strip() if unknown is not None else '',
            (tuple(first.config.bounds_min), tuple(first.config.bounds_max)))
        self.commands = CommandInputs(node, self.inputs, self.intake, self.diagnostics,
                                      takeover)
        self.status = NodeStatus(node, self.inputs, self.intake, self.diagnostics, prior)
        # Before the mission export declares geodetic_origin (declaring runs the callbacks).
        self.parameters = NodeParameters(node, param_values, map_margin_m, self.inputs,
                                         self.intake, self.in_force, takeover)
        self.nav2 = PlannerInterfaces(self)
        self.mission_export = MissionExportService(self)
        # The geofence and the terrain_file are read once geodetic_origin (declared by the
        # mission export) exists; their zones and ground join the map as shapes of their own.
        self.intake.start_shapes(self.parameters.read_start_geofence())

    def start(self) -> None:
        """Compile the kernels and build the grid, then start the threads and log readiness."""
        self.worker.start()
        self.intake.start()
        settings = self.inputs.current_settings()
        config = settings.config
        shape = self.worker.grid_shape()
        prior = ''
        if self._prior is not None:
            prior = ''.join(f'; prior map {report.summary()}' for report in self._prior.reports)
            prior += f' (margin {self._prior.margin_m:.3f} m added to gamma)'
        terrain = self.inputs.terrain()
        if terrain is not None and terrain.field is not None:
            prior += f'; {describe_terrain(terrain)}'
        self._log.info(
            f'{READY_TEXT}: frame {settings.frame_id!r}, grid {shape[0]}x{shape[1]}x'
            f'{shape[2]} (delta {config.resolution} m, gamma {config.safety_margin} m, '
            f'eta {config.adaptive_threshold} m), algorithm {config.algorithm}; goals on '
            f'{self.commands.goal_topic}{prior}')
        self.status.check_duplicate_name()

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the threads (a running plan is cancelled within milliseconds) and destroy the
        node."""
        self.nav2.destroy()
        self.inputs.stop()
        self.intake.stop(timeout_s)
        self.worker.stop(timeout_s)
        self.node.destroy_node()

    # ------------------------------------------- the parts' interface for Nav2 and the mission

    def submit(self, job: Job) -> None:
        """Run ``job(planner, snapshot)`` on the worker (:meth:`PlanningInputs.submit`)."""
        self.inputs.submit(job)

    def release(self, result: PlanResult, checked_version: int, frame_id: str, stamp_ns: int,
                orientation: Tuple[float, ...], *, publish: bool,
                position: Optional[np.ndarray] = None,
                start_source: StartSource = StartSource.REQUEST,
                goal_serial: Optional[int] = None) -> Release:
        """The gate of every plan (:meth:`PlanInForce.release`)."""
        return self.in_force.release(result, checked_version, frame_id, stamp_ns, orientation,
                                     publish=publish, position=position,
                                     start_source=start_source, goal_serial=goal_serial)

    def plan_for_export(self) -> Tuple[Optional[ExportablePlan], str]:
        """The plan in force for the mission export (:meth:`PlanInForce.plan_for_export`)."""
        return self.in_force.plan_for_export()

    def while_in_force(self, stamp_ns: int, action: Callable[[], T]) -> Tuple[bool, Optional[T]]:
        """Run ``action`` while a plan is in force (:meth:`PlanInForce.while_in_force`)."""
        return self.in_force.while_in_force(stamp_ns, action)

    def publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                            values: Mapping[str, object]) -> None:
        """Publish one status of this node on ``/diagnostics`` (any thread)."""
        self.diagnostics.publish(stamp_ns, level, message, values)

    def current_settings(self) -> NodeSettings:
        """The settings in force (any thread)."""
        return self.inputs.current_settings()

    def map_refusal(self) -> str:
        """Why ``map_file`` or ``terrain_file`` was refused, with what to do ('' when neither
        was): no request is planned without the map or the terrain asked for (any thread)."""
        return self.inputs.map_refusal()

    def predict_takeover(self, snapshot: Snapshot,
                         request_start: Optional[np.ndarray] = None) -> Takeover:
        """On the worker: where a plan beginning now starts
        (:meth:`PlanningWorker.predict_takeover`)."""
        return self.worker.predict_takeover(snapshot, request_start)

    def settle_takeover(self, takeover: Takeover, result: PlanResult) -> Settlement:
        """On the worker: how a plan from ``takeover`` goes out now
        (:meth:`PlanInForce.settle_takeover`)."""
        return self.in_force.settle_takeover(takeover, result)


def main(args: Optional[List[str]] = None) -> int:
    """Entry point of ``planner_node``: run until SIGINT/SIGTERM, then exit with 0.

    Returns
    -------
    int
        0 after a clean shutdown, :data:`EXIT_BAD_SETTINGS` for invalid start-up parameters
        (a ``map_file`` that cannot be used is reported by the running node instead).
    """
    return run_node('planner_node', PlannerNode, args)


if __name__ == '__main__':
    sys.exit(main())
