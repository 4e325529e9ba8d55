"""A plain ``pip install`` ships the scenes and planner.yaml: they resolve without the checkout.

The package is installed with pip (offline: ``--no-index --no-deps --no-build-isolation``, the
dependencies come from this environment) into a temporary ``--target`` folder from a copy of the
files a source distribution holds, so nothing is written into the checkout. The installed
``uav-plan`` then runs from a folder outside the checkout, with the target first on
``PYTHONPATH`` and no ``AMENT_PREFIX_PATH``: a shipped scene can only come from the package data.
"""

import json
import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

PACKAGE = 'uav_global_planner'
# What a source distribution of the package holds (tests, benchmarks and scripts stay behind).
_SOURCES = ('setup.py', 'setup.cfg', 'package.xml', 'resource', 'config', PACKAGE,
            'uav_global_planner_tools')
_IGNORED = shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info')


@pytest.fixture(scope='module')
def installed(tmp_path_factory, repo_root) -> Path:
    """The ``--target`` folder of a fresh pip install."""
    root = tmp_path_factory.mktemp('pip_install')
    source = root / 'source'
    source.mkdir()
    for name in _SOURCES:
        if (repo_root / name).is_dir():
            shutil.copytree(repo_root / name, source / name, ignore=_IGNORED)
        else:
            shutil.copy2(repo_root / name, source / name)
    target = root / 'target'
    run = subprocess.run([sys.executable, '-m', 'pip', 'install', '--no-index', '--no-deps',
                          '--no-build-isolation', '--target', str(target), str(source)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return target


def _outside_env(target: Path) -> dict:
    env = dict(os.environ)
    env.pop('AMENT_PREFIX_PATH', None)
    env['PYTHONPATH'] = str(target)
    # The lookup is under test, not the compiled kernels: the same search runs uncompiled.
    env['UAV_PLANNER_DISABLE_JIT'] = '1'
    return env


def test_package_data_holds_the_shipped_configuration(installed, repo_root):
    data = installed / PACKAGE / 'config'
    shipped = sorted(p.name for p in (repo_root / 'config' / 'scenes').glob('*.yaml'))
    assert shipped and sorted(p.name for p in (data / 'scenes').glob('*.yaml')) == shipped
    assert (data / 'planner.yaml').read_bytes() == (repo_root / 'config' / 'planner.yaml'
                                                    ).read_bytes()
    # The ament share copy stays, for ros2 launch files and --params-file.
    assert (installed / 'share' / PACKAGE / 'config' / 'scenes' / 'paper_medium.yaml').is_file()


def test_shipped_scene_and_config_resolve_from_the_install(installed, tmp_path):
    code = ('from uav_global_planner.core.io.scene import find_scene, shipped_scenes\n'
            'from uav_global_planner_tools.processes import find_config\n'
            "print(find_scene('paper_medium'))\n"
            'print(len(shipped_scenes()))\n'
            'print(find_config())\n')
    run = subprocess.run([sys.executable, '-c', code], cwd=tmp_path, env=_outside_env(installed),
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    scene, count, config = run.stdout.split()
    data = installed / PACKAGE / 'config'
    assert Path(scene) == data / 'scenes' / 'paper_medium.yaml'
    assert int(count) == len(list((data / 'scenes').glob('*.yaml')))
    assert Path(config) == data / 'planner.yaml'


def test_installed_uav_plan_plans_a_shipped_scene(installed, tmp_path):
    run = subprocess.run([sys.executable, str(installed / 'bin' / 'uav-plan'), 'plan',
                          'paper_medium', '--json'], cwd=tmp_path, env=_outside_env(installed),
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    result = json.loads(run.stdout)
    assert result['status'] == 'ok', result
    assert result['goal'] == [10.0, 5.0, 10.0]


def test_installed_entry_points_name_the_tools(installed):
    [info] = installed.glob(f'{PACKAGE}-*.dist-info')
    text = (info / 'entry_points.txt').read_text(encoding='utf-8')
    assert 'uav-demo = uav_global_planner_tools.demo:main' in text
    assert '[uav_global_planner.bench]' in text
    assert 'ros = uav_global_planner_tools.latency_bench.uav_plan_bench:ros_figures' in text
    assert 'outdoor = uav_global_planner_tools.outdoor_bench:main' in text


def test_installed_uav_plan_bench_outdoor_needs_no_checkout(installed, tmp_path):
    env = _outside_env(installed)
    env.pop('UAV_PLANNER_DISABLE_JIT')  # a benchmark: the compiled kernels, as installed
    run = subprocess.run([sys.executable, str(installed / 'bin' / 'uav-plan'), 'bench',
                          '--outdoor', 'wall_gap_0.2', '--json'], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    [case] = json.loads(run.stdout)['cases']
    assert case['case'] == 'wall_gap_0.2' and case['first']['status'] == 'ok', case
