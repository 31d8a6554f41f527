"""Tests of pyroute_rel.diskcache: the folder's choice, atomic writes, pruning only its own entries, unwritable and
untrusted folders, and entries that do not verify (issue 17: a cache no one else can poison)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from pyroute_rel import diskcache


def _name(kind: str, i: int, ext: str = "bin") -> str:
    return f"{kind}-{diskcache.key([str(i).encode()])}.{ext}"


@pytest.fixture
def cache(tmp_path: Path, monkeypatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv(diskcache.ENV, str(folder))
    return folder


def test_folder_follows_the_environment(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv(diskcache.ENV, str(tmp_path / "a"))
    assert diskcache.cache_dir() == tmp_path / "a"
    assert diskcache.entries_dir() == tmp_path / "a" / diskcache.ENTRIES
    monkeypatch.delenv(diskcache.ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert diskcache.cache_dir() == tmp_path / "xdg" / "pyroute_rel"


def test_entries_are_written_whole_and_pruned_oldest_first(cache: Path) -> None:
    names = [_name("kind", i) for i in range(5)]
    for i, name in enumerate(names):
        diskcache.write(name, f"entry {i}".encode(), keep=3)
        os.utime(cache / diskcache.ENTRIES / name, ns=(10**18 + i * 10**9,) * 2)  # distinct ages, oldest first
    other = _name("other", 0)
    diskcache.write(other, lambda fh: fh.write(b"x"), keep=3)  # another kind is not pruned with it
    left = sorted(p.name for p in (cache / diskcache.ENTRIES).iterdir() if not p.name.startswith("."))
    assert left == sorted([*names[2:], other])  # no temporary files left
    assert diskcache.read(names[4]) == b"entry 4"
    assert diskcache.read(other) == b"x"
    assert diskcache.read(names[0]) is None


def test_pruning_never_touches_files_the_cache_did_not_write(cache: Path) -> None:
    """A user's own files named like entries, in the folder given as the cache folder, survive (issue 17: pruning
    deleted 8 of a user's files named land-*)."""
    cache.mkdir(mode=0o700)
    mine = [cache / f"land-{i}.wkb" for i in range(8)]
    for p in mine:
        p.write_bytes(b"user data")
    odd = cache / diskcache.ENTRIES / "land-notahash.wkb"
    for i in range(5):
        diskcache.write(_name("land", i, "wkb"), b"entry", keep=1)
        if i == 0:
            odd.write_bytes(b"also the user's")
    assert all(p.read_bytes() == b"user data" for p in mine)
    assert odd.read_bytes() == b"also the user's"


def test_an_unwritable_folder_is_skipped(tmp_path: Path, monkeypatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(diskcache.ENV, str(blocker / "cache"))
    diskcache.write(_name("kind", 0), b"data")  # no error
    assert diskcache.read(_name("kind", 0)) is None


def test_keys_separate_their_parts() -> None:
    assert diskcache.key([b"ab", b"c"]) != diskcache.key([b"a", b"bc"])
    assert diskcache.key([b"ab", b"c"]) == diskcache.key([b"ab", b"c"])
    assert len(diskcache.key([b""])) == 32


def test_keys_follow_the_content_of_a_source_not_its_date(tmp_path: Path) -> None:
    src = tmp_path / "coast.dat"
    src.write_bytes(b"coast v1")
    first = diskcache.stamp(src)
    os.utime(src, ns=(10**18, 10**18))
    assert diskcache.stamp(src) == first  # touched, same content: same key
    src.write_bytes(b"coast v2")
    os.utime(src, ns=(10**18 + 10**9,) * 2)
    assert diskcache.stamp(src) != first


def test_names_the_cache_does_not_write_are_refused(cache: Path) -> None:
    for bad in ("../escape-0.bin", "kind.bin", "kind-123.bin", "Kind-" + "0" * 32 + ".bin"):
        with pytest.raises(ValueError, match="kind-<32 hex digits>"):
            diskcache.write(bad, b"x")


@pytest.mark.parametrize(
    "tamper",
    ["zeros_same_size", "copied_from_another_name", "truncated", "payload_edited", "no_header", "other_key"],
)
def test_an_entry_that_does_not_verify_is_never_used(cache: Path, tamper: str) -> None:
    """Each kind of wrong entry, well formed or not, reads as absent (and the caller makes it again)."""
    name, other = _name("failure", 1, "npz"), _name("failure", 2, "npz")
    table = np.linspace(0.0, 1.0, 16)

    def save(fh) -> None:
        np.savez(fh, table=table)

    diskcache.write(name, save)
    diskcache.write(other, lambda fh: np.savez(fh, table=np.zeros(16)))
    path = cache / diskcache.ENTRIES / name
    good = path.read_bytes()
    assert np.array_equal(diskcache.load(name, lambda b: _table(b)), table)
    head = len(good) - len(diskcache.read(name))
    if tamper == "zeros_same_size":  # a well-formed table of zeros, with the old digest
        import io

        buf = io.BytesIO()
        np.savez(buf, table=np.zeros(16))
        path.write_bytes(good[:head] + buf.getvalue())
    elif tamper == "copied_from_another_name":  # a genuine entry of another key, renamed
        path.write_bytes((cache / diskcache.ENTRIES / other).read_bytes())
    elif tamper == "truncated":
        path.write_bytes(good[: len(good) // 2])
    elif tamper == "payload_edited":
        path.write_bytes(good[:-1] + bytes([good[-1] ^ 1]))
    elif tamper == "no_header":
        path.write_bytes(good[head:])
    elif tamper == "other_key":  # signed with another user's key
        (cache / diskcache.ENTRIES / ".key").chmod(0o600)
        (cache / diskcache.ENTRIES / ".key").write_bytes(b"k" * 32)
    assert diskcache.read(name) is None
    assert diskcache.load(name, lambda b: _table(b)) is None


def _table(data: bytes) -> np.ndarray:
    import io

    return np.load(io.BytesIO(data))["table"]


def test_a_folder_others_may_write_is_not_used(cache: Path) -> None:
    cache.mkdir()
    cache.chmod(0o777)  # no sticky bit: anyone may replace what is in it
    with pytest.warns(diskcache.CacheWarning, match="other users may write in it"):
        diskcache.write(_name("kind", 7), b"data")
    assert not (cache / diskcache.ENTRIES).exists()
    assert diskcache.read(_name("kind", 7)) is None


def test_a_shared_sticky_folder_is_used_through_the_private_subfolder(cache: Path) -> None:
    cache.mkdir()
    cache.chmod(0o1777)  # like /tmp
    diskcache.write(_name("kind", 8), b"data")
    assert diskcache.read(_name("kind", 8)) == b"data"
    sub = (cache / diskcache.ENTRIES).stat()
    assert stat.S_IMODE(sub.st_mode) & 0o077 == 0
    assert stat.S_IMODE((cache / diskcache.ENTRIES / ".key").stat().st_mode) == 0o600


def test_a_private_subfolder_opened_to_others_is_not_used(cache: Path) -> None:
    diskcache.write(_name("kind", 9), b"data")
    (cache / diskcache.ENTRIES).chmod(0o777)
    with pytest.warns(diskcache.CacheWarning):
        assert diskcache.read(_name("kind", 9)) is None


def test_a_cache_folder_under_an_unknown_home_is_not_used(monkeypatch) -> None:
    monkeypatch.setenv(diskcache.ENV, "~nosuchuser_pyroute/x")
    with pytest.warns(diskcache.CacheWarning, match="cannot be resolved"):
        diskcache.write(_name("kind", 10), b"data")
    assert diskcache.read(_name("kind", 10)) is None
