"""``pyroute-rel sweep``: many routes of one scenario (:mod:`pyroute_rel.batch.sweep`), a table and a plot."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pyroute_rel.cli._help import APF_HELP

__all__ = ["add_sweep_parser", "departures_option"]


def departures_option(text: str) -> Any:
    """``--departures``: ``START,END,STEP_H`` (a range every STEP_H hours) or ISO 8601 times, comma-separated;
    as the ``departures`` of a ``[sweep]`` table.

    >>> departures_option("2018-06-01T00:00Z,2018-06-02T00:00Z,12")
    {'start': '2018-06-01T00:00Z', 'end': '2018-06-02T00:00Z', 'step_h': 12.0}
    >>> departures_option("2018-06-01T00:00Z, 2018-06-05T00:00Z")
    ['2018-06-01T00:00Z', '2018-06-05T00:00Z']
    """
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if len(parts) == 3:
        try:
            return {"start": parts[0], "end": parts[1], "step_h": float(parts[2])}
        except ValueError:
            pass
    return parts


def _members_option(text: str) -> Any:
    if text.strip() == "all":
        return "all"
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'all' or comma-separated member numbers (got {text!r})") from None


def add_sweep_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None], csv_floats: Any) -> None:
    """Add ``sweep`` to the ``pyroute-rel`` command."""
    s = sub.add_parser(
        "sweep",
        help="route many runs of a scenario (departures, members, apf, polars, grids): a table and a plot",
        description="Route every run of a sweep specification (a TOML file with a [sweep] table), or of a "
        "scenario with --departures; print a table of the runs and plot voyage time and voyage p_f against "
        "departure. With --out the runs are recorded as they finish (runs.parquet/, tracks/): running the same "
        "command again routes only the runs not yet recorded.",
    )
    s.add_argument("spec", help="sweep specification (TOML with [sweep]) or a scenario TOML file")
    s.add_argument(
        "--departures",
        type=departures_option,
        help="START,END,STEP_H (ISO 8601 times, hours) or comma-separated ISO 8601 departure times",
    )
    s.add_argument("--members", type=_members_option, help="ensemble members: 'all' or comma-separated numbers")
    s.add_argument("--apf", type=csv_floats, help=f"comma-separated values, each an {APF_HELP}")
    s.add_argument("--out", help="folder for runs.parquet/ (one part per finished batch), tracks/ and sweep.png")
    s.add_argument("--plot", help="PNG to write the plot to (default: sweep.png in --out; none without --out)")
    s.add_argument(
        "--engine",
        choices=("auto", "inline", "processes", "dask"),
        help="where runs are routed: auto (the default: this process below 16 runs to route or on one CPU, else "
        "a local pool of one process per CPU), inline (this process), processes (a local pool of --workers), "
        "dask (--scheduler's cluster, or a LocalCluster of --workers one thread each; the default with either)",
    )
    s.add_argument(
        "--workers",
        type=int,
        help="worker processes, at most one per CPU (a warning and the CPUs beyond): a dask LocalCluster, or the "
        "pool of --engine processes or auto; not with --engine inline nor --scheduler",
    )
    s.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="address of a running dask scheduler")
    s.add_argument(
        "--retries",
        type=int,
        default=2,
        help="a run with an internal error, or a task whose worker died, is tried again this often (default 2)",
    )
    s.add_argument(
        "--batch",
        type=int,
        help="with --out, write a part file every this many finished runs (or every 5 s): a killed sweep loses at "
        "most the runs of its last batch (default 32)",
    )
    s.add_argument("--connect-timeout", type=float, help="how long to try reaching --scheduler [s] (default 10)")
    s.add_argument("--json", action="store_true", help='print {"runs": [one object per run]} instead of a table')
    add_common(s)
    s.set_defaults(func=_cmd_sweep)


def _spec_table(args: argparse.Namespace) -> tuple[dict[str, Any], Path, str]:
    """The sweep table of the file (a spec, or a scenario made into one), with the options written in."""
    from pyroute_rel.batch.sweep import SweepError
    from pyroute_rel.scenario import read_scenario_table

    path = Path(args.spec)
    table = read_scenario_table(path)
    if "sweep" in table:
        spec = dict(table["sweep"]) if isinstance(table["sweep"], dict) else table["sweep"]
        base, source = path.parent, str(path)
    else:
        spec, base, source = {"scenario": str(path.resolve())}, Path("."), str(path)
    if not isinstance(spec, dict):
        raise SweepError(f"{source}: [sweep] must be a table")
    for key, value in (("departures", args.departures), ("members", args.members), ("apf", args.apf)):
        if value is not None:
            spec[key] = value
    return {"sweep": spec}, base, source


def _engine(args: argparse.Namespace) -> str:
    if args.engine is not None:
        return str(args.engine)
    return "dask" if args.scheduler is not None or args.workers is not None else "auto"


def _check_combinations(args: argparse.Namespace) -> None:
    """Options that would do nothing with the others given: a one-line error naming the option."""
    from pyroute_rel.batch.sweep import SweepError

    if args.batch is not None and args.out is None:
        raise SweepError("--batch sets how often --out is written: it needs --out")
    if args.connect_timeout is not None and args.scheduler is None:
        raise SweepError("--connect-timeout is how long to try reaching --scheduler: it needs --scheduler")
    if args.workers is not None and args.engine == "inline":
        raise SweepError("--workers needs the processes, dask or auto engine (--engine inline routes in this process)")
    if args.workers is not None and args.scheduler is not None:
        raise SweepError("--workers starts a LocalCluster: not with --scheduler (the cluster's workers are used)")


def _cmd_sweep(args: argparse.Namespace) -> int:
    from pyroute_rel.batch.sweep import SweepError, run_sweep, sweep_from_mapping

    _check_combinations(args)
    table, base, source = _spec_table(args)
    try:
        runs = sweep_from_mapping(table, base_dir=base, source=source).runs
    except SweepError as exc:  # a value given on the command line is named as its option
        msg = str(exc)
        for key in ("departures", "members", "apf"):
            if getattr(args, key) is not None:
                msg = msg.replace(f"[sweep].{key}", f"--{key}")
        raise SweepError(msg) from None
    plot = Path(args.plot) if args.plot else (Path(args.out) / "sweep.png" if args.out else None)
    if args.out is not None:
        from pyroute_rel.files import check_out_dir

        check_out_dir(args.out, files=() if args.plot else ("sweep.png",))
    if args.plot and not Path(args.plot).resolve().parent.is_dir():
        raise SweepError(f"--plot {args.plot}: its folder does not exist")
    if args.plot:
        from pyroute_rel.files import check_targets

        check_targets(Path(args.plot).parent, [Path(args.plot).name], option="--plot")
    result = run_sweep(
        runs,
        engine=_engine(args),
        workers=args.workers,
        scheduler=args.scheduler,
        out=args.out,
        retries=args.retries,
        batch=32 if args.batch is None else args.batch,
        connect_timeout_s=10.0 if args.connect_timeout is None else args.connect_timeout,
        progress=not args.quiet,
        log=None if args.quiet else lambda line: print(f"pyroute-rel: {line}", file=sys.stderr),
    )
    rows = result.to_pylist()
    if plot is not None:
        from pyroute_rel.viz.sweep import write_sweep_figure

        write_sweep_figure(rows, plot)
    if args.json:
        print(json.dumps({"runs": rows}))
    else:
        print(_table_text(rows))
        if plot is not None:
            print(f"plot: {plot}")
    return _exit_code(rows)


def _exit_code(rows: list[dict[str, Any]]) -> int:
    """3 when a run hit an internal error; 2 when every run was a user error, or no run has a route (the table is
    printed and written first); else 0 (some runs without a route are results: the table says why for each)."""
    from pyroute_rel.errors import NoFeasibleRouteError, ScenarioError

    if any(str(r["message"]).startswith("internal error") for r in rows):
        first = next(r for r in rows if str(r["message"]).startswith("internal error"))
        print(f"pyroute-rel: {first['message']} (run {first['key']}; see --debug)", file=sys.stderr)
        return 3
    if rows and all(r["status"] == "error" for r in rows):
        raise ScenarioError(f"no run could be routed: {rows[0]['message']}")
    if rows and not any(r["status"] == "ok" for r in rows):
        first = next(r for r in rows if r["status"] == "no_route")
        raise NoFeasibleRouteError(f"no run has a route; the first (run {first['key']}): {first['message']}")
    return 0


def _table_text(rows: list[dict[str, Any]]) -> str:
    """The runs as a table: the settings that vary, then the results."""
    from pyroute_rel.viz.sweep import VARIED

    varied = [c for c in VARIED if len({json.dumps(r.get(c)) for r in rows}) > 1]
    head = f"{'departure':<21}" + "".join(f" {c:<14}" for c in varied)
    head += f" {'status':<9}{'voyage [h]':>11} {'arrival':<21}{'max p_f':>8}{'voy. p_f':>9}"
    lines = [head]
    for r in rows:
        line = f"{r['departure'] or '-':<21}" + "".join(f" {_cell(r.get(c)):<14}" for c in varied)
        if r["status"] == "ok":
            line += (
                f" {'ok':<9}{r['voyage_time_h']:>11.2f} {r['arrival']:<21}{r['max_failure_probability']:>8.3f}"
                f"{r['voyage_failure_probability'] + 0.0:>9.3f}"
            )
        else:
            line += f" {r['status']:<9} {r['message']}"
        lines.append(line)
    n_ok = sum(r["status"] == "ok" for r in rows)
    n_error = sum(r["status"] == "error" for r in rows)
    failed = f", {n_error} failed (status error)" if n_error else ""
    lines.append(f"{len(rows)} runs: {n_ok} routed, {len(rows) - n_ok - n_error} without a route{failed}")
    return "\n".join(lines)


def _cell(v: Any) -> str:
    if isinstance(v, str) and v.startswith("{"):
        return " ".join(f"{k}={x}" for k, x in json.loads(v).items()) or "-"
    return "-" if v is None else str(v)
