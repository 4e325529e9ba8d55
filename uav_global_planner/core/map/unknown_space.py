"""Unknown space: the part of the planning bounds that a map never observed, as boxes.

A point cloud says where obstacles are; it does not say where the sensor looked. Two sources do:

- An OctoMap (``.bt``) knows every cell it has observed, free or occupied: its known space is
  the union of its leaves (a pruned leaf is a cube of several cells). Everything else is
  unknown: under every inner node the children that do not exist, and everything outside the
  root's cube. :func:`octomap_unknown` walks the tree's leaves level by level on their integer
  keys and returns exactly those cubes (clipped to the bounds), merged into larger boxes where
  neighbours share a face.
- A scene's ``known_volume`` (a list of boxes): everything outside them is unknown
  (:func:`known_volume_unknown`).

With several sources a point is known when any source observed it, so the unknown space is the
intersection of their unknown spaces (:func:`combine`). Maps without such knowledge (PCD, PLY,
LAS, ``.npy``) add nothing: the planner has no unknown space and the question does not arise.

All boxes are axis-aligned, closed, in the map frame (ENU) [m], with pairwise disjoint
interiors, so lengths and volumes inside their union are sums over the boxes.

What the planner does with unknown space is the setting ``unknown_space``
(:mod:`uav_global_planner.core.settings`): ``occupied`` (the default: a drone does not fly into
space nobody has seen; the boxes join the obstacles as :class:`~.obstacles.Box` items, so the
grid, the clearance certificate and every check keep the safety margin from them), ``free``
(flown through) or ``cost`` (flown through at ``unknown_cost`` extra per metre: the search
charges its steps between grid nodes in unknown space, see
:mod:`uav_global_planner.core.search.grid_search`,
and the curve follows the searched path's nodes where shortcuts would fly more unknown space
than it). Every plan reports the arc length of its smoothed curve inside the boxes
(:meth:`UnknownSpace.length_inside`).
"""

from dataclasses import dataclass
from functools import cached_property
import importlib
import math
from pathlib import Path
from typing import Any, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from uav_global_planner.core.checks import check_file, check_point
from uav_global_planner.core.errors import InvalidInputError, MissingDependencyError
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.obstacles import Box, ObstacleSet

PathLike = Union[str, Path]

#: Box pairs compared per block when two box sets are intersected (memory of one block).
_PAIR_BLOCK = 2_000_000


@dataclass(frozen=True, eq=False)
class UnknownSpace:
    """Unknown space as a set of axis-aligned boxes with disjoint interiors.

    Attributes
    ----------
    mins, maxs : numpy.ndarray, shape (K, 3)
        Opposite corners of each box [m] (map frame, ENU), ``mins < maxs`` on every axis;
        K may be 0 (everything within the bounds was observed).
    source : str
        What the boxes come from (file names, ``known_volume``), for messages.
    """

    mins: np.ndarray
    maxs: np.ndarray
    source: str = ''

    def __post_init__(self) -> None:
        lo = np.ascontiguousarray(np.asarray(self.mins, dtype=np.float64).reshape(-1, 3))
        hi = np.ascontiguousarray(np.asarray(self.maxs, dtype=np.float64).reshape(-1, 3))
        if lo.shape != hi.shape:
            raise InvalidInputError(f'unknown space: {len(lo)} box minima but {len(hi)} maxima')
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise InvalidInputError('unknown space: box corners must be finite')
        if np.any(lo >= hi):
            raise InvalidInputError('unknown space: every box min must be below its max')
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, 'mins', lo)
        object.__setattr__(self, 'maxs', hi)

    def __len__(self) -> int:
        return len(self.mins)

    def is_empty(self) -> bool:
        """True when there is no unknown space."""
        return len(self.mins) == 0

    @property
    def volume_m3(self) -> float:
        """Volume of the unknown space [m^3]."""
        return float(np.sum(np.prod(self.maxs - self.mins, axis=1)))

    def boxes(self) -> List[Box]:
        """The boxes as :class:`~uav_global_planner.core.map.obstacles.Box` obstacles."""
        # Checked once here (finite, min < max): a Box's own checks cost about 40 us each,
        # seconds for the 10^5 boxes of a large scan.
        made = []
        for lo, hi in zip(self.mins, self.maxs):
            box = object.__new__(Box)
            object.__setattr__(box, 'min', lo)
            object.__setattr__(box, 'max', hi)
            made.append(box)
        return made

    @cached_property
    def obstacles(self) -> ObstacleSet:
        """The boxes as an obstacle set, for exact distances (built once)."""
        return ObstacleSet(self.boxes())

    def distance(self, points, cap: float = math.inf) -> np.ndarray:
        """Euclidean distance from each point to the unknown space [m], 0 inside.

        As :meth:`ObstacleSet.distance`; +inf when there is no unknown space and no cap.
        """
        return self.obstacles.distance(points, cap)

    def contains(self, points) -> np.ndarray:
        """True for each point inside (or on the boundary of) a box; shape ``points[..., 0]``."""
        p = np.asarray(points, dtype=np.float64)
        flat = p.reshape(-1, 3)
        inside = np.zeros(len(flat), dtype=bool)
        for lo, hi in _blocks(self.mins, self.maxs, len(flat)):
            within = (flat[:, None, :] >= lo[None]) & (flat[:, None, :] <= hi[None])
            inside |= np.any(np.all(within, axis=2), axis=1)
        return inside.reshape(p.shape[:-1])

    def length_inside(self, positions) -> float:
        """Length of the polyline through ``positions`` that lies inside the boxes [m].

        Each segment is clipped against each box (slab method) and the clipped lengths summed:
        exact for the polyline, since the boxes' interiors are disjoint (a segment lying in a
        face shared by two boxes counts for the one on the face's upper side only). On the
        dense samples of a smoothed curve it measures the curve's length in unknown space (a
        report, not a safety decision).

        Parameters
        ----------
        positions : array_like, shape (M, 3)
            Polyline vertices [m].
        """
        pts = np.ascontiguousarray(np.asarray(positions, dtype=np.float64).reshape(-1, 3))
        if len(pts) < 2 or self.is_empty():
            return 0.0
        low, high = pts.min(axis=0), pts.max(axis=0)
        near = np.all((self.maxs >= low) & (self.mins <= high), axis=1)
        if not near.any():
            return 0.0
        return float(_clipped_length(pts, np.ascontiguousarray(self.mins[near]),
                                     np.ascontiguousarray(self.maxs[near])))


@njit
def _clipped_length(points, mins, maxs):  # pragma: no cover - compiled
    total = 0.0
    for s in range(points.shape[0] - 1):
        length = math.sqrt((points[s + 1, 0] - points[s, 0]) ** 2
                           + (points[s + 1, 1] - points[s, 1]) ** 2
                           + (points[s + 1, 2] - points[s, 2]) ** 2)
        if length == 0.0:
            continue
        for b in range(mins.shape[0]):
            t0 = 0.0
            t1 = 1.0
            for a in range(3):
                p = points[s, a]
                d = points[s + 1, a] - p
                if d == 0.0:
                    # Half-open [min, max) across a face: a segment in a face shared by two
                    # boxes is counted once.
                    if p < mins[b, a] or p >= maxs[b, a]:
                        t1 = -1.0
                        break
                    continue
                ta = (mins[b, a] - p) / d
                tb = (maxs[b, a] - p) / d
                if ta > tb:
                    ta, tb = tb, ta
                if ta > t0:
                    t0 = ta
                if tb < t1:
                    t1 = tb
                if t1 <= t0:
                    break
            if t1 > t0:
                total += (t1 - t0) * length
    return total


def _blocks(mins: np.ndarray, maxs: np.ndarray, rows: int):
    """``(mins, maxs)`` in slices so that ``rows`` x slice stays within one pair block."""
    step = max(1, _PAIR_BLOCK // max(rows, 1))
    for first in range(0, len(mins), step):
        yield mins[first:first + step], maxs[first:first + step]


def _bounds(bounds_min, bounds_max) -> Tuple[np.ndarray, np.ndarray]:
    lo = check_point('bounds min', bounds_min)
    hi = check_point('bounds max', bounds_max)
    if np.any(lo >= hi):
        raise InvalidInputError(f'bounds min must be below bounds max on every axis, got '
                                f'{lo.tolist()} and {hi.tolist()}')
    return lo, hi


def _clip(mins: np.ndarray, maxs: np.ndarray, lo: np.ndarray,
          hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The boxes clipped to ``[lo, hi]``, empty ones dropped."""
    mins = np.maximum(mins, lo)
    maxs = np.minimum(maxs, hi)
    keep = np.all(mins < maxs, axis=1)
    return mins[keep], maxs[keep]


def merge_boxes(mins: np.ndarray, maxs: np.ndarray,
                rounds: int = 2) -> Tuple[np.ndarray, np.ndarray]:
    """Fewer boxes for the same union: neighbours that share a whole face are joined.

    For boxes with disjoint interiors, along each axis in turn, boxes with the same extent on
    the other two axes that touch (one's max equals the next one's min, exactly) become one.

    Parameters
    ----------
    mins, maxs : numpy.ndarray, shape (K, 3)
        Corners (integer keys or metres), disjoint interiors.
    rounds : int
        Passes over the three axes.
    """
    lo = np.asarray(mins).reshape(-1, 3)
    hi = np.asarray(maxs).reshape(-1, 3)
    for _ in range(rounds):
        before = len(lo)
        for axis in range(3):
            if len(lo) < 2:
                return lo, hi
            one, two = (a for a in range(3) if a != axis)
            order = np.lexsort((lo[:, axis], hi[:, two], lo[:, two], hi[:, one], lo[:, one]))
            lo, hi = lo[order], hi[order]
            joins = ((lo[1:, one] == lo[:-1, one]) & (hi[1:, one] == hi[:-1, one])
                     & (lo[1:, two] == lo[:-1, two]) & (hi[1:, two] == hi[:-1, two])
                     & (lo[1:, axis] == hi[:-1, axis]))
            if not joins.any():
                continue
            first = np.flatnonzero(np.r_[True, ~joins])
            last = np.r_[first[1:] - 1, len(lo) - 1]
            new_hi = hi[first].copy()
            new_hi[:, axis] = hi[last, axis]
            lo, hi = lo[first], new_hi
        if len(lo) == before:
            break
    return lo, hi


def _outside(inner_lo: np.ndarray, inner_hi: np.ndarray, lo: np.ndarray,
             hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """``[lo, hi]`` minus the box ``[inner_lo, inner_hi]``: at most six disjoint boxes."""
    mins: List[np.ndarray] = []
    maxs: List[np.ndarray] = []
    cur_lo, cur_hi = lo.copy(), hi.copy()
    for axis in range(3):
        if inner_lo[axis] > cur_lo[axis]:
            top = cur_hi.copy()
            top[axis] = min(inner_lo[axis], cur_hi[axis])
            mins.append(cur_lo.copy())
            maxs.append(top)
        if inner_hi[axis] < cur_hi[axis]:
            bottom = cur_lo.copy()
            bottom[axis] = max(inner_hi[axis], cur_lo[axis])
            mins.append(bottom)
            maxs.append(cur_hi.copy())
        cur_lo[axis] = max(cur_lo[axis], inner_lo[axis])
        cur_hi[axis] = min(cur_hi[axis], inner_hi[axis])
        if cur_lo[axis] >= cur_hi[axis]:
            break
    if not mins:
        return np.empty((0, 3)), np.empty((0, 3))
    return _clip(np.array(mins), np.array(maxs), lo, hi)


# --------------------------------------------------------------------------------------------
# OctoMap
# --------------------------------------------------------------------------------------------

def read_octree(path: PathLike) -> Any:
    """An ``octomap.OcTree`` read from a ``.bt`` file (octomap-python).

    Raises
    ------
    MissingDependencyError
        When octomap-python is not installed.
    InvalidInputError
        For a missing file or one the OctoMap library cannot read.
    """
    file = Path(path).expanduser()
    try:
        octomap = importlib.import_module('octomap')
    except ImportError:
        raise MissingDependencyError(
            "reading OctoMap .bt files needs the Python package 'octomap-python', which is "
            'not installed: pip install octomap-python (or pip install '
            'uav_global_planner[maps])') from None
    check_file(file, 'map file')
    tree = octomap.OcTree(0.1)  # the resolution stored in the file replaces it
    if not tree.readBinary(str(file).encode()):
        raise InvalidInputError(f'{file}: not a valid OctoMap binary (.bt) file: the OctoMap '
                                'library could not read it (truncated, or not an OcTree)')
    return tree


def octree_leaves(tree: Any, bounds_min=None,
                  bounds_max=None) -> Tuple[np.ndarray, np.ndarray, float, int]:
    """The known leaves of an octree (free and occupied), as integer keys and depths.

    Parameters
    ----------
    tree : octomap.OcTree
    bounds_min, bounds_max : array_like, shape (3,), optional
        Keep only leaves whose cube meets these bounds [m].

    Returns
    -------
    keys : numpy.ndarray of int64, shape (N, 3)
        Key (cell index, 0 .. 2^depth - 1 per axis) of each leaf's minimum corner; cell ``k``
        spans ``[(k - 2^(depth-1)) r, (k + 1 - 2^(depth-1)) r)`` with ``r`` the resolution.
    depths : numpy.ndarray of int64, shape (N,)
        Depth of each leaf (the tree depth for a single cell, less for pruned leaves).
    resolution : float
        Cell side [m].
    tree_depth : int
        Depth of the tree (16 for OctoMap).
    """
    resolution = float(tree.getResolution())
    tree_depth = int(tree.getTreeDepth())
    flat: list = []
    append = flat.extend
    for leaf in tree.begin_leafs():
        append((leaf.getX(), leaf.getY(), leaf.getZ(), leaf.getSize()))
    leaves = np.array(flat, dtype=np.float64).reshape(-1, 4)
    del flat
    half = leaves[:, 3:4] / 2.0
    if bounds_min is not None and bounds_max is not None:
        lo, hi = _bounds(bounds_min, bounds_max)
        meets = np.all((leaves[:, :3] + half > lo) & (leaves[:, :3] - half < hi), axis=1)
        leaves, half = leaves[meets], half[meets]
    cells = np.maximum(np.rint(leaves[:, 3] / resolution).astype(np.int64), 1)
    depths = tree_depth - np.rint(np.log2(cells)).astype(np.int64)
    keys = np.rint((leaves[:, :3] - half) / resolution).astype(np.int64) \
        + (1 << (tree_depth - 1))
    return keys, depths, resolution, tree_depth


def _spread(values: np.ndarray) -> np.ndarray:
    """Bits 0..20 of each value moved to bits 0, 3, 6, ... (Morton interleaving)."""
    v = values.astype(np.int64) & 0x1FFFFF
    v = (v | (v << 32)) & 0x1F00000000FFFF
    v = (v | (v << 16)) & 0x1F0000FF0000FF
    v = (v | (v << 8)) & 0x100F00F00F00F00F
    v = (v | (v << 4)) & 0x10C30C30C30C30C3
    return (v | (v << 2)) & 0x1249249249249249


def _compact(codes: np.ndarray) -> np.ndarray:
    """The inverse of :func:`_spread`: bits 0, 3, 6, ... of each code, packed."""
    v = codes & 0x1249249249249249
    v = (v ^ (v >> 2)) & 0x10C30C30C30C30C3
    v = (v ^ (v >> 4)) & 0x100F00F00F00F00F
    v = (v ^ (v >> 8)) & 0x1F0000FF0000FF
    v = (v ^ (v >> 16)) & 0x1F00000000FFFF
    return (v ^ (v >> 32)) & 0x1FFFFF


def _absent_children(keys: np.ndarray, depths: np.ndarray,
                     tree_depth: int) -> Tuple[np.ndarray, np.ndarray]:
    """Key boxes ``[lo, hi)`` of the children missing under the inner nodes of the tree that
    the leaves ``keys`` (minimum corners) at ``depths`` span.

    Bottom-up on Morton codes: a node at level ``l`` is the code of its key prefix, its parent
    the code shifted by 3 bits and its octant the 3 bits shifted out. The nodes of a level are
    its leaves and the parents of the level below; under each parent, the octants no node has
    are missing.
    """
    empty = np.empty((0, 3), np.int64)
    if len(keys) == 0 or np.any(depths == 0):
        return empty, empty
    morton = _spread(keys[:, 0]) | (_spread(keys[:, 1]) << 1) | (_spread(keys[:, 2]) << 2)
    octants = np.arange(8, dtype=np.int64)
    found_lo: List[np.ndarray] = []
    found_hi: List[np.ndarray] = []
    carried = np.empty(0, dtype=np.int64)
    for level in range(tree_depth, 0, -1):
        shift = tree_depth - level
        leaves = morton[depths == level] >> (3 * shift)
        nodes = np.sort(np.concatenate([leaves, carried])) if len(carried) else np.sort(leaves)
        if not len(nodes):
            continue
        parents = nodes >> 3
        starts = np.flatnonzero(np.r_[True, parents[1:] != parents[:-1]])
        present = np.bitwise_or.reduceat(np.left_shift(1, nodes & 7), starts)
        owners = parents[starts]
        rows, bits = np.nonzero(((present[:, None] >> octants[None, :]) & 1) == 0)
        if len(rows):
            child = (owners[rows] << 3) | bits
            lo = np.stack([_compact(child), _compact(child >> 1), _compact(child >> 2)],
                          axis=1) << shift
            found_lo.append(lo)
            found_hi.append(lo + (1 << shift))
        carried = owners
    if not found_lo:
        return empty, empty
    return np.concatenate(found_lo), np.concatenate(found_hi)


def octree_unknown(tree: Any, bounds_min, bounds_max, source: str = '') -> UnknownSpace:
    """The unknown space of an octree within the bounds (see the module notes).

    Parameters
    ----------
    tree : octomap.OcTree
    bounds_min, bounds_max : array_like, shape (3,)
        Planning bounds [m].
    source : str
        Name for messages.
    """
    lo, hi = _bounds(bounds_min, bounds_max)
    keys, depths, resolution, tree_depth = octree_leaves(tree, lo, hi)
    half = 1 << (tree_depth - 1)
    root_lo = np.full(3, -half * resolution)
    root_hi = np.full(3, half * resolution)
    if len(keys) == 0:
        return UnknownSpace(lo[None, :], hi[None, :], source)
    key_lo, key_hi = _absent_children(keys, depths, tree_depth)
    key_lo, key_hi = merge_boxes(key_lo, key_hi)
    mins = (key_lo - half).astype(np.float64) * resolution
    maxs = (key_hi - half).astype(np.float64) * resolution
    mins, maxs = _clip(mins, maxs, lo, hi)
    out_lo, out_hi = _outside(root_lo, root_hi, lo, hi)
    mins, maxs = merge_boxes(np.vstack([mins, out_lo]), np.vstack([maxs, out_hi]))
    return UnknownSpace(mins, maxs, source)


def octomap_unknown(path: PathLike, bounds_min, bounds_max) -> UnknownSpace:
    """The unknown space of an OctoMap ``.bt`` file within the bounds [m]."""
    return octree_unknown(read_octree(path), bounds_min, bounds_max, str(path))


# --------------------------------------------------------------------------------------------
# Known volumes and combinations
# --------------------------------------------------------------------------------------------

def known_volume_unknown(mins, maxs, bounds_min, bounds_max,
                         source: str = 'known_volume') -> UnknownSpace:
    """The bounds minus the union of the known boxes ``[mins, maxs]`` [m].

    Exact: the axes are cut at every box face and each cell of that lattice is known or not;
    the unknown cells are merged into boxes.
    """
    lo, hi = _bounds(bounds_min, bounds_max)
    known_lo = np.asarray(mins, dtype=np.float64).reshape(-1, 3)
    known_hi = np.asarray(maxs, dtype=np.float64).reshape(-1, 3)
    known_lo, known_hi = _clip(known_lo, known_hi, lo, hi)
    if len(known_lo) == 0:
        return UnknownSpace(lo[None, :], hi[None, :], source)
    cuts = [np.unique(np.r_[lo[a], hi[a], known_lo[:, a], known_hi[:, a]]) for a in range(3)]
    shape = tuple(len(c) - 1 for c in cuts)
    known = np.zeros(shape, dtype=bool)
    for box_lo, box_hi in zip(known_lo, known_hi):
        first = [int(np.searchsorted(cuts[a], box_lo[a])) for a in range(3)]
        last = [int(np.searchsorted(cuts[a], box_hi[a])) for a in range(3)]
        known[first[0]:last[0], first[1]:last[1], first[2]:last[2]] = True
    cells = np.argwhere(~known)
    cell_lo = np.stack([cuts[a][cells[:, a]] for a in range(3)], axis=1).reshape(-1, 3)
    cell_hi = np.stack([cuts[a][cells[:, a] + 1] for a in range(3)], axis=1).reshape(-1, 3)
    return UnknownSpace(*merge_boxes(cell_lo, cell_hi), source=source)


def intersect(first: UnknownSpace, second: UnknownSpace) -> UnknownSpace:
    """Space unknown to both (what neither observed): pairwise box intersections."""
    small, large = (first, second) if len(first) <= len(second) else (second, first)
    mins: List[np.ndarray] = []
    maxs: List[np.ndarray] = []
    for lo, hi in _blocks(small.mins, small.maxs, len(large)):
        pair_lo = np.maximum(lo[:, None, :], large.mins[None, :, :]).reshape(-1, 3)
        pair_hi = np.minimum(hi[:, None, :], large.maxs[None, :, :]).reshape(-1, 3)
        keep = np.all(pair_lo < pair_hi, axis=1)
        mins.append(pair_lo[keep])
        maxs.append(pair_hi[keep])
    source = ', '.join(s for s in (first.source, second.source) if s)
    if not mins:
        return UnknownSpace(np.empty((0, 3)), np.empty((0, 3)), source)
    return UnknownSpace(*merge_boxes(np.vstack(mins), np.vstack(maxs)), source=source)


def combine(spaces: Iterable[Optional[UnknownSpace]]) -> Optional[UnknownSpace]:
    """The unknown space of several sources: what none of them observed.

    None entries (sources without knowledge of unknown space) are skipped; None when every
    entry is None.
    """
    result: Optional[UnknownSpace] = None
    for space in spaces:
        if space is None:
            continue
        result = space if result is None else intersect(result, space)
    return result


def unknown_from_map_files(paths: Sequence[PathLike], bounds_min,
                           bounds_max) -> Optional[UnknownSpace]:
    """The unknown space of the OctoMap files among ``paths``; None when there are none."""
    return combine(octomap_unknown(path, bounds_min, bounds_max) for path in paths
                   if Path(path).suffix.lower() == '.bt')


def parse_known_volume(value: Any, key: str = 'known_volume') -> Tuple[np.ndarray, np.ndarray]:
    """A scene's ``known_volume``: a list of ``{min: [x, y, z], max: [x, y, z]}`` boxes [m].

    Raises
    ------
    InvalidInputError
        Whose message starts with the key path (``known_volume[1].max: ...``).
    """
    if not isinstance(value, list):
        raise InvalidInputError(f'{key}: must be a list of boxes {{min: [x, y, z], max: '
                                f'[x, y, z]}}, got {type(value).__name__}')
    mins, maxs = [], []
    for number, entry in enumerate(value):
        path = f'{key}[{number}]'
        if not isinstance(entry, dict) or set(entry) != {'min', 'max'}:
            raise InvalidInputError(f'{path}: must be a mapping with the keys min and max, got '
                                    f'{entry!r}')
        corners = []
        for name in ('min', 'max'):
            try:
                corners.append(check_point(name, entry[name]))
            except InvalidInputError as error:
                raise InvalidInputError(f'{path}.{name}: {error}') from None
        if np.any(corners[0] >= corners[1]):
            raise InvalidInputError(f'{path}: min must be below max on every axis, got min '
                                    f'{corners[0].tolist()} and max {corners[1].tolist()}')
        mins.append(corners[0])
        maxs.append(corners[1])
    return np.array(mins).reshape(-1, 3), np.array(maxs).reshape(-1, 3)


def scene_unknown(known_volume: Any, map_files: Sequence[PathLike], bounds_min,
                  bounds_max) -> Optional[UnknownSpace]:
    """The unknown space of a scene: its ``known_volume`` (None when it has none) and its
    OctoMap files, combined (:func:`combine`); None when neither says anything."""
    spaces: List[Optional[UnknownSpace]] = []
    if known_volume is not None:
        spaces.append(known_volume_unknown(*parse_known_volume(known_volume), bounds_min,
                                           bounds_max))
    try:
        spaces.append(unknown_from_map_files(map_files, bounds_min, bounds_max))
    except InvalidInputError as error:
        raise type(error)(f'unknown space: {error}') from None
    return combine(spaces)
