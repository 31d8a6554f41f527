"""``pyroute-rel gci``: grid-convergence estimates from given values, or from routed studies, with a CI gate."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pyroute_rel.cli._help import APF_HELP

__all__ = ["add_gci_parser"]

EXIT_OK, EXIT_GATE = 0, 1

#: The files ``gci --out`` writes.
GCI_FILES = ("gci.png", "gci.csv", "gci.json")

#: Arguments that are (lists of) numbers even when they start with '-' ("--h -1,2,4", "--max-gci -1e-3"), so that
#: argparse hands them to the option's type and the validation can say what is wrong, instead of reading them as
#: an unknown option. argparse's own pattern covers only single plain numbers such as "-1" or "-.5".
NEGATIVE_NUMBERS = re.compile(r"^-(\.?\d[\d.,eE+\-]*%?|inf|infinity|nan)$", re.IGNORECASE)

#: Options of ``gci study`` that only apply to one --refinement.
_ANGULAR_ONLY = (
    ("aspect0", "--aspect0"),
    ("half_width_km", "--half-width-km"),
    ("max_deviation_deg", "--max-deviation"),
)
_ANGULAR_DEFAULTS = {"aspect0": 2.0, "half_width_km": 1200.0, "max_deviation_deg": 60.0}


def add_gci_parser(
    sub: Any,
    add_common: Callable[[argparse.ArgumentParser], None],
    csv_ints: Callable[[str], list[int]],
    csv_floats: Callable[[str], list[float]],
) -> None:
    """Add ``gci`` (values given) and ``gci study`` (routed) to the CLI."""
    g = sub.add_parser(
        "gci",
        help="grid convergence index",
        description="Grid convergence (Celik et al. 2008; least squares after Eca & Hoekstra 2014 for 4+ grids). "
        "'pyroute-rel gci --h ... --phi ...' evaluates given values; 'pyroute-rel gci study "
        "SCENARIO.toml' routes a family of grids first.",
    )
    g.add_argument("--h", type=csv_floats, help="grid spacings, comma-separated [any unit, e.g. km]")
    g.add_argument("--phi", type=csv_floats, help="solution values paired with --h [e.g. h]")
    _gate_args(g)
    add_common(g)
    g.set_defaults(func=_cmd_gci)
    g_sub = g.add_subparsers(dest="gci_command", parser_class=type(g))
    s = g_sub.add_parser(
        "study",
        help="route a scenario on several grids and estimate the discretisation error",
        description="Route a scenario on a family of grids and estimate the error of the voyage time. The angular "
        "defaults (--aspect0 2, --half-width-km 1200, --max-deviation 60) differ from the route's (aspect 6, "
        "1000 km, 45 deg) on purpose: they describe a refinement path, not one grid. --aspect0 is the coarsest "
        "grid's aspect and doubles with every doubling of ranks (2, 4, 8 on 41,81,161 ranks: the finest grid is "
        "finer than the route's 6; from 6 it would be 24, with about 4x the arcs). The band is wider so that the "
        "coarse, low-aspect grids can still turn (at aspect 2 a 45 deg band holds only 2 arcs each side, 60 deg "
        "holds 3), and the half-width, fixed along the path, keeps a margin over the route's. Each grid's runtime "
        "(runtime_s) is its routing alone; loading the scenario and weather, done once, is not in it.",
    )
    s.add_argument("scenario", help="scenario TOML file")
    s.add_argument(
        "--refinement",
        choices=("square", "angular"),
        default="square",
        help="square: the paper's n x n all-to-all grids (--n-nodes); angular: rank and lateral "
        "spacing both shrink, lateral faster, banded arcs (--n-ranks)",
    )
    s.add_argument("--n-nodes", type=csv_ints, help="square: nodes per rank of each grid, e.g. 41,57,81,115,161")
    s.add_argument("--n-ranks", type=csv_ints, help="ranks of each grid (square: default = --n-nodes)")
    s.add_argument(
        "--half-width-km",
        type=float,
        help=f"angular: domain half-width [km] (default {_ANGULAR_DEFAULTS['half_width_km']:g}; the route's is 1000, "
        "see above)",
    )
    s.add_argument(
        "--max-deviation",
        type=float,
        dest="max_deviation_deg",
        help="angular: largest arc angle from the rank direction [deg] "
        f"(default {_ANGULAR_DEFAULTS['max_deviation_deg']:g}; the route's is 45, see above)",
    )
    s.add_argument(
        "--aspect0",
        type=float,
        help=f"angular: rank/lateral spacing of the coarsest grid, doubled with every doubling of ranks "
        f"(default {_ANGULAR_DEFAULTS['aspect0']:g}; the route's fixed aspect is 6, see above)",
    )
    s.add_argument("--apf", type=float, help=f"{APF_HELP} (overrides [failure].apf)")
    s.add_argument("--failure-model", help="failure model name or file ('none' for no model)")
    s.add_argument("--no-land", action="store_true", help="do not avoid land (overrides [avoid].land)")
    _gate_args(s)
    add_common(s)
    s.set_defaults(func=_cmd_study)
    # options both parsers know (gate, --json, --out, --quiet, ...) may come before or after 'study': the
    # subparser must not overwrite a value given before 'study' with its default
    shared = {a.dest for a in g._actions}
    for action in s._actions:
        if action.dest in shared:
            action.default = argparse.SUPPRESS
    for parser in (g, s):
        parser._negative_number_matcher = NEGATIVE_NUMBERS


def _parse_max_gci(text: str) -> float:
    """``--max-gci``: a fraction in (0, 1] (``0.015``) or a percent in (0, 100] (``1.5%``) -> the fraction.

    A bare number above 1 is refused rather than read as a percent: ``--max-gci 1.5`` would otherwise pass any
    study with a GCI below 150 %.

    >>> _parse_max_gci("0.015"), _parse_max_gci("1.5%")
    (0.015, 0.015)
    """
    from pyroute_rel.errors import ConvergenceError

    percent = text.strip().endswith("%")
    try:
        value = float(text.strip().removesuffix("%"))
    except ValueError:
        raise ConvergenceError(
            f"--max-gci must be a fraction such as 0.015 or a percent such as 1.5% (got {text!r})"
        ) from None
    if not percent and math.isfinite(value) and value > 1.0:
        raise ConvergenceError(
            f"--max-gci {text} is above 1 (a bare number is a fraction): write {value / 100.0:g} or {value:g}% "
            f"for {value:g} %"
        )
    fraction = value / 100.0 if percent else value
    if not (math.isfinite(fraction) and 0.0 < fraction <= 1.0):
        raise ConvergenceError(
            f"--max-gci must be a fraction in (0, 1] such as 0.015, or a percent in (0, 100] such as 1.5% (got {text})"
        )
    return fraction


def _gate_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--safety-factor", type=float, default=1.25, help="Fs of the three-grid GCI (default 1.25)")
    p.add_argument("--json", action="store_true", help="print one JSON object (with the gate's settings and verdict)")
    p.add_argument(
        "--out",
        help="folder for gci.csv, gci.json (the --json object, gate included) and gci.png",
    )
    p.add_argument(
        "--max-gci",
        type=str,
        help="exit 1 when GCI_fine exceeds this: a fraction in (0, 1] (0.015) or a percent (1.5%%)",
    )
    p.add_argument(
        "--require-asymptotic",
        action="store_true",
        help="exit 1 unless the finest triplet converges monotonically with an asymptotic ratio within "
        "--asymptotic-tol of 1 (a gate on its own, or in addition to --max-gci)",
    )
    p.add_argument(
        "--asymptotic-tol",
        type=float,
        default=0.1,
        help="tolerance on |ratio - 1| of --require-asymptotic (default 0.1)",
    )


def _check_gate_args(args: argparse.Namespace) -> None:
    """Refuse bad gate and output options before any work (one line naming the option)."""
    from pyroute_rel.errors import ConvergenceError
    from pyroute_rel.files import check_out_dir
    from pyroute_rel.gci.numbers import check_safety_factor

    check_safety_factor(args.safety_factor, "gci", "--safety-factor")
    if args.max_gci is not None:
        args.max_gci = _parse_max_gci(str(args.max_gci))
    tol = args.asymptotic_tol
    if not (math.isfinite(tol) and tol >= 0.0):
        raise ConvergenceError(f"--asymptotic-tol must be a finite number >= 0, e.g. 0.1 (got {tol:g})")
    if args.out is not None:
        check_out_dir(args.out, files=GCI_FILES)


def _gate(study: Any, args: argparse.Namespace) -> str | None:
    """Reason the gate fails, or None. A study whose verdict is "indeterminate" (implausible order, round-off
    level differences, divergent, ...) fails any gate: it cannot pass by accident."""
    fin = study.finest
    if args.max_gci is not None or args.require_asymptotic:
        verdict, why = study.verdict()
        if verdict == "indeterminate":
            gates = [f"--max-gci {args.max_gci:g}"] if args.max_gci is not None else []
            gates += ["--require-asymptotic"] if args.require_asymptotic else []
            return f"the gate ({', '.join(gates)}) requires a converging study; it is indeterminate: {why}"
    if args.max_gci is not None:
        if fin.gci_fine is None or not fin.gci_fine <= args.max_gci:
            got = "undefined" if fin.gci_fine is None else f"{fin.gci_fine:.4g} ({100.0 * fin.gci_fine:.4g} %)"
            return (
                f"GCI_fine {got} exceeds --max-gci {args.max_gci:g} ({100.0 * args.max_gci:g} %) "
                f"(convergence: {fin.convergence}{'; ' + fin.note if fin.note else ''})"
            )
    if args.require_asymptotic:
        ar = fin.asymptotic_ratio
        if fin.convergence != "monotonic" or ar is None or abs(ar - 1.0) > args.asymptotic_tol:
            got = "undefined" if ar is None else f"{ar:.4g}"
            return (
                f"not in the asymptotic range: convergence {fin.convergence}, asymptotic ratio {got} "
                f"(needs monotonic and |ratio - 1| <= {args.asymptotic_tol:g})"
            )
    return None


def _write_out(out: str, payload: dict[str, Any], csv_text: str, study: Any, title: str) -> None:
    """Write gci.png, gci.csv and gci.json into ``out``: all three, or none."""
    from pyroute_rel.files import write_together
    from pyroute_rel.viz.convergence import plot_convergence

    write_together(
        out,
        {
            "gci.png": lambda p: plot_convergence(study, path=p, title=title),
            "gci.csv": lambda p: p.write_text(csv_text, encoding="utf-8"),
            "gci.json": lambda p: p.write_text(json.dumps(payload, indent=1), encoding="utf-8"),
        },
        option="--out",
    )


def _add_gate(payload: dict[str, Any], study: Any, args: argparse.Namespace) -> str | None:
    """Put the gate's settings and verdict into ``payload["gate"]``; the reason it fails, or None."""
    reason = _gate(study, args)
    payload["gate"] = {
        "max_gci": args.max_gci,
        "require_asymptotic": args.require_asymptotic,
        "asymptotic_tol": args.asymptotic_tol,
        "passed": reason is None,
        "reason": reason,
    }
    return reason


def _finish(payload: dict[str, Any], text: str, reason: str | None, args: argparse.Namespace) -> int:
    """Print the result and return the exit code: the gate's verdict survives a closed stdout (``| head``)."""
    try:
        print(json.dumps(payload) if args.json else text)
        sys.stdout.flush()
    except BrokenPipeError:  # the reader went away: stdout to /dev/null so that the exit's flush stays quiet
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    if reason is not None:
        print(f"pyroute-rel: gate failed: {reason}", file=sys.stderr)
        return EXIT_GATE
    return EXIT_OK


def _cmd_gci(args: argparse.Namespace) -> int:
    from pyroute_rel.errors import ConvergenceError
    from pyroute_rel.gci.numbers import convergence_study

    if args.h is None or args.phi is None:
        raise ConvergenceError("give --h and --phi (three or more values each), or use 'pyroute-rel gci study'")
    _check_gate_args(args)
    study = convergence_study(
        args.h, args.phi, safety_factor=args.safety_factor, names=("--h", "--phi", "--safety-factor")
    )
    payload = study.to_dict()
    fin = study.finest
    payload.update(
        {
            k: payload["finest"][k]
            for k in ("p", "phi_ext", "gci_fine", "gci_coarse", "e_a", "asymptotic_ratio", "convergence", "method")
        }
    )
    csv_text = "h,phi\n" + "".join(f"{h:.10g},{p:.10g}\n" for h, p in zip(study.h, study.phi, strict=True))
    reason = _add_gate(payload, study, args)
    if args.out is not None:
        _write_out(args.out, payload, csv_text, study, f"{len(study.h)} grids: {fin.convergence}")
    return _finish(payload, study.report(), reason, args)


def _check_study_args(args: argparse.Namespace) -> None:
    """Refuse options of ``gci study`` that are missing, out of range or do not apply to the --refinement."""
    from pyroute_rel.errors import ConvergenceError

    if args.h is not None or args.phi is not None:
        raise ConvergenceError(
            "--h and --phi give values to 'pyroute-rel gci'; 'gci study' routes its own grids "
            "(drop --h/--phi or the word 'study')"
        )
    if args.refinement == "square":
        if not args.n_nodes:
            raise ConvergenceError("gci study --refinement square needs --n-nodes, e.g. 41,57,81,115,161")
        given = [opt for dest, opt in _ANGULAR_ONLY if getattr(args, dest) is not None]
        if given:
            raise ConvergenceError(
                f"{', '.join(given)} only apply to --refinement angular (the square grids are "
                "n x n, all-to-all): drop them or add --refinement angular"
            )
    else:
        if args.n_nodes is not None:
            raise ConvergenceError(
                "--n-nodes only applies to --refinement square (the angular grids derive their "
                "nodes from --half-width-km and --aspect0): drop it or use --n-ranks"
            )
        if not args.n_ranks:
            raise ConvergenceError("gci study --refinement angular needs --n-ranks, e.g. 21,41,81")
        for dest, _ in _ANGULAR_ONLY:
            if getattr(args, dest) is None:
                setattr(args, dest, _ANGULAR_DEFAULTS[dest])
    _check_gate_args(args)


def _cmd_study(args: argparse.Namespace) -> int:
    from pyroute_rel.gci.study import angular_levels, check_study_scenario, run_study, square_levels
    from pyroute_rel.geodesy import distance_km
    from pyroute_rel.scenario import load_scenario

    _check_study_args(args)
    if args.refinement == "square":
        square_levels(args.n_nodes, args.n_ranks)  # refuse bad counts before loading anything
    scenario = load_scenario(args.scenario).with_options(
        apf=args.apf, failure_model=args.failure_model, land=False if args.no_land else None
    )
    check_study_scenario(scenario)
    if scenario.refine and not args.quiet:
        print(
            f"pyroute-rel: note: [grid].refine = {scenario.refine} is not applied: a study measures its grids' own "
            "voyage times",
            file=sys.stderr,
        )
    if args.refinement == "square":
        levels = square_levels(args.n_nodes, args.n_ranks)
    else:
        length = float(distance_km(*scenario.start, *scenario.finish))
        levels = angular_levels(
            length,
            args.n_ranks,
            aspect0=args.aspect0,
            half_width_km=args.half_width_km,
            max_deviation_deg=args.max_deviation_deg,
        )

    def report(i: int, n: int, row: dict[str, Any]) -> None:
        if not args.quiet and sys.stderr.isatty():
            print(
                f"  grid {i + 1}/{n}: {row['n_ranks']}x{row['n_nodes']} -> {row['voyage_time_h']:.3f} h "
                f"({row['runtime_s']:.1f} s)",
                file=sys.stderr,
            )

    result = run_study(scenario, levels, refinement=args.refinement, safety_factor=args.safety_factor, progress=report)
    payload = result.to_dict()
    lines = [
        f"refinement path: {args.refinement}",
        f"{'ranks':>6} {'nodes':>6} {'h [km]':>10} {'lateral [km]':>12} {'arcs':>11} {'voyage [h]':>12} "
        f"{'runtime [s]':>11}",
    ]
    for r in result.rows:
        lines.append(
            f"{r['n_ranks']:>6} {r['n_nodes']:>6} {r['h_km']:>10.3f} {r['spacing_km']:>12.3f} "
            f"{r['arcs']:>11} {r['voyage_time_h']:>12.4f} {r['runtime_s']:>11.2f}"
        )
    text = "\n".join(lines) + "\n\n" + result.study.report()
    reason = _add_gate(payload, result.study, args)
    if args.out is not None:
        _write_out(
            args.out, payload, result.csv(), result.study, f"{Path(args.scenario).name}: {args.refinement} refinement"
        )
    return _finish(payload, text, reason, args)
