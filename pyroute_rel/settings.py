"""Settings: which engine does each job, and every environment variable pyroute_rel reads, in one place.

The engines are interchangeable: each pair gives the same numbers (the test suite pins every fast engine to its
reference twin), so a setting changes speed and memory, never a route. Defaults are the fast engines; the reference
ones stay for comparisons, tests and benchmarks.

Use :func:`settings_context` as a context manager (scikit-learn's ``config_context`` is the model) or
:func:`set_settings` for the rest of the current context; :func:`get_settings` reads them:

>>> from pyroute_rel.settings import get_settings, settings_context
>>> get_settings().lazy_pieces
True
>>> with settings_context(lazy_pieces=False):
...     get_settings().lazy_pieces
False
>>> get_settings().lazy_pieces
True

Settings live in a :class:`contextvars.ContextVar`: a thread or asyncio task sees the settings of the context it
runs in; the threads pyroute_rel starts itself (:func:`pyroute_rel.resources.thread_map`) run in a copy of the
caller's context, and the worker processes of sweeps and ensembles are started with the caller's settings. Dask
workers run with the defaults.

Environment variables (read when the job that needs them runs):

``PYROUTE_REL_THREADS``
    Threads for the hot spots that release the GIL (:func:`pyroute_rel.resources.default_workers`; default: the CPUs
    this process may use; ``1`` turns threads off). Worker processes set it to ``1``.
``PYROUTE_REL_MAX_MEMORY``
    The memory budget of one route (:mod:`pyroute_rel.resources`; the CLI's ``--max-memory`` sets it for a run).
``PYROUTE_REL_KEEP``
    ``0`` (or ``false``, ``no``, ``off``): the process keeps nothing between calls (:mod:`pyroute_rel.store`: files,
    parsed models, grids and tables are read and built afresh each time); default: kept, by content.
``PYROUTE_REL_CACHE_DIR``
    Where sweeps keep their on-disk cache (:mod:`pyroute_rel.diskcache`; default: ``$XDG_CACHE_HOME/pyroute_rel`` or
    ``~/.cache/pyroute_rel``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

from pyroute_rel.errors import ScenarioError

__all__ = ["Settings", "get_settings", "set_settings", "settings_context"]


@dataclass(frozen=True)
class Settings:
    """The engines pyroute_rel uses (each True: the fast engine; False: its reference twin, the same numbers).

    Attributes
    ----------
    compiled_rank_step : The forward DP hands a rank to compiled code where it can (steady weather with wind only,
        or a failure model on uniform weather with patches: :mod:`pyroute_rel._kernels.dp`); False: the numpy path.
    compiled_march : Time-varying gridded weather with wind only is sailed by the compiled march
        (:mod:`pyroute_rel._kernels.march`); False: the numpy march (:mod:`pyroute_rel.boat.march`).
    lazy_pieces : The DP judges on the pieces they cross (:mod:`pyroute_rel.reliability.crossings`) only the arcs it
        would pick (:func:`pyroute_rel.routing.solve._lazy_pieces`); False: every arc the cost function would judge,
        eagerly.
    locate_cache : The cost kernel keeps each arc geometry's sample points located on the weather grids of
        time-varying sources and reuses them for every source on the same grid; False: located every time.
    fused_sampling : :meth:`~pyroute_rel.weather.GriddedWeather.sample_at` turns the wind's (u, v) and the wave
        direction's (sin, cos) into speed and direction in the interpolation loop; False: after it, in numpy.
    """

    compiled_rank_step: bool = True
    compiled_march: bool = True
    lazy_pieces: bool = True
    locate_cache: bool = True
    fused_sampling: bool = True

    def replace(self, **changes: bool) -> Settings:
        """These settings with ``changes`` (names of :class:`Settings`' fields, booleans), checked: an unknown name
        or a value that is not a bool is a ``TypeError`` naming it."""
        names = {f.name for f in dataclasses.fields(self)}
        for name, value in changes.items():
            if name not in names:
                raise ScenarioError(f"settings: unknown setting {name!r} (expected one of {', '.join(sorted(names))})")
            if not isinstance(value, bool):
                raise ScenarioError(f"settings: {name} must be True or False (got {value!r})")
        return dataclasses.replace(self, **changes)


_CURRENT: ContextVar[Settings] = ContextVar("pyroute_rel_settings", default=Settings())  # noqa: B039 (frozen)


def get_settings() -> Settings:
    """The settings in force in the current context."""
    return _CURRENT.get()


def set_settings(settings_: Settings | None = None, /, **changes: bool) -> Settings:
    """Set the settings for the rest of the current context (a :class:`Settings`, or the current ones with
    ``changes``); returns them."""
    new = (settings_ or get_settings()).replace(**changes)
    _CURRENT.set(new)
    return new


def settings_context(**changes: bool) -> AbstractContextManager[Settings]:
    """The current settings with ``changes`` within a ``with`` block (restored on leaving it, whatever happens); a
    bad name or value is a :class:`~pyroute_rel.errors.ScenarioError` at the call.

    >>> with settings_context(compiled_march=False) as s:
    ...     s.compiled_march, s.lazy_pieces
    (False, True)
    """
    return _in_force(get_settings().replace(**changes))


@contextmanager
def _in_force(settings_: Settings) -> Iterator[Settings]:
    token = _CURRENT.set(settings_)
    try:
        yield settings_
    finally:
        _CURRENT.reset(token)
