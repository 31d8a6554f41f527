"""``pyroute-rel ensemble``: route every member of an ensemble forecast and choose a route by risk."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from typing import Any

__all__ = ["add_ensemble_parser", "ENSEMBLE_FILES"]

EXIT_OK = 0

#: The files ``ensemble --out`` writes.
ENSEMBLE_FILES = ("ensemble.json", "spaghetti.png", "arrival_cdf.png", "regret.png")


def _members(text: str) -> list[int] | None:
    if text.strip().lower() == "all":
        return None
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'all' or comma-separated member numbers (got {text!r})") from None
    if not values:
        raise argparse.ArgumentTypeError("expected 'all' or at least one member number")
    return values


def add_ensemble_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``ensemble`` to the CLI."""
    e = sub.add_parser(
        "ensemble",
        help="route every member of an ensemble forecast and choose a route by risk",
        description="Route every member of the scenario's ensemble weather ([weather] files with a number, "
        "realization or member dimension, or --member-files) and the ensemble mean, sail every route in every "
        "member, and choose the route whose arrival times have the least risk measure among those infeasible in "
        "the fewest members. Prints the candidates' arrival distributions and the choice; --json gives the regret "
        "matrix too.",
    )
    e.add_argument("scenario", help="scenario TOML file ([weather] kind = 'file')")
    e.add_argument("--members", type=_members, default=None, help="'all' (default) or member numbers, e.g. 0,3,7")
    e.add_argument(
        "--member-files",
        nargs="+",
        metavar="FILE",
        help="one weather file per member, replacing the first of [weather].paths",
    )
    e.add_argument("--risk", default="cvar:0.9", help="mean, pXX (e.g. p90), cvar:ALPHA (default cvar:0.9) or worst")
    e.add_argument("--no-mean", action="store_true", help="do not route the ensemble-mean field")
    e.add_argument(
        "--engine",
        choices=("auto", "inline", "processes", "dask"),
        default="auto",
        help="where members are routed and sailed: auto (the default: dask with --scheduler, else processes), "
        "inline (this process), processes (local processes, --workers), dask (--scheduler's cluster, else a "
        "LocalCluster of --workers processes, one thread each); the result does not depend on it",
    )
    e.add_argument(
        "--workers",
        type=int,
        help="processes, or the dask LocalCluster's workers (default: the CPUs available; 1: no child processes)",
    )
    e.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="address of a running dask scheduler")
    e.add_argument(
        "--connect-timeout",
        type=float,
        default=10.0,
        help="how long to try reaching --scheduler and wait for a worker there [s] (default 10)",
    )
    e.add_argument("--json", action="store_true", help="print the result as one JSON object")
    e.add_argument("--out", help=f"folder for {', '.join(ENSEMBLE_FILES)}")
    add_common(e)
    e.set_defaults(func=_cmd_ensemble)


def _cmd_ensemble(args: argparse.Namespace) -> int:
    from pyroute_rel.analysis.ensemble import parse_risk, route_ensemble

    risk = parse_risk(args.risk)  # before the work
    if args.workers is not None and args.workers < 1:
        from pyroute_rel.errors import ScenarioError

        raise ScenarioError(f"--workers must be a whole number >= 1 (got {args.workers})")
    if args.out is not None:
        from pyroute_rel.files import check_out_dir

        check_out_dir(args.out, files=ENSEMBLE_FILES)
    result = route_ensemble(
        args.scenario,
        members=args.members,
        member_files=args.member_files,
        risk=risk,
        mean_field=not args.no_mean,
        workers=args.workers,
        progress=not args.quiet,
        engine=args.engine,
        scheduler=args.scheduler,
        connect_timeout_s=args.connect_timeout,
    )
    summary = result.summary()
    if args.out is not None:
        _write(result, summary, args.out)
    print(json.dumps(summary) if args.json else _text(summary))
    return EXIT_OK


def _write(result: Any, summary: dict[str, Any], out: str) -> None:
    from pyroute_rel.files import write_together
    from pyroute_rel.viz.ensemble import arrival_cdf, regret_heatmap, spaghetti_map

    write_together(
        out,
        {
            "ensemble.json": lambda p: p.write_text(json.dumps(summary, indent=1), encoding="utf-8"),
            "spaghetti.png": lambda p: spaghetti_map(result, path=p),
            "arrival_cdf.png": lambda p: arrival_cdf(result, path=p),
            "regret.png": lambda p: regret_heatmap(result, path=p),
        },
    )


def _h(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.1f}"


def _text(s: dict[str, Any]) -> str:
    members = s["members"]
    routed = sum(1 for m in members if m["feasible"])
    lines = [
        f"members          {len(members)} ({routed} with a route)",
        f"{'candidate':<12} {'mean':>7} {'p5':>7} {'p50':>7} {'p95':>7} {'cvar':>7} {'worst':>7} {'risk':>7} "
        f"{'p_f>apf':>8} {'infeas.':>8}",
    ]
    for c in s["candidates"]:
        a = c["arrival_h"]
        lines.append(
            f"{c['name']:<12} {_h(a['mean']):>7} {_h(a['p5']):>7} {_h(a['p50']):>7} {_h(a['p95']):>7} "
            f"{_h(a['cvar']):>7} {_h(a['worst']):>7} {_h(c['risk_h']):>7} {c['p_fail_conditions']:>8.2f} "
            f"{c['infeasible_members']:>8.2f}"
        )
    ch = s["chosen"]
    if any(_h(v) == "-" for c in s["candidates"] for v in (*c["arrival_h"].values(), c["risk_h"])):
        lines.append("                 (-: infinite, the candidate does not arrive in the members that figure needs)")
    lines.append(
        f"choice           feasibility first: of the candidates infeasible in the fewest members, the least "
        f"{ch['risk']} [h]"
    )
    line = (
        f"chosen           {ch['name']}: {ch['risk']} {_h(ch['value_h'])} h, infeasible in "
        f"{ch['infeasible_members']:.0%} of the members"
    )
    if ch.get("mean_field_value_h") is not None or ch.get("mean_field_infeasible_members") is not None:
        line += (
            f"; the mean-field route: {_h(ch['mean_field_value_h'])} h, infeasible in "
            f"{ch['mean_field_infeasible_members']:.0%}" + _against_mean(ch)
        )
    lines.append(line)
    return "\n".join(lines)


def _against_mean(ch: dict[str, Any]) -> str:
    """How the chosen route compares with the mean-field route, signed right: ``beats_mean_field_by_h`` is the
    mean-field route's risk minus the chosen one's [h]."""
    beats = ch["beats_mean_field_by_h"]
    if beats is None:
        return ""
    if beats >= 0.0:
        return f" (the chosen route's {ch['risk']} is {beats:.1f} h less)"
    return (
        f" (its {ch['risk']} is {-beats:.1f} h less, but it is infeasible in more members: feasibility decides first)"
    )
