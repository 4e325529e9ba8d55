"""Figures of a scene and its paths: a PNG with an oblique 3D view, a top view and a side view
(matplotlib, like the paper's Figs. 3-4), and an interactive 3D page (plotly, optional).

Obstacles are translucent and drawn beneath the paths, so a path through a town stays visible
behind the buildings.
"""

from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

import matplotlib
matplotlib.use('Agg')
from matplotlib.collections import PatchCollection  # noqa: E402 - the backend must be first
from matplotlib.patches import Circle, Rectangle  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
import numpy as np  # noqa: E402

from uav_global_planner.core.errors import MissingDependencyError  # noqa: E402
from uav_global_planner.core.io.scene import Scene  # noqa: E402
from uav_global_planner.core.map.obstacles import ObstacleSet  # noqa: E402

# Oblique viewpoint of the 3D view (elevation, azimuth) [deg].
_OBLIQUE = (28.0, -60.0)
_COLOURS = ('tab:blue', 'tab:red', 'tab:green', 'tab:purple', 'tab:orange', 'tab:brown')
_OBSTACLE_COLOUR = '0.55'
# Translucent enough that a path behind a building still shows through it.
_OBSTACLE_ALPHA = 0.25
# Obstacles first, paths above them, start and goal on top.
_Z_OBSTACLES, _Z_PATHS, _Z_ENDPOINTS = 1, 10, 20
# Faces and outlines of the obstacle patches (2D views) and box faces (3D view).
_OBSTACLE_FACES: Dict[str, Any] = {'facecolor': _OBSTACLE_COLOUR, 'edgecolor': '0.35',
                                   'alpha': _OBSTACLE_ALPHA, 'zorder': _Z_OBSTACLES}
# Point sets are drawn from an evenly spread subset: a million dots only paint the same pixels.
_MAX_DRAWN_POINTS = 60_000
# The ground (terrain, flat ground) and the AGL band's surfaces; the 3D view draws them from at
# most this many lattice nodes per axis.
_GROUND_COLOUR, _BAND_COLOUR = '#8c7a5b', 'tab:cyan'
_MAX_GROUND_NODES = 80
_MAX_HTML_POINTS = 200_000
# Corners of a box as (x, y, z) choices of (min, max), and its six faces.
_BOX_FACES = ((0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5))


def _box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])


def _drawn_points(points: np.ndarray, limit: int) -> np.ndarray:
    """At most ``limit`` of the points, evenly spread over the array."""
    if len(points) <= limit:
        return points
    return points[np.linspace(0, len(points) - 1, limit).astype(np.int64)]


def _draw_point_obstacles(axes, obstacles: ObstacleSet, columns: Tuple[int, ...]) -> None:
    """Scatter an evenly spread subset of the point obstacles on the axes ``columns`` (0 = x,
    1 = y, 2 = z) of a 3D view or a plane."""
    if len(obstacles.points):
        pts = _drawn_points(obstacles.points, _MAX_DRAWN_POINTS)
        axes.scatter(*(pts[:, column] for column in columns), s=1, c='0.35', alpha=0.3,
                     linewidths=0, zorder=_Z_OBSTACLES, rasterized=True)


def _draw_obstacles_3d(axes, obstacles: ObstacleSet) -> None:
    u, v = np.mgrid[0:2 * np.pi:24j, 0:np.pi:12j]
    unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)])
    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        x, y, z = center[:, None, None] + radius * unit
        axes.plot_surface(x, y, z, color=_OBSTACLE_COLOUR, alpha=_OBSTACLE_ALPHA, linewidth=0,
                          shade=True, zorder=_Z_OBSTACLES)
    faces = [corners[list(face)] for corners in
             (_box_corners(lo, hi) for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs))
             for face in _BOX_FACES]
    if faces:
        # One collection for every box: a town of hundreds of buildings stays quick to draw.
        axes.add_collection3d(Poly3DCollection(faces, linewidth=0.3, **_OBSTACLE_FACES))
    _draw_point_obstacles(axes, obstacles, (0, 1, 2))
    for field in obstacles.height_fields:
        x, y, z = _height_field_nodes(field)
        ground = field.label in ('terrain', 'ground')
        axes.plot_surface(x, y, z, color=_GROUND_COLOUR if ground else _BAND_COLOUR,
                          alpha=0.35 if ground else 0.1, linewidth=0, shade=ground,
                          zorder=_Z_OBSTACLES)


def _height_field_nodes(field):
    """x, y, z of an evenly spread subset of a height field's lattice (edges kept)."""
    ny, nx = field.heights.shape
    cols = np.unique(np.linspace(0, nx - 1, min(nx, _MAX_GROUND_NODES)).astype(np.int64))
    rows = np.unique(np.linspace(0, ny - 1, min(ny, _MAX_GROUND_NODES)).astype(np.int64))
    x, y = np.meshgrid(field.origin[0] + cols * field.spacing[0],
                       field.origin[1] + rows * field.spacing[1])
    return x, y, np.asarray(field.heights)[np.ix_(rows, cols)]


def _draw_ground_under(axes, obstacles: ObstacleSet, paths: Mapping[str, np.ndarray],
                       horizontal: int) -> None:
    """Side view: the ground under the first smoothed path (solid) and the AGL band's
    surfaces there (dashed), against the path's ``horizontal`` coordinate."""
    smoothed = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for label, p in paths.items()
                if not label.endswith('raw') and len(p)]
    if not obstacles.height_fields or not smoothed:
        return
    path = smoothed[0]
    for field in obstacles.height_fields:
        lo, hi = field.extent
        inside = np.all((path[:, :2] >= lo) & (path[:, :2] <= hi), axis=1)
        under = np.where(inside, field.height_at(np.clip(path[:, :2], lo, hi)), np.nan)
        ground = field.label in ('terrain', 'ground')
        axes.plot(path[:, horizontal], under, color=_GROUND_COLOUR if ground else _BAND_COLOUR,
                  linestyle='-' if ground else '--', linewidth=1.5 if ground else 0.8,
                  label=f'{field.label} under the path' if ground else None,
                  zorder=_Z_OBSTACLES)


def _draw_obstacles_2d(axes, obstacles: ObstacleSet, horizontal: int, vertical: int) -> None:
    """Obstacles projected onto the plane of two axes (0 = x, 1 = y, 2 = z)."""
    patches: List = [Circle((c[horizontal], c[vertical]), r)
                     for c, r in zip(obstacles.sphere_centers, obstacles.sphere_radii)]
    patches += [Rectangle((lo[horizontal], lo[vertical]), hi[horizontal] - lo[horizontal],
                          hi[vertical] - lo[vertical])
                for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs)]
    if patches:
        axes.add_collection(PatchCollection(patches, linewidth=0.4, **_OBSTACLE_FACES))
    _draw_point_obstacles(axes, obstacles, (horizontal, vertical))


def _draw_paths(axes, scene: Scene, paths: Mapping[str, np.ndarray], axes_index=None) -> None:
    """Paths, start and goal; ``axes_index`` picks two axes for a 2D view, None for 3D."""
    def coordinates(pts: np.ndarray):
        return [pts[:, a] for a in (axes_index or (0, 1, 2))]

    for colour, (label, path) in zip(_COLOURS * 4, paths.items()):
        pts = np.asarray(path, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 0:
            continue
        raw = label.endswith('raw')
        axes.plot(*coordinates(pts), '--' if raw else '-', color=colour,
                  marker='.' if raw else None, markersize=3, linewidth=1.2 if raw else 2.0,
                  label=label, zorder=_Z_PATHS)
    for point, colour, marker, size, label in ((scene.start, 'green', 'o', 50, 'start'),
                                               (scene.goal, 'red', '*', 90, 'goal')):
        axes.scatter(*coordinates(np.asarray(point).reshape(1, 3)), color=colour, s=size,
                     marker=marker, label=label, zorder=_Z_ENDPOINTS, edgecolors='black',
                     linewidths=0.5)


def plot_scene_paths(scene: Scene, paths: Mapping[str, np.ndarray],
                     output_path: Union[str, Path], title: Optional[str] = None) -> Path:
    """Draw the scene's obstacles and the given paths into a PNG: an oblique 3D view, a top
    view (x-y) and a side view (x-z).

    Parameters
    ----------
    scene : Scene
        Bounds, obstacles, start and goal [m].
    paths : mapping of str to numpy.ndarray, shape (N, 3)
        Label to path positions [m]; labels ending in ``raw`` are drawn dashed with markers.
    output_path : str or Path
        PNG file to write.
    title : str, optional

    Returns
    -------
    Path
        The written file.
    """
    lo = np.asarray(scene.config.bounds_min, dtype=np.float64)
    hi = np.asarray(scene.config.bounds_max, dtype=np.float64)
    span = hi - lo
    # The plan views take the shape of the workspace, within limits that keep them readable.
    top_ratio = float(np.clip(span[1] / span[0], 0.3, 3.0))
    side_ratio = float(np.clip(span[2] / span[0], 0.35, 3.0))
    figure = plt.figure(figsize=(19, 6.5))
    grid = figure.add_gridspec(1, 3, width_ratios=(1.15, 1.0, 1.0))

    oblique = figure.add_subplot(grid[0], projection='3d')
    # Draw in the order given (obstacles, then paths) instead of mplot3d's depth sort, which
    # puts a path behind the buildings it passes.
    oblique.computed_zorder = False
    _draw_obstacles_3d(oblique, scene.obstacles)
    _draw_paths(oblique, scene, paths)
    oblique.set_xlim(lo[0], hi[0])
    oblique.set_ylim(lo[1], hi[1])
    oblique.set_zlim(lo[2], hi[2])
    oblique.set_box_aspect(np.maximum(span, 1e-3 * span.max()))
    oblique.set_xlabel('x [m]')
    oblique.set_ylabel('y [m]')
    oblique.set_zlabel('z [m]')
    oblique.view_init(elev=_OBLIQUE[0], azim=_OBLIQUE[1])
    oblique.set_title('3D view')
    oblique.legend(loc='upper left', fontsize=8)

    for number, (index, name, ratio) in enumerate((((0, 1), 'top view (x-y)', top_ratio),
                                                   ((0, 2), 'side view (x-z)', side_ratio))):
        axes = figure.add_subplot(grid[number + 1])
        _draw_obstacles_2d(axes, scene.obstacles, *index)
        if index[1] == 2:
            _draw_ground_under(axes, scene.obstacles, paths, index[0])
        _draw_paths(axes, scene, paths, index)
        axes.set_xlim(lo[index[0]], hi[index[0]])
        axes.set_ylim(lo[index[1]], hi[index[1]])
        # Equal scales unless the workspace is very flat or narrow, then stretched (and said).
        axes.set_aspect(ratio * span[index[0]] / span[index[1]], adjustable='box')
        axes.set_xlabel('x [m]')
        axes.set_ylabel('y [m]' if index[1] == 1 else 'z [m]')
        stretch = ratio * span[index[0]] / span[index[1]]
        axes.set_title(name if abs(stretch - 1.0) < 0.01 else
                       f'{name}, {name[-2]} stretched {stretch:.2g}x')
        axes.grid(True, linewidth=0.3, alpha=0.5)
    figure.suptitle(title or scene.name)
    figure.tight_layout()
    output = Path(output_path)
    output.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(output, dpi=110)
    plt.close(figure)
    return output


def _sphere_mesh(center: np.ndarray, radius: float, rings: int = 12, segments: int = 24):
    """Vertices and triangles of a UV sphere."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing='ij')
    vertices = center + radius * np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p),
                                           np.cos(t)], axis=-1).reshape(-1, 3)
    triangles = []
    for ring in range(rings):
        for seg in range(segments):
            a = ring * segments + seg
            b = ring * segments + (seg + 1) % segments
            c, d = a + segments, b + segments
            triangles += [(a, b, d), (a, d, c)]
    return vertices, np.array(triangles)


def _obstacle_mesh(obstacles: ObstacleSet):
    """One triangle mesh of every sphere and box: (vertices, triangles), or None."""
    vertices, triangles, offset = [], [], 0
    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        v, t = _sphere_mesh(center, float(radius))
        vertices.append(v)
        triangles.append(t + offset)
        offset += len(v)
    quads = np.array(_BOX_FACES)
    box_triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        vertices.append(_box_corners(lo, hi))
        triangles.append(box_triangles + offset)
        offset += 8
    if not vertices:
        return None
    return np.concatenate(vertices), np.concatenate(triangles)


def plotly_objects(view: str):
    """The module ``plotly.graph_objects``, imported when a page is drawn.

    Parameters
    ----------
    view : str
        What the page is, for the message (``'interactive view'``, ``'fleet view'``).

    Raises
    ------
    MissingDependencyError
        When plotly is not installed; the message names the pip package.
    """
    try:
        import plotly.graph_objects as go
    except ImportError:
        raise MissingDependencyError(
            f"the {view} needs the Python package 'plotly', which is not installed: "
            'pip install plotly (or pip install uav_global_planner[plot])') from None
    return go


def obstacle_mesh_traces(go, obstacles: ObstacleSet, **style) -> list:
    """One grey ``Mesh3d`` trace of every sphere and box in a list, empty when there are none.

    Parameters
    ----------
    go : module
        ``plotly.graph_objects`` (:func:`plotly_objects`).
    obstacles : ObstacleSet
        Spheres and boxes in the map frame (ENU) [m].
    **style
        Further ``Mesh3d`` arguments (``opacity``, ``name``, ``showlegend``).
    """
    mesh = _obstacle_mesh(obstacles)
    if mesh is None:
        return []
    (x, y, z), (i, j, k) = mesh[0].T, mesh[1].T
    return [go.Mesh3d(x=x, y=y, z=z, i=i, j=j, k=k, color='gray', flatshading=True,
                      hoverinfo='skip', **style)]


def scene_figure(scene: Scene, paths: Mapping[str, np.ndarray], title: Optional[str] = None):
    """The interactive 3D view of the scene and paths as a plotly figure.

    Obstacles are translucent; point sets are drawn from an evenly spread subset of at most
    200 000 points.

    Parameters
    ----------
    scene : Scene
    paths : mapping of str to numpy.ndarray, shape (N, 3)
        Label to path positions [m]; labels ending in ``raw`` are drawn dashed.
    title : str, optional

    Returns
    -------
    plotly.graph_objects.Figure

    Raises
    ------
    MissingDependencyError
        When plotly is not installed; the message names the pip package.
    """
    go = plotly_objects('interactive view')
    traces = obstacle_mesh_traces(go, scene.obstacles, opacity=0.3, name='obstacles',
                                  showlegend=True)
    if len(scene.obstacles.points):
        pts = _drawn_points(scene.obstacles.points, _MAX_HTML_POINTS)
        traces.append(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode='markers',
                                   marker={'size': 1.5, 'color': 'dimgray', 'opacity': 0.35},
                                   name='occupied points', hoverinfo='skip'))
    for colour, (label, path) in zip(_COLOURS * 4, paths.items()):
        pts = np.asarray(path, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 0:
            continue
        raw = label.endswith('raw')
        line = {'color': colour.replace('tab:', ''), 'width': 3 if raw else 6}
        if raw:
            line['dash'] = 'dash'
        traces.append(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2],
                                   mode='lines+markers' if raw else 'lines', line=line,
                                   marker={'size': 2}, name=label))
    for point, colour, symbol, label in ((scene.start, 'green', 'circle', 'start'),
                                         (scene.goal, 'red', 'diamond', 'goal')):
        traces.append(go.Scatter3d(x=[point[0]], y=[point[1]], z=[point[2]], mode='markers',
                                   marker={'size': 7, 'color': colour, 'symbol': symbol},
                                   name=label))
    lo = np.asarray(scene.config.bounds_min, dtype=np.float64)
    hi = np.asarray(scene.config.bounds_max, dtype=np.float64)
    figure = go.Figure(data=traces)
    figure.update_layout(
        title=title or scene.name, margin={'l': 0, 'r': 0, 't': 40, 'b': 0},
        scene={'xaxis': {'title': {'text': 'x [m]'}, 'range': [lo[0], hi[0]]},
               'yaxis': {'title': {'text': 'y [m]'}, 'range': [lo[1], hi[1]]},
               'zaxis': {'title': {'text': 'z [m]'}, 'range': [lo[2], hi[2]]},
               # True proportions: a 1 km town 100 m high looks like one.
               'aspectmode': 'manual',
               'aspectratio': dict(zip('xyz', (hi - lo) / np.max(hi - lo))),
               # From the (+x, -y) side, across the usual corner-to-corner crossing.
               'camera': {'eye': {'x': 1.3, 'y': -1.5, 'z': 0.9}}})
    return figure


def plot_scene_html(scene: Scene, paths: Mapping[str, np.ndarray],
                    output_path: Union[str, Path], title: Optional[str] = None) -> Path:
    """Write the interactive 3D view (:func:`scene_figure`) into one HTML file.

    The page carries plotly's JavaScript itself (about 5 MB), so it opens without a network.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    MissingDependencyError
        When plotly is not installed; the message names the pip package.
    """
    figure = scene_figure(scene, paths, title)
    output = Path(output_path)
    output.parent.mkdir(parents=True, exist_ok=True)
    figure.write_html(str(output), include_plotlyjs=True, full_html=True)
    return output
