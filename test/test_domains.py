"""ROS domain choice: a domain in use is seen as such, and ROS_DOMAIN_ID sets the tests' base."""

import os
from pathlib import Path
import subprocess
import sys

import pytest

from uav_global_planner_tools.domains import (candidate_domains, choose_domain_id, domain_in_use,
                                              free_domain_id, SAFE_DOMAIN_IDS)
from uav_global_planner_tools.processes import localhost_discovery

HERE = Path(__file__).resolve().parent


def test_candidates_start_at_the_base_and_cover_every_safe_id_once():
    assert list(candidate_domains(40))[:3] == [40, 41, 42]
    # 102-214 are not safe: the next safe id after 101 is 215.
    assert list(candidate_domains(150))[0] == 215
    assert list(candidate_domains(232))[:2] == [232, 1]
    for start in (None, 0, 1, 77, 500):
        assert sorted(candidate_domains(start)) == sorted(SAFE_DOMAIN_IDS)
    assert 0 not in SAFE_DOMAIN_IDS


def test_a_tool_never_takes_the_shells_domain_unless_asked(monkeypatch):
    first = free_domain_id()  # the domain a tool in this process would take
    monkeypatch.setenv('ROS_DOMAIN_ID', str(first))
    chosen = choose_domain_id()
    assert chosen != first and chosen in SAFE_DOMAIN_IDS
    assert choose_domain_id(first) == first


@pytest.mark.ros
def test_a_running_participant_makes_its_domain_in_use():
    # rclpy only here: the test above runs without ROS.
    from uav_global_planner.ros.background_node import BackgroundNode
    domain_id = free_domain_id()
    assert not domain_in_use(domain_id)
    localhost_discovery()
    node = BackgroundNode('domain_probe', domain_id)
    try:
        assert domain_in_use(domain_id)
        assert free_domain_id(start=domain_id) != domain_id
        assert free_domain_id(start=domain_id, avoid=[domain_id]) != domain_id
    finally:
        node.close()
    assert not domain_in_use(domain_id)


@pytest.mark.ros
def test_ros_domain_id_is_the_first_domain_of_the_tests():
    base = free_domain_id(start=30)
    expected = [d for d in candidate_domains(base) if not domain_in_use(d)][:2]
    code = ('import ros_harness\n'
            'print(ros_harness.unique_domain_id(), ros_harness.unique_domain_id())\n')
    # A test run of its own, not a worker of this one (the test command's workers split the ids).
    env = {key: value for key, value in os.environ.items()
           if not key.startswith('PYTEST_XDIST_')}
    env['ROS_DOMAIN_ID'] = str(base)
    run = subprocess.run([sys.executable, '-c', code], cwd=HERE, env=env, capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert [int(v) for v in run.stdout.split()] == expected
    assert expected[0] == base
    # Worker gw1 of 2 takes only the ids at odd positions of the safe list, gw0 the even ones.
    for worker, parity in (('gw0', 0), ('gw1', 1)):
        split = dict(env, PYTEST_XDIST_WORKER=worker, PYTEST_XDIST_WORKER_COUNT='2')
        run = subprocess.run([sys.executable, '-c', code], cwd=HERE, env=split,
                             capture_output=True, text=True, timeout=60)
        assert run.returncode == 0, run.stderr
        taken = [int(v) for v in run.stdout.split()]
        assert [SAFE_DOMAIN_IDS.index(d) % 2 for d in taken] == [parity, parity], taken
