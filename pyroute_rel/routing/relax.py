"""When no route exists: what would make one, found by routing again (issue 35).

A route that cannot be found is the most common complaint about weather routers; "the front died at rank 57" says
where, not what to change. :func:`relax` answers with what routes:

- **the smallest apf that routes**, exact: a route exists at a threshold when every arc of some path has ``p_f`` at
  most it, and an arc's ``p_f`` is a value of the failure model's table, so only the table's values above the
  current apf can be the answer. The course is routed at the largest (1: nothing is forbidden by the model) and, when
  that routes, at the values below it, smallest first (a binary search over them when there are more than
  :data:`LINEAR_LEVELS`; it needs feasibility to grow with apf, which holds in steady weather, where the allowed arcs
  of a larger apf include those of a smaller one). The route at that apf is the first point of the bottleneck front
  (:mod:`pyroute_rel.routing.tradeoff`) beyond the current apf. None when the failure model forbids nothing where the
  front dies, or when even apf 1 does not route (land, the polar or the weather's extent blocks it);
- **the earliest departure that routes**, within a window the caller gives (``route --departure-window``): the course
  routed leaving at each time of the window in turn, the first that routes;
- **the best partial route**: of the nodes the DP reached, the one closest to the finish (its finish line when it
  has one) and the DP's path to it: how close the craft can get, and where it stops;
- **a wider grid**, when the front died on the failure model or an obstacle and the DP reached the grid's outermost
  nodes: the course routed at its own apf on a grid twice as wide (:func:`~pyroute_rel.routing.grid.widened`: the
  angular layout's half-width doubled, the square layout's nodes; :meth:`Scenario.route
  <pyroute_rel.scenario.Scenario.route>` tries it, a single route only);
- for a course through waypoints, **which leg** fails (the legs before it route).

The cause itself, with the conditions met where the front dies (the criteria fired, the polar's empty columns and the
wind met there, the weather's extent), is :func:`~pyroute_rel.routing.solve.explain_cause`'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import NoFeasibleRouteError, WeatherCoverageError
from pyroute_rel.routing.grid import Grid
from pyroute_rel.routing.route import Route, join_routes, route_on_grid
from pyroute_rel.routing.solve import DPResult, RoutingProblem
from pyroute_rel.times import iso_utc

__all__ = [
    "LINEAR_LEVELS",
    "PartialRoute",
    "Relaxation",
    "departure_window",
    "window_size",
    "earliest_departure",
    "partial_route",
    "relax",
    "route_course",
    "smallest_apf",
]

FloatArray = npt.NDArray[np.float64]

#: Up to this many apf levels above the current one are tried in turn, smallest first (exact whatever the weather);
#: beyond it, by a binary search (exact when feasibility grows with apf: steady weather).
LINEAR_LEVELS = 8


@dataclass(frozen=True)
class PartialRoute:
    """The DP's path to the reached node closest to the leg's finish.

    Attributes
    ----------
    lon_deg, lat_deg : From the leg's start to that node [deg].
    elapsed_h : The DP's arrival at each point [h after the leg's departure].
    distance_to_finish_nm : How far that node is from the leg's finish (its finish line when it has one) [nm].
    rank : The rank of that node (0-based) of the leg's grid of ``n_ranks``.
    n_ranks : The leg grid's ranks.
    departure : When the leg departs (UTC).
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    distance_to_finish_nm: float
    rank: int
    n_ranks: int
    departure: np.datetime64

    def summary(self) -> dict[str, Any]:
        """JSON values: the closest approach, where it stops and the points."""
        return {
            "distance_to_finish_nm": self.distance_to_finish_nm,
            "stops_at": {"lon": float(self.lon_deg[-1]), "lat": float(self.lat_deg[-1])},
            "rank": self.rank,
            "n_ranks": self.n_ranks,
            "elapsed_h": float(self.elapsed_h[-1]),
            "departure": iso_utc(self.departure),
            "track": [[float(a), float(b)] for a, b in zip(self.lon_deg, self.lat_deg, strict=True)],
        }


@dataclass(frozen=True)
class Relaxation:
    """What would make a course route (:func:`relax`; the module notes say how each is found).

    Attributes
    ----------
    cause : Why it does not route: where the front died and what forbade the arcs there, with the conditions met.
    hint : What the DP's explanation suggests after it (" (raise --apf, or widen the grid ...)"; "" for none): said
        only when neither a larger apf nor a wider grid was tried (a weather-extent hint always).
    leg, n_legs : The leg that fails (0-based) and the course's legs (one without waypoints).
    apf : The smallest apf that routes, or None (no apf routes it, or the failure model is not what blocks it).
    apf_voyage_time_h : The voyage time at that apf [h].
    departure : The earliest departure of the window searched that routes, or None (none, or no window).
    departure_voyage_time_h : The voyage time leaving then [h].
    window : The departures searched (first, last, count), or None.
    wider : The option that widens the grid so that the course routes at its apf (e.g. ``"--half-width-km 200"``),
        or None (not tried, or the wider grid does not route either); ``wider_voyage_time_h`` its voyage [h].
    partial : The best partial route of the failing leg (None when the DP reached no node).
    apf_tried, wider_tried : Whether a larger apf (up to 1) and a wider grid were tried (None above: neither routes).
    window_beyond : Of the departures tried, how many the weather does not cover.
    """

    cause: str
    leg: int
    n_legs: int
    hint: str = ""
    apf: float | None = None
    apf_voyage_time_h: float | None = None
    departure: np.datetime64 | None = None
    departure_voyage_time_h: float | None = None
    window: tuple[str, str, int] | None = None
    partial: PartialRoute | None = None
    wider: str | None = None
    wider_voyage_time_h: float | None = None
    apf_tried: bool = False
    wider_tried: bool = False
    window_beyond: int = 0

    def fixes(self) -> list[str]:
        """What routes the course, each with its voyage time (the options of ``pyroute-rel route``)."""
        parts = []
        if self.wider is not None:
            parts.append(f"it routes on a wider grid, {self.wider} ({self.wider_voyage_time_h:.2f} h)")
        if self.apf is not None:
            parts.append(f"it routes with --apf {apf_text(self.apf)} ({self.apf_voyage_time_h:.2f} h)")
        if self.departure is not None:
            when = iso_utc(self.departure)
            parts.append(f"it routes leaving at {when} (--departure {when}; {self.departure_voyage_time_h:.2f} h)")
        return parts

    def facts(self) -> list[str]:
        """What was tried and does not route, and the best partial route."""
        parts = []
        if self.apf_tried and self.apf is None:
            parts.append("not even apf 1 routes it")
        if self.wider_tried and self.wider is None:
            parts.append("a grid twice as wide does not route it either")
        if self.departure is None and self.window is not None:
            beyond = f", {self.window_beyond} of them beyond the weather's times" if self.window_beyond else ""
            parts.append(
                f"no departure from {self.window[0]} to {self.window[1]} routes ({self.window[2]} tried{beyond})"
            )
        if self.partial is not None:
            p = self.partial
            parts.append(
                f"the closest a route gets is {p.distance_to_finish_nm:.0f} nm from the "
                f"{'finish' if self.leg == self.n_legs - 1 else 'next mark'}, at lon {p.lon_deg[-1]:.2f}, lat "
                f"{p.lat_deg[-1]:.2f} (rank {p.rank + 1} of {p.n_ranks})"
            )
        return parts

    def advice(self) -> str:
        """What routes the course and what does not, on one line."""
        return "; ".join(self.fixes() + self.facts())

    def message(self) -> str:
        """The one-line error: the leg (with waypoints), the cause, what routes it and what does not. The DP's own
        hint (raise apf, widen the grid) is left out where the relaxation tried it."""
        leg = f"leg {self.leg + 1} of {self.n_legs}: " if self.n_legs > 1 else ""
        tried = self.apf_tried or self.wider_tried
        hint = "" if tried and not self.hint.startswith(" (the weather does not cover") else self.hint
        text = f"{leg}{self.cause}{hint}"
        fixes, facts = self.fixes(), self.facts()
        if fixes:
            text += ". To route: " + "; ".join(fixes)
            return text + ("; " + "; ".join(facts) if facts else "")
        if facts:
            first = facts[0][0].upper() + facts[0][1:]
            text += ". " + "; ".join([first, *facts[1:]])
        return text

    def summary(self) -> dict[str, Any]:
        """The JSON of ``route --json`` when no route exists (under ``relaxation``)."""
        return {
            "cause": self.cause,
            "leg": self.leg,
            "n_legs": self.n_legs,
            "apf": self.apf,
            "apf_voyage_time_h": self.apf_voyage_time_h,
            "departure": None if self.departure is None else iso_utc(self.departure),
            "departure_voyage_time_h": self.departure_voyage_time_h,
            "window": None
            if self.window is None
            else {"first": self.window[0], "last": self.window[1], "tried": self.window[2]},  # fmt: skip
            "partial": None if self.partial is None else self.partial.summary(),
            "wider": self.wider,
            "wider_voyage_time_h": self.wider_voyage_time_h,
            "apf_tried": self.apf_tried,
            "wider_tried": self.wider_tried,
            "window_beyond_weather": self.window_beyond,
        }


def apf_text(apf: float) -> str:
    """``apf`` with at most 6 significant digits, rounded up so that the value written is never below it (an apf
    just below a table value forbids the arcs at that value).

    >>> apf_text(0.16605949999999997), apf_text(0.9), apf_text(1.0)
    ('0.16606', '0.9', '1')
    """
    text = f"{apf:.6g}"
    if float(text) < apf:
        digits = 5 - math.floor(math.log10(apf))
        text = f"{math.ceil(apf * 10**digits) / 10**digits:.{max(digits, 0)}f}".rstrip("0").rstrip(".")
    return text


def partial_route(grid: Grid, result: DPResult, departure: np.datetime64) -> PartialRoute | None:
    """The DP's path to the node it reached that is closest to the grid's finish (None when it reached none), the leg
    departing at ``departure``."""
    reached = np.isfinite(result.arrival_h)
    if not reached.any():
        return None
    ranks, nodes = np.nonzero(reached)
    dist = np.array([grid.distance_to_finish_nm(float(grid.lon_deg[k, j]), float(grid.lat_deg[k, j]))
                     for k, j in zip(ranks, nodes, strict=True)])  # fmt: skip
    best = int(np.argmin(dist))
    k_end, node = int(ranks[best]), int(nodes[best])
    path = [node]
    for k in range(k_end, 0, -1):
        node = int(result.back[k, node])
        path.append(node)
    path.reverse()
    start = int(result.back[0, path[0]])
    s_lon, s_lat = grid.start_points
    ks = np.arange(k_end + 1)
    lon = np.concatenate([[s_lon[max(start, 0)]], grid.lon_deg[ks, path]])
    lat = np.concatenate([[s_lat[max(start, 0)]], grid.lat_deg[ks, path]])
    elapsed = np.concatenate([[0.0], result.arrival_h[ks, path]])
    return PartialRoute(lon, lat, elapsed, float(dist[best]), k_end, grid.n_ranks, _seconds(departure))


def route_course(
    legs: Sequence[tuple[Grid, RoutingProblem]], *, departure: np.datetime64 | None = None, **changes: Any
) -> Route:
    """The course's route on its legs' grids, each leg departing when the previous one arrives (on the side of the
    wind it ended on), with ``changes`` made to every leg's problem (e.g. ``apf``, ``failure``) and the first leg's
    departure changed (None: as it is)."""
    routes: list[Route] = []
    t = legs[0][1].departure if departure is None else departure
    for grid, problem in legs:
        leg_problem = replace(problem, departure=t, **changes)
        last = routes[-1].manoeuvres if routes else None
        if last is not None and last.side.size and leg_problem.sides:  # a leg starts on the side the last ended on
            leg_problem = replace(leg_problem, initial_side=int(last.side[-1]))
        routes.append(route_on_grid(grid, leg_problem))
        t = routes[-1].arrival
    return routes[0] if len(routes) == 1 else join_routes(routes)


def _routes(legs: Sequence[tuple[Grid, RoutingProblem]], **change: Any) -> Route | None:
    try:
        return route_course(legs, **change)
    except (NoFeasibleRouteError, WeatherCoverageError):
        return None


def smallest_apf(legs: Sequence[tuple[Grid, RoutingProblem]]) -> tuple[float, Route] | None:
    """The smallest apf above the course's that routes it, and the route there (None: not even apf 1 does; see the
    module notes)."""
    problem = legs[0][1]
    if problem.failure is None:
        return None
    p = np.unique(problem.failure.p_flat)
    levels = [float(x) for x in p[np.isfinite(p) & (p > problem.apf) & (p < 1.0)]] + [1.0]
    top = _routes(legs, apf=levels[-1])
    if top is None:
        return None
    found = (levels[-1], top)
    lower = levels[:-1]
    if len(lower) <= LINEAR_LEVELS:
        for level in lower:
            route = _routes(legs, apf=level)
            if route is not None:
                return level, route
        return found
    lo, hi = 0, len(lower)  # lower[hi] (or the top) routes; find the first that does
    while lo < hi:
        mid = (lo + hi) // 2
        route = _routes(legs, apf=lower[mid])
        if route is not None:
            found, hi = (lower[mid], route), mid
        else:
            lo = mid + 1
    return found


def earliest_departure(
    legs: Sequence[tuple[Grid, RoutingProblem]], departures: Sequence[np.datetime64]
) -> tuple[tuple[np.datetime64, Route] | None, int]:
    """The first of ``departures`` (in order) at which the course routes, and its route (None: none does), and how
    many of those tried before it the weather does not cover."""
    beyond = 0
    for t in departures:
        when = _seconds(t)
        try:
            return (when, route_course(legs, departure=when)), beyond
        except WeatherCoverageError:
            beyond += 1
        except NoFeasibleRouteError:
            pass
    return None, beyond


def relax(
    legs: Sequence[tuple[Grid, RoutingProblem]],
    failed: int,
    error: NoFeasibleRouteError,
    *,
    departures: Sequence[np.datetime64] = (),
) -> Relaxation:
    """What would make the course route (see the module notes).

    Parameters
    ----------
    legs : The course's legs (grid and problem each; the first problem's departure is the course's, the failing
        leg's its own: when the legs before it arrive).
    failed : The leg that did not route (0-based).
    error : Its error, from :func:`~pyroute_rel.routing.route.route_on_grid` (its ``result`` is the DP's).
    departures : Departures to try, in order (none: the search is skipped).
    """
    grid, problem = legs[failed]
    result: DPResult | None = error.result
    cause = error.cause or str(error)
    hint = error.hint if error.cause else ""
    blocked_by_model = result is None or result.forbidden_by_reason.get("failure", 0) > 0
    p = np.array([]) if problem.failure is None else problem.failure.p_flat
    hard = bool(np.all((p[np.isfinite(p)] == 0.0) | (p[np.isfinite(p)] == 1.0)))  # limits: apf 1 ignores them
    apf_tried = blocked_by_model and problem.apf < 1.0 and problem.failure is not None and not hard
    at = smallest_apf(legs) if apf_tried else None
    when, beyond = earliest_departure(legs, departures) if len(departures) else (None, 0)
    window = None
    if len(departures):
        window = (iso_utc(departures[0]), iso_utc(departures[-1]), len(departures))
    return Relaxation(
        cause=cause,
        hint=hint,
        leg=failed,
        n_legs=len(legs),
        apf=None if at is None else at[0],
        apf_voyage_time_h=None if at is None else at[1].voyage_time_h,
        departure=None if when is None else when[0],
        departure_voyage_time_h=None if when is None else when[1].voyage_time_h,
        window=window,
        window_beyond=beyond,
        apf_tried=apf_tried,
        partial=None if result is None else partial_route(grid, result, problem.departure),
    )


def _seconds(t: Any) -> np.datetime64:
    """A time as ``datetime64[s]``."""
    return cast(np.datetime64, np.asarray(t).astype("datetime64[s]")[()])


def window_size(first: np.datetime64, last: np.datetime64, step_h: float) -> int:
    """How many departures :func:`departure_window` makes, counted without making them."""
    span_h = float((_seconds(last) - _seconds(first)) / np.timedelta64(1, "s")) / 3600.0
    return max(int(np.floor(span_h / step_h + 1e-9)) + 1, 0)


def departure_window(first: np.datetime64, last: np.datetime64, step_h: float) -> list[np.datetime64]:
    """The departures from ``first`` to ``last`` (included when on the step) every ``step_h`` hours."""
    t0 = _seconds(first)
    return [t0 + np.timedelta64(round(i * step_h * 3600.0), "s") for i in range(window_size(first, last, step_h))]
