"""Dependencies point one way: core <- cli, core <- ros, and the tools on top of all three.

Every module of ``uav_global_planner`` and ``uav_global_planner_tools``, and every script of
``benchmarks/`` and ``tools/``, is parsed (imports inside
functions included, relative imports resolved), and so is every string that names one of their
modules outside a docstring (``python -m ...``, ``importlib.import_module(...)``), since running
a module is a dependency too. The layers and what each may not use:

=========  ===================================  ==============================================
layer      modules                              must not use
=========  ===================================  ==============================================
core       uav_global_planner.core (and the     ros, cli, tools, fleet_ray, scripts, rclpy or
           package's ``__init__``)              any ROS package
ros        uav_global_planner.ros               cli, tools, scripts
cli        uav_global_planner.cli               ros, tools, scripts, rclpy or any ROS package
fleet_ray  uav_global_planner.fleet_ray         ros, cli, tools, scripts, rclpy or any ROS
                                                package
tools      uav_global_planner_tools             scripts
scripts    benchmarks/*.py, tools/*.py          (anything)
=========  ===================================  ==============================================
"""

import ast
from pathlib import Path
import re
import sys
from typing import Dict, Iterator, List, Optional, Set, Tuple

import pytest

REPO = Path(__file__).resolve().parents[1]
LIBRARY = 'uav_global_planner'
TOOLS = 'uav_global_planner_tools'
ROS = 'ros-packages'

#: Layer -> the layers (and ROS itself) it must not use.
FORBIDDEN = {'core': {'ros', 'cli', 'tools', 'fleet_ray', 'scripts', ROS},
             'ros': {'cli', 'tools', 'scripts'},
             'cli': {'ros', 'tools', 'scripts', ROS},
             'fleet_ray': {'ros', 'cli', 'tools', 'scripts', ROS},
             'tools': {'scripts'},
             'scripts': set()}
#: Folders of scripts (benchmarks, scene makers): they may use every layer, and no installed
#: module may use them (they are not installed).
SCRIPT_FOLDERS = ('benchmarks', 'tools')

# ROS Python packages, when the ament index of this environment does not list them.
_ROS_NAMES = {'rclpy', 'ament_index_python', 'rosidl_runtime_py', 'rosidl_parser', 'launch',
              'launch_ros', 'tf2_ros', 'tf2_py', 'message_filters', 'rosbag2_py',
              'rpyutils', 'rmw_implementation'}
_ROS_SUFFIXES = ('_msgs', '_srvs', '_interfaces', '_actions')
# A dotted name of one of the two packages' modules, as a whole string.
_MODULE_STRING = re.compile(r'(uav_global_planner(_tools)?)(\.[A-Za-z_][A-Za-z0-9_]*)+')


def _ament_packages() -> Set[str]:
    index = Path(sys.prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages'
    return {entry.name for entry in index.iterdir()} if index.is_dir() else set()


def layer_of(module: str, ros_packages: Set[str]) -> Optional[str]:
    """Layer of a dotted module name: core, ros, cli, fleet_ray, tools, scripts (benchmarks/ and
    tools/), ROS (a ROS package) or None.

    ``uav_global_planner`` itself and its ``config`` data count as core.
    """
    parts = module.split('.')
    if parts[0] == TOOLS:
        return 'tools'
    if parts[0] in SCRIPT_FOLDERS:
        return 'scripts'
    if parts[0] == LIBRARY:
        if len(parts) == 1 or parts[1] in ('core', 'config', '__init__'):
            return 'core'
        if parts[1] in ('ros', 'cli', 'fleet_ray'):
            return parts[1]
        return 'unknown'
    if parts[0] in ros_packages or parts[0] in _ROS_NAMES or parts[0].endswith(_ROS_SUFFIXES):
        return ROS
    return None


def _module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts = parts[:-1]
    return '.'.join(parts)


def _docstring_nodes(tree: ast.AST) -> Set[int]:
    """ids of the string constants that are docstrings."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)):
                found.add(id(body[0].value))
    return found


def used_modules(path: Path, module: str) -> Iterator[Tuple[int, str]]:
    """(line, dotted name) of every module that ``path`` imports or names in a string."""
    tree = ast.parse(path.read_text(encoding='utf-8'), str(path))
    package = module if path.name == '__init__.py' else module.rpartition('.')[0]
    docstrings = _docstring_nodes(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')
                base = base[:len(base) - (node.level - 1)]
                target = '.'.join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ''
            yield node.lineno, target
            # from uav_global_planner import ros: the submodule is what is used.
            for alias in node.names:
                yield node.lineno, f'{target}.{alias.name}'
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
              and id(node) not in docstrings and _MODULE_STRING.fullmatch(node.value)):
            yield node.lineno, node.value


def violations(root: Path) -> List[str]:
    """Every use of a module that the using module's layer must not use, under ``root``."""
    ros_packages = _ament_packages()
    found = []
    files = sorted((root / LIBRARY).rglob('*.py')) + sorted((root / TOOLS).rglob('*.py'))
    for folder in SCRIPT_FOLDERS:
        files += sorted((root / folder).glob('*.py'))
    for path in files:
        module = _module_name(root, path)
        layer = layer_of(module, ros_packages)
        where = path.relative_to(root).as_posix()
        if layer not in FORBIDDEN:
            found.append(f'{where}: no layer for module {module} (add it to test_import_layers)')
            continue
        reported = set()
        for line, used in used_modules(path, module):
            used_layer = layer_of(used, ros_packages)
            # ``from a.b import c`` yields a.b and a.b.c: one report per line and layer.
            if used_layer in FORBIDDEN[layer] and (line, used_layer) not in reported:
                reported.add((line, used_layer))
                found.append(f'{where}:{line}: {layer} module uses {used} ({used_layer})')
    return found


def test_no_module_uses_a_layer_above_its_own():
    found = violations(REPO)
    assert not found, 'imports against the layering:\n' + '\n'.join(found)


def test_every_layer_has_modules():
    """The test looks at the real tree: each layer is there and the tools import the others."""
    files = {layer: [p for p in (REPO / LIBRARY / layer).rglob('*.py')]
             for layer in ('core', 'ros', 'cli')}
    files['tools'] = list((REPO / TOOLS).rglob('*.py'))
    assert all(len(paths) >= 2 for paths in files.values()), files
    used: Dict[str, Set[str]] = {}
    for path in files['tools']:
        module = _module_name(REPO, path)
        for _, name in used_modules(path, module):
            used.setdefault(layer_of(name, set()) or '', set()).add(name)
    assert {'core', 'ros', 'cli'} <= set(used), sorted(used)


@pytest.mark.parametrize('layer, source, expected', [
    ('core', 'import rclpy\n', 'uses rclpy'),
    ('core', 'def f():\n    from geometry_msgs.msg import Pose\n', 'uses geometry_msgs.msg'),
    ('core', 'from uav_global_planner.cli import plotting\n', 'uses uav_global_planner.cli'),
    ('core', 'from ..ros import conversions\n', 'uses uav_global_planner.ros'),
    ('ros', 'from uav_global_planner.cli.bench import format_table\n', '(cli)'),
    ('ros', 'from uav_global_planner_tools.processes import NodeProcess\n', '(tools)'),
    ('cli', "CHILD = ['-m', 'uav_global_planner.ros.planner_node']\n", '(ros)'),
    ('cli', 'from uav_global_planner import ros\n', 'uses uav_global_planner.ros'),
    ('cli', 'import uav_global_planner_tools.demo\n', '(tools)'),
    ('cli', 'from benchmarks.bench_outdoor import main\n', '(scripts)'),
    ('ros', 'import tools.make_scenes\n', '(scripts)'),
])
def test_an_upward_import_is_reported(tmp_path, layer, source, expected):
    folder = tmp_path / LIBRARY / layer
    folder.mkdir(parents=True)
    for init in (tmp_path / LIBRARY / '__init__.py', folder / '__init__.py'):
        init.write_text('"""Package."""\n', encoding='utf-8')
    (folder / 'planted.py').write_text(f'"""uav_global_planner.ros.x in a docstring."""\n{source}',
                                       encoding='utf-8')
    found = violations(tmp_path)
    assert len(found) >= 1 and all(f'{layer}/planted.py' in entry for entry in found), found
    assert any(expected in entry for entry in found), found


def test_allowed_directions_are_not_reported(tmp_path):
    for layer, source in (('core', 'import numpy\n'),
                          ('ros', 'import rclpy\nfrom uav_global_planner.core.io import scene\n'),
                          ('cli', 'from uav_global_planner.core.io.scene import find_scene\n')):
        folder = tmp_path / LIBRARY / layer
        folder.mkdir(parents=True)
        (folder / '__init__.py').write_text('', encoding='utf-8')
        (folder / 'fine.py').write_text(source, encoding='utf-8')
    (tmp_path / LIBRARY / '__init__.py').write_text('', encoding='utf-8')
    (tmp_path / TOOLS).mkdir()
    (tmp_path / TOOLS / 'demo.py').write_text(
        'import rclpy\nfrom uav_global_planner.cli import plotting\n'
        'from uav_global_planner.ros import names\n', encoding='utf-8')
    # A benchmark script uses every layer.
    (tmp_path / 'benchmarks').mkdir()
    (tmp_path / 'benchmarks' / 'bench_x.py').write_text(
        'import rclpy\nfrom uav_global_planner.ros import names\n'
        'from uav_global_planner_tools import demo\n', encoding='utf-8')
    assert violations(tmp_path) == []


def test_a_new_subpackage_needs_a_layer(tmp_path):
    folder = tmp_path / LIBRARY / 'extras'
    folder.mkdir(parents=True)
    (tmp_path / LIBRARY / '__init__.py').write_text('', encoding='utf-8')
    (folder / 'thing.py').write_text('import os\n', encoding='utf-8')
    assert violations(tmp_path) == [
        f'{LIBRARY}/extras/thing.py: no layer for module {LIBRARY}.extras.thing '
        '(add it to test_import_layers)']
