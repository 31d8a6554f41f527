"""Test-session settings shared by the tests and the doctests of every package folder."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True, scope="session")
def _private_disk_cache(tmp_path_factory: pytest.TempPathFactory):
    """Keep the on-disk cache (pyroute_rel.diskcache) of a test run out of the user's cache folder."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
        yield
