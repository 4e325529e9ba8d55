"""``uav-plan fleet``: plan and deconflict a fleet's missions on one map, on Ray.

``uav-plan fleet MISSIONS.yaml [--scene S] [--workers N] [--address A] [--out DIR]`` plans
every mission of the batch file (:func:`~uav_global_planner.core.fleet.load_missions`) on the
scene it names, resolves the conflicts in the fleet order (priority, then departure) and writes
into ``DIR``:

- ``report.json``: every mission accepted (how: as planned, delayed, in an altitude layer, at
  a lower speed) or rejected (why), every conflict found and each step tried, the missions
  refused before planning (named, with the setting), and each accepted mission's trajectory as
  ``times`` [s, batch clock] and ``positions`` [m, ENU map frame];
- one QGroundControl ``.plan`` per accepted mission (with ``--origin`` or the scene's
  ``geodetic_origin``);
- ``fleet.html``: every vehicle and its separation envelope over time, with a time slider.

Exit codes: 0 every mission accepted, 1 some rejected or refused (the report says why), 2 invalid
input (options, batch file, scene) or a missing optional package.
"""

import argparse
from dataclasses import replace
import json
import math
from pathlib import Path
import sys
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple

from uav_global_planner.cli.options import HelpFormatter
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.fleet import FleetResult, load_missions, MissionBatch, MissionOutcome
from uav_global_planner.core.io.geodesy import GeodeticOrigin, MissingDependencyError, parse_origin
from uav_global_planner.core.io.scene import find_scene, load_scene, Scene, with_ground
from uav_global_planner.core.mission import (build_mission, MissionSettings,
                                             UncertifiableMissionError, write_mission)

EXIT_OK = 0
EXIT_REJECTED = 1
EXIT_INVALID_INPUT = 2

_DESCRIPTION = ("Plan every mission of a batch file on the batch's scene, resolve the conflicts "
                'in the fleet order (priority, then departure) on Ray, and write report.json, '
                'one .plan per accepted mission and fleet.html (a time slider) into DIR.')
_EXIT_CODES = ('exit codes:\n'
               '  0  every mission accepted\n'
               '  1  some missions rejected or refused (report.json says why)\n'
               '  2  invalid input: options, batch file or scene, or a missing package')


def fleet_parser(prog: str = 'uav-plan fleet') -> argparse.ArgumentParser:
    """The options of ``uav-plan fleet``."""
    parser = argparse.ArgumentParser(prog=prog, description=_DESCRIPTION, epilog=_EXIT_CODES,
                                     formatter_class=HelpFormatter)
    parser.add_argument('missions', help='batch file (YAML): scene, now_s, settings, missions')
    parser.add_argument('--scene', help='scene file or shipped scene name (default: the '
                        'scene key of the batch file)')
    parser.add_argument('--workers', type=int, default=2, metavar='N',
                        help='planner actors, one CPU each; default %(default)s')
    parser.add_argument('--address', metavar='A',
                        help='join a running Ray cluster (auto, HOST:PORT or ray://HOST:PORT) '
                        'instead of starting one in this process')
    parser.add_argument('--out', metavar='DIR',
                        help='output folder (default: <batch file name>_fleet in the working '
                        'folder)')
    parser.add_argument('--origin', metavar='LAT,LON,ALT',
                        help='WGS84 latitude, longitude [deg] and altitude AMSL [m] of the map '
                        "frame's origin for the .plan files (default: the scene's "
                        'geodetic_origin; without either no .plan is written)')
    parser.add_argument('--step', type=float, default=1.0, metavar='S',
                        help='time step of the trajectories in report.json [s]; default '
                        '%(default)s')
    parser.add_argument('--frame-step', type=float, default=10.0, metavar='S',
                        help='time between the frames of fleet.html [s]; default %(default)s')
    parser.add_argument('--no-html', action='store_true', help='do not write fleet.html')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``uav-plan fleet``; returns the exit code."""
    parser = fleet_parser()
    try:
        args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    except SystemExit as stop:  # --help (0) or a usage error (2), already printed
        return int(stop.code or 0)
    try:
        return _run(args)
    except (InvalidInputError, MissingDependencyError) as error:
        print(f'uav-plan fleet: error: {error}', file=sys.stderr)
        return EXIT_INVALID_INPUT


def _check_options(args: argparse.Namespace) -> None:
    if args.workers < 1:
        raise InvalidInputError(f'--workers must be >= 1, got {args.workers}')
    for flag, value in (('--step', args.step), ('--frame-step', args.frame_step)):
        if not (math.isfinite(value) and value > 0.0):
            raise InvalidInputError(f'{flag} must be a number of seconds > 0, got {value}')


def _scene(args: argparse.Namespace, batch: MissionBatch) -> Scene:
    name = args.scene or batch.scene
    if not name:
        raise InvalidInputError(f'{args.missions}: no scene: give --scene or a scene key in '
                                'the batch file')
    candidate = Path(name)
    if not args.scene and not candidate.is_absolute():
        # A scene path in the batch file is relative to the batch file.
        beside = Path(args.missions).resolve().parent / candidate
        if beside.is_file():
            name = str(beside)
    scene = load_scene(find_scene(name))
    return with_ground(scene, scene.terrain)


def _run(args: argparse.Namespace) -> int:
    _check_options(args)
    origin = parse_origin(args.origin) if args.origin else None
    batch = load_missions(args.missions)
    scene = _scene(args, batch)
    origin = origin or scene.geodetic_origin
    out = Path(args.out) if args.out else Path(f'{Path(args.missions).stem}_fleet')
    # Ray is imported only now: the options and the batch are checked without it.
    from uav_global_planner.fleet_ray import plan_fleet_ray
    total = len(batch.missions)
    bar = _progress_bar(total, args.quiet)

    def progress(done: int, count: int, outcome: MissionOutcome) -> None:
        if bar is not None:
            bar.total = count
            bar.set_postfix_str(f'{outcome.name}: {"ok" if outcome.accepted else "rejected"}',
                                refresh=False)
            bar.update(1)

    started = time.perf_counter()
    try:
        run = plan_fleet_ray(scene, batch, workers=args.workers, address=args.address,
                             progress=progress)
    finally:
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - started
    result = run.result
    out.mkdir(parents=True, exist_ok=True)
    plan_files = _write_plan_files(result, scene, origin, out)
    report = result.to_dict(args.step)
    for entry in report['missions']:
        entry['plan_file'] = plan_files.get(entry['name'], (None, None))[0]
        entry['plan_file_note'] = plan_files.get(entry['name'], (None, None))[1]
    report['scene'] = scene.name
    report['missions_file'] = str(args.missions)
    report['run'] = {'workers': run.stats.workers, 'nodes': run.stats.nodes,
                     'address': args.address or 'local', 'wall_s': elapsed,
                     'base_plans': run.stats.base_plans,
                     'resolutions': run.stats.resolutions, 'stale': run.stats.stale,
                     'map_bytes': run.stats.map_bytes, 'zero_copy': run.stats.zero_copy}
    report_path = out / 'report.json'
    report_path.write_text(json.dumps(report), encoding='utf-8')
    html_path = None
    if not args.no_html:
        from uav_global_planner.cli.fleet_plot import plot_fleet_html
        html_path = plot_fleet_html(scene, result, out / 'fleet.html',
                                    frame_step_s=args.frame_step,
                                    title=f'{scene.name}: {Path(args.missions).name}')
    for line in summary_lines(result, elapsed, run.stats.workers):
        print(line)
    written = sum(1 for name, _ in plan_files.values() if name)
    print(f'report: {report_path}')
    print(f'.plan files: {written} of {len(result.accepted)} accepted missions in {out}'
          + ('' if origin is not None else ' (no geodetic origin: pass --origin LAT,LON,ALT)'))
    if html_path is not None:
        print(f'time-slider view: {html_path}')
    return EXIT_OK if not result.rejected and not result.errors else EXIT_REJECTED


def _progress_bar(total: int, quiet: bool) -> Any:
    if quiet:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit='mission', file=sys.stderr, dynamic_ncols=True)


def summary_lines(result: FleetResult, elapsed_s: float, workers: int) -> List[str]:
    """The run in a few lines: counts by outcome, the rejections and the refused missions."""
    kinds: Dict[str, int] = {}
    for outcome in result.accepted:
        kind = ('as planned' if outcome.reason == 'accepted as planned' else
                'in a layer' if outcome.layer_m else
                'slowed' if outcome.speed_factor < 1.0 else 'delayed')
        kinds[kind] = kinds.get(kind, 0) + 1
    count = len(result.outcomes) + len(result.errors)
    lines = [f'{count} missions in {elapsed_s:.1f} s on {workers} worker(s): '
             f'{len(result.accepted)} accepted ('
             + ', '.join(f'{n} {kind}' for kind, n in sorted(kinds.items())) + '), '
             f'{len(result.rejected)} rejected, {len(result.errors)} refused; '
             f'{len(result.conflicts)} conflicts found']
    lines += [f'rejected {outcome.name}: {outcome.reason}' for outcome in result.rejected]
    lines += [f'refused {error}' for error in result.errors]
    return lines


def _write_plan_files(result: FleetResult, scene: Scene, origin: Optional[GeodeticOrigin],
                      out: Path) -> Dict[str, Tuple[Optional[str], Optional[str]]]:
    """One QGroundControl .plan per accepted mission: name -> (file, note)."""
    files: Dict[str, Tuple[Optional[str], Optional[str]]] = {}
    if origin is None:
        return {outcome.name: (None, 'no geodetic origin') for outcome in result.accepted}
    for outcome in result.accepted:
        plan = outcome.plan
        if plan is None or outcome.flight is None:
            continue
        # A slowed flight flies the same curve with every speed times its factor.
        factor = outcome.speed_factor
        config = replace(scene.config,
                         max_speed_horizontal=scene.config.max_speed_horizontal * factor,
                         max_speed_vertical=scene.config.max_speed_vertical * factor)
        try:
            mission = build_mission(plan.smoothed_path, scene.obstacles, config, origin,
                                    MissionSettings(), raw_path=plan.path,
                                    via=_via_of(outcome), airspace=scene.airspace)
            path = write_mission(mission, out / f'{_file_name(outcome.name)}.plan', 'qgc')
            files[outcome.name] = (path.name, f'departure {outcome.departure_s:g} s')
        except UncertifiableMissionError as error:
            files[outcome.name] = (None, f'no certified mission: {error}')
    return files


def _via_of(outcome: MissionOutcome) -> Any:
    """The via-points the plan passed through exactly (a layer's climb and descent points
    included) [m]."""
    plan = outcome.plan
    return () if plan is None else getattr(plan, 'via', ())


def _file_name(name: str) -> str:
    return ''.join(c if c.isalnum() or c in '-_.' else '_' for c in name) or 'mission'
