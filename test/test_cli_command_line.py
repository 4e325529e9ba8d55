"""The ``uav-plan`` command line without traps: scene paths, negative values, help, memory.

Each test runs the real command line: the console script as a process, or its ``main()`` in
this process where a process limit or many cases make that the clearer test.
"""

import functools
import json
from pathlib import Path
import re
import resource
import shutil
import subprocess
from typing import Dict, List

import pytest
import yaml

from uav_global_planner.cli.main import main as uav_plan_main
from uav_global_planner.cli.memory import data_bytes, estimate, grid_nodes
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import shipped_scenes
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.settings import planner_settings

COMMANDS = ('plan', 'compare', 'plot', 'export')
# A small scene whose bounds reach negative coordinates (as test_scene.VALID).
SCENE = {
    'bounds': {'min': [-2.0, -2.0, 0.0], 'max': [2.0, 2.0, 3.0]}, 'resolution': 0.25,
    'safety_margin': 0.2, 'adaptive_threshold': 1.5, 'start': [-1.5, -1.5, 0.5],
    'goal': [1.5, 1.5, 2.5],
    'obstacles': [{'type': 'sphere', 'center': [0.0, 0.0, 1.5], 'radius': 0.5}],
}


def uav_plan(*args: str, cwd=None, limit_data: int = 0) -> subprocess.CompletedProcess:
    """``uav-plan ARGS`` as a process; ``limit_data`` [bytes] sets its ``ulimit -d``."""
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'

    def limit() -> None:
        if limit_data:
            hard = resource.getrlimit(resource.RLIMIT_DATA)[1]
            resource.setrlimit(resource.RLIMIT_DATA, (limit_data, hard))

    return subprocess.run([executable, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600, preexec_fn=limit)


def _scene_file(folder: Path, name: str = 'scene.yaml', **changes) -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({**SCENE, **changes}))
    return path


def _plan_json(capsys, *args: str) -> tuple:
    code = uav_plan_main(['plan', *args, '--json'])
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert len(lines) == 1, out + err
    return code, json.loads(lines[0]), err


# ------------------------------------------------------------------------------ scene paths

def test_a_missing_scene_path_is_refused_not_replaced_by_a_shipped_scene(tmp_path):
    # A shipped scene of that name exists: the path must still not fall back to it.
    missing = tmp_path / 'nowhere' / 'paper_medium.yaml'
    run = uav_plan('plan', str(missing), '--json')
    assert run.returncode == 2, run.stdout + run.stderr
    result = json.loads(run.stdout)
    assert result['status'] == 'invalid_input' and result['path'] == []
    assert result['message'] == (f'{missing}: no such scene file; the shipped scene of that '
                                 'name is given by its name alone: paper_medium')


@pytest.mark.parametrize('text', ['paper_medium.yaml', './paper_medium', 'scenes/town400.yml'])
def test_text_that_names_a_path_must_be_a_file(text, tmp_path, capsys):
    code, result, _ = _plan_json(capsys, text)
    assert code == 2 and result['status'] == 'invalid_input'
    assert f'{text}: no such scene file' in result['message']


def test_an_unknown_name_lists_every_shipped_scene(capsys):
    code, result, _ = _plan_json(capsys, 'paper_mediun')
    assert code == 2
    names = ', '.join(path.stem for path in shipped_scenes())
    assert result['message'] == ('paper_mediun: no such scene file or shipped scene (shipped '
                                 f'scenes: {names})')


def test_a_folder_is_not_a_scene_file(tmp_path, capsys):
    code, result, _ = _plan_json(capsys, f'{tmp_path}/')
    assert code == 2 and 'is a folder, not a scene file' in result['message']


def test_an_existing_file_and_a_shipped_name_both_plan(tmp_path, capsys):
    code, result, _ = _plan_json(capsys, str(_scene_file(tmp_path)))
    assert code == 0 and result['status'] == 'ok'
    assert result['start'] == SCENE['start']
    code, result, _ = _plan_json(capsys, 'paper_medium')
    assert code == 0 and result['start'] == [0.0, -5.0, 0.0]


# ------------------------------------------------------------------------------ negative values

def test_negative_via_point_is_read_and_flown_through(tmp_path, capsys):
    code, result, _ = _plan_json(capsys, str(_scene_file(tmp_path)), '--via', '-1.5,1.5,1')
    assert code == 0, result['message']
    assert [-1.5, 1.5, 1.0] in result['path']


def test_a_negative_via_outside_the_bounds_is_a_plan_failure(tmp_path, capsys):
    code, result, err = _plan_json(capsys, str(_scene_file(tmp_path)), '--via', '-50,100,40')
    assert code == 1 and 'outside the bounds' in result['message']
    assert 'expected one argument' not in result['message'] + err


def _value_options(command: str) -> Dict[str, int]:
    """Every option of ``uav-plan COMMAND --help`` that takes a value, with its nargs."""
    from uav_global_planner.cli.main import _parser
    commands = next(action for action in _parser()._actions
                    if isinstance(action.choices, dict))
    return {action.option_strings[-1]: action.nargs
            for action in commands.choices[command]._actions
            if action.option_strings and action.nargs != 0}


@pytest.mark.parametrize('command', COMMANDS)
def test_every_option_reads_a_value_that_starts_with_a_minus_sign(command, tmp_path, capsys,
                                                                  monkeypatch):
    # Each value is refused or used by the option itself; none is taken for an option, and
    # none ends in a traceback (an image file name such as -1.5e0 names no format).
    monkeypatch.chdir(tmp_path)
    scene = str(_scene_file(tmp_path))
    extra = ['-o', 'out.plan', '--origin', '47.0,8.0,400'] if command == 'export' else []
    for option in _value_options(command):
        # --max-planning-time keeps the accepted ones short; -o out.plan is the required one.
        args = [command, scene, *extra, '--max-planning-time', '5', option, '-1.5e0']
        if option in ('-o', '--output') and command == 'export':
            args = [command, scene, '--origin', '47.0,8.0,400', option, '-1.plan']
        uav_plan_main(args)
        out, err = capsys.readouterr()
        assert 'expected one argument' not in err + out, (option, err)
        assert 'unrecognized arguments' not in err + out, (option, err)


def test_origin_with_a_negative_latitude_exports(tmp_path, capsys):
    pytest.importorskip('pymap3d')
    mission = tmp_path / 'south.plan'
    code = uav_plan_main(['export', str(_scene_file(tmp_path)), '-o', str(mission),
                          '--origin', '-33.86,151.2,10', '--json'])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    plan = json.loads(mission.read_text())
    assert plan['mission']['plannedHomePosition'][0] == pytest.approx(-33.86, abs=1e-4)


def test_an_image_file_without_a_format_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scene = str(_scene_file(tmp_path))
    for args, reason in ((['plot', scene, '-o', 'out'], '-o: out: the extension names no image '
                          'format; use one of .avif, .eps'),
                         (['plot', scene, '--profile', 'missing/p.png'],
                          '--profile: missing/p.png: no such folder missing'),
                         (['compare', scene, '--plot', '-1.5e0'],
                          '--plot: -1.5e0: the extension names no image format')):
        assert uav_plan_main(args) == 2
        out, err = capsys.readouterr()
        assert err.startswith(f'uav-plan: error: {reason}'), err
        assert out == ''          # refused before anything was planned
    assert sorted(path.name for path in tmp_path.iterdir()) == ['scene.yaml']


def test_bench_refuses_an_unknown_scene_and_a_goal_count_below_one_before_measuring():
    run = uav_plan('bench', 'paper_mediun')
    assert run.returncode == 2 and 'Traceback' not in run.stderr
    assert 'paper_mediun: no such scene file or shipped scene (shipped scenes:' in run.stderr
    run = uav_plan('bench', '--ros-goals', '-5')
    assert run.returncode == 2
    assert 'argument --ros-goals: must be >= 1, got -5' in run.stderr


def test_a_negative_setting_out_of_range_names_the_setting(tmp_path, capsys):
    code, result, _ = _plan_json(capsys, str(_scene_file(tmp_path)), '--max-jerk', '-1e3')
    assert code == 2
    assert result['message'].endswith('max_jerk must be in (0.0, 10000.0], got -1000.0')


# ------------------------------------------------------------------------------ help

@functools.lru_cache(maxsize=None)
def _help(*command: str) -> str:
    """``uav-plan COMMAND --help`` of the console script (once per command)."""
    run = uav_plan(*command, '--help')
    assert run.returncode == 0, run.stderr
    return run.stdout


def _option_entries(text: str) -> Dict[str, str]:
    """Help text by option, from the ``options:`` section of a help page."""
    section = text.split('\noptions:\n', 1)[1].split('\n\n', 1)[0]
    entries: Dict[str, List[str]] = {}
    current = ''
    for line in section.splitlines():
        found = re.match(r'^  (-\S+)', line)
        if found:
            current = found.group(1).rstrip(',')
            entries[current] = [line]
        else:
            entries[current].append(line)
    return {name: ' '.join(' '.join(lines).split()) for name, lines in entries.items()}


@pytest.mark.parametrize('command', [*COMMANDS, 'bench'])
def test_every_option_has_help_and_shows_its_default(command):
    text = _help(command)
    entries = _option_entries(text)
    assert len(entries) > 2
    for name, entry in entries.items():
        if name == '-h' or (command == 'export' and name == '-o'):
            continue  # help itself; the one required option
        words = entry.split(None, 1)
        assert len(words) == 2 and len(entry) > len(name) + 20, (name, entry)
        assert 'default' in entry.lower(), (name, entry)


def test_algorithm_shows_its_choices_explained_and_its_default():
    entry = _option_entries(_help('plan'))['--algorithm']
    assert 'default adaptive' in entry
    for name in ('dijkstra', 'astar', 'adaptive', 'octile', 'weighted', 'bounded'):
        assert f'{name} (' in entry, (name, entry)


@pytest.mark.parametrize('command', [(), ('plan',), ('export',), ('bench',)])
def test_help_lists_the_exit_codes(command):
    text = _help(*command)
    epilog = text.split('\nexit codes:\n', 1)[1]
    codes = [line.split()[0] for line in epilog.splitlines() if re.match(r'^  \d', line)]
    assert codes == ['0', '1', '2'], epilog


def test_scene_help_names_every_shipped_scene():
    text = ' '.join(_help('plan').split())
    for path in shipped_scenes():
        assert path.stem in text, path.stem


def test_every_settings_flag_is_in_the_help():
    entries = _option_entries(_help('plan'))
    flags = [entry.flag for entry in planner_settings() if entry.flag]
    assert flags and all(flag in entries for flag in flags)


# ------------------------------------------------------------------------------ memory

def test_memory_estimate_follows_the_layouts():
    empty = ObstacleSet()
    small = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(10.0, 10.0, 10.0),
                          resolution=0.1)
    figures = estimate(small, empty)
    assert figures.layout == 'dense' and figures.nodes == grid_nodes(small) == 101 ** 3
    assert figures.grid_bytes == 18 * 101 ** 3        # mask and search records
    large = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(100.0, 100.0, 10.0),
                          resolution=0.05, max_voxels=2 ** 31)
    figures = estimate(large, empty)
    assert figures.layout == 'sparse'
    bricks = -(-figures.nodes // 512)
    assert figures.grid_bytes == 8 * bricks           # the two brick tables, no surface
    assert figures.search_bytes == 41 * figures.nodes


@pytest.fixture
def data_limit():
    """Sets this process's soft RLIMIT_DATA to its data segment plus n bytes; restored after."""
    previous = resource.getrlimit(resource.RLIMIT_DATA)

    def set_headroom(headroom: int) -> None:
        resource.setrlimit(resource.RLIMIT_DATA, (data_bytes() + headroom, previous[1]))

    yield set_headroom
    resource.setrlimit(resource.RLIMIT_DATA, previous)


def test_a_grid_larger_than_the_memory_available_is_refused_before_it_is_built(
        tmp_path, capsys, data_limit):
    # 15.6 M nodes, dense: about 0.28 GB of mask and search records; 0.1 GB available.
    scene = _scene_file(tmp_path, bounds={'min': [0.0, 0.0, 0.0], 'max': [24.9, 24.9, 24.9]},
                        resolution=0.1, start=[1.0, 1.0, 1.0], goal=[20.0, 20.0, 20.0],
                        obstacles=[])
    data_limit(100_000_000)
    code = uav_plan_main(['plan', str(scene), '--json'])
    out, err = capsys.readouterr()
    assert code == 2
    result = json.loads(out)
    assert result['status'] == 'invalid_input' and result['expanded_nodes'] == 0
    message = result['message']
    assert message.startswith('grid of 15.6 M nodes (dense): about 0.28 GB before the search')
    assert re.search(r'this machine has 0\.\d\d GB available: raise --resolution', message)


def test_a_grid_beyond_the_search_is_refused_before_it_is_built(capsys):
    code, result, _ = _plan_json(capsys, 'paper_medium', '--resolution', '0.005',
                                 '--max-voxels', '100000000000')
    assert code == 2
    assert 'nodes: the search supports at most 2147483647' in result['message']


def test_a_search_that_runs_out_of_memory_is_an_error_not_a_killed_process():
    # A block-sparse grid of 223 M nodes that Dijkstra would search entirely (9 GB) under a
    # data limit: the search stops with MemoryError, reported with the figures.
    options = ('plan', 'paper_medium', '--resolution', '0.03', '--max-voxels', '300000000',
               '--algorithm', 'dijkstra', '--json')
    # The same plan for a second without the limit first: the kernels it runs are compiled
    # into the cache, so that compiling them does not count against the limit below.
    assert uav_plan(*options, '--max-planning-time', '1').returncode == 1
    run = uav_plan(*options, '--max-planning-time', '0', limit_data=350_000_000)
    assert run.returncode == 2, run.stdout + run.stderr
    assert 'Traceback' not in run.stderr
    result = json.loads(run.stdout)
    assert result['status'] == 'invalid_input'
    assert result['message'].startswith('out of memory: grid of 222.9 M nodes (block-sparse)')
    assert re.search(r'the plan needed more than the 0\.\d\d GB available', result['message'])
    # Announced on stderr before the grid was built.
    assert 'planning: grid of 222.9 M nodes (block-sparse)' in run.stderr
