"""The exact forward DP (:meth:`pyroute_rel.scenario.Scenario.route`) as a planner, the reference of the others."""

from __future__ import annotations

import time as _time

from pyroute_rel.planners.base import PlannedTrack, PlanningProblem

__all__ = ["DPPlanner"]


class DPPlanner:
    """The forward DP on the scenario's rank digraph (refined in corridors when the scenario says so)."""

    name = "dp"

    def plan(self, problem: PlanningProblem, *, progress: bool = False) -> PlannedTrack:
        """Route the scenario with the DP; its track and the times the DP found."""
        t0 = _time.perf_counter()
        route = problem.scenario.route(progress=progress)
        stats = {
            "runtime_s": _time.perf_counter() - t0,
            "training_s": 0.0,
            "arcs_evaluated": route.dp.arcs_evaluated,
            "nodes": route.nodes.tolist(),
        }
        return PlannedTrack(self.name, route.lon_deg, route.lat_deg, route.elapsed_h, True, stats)
