"""Inflated masks of a live map, written tile by tile into up to three buffers.

The planner reads one mask while the next is written, so a plan always runs on one consistent
map (double buffering; a third buffer lets a new map be written while the newest one waits to
be picked up). A buffer is brought up to date by re-inflating only the tiles changed since it
was last written (:func:`~uav_global_planner.core.map.inflation.reinflate_tiles`, or
:func:`~uav_global_planner.core.map.sparse_inflation.reinflate_sparse` on a block-sparse grid),
which gives the mask of a full rebuild to the bit.
"""

from dataclasses import dataclass
import time
from typing import List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask, Mask, reinflate_tiles
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.point_cells import PointCells
from uav_global_planner.core.map.sparse_grid import choose_layout, SparseMask
from uav_global_planner.core.map.sparse_inflation import reinflate_sparse
from uav_global_planner.core.map.tiles import CellGeometry, dilate_cells, reach_tiles

#: Above this fraction of stale tiles a mask is rebuilt whole (cheaper than tile by tile).
FULL_REBUILD_FRACTION = 0.5
#: Masks kept per grid: the one the planner reads, the newest, and one being written.
MAX_BUFFERS = 3


@dataclass(frozen=True)
class MaskUpdate:
    """What bringing one mask up to date cost.

    Attributes
    ----------
    full : bool
        The whole mask was rebuilt.
    tiles : int
        Tiles re-inflated (all of them when ``full``).
    points : int
        Points stamped again.
    time_s : float
        [s]
    """

    full: bool
    tiles: int
    points: int
    time_s: float


class _Buffer:
    def __init__(self, shape: Tuple[int, int, int]) -> None:
        self.mask = np.zeros(shape, dtype=bool)
        self.version = -1


class MaskBuffers:
    """Up to :data:`MAX_BUFFERS` inflated masks of one grid and margin.

    Each write goes to a buffer that neither a reader holds (``held``) nor is the newest one:
    the buffer takes a copy of the newest mask (a memory copy) and then the tiles of this
    change are re-inflated in it. The newest buffer is never written, so a reader always sees a
    complete mask.

    Parameters
    ----------
    grid : VoxelGrid
    safety_margin : float
        gamma [m].
    """

    def __init__(self, grid: VoxelGrid, safety_margin: float) -> None:
        self.grid = grid
        self.safety_margin = float(safety_margin)
        self.geometry = CellGeometry.of_grid(grid)
        self.reach = reach_tiles(self.safety_margin, self.geometry)
        self._buffers: List[_Buffer] = []
        self._newest: Optional[_Buffer] = None
        self._sparse_newest: Optional[SparseMask] = None

    def write(self, obstacles: ObstacleSet, version: int, changed: Optional[np.ndarray],
              layers: Sequence[PointCells] = (),
              held: Optional[Mask] = None) -> Tuple[Mask, MaskUpdate]:
        """Write the mask of ``obstacles`` (map ``version``) and make it the newest.

        Parameters
        ----------
        obstacles : ObstacleSet
        version : int
            Greater than every version written before.
        changed : numpy.ndarray of int, or None
            Flat numbers of the tiles (C order over ``geometry.tiles``) whose nodes may differ
            from the newest mask; None: any (a full rebuild).
        layers : sequence of PointCells
            The point layers of ``obstacles`` (their points are gathered tile by tile).
        held : numpy.ndarray or SparseMask, optional
            A mask a reader still uses; it is not written.

        Returns
        -------
        mask : numpy.ndarray of bool, shape ``grid.shape``
        update : MaskUpdate
        """
        started = time.perf_counter()
        if choose_layout(self.grid.size) == 'sparse':
            return self._write_sparse(obstacles, changed, layers, started)
        buffer = next((b for b in self._buffers
                       if b is not self._newest and b.mask is not held), None)
        if buffer is None:
            if len(self._buffers) >= MAX_BUFFERS:  # cannot happen: at most two are excluded
                raise RuntimeError('no free mask buffer')
            buffer = _Buffer(tuple(self.grid.shape))
            self._buffers.append(buffer)
        newest = self._newest
        tiles = int(np.prod(self.geometry.tiles))
        if newest is None or changed is None or len(changed) > FULL_REBUILD_FRACTION * tiles:
            blocked_mask(self.grid, obstacles, self.safety_margin, out=buffer.mask)
            update = MaskUpdate(True, tiles, len(obstacles.points), 0.0)
        else:
            if buffer.version != newest.version:
                np.copyto(buffer.mask, newest.mask)
            near = self._points_near(changed, layers)
            index = np.stack(np.unravel_index(
                np.asarray(changed, dtype=np.int64),
                tuple(int(t) for t in self.geometry.tiles)), axis=-1)
            reinflate_tiles(self.grid, obstacles, self.safety_margin, buffer.mask, index,
                            self.geometry.tile_nodes, near)
            update = MaskUpdate(False, len(changed), len(near), 0.0)
        buffer.version = version
        self._newest = buffer
        return buffer.mask, MaskUpdate(update.full, update.tiles, update.points,
                                       time.perf_counter() - started)

    def _write_sparse(self, obstacles: ObstacleSet, changed: Optional[np.ndarray],
                      layers: Sequence[PointCells],
                      started: float) -> Tuple[SparseMask, MaskUpdate]:
        """:meth:`write` on a block-sparse grid: each mask is a new object (no buffers; the
        old one stays intact for its readers), built whole or from the newest one with the
        changed tiles re-inflated."""
        newest = self._sparse_newest
        tiles = int(np.prod(self.geometry.tiles))
        if newest is None or changed is None or len(changed) > FULL_REBUILD_FRACTION * tiles:
            mask = blocked_mask(self.grid, obstacles, self.safety_margin)
            update = MaskUpdate(True, tiles, len(obstacles.points), 0.0)
        else:
            near = self._points_near(changed, layers)
            index = np.stack(np.unravel_index(
                np.asarray(changed, dtype=np.int64),
                tuple(int(t) for t in self.geometry.tiles)), axis=-1)
            mask = reinflate_sparse(self.grid, obstacles, self.safety_margin, newest, index,
                                    self.geometry.tile_nodes, near)
            update = MaskUpdate(False, len(changed), len(near), 0.0)
        assert isinstance(mask, SparseMask)
        self._sparse_newest = mask
        return mask, MaskUpdate(update.full, update.tiles, update.points,
                                time.perf_counter() - started)

    def _points_near(self, tiles: np.ndarray, layers: Sequence[PointCells]) -> np.ndarray:
        """Every layer point within gamma of a node of the tiles (and a few more)."""
        if not layers or len(tiles) == 0:
            return np.empty((0, 3))
        geometry = self.geometry
        index = np.unravel_index(np.asarray(tiles, dtype=np.int64),
                                 tuple(int(t) for t in geometry.tiles))
        cells = np.ravel_multi_index(index, tuple(int(d) for d in geometry.dims))
        near = dilate_cells(cells, geometry.dims, self.reach)
        parts = [layer.points_in(near) for layer in layers]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)
