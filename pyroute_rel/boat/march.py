"""Sailing arcs through weather that changes in time: the one time-integration rule every arc is costed with.

An arc of a route is cut into ``S`` equal sub-segments (:class:`~pyroute_rel.routing.cost.ArcGeometry`; at most the
sample spacing long). The craft sails them in order. Each sub-segment is represented by its midpoint (its sample point,
where the weather is sampled) and the time to cross it is integrated along the time the craft spends on it:

1. **Predictor.** At the time ``t`` the craft starts (or goes on with) the sub-segment, the speed over ground
   ``v(t)`` at the sample point gives the time ``h = r / v(t)`` to sail the ``r`` [nm] left.
2. **Cut at the weather's time steps while the craft crawls.** Between two time steps of a weather file every field
   is linear in time. A craft slower than :data:`SPEED_FLOOR_KN` (in irons, in a calm) has its step end at the next
   time step, where it is judged again; a craft under way is timed across time steps, and the halving below resolves
   any change of trend within its step (cutting every step of an hourly file multiplied the steps by ten on long
   arcs, for no measurable gain).
3. **Corrector (midpoint rule).** The speed is taken again at the step's middle time, ``v_m = v(t + h / 2)``: an
   uncut step takes ``r / v_m``; a cut step makes ``v_m h`` of progress (finishing the sub-segment at
   ``t + r / v_m`` if that is enough) and the march goes on from its end. Where ``v_m`` differs from the speed at the
   step's start by more than :data:`SPEED_CHANGE` of the larger (or of :data:`SPEED_FLOOR_KN`), the step is tried
   again with half the time, down to :data:`MIN_STEP_H` (the speed alone decides this; a step tried again judges
   nothing and stops nothing).
4. **No progress, no borrowing.** Where the polar gives no speed (head to wind, calm) or the current holds the craft,
   it makes no progress until the next time step, and is judged again there; it never takes a later wind to cross
   now. An arc on which the craft can make no progress before the weather's last time step is forbidden (the
   polar's or the current's flag), and one that reaches missing weather (NaN, past the file's end) is forbidden as
   missing weather.

The failure model judges the conditions at every corrector sample: where and when the craft is, at the middle of
each step. :mod:`pyroute_rel.reliability.crossings` then judges each arc on every piece it crosses, in space and in
time, along the times this march gives at the sub-segment ends (:attr:`Marched.marks_h`).

Why the midpoint rule: it is second order in the step (the time at the middle of a step is known to first order
from the predictor, which is all the midpoint rule needs), costs two samples a step, and is exact for a speed linear
in time. The halving bounds how much the speed may change within a step, wherever the change comes from (a change
of trend at a time step, a polar kink); a craft crawling in a near-calm is re-judged at each time step instead of
being costed with a wind hours ahead. The steps are at most a sub-segment long, so the reported time converges to
the continuously sailed track as the sample spacing shrinks (docs/method.md gives the measured error against 100 m
steps).

Where the source names no time steps (a source smooth in time, :attr:`~pyroute_rel.weather.WeatherSource.time_steps`
None), steps are not cut in time (the halving above still resolves a fast change); a craft without speed looks again
every :data:`MAX_STEP_H`, for at most :data:`MAX_WAIT_H` on one sub-segment (then the arc is forbidden).

FIFO: sailing a sub-segment is the ordinary differential equation ``ds/dt = v(t) >= 0`` at its sample point, whose
solutions do not cross: a craft that starts later never arrives earlier. The discrete march keeps this up to its
truncation error (docs/method.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = [
    "MAX_STEP_H",
    "MAX_WAIT_H",
    "MIN_STEP_H",
    "SPEED_CHANGE",
    "SPEED_FLOOR_KN",
    "Marched",
    "SpeedNoise",
    "Step",
    "march",
    "next_steps",
    "step_hours",
    "time_along",
]

FloatArray = npt.NDArray[np.float64]

#: Where the weather names no time steps of its own: how long a craft without speed waits before it looks again [h],
#: and for how long at most on one sub-segment [h].
MAX_STEP_H = 1.0
MAX_WAIT_H = 720.0

#: Largest change of the speed over ground between a step's start and its middle, relative to the larger of the two
#: (and of :data:`SPEED_FLOOR_KN`) [-]: a step over which the speed changes more is tried again with half the time
#: (down to :data:`MIN_STEP_H`).
SPEED_CHANGE = 0.1

#: The speed below which changes are measured against it rather than against the speed [kn]: a craft crawling in
#: irons (a few hundredths of a knot) is not re-timed in minutes for changes that move it a few metres.
SPEED_FLOOR_KN = 1.0

#: Shortest step [h] the march halves a step down to.
MIN_STEP_H = 0.05


@dataclass(frozen=True)
class SpeedNoise:
    """A noise on the craft's speed over ground, one draw per arc, applied wherever the craft's speed is taken.

    The speed ``v`` [kn] becomes ``v' = max(gain v + spread sqrt(v), FLOOR v)`` where ``v > 0`` (no progress and
    missing weather stay as they are): with ``gain = a`` and ``spread = sqrt(kappa a) eta`` it is Monte Carlo's
    ``V' = a V + sqrt(kappa a V) eta`` (:mod:`pyroute_rel.monte_carlo`). Applied to the speed at every step of the
    march, the slower craft meets the wind of the times it is there, not the wind of the deterministic craft's times.

    Attributes
    ----------
    gain : Each arc's factor on the speed [-], in the block's shape (or one value for all).
    spread : Each arc's term in ``sqrt(v)`` [kn**0.5], in the block's shape (or one value for all).
    """

    gain: FloatArray
    spread: FloatArray

    #: The floor of the noisy speed, as a fraction of the speed [-].
    FLOOR = 0.1

    def flat(self, size: int) -> tuple[FloatArray, FloatArray]:
        """``gain`` and ``spread`` of every arc of a block of ``size`` arcs, flat (C order)."""
        return tuple(  # type: ignore[return-value]
            np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float).ravel(), (size,)))
            for a in (self.gain, self.spread)
        )

    def apply(self, sog_kn: FloatArray, gain: FloatArray, spread: FloatArray) -> FloatArray:
        """The noisy speed [kn] of speeds ``sog_kn`` whose arcs draw ``gain`` and ``spread`` (broadcast against it)."""
        v = np.asarray(sog_kn, dtype=float)
        with np.errstate(invalid="ignore"):
            moves = v > 0.0
            noisy = np.maximum(gain * v + spread * np.sqrt(np.where(moves, v, 0.0)), self.FLOOR * v)
        return np.where(moves, noisy, v)


@dataclass(frozen=True)
class Step:
    """The craft's speed and what the failure model says at some points of one sub-segment's sample.

    Attributes
    ----------
    sog_kn : Speed over ground along the course [kn]: 0 where the craft makes no progress (no polar speed, a current
        it cannot hold the course in), NaN where the weather is missing.
    p_f : Failure probability of the conditions (0 when not judged or without a failure model) [-].
    reason : Bit flags (:data:`~pyroute_rel.routing.cost.REASONS`) of the conditions.
    fired : Criteria fired above apf (bits), or None.
    """

    sog_kn: FloatArray
    p_f: FloatArray
    reason: npt.NDArray[np.uint8]
    fired: npt.NDArray[np.uint32] | None


#: ``speed(column, index, t_h, judge)``: the craft's :class:`Step` at sample ``column`` of the arcs ``index`` (flat
#: indices, increasing; None: every arc) at times ``t_h`` [h after the departure origin]; ``judge``: the failure
#: model judges them (else only the speed is wanted).
SpeedAt = Callable[[int, "npt.NDArray[np.intp] | None", FloatArray, bool], Step]


@dataclass(frozen=True)
class Marched:
    """Arcs sailed by :func:`march` (flat: one entry per arc).

    Attributes
    ----------
    time_h : Time to sail each arc [h]; ``inf`` where forbidden.
    marks_h : Time at each sub-segment end [h after the departure origin], shape (n, S + 1): column 0 is the arc's
        departure, column ``k`` the end of sub-segment ``k``; the time along sub-segment ``k`` is taken as linear
        between its marks (:func:`pyroute_rel.reliability.crossings.arc_extremes`). Where an arc is forbidden, the marks
        after the point where it stopped repeat its last time.
    p_f : Largest failure probability of the conditions judged along each arc [-] (NaN where weather was missing).
    reason : Bit flags (0 where the arc is allowed).
    fired : Criteria fired above apf somewhere along each arc, or None.
    """

    time_h: FloatArray
    marks_h: FloatArray
    p_f: FloatArray
    reason: npt.NDArray[np.uint8]
    fired: npt.NDArray[np.uint32] | None


def time_along(marks_h: FloatArray, fraction: npt.ArrayLike) -> FloatArray:
    """When the craft is at ``fraction`` [0, 1] of arcs sailed by :func:`march`: linear between the times it reaches
    their sub-segments' ends (``marks_h``, shape (n, S + 1) [h]); ``fraction`` of shape (n,) or (n, m).

    >>> time_along(np.array([[0.0, 10.0, 12.0]]), np.array([[0.25, 0.5, 0.75, 1.0]])).tolist()
    [[5.0, 10.0, 11.0, 12.0]]
    """
    marks = np.asarray(marks_h, dtype=float)
    f = np.asarray(fraction, dtype=float)
    flat = f.ndim == 1
    f2 = f[:, None] if flat else f
    samples = marks.shape[1] - 1
    x = np.clip(f2, 0.0, 1.0) * samples
    k = np.minimum(np.floor(x).astype(np.intp), samples - 1)
    lo = np.take_along_axis(marks, k, axis=1)
    hi = np.take_along_axis(marks, k + 1, axis=1)
    out = lo + (x - k) * (hi - lo)
    return out[:, 0] if flat else out


def step_hours(steps: npt.NDArray[np.datetime64] | None, departure: np.datetime64) -> FloatArray | None:
    """A weather's :attr:`~pyroute_rel.weather.WeatherSource.time_steps` as hours after ``departure`` [h] (None:
    none).

    >>> step_hours(np.array(["2018-06-01T03", "2018-06-01T09"], "datetime64[ns]"), np.datetime64("2018-06-01")).tolist()
    [3.0, 9.0]
    """
    if steps is None:
        return None
    t0: np.datetime64 = np.datetime64(departure, "ns")  # type: ignore[call-overload]  # numpy's stubs have no datetime64(datetime64, unit) overload
    return np.asarray((steps - t0) / np.timedelta64(3600, "s"), dtype=float)


def next_steps(steps_h: FloatArray | None, t_h: FloatArray) -> FloatArray:
    """The first time step strictly after each time [h] (``inf`` after the last, and without steps).

    >>> next_steps(np.array([0.0, 3.0, 6.0]), np.array([-1.0, 0.0, 2.5, 6.0])).tolist()
    [0.0, 3.0, 3.0, inf]
    """
    if steps_h is None:
        return np.full(np.shape(t_h), np.inf)
    i = np.searchsorted(steps_h, t_h, side="right")
    padded = np.append(steps_h, np.inf)
    return padded[i]


def march(
    t0_h: FloatArray,
    seg_nm: FloatArray,
    samples: int,
    speed: SpeedAt,
    steps_h: FloatArray | None,
    *,
    missing_flag: int,
    failure_flag: int,
    polar_flag: int,
) -> Marched:
    """Sail ``n`` arcs of ``samples`` equal sub-segments each (see the module notes).

    Parameters
    ----------
    t0_h : Departure of each arc [h after the departure origin], shape (n,) (not finite: sailed from 0).
    seg_nm : Length of each arc's sub-segments [nm], shape (n,).
    samples : Sub-segments per arc.
    speed : The craft's speed at a sample and time (:data:`SpeedAt`).
    steps_h : The weather's time steps [h after the departure origin], increasing, or None (:func:`next_steps`).
    missing_flag, failure_flag, polar_flag : The reason bits of missing weather, of a failure above apf and of no
        speed from the polar (an arc on which the craft waits for ever is flagged with the bits that held it, the
        polar's or the current's).

    Returns
    -------
    Marched
    """
    n = t0_h.size
    start = np.where(np.isfinite(t0_h), t0_h, 0.0)
    elapsed = np.zeros(n)  # since each arc's departure (kept apart from it: the same sums at any departure)
    marks = np.empty((n, samples + 1))
    marks[:, 0] = start
    reason = np.zeros(n, dtype=np.uint8)
    p_f = np.zeros(n)
    fired: npt.NDArray[np.uint32] | None = None
    going = np.ones(n, dtype=bool)  # not stopped by missing weather or by no progress for ever
    no_progress = np.uint8(~(missing_flag | failure_flag) & 0xFF)  # polar, current: the craft waits
    for k in range(samples):
        left = np.array(seg_nm, dtype=float, copy=True)
        t_sub = start + elapsed  # when each arc started this sub-segment
        cap = np.full(n, np.inf)  # the longest step to try next [h] (halved where the speed changed too fast)
        idx: npt.NDArray[np.intp] | None = None if going.all() else np.flatnonzero(going)
        while idx is None or idx.size:
            at = np.arange(n) if idx is None else idx
            e, r, t_start, c = (
                (elapsed, left, start, cap) if idx is None else (elapsed[idx], left[idx], start[idx], cap[idx])
            )
            tk = t_start + e
            nxt = next_steps(steps_h, tk)
            first = speed(k, idx, tk, False)
            v0 = first.sog_kn
            with np.errstate(divide="ignore", invalid="ignore"):
                hp = np.where(v0 > 0.0, r / v0, np.inf)
                # a craft under way is timed across the file's time steps (the halving below resolves a change of
                # trend); a crawling or held one is judged again at each time step
                h = np.minimum(np.minimum(hp, np.where(v0 < SPEED_FLOOR_KN, nxt, np.inf) - tk), c)
                if steps_h is None:  # no time step to wait for: look again a while later, for a while
                    wait = ~(v0 > 0.0) & (tk - t_sub[at] < MAX_WAIT_H)
                    h = np.where(wait, np.minimum(MAX_STEP_H, c), h)
                cut = h < hp  # the step ends before the sub-segment's end (as predicted)
            stuck = ~np.isfinite(h)  # no speed now, and no later time step to wait for
            mid = speed(k, idx, np.where(stuck, tk, tk + 0.5 * h), True)
            vm = mid.sog_kn
            missing = ((first.reason | mid.reason) & np.uint8(missing_flag)) != 0
            with np.errstate(invalid="ignore", divide="ignore"):
                # the speed changes too much within the step for its middle to stand for it: try half the step
                scale = np.fmax(np.fmax(vm, v0), SPEED_FLOOR_KN)
                # (on the speed alone: NaN where the wind is missing compares False; fields only the failure
                # model judges, missing at the middle of a step taken, stop the arc there)
                rough = (np.abs(vm - v0) > SPEED_CHANGE * scale) & (h > MIN_STEP_H) & ~stuck
                missing &= ~rough  # (a step tried again stops nothing)
                ok = ~rough
                moves = vm > 0.0
                done = ok & moves & (~cut | (vm * h >= r)) & ~missing & ~stuck
                progress = np.where(ok & cut & moves, vm * h, 0.0)
                dt_done = r / vm
            # what the failure model says where and when the craft is (at the middle of every step taken)
            take = ok & ~stuck
            p_f[at[take]] = np.maximum(p_f[at[take]], mid.p_f[take])
            reason[at[take]] |= mid.reason[take] & np.uint8(failure_flag)
            if mid.fired is not None:  # criteria fired in the states above apf taken
                over = take & ((mid.reason & np.uint8(failure_flag)) != 0)
                if over.any():
                    if fired is None:
                        fired = np.zeros(n, dtype=np.uint32)
                    fired[at[over]] |= mid.fired[over]
            # a stop for ever: missing weather, or no speed with no later time step to wait for
            # (without time steps the craft looks again a while later: stuck says when it gives up)
            last = ~np.isfinite(nxt) if steps_h is not None else np.zeros(nxt.shape, dtype=bool)
            wait_for_ever = ok & ~done & ~missing & (stuck | (~cut & ~moves & last))
            reason[at[missing]] |= np.uint8(missing_flag)
            why = np.where(stuck, first.reason, mid.reason) & no_progress
            reason[at[wait_for_ever]] |= np.where(why[wait_for_ever] != 0, why[wait_for_ever], np.uint8(polar_flag))
            stop = missing | wait_for_ever
            going[at[stop]] = False
            # on: a step short of the sub-segment's end taken (cut at a time step, by the cap, or no progress until
            # the next time step), or a step to try again shorter; done: the sub-segment's end reached
            on = ~done & ~stop
            step_on = on & ok
            with np.errstate(invalid="ignore"):
                elapsed[at] = np.where(done, e + dt_done, np.where(step_on, e + h, e))
            left[at] = np.where(on, r - progress, 0.0)
            cap[at] = np.where(rough, 0.5 * h, np.where(h >= c, 2.0 * c, np.inf))
            idx = at[on]
        marks[:, k + 1] = start + elapsed
    time_h = np.where(going & (reason == 0), elapsed, np.inf)
    return Marched(time_h=time_h, marks_h=marks, p_f=p_f, reason=reason, fired=fired)
