"""The planning core must work without ROS: importing it must not import rclpy."""

import subprocess
import sys


def test_core_import_does_not_import_rclpy():
    code = (
        'import sys\n'
        'import uav_global_planner.core.planner, uav_global_planner.core.io.scene\n'
        'import uav_global_planner.cli.main\n'
        "leaked = [m for m in sys.modules if m.split('.')[0] in "
        "('rclpy', 'geometry_msgs', 'nav_msgs', 'visualization_msgs', 'sensor_msgs')]\n"
        'print(leaked)\n'
        'sys.exit(1 if leaked else 0)\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_core_plans_without_rclpy(repo_root):
    code = (
        'import sys\n'
        "sys.modules['rclpy'] = None  # any import of rclpy now fails\n"
        'from uav_global_planner.core.io.scene import load_scene, find_scene\n'
        'from uav_global_planner.core.planner import Planner\n'
        "scene = load_scene(find_scene('paper_medium'))\n"
        'result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal)\n'
        'print(result.status.value)\n'
        'sys.exit(0 if result.ok else 1)\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=repo_root)
    assert run.returncode == 0, run.stdout + run.stderr


def test_the_public_api_plans_and_loads_nothing_before_it_is_used():
    # The names of the package's docstring, each from the module that defines it; a module of
    # the core imported alone does not load the planner (lazy names, PEP 562).
    code = (
        'import sys\n'
        'import uav_global_planner.core.map.grid\n'
        "assert 'uav_global_planner.core.planner' not in sys.modules\n"
        'import uav_global_planner.core as core\n'
        "assert 'uav_global_planner.core.planner' not in sys.modules\n"
        'from uav_global_planner.core import Planner, find_scene, load_scene\n'
        'from uav_global_planner.core import planner, errors\n'
        'from uav_global_planner.core.map import obstacles\n'
        'assert Planner is planner.Planner\n'
        'assert core.InvalidInputError is errors.InvalidInputError\n'
        'assert core.Sphere is obstacles.Sphere\n'
        'assert all(getattr(core, name) is not None for name in core.__all__)\n'
        'assert set(core.__all__) <= set(dir(core))\n'
        'try:\n'
        '    core.NoSuchName\n'
        'except AttributeError as error:\n'
        "    assert 'NoSuchName' in str(error)\n"
        'else:\n'
        '    sys.exit(2)\n'
        "scene = load_scene(find_scene('paper_medium'))\n"
        'result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal)\n'
        'sys.exit(0 if result.ok else 1)\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
