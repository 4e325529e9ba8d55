"""``uav-demo`` end to end: planner_node and scene_publisher as processes, the plan over ROS."""

import re
import subprocess
import sys

import pytest

from ros_harness import ros_environment, STARTUP_TIMEOUT_S, unique_domain_id

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_demo_plans_paper_medium_over_ros_and_writes_the_plot(tmp_path):
    """Run as a user would, from a shell whose ROS_DOMAIN_ID is set: the demo keeps out of
    that domain and plans in one of its own."""
    output = tmp_path / 'demo.png'
    shell_domain = unique_domain_id()
    run = subprocess.run(
        [sys.executable, '-m', 'uav_global_planner_tools.demo', '--output', str(output),
         '--timeout', str(STARTUP_TIMEOUT_S)],
        env=ros_environment(shell_domain), capture_output=True, text=True,
        timeout=STARTUP_TIMEOUT_S + 60, cwd=tmp_path)
    report = run.stdout + run.stderr
    assert run.returncode == 0, report
    assert 'Traceback' not in report
    domain = re.search(r'ROS domain\s+: (\d+) \(its own', report)
    assert domain is not None, report
    assert int(domain.group(1)) not in (shell_domain, 0), report
    assert re.search(r'status\s+: ok \(Nav2 code 0\)', report), report
    assert re.search(r'start source\s+: start_pose', report), report
    measured = re.search(r'min clearance\s+: \S+ m reported, (\S+) m measured on the received '
                         r'path \(gamma (\S+) m\)', report)
    assert measured is not None, report
    assert float(measured.group(1)) >= float(measured.group(2)) - 1e-6
    assert output.is_file() and output.stat().st_size > 10_000
