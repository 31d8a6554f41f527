"""``pyroute-rel tradeoff``: time against reliability (:mod:`pyroute_rel.routing.tradeoff`) from the command line."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from pyroute_rel.cli._help import APF_HELP
from pyroute_rel.errors import NoFeasibleRouteError, ScenarioError

__all__ = ["add_tradeoff_parser", "OUTPUT_FILES"]

#: The files ``--out`` writes.
OUTPUT_FILES = ("front.png", "routes.png", "sensitivity.png", "tradeoff.json")


def add_tradeoff_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``tradeoff`` to the CLI."""
    from pyroute_rel.routing.tradeoff import MAX_LABELS

    t = sub.add_parser(
        "tradeoff",
        help="the exact front of voyage time against reliability, and what each failure criterion costs",
        description="The Pareto front of voyage time against reliability on the scenario's grid: 'bottleneck' "
        "(largest leg p_f; one route per front point plus one) or 'voyage' (voyage failure probability from the "
        "time spent in each condition; label setting, exact on the grid with steady weather). Arcs with p_f above "
        "the scenario's apf stay forbidden. Also the sensitivity to each criterion of the failure model at the apf: "
        "the hours it costs (routes with and without it) and where it binds. Routes on the grid unless --refine; "
        "a course through waypoints is routed leg after leg, the voyage front's labels carried from mark to mark.",
    )
    t.add_argument("scenario", help="scenario TOML file")
    t.add_argument(
        "--front", choices=("bottleneck", "voyage"), default="bottleneck", help="which front (default bottleneck)"
    )
    t.add_argument(
        "--max-labels",
        type=int,
        default=None,
        help=f"voyage front: most non-dominated labels a node may hold (default {MAX_LABELS}); past it the run "
        "stops with an error",
    )
    t.add_argument(
        "--refine",
        type=int,
        default=0,
        metavar="LEVELS",
        help="bottleneck front: route each front point again as `route --apf P --refine LEVELS` does (P its largest "
        "leg p_f: corridor grids around it), keeping the non-dominated results (default 0: the routes on the grid; "
        "[grid].refine is not applied)",
    )
    t.add_argument("--apf", type=float, help=f"{APF_HELP} (overrides [failure].apf)")
    t.add_argument("--n-ranks", type=int, help="number of ranks (overrides [grid].n_ranks)")
    t.add_argument("--json", action="store_true", help="print the result as one JSON object")
    t.add_argument("--out", help="folder for " + ", ".join(OUTPUT_FILES))
    add_common(t)
    t.set_defaults(func=_cmd_tradeoff)


def _cmd_tradeoff(args: argparse.Namespace) -> int:
    from pyroute_rel.files import check_out_dir, write_together
    from pyroute_rel.outputs import finite_or_null
    from pyroute_rel.scenario import load_scenario

    t0 = time.perf_counter()
    if args.max_labels is not None and args.max_labels < 1:  # refused whichever front
        raise ScenarioError(f"--max-labels must be a whole number >= 1 (got {args.max_labels})")
    if args.max_labels is not None and args.front != "voyage":  # never silently ignored
        raise ScenarioError(
            "--max-labels applies to the voyage front (--front voyage): the bottleneck front holds one label a node"
        )
    if args.refine < 0:
        raise ScenarioError(f"--refine must be a whole number >= 0 (got {args.refine})")
    if args.refine and args.front == "voyage":
        raise ScenarioError("--refine applies to the bottleneck front: the voyage front is computed on the grid")
    scenario = load_scenario(args.scenario).with_options(apf=args.apf, n_ranks=args.n_ranks)
    if args.out is not None:
        check_out_dir(args.out, files=OUTPUT_FILES)
    result = _compute(scenario, args)
    doc = _document(result, args.front)
    doc["refine"] = args.refine
    doc["runtime_s"] = time.perf_counter() - t0
    text = json.dumps(finite_or_null(doc), allow_nan=False)  # a hazard is inf where a leg meets p_f = 1: null
    if args.out is not None:
        figures = _figures(result, args.front)
        writers = {name: _png_writer(fig) for name, fig in figures.items()}
        writers["tradeoff.json"] = lambda p: p.write_text(
            json.dumps(json.loads(text), indent=1) + "\n", encoding="utf-8"
        )
        write_together(args.out, writers, option="--out")
    print(text if args.json else _text(doc, args.out))
    return 0


def _png_writer(fig: Any) -> Callable[[Path], object]:
    """Writes the figure ``fig`` as PNG to the path it is given."""
    return lambda p: fig.savefig(p, format="png")


def _compute(scenario: Any, args: argparse.Namespace) -> dict[str, Any]:
    """The fronts (the bottleneck front always: its routes are the single-apf routes), the route at the apf and
    the sensitivity table; a course through waypoints leg after leg, on one grid per leg."""
    from pyroute_rel.routing.tradeoff import (
        MAX_LABELS,
        course_bottleneck_front,
        course_route,
        course_sensitivity,
        course_voyage_front,
        refined_front,
    )

    failure = scenario.load_failure()
    grids = scenario.leg_grids()
    legs = [(g, scenario.problem(failure=failure, grid=g)) for g in grids]
    progress = not args.quiet
    try:
        bottleneck = course_bottleneck_front(legs, progress=progress)
    except NoFeasibleRouteError:  # no route at the apf: the scenario's own error says what would make one
        scenario.route(grids=grids)
        raise
    if args.refine:
        refined = scenario.with_options(refine=args.refine)

        def route_at(apf: float) -> Any:
            return replace(refined, apf=apf).route(grids=grids)

        bottleneck = refined_front(bottleneck, route_at, progress=progress)
    voyage = None
    if args.front == "voyage":
        max_labels = MAX_LABELS if args.max_labels is None else args.max_labels
        voyage = course_voyage_front(legs, max_labels=max_labels, progress=progress)
    route = course_route(legs)  # the route at the apf (its arc costs are cached on the grids by now)
    rows = course_sensitivity(legs, route)
    return {"bottleneck": bottleneck, "voyage": voyage, "route": route, "rows": rows, "problem": legs[0][1]}


def _document(result: dict[str, Any], kind: str) -> dict[str, Any]:
    """The JSON of ``--json`` and ``tradeoff.json``."""
    front = result[kind]
    return {
        "kind": kind,
        "apf": float(result["problem"].apf),
        "front": [p.as_dict() for p in front.points],
        "runs": front.runs,
        "labels": {"mean": front.labels_mean, "max": front.labels_max},
        "single_apf": [{k: v for k, v in p.as_dict().items() if k != "track"} for p in result["bottleneck"].points],
        "sensitivity": [row.as_dict(result["route"]) for row in result["rows"]],
    }


def _figures(result: dict[str, Any], kind: str) -> dict[str, Any]:
    from pyroute_rel.routing.tradeoff import bounding_criterion
    from pyroute_rel.viz.tradeoff import OBJECTIVE, front_figure, routes_figure, sensitivity_figure

    key, _ = OBJECTIVE[kind]
    marked = [
        (f"route at apf {p.apf:.3g}", p.voyage_time_h, getattr(p, key), p.hazard) for p in result["bottleneck"].points
    ]
    route, rows = result["route"], result["rows"]
    return {
        "front.png": front_figure(result[kind], marked),
        "routes.png": routes_figure(result[kind]),
        "sensitivity.png": sensitivity_figure(route, rows, bounding_criterion(rows, route.legs.n_legs)),
    }


def _text(doc: dict[str, Any], out: str | None) -> str:
    """The tables printed without ``--json``."""
    lines = [
        f"{doc['kind']} front at apf {doc['apf']:g}: {len(doc['front'])} routes ({doc['runs']} runs, "
        f"{doc['runtime_s']:.1f} s)"
    ]
    if doc["refine"]:
        lines[0] += f", each route refined in {doc['refine']} corridor levels"
    if doc["labels"]["max"] is not None:
        lines[0] += f", labels per node: mean {doc['labels']['mean']:.1f}, max {doc['labels']['max']}"
    lines.append(f"{'time [h]':>10} {'max p_f':>8} {'voyage p_f':>10} {'hazard':>8} {'distance [nm]':>13}")
    for p in doc["front"]:
        lines.append(
            f"{p['voyage_time_h']:10.2f} {p['max_failure_probability']:8.3g} "
            f"{p['voyage_failure_probability']:10.4f} {p['hazard']:8.3g} {p['distance_nm']:13.1f}"
        )
    if doc["sensitivity"]:
        lines.append(f"sensitivity at apf {doc['apf']:g}:")
        lines.append(f"{'criterion':<28} {'costs [h]':>9} {'exposed [h]':>11} {'bent [h]':>8}")
        for r in doc["sensitivity"]:
            lines.append(f"{r['criterion']:<28} {r['hours_cost']:9.2f} {r['exposure_h']:11.2f} {r['bound_h']:8.1f}")
    if out is not None:
        lines.append(f"wrote {', '.join(OUTPUT_FILES)} to {out}")
    return "\n".join(lines)
