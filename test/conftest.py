"""Shared fixtures and helpers of the test suite."""

import os
from pathlib import Path
import sys

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SCENES = REPO_ROOT / 'config' / 'scenes'

# The ROS harness lives beside the tests.
sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_report_header(config) -> str:
    """Says where the ROS tests take their domain ids from (see ros_harness.py)."""
    base = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if base.isdigit():
        return f'ROS domain ids: from {base} on ($ROS_DOMAIN_ID), skipping those in use'
    return ('ROS domain ids: from a point derived from the process id, skipping those in use '
            '(ROS_DOMAIN_ID=N sets the first)')


@pytest.fixture(scope='session')
def repo_root() -> Path:
    """The repository's top folder."""
    return REPO_ROOT


@pytest.fixture(scope='session')
def scenes_dir() -> Path:
    """The folder of the shipped scene files."""
    return SCENES


#: Modules whose tests measure time or fly a simulator in real time: the test command runs
#: them alone, after the others have run on parallel workers (scripts/test.sh), so that a
#: latency or an odometry rate they assert is the planner's and not the other worker's load.
SERIAL_MODULES = frozenset({
    'test_budget',              # budgets against wall-clock time
    'test_follower_node',       # setpoint timing at 50 Hz
    'test_node_bounded_time',   # replans within a time bound
    'test_node_faults',         # parameter services answer within 1 s during a plan
    'test_node_load',           # the node under a 10 Hz cloud load
    'test_px4_closed_loop',     # RotorPy flown in real time at 100+ Hz odometry
    'test_px4_sim',             # the simulated vehicle in real time
})


def pytest_addoption(parser) -> None:
    """``--serial skip|only``: leave out the serial tests, or run only them (scripts/test.sh)."""
    parser.addoption('--serial', choices=('all', 'skip', 'only'), default='all',
                     help='run all tests (default), skip the serial ones, or only those')


def pytest_collection_modifyitems(config, items) -> None:
    """Marks the tests of :data:`SERIAL_MODULES` ``serial`` and applies ``--serial``."""
    choice = config.getoption('--serial')
    kept, dropped = [], []
    for item in items:
        serial = item.path.stem in SERIAL_MODULES
        if serial:
            item.add_marker(pytest.mark.serial)
        if choice == 'all' or serial == (choice == 'only'):
            kept.append(item)
        else:
            dropped.append(item)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept
