"""The outdoor benchmark scenes, generated deterministically in code.

- ``town400``: 200 x 200 x 40 m at delta 0.5 m (401 x 401 x 81 = 13.0 M voxels), 400 box
  buildings on a jittered street grid, start and goal at opposite corners near the ground.
- ``city1km``: 1000 x 1000 x 100 m at delta 1 m (1001 x 1001 x 101 = 101 M voxels), 300 box
  buildings, a 1.3 km crossing corner to corner.
- ``wall_gap``: the README workspace (20 x 20 x 15 m) at delta 0.25 m, two staggered walls
  with a gap at one end each and a sphere; start and goal keep more than 3 m from every
  obstacle.
- ``cloud_town``: the surfaces of the town's buildings as a point cloud (:func:`cloud_town`),
  about 0.8 M points; too large for a YAML file, so it is built here when needed.
- ``spheres_boxes_100m``: 20 x 15 x 10 m at delta 1/32 m (99 M voxels) with spheres and boxes
  across the 26.9 m diagonal, for the search on a large, mostly open grid.

The first three are written to ``config/scenes/`` by ``tools/make_scenes.py``; this module,
installed with the tools so that the benchmarks and ``uav-plan bench --outdoor`` import it, is
the one source of their geometry. Every coordinate is rounded to 0.1 m (the 100 M scene: to
1 cm) before use, so the YAML files reproduce the arrays here exactly. Random layouts use
``numpy.random.default_rng`` with fixed seeds.
"""

from dataclasses import dataclass
import math
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.map.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere

Triple = Tuple[float, float, float]

#: Face spacing of the town's surface cloud [m]: about 0.82 M points.
CLOUD_SPACING = 0.5


@dataclass(frozen=True, eq=False)
class OutdoorScene:
    """Geometry and settings of one generated scene.

    Attributes
    ----------
    name, description : str
    bounds_min, bounds_max : tuple of float
        Workspace corners [m].
    resolution, safety_margin, adaptive_threshold : float
        delta, gamma and eta [m].
    start, goal : tuple of float
        [m]
    boxes : numpy.ndarray, shape (B, 2, 3)
        ``boxes[b, 0]`` the minimum and ``boxes[b, 1]`` the maximum corner [m].
    spheres : numpy.ndarray, shape (S, 4)
        Centre x, y, z and radius [m].
    max_voxels : int or None
        Node cap the scene sets (``max_voxels`` in its file) because its grid is larger than
        planners accept by default; None otherwise.
    ground : str
        The ``ground`` setting of its file: ``'floor'`` for the outdoor towns (the ground is
        real: the scene loader adds it as a height field), ``'none'`` to leave the key out.
    """

    name: str
    description: str
    bounds_min: Triple
    bounds_max: Triple
    resolution: float
    safety_margin: float
    adaptive_threshold: float
    start: Triple
    goal: Triple
    boxes: np.ndarray
    spheres: np.ndarray
    max_voxels: Optional[int] = None
    ground: str = 'none'

    @property
    def shape(self) -> Tuple[int, int, int]:
        """Grid nodes per axis (the rule of core.grid: floor(extent / delta) + 1)."""
        extent = np.asarray(self.bounds_max) - np.asarray(self.bounds_min)
        nx, ny, nz = (int(n) for n in np.floor(extent / self.resolution + 1e-9) + 1)
        return nx, ny, nz

    @property
    def voxels(self) -> int:
        """Number of grid nodes."""
        nx, ny, nz = self.shape
        return nx * ny * nz

    def obstacle_set(self, points: Optional[np.ndarray] = None) -> ObstacleSet:
        """The obstacles as the core takes them; ``points`` replaces them by a point set."""
        if points is not None:
            return ObstacleSet([PointSet(points)])
        items: List[Obstacle] = [Sphere(s[:3], s[3]) for s in self.spheres]
        items += [Box(b[0], b[1]) for b in self.boxes]
        return ObstacleSet(items)

    def config(self, **changes: Any) -> PlannerConfig:
        """Planner settings of the scene, with a voxel cap that admits its grid."""
        values: Dict[str, Any] = {
            'bounds_min': self.bounds_min, 'bounds_max': self.bounds_max,
            'resolution': self.resolution, 'safety_margin': self.safety_margin,
            'adaptive_threshold': self.adaptive_threshold,
            'max_voxels': max(self.max_voxels or 0, PlannerConfig().max_voxels)}
        values.update(changes)
        return validate_config(PlannerConfig(**values))


def _street_cells(rng: np.random.Generator, count: int, low: float, high: float) -> np.ndarray:
    """Split [low, high] into ``count`` cells, widths drawn from U(0.6, 1.6) and scaled to fit."""
    widths = rng.uniform(0.6, 1.6, count)
    edges = low + np.concatenate([[0.0], np.cumsum(widths)]) * (high - low) / widths.sum()
    edges[-1] = high
    return np.stack([edges[:-1], edges[1:]], axis=1)


def _street_grid_town(seed: int, counts: Tuple[int, int], extent: Tuple[float, float],
                      street: float, footprint: float, heights: Tuple[float, float]) -> np.ndarray:
    """One box per cell of a jittered street grid.

    Each cell keeps half a street (``street / 2`` [m]) free along each of its edges, so two
    neighbouring buildings are at least ``street`` apart; inside the rest the footprint side is
    drawn between ``footprint`` (or the room left, when smaller) and the room left, and placed
    at random; the height is drawn from ``heights`` [m]. Coordinates are rounded to 0.1 m.
    """
    rng = np.random.default_rng(seed)
    columns = _street_cells(rng, counts[0], *extent)
    rows = _street_cells(rng, counts[1], *extent)
    boxes = []
    for column in columns:
        for row in rows:
            corner_min, corner_max = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            for axis, (a, b) in enumerate((column, row)):
                room = (b - a) - street
                side = rng.uniform(min(footprint, room), room)
                lo = a + 0.5 * street + rng.uniform(0.0, room - side)
                corner_min[axis], corner_max[axis] = lo, lo + side
            corner_max[2] = rng.uniform(*heights)
            boxes.append([corner_min, corner_max])
    return _rounded(np.array(boxes), 1)


def _rounded(values: np.ndarray, decimals: int) -> np.ndarray:
    """Round to ``decimals`` and map -0.0 to 0.0, so that the YAML text reproduces the array."""
    out = np.round(values, decimals)
    out[out == 0.0] = 0.0
    return out


def town400_boxes() -> np.ndarray:
    """The 400 buildings of ``town400``, shape (400, 2, 3) [m].

    A 20 x 20 street grid over [-95, 95] m on x and y, cells 5.5 to 15.2 m wide, streets at
    least 2 m wide, footprint sides 3.5 to 13.0 m (4 m or more where the cell allows), heights
    5 to 34.9 m.
    """
    return _street_grid_town(seed=400, counts=(20, 20), extent=(-95.0, 95.0), street=2.0,
                             footprint=4.0, heights=(5.0, 35.0))


def city1km_boxes() -> np.ndarray:
    """The 300 buildings of ``city1km``, shape (300, 2, 3) [m].

    A 15 x 20 street grid over [-450, 450] m on x and y, cells 26 to 85 m wide, streets at
    least 8 m wide, footprint sides 15.2 to 73.9 m, heights 10.4 to 89.7 m.
    """
    return _street_grid_town(seed=1000, counts=(15, 20), extent=(-450.0, 450.0), street=8.0,
                             footprint=15.0, heights=(10.0, 90.0))


def _street_town(name: str, description: str, half: float, height: float, delta: float,
                 corner: float, boxes: np.ndarray,
                 max_voxels: Optional[int] = None) -> OutdoorScene:
    """A town of box buildings over [-half, half]^2 x [0, height] m on a real ground (its
    floor), planned at ``delta`` with gamma = delta, crossed from (-corner, -corner, 2) to
    (corner, corner, 2) m."""
    return OutdoorScene(
        name=name, description=description, bounds_min=(-half, -half, 0.0),
        bounds_max=(half, half, height), resolution=delta, safety_margin=delta,
        adaptive_threshold=1.5, start=(-corner, -corner, 2.0), goal=(corner, corner, 2.0),
        boxes=boxes, spheres=np.empty((0, 4)), max_voxels=max_voxels, ground='floor')


def town400() -> OutdoorScene:
    """The 400-building town: 13.0 M voxels, a 277 m crossing from corner to corner."""
    return _street_town(
        'town400', '400 box buildings (5-35 m high) on a jittered 20 x 20 street grid, '
        '200 x 200 x 40 m at 0.5 m: 401 x 401 x 81 = 13.0 M voxels; a 277 m crossing between '
        'opposite corners near the ground. Generated by tools/make_scenes.py.',
        half=100.0, height=40.0, delta=0.5, corner=98.0, boxes=town400_boxes())


def city1km() -> OutdoorScene:
    """The 1 km city: 101 M voxels (above the default cap), a 1.30 km crossing."""
    return _street_town(
        'city1km', '300 box buildings (10-90 m high) on a jittered 15 x 20 street grid, '
        '1000 x 1000 x 100 m at 1 m: 1001 x 1001 x 101 = 101 M voxels (above the default node '
        'cap, hence max_voxels); a 1.30 km crossing between opposite corners near the ground. '
        'Generated by tools/make_scenes.py.',
        half=500.0, height=100.0, delta=1.0, corner=460.0, boxes=city1km_boxes(),
        max_voxels=110_000_000)


def wall_gap() -> OutdoorScene:
    """The README workspace with two staggered walls and a sphere over the corridor between them.

    Each full-height wall leaves a 5 m gap at one end, so a path from one side to the other
    winds through both gaps and along the 6.8 m corridor between the walls (0.8 m wide at gamma
    3 m, where the path is about 43 m long). Start and goal keep 4.9 m from every obstacle, so
    the scene plans with gamma up to 4.8 m.
    """
    walls = np.array([[[-10.0, -3.6, 0.0], [5.0, -3.4, 15.0]],
                      [[-5.0, 3.4, 0.0], [10.0, 3.6, 15.0]]])
    return OutdoorScene(
        name='wall_gap',
        description=('The README workspace at 0.25 m (81 x 81 x 61 = 0.40 M voxels): two '
                     'staggered full-height walls across y = -3.5 and y = 3.5, each leaving a '
                     '5 m gap at one end, and a sphere of radius 1.5 m over the corridor '
                     'between them; start and goal on either side are free for gamma up to '
                     '4.8 m. Generated by tools/make_scenes.py.'),
        bounds_min=(-10.0, -10.0, 0.0), bounds_max=(10.0, 10.0, 15.0), resolution=0.25,
        safety_margin=0.2, adaptive_threshold=1.5, start=(0.0, -8.5, 1.0),
        goal=(0.0, 8.5, 1.0), boxes=walls, spheres=np.array([[0.0, 0.0, 12.0, 1.5]]))


def spheres_boxes_100m() -> OutdoorScene:
    """Spheres and boxes across a 20 x 15 x 10 m box at delta 1/32 m: 99.0 M voxels.

    Start and goal are opposite corners (26.9 m apart); ten spheres and six boxes sit near the
    diagonal between them, none within 2 m of either corner.
    """
    rng = np.random.default_rng(27)
    low, high = np.array([0.0, 0.0, 0.0]), np.array([20.0, 15.0, 10.0])
    spheres, boxes = [], []
    for t in np.linspace(0.15, 0.85, 10):
        center = np.clip(low + t * (high - low) + rng.uniform(-1.5, 1.5, 3), 1.0, high - 1.0)
        spheres.append([*center, rng.uniform(0.6, 1.6)])
    for t in np.linspace(0.2, 0.8, 6):
        center = low + t * (high - low) + rng.uniform(-2.0, 2.0, 3)
        half = rng.uniform(0.3, 1.5, 3)
        boxes.append([np.maximum(center - half, 0.0), np.minimum(center + half, high)])
    return OutdoorScene(
        name='spheres_boxes_100m',
        description='10 spheres and 6 boxes over a 26.9 m diagonal, 641 x 481 x 321 nodes',
        bounds_min=(0.0, 0.0, 0.0), bounds_max=(20.0, 15.0, 10.0), resolution=0.03125,
        safety_margin=0.2, adaptive_threshold=1.5, start=(0.0, 0.0, 0.0),
        goal=(20.0, 15.0, 10.0), boxes=_rounded(np.array(boxes), 2),
        spheres=_rounded(np.array(spheres), 2), max_voxels=110_000_000)


#: The scenes written to config/scenes/ by tools/make_scenes.py, by name.
SHIPPED = {'town400': town400, 'city1km': city1km, 'wall_gap': wall_gap}


def _lattice(low: float, high: float, spacing: float) -> np.ndarray:
    """Evenly spaced values from ``low`` to ``high`` inclusive, at most ``spacing`` apart."""
    return np.linspace(low, high, int(math.ceil((high - low) / spacing - 1e-9)) + 1)


def surface_cloud(boxes: np.ndarray, spacing: float = CLOUD_SPACING,
                  ground: float = 0.0) -> np.ndarray:
    """Points on the surfaces of boxes, on a lattice at most ``spacing`` apart on each face.

    The roof and the four walls of every box are sampled (the floor too when it is above
    ``ground``), edges and corners once each, as a scanner's cloud of the buildings would see
    them; the inside stays empty.

    Parameters
    ----------
    boxes : numpy.ndarray, shape (B, 2, 3)
        Minimum and maximum corners [m].
    spacing : float
        Largest distance between neighbouring points on a face [m], > 0.
    ground : float
        Height of the ground [m]: a floor at or below it is not sampled.

    Returns
    -------
    numpy.ndarray, shape (M, 3)
        [m], deterministic (box by box, face by face).

    Raises
    ------
    ValueError
        For a spacing that is not a positive number, or boxes not of shape (B, 2, 3).
    """
    if not (isinstance(spacing, (int, float)) and math.isfinite(spacing) and spacing > 0.0):
        raise ValueError(f'spacing must be a number > 0 m, got {spacing!r}')
    boxes = np.asarray(boxes, dtype=np.float64)
    if boxes.ndim != 3 or boxes.shape[1:] != (2, 3):
        raise ValueError(f'boxes must have shape (B, 2, 3), got {boxes.shape}')
    parts = []
    for (x0, y0, z0), (x1, y1, z1) in boxes:
        xs, ys, zs = (_lattice(x0, x1, spacing), _lattice(y0, y1, spacing),
                      _lattice(z0, z1, spacing))
        floor = z0 > ground
        roof_x, roof_y = np.meshgrid(xs, ys, indexing='ij')
        for height in ((z1, z0) if floor else (z1,)):
            parts.append(np.stack([roof_x.ravel(), roof_y.ravel(),
                                   np.full(roof_x.size, height)], axis=1))
        side_z = zs[1:-1] if floor else zs[:-1]
        wall_y, wall_z = np.meshgrid(ys, side_z, indexing='ij')
        for x in (x0, x1):
            parts.append(np.stack([np.full(wall_y.size, x), wall_y.ravel(), wall_z.ravel()],
                                  axis=1))
        wall_x, wall_z = np.meshgrid(xs[1:-1], side_z, indexing='ij')
        for y in (y0, y1):
            parts.append(np.stack([wall_x.ravel(), np.full(wall_x.size, y), wall_z.ravel()],
                                  axis=1))
    if not parts:
        return np.empty((0, 3))
    return np.concatenate(parts)


def cloud_town(spacing: float = CLOUD_SPACING) -> np.ndarray:
    """``cloud_town``: the surfaces of the town's 400 buildings as points, shape (M, 3) [m]."""
    return surface_cloud(town400_boxes(), spacing)


def _number(value: float) -> str:
    """A float as YAML reads it back exactly (shortest round-trip text, always with a dot)."""
    text = repr(float(value))
    if '.' not in text or 'e' in text or 'n' in text:
        raise ValueError(f'{value!r} has no plain decimal YAML form')
    return text


def _triple(values) -> str:
    return '[' + ', '.join(_number(v) for v in values) + ']'


def scene_yaml(scene: OutdoorScene, with_max_voxels: bool) -> str:
    """The scene file text of ``scene`` (the format of core.scene), one obstacle per line.

    Parameters
    ----------
    scene : OutdoorScene
    with_max_voxels : bool
        Write the scene's node cap, if it has one, as ``max_voxels`` (for a scene loader that
        accepts that key).
    """
    quoted = scene.description.replace("'", "''")
    lines = [f'# {scene.name}: generated by tools/make_scenes.py from '
             'uav_global_planner_tools/outdoor_scenes.py; '
             'edit those, not this file.',
             f"description: '{quoted}'",
             'frame_id: map',
             'bounds:',
             f'  min: {_triple(scene.bounds_min)}',
             f'  max: {_triple(scene.bounds_max)}',
             f'resolution: {_number(scene.resolution)}',
             f'safety_margin: {_number(scene.safety_margin)}',
             f'adaptive_threshold: {_number(scene.adaptive_threshold)}']
    if with_max_voxels and scene.max_voxels is not None:
        lines.append(f'max_voxels: {int(scene.max_voxels)}')
    if scene.ground != 'none':
        lines.append(f'ground: {scene.ground}')
    lines += [f'start: {_triple(scene.start)}', f'goal: {_triple(scene.goal)}', 'obstacles:']
    for x, y, z, r in scene.spheres:
        lines.append(f'- {{type: sphere, center: {_triple((x, y, z))}, radius: {_number(r)}}}')
    for lo, hi in scene.boxes:
        lines.append(f'- {{type: box, min: {_triple(lo)}, max: {_triple(hi)}}}')
    return '\n'.join(lines) + '\n'


def summary(scene: OutdoorScene) -> Dict[str, object]:
    """Sizes of a scene, for reports: voxels, obstacles, footprint and height ranges [m]."""
    sides = scene.boxes[:, 1, :2] - scene.boxes[:, 0, :2] if len(scene.boxes) else np.zeros((0, 2))
    heights = scene.boxes[:, 1, 2] - scene.boxes[:, 0, 2] if len(scene.boxes) else np.zeros(0)
    crossing = float(np.linalg.norm(np.subtract(scene.goal, scene.start)))
    return {'name': scene.name, 'shape': list(scene.shape), 'voxels': scene.voxels,
            'boxes': len(scene.boxes), 'spheres': len(scene.spheres),
            'footprint_m': [float(sides.min()), float(sides.max())] if sides.size else None,
            'height_m': [float(heights.min()), float(heights.max())] if heights.size else None,
            'crossing_m': crossing}
