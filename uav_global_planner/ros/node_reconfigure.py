"""Parameter changes of the planner node: validated as a whole, applied at the next plan.

A part of :class:`~uav_global_planner.ros.planner_node.PlannerNode`: the on-set callback
refuses a set of values that does not validate together (and a geofence file that cannot be
read, or bounds or a geodetic origin the terrain_file cannot be placed on, so the geofence and
the terrain in force stay); the post-set callback hands the new settings to the
worker and the intake, and withdraws the plan in force when the frame changes.
"""

from typing import Any, Dict, List, Optional, Tuple

from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterNotDeclaredException, ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import (airspace_from_values, describe,
                                                    geofence_key, GEOFENCE_PARAMETERS)
from uav_global_planner.ros.ground_source import ground_key
from uav_global_planner.ros.mission_service import ORIGIN_PARAMETER
from uav_global_planner.ros.node_in_force import PlanInForce
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.parameters import (NodeSettings, plain as _plain,
                                               settings_from_parameters, SPECS_BY_NAME)
from uav_global_planner.ros.takeover import TakeoverPredictor
from uav_global_planner.ros.terrain_source import (describe_terrain, read_terrain, terrain_key,
                                                   TerrainState)


class NodeParameters:
    """The parameter callbacks, and the geofence and terrain read from the parameters.

    No lock: its state (the parameter values in force, the key of the geofence in force, a
    terrain read for values about to be set) belongs to the executor, which runs the
    callbacks. The settings, the geofence and the terrain it puts in force go to the planning
    inputs (their condition guards them), new maps are asked of the intake.

    Parameters
    ----------
    node : rclpy.node.Node
        Its parameter callbacks are registered here (after the planner's parameters are
        declared, before any other part declares parameters).
    values : dict
        The planner's parameter values as declared.
    map_margin_m : float
        The ``map_file``'s margin added to gamma [m].
    inputs : PlanningInputs
    intake : MapIntake
    in_force : PlanInForce
        A plan in the old frame is withdrawn when ``frame_id`` changes.
    takeover : TakeoverPredictor
    """

    def __init__(self, node: Node, values: Dict[str, Any], map_margin_m: float,
                 inputs: PlanningInputs, intake: MapIntake, in_force: PlanInForce,
                 takeover: TakeoverPredictor) -> None:
        self._node = node
        self._log = node.get_logger()
        self._param_values = values
        self._map_margin_m = map_margin_m
        self._inputs = inputs
        self._intake = intake
        self._in_force = in_force
        self._takeover = takeover
        # A terrain read by the on-set callback for values about to be set.
        self._terrain_candidate: Optional[TerrainState] = None
        # The parameters the geofence in force was read from (None: not read yet).
        self._geofence_key: Optional[Tuple[Any, ...]] = None
        # Registered after declaring, so start-up values are checked once, not per item.
        node.add_on_set_parameters_callback(self._validate_parameters)
        node.add_post_set_parameters_callback(self._apply_parameters)

    def read_start_geofence(self) -> Airspace:
        """Read the geofence and the terrain of the start-up parameters and put them in force
        (once ``geodetic_origin`` is declared); the geofence read.

        Raises
        ------
        InvalidInputError
            When the geofence cannot be read (the node does not start).
        """
        geofence = self.geofence_values()
        airspace = airspace_from_values(geofence)
        self._inputs.set_airspace(airspace)
        self._geofence_key = geofence_key(geofence)
        settings = self._inputs.current_settings()
        terrain = read_terrain(settings.terrain_file, settings.config, geofence[ORIGIN_PARAMETER])
        self._inputs.set_terrain(terrain)
        if terrain.refusal:  # a terrain read is in the ready line
            self._log_terrain(terrain)
        return airspace

    def _log_terrain(self, state: TerrainState) -> None:
        """Log the terrain read, or why it was refused."""
        if state.refusal:
            self._log.error(f'refused terrain_file: {state.refusal}; goals are refused until '
                            'a terrain that can be used is in force')
        elif state.field is not None:
            self._log.info(f'{describe_terrain(state)}: the ground from the next plan')

    def _validate_parameters(self, parameters: List[Parameter]) -> SetParametersResult:
        """On-set callback: accept only a set of values that validates as a whole."""
        values = dict(self._param_values)
        owned = False
        geofence = self.geofence_values()
        for parameter in parameters:
            if parameter.name in GEOFENCE_PARAMETERS:
                geofence[parameter.name] = parameter.value
            if parameter.name not in SPECS_BY_NAME:
                continue  # use_sim_time and friends belong to rclpy
            if parameter.type_ == Parameter.Type.NOT_SET:
                return SetParametersResult(
                    successful=False, reason=f'{parameter.name} cannot be undeclared')
            # Start-up parameters (STARTUP_ONLY) are read-only: rclpy refuses them first.
            values[parameter.name] = parameter.value
            owned = True
        try:
            if owned:
                settings_from_parameters(values, self._map_margin_m)
            if any(parameter.name in GEOFENCE_PARAMETERS for parameter in parameters):
                # The file is read here, so a bad fence is refused with the reason and the
                # geofence in force stays.
                airspace_from_values(geofence)
            self._check_terrain(values, geofence[ORIGIN_PARAMETER])
        except InvalidInputError as error:
            self._log.warning(f'parameter change refused: {error}')
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _check_terrain(self, values: Dict[str, Any], origin: Any) -> None:
        """Read the terrain_file again when ``values`` and ``origin`` move or re-place it; keep
        it for :meth:`_follow_terrain`.

        Raises
        ------
        InvalidInputError
            When the terrain in force cannot be read for them (it stays in force).
        """
        state = self._inputs.terrain()
        if state is None or not state.file:
            return  # not read yet (start-up), or no terrain_file
        config = settings_from_parameters(values, self._map_margin_m).config
        if terrain_key(state.file, config, origin) == state.key:
            return
        candidate = read_terrain(state.file, config, origin)
        if candidate.refusal and not state.refusal:
            raise InvalidInputError(f'terrain_file cannot follow: {candidate.refusal}; the '
                                    'terrain in force stays')
        self._terrain_candidate = candidate

    def _follow_terrain(self, settings: NodeSettings) -> bool:
        """Put the terrain of the settings and geodetic origin in force (the one read by
        :meth:`_check_terrain`, or read now); True when it changed."""
        state = self._inputs.terrain()
        if state is None or not state.file:
            return False
        origin = self.geofence_values()[ORIGIN_PARAMETER]
        key = terrain_key(state.file, settings.config, origin)
        if key == state.key:
            return False
        candidate = self._terrain_candidate
        self._terrain_candidate = None
        if candidate is None or candidate.key != key:
            candidate = read_terrain(state.file, settings.config, origin)
        self._inputs.set_terrain(candidate)
        self._log_terrain(candidate)
        return True

    def geofence_values(self) -> Dict[str, Any]:
        """The values of :data:`GEOFENCE_PARAMETERS` in force (geodetic_origin None when not
        set)."""
        values = {name: self._param_values[name] for name in GEOFENCE_PARAMETERS
                  if name in self._param_values}
        origin = GEOFENCE_PARAMETERS[-1]
        try:
            values[origin] = self._node.get_parameter(origin).value
        except (ParameterNotDeclaredException, ParameterUninitializedException):
            values[origin] = None
        return values

    def _apply_geofence(self) -> None:
        """Read the geofence of the parameters in force and hand it to the intake, which
        joins it to the map and replans the active goal."""
        values = self.geofence_values()
        key = geofence_key(values)
        if self._geofence_key is None or key == self._geofence_key:
            # Before the node has read its first geofence (declaring geodetic_origin runs this
            # callback), or values set again unchanged: nothing to read.
            return
        try:
            airspace = airspace_from_values(values)
        except InvalidInputError as error:  # the file changed since it was validated
            self._log.error(f'geofence not changed: {error}')
            return
        self._inputs.set_airspace(airspace)
        self._geofence_key = key
        self._log.info(f'{describe(airspace, self._inputs.current_settings().geofence_file)}: '
                       'in force from the next plan')
        # The worker plans nothing until the map holds this geofence.
        self._intake.queue_airspace(airspace, self._inputs.request_shapes())

    def _apply_parameters(self, parameters: List[Parameter]) -> None:
        """Post-set callback: the new settings take effect at the next plan; a running plan
        with other settings is cancelled and made again."""
        changed = {p.name: p.value for p in parameters if p.name in SPECS_BY_NAME}
        geofence_changed = any(p.name in GEOFENCE_PARAMETERS for p in parameters)
        if not changed:
            if geofence_changed:  # geodetic_origin alone
                if self._follow_terrain(self._inputs.current_settings()):
                    # The ground shapes follow the terrain.
                    self._intake.queue_reconfigure(shapes_serial=self._inputs.request_shapes())
                self._apply_geofence()
            return
        self._param_values.update(changed)
        settings = settings_from_parameters(self._param_values, self._map_margin_m)
        ground_before = ground_key(self._inputs.current_settings().config,
                                   self._inputs.terrain())
        self._follow_terrain(settings)
        # New ground or band shapes: the worker plans nothing until the map holds them, so no
        # plan is made with the new settings against the old band.
        serial = (self._inputs.request_shapes() if ground_key(
            settings.config, self._inputs.terrain()) != ground_before else 0)
        # Data stamped in the old frame means nothing in the new one: the goal and start are
        # cleared, and the intake drops the map (the prior map file stays: it is in the
        # planning frame).
        frame_changed = self._inputs.replace_settings(settings)
        if frame_changed:
            self._intake.forget_sources()
        self._intake.queue_reconfigure(frame_changed, serial)
        if frame_changed:
            self._takeover.forget_odometry()
            self._log.warning(f'frame_id changed to {settings.frame_id!r}: obstacles, '
                              'start and goal cleared; republish them in the new frame')
            # A plan in the old frame must not stay in force.
            self._in_force.withdraw(settings.frame_id,
                                    f'frame_id changed to {settings.frame_id!r}', None)
        shown = ', '.join(f'{name} = {conv.format_value(_plain(value))}'
                          for name, value in changed.items())
        self._log.info(f'parameters set: {shown}; in force from the next plan')
        if geofence_changed:
            self._apply_geofence()
