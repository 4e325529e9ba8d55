"""``uav-plan warmup``: compile the planner's kernels into their cache, once.

numba compiles a kernel the first time a process calls it with new argument types, and keeps the
machine code in its cache (:func:`uav_global_planner.core.jit.cache_dir`), so that later
processes load it in milliseconds. A first plan after an install, an upgrade or an emptied
cache waits for that compilation (seconds per kernel). This command pays it ahead: it plans
every shipped scene (the larger ones on a coarser grid: the same code, so the same kernel
specialisations), in the dense and in the block-sparse grid layout, and prints how many kernels
it compiled and how many the cache already held. Run it after installing, as the user that
plans (the cache is per user); running it again costs only the loading.
"""

import argparse
import sys
import time
from typing import List, Optional

from uav_global_planner.cli.options import HelpFormatter

_EXIT_CODES = ('exit codes:\n'
               '  0  every kernel the plans use is in the cache\n'
               '  1  a warm-up plan failed for another reason than its coarse grid\n'
               '  2  invalid options')


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='uav-plan warmup', description=__doc__.split('\n\n')[1]
                                     .replace('\n', ' '), formatter_class=HelpFormatter,
                                     epilog=_EXIT_CODES)
    parser.add_argument('scenes', nargs='*', metavar='SCENE',
                        help='shipped scenes to plan (default: every one)')
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``uav-plan warmup``; returns the exit code."""
    args = _parser().parse_args(argv)
    # The planner, imported once the options are read (not for --help).
    from uav_global_planner.cli.warm_kernels import warm_up
    from uav_global_planner.core import jit
    from uav_global_planner.core.errors import InvalidInputError
    from uav_global_planner.core.io.scene import shipped_scenes
    known = {path.stem for path in shipped_scenes()}
    unknown = [name for name in args.scenes if name not in known]
    if unknown:
        print(f'uav-plan warmup: error: no shipped scene {", ".join(unknown)} (shipped: '
              f'{", ".join(sorted(known))})', file=sys.stderr)
        return 2
    if not jit.JIT_ENABLED:
        print('uav-plan warmup: numba is off (not installed, or UAV_PLANNER_DISABLE_JIT=1): '
              'nothing to compile')
        return 0
    print(f"compiling the planner's kernels into {jit.cache_dir()} ...", flush=True)
    started = time.perf_counter()
    try:
        compiled, loaded, seconds = warm_up(args.scenes or None)
    except InvalidInputError as error:
        print(f'uav-plan warmup: error: {error}', file=sys.stderr)
        return 1
    print(f'{compiled} kernels compiled ({seconds:.1f} s), {loaded} loaded from the cache, '
          f'in {time.perf_counter() - started:.1f} s; cached in {jit.cache_dir()}')
    return 0
