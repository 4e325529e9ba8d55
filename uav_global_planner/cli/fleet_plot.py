"""The fleet over time: a plotly page with a time slider (``uav-plan fleet``'s ``fleet.html``).

The buildings and every accepted flight's path are drawn once; each frame of the slider shows
the vehicles airborne at that time [s, batch clock] and their separation envelopes, cylinders
of radius ``horizontal_separation / 2`` and height ``vertical_separation`` around each vehicle
(ENU map frame, [m]): two flights keep their separation exactly when their cylinders never
overlap.
"""

from pathlib import Path
from typing import Any, List, Optional, Tuple, Union

import numpy as np

from uav_global_planner.cli.plotting import obstacle_mesh_traces, plotly_objects
from uav_global_planner.core.fleet import FleetResult, Flight
from uav_global_planner.core.io.scene import Scene

# Sides of the polygon drawn for an envelope's top and bottom circle.
_SIDES = 16
# Most frames a page gets; a longer batch gets a coarser step.
_MAX_FRAMES = 400


def _envelope_lines(centres: np.ndarray, radius: float, height: float) -> np.ndarray:
    """Line vertices of cylinders around ``centres`` (N, 3) [m], separated by NaN rows."""
    angle = np.linspace(0.0, 2.0 * np.pi, _SIDES + 1)
    ring = np.stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros_like(angle)],
                    axis=1)
    half = np.array([0.0, 0.0, 0.5 * height])
    gap = np.full((1, 3), np.nan)
    parts: List[np.ndarray] = []
    for centre in centres:
        parts += [centre + ring - half, gap, centre + ring + half, gap]
        for k in range(0, _SIDES, _SIDES // 4):
            parts += [np.stack([centre + ring[k] - half, centre + ring[k] + half]), gap]
    return np.vstack(parts) if parts else np.empty((0, 3))


def _airborne(flights: List[Flight], time_s: float) -> Tuple[List[str], np.ndarray]:
    names = [f.mission for f in flights if f.start_s <= time_s <= f.end_s]
    points = [f.positions(time_s)[0] for f in flights if f.start_s <= time_s <= f.end_s]
    return names, np.asarray(points, dtype=np.float64).reshape(-1, 3)


def _xyz(points: np.ndarray) -> dict:
    """plotly coordinates; NaN becomes None (a gap in a line)."""
    return {axis: [None if not np.isfinite(v) else float(v) for v in points[:, k]]
            for k, axis in enumerate('xyz')}


def fleet_figure(scene: Scene, result: FleetResult, frame_step_s: float = 10.0,
                 title: Optional[str] = None) -> Any:
    """The figure: buildings, paths, and per frame the vehicles and their envelopes.

    Parameters
    ----------
    scene : Scene
    result : FleetResult
    frame_step_s : float
        Time between frames [s] (made coarser when the batch would need more than 400).
    title : str, optional
        Above the plot; default: the scene name.

    Returns
    -------
    plotly.graph_objects.Figure

    Raises
    ------
    MissingDependencyError
        From :func:`~uav_global_planner.cli.plotting.plotly_objects`: plotly is not installed.
    """
    go = plotly_objects('fleet view')
    flights = [o.flight for o in result.accepted if o.flight is not None]
    settings = result.settings
    radius = 0.5 * settings.horizontal_separation
    height = settings.vertical_separation
    traces = obstacle_mesh_traces(go, scene.obstacles, opacity=0.25, name='buildings')
    paths = []
    for flight in flights:
        _, points = flight.sample(max(1.0, flight.duration_s / 200.0))
        paths += [points, np.full((1, 3), np.nan)]
    path_points = np.vstack(paths) if paths else np.empty((0, 3))
    traces.append(go.Scatter3d(**_xyz(path_points), mode='lines', name='paths',
                               line={'color': 'steelblue', 'width': 2}, opacity=0.5,
                               hoverinfo='skip'))
    start = min((f.start_s for f in flights), default=0.0)
    end = max((f.end_s for f in flights), default=0.0)
    step = max(float(frame_step_s), (end - start) / _MAX_FRAMES)
    times = np.arange(start, end + step, step) if flights else np.zeros(1)
    moving = len(traces)

    def frame_data(time_s: float) -> list:
        names, points = _airborne(flights, time_s)
        return [go.Scatter3d(**_xyz(points), mode='markers', text=names, name='vehicles',
                             marker={'size': 4, 'color': 'crimson'},
                             hovertemplate='%{text}<extra></extra>'),
                go.Scatter3d(**_xyz(_envelope_lines(points, radius, height)), mode='lines',
                             name='envelopes', line={'color': 'orange', 'width': 2},
                             hoverinfo='skip')]

    traces += frame_data(float(times[0]))
    frames = [go.Frame(data=frame_data(float(t)), name=f'{t:.0f}',
                       traces=[moving, moving + 1]) for t in times]
    lo = np.asarray(scene.config.bounds_min, dtype=np.float64)
    hi = np.asarray(scene.config.bounds_max, dtype=np.float64)
    slider = {'active': 0, 'currentvalue': {'prefix': 't = ', 'suffix': ' s'},
              'pad': {'t': 30}, 'x': 0.08, 'len': 0.92,
              'steps': [{'label': f'{t:.0f}', 'method': 'animate',
                         'args': [[f'{t:.0f}'], {'mode': 'immediate',
                                                 'frame': {'duration': 0, 'redraw': True},
                                                 'transition': {'duration': 0}}]}
                        for t in times]}
    play = {'type': 'buttons', 'showactive': False, 'x': 0.0, 'y': 0.0,
            'buttons': [{'label': 'play', 'method': 'animate',
                         'args': [None, {'frame': {'duration': 150, 'redraw': True},
                                         'fromcurrent': True}]},
                        {'label': 'pause', 'method': 'animate',
                         'args': [[None], {'mode': 'immediate',
                                           'frame': {'duration': 0, 'redraw': False}}]}]}
    figure = go.Figure(data=traces, frames=frames)
    figure.update_layout(
        title=title or scene.name, margin={'l': 0, 'r': 0, 't': 40, 'b': 0},
        sliders=[slider], updatemenus=[play],
        scene={'xaxis': {'title': {'text': 'x [m]'}, 'range': [lo[0], hi[0]]},
               'yaxis': {'title': {'text': 'y [m]'}, 'range': [lo[1], hi[1]]},
               'zaxis': {'title': {'text': 'z [m]'}, 'range': [lo[2], hi[2]]},
               'aspectmode': 'manual',
               'aspectratio': dict(zip('xyz', (hi - lo) / np.max(hi - lo)))})
    return figure


def plot_fleet_html(scene: Scene, result: FleetResult, output_path: Union[str, Path],
                    frame_step_s: float = 10.0, title: Optional[str] = None) -> Path:
    """Write :func:`fleet_figure` into one HTML file (plotly's JavaScript inside, so it opens
    without a network); returns the file written."""
    figure = fleet_figure(scene, result, frame_step_s, title)
    output = Path(output_path)
    output.parent.mkdir(parents=True, exist_ok=True)
    figure.write_html(str(output), include_plotlyjs=True, full_html=True,
                      auto_play=False)
    return output
