"""Mission export on the planner node: write the plan in force as a ground-station mission.

``export_mission`` (std_srvs/srv/Trigger, relative name) writes the mission of the plan in force
(:mod:`uav_global_planner.core.mission`: certified waypoints, take-off, speed items, the end
action) to the file named by the ``mission_file`` parameter, as a QGroundControl ``.plan`` or a
``QGC WPL 110`` file, and answers with ``success`` and, in ``message``, a JSON object:
``path`` (absolute), ``waypoints`` (items with a position), ``items``, ``format``, ``firmware``,
``required_clearance_m``, ``certified_clearance_m`` and ``plan_stamp_ns`` (the header stamp of
the exported ``plan``). On failure ``success`` is false and ``message`` says why (no plan in
force, no geodetic origin, no certified mission and where, an unwritable file).

Why std_srvs/Trigger: it is in every ROS 2 installation (ros-jazzy-common-interfaces here), so
``ros2 service call <ns>/export_mission std_srvs/srv/Trigger`` works without building a
custom interface package, and its answer (a flag and a text) carries the path and the waypoint
count. The file name is a parameter, as the rest of the export's settings are::

    ros2 param set /global_planner mission_file /tmp/survey.plan
    ros2 service call /export_mission std_srvs/srv/Trigger    # <namespace>/export_mission

The plan in force is the one latched on the node's ``plan``, ``unsmoothed_plan`` and
``trajectory`` topics, read from the node itself
(:meth:`~uav_global_planner.ros.node_in_force.PlanInForce.plan_for_export`): never a copy that a
withdrawal has overtaken. The mission is built on the node's planning worker
(:meth:`PlanHost.submit`) and certified against the newest map the node holds (with the unknown
space when that is occupied); the file is written only while that plan is still in force, and
the export is refused when it was withdrawn or replaced meanwhile. The service callback awaits
the answer without blocking the executor.

Parameters (declared on the node from :data:`MISSION_PARAMETER_SPECS`, with their ranges;
validated when set, other parameters are left to their owner): ``mission_file``,
``mission_format`` and ``mission_<name>`` for each setting of the mission's table
(:data:`~uav_global_planner.core.mission.settings.MISSION_SETTINGS`: ``acceptance_radius``,
``tracking_allowance``, ``takeoff_height``, ``end``, ``rtl_altitude``, ``firmware``), and
``geodetic_origin`` ([lat deg, lon deg, alt m AMSL] of the frame origin).
"""

from dataclasses import dataclass, field, replace
import json
import math
import queue
from typing import Any, Dict, List, Mapping, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import ParameterUninitializedException
from rclpy.parameter import Parameter
from rclpy.task import Future
from std_srvs.srv import Trigger

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import (GeodeticOrigin, MissingDependencyError,
                                                origin_from_sequence)
from uav_global_planner.core.mission import (build_mission, format_from_path, FORMATS,
                                             MissionSettings, UncertifiableMissionError,
                                             write_mission)
from uav_global_planner.core.mission.settings import MISSION_SETTINGS
from uav_global_planner.core.settings import by_name, Kind, Setting
from uav_global_planner.ros.parameters import descriptor, parameter_default

#: Name of the service (relative to the node's namespace).
EXPORT_SERVICE = 'export_mission'

#: The node's mission parameters: the file, its format, and every setting of the mission's table
#: (:data:`~uav_global_planner.core.mission.settings.MISSION_SETTINGS`) as ``mission_<name>``,
#: declared with the table's description and range.
MISSION_PARAMETER_SPECS: Tuple[Setting, ...] = (
    Setting('mission_file', Kind.TEXT, '', 'mission file',
            'File the export_mission service writes (.plan: QGroundControl, .waypoints: QGC WPL '
            '110); empty: not set.', accepts="a path, or '' (not set)"),
    Setting('mission_format', Kind.CHOICE, '', 'mission file format',
            "Format of mission_file: qgc, wpl, or '' to tell it from the extension.",
            choices=('',) + FORMATS, accepts="one of '' (from the extension), qgc, wpl"),
) + tuple(replace(setting, name=f'mission_{setting.name}')
          for setting in MISSION_SETTINGS if setting.node)
_MISSION_SPECS: Dict[str, Setting] = by_name(MISSION_PARAMETER_SPECS)
ORIGIN_PARAMETER = 'geodetic_origin'
ORIGIN_DESCRIPTION = ('WGS84 origin of the planning frame (x east, y north, z up): [latitude '
                      'deg, longitude deg, altitude m above mean sea level of z = 0].')
_OWNED = set(_MISSION_SPECS) | {ORIGIN_PARAMETER}


@dataclass(frozen=True)
class ExportRequest:
    """What one export writes, from the parameters.

    Attributes
    ----------
    file : str
    file_format : str
        ``qgc`` or ``wpl``.
    settings : MissionSettings
    origin : GeodeticOrigin
    """

    file: str
    file_format: str
    settings: MissionSettings
    origin: GeodeticOrigin


def settings_from_values(values: Mapping[str, Any]) -> MissionSettings:
    """Mission settings of the parameter values (ROS-free; the on-set check uses it).

    Raises
    ------
    InvalidInputError
        Naming the parameter.
    """
    for name in ('mission_file', 'mission_format'):
        _MISSION_SPECS[name].check(values[name])
    try:
        return MissionSettings(**{setting.name: values[f'mission_{setting.name}']
                                  for setting in MISSION_SETTINGS if setting.node})
    except InvalidInputError as error:
        raise InvalidInputError(f'mission_{error}') from None


def origin_from_value(value: Any) -> Optional[GeodeticOrigin]:
    """The origin of a ``geodetic_origin`` value (None: not set).

    Raises
    ------
    InvalidInputError
        When it is set but not three valid numbers.
    """
    if value is None:
        return None
    return origin_from_sequence(list(value), ORIGIN_PARAMETER)


def request_from_values(values: Mapping[str, Any]) -> ExportRequest:
    """The export request of the parameter values.

    Raises
    ------
    InvalidInputError
        When ``mission_file`` or ``geodetic_origin`` is not set, or a value is invalid.
    """
    settings = settings_from_values(values)
    origin = origin_from_value(values.get(ORIGIN_PARAMETER))
    file = values['mission_file']
    if not isinstance(file, str) or not file:
        raise InvalidInputError('mission_file is not set: ros2 param set <node> mission_file '
                                '/path/to/mission.plan')
    if origin is None:
        raise InvalidInputError('geodetic_origin is not set: ros2 param set <node> '
                                'geodetic_origin "[LAT, LON, ALT_AMSL]"')
    file_format = values['mission_format'] or format_from_path(file)
    return ExportRequest(file, file_format, settings, origin)


@dataclass
class _Export:
    """One service request between the executor and the planning worker."""

    request: ExportRequest
    future: Future = field(default_factory=Future)
    outcome: Tuple[bool, str] = (False, '')


class MissionExportService:
    """The ``export_mission`` service and its parameters, composed with the planner node.

    Parameters
    ----------
    host : PlanHost
        The planner node (:class:`~uav_global_planner.ros.nav2_interfaces.PlanHost`): its
        ``node``, ``submit``, ``publish_diagnostics``, ``plan_for_export`` and
        ``while_in_force`` are used.

    Raises
    ------
    InvalidInputError
        When the mission parameters given at start-up are invalid.
    """

    def __init__(self, host: Any) -> None:
        self._host = host
        node = host.node
        self._node = node
        self._log = node.get_logger()
        for spec in MISSION_PARAMETER_SPECS:
            if not node.has_parameter(spec.name):
                node.declare_parameter(spec.name, parameter_default(spec), descriptor(spec))
        if not node.has_parameter(ORIGIN_PARAMETER):
            node.declare_parameter(ORIGIN_PARAMETER, Parameter.Type.DOUBLE_ARRAY,
                                   ParameterDescriptor(
                                       name=ORIGIN_PARAMETER, description=ORIGIN_DESCRIPTION,
                                       type=ParameterType.PARAMETER_DOUBLE_ARRAY,
                                       additional_constraints='three numbers: latitude in '
                                       '(-90, 90), longitude in [-180, 180], altitude in '
                                       '[-500, 10000]'))
        # Start-up values are checked once here (main() reports them as invalid parameters).
        values = self._values()
        settings_from_values(values)
        origin_from_value(values[ORIGIN_PARAMETER])
        node.add_on_set_parameters_callback(self._validate)

        self._finished: 'queue.SimpleQueue[_Export]' = queue.SimpleQueue()
        # Reentrant: the coroutine keeps its group busy while the worker builds the mission,
        # and the node's default group would stall the node's other callbacks meanwhile.
        self._group = ReentrantCallbackGroup()
        self._guard = node.create_guard_condition(self._complete_finished, self._group)
        self._service = node.create_service(Trigger, EXPORT_SERVICE, self._on_export,
                                            callback_group=self._group)

    def destroy(self) -> None:
        """Destroy the service and the guard condition (before the node)."""
        self._node.destroy_service(self._service)
        self._node.destroy_guard_condition(self._guard)

    # ---------------------------------------------------------------------------- parameters

    def _values(self, overrides: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
        values: Dict[str, Any] = {}
        for name in _OWNED:
            try:
                values[name] = self._node.get_parameter(name).value
            except ParameterUninitializedException:
                values[name] = None
        values.update(overrides or {})
        return values

    def _validate(self, parameters: List[Parameter]) -> SetParametersResult:
        """On-set callback: refuse invalid values of this module's parameters only."""
        changes = {p.name: p.value for p in parameters if p.name in _OWNED}
        if not changes:
            return SetParametersResult(successful=True)
        try:
            values = self._values(changes)
            settings_from_values(values)
            origin_from_value(values[ORIGIN_PARAMETER])
        except InvalidInputError as error:
            self._log.warning(f'parameter change refused: {error}')
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    # ---------------------------------------------------------------------------- service

    async def _on_export(self, request_msg, response):
        try:
            request = request_from_values(self._values())
        except InvalidInputError as error:
            return self._answer(response, False, f'not exported: {error}')
        export = _Export(request)
        self._host.submit(lambda planner, snapshot: self._run(export, planner, snapshot))
        success, message = await export.future
        return self._answer(response, success, message)

    def _answer(self, response, success: bool, message: str):
        response.success = bool(success)
        response.message = message
        level = DiagnosticStatus.OK if success else DiagnosticStatus.WARN
        if success:
            self._log.info(f'{EXPORT_SERVICE}: {message}')
        else:
            self._log.warning(f'{EXPORT_SERVICE}: {message}')
        try:
            self._host.publish_diagnostics(
                self._node.get_clock().now().nanoseconds, level,
                f'{EXPORT_SERVICE}: {"written" if success else "refused"}',
                {'event': 'mission_export', 'status': 'ok' if success else 'refused',
                 'message': message})
        except Exception:  # noqa: BLE001 - the answer matters more than the status line
            pass
        return response

    # ---------------------------------------------------------------------------- worker side

    def _run(self, export: _Export, planner: Any, snapshot: Any) -> None:
        """On the planning worker: build, certify and write the mission; hand the answer back."""
        try:
            export.outcome = self._export(export, planner, snapshot)
        except Exception as error:  # noqa: BLE001 - the client must get an answer
            self._log.error(f'{EXPORT_SERVICE} failed: {error!r}')
            export.outcome = (False, f'internal error: {error!r}')
        self._finished.put(export)
        try:
            self._guard.trigger()
        except Exception:  # noqa: BLE001 - the node is being destroyed; nobody waits
            pass

    def _export(self, export: _Export, planner: Any, snapshot: Any) -> Tuple[bool, str]:
        plan, why_not = self._host.plan_for_export()
        if plan is None:
            return False, f'not exported: {why_not}'
        settings = snapshot.settings
        if plan.frame_id != settings.frame_id:
            return False, (f'not exported: the plan in force is in frame {plan.frame_id!r} '
                           f'but the planner now works in {settings.frame_id!r}')
        request = export.request
        result = plan.result
        try:
            mission = build_mission(result.trajectory.positions,
                                    planner.solid(plan.live.obstacles), settings.config,
                                    request.origin, request.settings, raw_path=result.path)
            # Written while the plan is in force: a ground station never loads the mission of
            # a plan that a map withdrew (or a newer plan replaced) meanwhile.
            in_force, path = self._host.while_in_force(
                plan.stamp_ns,
                lambda: write_mission(mission, request.file, request.file_format))
        except UncertifiableMissionError as error:
            return False, f'not exported: no certified mission: {error}'
        except (InvalidInputError, MissingDependencyError) as error:
            return False, f'not exported: {error}'
        if not in_force:
            return False, ('not exported: the plan in force was withdrawn or replaced while '
                           'its mission was built; ask again')
        clearance = mission.certified_clearance_m
        return True, json.dumps({
            'path': str(path), 'format': request.file_format,
            'firmware': request.settings.firmware, 'waypoints': mission.waypoint_count,
            'items': len(mission.items), 'required_clearance_m': mission.required_clearance_m,
            'certified_clearance_m': clearance if math.isfinite(clearance) else None,
            'plan_stamp_ns': plan.stamp_ns})

    def _complete_finished(self) -> None:
        """Guard-condition callback (executor thread): complete the finished requests."""
        while True:
            try:
                export = self._finished.get_nowait()
            except queue.Empty:
                return
            if not export.future.done():
                export.future.set_result(export.outcome)
