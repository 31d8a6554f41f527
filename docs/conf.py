"""Sphinx configuration of the pyroute_rel documentation.

Build: ``python -m sphinx -W --keep-going -b html docs docs/_build/html -q`` (what ``.ci/run`` runs).
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # document this tree, installed or not

import pyroute_rel  # noqa: E402

project = "pyroute_rel"
author = "pyroute_rel developers"
copyright = "pyroute_rel developers"  # noqa: A001 - Sphinx's name
release = version = pyroute_rel.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3

# numpydoc docstrings, read leniently (napoleon): the docstrings stay the modules' business
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# members defined in each module (names a module re-exports in __all__ are documented where they are defined)
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
# names of array aliases shown as they are written (numpy.str_ would read as a reST link target)
autodoc_type_aliases = {"StrArray": "pyroute_rel.routing.route.StrArray"}
autosummary_generate = False
# Leniency for docstrings written for the terminal: |x| is an absolute value there, not a reST substitution.
# PYROUTE_REL_DOCS_STRICT=1 turns it off, to list the docstrings that need it.
STRICT = os.environ.get("PYROUTE_REL_DOCS_STRICT") == "1"

try:  # a maintained theme when installed (the docs extra installs it), else Sphinx's own
    import furo  # noqa: F401

    html_theme = "furo"
except ImportError:
    html_theme = "alabaster"
html_title = f"pyroute_rel {release}"
html_static_path: list[str] = []

PUBLIC_API_MARK = ".. public-api-table::"


SECTIONS = ("Parameters", "Other Parameters", "Attributes", "Returns", "Yields", "Receives")
_ENTRY = re.compile(
    r"^(?P<indent>\s*)(?P<names>\*{0,2}[A-Za-z_][\w]*(?:\s*,\s*\*{0,2}[A-Za-z_][\w]*)*)\s+:\s+(?P<rest>.+)$"
)


def _looks_like_type(text: str) -> bool:
    """``float``, ``dict[str, float]``, ``int or None``: a short phrase without sentence punctuation."""
    return not text.endswith(".") and len(text.split()) <= 3 and text[0].islower() and "[" not in text.split()[-1][:1]


def _descriptions_not_types(app, what, name, obj, options, lines):  # noqa: ANN001 - Sphinx's event signature
    """Read ``name : Description [unit].`` entries (this project's habit: types live in the signature) as a name
    and its description, not as a name and a type, so the description is not rendered as a type."""
    section_indent = None
    i = 0
    while i < len(lines):
        line = lines[i]
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if line.strip() in SECTIONS and nxt.strip() and set(nxt.strip()) == {"-"}:
            section_indent = len(line) - len(line.lstrip())
            i += 2
            continue
        if section_indent is not None and line.strip() and len(line) - len(line.lstrip()) < section_indent:
            section_indent = None
        m = _ENTRY.match(line) if section_indent is not None else None
        if m and len(m["indent"]) == section_indent and not _looks_like_type(m["rest"]):
            lines[i] = m["indent"] + m["names"]
            lines.insert(i + 1, m["indent"] + "    " + m["rest"])
            i += 1
        i += 1


def _escape_bars(app, what, name, obj, options, lines):  # noqa: ANN001 - Sphinx's event signature
    """Read ``|x|`` in docstrings as text (absolute values), not as an undefined reST substitution.

    Lines of tables, line blocks and doctests, and inline literals, are left as they are.
    """
    for i, line in enumerate(lines):
        head = line.lstrip()
        if "|" not in line or head.startswith(("|", "+", ">>>", "...")):
            continue
        parts = line.split("``")
        lines[i] = "``".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def public_api_table() -> str:
    """An autosummary of ``pyroute_rel.__all__``, each name resolved through the package's lazy loader."""
    rows = []
    for name in pyroute_rel.__all__:
        if name.startswith("__"):
            continue
        obj = getattr(pyroute_rel, name)  # the lazy loader imports the defining module
        module = obj.__module__.removeprefix("pyroute_rel.")  # relative to the page's module, pyroute_rel
        rows.append(f"   ~{module}.{obj.__qualname__}")
    return ".. autosummary::\n   :nosignatures:\n\n" + "\n".join(rows) + "\n"


def _fill_public_api(app, docname, source):  # noqa: ANN001 - Sphinx's event signature
    if PUBLIC_API_MARK in source[0]:
        source[0] = source[0].replace(PUBLIC_API_MARK, public_api_table())


def setup(app):  # noqa: ANN001, ANN201 - Sphinx's hook
    app.connect("source-read", _fill_public_api)
    if not STRICT:
        app.connect("autodoc-process-docstring", _escape_bars)
    app.connect("autodoc-process-docstring", _descriptions_not_types, priority=100)  # before napoleon
