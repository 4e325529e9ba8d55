"""Memory of a plan before it is allocated, and a limit that turns exhaustion into an error.

``uav-plan`` estimates what a plan's grid will take before building it (:func:`estimate`) and
compares it with what this process may still use (:func:`allowance_bytes`: the kernel's
``MemAvailable``, or less when the process has a data limit, ``ulimit -d``). A grid that does
not fit is refused up front with both figures (:func:`check`). The search's memory follows the
nodes it reaches, which no estimate knows in advance; :func:`limited` therefore caps the
process's data segment (``RLIMIT_DATA``) at the allowance while planning, so that running out
raises ``MemoryError`` (reported with the figures, exit code 2) instead of waking the kernel's
out-of-memory killer.

The figures follow the layouts of :mod:`uav_global_planner.core.map.sparse_grid` and
:mod:`uav_global_planner.core.search.grid_search`:

- dense grids (below ``SPARSE_MIN_NODES`` nodes): 1 byte a node of mask and 17 bytes a node of
  search records, all resident after a few queries, plus up to 20 bytes a node of heap;
- block-sparse grids: 4 bytes a brick of 512 nodes of mask table and 4 of search table, 512
  bytes per brick an obstacle's surface crosses (estimated from the surface areas), and 17
  bytes a node plus 24 an open-list entry in the bricks the search reaches.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import math
from pathlib import Path
import re
import resource
from typing import Iterator, Optional

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.sparse_grid import BRICK, BRICK_NODES, choose_layout

# Bytes a node: dense mask, search record (cost, stamp, heap position, parent), heap entry.
_MASK_BYTES = 1
_RECORD_BYTES = 17
_DENSE_HEAP_BYTES = 20
# Bytes a brick of the block-sparse mask table and of the search's brick table.
_TABLE_BYTES = 4
# Bytes an open-list entry of the block-sparse search.
_SPARSE_HEAP_BYTES = 24
# Bricks per brick face of surface area: a surface seldom lies in one layer of bricks, and the
# mask's pool grows by doubling while it is built. Measured: the estimate is 2.0-2.7 times the
# finished mask of city1km (delta 0.4 m), town400 (0.25 m) and paper_medium (0.03 m); on city1km
# 364 MiB against a peak of 193 MiB while the mask was built (137 MiB when done). It errs large.
_STRADDLE = 2.0

_GB = 1e9

#: Most nodes a search takes (node numbers are int32 in
#: :mod:`uav_global_planner.core.search.grid_search`).
SEARCH_MAX_NODES = 2 ** 31 - 1


def gigabytes(count: float) -> str:
    """``count`` bytes as text in GB (1e9 bytes), for messages."""
    return f'{count / _GB:.2f} GB' if count < 10 * _GB else f'{count / _GB:.1f} GB'


@dataclass(frozen=True)
class MemoryEstimate:
    """What a plan's grid and search take [bytes].

    Attributes
    ----------
    nodes : int
        Grid nodes.
    layout : str
        ``'dense'`` or ``'sparse'``
        (:func:`~uav_global_planner.core.map.sparse_grid.choose_layout`).
    grid_bytes : int
        Built before any search: the mask, and the search's per-node records (dense) or brick
        table (block-sparse); for a block-sparse grid the surface bricks are estimated from the
        obstacles' surface areas.
    search_bytes : int
        At most, on top of ``grid_bytes``, when the searches reach every node.
    """

    nodes: int
    layout: str
    grid_bytes: int
    search_bytes: int

    def describe(self) -> str:
        """One line: the figures in GB."""
        kind = 'block-sparse' if self.layout == 'sparse' else 'dense'
        return (f'grid of {self.nodes / 1e6:.1f} M nodes ({kind}): about '
                f'{gigabytes(self.grid_bytes)} before the search, up to '
                f'{gigabytes(self.grid_bytes + self.search_bytes)} if the search reaches every '
                'node')


def grid_nodes(config: PlannerConfig) -> int:
    """Nodes of the grid of ``config`` (paper eq. 7), without building it."""
    extent = np.asarray(config.bounds_max, dtype=np.float64) - np.asarray(config.bounds_min)
    return int(np.prod(np.floor(extent / config.resolution + 1e-9) + 1.0))


def _surface_area(config: PlannerConfig, obstacles: ObstacleSet) -> float:
    """Area of the obstacles' surfaces inflated by gamma, within reason [m^2]: boxes and
    spheres as grown by gamma, a ball of gamma per point, the bounds' floor per height field."""
    gamma = float(config.safety_margin)
    sizes = np.asarray(obstacles.box_maxs) - np.asarray(obstacles.box_mins) + 2.0 * gamma
    boxes = float(np.sum(2.0 * (sizes[:, 0] * sizes[:, 1] + sizes[:, 1] * sizes[:, 2]
                                + sizes[:, 2] * sizes[:, 0]))) if len(sizes) else 0.0
    spheres = float(np.sum(4.0 * math.pi * (np.asarray(obstacles.sphere_radii) + gamma) ** 2))
    ball = 4.0 * math.pi * max(gamma, float(config.resolution)) ** 2
    points = float(len(obstacles.points)) * ball
    extent = np.asarray(config.bounds_max, dtype=np.float64) - np.asarray(config.bounds_min)
    fields = float(len(obstacles.height_fields)) * float(extent[0] * extent[1])
    return boxes + spheres + points + fields


def estimate(config: PlannerConfig, obstacles: ObstacleSet) -> MemoryEstimate:
    """The memory of planning on the grid of ``config`` around ``obstacles``.

    Parameters
    ----------
    config : PlannerConfig
        Bounds [m] and resolution delta [m] give the grid; gamma [m] the inflated surfaces.
    obstacles : ObstacleSet
        Everything the grid is built from (map files and geofences included).
    """
    nodes = grid_nodes(config)
    layout = choose_layout(nodes)
    if layout == 'dense':
        return MemoryEstimate(nodes, layout, nodes * (_MASK_BYTES + _RECORD_BYTES),
                              nodes * _DENSE_HEAP_BYTES)
    bricks = -(-nodes // BRICK_NODES)
    face = (BRICK * float(config.resolution)) ** 2
    surface = min(bricks, int(_STRADDLE * _surface_area(config, obstacles) / face))
    return MemoryEstimate(nodes, layout,
                          2 * _TABLE_BYTES * bricks + surface * BRICK_NODES * _MASK_BYTES,
                          nodes * (_RECORD_BYTES + _SPARSE_HEAP_BYTES))


def _status_bytes(key: str, status: str) -> Optional[int]:
    found = re.search(rf'^{key}:\s+(\d+) kB', status, re.MULTILINE)
    return int(found.group(1)) * 1024 if found else None


def data_bytes() -> Optional[int]:
    """This process's data segment (``VmData``), what ``RLIMIT_DATA`` counts [bytes]; None
    where ``/proc`` does not say."""
    try:
        return _status_bytes('VmData', Path('/proc/self/status').read_text())
    except OSError:
        return None


def allowance_bytes() -> Optional[int]:
    """What this process may still allocate [bytes]: the kernel's ``MemAvailable``, or less
    when a data limit (``ulimit -d``) leaves less; None where neither is known."""
    try:
        available = _status_bytes('MemAvailable', Path('/proc/meminfo').read_text())
    except OSError:
        available = None
    soft, _ = resource.getrlimit(resource.RLIMIT_DATA)
    used = data_bytes()
    if soft != resource.RLIM_INFINITY and used is not None:
        headroom = max(0, soft - used)
        available = headroom if available is None else min(available, headroom)
    return available


class MemoryLimitError(Exception):
    """A plan that does not fit into the memory this process may use."""


def check(figures: MemoryEstimate, allowance: Optional[int], what: str) -> None:
    """Refuse a grid that does not fit.

    Parameters
    ----------
    figures : MemoryEstimate
    allowance : int or None
        :func:`allowance_bytes`; None: not known, nothing is refused.
    what : str
        The settings that set the grid's size, for the fix in the message.

    Raises
    ------
    MemoryLimitError
        When ``figures.grid_bytes`` exceeds ``allowance``.
    """
    if allowance is not None and figures.grid_bytes > allowance:
        raise MemoryLimitError(
            f'{figures.describe()}; this machine has {gigabytes(allowance)} available: '
            f'{what}')


@contextmanager
def limited(allowance: Optional[int]) -> Iterator[None]:
    """Cap this process's data segment at its current size plus ``allowance`` bytes while the
    block runs (the soft ``RLIMIT_DATA``; the previous limit comes back afterwards), so that an
    allocation beyond it raises ``MemoryError`` instead of waking the out-of-memory killer.
    Without a figure (None) nothing is capped."""
    used = data_bytes()
    if allowance is None or used is None:
        yield
        return
    previous = resource.getrlimit(resource.RLIMIT_DATA)
    cap = used + allowance
    if previous[0] != resource.RLIM_INFINITY:
        cap = min(cap, previous[0])
    if previous[1] != resource.RLIM_INFINITY:
        cap = min(cap, previous[1])
    resource.setrlimit(resource.RLIMIT_DATA, (cap, previous[1]))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_DATA, previous)
