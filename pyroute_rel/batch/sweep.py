"""Sweeps: many routes of one scenario (departures × ensemble members × apf × failure models × polars × grids), in
this process, a local process pool or on a dask.distributed cluster, into a tidy, resumable table.

A sweep is a list of :class:`Run` (a scenario file plus the settings it changes). Each run is the scenario file with
those settings written into its tables (``[route].departure``, ``[weather].member``, ``[failure].apf`` and
``model``, ``[boat].polar``, ``[grid]`` keys), validated and routed as ``pyroute-rel route`` would route the edited
file; so a row equals that route. :func:`run_sweep` returns a :class:`pyarrow.Table`, one row per run
(:data:`COLUMNS`): the run's key, its parameters, ``status`` (``ok``; ``no_route`` when no route respects the
constraints or the weather does not cover the departure; ``error`` with the one-line message of any other user
error), voyage time, distance, arrival, failure probabilities, arcs, runtime and the track's file.

Engines: ``"auto"`` (the default: this process for fewer than :data:`AUTO_MIN_RUNS` runs or on one CPU, else a
process pool of one process per CPU, :func:`auto_engine`), ``"inline"`` (this process), ``"processes"`` (a local
process pool) and ``"dask"`` (:mod:`distributed`: a running scheduler's address, or a ``LocalCluster`` of
``workers`` processes). Every process keeps the weather it opened (:mod:`pyroute_rel.weather.cache`) and the grids
it built for its later runs. Worker processes run one thread each (:data:`WORKER_ENV`), and their tasks are
batches of runs of the same member (:func:`task_batches`), and all the batches of a member go to one worker, so
that a member's weather is read by one worker only: on dask by :func:`place_batches` (dask's worker restrictions,
loose: another worker may take them when it would be idle, or when that worker dies); in the local pool by a
:class:`BatchQueue` that gives each worker its next batch when it finishes one (its member's next, else a member
not started yet, largest first, else the last batches of a member another worker started, rather than idle). The
weather each process read is in the table's metadata (:data:`READS_METADATA`). Failures are retried a bounded
number of times (``retries``): a run's internal error in its worker, a task whose worker died by the engine (dask's
``retries``; in the local pool a new process replaces the dead one and runs its batch again); a user error is a
row, never retried.

Output (``out``): ``runs.parquet/``, a Parquet dataset folder: each batch of finished runs is one part file,
written whole (a temporary name, then a rename), so a sweep that is killed keeps every batch it wrote;
``pyarrow.parquet.read_table("out/runs.parquet")`` reads them all. ``tracks/<key>.geojson``: the track of each
routed run, a GeoJSON Feature whose LineString holds the points and whose properties hold the time and the leg's
failure probability at each point. A run's key hashes its parameters, the package version and the content of every
file it reads (scenario, weather, polar, failure model, zones); running the same sweep again skips the keys already
recorded. Internal errors are returned but not recorded, so a re-run tries them again.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import itertools
import json
import math
import os
import socket
import time
import uuid

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pyroute_rel.batch.cluster import (
    WORKER_ENV,
    WorkersOption,
    check_engine_combinations,
    check_engine_name,
    close_client,
    synchronous_reads,
)
from pyroute_rel.config import SCHEMA, parse_departure, probability
from pyroute_rel.errors import (
    NoFeasibleRouteError,
    PyrouteError,
    PyrouteWarning,
    ScenarioError,
    WeatherCoverageError,
    brief,
    check_callable,
    check_flag,
    check_numbers,
    check_path,
    show,
)
from pyroute_rel.files import atomic_write, atomic_write_text, brief_path
from pyroute_rel.resources import pool_worker_init
from pyroute_rel.settings import Settings, get_settings, set_settings
from pyroute_rel.store import current_store, kept_call
from pyroute_rel.times import iso_utc

if TYPE_CHECKING:
    import pyarrow as pa

    from pyroute_rel.routing.grid import Grid
    from pyroute_rel.routing.route import Route
    from pyroute_rel.scenario import Scenario

__all__ = [
    "Run",
    "SweepSpec",
    "SweepError",
    "COLUMNS",
    "ENGINES",
    "load_sweep",
    "sweep_from_mapping",
    "departure_range",
    "run_key",
    "run_one",
    "run_sweep",
    "read_runs",
    "MAX_RUNS",
    "auto_engine",
    "run_batch",
    "task_batches",
    "place_batches",
    "BatchQueue",
    "WORKER_ENV",
    "AUTO_MIN_RUNS",
    "MAX_BATCH_RUNS",
    "READS_METADATA",
]

#: Key of the schema metadata of :func:`run_sweep`'s table that holds the weather each process read (JSON).
READS_METADATA = "pyroute_rel.weather_reads"
#: Engines of :func:`run_sweep`.
ENGINES = ("auto", "inline", "processes", "dask")
#: Most runs one sweep may hold: a day and more of routing on a few cores at a second a run; more is a typo or a job
#: for several sweeps (10^6 runs used to be built and keyed for minutes before anything was routed).
MAX_RUNS = 100_000
#: Files larger than this are keyed by size, modification time and their first and last MB instead of their whole
#: content [bytes].
HASH_WHOLE_BYTES = 256_000_000
#: Grids kept per process for later runs.
GRID_CACHE_SIZE = 8
#: Sweep specification keys (the ``[sweep]`` table).
SPEC_KEYS = ("scenario", "departures", "members", "apf", "failure_models", "polars", "grids")

#: The table's columns and their Arrow types (as strings: ``pyarrow`` is imported only when a table is built).
COLUMNS: dict[str, str] = {
    "key": "string",
    "scenario": "string",
    "departure": "string",
    "member": "int64",
    "apf": "float64",
    "failure_model": "string",
    "polar": "string",
    "grid": "string",
    "options": "string",
    "status": "string",
    "message": "string",
    "voyage_time_h": "float64",
    "distance_nm": "float64",
    "arrival": "string",
    "max_failure_probability": "float64",
    "voyage_failure_probability": "float64",
    "grid_voyage_time_h": "float64",
    "arcs": "int64",
    "runtime_s": "float64",
    "track": "string",
}


class SweepError(ScenarioError):
    """A sweep specification, option or engine that cannot be used (a user error: exit 2)."""


@dataclass(frozen=True)
class Run:
    """One run of a sweep: a scenario file and the settings it changes (None: the file's).

    Attributes
    ----------
    scenario : The scenario TOML file.
    departure : ``[route].departure``, ISO 8601 UTC.
    member : ``[weather].member``, the ensemble member.
    apf : ``[failure].apf``.
    failure_model : ``[failure].model`` (``"none"`` for none).
    polar : ``[boat].polar``, a shipped name or a file.
    grid : ``[grid]`` keys and values, e.g. ``(("n_ranks", 80),)``.
    options : Further settings of :meth:`~pyroute_rel.scenario.Scenario.with_options` (``pyroute-rel route``'s
        options), applied after the file's.
    """

    scenario: str
    departure: str | None = None
    member: int | None = None
    apf: float | None = None
    failure_model: str | None = None
    polar: str | None = None
    grid: tuple[tuple[str, Any], ...] = ()
    options: tuple[tuple[str, Any], ...] = ()

    def params(self) -> dict[str, Any]:
        """The run's settings as the table's parameter columns."""
        return {
            "scenario": self.scenario,
            "departure": self.departure,
            "member": self.member,
            "apf": self.apf,
            "failure_model": self.failure_model,
            "polar": self.polar,
            "grid": json.dumps(dict(self.grid), sort_keys=True),
            "options": json.dumps(dict(self.options), sort_keys=True, default=str),
        }


@dataclass(frozen=True)
class SweepSpec:
    """A sweep specification (:func:`load_sweep`): its runs, and where it came from."""

    source: str
    runs: tuple[Run, ...]
    base_dir: Path = field(default=Path("."))


# --- specifications ----------------------------------------------------------------------------------------------


def departure_range(start: Any, end: Any, step_h: Any, where: str = "departures") -> list[str]:
    """Departures from ``start`` to ``end`` (included when on a step) every ``step_h`` hours, ISO 8601 UTC.

    >>> departure_range("2018-06-01T00:00:00Z", "2018-06-02T00:00:00Z", 12)
    ['2018-06-01T00:00:00Z', '2018-06-01T12:00:00Z', '2018-06-02T00:00:00Z']
    """
    import numpy as np

    t0 = parse_departure(start, f"{where}.start")
    t1 = parse_departure(end, f"{where}.end")
    if isinstance(step_h, bool) or not isinstance(step_h, int | float) or not math.isfinite(step_h) or step_h <= 0:
        raise SweepError(f"{where}.step_h must be a positive number of hours (got {brief(step_h)})")
    if step_h < 1.0 / 3600.0:  # (departures are to the second; a denormal step overflowed, issue 34)
        raise SweepError(f"{where}.step_h must be at least one second, 1/3600 h (got {brief(step_h)})")
    if t1 < t0:
        raise SweepError(f"{where}.end must not be before {where}.start (got {iso_utc(t1)} < {iso_utc(t0)})")
    span_h = float((t1 - t0) / np.timedelta64(1, "s")) / 3600.0
    steps = math.floor(span_h / step_h + 1e-9)
    if steps + 1 > MAX_RUNS:  # (before anything is made of them)
        raise SweepError(f"{where} gives {steps + 1} departures (at most {MAX_RUNS}): use a larger step_h")
    n = int(steps) + 1
    return [iso_utc(t0 + np.timedelta64(round(i * step_h * 3600.0), "s")) for i in range(n)]


def _departures(raw: Any, where: str) -> list[str | None]:
    if raw is None:
        return [None]
    if isinstance(raw, Mapping):
        unknown = sorted(set(raw) - {"start", "end", "step_h"})
        missing = [k for k in ("start", "end", "step_h") if k not in raw]
        if unknown or missing:
            raise SweepError(
                f"{where} must be {{start, end, step_h}} or a list of times "
                f"({'unknown key ' + show(unknown[0]) if unknown else 'missing ' + missing[0]})"
            )
        return list(departure_range(raw["start"], raw["end"], raw["step_h"], where))
    if isinstance(raw, list) and raw:
        return [iso_utc(parse_departure(v, f"{where}[{i}]")) for i, v in enumerate(raw)]
    raise SweepError(f"{where} must be {{start, end, step_h}} or a non-empty list of ISO 8601 times (got {brief(raw)})")


def _nonempty_list(raw: Any, where: str, check: Callable[[Any, str], Any]) -> list[Any]:
    if not isinstance(raw, list) or not raw:
        raise SweepError(f"{where} must be a non-empty list (got {brief(raw)})")
    return [check(v, f"{where}[{i}]") for i, v in enumerate(raw)]


def _name(v: Any, where: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise SweepError(f"{where} must be a name or a file name (got {brief(v)})")
    return v


def _member(v: Any, where: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise SweepError(f"{where} must be a whole number >= 0 (got {brief(v)})")
    return int(v)


def _grid_settings(v: Any, where: str) -> tuple[tuple[str, Any], ...]:
    if not isinstance(v, Mapping):
        raise SweepError(f"{where} must be a table of [grid] settings such as {{n_ranks = 80}} (got {brief(v)})")
    keys = SCHEMA["grid"]
    for k, value in v.items():
        if k not in keys:
            raise SweepError(f"{where}: unknown [grid] key {show(k)} (expected one of {', '.join(keys)})")
        check = keys[k].check
        if check is not None:
            check(value, f"{where}.{k}")
    return tuple(sorted(v.items()))


def _members(raw: Any, where: str, scenario: Path) -> list[int | None]:
    if raw is None:
        return [None]
    if raw != "all":
        return list(_nonempty_list(raw, where, _member))
    from pyroute_rel.scenario import read_scenario_table

    weather = read_scenario_table(scenario).get("weather")
    paths = weather.get("paths") if isinstance(weather, Mapping) and weather.get("kind") == "file" else None
    if not isinstance(paths, list) or not all(isinstance(p, str) for p in paths):
        raise SweepError(f'{where} = "all" needs a scenario whose [weather] is kind = "file" with paths')
    from pyroute_rel.weather.io.readers import ensemble_size

    n = ensemble_size([_resolve(p, scenario.parent) for p in paths])
    if n is None:
        raise SweepError(f'{where} = "all": the weather files of {brief_path(scenario)} have no ensemble dimension')
    return list(range(n))


def _resolve(name: str, base: Path) -> Path:
    p = Path(name).expanduser()
    return p if p.is_absolute() else base / p


def _file_or_name(name: str, base: Path) -> str:
    """A polar or failure model named in a spec: a file beside the spec as an absolute path, else the name."""
    p = _resolve(name, base)
    return str(p.resolve()) if p.is_file() else name


def _check_loadable(models: list[str | None], polars: list[str | None]) -> None:
    """Every failure model and polar a spec names loads (a shipped name or a readable file beside the spec;
    ``"none"``: no failure model): a spec error now, not an error row in every run that uses it."""
    from pyroute_rel.boat.polar import get_polar
    from pyroute_rel.reliability.failure import load_failure_model

    for key, names, load in (("failure_models", models, load_failure_model), ("polars", polars, get_polar)):
        for name in names:
            if name is not None and not (key == "failure_models" and name.lower() == "none"):
                try:
                    load(name)
                except PyrouteError as exc:
                    raise ScenarioError(f"[sweep].{key}: {exc}") from None


def sweep_from_mapping(table: Mapping[str, Any], *, base_dir: str | Path = ".", source: str = "<sweep>") -> SweepSpec:
    """Validate a sweep specification given as mappings (the parsed TOML): see :func:`load_sweep`."""
    try:
        spec = _sweep_from_mapping(table, Path(base_dir))
    except PyrouteError as exc:
        raise SweepError(f"{source}: {exc}") from None
    return SweepSpec(source=source, runs=spec.runs, base_dir=spec.base_dir)


def _sweep_from_mapping(table: Mapping[str, Any], base: Path) -> SweepSpec:
    if not isinstance(table, Mapping) or "sweep" not in table:
        raise SweepError("a sweep specification needs a [sweep] table")
    extra = sorted(set(table) - {"sweep"})
    if extra:
        raise SweepError(f"unknown table [{show(extra[0])}] (a sweep specification has only [sweep])")
    raw = table["sweep"]
    if not isinstance(raw, Mapping):
        raise SweepError("[sweep] must be a table")
    for k in raw:
        if k not in SPEC_KEYS:
            raise SweepError(f"[sweep]: unknown key {show(k)} (expected one of {', '.join(SPEC_KEYS)})")
    name = raw.get("scenario")
    if not isinstance(name, str) or not name.strip():
        raise SweepError(f"[sweep].scenario must be the scenario TOML file (got {brief(name)})")
    scenario = _resolve(name, base)
    if not scenario.is_file():
        raise SweepError(f"[sweep].scenario: no such file {brief_path(scenario)}")
    deps = _departures(raw.get("departures"), "[sweep].departures")
    members = _members(raw.get("members"), "[sweep].members", scenario)
    apfs = _nonempty_list(raw["apf"], "[sweep].apf", probability) if "apf" in raw else [None]
    models: list[str | None] = (
        [_file_or_name(m, base) for m in _nonempty_list(raw["failure_models"], "[sweep].failure_models", _name)]
        if "failure_models" in raw
        else [None]
    )
    polars: list[str | None] = (
        [_file_or_name(p, base) for p in _nonempty_list(raw["polars"], "[sweep].polars", _name)]
        if "polars" in raw
        else [None]
    )
    _check_loadable(models, polars)
    grids = _nonempty_list(raw["grids"], "[sweep].grids", _grid_settings) if "grids" in raw else [()]
    n = len(deps) * len(members) * len(apfs) * len(models) * len(polars) * len(grids)
    if n > MAX_RUNS:
        raise SweepError(f"[sweep] gives {n} runs (at most {MAX_RUNS})")
    runs = tuple(
        Run(str(scenario), departure=d, member=m, apf=a, failure_model=f, polar=p, grid=g)
        for g, m, p, f, a, d in itertools.product(grids, members, polars, models, apfs, deps)
    )
    return SweepSpec(source="", runs=runs, base_dir=base)


def _check_routed_by_the_dp(scenario: Path) -> None:
    """A sweep routes every run with the DP: a scenario whose ``[planner] kind`` names another planner is refused
    rather than routed by the DP without a word (issue 34)."""
    from pyroute_rel.scenario import read_scenario_table

    try:
        planner = read_scenario_table(scenario).get("planner")
    except ScenarioError:
        return  # (the file's own error comes with its first run)
    kind = planner.get("kind", "dp") if isinstance(planner, Mapping) else "dp"
    if kind != "dp":
        raise SweepError(
            f"scenario {brief_path(scenario)} plans with [planner] kind = {brief(kind)}, but a sweep routes "
            'every run with the DP: remove the [planner] table (or set kind = "dp"), or run `pyroute-rel plan`'
        )


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep specification (TOML)::

        [sweep]
        scenario = "microtransat_era5.toml"        # relative to this file
        departures = {start = "2018-06-01T00:00:00Z", end = "2018-06-03T00:00:00Z", step_h = 12}
        # or departures = ["2018-06-01T00:00:00Z", ...]
        members = "all"                            # or [0, 1, 2]: [weather].member of an ensemble file
        apf = [1.0, 0.2]
        failure_models = ["dickson2018"]           # optional
        polars = ["maribot_vane"]                  # optional: shipped names or files
        grids = [{n_ranks = 40}, {n_ranks = 80}]   # optional: [grid] settings

    Every key but ``scenario`` is optional (the scenario's own setting). The runs are every combination, grids
    outermost and departures innermost.

    Raises
    ------
    SweepError
        (a ``ValueError``) naming the file and the field, in one line.
    """
    from pyroute_rel.scenario import read_scenario_table

    p = Path(check_path(path, "sweep file", SweepError))
    try:
        table = read_scenario_table(p)  # the same reading checks as a scenario file's
    except ScenarioError as exc:
        raise SweepError(str(exc).replace("scenario file", "sweep file")) from None
    spec = sweep_from_mapping(table, base_dir=p.parent, source=brief_path(p))
    return SweepSpec(source=str(p), runs=spec.runs, base_dir=spec.base_dir)


# --- keys ----------------------------------------------------------------------------------------------------------


def _file_digest(path: Path) -> str:
    """A hash of a file's content (see :data:`HASH_WHOLE_BYTES`), remembered by path, size and time (in the current
    store, :mod:`pyroute_rel.store`)."""
    try:
        st = path.stat()
    except OSError:
        return "missing"
    return _digest_of(str(path.resolve()), st.st_size, st.st_mtime_ns)


@kept_call("sweep.digests", limit=4096)
def _digest_of(path: str, size: int, mtime_ns: int) -> str:
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as fh:
        if size <= HASH_WHOLE_BYTES:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        else:
            h.update(f"{size}:{mtime_ns}".encode())
            h.update(fh.read(1 << 20))
            fh.seek(-(1 << 20), os.SEEK_END)
            h.update(fh.read(1 << 20))
    return h.hexdigest()


def _subtable(table: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    """``table[key]`` when it is a table, else an empty one."""
    value = table.get(key)
    return value if isinstance(value, Mapping) else {}


def _referenced_files(table: Mapping[str, Any], base: Path, run: Run) -> list[str]:
    """Names of the files a run reads besides its scenario (weather, polar, failure model, zones), as written."""
    names: list[Any] = []
    weather = table.get("weather")
    if isinstance(weather, Mapping) and weather.get("kind") == "file" and isinstance(weather.get("paths"), list):
        names += weather["paths"]
    boat, failure, avoid = (_subtable(table, k) for k in ("boat", "failure", "avoid"))
    names.append(run.polar or boat.get("polar"))
    model = run.failure_model or failure.get("model")
    if isinstance(model, str):  # the model's TOML and the network it names (a shipped one's too)
        from pyroute_rel.reliability.failure import model_files

        resolved = str(_resolve(model, base)) if _resolve(model, base).is_file() else model
        names += [str(f) for f in model_files(resolved)]
    if isinstance(avoid.get("zones"), list):
        names += avoid["zones"]
    return [n for n in names if isinstance(n, str) and _resolve(n, base).is_file()]


def run_key(run: Run) -> str:
    """The run's key: a hash of its settings, the package version and the content of the files it reads.

    A changed scenario, weather, polar, failure model or zones file gives a new key (files beyond
    :data:`HASH_WHOLE_BYTES` by size, modification time and their ends).
    """
    from pyroute_rel import __version__
    from pyroute_rel.scenario import read_scenario_table

    path = Path(run.scenario)
    try:
        table = read_scenario_table(path)
    except ScenarioError:
        table = {}
    files = {n: _file_digest(_resolve(n, path.parent)) for n in _referenced_files(table, path.parent, run)}
    params = {k: v for k, v in run.params().items() if k != "scenario"}
    doc = {"version": __version__, "run": params, "scenario": _file_digest(path), "files": files}
    return hashlib.blake2b(json.dumps(doc, sort_keys=True, default=str).encode(), digest_size=12).hexdigest()


# --- running one -------------------------------------------------------------------------------------------------


def _edited_table(run: Run) -> dict[str, Any]:
    """The run's scenario tables with its settings written in."""
    from pyroute_rel.scenario import read_scenario_table

    table = copy.deepcopy(read_scenario_table(run.scenario))

    def put(name: str, key: str, value: Any) -> None:
        sub = table.setdefault(name, {})
        if not isinstance(sub, dict):
            raise ScenarioError(f"{run.scenario}: [{name}] must be a table")
        sub[key] = value

    if run.departure is not None:
        put("route", "departure", run.departure)
    if run.member is not None:
        put("weather", "member", run.member)
    if run.apf is not None:
        put("failure", "apf", run.apf)
    if run.failure_model is not None:  # a model replaces plain limits (and their default apf), as --failure-model does
        put("failure", "model", run.failure_model)
        if table["failure"].pop("limits", None) is not None and run.apf is None and "apf" not in table["failure"]:
            table["failure"]["apf"] = 1.0
    if run.polar is not None:
        put("boat", "polar", run.polar)
    for k, v in run.grid:
        put("grid", k, v)
    return table


def _scenario(run: Run) -> Scenario:
    from pyroute_rel.scenario import scenario_from_mapping

    path = Path(run.scenario)
    sc = scenario_from_mapping(_edited_table(run), base_dir=path.parent, source=str(path))
    return sc.with_options(**dict(run.options)) if run.options else sc


def _grids(sc: Scenario) -> list[Grid]:
    """The scenario's grids, shared by every run of this process with the same course and grid settings (what is
    cached on them, arc geometry and obstacle masks, is then computed once)."""
    names = ("start", "finish", "waypoints", "start_line", "finish_line", "layout", "n_ranks", "n_nodes",
             "spacing_km", "aspect", "half_width_km", "max_deviation_deg")  # fmt: skip
    key = json.dumps([getattr(sc, n) for n in names], default=str)
    return current_store().shelf("sweep.grids", limit=GRID_CACHE_SIZE).get_or_make(key, sc.leg_grids)  # type: ignore[no-any-return]


def _route_columns(route: Route) -> dict[str, Any]:
    s = route.summary()
    return {
        "departure": s["departure"],
        "voyage_time_h": route.voyage_time_h,
        "distance_nm": route.distance_nm,
        "arrival": s["arrival"],
        "max_failure_probability": route.max_failure_probability,
        "voyage_failure_probability": route.voyage_failure_probability,
        "grid_voyage_time_h": route.meta["refine"]["grid_voyage_time_h"] if "refine" in route.meta else None,
        "arcs": int(s["arcs"]["evaluated"]),
        "_track": s["track"],
    }


def run_one(run: Run, key: str = "") -> dict[str, Any]:
    """Route one run: its row of the table (:data:`COLUMNS`), plus ``_track`` (the summary's track points) when
    routed.

    A user error (:class:`~pyroute_rel.errors.PyrouteError`) is the row's ``status`` and ``message``; any other
    exception is raised (an engine may retry it). The process keeps the weather and grids for its next runs.
    """
    from pyroute_rel.weather import cache

    row: dict[str, Any] = {c: None for c in COLUMNS}
    row.update(run.params(), key=key, status="ok", message="")
    t0 = time.perf_counter()
    try:
        with cache.caching():
            sc = _scenario(run)
            row["departure"] = iso_utc(sc.departure)
            route = sc.route(grids=_grids(sc), relax_wider=False)
    except (NoFeasibleRouteError, WeatherCoverageError) as exc:
        row.update(status="no_route", message=_one_line(exc))
    except PyrouteError as exc:
        row.update(status="error", message=_one_line(exc))
    else:
        row.update(_route_columns(route))
    row["runtime_s"] = time.perf_counter() - t0
    return row


def _one_line(exc: BaseException, limit: int = 1000) -> str:
    line = " ".join(str(exc).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


# --- output ------------------------------------------------------------------------------------------------------

RUNS_DIR = "runs.parquet"
TRACKS_DIR = "tracks"


def _schema() -> pa.Schema:
    import pyarrow as pa

    return pa.schema([(name, pa.type_for_alias(kind)) for name, kind in COLUMNS.items()])


def _table(rows: Sequence[Mapping[str, Any]]) -> pa.Table:
    import pyarrow as pa

    return pa.Table.from_pylist([{c: r.get(c) for c in COLUMNS} for r in rows], schema=_schema())


def read_runs(out: str | Path, *, set_aside: bool = False) -> pa.Table:
    """Every run recorded in a sweep's output folder (``out/runs.parquet``), once per key (an empty table if none).

    A part that cannot be read as this table (truncated, corrupt, empty, not a file, another schema) is skipped with a
    :class:`~pyroute_rel.errors.PyrouteWarning` naming it; with ``set_aside`` (a sweep resuming) it is also moved to
    ``runs.parquet/set-aside/``, so that its runs are routed again and the folder reads cleanly afterwards.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder = Path(out) / RUNS_DIR
    parts = sorted(folder.glob("part-*.parquet")) if folder.is_dir() else []
    if not parts:
        return _table([])
    rows: dict[str, dict[str, Any]] = {}
    for p in parts:
        try:
            if not p.is_file():
                raise IsADirectoryError("not a file")
            if set(pq.read_schema(p).names) != set(COLUMNS):
                raise ValueError("not the runs' columns")
            table = pq.read_table(p, schema=_schema())
        except (OSError, ValueError, pa.ArrowException) as exc:
            _unreadable_part(p, exc, set_aside)
            continue
        for r in table.to_pylist():
            rows.setdefault(r["key"], r)
    return _table(list(rows.values()))


def _unreadable_part(part: Path, exc: BaseException, set_aside: bool) -> None:
    """Warn of a part :func:`read_runs` cannot read and, with ``set_aside``, move it out of the runs."""
    why = f"{type(exc).__name__}: {_one_line(exc)}"[:200]
    what = "skipped"
    if set_aside:
        aside = part.parent / "set-aside"
        try:
            aside.mkdir(exist_ok=True)
            part.rename(aside / part.name)
            what = f"set aside in {brief_path(aside)}: its runs are routed again"
        except OSError as move:
            raise SweepError(f"{brief_path(part)}: cannot be read ({why}) nor set aside ({move.strerror})") from None
    warnings.warn(f"{brief_path(part)}: not a readable part of the runs ({why}); {what}", PyrouteWarning, stacklevel=3)


def _track_geojson(row: Mapping[str, Any]) -> str:
    pts = row["_track"]
    return json.dumps(
        {
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": [[p["lon"], p["lat"]] for p in pts]},
            "properties": {
                "key": row["key"],
                "departure": row["departure"],
                "voyage_time_h": row["voyage_time_h"],
                "time": [p["time"] for p in pts],
                "p_f": [p["p_f"] for p in pts],
            },
        }
    )


class _Store:
    """A sweep's output folder: finished rows are buffered and written as one part file per batch."""

    def __init__(self, out: Path, *, batch: int, flush_s: float):
        self.out, self.batch, self.flush_s = out, batch, flush_s
        self.pending: list[dict[str, Any]] = []
        self.last = time.monotonic()

    def add(self, row: dict[str, Any]) -> None:
        if row.get("_internal"):
            return  # not recorded: a re-run tries it again
        with self._writing():
            (self.out / RUNS_DIR).mkdir(parents=True, exist_ok=True)  # on the first result: nothing before
            (self.out / TRACKS_DIR).mkdir(exist_ok=True)
            if row.get("_track") is not None:
                name = f"{TRACKS_DIR}/{row['key']}.geojson"
                atomic_write_text(self.out / name, _track_geojson(row))
                row["track"] = name
        self.pending.append(row)
        if len(self.pending) >= self.batch or time.monotonic() - self.last >= self.flush_s:
            self.flush()

    def flush(self) -> None:
        self.last = time.monotonic()
        if not self.pending:
            return
        import pyarrow.parquet as pq

        table, self.pending = _table(self.pending), []
        name = f"part-{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:12]}.parquet"
        with self._writing():
            atomic_write(self.out / RUNS_DIR / name, lambda p: pq.write_table(table, p))

    @contextmanager
    def _writing(self) -> Iterator[None]:
        """The folder's own trouble (a full disk, a folder made read-only, a name taken by a directory) as one line:
        the runs recorded so far stay, and running the sweep again resumes after them (issue 34: exit 3)."""
        try:
            yield
        except OSError as exc:
            self.pending = []  # (not recorded: the resume routes them again)
            where = brief_path(exc.filename) if exc.filename else brief_path(self.out)
            raise SweepError(
                f"cannot write the sweep's results to {where}: {exc.strerror or exc}; the runs recorded before are "
                "kept, and running the sweep again resumes after them"
            ) from None


# --- engines -----------------------------------------------------------------------------------------------------


def _internal_row(run: Run, key: str, exc: BaseException) -> dict[str, Any]:
    row: dict[str, Any] = {c: None for c in COLUMNS}
    row.update(run.params(), key=key, status="error", _internal=True)
    row["message"] = f"internal error: {type(exc).__name__}: {_one_line(exc)}"
    return row


def _attempts(run: Run, key: str, retries: int) -> dict[str, Any]:
    """The run's row, tried again up to ``retries`` times after an internal error (then an internal-error row, not
    recorded in the files: a later sweep tries it again)."""
    for attempt in range(retries + 1):
        try:
            return run_one(run, key)
        except Exception as exc:  # a bug of ours
            if attempt == retries:
                return _internal_row(run, key, exc)
    raise AssertionError("unreachable")  # pragma: no cover


def _inline(todo: Sequence[tuple[str, Run]], retries: int) -> Iterator[dict[str, Any]]:
    for key, run in todo:
        yield _counted(run, key, retries)


def _pin_threads(engines: Settings | None = None) -> None:
    """One thread in this worker process: :data:`WORKER_ENV` for what reads it later, and the BLAS/OpenMP pools
    already loaded limited to 1 (``threadpoolctl``) for a ``dask worker`` started without that environment; and the
    caller's ``engines`` (:mod:`pyroute_rel.settings`; None: the defaults)."""
    if engines is not None:
        set_settings(engines)
    _limit_pools()


def _limit_pools() -> None:
    """:data:`WORKER_ENV` in this process's environment and its BLAS/OpenMP pools limited to one thread (once: a
    process already so is left alone; the pools read the environment when they load)."""
    if all(os.environ.get(k) == v for k, v in WORKER_ENV.items()):
        return
    os.environ.update(WORKER_ENV)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - installed with scikit-learn/numpy stacks; the env still applies
        return
    threadpool_limits(limits=1)  # the limit holds while the process lives


def run_batch(batch: Sequence[tuple[str, Run]], retries: int = 0) -> list[dict[str, Any]]:
    """Route a batch of runs in this (worker) process, one thread: the rows of :func:`run_one`.

    A run that raises an internal error is tried again up to ``retries`` times here, then is an internal-error row
    (not recorded in the output, so a later sweep tries it again). The batch of an engine's task: runs of the same
    member and grid are batched together, so a worker opens their weather and builds their grid once.

    The weather files' dask arrays are read with dask's synchronous scheduler, in this thread: in a dask worker the
    default would be the cluster itself, and a task waiting there for its weather's chunks secedes from the
    worker's thread, so that the worker starts its next task, and the next, all at once.
    """
    _pin_threads()
    with synchronous_reads():  # the weather's dask arrays: read here, not on the cluster
        return [_counted(run, key, retries) for key, run in batch]


def _counted(run: Run, key: str, retries: int) -> dict[str, Any]:
    """:func:`_attempts`, with the process that routed it (``_worker``: ``host:pid``) and the weather it read there
    (``_reads``: the weather cache's misses during the run)."""
    from pyroute_rel.weather import cache

    before = cache.stats()["misses"]
    row = _attempts(run, key, retries)
    row["_reads"] = max(0, cache.stats()["misses"] - before)
    row["_worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return row


#: Most runs in one task of the process-pool and dask engines (tasks of about a second each are batched up to this
#: many runs: fewer, larger tasks, still about 4 per worker or more for balance).
MAX_BATCH_RUNS = 8


def _group(run: Run) -> tuple[str, int]:
    """The runs that share their weather: same scenario and member (the grid is cheap to build again)."""
    return run.scenario, -1 if run.member is None else run.member


def task_batches(todo: Sequence[tuple[str, Run]], workers: int) -> list[list[tuple[str, Run]]]:
    """The runs of an engine's tasks: sorted by scenario, member and grid (so that a task's runs share their weather
    and grid) and split into batches of at most :data:`MAX_BATCH_RUNS` runs and about ``len(todo) / (4 workers)``;
    a batch never holds runs of two members (each member's runs are split into equal batches).

    >>> runs = [("k%d" % i, Run("s.toml", member=i % 3)) for i in range(10)]
    >>> [[k for k, _ in b] for b in task_batches(runs, 1)]
    [['k0', 'k3'], ['k6', 'k9'], ['k1', 'k4', 'k7'], ['k2', 'k5', 'k8']]
    """
    order = sorted(todo, key=lambda kr: (*_group(kr[1]), kr[1].grid))
    size = max(1, min(MAX_BATCH_RUNS, math.ceil(len(order) / (4 * max(1, workers)))))
    batches = []
    for _, runs in itertools.groupby(order, key=lambda kr: _group(kr[1])):
        group = list(runs)
        n = math.ceil(len(group) / size)
        batches += [group[len(group) * i // n : len(group) * (i + 1) // n] for i in range(n)]
    return batches


def place_batches(
    batches: Sequence[Sequence[tuple[str, Run]]], threads: Mapping[str, int]
) -> list[tuple[Sequence[tuple[str, Run]], str | None]]:
    """Each batch with the worker it should run on, so that each member's runs go to one worker: the members
    (:func:`task_batches`' groups), largest first, each to the worker that would then have the fewest runs per
    thread (``threads``: worker address -> threads; no worker: None). The batches keep their order.

    >>> b = [[("a", Run("s", member=0))] * 3, [("b", Run("s", member=1))] * 2, [("c", Run("s", member=2))] * 2]
    >>> [w for _, w in place_batches(b, {"w1": 1, "w2": 1})]
    ['w1', 'w2', 'w2']
    """
    groups: dict[tuple[str, int], int] = {}
    for b in batches:
        if b:
            groups[_group(b[0][1])] = groups.get(_group(b[0][1]), 0) + len(b)
    load = {w: 0.0 for w, n in threads.items() if n > 0}
    where: dict[tuple[str, int], str | None] = {}
    for g in sorted(groups, key=lambda g: -groups[g]):
        w = min(load, key=lambda w: (load[w] + groups[g]) / threads[w], default=None)
        where[g] = w
        if w is not None:
            load[w] += groups[g]
    return [(b, where[_group(b[0][1])] if b else None) for b in batches]


class BatchQueue:
    """The batches of a local pool (:func:`task_batches`), handed out as each worker asks for its next one, so that
    each member's runs stay on one worker: a worker takes the next batch of its member; else the first member not
    started yet, largest first (as :func:`place_batches`); else, when every member has started, the last waiting
    batch of the member with the most waiting, one it has read before first (it reads that member's weather,
    rather than stay idle while another worker has batches waiting). :meth:`put_back` makes a batch whose worker
    died waiting again, first of its member.

    >>> b = [[("a", Run("s", member=0))] * 3, [("b", Run("s", member=0))] * 3, [("c", Run("s", member=1))] * 2]
    >>> q = BatchQueue(b)
    >>> q.take("w1"), q.take("w2"), q.take("w2"), q.take("w1"), len(q)
    (0, 2, 1, None, 0)
    """

    def __init__(self, batches: Sequence[Sequence[tuple[str, Run]]]) -> None:
        self.waiting: dict[tuple[str, int], list[int]] = {}
        runs: dict[tuple[str, int], int] = {}
        self.group: list[tuple[str, int] | None] = []
        for i, b in enumerate(batches):
            g = _group(b[0][1]) if b else None
            self.group.append(g)
            if g is not None:
                self.waiting.setdefault(g, []).append(i)
                runs[g] = runs.get(g, 0) + len(b)
        self.unstarted = sorted(self.waiting, key=lambda g: -runs[g])  # stable: ties in the batches' order
        self.owner: dict[tuple[str, int], Any] = {}  # the worker that started each member
        self.current: dict[Any, tuple[str, int]] = {}
        self.read: dict[Any, set[tuple[str, int]]] = {}

    def __len__(self) -> int:
        """Batches waiting."""
        return sum(len(v) for v in self.waiting.values())

    def take(self, worker: Any) -> int | None:
        """The index of the batch ``worker`` runs next (None: none waiting)."""
        g = self.current.get(worker)
        if g is None or not self.waiting[g]:
            if self.unstarted:
                g = self.unstarted.pop(0)
                self.owner[g] = worker
            else:
                read = self.read.get(worker, set())
                waiting = [h for h, v in self.waiting.items() if v]
                g = min(waiting, key=lambda h: (h not in read, -len(self.waiting[h])), default=None)
                if g is None:
                    return None
            self.current[worker] = g
            self.read.setdefault(worker, set()).add(g)
        return self.waiting[g].pop(0) if self.owner[g] == worker else self.waiting[g].pop()

    def put_back(self, i: int) -> None:
        """Batch ``i`` waits again, first of its member."""
        g = self.group[i]
        if g is not None:
            self.waiting[g].insert(0, i)


def _processes(todo: Sequence[tuple[str, Run]], workers: int, retries: int) -> Iterator[dict[str, Any]]:
    """A local pool of ``workers`` processes (one single-process executor each), fed one batch at a time by a
    :class:`BatchQueue`, so that each member's weather is read by one worker; rows are yielded per finished batch.
    A worker that dies is replaced by a new process, and the batch it was running waits again, at most
    ``retries`` times per batch (then its runs are internal-error rows); an internal error of a run is tried again
    in its worker (:func:`run_batch`)."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("forkserver")
    batches = task_batches(todo, workers)
    queue, tries = BatchQueue(batches), [0] * len(batches)
    pools: dict[int, ProcessPoolExecutor] = {}
    running: dict[Future[list[dict[str, Any]]], tuple[int, int]] = {}  # future -> (worker, batch)

    def feed(w: int) -> None:
        i = queue.take(w)
        if i is not None:
            if w not in pools:
                pools[w] = ProcessPoolExecutor(
                    max_workers=1,
                    mp_context=ctx,
                    initializer=pool_worker_init,
                    initargs=(os.getpid(), _pin_threads, get_settings()),
                )
            running[pools[w].submit(run_batch, batches[i], retries)] = (w, i)

    try:
        for w in range(min(workers, len(batches))):  # never more processes than batches to run
            feed(w)
        while running:
            for fut in wait(running, return_when=FIRST_COMPLETED).done:
                w, i = running.pop(fut)
                try:
                    rows = fut.result()
                except BrokenProcessPool as exc:  # its process died: a new one runs the batch again
                    pools.pop(w).shutdown(wait=True)
                    rows = [] if tries[i] < retries else [_internal_row(run, key, exc) for key, run in batches[i]]
                    if tries[i] < retries:
                        tries[i] += 1
                        queue.put_back(i)
                except Exception as exc:  # pragma: no cover - run_batch records run errors itself
                    rows = [_internal_row(run, key, exc) for key, run in batches[i]]
                feed(w)  # its next batch starts before these rows are written
                yield from rows
    finally:
        for pool in pools.values():
            pool.shutdown(wait=True, cancel_futures=True)


def _dask_client(scheduler: str | None, workers: int | None, timeout_s: float) -> Any:
    from pyroute_rel.batch.cluster import dask_client

    return dask_client(scheduler, workers=workers, timeout_s=timeout_s, error=SweepError)


def _dask(
    todo: Sequence[tuple[str, Run]], scheduler: str | None, workers: int | None, retries: int, timeout_s: float
) -> Iterator[dict[str, Any]]:
    from distributed import as_completed

    from pyroute_rel.batch.cluster import scheduler_lost, watching_scheduler

    if scheduler is None:  # a LocalCluster: never more processes than batches to run
        workers = min(workers or 1, len(task_batches(todo, workers or 1)))
    client = _dask_client(scheduler, workers, timeout_s)
    kept = "the runs finished so far are kept; start a scheduler and run the same command to route the rest"
    with watching_scheduler(client, SweepError, kept):  # (closing the client too: it logs its lost connection)
        try:
            threads = client.nthreads()  # worker address -> threads
            placed = place_batches(task_batches(todo, workers or max(1, sum(threads.values()))), threads)
            rank: list[int] = []
            seen: dict[str | None, int] = {}
            for _, worker in placed:  # submitted in turns, each worker's first task first: none idle meanwhile
                rank.append(seen.get(worker, 0))
                seen[worker] = rank[-1] + 1
            futures = {}
            for i in sorted(range(len(placed)), key=lambda i: (rank[i], i)):  # run in the order given: priority -i
                b, worker = placed[i]  # each member on one worker; another may take it (when idle, or that one died)
                where = {"workers": [worker], "allow_other_workers": True} if worker is not None else {}
                key = f"pyroute-rel-runs-{b[0][0]}-{len(b)}"
                fut = client.submit(run_batch, b, retries, key=key, pure=False, retries=retries, priority=-i, **where)
                futures[fut] = b
            for fut in as_completed(futures, loop=client.loop):
                try:
                    yield from fut.result()
                except Exception as exc:  # failed retries + 1 times (or its workers died): recorded, not in the files
                    if scheduler_lost(client, exc):
                        raise
                    yield from (_internal_row(run, key, exc) for key, run in futures[fut])
        finally:
            close_client(client)


#: With ``engine="auto"``: sweeps of fewer runs than this are routed in this process (starting worker processes,
#: importing and opening the weather in each, costs several seconds), larger ones in a local pool of one process
#: per CPU this process may use (in this process when there is one CPU).
AUTO_MIN_RUNS = 16


def _cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def auto_engine(n_runs: int, cpus: int | None = None) -> tuple[str, int | None]:
    """The engine ``"auto"`` chooses for ``n_runs`` runs on ``cpus`` CPUs (default: this process's): ``("inline",
    None)`` below :data:`AUTO_MIN_RUNS` runs or on one CPU, else ``("processes", cpus)``.

    >>> auto_engine(10, 2), auto_engine(240, 2), auto_engine(240, 1)
    (('inline', None), ('processes', 2), ('inline', None))
    """
    cpus = _cpus() if cpus is None else cpus
    if n_runs < AUTO_MIN_RUNS or cpus < 2:
        return "inline", None
    return "processes", cpus


def _engine_rows(
    engine: str,
    todo: Sequence[tuple[str, Run]],
    *,
    workers: int | None,
    scheduler: str | None,
    retries: int,
    timeout_s: float,
) -> Iterator[dict[str, Any]]:
    if engine == "auto":
        engine, chosen = auto_engine(len(todo))
        workers = workers or chosen
    if engine == "inline":
        return _inline(todo, retries)
    if engine == "processes":
        return _processes(todo, _local_workers(workers or 2, "a pool"), retries)
    if scheduler is None and workers is not None:
        workers = _local_workers(workers, "a LocalCluster")
    return _dask(todo, scheduler, workers, retries, timeout_s)


def _local_workers(workers: int, what: str) -> int:
    """``workers`` processes on this machine, at most one per CPU this process may use (a warning when fewer)."""
    cpus = _cpus()
    if workers > cpus:
        warnings.warn(
            f"--workers {workers} is more than the {cpus} CPUs this process may use: {what} of {cpus} processes",
            PyrouteWarning,
            stacklevel=4,
        )
    return min(workers, cpus)


#: What ``--workers`` means to a sweep: the processes of a local pool or a LocalCluster (the engine ``"dask"``, and
#: the default of the CLI with ``--workers`` alone).
_WORKERS = WorkersOption(
    scheduler_engines=("dask",),
    with_scheduler="--workers starts a LocalCluster: not with --scheduler (the cluster's workers are used)",
    with_inline="--workers needs the processes, dask or auto engine (engine 'inline' routes in this process)",
)


def _check_engine(engine: str, workers: int | None, scheduler: str | None, retries: int, batch: int) -> None:
    check_engine_name(engine, ENGINES, SweepError)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise SweepError(f"--workers must be a whole number >= 1 (got {brief(workers)})")
    check_engine_combinations(engine, workers, scheduler, _WORKERS, SweepError)
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise SweepError(f"--retries must be a whole number >= 0 (got {brief(retries)})")
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise SweepError(f"--batch must be a whole number >= 1 (got {brief(batch)})")


def _check_run_options(runs: Any, out: Any, progress: Any, log: Any, flush_s: Any, connect_timeout_s: Any) -> list[Run]:
    """The other arguments of :func:`run_sweep`, checked before any run: a SweepError naming the argument."""
    if isinstance(runs, str | bytes | Mapping) or not isinstance(runs, Iterable):
        raise SweepError(f"runs must be a list of sweep runs (load_sweep(...).runs) (got {brief(runs)})")
    runs = list(runs)
    bad = next((r for r in runs if not isinstance(r, Run)), None)
    if bad is not None:
        raise SweepError(f"runs must hold sweep runs (pyroute_rel.batch.sweep.Run) (got {brief(bad)})")
    if out is not None:
        check_path(out, "out", SweepError)
    check_flag(progress, "progress", SweepError)
    if log is not None:
        check_callable(log, "log", SweepError)
    for name, value in (("flush_s", flush_s), ("connect_timeout_s", connect_timeout_s)):
        seconds = check_numbers(value, name, SweepError, missing=False, unit="s")
        if isinstance(value, bool) or seconds.shape != () or not seconds > 0:
            raise SweepError(f"{name} must be a finite number > 0 [s] (got {brief(value)})")
    return runs


def run_sweep(
    runs: Iterable[Run],
    *,
    engine: str = "auto",
    workers: int | None = None,
    scheduler: str | None = None,
    out: str | Path | None = None,
    retries: int = 2,
    progress: bool = False,
    log: Callable[[str], object] | None = None,
    batch: int = 32,
    flush_s: float = 5.0,
    connect_timeout_s: float = 10.0,
) -> pa.Table:
    """Route every run; the tidy table, one row per run in the order given (:data:`COLUMNS`).

    Parameters
    ----------
    runs : The runs (:class:`Run`; :func:`load_sweep` gives a specification's). Runs with the same key are routed
        once.
    engine : ``"auto"`` (:func:`auto_engine`: inline below :data:`AUTO_MIN_RUNS` runs to route or on one CPU, else
        processes, one per CPU or ``workers``), ``"inline"`` (this process), ``"processes"`` (a local pool of
        ``workers`` processes, default 2) or ``"dask"`` (``scheduler``'s cluster, else a ``LocalCluster`` of
        ``workers`` processes, default 1). The rows do not depend on the engine.
    workers : Processes of a local engine (not with ``"inline"`` nor with ``scheduler``: a SweepError); at most
        one per CPU this process may use (more is a :class:`~pyroute_rel.errors.PyrouteWarning`, and the CPUs) and
        one per task.
    out : Output folder: runs already recorded there are not routed again; each finished batch (``batch`` runs or
        ``flush_s`` seconds [s], whichever first) is written at once (see the module notes).
    retries : How often a run is tried again after an internal error, and a task after its worker died (dask's
        ``retries``; the process pool is restarted); a user error is never retried.
    progress : Show a progress bar (runs done, failed, rate) on stderr.
    log : Called with one line of news, e.g. ``"12 done, 228 to run"``.
    batch, flush_s : A part file is written every ``batch`` finished runs, or ``flush_s`` [s] after the last one.
    connect_timeout_s : How long to try reaching ``scheduler`` [s].

    Returns
    -------
    pyarrow.Table
        Internal errors (after the retries) are rows with status ``error`` and a message starting
        ``"internal error"``, not written to ``out``. The schema's metadata :data:`READS_METADATA` says, as JSON,
        how often each process read the weather of each scenario and member for the runs routed in this call: a
        list of ``{"worker": "HOST:PID", "scenario": ..., "member": ..., "reads": N}`` (the weather cache's
        misses, :mod:`pyroute_rel.weather.cache`; a run that reads several files counts each).

    Raises
    ------
    SweepError
        For an unknown engine, bad options, or a scheduler that cannot be reached.
    """

    _check_engine(engine, workers, scheduler, retries, batch)
    runs = _check_run_options(runs, out, progress, log, flush_s, connect_timeout_s)
    for scenario in sorted({r.scenario for r in runs}):
        _check_routed_by_the_dp(Path(scenario))
    with _writing_to(None if out is None else Path(out)):
        return _run_sweep(runs, out, engine, workers, scheduler, batch, flush_s, retries, connect_timeout_s,
                          progress, log)  # fmt: skip


@contextmanager
def _writing_to(out: Path | None) -> Iterator[None]:
    """Hold the output folder for one sweep: a second sweep into it (another process, or this one) refuses with one
    line instead of routing and recording the same runs again (their rows doubled). The lock is the kernel's
    (``flock`` on the folder itself: released when the process ends, however it ends; nothing written for it). A
    folder made only to hold the lock is removed if the sweep writes nothing into it."""
    if out is not None:
        _check_layout(out)
    if out is None or fcntl is None:  # (no flock: Windows)
        yield
        return
    made = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd = os.open(out, os.O_RDONLY)
    except OSError as exc:
        raise SweepError(f"out folder '{brief_path(out)}' cannot be used: {exc.strerror or exc}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise SweepError(
                f"another sweep is writing to '{brief_path(out)}': wait for it to finish, or give another --out"
            ) from None
        yield
    finally:
        os.close(fd)  # (releases the lock)
        if made:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if nothing was written


def _check_layout(out: Path) -> None:
    """The folders a sweep writes into ``out`` (:data:`RUNS_DIR`, :data:`TRACKS_DIR`) are folders of its own where
    they exist: not a file, nor a link that would send the runs or the tracks elsewhere (issue 34)."""
    for name in (RUNS_DIR, TRACKS_DIR):
        target = out / name
        if target.is_symlink() or (os.path.lexists(target) and not target.is_dir()):
            kind = "a link" if target.is_symlink() else "not a folder"
            raise SweepError(
                f"{brief_path(target)} is {kind}: the sweep writes its {'runs' if name == RUNS_DIR else 'tracks'} "
                "there; move it away or give another --out (nothing was written)"
            )


def _run_sweep(
    runs: list[Run],
    out: str | Path | None,
    engine: str,
    workers: int | None,
    scheduler: str | None,
    batch: int,
    flush_s: float,
    retries: int,
    connect_timeout_s: float,
    progress: bool,
    log: Callable[[str], object] | None,
) -> pa.Table:
    from pyroute_rel.progress import progress_bar

    keyed = [(run_key(r), r) for r in runs]
    store = _Store(Path(out), batch=batch, flush_s=flush_s) if out is not None else None
    done = {r["key"]: r for r in read_runs(out, set_aside=True).to_pylist()} if out is not None else {}
    todo = list({k: r for k, r in keyed if k not in done}.items())
    if log is not None:
        log(f"{len(set(k for k, _ in keyed) & set(done))} done, {len(todo)} to run")
    bar = progress_bar(len(todo), enabled=progress, desc="sweep", unit="run")
    failed = 0
    reads: dict[tuple[str, str, int | None], int] = {}  # (worker, scenario, member) -> weather files read
    try:
        for row in (
            _engine_rows(
                engine, todo, workers=workers, scheduler=scheduler, retries=retries, timeout_s=connect_timeout_s
            )
            if todo
            else ()
        ):
            if store is not None:
                store.add(row)
            done[row["key"]] = row
            if "_worker" in row:
                where = (row["_worker"], row["scenario"], row["member"])
                reads[where] = reads.get(where, 0) + row["_reads"]
            failed += row["status"] != "ok"
            if hasattr(bar, "set_postfix_str"):
                bar.set_postfix_str(f"failed {failed}", refresh=False)
            bar.update(1)
    finally:
        bar.close()
        if store is not None:
            store.flush()
    reads_json = json.dumps([{"worker": w, "scenario": sc, "member": m, "reads": n} for (w, sc, m), n in reads.items()])
    return _table([done[k] for k, _ in keyed]).replace_schema_metadata({READS_METADATA: reads_json})
