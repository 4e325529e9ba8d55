"""The ament_python layout: ``colcon build`` installs a package that ``ros2 run`` could start.

The repository is copied into a temporary workspace (without .venv, .git and build output), so
nothing is written into the checkout. The installed ``planner_node`` is started from the install
space, with only the install space on PYTHONPATH ahead of the venv, and must log its ready line
and exit 0 on SIGINT. ``colcon test`` then runs a small, ROS-process-free test selection from the
workspace with ``--return-code-on-test-failure``.
"""

import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys

import pytest

from ros_harness import (assert_clean_exit, NodeProcess, planner_command, READY_TEXT,
                         ros_environment, STARTUP_TIMEOUT_S, unique_domain_id)

pytestmark = [pytest.mark.ros, pytest.mark.slow]

PACKAGE = 'uav_global_planner'
_IGNORED = shutil.ignore_patterns('.venv', '.git', 'build', 'install', 'log', '__pycache__',
                                  '*.egg-info', '.pytest_cache', '.hypothesis', '*.png')


def _colcon() -> str:
    found = shutil.which('colcon', path=str(Path(sys.executable).parent)) or shutil.which(
        'colcon')
    if found is None:
        pytest.skip('colcon is not installed (pip install colcon-common-extensions)')
    return found


def _run(command, cwd: Path, env=None, timeout_s: float = 300.0) -> subprocess.CompletedProcess:
    run = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True,
                         timeout=timeout_s)
    assert run.returncode == 0, (f'{" ".join(map(str, command))} failed with '
                                 f'{run.returncode}:\n{run.stdout[-4000:]}\n{run.stderr[-4000:]}')
    return run


@pytest.fixture(scope='module')
def workspace(tmp_path_factory, repo_root):
    """A colcon workspace with the package built into ``install/``."""
    root = tmp_path_factory.mktemp('colcon_ws')
    shutil.copytree(repo_root, root / 'src' / PACKAGE, ignore=_IGNORED)
    colcon = _colcon()
    _run([colcon, '--log-base', str(root / 'log'), 'build', '--base-paths', str(root / 'src'),
          '--build-base', str(root / 'build'), '--install-base', str(root / 'install'),
          '--event-handlers', 'console_direct-'], cwd=root)
    return root


def _installed_env(workspace: Path, domain_id: int) -> dict:
    """What ``source install/setup.bash`` would add for this package, on top of the venv."""
    prefix = workspace / 'install' / PACKAGE
    site = prefix / 'lib' / f'python{sys.version_info.major}.{sys.version_info.minor}' / \
        'site-packages'
    env = ros_environment(domain_id)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(site), env.get('PYTHONPATH')]))
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(
        filter(None, [str(prefix), env.get('AMENT_PREFIX_PATH')]))
    return env


def test_install_space_layout(workspace, repo_root):
    prefix = workspace / 'install' / PACKAGE
    share = prefix / 'share' / PACKAGE
    assert (share / 'package.xml').is_file()
    assert (share / 'config' / 'planner.yaml').is_file()
    assert (share / 'config' / 'scenes' / 'paper_medium.yaml').is_file()
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).is_file()
    for script in ('planner_node', 'scene_publisher', 'uav-demo'):
        assert os.access(prefix / 'lib' / PACKAGE / script, os.X_OK), script
    # The package data beside the modules (what the core finds the shipped scenes by), and the
    # tools package that uav-demo runs.
    site = prefix / 'lib' / f'python{sys.version_info.major}.{sys.version_info.minor}' / \
        'site-packages'
    assert (site / PACKAGE / 'config' / 'scenes' / 'paper_medium.yaml').is_file()
    assert (site / PACKAGE / 'config' / 'planner.yaml').is_file()
    assert (site / 'uav_global_planner_tools' / 'demo.py').is_file()
    for output in ('build', 'install', 'log'):
        assert not (repo_root / output).exists(), f'colcon wrote {output}/ into the checkout'


def test_installed_planner_node_starts_and_stops_cleanly(workspace):
    prefix = workspace / 'install' / PACKAGE
    env = _installed_env(workspace, unique_domain_id())
    # The installed copy, not the checkout, must be the one imported.
    where = _run([sys.executable, '-c', 'import uav_global_planner.ros.planner_node as m; '
                  'print(m.__file__)'], cwd=workspace, env=env)
    assert where.stdout.strip().startswith(str(prefix)), where.stdout
    command = planner_command(
        params_file=prefix / 'share' / PACKAGE / 'config' / 'planner.yaml',
        executable=str(prefix / 'lib' / PACKAGE / 'planner_node'))
    node = NodeProcess(command, env)
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        assert_clean_exit(node, node.stop(signal.SIGINT))
    finally:
        node.kill()


def test_colcon_test_runs_a_small_selection(workspace):
    run = _run([_colcon(), '--log-base', str(workspace / 'log'), 'test', '--base-paths',
                str(workspace / 'src'), '--build-base', str(workspace / 'build'),
                '--install-base', str(workspace / 'install'), '--packages-select', PACKAGE,
                '--event-handlers', 'console_direct+', '--return-code-on-test-failure',
                '--pytest-args', 'test/test_node_conversions.py', '-k', 'marker', '-q'],
               cwd=workspace)
    assert ' passed' in run.stdout, run.stdout[-3000:]
