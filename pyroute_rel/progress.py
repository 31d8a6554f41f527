"""Progress bars for long jobs: a tqdm bar on a terminal, nothing when quiet or when stderr is not a TTY."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from pyroute_rel.errors import ScenarioError, brief

__all__ = ["progress_bar"]


class _NullBar:
    """A bar that shows nothing (quiet, or not on a terminal)."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(total: int | None, *, enabled: bool, desc: str = "routing", unit: str = "rank") -> Any:
    """A tqdm bar of ``total`` steps (None: not known) on stderr when ``enabled`` and stderr is a terminal, else one
    that shows nothing; both have ``update(n)`` and ``close()``. ``enabled`` other than True or False (a caller's
    ``progress`` argument) is a :class:`~pyroute_rel.errors.ScenarioError`."""
    if not isinstance(enabled, bool | np.bool_):
        raise ScenarioError(f"progress must be True or False (got {brief(enabled)})")
    if not enabled or not sys.stderr.isatty():
        return _NullBar()
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, leave=False, file=sys.stderr)
