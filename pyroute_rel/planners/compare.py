"""Every planner on one scenario, measured the same way: the evaluator's re-timing, the gap to the DP (and to the
refined DP), feasibility, runtime and training time, and each track's distance from the DP's.

:func:`compare_planners` is what ``benchmarks/planners.py`` and ``examples/planners_comparison.py`` run per course;
:func:`pyroute_rel.viz.planners.planners_map` draws its tracks.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from pyroute_rel.analysis.evaluate import Evaluation, evaluate_track
from pyroute_rel.analysis.similarity import TrackSimilarity, track_similarity
from pyroute_rel.planners.base import PlannedTrack, PlanningProblem
from pyroute_rel.planners.plan import get_planner
from pyroute_rel.planners.settings import PLANNERS, PlannerSettings

if TYPE_CHECKING:
    from pyroute_rel.scenario import Scenario

__all__ = ["PlannerRun", "Comparison", "compare_planners", "episodes_to_final"]

#: Q-learning's greedy route is checked after this many evenly spaced episodes (per costing pass).
CHECKPOINTS = 100


def episodes_to_final(history: list[list[float]] | list[tuple[int, float]], final_h: float) -> int | None:
    """The first checkpoint from which Q-learning's greedy route time stays at ``final_h`` [h] to the end
    (``history``: ``[(episode, time_h), ...]``), or None without a history or when it never arrived."""
    if not history or not np.isfinite(final_h):
        return None
    first = None
    for episode, t in reversed(history):
        if not np.isclose(t, final_h, rtol=1e-12, atol=0.0):
            break
        first = int(episode)
    return first


@dataclass(frozen=True)
class PlannerRun:
    """One planner's track on a scenario and how it measures.

    Attributes
    ----------
    label : The planner, with its variant (e.g. ``"qlearning (cells)"``).
    track : What the planner returned.
    evaluation : The evaluator's re-timing of the track in the scenario's weather.
    similarity : The track measured against the DP's (None for the DP itself).
    """

    label: str
    track: PlannedTrack
    evaluation: Evaluation
    similarity: TrackSimilarity | None

    @property
    def voyage_time_h(self) -> float:
        """The evaluator's voyage time [h] (``inf`` when the track does not reach the finish)."""
        return self.evaluation.voyage_time_h if self.track.reached else float("inf")

    @property
    def feasible(self) -> bool:
        """True when the track reaches the finish and every leg may be sailed (no ``p_f > apf``, land or zone)."""
        return bool(self.track.reached and self.evaluation.feasible)


@dataclass(frozen=True)
class Comparison:
    """The planners' runs on one scenario (the DP's first) and the refined DP's voyage time.

    Attributes
    ----------
    name : The course's name.
    scenario : The scenario.
    runs : One per planner run, the DP first.
    refined_voyage_time_h : The DP refined in corridors (:mod:`pyroute_rel.refine`) [h], or None.
    """

    name: str
    scenario: Any
    runs: tuple[PlannerRun, ...]
    refined_voyage_time_h: float | None

    def rows(self) -> list[dict[str, Any]]:
        """One row per run: voyage [h], gaps to the DP and the refined DP [h], feasibility, runtime and training
        [s], iterations, cross-track distance from the DP's track [nm] (plain JSON values; None for missing)."""
        dp = self.runs[0].voyage_time_h
        out = []
        for r in self.runs:
            v = r.voyage_time_h
            st = r.track.stats
            out.append(
                {
                    "course": self.name,
                    "planner": r.label,
                    "voyage_time_h": v if np.isfinite(v) else None,
                    "gap_to_dp_h": v - dp if np.isfinite(v) else None,
                    "gap_to_refined_dp_h": (v - self.refined_voyage_time_h)
                    if np.isfinite(v) and self.refined_voyage_time_h is not None
                    else None,
                    "reached": r.track.reached,
                    "feasible": r.feasible,
                    "runtime_s": st.get("runtime_s"),
                    "training_s": st.get("training_s", 0.0),
                    "iterations": st.get("iterations_total", st.get("episodes", st.get("arcs_evaluated"))),
                    "episodes_to_final": episodes_to_final(
                        st.get("history", []), st.get("model_voyage_time_h", np.inf)
                    ),
                    "own_optimum_h": st.get("optimum_h"),
                    "pass_voyage_times_h": [
                        None if not np.isfinite(t) else t for t in st.get("pass_voyage_times_h", [])
                    ],
                    "mean_cross_track_nm": None if r.similarity is None else r.similarity.mean_cross_track_nm,
                    "max_cross_track_nm": None if r.similarity is None else r.similarity.max_cross_track_nm,
                }
            )
        return out


def compare_planners(
    scenario: Scenario,
    *,
    name: str = "",
    runs: list[tuple[str, str, PlannerSettings]] | None = None,
    refine: int = 2,
    progress: bool = False,
) -> Comparison:
    """Run the DP and each planner on a scenario and measure their tracks (see the module notes).

    Parameters
    ----------
    scenario : The scenario (a plain start-to-finish course for planners other than the DP).
    name : The course's name for the table.
    runs : ``(label, kind, settings)`` of each planner run after the DP; default every planner of
        :data:`~pyroute_rel.planners.settings.PLANNERS` with the scenario's ``[planner]`` settings.
    refine : Corridor refinements of the DP for the ``gap_to_refined_dp_h`` column (0: none).
    progress : Show progress bars.
    """
    todo = runs if runs is not None else [(k, k, scenario.planner) for k in PLANNERS if k != "dp"]
    dp_problem = PlanningProblem.of(scenario)
    dp = get_planner("dp").plan(dp_problem, progress=progress)
    done = [PlannerRun("dp", dp, evaluate_track(scenario, dp.points()), None)]
    arrival = _arrival(done[0])
    for label, kind, settings in todo:
        sc = replace(scenario, planner=replace(settings, kind=kind))
        t0 = _time.perf_counter()
        planner = get_planner(kind)
        if kind == "qlearning":  # the greedy route after each hundredth of the episodes: when it was found
            track = planner.plan(PlanningProblem.of(sc), progress=progress, checkpoints=CHECKPOINTS)  # type: ignore[call-arg]
        else:
            track = planner.plan(PlanningProblem.of(sc), progress=progress)
        track.stats.setdefault("runtime_s", _time.perf_counter() - t0)
        ev = evaluate_track(scenario, track.points())
        sim = track_similarity(
            dp.lon_deg, dp.lat_deg, track.lon_deg, track.lat_deg, arrival_a=arrival, arrival_b=_arrival_of(ev, track)
        )
        done.append(PlannerRun(label, track, ev, sim))
    refined = scenario.with_options(refine=refine).route().voyage_time_h if refine else None
    return Comparison(name, scenario, tuple(done), refined)


def _arrival(run: PlannerRun) -> np.datetime64:
    return run.evaluation.arrival


def _arrival_of(ev: Evaluation, track: PlannedTrack) -> np.datetime64 | None:
    return ev.arrival if track.reached and not np.isnat(ev.arrival) else None
