"""Pictures of a scene: the PNG's three views show the path, and the interactive HTML view
renders in a real browser (headless Chromium) without a network.
"""

from pathlib import Path
import shutil
import subprocess

import matplotlib.pyplot as plt
import numpy as np
import pytest
import yaml

from uav_global_planner.cli.plotting import plot_scene_html, scene_figure
from uav_global_planner.core.io.scene import load_scene
from uav_global_planner.core.planner import Planner

# The flags that keep a headless Chromium off the network and out of the user's profile.
CHROMIUM_FLAGS = ('--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking',
                  '--disable-component-update', '--disable-sync', '--no-first-run',
                  '--hide-scrollbars', '--window-size=1200,900',
                  # Virtual time runs the page's scripts to the end before the screenshot.
                  '--virtual-time-budget=15000')


def town_scene(folder: Path) -> Path:
    """Twelve buildings on a 200 m x 200 m site, 60 m of air space."""
    rng = np.random.default_rng(5)
    boxes = []
    for _ in range(12):
        corner = rng.uniform(20.0, 160.0, size=2)
        size = rng.uniform(10.0, 25.0, size=2)
        boxes.append({'type': 'box', 'min': [*map(float, corner), 0.0],
                      'max': [*map(float, corner + size), float(rng.uniform(15.0, 45.0))]})
    file = folder / 'town.yaml'
    file.write_text(yaml.safe_dump({
        'bounds': {'min': [0.0, 0.0, 0.0], 'max': [200.0, 200.0, 60.0]}, 'resolution': 2.0,
        'safety_margin': 1.0, 'adaptive_threshold': 5.0, 'start': [5.0, 5.0, 5.0],
        'goal': [195.0, 195.0, 20.0], 'obstacles': boxes}))
    return file


def planned_paths(scene):
    result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal, 'octile')
    assert result.ok, result.message
    return {'octile raw': result.path, 'octile smoothed': result.smoothed_path}


def red_pixels(image: np.ndarray) -> np.ndarray:
    """Where the pixels are the smoothed path's red (matplotlib tab:red or plotly red)."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (r > 0.75) & (g < 0.3) & (b < 0.3)


def grey_pixels(image: np.ndarray) -> np.ndarray:
    """Where the pixels are the translucent grey of the obstacles."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (np.abs(r - g) < 0.04) & (np.abs(g - b) < 0.04) & (r > 0.25) & (r < 0.85)


def test_png_shows_the_path_in_the_3d_top_and_side_views(tmp_path):
    from uav_global_planner.cli.plotting import plot_scene_paths
    scene = load_scene(town_scene(tmp_path))
    output = plot_scene_paths(scene, planned_paths(scene), tmp_path / 'town.png')
    image = plt.imread(output)[..., :3]
    width = image.shape[1]
    # The views sit side by side: 3D (a little wider), top, side.
    panels = {'3d': image[:, :int(width * 0.36)],
              'top': image[:, int(width * 0.38):int(width * 0.66)],
              'side': image[:, int(width * 0.69):]}
    for name, panel in panels.items():
        assert np.count_nonzero(red_pixels(panel)) > 200, f'no path in the {name} view'
        assert np.count_nonzero(grey_pixels(panel)) > 2000, f'no obstacles in the {name} view'


def chromium_screenshot(page: Path, screenshot: Path, profile: Path) -> np.ndarray:
    """Open ``page`` in headless Chromium and return its screenshot as RGB floats."""
    binary = shutil.which('chromium') or shutil.which('chromium-browser')
    assert binary, ('headless Chromium is needed to check the HTML view: install the Debian '
                    'package chromium (apt-get install -y chromium)')
    run = subprocess.run([binary, *CHROMIUM_FLAGS, f'--user-data-dir={profile}',
                          f'--screenshot={screenshot}', page.resolve().as_uri()],
                         capture_output=True, text=True, timeout=300)
    assert screenshot.is_file(), f'no screenshot (exit {run.returncode}): {run.stderr[-3000:]}'
    return plt.imread(screenshot)[..., :3]


def rendered_scene(image: np.ndarray) -> bool:
    """True when the 3D scene was drawn: the path's red and the buildings' grey in the middle
    of the page (away from the title and the legend, which plotly draws outside WebGL)."""
    height, width = image.shape[:2]
    middle = image[int(height * 0.2):int(height * 0.9), int(width * 0.05):int(width * 0.8)]
    return (np.count_nonzero(red_pixels(middle)) > 100
            and np.count_nonzero(grey_pixels(middle)) > 5000)


def test_html_view_renders_in_headless_chromium(tmp_path):
    scene = load_scene(town_scene(tmp_path))
    paths = planned_paths(scene)
    page = plot_scene_html(scene, paths, tmp_path / 'town.html')
    text = page.read_text(encoding='utf-8')
    # Everything the page needs is inside it: no script from elsewhere.
    assert '<script src="http' not in text and 'plotly.js v' in text
    image = chromium_screenshot(page, tmp_path / 'town.png', tmp_path / 'profile')
    assert image.std() > 0.05, 'the screenshot is blank'
    assert rendered_scene(image), 'the 3D scene did not render'

    # The same figure without its JavaScript renders nothing: the check above can fail.
    bare = tmp_path / 'bare.html'
    scene_figure(scene, paths).write_html(str(bare), include_plotlyjs=False)
    control = chromium_screenshot(bare, tmp_path / 'bare.png', tmp_path / 'profile_bare')
    assert not rendered_scene(control)


@pytest.mark.parametrize('arguments, message', [
    ([], 'plot needs -o PNG, --html FILE, --profile PNG or more'),
])
def test_plot_needs_an_output(arguments, message):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    run = subprocess.run([executable, 'plot', 'paper_medium', *arguments], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 2 and message in run.stderr


def test_plot_writes_png_and_html_from_the_command_line(tmp_path):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    png, html = tmp_path / 'town.png', tmp_path / 'town.html'
    run = subprocess.run([executable, 'plot', str(town_scene(tmp_path)), '-o', str(png),
                          '--html', str(html), '--algorithm', 'octile'], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert html.read_text(encoding='utf-8').count('Plotly.newPlot') == 1
