"""Every command and snippet in README.md and docs/ runs, so none can rot.

Fenced blocks are collected from README.md and docs/**/*.md:

- ``sh`` / ``console``: each ``pyroute-rel ...`` command runs (through :func:`pyroute_rel.cli.main`, the function the
  ``pyroute-rel`` script calls, in the test's process, from the repository root, with ``--out`` sent to a temporary
  folder; warnings are errors there, as in every test) and must exit 0, or the code a trailing ``# exits N`` comment
  names. A ``text output`` block after a shell block is an excerpt of what its last command prints: each of its
  lines must be printed (whitespace aside; ``runtime`` lines vary and are skipped). Installing (``pip``,
  ``python -m venv``), building the docs and running the test suite are what CI does around this test; scripts
  (``python examples/...``) are checked to exist and run only where a command needs their output.
- ``toml``: a whole scenario loads with :func:`pyroute_rel.scenario_from_mapping`; a fragment loads merged into the
  control example (its tables replace the example's); a failure model (or a fragment of its criteria) loads with
  :func:`pyroute_rel.load_failure_model`. Every group of commented-out lines (``# key = value``) loads too, once
  uncommented, so the comments are valid TOML.
- ``python``: run, as a doctest when it holds ``>>>`` lines.
- ``json``: parsed; a GeoJSON FeatureCollection loads as exclusion zones.

Other ``text`` fences are synopses and file excerpts, and ``{directive}`` fences are MyST's; no other language
may be used.
"""

from __future__ import annotations

import copy
import doctest
import json
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

import pyroute_rel as pr
from pyroute_rel.cli import main

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
EXAMPLES = ROOT / "examples"
LANGUAGES = {"sh", "console", "toml", "python", "json", "text"}
FENCE = re.compile(
    r"^(?P<indent>[ ]*)```(?P<lang>[^\s`]*)(?P<info>[^\n]*)\n(?P<body>.*?)^(?P=indent)```[ ]*$", re.M | re.S
)
COMMENTED_TOML = re.compile(r"^\s*#\s?(?=\[|[A-Za-z_][\w.-]*\s*=)")
EXIT = re.compile(r"#\s*exits?\s+(\d)\b")
# commands that take more than a few seconds
SLOW = ("microtransat_era5", "era5_synthetic", "gci study", "--refine 5")
# output lines that vary from run to run
VARIABLE_OUTPUT = ("runtime",)
ERA5_DATA = EXAMPLES / "data" / "era5_synthetic.nc"


@dataclass(frozen=True)
class Block:
    path: Path
    line: int
    lang: str
    body: str
    info: str = ""

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def doc_files() -> list[Path]:
    files = [ROOT / "README.md", ROOT / "failure_models" / "README.md"]
    return files + sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)


def blocks() -> list[Block]:
    found = []
    for path in doc_files():
        text = path.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            body = "\n".join(line[len(m["indent"]) :] for line in m["body"].splitlines())
            found.append(Block(path, text.count("\n", 0, m.start()) + 1, m["lang"], body, m["info"].strip()))
    return found


def of(*langs: str) -> list[pytest.param]:
    return [
        pytest.param(b, id=b.where, marks=[pytest.mark.slow] if any(s in b.body for s in SLOW) else [])
        for b in blocks()
        if b.lang in langs
    ]


def test_blocks_are_found_and_languages_known():
    found = blocks()
    assert {b.lang for b in found} >= {"sh", "toml", "python"}
    unknown = [f"{b.where}: ```{b.lang}" for b in found if b.lang not in LANGUAGES and not b.lang.startswith("{")]
    assert not unknown, f"fenced blocks must name one of {sorted(LANGUAGES)}: {unknown}"


# ------------------------------------------------------------------------------------------------- commands


@dataclass(frozen=True)
class Command:
    where: str
    argv: tuple[str, ...]
    exit_code: int
    expected: str = ""  # an output excerpt: lines the command prints (```text output after its block)


def shell_lines(block: Block) -> list[str]:
    """Logical command lines of a block (continuations joined; console output lines dropped)."""
    text = block.body.replace("\\\n", " ")
    lines = []
    for line in text.splitlines():
        if block.lang == "console":
            if not line.startswith("$ "):
                continue
            line = line[2:]
        if line.strip() and not line.lstrip().startswith("#"):
            lines.append(line)
    return lines


def commands(block: Block) -> list[Command | str]:
    """The block's ``pyroute-rel`` commands, and a note for each other command it checks without running."""
    out: list[Command | str] = []
    for line in shell_lines(block):
        m = EXIT.search(line)
        code = int(m[1]) if m else 0
        tokens = shlex.split(line, comments=True)
        parts: list[list[str]] = [[]]
        for tok in tokens:
            if tok == "&&":
                parts.append([])
            else:
                parts[-1].append(tok)
        for argv in parts:
            out.append(classify(block, argv, code))
    return out


def classify(block: Block, argv: list[str], code: int) -> Command | str:
    where = block.where
    if not argv:
        raise AssertionError(f"{where}: empty command")
    head = argv[0]
    if head == "pyroute-rel":
        return Command(where, tuple(argv[1:]), code)
    if head == "pip" or head in (".", "source"):
        return "install"
    if head == "python" and argv[1:3] in (["-m", "venv"], ["-m", "pytest"], ["-m", "sphinx"]):
        return f"python -m {argv[2]}"  # what .ci/run does around this test
    if head == "python" and len(argv) >= 2 and argv[1].endswith(".py"):
        script = ROOT / argv[1]
        assert script.is_file(), f"{where}: {argv[1]} does not exist"
        return f"script {argv[1]}"
    if head == "python" and argv[1:3] == ["-m", "pyroute_rel.cli"]:
        return Command(where, tuple(argv[3:]), code)
    raise AssertionError(f"{where}: no rule for the command {shlex.join(argv)!r}: teach tests/test_docs.py")


def all_commands() -> list[Command | str]:
    """Every command of every page, with the output excerpt (a ```text output block) that follows its block."""
    found: list[Command | str] = []
    last: dict[Path, int] = {}  # per page: index in found of the last command of the last shell block
    for block in blocks():
        if block.lang == "text" and "output" in block.info.split():
            i = last.pop(block.path, None)
            if i is None or not isinstance(found[i], Command):
                found.append(f"{block.where}: an output block must follow a block whose last command prints it")
            else:
                found[i] = replace(found[i], expected=block.body)
        if block.lang not in ("sh", "console"):
            continue
        try:
            cmds = commands(block)
        except (AssertionError, ValueError) as exc:  # reported by the test, not at collection
            found.append(f"{block.where}: {exc}")
            continue
        found += [c for c in cmds if isinstance(c, Command)]
        last[block.path] = len(found) - 1
    return found


def command_params() -> list[pytest.param]:
    params = []
    for cmd in all_commands():
        if isinstance(cmd, str):
            params.append(pytest.param(cmd, id=cmd.split(":")[0]))
        else:
            marks = [pytest.mark.slow] if any(s in " ".join(cmd.argv) for s in SLOW) else []
            params.append(pytest.param(cmd, id=f"{cmd.where} {' '.join(cmd.argv[:2])}", marks=marks))
    return params


def test_commands_are_found_with_their_outputs():
    found = [c for c in all_commands() if isinstance(c, Command)]
    assert len(found) > 10
    assert sum(bool(c.expected) for c in found) >= 5


def redirect_out(argv: tuple[str, ...], tmp: Path) -> list[str]:
    args = list(argv)
    for i, arg in enumerate(args):
        if arg == "--out" and i + 1 < len(args):
            args[i + 1] = str(tmp / args[i + 1].strip("/").replace("/", "_"))
        elif arg.startswith("--out="):
            args[i] = f"--out={tmp / arg[6:].strip('/').replace('/', '_')}"
    return args


def make_era5_data() -> None:
    if not ERA5_DATA.is_file():
        subprocess.run([sys.executable, str(EXAMPLES / "make_era5_example.py")], cwd=ROOT, check=True, timeout=300)


@pytest.mark.parametrize("cmd", command_params())
def test_command(
    cmd: Command | str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
):
    if isinstance(cmd, str):
        pytest.fail(cmd)
    if any("microtransat_era5" in a for a in cmd.argv):
        make_era5_data()
    # in this process, through the entry point the ``pyroute-rel`` script calls (a subprocess per command spent
    # its time importing numpy, numba and xarray again); the output at file-descriptor level, as a terminal sees it
    monkeypatch.chdir(ROOT)
    try:
        code = main(redirect_out(cmd.argv, tmp_path))
    except SystemExit as exc:  # argparse's usage errors, --help and --version
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    stdout, stderr = capfd.readouterr()
    assert code == cmd.exit_code, (
        f"{cmd.where}: `pyroute-rel {shlex.join(cmd.argv)}` exited {code}, the docs say "
        f"{cmd.exit_code}\n{stdout[-2000:]}\n{stderr[-2000:]}"
    )
    assert "Traceback" not in stderr
    if "--json" in cmd.argv and cmd.exit_code == 0:
        json.loads(stdout)
    printed = (stdout + stderr).replace(str(tmp_path / "out_"), "out/")
    printed_lines = {" ".join(line.split()) for line in printed.splitlines()}
    for line in cmd.expected.splitlines():
        if line.strip() and not line.startswith(VARIABLE_OUTPUT):
            assert " ".join(line.split()) in printed_lines, (
                f"{cmd.where}: the docs show a line it does not print:\n{line}\n\nit printed:\n{printed}"
            )


# ----------------------------------------------------------------------------------------------------- TOML


def base_scenario() -> dict:
    with open(EXAMPLES / "microtransat_control.toml", "rb") as fh:
        return tomllib.load(fh)


def load_toml_snippet(text: str, where: str, tmp: Path) -> None:
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise AssertionError(f"{where}: not valid TOML ({exc}):\n{text}") from None
    if "criteria" in table or "target" in table or "network" in table:
        load_model_snippet(table, tmp)
    elif "sweep" in table:
        from pyroute_rel.batch.sweep import sweep_from_mapping

        sweep_from_mapping(table, base_dir=EXAMPLES, source=where)
    elif "route" in table and "weather" in table:
        pr.scenario_from_mapping(table, base_dir=EXAMPLES, source=where)
    else:
        merged = {**base_scenario(), **copy.deepcopy(table)}  # a fragment's tables replace the example's
        pr.scenario_from_mapping(merged, base_dir=EXAMPLES, source=where)


def load_model_snippet(table: dict, tmp: Path) -> None:
    """A failure model, or a fragment of one's criteria, merged into the shipped model whose nodes it uses."""
    shipped = ROOT / "failure_models"
    if "target" in table:
        model = table
        network = shipped / Path(table["network"]).name
    else:
        nodes = {c["node"] for c in table["criteria"]}
        name = "dickson2018" if nodes <= {"WH", "WD"} else "wind_wave_multistate"
        with open(shipped / f"{name}.toml", "rb") as fh:
            model = tomllib.load(fh)
        model["criteria"] = [c for c in model["criteria"] if c["node"] not in nodes] + table["criteria"]
        network = shipped / model["network"]
    folder = tmp / f"model{len(list(tmp.iterdir()))}"
    folder.mkdir()
    shutil.copy(network, folder / Path(model["network"]).name)
    (folder / "model.toml").write_text(dump_toml(model), encoding="utf-8")
    pr.load_failure_model(folder / "model.toml")


def dump_toml(table: dict) -> str:
    """Enough of a TOML writer for failure models: scalars and lists at the top, tables, arrays of tables."""
    lines = [f"{k} = {json.dumps(v)}" for k, v in table.items() if not isinstance(v, dict | list) or not _tables(v)]
    for k, v in table.items():
        if isinstance(v, dict):
            lines += [f"[{k}]", *(f"{kk} = {json.dumps(vv)}" for kk, vv in v.items())]
        elif isinstance(v, list) and _tables(v):
            for item in v:
                lines += [f"[[{k}]]", *(f"{kk} = {json.dumps(vv)}" for kk, vv in item.items())]
    return "\n".join(lines) + "\n"


def _tables(v: object) -> bool:
    return isinstance(v, dict) or (isinstance(v, list) and bool(v) and all(isinstance(i, dict) for i in v))


def commented_groups(text: str) -> list[tuple[int, list[int]]]:
    """Runs of consecutive commented-out TOML lines: (first line number, line indices)."""
    groups: list[list[int]] = []
    previous = -2
    for i, line in enumerate(text.splitlines()):
        if COMMENTED_TOML.match(line):
            if i == previous + 1:
                groups[-1].append(i)
            else:
                groups.append([i])
            previous = i
    return [(g[0] + 1, g) for g in groups]


def uncomment(text: str, indices: list[int]) -> str:
    lines = text.splitlines()
    for i in indices:
        lines[i] = COMMENTED_TOML.sub("", lines[i], count=1)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("block", of("toml"))
def test_toml_snippet(block: Block, tmp_path: Path):
    if "era5_synthetic" in block.body:
        make_era5_data()
    load_toml_snippet(block.body, block.where, tmp_path)
    for first, group in commented_groups(block.body):
        text = uncomment(block.body, group)
        load_toml_snippet(
            text, f"{block.where} (commented lines from line {first} of the block, uncommented)", tmp_path
        )


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.name)
def test_example_comments_are_valid_toml(path: Path):
    """The examples' commented-out settings parse once uncommented (what they mean is the example's to say:
    ``member = 0`` needs an ensemble file)."""
    text = path.read_text(encoding="utf-8")
    tomllib.loads(text)
    for first, group in commented_groups(text):
        try:
            tomllib.loads(uncomment(text, group))
        except tomllib.TOMLDecodeError as exc:
            raise AssertionError(f"{path.name}:{first}: not valid TOML once uncommented ({exc})") from None


def test_commented_lines_are_found():
    text = "[grid]\n# aspect = 6.0\n# refine = 5\n\n# a comment\n# [[weather.patch]]\n"
    assert commented_groups(text) == [(2, [1, 2]), (6, [5])]
    assert uncomment(text, [1, 2]).splitlines()[1:3] == ["aspect = 6.0", "refine = 5"]


# ------------------------------------------------------------------------------------------- Python and JSON


def python_files() -> list[pytest.param]:
    files = sorted({b.path for b in blocks() if b.lang == "python"})
    return [pytest.param(p, id=str(p.relative_to(ROOT))) for p in files]


@pytest.mark.parametrize("path", python_files())
def test_python_snippets(path: Path, monkeypatch: pytest.MonkeyPatch):
    """A page's Python blocks, in order, in one namespace (as a reader runs them); ``>>>`` blocks as doctests."""
    monkeypatch.chdir(ROOT)  # the examples' relative paths are from the repository root
    namespace: dict = {"__name__": "__docs__"}
    for block in (b for b in blocks() if b.path == path and b.lang == "python"):
        if ">>>" in block.body:
            test = doctest.DocTestParser().get_doctest(block.body, namespace, block.where, str(path), block.line)
            runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
            runner.run(test, clear_globs=False)
            namespace.update(test.globs)  # a DocTest works on a copy
            assert runner.failures == 0, f"{block.where}: {runner.failures} doctest example(s) failed (output above)"
        else:
            exec(compile(block.body, block.where, "exec"), namespace)


@pytest.mark.parametrize("block", of("json"))
def test_json_snippet(block: Block, tmp_path: Path):
    data = json.loads(block.body)
    if isinstance(data, dict) and data.get("type") == "FeatureCollection":
        path = tmp_path / "zones.geojson"
        path.write_text(block.body, encoding="utf-8")
        assert pr.load_zones([path])


# --------------------------------------------------------------------------------------------- the site itself


def test_every_module_has_an_api_page():
    """Each public module of the package is documented by an ``automodule`` directive under docs/api; private ones
    (``_kernels``: compiled twins of documented numpy code) have no page."""
    documented = set()
    for page in (DOCS / "api").glob("*.rst"):
        documented |= set(re.findall(r"^\.\. automodule:: (\S+)", page.read_text(encoding="utf-8"), re.M))
    modules = set()
    for path in (ROOT / "pyroute_rel").rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__main__":
            continue
        modules.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    private = {m for m in modules if any(part.startswith("_") for part in m.split("."))}
    assert private, "the compiled kernels are private modules"
    assert not documented & private, f"private modules with an API page: {sorted(documented & private)}"
    missing = sorted(modules - private - documented)
    assert not missing, f"modules without an API page (add an automodule to docs/api): {missing}"


def test_public_api_resolves():
    """Every name of ``pyroute_rel.__all__`` loads (the API page lists them through the lazy loader)."""
    for name in pr.__all__:
        assert getattr(pr, name) is not None


def test_readme_links_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    assert local
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, f"README links to missing files: {missing}"
