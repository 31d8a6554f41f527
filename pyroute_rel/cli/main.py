"""The ``pyroute-rel`` command: a thin layer over the public API.

Exit codes: 0 success; 1 the run worked but a gate failed (e.g. ``gci study --max-gci``); 2 a user error
(bad scenario, polar, weather, failure model, no feasible route) reported in one line on stderr;
3 an unexpected internal error (with a request to report it; ``--debug`` shows the traceback).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pyroute_rel import __version__
from pyroute_rel.cli._help import APF_HELP
from pyroute_rel.cli.ensemble import add_ensemble_parser
from pyroute_rel.cli.evaluate import add_evaluate_parser
from pyroute_rel.cli.gci import NEGATIVE_NUMBERS, add_gci_parser
from pyroute_rel.cli.planners import add_compare_parser
from pyroute_rel.cli.sweep import add_sweep_parser
from pyroute_rel.cli.tradeoff import add_tradeoff_parser
from pyroute_rel.errors import PyrouteError, PyrouteWarning, ScenarioError

__all__ = ["main", "build_parser", "one_line", "MESSAGE_MAX_CHARS"]

EXIT_OK, EXIT_GATE, EXIT_USER, EXIT_INTERNAL = 0, 1, 2, 3


#: Longest message line printed [characters]: a user value echoed in a message (a 10 MB polar name, a key) is cut
#: in the middle beyond this, so that an error stays one readable line.
MESSAGE_MAX_CHARS = 1000


def one_line(text: object, limit: int = MESSAGE_MAX_CHARS) -> str:
    """``text`` on one line (white space runs collapsed), cut in the middle to at most ``limit`` characters.

    >>> one_line("a\\n  b"), len(one_line("x" * 5000))
    ('a b', 1000)
    """
    line = " ".join(str(text).split())
    if len(line) <= limit:
        return line
    keep = limit
    for _ in range(3):  # the note's own length depends on the count it states: settle it
        cut = f" ... [{len(line) - keep} characters cut] ... "
        keep = limit - len(cut)
    return line[: keep // 2] + cut + line[len(line) - (keep - keep // 2) :]


class _Parser(argparse.ArgumentParser):
    """argparse with exit code 2 and one line for usage errors (its default is also 2)."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        self.exit(EXIT_USER, f"{self.prog}: error: {one_line(message)} (see --help)\n")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--debug", action="store_true", help="show tracebacks of errors")


def _csv_ints(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers (got {text!r})") from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def _csv_floats(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.replace(" ", ",").split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers (got {text!r})") from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pyroute-rel``."""
    parser = _Parser(prog="pyroute-rel", description="Reliability-informed routing for autonomous sailing craft.")
    parser.add_argument("--version", action="version", version=f"pyroute-rel {__version__}")
    parser.set_defaults(debug=False)  # every command has --debug; main() reads args.debug whatever ran
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_route_parser(sub)
    f = sub.add_parser(
        "failure",
        help="show a failure model and its compiled table",
        description="Show a failure model (criteria, network, compiled P(fail | evidence)).",
    )
    f.add_argument("model", nargs="?", help="shipped model name or model file (omit to list shipped models)")
    f.add_argument("--json", action="store_true", help="print the model as one JSON object")
    _add_common(f)
    f.set_defaults(func=_cmd_failure)

    add_gci_parser(sub, _add_common, _csv_ints, _csv_floats)
    add_sweep_parser(sub, _add_common, _csv_floats)
    add_tradeoff_parser(sub, _add_common)
    add_evaluate_parser(sub, _add_common)
    add_ensemble_parser(sub, _add_common)
    add_compare_parser(sub, _add_common)
    return parser


def _add_grid_options(r: argparse.ArgumentParser) -> None:
    """``route``'s grid and sampling options."""
    r.add_argument(
        "--layout",
        choices=("angular", "square"),
        help="grid layout: angular (default: lateral refinement, banded arcs) or square (the paper's)",
    )
    r.add_argument(
        "--n-nodes",
        type=int,
        help="square layout: nodes per rank (overrides [grid].n_nodes; the angular layout derives its own "
        "from --half-width-km and --aspect)",
    )
    r.add_argument("--aspect", type=float, help="angular: rank spacing / lateral spacing")
    r.add_argument("--half-width-km", type=float, help="angular: distance from the great circle to the edge [km]")
    r.add_argument("--n-ranks", type=int, help="number of ranks (overrides [grid].n_ranks)")
    r.add_argument("--spacing-km", type=float, help="lateral node spacing [km] (overrides [grid].spacing_km)")
    r.add_argument(
        "--max-deviation",
        type=float,
        dest="max_deviation_deg",
        help="largest arc angle from the rank direction [deg] (overrides [grid].max_deviation_deg)",
    )
    r.add_argument("--samples", type=int, dest="samples_per_arc", help="weather samples per arc")
    r.add_argument(
        "--sample-km",
        type=float,
        dest="sample_km",
        help="weather samples along arcs at most this far apart [km] (default 25; overrides "
        "[grid].sample_km); a count with --samples instead",
    )
    r.add_argument(
        "--refine",
        type=int,
        metavar="LEVELS",
        help="refine the track in LEVELS corridor grids around it, each solved exactly: its points slide "
        "along the ranks (0 = none; overrides [grid].refine)",
    )


def _add_route_parser(sub: Any) -> None:
    """Add ``route``."""
    r = sub.add_parser(
        "route",
        help="route a scenario",
        description="Route a scenario TOML file. The runtime it reports (runtime_s in --json and summary.json) "
        "covers loading the scenario, polar, weather and failure model and routing, not writing --out files.",
    )
    r.add_argument("scenario", help="scenario TOML file")
    r._negative_number_matcher = NEGATIVE_NUMBERS  # "--time-step -inf" is a (bad) value, not an option
    _add_grid_options(r)
    r.add_argument("--apf", type=float, help=f"{APF_HELP} (overrides [failure].apf)")
    r.add_argument(
        "--max-memory",
        metavar="SIZE",
        help="memory budget, e.g. 8G or 500M (default: $PYROUTE_REL_MAX_MEMORY, else 75%% of the available "
        "memory): a route that would need more is refused before allocating",
    )
    r.add_argument("--failure-model", help="failure model name or file ('none' for no model)")
    r.add_argument(
        "--time-step",
        type=float,
        dest="time_step_h",
        help="time-expanded DP on this time lattice [h] (exact without FIFO; allows waiting)",
    )
    r.add_argument("--max-wait", type=float, dest="max_wait_h", help="longest wait at a node [h] (needs --time-step)")
    r.add_argument("--no-land", action="store_true", help="do not avoid land (overrides [avoid].land)")
    r.add_argument(
        "--prune",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="cost only the arcs that can still win (default): the same route, fewer arcs costed; "
        "--no-prune costs every arc, e.g. to count all forbidden arcs ([route].prune)",
    )
    r.add_argument("--departure", help="departure time, ISO 8601 UTC (overrides [route].departure)")
    r.add_argument(
        "--departure-window",
        metavar="START,END,STEP_H",
        help="when no route exists, also look for the earliest departure from START to END (ISO 8601 UTC) every "
        "STEP_H hours that routes, and say it (each is a route of the course: the window's size is the cost)",
    )
    r.add_argument(
        "--no-relax",
        action="store_true",
        help="when no route exists, say where and why only: do not route again to find what would make one (the "
        "smallest apf, a wider grid, a departure of --departure-window)",
    )
    r.add_argument("--departures", help="comma-separated ISO 8601 departure times: route each and print a table")
    r.add_argument(
        "--planner",
        choices=("dp", "mcts", "qlearning", "dqn"),
        help="who plans the track: dp (default, the exact DP), mcts, qlearning or dqn (overrides [planner].kind; "
        "the evaluator re-times their tracks; --out writes the same files from the re-timed track, without "
        "forbidden.geojson; --departures, --refine and --prune are the DP's)",
    )
    r.add_argument(
        "--out",
        help="folder for route.geojson, route.gpx (the track with times and speeds, and a route of its turning "
        "points for chart plotters such as OpenCPN), route.csv, summary.json, forbidden.geojson (the arcs the "
        "route could not take, and why), route.png",
    )
    r.add_argument(
        "--json",
        action="store_true",
        help="print the summary as one JSON object; its runtime_s, as the printed runtime, is the wall time from "
        "after argument parsing to the routed voyage: loading the scenario, polar, weather and failure model, "
        "and routing (writing --out files not included)",
    )
    _add_common(r)
    r.set_defaults(func=_cmd_route)


def _cmd_route(args: argparse.Namespace) -> int:
    if args.max_memory is None:
        return _route(args)
    from pyroute_rel.errors import MemoryBudgetError
    from pyroute_rel.resources import MEMORY_ENV, parse_bytes

    budget = str(parse_bytes(args.max_memory, "--max-memory"))
    before = os.environ.get(MEMORY_ENV)
    os.environ[MEMORY_ENV] = budget  # the grid, the failure table and the DP all read it
    try:
        return _route(args)
    except MemoryBudgetError as exc:  # the budget is the user's --max-memory, not the environment's
        raise MemoryBudgetError(str(exc).replace(f"the budget {MEMORY_ENV} is", "the budget --max-memory is")) from None
    finally:
        if before is None:
            del os.environ[MEMORY_ENV]
        else:
            os.environ[MEMORY_ENV] = before


def _route(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()  # runtime: loading the scenario, polar, weather and failure model, then routing
    from pyroute_rel.scenario import load_scenario

    options = dict(
        n_nodes=args.n_nodes,
        n_ranks=args.n_ranks,
        apf=args.apf,
        failure_model=args.failure_model,
        spacing_km=args.spacing_km,
        max_deviation_deg=args.max_deviation_deg,
        samples_per_arc=args.samples_per_arc,
        time_step_h=args.time_step_h,
        max_wait_h=args.max_wait_h,
        layout=args.layout,
        aspect=args.aspect,
        half_width_km=args.half_width_km,
        land=False if args.no_land else None,
        prune=args.prune,
        refine=args.refine,
        sample_km=args.sample_km,
        departure=args.departure,
    )
    for given, other in (("--departure", "--departures"), ("--departure-window", "--departures")):
        if getattr(args, given[2:].replace("-", "_")) is not None and args.departures is not None:
            raise ScenarioError(f"{given} and {other} do not go together: {other} routes each of its departures")
    if args.departure_window is not None and (args.planner or "dp") != "dp":
        raise ScenarioError("--departure-window applies to the DP only (leave it out, or use --planner dp)")
    scenario = load_scenario(args.scenario).with_options(**options)
    window = _departure_window(args.departure_window)
    if (args.planner or scenario.planner.kind) != "dp":
        from pyroute_rel.cli.planners import route_with_planner

        return route_with_planner(scenario, args, t0)
    if args.out is not None:  # '' too: refused, not read as "no --out"
        from pyroute_rel.files import check_out_dir
        from pyroute_rel.outputs import OUTPUT_FILES

        check_out_dir(args.out, files=OUTPUT_FILES)  # before the work, not after it
    if args.departures is not None:
        if args.out is not None:
            raise ScenarioError(
                "--out writes one route's files; with --departures use --json for the table, or "
                "route each departure on its own"
            )
        return _departure_sweep(args, {k: v for k, v in options.items() if v is not None})
    from pyroute_rel.errors import NoFeasibleRouteError

    try:
        route = scenario.route(progress=not args.quiet, departures=window, relax=not args.no_relax)
    except NoFeasibleRouteError as exc:  # the figures of what would route, then the one-line error
        _no_route(exc, scenario, args, time.perf_counter() - t0)
        raise
    elapsed = time.perf_counter() - t0
    summary = route.summary()
    summary["runtime_s"] = elapsed
    if args.out is not None:
        from pyroute_rel.outputs import write_outputs

        write_outputs(route, args.out, extra={"runtime_s": elapsed})
    if scenario.layout == "angular" and args.n_nodes is not None and not args.json:
        # only for --n-nodes: a scenario file may set n_nodes for its square layout (the examples do, and say so)
        print(
            f"pyroute-rel: note: --n-nodes {args.n_nodes} applies to layout = 'square'; the angular layout "
            f"used {route.grid.n_nodes} nodes per rank (half-width {route.grid.half_width_km:.0f} km, aspect "
            f"{route.grid.aspect:g}, arcs within {route.grid.max_deviation_deg:g} deg)",
            file=sys.stderr,
        )
    if route.touches_edge:
        print(f"pyroute-rel: warning: {widen_advice(scenario.layout, route.grid)}", file=sys.stderr)
    for note in scenario.notes:  # how the file was read (a time without a zone): with the result, even if --quiet
        print(f"pyroute-rel: note: {one_line(note)}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary))
    else:
        print(_route_text(route, elapsed, args.out, scenario.marks()))
    return EXIT_OK


def _departure_window(text: str | None) -> list[Any]:
    """``--departure-window START,END,STEP_H`` as the departures it tries (none without it)."""
    if text is None:
        return []
    from pyroute_rel.routing.relax import departure_window, window_size
    from pyroute_rel.scenario import parse_departure

    parts = [p.strip() for p in text.split(",")]
    try:
        step = float(parts[2]) if len(parts) == 3 else math.nan
    except ValueError:
        step = math.nan
    if len(parts) != 3 or not math.isfinite(step) or step <= 0.0:
        raise ScenarioError(
            f"--departure-window needs START,END,STEP_H: two ISO 8601 UTC times and a step > 0 [h] (got {text!r})"
        )
    first, last = (parse_departure(p, "--departure-window") for p in parts[:2])
    if last < first:
        raise ScenarioError(f"--departure-window: END {parts[1]} is before START {parts[0]}")
    n = window_size(first, last, step)
    if n > MAX_WINDOW:  # counted before any time is made
        raise ScenarioError(f"--departure-window tries {n} departures, more than {MAX_WINDOW}: use a larger STEP_H")
    return departure_window(first, last, step)


#: Most departures ``--departure-window`` tries (each is a route of the course).
MAX_WINDOW = 1000


def _no_route(error: Any, scenario: Any, args: argparse.Namespace, elapsed: float) -> None:
    """``route --json`` / ``--out`` when no route exists: the relaxation as JSON (printed, ``summary.json``) and the
    best partial route as a track (``route.*``: its map marks the finish and where the track stops)."""
    relaxation = getattr(error, "relaxation", None)
    summary = {
        "feasible": False,
        "error": str(error),
        "relaxation": None if relaxation is None else relaxation.summary(),
        "runtime_s": elapsed,
    }
    if args.out is not None:
        from pyroute_rel.outputs import write_no_route

        write_no_route(scenario, relaxation, summary, args.out)
    if args.json:
        print(json.dumps(summary))


def widen_advice(layout: str, grid: Any) -> str:
    """The grid-edge warning: the route uses the outermost nodes, and the option that widens the grid in use (the
    angular layout's width is its half-width; the square layout's, its nodes times their spacing)."""
    from pyroute_rel.routing.grid import widened

    head = "the route uses the outermost nodes of the grid, so a wider detour may be faster: widen the grid with "
    example = widened(layout, grid)[0]  # the grid twice as wide, as a failed route's relaxation tries it
    if layout == "angular":
        hw = grid.half_width_km
        return f"{head}--half-width-km (now {hw:.0f} km, [grid].half_width_km), e.g. {example}"
    return (
        f"{head}--n-nodes (now {grid.n_nodes}, [grid].n_nodes) or --spacing-km (now {grid.spacing_km:.3g} km, "
        f"[grid].spacing_km), e.g. {example}"
    )


def _departure_sweep(args: argparse.Namespace, options: dict[str, Any]) -> int:
    """Route one scenario for several departure times (planning): a table, or JSON with --json. A thin use of
    :mod:`pyroute_rel.batch.sweep` (one run per departure, on the sweep's default engine: a process pool from 16
    runs)."""
    from pyroute_rel.batch.sweep import Run, run_sweep
    from pyroute_rel.errors import NoFeasibleRouteError
    from pyroute_rel.scenario import parse_departure
    from pyroute_rel.times import iso_utc

    times = [parse_departure(t.strip(), "--departures") for t in args.departures.split(",") if t.strip()]
    if not times:
        raise ScenarioError(
            f"--departures needs at least one ISO 8601 UTC time, comma-separated (got {args.departures!r})"
        )
    repeated = sorted({str(t) for t in times if times.count(t) > 1})
    if repeated:
        raise ScenarioError(f"--departures lists {repeated[0]}Z more than once (each departure is routed once)")
    runs = [Run(args.scenario, departure=iso_utc(t), options=tuple(options.items())) for t in times]
    rows = []
    for r in run_sweep(runs, progress=not args.quiet).to_pylist():
        if r["status"] == "error":  # the scenario's own error, the same for every departure
            raise (RuntimeError if r["message"].startswith("internal error") else ScenarioError)(r["message"])
        row: dict[str, Any] = {"departure": r["departure"], "voyage_time_h": r["voyage_time_h"], "feasible": False}
        if r["status"] == "no_route":  # this departure only: the others still route
            row["reason"] = r["message"]
        else:
            row.update(feasible=True, arrival=r["arrival"], max_failure_probability=r["max_failure_probability"])
            if r["grid_voyage_time_h"] is not None:
                row["grid_voyage_time_h"] = r["grid_voyage_time_h"]
        rows.append(row)
    if args.json:
        print(json.dumps({"departures": rows}))
    else:
        print(f"{'departure':<22} {'voyage [h]':>11} {'arrival':<22} {'max p_f':>8}")
        for r in rows:
            if r["feasible"]:
                print(
                    f"{r['departure']:<22} {r['voyage_time_h']:>11.2f} {r['arrival']:<22} "
                    f"{r['max_failure_probability']:>8.3f}"
                )
            else:
                print(f"{r['departure']:<22} {'no route':>11}  {r['reason']}")
    if not any(r["feasible"] for r in rows):
        raise NoFeasibleRouteError("no departure time has a feasible route")
    return EXIT_OK


def hemispheres(lon_deg: float, lat_deg: float) -> str:
    """A position as sailors write it, latitude first, with hemispheres: the main defence against a start or
    finish given as [lat, lon] by mistake, which the numbers alone often cannot reveal (both orders are valid
    positions whenever |lon| <= 90).

    >>> hemispheres(-12.0, 45.0), hemispheres(151.25, -33.85), hemispheres(0.0, 0.0)
    ('45.00°N 12.00°W', '33.85°S 151.25°E', '0.00°N 0.00°E')
    """
    ns = "S" if lat_deg < 0 else "N"
    ew = "W" if lon_deg < 0 else "E"
    return f"{abs(lat_deg):.2f}°{ns} {abs(lon_deg):.2f}°{ew}"


def _marks_lines(marks: Sequence[tuple[str, tuple[float, float]]]) -> list[str]:
    """The course's marks with hemispheres (start, waypoints, finish), and [lon, lat] as written in the file."""
    lines = []
    for name, (lon, lat) in marks:
        label = name.removeprefix("[route].").replace("waypoints", "waypoint")
        lines.append(f"{label:<16} {hemispheres(lon, lat)}  ([lon, lat] = [{lon:g}, {lat:g}])")
    return lines


def _route_text(
    route: Any, elapsed: float, out: str | None, marks: Sequence[tuple[str, tuple[float, float]]] = ()
) -> str:
    s = route.summary()
    days, hours = divmod(round(route.voyage_time_h, 1), 24.0)  # 311.98 h is 13 d 0.0 h, not 12 d 24.0 h
    lines = [
        *_marks_lines(marks),
        f"voyage time      {route.voyage_time_h:.2f} h ({int(days)} d {hours:.1f} h)",
        f"distance         {route.distance_nm:.1f} nm",
        f"departure        {s['departure']}",
        f"arrival          {s['arrival']}",
        f"grid             {_grid_ranks(s['grid'])} x {route.grid.n_nodes} nodes, lateral spacing "
        f"{route.grid.spacing_km:.2f} km, rank spacing {route.grid.rank_spacing_km:.2f} km",
        f"arcs             {s['arcs']['evaluated']} evaluated, {s['arcs']['forbidden']} forbidden"
        + (f", {s['arcs']['pruned']} skipped (could not win)" if s["arcs"]["pruned"] else ""),
        *_refine_lines(s.get("refine")),
        f"failure model    {s.get('failure_model') or 'none'} (apf {s.get('apf', 1.0):g}): max leg p_f "
        f"{route.max_failure_probability:.3f}, voyage p_f {route.voyage_failure_probability:.3f}",
        f"manoeuvres       {s['manoeuvres']['tacks']} tacks, {s['manoeuvres']['gybes']} gybes, costing "
        f"{s['manoeuvres']['penalty_h'] * 3600.0:.0f} s",
        f"runtime          {elapsed:.2f} s (loading the scenario and its weather, routing)",
    ]
    if out:
        from pyroute_rel.outputs import OUTPUT_FILES

        lines.append(f"outputs          {Path(out)}/ ({', '.join(OUTPUT_FILES)})")
    return "\n".join(lines)


def _grid_ranks(grid: dict[str, Any]) -> str:
    legs = grid.get("legs")
    if not legs:
        return f"{grid['n_ranks']} ranks"
    return f"{grid['n_ranks']} ranks in {len(legs)} legs ({', '.join(str(g['n_ranks']) for g in legs)})"


def _refine_lines(info: Any) -> list[str]:
    if not info:
        return []
    levels = info["levels"]
    steps = " -> ".join(f"{lv['voyage_time_h']:.2f}" for lv in levels)
    arcs = sum(lv["arcs_evaluated"] for lv in levels)
    return [
        f"refined          {info['grid_voyage_time_h']:.2f} h on the grid -> {steps} h in {len(levels)} corridor"
        f"{'s' if len(levels) != 1 else ''} (last spacing {levels[-1]['spacing_km']:.3g} km, {arcs} arcs)"
    ]


def _cmd_failure(args: argparse.Namespace) -> int:
    from pyroute_rel.reliability.failure import list_failure_models, load_failure_model

    if args.model is None:
        names = list_failure_models()
        print(json.dumps({"models": names}) if args.json else "\n".join(names))
        return EXIT_OK
    model = load_failure_model(args.model)
    info = model.describe()
    if args.json:
        print(json.dumps(info))
        return EXIT_OK
    print(f"model: {info['model']}  ({info.get('path', '')})")
    if info.get("description"):
        print(info["description"])
    print("criteria:")
    for c in model.criteria:
        print(f"  {c.describe()}")
    net = info.get("network", {})
    if net:
        print("network: " + ", ".join(f"{a} -> {b}" for a, b in net.get("edges", [])))
    print("P(fail | evidence):")
    for row in info["table"]:
        ev = ", ".join(f"{k}={v}" for k, v in row["evidence"].items())
        print(f"  {ev:<50s} {row['p_fail']:.4f}")
    return EXIT_OK


def _one_line_warning(message: Warning | str, category: type[Warning], *_: object, **__: object) -> None:
    """Our warnings as one line on stderr, as errors are; others as Python shows them."""
    if issubclass(category, PyrouteWarning):
        print(f"pyroute-rel: warning: {one_line(message)}", file=sys.stderr)
    else:
        _SHOW_WARNING(message, category, *_, **__)  # type: ignore[arg-type]


_SHOW_WARNING = warnings.showwarning


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``pyroute-rel``; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default", PyrouteWarning)  # shown once each, never raised
            warnings.showwarning = _one_line_warning
            return func(args)
    except PyrouteError as exc:
        if args.debug:
            raise
        print(f"pyroute-rel: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USER
    except BrokenPipeError:  # e.g. piped into `head`: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except KeyboardInterrupt:
        print("pyroute-rel: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an unexpected failure: say how to report it
        if args.debug:
            raise
        print(
            f"pyroute-rel: internal error: {exc.__class__.__name__}: {one_line(exc)}. This is a bug: please report "
            "it with the command, the scenario file and the output of the same command with --debug.",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
