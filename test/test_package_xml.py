"""package.xml declares every ROS package the code imports, so rosdep installs them all.

Every module of the package is parsed (imports inside functions included); an imported top-level
name is a ROS package when the ament index of this environment knows it (a file
``share/ament_index/resource_index/packages/<name>``).
"""

import ast
from pathlib import Path
import sys
import xml.etree.ElementTree as ElementTree

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / 'uav_global_planner'
# The tools (uav-demo, the ROS benchmark) are installed with the package and import ROS too.
TOOLS = REPO / 'uav_global_planner_tools'


def imported_names() -> dict:
    """Top-level module name -> the files importing it."""
    found: dict = {}
    for path in sorted(PACKAGE.rglob('*.py')) + sorted(TOOLS.rglob('*.py')):
        tree = ast.parse(path.read_text(encoding='utf-8'))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            else:
                continue
            for name in names:
                found.setdefault(name.split('.')[0], set()).add(path.relative_to(REPO).as_posix())
    return found


def ament_packages() -> set:
    """ROS packages registered in the ament index of this environment."""
    index = Path(sys.prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages'
    return {entry.name for entry in index.iterdir()} if index.is_dir() else set()


def declared() -> set:
    root = ElementTree.parse(REPO / 'package.xml').getroot()
    tags = ('depend', 'exec_depend', 'build_depend', 'test_depend')
    return {element.text.strip() for tag in tags for element in root.iter(tag)}


def test_every_imported_ros_package_is_declared():
    known = ament_packages()
    assert {'rclpy', 'nav_msgs', 'geometry_msgs'} <= known, 'no ament index found'
    imported = imported_names()
    ros = {name: files for name, files in imported.items() if name in known}
    assert 'rclpy' in ros and 'rcl_interfaces' in ros
    missing = {name: sorted(files) for name, files in ros.items() if name not in declared()}
    assert not missing, f'imported ROS packages missing from package.xml: {missing}'


def test_the_core_imports_no_ros_package():
    """The core runs without ROS, and imports no ROS package at all: the shipped scenes are
    package data (importlib.resources), not looked up in the ament index."""
    known = ament_packages()
    for name, files in imported_names().items():
        if name in known:
            assert not any(f.startswith('uav_global_planner/core/') for f in files), (name, files)
