"""Domain errors of pyroute_rel, all in one place, and the argument checks that raise them.

Every error a user can cause (a bad scenario, polar, weather file or failure model) is one of these. Each
subclasses a built-in so callers may catch ``ValueError`` as usual; the CLI turns any :class:`PyrouteError`
into one line on stderr and exit code 2.

Public functions and the constructors of public classes check their arguments with :func:`check_flag`,
:func:`check_numbers`, :func:`check_instance`, :func:`check_path` and :func:`check_callable`: a wrong type, None
where a value is needed, an infinity or a NaN where no value may be missing is one of these errors naming the
argument, never a raw ``TypeError`` or ``AttributeError`` from deep inside, a NaN result or a silent default.
Inner kernels trust their callers and stay fast.
"""

from __future__ import annotations

import math
import numbers
import os
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "show",
    "brief",
    "check_flag",
    "check_numbers",
    "check_instance",
    "check_path",
    "check_callable",
    "check_fields",
    "FINITE",
    "PyrouteError",
    "ScenarioError",
    "PolarError",
    "WeatherError",
    "WeatherCoverageError",
    "FailureModelError",
    "GridError",
    "ConvergenceError",
    "NoFeasibleRouteError",
    "LabelLimitError",
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
    if "\n" in r:  # numpy arrays, long containers: one line
        r = " ".join(r.split())
    return r if len(r) <= limit else r[: limit - 3] + "..."


class PyrouteError(Exception):
    """Base class of every error pyroute_rel raises on purpose. Its message is one line: a value quoted in it whose
    ``repr`` spans lines (a numpy array) is joined onto one, as the command line prints it."""

    def __str__(self) -> str:
        text = super().__str__()
        return " ".join(text.split()) if "\n" in text or "\r" in text else text


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
    criteria, polar limits, land, zones, missing weather) forbade the arcs there. Raised by a route, it also carries
    ``result`` (the DP's :class:`~pyroute_rel.routing.solve.DPResult`) and, from
    :meth:`Scenario.route <pyroute_rel.scenario.Scenario.route>`, ``relaxation``: what would make it route
    (:class:`~pyroute_rel.routing.relax.Relaxation`); both None otherwise.
    """

    result: Any = None
    relaxation: Any = None
    cause: str | None = None
    hint: str = ""


class OutputError(PyrouteError, OSError):
    """An output folder or file cannot be written (a file in the way, no permission, disk full)."""


class CoordinateError(PyrouteError, ValueError):
    """A position is off the globe: a latitude outside [-90, 90] deg."""


class MemoryBudgetError(PyrouteError, MemoryError):
    """A route would need more memory than the budget allows (:mod:`pyroute_rel.routing.memory`); refused before
    allocating."""


class LabelLimitError(PyrouteError, RuntimeError):
    """A multi-objective search kept more non-dominated labels at a node than its cap allows
    (:func:`pyroute_rel.routing.tradeoff.voyage_front`, ``--max-labels``); refused rather than run on unbounded."""


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


# ----------------------------------------------------------------------------------------------- argument checks


def _got(value: object) -> str:
    if value is None:
        return "None"
    kind = type(value).__name__
    return f"{brief(value)}, {'an' if kind[:1] in 'aeiouAEIOU' else 'a'} {kind}"


def check_flag(value: Any, name: str, error: type[PyrouteError]) -> bool:
    """``value`` as a bool; anything but ``True``/``False`` (None, 1, "yes", an array) is ``error``.

    >>> check_flag(np.True_, "plot", ScenarioError)
    True
    >>> check_flag("no", "plot", ScenarioError)
    Traceback (most recent call last):
    ...
    pyroute_rel.errors.ScenarioError: plot must be True or False (got 'no', a str)
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise error(f"{name} must be True or False (got {_got(value)})")


def check_numbers(
    value: Any, name: str, error: type[PyrouteError], *, missing: bool = True, infinite: bool = False, unit: str = ""
) -> npt.NDArray[np.float64]:
    """``value`` (a number or an array of them, any shape) as float64; a non-numeric value (None, a string, a
    complex or boolean value, objects) is ``error``, and so is an infinity unless ``infinite``, and NaN unless
    ``missing`` (NaN then means a missing value and passes through).

    >>> check_numbers([1, 2.5], "tws_kn", ScenarioError).tolist()
    [1.0, 2.5]
    >>> check_numbers("a", "twa_deg", ScenarioError, unit="deg")
    Traceback (most recent call last):
    ...
    pyroute_rel.errors.ScenarioError: twa_deg must be a number or numbers [deg] (got 'a', a str)
    """
    arr = value if isinstance(value, np.ndarray) else None
    if arr is None and _plain(value):
        try:
            arr = np.asarray(value)
        except (TypeError, ValueError):  # ragged lists
            arr = None
    kind = "a number or numbers" if arr is None or arr.ndim else "a number"
    what = f"{name} must be {kind}{f' [{unit}]' if unit else ''}"
    if arr is None or arr.dtype.kind not in "fiu":
        raise error(f"{what} (got {_got(value)})")
    arr = arr.astype(np.float64, copy=False)
    if arr.size and not (missing and infinite):
        bad = np.isnan(arr) if infinite else np.isinf(arr) if missing else ~np.isfinite(arr)
        if bad.any():
            first = float(arr.reshape(-1)[int(np.argmax(bad.reshape(-1)))])
            rule = "not NaN" if infinite else "finite (NaN for missing)" if missing else "finite"
            raise error(f"{what}, {rule} (got {first:g}{f' at index {_where(bad)}' if arr.ndim else ''})")
    return arr


def _plain(value: Any) -> bool:
    """A number, or a (nested) list or tuple: what ``np.asarray`` may turn into numbers (never a str or object)."""
    return isinstance(value, (int, float, np.number, list, tuple)) and not isinstance(value, bool)


def _where(bad: npt.NDArray[np.bool_]) -> str:
    index = np.unravel_index(int(np.argmax(bad)), bad.shape)
    return str(int(index[0])) if len(index) == 1 else str(tuple(int(i) for i in index))


def check_instance(
    value: Any, types: type | tuple[type, ...], name: str, error: type[PyrouteError], *, expected: str = ""
) -> Any:
    """``value`` itself when it is one of ``types``, else ``error`` naming the expected (``expected``, default the
    types' names) and the given type.

    >>> check_instance(None, dict, "extra", OutputError)
    Traceback (most recent call last):
    ...
    pyroute_rel.errors.OutputError: extra must be a dict (got None)
    """
    if isinstance(value, types):
        return value
    names = expected or "a " + " or ".join(t.__name__ for t in (types if isinstance(types, tuple) else (types,)))
    raise error(f"{name} must be {names} (got {_got(value)})")


def check_path(value: Any, name: str, error: type[PyrouteError]) -> str | os.PathLike[str]:
    """``value`` when it is a non-empty file name (``str`` or ``os.PathLike`` of str), else ``error``."""
    if isinstance(value, os.PathLike):
        value_ = os.fspath(value)
        if isinstance(value_, str) and value_:
            return value
    elif isinstance(value, str) and value.strip():
        return value
    got = "an empty name" if isinstance(value, str) else _got(value)
    raise error(f"{name} must be a file name (str or pathlib.Path) (got {got})")


def check_callable(value: Any, name: str, error: type[PyrouteError]) -> Any:
    """``value`` when it can be called, else ``error``."""
    if callable(value):
        return value
    raise error(f"{name} must be a function (got {_got(value)})")


#: The largest finite float: the upper end of a range that refuses only the infinite.
FINITE = sys.float_info.max


def _number(value: Any, where: str, lo: float, hi: float, *, lo_open: bool = False, expected: str = "") -> float:
    ok = not isinstance(value, bool) and isinstance(value, numbers.Real)
    if ok:
        try:
            x = float(value)
        except OverflowError:  # a whole number beyond the floats
            x = math.nan
        ok = (x > lo if lo_open else x >= lo) and x <= hi  # False for NaN
    if not ok:
        bracket = "(" if lo_open else "["
        raise ScenarioError(
            f"{where} must be {expected or f'a number in {bracket}{lo:g}, {hi:g}]'} (got {brief(value)})"
        )
    return x


def _whole(value: Any, where: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
        raise ScenarioError(f"{where} must be a whole number in [{lo}, {hi}] (got {brief(value)})")
    return int(value)


def check_fields(obj: Any, limits: Mapping[str, tuple[Any, ...]], *, where: str) -> None:
    """Check the fields of a frozen settings dataclass, in the order of ``limits``, raising a one-line
    :class:`~pyroute_rel.errors.ScenarioError` that names the first bad one as ``where + name``; numbers are stored
    back as ``int`` or ``float``.

    Parameters
    ----------
    obj : The settings (``object.__setattr__`` stores the checked values).
    limits : Field name -> its rule: ``("int", lo, hi)`` a whole number in [lo, hi]; ``("float", lo, hi)`` a real
        number in [lo, hi] (NaN never; ``hi = inf`` takes the infinite, :data:`FINITE` does not), with optional
        ``lo_open`` (``(lo, hi]``) and the phrase of what is expected (default ``"a number in [lo, hi]"``);
        ``("bool",)``; ``("choice", options)`` one of the strings ``options``; ``("str",)`` a file name.
    where : What the message names a field with: ``"[planner.mcts]."`` gives ``"[planner.mcts].iterations"``.

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Noise:
    ...     sd: float = 1.0
    >>> check_fields(Noise(sd=-2), {"sd": ("float", 0.0, FINITE, False, "a finite number >= 0")}, where="Noise ")
    Traceback (most recent call last):
    ...
    pyroute_rel.errors.ScenarioError: Noise sd must be a finite number >= 0 (got -2)
    """
    for name, spec in limits.items():
        value = getattr(obj, name)
        at = f"{where}{name}"
        if spec[0] == "int":
            object.__setattr__(obj, name, _whole(value, at, spec[1], spec[2]))
        elif spec[0] == "float":
            lo_open, expected = (spec[3:] + (False, ""))[:2]
            object.__setattr__(obj, name, _number(value, at, spec[1], spec[2], lo_open=lo_open, expected=expected))
        elif spec[0] == "bool":
            if not isinstance(value, bool):
                raise ScenarioError(f"{at} must be true or false (got {brief(value)})")
        elif spec[0] == "choice":
            if not isinstance(value, str) or value not in spec[1]:
                raise ScenarioError(f"{at} must be one of {list(spec[1])} (got {brief(value)})")
        elif spec[0] == "str":
            if not isinstance(value, str):
                raise ScenarioError(f"{at} must be a file name (a string) (got {brief(value)})")
