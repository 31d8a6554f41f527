"""How an ensemble is read (issue 19's benchmark): a process routing many members of one file opens it once and
reads each member once, and the result does not depend on the reading path or the engine: the JSON of a small
ensemble is the same byte for byte with files kept open or opened for every member (the reading before session 10),
with the members sailed together or one by one, in this process or in two worker processes."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from test_evaluate import write_ensemble_scenario

from pyroute_rel.analysis import evaluate
from pyroute_rel.analysis.ensemble import route_ensemble
from pyroute_rel.analysis.members import member_scenario
from pyroute_rel.weather.io import readers


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_ensemble_scenario(tmp_path_factory.mktemp("ens"), n_members=5)


def _json(path: Path, **options: object) -> str:
    return json.dumps(route_ensemble(path, risk="cvar:0.75", **options).summary(), sort_keys=True)


@pytest.mark.slow
def test_a_process_opens_the_file_once_and_reads_each_member_once(small: Path, monkeypatch: pytest.MonkeyPatch):
    """Inline (every member routed and sailed in this process): the file is opened once to count the members, once
    for the members and once for the ensemble mean (not once per member), and each member's variables are read
    once (a hook counting reads: routing and sailing share them). Files are closed at the end of the call."""
    reads: Counter[tuple[object, str]] = Counter()
    extract = readers._extract

    def counting(da, name, source, var, box, window, member, *args, **kwargs):
        reads[(member, var)] += 1
        return extract(da, name, source, var, box, window, member, *args, **kwargs)

    monkeypatch.setattr(readers, "_extract", counting)
    readers.files_opened(reset=True)
    res = route_ensemble(small, engine="inline")
    opened = readers.files_opened(reset=True)
    assert opened == {str((small.parent / "ens.nc").resolve()): 3}
    variables = {"u10", "v10", "swh", "mwd"}
    assert set(reads) == {(m, v) for m in [*range(5), "mean"] for v in variables}
    assert set(reads.values()) == {1}
    assert (
        res.members == tuple(range(5)) and readers._files().kept == {} and readers._files().raw == []
    )  # nothing left open


@pytest.mark.slow
def test_a_member_read_from_the_kept_file_is_the_member_read_alone(small: Path):
    """The kept file is read without dask: the same numbers as opening the file for that member (with dask)."""
    alone = [member_scenario(small, k).weather for k in range(5)]
    readers.keep_files_open(True)
    try:
        kept = [member_scenario(small, k).weather for k in (4, 0, 2, 1, 3)]
    finally:
        readers.keep_files_open(False)
    for k, w in zip((4, 0, 2, 1, 3), kept, strict=True):
        a, b = (x._blocks for x in (alone[k], w))  # the stored data, bit for bit
        assert len(a) == len(b) and all(
            np.array_equal(x.flat, y.flat, equal_nan=True) for x, y in zip(a, b, strict=True)
        )
        for name, f in alone[k].field_info.items():  # the same grids and times
            g = w.field_info[name]
            assert all(np.array_equal(getattr(f, c), getattr(g, c)) for c in ("lon", "lat", "time")), name
    assert not np.array_equal(kept[0]._blocks[0].flat, kept[1]._blocks[0].flat, equal_nan=True)  # members differ


@pytest.mark.slow
def test_the_json_does_not_depend_on_the_reading_path_or_the_engine(small: Path, monkeypatch: pytest.MonkeyPatch):
    fast = _json(small, engine="inline")
    with monkeypatch.context() as m:  # files opened for every member, members sailed one by one: the old paths
        m.setattr(readers, "keep_files_open", lambda keep: None)
        m.setattr(evaluate, "_member_stack", lambda problems: None)
        old = _json(small, engine="inline")
    assert fast == old
    assert _json(small, engine="processes", workers=2) == fast
    assert json.loads(fast)["chosen"]["name"] and np.isfinite(json.loads(fast)["members"][0]["voyage_time_h"])


def test_a_kept_file_changed_since_is_opened_again(small: Path, tmp_path: Path):
    """A file rewritten between two members is read anew (the new values), the old handle closed."""
    import os
    import shutil

    path = tmp_path / "ens.nc"
    shutil.copy(small.parent / "ens.nc", path)
    readers.keep_files_open(True)
    try:
        readers.files_opened(reset=True)
        first = readers.open_weather(path, member=1)
        readers.open_weather(path, member=2)
        assert readers.files_opened() == {str(path.resolve()): 1}
        shutil.copy(small.parent / "ens.nc", tmp_path / "other.nc")
        os.replace(tmp_path / "other.nc", path)  # the same bytes, a new file (new modification time)
        os.utime(path, ns=(1, 1))
        again = readers.open_weather(path, member=1)
        assert readers.files_opened(reset=True) == {str(path.resolve()): 2} and len(readers._files().kept) == 1
        assert np.array_equal(first._blocks[0].flat, again._blocks[0].flat, equal_nan=True)
    finally:
        readers.keep_files_open(False)
    assert readers._files().kept == {}
