"""Failure models: loading, compiled tables vs pgmpy, gather at thresholds, NaN rules, caches, bad files."""

from __future__ import annotations

import fnmatch
import io
import itertools
import json
import math
import os
import subprocess
import sys
import tomllib
import warnings
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel import diskcache
from pyroute_rel.errors import FailureModelError
from pyroute_rel.reliability import failure
from pyroute_rel.reliability.failure import QUANTITIES, build_network, list_failure_models, load_failure_model

SHIPPED = files("failure_models")
MODELS = ("dickson2018", "wind_wave_multistate")
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module", autouse=True)
def _cache_dir(tmp_path_factory: pytest.TempPathFactory):
    """Keep the disk cache of these tests out of the user's cache folder."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
        yield


def _pgmpy():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from pgmpy.inference import VariableElimination
        from pgmpy.readwrite import BIFReader
    return BIFReader, VariableElimination


def _query(ve, target: str, state: str, evidence: dict[str, str]) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = ve.query([target], evidence=evidence, show_progress=False)
    return float(f.values[list(f.state_names[target]).index(state)])


@pytest.fixture(scope="module")
def engines():
    """pgmpy VariableElimination on each shipped network, read straight from the BIF file (not via failure.py)."""
    BIFReader, VariableElimination = _pgmpy()
    out = {}
    for name in MODELS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            net = BIFReader(path=str(SHIPPED / f"{name}.bif")).get_model()
        out[name] = VariableElimination(net)
    return out


# ------------------------------------------------------------------------------------------ shipped models


def test_shipped_models_are_package_resources():
    names = list_failure_models()
    assert set(MODELS) <= set(names)
    for name in names:
        m = load_failure_model(name)
        assert Path(m.path) == Path(str(SHIPPED / f"{name}.toml"))
        assert Path(m.network_path).parent == Path(str(SHIPPED))


def test_package_data_globs_cover_shipped_files():
    """A wheel (non-editable install) carries every data file of failure_models/ (pyproject package-data)."""
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["failure_models"]
    data = [p.name for p in Path(str(SHIPPED)).iterdir() if p.is_file() and p.suffix not in (".py", ".pyc")]
    assert {"dickson2018.toml", "dickson2018.bif", "README.md"} <= set(data)
    for name in data:
        assert any(fnmatch.fnmatch(name, g) for g in globs), name


@pytest.mark.slow
@pytest.mark.parametrize("name", MODELS)
def test_table_equals_pgmpy_query_on_every_evidence_state(name, engines):
    m = load_failure_model(name)
    assert m.table.shape == tuple(len(c.states) for c in m.criteria)
    n = 0
    for ev, idx in zip(m.evidence_states(), np.ndindex(m.table.shape), strict=True):
        assert [c.states[i] for c, i in zip(m.criteria, idx, strict=True)] == list(ev.values())
        ref = _query(engines[name], m.target, m.fail_state, ev)
        assert m.table[idx] == pytest.approx(ref, rel=1e-12, abs=1e-14), ev
        n += 1
    assert n == math.prod(m.table.shape)


def test_dickson2018_reproduces_paper_table_1():
    # Dickson, Blake and Sear (2018), Reliability informed routing for Autonomous Sailing Craft, Table 1:
    # P(F = fail) = 0.9 with WH xor WD met, 0.0 with neither, 1.0 with both.
    m = load_failure_model("dickson2018")
    table1 = {("true", "false"): 0.9, ("false", "true"): 0.9, ("false", "false"): 0.0, ("true", "true"): 1.0}
    assert [c.node for c in m.criteria] == ["WH", "WD"]
    for ev, idx in zip(m.evidence_states(), np.ndindex(m.table.shape), strict=True):
        assert m.table[idx] == table1[ev["WH"], ev["WD"]]
    assert (m.target, m.fail_state) == ("F", "fail")
    assert [c.describe() for c in m.criteria] == ["WH: hs_m >= 4 m", "WD: awd_deg < 60 deg"]


@pytest.mark.slow
def test_multistate_model_has_hidden_nodes_and_wind_criteria():
    m = load_failure_model("wind_wave_multistate")
    observed = {c.node for c in m.criteria}
    assert {"tws_kn", "twa_deg"} <= m.quantities
    assert any(len(c.states) > 2 for c in m.criteria)
    hidden = set(m.nodes) - observed - {m.target}
    assert hidden, "the network must have hidden nodes"
    parents_of_target = {a for a, b in m.edges if b == m.target}
    assert parents_of_target and parents_of_target <= hidden  # not simply evidence -> F
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net = build_network(m)
    assert set(map(tuple, net.edges())) == set(m.edges)


# ---------------------------------------------------------------------------------------------- gathering


def _dickson_brute(hs: float, awd: float) -> float:
    n = int(hs >= 4.0) + int(awd < 60.0)  # Table 1 by the number of criteria met
    return (0.0, 0.9, 1.0)[n]


def test_thresholds_are_exact_and_gather_broadcasts():
    m = load_failure_model("dickson2018")
    hs = np.array([[3.9999999, 4.0, 4.0000001], [0.0, 12.0, 4.0]])
    awd = np.array([59.9999999, 60.0, 60.0000001])
    p = m.p_fail({"hs_m": hs, "awd_deg": awd})
    assert p.shape == (2, 3)
    ref = np.array([[_dickson_brute(h, a) for h, a in zip(row, awd, strict=True)] for row in hs])
    np.testing.assert_array_equal(p, ref)
    fired = m.fired({"hs_m": hs, "awd_deg": awd})
    assert fired.shape == (2, 2, 3)
    np.testing.assert_array_equal(fired[0], hs >= 4.0)
    np.testing.assert_array_equal(fired[1], np.broadcast_to(awd < 60.0, (2, 3)))
    assert m.fired({"hs_m": 4.0, "awd_deg": 60.0}).tolist() == [True, False]
    assert float(m.p_fail({"hs_m": 4.0, "awd_deg": 60.0})) == 0.9


# physical ranges (p_fail refuses others): hs_m >= 0, awd_deg in [0, 180]; thresholds and ends included
_hs = st.one_of(st.floats(0.0, 30.0, allow_nan=False), st.sampled_from([4.0, 0.0, 60.0]))
_awd = st.one_of(st.floats(0.0, 180.0, allow_nan=False), st.sampled_from([4.0, 60.0, 0.0, 180.0]))


@pytest.mark.slow
@given(st.lists(st.tuples(_hs, _awd), min_size=1, max_size=20))
@settings(max_examples=100, deadline=None)
def test_dickson_gather_equals_brute_force(pairs):
    m = load_failure_model("dickson2018")
    hs, awd = np.array(pairs).T
    p = m.p_fail({"hs_m": hs, "awd_deg": awd, "tws_kn": np.zeros_like(hs)})  # extra quantities are ignored
    assert p.tolist() == [_dickson_brute(h, a) for h, a in pairs]


def _multistate_states(tws: float, hs: float, awd: float, twa: float, tp: float) -> dict[str, str]:
    """Classify by hand, from the comments of wind_wave_multistate.toml (edges closed on the left)."""
    return {
        "TWS": "light" if tws < 25 else ("strong" if tws < 35 else "gale"),
        "HS": "low" if hs < 2.5 else ("moderate" if hs < 4 else "high"),
        "SEA": "head" if awd < 45 else ("beam" if awd < 135 else "following"),
        "RUN": "running" if twa >= 150 else "sailing",
        "STEEP": "short" if tp < 8 else "long",
    }


@pytest.fixture(scope="module")
def multistate_reference(engines):
    """P(F = fail | evidence) from pgmpy for every evidence state, and with STEEP unobserved."""
    m = load_failure_model("wind_wave_multistate")
    ref = {}
    for ev in m.evidence_states():
        ref[tuple(ev.values())] = _query(engines[m.name], "F", "fail", ev)
        partial = {k: v for k, v in ev.items() if k != "STEEP"}
        ref[(*partial.values(), None)] = _query(engines[m.name], "F", "fail", partial)
    return ref


_edge_values = {
    "tws_kn": [25.0, 35.0],
    "hs_m": [2.5, 4.0],
    "awd_deg": [45.0, 135.0],
    "twa_deg": [150.0],
    "wave_period_s": [8.0],
}
_ranges = {"tws_kn": (0, 60), "hs_m": (0, 12), "awd_deg": (0, 180), "twa_deg": (0, 180), "wave_period_s": (1, 20)}


def _quantity(name: str) -> st.SearchStrategy[float]:
    lo, hi = _ranges[name]
    return st.one_of(st.floats(lo, hi, allow_nan=False), st.sampled_from(_edge_values[name]))


_order = ("tws_kn", "hs_m", "awd_deg", "twa_deg", "wave_period_s")


@pytest.mark.slow
@given(st.lists(st.tuples(*[_quantity(q) for q in _order]), min_size=1, max_size=10), st.data())
@settings(max_examples=60, deadline=None)
def test_multistate_gather_equals_pgmpy(multistate_reference, rows, data):
    m = load_failure_model("wind_wave_multistate")
    arr = np.array(rows, dtype=float)
    no_period = data.draw(st.lists(st.booleans(), min_size=len(rows), max_size=len(rows)))
    arr[np.array(no_period), 4] = np.nan  # weather without wave period: STEEP falls back to its prior
    p = m.p_fail(dict(zip(_order, arr.T, strict=True)))
    for row, got in zip(arr, p, strict=True):
        states = _multistate_states(*row)
        key = tuple(states.values()) if not np.isnan(row[4]) else (*list(states.values())[:4], None)
        assert got == pytest.approx(multistate_reference[key], rel=1e-12, abs=1e-14)


def _with_named_missing_state(tmp: Path) -> Path:
    """dickson2018 with WH assumed "true" (fired) when Hs is NaN: the third NaN rule."""
    folder = tmp / "named_missing"
    folder.mkdir(exist_ok=True)
    toml = files("failure_models").joinpath("dickson2018.toml").read_text()
    (folder / "m.toml").write_text(toml.replace('fired = "true"', 'fired = "true"\nif_missing = "true"', 1))
    (folder / "dickson2018.bif").write_text(files("failure_models").joinpath("dickson2018.bif").read_text())
    return folder / "m.toml"


@pytest.mark.slow
@given(
    st.lists(st.tuples(*[st.one_of(_quantity(q), st.just(math.nan)) for q in _order]), min_size=1, max_size=12),
    st.sampled_from(["dickson2018", "wind_wave_multistate", "named"]),
)
@settings(max_examples=80, deadline=None)
def test_kernel_flat_index_equals_reference_classifier(tmp_path_factory, rows, which):
    # the cost kernel's fast path (one comparison per threshold, one flat gather) against the reference
    # path (binary search per criterion, one index per axis): same p_f, same fired criteria, same unknowns
    name = _with_named_missing_state(tmp_path_factory.getbasetemp()) if which == "named" else which
    m = load_failure_model(name)
    q = dict(zip(_order, np.array(rows, dtype=float).T, strict=True))
    q = {k: v for k, v in q.items() if k in m.quantities}
    idx, unknown = m.evidence_index(q)
    p = m.p_flat[idx]
    if unknown is not None:
        p = np.where(unknown, np.nan, p)
    np.testing.assert_array_equal(p, m.p_fail(q))  # NaN where the reference gives NaN, equal elsewhere
    bits = m.fired_bits_flat[idx]
    ref = m.fired(q)
    known = ~np.isnan(p)
    for i in range(len(m.criteria)):
        np.testing.assert_array_equal(((bits >> i) & 1).astype(bool)[known], ref[i][known])


def test_nan_is_never_read_as_criterion_not_met():
    m = load_failure_model("dickson2018")
    p = m.p_fail({"hs_m": [np.nan, 1.0, np.nan], "awd_deg": [90.0, np.nan, np.nan]})
    assert np.isnan(p).all()
    assert not m.fired({"hs_m": [np.nan], "awd_deg": [np.nan]}).any()
    ms = load_failure_model("wind_wave_multistate")
    q = {"tws_kn": np.nan, "hs_m": 1.0, "awd_deg": 90.0, "twa_deg": 90.0, "wave_period_s": 10.0}
    assert np.isnan(ms.p_fail(q))
    assert np.isfinite(ms.p_fail({**q, "tws_kn": 10.0, "wave_period_s": np.nan}))


def test_missing_quantity_is_an_error():
    m = load_failure_model("dickson2018")
    with pytest.raises(FailureModelError, match=r"needs quantities \['awd_deg'\]"):
        m.p_fail({"hs_m": 1.0})


def test_describe_is_json_and_consistent():
    for name in MODELS:
        m = load_failure_model(name)
        d = json.loads(json.dumps(m.describe()))
        assert {"model", "path", "description", "criteria", "network", "table"} <= set(d)
        assert d["model"] == name and d["path"] == m.path
        assert [c["node"] for c in d["criteria"]] == [c.node for c in m.criteria]
        assert len(d["table"]) == m.table.size
        for row in d["table"]:
            idx = tuple(c.states.index(row["evidence"][c.node]) for c in m.criteria)
            assert row["p_fail"] == m.table[idx]
        assert {tuple(e) for e in d["network"]["edges"]} == set(m.edges)
        assert set(d["network"]["nodes"]) == set(m.nodes)
    assert load_failure_model("dickson2018").describe()["criteria"][0]["rule"] == "hs_m >= 4"


def test_quantities_constant_names_units():
    assert set(QUANTITIES) == {"hs_m", "awd_deg", "tws_kn", "twa_deg", "wave_period_s"}
    for name, text in QUANTITIES.items():  # the unit in the name is the unit in the description
        assert f"[{name.rsplit('_', 1)[1]}]" in text


# --------------------------------------------------------------------------------------------------- caches


def _copy_model(folder: Path, name: str = "dickson2018", network_text: str | None = None) -> Path:
    """A copy of a shipped model whose TOML differs by a comment line, so no shipped table matches its bytes."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.bif").write_text(network_text or (SHIPPED / f"{name}.bif").read_text())
    toml = folder / f"{name}.toml"
    toml.write_text("# a designer's copy\n" + (SHIPPED / f"{name}.toml").read_text())
    return toml


@pytest.mark.slow
def test_shipped_tables_equal_a_fresh_pgmpy_compile():
    """The tables shipped in failure_models/compiled_tables.json are what pgmpy compiles from today's files."""
    shipped = failure._shipped_tables()
    for name in list_failure_models():
        toml_bytes = (SHIPPED / f"{name}.toml").read_bytes()
        net_bytes = (SHIPPED / f"{name}.bif").read_bytes()
        entry = shipped.get(failure._content_key(toml_bytes, net_bytes))
        assert entry is not None, (
            f"{name}: model files changed; refresh the tables: python -m pyroute_rel.reliability.failure"
        )
        fresh = load_failure_model(name, cache=False)  # compiled by pgmpy, no cache of any kind
        assert np.array_equal(entry.table, fresh._full), f"{name}: refresh: python -m pyroute_rel.reliability.failure"
        assert entry.nodes == list(fresh.nodes)
        assert entry.states == {k: list(v) for k, v in fresh.node_states.items()}


@pytest.mark.slow
def test_first_run_of_a_shipped_model_needs_neither_pgmpy_nor_the_disk_cache(tmp_path):
    code = (
        "import json, sys; from pyroute_rel.reliability.failure import load_failure_model; "
        "t = {n: load_failure_model(n).table.tolist() for n in ('dickson2018', 'wind_wave_multistate')}; "
        "print(json.dumps({'pgmpy': any(k.split('.')[0] == 'pgmpy' for k in sys.modules), 'tables': t}))"
    )
    env = {**os.environ, "PYROUTE_REL_CACHE_DIR": str(tmp_path / "empty")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    got = json.loads(out.stdout)
    assert got["pgmpy"] is False
    assert not (tmp_path / "empty").exists()  # nothing compiled, nothing written
    for name, table in got["tables"].items():
        assert np.array_equal(np.array(table), load_failure_model(name, cache=False).table)


@pytest.mark.slow
def test_without_the_shipped_tables_models_are_compiled(monkeypatch, tmp_path):
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path))
    failure._compiled_tables().clear()
    monkeypatch.setattr(failure, "_SHIPPED_TABLES", "no_such_file.json")
    assert failure._shipped_tables() == {}
    try:
        assert load_failure_model("dickson2018").table.tolist() == [[0.0, 0.9], [0.9, 1.0]]
        assert len(list((tmp_path / diskcache.ENTRIES).glob("failure-*.npz"))) == 1  # compiled, then kept on disk
    finally:
        monkeypatch.undo()
    failure._compiled_tables().clear()
    assert failure._shipped_tables() != {}  # the shipped file again (kept by its path, size and time)


@pytest.mark.slow
def test_disk_cache_second_run_does_not_import_pgmpy(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(cache))
    failure._compiled_tables().clear()
    toml = _copy_model(tmp_path / "m", "wind_wave_multistate")
    first = load_failure_model(toml)
    assert len(list((cache / diskcache.ENTRIES).glob("failure-*.npz"))) == 1
    code = (
        "import json, sys; from pyroute_rel.reliability.failure import load_failure_model; "
        f"m = load_failure_model({str(toml)!r}); "
        "print(json.dumps({'pgmpy': any(k.split('.')[0] == 'pgmpy' for k in sys.modules), "
        "'table': m.table.tolist(), 'edges': [list(e) for e in m.edges]}))"
    )
    env = {**os.environ, "PYROUTE_REL_CACHE_DIR": str(cache)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    got = json.loads(out.stdout)
    assert got["pgmpy"] is False
    assert np.array_equal(np.array(got["table"]), first.table)
    assert got["edges"] == [list(e) for e in first.edges]


@pytest.mark.slow
def test_disk_cache_is_used_instead_of_compiling(tmp_path, monkeypatch):
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path / "cache"))
    failure._compiled_tables().clear()
    toml = _copy_model(tmp_path / "m")
    first = load_failure_model(toml)

    def boom(*args, **kwargs):
        raise AssertionError("compiled again")

    failure._compiled_tables().clear()
    monkeypatch.setattr(failure, "_compile", boom)
    again = load_failure_model(toml)
    assert np.array_equal(again.table, first.table)
    assert again.table.tolist() == [[0.0, 0.9], [0.9, 1.0]]
    assert load_failure_model("dickson2018").table.tolist() == [[0.0, 0.9], [0.9, 1.0]]  # the shipped table


@pytest.mark.slow
def test_editing_the_network_recompiles(tmp_path, monkeypatch):
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path / "cache"))
    failure._compiled_tables().clear()
    toml = _copy_model(tmp_path / "m")
    assert load_failure_model(toml).table.tolist() == [[0.0, 0.9], [0.9, 1.0]]
    bif = tmp_path / "m" / "dickson2018.bif"
    bif.write_text(bif.read_text().replace("0.1, 0.9;", "0.2, 0.8;"))
    assert load_failure_model(toml).table.tolist() == [[0.0, 0.8], [0.8, 1.0]]
    assert len(list((tmp_path / "cache" / diskcache.ENTRIES).glob("failure-*.npz"))) == 2


@pytest.mark.slow
def test_editing_a_shipped_model_in_place_is_not_served_the_shipped_table(tmp_path, monkeypatch):
    """The shipped tables are keyed by the files' bytes: an edited copy (here: another CPT) is compiled."""
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path / "cache"))
    failure._compiled_tables().clear()
    folder = tmp_path / "m"
    folder.mkdir()
    (folder / "dickson2018.toml").write_text((SHIPPED / "dickson2018.toml").read_text())  # same bytes as shipped
    (folder / "dickson2018.bif").write_text((SHIPPED / "dickson2018.bif").read_text().replace("0.1, 0.9;", "0.3, 0.7;"))
    np.testing.assert_allclose(
        load_failure_model(folder / "dickson2018.toml").table, [[0.0, 0.7], [0.7, 1.0]], rtol=0, atol=1e-15
    )


def test_corrupt_cache_file_is_ignored(tmp_path, monkeypatch):
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path / "cache"))
    failure._compiled_tables().clear()
    toml = _copy_model(tmp_path / "m")
    load_failure_model(toml)
    (entry,) = (tmp_path / "cache" / diskcache.ENTRIES).glob("failure-*.npz")
    entry.write_bytes(b"not a zip file")
    failure._compiled_tables().clear()
    assert load_failure_model(toml).table.tolist() == [[0.0, 0.9], [0.9, 1.0]]
    with np.load(io.BytesIO(diskcache.read(entry.name))) as data:  # rewritten atomically with a good entry
        assert data["table"].shape == (3, 3)
        meta = data["meta"]
    signed = entry.read_bytes()
    for table in (np.full((2, 2), 0.5), np.zeros((3, 3))):  # does not fit the model; fits but is wrong (all zeros)
        buf = io.BytesIO()
        np.savez(buf, table=table, meta=meta)
        head = len(signed) - len(diskcache.read(entry.name))
        entry.write_bytes(signed[:head] + buf.getvalue())  # well formed, with the genuine entry's header
        failure._compiled_tables().clear()
        assert load_failure_model(toml).table.tolist() == [[0.0, 0.9], [0.9, 1.0]]


def test_unwritable_cache_folder_falls_back_silently(tmp_path, monkeypatch):
    toml = _copy_model(tmp_path / "m")
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(blocker / "cache"))  # cannot mkdir under a file
    failure._compiled_tables().clear()
    assert load_failure_model(toml).table.tolist() == [[0.0, 0.9], [0.9, 1.0]]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "m"]


def test_cache_false_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path))
    assert load_failure_model("dickson2018", cache=False).table.tolist() == [[0.0, 0.9], [0.9, 1.0]]
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------- other formats


@pytest.mark.slow
@pytest.mark.parametrize(
    ("ext", "writer", "method"),
    [
        (".xdsl", "XDSLWriter", "write_xdsl"),
        (".net", "NETWriter", "write_net"),
        (".xmlbif", "XMLBIFWriter", "write_xmlbif"),
    ],
)
def test_other_network_formats_give_the_same_table(tmp_path, ext, writer, method):
    """A network saved by pgmpy's writers for GeNIe, Hugin and XMLBIF compiles to the BIF model's table."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from pgmpy import readwrite

        ref = load_failure_model("wind_wave_multistate")
        getattr(getattr(readwrite, writer)(build_network(ref)), method)(str(tmp_path / f"net{ext}"))
    text = (SHIPPED / "wind_wave_multistate.toml").read_text()
    toml = tmp_path / "model.toml"
    toml.write_text(text.replace('network = "wind_wave_multistate.bif"', f'network = "net{ext}"'))
    got = load_failure_model(toml)
    np.testing.assert_allclose(got.table, ref.table, rtol=1e-12, atol=1e-14)
    assert got.name == "wind_wave_multistate"


# ----------------------------------------------------------------------------------------------- bad files

_DICKSON_TOML = (SHIPPED / "dickson2018.toml").read_text()
_DICKSON_BIF = (SHIPPED / "dickson2018.bif").read_text()
_MULTI_TOML = (SHIPPED / "wind_wave_multistate.toml").read_text()
_MULTI_BIF = (SHIPPED / "wind_wave_multistate.bif").read_text()

# (id, TOML text, network text, file named in the message, pattern the message must contain)
_BAD = [
    ("toml_syntax", _DICKSON_TOML.replace('node = "WH"', 'node = "WH'), _DICKSON_BIF, "toml", "TOML syntax error"),
    (
        "unknown_key",
        _DICKSON_TOML.replace('name = "dickson2018"', 'nmae = "x"'),
        _DICKSON_BIF,
        "toml",
        "unknown key 'nmae'",
    ),
    (
        "unknown_criterion_key",
        _DICKSON_TOML.replace('fired = "true"', 'fired = "true"\nthreshhold = 3', 1),
        _DICKSON_BIF,
        "toml",
        r"criteria\[0\] \(WH\): unknown key 'threshhold'",
    ),
    (
        "unknown_quantity",
        _DICKSON_TOML.replace('"hs_m"', '"hs"'),
        _DICKSON_BIF,
        "toml",
        r"'quantity' must be one of \['hs_m'.*\] \(got 'hs'\)",
    ),
    ("bad_operator", _DICKSON_TOML.replace('">="', '"=>"'), _DICKSON_BIF, "toml", r"'operator' must be one of"),
    ("missing_fired", _DICKSON_TOML.replace('fired = "true"', "", 1), _DICKSON_BIF, "toml", "missing key 'fired'"),
    (
        "fired_not_a_state",
        _DICKSON_TOML.replace('fired = "true"', 'fired = "yes"', 1),
        _DICKSON_BIF,
        "toml",
        r"'fired' 'yes' is not a state of WH",
    ),
    (
        "node_not_in_network",
        _DICKSON_TOML.replace('node = "WH"', 'node = "HW"'),
        _DICKSON_BIF,
        "toml",
        "node 'HW' is not in the network",
    ),
    (
        "target_missing",
        _DICKSON_TOML.replace('node = "F"', 'node = "FAIL"'),
        _DICKSON_BIF,
        "toml",
        r"\[target\] node 'FAIL' is not in the network",
    ),
    (
        "fail_state_missing",
        _DICKSON_TOML.replace('state = "fail"', 'state = "broken"'),
        _DICKSON_BIF,
        "toml",
        r"\[target\] state 'broken' is not a state of F",
    ),
    (
        "no_target_table",
        _DICKSON_TOML.replace('[target]\nnode = "F"\nstate = "fail"', ""),
        _DICKSON_BIF,
        "toml",
        r"missing table \[target\]",
    ),
    (
        "bad_if_missing",
        _DICKSON_TOML.replace('fired = "true"', 'fired = "true"\nif_missing = "zero"', 1),
        _DICKSON_BIF,
        "toml",
        r"'if_missing' must be one of \['nan', 'prior'\] or a state of WH",
    ),
    (
        "wrong_cardinality_bins",
        _MULTI_TOML.replace("bins = [25.0, 35.0]", "bins = [25.0]"),
        _MULTI_BIF,
        "toml",
        "wrong cardinality: 1 bin edges make 2 bins but node TWS has 3 states",
    ),
    (
        "threshold_on_multistate",
        _MULTI_TOML.replace("bins = [25.0, 35.0]", 'operator = ">="\nthreshold = 25.0\nfired = "gale"').replace(
            'nominal = "light"', "", 1
        ),
        _MULTI_BIF,
        "toml",
        "wrong cardinality: a threshold criterion needs a two-state node but TWS has 3 states",
    ),
    (
        "bins_not_increasing",
        _MULTI_TOML.replace("bins = [25.0, 35.0]", "bins = [35.0, 25.0]"),
        _MULTI_BIF,
        "toml",
        "'bins' must be strictly increasing",
    ),
    (
        "both_forms",
        _DICKSON_TOML.replace('fired = "true"', 'fired = "true"\nbins = [1.0]', 1),
        _DICKSON_BIF,
        "toml",
        "either 'operator' and 'threshold'",
    ),
    (
        "bad_network_extension",
        _DICKSON_TOML.replace("dickson2018.bif", "dickson2018.txt"),
        _DICKSON_BIF,
        "toml",
        r"extension must be one of \['.bif'",
    ),
    (
        "missing_cpt",
        _DICKSON_TOML,
        _DICKSON_BIF.replace("probability ( WD ) {\n  table 0.666667, 0.333333;\n}\n", ""),
        "bif",
        "missing CPT: no probability table for WD",
    ),
    (
        "not_summing_to_1",
        _DICKSON_TOML,
        _DICKSON_BIF.replace("table 0.8, 0.2;", "table 0.8, 0.2001;"),
        "bif",
        r"CPT of WH: P\(WH\) = \[0.8, 0.2001\] sums to 1.0001",
    ),
    (
        "missing_cpt_row",
        _DICKSON_TOML,
        _DICKSON_BIF.replace("  (true, true) 0.0, 1.0;\n", ""),
        "bif",
        r"CPT of F: P\(F \| WH=true, WD=true\) = \[0.0, 0.0\] sums to 0",
    ),
    ("bif_garbage", _DICKSON_TOML, "this is not a network", "bif", "network parse failure: no variables found"),
    (
        "bif_undeclared",
        _DICKSON_TOML,
        _DICKSON_BIF.replace("variable WD {", "variable WX {"),
        "bif",
        "network parse failure: KeyError",
    ),
    (
        "bif_declared_count",
        _DICKSON_TOML,
        _DICKSON_BIF.replace("[ 2 ] { pass, fail }", "[ 3 ] { pass, fail }"),
        "bif",
        r"variable F declares \[ 3 \] states but lists 2",
    ),
]


@pytest.mark.slow
@pytest.mark.parametrize(("toml_text", "net_text", "named", "pattern"), [b[1:] for b in _BAD], ids=[b[0] for b in _BAD])
def test_bad_model_files_give_one_line_errors(tmp_path, toml_text, net_text, named, pattern):
    toml = tmp_path / "model.toml"
    toml.write_text(toml_text)
    net = tmp_path / ("dickson2018.bif" if "dickson2018" in toml_text else "wind_wave_multistate.bif")
    net.write_text(net_text)
    with pytest.raises(FailureModelError, match=pattern) as info:
        load_failure_model(toml)
    message = str(info.value)
    assert "\n" not in message
    assert str(toml if named == "toml" else net) in message
    assert info.value.__cause__ is None  # no chained traceback for a user mistake


def test_missing_files_are_named(tmp_path):
    with pytest.raises(FailureModelError, match="file not found") as info:
        load_failure_model(tmp_path / "nope.toml")
    assert str(tmp_path / "nope.toml") in str(info.value)
    toml = tmp_path / "m.toml"
    toml.write_text(_DICKSON_TOML)  # its dickson2018.bif is not next to it
    with pytest.raises(FailureModelError, match="network file 'dickson2018.bif'.*file not found") as info:
        load_failure_model(toml)
    assert str(toml) in str(info.value)
    with pytest.raises(FailureModelError, match=r"failure model 'dikson2018' not found: expected .*'dickson2018'"):
        load_failure_model("dikson2018")


@pytest.mark.slow
def test_zero_probability_evidence_is_rejected(tmp_path):
    toml = _copy_model(tmp_path, network_text=_DICKSON_BIF.replace("table 0.8, 0.2;", "table 1.0, 0.0;"))
    with pytest.raises(FailureModelError, match=r"evidence \(WH=true, WD=false\) has probability 0"):
        load_failure_model(toml)


def test_every_shipped_model_quantity_is_known():
    for name in list_failure_models():
        m = load_failure_model(name)
        assert m.quantities <= set(QUANTITIES)
        assert list(itertools.islice(m.evidence_states(), 1))


def test_p_fail_refuses_quantities_out_of_their_range() -> None:
    m = load_failure_model("dickson2018")
    # 400 deg would fold to 40 deg (head seas, 0.9) but gathered as "not < 60" (0.0): refused instead
    with pytest.raises(FailureModelError, match=r"awd_deg must be in \[0, 180\].*\(got 400\)"):
        m.p_fail({"hs_m": 1.0, "awd_deg": 400.0})
    with pytest.raises(FailureModelError, match=r"hs_m must be in \[0, inf\]"):
        m.p_fail({"hs_m": -1.0, "awd_deg": 90.0})


def test_one_map_from_quantities_to_weather_fields():
    from pyroute_rel.geodesy import angle_diff_deg
    from pyroute_rel.reliability.failure import QUANTITIES, QUANTITY_FIELDS, arc_quantities
    from pyroute_rel.weather import FIELDS, UniformWeather

    assert set(QUANTITY_FIELDS) == set(QUANTITIES)
    assert all(field in FIELDS for field, _ in QUANTITY_FIELDS.values())
    c = UniformWeather(tws_kn=11.0, twd_deg=30.0, hs_m=2.5, wave_dir_deg=300.0, wave_period_s=7.0).sample(0, 0, 0)
    q = arc_quantities(c, 80.0)
    assert (float(q["twa_deg"]), float(q["awd_deg"])) == (angle_diff_deg(30.0, 80.0), angle_diff_deg(300.0, 80.0))
    assert (float(q["tws_kn"]), float(q["hs_m"]), float(q["wave_period_s"])) == (11.0, 2.5, 7.0)
    assert list(arc_quantities(c, 80.0, ["hs_m"])) == ["hs_m"]
    model = load_failure_model("dickson2018")
    assert model.weather_fields == {QUANTITY_FIELDS[q][0] for q in model.quantities} == {"hs_m", "wave_dir_deg"}


def test_a_model_name_too_long_for_the_file_system_is_not_found_not_an_oserror() -> None:
    # 5000 characters: Path.exists() raised OSError (ENAMETOOLONG), which the CLI reported as an internal error
    # (exit 3). Now the usual "not found", with the name cut to a short repr.
    with pytest.raises(FailureModelError, match=r"failure model 'xxx+\.\.\. not found") as info:
        load_failure_model("x" * 5000)
    assert len(str(info.value)) < 200


@pytest.mark.parametrize("name", [None, 5, ["dickson2018"]])
def test_a_model_given_by_something_else_than_a_name_or_path_is_refused(name: object) -> None:
    # None and 5 raised TypeError from os.fspath.
    with pytest.raises(FailureModelError, match="must be given by name or path"):
        load_failure_model(name)  # type: ignore[arg-type]


def test_a_very_long_model_path_is_cut_in_the_message() -> None:
    # A 5000-character .toml path was echoed whole (a 5000-character error line); now cut in the middle.
    with pytest.raises(FailureModelError) as info:
        load_failure_model("x" * 5000 + ".toml")
    msg = str(info.value)
    assert len(msg) < 250 and "..." in msg and msg.startswith("xxx")
