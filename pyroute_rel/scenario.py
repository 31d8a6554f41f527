"""Scenario files (TOML): what to route, on which grid, with which boat, weather and failure model.

A scenario has these tables (unknown tables or keys are refused with the file and key named)::

    [route]    start = [lon, lat]  finish = [lon, lat]  departure = "2018-06-01T00:00:00Z"
    [grid]     layout = "angular" | "square"  n_ranks = 160  n_nodes = 160  (all optional; see grid.plan_grid)
               spacing_km, aspect, half_width_km, max_deviation_deg, samples_per_arc = 1 | sample_km = 25,
               refine = 0
    [boat]     polar = "maribot_vane" | "path/to/file.pol"   beyond = "clamp" | "forbid"
    [weather]  kind = "uniform" (tws_kn, twd_deg, hs_m, wave_dir_deg, ... and [[weather.patch]] boxes)
               kind = "file"    (paths = [...], see pyroute_rel.weather.readers)
    [failure]  model = "dickson2018" | "path/to/model.toml" | "none"   apf = 1.0

Paths are relative to the scenario file's folder.
"""

from __future__ import annotations

import math
import numbers
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .cost import WaveLoss
from .errors import FailureModelError, PyrouteError, ScenarioError, brief, show
from .geodesy import along_track_km, crossing_fraction, distance_km, intermediate_point
from .grid import DEFAULT_N_RANKS, DEFAULT_SAMPLE_KM, LAYOUTS, Grid, auto_samples, plan_grid
from .obstacles.mask import Avoid, check_points, obstacle_mask
from .polar import BEYOND_MODES, Polar, get_polar
from .route import GridTrack, Route, build_route, join_routes, route_on_grid
from .solve import RoutingProblem
from .weather import UniformWeather, WeatherSource

if TYPE_CHECKING:
    from .failure import FailureModel

__all__ = ["Scenario", "load_scenario", "scenario_from_mapping", "parse_departure", "WEATHER_KINDS"]

#: Allowed keys per table.
SCHEMA: dict[str, dict[str, str]] = {
    "route": {
        "start": "[lon, lat] [deg]",
        "finish": "[lon, lat] [deg]",
        "departure": "ISO 8601 UTC time",
        "start_line": "[[lon, lat], [lon, lat]] [deg]: start anywhere on this line",
        "finish_line": "[[lon, lat], [lon, lat]] [deg]: the voyage ends at its first crossing",
        "waypoints": "[[lon, lat], ...] [deg]: marks to pass, in order",
        "time_step_h": "time lattice of the time-expanded DP [h]",
        "max_wait_h": "longest wait at a node [h] (needs time_step_h)",
        "prune": "true (default): cost only the arcs that can still win (same route); false: cost every arc",
    },
    "grid": {
        "layout": "'angular' (default) or 'square' (the paper's grid)",
        "n_ranks": "whole number >= 1",
        "n_nodes": "whole number >= 1: nodes per rank of the square layout (the angular layout derives its own)",
        "spacing_km": "lateral node spacing [km]",
        "aspect": "rank spacing / lateral spacing (angular layout)",
        "half_width_km": "distance from the great circle to the outermost nodes [km] (angular layout)",
        "max_deviation_deg": "largest arc angle from the rank direction [deg]",
        "samples_per_arc": "weather samples per arc (default: as many as sample_km asks)",
        "sample_km": "weather samples along arcs at most this far apart [km] (default 25)",
        "refine": "whole number >= 0: corridor refinements of the track (0 = none; see pyroute_rel.refine)",
    },
    "boat": {
        "polar": "built-in name or polar file",
        "beyond": f"one of {list(BEYOND_MODES)}",
        "wave_speed_loss": "[[hs_m, factor], ...]: polar speed x factor(Hs), linear, from Hs = 0",
    },
    "weather": {},  # validated by the weather kind
    "failure": {"model": "model name, model file, or 'none'", "apf": "probability in [0, 1]"},
    "avoid": {
        "land": "true (default) or false: forbid arcs over land (offline GSHHG shoreline)",
        "margin_km": "keep this far from any coast [km]",
        "resolution": "GSHHG resolution: 'intermediate' (default), 'low', 'high', 'full'",
        "zones": "GeoJSON files of exclusion zones (relative to the scenario file)",
    },
}
WEATHER_KINDS = ("uniform", "file")
#: Consecutive marks of a course (start, waypoints, finish) must be at least this far apart [km].
MIN_LEG_KM = 1.0


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. Build with :func:`load_scenario` or :func:`scenario_from_mapping`."""

    source: str
    start: tuple[float, float]
    finish: tuple[float, float]
    departure: np.datetime64
    n_ranks: int | None
    n_nodes: int | None
    spacing_km: float | None
    max_deviation_deg: float | None
    samples_per_arc: int | None
    polar: Polar
    beyond: str
    weather: WeatherSource
    failure_model: str | None
    apf: float
    base_dir: Path
    time_step_h: float | None = None
    max_wait_h: float = 0.0
    prune: bool = True
    layout: str = "angular"
    aspect: float | None = None
    half_width_km: float | None = None
    start_line: tuple[tuple[float, float], tuple[float, float]] | None = None
    finish_line: tuple[tuple[float, float], tuple[float, float]] | None = None
    waypoints: tuple[tuple[float, float], ...] = ()
    avoid: Avoid = field(default_factory=Avoid)
    wave_loss: WaveLoss | None = None
    refine: int = 0
    sample_km: float | None = None

    def with_options(self, **changes: Any) -> Scenario:
        """A copy with some settings changed (validated like the file's, with the command-line option named).

        ``None`` leaves a setting as it is (the CLI passes None for options not given), so a setting cannot be reset
        to None here: build the scenario from a mapping without it (:func:`scenario_from_mapping`) instead.
        """
        checked: dict[str, Any] = {}
        for key, value in changes.items():
            if value is None:
                continue
            if key in ("n_ranks", "n_nodes"):
                checked[key] = _int(value, f"--{key.replace('_', '-')}", 1)
            elif key == "refine":
                checked[key] = _int(value, "--refine", 0)
            elif key == "sample_km":
                checked[key] = _sample_km(value, "--sample-km")
            elif key == "apf":
                checked[key] = _prob(value, "--apf")
            elif key == "failure_model":
                if not str(value).strip():
                    raise ScenarioError("--failure-model needs a shipped model name, a model file or 'none' (got '')")
                checked[key] = None if str(value).lower() == "none" else str(value)
            elif key == "departure":
                checked[key] = parse_departure(value, "--departures")
            elif key == "layout":
                if value not in LAYOUTS:
                    raise ScenarioError(f"--layout must be one of {list(LAYOUTS)} (got {value!r})")
                checked[key] = value
            elif key in ("land", "prune"):
                if not isinstance(value, bool | np.bool_):
                    raise ScenarioError(f"{key} must be True or False (got {value!r})")
                if key == "land":
                    checked["avoid"] = replace(self.avoid, land=bool(value))
                else:
                    checked[key] = bool(value)
            elif key in (
                "spacing_km",
                "max_deviation_deg",
                "samples_per_arc",
                "beyond",
                "time_step_h",
                "max_wait_h",
                "aspect",
                "half_width_km",
            ):
                checked[key] = value
            else:
                raise ScenarioError(f"unknown scenario option {key!r}")
        return replace(self, **checked)

    def marks(self) -> list[tuple[str, tuple[float, float]]]:
        """The course's marks in order, named by their scenario field: start, waypoints, finish."""
        return [
            ("[route].start", self.start),
            *((f"[route].waypoints[{i}]", w) for i, w in enumerate(self.waypoints)),
            ("[route].finish", self.finish),
        ]

    def make_grid(self) -> Grid:
        """The scenario's rank digraph (the first leg's when the course has waypoints)."""
        return self.leg_grids()[0]

    def leg_grids(self) -> list[Grid]:
        """One grid per leg: start → waypoints → finish. Legs share the rank spacing of the whole course."""
        marks = [self.start, *self.waypoints, self.finish]
        lengths = [float(distance_km(*a, *b)) for a, b in zip(marks[:-1], marks[1:], strict=True)]
        total = sum(lengths)
        grids = []
        for i, (a, b) in enumerate(zip(marks[:-1], marks[1:], strict=True)):
            n_ranks = self.n_ranks
            n_nodes = self.n_nodes
            if len(marks) > 2:
                n = self.n_ranks if self.n_ranks is not None else DEFAULT_N_RANKS
                n_ranks = max(1, round(n * lengths[i] / total))
            grids.append(
                plan_grid(
                    a,
                    b,
                    layout=self.layout,
                    n_ranks=n_ranks,
                    n_nodes=n_nodes,
                    spacing_km=self.spacing_km,
                    aspect=self.aspect,
                    half_width_km=self.half_width_km,
                    max_deviation_deg=self.max_deviation_deg,
                    start_line=self.start_line if i == 0 else None,
                    finish_line=self.finish_line if i == len(marks) - 2 else None,
                )
            )
        return grids

    def load_failure(self) -> FailureModel | None:
        """The compiled failure model, or None. Refuses a model that needs fields the weather lacks."""
        if self.failure_model is None:
            return None
        from .failure import load_failure_model

        name = self.failure_model
        candidate = self.base_dir / name
        if ("/" in name or name.endswith(".toml")) and candidate.exists():
            name = str(candidate)
        try:
            model = load_failure_model(name)
        except FailureModelError as exc:
            raise FailureModelError(f"{self.source}: [failure].model {self.failure_model!r}: {exc}") from None
        have = getattr(self.weather, "fields", None)
        if have is not None:
            needs = {
                "hs_m": {"hs_m"},
                "awd_deg": {"wave_dir_deg"},
                "tws_kn": {"tws_kn"},
                "twa_deg": {"twd_deg"},
                "wave_period_s": {"wave_period_s"},
            }
            missing = sorted({f for q in model.quantities for f in needs.get(q, set())} - set(have))
            if missing:
                raise ScenarioError(
                    f"failure model {model.name!r} needs {', '.join(missing)} but the weather provides only "
                    f"{', '.join(sorted(have))}: add a file with those fields to [weather].paths or choose "
                    "another model (--failure-model none)"
                )
        return model

    def problem(
        self, *, failure: FailureModel | None = None, blocked: Any = "auto", grid: Grid | None = None
    ) -> RoutingProblem:
        """The routing problem (weather, polar, failure model, apf) for a grid (default: the scenario's).

        With ``samples_per_arc`` unset the number of weather samples per arc follows the grid
        (:func:`~pyroute_rel.grid.auto_samples`).
        """
        samples = self.samples_per_arc
        if grid is None:
            grid = self.make_grid()
        km = self.sample_km
        if samples is None and km is None:
            samples = auto_samples(grid, sample_km=DEFAULT_SAMPLE_KM)
        elif samples is None and km is not None:  # the user's spacing is kept: never a silent cap
            samples = auto_samples(grid, sample_km=km, max_samples=10**6)
            if samples > 64:
                raise ScenarioError(
                    f"sample_km = {km:g} needs {samples} weather samples per arc on this grid (at "
                    "most 64): use a larger sample_km or more ranks"
                )
        if blocked == "auto":
            blocked = obstacle_mask(grid, self.avoid)
        assert samples is not None
        return RoutingProblem(
            departure=self.departure,
            weather=self.weather,
            polar=self.polar,
            failure=failure if failure is not None else self.load_failure(),
            apf=self.apf,
            samples=samples,
            beyond=self.beyond,
            blocked=blocked,
            time_step_h=self.time_step_h,
            max_wait_h=self.max_wait_h,
            wave_loss=self.wave_loss,
            prune=self.prune,
        )

    def route(self, *, progress: bool = False, grids: list[Grid] | None = None) -> Route:
        """Route the scenario (forward DP on its grid; leg after leg through waypoints).

        Legs are solved in order, each departing when the previous one arrives at its mark; under FIFO
        weather this is optimal for the whole course, since the earliest arrival at a mark is best for what
        follows. ``grids``: the legs' grids from an earlier :meth:`leg_grids` of this course, to reuse what is
        cached on them (arc geometry, obstacle masks) when routing it again, e.g. for another departure.
        """
        check_points(self.marks(), self.avoid)
        failure = self.load_failure()
        routes = []
        departure = self.departure
        for grid in self.leg_grids() if grids is None else grids:
            # the weather must cover the leg's end points and its departure; cells missing elsewhere in the
            # (wider) grid are NaN and forbid the arcs through them
            s_lon, s_lat = grid.start_points
            lons = [*s_lon, grid.finish[0]]
            lats = [*s_lat, grid.finish[1]]
            self.weather.check_coverage((min(lons), max(lons)), (min(lats), max(lats)), (departure, departure))
            leg_problem = replace(self.problem(failure=failure, grid=grid), departure=departure)
            leg = route_on_grid(grid, leg_problem, progress=progress)
            if self.refine:
                leg = self._refined(leg, leg_problem)
            routes.append(leg)
            departure = routes[-1].arrival
        route = routes[0] if len(routes) == 1 else join_routes(routes)
        return replace(
            route, meta={**route.meta, "scenario": self.source, "land": self.avoid.land}, zones=self.avoid.zones
        )

    def _refined(self, route: Route, problem: RoutingProblem) -> Route:
        """The route with its track refined in corridors (:mod:`pyroute_rel.refine`); the grid, its DP result and
        nodes stay those of the grid routed on, the levels are reported in ``meta["refine"]``."""
        from .refine import refine

        grid = route.grid

        def problem_for(corridor: Grid) -> RoutingProblem:
            return replace(problem, blocked=obstacle_mask(corridor, self.avoid, parent=grid))

        c_grid, c_problem, c_result, levels = refine(
            grid, problem, route.dp, levels=self.refine, problem_for=problem_for
        )
        better = c_grid is not grid
        out = (
            replace(
                build_route(c_grid, c_problem, c_result), grid=grid, nodes=route.nodes, dp=route.dp, problem=problem
            )
            if better
            else route
        )
        refined = {
            "levels": [
                {
                    "half_width_km": lv.half_width_km,
                    "spacing_km": lv.spacing_km,
                    "voyage_time_h": lv.voyage_time_h,
                    "arcs_evaluated": lv.arcs_evaluated,
                }
                for lv in levels
            ],
            "grid_voyage_time_h": route.voyage_time_h,
        }
        return replace(
            out,
            meta={**route.meta, "refine": refined},
            grid_track=GridTrack(route.lon_deg, route.lat_deg, route.voyage_time_h),  # for the map
        )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file.

    Raises :class:`~pyroute_rel.errors.ScenarioError` naming the file and the field for any problem.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(f"{show(p)}: scenario file not found") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ScenarioError(f"{show(p)}: cannot read scenario file ({exc.__class__.__name__}: {show(exc)})") from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{p}: not valid TOML ({exc})") from None
    return scenario_from_mapping(table, base_dir=p.parent, source=str(p))


def scenario_from_mapping(
    table: Mapping[str, Any], *, base_dir: str | Path = ".", source: str = "<scenario>"
) -> Scenario:
    """Validate a scenario given as nested mappings (the parsed TOML)."""
    try:
        return _parse(table, Path(base_dir), source)
    except PyrouteError as exc:
        msg = str(exc)
        if not msg.startswith(source):
            raise type(exc)(f"{source}: {msg}") from None
        raise


def _parse(table: Mapping[str, Any], base_dir: Path, source: str) -> Scenario:  # noqa: C901 - to split
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
    route = table.get("route", {})
    start_line = _line(route["start_line"], "[route].start_line") if "start_line" in route else None
    finish_line = _line(route["finish_line"], "[route].finish_line") if "finish_line" in route else None
    if "start" not in route and start_line is not None:
        route = {**route, "start": list(_midpoint(start_line))}
    if "finish" not in route and finish_line is not None:
        if "start" not in route:
            raise ScenarioError("[route].start is missing ([lon, lat] [deg], or a start_line)")
        route = {**route, "finish": list(_nearest_on_line(finish_line, _point(route["start"], "[route].start")))}
    for key in ("start", "finish"):
        if key not in route:
            raise ScenarioError(f"[route].{key} is missing ({SCHEMA['route'][key]})")
    start = _point(route["start"], "[route].start")
    finish = _point(route["finish"], "[route].finish")
    for name, point, line in (("start", start, start_line), ("finish", finish, finish_line)):
        if line is not None and (off := _off_line_km(line, point)) > 1.0:
            raise ScenarioError(f"[route].{name} {list(point)} must lie on [route].{name}_line ({off:.1f} km off it)")
    if start_line is not None and finish_line is not None:
        frac = crossing_fraction(*start_line[0], *start_line[1], *finish_line[0], *finish_line[1])
        if np.isfinite(frac).any():
            raise ScenarioError("[route].start_line crosses [route].finish_line: the course would end where it starts")
    raw_wp = route.get("waypoints", [])
    if not isinstance(raw_wp, list):
        raise ScenarioError("[route].waypoints must be a list of [lon, lat] points [deg]")
    waypoints = tuple(_point(p, f"[route].waypoints[{i}]") for i, p in enumerate(raw_wp))
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
    departure = parse_departure(route.get("departure", "2018-06-01T00:00:00Z"), "[route].departure")
    step = route.get("time_step_h")
    if step is not None:
        step = _positive(step, "[route].time_step_h")
        if step > 48.0:
            raise ScenarioError(f"[route].time_step_h must be in (0, 48] [h] (got {step:g})")
    max_wait = route.get("max_wait_h", 0.0)
    max_wait = _number(max_wait, "[route].max_wait_h")
    if max_wait < 0:
        raise ScenarioError(f"[route].max_wait_h must be >= 0 [h] (got {max_wait:g})")
    if max_wait > 0 and step is None:
        raise ScenarioError("[route].max_wait_h needs [route].time_step_h (waiting is modelled on a time lattice)")
    if step is not None and max_wait / step > 10_000:
        raise ScenarioError(
            f"[route].max_wait_h / [route].time_step_h must be at most 10000 wait steps per node (got "
            f"{max_wait:g} h / {step:g} h): use a larger time_step_h"
        )
    prune = route.get("prune", True)
    if not isinstance(prune, bool):
        raise ScenarioError(f"[route].prune must be true or false (got {prune!r})")

    grid = table.get("grid", {})
    layout = grid.get("layout", "angular")
    if layout not in LAYOUTS:
        raise ScenarioError(f"[grid].layout must be one of {list(LAYOUTS)} (got {layout!r})")
    n_ranks = None if "n_ranks" not in grid else _int(grid["n_ranks"], "[grid].n_ranks", 1)
    n_nodes = None if "n_nodes" not in grid else _int(grid["n_nodes"], "[grid].n_nodes", 1)
    aspect = None if "aspect" not in grid else _positive(grid["aspect"], "[grid].aspect")
    if aspect is not None and not 0.01 <= aspect <= 1000.0:
        raise ScenarioError(f"[grid].aspect (rank spacing / lateral spacing) must be in [0.01, 1000] (got {aspect:g})")
    half_width = None if "half_width_km" not in grid else _number(grid["half_width_km"], "[grid].half_width_km")
    if half_width is not None and half_width < 0:
        raise ScenarioError(f"[grid].half_width_km must be >= 0 [km] (got {half_width:g})")
    spacing = grid.get("spacing_km")
    if spacing is not None:
        spacing = _positive(spacing, "[grid].spacing_km")
    dev = grid.get("max_deviation_deg")
    if dev is not None:
        dev = _number(dev, "[grid].max_deviation_deg")
        if not 0.0 < dev < 90.0:
            raise ScenarioError(f"[grid].max_deviation_deg must be in (0, 90) [deg] (got {dev:g})")
    samples = None if "samples_per_arc" not in grid else _int(grid["samples_per_arc"], "[grid].samples_per_arc", 1)
    if samples is not None and samples > 64:
        raise ScenarioError(f"[grid].samples_per_arc must be at most 64 (got {samples})")
    refine = _int(grid.get("refine", 0), "[grid].refine", 0)
    sample_km = None
    if "sample_km" in grid:
        sample_km = _sample_km(grid["sample_km"], "[grid].sample_km")
        if samples is not None:
            raise ScenarioError("[grid]: give samples_per_arc (a count) or sample_km (a spacing), not both")

    boat = table.get("boat", {})
    polar_name = boat.get("polar", "maribot_vane")
    if not isinstance(polar_name, str):
        raise ScenarioError(f"[boat].polar must be a built-in name or a file path (got {polar_name!r})")
    polar = get_polar(polar_name, base_dir=base_dir)
    wave_loss = None
    if "wave_speed_loss" in boat:
        raw = boat["wave_speed_loss"]
        try:
            if not isinstance(raw, list) or not all(isinstance(r, list) and len(r) == 2 for r in raw):
                raise ValueError("expected a list of [hs_m, factor] pairs")
            wave_loss = WaveLoss(
                hs_m=[_number(r[0], "[boat].wave_speed_loss") for r in raw],
                factor=[_number(r[1], "[boat].wave_speed_loss") for r in raw],
            )
        except ValueError as exc:
            raise ScenarioError(f"[boat].wave_speed_loss: {exc} (got {raw!r})") from None
    beyond = boat.get("beyond", "clamp")
    if beyond not in BEYOND_MODES:
        raise ScenarioError(f"[boat].beyond must be one of {list(BEYOND_MODES)} (got {beyond!r})")

    avoid = _avoid(table.get("avoid", {}), base_dir)
    grid_sizes = {"half_width_km": half_width, "n_ranks": n_ranks, "n_nodes": n_nodes}
    bbox = _course_bbox(
        start,
        finish,
        waypoints,
        start_line,
        finish_line,
        grid_table={k: v for k, v in grid_sizes.items() if v is not None},
    )
    weather = _weather(table.get("weather"), base_dir, bbox=bbox, departure=departure)

    failure = table.get("failure", {})
    model = failure.get("model", None)
    if model is not None and not isinstance(model, str):
        raise ScenarioError(f"[failure].model must be a model name or path (got {model!r})")
    if model is not None and model.lower() == "none":
        model = None
    apf = _prob(failure.get("apf", 1.0), "[failure].apf")
    return Scenario(
        source=source,
        start=start,
        finish=finish,
        departure=departure,
        n_ranks=n_ranks,
        n_nodes=n_nodes,
        spacing_km=spacing,
        max_deviation_deg=dev,
        samples_per_arc=samples,
        polar=polar,
        beyond=beyond,
        weather=weather,
        failure_model=model,
        apf=apf,
        base_dir=base_dir,
        time_step_h=step,
        max_wait_h=max_wait,
        prune=prune,
        layout=layout,
        aspect=aspect,
        half_width_km=half_width,
        start_line=start_line,
        finish_line=finish_line,
        waypoints=waypoints,
        avoid=avoid,
        wave_loss=wave_loss,
        refine=refine,
        sample_km=sample_km,
    )


def _avoid(raw: Mapping[str, Any], base_dir: Path) -> Avoid:
    land = raw.get("land", True)
    if not isinstance(land, bool):
        raise ScenarioError(f"[avoid].land must be true or false (got {land!r})")
    margin = _number(raw.get("margin_km", 0.0), "[avoid].margin_km")
    if not 0.0 <= margin <= 200.0:
        raise ScenarioError(f"[avoid].margin_km must be in [0, 200] [km] (got {margin:g})")
    resolution = raw.get("resolution", "intermediate")
    from .obstacles.land import RESOLUTIONS
    from .obstacles.zones import load_zones

    if not isinstance(resolution, str) or resolution not in RESOLUTIONS:
        raise ScenarioError(f"[avoid].resolution must be one of {list(RESOLUTIONS)} (got {resolution!r})")
    paths = raw.get("zones", [])
    if isinstance(paths, str):
        paths = [paths]
    if not isinstance(paths, list) or not all(isinstance(p, str) for p in paths):
        raise ScenarioError(f"[avoid].zones must be a list of GeoJSON file names (got {paths!r})")
    zones = load_zones(paths, base_dir=base_dir) if paths else ()
    return Avoid(land=land, margin_km=margin, resolution=resolution, zones=tuple(zones))


def _course_bbox(
    start: Any, finish: Any, waypoints: Any, start_line: Any, finish_line: Any, *, grid_table: Mapping[str, Any]
) -> tuple[float, float, float, float]:
    """A lon/lat box [deg] sure to hold the grid: the course's points widened by the grid's half-width."""
    pts = [start, finish, *waypoints, *(start_line or ()), *(finish_line or ())]
    lon = np.array([p[0] for p in pts])
    lat = np.array([p[1] for p in pts])
    length = float(distance_km(*start, *finish))
    half = grid_table.get("half_width_km")
    if half is None:
        n_ranks = grid_table.get("n_ranks", DEFAULT_N_RANKS)
        n_nodes = grid_table.get("n_nodes")
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


def _weather(raw: Any, base_dir: Path, *, bbox: Any = None, departure: Any = None) -> WeatherSource:
    if raw is None:
        raise ScenarioError('[weather] is missing (kind = "uniform" with tws_kn and twd_deg, or kind = "file")')
    if not isinstance(raw, Mapping):
        raise ScenarioError("[weather] must be a table")
    kind = raw.get("kind", "uniform")
    if kind == "uniform":
        return UniformWeather.from_mapping(raw)
    if kind == "file":
        from .weather.readers import weather_from_mapping

        window = None
        if departure is not None:  # the voyage window: from departure, for up to 120 days
            window = (departure - np.timedelta64(1, "h"), departure + np.timedelta64(120, "D"))
        return weather_from_mapping(raw, base_dir=base_dir, bbox=bbox, time_window=window)
    raise ScenarioError(f"[weather].kind must be one of {list(WEATHER_KINDS)} (got {kind!r})")


def parse_departure(value: Any, where: str = "departure") -> np.datetime64:
    """Parse an ISO 8601 time (``Z`` or ``+00:00`` offsets; naive times are taken as UTC)."""
    import datetime as dt

    if isinstance(value, dt.datetime):
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
    except OverflowError:
        raise ScenarioError(f"{where} is out of range (got {value!r})") from None
    if not 1900 <= t.year <= 2200:
        raise ScenarioError(f"{where} must be between the years 1900 and 2200 (got {value!r})")
    return np.datetime64(t, "s")


def _number(v: Any, where: str) -> float:
    try:
        ok = not isinstance(v, bool) and isinstance(v, numbers.Real) and math.isfinite(float(v))
    except OverflowError:  # an int beyond the float range
        ok = False
    if not ok:
        raise ScenarioError(f"{where} must be a finite number (got {brief(v)})")
    return float(v)


def _positive(v: Any, where: str) -> float:
    x = _number(v, where)
    if x <= 0:
        raise ScenarioError(f"{where} must be positive (got {v!r})")
    return x


def _prob(v: Any, where: str) -> float:
    try:
        x = float(v) if isinstance(v, str) else _number(v, where)
    except ValueError:
        raise ScenarioError(f"{where} must be a probability in [0, 1] (got {v!r})") from None
    if not 0.0 <= x <= 1.0 or isinstance(v, bool):
        raise ScenarioError(f"{where} must be a probability in [0, 1] (got {v!r})")
    return x


def _sample_km(v: Any, where: str) -> float:
    km = _number(v, where)
    if not 0.1 <= km <= 1000.0:
        raise ScenarioError(f"{where} must be in [0.1, 1000] [km] (got {km:g})")
    return km


def _int(v: Any, where: str, lo: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer):  # "20" is refused, as for every number
        raise ScenarioError(f"{where} must be a whole number (got {v!r})")
    if v < lo:
        raise ScenarioError(f"{where} must be >= {lo} (got {brief(v)})")
    if v > 100_000:
        raise ScenarioError(f"{where} must be at most 100000 (got {brief(v)})")
    return int(v)


def _line(v: Any, where: str) -> tuple[tuple[float, float], tuple[float, float]]:
    if not isinstance(v, list | tuple) or len(v) != 2:
        raise ScenarioError(f"{where} must be [[lon, lat], [lon, lat]] in degrees (got {v!r})")
    a, b = _point(v[0], f"{where}[0]"), _point(v[1], f"{where}[1]")
    if a == b:
        raise ScenarioError(f"{where} end points must differ (got {v!r})")
    return a, b


def _midpoint(line: tuple[tuple[float, float], tuple[float, float]]) -> tuple[float, float]:
    lon, lat = intermediate_point(*line[0], *line[1], 0.5)
    return float(lon), float(lat)


def _nearest_on_line(
    line: tuple[tuple[float, float], tuple[float, float]], p: tuple[float, float]
) -> tuple[float, float]:
    """The point of a great-circle segment nearest to p (the grid aims there by default)."""
    (c_lon, c_lat), (d_lon, d_lat) = line
    length = float(distance_km(c_lon, c_lat, d_lon, d_lat))
    along = float(along_track_km(c_lon, c_lat, d_lon, d_lat, *p))
    lon, lat = intermediate_point(c_lon, c_lat, d_lon, d_lat, min(max(along / length, 0.0), 1.0))
    return float(lon), float(lat)


def _off_line_km(line: tuple[tuple[float, float], tuple[float, float]], point: tuple[float, float]) -> float:
    """Distance [km] from a point to a great-circle segment: to the segment's point nearest it."""
    return float(distance_km(*point, *_nearest_on_line(line, point)))


def _point(v: Any, where: str) -> tuple[float, float]:
    if not isinstance(v, list | tuple) or len(v) != 2:
        raise ScenarioError(f"{where} must be [lon, lat] in degrees (got {v!r})")
    lon, lat = _number(v[0], f"{where}[0] (lon)"), _number(v[1], f"{where}[1] (lat)")
    if not -180.0 <= lon <= 180.0:
        raise ScenarioError(f"{where} longitude must be in [-180, 180] [deg] (got {lon:g})")
    if not -90.0 <= lat <= 90.0:
        raise ScenarioError(f"{where} latitude must be in [-90, 90] [deg] (got {lat:g})")
    return lon, lat
