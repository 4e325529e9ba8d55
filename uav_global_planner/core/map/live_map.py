"""Live maps: obstacles that change while the vehicle flies, indexed and inflated incrementally.

A mapping stack (octomap_server, voxblox, nvblox, a LiDAR SLAM) republishes the occupied space
at 1-10 Hz, and markers add or remove shapes in between. Rebuilding the inflated grid and the
point index of a large map for every message takes seconds; this module keeps both up to date
at a cost that follows what changed, and gives every consumer one consistent map at a time.

The pieces
----------
:class:`~uav_global_planner.core.map.point_cells.PointCells`
    A point index for one cloud (:mod:`~uav_global_planner.core.map.point_cells`), in the cells
    of the tiles of grid nodes (:mod:`~uav_global_planner.core.map.tiles`).
:class:`LiveObstacles`
    An :class:`~uav_global_planner.core.map.obstacles.ObstacleSet` of shapes (markers) plus point
    layers (the newest cloud, a static prior map), each point layer indexed once: a marker
    update keeps the cloud's index, a cloud update the prior's.
:class:`~uav_global_planner.core.map.mask_buffers.MaskBuffers`
    Up to three inflated masks of one grid and margin, brought up to date tile by tile
    (:mod:`~uav_global_planner.core.map.mask_buffers`).
:class:`LiveMapBuilder`
    Applies marker and cloud updates and produces :class:`LiveMap` objects: obstacles, their
    inflated mask and what the update cost.
"""

from dataclasses import dataclass, replace
import math
import time
from typing import Any, Dict, Hashable, Iterable, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import Mask
from uav_global_planner.core.map.mask_buffers import MaskBuffers, MaskUpdate
from uav_global_planner.core.map.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.point_cells import changed_cells, PointCells
from uav_global_planner.core.map.sparse_grid import choose_layout, SPARSE_MIN_NODES
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner.core.map.tiles import cell_tiles, shape_tiles
from uav_global_planner.core.planner import certify_plan, fallback_margin, Planner


class LiveObstacles(ObstacleSet):
    """Shapes plus point layers, each point layer with its own index, built once.

    Behaves as the :class:`ObstacleSet` of all of them: ``points`` holds every layer's points,
    :meth:`distance` the nearest of shapes and points, ``items`` the shapes and one
    :class:`PointSet` per layer.

    Parameters
    ----------
    shapes : iterable of Sphere, Box, TableShape or HeightField
    layers : sequence of PointCells
        Empty layers are dropped.

    Raises
    ------
    InvalidInputError
        If a shape is a point set (points go in layers).
    """

    def __init__(self, shapes: Iterable[Obstacle] = (), layers: Sequence[PointCells] = ()):
        shapes = tuple(shapes)
        for number, shape in enumerate(shapes):
            if isinstance(shape, PointSet):
                raise InvalidInputError(f'shape {number} is a point set; points are layers')
        super().__init__(shapes)
        self.layers = tuple(layer for layer in layers if len(layer))
        self._shape_count = len(shapes)
        if not self.layers:
            points = np.empty((0, 3))
        elif len(self.layers) == 1:
            points = self.layers[0].points
        else:
            points = np.concatenate([layer.points for layer in self.layers])
        points.setflags(write=False)
        self.points = points
        self._layer_items: Optional[Tuple[PointSet, ...]] = None

    @property
    def items(self) -> Sequence[Obstacle]:
        """The shapes, then one point set per layer."""
        if self._layer_items is None:
            self._layer_items = tuple(PointSet(layer.points) for layer in self.layers)
        return tuple(super().items) + self._layer_items

    def __len__(self) -> int:
        return self._shape_count + len(self.layers)

    def distance(self, points, cap: float = math.inf) -> np.ndarray:
        """Euclidean distance to the nearest shape or point [m]; see
        :meth:`ObstacleSet.distance` for ``cap``."""
        p = np.asarray(points, dtype=np.float64)
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = np.array(super().distance(flat, cap), dtype=np.float64).reshape(-1)
        for layer in self.layers:
            np.minimum(out, layer.distance(flat, cap), out=out)
        return out.reshape(p.shape[:-1])


@dataclass(frozen=True, eq=False)
class LiveMap:
    """One consistent map: obstacles and, for one grid and margin, their inflated mask.

    Attributes
    ----------
    obstacles : LiveObstacles
    blocked : numpy.ndarray of bool, or SparseMask
        Inflated mask of ``grid_key`` (read-only by contract: the builder rewrites the buffer
        only once no reader holds it).
    grid_key : tuple
        :meth:`PlannerConfig.grid_key` the mask was built for.
    version : int
        Increases with every change of the obstacles.
    update : MaskUpdate
        What the mask cost.
    index_time_s : float
        Time spent indexing a new cloud and finding its changed cells [s].
    fallback : numpy.ndarray of bool, or SparseMask, optional
        Mask of the same obstacles for the planner's conservative fallback margin
        (:func:`~uav_global_planner.core.planner.fallback_margin`), once asked for
        (:attr:`LiveMapBuilder.want_fallback`).
    """

    obstacles: LiveObstacles
    blocked: Mask
    grid_key: tuple
    version: int
    update: MaskUpdate
    index_time_s: float
    fallback: Optional[Mask] = None


#: Pass as ``cloud`` to :meth:`LiveMapBuilder.update` to keep the cloud.
UNCHANGED = object()


def same_shape(first: Obstacle, second: Obstacle) -> bool:
    """True when two shapes are of one type with bit-identical parameters."""
    if type(first) is not type(second):
        return False
    if isinstance(first, Sphere) and isinstance(second, Sphere):
        return (bool(np.array_equal(first.center, second.center))
                and first.radius == second.radius)
    if isinstance(first, Box) and isinstance(second, Box):
        return (bool(np.array_equal(first.min, second.min))
                and bool(np.array_equal(first.max, second.max)))
    if isinstance(first, HeightField) and isinstance(second, HeightField):
        return (first is second or (
            first.side == second.side and first.label == second.label
            and bool(np.array_equal(first.origin, second.origin))
            and bool(np.array_equal(first.spacing, second.spacing))
            and bool(np.array_equal(first.heights, second.heights))))
    return first is second


class LiveMapBuilder:
    """Turns marker and cloud updates into :class:`LiveMap` objects (one thread at a time).

    Parameters
    ----------
    config : PlannerConfig
        The grid (bounds, delta) and margin gamma to inflate for.
    prior : array_like, shape (P, 3), optional
        Points of a static prior map [m]: indexed once per grid, and joined to every map.
    first_version : int
        Version of the first map.

    Attributes
    ----------
    want_fallback : bool
        Also keep the mask for the planner's fallback margin up to date (set it once a plan
        needed that grid: then it costs plans nothing more; a plain flag, so another thread may
        set it).
    """

    def __init__(self, config: PlannerConfig, prior=None, first_version: int = 1) -> None:
        self._prior_points = (None if prior is None or len(prior) == 0
                              else PointSet(prior).points)
        self._shapes: Dict[Hashable, Obstacle] = {}
        self._cloud_points: Optional[np.ndarray] = None
        self._cloud: Optional[PointCells] = None
        self._prior: Optional[PointCells] = None
        self._buffers: Optional[MaskBuffers] = None
        self._fallback_buffers: Optional[MaskBuffers] = None
        self.want_fallback = False
        self._grid_key: Optional[tuple] = None
        self._config = config
        self._version = int(first_version) - 1
        self._newest: Optional[LiveMap] = None

    @property
    def newest(self) -> Optional[LiveMap]:
        """The last map built (None before the first)."""
        return self._newest

    def update(self, shapes: Optional[Mapping[Any, Obstacle]] = None, cloud=UNCHANGED,
               config: Optional[PlannerConfig] = None, held: Optional[Mask] = None,
               give_cloud: bool = False, held_fallback: Optional[Mask] = None) -> LiveMap:
        """Apply an update and return the map it gives.

        Parameters
        ----------
        shapes : mapping of key to Sphere or Box, optional
            Every shape now, keyed by any hashable (for example by marker (ns, id)); None
            keeps them.
        cloud : numpy.ndarray of shape (M, 3), None or UNCHANGED
            The newest cloud (replacing the last one), None for no cloud, or UNCHANGED.
        config : PlannerConfig, optional
            New settings; a new grid or margin rebuilds the mask (and a new grid the indexes).
        held : numpy.ndarray or SparseMask, optional
            The mask a reader still uses (never written).
        give_cloud : bool
            The caller hands ``cloud`` over (a float64 array it will not touch again), so it
            is kept without a copy; by default it is copied.
        held_fallback : numpy.ndarray or SparseMask, optional
            The fallback mask a reader still uses (never written).

        Returns
        -------
        LiveMap
            A new version when the obstacles changed, else the same obstacles with a mask of
            the current settings.
        """
        if config is not None:
            self._config = config
        config = self._config
        grid_key = config.grid_key()
        regrid = self._buffers is None or grid_key != self._grid_key
        new_geometry = regrid and (self._buffers is None or self._grid_key is None or (
            grid_key[:3] != self._grid_key[:3]))
        if regrid:
            grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max,
                                         config.resolution, config.max_voxels)
            self._buffers = MaskBuffers(grid, config.planning_margin)
            self._fallback_buffers = None
            self._grid_key = grid_key
        buffers = self._buffers
        assert buffers is not None  # made above when there were none
        geometry = buffers.geometry
        indexing_started = time.perf_counter()
        if new_geometry:
            self._prior = (None if self._prior_points is None
                           else PointCells(self._prior_points, geometry))
            self._cloud = (None if self._cloud_points is None
                           else PointCells(self._cloud_points, geometry))
        moved_shapes: List[Obstacle] = []
        moved_cells: List[np.ndarray] = []
        moved = False
        if shapes is not None:
            new_shapes = dict(shapes)
            differ = [shape for key, shape in self._shapes.items()
                      if key not in new_shapes or not same_shape(shape, new_shapes[key])]
            differ += [shape for key, shape in new_shapes.items()
                       if key not in self._shapes or not same_shape(shape, self._shapes[key])]
            if differ:
                moved_shapes = differ
                moved = True
            self._shapes = new_shapes
        if cloud is not UNCHANGED:
            points = None if cloud is None or len(cloud) == 0 else (
                np.asarray(cloud, dtype=np.float64) if give_cloud
                else np.array(cloud, dtype=np.float64))
            cells = None if points is None else PointCells(points, geometry, self._cloud)
            if cells is not None and cells.changed_from_previous is not None:
                differ_cells = cells.changed_from_previous
            else:
                differ_cells = changed_cells(self._cloud, cells, geometry)
            if len(differ_cells):
                moved_cells.append(differ_cells)
                moved = True
            self._cloud_points, self._cloud = (None if cells is None else cells.points), cells
        index_time = time.perf_counter() - indexing_started
        fallback_missing = self.want_fallback and self._fallback_buffers is None
        if not (moved or regrid or fallback_missing) and self._newest is not None:
            return self._newest
        if moved or self._newest is None:
            self._version += 1
            layers = [layer for layer in (self._prior, self._cloud) if layer is not None]
            # Keys are orderable as well as hashable (marker (ns, id) pairs, names).
            keys = sorted(self._shapes)  # type: ignore[type-var]
            obstacles = LiveObstacles([self._shapes[key] for key in keys], layers)
        else:
            obstacles = self._newest.obstacles
            layers = list(obstacles.layers)
        if regrid or moved or self._newest is None:
            tiles = None if regrid else _changed_tiles(buffers, moved_shapes, moved_cells)
            mask, update = buffers.write(obstacles, self._version, tiles, layers, held)
        else:
            mask, update = self._newest.blocked, MaskUpdate(False, 0, 0, 0.0)
        fallback = None
        if self.want_fallback:
            fallback = self._write_fallback(obstacles, layers, moved_shapes, moved_cells,
                                            moved, held_fallback)
        self._newest = LiveMap(obstacles, mask, grid_key, self._version, update, index_time,
                               fallback)
        return self._newest

    def _write_fallback(self, obstacles: LiveObstacles, layers: Sequence[PointCells],
                        moved_shapes: List[Obstacle], moved_cells: List[np.ndarray],
                        moved: bool, held: Optional[Mask]) -> Mask:
        """The mask for the planner's fallback margin, kept up to date like the other."""
        buffers = self._fallback_buffers
        if buffers is None:
            assert self._buffers is not None  # update() makes them first
            buffers = self._fallback_buffers = MaskBuffers(self._buffers.grid,
                                                           fallback_margin(self._config))
            return buffers.write(obstacles, self._version, None, layers, held)[0]
        if moved or self._newest is None or self._newest.fallback is None:
            tiles = _changed_tiles(buffers, moved_shapes, moved_cells) if moved else None
            return buffers.write(obstacles, self._version, tiles, layers, held)[0]
        return self._newest.fallback


def _changed_tiles(buffers: MaskBuffers, shapes: Sequence[Obstacle],
                   cells: Sequence[np.ndarray]) -> Optional[np.ndarray]:
    """Tiles of ``buffers`` that shapes added or removed and changed cells reach (with the
    buffers' own margin); None when anything may have changed."""
    parts = []
    if shapes:
        tiles = shape_tiles(buffers.grid, shapes, buffers.safety_margin, buffers.geometry)
        if tiles is None:
            return None
        parts.append(tiles)
    for changed in cells:
        parts.append(cell_tiles(changed, buffers.geometry, buffers.reach))
    return np.unique(np.concatenate(parts)) if parts else np.empty(0, dtype=np.int64)


def warm_up_changes(config: PlannerConfig) -> None:
    """Load the kernels of a map change before the first real one needs them.

    The first change of a map (a shape added or moved, a new cloud) re-inflates only the tiles
    it touched, through kernels the first build does not call, and the plan in force is
    certified against it from the vehicle's position on; loading those kernels from the cache
    takes 10-60 ms each (and compiling them, on a new install, seconds), all of it in the time
    between an obstacle's arrival and the withdrawal of a plan it blocks. This applies such
    changes to a throwaway map of the layout ``config``'s grid has (dense, or a large empty
    block-sparse one), at ``config``'s resolution and margin, and certifies a short plan on it
    from its start, as the node does.

    Parameters
    ----------
    config : PlannerConfig
        The node's settings (only its grid's layout, resolution and margin are used).
    """
    delta = config.resolution
    grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, delta, config.max_voxels)
    side = 12
    if choose_layout(grid.size) == 'sparse':
        side = int(math.ceil(SPARSE_MIN_NODES ** (1.0 / 3.0))) + 1
    extent = (side - 1) * delta
    small = replace(config, bounds_min=(0.0, 0.0, 0.0), bounds_max=(extent,) * 3,
                    max_voxels=max(side ** 3, 1))
    builder = LiveMapBuilder(small)
    corner = np.full(3, 2.0 * delta)
    box = Box(corner, corner + 2.0 * delta)
    builder.update({'box': box})
    builder.update({'box': box, 'moved': Box(corner + 4.0 * delta, corner + 6.0 * delta)})
    points = corner + delta * np.array([[0.5, 0.5, 0.5], [3.5, 0.5, 0.5]])
    builder.update(cloud=points)
    live = builder.update(cloud=points + delta)
    far = corner + 8.0 * delta
    result = Planner(small, ObstacleSet([box])).plan(corner + (0.0, 4.0 * delta, 0.0), far)
    if result.ok:
        certify_plan(result, live.obstacles, result.planning_margin, result.resolution,
                     result.path[0], ahead_m=30.0)
