"""Build script for the uav_global_planner ament_python package."""

from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'uav_global_planner'

setup(
    name=package_name,
    version='0.1.0',
    # The library (core, ros, cli), the tools built on it (demo, ROS benchmark), and config/ as
    # the package data uav_global_planner/config: the shipped scenes and planner.yaml are then
    # found with importlib.resources wherever pip or colcon installed the package.
    packages=find_packages(exclude=['test']) + [package_name + '.config'],
    package_dir={package_name + '.config': 'config'},
    package_data={package_name + '.config': ['*.yaml', 'scenes/*.yaml']},
    # The share copy is what ros2 launch files and --params-file point at.
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (os.path.join('share', package_name, 'config'), glob('config/*.yaml')),
        (os.path.join('share', package_name, 'config', 'scenes'), glob('config/scenes/*.yaml')),
    ],
    # Versions are pinned in requirements.txt only.
    install_requires=['setuptools', 'numpy', 'scipy', 'pyyaml', 'numba', 'matplotlib'],
    extras_require={'test': ['pytest', 'pytest-xdist', 'hypothesis', 'psutil', 'flake8',
                             'pymavlink', 'mavsdk'],
                    # Map frame <-> WGS84 for mission export (core/geodesy.py).
                    'geodesy': ['pymap3d'],
                    # GeoTIFF terrain (core/dem.py), imported only when one is read.
                    'terrain': ['rasterio'],
                    # Readers of map files (core/mapfiles.py), imported only when used.
                    'maps': ['pypcd4', 'plyfile', 'laspy', 'lazrs', 'octomap-python'],
                    # The interactive 3D view of uav-plan plot --html.
                    'plot': ['plotly'],
                    # The time-optimal reference of benchmarks/bench_timing.py.
                    'bench': ['copp-py'],
                    # Closed-loop flights in RotorPy (uav_global_planner_tools/flight).
                    'flight': ['rotorpy'],
                    # A fleet's missions planned in parallel on Ray (uav-plan fleet).
                    'fleet': ['ray'],
                    # setpoint_follower --mavlink (ArduPilot, MAVSDK, PX4 over MAVLink).
                    'mavlink': ['pymavlink'],
                    # The peers that benchmarks/bench_search_peers.py measures against.
                    'peers': ['ompl', 'dijkstra3d'],
                    # The documentation in docs/ (Sphinx with MyST).
                    'docs': ['sphinx', 'myst-parser', 'furo']},
    # The shipped scenes are read as files (importlib.resources paths), so never as a zip.
    zip_safe=False,
    maintainer='uav_global_planner maintainers',
    maintainer_email='maintainers@uav-global-planner.invalid',
    description='3D global path planner for quadcopters with a ROS 2 node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uav-plan = uav_global_planner.cli.main:main',
            'planner_node = uav_global_planner.ros.planner_node:main',
            'scene_publisher = uav_global_planner.ros.scene_publisher:main',
            'setpoint_follower = uav_global_planner.ros.follower_node:main',
            'uav-demo = uav_global_planner_tools.demo:main',
        ],
        # Figures that the tools add to uav-plan bench (its --ros and --outdoor flags), so
        # that the command-line tool runs them without importing the tools.
        'uav_global_planner.bench': [
            'ros = uav_global_planner_tools.latency_bench.uav_plan_bench:ros_figures',
            'outdoor = uav_global_planner_tools.outdoor_bench:main',
        ],
    },
)
