"""Writes the outdoor scene files (town400, city1km, wall_gap) into config/scenes/.

Run from anywhere inside the project's environment::

    source scripts/venv.sh && python tools/make_scenes.py [--out DIR] [--check]

The geometry comes from :mod:`uav_global_planner_tools.outdoor_scenes` (fixed seeds,
coordinates rounded so the text reproduces them exactly), so the files are the same on every
run. Each file is parsed back
with the package's scene loader and compared with the generated geometry, and its start and
goal are checked to keep more than gamma from every obstacle (wall_gap: more than 3 m too).
``--check`` writes nothing and exits 1 when a file in place differs from what would be written.
"""

import argparse
from pathlib import Path
import sys
from typing import List, Optional

import numpy as np
import yaml

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import parse_scene
from uav_global_planner.core.map.grid import DEFAULT_MAX_VOXELS
from uav_global_planner_tools import outdoor_scenes

ROOT = Path(__file__).resolve().parents[1]
# Safety margins [m] each scene's start and goal must keep, beyond the scene's own.
EXTRA_MARGINS = {'wall_gap': (3.0,)}


def scene_files_take_max_voxels() -> bool:
    """True when the package's scene loader accepts a ``max_voxels`` key."""
    probe = {'bounds': {'min': [0.0, 0.0, 0.0], 'max': [1.0, 1.0, 1.0]}, 'resolution': 0.5,
             'safety_margin': 0.1, 'adaptive_threshold': 1.0, 'start': [0.0, 0.0, 0.0],
             'goal': [1.0, 1.0, 1.0], 'max_voxels': DEFAULT_MAX_VOXELS}
    try:
        parse_scene(probe, name='probe')
    except InvalidInputError:
        return False
    return True


def render(scene, with_max_voxels: bool) -> str:
    """The file text of one scene, checked by parsing it back.

    Raises
    ------
    RuntimeError
        When the parsed file differs from the generated geometry, or its start or goal is within
        a margin it must keep.
    """
    text = outdoor_scenes.scene_yaml(scene, with_max_voxels)
    base = PlannerConfig(max_voxels=max(scene.max_voxels or 0, DEFAULT_MAX_VOXELS))
    parsed = parse_scene(yaml.safe_load(text), name=scene.name, base=base)
    obstacles = parsed.obstacles
    if not (np.array_equal(obstacles.box_mins, scene.boxes[:, 0].reshape(-1, 3))
            and np.array_equal(obstacles.box_maxs, scene.boxes[:, 1].reshape(-1, 3))
            and np.array_equal(obstacles.sphere_centers, scene.spheres[:, :3].reshape(-1, 3))
            and np.array_equal(obstacles.sphere_radii, scene.spheres[:, 3])):
        raise RuntimeError(f'{scene.name}: the file text does not reproduce the geometry')
    clearance = obstacles.distance(np.stack([parsed.start, parsed.goal]))
    for margin in (scene.safety_margin, *EXTRA_MARGINS.get(scene.name, ())):
        if np.any(clearance <= margin):
            raise RuntimeError(f'{scene.name}: start or goal within {margin} m of an obstacle '
                               f'(clearances {clearance.tolist()} m)')
    return text


def main(argv: Optional[List[str]] = None) -> int:
    """Write (or with ``--check``, compare) every generated scene file."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', type=Path, default=ROOT / 'config' / 'scenes',
                        help='folder of the scene files (default: config/scenes)')
    parser.add_argument('--check', action='store_true',
                        help='compare with the files in place instead of writing them')
    args = parser.parse_args(argv)
    with_max_voxels = scene_files_take_max_voxels()
    stale = []
    for name, make in outdoor_scenes.SHIPPED.items():
        scene = make()
        text = render(scene, with_max_voxels)
        path = args.out / f'{name}.yaml'
        if args.check:
            current = path.read_text(encoding='utf-8') if path.is_file() else None
            if current != text:
                stale.append(path)
            continue
        args.out.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding='utf-8')
        print(f'{path}: {len(scene.boxes)} boxes, {len(scene.spheres)} spheres, '
              f'{scene.voxels / 1e6:.1f} M voxels, {len(text) / 1024:.0f} KiB')
        if scene.max_voxels is not None and not with_max_voxels:
            print(f'  note: {name} needs max_voxels = {scene.max_voxels}, and scene files do '
                  'not take max_voxels: load it with a PlannerConfig base that raises it',
                  file=sys.stderr)
    if stale:
        print('out of date (run python tools/make_scenes.py): '
              + ', '.join(str(path) for path in stale), file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
