"""A first plan that does not wait: where the compiled kernels are kept, ``uav-plan warmup``,
and a command line that imports only what its command uses.

Every check runs ``uav-plan`` (or its ``main()``) in a fresh process with a cache folder of its
own, as on a machine where the package was just installed. The module's first test compiles
the kernels of a small scene once (tens of seconds on a slow machine); the others reuse them.
"""

import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
from typing import Dict, List

import pytest

from ros_harness import unique_domain_id
from uav_global_planner_tools.processes import ros_environment

# Lists the modules of a list that a uav-plan command line imported, as JSON on the last line.
_IMPORTED = """
import json, sys
from uav_global_planner.cli.main import main
try:
    code = main(sys.argv[2:])
except SystemExit as stop:
    code = stop.code
print(json.dumps({'code': code, 'imported': sorted(
    name for name in json.loads(sys.argv[1]) if name in sys.modules)}))
"""
_HEAVY = ['numba', 'scipy', 'scipy.interpolate', 'scipy.linalg', 'scipy.optimize', 'scipy.special',
          'matplotlib', 'plotly', 'rclpy', 'ray']
_SCENE = 'paper_medium'


def _environment(tmp_path: Path, cache_home: Path) -> Dict[str, str]:
    """A child's environment: its ROS domain and logs, and no cache folder but its own
    ``XDG_CACHE_HOME`` (the folder of a user that never ran the planner)."""
    env = ros_environment(unique_domain_id(), tmp_path / 'roslog')
    env.pop('NUMBA_CACHE_DIR', None)
    env.pop('UAV_PLANNER_DISABLE_JIT', None)
    env['XDG_CACHE_HOME'] = str(cache_home)
    return env


def _uav_plan(env: Dict[str, str], *args: str) -> subprocess.CompletedProcess:
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    return subprocess.run([executable, *args], capture_output=True, text=True, env=env,
                          timeout=900)


def _imported(env: Dict[str, str], modules: List[str], *args: str) -> dict:
    """Exit code and which of ``modules`` the command line ``args`` imported."""
    run = subprocess.run([sys.executable, '-c', _IMPORTED, json.dumps(modules), *args],
                         capture_output=True, text=True, env=env, timeout=900)
    return json.loads(run.stdout.strip().splitlines()[-1])


def _saved_and_loaded(stdout: str) -> tuple:
    """Kernel files numba wrote and read, from its NUMBA_DEBUG_CACHE lines (on stdout)."""
    saved = re.findall(r"\[cache\] data saved to '([^']+)'", stdout)
    loaded = re.findall(r"\[cache\] data loaded from '([^']+)'", stdout)
    return saved, loaded


@pytest.fixture(scope='module')
def warm_cache(tmp_path_factory) -> Path:
    """``XDG_CACHE_HOME`` of a user who ran ``uav-plan warmup paper_medium`` once."""
    home = tmp_path_factory.mktemp('cache_home')
    run = _uav_plan(_environment(home, home), 'warmup', _SCENE)
    assert run.returncode == 0, run.stdout + run.stderr
    return home


@pytest.mark.slow
def test_warmup_fills_the_user_cache_and_a_later_plan_compiles_nothing(warm_cache, tmp_path):
    folder = warm_cache / 'uav_global_planner' / 'numba'
    assert list(folder.rglob('*.nbi')) and list(folder.rglob('*.nbc'))
    env = _environment(tmp_path, warm_cache)
    env['NUMBA_DEBUG_CACHE'] = '1'
    again = _uav_plan(env, 'warmup', _SCENE)
    assert again.returncode == 0, again.stderr
    # Nothing left to compile: the second warm-up only loads.
    saved, _ = _saved_and_loaded(again.stdout)
    counts = re.search(r'(\d+) kernels compiled .*?, (\d+) loaded', again.stdout)
    assert counts and counts.group(1) == '0' and int(counts.group(2)) > 0, saved
    assert str(folder) in again.stdout

    plan = _uav_plan(env, 'plan', _SCENE, '--json')
    assert plan.returncode == 0, plan.stderr[-2000:]
    assert json.loads(plan.stdout.strip().splitlines()[-1])['status'] == 'ok'
    saved, loaded = _saved_and_loaded(plan.stdout)
    assert saved == [] and loaded, plan.stdout[-3000:]
    assert all(path.startswith(str(folder)) for path in loaded)
    assert 'compiling' not in plan.stderr


@pytest.mark.slow
def test_a_plan_that_compiles_says_so_and_names_the_cache(warm_cache, tmp_path):
    # A copy of the warm cache without one kernel the plan loads: that one is compiled again.
    home = tmp_path / 'home'
    shutil.copytree(warm_cache, home)
    env = _environment(tmp_path, home)
    env['NUMBA_DEBUG_CACHE'] = '1'
    first = _uav_plan(env, 'plan', _SCENE)
    _, loaded = _saved_and_loaded(first.stdout)
    assert loaded, first.stdout[-3000:]
    index = Path(loaded[0]).with_suffix('').with_suffix('.nbi')
    assert index.is_file(), index
    index.unlink()

    plan = _uav_plan(env, 'plan', _SCENE)
    assert plan.returncode == 0, plan.stderr[-2000:]
    saved, _ = _saved_and_loaded(plan.stdout)
    assert saved, plan.stdout[-3000:]
    folder = home / 'uav_global_planner' / 'numba'
    lines = [line for line in plan.stderr.splitlines() if 'kernels once' in line]
    assert len(lines) == 2 and all(str(folder) in line for line in lines), plan.stderr
    assert re.search(r"compiled the planner's kernels once \(\d+\.\d s\)", lines[1])


def test_an_explicit_cache_folder_is_kept(tmp_path):
    env = _environment(tmp_path, tmp_path / 'unused')
    env['NUMBA_CACHE_DIR'] = str(tmp_path / 'kernels')
    code = ('import os\nfrom uav_global_planner.core import jit\n'
            "print(jit.cache_dir(), os.environ['NUMBA_CACHE_DIR'])")
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=env,
                         timeout=300)
    assert run.stdout.split() == [str(tmp_path / 'kernels')] * 2, run.stderr


@pytest.mark.parametrize('args', [['--help'], ['warmup', '--help'], ['no-such-command']])
def test_the_help_imports_no_planner(args, tmp_path):
    result = _imported(_environment(tmp_path, tmp_path / 'cache'), _HEAVY, *args)
    assert result['code'] in (0, 2)
    assert result['imported'] == []


@pytest.mark.slow
def test_a_plan_imports_no_plotting_and_no_ros(warm_cache, tmp_path):
    result = _imported(_environment(tmp_path, warm_cache), _HEAVY, 'plan', _SCENE)
    assert result['code'] == 0
    # The planner's own (numba, scipy), not the plots', ROS' or the fleet's, nor the scipy
    # subpackages that take 0.7 s to import (the splines are the planner's own, and numba's
    # look for a BLAS is skipped: no kernel calls np.dot).
    assert result['imported'] == ['numba', 'scipy']


# Imports the planner, then plans a small scene: numba is imported by the first kernel call,
# and kernels that call kernels (in other modules) find their dispatchers.
_LAZY = """
import json, sys
import numpy as np
from uav_global_planner.core import jit, ObstacleSet, Planner, PlannerConfig, Sphere
from uav_global_planner.core.map import dense_inflation
before = 'numba' in sys.modules
config = PlannerConfig(bounds_min=(-2.0, -2.0, 0.0), bounds_max=(2.0, 2.0, 3.0), resolution=0.25)
result = Planner(config, ObstacleSet([Sphere([0.0, 0.0, 1.5], 0.6)])).plan(
    [-1.5, -1.5, 0.5], [1.5, 1.5, 2.0])
kernels = [value for value in vars(dense_inflation).values() if hasattr(value, 'py_func')]
print(json.dumps({'before': before, 'after': 'numba' in sys.modules, 'ok': result.ok,
                  'jit': jit.JIT_ENABLED, 'kernels': len(kernels),
                  'dispatchers': sum(type(k).__name__ == 'CPUDispatcher' for k in kernels)}))
"""


@pytest.mark.slow
def test_numba_is_imported_by_the_first_kernel_call(warm_cache, tmp_path):
    run = subprocess.run([sys.executable, '-c', _LAZY], capture_output=True, text=True,
                         env=_environment(tmp_path, warm_cache), timeout=900)
    result = json.loads(run.stdout.strip().splitlines()[-1])
    assert result['jit'] and result['ok'], run.stderr[-2000:]
    assert not result['before'] and result['after']
    # The module's kernels are numba's dispatchers once one ran.
    assert result['kernels'] > 0 and result['dispatchers'] == result['kernels']


def test_the_cache_folder_follows_xdg_cache_home(tmp_path):
    env = _environment(tmp_path, tmp_path / 'xdg')
    code = 'from uav_global_planner.core import jit\nprint(jit.cache_dir())'
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=env,
                         timeout=300)
    assert run.stdout.strip() == os.path.join(str(tmp_path / 'xdg'), 'uav_global_planner',
                                              'numba'), run.stderr
