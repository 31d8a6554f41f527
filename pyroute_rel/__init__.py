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
import sys
import types
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS: dict[str, str] = {
    # the entry point
    "load_scenario": "scenario",
    "scenario_from_mapping": "scenario",
    "Scenario": "scenario",
    "Route": "route",
    "Legs": "route",
    "ForbiddenArcs": "route",
    "register_weather_kind": "config",
    # building blocks a user assembles or inspects
    "Polar": "polar",
    "get_polar": "polar",
    "read_polar": "polar",
    "boat_speed_kn": "polar",
    "FailureModel": "failure",
    "load_failure_model": "failure",
    "list_failure_models": "failure",
    "WeatherSource": "weather.base",
    "Conditions": "weather.base",
    "UniformWeather": "weather.uniform",
    "Patch": "weather.uniform",
    "GriddedWeather": "weather.gridded",
    "open_weather": "weather.readers",
    "weather_from_dataset": "weather.readers",
    "Avoid": "obstacles.mask",
    "load_zones": "obstacles.zones",
    "Grid": "grid",
    "make_grid": "grid",
    "plan_grid": "grid",
    "RoutingProblem": "solve",
    "forward_dp": "solve",
    "route_on_grid": "route",
    "refine": "refine",
    "write_outputs": "outputs",
    "load_sweep": "sweep",
    "run_sweep": "sweep",
    "read_track": "evaluate",
    "evaluate_track": "evaluate",
    "Track": "evaluate",
    "Evaluation": "evaluate",
    "route_ensemble": "ensemble",
    "EnsembleResult": "ensemble",
    "monte_carlo": "monte_carlo",
    "MonteCarloSettings": "monte_carlo",
    "ManoeuvrePenalties": "manoeuvre",
    "plan": "planners.plan",
    "PlannedTrack": "planners.base",
    "PlannerSettings": "planners.settings",
    "track_similarity": "similarity",
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


class _Package(types.ModuleType):
    """The package's module type: importing a submodule does not bind it over a public function of the same name.

    ``import pyroute_rel.refine`` (the module) would otherwise make ``pyroute_rel.refine`` (the function) the module,
    and ``pr.refine(...)`` a TypeError; the same for ``monte_carlo``. The submodules stay in :data:`sys.modules`.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and _EXPORTS.get(name) == name:
            return  # the public function of that name is loaded on first use by __getattr__
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # for type checkers and IDEs; at run time the names load on first use
    from .config import register_weather_kind
    from .ensemble import EnsembleResult, route_ensemble
    from .errors import (
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
    from .evaluate import Evaluation, Track, evaluate_track, read_track
    from .failure import FailureModel, list_failure_models, load_failure_model
    from .gci.numbers import convergence_study, grid_convergence, least_squares_convergence
    from .grid import Grid, make_grid, plan_grid
    from .manoeuvre import ManoeuvrePenalties
    from .monte_carlo import MonteCarloSettings, monte_carlo
    from .obstacles.mask import Avoid
    from .obstacles.zones import load_zones
    from .outputs import write_outputs
    from .planners.base import PlannedTrack
    from .planners.plan import plan
    from .planners.settings import PlannerSettings
    from .polar import Polar, boat_speed_kn, get_polar, read_polar
    from .refine import refine
    from .route import ForbiddenArcs, Legs, Route, route_on_grid
    from .scenario import Scenario, load_scenario, scenario_from_mapping
    from .settings import settings_context
    from .similarity import track_similarity
    from .solve import RoutingProblem, forward_dp
    from .store import clear_kept, kept
    from .sweep import load_sweep, run_sweep
    from .weather.base import Conditions, WeatherSource
    from .weather.gridded import GriddedWeather
    from .weather.readers import open_weather, weather_from_dataset
    from .weather.uniform import Patch, UniformWeather
