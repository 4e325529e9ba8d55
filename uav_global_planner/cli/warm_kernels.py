"""The plans of ``uav-plan warmup``: every shipped scene (the larger ones on a coarser grid), in
the dense and in the block-sparse grid layout, so that numba compiles (or loads) every kernel
specialisation a plan uses (:mod:`uav_global_planner.cli.warmup`).
"""

from dataclasses import replace
import time
from typing import Callable, Optional, Sequence, Tuple

from uav_global_planner.core import jit
from uav_global_planner.core.config import validate_config
from uav_global_planner.core.errors import PlanningError
from uav_global_planner.core.io.scene import load_scene, Scene, shipped_scenes, with_ground
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.search.start_admission import admit, GOAL, START

# Largest grid each scene is planned on [nodes]: the shipped scenes up to town400 (13 M nodes)
# at their own resolution, since some code paths start at a grid size (a coarse corridor for a
# long search); larger scenes on a coarser grid, with the same code and kernel argument types.
_WARMUP_NODES = 14_000_000


def _coarse(scene: Scene, nodes: int = _WARMUP_NODES) -> Scene:
    """``scene`` on a grid of at most ``nodes`` nodes (its resolution raised)."""
    config = scene.config
    extent = [high - low for low, high in zip(config.bounds_min, config.bounds_max)]
    resolution = config.resolution
    while _node_count(extent, resolution) > nodes:
        resolution *= 1.25
    if resolution == config.resolution:
        return scene
    return replace(scene, config=validate_config(replace(config, resolution=resolution)))


def _node_count(extent: Sequence[float], resolution: float) -> int:
    count = 1
    for length in extent:
        count *= int(length // resolution) + 1
    return count


def _plan(planner: Planner, scene: Scene) -> None:
    """One plan from the scene's start to its goal (each admitted as ``uav-plan plan`` does);
    planning failures of the coarse grid are fine: the kernels they ran are compiled."""
    try:
        start = admit(planner, scene.start, START).point
        goal = admit(planner, scene.goal, GOAL).point
        planner.plan(start, goal, 'adaptive', via=scene.via)
    except PlanningError:
        pass


def warm_scene(scene: Scene) -> None:
    """Plan ``scene`` on a coarse grid in both grid layouts (dense, then block-sparse),
    compiling (or loading) every kernel such a plan uses.

    Raises
    ------
    InvalidInputError
        When the scene cannot be planned at all (its settings refuse the coarse grid).
    """
    scene = _coarse(with_ground(scene, scene.terrain))
    planner = Planner(scene.config, scene.obstacles, unknown=scene.unknown)
    planner.warm_up()
    _plan(planner, scene)
    config = scene.config
    sparse = blocked_mask(planner.grid, planner.obstacles, config.planning_margin,
                          layout='sparse')
    if planner.set_map(scene.obstacles, sparse, config.grid_key()):
        planner.warm_up()
        _plan(planner, scene)


def warm_up(names: Optional[Sequence[str]] = None,
            say: Callable[[str], None] = print) -> Tuple[int, int, float]:
    """Compile (or load) the kernels of a plan of every shipped scene (or those ``names``).

    Returns
    -------
    tuple
        (kernels compiled, kernels loaded from the cache, seconds spent compiling).
    """
    paths = [path for path in shipped_scenes() if names is None or path.stem in names]
    for path in paths:
        started = time.perf_counter()
        warm_scene(load_scene(path))
        say(f'{path.stem}: {time.perf_counter() - started:.1f} s')
    counts = jit.kernel_counts()
    return counts.compiled, counts.loaded, jit.compile_seconds()
