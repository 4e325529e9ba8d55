"""Parameter changes of the planner node: validated as a whole, applied at the next plan.

A mixin of :class:`~uav_global_planner.ros.planner_node.PlannerNode`: the on-set callback
refuses a set of values that does not validate together (and a geofence file that cannot be
read, or bounds or a geodetic origin the terrain_file cannot be placed on, so the geofence and
the terrain in force stay); the post-set callback hands the new settings to the
worker and the intake, and withdraws the plan in force when the frame changes.
"""

from typing import Any, Dict, List

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterNotDeclaredException, ParameterUninitializedException
from rclpy.parameter import Parameter

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import (airspace_from_values, describe,
                                                    geofence_key, GEOFENCE_PARAMETERS)
from uav_global_planner.ros.ground_source import ground_key
from uav_global_planner.ros.mission_service import ORIGIN_PARAMETER
from uav_global_planner.ros.node_attributes import NodeAttributes
from uav_global_planner.ros.node_state import SourceState
from uav_global_planner.ros.parameters import (NodeSettings, plain as _plain,
                                               settings_from_parameters, SPECS_BY_NAME)
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.terrain_source import read_terrain, terrain_key


class ParameterHandling(NodeAttributes):
    """Parameter callbacks; own ``_param_values``, write ``_settings`` (under ``_wake``)."""

    def _validate_parameters(self, parameters: List[Parameter]) -> SetParametersResult:
        """On-set callback: accept only a set of values that validates as a whole."""
        values = dict(self._param_values)
        owned = False
        geofence = self._geofence_values()
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
        state = getattr(self, '_terrain_state', None)
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
        state = getattr(self, '_terrain_state', None)
        if state is None or not state.file:
            return False
        origin = self._geofence_values()[ORIGIN_PARAMETER]
        key = terrain_key(state.file, settings.config, origin)
        if key == state.key:
            return False
        candidate = getattr(self, '_terrain_candidate', None)
        self._terrain_candidate = None
        if candidate is None or candidate.key != key:
            candidate = read_terrain(state.file, settings.config, origin)
        with self._wake:
            self._terrain_state = candidate
        self._log_terrain(candidate)
        return True

    def _geofence_values(self) -> Dict[str, Any]:
        """The values of :data:`GEOFENCE_PARAMETERS` in force (geodetic_origin None when not
        set)."""
        values = {name: self._param_values[name] for name in GEOFENCE_PARAMETERS
                  if name in self._param_values}
        origin = GEOFENCE_PARAMETERS[-1]
        try:
            values[origin] = self.node.get_parameter(origin).value
        except (ParameterNotDeclaredException, ParameterUninitializedException):
            values[origin] = None
        return values

    def _apply_geofence(self) -> None:
        """Read the geofence of the parameters in force and hand it to the intake, which
        joins it to the map and replans the active goal."""
        values = self._geofence_values()
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
        self._airspace, self._geofence_key = airspace, key
        self._log.info(f'{describe(airspace, self._settings.geofence_file)}: in force from '
                       'the next plan')
        # The worker plans nothing until the map holds this geofence.
        serial = self._request_shapes()
        with self._intake_cv:
            self._inbox.airspace = airspace
            self._inbox.airspace_serial = max(self._inbox.airspace_serial, serial)
            self._intake_cv.notify_all()

    def _request_shapes(self) -> int:
        """A new serial of the map's own shapes (geofence, ground, band): the worker takes no
        snapshot until the intake has built a map with them (``_geofence_applied``)."""
        with self._wake:
            self._geofence_requested += 1
            return self._geofence_requested

    def _apply_parameters(self, parameters: List[Parameter]) -> None:
        """Post-set callback: the new settings take effect at the next plan; a running plan
        with other settings is cancelled and made again."""
        changed = {p.name: p.value for p in parameters if p.name in SPECS_BY_NAME}
        geofence_changed = any(p.name in GEOFENCE_PARAMETERS for p in parameters)
        if not changed:
            if geofence_changed:  # geodetic_origin alone
                if self._follow_terrain(self._settings):
                    serial = self._request_shapes()
                    with self._intake_cv:  # the ground shapes follow the terrain
                        self._inbox.reconfigure = True
                        self._inbox.airspace_serial = max(self._inbox.airspace_serial, serial)
                        self._intake_cv.notify_all()
                self._apply_geofence()
            return
        self._param_values.update(changed)
        settings = settings_from_parameters(self._param_values, self._map_margin_m)
        ground_before = ground_key(self._settings.config, getattr(self, '_terrain_state', None))
        self._follow_terrain(settings)
        # New ground or band shapes: the worker plans nothing until the map holds them, so no
        # plan is made with the new settings against the old band.
        serial = (self._request_shapes() if ground_key(
            settings.config, getattr(self, '_terrain_state', None)) != ground_before else 0)
        frame_changed = False
        with self._wake:
            previous = self._settings
            self._settings = settings
            if conv.normalize_frame(settings.frame_id) != conv.normalize_frame(
                    previous.frame_id):
                # Data stamped in the old frame means nothing in the new one; the intake
                # drops the map (the prior map file stays: it is in the planning frame).
                frame_changed = True
                self._goal, self._start, self._start_source = None, None, StartSource.PARAMETER
                for name in ('obstacles', 'obstacle_cloud'):
                    self._sources[name] = SourceState()
            start_matters = (self._start is None
                             and not np.array_equal(settings.start, previous.start))
            if settings.config != previous.config or start_matters:
                self._settings_changed = True
            self._wake.notify_all()
        with self._intake_cv:
            self._inbox.reconfigure = True
            self._inbox.frame_reset = self._inbox.frame_reset or frame_changed
            self._inbox.airspace_serial = max(self._inbox.airspace_serial, serial)
            self._intake_cv.notify_all()
        if frame_changed:
            self._takeover.forget_odometry()
            self._log.warning(f'frame_id changed to {settings.frame_id!r}: obstacles, '
                              'start and goal cleared; republish them in the new frame')
            # A plan in the old frame must not stay in force.
            self._withdraw_in_force(settings.frame_id,
                                    f'frame_id changed to {settings.frame_id!r}', None)
        shown = ', '.join(f'{name} = {conv.format_value(_plain(value))}'
                          for name, value in changed.items())
        self._log.info(f'parameters set: {shown}; in force from the next plan')
        if geofence_changed:
            self._apply_geofence()
