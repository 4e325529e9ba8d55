"""Prints the planner's figures over terrain and above the ground, beside the targets.

Run inside the project's environment (rasterio and pymap3d, the ``terrain`` and ``geodesy``
extras, are needed)::

    source scripts/venv.sh && python benchmarks/bench_terrain.py [--json]

Cases:

==========  ====================================================================================
dem2km      A synthetic SRTM-like DEM, 2 km x 2 km at 30 m (hills up to 200 m and 5 m of
            roughness), written as a real GeoTIFF in UTM zone 33 and read through the scene's
            ``terrain`` key with a geodetic origin; delta 2 m, gamma 2 m, ``min_agl`` 30 m,
            ``max_agl`` 120 m (the usual legal ceiling), corner to corner at 60 m AGL, bounds
            spanning the band over the DEM. Prints the DEM load, grid build and plan times of
            the octile (optimal), weighted (w = 1.05) and adaptive searches, and the worst AGL
            and terrain clearance of each curve at 10**4 samples (target: plan <= 3 s, the
            whole curve in the band).
survey      A 600 x 400 m survey site with ``ground: floor``, gamma 2 m, a start on the ground
            and a goal at 30 m: the length of the curve below gamma AGL (target 0 m; before the
            ground was a surface, 57 m). The start on the ground is lifted by the start
            admission, so the curve is measured from the plan's first point.
==========  ====================================================================================

Figures only: nothing here asserts a speed. The compiled kernels are loaded first on a tiny
scene, so the times are the planner's, not the compiler's.
"""

import argparse
import json
from pathlib import Path
import sys
import tempfile
import time
from typing import Any, Dict, List

import numpy as np

from uav_global_planner.core.io.scene import parse_scene
from uav_global_planner.core.map.ground import ground_surface, height_above_ground
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.core.planner import Planner

#: Dense samples of a curve for the AGL figures.
DENSE_SAMPLES = 10_000
#: The map frame's WGS84 origin: lat, lon [deg], alt_amsl [m] (UTM zone 33 north).
ORIGIN = {'lat': 47.0, 'lon': 15.0, 'alt_amsl': 400.0}
ALGORITHM = 'octile'
#: Searches of the DEM case: the optimum, the bounded-suboptimal one and the paper's.
ALGORITHMS = ('octile', 'weighted', 'adaptive')


def write_dem(path: Path, size_m: float = 2400.0, pixel_m: float = 30.0,
              seed: int = 20) -> Path:
    """A synthetic SRTM-like GeoTIFF (float32, EPSG:32633) centred on :data:`ORIGIN`: a plain
    at 500 m AMSL, twelve Gaussian hills of 60-200 m (sigma 120-400 m) and 5 m of smooth
    roughness, at ``pixel_m`` over a square of ``size_m`` (more than the 2 km bounds)."""
    import affine
    import rasterio
    import rasterio.warp
    east, north = rasterio.warp.transform('EPSG:4326', 'EPSG:32633', [ORIGIN['lon']],
                                          [ORIGIN['lat']])
    count = int(round(size_m / pixel_m))
    west, top = east[0] - size_m / 2, north[0] + size_m / 2
    x = (np.arange(count) + 0.5) * pixel_m - size_m / 2
    grid_x, grid_y = np.meshgrid(x, -x)
    rng = np.random.default_rng(seed)
    heights = np.full(grid_x.shape, 500.0)
    heights += 200.0 * np.exp(-((grid_x - 150.0) ** 2 + (grid_y + 80.0) ** 2)
                              / (2.0 * 300.0 ** 2))
    for _ in range(11):
        cx, cy = rng.uniform(-1100.0, 1100.0, 2)
        amplitude, sigma = rng.uniform(60.0, 180.0), rng.uniform(120.0, 400.0)
        heights += amplitude * np.exp(-((grid_x - cx) ** 2 + (grid_y - cy) ** 2)
                                      / (2.0 * sigma ** 2))
    for _ in range(6):
        k = rng.uniform(0.004, 0.02, 2)
        heights += 5.0 / 6.0 * np.sin(k[0] * grid_x + k[1] * grid_y + rng.uniform(0, 6.3))
    with rasterio.open(path, 'w', driver='GTiff', width=count, height=count, count=1,
                       dtype='float32', crs='EPSG:32633', nodata=-32768.0,
                       transform=affine.Affine(pixel_m, 0.0, west, 0.0, -pixel_m, top)
                       ) as dataset:
        dataset.write(heights.astype(np.float32), 1)
    return path


def _warm_up() -> None:
    """Load the compiled kernels on a tiny scene with a ground."""
    scene = parse_scene({'bounds': {'min': [0.0, 0.0, 0.0], 'max': [10.0, 10.0, 10.0]},
                         'resolution': 1.0, 'safety_margin': 0.5, 'adaptive_threshold': 1.5,
                         'start': [1.0, 1.0, 2.0], 'goal': [9.0, 9.0, 2.0], 'ground': 'floor',
                         'min_agl': 1.0, 'max_agl': 5.0})
    Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal, ALGORITHM)


def _curve_figures(result: Any, surface: Any) -> Dict[str, float]:
    s = np.linspace(0.0, result.curve.length_m, DENSE_SAMPLES)
    curve = result.curve.evaluate(s)
    agl = height_above_ground(surface, curve)
    return {'curve_m': float(result.curve.length_m), 'agl_min_m': float(agl.min()),
            'agl_max_m': float(agl.max()),
            'ground_clearance_m': float(surface.distance(curve).min())}


def dem2km(folder: Path) -> List[Dict[str, Any]]:
    """The 2 km DEM case (see the module notes), one row per algorithm."""
    from uav_global_planner.core.io.geodesy import GeodeticOrigin
    from uav_global_planner.core.map.dem import load_dem
    write_dem(folder / 'dem.tif')
    min_agl, max_agl, gamma, delta = 30.0, 120.0, 2.0, 2.0
    # The bounds span the band over this DEM: from its lowest point + min_agl - gamma to its
    # highest + max_agl + gamma (a delta more each way).
    relief = load_dem(folder / 'dem.tif', [-1000.0, -1000.0], [1000.0, 1000.0],
                      GeodeticOrigin(**ORIGIN)).heights
    low = float(np.floor(relief.min() + min_agl - gamma - delta))
    high = float(np.ceil(relief.max() + max_agl + gamma + delta))
    document = {'bounds': {'min': [-1000.0, -1000.0, low], 'max': [1000.0, 1000.0, high]},
                'resolution': delta, 'safety_margin': gamma, 'adaptive_threshold': 4.0,
                'start': [0.0, 0.0, 0.0], 'goal': [0.0, 0.0, 0.0],
                'geodetic_origin': ORIGIN, 'terrain': {'file': 'dem.tif'},
                'min_agl': min_agl, 'max_agl': max_agl, 'planner': {'max_planning_time': 0.0}}
    began = time.perf_counter()
    scene = parse_scene(document, folder=folder)
    load_s = time.perf_counter() - began
    terrain = scene.terrain
    ends = np.array([[-960.0, -960.0], [960.0, 960.0]])
    start, goal = (np.append(xy, terrain.height_at(xy[None])[0] + 60.0) for xy in ends)
    planner = Planner(scene.config, scene.obstacles)
    began = time.perf_counter()
    planner.warm_up()
    grid_s = time.perf_counter() - began
    rows = []
    for algorithm in ALGORITHMS:
        began = time.perf_counter()
        result = planner.plan(start, goal, algorithm)
        plan_s = time.perf_counter() - began
        figures: Dict[str, Any] = {
            'case': f'dem2km {algorithm}', 'status': result.status.value,
            'dem_load_s': load_s, 'grid_build_s': grid_s, 'plan_s': plan_s,
            'grid_and_plan_s': grid_s + plan_s, 'expanded_nodes': result.expanded_nodes,
            'nodes': int(np.prod(planner.grid.shape)),
            'terrain_lattice': list(terrain.heights.shape),
            'terrain_relief_m': float(np.ptp(terrain.heights)), 'min_agl_m': min_agl,
            'max_agl_m': max_agl, 'margin_m': scene.config.planning_margin}
        if result.ok:
            figures['path_m'] = float(result.path_length_m)
            figures.update(_curve_figures(result, terrain))
        else:
            figures['message'] = result.message
        rows.append(figures)
    return rows


def survey() -> Dict[str, Any]:
    """The 600 x 400 m survey from the ground (see the module notes)."""
    gamma = 2.0
    document = {'bounds': {'min': [0.0, 0.0, 0.0], 'max': [600.0, 400.0, 60.0]},
                'resolution': 2.0, 'safety_margin': gamma, 'adaptive_threshold': 4.0,
                'start': [10.0, 10.0, 0.0], 'goal': [590.0, 390.0, 30.0], 'ground': 'floor',
                'planner': {'max_planning_time': 0.0}}
    scene = parse_scene(document)
    # Two buildings and a mast between start and goal.
    extra = [Box([150.0, 80.0, 0.0], [210.0, 160.0, 18.0]),
             Box([330.0, 200.0, 0.0], [400.0, 300.0, 25.0]),
             Box([470.0, 300.0, 0.0], [474.0, 304.0, 45.0])]
    obstacles = ObstacleSet([*scene.obstacles.items, *extra])
    planner = Planner(scene.config, obstacles)
    start, goal = scene.start, scene.goal
    lifted = 'no start admission'
    try:
        from uav_global_planner.core.search.start_admission import admit, GOAL, START
    except ImportError:
        start = start + np.array([0.0, 0.0, gamma + scene.config.resolution])
    else:
        admitted = admit(planner, start, START, tolerance=3.0 * gamma)
        start, lifted = admitted.point, f'start admitted at z {admitted.point[2]:.3f} m'
        goal = admit(planner, goal, GOAL, tolerance=3.0 * gamma).point
    began = time.perf_counter()
    result = planner.plan(start, goal, ALGORITHM)
    plan_s = time.perf_counter() - began
    figures: Dict[str, Any] = {'case': 'survey', 'status': result.status.value,
                               'plan_s': plan_s, 'gamma_m': gamma, 'start': lifted}
    if result.ok:
        surface = ground_surface(scene.config)
        s = np.linspace(0.0, result.curve.length_m, DENSE_SAMPLES)
        agl = height_above_ground(surface, result.curve.evaluate(s))
        step = result.curve.length_m / (DENSE_SAMPLES - 1)
        figures.update(_curve_figures(result, surface))
        figures['below_gamma_m'] = float(np.count_nonzero(agl < gamma - 1e-9) * step)
        figures['below_1m_m'] = float(np.count_nonzero(agl < 1.0) * step)
    else:
        figures['message'] = result.message
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--json', action='store_true', help='print one JSON object per case')
    args = parser.parse_args()
    _warm_up()
    with tempfile.TemporaryDirectory() as folder:
        rows = dem2km(Path(folder)) + [survey()]
    for row in rows:
        if args.json:
            print(json.dumps(row))
            continue
        print(f"{row['case']}: {row['status']}")
        for key, value in row.items():
            if key not in ('case', 'status'):
                text = f'{value:.3f}' if isinstance(value, float) else str(value)
                print(f'  {key}: {text}')
    print('targets: dem2km plan <= 3 s with agl_min_m >= min_agl_m and agl_max_m <= max_agl_m; '
          'survey below_gamma_m = 0', file=sys.stderr if args.json else sys.stdout)
    return 0


if __name__ == '__main__':
    sys.exit(main())
