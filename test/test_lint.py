"""flake8 with the ament settings (99 columns, single quotes, google import order)."""

import subprocess
import sys


def test_flake8_clean(repo_root):
    run = subprocess.run([sys.executable, '-m', 'flake8', '--config', 'setup.cfg',
                          'uav_global_planner', 'uav_global_planner_tools', 'test',
                          'benchmarks', 'tools', 'docs', 'setup.py'],
                         cwd=repo_root, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
