"""Sphinx configuration of the ldaspark manual: numpydoc API pages, the topic notes and tutorials.

Built offline (no intersphinx) with warnings as errors:
``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
"""
import os
import sys

sys.path.insert(0, os.path.abspath(".."))

import ldaspark  # noqa: E402

project = "ldaspark"
author = "the ldaspark developers"
copyright = "2026, the ldaspark developers"
release = version = ldaspark.__version__

extensions = [
    "sphinx.ext.autodoc",
    "numpydoc",
    "myst_parser",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]
# the topic notes link to source files of the repository (outside docs/): they stay plain links
myst_heading_anchors = 3
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
# every public docstring is checked for the sections a numpydoc reader expects
numpydoc_validation_checks = {"PR01", "PR02", "RT01", "SS01", "GL08", "EX01"}
autodoc_typehints = "none"
autodoc_default_options = {"members": False}
html_theme = "pydata_sphinx_theme"
html_theme_options = {"navigation_with_keys": False}
html_static_path = []
