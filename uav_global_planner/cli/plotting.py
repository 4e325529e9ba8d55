"""3D figures of a scene and its paths (matplotlib, written to PNG), like the paper's Figs. 3-4."""

from pathlib import Path
from typing import Mapping, Optional, Union

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402 - the backend must be chosen first
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
import numpy as np  # noqa: E402

from uav_global_planner.core.obstacles import ObstacleSet  # noqa: E402
from uav_global_planner.core.scene import Scene  # noqa: E402

# Two viewpoints (elevation, azimuth) [deg]: an oblique view and one from the side.
_VIEWS = ((28.0, -60.0), (12.0, 20.0))
_COLOURS = ('tab:blue', 'tab:red', 'tab:green', 'tab:purple', 'tab:orange', 'tab:brown')


def _draw_obstacles(axes, obstacles: ObstacleSet) -> None:
    u, v = np.mgrid[0:2 * np.pi:24j, 0:np.pi:12j]
    unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)])
    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        x, y, z = center[:, None, None] + radius * unit
        axes.plot_surface(x, y, z, color='0.55', alpha=0.35, linewidth=0, shade=True)
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])
        faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4],
                 [1, 3, 7, 5]]
        axes.add_collection3d(Poly3DCollection([corners[f] for f in faces], facecolor='0.55',
                                               edgecolor='0.3', alpha=0.35))
    if len(obstacles.points):
        pts = obstacles.points
        axes.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=2, c='0.35', alpha=0.5)


def plot_scene_paths(scene: Scene, paths: Mapping[str, np.ndarray],
                     output_path: Union[str, Path], title: Optional[str] = None) -> Path:
    """Draw the scene's obstacles and the given paths from two viewpoints into a PNG.

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
    figure = plt.figure(figsize=(14, 6.5))
    lo = np.asarray(scene.config.bounds_min)
    hi = np.asarray(scene.config.bounds_max)
    for number, (elevation, azimuth) in enumerate(_VIEWS):
        axes = figure.add_subplot(1, 2, number + 1, projection='3d')
        _draw_obstacles(axes, scene.obstacles)
        for colour, (label, path) in zip(_COLOURS * 4, paths.items()):
            pts = np.asarray(path).reshape(-1, 3)
            if len(pts) == 0:
                continue
            raw = label.endswith('raw')
            axes.plot(pts[:, 0], pts[:, 1], pts[:, 2], '--' if raw else '-', color=colour,
                      marker='.' if raw else None, markersize=3, linewidth=1.2 if raw else 2.0,
                      label=label)
        axes.scatter(*scene.start, color='green', s=50, marker='o', label='start')
        axes.scatter(*scene.goal, color='red', s=70, marker='*', label='goal')
        axes.set_xlim(lo[0], hi[0])
        axes.set_ylim(lo[1], hi[1])
        axes.set_zlim(lo[2], hi[2])
        axes.set_box_aspect(hi - lo)
        axes.set_xlabel('x [m]')
        axes.set_ylabel('y [m]')
        axes.set_zlabel('z [m]')
        axes.view_init(elev=elevation, azim=azimuth)
        if number == 0:
            axes.legend(loc='upper left', fontsize=8)
    figure.suptitle(title or scene.name)
    figure.tight_layout()
    output = Path(output_path)
    output.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(output, dpi=110)
    plt.close(figure)
    return output
