"""docs/refused_inputs.md is generated from the test catalogues, so it cannot drift from them.

Regenerate it with ``python test/test_docs.py``.
"""

from pathlib import Path

import test_refused_inputs_core
import test_refused_inputs_ros

DOC = Path(__file__).resolve().parents[1] / 'docs' / 'refused_inputs.md'


def refused_inputs_markdown() -> str:
    """The whole document: both catalogues with an introduction."""
    return '\n'.join([
        '# Refused inputs',
        '',
        'Every row is a test (`test/test_refused_inputs_core.py`, '
        '`test/test_refused_inputs_ros.py` and the tests they name). In every case nothing '
        'crashes, the previous good state is kept and the next valid request succeeds. This '
        'file is generated: `python test/test_docs.py` (run inside the project environment).',
        '',
        '## Planning core, scene files and `uav-plan`',
        '',
        test_refused_inputs_core.catalogue_markdown(),
        '',
        '## planner_node (topics, parameter services and map_file)',
        '',
        'WARN `input_rejected` and ERROR plan entries are published on `/diagnostics` with the '
        'Nav2 code shown, next to a log line; refused parameters come back in the '
        '`SetParametersResult`; a refused `map_file` is an ERROR map status, and goals are '
        'refused with its reason.',
        '',
        test_refused_inputs_ros.catalogue_markdown(),
        '',
    ])


def test_refused_inputs_doc_is_up_to_date():
    assert DOC.read_text(encoding='utf-8') == refused_inputs_markdown(), (
        'docs/refused_inputs.md is stale: run python test/test_docs.py')


if __name__ == '__main__':
    DOC.write_text(refused_inputs_markdown(), encoding='utf-8')
    print(f'wrote {DOC}')
