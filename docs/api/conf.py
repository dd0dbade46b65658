"""Sphinx configuration of the efam_mujoco API reference (built from the docstrings).

Build: ``python -m sphinx -W --keep-going -b html docs/api build/api`` (CI does, warnings are
errors). ``pip install -e ".[docs]"`` installs Sphinx.
"""

project = "efam_mujoco"
author = "the efam_mujoco developers"
copyright = "the efam_mujoco developers, Apache-2.0"  # noqa: A001 (Sphinx's name)

extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
autodoc_default_options = {"members": True, "undoc-members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_google_docstring = True
napoleon_numpy_docstring = True
default_role = "code"  # `x` in a docstring is code, as in the Markdown docs
nitpicky = False
# ref.python: short names (name, sections, effects) exist in several modules; the ambiguity is harmless
suppress_warnings = ["autodoc.import_object", "ref.python"]
html_theme = "alabaster"
html_static_path = []
exclude_patterns = ["_build"]


def _plain_bars(app, what, name, obj, options, lines):
    """Docstrings here are plain text: ``|x|`` means an absolute value, not an RST substitution."""
    for i, line in enumerate(lines):
        if "|" in line and not line.lstrip().startswith(("|", "+")):
            lines[i] = line.replace("\\|", "|").replace("|", "\\|")


def setup(app):
    """Register the docstring filter."""
    app.connect("autodoc-process-docstring", _plain_bars)
