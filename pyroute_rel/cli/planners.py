"""``pyroute-rel route --planner mcts|qlearning|dqn`` and ``pyroute-rel compare TRACK_A TRACK_B``.

A planner other than the DP plans a track (:func:`pyroute_rel.planners.plan.plan`); the evaluator re-times it in the
scenario's weather (:func:`pyroute_rel.analysis.evaluate.evaluate_track`), and those are the figures printed: the same
measure as every other track.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

__all__ = ["add_compare_parser", "route_with_planner", "why_not_arrived", "PLANNER_FILES"]

#: Files ``route --planner ... --out DIR`` writes: those of a DP route (``pyroute_rel.outputs``) but
#: ``forbidden.geojson`` (the arcs the DP found forbidden); only ``summary.json`` when a leg cannot be sailed.
PLANNER_FILES = ("route.geojson", "route.gpx", "route.csv", "summary.json", "route.png")


def _planner_summary(scenario: Any, kind: str, progress: bool) -> tuple[Any, Any, Any, dict[str, Any]]:
    from pyroute_rel.analysis.evaluate import evaluate_track
    from pyroute_rel.planners.base import PlanningProblem
    from pyroute_rel.planners.plan import get_planner, track_route

    problem = PlanningProblem.of(scenario)
    planned = get_planner(kind).plan(problem, progress=progress)
    ev = evaluate_track(scenario, planned.points())
    summary = {
        "planner": kind,
        "reached": planned.reached,
        "planner_voyage_time_h": planned.voyage_time_h,
        "planner_stats": planned.stats,
        **ev.summary(),
    }
    if not planned.reached:
        summary["feasible"] = False
        summary["reason"] = summary.get("reason") or "not_reached"
        summary["arrival"] = None  # the track's end is not an arrival
        end = float(planned.lon_deg[-1]), float(planned.lat_deg[-1])
        summary["distance_to_finish_nm"] = problem.grid.distance_to_finish_nm(*end)
    return planned, ev, track_route(problem, planned, ev), summary


#: The setting that gives each planner more search when it did not reach the finish.
_MORE_SEARCH = {"mcts": "iterations", "qlearning": "episodes", "dqn": "episodes"}


def why_not_arrived(kind: str, scenario: Any, planned: Any, summary: dict[str, Any]) -> str:
    """One line on why a planner's track is not a route: it stopped short of the finish (how far, where, after how
    long, and which setting searches more), or a leg cannot be sailed as the router would (the evaluator's reason)."""
    if not planned.reached:
        setting = _MORE_SEARCH.get(kind)
        more = ""
        if setting is not None:
            now = planned.stats.get(setting) or getattr(getattr(scenario.planner, kind), setting)
            more = f"; search more with [planner.{kind}] {setting} (it ran {now}), or plan with --planner dp"
        return (
            f"the {kind} planner did not reach the finish: its track ends {summary['distance_to_finish_nm']:.0f} nm "
            f"short of it, at lon {planned.lon_deg[-1]:.2f}, lat {planned.lat_deg[-1]:.2f}, after "
            f"{planned.voyage_time_h:.1f} h{more}"
        )
    return f"the {kind} planner's track is not feasible as the router would sail it: {summary['reason']}" + (
        f" on leg {summary['blocked_leg']}" if summary.get("blocked_leg") is not None else ""
    )


def _write(out: str, route: Any, summary: dict[str, Any]) -> list[str]:
    """Write the planner's files (all or none); the names written."""
    from pyroute_rel.outputs import OUTPUT_FILES, track_writers, write_replacing

    text = json.dumps(summary, indent=1, allow_nan=False)
    writers: dict[str, Callable[[Path], object]] = {
        "summary.json": lambda p: Path(p).write_text(text, encoding="utf-8")
    }
    if route is not None:
        title = (
            f"{summary['planner']}: {route.voyage_time_h:.1f} h (re-timed by the evaluator)"
            if route.arrived
            else f"{summary['planner']}: did NOT reach the finish (ends {summary['distance_to_finish_nm']:.0f} nm "
            f"short after {route.voyage_time_h:.1f} h)"
        )
        writers.update(track_writers(route, title=title))
    # an earlier run's track that could be sailed, or a DP route's forbidden arcs: stale now
    write_replacing(out, writers, set(PLANNER_FILES) | set(OUTPUT_FILES), option="--out")
    return [n for n in PLANNER_FILES if n in writers]


def route_with_planner(scenario: Any, args: argparse.Namespace, t0: float) -> int:
    """Plan the scenario with ``args.planner`` (or its ``[planner].kind``), re-time the track, print and write it."""
    from pyroute_rel.errors import ScenarioError
    from pyroute_rel.files import check_out_dir
    from pyroute_rel.outputs import finite_or_null
    from pyroute_rel.planners.settings import unused_settings

    kind = args.planner or scenario.planner.kind
    scenario = replace(scenario, planner=replace(scenario.planner, kind=kind))
    dp_only = {"--departures": args.departures, "--refine": args.refine, "--prune": args.prune}
    for option, value in dp_only.items():
        if value is not None:
            shown = "--no-prune" if value is False else option
            raise ScenarioError(
                f"{shown} applies to the DP only (leave it out, or use --planner dp; the planner is {kind})"
            )
    if args.out is not None:
        check_out_dir(args.out, files=PLANNER_FILES)
    notes = [*scenario.notes, *(f"{scenario.source}: {n}" for n in unused_settings(scenario.planner))]
    planned, ev, route, summary = _planner_summary(scenario, kind, progress=not args.quiet)
    elapsed = time.perf_counter() - t0
    summary["runtime_s"] = elapsed
    summary = finite_or_null(summary)  # e.g. planner_stats.model_voyage_time_h inf when not reached: not JSON
    written = _write(args.out, route, summary) if args.out is not None else []
    for note in notes:  # as route's (with the result, even if --quiet)
        print(f"pyroute-rel: note: {' '.join(note.split())}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary))
        return _arrived_or_raise(kind, scenario, planned, summary)
    st = planned.stats
    voyage = summary["voyage_time_h"]
    lines = [
        f"planner          {kind} ({'reached the finish' if planned.reached else 'did NOT reach the finish'})",
        f"voyage time      {voyage:.2f} h (re-timed by the evaluator; the planner's own: {planned.voyage_time_h:.2f} h)"
        if voyage is not None and planned.reached
        else f"time sailed      {voyage:.2f} h, ending {summary['distance_to_finish_nm']:.0f} nm short of the finish"
        if voyage is not None
        else "voyage time      none (a leg cannot be sailed)",
        f"distance         {ev.distance_nm:.1f} nm",
        f"feasible         {summary['feasible']}" + (f" ({summary['reason']})" if summary["reason"] else ""),
        f"failure          max leg p_f {ev.max_failure_probability:.3f}, "
        f"voyage p_f {ev.voyage_failure_probability + 0.0:.3f}",  # no -0.000
        f"work             {_work(st)}",
        f"runtime          {elapsed:.2f} s",
    ]
    if args.out is not None:
        lines.append(f"outputs          {Path(args.out)}/ ({', '.join(written)})")
    print("\n".join(lines))
    return _arrived_or_raise(kind, scenario, planned, summary)


def _arrived_or_raise(kind: str, scenario: Any, planned: Any, summary: dict[str, Any]) -> int:
    """0 for a feasible track that reached the finish; else the no-route error (its one line, exit 2), after the
    figures were printed and the files written."""
    from pyroute_rel.errors import NoFeasibleRouteError

    if planned.reached and summary["feasible"]:
        return 0
    raise NoFeasibleRouteError(why_not_arrived(kind, scenario, planned, summary))


def _work(stats: dict[str, Any]) -> str:
    keys = ("iterations", "decisions", "episodes", "training_s", "states", "actions", "arcs_evaluated")
    return ", ".join(
        f"{k} {stats[k]:.3g}" if isinstance(stats[k], float) else f"{k} {stats[k]}" for k in keys if k in stats
    )


def add_compare_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``compare``."""
    c = sub.add_parser(
        "compare",
        help="how close two tracks are (cross-track distances, arrival difference)",
        description="Measure track B against track A (GPX, GeoJSON or CSV): the mean and largest distance of B's "
        "points from A, the Hausdorff distance, and B's arrival minus A's when both files have times.",
    )
    c.add_argument("track_a", help="reference track file (e.g. the DP's route.geojson)")
    c.add_argument("track_b", help="track file to measure against it")
    c.add_argument("--step-km", type=float, default=5.0, help="densify the tracks to points this far apart [km]")
    c.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    add_common(c)
    c.set_defaults(func=_cmd_compare)


def _cmd_compare(args: argparse.Namespace) -> int:
    from pyroute_rel.analysis.evaluate import read_track
    from pyroute_rel.analysis.similarity import track_similarity

    a, b = read_track(args.track_a), read_track(args.track_b)
    s = track_similarity(
        a.lon_deg,
        a.lat_deg,
        b.lon_deg,
        b.lat_deg,
        arrival_a=None if a.time is None else a.time[-1],
        arrival_b=None if b.time is None else b.time[-1],
        step_km=args.step_km,
    )
    if args.json:
        print(json.dumps(s.as_dict()))
        return 0
    diff = s.arrival_difference_h
    print(
        "\n".join(
            [
                f"mean cross-track  {s.mean_cross_track_nm:.2f} nm",
                f"max cross-track   {s.max_cross_track_nm:.2f} nm",
                f"hausdorff         {s.hausdorff_nm:.2f} nm",
                "arrival B - A     " + ("unknown (a track has no times)" if diff is None else f"{diff:+.2f} h"),
            ]
        )
    )
    return 0
