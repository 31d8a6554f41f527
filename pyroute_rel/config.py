"""Scenario files (TOML) read into settings: one parser per table, the keys of each declared once in :data:`SCHEMA`.

A scenario has these tables (unknown tables or keys are refused with the file and key named)::

    [route]    start = [lon, lat]  finish = [lon, lat]  departure = "2018-06-01T00:00:00Z"
    [grid]     layout = "angular" | "square"  n_ranks = 160  n_nodes = 160  (all optional; see grid.plan_grid)
               spacing_km, aspect, half_width_km, max_deviation_deg, samples_per_arc = 1 | sample_km = 25,
               refine = 0
    [boat]     polar = "maribot_vane" | "path/to/file.pol"   beyond = "clamp" | "forbid"
               tack_penalty_s = [[tws_kn, s], ...]  gybe_penalty_s = [[tws_kn, s], ...]  (default: none)
    [weather]  kind = "uniform" (tws_kn, twd_deg, hs_m, wave_dir_deg, ... and [[weather.patch]] boxes)
               kind = "file"    (paths = [...], see pyroute_rel.weather.io.readers)
               (more kinds: :func:`register_weather_kind`)
    [failure]  model = "dickson2018" | "path/to/model.toml" | "none"   apf = 1.0
               (or limits = { tws_kn_max = 35, hs_m_max = 5, twa_deg_min = 40 }: apf defaults to 0)
    [avoid]    land = true  margin_km = 0  resolution = "intermediate"  zones = ["zones.geojson"]
    [planner]  kind = "dp" | "mcts" | "qlearning" | "dqn"  seed = 0  and [planner.mcts], ... (see
               pyroute_rel.planners.settings)

Paths are relative to the scenario file's folder. Times without a zone are read as UTC, with a note
(:attr:`~pyroute_rel.scenario.Scenario.notes`). :func:`parse_tables` gives the settings
:class:`~pyroute_rel.scenario.Scenario` is built from; this module knows nothing of routing.
"""

from __future__ import annotations

import datetime as dt
import math
import numbers
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties
from pyroute_rel.boat.polar import BEYOND_MODES, get_polar
from pyroute_rel.errors import ScenarioError, brief, check_flag, show
from pyroute_rel.geodesy import along_track_km, crossing_fraction, distance_km, intermediate_point
from pyroute_rel.obstacles.mask import Avoid
from pyroute_rel.planners.settings import parse_planner
from pyroute_rel.routing.cost import WaveLoss
from pyroute_rel.routing.grid import DEFAULT_N_RANKS, LAYOUTS
from pyroute_rel.weather import UniformWeather, WeatherSource

__all__ = [
    "SCHEMA",
    "Key",
    "WEATHER_KINDS",
    "WeatherBuilder",
    "register_weather_kind",
    "parse_tables",
    "weather_course",
    "parse_options",
    "parse_departure",
    "MIN_LEG_KM",
]

#: Consecutive marks of a course (start, waypoints, finish) must be at least this far apart [km].
MIN_LEG_KM = 1.0
#: Default departure (the paper's).
DEFAULT_DEPARTURE = "2018-06-01T00:00:00Z"

Line = tuple[tuple[float, float], tuple[float, float]]


# --- checks of single values: (value, where) -> the value read; each raises ScenarioError naming ``where`` ------


def finite_number(v: Any, where: str) -> float:
    """A finite real number (not a bool or a string)."""
    try:
        ok = not isinstance(v, bool) and isinstance(v, numbers.Real) and math.isfinite(float(v))
    except OverflowError:  # an int beyond the float range
        ok = False
    if not ok:
        raise ScenarioError(f"{where} must be a finite number (got {brief(v)})")
    return float(v)


def positive_number(v: Any, where: str) -> float:
    """A finite number > 0."""
    x = finite_number(v, where)
    if x <= 0:
        raise ScenarioError(f"{where} must be positive (got {v!r})")
    return x


def probability(v: Any, where: str) -> float:
    """A probability in [0, 1] (a number, or a string holding one)."""
    try:
        x = float(v) if isinstance(v, str) else finite_number(v, where)
    except ValueError:
        raise ScenarioError(f"{where} must be a probability in [0, 1] (got {v!r})") from None
    if not 0.0 <= x <= 1.0 or isinstance(v, bool):
        raise ScenarioError(f"{where} must be a probability in [0, 1] (got {v!r})")
    return x


def sample_spacing_km(v: Any, where: str) -> float:
    """Weather sample spacing along arcs [km], in [0.1, 1000]."""
    km = finite_number(v, where)
    if not 0.1 <= km <= 1000.0:
        raise ScenarioError(f"{where} must be in [0.1, 1000] [km] (got {km:g})")
    return km


def whole_number(lo: int) -> Callable[[Any, str], int]:
    """A check of whole numbers in [lo, 100000] (``"20"`` is refused, as for every number)."""

    def check(v: Any, where: str) -> int:
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise ScenarioError(f"{where} must be a whole number (got {v!r})")
        if v < lo:
            raise ScenarioError(f"{where} must be >= {lo} (got {brief(v)})")
        if v > 100_000:
            raise ScenarioError(f"{where} must be at most 100000 (got {brief(v)})")
        return int(v)

    return check


def true_or_false(v: Any, where: str) -> bool:
    """A TOML boolean."""
    if not isinstance(v, bool):
        raise ScenarioError(f"{where} must be true or false (got {v!r})")
    return v


def one_of(choices: Any) -> Callable[[Any, str], Any]:
    """A check that the value is one of ``choices``."""

    def check(v: Any, where: str) -> Any:
        if not isinstance(v, str) or v not in choices:
            raise ScenarioError(f"{where} must be one of {list(choices)} (got {v!r})")
        return v

    return check


def point(v: Any, where: str) -> tuple[float, float]:
    """A ``[lon, lat]`` point [deg]."""
    if not isinstance(v, list | tuple) or len(v) != 2:
        raise ScenarioError(f"{where} must be [lon, lat] in degrees (got {v!r})")
    lon, lat = finite_number(v[0], f"{where}[0] (lon)"), finite_number(v[1], f"{where}[1] (lat)")
    if not -180.0 <= lon <= 180.0:
        raise ScenarioError(f"{where} longitude must be in [-180, 180] [deg] (got {lon:g})")
    if not -90.0 <= lat <= 90.0:
        raise ScenarioError(f"{where} latitude must be in [-90, 90] [deg] (got {lat:g})")
    return lon, lat


def line(v: Any, where: str) -> Line:
    """A ``[[lon, lat], [lon, lat]]`` segment [deg] with distinct ends."""
    if not isinstance(v, list | tuple) or len(v) != 2:
        raise ScenarioError(f"{where} must be [[lon, lat], [lon, lat]] in degrees (got {v!r})")
    a, b = point(v[0], f"{where}[0]"), point(v[1], f"{where}[1]")
    if a == b:
        raise ScenarioError(f"{where} end points must differ (got {v!r})")
    return a, b


def _in_range(
    check: Callable[[Any, str], float], ok: Callable[[float], bool], message: str
) -> Callable[[Any, str], float]:
    """``check`` followed by a range test; ``message`` is the error's, with ``{where}`` and ``{x}`` (the value)."""

    def checked(v: Any, where: str) -> float:
        x = check(v, where)
        if not ok(x):
            raise ScenarioError(message.format(where=where, x=f"{x:g}"))
        return x

    return checked


def _samples(v: Any, where: str) -> int:
    n = whole_number(1)(v, where)
    if n > 64:
        raise ScenarioError(f"{where} must be at most 64 (got {n})")
    return n


def _polar_name(v: Any, where: str) -> str:
    if not isinstance(v, str):
        raise ScenarioError(f"{where} must be a built-in name or a file path (got {v!r})")
    return v


def _model_name(v: Any, where: str) -> str | None:
    if not isinstance(v, str):
        raise ScenarioError(f"{where} must be a model name or path (got {v!r})")
    return None if v.lower() == "none" else v


def _resolution(v: Any, where: str) -> str:
    from pyroute_rel.obstacles.land import RESOLUTIONS

    return one_of(RESOLUTIONS)(v, where)  # type: ignore[no-any-return]


def _zone_files(v: Any, where: str) -> list[str]:
    paths = [v] if isinstance(v, str) else v
    if not isinstance(paths, list) or not all(isinstance(p, str) for p in paths):
        raise ScenarioError(f"{where} must be a list of GeoJSON file names (got {paths!r})")
    return paths


def _wave_loss(raw: Any, where: str) -> WaveLoss:
    try:
        if not isinstance(raw, list) or not all(isinstance(r, list) and len(r) == 2 for r in raw):
            raise ValueError("expected a list of [hs_m, factor] pairs")
        return WaveLoss(
            hs_m=[finite_number(r[0], where) for r in raw],
            factor=[finite_number(r[1], where) for r in raw],
        )
    except ValueError as exc:
        raise ScenarioError(f"{where}: {exc} (got {raw!r})") from None


def _penalty_table(raw: Any, where: str) -> Any:
    kind = where.rsplit(".", 1)[-1].split("_", 1)[0]
    ManoeuvrePenalties(**{f"{kind}_s": raw}, where=where.rsplit(".", 1)[0])  # checked here, kept as read
    return raw


# --- the schema ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Key:
    """One key of a scenario table.

    Attributes
    ----------
    help : What the key holds, with its unit (shown in messages).
    check : ``check(value, where) -> value read``, raising :class:`~pyroute_rel.errors.ScenarioError` that names
        ``where`` (e.g. ``[grid].n_ranks``); None for a key its table's parser reads with the others it depends on.
    default : The value when the key is absent (not checked).
    """

    help: str
    check: Callable[[Any, str], Any] | None = None
    default: Any = None


def _limits(value: Any, where: str) -> tuple[tuple[str, float], ...]:
    from pyroute_rel.errors import FailureModelError
    from pyroute_rel.reliability.limits import check_limits

    try:
        return check_limits(value, where)
    except FailureModelError as exc:
        raise ScenarioError(str(exc)) from None


#: The keys of every table: what each holds and how it is checked. ``[weather]`` is checked by its kind's builder.
SCHEMA: dict[str, dict[str, Key]] = {
    "route": {
        "start": Key("[lon, lat] [deg]", point),
        "finish": Key("[lon, lat] [deg]", point),
        "departure": Key("ISO 8601 UTC time", None, DEFAULT_DEPARTURE),
        "start_line": Key("[[lon, lat], [lon, lat]] [deg]: start anywhere on this line", line),
        "finish_line": Key("[[lon, lat], [lon, lat]] [deg]: the voyage ends at its first crossing", line),
        "waypoints": Key("[[lon, lat], ...] [deg]: marks to pass, in order", None, []),
        "time_step_h": Key(
            "time lattice of the time-expanded DP [h]",
            _in_range(positive_number, lambda x: x <= 48.0, "{where} must be in (0, 48] [h] (got {x})"),
        ),
        "max_wait_h": Key(
            "longest wait at a node [h] (needs time_step_h)",
            _in_range(finite_number, lambda x: x >= 0, "{where} must be >= 0 [h] (got {x})"),
            0.0,
        ),
        "prune": Key(
            "true (default): cost only the arcs that can still win (same route); false: cost every arc",
            true_or_false,
            True,
        ),
    },
    "grid": {
        "layout": Key("'angular' (default) or 'square' (the paper's grid)", one_of(LAYOUTS), "angular"),
        "n_ranks": Key("whole number >= 1", whole_number(1)),
        "n_nodes": Key(
            "whole number >= 1: nodes per rank of the square layout (the angular layout derives its own)",
            whole_number(1),
        ),
        "spacing_km": Key("lateral node spacing [km]", positive_number),
        "aspect": Key(
            "rank spacing / lateral spacing (angular layout)",
            _in_range(
                positive_number,
                lambda x: 0.01 <= x <= 1000.0,
                "{where} (rank spacing / lateral spacing) must be in [0.01, 1000] (got {x})",
            ),
        ),
        "half_width_km": Key(
            "distance from the great circle to the outermost nodes [km] (angular layout)",
            _in_range(finite_number, lambda x: x >= 0, "{where} must be >= 0 [km] (got {x})"),
        ),
        "max_deviation_deg": Key(
            "largest arc angle from the rank direction [deg]",
            _in_range(finite_number, lambda x: 0.0 < x < 90.0, "{where} must be in (0, 90) [deg] (got {x})"),
        ),
        "samples_per_arc": Key("weather samples per arc (default: as many as sample_km asks)", _samples),
        "sample_km": Key("weather samples along arcs at most this far apart [km] (default 25)", sample_spacing_km),
        "refine": Key(
            "whole number >= 0: corridor refinements of the track (0 = none; see pyroute_rel.refine)",
            whole_number(0),
            0,
        ),
    },
    "boat": {
        "polar": Key("built-in name or polar file", _polar_name, "maribot_vane"),
        "beyond": Key(f"one of {list(BEYOND_MODES)}", one_of(BEYOND_MODES), "clamp"),
        "wave_speed_loss": Key("[[hs_m, factor], ...]: polar speed x factor(Hs), linear, from Hs = 0", _wave_loss),
        "tack_penalty_s": Key("[[tws_kn, s], ...]: time a tack costs, linear in the wind speed", _penalty_table),
        "gybe_penalty_s": Key("[[tws_kn, s], ...]: time a gybe costs, linear in the wind speed", _penalty_table),
    },
    "weather": {},  # validated by the weather kind
    "failure": {
        "model": Key("model name, model file, or 'none'", _model_name),
        "apf": Key("probability in [0, 1]", probability, 1.0),
        "limits": Key(
            "{ tws_kn_max = 35, hs_m_max = 5, twa_deg_min = 40, ... }: plain limits, compiled to a failure model "
            "(instead of 'model')",
            _limits,
        ),
    },
    "avoid": {
        "land": Key("true (default) or false: forbid arcs over land (offline GSHHG shoreline)", true_or_false, True),
        "margin_km": Key(
            "keep this far from any coast [km]",
            _in_range(finite_number, lambda x: 0.0 <= x <= 200.0, "{where} must be in [0, 200] [km] (got {x})"),
            0.0,
        ),
        "resolution": Key(
            "GSHHG resolution: 'intermediate' (default), 'low', 'high', 'full'", _resolution, "intermediate"
        ),
        "zones": Key("GeoJSON files of exclusion zones (relative to the scenario file)", _zone_files, []),
    },
    "planner": {},  # validated by pyroute_rel.planners.settings.parse_planner
}


def _check_tables(table: Mapping[str, Any]) -> None:
    """Unknown tables and keys are refused, as are tables that are not tables."""
    for key in table:
        if key not in SCHEMA:
            raise ScenarioError(f"unknown table [{show(key)}] (expected {', '.join(f'[{k}]' for k in SCHEMA)})")
    for name, spec in SCHEMA.items():
        sub = table.get(name, {})
        if not isinstance(sub, Mapping):
            raise ScenarioError(f"[{name}] must be a table")
        if spec:
            for key in sub:
                if key not in spec:
                    raise ScenarioError(f"[{name}]: unknown key '{show(key)}' (expected one of {', '.join(spec)})")


def _read(name: str, raw: Mapping[str, Any]) -> dict[str, Any]:
    """Every key of table ``name`` with a check, read (or its default when absent), in the schema's order."""
    out = {}
    for key, spec in SCHEMA[name].items():
        if spec.check is None:
            continue
        out[key] = spec.check(raw[key], f"[{name}].{key}") if key in raw else spec.default
    return out


# --- one parser per table -------------------------------------------------------------------------------------


def parse_departure(value: Any, where: str = "departure", *, notes: list[str] | None = None) -> np.datetime64:
    """Parse an ISO 8601 time (``Z`` or ``+00:00`` offsets; naive times are taken as UTC).

    Parameters
    ----------
    value : An ISO 8601 string, a ``datetime``, a ``date`` (midnight) or a ``numpy.datetime64`` (UTC).
    where : Named in messages (e.g. ``[route].departure``).
    notes : When given, a time without a zone (read as UTC) appends a note saying so.

    Returns
    -------
    The time (UTC), ``datetime64[s]``.

    Raises
    ------
    ScenarioError
        For anything but a time between the years 1900 and 2200.
    """
    if isinstance(value, np.datetime64) and not np.isnat(value):  # UTC, as the library's own times are
        t = value.astype("datetime64[us]").item()
    elif isinstance(value, dt.datetime):
        t = value
    elif isinstance(value, dt.date):  # a TOML date literal (departure = 2018-06-01): midnight UTC
        t = dt.datetime(value.year, value.month, value.day)
    elif isinstance(value, str):
        try:
            t = dt.datetime.fromisoformat(value.replace("Z", "+00:00"))
        except ValueError:
            raise ScenarioError(
                f"{where} must be an ISO 8601 time such as '2018-06-01T00:00:00Z' (got {value!r})"
            ) from None
    else:
        raise ScenarioError(f"{where} must be an ISO 8601 time string (got {value!r})")
    try:
        if t.tzinfo is not None:
            t = t.astimezone(dt.UTC).replace(tzinfo=None)
        elif notes is not None:
            shown = value if isinstance(value, str) else value.isoformat()
            notes.append(f"{where} {shown!r} has no time zone: read as UTC")
    except OverflowError:
        raise ScenarioError(f"{where} is out of range (got {value!r})") from None
    if not 1900 <= t.year <= 2200:
        raise ScenarioError(f"{where} must be between the years 1900 and 2200 (got {value!r})")
    return np.datetime64(t, "s")


def _midpoint(segment: Line) -> tuple[float, float]:
    lon, lat = intermediate_point(*segment[0], *segment[1], 0.5)
    return float(lon), float(lat)


def _nearest_on_line(segment: Line, p: tuple[float, float]) -> tuple[float, float]:
    """The point of a great-circle segment nearest to p [deg] (the grid aims there by default)."""
    (c_lon, c_lat), (d_lon, d_lat) = segment
    length = float(distance_km(c_lon, c_lat, d_lon, d_lat))
    along = float(along_track_km(c_lon, c_lat, d_lon, d_lat, *p))
    lon, lat = intermediate_point(c_lon, c_lat, d_lon, d_lat, min(max(along / length, 0.0), 1.0))
    return float(lon), float(lat)


def _off_line_km(segment: Line, p: tuple[float, float]) -> float:
    """Distance [km] from a point to a great-circle segment: to the segment's point nearest it."""
    return float(distance_km(*p, *_nearest_on_line(segment, p)))


def _marks(raw: Mapping[str, Any], start_line: Line | None, finish_line: Line | None) -> dict[str, Any]:
    """Start and finish (on their lines, or derived from them) and the waypoints, at least MIN_LEG_KM apart."""
    if "start" not in raw and start_line is not None:
        raw = {**raw, "start": list(_midpoint(start_line))}
    if "finish" not in raw and finish_line is not None:
        if "start" not in raw:
            raise ScenarioError("[route].start is missing ([lon, lat] [deg], or a start_line)")
        raw = {**raw, "finish": list(_nearest_on_line(finish_line, point(raw["start"], "[route].start")))}
    for key in ("start", "finish"):
        if key not in raw:
            raise ScenarioError(f"[route].{key} is missing ({SCHEMA['route'][key].help})")
    start = point(raw["start"], "[route].start")
    finish = point(raw["finish"], "[route].finish")
    for name, p, segment in (("start", start, start_line), ("finish", finish, finish_line)):
        if segment is not None and (off := _off_line_km(segment, p)) > 1.0:
            raise ScenarioError(f"[route].{name} {list(p)} must lie on [route].{name}_line ({off:.1f} km off it)")
    if start_line is not None and finish_line is not None:
        frac = crossing_fraction(*start_line[0], *start_line[1], *finish_line[0], *finish_line[1])
        if np.isfinite(frac).any():
            raise ScenarioError("[route].start_line crosses [route].finish_line: the course would end where it starts")
    raw_wp = raw.get("waypoints", [])
    if not isinstance(raw_wp, list):
        raise ScenarioError("[route].waypoints must be a list of [lon, lat] points [deg]")
    waypoints = tuple(point(p, f"[route].waypoints[{i}]") for i, p in enumerate(raw_wp))
    marks = [
        ("[route].start", start),
        *((f"[route].waypoints[{i}]", w) for i, w in enumerate(waypoints)),
        ("[route].finish", finish),
    ]
    for (name_a, a), (name_b, b) in zip(marks[:-1], marks[1:], strict=True):
        gap = float(distance_km(*a, *b))
        if gap < MIN_LEG_KM:
            what = "the same point" if gap < 1e-6 else f"{gap * 1000.0:.0f} m apart"
            raise ScenarioError(
                f"{name_a} {list(a)} and {name_b} {list(b)} are {what}: consecutive marks must be at "
                f"least {MIN_LEG_KM:g} km apart (nothing to route between them)"
            )
    return {"start": start, "finish": finish, "waypoints": waypoints}


def parse_route(raw: Mapping[str, Any], notes: list[str]) -> dict[str, Any]:
    """``[route]``: the marks, the departure, waiting and pruning."""
    start_line = line(raw["start_line"], "[route].start_line") if "start_line" in raw else None
    finish_line = line(raw["finish_line"], "[route].finish_line") if "finish_line" in raw else None
    marks = _marks(raw, start_line, finish_line)
    departure = parse_departure(raw.get("departure", DEFAULT_DEPARTURE), "[route].departure", notes=notes)
    values = _read("route", {k: v for k, v in raw.items() if k not in ("start", "finish", "start_line", "finish_line")})
    step, max_wait = values["time_step_h"], values["max_wait_h"]
    if max_wait > 0 and step is None:
        raise ScenarioError("[route].max_wait_h needs [route].time_step_h (waiting is modelled on a time lattice)")
    if step is not None and max_wait / step > 10_000:
        raise ScenarioError(
            f"[route].max_wait_h / [route].time_step_h must be at most 10000 wait steps per node (got "
            f"{max_wait:g} h / {step:g} h): use a larger time_step_h"
        )
    return {
        **marks,
        "start_line": start_line,
        "finish_line": finish_line,
        "departure": departure,
        "time_step_h": step,
        "max_wait_h": float(max_wait),
        "prune": values["prune"],
    }


def parse_grid(raw: Mapping[str, Any]) -> dict[str, Any]:
    """``[grid]``: layout, sizes, sampling along arcs, refinement."""
    values = _read("grid", raw)
    if values["sample_km"] is not None and values["samples_per_arc"] is not None:
        raise ScenarioError("[grid]: give samples_per_arc (a count) or sample_km (a spacing), not both")
    return values


def parse_boat(raw: Mapping[str, Any], base_dir: Path) -> dict[str, Any]:
    """``[boat]``: the polar (a built-in name or a file), its speed loss in waves, what to do beyond its table."""
    values = _read("boat", raw)
    return {
        "polar": get_polar(values["polar"], base_dir=base_dir),
        "wave_loss": values["wave_speed_loss"],
        "beyond": values["beyond"],
        "manoeuvres": ManoeuvrePenalties(tack_s=values["tack_penalty_s"], gybe_s=values["gybe_penalty_s"]),
    }


def parse_failure(raw: Mapping[str, Any]) -> dict[str, Any]:
    """``[failure]``: the model's name or file (None for ``"none"``), or plain limits
    (:mod:`pyroute_rel.reliability.limits`), and the acceptable probability of failure (default 1; 0 with limits, so
    that they hold)."""
    values = _read("failure", raw)
    limits = values["limits"] or ()
    if limits and "model" in raw:
        raise ScenarioError(
            "[failure]: give either 'model' (a network) or 'limits' (plain limits compiled to one), not both"
        )
    apf = values["apf"] if "apf" in raw or not limits else 0.0
    return {
        "failure_model": values["model"],
        "apf": apf,
        "failure_limits": limits,
        "apf_from_limits": bool(limits) and "apf" not in raw,
    }


def parse_avoid(raw: Mapping[str, Any], base_dir: Path) -> Avoid:
    """``[avoid]``: land, its margin and shoreline resolution, exclusion zones."""
    from pyroute_rel.obstacles.zones import load_zones

    values = _read("avoid", raw)
    zones = load_zones(values["zones"], base_dir=base_dir) if values["zones"] else ()
    return Avoid(
        land=values["land"], margin_km=values["margin_km"], resolution=values["resolution"], zones=tuple(zones)
    )


# --- weather kinds --------------------------------------------------------------------------------------------


class WeatherBuilder(Protocol):
    """Builds a weather source from a scenario's ``[weather]`` table (registered with
    :func:`register_weather_kind`).

    Parameters
    ----------
    table : The ``[weather]`` table, ``kind`` included; the builder refuses keys it does not know, naming them.
    base_dir : The scenario file's folder (paths are relative to it).
    bbox : ``(west, south, east, north)`` [deg], a box sure to hold the grid: data outside it need not be read.
    departure : Departure time (UTC).
    """

    def __call__(
        self, table: Mapping[str, Any], *, base_dir: Path, bbox: tuple[float, float, float, float], departure: Any
    ) -> WeatherSource: ...


def _uniform_weather(table: Mapping[str, Any], *, base_dir: Path, bbox: Any, departure: Any) -> WeatherSource:
    return UniformWeather.from_mapping(table)


def _file_weather(table: Mapping[str, Any], *, base_dir: Path, bbox: Any, departure: Any) -> WeatherSource:
    from pyroute_rel.weather.io.readers import weather_from_mapping

    window = (departure - np.timedelta64(1, "h"), departure + np.timedelta64(120, "D"))  # from departure, 120 days
    return weather_from_mapping(table, base_dir=base_dir, bbox=bbox, time_window=window)


#: Weather kinds a scenario may name in ``[weather].kind``, each with its builder (:func:`register_weather_kind`).
WEATHER_KINDS: dict[str, WeatherBuilder] = {"uniform": _uniform_weather, "file": _file_weather}


def register_weather_kind(kind: str, builder: WeatherBuilder, *, replace: bool = False) -> None:
    """Let scenarios name a new weather source: ``[weather] kind = "<kind>"`` calls ``builder``.

    Parameters
    ----------
    kind : The name scenarios use.
    builder : ``builder(table, *, base_dir, bbox, departure) -> WeatherSource`` (see :class:`WeatherBuilder`).
    replace : Allow replacing a kind already registered (default: refused).

    Raises
    ------
    ScenarioError
        (a ``ValueError``) for a kind that is not a name (letters, digits, ``_``, ``-``; e.g. none with spaces), a
        builder that is not callable, a ``replace`` other than True or False, or a kind already registered without
        ``replace``.

    Examples
    --------
    >>> from pyroute_rel.weather import UniformWeather
    >>> def calm(table, *, base_dir, bbox, departure):
    ...     return UniformWeather(tws_kn=float(table.get("tws_kn", 5.0)), twd_deg=0.0)
    >>> register_weather_kind("calm", calm)
    >>> "calm" in WEATHER_KINDS
    True
    >>> del WEATHER_KINDS["calm"]
    """
    if not isinstance(kind, str) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9_-]{0,63}", kind):
        raise ScenarioError(
            "a weather kind must be a name of letters, digits, '_' and '-' starting with a letter, at most 64 "
            f"characters (got {brief(kind)})"
        )
    check_flag(replace, "replace", ScenarioError)
    if not callable(builder):
        raise ScenarioError(f"the builder of weather kind {kind!r} must be callable (got {type(builder).__name__})")
    if kind in WEATHER_KINDS and not replace:
        raise ScenarioError(f"weather kind {kind!r} is already registered (pass replace=True to replace it)")
    WEATHER_KINDS[kind] = builder


def parse_weather(
    raw: Any, base_dir: Path, *, bbox: tuple[float, float, float, float], departure: Any
) -> WeatherSource:
    """``[weather]``: built by its kind's registered builder (:data:`WEATHER_KINDS`)."""
    if raw is None:
        raise ScenarioError('[weather] is missing (kind = "uniform" with tws_kn and twd_deg, or kind = "file")')
    if not isinstance(raw, Mapping):
        raise ScenarioError("[weather] must be a table")
    kind = raw.get("kind", "uniform")
    builder = WEATHER_KINDS.get(kind) if isinstance(kind, str) else None
    if builder is None:
        raise ScenarioError(f"[weather].kind must be one of {list(WEATHER_KINDS)} (got {kind!r})")
    return builder(raw, base_dir=base_dir, bbox=bbox, departure=departure)


def _course_bbox(marks: Mapping[str, Any], grid: Mapping[str, Any]) -> tuple[float, float, float, float]:
    """A lon/lat box [deg] sure to hold the grid: the course's points widened by the grid's half-width.

    ``marks``: start, finish, waypoints, start_line, finish_line; ``grid``: half_width_km, n_ranks, n_nodes (None
    when not set).
    """
    pts = [
        marks["start"],
        marks["finish"],
        *marks["waypoints"],
        *(marks["start_line"] or ()),
        *(marks["finish_line"] or ()),
    ]
    lon = np.array([p[0] for p in pts])
    lat = np.array([p[1] for p in pts])
    length = float(distance_km(*marks["start"], *marks["finish"]))
    half = grid.get("half_width_km")
    if half is None:
        n_ranks = grid.get("n_ranks") or DEFAULT_N_RANKS
        n_nodes = grid.get("n_nodes")
        half = 2000.0 if n_nodes is None else min((n_nodes - 1) / 2.0 * length / (n_ranks + 1), 1e4)
    half = min(float(half), 1e4)
    pad_lat = float(half) / 111.0 + 1.0
    pad_lon = pad_lat / max(np.cos(np.radians(min(80.0, float(np.max(np.abs(lat))) + pad_lat))), 0.2)
    return (
        max(float(lon.min()) - pad_lon, -180.0),
        max(float(lat.min()) - pad_lat, -89.0),
        min(float(lon.max()) + pad_lon, 180.0),
        min(float(lat.max()) + pad_lat, 89.0),
    )


def weather_course(table: Mapping[str, Any]) -> tuple[tuple[float, float, float, float], np.datetime64]:
    """The lon/lat box [deg] and the departure a scenario's ``[weather]`` is read for (as :func:`parse_tables` reads
    it: the course's box widened by the grid; the data from the departure on)."""
    route = parse_route(table.get("route", {}), [])
    return _course_bbox(route, parse_grid(table.get("grid", {}))), route["departure"]


def parse_tables(table: Mapping[str, Any], base_dir: Path) -> dict[str, Any]:
    """A scenario's tables read into the settings of :class:`~pyroute_rel.scenario.Scenario` (its field names).

    Tables are read in order: ``[route]``, ``[grid]``, ``[boat]``, ``[avoid]``, ``[weather]`` (reading only the
    data the course needs), ``[failure]``; ``notes`` holds what the reader assumed (times without a zone).

    Raises
    ------
    ScenarioError
        Naming the table and key of the first problem found.
    """
    _check_tables(table)
    notes: list[str] = []
    route = parse_route(table.get("route", {}), notes)
    grid = parse_grid(table.get("grid", {}))
    boat = parse_boat(table.get("boat", {}), base_dir)
    avoid = parse_avoid(table.get("avoid", {}), base_dir)
    bbox = _course_bbox(route, grid)
    weather = parse_weather(table.get("weather"), base_dir, bbox=bbox, departure=route["departure"])
    failure = parse_failure(table.get("failure", {}))
    if failure["failure_limits"] and failure["apf"] >= 1.0:
        notes.append(
            "[failure].limits with apf 1 are reported (the exposure, the voyage p_f) but never enforced: "
            "leave apf out (0) or set it below 1 to keep the route within them"
        )
    planner = parse_planner(table.get("planner", {}))
    return {
        **route,
        **grid,
        **boat,
        **failure,
        "weather": weather,
        "avoid": avoid,
        "planner": planner,
        "base_dir": base_dir,
        "notes": tuple(notes),
    }


# --- options given in code or on the command line ---------------------------------------------------------------


def _failure_option(value: Any, where: str) -> str | None:
    if not str(value).strip():
        raise ScenarioError(f"{where} needs a shipped model name, a model file or 'none' (got '')")
    return None if str(value).lower() == "none" else str(value)


def _departure_option(value: Any, where: str) -> np.datetime64:
    return parse_departure(value, where)


def _layout_option(value: Any, where: str) -> str:
    return one_of(LAYOUTS)(value, "--layout")  # type: ignore[no-any-return]


def _bool_option(value: Any, where: str) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise ScenarioError(f"{where} must be True or False (got {value!r})")
    return bool(value)


#: Options of :meth:`~pyroute_rel.scenario.Scenario.with_options`: how each is checked (None: by the grid or the
#: problem it reaches), under the command-line option's name.
OPTIONS: dict[str, Callable[[Any, str], Any] | None] = {
    "n_ranks": whole_number(1),
    "n_nodes": whole_number(1),
    "refine": whole_number(0),
    "sample_km": sample_spacing_km,
    "apf": probability,
    "failure_model": _failure_option,
    "departure": _departure_option,
    "layout": _layout_option,
    "land": _bool_option,
    "prune": _bool_option,
    "spacing_km": None,
    "max_deviation_deg": None,
    "samples_per_arc": None,
    "beyond": None,
    "time_step_h": None,
    "max_wait_h": None,
    "aspect": None,
    "half_width_km": None,
}


def parse_options(changes: Mapping[str, Any], *, avoid: Avoid) -> dict[str, Any]:
    """Options checked like the file's settings, named as on the command line (``--n-ranks``); ``None`` values are
    left out; ``land`` changes ``avoid``."""
    checked: dict[str, Any] = {}
    for key, value in changes.items():
        if value is None:
            continue
        if key not in OPTIONS:
            raise ScenarioError(f"unknown scenario option {key!r}")
        check = OPTIONS[key]
        where = key if key in ("land", "prune") else f"--{key.replace('_', '-')}"
        value = value if check is None else check(value, where)
        if key == "land":
            checked["avoid"] = replace(avoid, land=value)
        else:
            checked[key] = value
    return checked
