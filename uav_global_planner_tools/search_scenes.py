"""The search scene family: one cluttered workspace at 6 M, 20 M, 100 M and 1 G grid nodes.

The workspace is the README's (and the paper's): 20 x 20 x 15 m, ENU map frame, from
[-10, -10, 0] to [10, 10, 15] m. Its obstacles are the 60 spheres of the shipped scene
``dense60_fine`` plus 20 axis-aligned boxes drawn here with ``numpy.random.default_rng(4820)``
(coordinates rounded to 1 cm), which together block 48 % of the nodes at gamma 0.2 m. Start
and goal are fixed, 27.1 m apart along the workspace diagonal; the boxes keep clear of both.

Only the resolution delta changes between the sizes (``delta = 1 / k`` m, so that 20 m and
15 m are whole numbers of cells where ``k`` is whole):

=====  ==========  ==================================
size   delta [m]   grid
=====  ==========  ==================================
6M     1/10        201 x 201 x 151 = 6.10 M nodes
20M    1/15        301 x 301 x 226 = 20.5 M nodes
100M   1/25.5      511 x 511 x 383 = 100.0 M nodes
1G     1/55        1101 x 1101 x 826 = 1.00 G nodes
=====  ==========  ==================================

Everything is built with the public API of the core (:class:`Planner`, :class:`PlannerConfig`,
the shapes, :func:`load_scene`); the blocked mask is the planner's own (its inflation, its
dense or block-sparse layout).
"""

from dataclasses import dataclass
import math
from typing import Dict, List, Tuple, Union

import numpy as np

from uav_global_planner.core import (Box, find_scene, load_scene, ObstacleSet, Planner,
                                     PlannerConfig, Sphere)

Triple = Tuple[float, float, float]

#: Workspace corners [m] (ENU): the README's workspace.
BOUNDS_MIN: Triple = (-10.0, -10.0, 0.0)
BOUNDS_MAX: Triple = (10.0, 10.0, 15.0)
#: Start and goal [m] (ENU), 27.1 m apart.
START: Triple = (-8.5, -8.5, 1.5)
GOAL: Triple = (8.5, 8.5, 14.0)
#: Safety margin gamma and adaptive threshold eta [m].
SAFETY_MARGIN = 0.2
ADAPTIVE_THRESHOLD = 1.5
#: Seed of the 20 boxes.
BOX_SEED = 4820
BOX_COUNT = 20
#: No box comes closer than this to the start or the goal [m].
BOX_KEEP_OUT = 1.5
#: Size label -> cells per metre k (delta = 1 / k m).
CELLS_PER_METRE: Dict[str, float] = {'6M': 10.0, '20M': 15.0, '100M': 25.5, '1G': 55.0}
SIZES: Tuple[str, ...] = tuple(CELLS_PER_METRE)


@dataclass(frozen=True, eq=False)
class SearchScene:
    """One member of the family.

    Attributes
    ----------
    size : str
        Its label (``'6M'``, ...), or ``'delta=<value>'`` for another resolution.
    config : PlannerConfig
        Bounds, delta, gamma 0.2 m, eta 1.5 m, a node cap that admits the grid, and no
        whole-plan time limit (``max_planning_time`` 0: a benchmark times the stages itself).
    obstacles : ObstacleSet
        60 spheres and 20 boxes [m], ENU.
    start, goal : tuple of float
        [m], ENU.
    """

    size: str
    config: PlannerConfig
    obstacles: ObstacleSet
    start: Triple
    goal: Triple

    @property
    def shape(self) -> Tuple[int, int, int]:
        """Nodes per axis (the grid rule: floor(extent / delta) + 1)."""
        return grid_shape(self.config.resolution)

    @property
    def nodes(self) -> int:
        """Number of grid nodes."""
        return int(np.prod(self.shape, dtype=np.int64))

    def planner(self) -> Planner:
        """A planner over the scene (the grid and its mask are built on first use)."""
        return Planner(self.config, self.obstacles)


def grid_shape(resolution: float) -> Tuple[int, int, int]:
    """Nodes per axis of the workspace at ``resolution`` [m]."""
    extent = np.asarray(BOUNDS_MAX) - np.asarray(BOUNDS_MIN)
    nx, ny, nz = (int(n) for n in np.floor(extent / resolution + 1e-9) + 1)
    return nx, ny, nz


def resolution_of(size: Union[str, float]) -> float:
    """delta [m] of a size label, or ``size`` itself when it is a number (a delta in metres)."""
    if isinstance(size, str):
        if size not in CELLS_PER_METRE:
            raise ValueError(f'size must be one of {", ".join(SIZES)} or a delta in metres, '
                             f'got {size!r}')
        return 1.0 / CELLS_PER_METRE[size]
    value = float(size)
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f'size: a delta must be > 0 m, got {size!r}')
    return value


def _boxes() -> List[Box]:
    """The 20 boxes: footprints 1-4 m, heights 2-10 m, kept off the start and the goal."""
    rng = np.random.default_rng(BOX_SEED)
    low, high = np.asarray(BOUNDS_MIN), np.asarray(BOUNDS_MAX)
    ends = np.array([START, GOAL])
    boxes: List[Box] = []
    while len(boxes) < BOX_COUNT:
        size = np.array([*rng.uniform(1.0, 4.0, 2), rng.uniform(2.0, 10.0)])
        centre = rng.uniform(low, high)
        minimum = np.round(np.maximum(centre - size / 2.0, low), 2)
        maximum = np.round(np.minimum(centre + size / 2.0, high), 2)
        # Distance from each endpoint to the box [m].
        gap = np.linalg.norm(np.maximum(np.maximum(minimum - ends, ends - maximum), 0.0), axis=1)
        if np.all(gap > BOX_KEEP_OUT):
            boxes.append(Box(minimum, maximum))
    return boxes


def scene_obstacles() -> ObstacleSet:
    """The 60 spheres of ``dense60_fine`` and the 20 boxes [m], ENU."""
    spheres = load_scene(find_scene('dense60_fine')).obstacles
    items: List[Union[Sphere, Box]] = [
        Sphere(centre, radius)
        for centre, radius in zip(spheres.sphere_centers, spheres.sphere_radii)]
    items.extend(_boxes())
    return ObstacleSet(items)


def search_scene(size: Union[str, float], obstacles: Union[ObstacleSet, None] = None
                 ) -> SearchScene:
    """The scene at one size.

    Parameters
    ----------
    size : str or float
        ``'6M'``, ``'20M'``, ``'100M'``, ``'1G'``, or a delta [m] (small grids for tests).
    obstacles : ObstacleSet, optional
        :func:`scene_obstacles` built once by the caller; built here when None.

    Raises
    ------
    ValueError
        For an unknown size label or a delta that is not > 0.
    """
    resolution = resolution_of(size)
    nodes = int(np.prod(grid_shape(resolution), dtype=np.int64))
    config = PlannerConfig(
        bounds_min=BOUNDS_MIN, bounds_max=BOUNDS_MAX, resolution=resolution,
        safety_margin=SAFETY_MARGIN, adaptive_threshold=ADAPTIVE_THRESHOLD,
        max_planning_time=0.0, max_voxels=max(nodes, PlannerConfig().max_voxels))
    label = size if isinstance(size, str) else f'delta={resolution:g}'
    return SearchScene(size=label, config=config,
                       obstacles=scene_obstacles() if obstacles is None else obstacles,
                       start=START, goal=GOAL)


def blocked_fraction(blocked) -> float:
    """Fraction of blocked nodes of a dense or block-sparse mask."""
    count = (blocked.count_blocked() if hasattr(blocked, 'count_blocked')
             else int(np.count_nonzero(blocked)))
    return count / float(np.prod(blocked.shape, dtype=np.int64))


def parse_sizes(text: str) -> List[Union[str, float]]:
    """Sizes from a comma-separated list: labels (``'6M,20M'``) or deltas in metres.

    Raises
    ------
    ValueError
        Naming the entry that is neither.
    """
    sizes: List[Union[str, float]] = []
    for part in (p.strip() for p in text.split(',')):
        if not part:
            continue
        if part in CELLS_PER_METRE:
            sizes.append(part)
            continue
        try:
            value = float(part)
        except ValueError:
            raise ValueError(f'size must be one of {", ".join(SIZES)} or a delta in metres, '
                             f'got {part!r}') from None
        sizes.append(resolution_of(value))
    if not sizes:
        raise ValueError('no size given')
    return sizes
