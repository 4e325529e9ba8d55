"""The work of ``uav-plan plan``, ``compare``, ``plot`` and ``export``: read the scene, check
that the plan fits into memory, plan, print.

:mod:`uav_global_planner.cli.main` imports this module only once a command line asks for one of
these commands, so that ``uav-plan --help`` and the other commands start without the planner
(numpy, numba, scipy and their kernels). A first run that has to compile the kernels says so
on stderr, with the folder they are kept in.
"""

import argparse
from dataclasses import replace
import json
import math
import sys
from typing import Any, Callable, Optional, Tuple, TYPE_CHECKING

import numpy as np

from uav_global_planner.cli.main import (_print_invalid_json, _setting_dest, EXIT_INVALID_INPUT,
                                         EXIT_OK, EXIT_PLAN_FAILED)
from uav_global_planner.cli.memory import (allowance_bytes, check as check_memory, estimate,
                                           gigabytes, limited, MemoryLimitError, SEARCH_MAX_NODES)
from uav_global_planner.cli.options import check_image_file
from uav_global_planner.cli.report import (admission_lines, admission_to_dict, finite_or_none,
                                           format_summary, format_table, map_report_lines,
                                           result_to_dict)
from uav_global_planner.core import jit
from uav_global_planner.core.budget import PlanBudget, PlanStage
from uav_global_planner.core.config import validate_config
from uav_global_planner.core.errors import InvalidInputError, PlanningError
from uav_global_planner.core.io.geofence import load_geofence
from uav_global_planner.core.io.scene import find_scene, load_scene, Scene, with_ground
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.settings import planner_settings
from uav_global_planner.core.status import PlanStatus

if TYPE_CHECKING:  # imported where used: the scene is read before the planner is imported
    from uav_global_planner.core.planner import Planner
    from uav_global_planner.core.result import PlanResult
    from uav_global_planner.core.search.start_admission import Admission

# Grids from this many nodes up are announced on stderr, with their memory, before they are built.
_ANNOUNCE_GRID_NODES = 10_000_000
# How to shrink a plan that does not fit into memory.
_MEMORY_FIX = ('raise --resolution or shrink the bounds (--max-voxels only lifts the node cap), '
               'or use an algorithm that reaches fewer nodes (adaptive, octile)')


def run_command(args: argparse.Namespace) -> int:
    """Run the ``plan``, ``compare``, ``plot`` or ``export`` command ``args`` asks for.

    Returns
    -------
    int
        The exit code: 0 success, 1 planning failure, 2 invalid input (printed on stderr, or
        as one JSON object by ``plan --json``).
    """
    compiled_before = jit.compile_seconds()
    withdraw = announce_compiling()
    try:
        return _run_scene_command(args)
    finally:
        withdraw()
        report_compiled(jit.compile_seconds() - compiled_before)


def announce_compiling() -> Callable[[], None]:
    """Say on stderr, once, when this command starts compiling kernels (a first run); returns
    what withdraws the announcement once the command is over."""
    return jit.on_next_compile(lambda: print(
        "planning: compiling the planner's kernels once, cached in "
        f'{jit.cache_dir()} (uav-plan warmup does it ahead of a first plan)',
        file=sys.stderr, flush=True))


def report_compiled(seconds: float) -> None:
    """Say on stderr how long this command compiled kernels [s], if it did."""
    if seconds > 0.0:
        print(f"planning: compiled the planner's kernels once ({seconds:.1f} s), cached in "
              f'{jit.cache_dir()}', file=sys.stderr, flush=True)


def _check_command_options(args: argparse.Namespace) -> None:
    """Refuse a command's own options before the scene is read or a kernel compiled."""
    if args.command == 'compare':
        if args.repeats < 1:
            raise InvalidInputError(f'--repeats must be >= 1, got {args.repeats}')
        check_image_file('--plot', args.plot)
    elif args.command == 'plot':
        if not args.output and not args.html and not args.profile:
            raise InvalidInputError('plot needs -o PNG, --html FILE, --profile PNG or more')
        check_image_file('-o', args.output)
        check_image_file('--profile', args.profile)


def _run_scene_command(args: argparse.Namespace) -> int:
    try:
        _check_command_options(args)
        scene = _scene_from_args(args)
        # The ground and its AGL band for the final planning margin (a map raises gamma).
        scene = with_ground(scene, scene.terrain)
        if args.command == 'export':
            from uav_global_planner.cli.export import run_export
            runner: Any = run_export
        else:
            runner = {'plan': _run_plan, 'compare': _run_compare,
                      'plot': _run_plot}[args.command]
        allowance = _memory_allowance(scene)
        try:
            with limited(allowance):
                return runner(args, scene)
        except MemoryError:
            raise MemoryLimitError(
                f'out of memory: {estimate(scene.config, scene.obstacles).describe()}; the '
                f'plan needed more than the {gigabytes(allowance or 0)} available: '
                f'{_MEMORY_FIX}') from None
    except (InvalidInputError, MemoryLimitError) as error:
        if getattr(args, 'json', False) and args.command == 'plan':
            _print_invalid_json(str(error), args.algorithm)
        else:
            print(f'uav-plan: error: {error}', file=sys.stderr)
        return EXIT_INVALID_INPUT


def _scene_from_args(args: argparse.Namespace) -> Scene:
    changes = {}
    for entry in planner_settings():
        value = getattr(args, _setting_dest(entry), None) if entry.flag else None
        if value is not None and entry.field:
            changes[entry.field] = value
    # The options replace the scene's values before it is validated, so --max-voxels can admit
    # a grid the scene's own cap refuses.
    scene = load_scene(find_scene(args.scene), overrides=changes,
                       terrain_file=_terrain_file(args.terrain))
    if args.via:
        scene = replace(scene, via=np.asarray(args.via, dtype=np.float64).reshape(-1, 3))
    if args.geofence:
        scene = _with_geofence(scene, args.geofence)
    if args.map_downsample is not None and not args.map:
        raise InvalidInputError('--map-downsample needs at least one --map FILE')
    if not args.map:
        return scene
    from uav_global_planner.core.io.mapfiles import load_map_files
    from uav_global_planner.core.map.unknown_space import combine, unknown_from_map_files
    try:
        # 0 means no downsampling, as for the node's map_downsample.
        # Checked against the bounds and delta; gamma as asked, without the scene's map margin.
        config = scene.config
        maps = load_map_files(args.map, args.map_downsample or None,
                              bounds=(config.bounds_min, config.bounds_max),
                              reach=config.safety_margin - scene.map_margin_m,
                              resolution=config.resolution)
    except InvalidInputError as error:
        raise type(error)(f'--map: {error}') from None
    # gamma as asked, plus the largest margin of any map (see core.mapfiles).
    margin = max(scene.map_margin_m, maps.margin_m)
    gamma = scene.config.safety_margin - scene.map_margin_m + margin
    return replace(scene, config=validate_config(replace(scene.config, safety_margin=gamma)),
                   obstacles=ObstacleSet([*scene.obstacles.items, maps.obstacle()]),
                   map_margin_m=margin, map_reports=scene.map_reports + maps.reports,
                   unknown=combine([scene.unknown, unknown_from_map_files(
                       args.map, config.bounds_min, config.bounds_max)]))


def _terrain_file(text: Optional[str]) -> Optional[str]:
    """``--terrain FILE`` as given (None without it); an ``.npy`` file is refused: its
    lattice needs an origin and a spacing, which only the scene's ``terrain`` key gives."""
    if text and text.lower().endswith('.npy'):
        raise InvalidInputError(f'--terrain: {text}: an .npy terrain needs its origin and '
                                "spacing: give it in the scene's terrain key")
    return text or None


def _with_geofence(scene: Scene, path: str) -> Scene:
    """``scene`` with the fences and zones of a geofence file instead of its own."""
    airspace = load_geofence(path, scene.geodetic_origin, scene.config.bounds_min[2],
                             scene.config.bounds_max[2])
    own = {id(shape) for shape in scene.airspace.shapes()}
    others = [item for item in scene.obstacles.items if id(item) not in own]
    return replace(scene, obstacles=ObstacleSet(others + list(airspace.shapes())),
                   airspace=airspace)


def _without_geofence(scene: Scene) -> Scene:
    """``scene`` with its obstacles only: the unconstrained plan, for comparison."""
    own = {id(shape) for shape in scene.airspace.shapes()}
    others = [item for item in scene.obstacles.items if id(item) not in own]
    return replace(scene, obstacles=ObstacleSet(others), airspace=Airspace())


def _warm_planner(scene: Scene, algorithm: str) -> Tuple['Planner', bool, PlanBudget]:
    """A planner with its grid built within the plan's budget and the search kernels of
    ``algorithm`` loaded (not the other searches'), so the reported time is search; whether
    the grid is built (False: the budget ran out during the build, which the plan with that
    budget then reports, naming the stage); and the budget (max_planning_time bounds the whole
    plan from the grid build on). The planner's modules are imported first: their import is
    no planning time."""
    from uav_global_planner.core.planner import Planner
    budget = PlanBudget(scene.config.max_planning_time, progress=_progress_to_stderr)
    planner = Planner(scene.config, scene.obstacles, unknown=scene.unknown)
    try:
        planner.warm_up(budget, (algorithm,))
    except PlanningError:
        return planner, False, budget
    return planner, True, budget


def _plan_admitted(planner: 'Planner', scene: Scene, algorithm: str, ready: bool = True,
                   **options: Any) -> Tuple['PlanResult', Tuple['Admission', 'Admission']]:
    """Plan the scene from its start to its goal, each first admitted by the scene's
    start_tolerance (:mod:`uav_global_planner.core.search.start_admission`): a start or goal on the
    ground is lifted to the lowest free height, and a refusal says how far and the fix.
    Without a grid (``ready`` False: the budget ran out building it) the points are taken as
    asked and the plan reports the timeout."""
    from uav_global_planner.core.search.start_admission import (Admission, admit, explain, GOAL,
                                                                START)
    admissions = ((admit(planner, scene.start, START), admit(planner, scene.goal, GOAL))
                  if ready else (Admission(START, scene.start, scene.start),
                                 Admission(GOAL, scene.goal, scene.goal)))
    result = planner.plan(admissions[0].point, admissions[1].point, algorithm, via=scene.via,
                          **options)
    return explain(result, admissions), admissions


def _progress_to_stderr(stage: PlanStage, elapsed_s: float, budget_s: float) -> None:
    """Progress of a long plan, on stderr so that ``--json`` output stays one object."""
    limit = f' of {budget_s:g} s' if budget_s > 0 else ''
    print(f'planning: {stage.value} after {elapsed_s:.1f} s{limit}', file=sys.stderr,
          flush=True)


def _run_plan(args: argparse.Namespace, scene: Scene) -> int:
    planner, ready, budget = _warm_planner(scene, args.algorithm)
    result, admissions = _plan_admitted(planner, scene, args.algorithm, ready, budget=budget)
    if args.json:
        output = result_to_dict(result)
        output.update(admission_to_dict(admissions))
        output['map_files'] = [report.as_dict() for report in scene.map_reports]
        print(json.dumps(output))
    else:
        print(f'scene: {scene.name}')
        for line in map_report_lines(scene.map_reports) + admission_lines(admissions):
            print(line)
        print(format_summary(result))
    return EXIT_OK if result.ok else EXIT_PLAN_FAILED


def _run_compare(args: argparse.Namespace, scene: Scene) -> int:
    from uav_global_planner.cli.compare import compare_algorithms
    rows = compare_algorithms(scene, repeats=args.repeats)
    if len(scene.airspace):
        # The unconstrained optimum beside the fenced plans: what the geofence costs.
        free = compare_algorithms(_without_geofence(scene), algorithms=('octile',),
                                  repeats=args.repeats)
        fenced = [row.result.path_length_m / row.relative_cost for row in rows
                  if row.result.ok and math.isfinite(row.relative_cost)]
        optimum = fenced[0] if fenced else math.nan
        rows += [replace(row, algorithm='octile, no geofence',
                         relative_cost=row.result.path_length_m / optimum) for row in free]
    if args.json:
        print(json.dumps({
            'scene': scene.name,
            'rows': [{'algorithm': row.algorithm, 'status': row.result.status.value,
                      'median_time_s': row.median_time_s, 'runs': row.runs,
                      'path_length_m': finite_or_none(row.result.path_length_m),
                      'expanded_nodes': row.result.expanded_nodes,
                      'relative_cost': finite_or_none(row.relative_cost),
                      'smoothed_length_m': finite_or_none(row.result.smoothed_length_m),
                      'min_clearance_m': finite_or_none(row.result.min_clearance_m),
                      'flight_time_s': finite_or_none(row.result.duration_s),
                      'energy_wh': finite_or_none(row.result.energy.energy_wh
                                                  if row.result.energy else math.nan)}
                     for row in rows],
            'map_files': [report.as_dict() for report in scene.map_reports]}))
    else:
        grid = f'{scene.config.resolution} m grid'
        print(f'{scene.name}: {len(scene.obstacles)} obstacles, {grid}, gamma '
              f'{scene.config.safety_margin} m, eta {scene.config.adaptive_threshold} m, '
              f'median of {args.repeats} runs')
        for line in map_report_lines(scene.map_reports):
            print(line)
        print(format_table(
            ['algorithm', 'time [ms]', 'length [m]', 'expanded', 'vs optimum',
             'smoothed [m]', 'clearance [m]', 'flight [s]', 'energy [Wh]', 'status'],
            [[row.algorithm, f'{row.median_time_s * 1e3:.3f}',
              f'{row.result.path_length_m:.3f}', str(row.result.expanded_nodes),
              f'{(row.relative_cost - 1) * 100:+.2f} %', f'{row.result.smoothed_length_m:.3f}',
              f'{row.result.min_clearance_m:.3f}', f'{row.result.duration_s:.1f}',
              f'{row.result.energy.energy_wh if row.result.energy else math.nan:.2f}',
              row.result.status.value]
             for row in rows]))
    if args.plot:
        from uav_global_planner.cli.plotting import plot_scene_paths
        paths = {row.algorithm: row.result.smoothed_path for row in rows if row.result.ok}
        plot_scene_paths(scene, paths, args.plot,
                         title=f'{scene.name}: smoothed paths of every algorithm')
        print(f'plot written to {args.plot}', file=sys.stderr if args.json else sys.stdout)
    failed = any(row.result.status is not PlanStatus.OK for row in rows)
    return EXIT_PLAN_FAILED if failed else EXIT_OK


def _run_plot(args: argparse.Namespace, scene: Scene) -> int:
    from uav_global_planner.cli.plotting import plot_scene_html, plot_scene_paths
    planner, ready, budget = _warm_planner(scene, args.algorithm)
    result, admissions = _plan_admitted(planner, scene, args.algorithm, ready, budget=budget)
    for line in map_report_lines(scene.map_reports) + admission_lines(admissions):
        print(line)
    print(format_summary(result))
    if not result.ok:
        return EXIT_PLAN_FAILED
    paths = {f'{args.algorithm} raw': result.path,
             f'{args.algorithm} smoothed': result.smoothed_path}
    title = f'{scene.name}: {args.algorithm}'
    if scene.unknown is not None:
        title += (f', {result.unknown_length_m:.1f} m in unknown space '
                  f'({scene.config.unknown_space})')
    if args.output:
        plot_scene_paths(scene, paths, args.output, title=title)
        print(f'plot written to {args.output}')
    if args.html:
        plot_scene_html(scene, paths, args.html, title=title)
        print(f'interactive view written to {args.html}')
    if args.profile and result.trajectory is not None:
        from uav_global_planner.cli.profile_plot import plot_profile
        from uav_global_planner.core.path.motion_limits import MotionLimits
        plot_profile(result.trajectory, MotionLimits.from_config(scene.config), args.profile,
                     title=title)
        print(f'time profile written to {args.profile}')
    return EXIT_OK


def _memory_allowance(scene: Scene) -> Optional[int]:
    """What the plan may allocate [bytes] (None: not known), after refusing a grid larger than
    that; a large grid is announced on stderr with its memory."""
    figures = estimate(scene.config, scene.obstacles)
    if figures.nodes > SEARCH_MAX_NODES:
        raise InvalidInputError(f'grid of {figures.nodes:.3g} nodes: the search supports at most '
                                f'{SEARCH_MAX_NODES}; raise --resolution or shrink the bounds')
    allowance = allowance_bytes()
    check_memory(figures, allowance, _MEMORY_FIX)
    if figures.nodes >= _ANNOUNCE_GRID_NODES:
        room = f'; {gigabytes(allowance)} available' if allowance is not None else ''
        print(f'planning: {figures.describe()}{room}', file=sys.stderr, flush=True)
    return allowance
