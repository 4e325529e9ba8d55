"""The readers of map files, one per format, each with the field's own library.

Each reader takes a path and returns the points as an (N, 3) float64 array [m], the margin of
the format [m] (0 for points that are the obstacles themselves; half a cell diagonal for
OctoMap leaf centres) and the number of points or cells read. The library of a format is an
optional extra, imported only when a file of that format is read (``pip install
uav_global_planner[maps]``); :func:`~uav_global_planner.core.io.mapfiles.load_map_points`
checks and reports what they read.
"""

import importlib
from pathlib import Path
from types import ModuleType
from typing import Callable, Dict, Sequence, Tuple

import numpy as np

from uav_global_planner.core.errors import InvalidInputError, MissingDependencyError
from uav_global_planner.core.map.grid import HALF_CELL_DIAGONAL

#: Largest number of points an OctoMap file may expand into (pruned leaves are split into cells
#: of the tree resolution): about 1.2 GB of float64 coordinates plus the search tree.
MAX_OCTOMAP_POINTS = 50_000_000


def _require(module: str, package: str, what: str) -> ModuleType:
    """Import an optional extra, or say which pip package brings it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingDependencyError(
            f'reading {what} needs the Python package {package!r}, which is not installed: '
            f'pip install {package} (or pip install uav_global_planner[maps])') from None


def _as_xyz(columns, file: Path, kind: str) -> np.ndarray:
    try:
        return np.column_stack([np.asarray(c, dtype=np.float64) for c in columns])
    except (TypeError, ValueError) as error:
        raise InvalidInputError(f'{file}: the x, y, z of this {kind} file are not numbers '
                                f'({error})') from None


def finite_header(file: Path, kind: str, fields: Dict[str, Sequence[float]]) -> None:
    """Refuse a header with a NaN or infinite number: the file is corrupt."""
    for name, values in fields.items():
        numbers = np.asarray(values, dtype=np.float64).ravel()
        if not np.all(np.isfinite(numbers)):
            raise InvalidInputError(
                f'{file}: the {kind} header holds a non-finite {name} '
                f'({", ".join(f"{v:g}" for v in numbers)}): the file is corrupt or was written '
                'wrong; write it again with finite header values')


def _read_pcd(file: Path) -> Tuple[np.ndarray, float, int]:
    pypcd4 = _require('pypcd4', 'pypcd4', 'PCD files')
    cloud = pypcd4.PointCloud.from_path(file)
    finite_header(file, 'PCD', {'VIEWPOINT': cloud.metadata.viewpoint})
    missing = [axis for axis in 'xyz' if axis not in cloud.fields]
    if missing:
        raise InvalidInputError(f'{file}: this PCD file has no {", ".join(missing)} field '
                                f'(fields: {", ".join(cloud.fields)})')
    points = _as_xyz([cloud.pc_data[axis] for axis in 'xyz'], file, 'PCD')
    expected = int(cloud.metadata.points)
    if len(points) != expected:
        # An ASCII file cut at a line end parses without complaint.
        raise InvalidInputError(f'{file}: truncated PCD file: the header announces {expected} '
                                f'points, the data holds {len(points)}')
    return points, 0.0, len(points)


def _read_ply(file: Path) -> Tuple[np.ndarray, float, int]:
    plyfile = _require('plyfile', 'plyfile', 'PLY files')
    data = plyfile.PlyData.read(str(file))
    names = [element.name for element in data.elements]
    if 'vertex' not in names:
        raise InvalidInputError(f'{file}: this PLY file has no vertex element '
                                f'(elements: {", ".join(names) or "none"})')
    if 'face' in names and data['face'].count > 0:
        # The planner avoids points: a mesh's faces between its vertices would be flown
        # through.
        raise InvalidInputError(
            f'{file}: this PLY file is a mesh ({data["face"].count} faces); only its vertices '
            'would be obstacles and its faces would be flown through: sample the surface into '
            'a point cloud first')
    vertex = data['vertex']
    properties = [p.name for p in vertex.properties]
    missing = [axis for axis in 'xyz' if axis not in properties]
    if missing:
        raise InvalidInputError(f'{file}: the PLY vertices have no {", ".join(missing)} '
                                f'property (properties: {", ".join(properties)})')
    points = _as_xyz([vertex[axis] for axis in 'xyz'], file, 'PLY')
    return points, 0.0, len(points)


def _read_las(file: Path) -> Tuple[np.ndarray, float, int]:
    laspy = _require('laspy', 'laspy', 'LAS/LAZ files')
    if file.suffix.lower() == '.laz' and not laspy.LazBackend.detect_available():
        raise MissingDependencyError(
            f'{file}: reading LAZ files needs a LAZ backend for laspy, and none is installed: '
            'pip install lazrs (or pip install uav_global_planner[maps])')
    with laspy.open(str(file)) as reader:
        header = reader.header
        finite_header(file, 'LAS', {'scale': header.scales, 'offset': header.offsets,
                                    'minimum': header.mins, 'maximum': header.maxs})
        data = reader.read()
    # laspy applies the header's scales and offsets: metres, as float64.
    points = np.ascontiguousarray(data.xyz, dtype=np.float64).reshape(-1, 3)
    return points, 0.0, len(points)


def _read_octomap(file: Path) -> Tuple[np.ndarray, float, int]:
    octomap = _require('octomap', 'octomap-python', 'OctoMap .bt files')
    # The resolution given here is replaced by the one stored in the file.
    tree = octomap.OcTree(0.1)
    if not tree.readBinary(str(file).encode()):
        raise InvalidInputError(f'{file}: not a valid OctoMap binary (.bt) file: the OctoMap '
                                'library could not read it (truncated, or not an OcTree)')
    resolution = float(tree.getResolution())
    occupied = tree.isNodeOccupied
    # One flat list of floats: a tuple per leaf would make millions of objects for the garbage
    # collector to walk.
    flat: list = []
    append = flat.extend
    for leaf in tree.begin_leafs():
        if occupied(leaf):
            append((leaf.getX(), leaf.getY(), leaf.getZ(), leaf.getSize()))
    leaves = np.array(flat, dtype=np.float64).reshape(-1, 4)
    del flat
    # Pruned leaves stand for 2^k cells of the tree resolution per axis; split them so that
    # every point is a cell centre and the margin is the same everywhere.
    per_axis = np.maximum(np.rint(leaves[:, 3] / resolution).astype(np.int64), 1)
    total = int(np.sum(per_axis.astype(np.float64) ** 3))
    if total > MAX_OCTOMAP_POINTS:
        raise InvalidInputError(
            f'{file}: the occupied leaves of this OctoMap make {total} cells of '
            f'{resolution} m, more than the {MAX_OCTOMAP_POINTS} accepted')
    parts = []
    for count in np.unique(per_axis):
        chosen = leaves[per_axis == count, :3]
        if count == 1:
            parts.append(chosen)
            continue
        steps = (np.arange(count) - (count - 1) / 2.0) * resolution
        offsets = np.stack(np.meshgrid(steps, steps, steps, indexing='ij'), axis=-1)
        parts.append((chosen[:, None, :] + offsets.reshape(1, -1, 3)).reshape(-1, 3))
    points = np.concatenate(parts) if parts else np.empty((0, 3))
    return points, resolution * HALF_CELL_DIAGONAL, len(points)


def _read_npy(file: Path) -> Tuple[np.ndarray, float, int]:
    array = np.load(file, allow_pickle=False)
    if array.ndim != 2 or array.shape[1] != 3:
        raise InvalidInputError(f'{file}: a .npy map must hold an (N, 3) array of x, y, z, '
                                f'got shape {tuple(array.shape)}')
    if array.dtype.kind not in 'fiu':
        raise InvalidInputError(f'{file}: a .npy map must hold numbers, got dtype {array.dtype}')
    points = np.asarray(array, dtype=np.float64)
    return points, 0.0, len(points)


#: Map file suffix (lower case) to (format name, reader).
READERS: Dict[str, Tuple[str, Callable[[Path], Tuple[np.ndarray, float, int]]]] = {
    '.pcd': ('PCD', _read_pcd),
    '.ply': ('PLY', _read_ply),
    '.las': ('LAS', _read_las),
    '.laz': ('LAZ', _read_las),
    '.bt': ('OctoMap binary', _read_octomap),
    '.npy': ('NumPy .npy', _read_npy),
}


#: The suffixes :func:`load_map_points` reads.
MAP_SUFFIXES = tuple(READERS)
