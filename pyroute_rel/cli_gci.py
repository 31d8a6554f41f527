"""``pyroute-rel gci``: grid-convergence estimates from given values, or from routed studies, with a CI gate."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["add_gci_parser"]

EXIT_OK, EXIT_GATE = 0, 1


def add_gci_parser(sub: Any, add_common: Callable[[argparse.ArgumentParser], None],
                   csv_ints: Callable[[str], list[int]], csv_floats: Callable[[str], list[float]]) -> None:
    """Add ``gci`` (values given) and ``gci study`` (routed) to the CLI."""
    g = sub.add_parser(
        "gci", help="grid convergence index",
        description="Grid convergence (Celik et al. 2008; least squares after Eca & Hoekstra 2014 for 4+ grids). "
                    "'pyroute-rel gci --h ... --phi ...' evaluates given values; 'pyroute-rel gci study "
                    "SCENARIO.toml' routes a family of grids first.")
    g.add_argument("--h", type=csv_floats, help="grid spacings, comma-separated [any unit, e.g. km]")
    g.add_argument("--phi", type=csv_floats, help="solution values paired with --h [e.g. h]")
    _gate_args(g)
    add_common(g)
    g.set_defaults(func=_cmd_gci)
    g_sub = g.add_subparsers(dest="gci_command", parser_class=type(g))
    s = g_sub.add_parser("study", help="route a scenario on several grids and estimate the discretisation error",
                         description="Route a scenario on a family of grids and estimate the error of the voyage "
                                     "time.")
    s.add_argument("scenario", help="scenario TOML file")
    s.add_argument("--refinement", choices=("square", "angular"), default="square",
                   help="square: the paper's n x n all-to-all grids (--n-nodes); angular: rank and lateral "
                        "spacing both shrink, lateral faster, banded arcs (--n-ranks)")
    s.add_argument("--n-nodes", type=csv_ints, help="square: nodes per rank of each grid, e.g. 41,57,81,115,161")
    s.add_argument("--n-ranks", type=csv_ints, help="ranks of each grid (square: default = --n-nodes)")
    s.add_argument("--half-width-km", type=float, default=1200.0, help="angular: domain half-width [km]")
    s.add_argument("--max-deviation", type=float, default=60.0, dest="max_deviation_deg",
                   help="angular: largest arc angle from the rank direction [deg]")
    s.add_argument("--aspect0", type=float, default=2.0, help="angular: rank/lateral spacing of the coarsest grid")
    s.add_argument("--apf", type=float, help="acceptable probability of failure")
    s.add_argument("--failure-model", help="failure model name or file ('none' for no model)")
    s.add_argument("--no-land", action="store_true", help="do not avoid land (overrides [avoid].land)")
    _gate_args(s)
    add_common(s)
    s.set_defaults(func=_cmd_study)


def _gate_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--safety-factor", type=float, default=1.25, help="Fs of the three-grid GCI (default 1.25)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", help="folder for gci.csv, gci.json and gci.png")
    p.add_argument("--max-gci", type=float, help="exit 1 when GCI_fine (a fraction, e.g. 0.01) exceeds this")
    p.add_argument("--require-asymptotic", action="store_true",
                   help="with --max-gci: also exit 1 unless the finest triplet converges monotonically with an "
                        "asymptotic ratio within --asymptotic-tol of 1")
    p.add_argument("--asymptotic-tol", type=float, default=0.1, help="tolerance on |ratio - 1| (default 0.1)")


def _gate(fin: Any, args: argparse.Namespace) -> str | None:
    """Reason the gate fails, or None."""
    if args.max_gci is not None:
        if fin.gci_fine is None or not fin.gci_fine <= args.max_gci:
            got = "undefined" if fin.gci_fine is None else f"{fin.gci_fine:.4g}"
            return (f"GCI_fine {got} exceeds --max-gci {args.max_gci:g} "
                    f"(convergence: {fin.convergence}{'; ' + fin.note if fin.note else ''})")
    if args.require_asymptotic:
        ar = fin.asymptotic_ratio
        if fin.convergence != "monotonic" or ar is None or abs(ar - 1.0) > args.asymptotic_tol:
            got = "undefined" if ar is None else f"{ar:.4g}"
            return (f"not in the asymptotic range: convergence {fin.convergence}, asymptotic ratio {got} "
                    f"(needs monotonic and |ratio - 1| <= {args.asymptotic_tol:g})")
    return None


def _write_out(out: str, payload: dict[str, Any], csv_text: str, study: Any, title: str) -> None:
    from .gci_plot import plot_convergence
    from .route import atomic_write

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    plot_convergence(study, path=folder / "gci.png", title=title)
    atomic_write(folder / "gci.csv", lambda p: p.write_text(csv_text, encoding="utf-8"))
    atomic_write(folder / "gci.json", lambda p: p.write_text(json.dumps(payload, indent=1), encoding="utf-8"))


def _finish(payload: dict[str, Any], text: str, fin: Any, args: argparse.Namespace) -> int:
    reason = _gate(fin, args)
    payload["gate"] = {"max_gci": args.max_gci, "require_asymptotic": args.require_asymptotic,
                       "passed": reason is None, "reason": reason}
    print(json.dumps(payload) if args.json else text)
    if reason is not None:
        print(f"pyroute-rel: gate failed: {reason}", file=sys.stderr)
        return EXIT_GATE
    return EXIT_OK


def _cmd_gci(args: argparse.Namespace) -> int:
    from .errors import ConvergenceError
    from .gci import convergence_study

    if args.h is None or args.phi is None:
        raise ConvergenceError("give --h and --phi (three or more values each), or use 'pyroute-rel gci study'")
    study = convergence_study(args.h, args.phi, safety_factor=args.safety_factor)
    payload = study.to_dict()
    fin = study.finest
    payload.update({k: payload["finest"][k] for k in ("p", "phi_ext", "gci_fine", "gci_coarse", "e_a",
                                                       "asymptotic_ratio", "convergence", "method")})
    csv_text = "h,phi\n" + "".join(f"{h:.10g},{p:.10g}\n" for h, p in zip(study.h, study.phi, strict=True))
    if args.out:
        _write_out(args.out, payload, csv_text, study, f"{len(study.h)} grids: {fin.convergence}")
    return _finish(payload, study.report(), fin, args)


def _cmd_study(args: argparse.Namespace) -> int:
    from .errors import ConvergenceError
    from .geodesy import distance_km
    from .scenario import load_scenario
    from .study import angular_levels, run_study, square_levels

    scenario = load_scenario(args.scenario).with_options(apf=args.apf, failure_model=args.failure_model,
                                                         land=False if args.no_land else None)
    if args.refinement == "square":
        if not args.n_nodes:
            raise ConvergenceError("gci study --refinement square needs --n-nodes, e.g. 41,57,81,115,161")
        levels = square_levels(args.n_nodes, args.n_ranks)
    else:
        if not args.n_ranks:
            raise ConvergenceError("gci study --refinement angular needs --n-ranks, e.g. 21,41,81")
        length = float(distance_km(*scenario.start, *scenario.finish))
        levels = angular_levels(length, args.n_ranks, aspect0=args.aspect0, half_width_km=args.half_width_km,
                                max_deviation_deg=args.max_deviation_deg)

    def report(i: int, n: int, row: dict[str, Any]) -> None:
        if not args.quiet and sys.stderr.isatty():
            print(f"  grid {i + 1}/{n}: {row['n_ranks']}x{row['n_nodes']} -> {row['voyage_time_h']:.3f} h "
                  f"({row['runtime_s']:.1f} s)", file=sys.stderr)

    result = run_study(scenario, levels, refinement=args.refinement, safety_factor=args.safety_factor,
                       progress=report)
    payload = result.to_dict()
    lines = [f"refinement path: {args.refinement}",
             f"{'ranks':>6} {'nodes':>6} {'h [km]':>10} {'lateral [km]':>12} {'arcs':>11} {'voyage [h]':>12} "
             f"{'runtime [s]':>11}"]
    for r in result.rows:
        lines.append(f"{r['n_ranks']:>6} {r['n_nodes']:>6} {r['h_km']:>10.3f} {r['spacing_km']:>12.3f} "
                     f"{r['arcs']:>11} {r['voyage_time_h']:>12.4f} {r['runtime_s']:>11.2f}")
    text = "\n".join(lines) + "\n\n" + result.study.report()
    if args.out:
        _write_out(args.out, payload, result.csv(), result.study,
                   f"{Path(args.scenario).name}: {args.refinement} refinement")
    return _finish(payload, text, result.study.finest, args)
