"""The planning core must work without ROS: importing it must not import rclpy."""

import subprocess
import sys


def test_core_import_does_not_import_rclpy():
    code = (
        'import sys\n'
        'import uav_global_planner.core.planner, uav_global_planner.core.scene\n'
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
        'from uav_global_planner.core.scene import load_scene, find_scene\n'
        'from uav_global_planner.core.planner import Planner\n'
        "scene = load_scene(find_scene('paper_medium'))\n"
        'result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal)\n'
        'print(result.status.value)\n'
        'sys.exit(0 if result.ok else 1)\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=repo_root)
    assert run.returncode == 0, run.stdout + run.stderr
