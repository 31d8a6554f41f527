"""``pyroute-rel evaluate``: sail a given track (GPX, GeoJSON, CSV) in a scenario's weather."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from pyroute_rel.cli._help import APF_HELP

__all__ = ["add_evaluate_parser", "EVALUATE_FILES"]

EXIT_OK = 0

#: The files ``evaluate --out`` writes (``monte_carlo.png`` with ``--monte-carlo``).
EVALUATE_FILES = ("evaluation.json", "evaluation.csv", "monte_carlo.png")


def add_evaluate_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``evaluate`` to the CLI."""
    e = sub.add_parser(
        "evaluate",
        help="sail a given track in a scenario's weather",
        description="Sail a track (GPX track or route, GeoJSON LineString, CSV of lon,lat[,time]) in a scenario's "
        "weather with its polar, failure model, land and zones, leg by leg as the router costs arcs: per-leg "
        "conditions, times, p_f and the voyage figures. A leg the router would forbid is sailed and reported "
        "(reason); a track that is not a feasible route (a leg blocked, or an end away from the finish) exits 2 after "
        "its figures, with one line saying why.",
    )
    e.add_argument("scenario", help="scenario TOML file")
    e.add_argument("track", help="track file: .gpx, .geojson/.json or .csv")
    e.add_argument("--departure", help="departure time, ISO 8601 UTC (default: the track's first time, else the "
                   "scenario's)")  # fmt: skip
    e.add_argument(
        "--member",
        type=_member,
        help="sail in this ensemble member's weather ([weather] member = k), or 'mean' for the ensemble mean",
    )
    e.add_argument("--apf", type=float, help=f"{APF_HELP} (overrides [failure].apf)")
    e.add_argument(
        "--monte-carlo",
        type=int,
        metavar="N",
        help="also sail the track N times with wind errors (AR(1) in time, growing with lead time, or the ensemble's "
        "spread with --member) and boat-speed noise: the arrival distribution and the probability of meeting "
        "p_f > apf with its 95%% interval",
    )
    e.add_argument("--seed", type=int, help="random seed of --monte-carlo (default 0)")
    e.add_argument("--kappa", type=float, help="boat-speed variance per unit speed [kn] (default 0.2, Barde 2023)")
    e.add_argument(
        "--speed-tau", type=float, help="correlation time of the boat-speed noise [h] (default 12, an assumption)"
    )
    e.add_argument("--polar-sd", type=float, help="standard deviation of a per-run polar scale factor (default 0)")
    e.add_argument("--wind-sd", type=float, help="wind error per component at departure [m/s] (default 1.0)")
    e.add_argument("--wind-growth", type=float, help="its growth with lead time [m/s per h] (default 0.015)")
    e.add_argument("--json", action="store_true", help="print the evaluation as one JSON object")
    e.add_argument("--out", help=f"folder for {', '.join(EVALUATE_FILES)}")
    add_common(e)
    e.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from pyroute_rel.analysis.evaluate import evaluate_track, read_track
    from pyroute_rel.scenario import load_scenario

    _check_monte_carlo_options(args)
    if args.out is not None:
        from pyroute_rel.files import check_out_dir

        check_out_dir(args.out, files=EVALUATE_FILES)
    if args.member is None:
        scenario = load_scenario(args.scenario)
    else:
        from pyroute_rel.analysis.members import member_scenario

        scenario = member_scenario(args.scenario, args.member)
    track = read_track(args.track)
    scenario = scenario.with_options(apf=args.apf)
    ev = evaluate_track(scenario, track, departure=args.departure)
    summary = ev.summary()
    summary["track_file"] = str(args.track)
    mc = None
    if args.monte_carlo is not None:
        mc = _monte_carlo(args, scenario, track)
        summary["monte_carlo"] = mc.summary()
    if args.out is not None:
        _write(ev, summary, args.out, mc)
    if args.json:
        print(json.dumps(summary))
    else:
        print(_text(ev, summary))
    why = ev.why()
    if why is not None:  # the figures are printed and written; the exit code says the track is not a route
        from pyroute_rel.errors import NoFeasibleRouteError

        raise NoFeasibleRouteError(f"the track is not a feasible route: {why}")
    return EXIT_OK


#: The Monte-Carlo options and the :class:`~pyroute_rel.analysis.monte_carlo.MonteCarloSettings` field each sets.
MONTE_CARLO_OPTIONS = {
    "kappa": ("--kappa", "kappa"),
    "speed_tau": ("--speed-tau", "tau_speed_h"),
    "polar_sd": ("--polar-sd", "polar_sd"),
    "wind_sd": ("--wind-sd", "sigma0_ms"),
    "wind_growth": ("--wind-growth", "growth_ms_per_h"),
}


def _check_monte_carlo_options(args: argparse.Namespace) -> None:
    """Refuse, before any work, a Monte-Carlo option without ``--monte-carlo N`` (it would be silently ignored)
    and a bad value, naming the option."""
    from pyroute_rel.analysis.monte_carlo import MonteCarloSettings
    from pyroute_rel.errors import ScenarioError

    given = {k: v for k, v in MONTE_CARLO_OPTIONS.items() if getattr(args, k) is not None}
    if args.monte_carlo is not None and args.monte_carlo < 1:
        raise ScenarioError(f"--monte-carlo needs a whole number of runs >= 1 (got {args.monte_carlo})")
    if (given or args.seed is not None) and args.monte_carlo is None:
        names = ", ".join([option for option, _ in given.values()] + ["--seed"] * (args.seed is not None))
        raise ScenarioError(f"{names} set the Monte-Carlo runs: add --monte-carlo N (or leave them out)")
    if args.seed is not None and args.seed < 0:
        raise ScenarioError(f"--seed must be a whole number >= 0 (got {args.seed})")
    for key, (option, field) in given.items():
        try:
            MonteCarloSettings(**{field: getattr(args, key)})
        except ScenarioError as exc:
            raise ScenarioError(f"{option}: {exc}") from None


def _member(text: str) -> int | str:
    if text.strip().lower() == "mean":
        return "mean"
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a member number or 'mean' (got {text!r})") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a member number >= 0 (got {value})")
    return value


def _monte_carlo(args: argparse.Namespace, scenario: Any, track: Any) -> Any:
    from pyroute_rel.analysis.monte_carlo import MonteCarloSettings, monte_carlo, spread_from_members

    given = {
        "kappa": args.kappa,
        "tau_speed_h": args.speed_tau,
        "polar_sd": args.polar_sd,
        "sigma0_ms": args.wind_sd,
        "growth_ms_per_h": args.wind_growth,
    }
    settings = MonteCarloSettings(**{k: v for k, v in given.items() if v is not None})
    if args.member is not None and args.wind_sd is None and args.wind_growth is None:
        spread = spread_from_members(args.scenario, track, departure=args.departure)
        settings = replace(settings, spread_ms=spread)
    seed = 0 if args.seed is None else args.seed
    return monte_carlo(scenario, track, runs=args.monte_carlo, seed=seed, settings=settings,
                       departure=args.departure)  # fmt: skip


def _write(ev: Any, summary: dict[str, Any], out: str, mc: Any = None) -> None:
    from pyroute_rel.files import write_together

    writers: dict[str, Callable[[Any], object]] = {
        "evaluation.json": lambda p: p.write_text(json.dumps(summary, indent=1), encoding="utf-8"),
        "evaluation.csv": lambda p: p.write_text(_csv(ev), encoding="utf-8"),
    }
    if mc is not None:
        from pyroute_rel.viz.ensemble import monte_carlo_histogram

        writers["monte_carlo.png"] = lambda p: monte_carlo_histogram(mc, path=p)
    write_together(out, writers)
    stale = Path(out) / "monte_carlo.png"
    if mc is None:
        stale.unlink(missing_ok=True)  # from an earlier run with --monte-carlo


def _csv(ev: Any) -> str:
    """One row per track point; leg columns describe the leg that starts at the point (as ``route.csv``)."""
    from pyroute_rel.outputs import MANOEUVRE_FIELDS, manoeuvre_cells
    from pyroute_rel.routing.route import LEG_FIELDS
    from pyroute_rel.times import iso_utc

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    leg_columns = [f"leg_{k}" for k in (*LEG_FIELDS, *MANOEUVRE_FIELDS)]
    w.writerow(["index", "lon_deg", "lat_deg", "time_utc", "elapsed_h", *leg_columns, "blocked"])
    n = ev.track.shape[0]
    for i in range(n):
        last = i == n - 1
        legs = ["" if last or not math.isfinite(ev.legs[k][i]) else f"{ev.legs[k][i]:.6g}" for k in LEG_FIELDS]
        sailed = not last and math.isfinite(ev.elapsed_h[i + 1])
        legs += manoeuvre_cells(ev.manoeuvres if sailed else None, i)
        t = ev.time[i]
        w.writerow(
            [
                i,
                f"{ev.track[i, 0]:.6f}",
                f"{ev.track[i, 1]:.6f}",
                "" if str(t) == "NaT" else iso_utc(t),
                f"{ev.elapsed_h[i]:.6f}" if math.isfinite(ev.elapsed_h[i]) else "",
                *legs,
                "" if last else "+".join(ev.leg_reasons[i]),
            ]
        )
    return buf.getvalue()


def _text(ev: Any, s: dict[str, Any]) -> str:
    if math.isfinite(ev.voyage_time_h):
        days, hours = divmod(round(ev.voyage_time_h, 1), 24.0)
        voyage = f"{ev.voyage_time_h:.2f} h ({int(days)} d {hours:.1f} h)"
    else:
        voyage = f"cannot be sailed beyond leg {ev.blocked_leg} ({ev.reason})"
    blocked = sum(1 for r in ev.leg_reasons if r)
    if not ev.feasible:  # the error line after the figures says why in full
        verdict = f"not feasible: leg {ev.blocked_leg} blocked by {ev.reason}" + (
            f" ({blocked} legs blocked)" if blocked > 1 else ""
        )
    elif not ev.arrived:
        verdict = f"does not arrive: ends {ev.distance_to_finish_nm:.1f} nm from the finish"
    else:
        verdict = "feasible"
    return "\n".join(
        [
            f"track            {s['track_file']} ({ev.track.shape[0]} points, {ev.legs.n_legs} legs)",
            f"voyage time      {voyage}",
            f"distance         {ev.distance_nm:.1f} nm",
            f"departure        {s['departure']}",
            f"arrival          {s['arrival'] or 'none'}",
            f"failure model    {s.get('failure_model') or 'none'} (apf {s.get('apf', 1.0):g}): max leg p_f "
            f"{ev.max_failure_probability:.3f}, voyage p_f {ev.voyage_failure_probability:.3f}",
            f"verdict          {verdict}",
            *_mc_lines(s.get("monte_carlo")),
        ]
    )


def _mc_lines(mc: dict[str, Any] | None) -> list[str]:
    if not mc:
        return []
    a = mc["arrival_h"]

    def h(x: float | None) -> str:
        return "-" if x is None else f"{x:.1f}"

    lo, hi = mc["p_fail_conditions_ci95"]
    d = mc["arrived_h"]
    lost = mc["runs"] - d["runs"]
    return [
        f"monte carlo      {mc['runs']} runs (seed {mc['seed']}): {d['runs']} arrive ({mc['completed']:.0%}); their "
        f"voyage time mean {h(d['mean'])} h, SD {h(d['sd'])}, P5 {h(d['p5'])}, P50 {h(d['p50'])}, P95 {h(d['p95'])}, "
        f"worst {h(d['worst'])} (deterministic {h(mc['deterministic_h'])} h)"
        + (
            f"; {lost} never arrive{'s' if lost == 1 else ''} (a leg {'it' if lost == 1 else 'they'} cannot sail: "
            f"below 0.01 kn, or no weather; over all runs P50 {h(a['p50'])}, P95 {h(a['p95'])})"
            if lost
            else ""
        ),
        f"                 P(p_f > apf {mc['apf']:g}) = {mc['p_fail_conditions']:.3f} (95% interval {lo:.3f} to "
        f"{hi:.3f})",
    ]
