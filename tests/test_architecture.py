"""The package's shape, checked from the source (issue 15): imports go one way, no module reaches into another's
private names, functions stay small, and the public API is what ``pyroute_rel.__all__`` says.

The import graph is read with :mod:`ast`, so imports inside functions count as much as those at the top; imports
under ``if TYPE_CHECKING:`` are for annotations only (never executed) and are left out.
"""

from __future__ import annotations

import ast
import importlib
import io
import tokenize
from pathlib import Path

import networkx as nx
import pytest

import pyroute_rel

PACKAGE = Path(pyroute_rel.__file__).parent


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(name: str) -> list[tuple[str, list[str], int]]:
    """(target module, imported names, line) of every runtime import of module ``name``."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: list[tuple[str, list[str], int]] = []

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for sub in child.orelse:
                    visit(sub)
                continue
            if isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")
                    base = base[: len(base) - (child.level - 1)]
                    target = ".".join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ""
                if target == "pyroute_rel" or target.startswith("pyroute_rel."):
                    names = [a.name for a in child.names]
                    sub = [f"{target}.{n}" for n in names if f"{target}.{n}" in MODULES]
                    if sub:  # from . import geodesy: an import of the module itself
                        found.extend((s, [], child.lineno) for s in sub)
                        names = [n for n in names if f"{target}.{n}" not in MODULES]
                    if names:
                        found.append((target, names, child.lineno))
            elif isinstance(child, ast.Import):
                for a in child.names:
                    if a.name.startswith("pyroute_rel"):
                        found.append((a.name, [], child.lineno))
            visit(child)

    visit(tree)
    return found


def _graph() -> nx.DiGraph:
    g = nx.DiGraph()
    g.add_nodes_from(MODULES)
    for name in MODULES:
        for target, _, _ in _imports(name):
            if target != name:
                g.add_edge(name, target)
    return g


@pytest.mark.slow
def test_import_graph_has_no_cycle():
    """No two modules import each other, directly or round a loop, even inside functions.

    A package's ``__init__`` re-exports its modules, so the edges from a module to its own package's ``__init__``
    (and from a package to its modules) are not dependencies of the design; they are left out.
    """
    g = _graph()
    for a, b in list(g.edges):
        if b == a.rpartition(".")[0] or a == b.rpartition(".")[0]:
            g.remove_edge(a, b)
        elif b == "pyroute_rel":  # the top-level package only re-exports, lazily
            g.remove_edge(a, b)
    cycles = list(nx.simple_cycles(g))
    assert not cycles, f"import cycles: {cycles[:5]}"


@pytest.mark.slow
def test_no_private_names_imported_across_modules():
    offences = []
    for name in MODULES:
        for target, names, line in _imports(name):
            if target == name:
                continue
            offences += [
                f"{name}:{line} imports {target}.{n}" for n in names if n.startswith("_") and not n.startswith("__")
            ]
    assert not offences, "\n".join(offences)


#: The package's layers, lowest first: a module imports only from its own layer and those below (imports under
#: ``if TYPE_CHECKING:`` are annotations, not dependencies). A module belongs to the entry naming the longest prefix of
#: its name; the top-level package is a foundation too (it imports nothing until a name is asked for).
LAYERS: list[tuple[str, ...]] = [
    ("", "errors", "units", "times", "settings", "store", "files", "progress", "resources", "diskcache", "geodesy"),
    ("weather", "_kernels.sampling"),  # the compiled sampling imports nothing of the package
    ("boat",),
    ("reliability", "obstacles"),
    ("_kernels",),
    ("routing",),
    ("scenario", "config", "planners.settings"),  # a scenario file holds the planners' settings
    ("batch",),
    ("analysis",),
    ("gci",),
    ("planners",),
    ("viz",),
    ("outputs",),
    ("cli", "__main__"),
]


def _layer(module: str) -> int:
    name = module.removeprefix("pyroute_rel").removeprefix(".")
    best, found = -1, -1
    for level, entries in enumerate(LAYERS):
        for entry in entries:
            if (name == entry or name.startswith(entry + ".") or entry == "") and len(entry) > best:
                best, found = len(entry), level
    return found


def test_every_module_has_a_layer():
    assert all(_layer(name) >= 0 for name in MODULES)
    assert _layer("pyroute_rel.planners.settings") < _layer("pyroute_rel.planners.plan")


@pytest.mark.slow
def test_lower_layers_never_import_higher_ones():
    """Folders are layers (``LAYERS``): weather knows nothing of boats, reliability nothing of routing, routing never
    draws or writes files, and the figures, outputs and command line sit on top."""
    offences = []
    for name in MODULES:
        for target, _, line in _imports(name):
            if _layer(target) > _layer(name):
                offences.append(f"{name}:{line} imports {target}")
    assert not offences, "\n".join(offences)


def test_few_modules_at_the_top():
    """The package's top holds the entry points and the foundation; everything else lives in a layer's folder."""
    top = sorted(path.name for path in PACKAGE.glob("*.py"))
    assert len(top) <= 15, top


def test_public_api_resolves_and_is_documented():
    for name in pyroute_rel.__all__:
        obj = getattr(pyroute_rel, name)
        if callable(obj):
            assert obj.__doc__, f"pyroute_rel.{name} has no docstring"
    assert sorted(set(pyroute_rel.__all__)) == sorted(pyroute_rel.__all__), "duplicates in __all__"
    assert set(pyroute_rel.__all__) <= set(dir(pyroute_rel))


@pytest.mark.parametrize("name", sorted(m for m in MODULES if not m.endswith("__main__")))
def test_every_module_imports_alone(name):
    importlib.import_module(name)


MAX_FUNCTION_LINES = 80  # lines of code, docstrings, comments and blank lines excluded (ruff checks complexity <= 20)


def _code_lines(path: Path) -> dict[str, int]:
    """Lines of code of every function and method of a module, by qualified name."""
    source = path.read_text()
    tree = ast.parse(source)
    code_lines = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in (
            tokenize.COMMENT,
            tokenize.NL,
            tokenize.NEWLINE,
            tokenize.INDENT,
            tokenize.DEDENT,
            tokenize.ENDMARKER,
        ):
            code_lines.update(range(tok.start[0], tok.end[0] + 1))
    out: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = set(range(child.lineno, (child.end_lineno or child.lineno) + 1)) & code_lines
                body = child.body
                if (
                    body
                    and isinstance(body[0], ast.Expr)
                    and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)
                ):
                    lines -= set(range(body[0].lineno, (body[0].end_lineno or body[0].lineno) + 1))
                # decorators and the signature count as one line
                lines -= set(range(child.lineno, body[0].lineno))
                out[prefix + child.name] = len(lines) + 1
                visit(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")

    visit(tree, "")
    return out


#: Functions allowed to stay longer, each with the reason.
LONG_FUNCTIONS: dict[str, str] = {
    "pyroute_rel._kernels.march._march_kernel": "one compiled loop: split into helpers over tuples, numba compiled it "
    "4x slower and ran it 2x slower (measured, session 14)",
}


def test_functions_are_short():
    long = []
    for name, path in MODULES.items():
        for func, n in _code_lines(path).items():
            key = f"{name}.{func}"
            if n > MAX_FUNCTION_LINES and key not in LONG_FUNCTIONS:
                long.append(f"{key}: {n} lines")
    assert not long, "\n".join(long)


@pytest.mark.slow
def test_weather_capabilities_are_declared_not_probed():
    """The weather protocol's members (:data:`~pyroute_rel.weather.base.WEATHER_MEMBERS`: the capabilities too, with
    their defaults in :class:`~pyroute_rel.weather.WeatherBase`) are used as declared: no ``getattr``/``hasattr`` of
    one of them anywhere in the package (issue 33)."""
    from pyroute_rel.weather.base import WEATHER_MEMBERS

    names = set(WEATHER_MEMBERS) | {"patches", "field_info"}
    found = []
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
                continue
            if node.func.id in {"getattr", "hasattr"} and len(node.args) >= 2:
                key = node.args[1]
                if isinstance(key, ast.Constant) and key.value in names:
                    found.append(f"{name}:{node.lineno} {node.func.id}(..., {key.value!r})")
    assert not found, found


@pytest.mark.slow
def test_compiled_code_lives_in_the_kernels():
    """Every numba-compiled function is in ``pyroute_rel._kernels`` (each kernel module names its numpy twin)."""
    outside = []
    for name, path in MODULES.items():
        if name.startswith("pyroute_rel._kernels"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                for dec in node.decorator_list:
                    if "numba" in ast.unparse(dec) or "njit" in ast.unparse(dec):
                        outside.append(f"{name}.{node.name}")
    assert not outside, outside
    for name, path in MODULES.items():
        if name.startswith("pyroute_rel._kernels.") and "njit" in path.read_text():
            assert "tests/test_" in (ast.get_docstring(ast.parse(path.read_text())) or ""), f"{name} names no test"
