"""Prints how fast a first plan comes: from an empty kernel cache, after ``uav-plan warmup``, and
once the cache is warm; the command line's start-up; the paper scenes' cold adaptive search.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_first_plan.py [--repeats N] [--scene S]

Every figure is the wall time of real ``uav-plan`` processes, started with their own
``XDG_CACHE_HOME`` and without ``NUMBA_CACHE_DIR``, as for a user who just installed the
package (the kernels then go to ``$XDG_CACHE_HOME/uav_global_planner/numba``). They write
Python's bytecode (into a folder of the benchmark, ``PYTHONPYCACHEPREFIX``), as an install
does, even where the environment sets ``PYTHONDONTWRITEBYTECODE``; the first run compiles it:

- first run: ``uav-plan plan SCENE`` with an empty cache (it compiles every kernel it uses);
- ``uav-plan warmup`` with another empty cache, then the first ``uav-plan plan SCENE``;
- later runs: ``uav-plan plan SCENE`` again, alternating between the two caches (median);
- start-up: from the start of the process to the plan's first work (the scene read, the
  options checked, the planner about to be built), and ``uav-plan --help``;
- cold search: the adaptive search time of ``uav-plan plan PAPER_SCENE --json``, the first
  search of a fresh process (median over processes).

Timing on a shared machine is noisy: runs are interleaved, medians are printed, and so is the
load average before and after. Figures only: nothing here asserts a speed.
"""

import argparse
import json
import os
from pathlib import Path
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Dict, List, Optional, Tuple

# Targets of the figures [s].
FIRST_RUN_TARGET_S = 2.5
LATER_RUN_TARGET_S = 0.8
STARTUP_TARGET_S = 0.5
COLD_SEARCH_TARGET_S = 0.2e-3
PAPER_SCENES = ('paper_medium', 'paper_high')

# Runs `uav-plan ARGS` in this process and prints the wall clock (time.time()) when the plan's
# own work begins: the scene is read, the options and the memory are checked.
_STARTUP_PROBE = """
import sys, time
from uav_global_planner.cli import commands
from uav_global_planner.cli.main import main
run_plan = commands._run_plan
def probe(args, scene):
    print(f'PLANNING_AT {time.time():.6f}', file=sys.stderr, flush=True)
    return run_plan(args, scene)
commands._run_plan = probe
sys.exit(main(sys.argv[1:]))
"""


def _environment(cache_home: Path, bytecode: Path) -> Dict[str, str]:
    env = dict(os.environ)
    env.pop('NUMBA_CACHE_DIR', None)
    env.pop('UAV_PLANNER_DISABLE_JIT', None)
    env.pop('PYTHONDONTWRITEBYTECODE', None)
    env['PYTHONPYCACHEPREFIX'] = str(bytecode)
    env['XDG_CACHE_HOME'] = str(cache_home)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return env


def _uav_plan() -> str:
    executable = shutil.which('uav-plan')
    if executable is None:
        sys.exit('uav-plan is not on PATH: source scripts/venv.sh first')
    return executable


def _timed(command: List[str], env: Dict[str, str]) -> Tuple[float, subprocess.CompletedProcess]:
    """Wall time [s] of one process, and the process."""
    started = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True, env=env, timeout=1800)
    elapsed = time.perf_counter() - started
    if run.returncode not in (0, 1):
        sys.exit(f'{" ".join(command)} failed ({run.returncode}):\n{run.stderr[-3000:]}')
    return elapsed, run


def _startup(env: Dict[str, str], scene: str) -> float:
    """Seconds from the process start to the plan's first work."""
    launched = time.time()
    run = subprocess.run([sys.executable, '-c', _STARTUP_PROBE, 'plan', scene],
                         capture_output=True, text=True, env=env, timeout=1800)
    for line in run.stderr.splitlines():
        if line.startswith('PLANNING_AT '):
            return float(line.split()[1]) - launched
    sys.exit(f'no start-up time in:\n{run.stderr[-3000:]}')


def _cold_search(env: Dict[str, str], scene: str) -> float:
    """The search time [s] of a fresh process's one adaptive plan of ``scene``."""
    _, run = _timed([_uav_plan(), 'plan', scene, '--algorithm', 'adaptive', '--json'], env)
    return float(json.loads(run.stdout.strip().splitlines()[-1])['planning_time_s'])


def _row(name: str, value_s: float, target_s: Optional[float], unit: str = 's') -> str:
    scale = 1e3 if unit == 'ms' else 1.0
    text = f'{name:<58} {value_s * scale:9.3f} {unit}'
    if target_s is not None:
        verdict = 'met' if value_s <= target_s else 'NOT met'
        text += f'   target <= {target_s * scale:g} {unit}: {verdict}'
    return text


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='town400', help='scene of the plan (default town400)')
    parser.add_argument('--repeats', type=int, default=5,
                        help='later runs, start-ups and cold searches measured (default 5)')
    args = parser.parse_args(argv)
    uav_plan = _uav_plan()
    load_before = os.getloadavg()
    print(f'load average before: {load_before[0]:.2f} {load_before[1]:.2f} '
          f'{load_before[2]:.2f} ({os.cpu_count()} cores)')
    with tempfile.TemporaryDirectory(prefix='uav_first_plan_') as folder:
        plain = _environment(Path(folder) / 'plain', Path(folder) / 'bytecode')
        warmed = _environment(Path(folder) / 'warmed', Path(folder) / 'bytecode')
        first_s, run = _timed([uav_plan, 'plan', args.scene], plain)
        compiled = [line for line in run.stderr.splitlines() if 'compiled' in line]
        warmup_s, warm_run = _timed([uav_plan, 'warmup'], warmed)
        after_warmup_s, _ = _timed([uav_plan, 'plan', args.scene], warmed)

        later: List[float] = []
        startups: List[float] = []
        helps: List[float] = []
        cold: Dict[str, List[float]] = {name: [] for name in PAPER_SCENES}
        for repeat in range(args.repeats):
            env = plain if repeat % 2 == 0 else warmed
            later.append(_timed([uav_plan, 'plan', args.scene], env)[0])
            startups.append(_startup(env, args.scene))
            helps.append(_timed([uav_plan, '--help'], env)[0])
            for name in PAPER_SCENES:
                cold[name].append(_cold_search(env, name))

    print(f'uav-plan plan {args.scene}, kernels cached in $XDG_CACHE_HOME/uav_global_planner/'
          f'numba; median of {args.repeats} where repeated')
    print(_row('first run, empty cache (compiles)', first_s, None))
    for line in compiled:
        print(f'    {line}')
    print(_row('uav-plan warmup, empty cache', warmup_s, None))
    print(f'    {warm_run.stdout.strip().splitlines()[-1]}')
    print(_row('first run after uav-plan warmup', after_warmup_s, FIRST_RUN_TARGET_S))
    print(_row('later runs', statistics.median(later), LATER_RUN_TARGET_S))
    print(_row('start-up to the first planning work', statistics.median(startups),
               STARTUP_TARGET_S))
    print(_row('uav-plan --help', statistics.median(helps), None))
    for name in PAPER_SCENES:
        print(_row(f'{name}: cold adaptive search (uav-plan plan --json)',
                   statistics.median(cold[name]), COLD_SEARCH_TARGET_S, 'ms'))
    load_after = os.getloadavg()
    print(f'load average after: {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
