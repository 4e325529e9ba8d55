"""``uav-plan``: plan offline from a scene file, compare the algorithms, draw the paths.

Exit codes: 0 when the plan succeeded, 1 for a planning failure (no path, occupied or outside
start or goal, timeout), 2 for invalid input (scene file, options).
"""

import argparse
from dataclasses import replace
import json
import sys
from typing import List, Optional

from uav_global_planner.cli.compare import compare_algorithms
from uav_global_planner.cli.report import (finite_or_none, format_summary, format_table,
                                           result_to_dict)
from uav_global_planner.core.config import ALGORITHMS, SMOOTHING_MODES, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.scene import find_scene, load_scene, Scene
from uav_global_planner.core.status import PlanStatus

EXIT_OK = 0
EXIT_PLAN_FAILED = 1
EXIT_INVALID_INPUT = 2


class _UsageError(Exception):
    """A command line argparse refuses (unknown option, bad value, invalid choice).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The (sub-)command parser that refused it, for its usage line.
    message : str
        argparse's reason, naming the option.
    """

    def __init__(self, parser: argparse.ArgumentParser, message: str) -> None:
        super().__init__(f'{parser.prog}: {message}')
        self.parser = parser
        self.reason = message


class _Parser(argparse.ArgumentParser):
    """An argument parser that raises instead of exiting, so ``plan --json`` can answer in JSON.

    Sub-command parsers are made of the same class.
    """

    def error(self, message: str) -> None:
        """Raise :class:`_UsageError` (argparse's hook; the default prints and exits 2)."""
        raise _UsageError(self, message)


def _add_scene_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('scene', help='scene YAML file, or the name of a shipped scene '
                        '(paper_medium, paper_high, dense60_mid, dense60_fine)')
    parser.add_argument('--resolution', type=float, help='override delta [m]')
    parser.add_argument('--safety-margin', type=float, help='override gamma [m]')
    parser.add_argument('--adaptive-threshold', type=float, help='override eta [m]')
    parser.add_argument('--smoothing', choices=SMOOTHING_MODES,
                        help='spline parameterisation (default chord)')
    parser.add_argument('--no-shortcut', action='store_true',
                        help='keep every grid node as a spline knot')
    parser.add_argument('--max-planning-time', type=float, help='search budget [s], 0 = none')


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog='uav-plan', description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest='command', required=True)

    plan = commands.add_parser('plan', help='plan once and print the result')
    _add_scene_options(plan)
    plan.add_argument('--algorithm', choices=ALGORITHMS, default='adaptive')
    plan.add_argument('--json', action='store_true', help='print one JSON object')

    compare = commands.add_parser('compare', help="the paper's table: every algorithm")
    _add_scene_options(compare)
    compare.add_argument('--repeats', type=int, default=5,
                         help='runs per algorithm; the median time is reported')
    compare.add_argument('--json', action='store_true', help='print JSON')
    compare.add_argument('--plot', metavar='PNG', help='also draw every path into this file')

    commands.add_parser('bench', help='performance figures of every shipped scene '
                        '(uav-plan bench --help)', add_help=False)

    plot = commands.add_parser('plot', help='draw the raw and the smoothed path in 3D')
    _add_scene_options(plot)
    plot.add_argument('--algorithm', choices=ALGORITHMS, default='adaptive')
    plot.add_argument('-o', '--output', required=True, metavar='PNG')
    return parser


def _scene_from_args(args: argparse.Namespace) -> Scene:
    scene = load_scene(find_scene(args.scene))
    changes = {}
    for option, name in (('resolution', 'resolution'), ('safety_margin', 'safety_margin'),
                         ('adaptive_threshold', 'adaptive_threshold'),
                         ('smoothing', 'smoothing'),
                         ('max_planning_time', 'max_planning_time')):
        if getattr(args, option) is not None:
            changes[name] = getattr(args, option)
    if args.no_shortcut:
        changes['shortcut'] = False
    return replace(scene, config=validate_config(replace(scene.config, **changes)))


def _warm_planner(scene: Scene) -> Planner:
    """A planner with its grid built and its kernels loaded, so the reported time is search."""
    planner = Planner(scene.config, scene.obstacles)
    planner.warm_up()
    return planner


def _run_plan(args: argparse.Namespace, scene: Scene) -> int:
    result = _warm_planner(scene).plan(scene.start, scene.goal, args.algorithm)
    if args.json:
        print(json.dumps(result_to_dict(result)))
    else:
        print(f'scene: {scene.name}')
        print(format_summary(result))
    return EXIT_OK if result.ok else EXIT_PLAN_FAILED


def _run_compare(args: argparse.Namespace, scene: Scene) -> int:
    if args.repeats < 1:
        raise InvalidInputError(f'--repeats must be >= 1, got {args.repeats}')
    rows = compare_algorithms(scene, repeats=args.repeats)
    if args.json:
        print(json.dumps({
            'scene': scene.name,
            'rows': [{'algorithm': row.algorithm, 'status': row.result.status.value,
                      'median_time_s': row.median_time_s, 'runs': row.runs,
                      'path_length_m': finite_or_none(row.result.path_length_m),
                      'expanded_nodes': row.result.expanded_nodes,
                      'relative_cost': finite_or_none(row.relative_cost),
                      'smoothed_length_m': finite_or_none(row.result.smoothed_length_m),
                      'min_clearance_m': finite_or_none(row.result.min_clearance_m)}
                     for row in rows]}))
    else:
        grid = f'{scene.config.resolution} m grid'
        print(f'{scene.name}: {len(scene.obstacles)} obstacles, {grid}, gamma '
              f'{scene.config.safety_margin} m, eta {scene.config.adaptive_threshold} m, '
              f'median of {args.repeats} runs')
        print(format_table(
            ['algorithm', 'time [ms]', 'length [m]', 'expanded', 'vs optimum',
             'smoothed [m]', 'clearance [m]', 'status'],
            [[row.algorithm, f'{row.median_time_s * 1e3:.3f}',
              f'{row.result.path_length_m:.3f}', str(row.result.expanded_nodes),
              f'{(row.relative_cost - 1) * 100:+.2f} %', f'{row.result.smoothed_length_m:.3f}',
              f'{row.result.min_clearance_m:.3f}', row.result.status.value]
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
    from uav_global_planner.cli.plotting import plot_scene_paths
    result = _warm_planner(scene).plan(scene.start, scene.goal, args.algorithm)
    print(format_summary(result))
    if not result.ok:
        return EXIT_PLAN_FAILED
    plot_scene_paths(scene, {f'{args.algorithm} raw': result.path,
                             f'{args.algorithm} smoothed': result.smoothed_path},
                     args.output, title=f'{scene.name}: {args.algorithm}')
    print(f'plot written to {args.output}')
    return EXIT_OK


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``uav-plan``; returns the process exit code."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['bench']:
        from uav_global_planner.cli.bench import main as bench_main
        return bench_main(argv[1:])
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as error:
        # plan --json promises one JSON object on stdout, even for a mistyped option.
        if argv[:1] == ['plan'] and '--json' in argv:
            _print_invalid_json(str(error), None)
        else:
            error.parser.print_usage(sys.stderr)
            print(f'{error.parser.prog}: error: {error.reason}', file=sys.stderr)
        return EXIT_INVALID_INPUT
    try:
        scene = _scene_from_args(args)
        runner = {'plan': _run_plan, 'compare': _run_compare, 'plot': _run_plot}[args.command]
        return runner(args, scene)
    except InvalidInputError as error:
        if getattr(args, 'json', False) and args.command == 'plan':
            _print_invalid_json(str(error), args.algorithm)
        else:
            print(f'uav-plan: error: {error}', file=sys.stderr)
        return EXIT_INVALID_INPUT


def _print_invalid_json(message: str, algorithm: Optional[str]) -> None:
    print(json.dumps({'status': PlanStatus.INVALID_INPUT.value, 'message': message,
                      'algorithm': algorithm, 'start': None, 'goal': None, 'path': [],
                      'path_length_m': None, 'expanded_nodes': 0, 'planning_time_s': None}))


if __name__ == '__main__':
    sys.exit(main())
