"""mypy over the ROS-free core with the settings of setup.cfg ([mypy]): the types must check."""

import subprocess
import sys


def test_mypy_clean_on_core(repo_root):
    # No arguments: setup.cfg names the files (uav_global_planner/core) and every setting.
    run = subprocess.run([sys.executable, '-m', 'mypy', '--config-file', 'setup.cfg'],
                         cwd=repo_root, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert 'Success: no issues found' in run.stdout, run.stdout
