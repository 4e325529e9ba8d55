"""What every ``uav-plan`` command line shares: help that shows defaults and exit codes, values
that start with a minus sign, the scene argument and the algorithm option.
"""

import argparse
from pathlib import Path
import re
from typing import List, Optional, Sequence

from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.errors import InvalidInputError

#: The epilog of every ``uav-plan`` command's help.
EXIT_CODES = ('exit codes:\n'
              '  0  success (the plan, table, plot or mission file)\n'
              '  1  planning failure: no path, start or goal occupied or outside the map,\n'
              '     timeout, no certified mission\n'
              '  2  invalid input: options, scene or map files, or a plan larger than the\n'
              '     memory this machine has available')

# A value that starts with a minus sign but is no option: a number, a list of numbers
# (-50,100,40), a coordinate triple, -inf or -nan.
_NEGATIVE_VALUE = re.compile(r'^-(\d|\.\d|inf|nan)', re.IGNORECASE)
# An option that may take such a value: --name (without =value), or -x.
_LONG_OPTION = re.compile(r'^--[A-Za-z][-A-Za-z0-9_]*$')
_SHORT_OPTION = re.compile(r'^-[A-Za-z]$')


class HelpFormatter(argparse.HelpFormatter):
    """argparse's help layout, with the default of every option that does not state its own;
    text with indented lines (the exit codes) keeps its line breaks."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if '\n  ' in text:
            return ''.join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ''
        # Positionals, required options, --help (default SUPPRESS) and help that names its
        # default keep their text.
        if (action.help == argparse.SUPPRESS or not action.option_strings
                or action.required or action.default == argparse.SUPPRESS
                or 'default' in text.lower()):
            return text
        if action.nargs == 0:
            shown = 'off'
        elif action.default is None or action.default == []:
            shown = 'none'
        else:
            shown = '%(default)s'
        return f'{text} (default: {shown})' if text else f'default: {shown}'


def join_negative_values(argv: Sequence[str]) -> List[str]:
    """``argv`` with every option followed by a value that starts with a minus sign written as
    one word (``--via -50,100,40`` becomes ``--via=-50,100,40``, ``-o -1.png`` becomes
    ``-o-1.png``), so that argparse reads the value instead of taking it for an option. Words
    after ``--`` stay as they are.
    """
    words = list(argv)
    out: List[str] = []
    index = 0
    while index < len(words):
        word = words[index]
        if word == '--':
            out += words[index:]
            break
        following = words[index + 1] if index + 1 < len(words) else ''
        if _NEGATIVE_VALUE.match(following) and (
                _LONG_OPTION.match(word) or _SHORT_OPTION.match(word)):
            out.append(f'{word}={following}' if word.startswith('--') else word + following)
            index += 2
            continue
        out.append(word)
        index += 1
    return out


def scene_help() -> str:
    """Help of the scene argument, naming every shipped scene."""
    # Imported here: the scene module brings the planner, which ``uav-plan --help`` needs not.
    from uav_global_planner.core.io.scene import shipped_scenes
    names = ', '.join(path.stem for path in shipped_scenes()) or 'none installed'
    return ('scene YAML file (a path, which must exist), or the name of a shipped scene: '
            f'{names}')


def add_algorithm_option(parser: argparse.ArgumentParser) -> None:
    """``--algorithm``, with its choices and default explained."""
    parser.add_argument('--algorithm', choices=ALGORITHMS, default='adaptive',
                        help='search heuristic on the 26-connected grid: dijkstra (none), '
                        "astar (Euclidean), adaptive (the paper's eq. 12: fewest expansions, "
                        'paths a few percent longer, no bound), octile (optimal, fewer '
                        'expansions than astar), weighted (at most search_weight times the '
                        'optimum), bounded (at most bound times the optimum, proven for each '
                        'query); default %(default)s')


def check_image_file(option: str, text: Optional[str]) -> None:
    """Refuse an image file matplotlib cannot write, before anything is planned: its extension
    must name a format (``.png``, ``.pdf``, ``.svg``, ...) and its folder must exist.

    Raises
    ------
    InvalidInputError
        Naming ``option``, the file and the formats.
    """
    if text is None:
        return
    from matplotlib.backend_bases import FigureCanvasBase
    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    path = Path(text)
    if path.suffix[1:].lower() not in formats:
        raise InvalidInputError(f'{option}: {text}: the extension names no image format; use '
                                f'one of .{", .".join(formats)}')
    if not path.parent.is_dir():
        raise InvalidInputError(f'{option}: {text}: no such folder {path.parent}')
