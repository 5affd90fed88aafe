"""
Sphinx configuration of the mmg_tuner documentation (Sphinx + MyST Markdown, the rosdoc2 layout).

Build: ``sphinx-build -W -b html doc build/doc`` from the repository root
(test/lint/test_docs.py does it, warnings as errors). The package is imported from the
checkout, as the tests do.
"""
from pathlib import Path
import re
import sys

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))            # mmg_tuner from this checkout (autodoc, the directives)
sys.path.insert(0, str(HERE / '_ext'))

project = 'mmg_tuner'
author = 'mmg_tuner developers'
copyright = 'mmg_tuner developers, Apache-2.0'  # noqa: A001 (Sphinx's name)
release = re.search(r'<version>([^<]+)</version>', (ROOT / 'package.xml').read_text()).group(1)
version = release

extensions = ['myst_parser', 'sphinx.ext.autodoc', 'mmg_docs']
source_suffix = {'.md': 'markdown'}
root_doc = 'index'
exclude_patterns = ['_build', 'Thumbs.db', '.DS_Store']

# anchors for [text](page.md#a-heading) links, checked by the -W build
myst_heading_anchors = 3
myst_enable_extensions = ['colon_fence']

autodoc_default_options = {'members': True, 'undoc-members': False}
autodoc_typehints = 'description'
autodoc_member_order = 'bysource'

html_theme = 'alabaster'
html_static_path = ['_static']
html_title = 'mmg_tuner'
