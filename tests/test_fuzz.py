"""Fuzzing of everything a user hands us by hand (issue 7): scenario tables and files, polar files, the CLI.

The contract under test: bad input is refused with a *domain* error (:class:`~pyroute_rel.errors.PyrouteError`
or, for polar files, :class:`~pyroute_rel.errors.PolarError`) carrying one line that names the file or field,
never with a traceback of some other exception; input that is accepted is really valid (nothing bad slips
through); the CLI exits 0 or 2, never 3, and leaves no partial output.

Examples are bounded and derandomised so that the file runs in a few seconds and CI is deterministic. Set
``PYROUTE_FUZZ_EXAMPLES=2000`` (any number) to fuzz harder with fresh random examples on each run.

Bugs found this way are pinned by regression tests at the end of the file. A bug found later and not yet
fixed goes into :data:`KNOWN_BUGS` (its exact signature) with a strict ``xfail`` test: the fuzzers then note it
and move on, so that they keep hunting for new ones; once it is fixed, drop the entry and the ``xfail`` mark.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import tempfile
import tomllib
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import event as _event
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context

from pyroute_rel.boat.polar import get_polar, read_pol, read_polar_csv
from pyroute_rel.cli import main
from pyroute_rel.config import SCHEMA
from pyroute_rel.errors import PolarError, PolarWarning, PyrouteError, ScenarioError
from pyroute_rel.routing.solve import RoutingProblem
from pyroute_rel.scenario import Scenario, load_scenario, scenario_from_mapping
from pyroute_rel.weather import FIELDS, UniformWeather

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "microtransat_control.toml"
EXAMPLE_TEXT = EXAMPLE.read_text(encoding="utf-8")
BASE = tomllib.loads(EXAMPLE_TEXT)
POL = ROOT / "examples" / "maribot_vane.pol"
POL_TEXT = POL.read_text(encoding="utf-8")
TINY = ["--layout", "square", "--n-nodes", "5", "--n-ranks", "5"]
OUTPUTS = ["forbidden.geojson", "route.csv", "route.geojson", "route.gpx", "route.png", "summary.json"]

_SCALE = int(os.environ.get("PYROUTE_FUZZ_EXAMPLES", "0"))


def event(label: str) -> None:
    """hypothesis.event (outcome statistics with --hypothesis-show-statistics) outside hypothesis tests too."""
    if currently_in_test_context():
        _event(label)


def fuzz_settings(n: int, **kw: Any) -> settings:
    """``n`` derandomised examples (CI), or ``$PYROUTE_FUZZ_EXAMPLES`` random ones when set."""
    return settings(max_examples=_SCALE or n, derandomize=not _SCALE, deadline=None, database=None, **kw)


# ---------------------------------------------------------------------------------------------------------
# Known bugs: exact signatures (exception type name, message pattern). See the module docstring.

KNOWN_BUGS: dict[str, tuple[str, str]] = {}  # none open: every bug this fuzzing found is fixed

#: Domain errors with a known defect in their message (none open: user strings are shown with repr() since
#: 73a9571). Entries: name -> pattern of the message.
KNOWN_MESSAGE_BUGS: dict[str, str] = {}


def known_bug(type_name: str, message: str) -> str | None:
    """The KNOWN_BUGS (or, for a domain error, KNOWN_MESSAGE_BUGS) key whose signature matches, or None."""
    for key, (name, pattern) in KNOWN_BUGS.items():
        if type_name == name and re.search(pattern, message):
            return key
    for key, pattern in KNOWN_MESSAGE_BUGS.items():
        if type_name.endswith("Error") and re.search(pattern, message):
            return key
    return None


# Messages may quote user values (repr); our fuzz strings contain no braces, so "{word}" can only be an
# f-string placeholder that was never filled.
PLACEHOLDER = re.compile(r"\{[A-Za-z_][A-Za-z0-9_.]*\}")


def check_message(msg: str, *, names: str) -> None:
    """A domain error's message: one line, no traceback, no unfilled placeholder, names the file/field."""
    assert msg, "empty error message"
    assert "\n" not in msg and "\r" not in msg, f"multi-line message: {msg!r}"
    assert "Traceback" not in msg, msg
    assert not PLACEHOLDER.search(msg), f"unfilled placeholder in {msg!r}"
    assert names in msg, f"message does not name {names!r}: {msg!r}"


# ---------------------------------------------------------------------------------------------------------
# JSON-like values and scenario mutations

# no braces (see PLACEHOLDER); everything else, control characters and non-ASCII included
_TEXT = st.text(st.characters(blacklist_characters="{}", blacklist_categories=("Cs",)), max_size=12)
_KEYS = st.one_of(
    _TEXT,
    st.sampled_from(
        sorted(
            {k for spec in SCHEMA.values() for k in spec}
            | set(SCHEMA)
            | set(FIELDS)
            | {"kind", "patch", "paths", "lon", "lat"}
        )
    ),
)
_HUGE = st.sampled_from([10**400, -(10**400), 2**63, -(2**63) - 1, 1e308, -1e308, 5e-324, -0.0])
_PLAUSIBLE = st.sampled_from(
    [
        "maribot_vane",
        "maribot_vane.pol",
        "none",
        "dickson2018",
        "square",
        "angular",
        "file",
        "uniform",
        "clamp",
        "forbid",
        "low",
        "2018-06-01T00:00:00Z",
        "9999-12-31T23:59:59-05:00",
        "0001-01-01T00:00:00+05:00",
        [-12.0, 45.0],
        [-60.0, 17.5],
        [[-60.0, 10.0], [-60.0, 25.0]],
        [0, 0],
        [180.0, -90.0],
        0,
        1,
        5,
        0.5,
    ]
)


def json_like(*, null: bool = True) -> st.SearchStrategy[Any]:
    """Random JSON-like values (``null``: with None, which TOML cannot write) of every type and magnitude."""
    scalars = st.one_of(
        st.booleans(),
        st.integers(),
        st.floats(allow_nan=True, allow_infinity=True),
        _HUGE,
        _TEXT,
        _PLAUSIBLE,
        *([st.none()] if null else []),
    )
    return st.recursive(
        scalars, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(_KEYS, inner, max_size=3), max_leaves=6
    )


JSON_LIKE = json_like()


def _paths(obj: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """(path, value) for the root and every value nested in dicts and lists."""
    yield prefix, obj
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*prefix, i))


def _get(obj: Any, path: tuple[Any, ...]) -> Any:
    for p in path:
        obj = obj[p]
    return obj


@st.composite
def mutated_scenarios(
    draw: st.DrawFn, *, min_mutations: int = 1, max_mutations: int = 3, values: st.SearchStrategy[Any] = JSON_LIKE
) -> dict[str, Any]:
    """The example scenario with 1-3 mutations: drop a key, add an unknown key, or replace a value."""
    d = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(min_mutations, max_mutations))):
        paths = [p for p, _ in _paths(d)]
        op = draw(st.sampled_from(["drop", "add", "replace"]))
        if op == "add":
            dicts = [p for p in paths if isinstance(_get(d, p), dict)]
            target = _get(d, draw(st.sampled_from(dicts)))
            target[draw(_KEYS)] = copy.deepcopy(draw(values))  # sampled constants are shared objects
            continue
        inner = [p for p in paths if p]
        if not inner:
            continue
        path = draw(st.sampled_from(inner))
        parent = _get(d, path[:-1])
        if op == "drop":
            del parent[path[-1]]
        else:
            parent[path[-1]] = copy.deepcopy(draw(values))
    return d


def _check_scenario(sc: Scenario) -> None:
    """An accepted scenario holds only valid values."""
    for lon, lat in (sc.start, sc.finish, *sc.waypoints):
        assert math.isfinite(lon) and math.isfinite(lat) and -180 <= lon <= 180 and -90 <= lat <= 90
    assert isinstance(sc.departure, np.datetime64) and not np.isnat(sc.departure)
    assert 0.0 <= sc.apf <= 1.0
    for n in (sc.n_ranks, sc.n_nodes, sc.samples_per_arc):
        assert n is None or (isinstance(n, int) and n >= 1)
    for x in (sc.spacing_km, sc.aspect, sc.time_step_h):
        assert x is None or (math.isfinite(x) and x > 0)
    assert math.isfinite(sc.max_wait_h) and sc.max_wait_h >= 0
    if isinstance(sc.weather, UniformWeather):
        w = sc.weather
        for name, (_, lo, hi) in FIELDS.items():
            v = getattr(w, name)
            assert (name == "wave_period_s" and math.isnan(v)) or lo <= v <= hi, (name, v)
        for p in w.patches:
            assert p.lon[0] < p.lon[1] and p.lat[0] < p.lat[1] and p.values
            assert all(math.isfinite(v) for v in p.values.values())


def _expect_domain_outcome(call: Callable[[], Any], *, names: str, error: type[Exception] = PyrouteError) -> Any:
    """Run ``call``; a domain error must be well-formed; a known bug is noted; anything else fails."""
    try:
        result = call()
    except error as exc:
        bug = known_bug(type(exc).__name__, str(exc))
        if bug is not None:
            event(f"known bug: {bug}")
            return None
        event(f"refused: {type(exc).__name__}")
        check_message(str(exc), names=names)
    except Exception as exc:
        bug = known_bug(type(exc).__name__, str(exc))
        if bug is None:
            raise
        event(f"known bug: {bug}")
    else:
        event("accepted")
        return result
    return None


# ---------------------------------------------------------------------------------------------------------
# Scenario parser


def test_example_scenario_parses() -> None:
    """Premise of the mutation fuzzers: the unmutated example is valid."""
    sc = scenario_from_mapping(BASE, base_dir=EXAMPLE.parent, source="<fuzz>")
    _check_scenario(sc)
    assert sc.start == (-12.0, 45.0) and sc.apf == 1.0 and len(sc.weather.patches) == 2


@pytest.mark.slow
@fuzz_settings(250)
@given(mutated_scenarios())
def test_mutated_mapping_only_domain_errors(table: dict[str, Any]) -> None:
    sc = _expect_domain_outcome(
        lambda: scenario_from_mapping(table, base_dir=EXAMPLE.parent, source="<fuzz>"), names="<fuzz>"
    )
    if sc is not None:
        _check_scenario(sc)


@pytest.mark.slow
@fuzz_settings(60)
@given(
    st.dictionaries(_KEYS, JSON_LIKE, max_size=4)
    | st.dictionaries(st.sampled_from(list(SCHEMA)), st.dictionaries(_KEYS, JSON_LIKE, max_size=4), max_size=6)
)
def test_random_mapping_only_domain_errors(table: dict[str, Any]) -> None:
    sc = _expect_domain_outcome(
        lambda: scenario_from_mapping(table, base_dir=EXAMPLE.parent, source="<fuzz>"), names="<fuzz>"
    )
    if sc is not None:
        _check_scenario(sc)


# Every value of the example (and every optional key) replaced in turn by each of these, and dropped in turn:
# a systematic sweep next to the random mutations above.
ADVERSARIAL: list[Any] = [
    None,
    True,
    False,
    0,
    -1,
    0.5,
    -0.0,
    5e-324,
    1e-300,
    360,
    1e6,
    -1e308,
    1e308,
    10**400,
    -(10**400),
    2**63,
    math.nan,
    math.inf,
    -math.inf,
    "",
    "x",
    "5",
    "-5",
    "nan",
    "a\nb",
    "a\x00b",
    [],
    [1],
    [1, 2],
    [[1, 2], [3, 4]],
    [1, 2, 3],
    {},
    {"x": 1},
    {"lon": [0, 1], "lat": [0, 1]},
]
OPTIONAL_KEYS = (
    [("route", key) for key in SCHEMA["route"] if key not in BASE["route"]]
    + [("grid", key) for key in SCHEMA["grid"] if key not in BASE["grid"]]
    + [
        ("boat", "beyond"),
        ("avoid", "land"),
        ("avoid", "margin_km"),
        ("avoid", "resolution"),
        ("avoid", "zones"),
        ("weather", "wave_period_s"),
        ("weather", "current_u_ms"),
        ("weather", "current_v_ms"),
        ("weather", "kind"),
        ("weather", "patch", 0, "name"),
        ("weather", "patch", 0, "tws_kn"),
    ]
)
LEAVES = [p for p, v in _paths(BASE) if p and not isinstance(v, dict)]
LEAVES += [p for p in OPTIONAL_KEYS if p not in LEAVES]


def _set(d: Any, path: tuple[Any, ...], value: Any) -> None:
    for k in path[:-1]:
        d = d[k] if isinstance(d, list) else d.setdefault(k, {})
    d[path[-1]] = value


@pytest.mark.slow
@pytest.mark.parametrize("path", LEAVES, ids=lambda p: ".".join(map(str, p)))
def test_every_value_replaced_or_dropped(path: tuple[Any, ...]) -> None:
    outcomes = set()
    for value in [*ADVERSARIAL, "drop"]:
        d = copy.deepcopy(BASE)
        _set(d, path, value)
        if value == "drop":
            parent = _get(d, path[:-1])
            del parent[path[-1]]
        sc = _expect_domain_outcome(
            lambda d=d: scenario_from_mapping(d, base_dir=EXAMPLE.parent, source="<fuzz>"), names="<fuzz>"
        )
        if sc is not None:
            _check_scenario(sc)
        outcomes.add(sc is not None)
    if path[-1] != "name":  # a patch's name is free text (any value is shown with str())
        assert False in outcomes  # some of those values were refused: the key is validated at all


@pytest.fixture(scope="module")
def workdir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="pyroute-fuzz-") as d:
        yield Path(d)


def _load_bytes(folder: Path, data: bytes) -> None:
    path = folder / "scenario.toml"
    path.write_bytes(data)
    sc = _expect_domain_outcome(lambda: load_scenario(path), names=str(path))
    if sc is not None:
        _check_scenario(sc)


@fuzz_settings(80)
@given(text=st.text(max_size=300))
def test_random_text_scenario_file(workdir: Path, text: str) -> None:
    _load_bytes(workdir, text.encode("utf-8", "surrogatepass"))


@st.composite
def corrupted_bytes(draw: st.DrawFn, original: bytes) -> bytes:
    """Byte-level corruption: flips, inserts (NUL, invalid UTF-8, BOM, newlines, junk), deletions, truncation."""
    b = bytearray(original)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "insert", "delete", "truncate", "duplicate"]))
        i = draw(st.integers(0, len(b)))
        if op == "flip" and b:
            b[min(i, len(b) - 1)] = draw(st.integers(0, 255))
        elif op == "insert":
            b[i:i] = draw(
                st.sampled_from(
                    [
                        b"\x00",
                        b"\xff\xfe",
                        b"\xef\xbb\xbf",
                        b"\n",
                        b"\r",
                        b"=",
                        b"[",
                        b"]",
                        b'"',
                        b"nan",
                        b"-",
                        b"9" * 40,
                        b"\xc3",
                        b"#",
                    ]
                )
                | st.binary(max_size=4)
            )
        elif op == "delete":
            del b[i : i + draw(st.integers(1, 20))]
        elif op == "truncate":
            del b[i:]
        elif b:
            j = draw(st.integers(0, len(b)))
            b[i:i] = b[min(i, j) : max(i, j)][:200]
    return bytes(b)


@pytest.mark.slow
@fuzz_settings(120)
@given(data=corrupted_bytes(EXAMPLE_TEXT.encode()))
def test_corrupted_scenario_file(workdir: Path, data: bytes) -> None:
    _load_bytes(workdir, data)


# ---------------------------------------------------------------------------------------------------------
# Polar parsers

# the example polar as a matrix of cells, and the same in the CSV form written by hand (independent of write_*)
POL_CELLS = [line.split("\t") for line in POL_TEXT.splitlines()]
CSV_TEXT = (
    "\n".join(",".join(["twa_deg\\tws_kn", *row[1:]] if i == 0 else row) for i, row in enumerate(POL_CELLS)) + "\n"
)


def _check_polar_file(path: Path, reader: Callable[[Path], Any]) -> None:
    def read() -> Any:
        with warnings.catch_warnings():  # empty cells are filled, with a warning: a valid outcome, checked below
            warnings.simplefilter("ignore", PolarWarning)
            return reader(path)

    polar = _expect_domain_outcome(read, names=str(path), error=PolarError)
    if polar is None:
        return
    twa, tws, speed = polar.twa_deg, polar.tws_kn, polar.speed_kn
    assert twa.ndim == tws.ndim == 1 and twa.size >= 2 and tws.size >= 2
    assert np.all(np.diff(twa) > 0) and np.all(np.diff(tws) > 0)
    assert np.all(np.isfinite(twa)) and 0 <= twa[0] and twa[-1] <= 180
    assert np.all(np.isfinite(tws)) and tws[0] >= 0
    assert speed.shape == (twa.size, tws.size)
    assert np.all(np.isfinite(speed)) and np.all(speed >= 0)


_BAD_CELLS = st.sampled_from(
    [
        "x",
        "",
        "nan",
        "NaN",
        "-inf",
        "inf",
        "Infinity",
        "1e999",
        "-1e999",
        "-1",
        "-0.5",
        "1,5",
        "1.2.3",
        "0x10",
        "1_0",
        "--1",
        "+",
        ".",
        "e5",
        "\x00",
        "\u00a0",
        "١٢",
    ]
)


@st.composite
def corrupted_polar(draw: st.DrawFn, sep: str) -> str:
    """Cell-level corruption of the example polar: swap, insert junk, delete, negatives, NaN/inf, long lines."""
    cells = copy.deepcopy(POL_CELLS)
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["swap", "bad", "delete", "negate", "long", "drop_line", "dup_line", "empty"]))
        r = draw(st.integers(0, len(cells) - 1)) if cells else 0
        if not cells or op == "empty":
            cells = []
            break
        row = cells[r]
        c = draw(st.integers(0, max(len(row) - 1, 0)))
        if op == "swap":
            r2 = draw(st.integers(0, len(cells) - 1))
            c2 = draw(st.integers(0, max(len(cells[r2]) - 1, 0)))
            if row and cells[r2]:
                row[c], cells[r2][c2] = cells[r2][c2], row[c]
        elif op == "bad":
            row.insert(c, draw(_BAD_CELLS)) if draw(st.booleans()) else row.__setitem__(c, draw(_BAD_CELLS))
        elif op == "delete" and row:
            del row[c]
        elif op == "negate" and row:
            row[c] = "-" + row[c].lstrip("+-")
        elif op == "long":
            if draw(st.booleans()):
                row.extend([row[-1] if row else "1"] * 20000)
            else:
                row[c] = "1" * 100000
        elif op == "drop_line":
            del cells[r]
        elif op == "dup_line":
            cells.insert(r, list(row))
    return "\n".join(sep.join(row) for row in cells)


def _write(folder: Path, name: str, text: str | bytes) -> Path:
    path = folder / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
    return path


@fuzz_settings(60)
@given(text=st.text(max_size=200))
def test_polar_random_text(workdir: Path, text: str) -> None:
    _check_polar_file(_write(workdir, "random.pol", text), read_pol)
    _check_polar_file(_write(workdir, "random.csv", text), read_polar_csv)


@pytest.mark.slow
@fuzz_settings(150)
@given(text=corrupted_polar("\t"))
def test_polar_pol_cell_corruption(workdir: Path, text: str) -> None:
    _check_polar_file(_write(workdir, "cells.pol", text), read_pol)


@pytest.mark.slow
@fuzz_settings(100)
@given(text=corrupted_polar(","))
def test_polar_csv_cell_corruption(workdir: Path, text: str) -> None:
    path = _write(workdir, "cells.csv", text.replace("TWA\\TWS", "twa_deg\\tws_kn", 1))
    _check_polar_file(path, read_polar_csv)


@pytest.mark.slow
@fuzz_settings(100)
@given(data=corrupted_bytes(POL_TEXT.encode()), csv_data=corrupted_bytes(CSV_TEXT.encode()))
def test_polar_byte_corruption(workdir: Path, data: bytes, csv_data: bytes) -> None:
    _check_polar_file(_write(workdir, "bytes.pol", data), read_pol)
    _check_polar_file(_write(workdir, "bytes.csv", csv_data), read_polar_csv)


def _cell(draw: st.DrawFn, x: float) -> str:
    """A number as users write it, read back exactly: repr, a '+' sign, and integers as '5', '5.' or '05'."""
    x = float(x)
    forms = [repr(x), "+" + repr(x)]
    if x == int(x) and abs(x) < 1e15:
        forms += [str(int(x)), f"{int(x)}.", f"0{int(x)}"]
    return draw(st.sampled_from(forms))


@st.composite
def formatted_polars(draw: st.DrawFn, *, csv: bool) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """A valid polar matrix written in one of the accepted dialects, with the values it must parse to."""
    twa = np.array(sorted(draw(st.sets(st.floats(0.0, 180.0), min_size=2, max_size=6))))
    tws = np.array(sorted(draw(st.sets(st.floats(0.0, 60.0) | st.integers(0, 60).map(float), min_size=2, max_size=6))))
    speed = np.array(
        draw(
            st.lists(
                st.lists(st.floats(0.0, 30.0) | st.integers(0, 30).map(float), min_size=tws.size, max_size=tws.size),
                min_size=twa.size,
                max_size=twa.size,
            )
        )
    )
    if csv:
        sep = draw(st.sampled_from([",", ", ", " ,"]))
        label = draw(st.sampled_from(["twa_deg\\tws_kn", "TWA\\TWS", "", '"twa_deg\\tws_kn"']))
        quote = draw(st.sampled_from(["", '"']))
    else:
        sep = draw(st.sampled_from(["\t", " ", "  ", ";", ",", "; ", " \t"]))
        label = draw(st.sampled_from(["TWA\\TWS", "twa/tws", "TWA/TWS", "Twa\\Tws"]))
        quote = ""
    trailing = sep.strip() if draw(st.booleans()) and sep.strip() else ""
    rows = [sep.join([label, *(quote + _cell(draw, v) + quote for v in tws)]) + trailing]
    for a, row in zip(twa, speed, strict=True):
        rows.append(
            sep.join([quote + _cell(draw, a) + quote, *(quote + _cell(draw, v) + quote for v in row)]) + trailing
        )
    for _ in range(draw(st.integers(0, 2))):  # comments and blank lines anywhere
        rows.insert(draw(st.integers(0, len(rows))), draw(st.sampled_from(["", "# a comment", "   ", "#"])))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    bom = draw(st.sampled_from(["", "\ufeff"]))
    return bom + eol.join(rows) + draw(st.sampled_from(["", eol])), twa, tws, speed


@pytest.mark.slow
@fuzz_settings(80)
@given(pol=formatted_polars(csv=False), csv=formatted_polars(csv=True))
def test_valid_polar_dialects_read_exactly(workdir: Path, pol: Any, csv: Any) -> None:
    """The accepted dialects (separators, labels, number forms, comments, CRLF, BOM) give back the exact table."""
    for (text, twa, tws, speed), name, reader in ((pol, "dialect.pol", read_pol), (csv, "dialect.csv", read_polar_csv)):
        polar = reader(_write(workdir, name, text))
        assert np.array_equal(polar.twa_deg, twa) and np.array_equal(polar.tws_kn, tws)
        assert np.array_equal(polar.speed_kn, speed)


def test_polar_fuzz_premise_example_parses(workdir: Path) -> None:
    """The uncorrupted inputs are valid, so the fuzzers start from a file that parses."""
    a = read_pol(POL)
    b = read_polar_csv(_write(workdir, "clean.csv", CSV_TEXT))
    assert np.array_equal(a.speed_kn, b.speed_kn) and a.speed_kn[3, 5] == 5.0  # TWA 55, TWS 20 (design.md table)


# ---------------------------------------------------------------------------------------------------------
# The CLI on fuzzed scenario files


def _toml_str(s: str) -> str:
    out = ['"']
    for ch in s:
        o = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif o < 0x20 or o == 0x7F:
            out.append(f"\\u{o:04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def to_toml(value: Any) -> str:
    """A minimal TOML writer for JSON-like values (inline tables; None is dropped, as TOML has no null)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _toml_str(value)
    if isinstance(value, list):
        return "[" + ", ".join(to_toml(v) for v in value if v is not None) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_str(str(k))} = {to_toml(v)}" for k, v in value.items() if v is not None) + "}"
    raise TypeError(f"not JSON-like: {value!r}")


def to_toml_document(table: dict[str, Any]) -> str:
    return "".join(f"{_toml_str(str(k))} = {to_toml(v)}\n" for k, v in table.items() if v is not None)


def test_toml_writer_round_trips_the_example() -> None:
    assert tomllib.loads(to_toml_document(BASE)) == BASE


def _run_cli(capsys: pytest.CaptureFixture[str], scenario: Path, out: Path) -> tuple[int, str]:
    code = main(["route", str(scenario), *TINY, "--out", str(out), "--quiet"])
    _, err = capsys.readouterr()
    return code, err


def _check_cli(capsys: pytest.CaptureFixture[str], text: str) -> None:
    with tempfile.TemporaryDirectory(prefix="pyroute-cli-fuzz-") as d:
        scenario = Path(d) / "s.toml"
        scenario.write_text(text, encoding="utf-8")
        out = Path(d) / "out"
        code, err = _run_cli(capsys, scenario, out)
        if code == 3:
            m = re.search(r"internal error: (\w+): (.*?)\. This is a bug", err)
            bug = m and known_bug(m.group(1), m.group(2))
            assert bug, f"exit code 3: {err}"
            event(f"known bug: {bug}")
            return
        assert code in (0, 2), err
        event(f"exit {code}")
        produced = sorted(p.name for p in out.iterdir()) if out.exists() else []
        if code == 2:
            lines = err.splitlines()
            assert len(lines) == 1 and err.endswith("\n") and lines[0].startswith("pyroute-rel: error: "), err
            assert "Traceback" not in err and not PLACEHOLDER.search(err), err
            if "no feasible route" in err:  # no route: what would make one, and the best partial route (issue 35)
                assert "summary.json" in produced and set(produced) <= set(OUTPUTS), produced
                assert json.loads((out / "summary.json").read_text(encoding="utf-8"))["feasible"] is False
            else:  # a user error: nothing written
                assert produced == [], produced
        else:
            assert produced == OUTPUTS
            summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
            assert math.isfinite(summary["voyage_time_h"]) and summary["voyage_time_h"] > 0
            assert len(summary["track"]) >= 2 and all(0.0 <= pt["p_f"] <= 1.0 for pt in summary["track"])


_TOML_VALUES = json_like(null=False)


@pytest.mark.slow
@fuzz_settings(8, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=mutated_scenarios(min_mutations=0, max_mutations=2, values=_TOML_VALUES))
def test_cli_on_fuzzed_scenarios(capsys: pytest.CaptureFixture[str], table: dict[str, Any]) -> None:
    _check_cli(capsys, to_toml_document(table))


def _in(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Numbers of a field's valid range, its end points often."""
    return st.one_of(st.sampled_from([lo, hi]), st.floats(lo, hi))


@st.composite
def plausible_scenarios(draw: st.DrawFn) -> dict[str, Any]:
    """Well-typed scenarios with values anywhere in their documented ranges (the globe, calm to storm)."""
    atlantic = draw(st.booleans())

    def point(lon: tuple[float, float], lat: tuple[float, float]) -> st.SearchStrategy[list[float]]:
        return st.tuples(_in(*lon), _in(*lat)).map(list)

    start = draw(point((-30.0, -5.0), (30.0, 50.0)) if atlantic else point((-180.0, 180.0), (-90.0, 90.0)))
    finish = draw(point((-70.0, -40.0), (5.0, 25.0)) if atlantic else point((-180.0, 180.0), (-90.0, 90.0)))
    weather: dict[str, Any] = {
        "kind": "uniform",
        **{
            name: draw(_in(lo, hi))
            for name, (_, lo, hi) in FIELDS.items()
            if name in ("tws_kn", "twd_deg") or draw(st.booleans())
        },
    }
    if draw(st.booleans()):
        lon0, lat0 = draw(_in(-180.0, 179.0)), draw(_in(-90.0, 89.0))
        weather["patch"] = [
            {
                "lon": [lon0, draw(st.floats(lon0 + 0.01, 180.0))],
                "lat": [lat0, draw(st.floats(lat0 + 0.01, 90.0))],
                "tws_kn": draw(_in(0.0, 200.0)),
            }
        ]
    route: dict[str, Any] = {"start": start, "finish": finish}
    # a coastal margin costs seconds once the course's box spans oceans (all the land in it is buffered): margins
    # on Atlantic courses only
    margin = draw(st.sampled_from([0.0, 10.0, 50.0])) if atlantic else 0.0
    if draw(st.booleans()):
        route["departure"] = draw(
            st.sampled_from(
                [
                    "1970-01-01T00:00:00Z",
                    "2100-01-01T00:00:00+14:00",
                    "1900-02-28T23:59:59",
                    "2018-06-01T00:00:00-12:00",
                ]
            )
        )
    if draw(st.booleans()):
        route["time_step_h"] = draw(st.floats(0.5, 48.0))
        route["max_wait_h"] = draw(st.floats(0.0, 4.0))
    return {
        "route": route,
        "boat": {"polar": "maribot_vane", "beyond": draw(st.sampled_from(["clamp", "forbid"]))},
        "weather": weather,
        "avoid": {"land": draw(st.booleans()), "margin_km": margin},
        "failure": {"model": draw(st.sampled_from(["dickson2018", "none"])), "apf": draw(_in(0.0, 1.0))},
    }


@pytest.mark.slow
@fuzz_settings(12, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=plausible_scenarios())
def test_cli_on_plausible_scenarios(capsys: pytest.CaptureFixture[str], table: dict[str, Any]) -> None:
    _check_cli(capsys, to_toml_document(table))


@pytest.mark.parametrize(
    "edit",
    [
        lambda t: t.replace("tws_kn = 15.0", "tws_kn = 0.0"),  # no wind anywhere: no feasible route
        lambda t: t.replace("start = [-12.0, 45.0]", "start = [2.35, 48.85]"),  # Paris: on land
        lambda t: t.replace("apf = 1.0", "apf = 0.0"),  # every arc with a failure probability is forbidden
        lambda t: t.replace("finish = [-60.0, 17.5]", "finish = [168.0, -45.0]"),  # (nearly) antipodal
        lambda t: t.replace('model = "dickson2018"', 'model = "no_such_model"'),
        lambda t: t.replace('polar = "maribot_vane"', 'polar = "missing.pol"'),
    ],
)
def test_cli_on_edited_scenarios(capsys: pytest.CaptureFixture[str], edit: Callable[[str], str]) -> None:
    text = edit(EXAMPLE_TEXT)
    assert text != EXAMPLE_TEXT
    _check_cli(capsys, text)


# ---------------------------------------------------------------------------------------------------------
# Regression tests of the bugs this fuzzing found (all fixed)


def _mapping(**edits: Any) -> dict[str, Any]:
    d = copy.deepcopy(BASE)
    for dotted, value in edits.items():
        *head, last = dotted.split("__")
        target = d
        for h in head:
            target = target.setdefault(h, {})
        target[last] = value
    return d


def _refused(table: dict[str, Any], field: str) -> None:
    with pytest.raises(PyrouteError) as info:
        scenario_from_mapping(table, base_dir=EXAMPLE.parent, source="<fuzz>")
    check_message(str(info.value), names=field)


@pytest.mark.parametrize(
    "edit,field",
    [
        ({"route__start": [10**400, 45.0]}, "[route].start"),
        ({"weather__tws_kn": 10**400}, "tws_kn"),
        ({"weather__patch": [{"lon": [-(10**400), 0.0], "lat": [0.0, 1.0], "hs_m": 1.0}]}, "[weather].patch[0].lon"),
        ({"failure__apf": 10**400}, "[failure].apf"),
        ({"route__max_wait_h": -(10**400)}, "[route].max_wait_h"),
        ({"avoid__margin_km": 10**400}, "[avoid].margin_km"),
    ],
)
def test_int_beyond_the_float_range_is_refused(edit: dict[str, Any], field: str) -> None:
    """Was an OverflowError from float() (scenario._number, weather._checked_value, weather._range)."""
    _refused(_mapping(**edit), field)


@pytest.mark.parametrize("key", ["n_ranks", "n_nodes"])
def test_huge_grid_size_in_mapping(key: str) -> None:
    """Was an OverflowError in scenario._course_bbox; accepted for later or refused, both are fine."""
    try:
        scenario_from_mapping(_mapping(**{f"grid__{key}": 10**400}), base_dir=EXAMPLE.parent, source="<fuzz>")
    except PyrouteError as exc:
        check_message(str(exc), names=f"[grid].{key}")


@pytest.mark.parametrize("key", ["n_ranks", "n_nodes"])
def test_digit_string_grid_size_in_toml(workdir: Path, key: str) -> None:
    """Was a TypeError: scenario._int accepts "7" but _course_bbox computed with the raw string."""
    path = workdir / "string_size.toml"
    path.write_text(EXAMPLE_TEXT.replace(f"{key} = 160", f'{key} = "7"'), encoding="utf-8")
    try:
        sc = load_scenario(path)
    except PyrouteError as exc:  # refusing a string is as good as reading it
        check_message(str(exc), names=f"[grid].{key}")
    else:
        assert getattr(sc, key) == 7


@pytest.mark.parametrize("value", ["[]", "{}", '["low"]'])
def test_unhashable_avoid_resolution_is_refused(workdir: Path, value: str) -> None:
    """Was a TypeError: `resolution not in RESOLUTIONS` (a dict) with a list or table."""
    path = workdir / "resolution.toml"
    path.write_text(EXAMPLE_TEXT + f"\n[avoid]\nresolution = {value}\n", encoding="utf-8")
    with pytest.raises(PyrouteError) as info:
        load_scenario(path)
    check_message(str(info.value), names="[avoid].resolution")


@pytest.mark.parametrize("extra", ['[boat]\npolar = "x\\u0000.pol"\n', '[avoid]\nzones = ["x\\u0000.geojson"]\n'])
def test_nul_in_a_file_name_of_the_scenario(workdir: Path, extra: str) -> None:
    """Was a ValueError (embedded null byte) from Path.read_*, which is not an OSError."""
    text = EXAMPLE_TEXT.replace('[boat]\npolar = "maribot_vane"\n', "") + "\n" + extra
    path = workdir / "nul.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(PyrouteError) as info:
        load_scenario(path)
    check_message(str(info.value), names=str(path))


@pytest.mark.parametrize(
    "reader,error", [(load_scenario, PyrouteError), (read_pol, PolarError), (read_polar_csv, PolarError)]
)
def test_nul_in_a_path_argument(workdir: Path, reader: Callable[[Path], Any], error: type[Exception]) -> None:
    with pytest.raises(error) as info:
        reader(workdir / "x\x00.toml")
    check_message(str(info.value), names="x")


@pytest.mark.parametrize("value", ["9999-12-31T23:59:59-05:00", "0001-01-01T00:00:00+05:00"])
def test_departure_at_the_calendar_edge(workdir: Path, value: str) -> None:
    """Was an OverflowError from astimezone() at year 1 / 9999 (a TOML string and a TOML offset date-time)."""
    for form in (f'"{value}"', value):
        path = workdir / "edge.toml"
        path.write_text(EXAMPLE_TEXT.replace('"2018-06-01T00:00:00Z"', form), encoding="utf-8")
        with pytest.raises(PyrouteError) as info:
            load_scenario(path)
        check_message(str(info.value), names="[route].departure")


@pytest.mark.parametrize(
    "edit,field",
    [
        ({"a\nb": 1}, "unknown table"),
        ({"boat": {"polar": "a\nb.pol"}}, "polar file"),
        ({"avoid": {"zones": ["a\nb.geojson"]}}, "zone file"),
    ],
)
def test_newline_in_a_user_string_keeps_the_message_on_one_line(edit: dict[str, Any], field: str) -> None:
    """Was a multi-line message: user strings put in without repr()."""
    _refused({**copy.deepcopy(BASE), **edit}, field)


def test_wait_steps_per_node_are_bounded() -> None:
    """Was a DP that never ends: 1440 h of waiting on a 1e-9 h lattice is 1.4e12 wait steps per node."""
    w = UniformWeather(tws_kn=15.0, twd_deg=0.0)
    try:
        problem = RoutingProblem(
            departure=np.datetime64("2018-06-01"),
            weather=w,
            polar=get_polar("maribot_vane"),
            time_step_h=1e-9,
            max_wait_h=1440.0,
        )
    except PyrouteError as exc:
        check_message(str(exc), names="time_step_h")
        return
    assert problem.n_wait <= 100_000, problem.n_wait  # ~0.3 ms per wait step and rank


@pytest.mark.slow
def test_long_patch_name_plots_without_warnings(capsys: pytest.CaptureFixture[str]) -> None:
    """Was a UserWarning from tight_layout() (exit 3 where warnings are errors); fixed in 94fba32."""
    text = EXAMPLE_TEXT.replace('name = "Area 1"', 'name = "' + "Area 1 " * 60 + '"')
    with tempfile.TemporaryDirectory(prefix="pyroute-cli-") as d:
        (Path(d) / "s.toml").write_text(text, encoding="utf-8")
        code, err = _run_cli(capsys, Path(d) / "s.toml", Path(d) / "out")  # warnings are errors under pytest
    assert code == 0, err


def test_near_calm_wind_is_not_an_endless_voyage(capsys: pytest.CaptureFixture[str]) -> None:
    """Was a voyage of ~1e176 h with arrival 'NaTZ' (1e-170 kn of wind sailed at ~1e-170 kn); fixed in 94fba32."""
    import datetime as dt

    text = EXAMPLE_TEXT.replace("tws_kn = 15.0", "tws_kn = 1e-170").replace('model = "dickson2018"', 'model = "none"')
    with tempfile.TemporaryDirectory(prefix="pyroute-cli-") as d:
        (Path(d) / "s.toml").write_text(text, encoding="utf-8")
        code = main(["route", str(Path(d) / "s.toml"), *TINY, "--no-land", "--quiet", "--json"])
    out, err = capsys.readouterr()
    assert code in (0, 2), err
    if code == 0:  # a route (at the very least) must have a real arrival time
        arrival = json.loads(out)["arrival"]
        assert dt.datetime.fromisoformat(arrival.replace("Z", "+00:00")).year < 10000, arrival


@pytest.mark.parametrize("margin_km", [1e-300, 1e-15])
def test_tiny_coastal_margin_keeps_the_land(margin_km: float) -> None:
    """A margin in (0, ~1e-12] km lost land polygons, so Paris was not on land; fixed in 94fba32."""
    from pyroute_rel.obstacles.mask import Avoid, check_points

    paris = ("[route].start", (2.35, 48.85))  # on land, as the margin-0 check says too
    with pytest.raises(ScenarioError, match="on land"):
        check_points([paris], Avoid(land=True, margin_km=0.0))
    with pytest.raises(ScenarioError, match="on land"):
        check_points([paris], Avoid(land=True, margin_km=margin_km))
