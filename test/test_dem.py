"""Terrain from digital elevation models, the ground setting and the height band above ground.

A real GeoTIFF, written by rasterio with a CRS and a geotransform, holds analytic hills; read
into the map frame it must give the hills' heights at every lattice node within the bilinear
interpolation error, bounded from the hills' curvature. ESRI ASCII grids and ``.npy`` lattices
come back exactly; every refusal names the file. A plan across the hills keeps its whole curve
clear of the terrain and inside the AGL band at dense samples.
"""

import math
from pathlib import Path
import sys

import numpy as np
import pytest

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import enu_to_geodetic, GeodeticOrigin
from uav_global_planner.core.io.scene import parse_scene
from uav_global_planner.core.map.dem import load_dem, parse_terrain, TerrainSource
from uav_global_planner.core.map.ground import ground_obstacles, ground_surface

rasterio = pytest.importorskip('rasterio')
warp = pytest.importorskip('rasterio.warp')
affine = pytest.importorskip('affine')

# A map frame in UTM zone 33 north (EPSG:32633, central meridian 15 deg E).
ORIGIN = GeodeticOrigin(47.0, 15.0, 400.0)
UTM = 'EPSG:32633'
PIXEL = 30.0           # DEM spacing [m], SRTM-like
HILL_HEIGHT = 200.0    # [m]
HILL_SIGMA = 300.0     # [m]
BASE = 600.0           # elevation of the plain [m AMSL]


def _origin_utm():
    east, north = warp.transform('EPSG:4326', UTM, [ORIGIN.lon], [ORIGIN.lat])
    return float(east[0]), float(north[0])


def hills(east, north, centre):
    """Elevation [m AMSL] of two Gaussian hills around ``centre`` (UTM easting, northing)."""
    e, n = np.asarray(east) - centre[0], np.asarray(north) - centre[1]
    return (BASE + HILL_HEIGHT * np.exp(-((e - 200.0) ** 2 + (n + 100.0) ** 2)
                                        / (2.0 * HILL_SIGMA ** 2))
            + 0.5 * HILL_HEIGHT * np.exp(-((e + 300.0) ** 2 + (n - 250.0) ** 2)
                                         / (2.0 * HILL_SIGMA ** 2)))


def write_geotiff(path: Path, crs=UTM, size=100, nodata_at=None, centre=None):
    """A float32 GeoTIFF of :func:`hills` centred on the map origin, ``size`` pixels square."""
    centre = _origin_utm() if centre is None else centre
    west, north = centre[0] - size * PIXEL / 2, centre[1] + size * PIXEL / 2
    east_c = west + (np.arange(size) + 0.5) * PIXEL
    north_c = north - (np.arange(size) + 0.5) * PIXEL
    grid_e, grid_n = np.meshgrid(east_c, north_c)
    data = hills(grid_e, grid_n, centre).astype(np.float32)
    if nodata_at is not None:
        data[nodata_at] = -9999.0
    with rasterio.open(path, 'w', driver='GTiff', width=size, height=size, count=1,
                       dtype='float32', crs=crs,
                       transform=from_origin(west, north, PIXEL, PIXEL),
                       nodata=-9999.0) as dataset:
        dataset.write(data, 1)
    return path


def _nodes(field):
    ny, nx = field.heights.shape
    xs = field.origin[0] + np.arange(nx) * field.spacing[0]
    ys = field.origin[1] + np.arange(ny) * field.spacing[1]
    return np.meshgrid(xs, ys)


def _bilinear_bound():
    """Bilinear interpolation error bound (dx**2 |f_xx| + dy**2 |f_yy|) / 8 for the hills
    (|f_xx| <= A / sigma**2 for a Gaussian of height A), plus float32 rounding."""
    curvature = 1.5 * HILL_HEIGHT / HILL_SIGMA ** 2
    return 2.0 * PIXEL ** 2 / 8.0 * curvature + 1e-3


def from_origin(west, north, xsize, ysize):
    """A north-up geotransform: the top-left corner and the pixel size [CRS units]."""
    return affine.Affine(xsize, 0.0, west, 0.0, -ysize, north)


# ------------------------------------------------------------------------------- GeoTIFF

def test_utm_geotiff_gives_the_hills_in_the_map_frame(tmp_path):
    field = load_dem(write_geotiff(tmp_path / 'hills.tif'), [-500.0, -400.0],
                     [500.0, 600.0], ORIGIN)
    assert field.side == 'below'
    assert np.allclose(field.origin, [-500.0, -400.0])
    assert np.all(field.spacing <= PIXEL) and np.all(field.spacing > 0.9 * PIXEL)
    grid_x, grid_y = _nodes(field)
    assert grid_x[-1, -1] == pytest.approx(500.0) and grid_y[-1, -1] == pytest.approx(600.0)
    enu = np.column_stack([grid_x.ravel(), grid_y.ravel(), np.zeros(grid_x.size)])
    lat, lon, base = enu_to_geodetic(enu, ORIGIN)
    east, north = warp.transform('EPSG:4326', UTM, lon, lat)
    expected = hills(east, north, _origin_utm()) - base
    error = np.abs(field.heights.ravel() - expected)
    assert error.max() <= _bilinear_bound()
    # z is the elevation less the origin's altitude and the ellipsoid's drop (< 0.1 m here).
    drop = base - ORIGIN.alt_amsl
    assert np.all((drop >= 0.0) & (drop < 0.1))


def test_geographic_geotiff_is_placed_with_the_origin(tmp_path):
    # The same hills sampled on a lat/lon raster (EPSG:4326), 1 arc-second pixels.
    step = 1.0 / 3600.0
    size = 120
    west, north = ORIGIN.lon - size * step / 2, ORIGIN.lat + size * step / 2
    lon_c = west + (np.arange(size) + 0.5) * step
    lat_c = north - (np.arange(size) + 0.5) * step
    grid_lon, grid_lat = np.meshgrid(lon_c, lat_c)
    east, north_m = warp.transform('EPSG:4326', UTM, grid_lon.ravel(), grid_lat.ravel())
    data = hills(east, north_m, _origin_utm()).reshape(size, size).astype(np.float32)
    path = tmp_path / 'geographic.tif'
    with rasterio.open(path, 'w', driver='GTiff', width=size, height=size, count=1,
                       dtype='float32', crs='EPSG:4326',
                       transform=from_origin(west, north, step, step)) as dataset:
        dataset.write(data, 1)
    field = load_dem(path, [-1000.0, -1000.0], [1000.0, 1000.0], ORIGIN)
    # 1 arc-second: 30.9 m north-south, 21.1 m east-west at 47 deg.
    assert field.spacing[0] == pytest.approx(21.1, abs=0.5)
    assert field.spacing[1] == pytest.approx(30.9, abs=0.5)
    grid_x, grid_y = _nodes(field)
    lat, lon, base = enu_to_geodetic(
        np.column_stack([grid_x.ravel(), grid_y.ravel(), np.zeros(grid_x.size)]), ORIGIN)
    east, north_m = warp.transform('EPSG:4326', UTM, lon, lat)
    expected = hills(east, north_m, _origin_utm()) - base
    assert np.abs(field.heights.ravel() - expected).max() <= _bilinear_bound()


def test_projected_geotiff_without_origin_is_its_own_map_frame(tmp_path):
    centre = (500_000.0, 5_200_000.0)
    path = write_geotiff(tmp_path / 'utm.tif', centre=centre)
    field = load_dem(path, [centre[0] - 900.0, centre[1] - 900.0],
                     [centre[0] + 900.0, centre[1] + 900.0])
    grid_x, grid_y = _nodes(field)
    expected = hills(grid_x, grid_y, centre)
    assert np.abs(field.heights - expected).max() <= _bilinear_bound()


@pytest.mark.filterwarnings('ignore::rasterio.errors.NotGeoreferencedWarning')
def test_geotiff_refusals_name_the_file(tmp_path):
    path = write_geotiff(tmp_path / 'hills.tif')
    with pytest.raises(InvalidInputError, match='does not cover the bounds') as error:
        load_dem(path, [-1600.0, -100.0], [100.0, 100.0], ORIGIN)
    assert 'hills.tif' in str(error.value)
    holed = write_geotiff(tmp_path / 'holed.tif', nodata_at=(50, 50))
    with pytest.raises(InvalidInputError, match='holes'):
        load_dem(holed, [-300.0, -300.0], [300.0, 300.0], ORIGIN)
    # A hole outside the bounds does not matter.
    load_dem(holed, [300.0, 300.0], [900.0, 900.0], ORIGIN)
    geographic = tmp_path / 'geographic.tif'
    with rasterio.open(geographic, 'w', driver='GTiff', width=4, height=4, count=1,
                       dtype='float32', crs='EPSG:4326',
                       transform=from_origin(15.0, 47.0, 0.001, 0.001)) as dataset:
        dataset.write(np.zeros((4, 4), np.float32), 1)
    with pytest.raises(InvalidInputError, match='geodetic_origin'):
        load_dem(geographic, [15.0005, 46.998], [15.002, 46.9995])
    bare = tmp_path / 'bare.tif'
    with rasterio.open(bare, 'w', driver='GTiff', width=4, height=4, count=1,
                       dtype='float32') as dataset:
        dataset.write(np.zeros((4, 4), np.float32), 1)
    with pytest.raises(InvalidInputError, match='no CRS'):
        load_dem(bare, [0.0, 0.0], [1.0, 1.0], ORIGIN)


# ------------------------------------------------------------------------- .asc and .npy

def _asc_text(heights, header):
    rows = '\n'.join(' '.join(f'{value:g}' for value in row) for row in heights[::-1])
    return ''.join(f'{key} {value}\n' for key, value in header.items()) + rows + '\n'


def test_asc_round_trip_and_crop(tmp_path):
    rng = np.random.default_rng(1)
    heights = rng.uniform(0.0, 50.0, (12, 15)).round(3)  # heights[j, i], j northwards
    path = tmp_path / 'grid.asc'
    path.write_text(_asc_text(heights, {'ncols': 15, 'nrows': 12, 'xllcorner': -5.0,
                                        'yllcorner': 10.0, 'cellsize': 2.0,
                                        'NODATA_value': -9999}))
    # Cell centres: x = -4 + 2 i, y = 11 + 2 j.
    whole = load_dem(path, [-4.0, 11.0], [24.0, 33.0])
    assert np.allclose(whole.origin, [-4.0, 11.0]) and np.allclose(whole.spacing, [2.0, 2.0])
    assert np.array_equal(whole.heights, heights)
    part = load_dem(path, [-1.0, 14.5], [6.0, 20.0])
    # The smallest window of nodes covering x [-1, 6], y [14.5, 20]: i 1..5, j 1..5.
    assert np.allclose(part.origin, [-2.0, 13.0])
    assert np.array_equal(part.heights, heights[1:6, 1:6])
    centred = tmp_path / 'centred.asc'
    centred.write_text(_asc_text(heights, {'ncols': 15, 'nrows': 12, 'xllcenter': -4.0,
                                           'yllcenter': 11.0, 'cellsize': 2.0}))
    assert np.array_equal(load_dem(centred, [-4.0, 11.0], [24.0, 33.0]).heights, heights)


def test_npy_round_trip(tmp_path):
    heights = np.arange(20.0).reshape(4, 5)
    path = tmp_path / 'grid.npy'
    np.save(path, heights)
    source = parse_terrain({'file': 'grid.npy', 'origin': [1.0, 2.0], 'spacing': [0.5, 1.5]},
                           tmp_path)
    field = load_dem(source, [1.0, 2.0], [3.0, 6.5])
    assert np.array_equal(field.heights, heights)
    assert np.allclose(field.origin, [1.0, 2.0]) and np.allclose(field.spacing, [0.5, 1.5])


@pytest.mark.parametrize('header, reason', [
    ({'cellsize': 'nan'}, 'must be finite'),
    ({'xllcorner': 'inf'}, 'must be finite'),
    ({'cellsize': 0.0}, 'cellsize must be > 0'),
    ({'cellsize': -1.0}, 'cellsize must be > 0'),
    ({'ncols': 3}, 'announces'),
])
def test_asc_header_refusals(tmp_path, header, reason):
    values = {'ncols': 4, 'nrows': 4, 'xllcorner': 0.0, 'yllcorner': 0.0, 'cellsize': 1.0,
              'nodata_value': -9999, **header}
    path = tmp_path / 'bad.asc'
    path.write_text(_asc_text(np.zeros((4, 4)), values))
    with pytest.raises(InvalidInputError, match=reason) as error:
        load_dem(path, [0.5, 0.5], [3.5, 3.5])
    assert 'bad.asc' in str(error.value)


def test_map_frame_grid_refusals(tmp_path):
    heights = np.zeros((4, 4))
    heights[2, 1] = -9999.0
    path = tmp_path / 'holed.asc'
    path.write_text(_asc_text(heights, {'ncols': 4, 'nrows': 4, 'xllcenter': 0.0,
                                        'yllcenter': 0.0, 'cellsize': 1.0,
                                        'nodata_value': -9999}))
    with pytest.raises(InvalidInputError, match=r'1 hole\(s\).*x 1.0, y 2.0'):
        load_dem(path, [0.0, 0.0], [3.0, 3.0])
    load_dem(path, [2.0, 0.0], [3.0, 3.0])  # the hole is outside these bounds
    with pytest.raises(InvalidInputError, match='does not cover the bounds'):
        load_dem(path, [2.0, 0.0], [3.5, 3.0])
    npy = tmp_path / 'nan.npy'
    np.save(npy, np.array([[0.0, np.nan], [0.0, 0.0]]))
    with pytest.raises(InvalidInputError, match='hole'):
        load_dem(TerrainSource(npy, (0.0, 0.0), (1.0, 1.0)), [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InvalidInputError, match='spacing must be finite and > 0'):
        load_dem(TerrainSource(npy, (0.0, 0.0), (0.0, 1.0)), [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InvalidInputError, match=r'terrain.spacing: must be > 0'):
        parse_terrain({'file': 'x.npy', 'origin': [0, 0], 'spacing': [1.0, -1.0]})
    with pytest.raises(InvalidInputError, match='needs origin'):
        parse_terrain({'file': 'x.npy'})
    with pytest.raises(InvalidInputError, match='must be finite'):
        parse_terrain({'file': 'x.npy', 'origin': [0, math.inf], 'spacing': [1, 1]})
    ragged = tmp_path / 'flat.npy'
    np.save(ragged, np.zeros(5))
    with pytest.raises(InvalidInputError, match='2D array'):
        load_dem(TerrainSource(ragged, (0.0, 0.0), (1.0, 1.0)), [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InvalidInputError, match='no such terrain file'):
        load_dem(tmp_path / 'missing.tif', [0.0, 0.0], [1.0, 1.0])


# ----------------------------------------------------------------- ground and AGL settings

def _scene(**extra):
    document = {'bounds': {'min': [0.0, 0.0, 0.0], 'max': [20.0, 20.0, 10.0]},
                'resolution': 1.0, 'safety_margin': 0.5, 'adaptive_threshold': 1.5,
                'start': [1.0, 1.0, 2.0], 'goal': [19.0, 19.0, 2.0]}
    document.update(extra)
    return document


def test_ground_setting_and_band_become_height_fields():
    assert parse_scene(_scene()).ground == ()
    floor = parse_scene(_scene(ground='floor'))
    assert [shape.label for shape in floor.ground] == ['ground']
    assert floor.ground[0].height_at(np.array([[5.0, 5.0]]))[0] == pytest.approx(0.0)
    assert floor.ground[0] in floor.obstacles.items
    band = parse_scene(_scene(ground=1.5, min_agl=2.0, max_agl=6.0))
    ground, low, high = band.ground
    xy = np.array([[3.0, 4.0]])
    margin = band.config.planning_margin
    assert ground.height_at(xy)[0] == pytest.approx(1.5)
    assert (low.side, low.label) == ('below', 'min_agl')
    assert low.height_at(xy)[0] == pytest.approx(1.5 + 2.0 - margin)
    assert (high.side, high.label) == ('above', 'max_agl')
    assert high.height_at(xy)[0] == pytest.approx(1.5 + 6.0 + margin)
    # A min_agl not above the margin needs no surface: the ground's clearance proves it.
    assert len(parse_scene(_scene(ground='floor', min_agl=0.4)).ground) == 1


def test_ground_and_band_refusals():
    with pytest.raises(InvalidInputError, match='ground: must be none, floor or a number'):
        parse_scene(_scene(ground='grass'))
    with pytest.raises(InvalidInputError, match='there is none'):
        parse_scene(_scene(min_agl=2.0))
    with pytest.raises(InvalidInputError, match='max_agl must be above min_agl'):
        validate_config(PlannerConfig(min_agl=5.0, max_agl=5.0))
    with pytest.raises(InvalidInputError, match='below bounds.max z'):
        parse_scene(_scene(ground=10.0))
    assert validate_config(PlannerConfig(ground='2.5')).ground == 2.5


def test_scene_terrain_key_reads_the_dem_over_the_bounds(tmp_path):
    write_geotiff(tmp_path / 'hills.tif')
    document = _scene(terrain={'file': 'hills.tif'}, max_agl=120.0,
                      geodetic_origin={'lat': ORIGIN.lat, 'lon': ORIGIN.lon,
                                       'alt_amsl': ORIGIN.alt_amsl})
    document['bounds'] = {'min': [-300.0, -300.0, 150.0], 'max': [300.0, 300.0, 450.0]}
    document['resolution'] = 10.0
    scene = parse_scene(document, folder=tmp_path)
    assert scene.terrain is scene.ground[0]
    assert [shape.label for shape in scene.ground] == ['terrain', 'max_agl']
    assert ground_surface(scene.config, scene.terrain) is scene.terrain
    assert len(ground_obstacles(scene.config, scene.terrain)) == 2
    document['terrain'] = {'file': 'missing.tif'}
    with pytest.raises(InvalidInputError, match='terrain.file: .*no such terrain file'):
        parse_scene(document, folder=tmp_path)


# --------------------------------------------------------------------- a plan over the hills

DENSE_SAMPLES = 10_000


MIN_AGL, MAX_AGL = 20.0, 120.0


@pytest.fixture(scope='module')
def hills_plan(tmp_path_factory):
    """A plan across the hills of a GeoTIFF, 60 m above the terrain at both ends."""
    from uav_global_planner.core.planner import Planner
    folder = tmp_path_factory.mktemp('hills')
    write_geotiff(folder / 'hills.tif')
    document = _scene(terrain={'file': 'hills.tif'}, min_agl=MIN_AGL, max_agl=MAX_AGL,
                      geodetic_origin={'lat': ORIGIN.lat, 'lon': ORIGIN.lon,
                                       'alt_amsl': ORIGIN.alt_amsl})
    document.update(bounds={'min': [-400.0, -400.0, 150.0], 'max': [400.0, 400.0, 550.0]},
                    resolution=10.0, safety_margin=5.0, adaptive_threshold=15.0)
    scene = parse_scene(document, folder=folder)
    ends = np.array([[-370.0, -370.0], [370.0, 370.0]])
    start, goal = (np.append(xy, scene.terrain.height_at(xy[None])[0] + 60.0) for xy in ends)
    result = Planner(scene.config, scene.obstacles).plan(start, goal, 'octile')
    assert result.ok, result.message
    return scene, result


def test_plan_across_the_hills_keeps_clearance_and_the_agl_band(hills_plan):
    from uav_global_planner.core.map.ground import height_above_ground
    scene, result = hills_plan
    terrain = scene.terrain
    s = np.linspace(0.0, result.curve.length_m, DENSE_SAMPLES)
    curve = result.curve.evaluate(s)
    margin = scene.config.planning_margin
    assert terrain.distance(curve).min() >= margin - 1e-9
    agl = height_above_ground(terrain, curve)
    assert agl.min() >= MIN_AGL - 1e-9 and agl.max() <= MAX_AGL + 1e-9
    # The straight line at 60 m AGL would not do: the hills make the curve climb and descend.
    assert np.ptp(curve[:, 2]) > 100.0
    # Certified against every obstacle, the band's surfaces included.
    assert scene.obstacles.distance(curve).min() >= margin - 1e-9
    assert result.min_clearance_m >= margin - 1e-9


def test_mission_over_the_hills_is_relative_to_home_and_keeps_the_band(hills_plan, tmp_path):
    from pymavlink import mavwp
    from uav_global_planner.core.io.geodesy import geodetic_to_enu
    from uav_global_planner.core.map.ground import height_above_ground
    from uav_global_planner.core.mission import (MAV_CMD_NAV_LAND, MAV_CMD_NAV_WAYPOINT,
                                                 MAV_FRAME_GLOBAL_RELATIVE_ALT, mission_from_plan,
                                                 MissionSettings, wpl_text)
    scene, result = hills_plan
    terrain = scene.terrain
    mission = mission_from_plan(result, scene.obstacles, scene.config, ORIGIN,
                                MissionSettings(firmware='px4', end='land'))
    # Home is the ground under the start (the start is in the air): its AMSL altitude is the
    # terrain's there.
    start = result.smoothed_path[0]
    ground_z = terrain.height_at(start[None, :2])[0]
    assert mission.home_enu[2] == pytest.approx(ground_z, abs=0.01)
    file = tmp_path / 'hills.waypoints'
    file.write_text(wpl_text(mission))
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(file)) == len(mission.items) + 1
    home_amsl = loader.wp(0).z
    assert home_amsl == pytest.approx(mission.home[2], abs=1e-3)
    waypoints = [loader.wp(n) for n in range(1, loader.count())
                 if loader.wp(n).command == MAV_CMD_NAV_WAYPOINT]
    assert waypoints
    assert all(wp.frame == MAV_FRAME_GLOBAL_RELATIVE_ALT for wp in waypoints)
    # Relative altitudes back to the map frame: every waypoint is inside the band above the
    # terrain under it (rounding of the file: 1 cm).
    enu = geodetic_to_enu([wp.x for wp in waypoints], [wp.y for wp in waypoints],
                          [home_amsl + wp.z for wp in waypoints], ORIGIN)
    agl = height_above_ground(terrain, enu)
    assert agl.min() >= MIN_AGL - 0.01 and agl.max() <= MAX_AGL + 0.01
    # Every straight leg flown, except the landing descent, keeps the band at dense samples.
    flight = mission.flight_path[:-1]
    t = np.linspace(0.0, 1.0, DENSE_SAMPLES // len(flight))[:, None, None]
    legs = (flight[:-1] + t * (flight[1:] - flight[:-1])).reshape(-1, 3)
    agl = height_above_ground(terrain, legs)
    assert agl.min() >= MIN_AGL - 1e-6 and agl.max() <= MAX_AGL + 1e-6
    assert mission.items[-1].command == MAV_CMD_NAV_LAND
    # The landing descent ends on the terrain under the goal.
    assert mission.flight_path[-1][2] == pytest.approx(
        terrain.height_at(mission.flight_path[-1][None, :2])[0], abs=0.01)


def mavsdk_import(path, autopilot):
    """MAVSDK's offline import of a QGroundControl ``.plan`` file, as the autopilot (a
    MAV_AUTOPILOT id) would get it: a raw link given one HEARTBEAT packed by pymavlink."""
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionRaw
    from pymavlink.dialects.v20 import common as mavlink2

    class Sink:
        def write(self, data):
            pass
    beat = mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR, autopilot, 0, 0, mavlink2.MAV_STATE_STANDBY,
        3).pack(mavlink2.MAVLink(Sink(), srcSystem=1, srcComponent=1))
    with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
        sdk.add_any_connection('raw://')
        sdk.subscribe_raw_bytes_to_be_sent(lambda data: None)
        sdk.pass_received_raw_bytes(beat)
        system = sdk.first_autopilot(5.0)
        assert system is not None, 'MAVSDK did not take the heartbeat'
        return MissionRaw(system).import_qgroundcontrol_mission(str(path)).mission_items


@pytest.mark.parametrize('firmware', ['px4', 'ardupilot'])
def test_mission_over_the_hills_opens_in_mavsdk_relative_to_home(hills_plan, tmp_path,
                                                                 firmware):
    pytest.importorskip('mavsdk')
    from uav_global_planner.core.io.geodesy import geodetic_to_enu
    from uav_global_planner.core.map.ground import height_above_ground
    from uav_global_planner.core.mission import (MAV_AUTOPILOT, MAV_CMD_NAV_WAYPOINT,
                                                 MAV_FRAME_GLOBAL_RELATIVE_ALT, mission_from_plan,
                                                 MissionSettings, plan_text)
    scene, result = hills_plan
    mission = mission_from_plan(result, scene.obstacles, scene.config, ORIGIN,
                                MissionSettings(firmware=firmware, end='land'))
    file = tmp_path / 'hills.plan'
    file.write_text(plan_text(mission))
    items = mavsdk_import(file, MAV_AUTOPILOT[firmware])
    home_amsl = mission.home[2]
    if firmware == 'ardupilot':
        # ArduPilot gets the planned home as item 0, in AMSL: the ground under the start.
        home, items = items[0], items[1:]
        assert home.seq == 0 and home.z == pytest.approx(home_amsl, abs=1e-3)
        home_amsl = home.z
    assert len(items) == len(mission.items)
    waypoints = [item for item in items if item.command == MAV_CMD_NAV_WAYPOINT]
    assert waypoints
    # Relative to home: home's AMSL altitude plus each waypoint's brings it back to the map
    # frame, where it lies in the band above the terrain under it (rounding: 1 cm).
    assert all(item.frame == MAV_FRAME_GLOBAL_RELATIVE_ALT for item in waypoints)
    enu = geodetic_to_enu([item.x * 1e-7 for item in waypoints],
                          [item.y * 1e-7 for item in waypoints],
                          [home_amsl + item.z for item in waypoints], ORIGIN)
    agl = height_above_ground(scene.terrain, enu)
    assert agl.min() >= MIN_AGL - 0.01 and agl.max() <= MAX_AGL + 0.01
    # The same altitudes as the mission (float32 in MAVLink).
    expected = [item.params[6] for item in mission.items if item.command == MAV_CMD_NAV_WAYPOINT]
    assert [item.z for item in waypoints] == pytest.approx(expected, abs=1e-3)


# ------------------------------------------------------------------------- the command line

def test_command_line_ground_terrain_and_band(tmp_path, capsys):
    import json
    import yaml
    from uav_global_planner.cli.main import _parser, main
    x = np.arange(41) * 1.0
    heights = 2.0 + 3.0 * np.exp(-((x[None, :] - 20.0) ** 2 + (x[:, None] - 20.0) ** 2) / 50.0)
    (tmp_path / 'hill.asc').write_text(_asc_text(heights, {
        'ncols': 41, 'nrows': 41, 'xllcenter': 0.0, 'yllcenter': 0.0, 'cellsize': 1.0}))
    document = _scene()
    document.update(bounds={'min': [0.0, 0.0, 0.0], 'max': [40.0, 40.0, 20.0]},
                    start=[2.0, 2.0, 6.0], goal=[38.0, 38.0, 6.0])
    scene_file = tmp_path / 'site.yaml'
    scene_file.write_text(yaml.safe_dump(document))
    args = _parser().parse_args(['plan', str(scene_file), '--ground', '2.5', '--min-agl', '3',
                                 '--max-agl', '9'])
    assert (args.ground, args.min_agl, args.max_agl) == (2.5, 3.0, 9.0)
    assert _parser().parse_args(['plan', str(scene_file), '--ground', 'floor']).ground == 'floor'
    code = main(['plan', str(scene_file), '--terrain', str(tmp_path / 'hill.asc'),
                 '--min-agl', '3', '--max-agl', '9', '--algorithm', 'octile', '--json'])
    output = json.loads(capsys.readouterr().out)
    assert code == 0, output['message']
    path = np.array(output['path'])
    from uav_global_planner.core.map.dem import load_dem
    hill = load_dem(tmp_path / 'hill.asc', [0.0, 0.0], [40.0, 40.0])
    agl = path[:, 2] - hill.height_at(path[:, :2])
    assert agl.min() >= 3.0 - 1e-9 and agl.max() <= 9.0 + 1e-9
    assert main(['plan', str(scene_file), '--ground', 'grass']) == 2
    assert '--ground: ground must be none, floor or a number' in capsys.readouterr().err
    assert main(['plan', str(scene_file), '--terrain', str(tmp_path / 'x.npy')]) == 2
    assert 'terrain key' in capsys.readouterr().err
    assert main(['plan', str(scene_file), '--min-agl', '3']) == 2
    assert 'there is none' in capsys.readouterr().err


def test_geotiff_without_rasterio_names_the_extra(tmp_path, monkeypatch):
    import builtins
    from uav_global_planner.core.errors import MissingDependencyError
    path = write_geotiff(tmp_path / 'hills.tif')
    real_import = builtins.__import__

    def no_rasterio(name, *args, **kwargs):
        if name == 'rasterio' or name.startswith('rasterio.'):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, '__import__', no_rasterio)
    monkeypatch.delitem(sys.modules, 'rasterio')
    with pytest.raises(MissingDependencyError, match=r'uav_global_planner\[terrain\]'):
        load_dem(path, [-100.0, -100.0], [100.0, 100.0], ORIGIN)
