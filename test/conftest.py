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
