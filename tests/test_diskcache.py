"""Tests of pyroute_rel.diskcache: the folder's choice, atomic writes, pruning, and unwritable folders."""

from __future__ import annotations

import os
from pathlib import Path

from pyroute_rel import diskcache


def test_folder_follows_the_environment(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv(diskcache.ENV, str(tmp_path / "a"))
    assert diskcache.cache_dir() == tmp_path / "a"
    monkeypatch.delenv(diskcache.ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert diskcache.cache_dir() == tmp_path / "xdg" / "pyroute_rel"


def test_entries_are_written_whole_and_pruned_oldest_first(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv(diskcache.ENV, str(tmp_path))
    for i in range(5):
        diskcache.write(f"kind-{i}.bin", f"entry {i}".encode(), keep=3)
        os.utime(tmp_path / f"kind-{i}.bin", ns=(10**18 + i * 10**9,) * 2)  # distinct ages, oldest first
    diskcache.write("other-0.bin", lambda fh: fh.write(b"x"), keep=3)  # another kind is not pruned with it
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["kind-2.bin", "kind-3.bin", "kind-4.bin", "other-0.bin"]  # no temporary files left
    assert diskcache.read("kind-4.bin") == b"entry 4"
    assert diskcache.read("kind-0.bin") is None


def test_an_unwritable_folder_is_skipped(tmp_path: Path, monkeypatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(diskcache.ENV, str(blocker / "cache"))
    diskcache.write("kind-0.bin", b"data")  # no error
    assert diskcache.read("kind-0.bin") is None


def test_keys_separate_their_parts() -> None:
    assert diskcache.key([b"ab", b"c"]) != diskcache.key([b"a", b"bc"])
    assert diskcache.key([b"ab", b"c"]) == diskcache.key([b"ab", b"c"])
    assert len(diskcache.key([b""])) == 32
