"""Sphinx configuration: ``sphinx-build -W -b html docs docs/_build/html``.

The pages are the markdown files of this folder (MyST, through MyST-NB); the tutorials are
Jupyter notebooks in MyST-NB's text form, executed at every build in a temporary folder (an
error in a cell fails the build); the API reference is autodoc over the installed ``ucontrol``
package with Google docstrings (napoleon); maths is MathJax.
"""

from __future__ import annotations

import ucontrol

project = "ucontrol"
author = "ucontrol developers"
copyright = "ucontrol developers"
version = release = ucontrol.__version__

extensions = [
    "myst_nb",  # MyST markdown (myst-parser) and executed notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax served from _static: formulas render offline
    "sphinx.ext.viewcode",
]
# .rst first: autosummary writes its generated pages with the first suffix that reads rst.
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
# The tables beside the figures are data written by experiments/, shown by the pages.
exclude_patterns = ["_build", "figures/*.md", "figures/**/*.md"]
autosummary_generate = True  # docs/_autosummary/: one page per module, written at build time

myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

# Notebooks (the pages with a kernelspec, docs/tutorials): run at every build, each in an empty
# temporary folder, as tests/test_tutorials.py runs them; a cell that raises fails the build.
nb_execution_mode = "force"
nb_execution_in_temp = True
nb_execution_raise_on_error = True
nb_execution_timeout = 300  # [s] per cell
nb_execution_show_tb = True

napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # "Attributes:" as fields: dataclass fields are documented once
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# Each object is documented in the module that defines it, not again where it is re-exported.
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}

html_theme = "alabaster"
# A wider column: the long formulas and tables of the pages fit at 1200 px.
html_theme_options = {"page_width": "1160px"}
html_static_path = ["_static"]
html_css_files = ["wrap.css"]  # code wraps in the column: no horizontal scroll bars
html_title = f"ucontrol {release}"
