"""Sphinx configuration: MyST Markdown pages, and the API reference from the docstrings.

Build (as the test command does, with warnings as errors)::

    sphinx-build -W --keep-going -b html docs /tmp/uav_planner_docs

Every build first runs ``docs/gen_tables.py``, which writes the settings tables, the refused-input
catalogue and one API page per module into ``docs/_generated/``.
"""

from pathlib import Path
import sys

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent))  # the checkout's package, as the tests import it
sys.path.insert(0, str(DOCS))

import gen_tables  # noqa: E402, I100 - after the path above

gen_tables.write_all()

project = 'uav_global_planner'
author = 'uav_global_planner maintainers'
copyright = 'uav_global_planner maintainers'  # noqa: A001 - the name Sphinx reads

extensions = ['myst_parser', 'sphinx.ext.autodoc', 'sphinx.ext.napoleon']
# Pages are MyST Markdown; the generated API pages are reStructuredText, as autodoc writes.
source_suffix = {'.md': 'markdown', '.rst': 'restructuredtext'}
root_doc = 'index'
# Settings, messages and values are shown as the program prints them: no curly quotes.
smartquotes = False
exclude_patterns = ['_build', '_generated/*.md', 'README.md']
myst_heading_anchors = 3
myst_enable_extensions = ['colon_fence']

# The docstrings are numpy style.
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# "Attributes" sections become fields of the class, so an attribute that also has a doc
# comment is described once.
napoleon_use_ivar = True
# Type fields such as "ndarray, shape (N, 3)" link each word; a word several classes define as
# an attribute (shape, radius, path) is ambiguous there, and no link is better than a wrong one.
# A shell block with placeholders (<the cluster's token>) that Pygments cannot lex is shown
# unhighlighted; that is not an error of the page.
suppress_warnings = ['ref.python', 'misc.highlighting_failure']
autodoc_member_order = 'bysource'
autodoc_typehints = 'description'

html_theme = 'furo'
html_title = 'uav_global_planner'
