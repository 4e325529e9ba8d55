"""The documentation builds with warnings as errors, and says what the code does.

``sphinx-build -W --keep-going -b html docs <tmp>`` runs once per test session (about 20-40 s on
two cores; most of it autodoc importing the core): a page missing from the toctree, a link to
a page or heading that does not exist, or a docstring Sphinx cannot parse fails it. The checks
after the build read the HTML: the generated tables hold every setting, every refused-input
case and every core module, from the code as it is now. The README's command-line tour and the
API page's example run as written, and the README's links lead to files that exist.
"""

from html.parser import HTMLParser
import importlib
from pathlib import Path
import pkgutil
import re
import subprocess
import sys
from typing import List

import pytest

from uav_global_planner.core.settings import PLANNER_SETTINGS

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / 'docs'
README = REPO / 'README.md'


class _Text(HTMLParser):
    """The text of an HTML page, tags dropped."""

    def __init__(self) -> None:
        super().__init__()
        self.parts: List[str] = []

    def handle_data(self, data: str) -> None:
        self.parts.append(data)


def page_text(html: Path) -> str:
    parser = _Text()
    parser.feed(html.read_text(encoding='utf-8'))
    return ' '.join(parser.parts)


@pytest.fixture(scope='module')
def built(tmp_path_factory) -> Path:
    """The HTML of a fresh build (no cached doctrees), warnings as errors."""
    out = tmp_path_factory.mktemp('docs_html')
    run = subprocess.run([sys.executable, '-m', 'sphinx', '-W', '--keep-going', '-q',
                          '-b', 'html', '-d', str(out / '.doctrees'), str(DOCS), str(out)],
                         cwd=REPO, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f'sphinx-build failed:\n{run.stderr[-6000:]}'
    assert 'WARNING' not in run.stderr, run.stderr[-6000:]
    return out


def test_the_docs_build_without_warnings(built):
    for page in ('index', 'install', 'cli', 'scenes', 'node', 'maps', 'airspace', 'missions',
                 'flight', 'safety', 'refused_inputs', 'performance', 'changelog', 'api'):
        assert (built / f'{page}.html').is_file(), page


def test_the_parameter_tables_hold_every_node_parameter(built):
    parameters = pytest.importorskip('uav_global_planner.ros.parameters')
    text = page_text(built / 'node.html')
    for spec in parameters.parameter_specs():
        assert f'{spec.name} ' in text, spec.name
        assert spec.constraints.split(';')[0] in text, spec.name
    mission_service = pytest.importorskip('uav_global_planner.ros.mission_service')
    missions = page_text(built / 'missions.html')
    for spec in mission_service.MISSION_PARAMETER_SPECS:
        assert f'{spec.name} ' in missions, spec.name


def test_the_scene_key_and_option_tables_follow_the_settings(built):
    scenes = page_text(built / 'scenes.html')
    options = page_text(built / 'cli.html')
    for entry in PLANNER_SETTINGS:
        if entry.scene_key:
            assert entry.scene_key in scenes, entry.name
        if entry.flag:
            assert entry.flag in options, entry.name


def test_the_refused_input_catalogue_lists_every_case(built):
    sys.path.insert(0, str(REPO / 'test'))
    core = importlib.import_module('test_refused_inputs_core')
    ros = importlib.import_module('test_refused_inputs_ros')
    html = (built / 'refused_inputs.html').read_text(encoding='utf-8')
    rows = html.count('<tr')
    # One header row per table.
    assert rows == len(core.CATALOGUE) + len(ros.CATALOGUE) + 2, rows
    text = page_text(built / 'refused_inputs.html')
    for case in ros.CATALOGUE:
        assert case.case_id in text, case.case_id


def test_every_core_and_fleet_module_has_an_api_page(built):
    modules = []
    for root in ('uav_global_planner.core', 'uav_global_planner.fleet_ray'):
        package = importlib.import_module(root)
        modules += [root] + [info.name for info in pkgutil.walk_packages(package.__path__,
                                                                         root + '.')]
    for name in modules:
        page = built / '_generated' / 'api' / f'{name}.html'
        assert page.is_file(), name
    # Members are documented on the page of the module that defines them.
    planner = (built / '_generated' / 'api' / 'uav_global_planner.core.planner.html').read_text(
        encoding='utf-8')
    for anchor in ('uav_global_planner.core.planner.Planner',
                   'uav_global_planner.core.planner.Planner.plan'):
        assert f'id="{anchor}"' in planner, anchor


def test_the_readme_links_into_docs_and_stays_short():
    text = README.read_text(encoding='utf-8')
    assert len(text.splitlines()) <= 250
    targets = re.findall(r'\]\(([^)#\s]+)(?:#[^)]*)?\)', text)
    local = [target for target in targets if '://' not in target]
    assert any(target.startswith('docs/') for target in local)
    for target in local:
        assert (REPO / target).exists(), f'README.md links to {target}, which does not exist'


def test_the_api_example_runs_as_written():
    text = (DOCS / 'api.md').read_text(encoding='utf-8')
    (example,) = re.findall(r'```python\n(.*?)```', text, re.S)
    run = subprocess.run([sys.executable, '-c', example], cwd=REPO, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    status, length, clearance = run.stdout.split()
    assert status == 'PlanStatus.OK'
    assert float(length) > 0.0 and float(clearance) >= 0.2 - 1e-9


def readme_tour_commands() -> List[List[str]]:
    """The ``uav-plan`` lines of the README's command-line tour, as argument lists."""
    text = README.read_text(encoding='utf-8')
    section = text.split('### The command line', 1)[1]
    block = re.search(r'```bash\n(.*?)```', section, re.S)
    assert block, 'no bash block in the README tour'
    commands = [line.split('#', 1)[0].split() for line in block.group(1).splitlines()]
    return [words[1:] for words in commands if words[:1] == ['uav-plan']]


def test_the_readme_tour_runs_as_written(tmp_path, monkeypatch, capsys):
    from uav_global_planner.cli.main import main as uav_plan_main
    monkeypatch.chdir(tmp_path)
    commands = readme_tour_commands()
    assert len(commands) >= 5
    for argv in commands:
        try:
            code = uav_plan_main(argv)
        except SystemExit as stop:  # --help
            code = stop.code
        assert code == 0, f'uav-plan {" ".join(argv)}: {capsys.readouterr().err[-2000:]}'
    assert (tmp_path / 'medium.plan').is_file() and (tmp_path / 'town.html').is_file()
