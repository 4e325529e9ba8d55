"""Shared fixtures and helpers of the test suite."""

from pathlib import Path
import sys

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SCENES = REPO_ROOT / 'config' / 'scenes'

# The ROS harness lives beside the tests.
sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope='session')
def repo_root() -> Path:
    """The repository's top folder."""
    return REPO_ROOT


@pytest.fixture(scope='session')
def scenes_dir() -> Path:
    """The folder of the shipped scene files."""
    return SCENES
