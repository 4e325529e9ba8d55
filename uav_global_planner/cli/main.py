"""``uav-plan``: plan offline from a scene file, compare the algorithms, draw the paths.

Exit codes: 0 when the plan succeeded, 1 for a planning failure (no path, occupied or outside
start or goal, timeout), 2 for invalid input (scene file, options, a plan larger than the memory
the machine has available). ``--help`` of every command lists them.
"""

import argparse
import json
import sys
from typing import Any, Callable, Dict, List, NoReturn, Optional, Sequence

from uav_global_planner.cli.options import (add_algorithm_option, EXIT_CODES, HelpFormatter,
                                            join_negative_values, scene_help)
from uav_global_planner.core.settings import format_value, Kind, planner_settings, Setting
from uav_global_planner.core.status import PlanStatus

EXIT_OK = 0
EXIT_PLAN_FAILED = 1
EXIT_INVALID_INPUT = 2

# The sub-commands, in the order of the help, with their line there. bench, fleet and warmup
# read their own options (the main() of their modules).
_COMMANDS = {
    'plan': 'plan once and print the result',
    'compare': "the paper's table: every algorithm",
    'bench': 'performance figures of every shipped scene (uav-plan bench --help)',
    'fleet': "plan and deconflict a fleet's missions on Ray (uav-plan fleet --help)",
    'plot': 'draw the raw and the smoothed path in 3D',
    'export': 'write a certified mission file (QGroundControl .plan or QGC WPL 110)',
    'warmup': "compile the planner's kernels into their cache once, so that a first plan "
              'does not wait for it (uav-plan warmup --help)',
}
_OWN_PARSERS = ('bench', 'fleet', 'warmup')


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

    Sub-command parsers are made of the same class; unless told otherwise, each shows every
    option's default and the exit codes in its help.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault('formatter_class', HelpFormatter)
        kwargs.setdefault('epilog', EXIT_CODES)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        """Raise :class:`_UsageError` (argparse's hook; the default prints and exits 2)."""
        raise _UsageError(self, message)


def _triple(text: str) -> List[float]:
    """``X,Y,Z`` as three floats (an argparse type: ValueError becomes a usage error)."""
    parts = text.split(',')
    if len(parts) != 3:
        raise ValueError(f'expected X,Y,Z, got {text!r}')
    return [float(part) for part in parts]


def _add_scene_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('scene', help=scene_help())
    _add_setting_flags(parser)
    parser.add_argument('--map', action='append', default=[], metavar='FILE',
                        help='add the occupied points of a map file (.pcd, .ply, .las, .laz, .bt, '
                        '.npy); repeatable')
    parser.add_argument('--via', action='append', default=[], metavar='X,Y,Z', type=_triple,
                        help='a via-point [m] passed through exactly, in order, e.g. '
                        "--via -50,100,40; repeatable (replaces the scene's via list)")
    parser.add_argument('--terrain', metavar='FILE',
                        help='the ground as a digital elevation model: a GeoTIFF (placed with '
                        "the scene's geodetic_origin) or an ESRI ASCII grid .asc in the map "
                        "frame; replaces the scene's terrain")
    parser.add_argument('--geofence', metavar='FILE',
                        help='inclusion fences and no-fly zones from a YAML file or a '
                        "QGroundControl .plan (placed with the scene's geodetic_origin; .plan "
                        "fences span the bounds in height); replaces the scene's geofence")


# Placeholder of a number option, by unit: metres, seconds.
_METAVARS = {'m': 'M', 's': 'S'}


def _argument_type(entry: Setting) -> Callable[[str], Any]:
    """An argparse ``type`` converting a word and checking it with the table, so a flag
    refuses exactly what the node, scene files and validate_config refuse."""
    parse: Callable[[str], Any] = {Kind.INT: int, Kind.CHOICE: str,
                                   Kind.WORD_OR_NUMBER: str}.get(entry.kind, float)

    def convert(text: str) -> Any:
        value = parse(text)  # ValueError: argparse says "invalid float value: 'abc'"
        problem = entry.refusal(value)
        if problem is not None:
            raise argparse.ArgumentTypeError(f'{entry.name}{problem[0]} {problem[1]}')
        return entry.normalise(value)

    convert.__name__ = parse.__name__
    return convert


def _setting_dest(entry: Setting) -> str:
    return entry.name.replace('.', '_')


def _add_setting_flags(parser: argparse.ArgumentParser) -> None:
    """One flag per setting of the table that has one: its type checks the value with the
    table, its help text is the table's words (unit, accepted values, default)."""
    for entry in planner_settings():
        if entry.flag is None:
            continue
        dest = _setting_dest(entry)
        if entry.kind is Kind.BOOL:
            # A switch to the value that is not the default, e.g. --no-shortcut.
            parser.add_argument(entry.flag, dest=dest, action='store_const',
                                const=not entry.default, default=None,
                                help=f'{entry.help_text()} This flag sets it to '
                                f'{format_value(not entry.default)}.')
            continue
        metavar = ('{' + ','.join(entry.choices) + '}' if entry.kind is Kind.CHOICE
                   else '{' + ','.join(entry.choices) + ',Z}'
                   if entry.kind is Kind.WORD_OR_NUMBER
                   else 'N' if entry.kind is Kind.INT else _METAVARS.get(entry.unit, 'X'))
        parser.add_argument(entry.flag, dest=dest, type=_argument_type(entry),
                            metavar=metavar, help=entry.help_text())


def _add_plan_options(plan: argparse.ArgumentParser) -> None:
    _add_scene_options(plan)
    add_algorithm_option(plan)
    plan.add_argument('--json', action='store_true', help='print one JSON object')


def _add_compare_options(compare: argparse.ArgumentParser) -> None:
    _add_scene_options(compare)
    compare.add_argument('--repeats', type=int, default=5,
                         help='runs per algorithm; the median time is reported')
    compare.add_argument('--json', action='store_true', help='print JSON')
    compare.add_argument('--plot', metavar='PNG', help='also draw every path into this file')


def _add_plot_options(plot: argparse.ArgumentParser) -> None:
    _add_scene_options(plot)
    add_algorithm_option(plot)
    plot.add_argument('-o', '--output', metavar='PNG',
                      help='oblique, top and side views of the scene and the paths')
    plot.add_argument('--html', metavar='FILE',
                      help='an interactive 3D view (plotly) to rotate in a browser')
    plot.add_argument('--profile', metavar='PNG',
                      help='speed, acceleration, jerk and tilt against time, with the limits')


_COMMAND_OPTIONS: Dict[str, Callable[[argparse.ArgumentParser], None]] = {
    'plan': _add_plan_options, 'compare': _add_compare_options, 'plot': _add_plot_options}


def _parser(full: Optional[Sequence[str]] = None) -> argparse.ArgumentParser:
    """The ``uav-plan`` command line.

    Parameters
    ----------
    full : sequence of str, optional
        The sub-commands that get their options (all when None); the others get their name
        and help line only, so that ``uav-plan --help`` and one command's parser do not import
        what the other commands' options need (the shipped scenes, the mission module).
    """
    parser = _Parser(prog='uav-plan', description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest='command', required=True)
    for name, text in _COMMANDS.items():
        if name in _OWN_PARSERS or (full is not None and name not in full):
            commands.add_parser(name, help=text, add_help=False)
        elif name == 'export':
            from uav_global_planner.cli.export import add_export_command
            add_export_command(commands, _add_scene_options)
        else:
            _COMMAND_OPTIONS[name](commands.add_parser(name, help=text))
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``uav-plan``; returns the process exit code."""
    # Values such as --via -50,100,40 are read as values, not as options.
    argv = join_negative_values(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ['bench']:
        from uav_global_planner.cli.bench import main as bench_main
        return bench_main(argv[1:])
    if argv[:1] == ['fleet']:
        from uav_global_planner.cli.fleet import main as fleet_main
        return fleet_main(argv[1:])
    if argv[:1] == ['warmup']:
        from uav_global_planner.cli.warmup import main as warmup_main
        return warmup_main(argv[1:])
    # Only the command asked for gets its options: the help alone imports no planner.
    parser = _parser(full=argv[:1])
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
    # The planner and the scene modules, imported once a command needs them.
    from uav_global_planner.cli.commands import run_command
    return run_command(args)


def _print_invalid_json(message: str, algorithm: Optional[str]) -> None:
    print(json.dumps({'status': PlanStatus.INVALID_INPUT.value, 'message': message,
                      'algorithm': algorithm, 'start': None, 'goal': None, 'path': [],
                      'path_length_m': None, 'expanded_nodes': 0, 'planning_time_s': None}))


if __name__ == '__main__':
    sys.exit(main())
