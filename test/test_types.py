"""mypy over the core, the ROS node and the command line with the settings of setup.cfg
([mypy]): the types must check."""

import configparser
import subprocess
import sys

#: The packages setup.cfg's [mypy] ``files`` must name (so none drops out of the check).
CHECKED = ('uav_global_planner/core', 'uav_global_planner/ros', 'uav_global_planner/cli',
           'uav_global_planner/fleet_ray')


def test_mypy_settings_cover_core_ros_and_cli(repo_root):
    config = configparser.ConfigParser()
    config.read(repo_root / 'setup.cfg')
    files = {name.strip().rstrip('/') for name in config['mypy']['files'].split(',')}
    assert set(CHECKED) <= files, f'[mypy] files = {sorted(files)}; must name {CHECKED}'


def test_mypy_clean_on_core_ros_and_cli(repo_root):
    # No arguments: setup.cfg names the files and every setting.
    run = subprocess.run([sys.executable, '-m', 'mypy', '--config-file', 'setup.cfg'],
                         cwd=repo_root, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert 'Success: no issues found' in run.stdout, run.stdout
