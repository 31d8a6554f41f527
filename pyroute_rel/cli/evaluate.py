"""``pyroute-rel evaluate``: sail a given track (GPX, GeoJSON, CSV) in a scenario's weather."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from collections.abc import Callable
from typing import Any

__all__ = ["add_evaluate_parser", "EVALUATE_FILES"]

EXIT_OK = 0

#: The files ``evaluate --out`` writes.
EVALUATE_FILES = ("evaluation.json", "evaluation.csv")


def add_evaluate_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``evaluate`` to the CLI."""
    e = sub.add_parser(
        "evaluate",
        help="sail a given track in a scenario's weather",
        description="Sail a track (GPX track or route, GeoJSON LineString, CSV of lon,lat[,time]) in a scenario's "
        "weather with its polar, failure model, land and zones, leg by leg as the router costs arcs: per-leg "
        "conditions, times, p_f and the voyage figures. A leg the router would forbid is reported (reason), not "
        "refused.",
    )
    e.add_argument("scenario", help="scenario TOML file")
    e.add_argument("track", help="track file: .gpx, .geojson/.json or .csv")
    e.add_argument("--departure", help="departure time, ISO 8601 UTC (default: the track's first time, else the "
                   "scenario's)")  # fmt: skip
    e.add_argument("--member", type=int, help="sail in this ensemble member's weather ([weather] member = k)")
    e.add_argument("--apf", type=float, help="acceptable probability of failure the legs are held to")
    e.add_argument("--json", action="store_true", help="print the evaluation as one JSON object")
    e.add_argument("--out", help=f"folder for {', '.join(EVALUATE_FILES)}")
    add_common(e)
    e.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from ..evaluate import evaluate_track, read_track
    from ..scenario import load_scenario

    if args.out is not None:
        from ..files import check_out_dir, check_targets

        out = check_out_dir(args.out)
        if out.is_dir():
            check_targets(out, EVALUATE_FILES)
    if args.member is None:
        scenario = load_scenario(args.scenario)
    else:
        from ..members import member_scenario

        scenario = member_scenario(args.scenario, args.member)
    track = read_track(args.track)
    ev = evaluate_track(scenario.with_options(apf=args.apf), track, departure=args.departure)
    summary = ev.summary()
    summary["track_file"] = str(args.track)
    if args.out is not None:
        _write(ev, summary, args.out)
    if args.json:
        print(json.dumps(summary))
    else:
        print(_text(ev, summary))
    return EXIT_OK


def _write(ev: Any, summary: dict[str, Any], out: str) -> None:
    from ..files import write_together

    write_together(
        out,
        {
            "evaluation.json": lambda p: p.write_text(json.dumps(summary, indent=1), encoding="utf-8"),
            "evaluation.csv": lambda p: p.write_text(_csv(ev), encoding="utf-8"),
        },
    )


def _csv(ev: Any) -> str:
    """One row per track point; leg columns describe the leg that starts at the point (as ``route.csv``)."""
    from ..route import LEG_FIELDS
    from ..times import iso_utc

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["index", "lon_deg", "lat_deg", "time_utc", "elapsed_h", *(f"leg_{k}" for k in LEG_FIELDS), "blocked"])
    n = ev.track.shape[0]
    for i in range(n):
        last = i == n - 1
        legs = ["" if last or not math.isfinite(ev.legs[k][i]) else f"{ev.legs[k][i]:.6g}" for k in LEG_FIELDS]
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
    verdict = "feasible" if ev.feasible else f"not feasible: leg {ev.blocked_leg} blocked by {ev.reason}"
    blocked = sum(1 for r in ev.leg_reasons if r)
    return "\n".join(
        [
            f"track            {s['track_file']} ({ev.track.shape[0]} points, {ev.legs.n_legs} legs)",
            f"voyage time      {voyage}",
            f"distance         {ev.distance_nm:.1f} nm",
            f"departure        {s['departure']}",
            f"arrival          {s['arrival'] or '-'}",
            f"failure model    {s.get('failure_model') or 'none'} (apf {s.get('apf', 1.0):g}): max leg p_f "
            f"{ev.max_failure_probability:.3f}, voyage p_f {ev.voyage_failure_probability:.3f}",
            f"verdict          {verdict}" + (f" ({blocked} legs blocked)" if blocked > 1 else ""),
        ]
    )
