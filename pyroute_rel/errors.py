"""Domain errors of pyroute_rel, all in one place.

Every error a user can cause (a bad scenario, polar, weather file or failure model) is one of these. Each
subclasses a built-in so callers may catch ``ValueError`` as usual; the CLI turns any :class:`PyrouteError`
into one line on stderr and exit code 2.
"""

from __future__ import annotations

__all__ = [
    "show",
    "brief",
    "PyrouteError",
    "ScenarioError",
    "PolarError",
    "WeatherError",
    "WeatherCoverageError",
    "FailureModelError",
    "GridError",
    "ConvergenceError",
    "NoFeasibleRouteError",
    "OutputError",
    "CoordinateError",
    "MemoryBudgetError",
    "TrackError",
    "PyrouteWarning",
    "PolarWarning",
    "CacheWarning",
    "WeatherWarning",
]


def show(value: object) -> str:
    """A user-given string (file name, key) as it may appear in a one-line message: control characters escaped.

    >>> show("a\\nb.pol")
    'a\\\\nb.pol'
    """
    return repr(str(value))[1:-1]


def brief(value: object, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, for one-line messages about user values."""
    r = repr(value)
    return r if len(r) <= limit else r[: limit - 3] + "..."


class PyrouteError(Exception):
    """Base class of every error pyroute_rel raises on purpose."""


class ScenarioError(PyrouteError, ValueError):
    """A scenario (TOML file or dict) is malformed: unknown key, wrong type, value out of range."""


class PolarError(PyrouteError, ValueError):
    """A polar table is malformed: ragged rows, non-increasing axes, negative or non-numeric speeds."""


class WeatherError(PyrouteError, ValueError):
    """A weather source is unusable: unreadable file, missing variable, unknown units, NaN-only field."""


class WeatherCoverageError(WeatherError):
    """A route or departure lies outside the time or space covered by a weather source."""


class FailureModelError(PyrouteError, ValueError):
    """A failure model is malformed: missing CPT, probabilities not summing to 1, unknown quantity."""


class GridError(PyrouteError, ValueError):
    """A grid cannot be built from the given settings (too few nodes, zero spacing, start = finish)."""


class ConvergenceError(PyrouteError, ValueError):
    """Grid-convergence input is unusable (fewer than three grids, non-positive spacing, ...)."""


class NoFeasibleRouteError(PyrouteError, RuntimeError):
    """No route on the graph reaches the finish: every path has a forbidden arc.

    The message says at which rank the front of reachable nodes died and which criteria (failure
    criteria, polar limits, land, zones, missing weather) forbade the arcs there.
    """


class OutputError(PyrouteError, OSError):
    """An output folder or file cannot be written (a file in the way, no permission, disk full)."""


class CoordinateError(PyrouteError, ValueError):
    """A position is off the globe: a latitude outside [-90, 90] deg."""


class MemoryBudgetError(PyrouteError, MemoryError):
    """A route would need more memory than the budget allows (:mod:`pyroute_rel.memory`); refused before allocating."""


class TrackError(PyrouteError, ValueError):
    """A track file (GPX, GeoJSON, CSV) cannot be read as a track: no line in it, a bad coordinate or time."""


class PyrouteWarning(UserWarning):
    """Base class of the warnings pyroute_rel gives: the run goes on, but the user should know (the CLI prints each
    as one line on stderr)."""


class PolarWarning(PyrouteWarning):
    """A polar file was read with cells filled in (empty or missing speeds)."""


class CacheWarning(PyrouteWarning):
    """The disk cache is not used (a folder other users may write); the run goes on without it."""


class WeatherWarning(PyrouteWarning):
    """Weather data were read with a caveat: a file with one time taken as steady weather, or values outside their
    plausible range treated as missing."""
