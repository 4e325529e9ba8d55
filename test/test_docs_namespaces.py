"""The documentation's namespaced parameter example, run as written.

The block under "One planner per vehicle: namespaces" is read from docs/node.md: its
``planner_node`` line is started as a process (the venv's console script, its arguments split as
a shell would), and each ``ros2 param set NODE NAME VALUE`` line is sent to NODE's parameter
service with VALUE read as ``ros2 param set`` reads it (YAML, rclpy's
``get_parameter_value``). There is no ``ros2`` command on PyPI, so that is the one part not run
literally.
"""

import re
import shlex
import shutil
from typing import List, Tuple

import pytest
from rclpy.parameter import get_parameter_value, Parameter, parameter_value_to_python

from ros_harness import (NodeProcess, READY_TEXT, REPO_ROOT, ros_environment, RosClient,
                         STARTUP_TIMEOUT_S, unique_domain_id, wait_future)

pytestmark = pytest.mark.ros

PAGE = REPO_ROOT / 'docs' / 'node.md'
HEADING = '## One planner per vehicle: namespaces'


def documented_block() -> List[str]:
    """The command lines of the first bash block after :data:`HEADING` in :data:`PAGE`."""
    text = PAGE.read_text(encoding='utf-8')
    assert HEADING in text, f'docs/node.md has no section {HEADING!r}'
    section = text.split(HEADING, 1)[1]
    match = re.search(r'```bash\n(.*?)```', section, re.S)
    assert match, 'no bash block in the section'
    return [line.strip() for line in match.group(1).splitlines() if line.strip()]


def split_block(lines: List[str]) -> Tuple[List[str], List[Tuple[str, str, str]]]:
    """The node command (without its trailing ``&``) and the (node, name, value) sets."""
    node_lines = [line for line in lines if line.startswith('planner_node ')]
    assert len(node_lines) == 1, lines
    command = shlex.split(node_lines[0].rstrip('&').strip())
    sets = []
    for line in lines:
        if line.startswith('ros2 param set '):
            words = shlex.split(line)
            assert len(words) == 6, line
            sets.append((words[3], words[4], words[5]))
    assert sets, 'the example sets no parameter'
    return command, sets


def test_the_namespaced_parameter_example_runs_as_written(monkeypatch) -> None:
    command, sets = split_block(documented_block())
    executable = shutil.which(command[0])
    assert executable, f'{command[0]} is not on PATH (the venv installs it)'
    domain_id = unique_domain_id()
    # Run from the repository root, as the documented commands are.
    monkeypatch.chdir(REPO_ROOT)
    node = NodeProcess([executable, *command[1:]], ros_environment(domain_id))
    client = None
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        names = {target for target, _, _ in sets}
        assert names == {'/uav1/global_planner'}, names
        helper = client.parameters('/uav1/global_planner')
        for target, name, text in sets:
            value = parameter_value_to_python(get_parameter_value(text))
            response = wait_future(helper.client.set_parameters([Parameter(name, value=value)]),
                                   10.0, f'ros2 param set {target} {name} {text}')
            (result,) = response.results
            assert result.successful, f'{name} {text}: {result.reason}'
        expected = {name: parameter_value_to_python(get_parameter_value(text))
                    for _, name, text in sets}
        assert helper.get(list(expected)) == expected
        # The node logs the change under its namespaced name.
        node.wait_for_output('parameters set: ', 10.0)
        assert '[uav1.global_planner]' in node.output, node.output[-2000:]
    finally:
        if client is not None:
            client.close()
        node.kill()
