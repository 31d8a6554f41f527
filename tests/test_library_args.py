"""Library calls refuse bad arguments with the domain errors (issue 17 item 10).

Every public name of ``pyroute_rel.__all__`` is called with None, wrong types, NaN and infinities, empty and
wrongly shaped arrays, negative sizes: each must raise a :class:`~pyroute_rel.errors.PyrouteError` subclass (the
domain error of its module, which subclasses a built-in) with a one-line message naming the argument, never a raw
``TypeError``/``AttributeError``/``ValueError`` from deep inside, a NaN result or a silent acceptance. The
references are the messages' contract (the argument's name and what was expected) and, for the values that are
accepted, an independent computation (JSON parsed strictly, the numbers given).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import inspect
import json
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pyroute_rel as pr
from pyroute_rel.errors import (
    ConvergenceError,
    FailureModelError,
    GridError,
    OutputError,
    PolarError,
    PyrouteError,
    ScenarioError,
    WeatherError,
    check_numbers,
)
from pyroute_rel.routing import tradeoff
from pyroute_rel.weather.io.readers import read_fields

ROOT = Path(__file__).resolve().parents[1]
T0 = np.datetime64("2018-06-01T00:00", "ns")
NAN, INF = float("nan"), float("inf")


def public(name: str) -> Any:
    """The public name ``pr.<name>`` as its module defines it (``pr.refine`` can be the module pyroute_rel.refine
    when that was imported first: see test_pr_refine_is_the_function_even_after_importing_its_module)."""
    obj = getattr(pr, name)
    return getattr(obj, name) if inspect.ismodule(obj) else obj


@functools.cache
def scenario() -> pr.Scenario:
    return pr.scenario_from_mapping(
        {
            "route": {"start": [-12.0, 45.0], "finish": [-20.0, 40.0], "departure": "2018-06-01T00:00:00Z"},
            "grid": {"n_ranks": 6, "n_nodes": 5},
            "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0},
            "avoid": {"land": False},
            "failure": {"model": "none"},
        }
    )


@functools.cache
def route() -> pr.Route:
    return scenario().route()


@functools.cache
def polar() -> pr.Polar:
    return pr.get_polar("maribot_vane")


@functools.cache
def model() -> pr.FailureModel:
    return pr.load_failure_model("dickson2018")


@functools.cache
def dataset() -> xr.Dataset:
    time = T0 + np.arange(2) * np.timedelta64(6, "h")
    dims = ("time", "latitude", "longitude")
    wind = np.ones((2, 2, 2))
    return xr.Dataset(
        {"u10": (dims, wind, {"units": "m s-1"}), "v10": (dims, wind, {"units": "m s-1"})},
        coords={"time": time, "latitude": [40.0, 41.0], "longitude": [-20.0, -19.0]},
    )


@functools.cache
def gridded() -> pr.GriddedWeather:
    return pr.weather_from_dataset(dataset())


def _builder(table, *, base_dir, bbox, departure):  # a weather builder of the right form
    return pr.UniformWeather(tws_kn=5.0, twd_deg=0.0)


class _MaskOf:
    """An obstacle mask (pyroute_rel.routing.solve.ArcMask) of the given grid that blocks nothing."""

    def __init__(self, grid: pr.Grid) -> None:
        self.grid, self.timed = grid, False

    def __call__(self, k: int, times: Any) -> np.ndarray:
        return np.zeros(self.grid.arcs(k)[4].shape, dtype=bool)

    known = hits = __call__

    def learn(self, k: int, select: Any = None) -> None:
        return None


#: id -> (the call, the domain error it must raise, fragments the one-line message must hold)
CASES: dict[str, tuple[Callable[[], Any], type[PyrouteError], tuple[str, ...]]] = {
    # ---- the named cases
    "write_outputs extra NaN": (
        lambda: pr.write_outputs(route(), "unused", plot=False, extra={"x": NAN}),
        OutputError,
        ("extra['x'] is nan", "not valid JSON"),
    ),
    "write_outputs route None": (lambda: pr.write_outputs(None, "unused"), OutputError, ("route must be a Route",)),
    "write_outputs extra=5": (
        lambda: pr.write_outputs(route(), "unused", extra=5),
        OutputError,
        ("extra must be a dict of JSON values", "got 5, an int"),
    ),
    "boat_speed_kn twa 'a'": (lambda: pr.boat_speed_kn(polar(), "a", 10), PolarError, ("twa_deg must be",)),
    "register_weather_kind with a space": (
        lambda: pr.register_weather_kind("my kind", _builder),
        ScenarioError,
        ("a weather kind must be a name", "'my kind'"),
    ),
    # ---- outputs
    "write_outputs extra inf nested": (
        lambda: pr.write_outputs(route(), "unused", extra={"a": [1, {"b": -INF}]}),
        OutputError,
        ("extra['a'][1]['b'] is -inf",),
    ),
    "write_outputs extra object": (
        lambda: pr.write_outputs(route(), "unused", extra={"x": object()}),
        OutputError,
        ("extra['x'] cannot be written to JSON",),
    ),
    "write_outputs extra key a tuple": (
        lambda: pr.write_outputs(route(), "unused", extra={(1, 2): 1}),
        OutputError,
        ("keys must be str",),
    ),
    "write_outputs extra a list": (lambda: pr.write_outputs(route(), "u", extra=[]), OutputError, ("extra must be",)),
    "write_outputs out_dir None": (
        lambda: pr.write_outputs(route(), None),
        OutputError,
        ("out_dir must be a folder name",),
    ),
    "write_outputs out_dir empty": (lambda: pr.write_outputs(route(), ""), OutputError, ("out_dir needs a folder",)),
    "write_outputs out_dir a file": (
        lambda: pr.write_outputs(route(), ROOT / "README.md"),
        OutputError,
        ("is a file, not a folder",),
    ),
    "write_outputs plot None": (
        lambda: pr.write_outputs(route(), "unused", plot=None),
        OutputError,
        ("plot must be True or False",),
    ),
    # ---- polars
    "boat_speed_kn polar None": (lambda: pr.boat_speed_kn(None, 90.0, 10.0), PolarError, ("polar must be a Polar",)),
    "boat_speed_kn tws None": (lambda: pr.boat_speed_kn(polar(), 90.0, None), PolarError, ("tws_kn must be",)),
    "boat_speed_kn tws complex": (lambda: pr.boat_speed_kn(polar(), 90.0, 1j), PolarError, ("a complex",)),
    "boat_speed_kn twa objects": (lambda: pr.boat_speed_kn(polar(), [1.0, None], 5.0), PolarError, ("twa_deg",)),
    "boat_speed_kn shapes": (
        lambda: pr.boat_speed_kn(polar(), np.zeros(3), np.zeros(4)),
        PolarError,
        ("must broadcast", "(3,) and (4,)"),
    ),
    "boat_speed_kn beyond array": (
        lambda: pr.boat_speed_kn(polar(), 90.0, 5.0, beyond=np.array([])),
        PolarError,
        ("beyond",),
    ),
    "Polar.speed tws bool array": (
        lambda: polar().speed(90.0, np.array([True])),
        PolarError,
        ("tws_kn must be",),
    ),
    "read_polar None": (lambda: pr.read_polar(None), PolarError, ("polar file must be a file name",)),
    "read_polar name a list": (
        lambda: pr.read_polar(ROOT / "examples/maribot_vane.pol", name=[]),
        PolarError,
        ("name must be a str",),
    ),
    "get_polar bytes": (lambda: pr.get_polar(b"maribot_vane"), PolarError, ("built-in name",)),
    "get_polar base_dir 5": (lambda: pr.get_polar("maribot_vane", base_dir=5), PolarError, ("base_dir",)),
    "Polar negative speed": (
        lambda: pr.Polar("p", [0.0, 90.0], [0.0, 10.0], [[0.0, 1.0], [0.0, -2.0]]),
        PolarError,
        ("speed",),
    ),
    "Polar TWA over 180": (
        lambda: pr.Polar("p", [0.0, 190.0], [0.0, 10.0], [[0.0, 1.0], [0.0, 2.0]]),
        PolarError,
        ("180",),
    ),
    # ---- scenario and the entry point
    "register_weather_kind empty": (lambda: pr.register_weather_kind("", _builder), ScenarioError, ("kind",)),
    "register_weather_kind builder 5": (
        lambda: pr.register_weather_kind("k5", 5),
        ScenarioError,
        ("must be callable",),
    ),
    "register_weather_kind replace None": (
        lambda: pr.register_weather_kind("k6", _builder, replace=None),
        ScenarioError,
        ("replace must be True or False",),
    ),
    "scenario_from_mapping base_dir None": (
        lambda: pr.scenario_from_mapping({}, base_dir=None),
        ScenarioError,
        ("base_dir must be a file name",),
    ),
    "scenario_from_mapping source 5": (
        lambda: pr.scenario_from_mapping({}, source=5),
        ScenarioError,
        ("source must be a str",),
    ),
    "scenario_from_mapping None": (lambda: pr.scenario_from_mapping(None), ScenarioError, ("mapping of tables",)),
    "load_scenario None": (lambda: pr.load_scenario(None), ScenarioError, ("scenario path",)),
    "Scenario.route progress None": (
        lambda: scenario().route(progress=None),
        ScenarioError,
        ("progress must be True or False",),
    ),
    "Scenario.route grids a string": (lambda: scenario().route(grids="x"), ScenarioError, ("grids must be",)),
    "Scenario.problem grid 'x'": (lambda: scenario().problem(grid="x"), ScenarioError, ("grid must be a Grid",)),
    "Scenario.problem blocked array": (
        lambda: scenario().problem(blocked=np.array([])),
        ScenarioError,
        ("blocked must be",),
    ),
    "Scenario.problem blocked 'none'": (lambda: scenario().problem(blocked="none"), ScenarioError, ("blocked",)),
    "Scenario.problem failure 5": (
        lambda: scenario().problem(failure=5),
        ScenarioError,
        ("failure must be a FailureModel or None",),
    ),
    "Scenario.with_options n_ranks -1": (lambda: scenario().with_options(n_ranks=-1), ScenarioError, ("n-ranks",)),
    "route_on_grid grid None": (
        lambda: pr.route_on_grid(None, route().problem),
        ScenarioError,
        ("grid must be a Grid",),
    ),
    "route_on_grid problem None": (
        lambda: pr.route_on_grid(route().grid, None),
        ScenarioError,
        ("problem must be a RoutingProblem",),
    ),
    "route_on_grid progress array": (
        lambda: pr.route_on_grid(route().grid, route().problem, progress=np.array([])),
        ScenarioError,
        ("progress must be True or False",),
    ),
    "forward_dp progress array": (
        lambda: pr.forward_dp(route().grid, route().problem, progress=np.array([])),
        ScenarioError,
        ("progress must be True or False",),
    ),
    "forward_dp grid None": (
        lambda: pr.forward_dp(None, route().problem),
        ScenarioError,
        ("grid must be a Grid", "got None"),
    ),
    "forward_dp grid a list": (lambda: pr.forward_dp([], route().problem), ScenarioError, ("grid must be a Grid",)),
    "forward_dp problem 'x'": (
        lambda: pr.forward_dp(route().grid, "x"),
        ScenarioError,
        ("problem must be a RoutingProblem", "'x', a str"),
    ),
    "forward_dp cost_hook 'x'": (
        lambda: pr.forward_dp(route().grid, route().problem, cost_hook="x"),
        ScenarioError,
        ("cost_hook must be a function", "'x', a str"),
    ),
    "forward_dp mask of another grid": (
        lambda: pr.forward_dp(
            copy.copy(route().grid), dataclasses.replace(route().problem, blocked=_MaskOf(route().grid))
        ),
        ScenarioError,
        ("obstacle mask was built for another grid",),
    ),
    "RoutingProblem departure 10**30": (
        lambda: pr.RoutingProblem(10**30, scenario().weather, polar()),
        ScenarioError,
        ("departure must be a UTC time", "1000000000000000000000000000000"),
    ),
    "RoutingProblem departure year 10**12": (
        lambda: pr.RoutingProblem("1000000000000-01-01", scenario().weather, polar()),
        ScenarioError,
        ("departure must be a UTC time in the years 1 to 9999",),
    ),
    "RoutingProblem departure complex": (
        lambda: pr.RoutingProblem(1j, scenario().weather, polar()),
        ScenarioError,
        ("departure must be a UTC time", "1j"),
    ),
    "RoutingProblem weather None": (
        lambda: pr.RoutingProblem(T0, None, polar()),
        ScenarioError,
        ("RoutingProblem.weather must be a weather source",),
    ),
    "RoutingProblem polar 'maribot_vane'": (
        lambda: pr.RoutingProblem(T0, scenario().weather, "maribot_vane"),
        ScenarioError,
        ("RoutingProblem.polar must be a Polar",),
    ),
    "RoutingProblem failure 'dickson2018'": (
        lambda: pr.RoutingProblem(T0, scenario().weather, polar(), failure="dickson2018"),
        ScenarioError,
        ("RoutingProblem.failure must be a FailureModel",),
    ),
    "RoutingProblem blocked True": (
        lambda: pr.RoutingProblem(T0, scenario().weather, polar(), blocked=True),
        ScenarioError,
        ("RoutingProblem.blocked must be",),
    ),
    "RoutingProblem prune None": (
        lambda: pr.RoutingProblem(T0, scenario().weather, polar(), prune=None),
        ScenarioError,
        ("RoutingProblem.prune must be True or False",),
    ),
    "RoutingProblem apf True": (
        lambda: pr.RoutingProblem(T0, scenario().weather, polar(), apf=True),
        ScenarioError,
        ("apf must be a probability",),
    ),
    "RoutingProblem time_step_h True": (
        lambda: pr.RoutingProblem(T0, scenario().weather, polar(), time_step_h=True),
        ScenarioError,
        ("time_step_h must be in (0, 48]",),
    ),
    "RoutingProblem.costs lon0 'x'": (
        lambda: route().problem.costs("x", 0.0, 1.0, 0.0, 0.0),
        ScenarioError,
        ("RoutingProblem.costs lon0 must be a number", "[deg]"),
    ),
    "RoutingProblem.costs lat1 None": (
        lambda: route().problem.costs(0.0, 0.0, 1.0, None, 0.0),
        ScenarioError,
        ("RoutingProblem.costs lat1 must be", "got None"),
    ),
    "RoutingProblem.costs lon1 inf": (
        lambda: route().problem.costs(0.0, 0.0, INF, 0.0, 0.0),
        ScenarioError,
        ("RoutingProblem.costs lon1", "finite (NaN for missing)"),
    ),
    "RoutingProblem.costs t0_h True": (
        lambda: route().problem.costs(0.0, 0.0, 1.0, 0.0, True),
        ScenarioError,
        ("RoutingProblem.costs t0_h must be", "[h]"),
    ),
    "RoutingProblem.costs t0_h a wrong shape": (
        lambda: route().problem.costs(0.0, 0.0, 1.0, 0.0, np.ones((2, 2))),
        ScenarioError,
        ("must broadcast together", "(2, 2)"),
    ),
    "ManoeuvrePenalties tack 'x'": (
        lambda: pr.ManoeuvrePenalties(tack_s="x"),
        ScenarioError,
        ("[boat].tack_penalty_s must be a list of [tws_kn, seconds] pairs",),
    ),
    "ManoeuvrePenalties gybe NaN": (
        lambda: pr.ManoeuvrePenalties(gybe_s=[[5.0, NAN]]),
        ScenarioError,
        ("[boat].gybe_penalty_s must hold finite numbers",),
    ),
    "ManoeuvrePenalties tack negative": (
        lambda: pr.ManoeuvrePenalties(tack_s=[[5.0, -1.0]]),
        ScenarioError,
        ("penalties must be in [0, 86400] [s]",),
    ),
    "ManoeuvrePenalties wind decreasing": (
        lambda: pr.ManoeuvrePenalties(tack_s=[[10.0, 1.0], [5.0, 1.0]]),
        ScenarioError,
        ("wind speeds must be >= 0 [kn] and increase",),
    ),
    "ManoeuvrePenalties.penalty_h wind 'x'": (
        lambda: pr.ManoeuvrePenalties(tack_s=[[5.0, 30.0]]).penalty_h([1], ["x"]),
        ScenarioError,
        ("tws_kn must be wind speeds [kn]", "'x'"),
    ),
    "ManoeuvrePenalties where 5": (
        lambda: pr.ManoeuvrePenalties(where=5),
        ScenarioError,
        ("ManoeuvrePenalties where must be a str",),
    ),
    # ---- failure models
    "load_failure_model None": (lambda: pr.load_failure_model(None), FailureModelError, ("by name or path",)),
    "load_failure_model cache array": (
        lambda: pr.load_failure_model("dickson2018", cache=np.array([])),
        FailureModelError,
        ("cache must be True or False",),
    ),
    "FailureModel.p_fail None": (lambda: model().p_fail(None), FailureModelError, ("quantities must be a dict",)),
    "FailureModel.p_fail a string": (
        lambda: model().p_fail({"hs_m": "high", "awd_deg": 90.0}),
        FailureModelError,
        ("p_fail: hs_m must be",),
    ),
    "FailureModel.p_fail inf": (
        lambda: model().p_fail({"hs_m": INF, "awd_deg": 90.0}),
        FailureModelError,
        ("hs_m must be a number", "got inf"),
    ),
    "FailureModel.p_fail shapes": (
        lambda: model().p_fail({"hs_m": np.ones(2), "awd_deg": np.ones(3)}),
        FailureModelError,
        ("must broadcast",),
    ),
    "FailureModel.p_fail missing quantity": (
        lambda: model().p_fail({"hs_m": 1.0}),
        FailureModelError,
        ("needs quantities",),
    ),
    # ---- weather
    "UniformWeather tws None": (lambda: pr.UniformWeather(tws_kn=None, twd_deg=0.0), ScenarioError, ("tws_kn",)),
    "UniformWeather tws NaN": (lambda: pr.UniformWeather(tws_kn=NAN, twd_deg=0.0), ScenarioError, ("tws_kn",)),
    "UniformWeather tws a 2-D array (message on one line)": (
        lambda: pr.UniformWeather(tws_kn=np.zeros((3, 2)), twd_deg=0.0),
        ScenarioError,
        ("tws_kn must be a number", "array([[0., 0.], [0., 0.], [0., 0.]])"),
    ),
    "UniformWeather hs negative": (
        lambda: pr.UniformWeather(tws_kn=5.0, twd_deg=0.0, hs_m=-1.0),
        ScenarioError,
        ("hs_m",),
    ),
    "UniformWeather patches None": (
        lambda: pr.UniformWeather(tws_kn=5.0, twd_deg=0.0, patches=None),
        ScenarioError,
        ("patches",),
    ),
    "UniformWeather.sample lon None": (
        lambda: pr.UniformWeather(tws_kn=5.0, twd_deg=0.0).sample(None, 0.0, T0),
        WeatherError,
        ("lon_deg must be",),
    ),
    "UniformWeather.sample lat inf": (
        lambda: pr.UniformWeather(tws_kn=5.0, twd_deg=0.0).sample(0.0, [0.0, INF], T0),
        WeatherError,
        ("lat_deg must be", "got inf at index 1"),
    ),
    "Patch name array": (
        lambda: pr.Patch((0.0, 1.0), (0.0, 1.0), {"tws_kn": 5.0}, name=np.array([])),
        ScenarioError,
        ("Patch.name must be a string",),
    ),
    "Patch values NaN": (lambda: pr.Patch((0.0, 1.0), (0.0, 1.0), {"tws_kn": NAN}), ScenarioError, ("tws_kn",)),
    "Patch lon reversed": (lambda: pr.Patch((1.0, 0.0), (0.0, 1.0), {"tws_kn": 5.0}), ScenarioError, ("lon",)),
    "GriddedWeather fields None": (
        lambda: pr.GriddedWeather(None),
        WeatherError,
        ("fields must be a list of WeatherField",),
    ),
    "GriddedWeather fields of ints": (lambda: pr.GriddedWeather([1, 2]), WeatherError, ("WeatherField objects",)),
    "GriddedWeather out_of_range array": (
        lambda: pr.GriddedWeather(read_fields([("s", [dataset()])]), out_of_range=np.array([])),
        WeatherError,
        ("out_of_range must be one of",),
    ),
    "GriddedWeather.sample lon 'x'": (
        lambda: gridded().sample("x", 40.5, T0),
        WeatherError,
        ("lon_deg must be",),
    ),
    "GriddedWeather.sample time a number": (
        lambda: gridded().sample(-19.5, 40.5, 5),
        WeatherError,
        ("time must be datetime64 values",),
    ),
    "GriddedWeather.sample time not a time": (
        lambda: gridded().sample(-19.5, 40.5, "noon"),
        WeatherError,
        ("time: expected a time",),
    ),
    "GriddedWeather.sample shapes": (
        lambda: gridded().sample(np.zeros(2), np.zeros(3), T0),
        WeatherError,
        ("must broadcast together",),
    ),
    "GriddedWeather.check_coverage lon_range None": (
        lambda: gridded().check_coverage(None, (40.0, 41.0), (T0, T0)),
        WeatherError,
        ("lon_range must be",),
    ),
    "GriddedWeather.check_coverage lat_range of 3": (
        lambda: gridded().check_coverage((-20.0, -19.0), (40.0, 41.0, 42.0), (T0, T0)),
        WeatherError,
        ("lat_range must be a pair",),
    ),
    "GriddedWeather.check_coverage time_range None": (
        lambda: gridded().check_coverage((-20.0, -19.0), (40.0, 41.0), None),
        WeatherError,
        ("time_range must be a pair",),
    ),
    "weather_from_dataset None": (
        lambda: pr.weather_from_dataset(None),
        WeatherError,
        ("ds must be an xarray.Dataset",),
    ),
    "weather_from_dataset margin 'x'": (
        lambda: pr.weather_from_dataset(dataset(), margin_deg="x"),
        WeatherError,
        ("margin_deg must be",),
    ),
    "weather_from_dataset margin array": (
        lambda: pr.weather_from_dataset(dataset(), margin_deg=np.zeros(2)),
        WeatherError,
        ("margin_deg must be",),
    ),
    "weather_from_dataset margin NaN": (
        lambda: pr.weather_from_dataset(dataset(), margin_deg=NAN),
        WeatherError,
        ("margin_deg must be",),
    ),
    "weather_from_dataset time_window 5": (
        lambda: pr.weather_from_dataset(dataset(), time_window=5),
        WeatherError,
        ("time_window must be a pair",),
    ),
    "weather_from_dataset variables a list": (
        lambda: pr.weather_from_dataset(dataset(), variables=["u10"]),
        WeatherError,
        ("variables must be a dict",),
    ),
    "weather_from_dataset variables value 5": (
        lambda: pr.weather_from_dataset(dataset(), variables={"hs_m": 5}),
        WeatherError,
        ("must be the name of a file variable",),
    ),
    "weather_from_dataset member -1": (
        lambda: pr.weather_from_dataset(dataset(), member=-1),
        WeatherError,
        ("member must be an integer >= 0",),
    ),
    "weather_from_dataset source None": (
        lambda: pr.weather_from_dataset(dataset(), source=None),
        WeatherError,
        ("source must be a str",),
    ),
    "weather_from_dataset bbox None inside": (
        lambda: pr.weather_from_dataset(dataset(), bbox=[0, None, 1, 2]),
        WeatherError,
        ("bbox must be",),
    ),
    "open_weather None": (lambda: pr.open_weather(None), WeatherError, ("weather files must be a path",)),
    "open_weather empty list": (lambda: pr.open_weather([]), WeatherError, ("no weather file given",)),
    # ---- grids
    "make_grid n_ranks -1": (lambda: pr.make_grid((0, 0), (1, 1), n_ranks=-1, n_nodes=3), GridError, ("n_ranks",)),
    "make_grid n_nodes 2.5": (lambda: pr.make_grid((0, 0), (1, 1), n_ranks=3, n_nodes=2.5), GridError, ("n_nodes",)),
    "make_grid start None": (lambda: pr.make_grid(None, (1, 1), n_ranks=3, n_nodes=3), GridError, ("start",)),
    "make_grid start NaN": (lambda: pr.make_grid((NAN, 0), (1, 1), n_ranks=3, n_nodes=3), GridError, ("start",)),
    "make_grid start a 2-D array": (
        lambda: pr.make_grid(np.zeros((2, 2)), (1, 1), n_ranks=3, n_nodes=3),
        GridError,
        ("start must be a pair", "array([[0., 0.], [0., 0.]])"),
    ),
    "make_grid start == finish": (
        lambda: pr.make_grid((1, 1), (1, 1), n_ranks=3, n_nodes=3),
        GridError,
        ("start and finish must differ",),
    ),
    "make_grid spacing True": (
        lambda: pr.make_grid((0, 0), (1, 1), n_ranks=3, n_nodes=3, spacing_km=True),
        GridError,
        ("spacing_km",),
    ),
    "plan_grid layout array": (
        lambda: pr.plan_grid((0, 0), (1, 1), layout=np.array([])),
        GridError,
        ("layout must be one of",),
    ),
    "plan_grid n_nodes 'x' (angular)": (
        lambda: pr.plan_grid((0, 0), (1, 1), n_nodes="x"),
        GridError,
        ("n_nodes must be a whole number",),
    ),
    "plan_grid n_nodes -3 (angular)": (lambda: pr.plan_grid((0, 0), (1, 1), n_nodes=-3), GridError, (">= 1",)),
    "plan_grid aspect True": (lambda: pr.plan_grid((0, 0), (1, 1), aspect=True), GridError, ("aspect",)),
    "Grid.arcs k None": (lambda: route().grid.arcs(None), GridError, ("rank index must be a whole number",)),
    "Grid.pattern k -1": (lambda: route().grid.pattern(-1), GridError, ("rank index", "got -1")),
    "Grid.to_networkx weight 'x'": (
        lambda: route().grid.to_networkx("x"),
        GridError,
        ("weight must be a list of n_ranks + 1 arrays",),
    ),
    "Grid.to_networkx weight too short": (
        lambda: route().grid.to_networkx([np.zeros(1)]),
        GridError,
        ("n_ranks + 1 = 7",),
    ),
    "refine problem_for 'x'": (
        lambda: public("refine")(route().grid, route().problem, route().dp, levels=1, problem_for="x"),
        GridError,
        ("refine: problem_for must be a function",),
    ),
    "refine levels 0": (
        lambda: public("refine")(route().grid, route().problem, route().dp, levels=0),
        GridError,
        ("levels",),
    ),
    "refine n_nodes 4": (
        lambda: public("refine")(route().grid, route().problem, route().dp, levels=1, n_nodes=4),
        GridError,
        ("n_nodes",),
    ),
    # ---- zones and obstacles
    "Avoid resolution a list": (lambda: pr.Avoid(resolution=[]), ScenarioError, ("Avoid.resolution",)),
    "Avoid margin NaN": (lambda: pr.Avoid(margin_km=NAN), ScenarioError, ("Avoid.margin_km",)),
    "Avoid zones a string": (lambda: pr.Avoid(zones="z.geojson"), ScenarioError, ("Avoid.zones",)),
    "load_zones a dict": (lambda: pr.load_zones({}), ScenarioError, ("zone files must be",)),
    "load_zones base_dir 5": (lambda: pr.load_zones([], base_dir=5), ScenarioError, ("base_dir must be",)),
    "load_zones None": (lambda: pr.load_zones(None), ScenarioError, ("zone files must be",)),
    # ---- tracks, evaluation, Monte Carlo, ensembles (modules of other branches: what they refuse well already)
    "Track None": (lambda: pr.Track(None, None), pr.TrackError, ("Track.lon_deg must be", "got None")),
    "Track NaN": (lambda: pr.Track([0.0, NAN], [0.0, 1.0]), pr.TrackError, ("finite numbers",)),
    "Track shapes": (lambda: pr.Track([0.0, 1.0, 2.0], [0.0, 1.0]), pr.TrackError, ("two or more points",)),
    "read_track missing": (lambda: pr.read_track("/nonexistent/t.csv"), pr.TrackError, ("track file not found",)),
    "evaluate_track None": (lambda: pr.evaluate_track(None, None), pr.TrackError, ("a track must be",)),
    "evaluate_track apf 2": (
        lambda: pr.evaluate_track(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], apf=2.0),
        ScenarioError,
        ("apf must be a probability",),
    ),
    "MonteCarloSettings sigma NaN": (
        lambda: pr.MonteCarloSettings(sigma0_ms=NAN),
        ScenarioError,
        ("sigma0_ms must be in [0, 50] [m/s]",),
    ),
    "MonteCarloSettings kappa None": (lambda: pr.MonteCarloSettings(kappa=None), ScenarioError, ("kappa",)),
    "kept keep 'no'": (lambda: pr.kept("no"), ScenarioError, ("kept: keep must be True or False (got 'no')",)),
    "settings_context unknown": (
        lambda: pr.settings_context(fast=True),
        ScenarioError,
        ("settings: unknown setting 'fast' (expected one of ",),
    ),
    "settings_context 1": (
        lambda: pr.settings_context(lazy_pieces=1),
        ScenarioError,
        ("settings: lazy_pieces must be True or False (got 1)",),
    ),
    "monte_carlo runs 0": (
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=0),
        ScenarioError,
        ("runs >= 1",),
    ),
    "route_ensemble risk 'x'": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", risk="x"),
        ScenarioError,
        ("--risk must be",),
    ),
    "Track lon 'x'": (lambda: pr.Track("x", [1.0]), pr.TrackError, ("Track.lon_deg must be a number", "'x', a str")),
    "Track lat a dict": (lambda: pr.Track([0.0, 1.0], {}), pr.TrackError, ("Track.lat_deg must be",)),
    "Track lat complex": (lambda: pr.Track([0.0, 1.0], [1j, 0.0]), pr.TrackError, ("Track.lat_deg must be",)),
    "Track time 'x'": (lambda: pr.Track([0.0, 1.0], [0.0, 1.0], time="x"), pr.TrackError, ("Track.time must be",)),
    "Track time 10**30": (
        lambda: pr.Track([0.0, 1.0], [0.0, 1.0], time=[10**30, 0]),
        pr.TrackError,
        ("Track.time must be UTC times",),
    ),
    "Track time an object": (
        lambda: pr.Track([0.0, 1.0], [0.0, 1.0], time=object()),
        pr.TrackError,
        ("Track.time must be",),
    ),
    "read_track None": (lambda: pr.read_track(None), pr.TrackError, ("track file must be a file name", "got None")),
    "read_track 5": (lambda: pr.read_track(5), pr.TrackError, ("track file must be a file name", "got 5, an int")),
    "read_track ''": (lambda: pr.read_track(""), pr.TrackError, ("an empty name",)),
    "evaluate_track track 'x'": (
        lambda: pr.evaluate_track(scenario(), "x"),
        pr.TrackError,
        ("a track must be a Track or an (N, 2) array", "'x'"),
    ),
    "evaluate_track track of words": (
        lambda: pr.evaluate_track(scenario(), [["a", "b"], ["c", "d"]]),
        pr.TrackError,
        ("track must be a number or numbers [deg]",),
    ),
    "evaluate_track track with inf": (
        lambda: pr.evaluate_track(scenario(), [[-12.0, 45.0], [INF, 40.0]]),
        pr.TrackError,
        ("finite",),
    ),
    "evaluate_track scenario 5": (
        lambda: pr.evaluate_track(5, [[-12.0, 45.0], [-20.0, 40.0]]),
        ScenarioError,
        ("expected a Scenario", "int"),
    ),
    "evaluate_track samples 0": (
        lambda: pr.evaluate_track(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], samples=0),
        ScenarioError,
        ("samples_per_arc must be",),
    ),
    "evaluate_track weather 'x'": (
        lambda: pr.evaluate_track(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], weather="x"),
        ScenarioError,
        ("RoutingProblem.weather must be",),
    ),
    "MonteCarloSettings sigma0 True": (
        lambda: pr.MonteCarloSettings(sigma0_ms=True),
        ScenarioError,
        ("sigma0_ms must be in [0, 50] [m/s]",),
    ),
    "MonteCarloSettings tau 'x'": (lambda: pr.MonteCarloSettings(tau_h="x"), ScenarioError, ("tau_h must be > 0",)),
    "MonteCarloSettings spread 'x'": (
        lambda: pr.MonteCarloSettings(spread_ms="x"),
        ScenarioError,
        ("spread_ms must be a number or numbers [m/s]",),
    ),
    "MonteCarloSettings spread NaN": (
        lambda: pr.MonteCarloSettings(spread_ms=[1.0, NAN]),
        ScenarioError,
        ("spread_ms", "finite", "index 1"),
    ),
    "MonteCarloSettings spread negative": (
        lambda: pr.MonteCarloSettings(spread_ms=[1.0, -1.0]),
        ScenarioError,
        ("spread_ms must be one value in [0, 50] per leg [m/s]",),
    ),
    "MonteCarloSettings spread 1e6": (  # issue 34: a wind SD of 1e6 m/s was accepted
        lambda: pr.MonteCarloSettings(spread_ms=[1.0, 1e6]),
        ScenarioError,
        ("spread_ms must be one value in [0, 50] per leg [m/s]",),
    ),
    "MonteCarloSettings spread 2-D": (
        lambda: pr.MonteCarloSettings(spread_ms=np.ones((2, 2))),
        ScenarioError,
        ("spread_ms must be one value in [0, 50] per leg [m/s]",),
    ),
    "monte_carlo seed 'x'": (
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=2, seed="x"),
        ScenarioError,
        ("seed must be a whole number >= 0 or None", "'x'"),
    ),
    "monte_carlo seed -1": (
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=2, seed=-1),
        ScenarioError,
        ("seed must be",),
    ),
    "monte_carlo seed 1.5": (
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=2, seed=1.5),
        ScenarioError,
        ("seed must be",),
    ),
    "monte_carlo settings 5": (
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=2, settings=5),
        ScenarioError,
        ("settings must be a MonteCarloSettings", "got 5, an int"),
    ),
    "monte_carlo settings {}": (  # was taken as "no settings" (falsy)
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=2, settings={}),
        ScenarioError,
        ("settings must be a MonteCarloSettings",),
    ),
    "monte_carlo problem 0": (  # was taken as "no problem" (falsy)
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=2, problem=0),
        ScenarioError,
        ("problem must be a RoutingProblem or None",),
    ),
    "monte_carlo scenario None": (
        lambda: public("monte_carlo")(None, [[-12.0, 45.0], [-20.0, 40.0]], runs=2),
        ScenarioError,
        ("scenario must be a Scenario", "got None"),
    ),
    "monte_carlo runs 10**30": (
        lambda: public("monte_carlo")(scenario(), [[-12.0, 45.0], [-20.0, 40.0]], runs=10**30),
        ScenarioError,
        ("runs must be at most",),
    ),
    "monte_carlo track 'x'": (
        lambda: public("monte_carlo")(scenario(), "x", runs=2),
        pr.TrackError,
        ("a track must be",),
    ),
    "route_ensemble None": (lambda: pr.route_ensemble(None), ScenarioError, ("scenario must be a file name",)),
    "route_ensemble path 5": (lambda: pr.route_ensemble(5), ScenarioError, ("scenario must be a file name",)),
    "route_ensemble member_files 5": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", member_files=5),
        ScenarioError,
        ("member_files must be a list of file names",),
    ),
    "route_ensemble member_files [None]": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", member_files=[None]),
        ScenarioError,
        ("member_files item must be a file name",),
    ),
    "route_ensemble members 'x'": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", members="x"),
        ScenarioError,
        ("members must be a list of ints",),
    ),
    "route_ensemble members [1.5]": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", members=[1.5]),
        ScenarioError,
        ("members must be whole numbers",),
    ),
    "route_ensemble members [0, 0, 1]": (  # issue 34: member 0 weighed twice in every risk measure
        lambda: pr.route_ensemble("/nonexistent/s.toml", members=[0, 0, 1]),
        ScenarioError,
        ("members must name each member once (got [0] more than once)",),
    ),
    "route_ensemble workers 0": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", workers=0),
        ScenarioError,
        ("workers must be a whole number >= 1",),
    ),
    "route_ensemble workers 'x'": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", workers="x"),
        ScenarioError,
        ("workers must be",),
    ),
    "route_ensemble mean_field None": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", mean_field=None),
        ScenarioError,
        ("mean_field must be True or False",),
    ),
    "route_ensemble options []": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", options=[]),
        ScenarioError,
        ("options must be a dict",),
    ),
    "route_ensemble risk 5": (
        lambda: pr.route_ensemble("/nonexistent/s.toml", risk=5),
        ScenarioError,
        ("risk must be a Risk",),
    ),
    # ---- trade-off fronts (pyroute_rel.routing.tradeoff, not exported at the top level)
    "tradeoff.bottleneck_front grid None": (
        lambda: tradeoff.bottleneck_front(None, route().problem),
        ScenarioError,
        ("grid must be a Grid", "got None"),
    ),
    "tradeoff.bottleneck_front problem 'x'": (
        lambda: tradeoff.bottleneck_front(route().grid, "x"),
        ScenarioError,
        ("problem must be a RoutingProblem", "'x', a str"),
    ),
    "tradeoff.bottleneck_front progress 'yes'": (
        lambda: tradeoff.bottleneck_front(route().grid, route().problem, progress="yes"),
        ScenarioError,
        ("progress must be True or False",),
    ),
    "tradeoff.voyage_front grid 5": (
        lambda: tradeoff.voyage_front(5, route().problem),
        ScenarioError,
        ("grid must be a Grid",),
    ),
    "tradeoff.voyage_front problem None": (
        lambda: tradeoff.voyage_front(route().grid, None),
        ScenarioError,
        ("problem must be a RoutingProblem",),
    ),
    "tradeoff.voyage_front max_labels 0": (
        lambda: tradeoff.voyage_front(route().grid, route().problem, max_labels=0),
        ScenarioError,
        ("max_labels (--max-labels) must be a whole number >= 1", "got 0"),
    ),
    "tradeoff.voyage_front max_labels -1": (
        lambda: tradeoff.voyage_front(route().grid, route().problem, max_labels=-1),
        ScenarioError,
        ("max_labels",),
    ),
    "tradeoff.voyage_front max_labels 'a'": (
        lambda: tradeoff.voyage_front(route().grid, route().problem, max_labels="a"),
        ScenarioError,
        ("max_labels", "'a'"),
    ),
    "tradeoff.voyage_front max_labels True": (
        lambda: tradeoff.voyage_front(route().grid, route().problem, max_labels=True),
        ScenarioError,
        ("max_labels",),
    ),
    "tradeoff.sensitivity problem None": (
        lambda: tradeoff.sensitivity(route().grid, None),
        ScenarioError,
        ("problem must be a RoutingProblem",),
    ),
    "tradeoff.sensitivity grid 'x'": (
        lambda: tradeoff.sensitivity("x", route().problem),
        ScenarioError,
        ("grid must be a Grid",),
    ),
    "tradeoff.sensitivity route 5": (
        lambda: tradeoff.sensitivity(route().grid, route().problem, route=5),
        ScenarioError,
        ("route must be a Route",),
    ),
    # ---- planners, track similarity, sweeps
    "plan scenario None": (lambda: pr.plan(None), ScenarioError, ("scenario must be a Scenario", "got None")),
    "plan scenario a file name": (lambda: pr.plan("s.toml"), ScenarioError, ("scenario must be a Scenario",)),
    "plan members 'x'": (
        lambda: pr.plan(scenario(), members="x"),
        ScenarioError,
        ("members must be a tuple of weather sources",),
    ),
    "plan members of numbers": (
        lambda: pr.plan(scenario(), members=(1, 2)),
        ScenarioError,
        ("members must be a tuple of weather sources",),
    ),
    "plan progress 'yes'": (
        lambda: pr.plan(scenario(), progress="yes"),
        ScenarioError,
        ("progress must be True or False",),
    ),
    "plan kind 'astar'": (lambda: pr.plan(scenario(), kind="astar"), ScenarioError, ("kind must be one of",)),
    "PlannedTrack lon 'x'": (
        lambda: pr.PlannedTrack("dp", "x", [0.0, 1.0], [0.0, 1.0], True),
        pr.TrackError,
        ("PlannedTrack.lon_deg must be a number", "'x', a str"),
    ),
    "PlannedTrack elapsed a dict": (
        lambda: pr.PlannedTrack("dp", [0.0, 1.0], [0.0, 1.0], {}, True),
        pr.TrackError,
        ("PlannedTrack.elapsed_h must be",),
    ),
    "PlannedTrack lengths": (
        lambda: pr.PlannedTrack("dp", [0.0, 1.0], [0.0, 1.0, 2.0], [0.0, 1.0], True),
        pr.TrackError,
        ("PlannedTrack.lat_deg must be a 1-D array, one value per track point",),
    ),
    "PlannedTrack reached None": (
        lambda: pr.PlannedTrack("dp", [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], None),
        pr.TrackError,
        ("PlannedTrack.reached must be True or False",),
    ),
    "PlannedTrack planner 5": (
        lambda: pr.PlannedTrack(5, [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], True),
        pr.TrackError,
        ("PlannedTrack.planner must be a str",),
    ),
    "PlannedTrack stats a list": (
        lambda: pr.PlannedTrack("dp", [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], True, stats=[]),
        pr.TrackError,
        ("PlannedTrack.stats must be a dict",),
    ),
    "PlannerSettings kind 5": (lambda: pr.PlannerSettings(kind=5), ScenarioError, ("[planner].kind must be one of",)),
    "PlannerSettings seed -1": (lambda: pr.PlannerSettings(seed=-1), ScenarioError, ("[planner].seed",)),
    "PlannerSettings mcts a dict": (
        lambda: pr.PlannerSettings(mcts={}),
        ScenarioError,
        ("PlannerSettings.mcts must be a MCTSSettings",),
    ),
    "track_similarity lon 'x'": (
        lambda: pr.track_similarity("x", [0.0, 1.0], [0.0, 1.0], [0.0, 1.0]),
        pr.CoordinateError,
        ("track A lon must be a number", "'x', a str"),
    ),
    "track_similarity lat_b a dict": (
        lambda: pr.track_similarity([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], {}),
        pr.CoordinateError,
        ("track B lat must be",),
    ),
    "track_similarity arrival 'x'": (
        lambda: pr.track_similarity([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], arrival_a="x"),
        pr.TrackError,
        ("arrival_a must be a UTC time", "'x'"),
    ),
    "track_similarity arrival a number": (  # was read as seconds after 1970 when the other was given
        lambda: pr.track_similarity(
            [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], arrival_a="2018-06-01T00:00", arrival_b=5
        ),
        pr.TrackError,
        ("arrival_b must be a UTC time", "(got 5)"),
    ),
    "track_similarity step_km True": (
        lambda: pr.track_similarity([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.0, 1.0], step_km=True),
        pr.CoordinateError,
        ("step_km must be in [0.01, 1000] [km]",),
    ),
    "load_sweep None": (lambda: pr.load_sweep(None), ScenarioError, ("sweep file must be a file name", "got None")),
    "load_sweep 5": (lambda: pr.load_sweep(5), ScenarioError, ("sweep file must be a file name",)),
    "run_sweep None": (lambda: pr.run_sweep(None), ScenarioError, ("runs must be a list of sweep runs", "got None")),
    "run_sweep 'x'": (lambda: pr.run_sweep("x"), ScenarioError, ("runs must be a list of sweep runs",)),
    "run_sweep runs of numbers": (lambda: pr.run_sweep([5]), ScenarioError, ("runs must hold sweep runs", "5")),
    "run_sweep engine an array": (
        lambda: pr.run_sweep([], engine=np.ones((2, 2))),
        ScenarioError,
        ("engine must be one of",),
    ),
    "run_sweep flush_s NaN": (lambda: pr.run_sweep([], flush_s=NAN), ScenarioError, ("flush_s must be", "finite")),
    "run_sweep connect_timeout_s 0": (
        lambda: pr.run_sweep([], connect_timeout_s=0),
        ScenarioError,
        ("connect_timeout_s must be a finite number > 0 [s]",),
    ),
    "run_sweep log 5": (lambda: pr.run_sweep([], log=5), ScenarioError, ("log must be a function",)),
    "run_sweep out ''": (lambda: pr.run_sweep([], out=""), ScenarioError, ("out must be a file name",)),
    "run_sweep progress None": (lambda: pr.run_sweep([], progress=None), ScenarioError, ("progress must be",)),
    # ---- grid convergence
    "grid_convergence None": (lambda: pr.grid_convergence(None, None), ConvergenceError, ()),
    "grid_convergence NaN h": (lambda: pr.grid_convergence([1, NAN, 4], [1, 2, 3]), ConvergenceError, ()),
    "grid_convergence unequal": (lambda: pr.grid_convergence([1, 2, 4], [1, 2]), ConvergenceError, ()),
    "least_squares_convergence 2-D": (
        lambda: pr.least_squares_convergence(np.ones((3, 2)), np.ones((3, 2))),
        ConvergenceError,
        (),
    ),
    "convergence_study inf phi": (
        lambda: pr.convergence_study([1, 2, 4], [1, INF, 3]),
        ConvergenceError,
        (),
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_bad_argument_is_a_domain_error_in_one_line(case: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # a call that wrongly succeeded would write here, not into the tree
    call, error, fragments = CASES[case]
    with pytest.raises(error) as info:
        call()
    message = str(info.value)
    assert isinstance(info.value, PyrouteError)
    assert "\n" not in message and 0 < len(message) <= 400, message
    for fragment in fragments:
        assert fragment in message, message
    assert list(tmp_path.iterdir()) == []  # nothing written


#: Public names that are values or take no argument
NO_ARGUMENTS = {"__version__", "list_failure_models", "clear_kept"}
#: Results the library builds and hands out (their constructors are not an entry point); a Protocol
RESULTS = {"Route", "Legs", "ForbiddenArcs", "Conditions", "Grid", "FailureModel", "Scenario", "WeatherSource"}
RESULTS |= {"EnsembleResult", "Evaluation"}


def _public_callables() -> list[str]:
    return [
        name
        for name in pr.__all__
        if name not in NO_ARGUMENTS
        and not (isinstance(public(name), type) and issubclass(public(name), BaseException | Warning))
    ]


def test_every_public_callable_is_called_with_bad_arguments() -> None:
    assert len(pr.__all__) >= 48
    covered = {case.split(" ")[0].split(".")[0] for case in CASES}
    assert set(_public_callables()) - RESULTS - covered == set()
    # and the results' methods that take user values are covered too
    assert {"Scenario", "Grid", "FailureModel"} <= {case.split(".")[0] for case in CASES}


@pytest.mark.parametrize("name", sorted(set(_public_callables()) - RESULTS))
def test_none_for_every_required_argument_is_a_domain_error(name: str, tmp_path: Path, monkeypatch) -> None:
    # the careless call: every required argument None
    monkeypatch.chdir(tmp_path)
    obj = public(name)
    params = inspect.signature(obj).parameters.values()
    required = {
        p.name: None
        for p in params
        if p.default is inspect.Parameter.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    }
    if not required:  # Avoid(), kept(), settings_context(): every argument has a default
        made = obj()
        if isinstance(obj, type):
            assert isinstance(made, obj)
        else:  # a context: entered and left
            with made:
                pass
        return
    with pytest.raises(PyrouteError) as info:
        obj(**required)
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("module", ["routing.refine", "analysis.monte_carlo"])
def test_pr_refine_is_the_function_even_after_importing_its_module(module: str) -> None:
    # found by this file: importing the module refine (or monte_carlo) once sat beside the function of the same name
    # and made pr.refine the module; the modules now live in their layers' folders, so nothing can bind over it
    name = module.rpartition(".")[2]
    code = f"import pyroute_rel.{module}, pyroute_rel as pr; print(callable(pr.{name}), hasattr(pr.{name}, '__code__'))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.stdout.strip() == "True True", out.stderr


# ---------------------------------------------------------------------------------------------------- accepted


def test_summary_json_is_strict_json_with_null_for_non_finite_numbers(tmp_path: Path, monkeypatch) -> None:
    r = route()
    real = type(r).summary
    monkeypatch.setattr(type(r), "summary", lambda self: {**real(self), "odd": [NAN, 1.5, {"x": -INF}]})
    pr.write_outputs(r, tmp_path / "o", plot=False, extra={"n": np.int64(3), "a": np.arange(2), "s": None})

    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} is not JSON")

    got = json.loads((tmp_path / "o" / "summary.json").read_text(), parse_constant=refuse)
    assert got["odd"] == [None, 1.5, {"x": None}]
    assert got["n"] == 3 and got["a"] == [0, 1] and got["s"] is None
    assert got["voyage_time_h"] == r.voyage_time_h


def test_a_refused_extra_writes_nothing(tmp_path: Path) -> None:
    with pytest.raises(OutputError):
        pr.write_outputs(route(), tmp_path / "o", plot=False, extra={"bad": NAN})
    assert list(tmp_path.iterdir()) == []


def test_register_weather_kind_accepts_names(monkeypatch) -> None:
    from pyroute_rel import config

    monkeypatch.setattr(config, "WEATHER_KINDS", dict(config.WEATHER_KINDS))
    for kind in ("calm", "my-kind_2", "K" * 64):
        pr.register_weather_kind(kind, _builder)
    with pytest.raises(ScenarioError, match="at most 64"):
        pr.register_weather_kind("K" * 65, _builder)


def test_nan_is_missing_and_passes_through_the_array_functions() -> None:
    # NaN means a missing value (documented): NaN in, NaN out, while the other points are computed
    speed = pr.boat_speed_kn(polar(), [NAN, 90.0], [10.0, 10.0])
    assert math.isnan(speed[0]) and speed[1] == pr.boat_speed_kn(polar(), 90.0, 10.0)
    c = gridded().sample([NAN, -19.5], 40.5, T0)
    assert math.isnan(c.tws_kn[0]) and c.tws_kn[1] == pytest.approx(math.hypot(1.0, 1.0) * 3600 / 1852, rel=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    hnp.arrays(
        np.float64,
        hnp.array_shapes(min_dims=0, max_dims=3, max_side=4),
        elements=st.floats(allow_nan=True, allow_infinity=True),
    )
)
def test_check_numbers_keeps_finite_values_and_names_the_first_infinity(values: np.ndarray) -> None:
    inf = np.isinf(values)
    if not inf.any():
        out = check_numbers(values, "x", ScenarioError)
        assert out.shape == values.shape and np.array_equal(out, values, equal_nan=True)
        return
    with pytest.raises(ScenarioError) as info:
        check_numbers(values, "x", ScenarioError)
    first = values.reshape(-1)[int(np.flatnonzero(inf.reshape(-1))[0])]
    assert f"got {first:g}" in str(info.value)


@settings(max_examples=60, deadline=None)
@given(
    st.one_of(
        st.none(),
        st.text(max_size=5),
        st.booleans(),
        st.complex_numbers(allow_nan=False, allow_infinity=False).filter(lambda z: z.imag != 0),
        st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
        st.lists(st.one_of(st.none(), st.text(max_size=2)), min_size=1, max_size=3),
    )
)
def test_boat_speed_refuses_anything_that_is_not_numbers(value: object) -> None:
    for twa, tws in ((value, 10.0), (90.0, value)):
        with pytest.raises(PolarError, match=r"(twa_deg|tws_kn) must be"):
            pr.boat_speed_kn(polar(), twa, tws)


@settings(max_examples=60, deadline=None)
@given(
    st.one_of(
        st.none(),
        st.text(max_size=5),
        st.booleans(),
        st.complex_numbers(allow_nan=False, allow_infinity=False).filter(lambda z: z.imag != 0),
        st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
        st.lists(st.one_of(st.none(), st.text(max_size=2)), min_size=2, max_size=3),
    ),
    st.booleans(),
)
def test_a_track_refuses_anything_that_is_not_numbers(value: object, as_lat: bool) -> None:
    # Track, evaluate_track and monte_carlo take the same points: a TrackError naming the coordinate, never a raw error
    good = [0.0, 1.0]
    with pytest.raises(pr.TrackError, match=r"Track\.(lon|lat)_deg must be a number"):
        pr.Track(good, value) if as_lat else pr.Track(value, good)
    with pytest.raises(pr.TrackError, match=r"a track must be|track must be a number"):
        # (a bool inside a list of numbers is the number numpy makes of it: only a bool on its own is refused)
        nested = as_lat and not isinstance(value, bool)
        pr.evaluate_track(scenario(), [[-12.0, 45.0], [value, 40.0]] if nested else value)
