"""Run the planner a scenario names (its ``[planner]`` table, or the command line's ``--planner``)."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from pyroute_rel.errors import ScenarioError, brief, check_flag, check_instance
from pyroute_rel.planners.base import PlannedTrack, Planner, PlanningProblem
from pyroute_rel.planners.settings import PLANNERS

if TYPE_CHECKING:
    from pyroute_rel.analysis.evaluate import Evaluation
    from pyroute_rel.routing.route import Route
    from pyroute_rel.scenario import Scenario
    from pyroute_rel.weather import WeatherSource

__all__ = ["get_planner", "plan", "track_route"]


def get_planner(kind: str) -> Planner:
    """The planner named ``kind`` (one of :data:`~pyroute_rel.planners.settings.PLANNERS`), with the settings of the
    problem it is given."""
    if kind == "dp":
        from pyroute_rel.planners.dp import DPPlanner

        return DPPlanner()
    if kind == "mcts":
        from pyroute_rel.planners.mcts import MCTSPlanner

        return MCTSPlanner()
    if kind == "qlearning":
        from pyroute_rel.planners.qlearning import QLearningPlanner

        return QLearningPlanner()
    if kind == "dqn":
        from pyroute_rel.planners.dqn import DQNPlanner

        return DQNPlanner()
    raise ScenarioError(f"planner must be one of {list(PLANNERS)} (got {kind!r})")


def plan(
    scenario: Scenario,
    *,
    kind: str | None = None,
    members: tuple[WeatherSource, ...] = (),
    progress: bool = False,
) -> PlannedTrack:
    """Plan a scenario's track with its planner (``kind`` overrides ``[planner].kind``).

    Examples
    --------
    >>> from pyroute_rel import scenario_from_mapping
    >>> sc = scenario_from_mapping({
    ...     "route": {"start": [-12.0, 45.0], "finish": [-14.0, 43.0]},
    ...     "grid": {"layout": "square", "n_ranks": 6, "n_nodes": 7},
    ...     "weather": {"kind": "uniform", "tws_kn": 15.0, "twd_deg": 0.0}, "avoid": {"land": False},
    ...     "planner": {"kind": "qlearning", "qlearning": {"episodes": 300, "gamma": 1.0}}})
    >>> track = plan(sc)
    >>> track.planner, track.reached, track.stats["nodes"] == plan(sc, kind="dp").stats["nodes"]
    ('qlearning', True, True)
    """
    from pyroute_rel.scenario import Scenario
    from pyroute_rel.weather import WeatherSource

    check_instance(scenario, Scenario, "scenario", ScenarioError, expected="a Scenario (pyroute_rel.load_scenario)")
    progress = check_flag(progress, "progress", ScenarioError)
    if not isinstance(members, tuple | list) or not all(isinstance(m, WeatherSource) for m in members):
        raise ScenarioError(
            f"members must be a tuple of weather sources, one per ensemble member (got {brief(members)})"
        )
    settings = scenario.planner if kind is None else replace(scenario.planner, kind=kind)
    problem = PlanningProblem.of(scenario, settings=settings, members=members)
    return get_planner(settings.kind).plan(problem, progress=progress)


def track_route(problem: PlanningProblem, planned: PlannedTrack, evaluation: Evaluation) -> Route | None:
    """A planner's track as a :class:`~pyroute_rel.routing.route.Route`, so the DP's outputs (map, GPX, CSV, GeoJSON:
    :mod:`pyroute_rel.outputs`, :func:`pyroute_rel.viz.maps.plot_route`) write it: the evaluator's re-timed track
    (:func:`~pyroute_rel.analysis.evaluate.evaluation_route`) on the scenario's grid and problem, with the planner's
    nodes on the grid (Q-learning on the graph) or none; it ``arrived`` when the planner reached the finish. None when
    a leg cannot be sailed (no times after it)."""
    from pyroute_rel.analysis.evaluate import evaluation_route

    return evaluation_route(
        evaluation,
        problem.grid,
        problem.problem,
        arrived=bool(planned.reached),
        nodes=planned.stats.get("nodes") or (),
        zones=tuple(problem.scenario.avoid.zones),
    )
