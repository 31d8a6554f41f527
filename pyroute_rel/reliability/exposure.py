"""Exposure-based reliability: a voyage's failure probability from the time spent in each condition.

A failure model's ``p_f`` is the probability of failure over a reference exposure ``exposure_h`` [h] spent in those
conditions (:attr:`~pyroute_rel.reliability.failure.FailureModel.exposure_h`). Time spent in conditions with ``p_f``
adds the hazard

    ``H = -ln(1 - p_f) * dt / exposure_h``  (``p_f = 1``: infinite hazard, certain failure on any exposure)

and the probability of failure over a stretch of the voyage is ``1 - exp(-sum H)``: ``1 - (1 - p_f) ** (T /
exposure_h)`` for ``T`` hours in uniform conditions, whatever the number of legs ``T`` is cut into. The ``apf``
constraint is unchanged: it bounds the conditions' ``p_f`` (an arc with ``p_f > apf`` somewhere is forbidden).

Where a leg's time goes: each leg of a route is cut into sub-arcs of at most :data:`EXPOSURE_STEP_KM` along its great
circle. In weather that changes in time each sub-arc is timed on the times the leg was sailed at (the march of
:mod:`pyroute_rel.boat.march`: linear between the ends of its sub-segments), the times the failure criteria were
judged at; in steady weather the cost function times each sub-arc (sampled at its midpoint, as the router samples arcs),
and the times are scaled so that they add up to the leg's time exactly. Each sub-arc contributes the hazard of the
conditions at its midpoint (the failure model's ``p_f`` for the heading the craft steers there), so the hours in each
condition are resolved to the step, not to the grid's legs: the voyage's figure converges as the grid is refined. Waits
at a node are not counted (the model's conditions need a heading).

References
----------
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft. Proc.
International Robotic Sailing Conference 2018 (P(fail) per arc, Algorithm 1).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.crab import steer
from pyroute_rel.boat.march import time_along
from pyroute_rel.reliability.failure import arc_quantities

if TYPE_CHECKING:
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.weather import Conditions

__all__ = ["EXPOSURE_STEP_KM", "LegExposure", "hazard", "failure_probability", "leg_exposure", "arc_exposure"]

FloatArray = npt.NDArray[np.float64]

#: Longest sub-arc [km] a leg is cut into to find how long it spends in each condition.
EXPOSURE_STEP_KM = 1.0


def hazard(p_f: npt.ArrayLike, dt_h: npt.ArrayLike, exposure_h: float) -> FloatArray:
    """Hazard of ``dt_h`` hours in conditions whose failure probability over ``exposure_h`` hours is ``p_f``.

    Parameters
    ----------
    p_f : Failure probability over the reference exposure [-], in [0, 1].
    dt_h : Time spent in the conditions [h], >= 0.
    exposure_h : The reference exposure [h], > 0.

    Returns
    -------
    ``-ln(1 - p_f) * dt_h / exposure_h`` [-]: ``inf`` where ``p_f = 1`` and ``dt_h > 0``, 0 where ``dt_h = 0``.

    Examples
    --------
    >>> float(hazard(0.5, 8.0, 4.0)) == 2.0 * float(np.log(2.0))
    True
    >>> hazard([1.0, 1.0, 0.0], [1.0, 0.0, 5.0], 4.0).tolist()
    [inf, 0.0, 0.0]
    """
    p = np.asarray(p_f, dtype=float)
    dt = np.asarray(dt_h, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        h = -np.log1p(-p) * (dt / exposure_h)
    # p_f = 0 is no hazard however long the stay: 0, not 0 * inf = nan when dt_h / exposure_h overflows.
    h = np.where(p == 0.0, 0.0, h)
    return np.asarray(np.where(dt > 0.0, h, 0.0), dtype=float)


def failure_probability(total_hazard: npt.ArrayLike) -> FloatArray:
    """Probability of failure ``1 - exp(-H)`` [-] of an accumulated hazard ``H`` [-].

    >>> float(failure_probability(float(hazard(0.2, 10.0, 5.0))))  # two exposures at 0.2: 1 - 0.8 ** 2
    0.36
    """
    return np.asarray(0.0 - np.expm1(-np.asarray(total_hazard, dtype=float)), dtype=float)  # 0, not -0, at no hazard


def combined_failure_probability(p_fail_leg: npt.ArrayLike) -> float:
    """Probability of failure over a sequence of legs, ``1 - prod(1 - p_fail_leg)`` [-], summed as hazards
    (``log1p``) so that small probabilities keep their digits; legs whose probability is not finite (not sailed)
    are left out, and a leg with ``p_fail_leg = 1`` makes it 1.

    >>> combined_failure_probability([0.2, 0.2])  # 1 - 0.8 ** 2
    0.36
    >>> combined_failure_probability([0.0, float("nan")])  # 0, not -0
    0.0
    """
    p = np.asarray(p_fail_leg, dtype=float).ravel()
    p = p[np.isfinite(p)]
    with np.errstate(divide="ignore"):  # log1p(-1) = -inf: certain failure
        return float(0.0 - np.expm1(np.sum(np.log1p(-p))))


@dataclass(frozen=True)
class LegExposure:
    """What each leg of a route adds to the voyage's failure probability.

    Attributes
    ----------
    hazard : Hazard of each leg [-] (one value per leg; ``inf`` where it meets ``p_f = 1``).
    criterion_h : Hours of each leg spent where each criterion of the failure model fires, by the criterion's
        description (e.g. ``"WH: hs_m >= 4 m"``) [h].
    p_max : The largest failure probability of the conditions met on each leg's sub-arcs [-] (0 where none; None
        where not computed): a route reports at least this as the leg's ``p_f``, so that its largest ``p_f`` covers
        every hour its exposure counts.
    """

    hazard: FloatArray
    criterion_h: dict[str, FloatArray]
    p_max: FloatArray | None = None

    @property
    def p_fail_leg(self) -> FloatArray:
        """Probability of failure over each leg's duration [-]."""
        return failure_probability(self.hazard)


def leg_exposure(
    problem: RoutingProblem,
    lon_deg: npt.ArrayLike,
    lat_deg: npt.ArrayLike,
    start_h: npt.ArrayLike,
    time_h: npt.ArrayLike,
    p_f: npt.ArrayLike,
    *,
    step_km: float = EXPOSURE_STEP_KM,
    marks_h: FloatArray | None = None,
) -> LegExposure:
    """Hazard and hours per criterion of each leg of a track (see the module notes).

    Parameters
    ----------
    problem : The routing problem (weather, polar, failure model; its ``apf`` and obstacles do not matter here).
    lon_deg, lat_deg : Track points [deg] (one more than legs).
    start_h : When each leg is sailed from its first point [h after ``problem.departure``] (after any wait).
    time_h : Each leg's sailing time [h] (finite).
    p_f : Each leg's largest failure probability as the router costed it [-]: used for a sub-arc whose weather
        is missing at its midpoint (the router found the leg sailable, but a finer sample fell into a hole).
    step_km : Longest sub-arc [km] (> 0).
    marks_h : With time-varying weather, when the craft reaches each leg's sub-segment ends [h after
        ``problem.departure``], shape (legs, samples + 1) (:attr:`~pyroute_rel.routing.cost.ArcCosts.marks_h`): each
        sub-arc is then timed on them (:func:`~pyroute_rel.boat.march.time_along`), as the cost function sailed it
        and judged its pieces. None: the sub-arcs are timed by the cost function from their own departures, then scaled
        to the leg's time.

    Returns
    -------
    LegExposure
        Zero hazards and no criteria without a failure model.
    """
    lon, lat = np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float)
    return arc_exposure(
        problem, lon[:-1], lat[:-1], lon[1:], lat[1:], start_h, time_h, p_f, step_km=step_km, marks_h=marks_h
    )


def arc_exposure(
    problem: RoutingProblem,
    lon0_deg: npt.ArrayLike,
    lat0_deg: npt.ArrayLike,
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    start_h: npt.ArrayLike,
    time_h: npt.ArrayLike,
    p_f: npt.ArrayLike,
    *,
    step_km: float = EXPOSURE_STEP_KM,
    marks_h: FloatArray | None = None,
) -> LegExposure:
    """Hazard and hours per criterion of separate arcs, each from ``(lon0, lat0)`` to ``(lon1, lat1)`` [deg] (1-D
    arrays of one value per arc); the other arguments as in :func:`leg_exposure`, one value per arc.

    :func:`leg_exposure` is this function on a track's consecutive legs. With steady weather the sub-arcs are timed
    only on the arcs where some sub-arc meets a ``p_f > 0`` or fires a criterion (elsewhere the hazard and hours are
    0 whatever the times): the same figures, without timing arcs that cannot add to them.
    """
    t_leg = np.asarray(time_h, dtype=float)
    model = problem.failure
    if model is None:
        return LegExposure(hazard=np.zeros(t_leg.size), criterion_h={}, p_max=np.zeros(t_leg.size))
    if not step_km > 0:
        raise ValueError(f"step_km must be > 0 [km] (got {step_km!r})")
    a0, b0, a1, b1 = (np.asarray(x, dtype=float) for x in (lon0_deg, lat0_deg, lon1_deg, lat1_deg))
    start_leg = np.asarray(start_h, dtype=float)
    p_leg = np.asarray(p_f, dtype=float)
    if problem.weather.steady:  # time the sub-arcs only of the arcs that meet some hazard or criterion
        keep = _exposed(problem, a0, b0, a1, b1, step_km)
        if not keep.all():
            n, out = (
                keep.size,
                LegExposure(np.zeros(0), {c.describe(): np.zeros(0) for c in model.criteria}, np.zeros(0)),
            )
            if keep.any():
                sel = (a0[keep], b0[keep], a1[keep], b1[keep], start_leg[keep], t_leg[keep], p_leg[keep])
                out = _sub_arc_exposure(problem, *sel, step_km)
            assert out.p_max is not None
            return LegExposure(
                hazard=_spread(out.hazard, keep, n),
                criterion_h={k: _spread(v, keep, n) for k, v in out.criterion_h.items()},
                p_max=_spread(out.p_max, keep, n),
            )
    if problem.weather.steady:
        marks = None
    elif marks_h is None:  # the times the arcs are sailed at (pyroute_rel.boat.march), from their departures
        marks = problem.costs(a0, b0, a1, b1, start_leg).marks_h
    else:
        marks = np.asarray(marks_h, dtype=float)
    return _sub_arc_exposure(problem, a0, b0, a1, b1, start_leg, t_leg, p_leg, step_km, marks)


@dataclass(frozen=True)
class _SubArcs:
    """Arcs (end points ``a0, b0 -> a1, b1`` [deg]) cut into sub-arcs of at most ``step_km``: each sub-arc's arc
    ``leg`` and its fractions ``f0, f1`` along it; ``first`` the first sub-arc of each arc."""

    a0: FloatArray
    b0: FloatArray
    a1: FloatArray
    b1: FloatArray
    leg: npt.NDArray[np.intp]
    first: npt.NDArray[np.intp]
    f0: FloatArray
    f1: FloatArray

    @classmethod
    def cut(cls, a0: FloatArray, b0: FloatArray, a1: FloatArray, b1: FloatArray, step_km: float) -> _SubArcs:
        per_leg = np.maximum(1, np.ceil(geodesy.distance_km(a0, b0, a1, b1) / step_km)).astype(np.intp)
        leg = np.repeat(np.arange(a0.size), per_leg)
        first = np.concatenate([[0], np.cumsum(per_leg)[:-1]]).astype(np.intp)
        j = np.arange(leg.size) - first[leg]
        return cls(a0, b0, a1, b1, leg, first, j / per_leg[leg], (j + 1) / per_leg[leg])

    def ends(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The sub-arcs' end points [deg] (the arcs' own end points exactly at their ends)."""
        leg = self.leg
        a, b, c, d = self.a0[leg], self.b0[leg], self.a1[leg], self.b1[leg]
        lon0, lat0 = self.along(self.f0)
        lon1, lat1 = self.along(self.f1)
        start, last = self.f0 == 0.0, self.f1 == 1.0
        return np.where(start, a, lon0), np.where(start, b, lat0), np.where(last, c, lon1), np.where(last, d, lat1)

    def along(self, fraction: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Points [deg] at ``fraction`` (one per sub-arc) along each sub-arc's arc. The arcs' sub-arcs are laid out
        in rows (padded with NaN) so that each arc's end points are converted once, when the padding is small; the
        points are the same either way."""
        n_arcs, leg = self.a0.size, self.leg
        width = int(np.max(np.bincount(leg, minlength=n_arcs))) if leg.size else 0
        if n_arcs * width > 2 * leg.size:  # arcs of very different lengths: one point at a time
            return geodesy.intermediate_point(self.a0[leg], self.b0[leg], self.a1[leg], self.b1[leg], fraction)
        col = np.arange(leg.size) - self.first[leg]
        rows = np.full((n_arcs, width), np.nan)
        rows[leg, col] = fraction
        a0, b0, a1, b1 = (x[:, None] for x in (self.a0, self.b0, self.a1, self.b1))
        lon, lat = geodesy.intermediate_point(a0, b0, a1, b1, rows)
        return lon[leg, col], lat[leg, col]

    def conditions(
        self, problem: RoutingProblem, t_mid_h: npt.ArrayLike, *, any_fired: bool = False
    ) -> tuple[FloatArray, npt.NDArray[np.bool_] | None, npt.NDArray[np.bool_]]:
        """``p_f`` at each sub-arc's midpoint (half-way between its fractions along the arc) for the heading steered
        there to hold the arc's great circle, at ``t_mid_h`` [h] (NaN where the weather is missing), where it is
        unknown, and which criteria fire (shape ``(n_criteria, n_sub_arcs)``; with ``any_fired``, whether any does,
        shape ``(1, n_sub_arcs)``, from the table's bit sets, where the evidence is known)."""
        model = problem.failure
        assert model is not None
        leg = self.leg
        c, d = self.a1[leg], self.b1[leg]
        mlon, mlat = self.along(0.5 * (self.f0 + self.f1))
        course = geodesy.initial_bearing_deg(mlon, mlat, c, d)
        cond = problem.weather_at(mlon, mlat, t_mid_h)
        q = arc_quantities(cond, _heading(problem, cond, course), model.quantities)
        index, unknown = model.evidence_index(q)  # the cost function's gather (p_fail would also check ranges)
        if any_fired:
            return model.p_flat[index], unknown, (model.fired_bits_flat[index] != 0).reshape(1, -1)
        return model.p_flat[index], unknown, np.asarray(model.fired(q)).reshape(len(model.criteria), -1)


def _exposed(
    problem: RoutingProblem, a0: FloatArray, b0: FloatArray, a1: FloatArray, b1: FloatArray, step_km: float
) -> npt.NDArray[np.bool_]:
    """Steady weather: the arcs where some sub-arc's midpoint has ``p_f > 0``, unknown weather or a criterion
    fired (the others add no hazard and no hours whatever their times)."""
    sub = _SubArcs.cut(a0, b0, a1, b1, step_km)
    p, unknown, fired = sub.conditions(problem, 0.0, any_fired=True)
    hit = (p > 0.0) | fired[0]
    if unknown is not None:
        hit |= unknown
    return np.asarray(np.bincount(sub.leg, weights=hit, minlength=a0.size) > 0, dtype=bool)


def _spread(values: FloatArray, keep: npt.NDArray[np.bool_], n: int) -> FloatArray:
    """``values`` of the kept arcs laid out on all ``n`` arcs (0 elsewhere)."""
    out = np.zeros(n)
    out[keep] = values
    return out


def _sub_arc_exposure(
    problem: RoutingProblem,
    a0: FloatArray,
    b0: FloatArray,
    a1: FloatArray,
    b1: FloatArray,
    start_leg: FloatArray,
    t_leg: FloatArray,
    p_leg: FloatArray,
    step_km: float,
    marks: FloatArray | None = None,
) -> LegExposure:
    """:func:`arc_exposure` on every arc: each cut into sub-arcs, timed, and its hazard and hours summed."""
    model = problem.failure
    assert model is not None
    n_legs = t_leg.size
    sub = _SubArcs.cut(a0, b0, a1, b1, step_km)
    leg, f0, f1 = sub.leg, sub.f0, sub.f1
    if marks is not None:  # the times the cost function sailed each arc at, linear within its sub-segments
        t0 = time_along(marks[leg], f0)
        dt = time_along(marks[leg], f1) - t0
        t_mid = time_along(marks[leg], 0.5 * (f0 + f1))
    else:  # steady weather: each sub-arc timed, the times scaled to add up to its arc's (conditions at any time)
        timing = replace(problem, samples=1, apf=1.0)  # times only: the failure model forbids nothing here
        share = (f1 - f0) * t_leg[leg]  # the leg's time shared by length, where a sub-arc has no time
        t0 = start_leg[leg] + f0 * t_leg[leg]
        dt = _scaled(timing.costs(*sub.ends(), t0).time_h, share, leg, t_leg)
        t_mid = t0 + 0.5 * dt
    p, unknown, fired = sub.conditions(problem, t_mid)
    if unknown is not None:  # missing weather at a sub-arc's midpoint: the leg's p_f as the router costed it
        p = np.where(unknown, p_leg[leg], p)
    h = hazard(p, dt, model.exposure_h)
    p_max = np.zeros(n_legs)
    np.fmax.at(p_max, leg, p)  # NaN (unknown) ignored
    return LegExposure(
        hazard=np.asarray(np.bincount(leg, weights=h, minlength=n_legs), float),  # hazards >= 0: a sum with inf is inf
        criterion_h={
            crit.describe(): np.asarray(np.bincount(leg, weights=np.where(fired[i], dt, 0.0), minlength=n_legs), float)
            for i, crit in enumerate(model.criteria)
        },
        p_max=p_max,
    )


def _scaled(w: FloatArray, share: FloatArray, leg: npt.NDArray[np.intp], t_leg: FloatArray) -> FloatArray:
    """Sub-arc times ``w`` [h] scaled so that each leg's add up to its time ``t_leg`` [h] (``share`` [h] where a
    sub-arc has no finite time)."""
    w = np.where(np.isfinite(w), w, share)
    total = np.bincount(leg, weights=w, minlength=t_leg.size)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(total > 0.0, t_leg / total, 0.0)
    return np.asarray(w * scale[leg], dtype=float)


def _heading(problem: RoutingProblem, cond: Conditions, course_deg: FloatArray) -> FloatArray:
    """The heading the craft steers to hold ``course_deg`` [deg]: the course itself, or with a current the crab
    heading (:func:`~pyroute_rel.boat.crab.hold_course`, as the cost function steers)."""
    if not cond.has_current:
        return course_deg
    factor = 1.0 if problem.wave_loss is None else problem.wave_loss.factor(cond.hs_m)
    crab = steer(cond, course_deg, problem.polar, beyond=problem.beyond, speed_factor=factor)
    return np.asarray(np.where(np.isfinite(crab.heading_deg), crab.heading_deg, course_deg), dtype=float)
