"""Map files that cannot be right, each written by its format's own library.

The refused-input catalogues (core, command line and node) write these into a test folder:
:class:`MapFile` names a file and how to write it, so a catalogue row can hold one.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Sequence

import laspy
import numpy as np
import octomap
from plyfile import PlyData, PlyElement
from pypcd4 import Encoding, PointCloud


@dataclass(frozen=True)
class MapFile:
    """A map file to write: its name (the suffix chooses the reader) and its writer.

    Attributes
    ----------
    name : str
    write : callable
        Writes the file at the path it is given.
    """

    name: str
    write: Callable[[Path], None]

    def at(self, folder: Path) -> Path:
        """Write the file into ``folder``; its path."""
        path = folder / self.name
        path.parent.mkdir(parents=True, exist_ok=True)
        self.write(path)
        return path


# A small block of points in the workspace of the catalogues (inside [-2, 2] x [-2, 2] x [0, 3]
# and [0, 6] x [0, 6] x [0, 4]), 50 of them [m].
BLOCK = np.array([[0.5 + 0.1 * i, 0.5 + 0.1 * j, 0.5 + 0.1 * k]
                  for i in range(5) for j in range(5) for k in range(2)])
# The same block in UTM coordinates (zone 32N, metres), as a survey exports it: every point is
# far outside a local planning frame.
UTM = BLOCK + np.array([465_000.0, 5_247_000.0, 410.0])
# NaN and infinite coordinates only (an organised cloud without a single return).
NON_FINITE = np.where(np.arange(150).reshape(50, 3) % 2 == 0, np.nan, np.inf)
EMPTY = np.empty((0, 3))


def ply(points: np.ndarray) -> Callable[[Path], None]:
    """A binary PLY file of float32 vertices, by plyfile."""
    def write(path: Path) -> None:
        vertex = np.empty(len(points), dtype=[('x', 'f4'), ('y', 'f4'), ('z', 'f4')])
        vertex['x'], vertex['y'], vertex['z'] = np.asarray(points, dtype=np.float64).T
        PlyData([PlyElement.describe(vertex, 'vertex')]).write(str(path))
    return write


def pcd(points: np.ndarray, viewpoint: Optional[Sequence[float]] = None
        ) -> Callable[[Path], None]:
    """An ASCII PCD file, by pypcd4, with the header's VIEWPOINT set when given."""
    def write(path: Path) -> None:
        cloud = PointCloud.from_xyz_points(np.asarray(points, dtype=np.float32).reshape(-1, 3))
        if viewpoint is not None:
            cloud.metadata.viewpoint = tuple(viewpoint)
        cloud.save(path, encoding=Encoding.ASCII)
    return write


def las(points: np.ndarray, scales: Sequence[float] = (0.001, 0.001, 0.001)
        ) -> Callable[[Path], None]:
    """A LAS 1.2 file, by laspy, with the header's scales as given."""
    def write(path: Path) -> None:
        header = laspy.LasHeader(point_format=3, version='1.2')
        cloud = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        header.offsets = np.floor(cloud.min(axis=0)) if len(cloud) else np.zeros(3)
        header.scales = np.asarray(scales, dtype=np.float64)
        data = laspy.LasData(header)
        with np.errstate(invalid='ignore'):  # a NaN scale casts to garbage integers
            data.x, data.y, data.z = cloud.T
            data.write(str(path))
    return write


def bt(points: np.ndarray, resolution: float = 0.1) -> Callable[[Path], None]:
    """An OctoMap binary file, by octomap-python: the cells of ``points`` occupied."""
    def write(path: Path) -> None:
        tree = octomap.OcTree(resolution)
        for point in np.asarray(points, dtype=np.float64).reshape(-1, 3):
            tree.updateNode(point, True)
        assert tree.writeBinary(str(path).encode())
    return write


def npy(points: np.ndarray) -> Callable[[Path], None]:
    """A NumPy .npy file of an (N, 3) float64 array."""
    def write(path: Path) -> None:
        np.save(path, np.asarray(points, dtype=np.float64).reshape(-1, 3))
    return write
