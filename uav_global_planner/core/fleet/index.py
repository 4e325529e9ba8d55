"""A space-time index of flights: boxes over (x, y, z, t) cells, so a check meets only the
flights near it.

A flight is cut into time chunks; over a chunk it stays in a ball around a curve point
(:func:`~uav_global_planner.core.fleet.separation.table_balls` explains why), whose box is the
chunk's box. A box is filed under every (x, y, z, t) cell it touches. A
query inflates its boxes by the envelope (horizontally and vertically) and collects every flight
filed under a cell those touch: two flights in conflict at an instant ``t`` have boxes holding
``t``, one within the envelope of the other, so they share a cell; the index never hides a
conflict.
"""

import math
from typing import Dict, List, Set, Tuple

import numpy as np

from uav_global_planner.core.fleet.separation import Flight, table_balls

Cell = Tuple[int, int, int, int]


def flight_boxes(flight: Flight, chunk_s: float) -> np.ndarray:
    """Boxes that hold the flight over chunks of ``chunk_s`` seconds.

    Returns
    -------
    numpy.ndarray, shape (n, 8)
        Rows ``[t0, t1, xmin, ymin, zmin, xmax, ymax, zmax]`` [s], [m], batch clock, ENU.
    """
    count = max(1, int(math.ceil(flight.duration_s / chunk_s)))
    edges = flight.start_s + flight.duration_s * np.arange(count + 1) / count
    edges[-1] = flight.end_s
    centre, radius = table_balls(flight, edges[:-1], edges[1:])
    radius = radius[:, None]
    return np.hstack([edges[:-1, None], edges[1:, None], centre - radius, centre + radius])


def box_cells(boxes: np.ndarray, cell_m: float, cell_z_m: float, cell_s: float,
              margin_h: float = 0.0, margin_v: float = 0.0) -> List[Cell]:
    """The (ix, iy, iz, it) cells the boxes touch, each widened by ``margin_h`` horizontally
    and ``margin_v`` vertically [m]; sorted, without repeats.

    Cell ``(ix, iy, iz, it)`` covers ``[ix, ix + 1) * cell_m`` in x (likewise y),
    ``[iz, iz + 1) * cell_z_m`` in z and ``[it, it + 1) * cell_s`` in time.
    """
    cells: Set[Cell] = set()
    if len(boxes) == 0:
        return []
    low = np.floor(np.stack([boxes[:, 2] - margin_h, boxes[:, 3] - margin_h,
                             boxes[:, 4] - margin_v, boxes[:, 0]], axis=1)
                   / np.array([cell_m, cell_m, cell_z_m, cell_s])).astype(np.int64)
    high = np.floor(np.stack([boxes[:, 5] + margin_h, boxes[:, 6] + margin_h,
                              boxes[:, 7] + margin_v, boxes[:, 1]], axis=1)
                    / np.array([cell_m, cell_m, cell_z_m, cell_s])).astype(np.int64)
    for lo, hi in zip(low.tolist(), high.tolist()):
        for ix in range(lo[0], hi[0] + 1):
            for iy in range(lo[1], hi[1] + 1):
                for iz in range(lo[2], hi[2] + 1):
                    for it in range(lo[3], hi[3] + 1):
                        cells.add((ix, iy, iz, it))
    return sorted(cells)


class SpaceTimeIndex:
    """Flights by the (x, y, z, t) cells their boxes touch.

    Parameters
    ----------
    cell_m, cell_z_m, cell_s : float
        Cell sizes: horizontal and vertical [m], time [s].
    """

    def __init__(self, cell_m: float, cell_z_m: float, cell_s: float) -> None:
        self.cell_m = float(cell_m)
        self.cell_z_m = float(cell_z_m)
        self.cell_s = float(cell_s)
        self._cells: Dict[Cell, List[int]] = {}
        self._count = 0

    @property
    def chunk_s(self) -> float:
        """Time chunk of the boxes filed and queried [s]."""
        return self.cell_s / 4.0

    def boxes(self, flight: Flight) -> np.ndarray:
        """The flight's boxes at this index's chunk (:func:`flight_boxes`)."""
        return flight_boxes(flight, self.chunk_s)

    def insert(self, key: int, boxes: np.ndarray) -> None:
        """File the boxes of the flight ``key`` (its place in the book)."""
        for cell in box_cells(boxes, self.cell_m, self.cell_z_m, self.cell_s):
            self._cells.setdefault(cell, []).append(key)
        self._count += 1

    def query(self, boxes: np.ndarray, margin_h: float, margin_v: float) -> List[int]:
        """Keys of the flights filed under a cell that the boxes, widened by the margins [m],
        touch; sorted."""
        found: Set[int] = set()
        for cell in box_cells(boxes, self.cell_m, self.cell_z_m, self.cell_s, margin_h,
                              margin_v):
            found.update(self._cells.get(cell, ()))
        return sorted(found)

    def cell_count(self) -> int:
        """Cells holding at least one flight."""
        return len(self._cells)

    def __len__(self) -> int:
        return self._count
