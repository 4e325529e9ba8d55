"""``uav-plan export``: write a certified mission for a ground station or an autopilot.

``uav-plan export SCENE --format {qgc,wpl} -o FILE`` plans the scene (or takes the route of a saved
``uav-plan plan --json`` result with ``--from-plan``), chooses certified waypoints
(:mod:`uav_global_planner.core.mission`) and writes a QGroundControl ``.plan`` or a ``QGC WPL 110``
file. The map frame's WGS84 origin comes from ``--origin LAT,LON,ALT`` or the scene's
``geodetic_origin``.

Exit codes: 0 written, 1 no plan or no certified mission (the reason is printed), 2 invalid input
(options, scene, plan file) or pymap3d missing.
"""

import argparse
from dataclasses import replace
import json
from pathlib import Path
import sys
from typing import Any, Callable, Dict, Iterator, List, Optional, Tuple

import numpy as np

from uav_global_planner.cli.options import add_algorithm_option
from uav_global_planner.core.config import validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import GeodeticOrigin, MissingDependencyError, parse_origin
from uav_global_planner.core.io.scene import Scene
from uav_global_planner.core.io.text_files import parse_text_file
from uav_global_planner.core.mission import (build_mission, format_from_path, FORMATS,
                                             MAV_CMD_NAV_TAKEOFF, Mission, MissionSettings,
                                             UncertifiableMissionError, write_mission)
from uav_global_planner.core.mission.settings import MISSION_SETTINGS
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.settings import Kind

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INVALID_INPUT = 2

_FORMAT_NAMES = {'qgc': 'QGroundControl .plan', 'wpl': 'QGC WPL 110'}


SceneOptions = Callable[[argparse.ArgumentParser], None]


def add_export_command(commands: Any, add_scene_options: SceneOptions) -> None:
    """Register ``export`` on the ``uav-plan`` sub-command parsers.

    Parameters
    ----------
    commands
        The object returned by ``ArgumentParser.add_subparsers``.
    add_scene_options : callable
        Adds the scene argument and the planner overrides shared by every sub-command.
    """
    parser = commands.add_parser(
        'export', help='write a certified mission file (QGroundControl .plan or QGC WPL 110)',
        description=__doc__.split('\n\n')[1].replace('\n', ' '))
    add_scene_options(parser)
    parser.add_argument('-o', '--output', required=True, metavar='FILE',
                        help='mission file to write (.plan or .waypoints)')
    parser.add_argument('--format', choices=FORMATS,
                        help='qgc: QGroundControl .plan (JSON); wpl: QGC WPL 110 text (Mission '
                        'Planner); default: from the extension of FILE')
    parser.add_argument('--from-plan', metavar='JSON',
                        help='take the route of a saved "uav-plan plan --json" result instead '
                        'of planning')
    add_algorithm_option(parser)
    parser.add_argument('--origin', metavar='LAT,LON,ALT',
                        help='WGS84 latitude, longitude [deg] and altitude AMSL [m] of the map '
                        "frame's origin, e.g. --origin -33.86,151.2,10 (default: the scene's "
                        'geodetic_origin)')
    _add_mission_flags(parser)
    parser.add_argument('--route-margin', type=float, metavar='M',
                        help='plan the route with this safety margin [m] (default: gamma, and '
                        'where that route is too tight for the mission, gamma + allowance + R/2); '
                        'the mission keeps gamma + allowance either way')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def _add_mission_flags(parser: argparse.ArgumentParser) -> None:
    """One flag per setting of :data:`MISSION_SETTINGS` that has one, in the table's words;
    :class:`MissionSettings` checks the values. The firmware's default follows the format."""
    for entry in MISSION_SETTINGS:
        if entry.flag is None:
            continue
        kind: Dict[str, Any] = ({'choices': entry.choices} if entry.kind is Kind.CHOICE
                                else {'type': float, 'metavar': 'M'})
        if entry.name == 'firmware':
            parser.add_argument(entry.flag, dest=entry.name, help=f'{entry.summary} Accepted: '
                                f'{entry.constraints}. Default: px4 for qgc, ardupilot for wpl.',
                                **kind)
        else:
            parser.add_argument(entry.flag, dest=entry.name, default=entry.default,
                                help=entry.help_text(), **kind)


def _settings(args: argparse.Namespace, file_format: str) -> MissionSettings:
    values = {entry.name: getattr(args, entry.name) for entry in MISSION_SETTINGS
              if entry.flag is not None}
    values['firmware'] = args.firmware or ('ardupilot' if file_format == 'wpl' else 'px4')
    return MissionSettings(**values)


def _origin(args: argparse.Namespace, scene: Scene) -> GeodeticOrigin:
    if args.origin is not None:
        return parse_origin(args.origin)
    origin = getattr(scene, 'geodetic_origin', None)
    if origin is None:
        raise InvalidInputError(
            f'{scene.name}: no geodetic origin: pass --origin LAT,LON,ALT or add '
            'geodetic_origin: {lat: ..., lon: ..., alt_amsl: ...} to the scene file')
    return origin


def load_plan_file(path: str) -> Dict[str, np.ndarray]:
    """The route of a saved ``uav-plan plan --json`` result.

    Returns
    -------
    dict
        ``smoothed_path`` (M, 3), ``path`` (N, 3) and ``via`` (V, 3) [m].

    Raises
    ------
    InvalidInputError
        When the file is unreadable, not JSON, not a plan result, or a failed plan.
    """
    file = Path(path)
    data = parse_text_file(file, 'plan file', json.loads, json.JSONDecodeError,
                           'not a JSON plan result')
    if not isinstance(data, dict) or 'status' not in data or 'smoothed_path' not in data:
        raise InvalidInputError(f'{file}: not a "uav-plan plan --json" result (needs status and '
                                'smoothed_path)')
    if data['status'] != 'ok':
        raise InvalidInputError(f'{file}: the saved plan failed ({data["status"]}: '
                                f'{data.get("message", "")}); nothing to export')
    route = {}
    for key, required in (('smoothed_path', True), ('path', False), ('via', False)):
        value = data.get(key) or []
        try:
            array = np.asarray(value, dtype=np.float64).reshape(-1, 3)
        except (TypeError, ValueError):
            raise InvalidInputError(f'{file}: {key} must be a list of [x, y, z]') from None
        if not np.all(np.isfinite(array)):
            raise InvalidInputError(f'{file}: {key} must be finite')
        if required and len(array) < 2:
            raise InvalidInputError(f'{file}: {key} has fewer than two points')
        route[key] = array
    return route


def route_margins(args: argparse.Namespace, scene: Scene) -> List[float]:
    """Safety margins to plan the route with, in the order tried [m].

    First gamma (the route ``uav-plan plan`` gives). The mission keeps gamma + allowance along
    straight legs that cut the curve's bends, so where that route is too tight for it, a route
    planned with gamma + allowance + R / 2 (room for the legs and the turns) comes next.
    """
    if args.route_margin is not None:
        return [args.route_margin]
    gamma = scene.config.safety_margin
    wide = gamma + args.tracking_allowance + 0.5 * args.acceptance_radius
    return [gamma] + ([wide] if gamma < wide <= 100.0 else [])


def _routes(args: argparse.Namespace, scene: Scene
            ) -> Iterator[Tuple[Optional[Dict[str, np.ndarray]], str]]:
    """Routes to try, each with a line saying where it came from (None: that plan failed)."""
    if args.from_plan:
        yield load_plan_file(args.from_plan), f'route of {args.from_plan}'
        return
    for margin in route_margins(args, scene):
        config = validate_config(replace(scene.config, safety_margin=margin))
        via = getattr(scene, 'via', np.empty((0, 3)))
        planner = Planner(config, scene.obstacles, unknown=getattr(scene, 'unknown', None))
        result = planner.plan(scene.start, scene.goal, args.algorithm, via=via)
        if not result.ok:
            yield None, f'route with safety margin {margin:g} m: {result.message}'
            continue
        yield ({'smoothed_path': result.smoothed_path, 'path': result.path, 'via': via},
               f'route planned with {args.algorithm} and safety margin {margin:g} m: '
               f'{result.smoothed_length_m:.2f} m smoothed, min clearance '
               f'{result.min_clearance_m:.3f} m')


def mission_summary(mission: Mission, path: Path, file_format: str) -> Dict[str, Any]:
    """The JSON-ready account of an exported mission."""
    settings = mission.settings
    return {
        'status': 'ok', 'file': str(path), 'format': file_format,
        'firmware': settings.firmware, 'items': len(mission.items),
        'waypoints': mission.waypoint_count,
        'commands': [item.command for item in mission.items],
        'safety_margin_m': mission.safety_margin_m,
        'tracking_allowance_m': settings.tracking_allowance,
        'required_clearance_m': mission.required_clearance_m,
        'certified_clearance_m': mission.certified_clearance_m,
        'acceptance_radius_m': settings.acceptance_radius, 'end': settings.end,
        'home': list(mission.home),
        'fence_polygons': len(mission.fence.polygons), 'fence_circles': len(mission.fence.circles),
        'fence_skipped': list(mission.fence.skipped),
        'takeoff_height_m': (round(float(mission.flight_path[1][2] - mission.home_enu[2]), 3)
                             if mission.items[0].command == MAV_CMD_NAV_TAKEOFF else None),
        'flight_path': np.round(mission.flight_path, 6).tolist(),
    }


def run_export(args: argparse.Namespace, scene: Scene) -> int:
    """Run ``uav-plan export``; returns the exit code.

    Raises
    ------
    InvalidInputError
        For invalid options, scene or plan file (``uav-plan`` reports them with exit code 2).
    """
    file_format = args.format or format_from_path(args.output)
    settings = _settings(args, file_format)
    origin = _origin(args, scene)
    failures = []
    mission = None
    uncertifiable = False
    try:
        for route, source in _routes(args, scene):
            if route is None:
                failures.append(source)
                continue
            try:
                mission = build_mission(route['smoothed_path'], scene.obstacles, scene.config,
                                        origin, settings, raw_path=route['path'],
                                        via=route['via'],
                                        airspace=getattr(scene, 'airspace', None))
                break
            except UncertifiableMissionError as error:
                failures.append(f'{source}: no certified mission: {error}')
                uncertifiable = True
        if mission is None:
            return _fail(args, 'uncertifiable' if uncertifiable else 'no_plan',
                         '\n'.join(failures))
        written = write_mission(mission, args.output, file_format)
    except MissingDependencyError as error:
        print(f'uav-plan: error: {error}', file=sys.stderr)
        return EXIT_INVALID_INPUT
    summary = mission_summary(mission, written, file_format)
    summary['route'] = source
    if args.json:
        print(json.dumps(summary))
        return EXIT_OK
    allowance = settings.tracking_allowance
    print(f'scene: {scene.name}; {source}')
    for failure in failures:
        print(f'tried first: {failure}')
    print(f'mission written to {written} ({_FORMAT_NAMES[file_format]}, {settings.firmware})')
    print(f'{len(mission.items)} items, {mission.waypoint_count} with a position; end: '
          f'{settings.end}')
    print(f'every leg and turn region keeps >= {mission.required_clearance_m:.3f} m (gamma '
          f'{mission.safety_margin_m:g} m + tracking allowance {allowance:g} m); certified '
          f'{mission.certified_clearance_m:.4f} m')
    fence = mission.fence
    if fence.polygons or fence.circles or fence.skipped:
        print(f'geofence: {len(fence.polygons)} polygon(s), {len(fence.circles)} circle(s)'
              + ''.join(f'; not written: {reason}' for reason in fence.skipped))
    print(f'acceptance radius {settings.acceptance_radius:g} m; speeds '
          f'{mission.speed_horizontal:g} m/s horizontal, {mission.speed_vertical:g} m/s '
          'vertical')
    return EXIT_OK


def _fail(args: argparse.Namespace, status: str, message: str) -> int:
    if args.json:
        print(json.dumps({'status': status, 'message': message}))
    else:
        print(message)
    return EXIT_FAILED
