"""Scenarios: what to route, on which grid, with which boat, weather and failure model; and routing them.

:func:`load_scenario` reads a TOML file (its tables: :mod:`pyroute_rel.config`) into a :class:`Scenario`, and
:meth:`Scenario.route` routes it: the one entry point of the library.
"""

from __future__ import annotations

import tomllib
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties
from pyroute_rel.config import parse_departure, parse_options, parse_tables
from pyroute_rel.errors import (
    FailureModelError,
    NoFeasibleRouteError,
    PyrouteError,
    PyrouteWarning,
    ScenarioError,
    brief,
    check_flag,
    check_instance,
    check_path,
)
from pyroute_rel.files import brief_path, read_regular_bytes
from pyroute_rel.geodesy import distance_km
from pyroute_rel.obstacles.mask import Avoid, check_points, obstacle_mask
from pyroute_rel.obstacles.zones import zones_outside
from pyroute_rel.planners.settings import PlannerSettings
from pyroute_rel.routing.grid import DEFAULT_N_RANKS, DEFAULT_SAMPLE_KM, Grid, auto_samples, plan_grid, widened
from pyroute_rel.routing.route import GridTrack, Route, build_route, join_routes, route_on_grid
from pyroute_rel.routing.solve import ArcMask, RoutingProblem

if TYPE_CHECKING:
    from pyroute_rel.boat.polar import Polar
    from pyroute_rel.reliability.failure import FailureModel
    from pyroute_rel.routing.cost import WaveLoss
    from pyroute_rel.routing.relax import Relaxation
    from pyroute_rel.weather import WeatherSource

#: Largest scenario file read [bytes]: 10 MB, a thousand times the largest example (a scenario holds settings
#: and file names, not data), so that a wrong path (a log, an image) is refused at once instead of parsed.
SCENARIO_MAX_BYTES = 10_000_000
#: Deepest nesting of arrays and tables in a scenario: the schema needs 5 ([weather] -> [[weather.patch]] ->
#: its table -> lon = [a, b]); 16 leaves room and refuses a crafted file before anything recurses over it.
SCENARIO_MAX_DEPTH = 16

__all__ = [
    "Scenario",
    "load_scenario",
    "read_scenario_table",
    "scenario_from_mapping",
    "parse_departure",
    "nesting_depth",
    "SCENARIO_MAX_BYTES",
    "SCENARIO_MAX_DEPTH",
]


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. Build with :func:`load_scenario` or :func:`scenario_from_mapping`; route with
    :meth:`route`.

    Attributes
    ----------
    source : Where the scenario came from (the file, or ``"<scenario>"``), named in messages.
    start, finish : The course's first and last marks, ``(lon, lat)`` [deg].
    departure : Departure time (UTC).
    n_ranks, n_nodes, spacing_km, max_deviation_deg, layout, aspect, half_width_km : The grid's settings
        (None: the grid's defaults; see :func:`~pyroute_rel.routing.grid.plan_grid`); spacing in [km], angle in [deg].
    samples_per_arc, sample_km : Weather samples per arc, or their largest spacing along arcs [km] (None: 25 km).
    polar, beyond, wave_loss : The boat: its polar, what to do outside its table, its speed loss in waves.
    manoeuvres : The time its tacks and gybes cost (:class:`~pyroute_rel.boat.manoeuvre.ManoeuvrePenalties`; None or
        zero: free, the route of the plain DP).
    weather : The weather source.
    failure_model, apf : The failure model's name or file (None: none) and the acceptable probability of failure.
    failure_limits : Plain limits instead of a model (``[failure].limits``: ``(key, value)`` pairs of
        :data:`~pyroute_rel.reliability.limits.LIMIT_KEYS`), compiled to one by :meth:`load_failure`; empty: none.
    apf_from_limits : True when ``apf`` is the limits' default (0), not written: a model given in their place
        (:meth:`with_options`) then routes at the file's default apf, 1.
    base_dir : Folder that relative paths start from.
    time_step_h, max_wait_h : Time lattice [h] and longest wait at a node [h] of the time-expanded DP.
    prune : Cost only the arcs that can still win.
    start_line, finish_line : Optional lines ``((lon, lat), (lon, lat))`` [deg] to start from and finish at.
    waypoints : Marks to pass in order, ``(lon, lat)`` [deg].
    avoid : Land, coastal margin and exclusion zones to keep out of.
    refine : Corridor refinements of the track (0 = none).
    notes : What reading the scenario assumed, one line each, for the user to see (e.g. a departure without a
        time zone read as UTC); the command line prints them on stderr.
    planner : The ``[planner]`` table: which planner routes the scenario and its settings
        (:mod:`pyroute_rel.planners`; :meth:`route` is always the DP).
    """

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
    notes: tuple[str, ...] = ()
    manoeuvres: ManoeuvrePenalties | None = None
    planner: PlannerSettings = field(default_factory=PlannerSettings)
    failure_limits: tuple[tuple[str, float], ...] = ()
    apf_from_limits: bool = False

    def with_options(self, **changes: Any) -> Scenario:
        """A copy with some settings changed (validated like the file's, with the command-line option named).

        ``None`` leaves a setting as it is (the CLI passes None for options not given), so a setting cannot be reset
        to None here: build the scenario from a mapping without it (:func:`scenario_from_mapping`) instead. The
        options and their checks: :data:`pyroute_rel.config.OPTIONS`.
        """
        checked = parse_options(changes, avoid=self.avoid)
        if "failure_model" in checked and self.failure_limits:  # a model given (or 'none') replaces the limits
            checked["failure_limits"] = ()
            if self.apf_from_limits and "apf" not in checked:  # and their default apf, 0: the file's default is 1
                checked["apf"] = 1.0
            checked["apf_from_limits"] = False
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
        """The compiled failure model (or plain limits compiled to one), or None. Refuses a model that needs fields
        the weather lacks."""
        if self.failure_limits:
            from pyroute_rel.reliability.limits import limits_model

            model = limits_model(self.failure_limits, where=f"{self.source}: [failure].limits")
            return self._weather_has(model)
        if self.failure_model is None:
            return None
        from pyroute_rel.reliability.failure import load_failure_model

        name = self.failure_model
        candidate = self.base_dir / name
        if ("/" in name or name.endswith(".toml")) and candidate.exists():
            name = str(candidate)
        try:
            model = load_failure_model(name)
        except FailureModelError as exc:
            raise FailureModelError(f"{self.source}: [failure].model {self.failure_model!r}: {exc}") from None
        return self._weather_has(model)

    def _weather_has(self, model: FailureModel) -> FailureModel:
        """``model``, refused when it needs weather fields the scenario's weather lacks."""
        have = self.weather.fields
        missing = sorted(model.weather_fields - have)
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
        (:func:`~pyroute_rel.routing.grid.auto_samples`).
        """
        if failure is not None:
            # at run time only when given (loading it is not cheap)
            from pyroute_rel.reliability.failure import FailureModel

            check_instance(failure, FailureModel, "failure", ScenarioError, expected="a FailureModel or None")
        if isinstance(blocked, str) and blocked != "auto":
            raise ScenarioError(f'blocked must be "auto", None or an obstacle mask (got {brief(blocked)})')
        if not isinstance(blocked, str) and blocked is not None and not isinstance(blocked, ArcMask):
            raise ScenarioError(f'blocked must be "auto", None or an obstacle mask (got {brief(blocked)})')
        if grid is not None:
            check_instance(grid, Grid, "grid", ScenarioError, expected="a Grid or None")
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
        if isinstance(blocked, str):  # "auto"
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
            manoeuvres=self.manoeuvres,
        )

    def route(
        self,
        *,
        progress: bool = False,
        grids: list[Grid] | None = None,
        relax: bool = True,
        departures: Sequence[np.datetime64] = (),
        relax_wider: bool = True,
    ) -> Route:
        """Route the scenario: the library's entry point.

        The minimum-time route that respects the failure model (no arc with ``p_f > apf``), land and zones, found
        by the forward DP on the scenario's grid (:func:`~pyroute_rel.routing.route.route_on_grid`), then refined in
        corridors when ``refine`` > 0 (:mod:`pyroute_rel.refine`). A course through waypoints is routed leg after
        leg, each departing when the previous one arrives at its mark; under FIFO weather this is optimal for the
        whole course, since the earliest arrival at a mark is best for what follows.

        Parameters
        ----------
        progress : Show a progress bar (on stderr).
        grids : The legs' grids from an earlier :meth:`leg_grids` of this course, to reuse what is cached on them
            (arc geometry, obstacle masks) when routing it again, e.g. for another departure.
        relax : When no route exists, find what would make one (:func:`pyroute_rel.routing.relax.relax`: the smallest
            apf that routes, the best partial route, the failing leg), said in the error's message and given as its
            ``relaxation``; False: the DP's explanation alone (no second routing).
        departures : With ``relax``, departure times to try, in order, when no route exists: the earliest that
            routes is part of the relaxation (``route --departure-window``).
        relax_wider : With ``relax``, also route the course on grids twice as wide (when the DP reached the grid's
            outermost nodes): the costliest try, as much as the route itself and more. Ensembles and sweeps leave it
            out (False), so that a member or run without a route costs about what one with a route does.

        Returns
        -------
        Route
            The track, its per-leg conditions (:class:`~pyroute_rel.routing.route.Legs`), failure probabilities, the
            DP's counts (``route.summary()`` is the JSON of ``pyroute-rel route --json``) and the forbidden arcs
            (:meth:`~pyroute_rel.routing.route.Route.forbidden_arcs`).

        Raises
        ------
        NoFeasibleRouteError
            When every path has a forbidden arc (the message says where the front died, why, and what would make it
            route; its ``relaxation`` holds the figures).
        WeatherCoverageError
            When the weather does not cover a leg's end points or its departure.
        ScenarioError
            When a mark lies on land or in a zone, or the weather lacks a field the failure model needs.
        FailureModelError
            When the failure model cannot be loaded.

        Examples
        --------
        >>> sc = scenario_from_mapping({
        ...     "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
        ...     "grid": {"n_ranks": 20}, "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
        ...     "avoid": {"land": False}, "failure": {"model": "dickson2018", "apf": 0.5}})
        >>> route = sc.route()
        >>> round(route.voyage_time_h, 2), round(route.distance_nm, 1), route.max_failure_probability
        (114.41, 463.9, 0.0)
        >>> float(route.legs.tws_kn[0]), len(route.forbidden_arcs())
        (15.0, 0)
        """
        progress = check_flag(progress, "progress", ScenarioError)
        check_points(self.marks(), self.avoid)
        failure = self.load_failure()
        routes: list[Route] = []
        departure = self.departure
        grids = self.leg_grids() if grids is None else self._checked_grids(grids)
        self._warn_zones_outside(grids)
        for i, grid in enumerate(grids):
            # the weather must cover the leg's end points and its departure; cells missing elsewhere in the
            # (wider) grid are NaN and forbid the arcs through them
            s_lon, s_lat = grid.start_points
            lons = [*s_lon, grid.finish[0]]
            lats = [*s_lat, grid.finish[1]]
            self.weather.check_coverage((min(lons), max(lons)), (min(lats), max(lats)), (departure, departure))
            leg_problem = replace(self.problem(failure=failure, grid=grid), departure=departure)
            last = routes[-1].manoeuvres if routes else None
            if last is not None and last.side.size and leg_problem.sides:  # a leg starts on the side the last ended on
                leg_problem = replace(leg_problem, initial_side=int(last.side[-1]))
            try:
                leg = route_on_grid(grid, leg_problem, progress=progress)
            except NoFeasibleRouteError as exc:
                if not relax:
                    raise
                raise self._relaxed(exc, grids, i, leg_problem, departures, relax_wider) from None
            if self.refine:
                leg = self._refined(leg, leg_problem)
            routes.append(leg)
            departure = routes[-1].arrival
        route = routes[0] if len(routes) == 1 else join_routes(routes)
        return replace(
            route, meta={**route.meta, "scenario": self.source, "land": self.avoid.land}, zones=self.avoid.zones
        )

    def _relaxed(
        self,
        error: NoFeasibleRouteError,
        grids: list[Grid],
        failed: int,
        failed_problem: RoutingProblem,
        departures: Sequence[np.datetime64],
        wider: bool = True,
    ) -> NoFeasibleRouteError:
        """The error of a course that does not route (leg ``failed``, routed as ``failed_problem``), with what would
        make it route (:func:`pyroute_rel.routing.relax.relax`) in its message and as its ``relaxation``."""
        from pyroute_rel.routing.relax import relax

        failure = failed_problem.failure
        legs = [
            (
                g,
                failed_problem
                if i == failed
                else replace(self.problem(failure=failure, grid=g), departure=self.departure),
            )
            for i, g in enumerate(grids)
        ]
        relaxation = relax(legs, failed, error, departures=departures)
        result = error.result
        reached = np.isfinite(result.arrival_h) if result is not None else None
        at_edge = reached is not None and reached.shape[1] > 2 and bool(reached[:, [0, -1]].any())
        if wider and at_edge and any(result.forbidden_by_reason.get(r, 0) for r in ("failure", "obstacle")):
            # only a route that reached the grid's outermost nodes may go round on a wider one
            relaxation = self._wider(relaxation, grids[failed])
        if self.refine and relaxation.apf is not None:  # the time at that apf as this scenario routes it: refined
            refined = self.with_options(apf=relaxation.apf).route(relax=False)
            relaxation = replace(relaxation, apf_voyage_time_h=refined.voyage_time_h)
        out = NoFeasibleRouteError(relaxation.message())
        out.result, out.relaxation = error.result, relaxation
        return out

    def _wider(self, relaxation: Relaxation, grid: Grid) -> Relaxation:
        """``relaxation`` with the course routed on grids twice as wide, when that routes: the angular layout's
        half-width doubled, or the square layout's nodes (``2 n - 1``, the same spacing)."""
        option, change = widened(self.layout, grid)
        try:
            route = self.with_options(**change).route(relax=False)
        except PyrouteError:  # no route there either, or a grid too wide or too big for the budget: no advice
            return replace(relaxation, wider_tried=True)
        return replace(relaxation, wider=option, wider_voyage_time_h=route.voyage_time_h, wider_tried=True)

    def _checked_grids(self, grids: Any) -> list[Grid]:
        """``grids`` given to :meth:`route`: one :class:`Grid` per leg (a shorter list routed only the first legs)."""
        n_legs = len(self.waypoints) + 1
        if not isinstance(grids, list | tuple) or not all(isinstance(g, Grid) for g in grids):
            raise ScenarioError(f"{self.source}: grids must be a list of Grid from leg_grids() (got {brief(grids)})")
        if len(grids) != n_legs:
            raise ScenarioError(
                f"{self.source}: grids must hold one Grid per leg of the course ({n_legs}), from leg_grids() "
                f"(got {len(grids)})"
            )
        return list(grids)

    def _warn_zones_outside(self, grids: list[Grid]) -> None:
        """One :class:`~pyroute_rel.errors.PyrouteWarning` per zone that lies wholly outside every leg's grid."""
        if not self.avoid.zones:
            return
        lon = np.concatenate([np.append(g.lon_deg.ravel(), [*g.start_points[0], g.finish[0]]) for g in grids])
        lat = np.concatenate([np.append(g.lat_deg.ravel(), [*g.start_points[1], g.finish[1]]) for g in grids])
        for zone in zones_outside(self.avoid.zones, lon, lat):
            x0, y0, x1, y1 = zone.geometry.bounds
            warnings.warn(
                f"{self.source}: zone {brief(zone.name)} (lon {x0:g} to {x1:g}, lat {y0:g} to {y1:g} [deg]) lies "
                f"wholly outside the routing area (lon {lon.min():.2f} to {lon.max():.2f}, lat {lat.min():.2f} to "
                f"{lat.max():.2f}): it cannot change the route; check that its coordinates are [lon, lat] (GeoJSON "
                "order) and that it is the intended file",
                PyrouteWarning,
                stacklevel=3,
            )

    def _refined(self, route: Route, problem: RoutingProblem) -> Route:
        """The route with its track refined in corridors (:mod:`pyroute_rel.refine`); the grid, its DP result and
        nodes stay those of the grid routed on, the levels are reported in ``meta["refine"]``."""
        from pyroute_rel.routing.refine import refine

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
    table = read_scenario_table(path)
    return scenario_from_mapping(table, base_dir=Path(path).parent, source=str(path))


def read_scenario_table(path: str | Path) -> dict[str, Any]:
    """A scenario file's TOML tables, not yet validated (:func:`scenario_from_mapping` does that): for code that
    changes a setting in the file's own terms before validating (:mod:`pyroute_rel.batch.sweep`).

    Raises :class:`~pyroute_rel.errors.ScenarioError` naming the file when it cannot be read as TOML.
    """
    if not isinstance(path, (str, Path)):
        raise ScenarioError(f"a scenario path must be a str or pathlib.Path (got {brief(path)})")
    p = Path(path)
    data = read_regular_bytes(
        p, limit_bytes=SCENARIO_MAX_BYTES, error=ScenarioError, label=brief_path(p), what="scenario file"
    )
    try:
        text = data.decode("utf-8-sig")  # a byte-order mark (Windows editors) is not part of the TOML
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            f"{brief_path(p)}: cannot read scenario file (not UTF-8 text: byte {exc.object[exc.start]:#04x} at offset "
            f"{exc.start})"
        ) from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{brief_path(p)}: not valid TOML ({exc})") from None
    except RecursionError:
        raise ScenarioError(
            f"{brief_path(p)}: arrays or tables nested too deeply to read (a scenario needs at most "
            f"{SCENARIO_MAX_DEPTH} levels)"
        ) from None
    depth = nesting_depth(table)
    if depth > SCENARIO_MAX_DEPTH:
        raise ScenarioError(
            f"{brief_path(p)}: arrays or tables nested {depth} levels deep (a scenario needs at most "
            f"{SCENARIO_MAX_DEPTH})"
        )
    return table


def nesting_depth(value: Any) -> int:
    """How deeply lists and mappings nest in ``value`` (0 for a scalar), without recursion."""
    deepest, todo = 0, [(value, 0)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, Mapping):
            todo.extend((v, depth + 1) for v in item.values())
        elif isinstance(item, list | tuple):
            todo.extend((v, depth + 1) for v in item)
        else:
            deepest = max(deepest, depth)
            continue
        deepest = max(deepest, depth + 1)
    return deepest


def scenario_from_mapping(
    table: Mapping[str, Any], *, base_dir: str | Path = ".", source: str = "<scenario>"
) -> Scenario:
    """Validate a scenario given as nested mappings (the parsed TOML)."""
    check_instance(source, str, "source", ScenarioError)
    check_path(base_dir, "base_dir", ScenarioError)
    if not isinstance(table, Mapping):
        raise ScenarioError(
            f"{source}: a scenario must be a mapping of tables such as {{'route': {{...}}}} (got {brief(table)})"
        )
    try:
        settings = parse_tables(table, Path(base_dir))
    except PyrouteError as exc:
        msg = str(exc)
        if not msg.startswith(source):
            raise type(exc)(f"{source}: {msg}") from None
        raise
    notes = tuple(f"{source}: {note}" for note in settings.pop("notes"))
    return Scenario(source=source, **settings, notes=notes)
