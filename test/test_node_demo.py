"""``uav-demo`` end to end: planner_node and scene_publisher as processes, the plan over ROS."""

import re
import subprocess
import sys

import pytest

from ros_harness import ros_environment, STARTUP_TIMEOUT_S, unique_domain_id

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_demo_plans_paper_medium_over_ros_and_writes_the_plot(tmp_path):
    output = tmp_path / 'demo.png'
    domain_id = unique_domain_id()
    run = subprocess.run(
        [sys.executable, '-m', 'uav_global_planner.ros.demo', '--output', str(output),
         '--domain-id', str(domain_id), '--timeout', str(STARTUP_TIMEOUT_S)],
        env=ros_environment(domain_id), capture_output=True, text=True,
        timeout=STARTUP_TIMEOUT_S + 60, cwd=tmp_path)
    report = run.stdout + run.stderr
    assert run.returncode == 0, report
    assert 'Traceback' not in report
    assert re.search(r'status\s+: ok \(Nav2 code 0\)', report), report
    assert re.search(r'start source\s+: start_pose', report), report
    measured = re.search(r'min clearance\s+: \S+ m reported, (\S+) m measured on the received '
                         r'path \(gamma (\S+) m\)', report)
    assert measured is not None, report
    assert float(measured.group(1)) >= float(measured.group(2)) - 1e-6
    assert output.is_file() and output.stat().st_size > 10_000
