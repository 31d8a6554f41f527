"""pyroute_rel: reliability-informed routing for autonomous sailing craft.

The one entry point is a scenario: :func:`load_scenario` reads a TOML file into a :class:`Scenario`, and
:meth:`Scenario.route` plans the route, returning a :class:`Route` (track, per-leg conditions, failure
probabilities). Everything a user handles is importable from here; the modules hold the functions underneath.

>>> import pyroute_rel as pr
>>> sc = pr.scenario_from_mapping({
...     "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
...     "grid": {"n_ranks": 20}, "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
...     "avoid": {"land": False}, "failure": {"model": "none"}})
>>> route = sc.route()
>>> round(route.voyage_time_h, 1) > 0, route.max_failure_probability
(True, 0.0)

Names are loaded on first use, so ``import pyroute_rel`` stays cheap (the command line starts fast).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS: dict[str, str] = {
    # the entry point
    "load_scenario": "scenario",
    "scenario_from_mapping": "scenario",
    "Scenario": "scenario",
    "Route": "routing.route",
    "Legs": "routing.route",
    "ForbiddenArcs": "routing.route",
    "register_weather_kind": "config",
    # building blocks a user assembles or inspects
    "Polar": "boat.polar",
    "get_polar": "boat.polar",
    "read_polar": "boat.polar",
    "boat_speed_kn": "boat.polar",
    "FailureModel": "reliability.failure",
    "load_failure_model": "reliability.failure",
    "list_failure_models": "reliability.failure",
    "WeatherSource": "weather.base",
    "Conditions": "weather.base",
    "UniformWeather": "weather.uniform",
    "Patch": "weather.uniform",
    "GriddedWeather": "weather.gridded",
    "open_weather": "weather.io.readers",
    "weather_from_dataset": "weather.io.readers",
    "Avoid": "obstacles.mask",
    "load_zones": "obstacles.zones",
    "Grid": "routing.grid",
    "make_grid": "routing.grid",
    "plan_grid": "routing.grid",
    "RoutingProblem": "routing.solve",
    "forward_dp": "routing.solve",
    "route_on_grid": "routing.route",
    "refine": "routing.refine",
    "write_outputs": "outputs",
    "load_sweep": "batch.sweep",
    "run_sweep": "batch.sweep",
    "read_track": "analysis.evaluate",
    "evaluate_track": "analysis.evaluate",
    "Track": "analysis.evaluate",
    "Evaluation": "analysis.evaluate",
    "route_ensemble": "analysis.ensemble",
    "EnsembleResult": "analysis.ensemble",
    "monte_carlo": "analysis.monte_carlo",
    "MonteCarloSettings": "analysis.monte_carlo",
    "ManoeuvrePenalties": "boat.manoeuvre",
    "plan": "planners.plan",
    "PlannedTrack": "planners.base",
    "PlannerSettings": "planners.settings",
    "track_similarity": "analysis.similarity",
    # what is kept between calls, and the engines
    "kept": "store",
    "clear_kept": "store",
    "settings_context": "settings",
    # grid convergence
    "grid_convergence": "gci.numbers",
    "least_squares_convergence": "gci.numbers",
    "convergence_study": "gci.numbers",
    # errors
    "PyrouteError": "errors",
    "ScenarioError": "errors",
    "PolarError": "errors",
    "WeatherError": "errors",
    "WeatherCoverageError": "errors",
    "FailureModelError": "errors",
    "GridError": "errors",
    "ConvergenceError": "errors",
    "NoFeasibleRouteError": "errors",
    "OutputError": "errors",
    "CoordinateError": "errors",
    "MemoryBudgetError": "errors",
    "TrackError": "errors",
    "PyrouteWarning": "errors",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # for type checkers and IDEs; at run time the names load on first use
    from pyroute_rel.analysis.ensemble import EnsembleResult, route_ensemble
    from pyroute_rel.analysis.evaluate import Evaluation, Track, evaluate_track, read_track
    from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, monte_carlo
    from pyroute_rel.analysis.similarity import track_similarity
    from pyroute_rel.batch.sweep import load_sweep, run_sweep
    from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties
    from pyroute_rel.boat.polar import Polar, boat_speed_kn, get_polar, read_polar
    from pyroute_rel.config import register_weather_kind
    from pyroute_rel.errors import (
        ConvergenceError,
        CoordinateError,
        FailureModelError,
        GridError,
        MemoryBudgetError,
        NoFeasibleRouteError,
        OutputError,
        PolarError,
        PyrouteError,
        PyrouteWarning,
        ScenarioError,
        TrackError,
        WeatherCoverageError,
        WeatherError,
    )
    from pyroute_rel.gci.numbers import convergence_study, grid_convergence, least_squares_convergence
    from pyroute_rel.obstacles.mask import Avoid
    from pyroute_rel.obstacles.zones import load_zones
    from pyroute_rel.outputs import write_outputs
    from pyroute_rel.planners.base import PlannedTrack
    from pyroute_rel.planners.plan import plan
    from pyroute_rel.planners.settings import PlannerSettings
    from pyroute_rel.reliability.failure import FailureModel, list_failure_models, load_failure_model
    from pyroute_rel.routing.grid import Grid, make_grid, plan_grid
    from pyroute_rel.routing.refine import refine
    from pyroute_rel.routing.route import ForbiddenArcs, Legs, Route, route_on_grid
    from pyroute_rel.routing.solve import RoutingProblem, forward_dp
    from pyroute_rel.scenario import Scenario, load_scenario, scenario_from_mapping
    from pyroute_rel.settings import settings_context
    from pyroute_rel.store import clear_kept, kept
    from pyroute_rel.weather.base import Conditions, WeatherSource
    from pyroute_rel.weather.gridded import GriddedWeather
    from pyroute_rel.weather.io.readers import open_weather, weather_from_dataset
    from pyroute_rel.weather.uniform import Patch, UniformWeather
