"""One owner of kept state (pyroute_rel.store): shelves bounded and keyed by content, a store's lifetime, the switch,
and each kept input changed between calls giving the fresh answer (in this process and in worker processes).

Other tests change kept inputs too: zones on a reused grid (test_avoid_routing), a scenario or weather file under
``route_member`` (test_ensemble), a weather file kept open (test_ensemble_reading), a failure network
(test_failure), a failure model's judgements kept for the compiled DP step (test_dp_judged)."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from test_evaluate import write_ensemble_scenario

import pyroute_rel as pr
from pyroute_rel.batch import sweep
from pyroute_rel.errors import ScenarioError
from pyroute_rel.reliability import failure
from pyroute_rel.resources import thread_map
from pyroute_rel.store import Shelf, current_store, file_stamps, kept, kept_call
from pyroute_rel.weather.io import readers

ROOT = Path(__file__).resolve().parents[1]


def touched(p: Path) -> None:
    """A later modification time, whatever the file system's clock resolution."""
    st = p.stat()
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 2_000_000_000))


# --- the store itself -----------------------------------------------------------------------------------------------


def test_a_shelf_drops_the_least_recently_used_beyond_its_bounds_and_closes_what_it_drops() -> None:
    dropped: list[str] = []
    shelf = Shelf(limit=2, max_bytes=10, nbytes=len, on_drop=dropped.append)
    shelf.put("a", "aaa")
    shelf.put("b", "bbb")
    assert shelf.get("a") == "aaa"  # now the most recent
    shelf.put("c", "ccc")
    assert shelf.keys() == ["a", "c"] and dropped == ["bbb"]
    shelf.put("d", "dddddddd")  # 3 + 3 + 8 bytes > 10: the oldest two go
    assert shelf.keys() == ["d"] and dropped == ["bbb", "aaa", "ccc"]
    shelf.put("d", "e")  # replaced: the old value is dropped
    assert dropped[-1] == "dddddddd" and shelf.get("d") == "e"
    assert shelf.pop("d") == "e" and dropped[-1] == "dddddddd"  # popped: taken over, not dropped
    with pytest.raises(ZeroDivisionError):
        shelf.get_or_make("x", lambda: 1 / 0)
    assert "x" not in shelf  # a failed make keeps nothing
    shelf.put("y", "y")
    assert shelf.put("y", "made meanwhile", replace=False) == "y" and dropped[-1] == "made meanwhile"
    shelf.clear()
    assert len(shelf) == 0 and dropped[-1] == "y"


def test_a_held_key_finds_its_own_object_only() -> None:
    """Kept by the object itself (area indexes by geometry): the same object finds its entry, an equal copy does not,
    and the object is never hashed."""
    import shapely

    from pyroute_rel.obstacles import areas
    from pyroute_rel.store import Held

    ring = shapely.Point(0.0, 0.0).buffer(1.0)
    with kept() as store:
        first = areas.area_index(ring)
        assert areas.area_index(ring) is first
        assert areas.area_index(shapely.from_wkb(shapely.to_wkb(ring))) is not first  # equal, but another object
        assert len(store.shelf("obstacles.indexes")) == 2
    assert Held(ring) == Held(ring) and Held(ring) != Held(shapely.from_wkb(shapely.to_wkb(ring)))


def test_a_kept_block_has_its_own_store_emptied_at_its_end() -> None:
    outer = current_store()
    closed: list[int] = []
    with kept() as store:
        assert current_store() is store and store is not outer
        store.shelf("files", on_drop=closed.append).put("k", 1)
        with kept(False) as nothing:
            assert nothing.shelf("files").put("k", 2) == 2 and len(nothing.shelf("files")) == 0
        assert current_store() is store and store.shelf("files").get("k") == 1
    assert closed == [1] and current_store() is outer and "files" not in outer.sizes()
    with pytest.raises(ScenarioError, match="keep must be True or False"):
        with kept("no"):  # type: ignore[arg-type]
            pass


def test_threads_share_the_callers_store_and_other_threads_have_the_process_store() -> None:
    with kept() as store:
        assert thread_map(lambda _: current_store() is store, range(4), 2) == [True] * 4
        seen: list[bool] = []
        t = threading.Thread(target=lambda: seen.append(current_store() is store))  # a thread we did not start
        t.start()
        t.join()
        assert seen == [False]


def test_kept_call_keeps_by_arguments_in_the_current_store() -> None:
    calls: list[int] = []

    @kept_call("test.square", limit=4)
    def square(x: int) -> int:
        calls.append(x)
        return x * x

    with kept():
        assert square(3) == 9 and square(3) == 9 and calls == [3]
        square.cache_clear()  # type: ignore[attr-defined]
        assert square(3) == 9 and calls == [3, 3]
    with kept():
        assert square(3) == 9 and calls == [3, 3, 3]  # another store: made again


def test_the_environment_switch_makes_the_process_keep_nothing() -> None:
    code = (
        "from pyroute_rel.store import current_store\n"
        "s = current_store(); s.shelf('x').put(1, 2)\n"
        "print(s.keep, len(s.shelf('x')))\n"
    )
    env = {**os.environ, "PYROUTE_REL_KEEP": "0"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "0"]


@pytest.mark.slow
def test_nothing_is_kept_outside_the_store() -> None:
    """No module-level or class-level mutable container, lru_cache/cache, weak dictionary or ``global`` statement in
    the package outside pyroute_rel/store.py, and no ``id(...)`` used as a key (the habits of issue 33)."""
    mutable = (ast.Dict, ast.List, ast.Set, ast.DictComp, ast.ListComp, ast.SetComp)
    makers = {"dict", "list", "set", "OrderedDict", "defaultdict", "WeakKeyDictionary", "WeakValueDictionary"}
    found = []
    for path in sorted((ROOT / "pyroute_rel").rglob("*.py")):
        if path.name == "store.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        where = path.relative_to(ROOT)
        for node in tree.body:  # module level
            value = node.value if isinstance(node, ast.Assign | ast.AnnAssign) else None
            names = [t.id for t in getattr(node, "targets", [getattr(node, "target", None)]) if isinstance(t, ast.Name)]
            if value is None or names == ["__all__"] or all(n.isupper() or n.lstrip("_").isupper() for n in names):
                # (UPPER_CASE tables are constants: checked below not to be written to)
                continue
            call = value.func.attr if isinstance(value, ast.Call) and isinstance(value.func, ast.Attribute) else None
            call = value.func.id if isinstance(value, ast.Call) and isinstance(value.func, ast.Name) else call
            if isinstance(value, mutable) or call in makers:
                found.append(f"{where}:{node.lineno} {names}")
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):  # class-level containers: shared
            for node in cls.body:
                value = node.value if isinstance(node, ast.Assign | ast.AnnAssign) else None
                call = value.func if isinstance(value, ast.Call) else None
                maker = (
                    call.id if isinstance(call, ast.Name) else call.attr if isinstance(call, ast.Attribute) else None
                )
                if isinstance(value, mutable) or maker in makers:
                    found.append(f"{where}:{node.lineno} {cls.name} class attribute")
        caches = {"lru_cache", "cache", "WeakKeyDictionary", "WeakValueDictionary"}
        for node in ast.walk(tree):
            if isinstance(node, ast.Global):
                found.append(f"{where}:{node.lineno} global {node.names}")
            if isinstance(node, ast.ImportFrom) and node.module in {"functools", "weakref"}:
                found += [
                    f"{where}:{node.lineno} from {node.module} import {a.name}" for a in node.names if a.name in caches
                ]
            if isinstance(node, ast.Attribute) and node.attr in caches:
                if isinstance(node.value, ast.Name) and node.value.id in {"functools", "weakref"}:
                    if not (path.name == "gridded.py" and node.attr == "cache"):  # (_load_kernels: loads code once)
                        found.append(f"{where}:{node.lineno} {node.value.id}.{node.attr}")
            if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Call):
                f = node.slice.func
                if isinstance(f, ast.Name) and f.id == "id":
                    found.append(f"{where}:{node.lineno} [id(...)]")
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in {"get", "pop"}:
                if node.args and isinstance(node.args[0], ast.Call) and getattr(node.args[0].func, "id", "") == "id":
                    found.append(f"{where}:{node.lineno} .{node.func.attr}(id(...))")
    assert not found, found


@pytest.mark.slow
def test_upper_case_tables_are_never_written_to() -> None:
    """Module-level UPPER_CASE names are constants: no subscript assignment, ``.update``, ``.append``, ``.clear``,
    ``.pop`` or ``.setdefault`` on them anywhere in the package."""
    writes = {"update", "append", "clear", "pop", "setdefault", "extend", "add", "popitem", "insert", "remove"}
    writes |= {"discard", "__setitem__", "__delitem__", "move_to_end"}
    found = []
    for path in sorted((ROOT / "pyroute_rel").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        upper = {
            t.id
            for node in tree.body
            if isinstance(node, ast.Assign | ast.AnnAssign)
            for t in getattr(node, "targets", [getattr(node, "target", None)])
            if isinstance(t, ast.Name) and t.id.lstrip("_").isupper() and t.id not in {"T", "R"}
        }
        for node in ast.walk(tree):
            target = None
            if isinstance(node, ast.Assign | ast.AugAssign | ast.Delete):
                for t in getattr(node, "targets", [getattr(node, "target", None)]):
                    if isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name):
                        target = t.value.id
                    elif isinstance(node, ast.AugAssign) and isinstance(t, ast.Name):
                        target = t.id  # (X |= ..., X += ...)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in writes:
                if isinstance(node.func.value, ast.Name):
                    target = node.func.value.id if node.func.attr in writes else None
            # (WEATHER_KINDS is the registry register_weather_kind writes to: configuration, not kept state)
            if target in upper and target != "WEATHER_KINDS":
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {target}")
    assert not found, found


# --- each kept input changed between calls: the fresh answer ----------------------------------------------------------


def test_an_edited_shipped_tables_file_is_read_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The shipped compiled tables are kept by the file's stamp: a replaced file is read again."""
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / failure._SHIPPED_TABLES).write_text('{"models": {}}', encoding="utf-8")
    monkeypatch.setattr(failure, "_shipped", lambda: folder)
    with kept():
        assert failure._shipped_tables() == {}
        real = (ROOT / "failure_models" / failure._SHIPPED_TABLES).read_text(encoding="utf-8")
        (folder / failure._SHIPPED_TABLES).write_text(real, encoding="utf-8")
        touched(folder / failure._SHIPPED_TABLES)
        keys = {entry["key"] for entry in json.loads(real)["models"].values()}
        assert set(failure._shipped_tables()) == keys and len(keys) >= 2


@pytest.mark.slow
def test_an_edited_failure_model_gives_its_own_table(tmp_path: Path) -> None:
    """A model file edited between two loads (one store): the second load judges with the edited file's table."""
    src = ROOT / "failure_models"
    for name in ("dickson2018.toml", "dickson2018.bif"):
        (tmp_path / name).write_bytes((src / name).read_bytes())
    with kept():
        first = failure.load_failure_model(tmp_path / "dickson2018.toml")
        bif = (tmp_path / "dickson2018.bif").read_text()
        assert "0.1, 0.9;" in bif
        (tmp_path / "dickson2018.bif").write_text(bif.replace("0.1, 0.9;", "0.3, 0.7;"))
        second = failure.load_failure_model(tmp_path / "dickson2018.toml")
    assert not np.array_equal(first.p_flat, second.p_flat)
    with kept():  # read in a store of its own, nothing kept: the same table
        np.testing.assert_array_equal(second.p_flat, failure.load_failure_model(tmp_path / "dickson2018.toml").p_flat)


def test_an_edited_polar_file_is_sailed_with_its_new_speeds(tmp_path: Path) -> None:
    """Polars are read afresh and their kernel tables kept by each Polar object: an edited file gives new times."""
    pol = tmp_path / "boat.pol"
    pol.write_bytes((ROOT / "examples" / "maribot_vane.pol").read_bytes())
    table = {
        "route": {"start": [-12.0, 45.0], "finish": [-14.0, 44.0], "departure": "2018-06-01T00:00:00Z"},
        "grid": {"n_ranks": 8},
        "weather": {"kind": "uniform", "tws_kn": 12.0, "twd_deg": 0.0},
        "boat": {"polar": str(pol)},
        "avoid": {"land": False},
    }
    before = pr.scenario_from_mapping(table).route().voyage_time_h
    lines = pol.read_text().splitlines()
    head, rows = lines[0], lines[1:]
    doubled = [r.split()[0] + "\t" + "\t".join(f"{2 * float(v):g}" for v in r.split()[1:]) for r in rows if r.strip()]
    pol.write_text("\n".join([head, *doubled]) + "\n")
    after = pr.scenario_from_mapping(table).route().voyage_time_h
    assert after == pytest.approx(before / 2, rel=1e-9)


def test_sweep_keys_follow_an_edited_referenced_file(tmp_path: Path) -> None:
    """The sweep's file digests are kept by path, size and time: an edited file gets a new digest."""
    f = tmp_path / "zones.geojson"
    f.write_text('{"type": "FeatureCollection", "features": []}')
    one = sweep._file_digest(f)
    assert sweep._file_digest(f) == one
    f.write_text('{"type": "FeatureCollection", "features": [] }')
    touched(f)
    assert sweep._file_digest(f) != one


@pytest.mark.slow
def test_an_ensemble_in_worker_processes_reads_edited_files_again(tmp_path: Path) -> None:
    """Two ensemble runs in worker processes, the scenario's finish moved between them: the second routes to the
    new finish, as the inline engine does. It guards the workers' side (each call's workers start with nothing kept,
    :func:`pyroute_rel.analysis.ensemble._begin`); within one process, the stamps that make a kept scenario fresh are
    checked by test_ensemble's ``test_route_member_reads_an_edited_scenario_or_weather_file_again``."""
    path = write_ensemble_scenario(tmp_path, n_members=2)
    first = pr.route_ensemble(path, engine="processes", workers=2)
    assert all(r.lon_deg[-1] == pytest.approx(-22.0) for r in first.routes)
    path.write_text(path.read_text().replace("finish = [-22.0, 25.0]", "finish = [-18.0, 25.0]"))
    touched(path)
    second = pr.route_ensemble(path, engine="processes", workers=2)
    inline = pr.route_ensemble(path, engine="inline")
    assert all(r.lon_deg[-1] == pytest.approx(-18.0) for r in second.routes)
    assert [r.voyage_time_h for r in second.routes] == [r.voyage_time_h for r in inline.routes]


def test_files_opened_in_a_kept_block_are_closed_at_its_end(tmp_path: Path) -> None:
    path = write_ensemble_scenario(tmp_path, n_members=2)
    nc = tmp_path / "ens.nc"
    with kept():
        readers.keep_files_open(True)
        readers.open_weather(nc, member=1)
        files = readers._files()
        assert len(files.kept) == 1 and files.raw
        assert files.kept.keys() == {file_stamps([nc])[0]}
    assert files.kept == {} and files.raw == []
    assert path.is_file()


@pytest.mark.slow
def test_a_pool_in_use_is_never_shut_down_under_a_call() -> None:
    """Calls asking for more threads replace the store's pool, and another thread empties the store, while calls
    run in the pool: every call finishes (a replaced pool is shut down by its last user)."""
    errors: list[str] = []
    done = threading.Event()

    def user(workers: int) -> None:
        for _ in range(25):
            try:
                assert thread_map(lambda x: x * x, range(16), workers) == [x * x for x in range(16)]
            except Exception as exc:  # noqa: BLE001 - reported below
                errors.append(f"{workers}: {type(exc).__name__}: {exc}")
                return

    def clearer() -> None:
        while not done.is_set():
            pr.clear_kept()

    with kept():
        threads = [threading.Thread(target=user, args=(w,)) for w in (2, 3, 4)]
        emptier = threading.Thread(target=clearer)
        for t in [*threads, emptier]:
            t.start()
        for t in threads:
            t.join()
        done.set()
        emptier.join()
    assert not errors, errors[:3]
