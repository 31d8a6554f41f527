"""Compiled twin of :func:`pyroute_rel.boat.march.march` for gridded weather with wind only (no current, no wave
speed loss), the failure model included.

The numpy march advances every arc of a block one step per round, and a block's slowest arc (a craft waiting days
in irons for the wind to shift) sets the number of rounds; each round costs two sampling calls and a few dozen array
operations. Here each arc is sailed from its departure to its end in one compiled loop: the same steps, the same
sampling arithmetic as :meth:`~pyroute_rel.weather.GriddedWeather.sample_at` (trilinear in the block's stored
float32 values, the wind turned into speed and direction as :func:`~pyroute_rel._kernels.sampling.speed_bearing`
does), the polar of :mod:`pyroute_rel._kernels.polar` and the failure model's evidence as
:func:`pyroute_rel._kernels.cost.evidence_index` classifies it; the same numbers as the numpy march (tested in
``tests/test_march.py``, which pins the two).

It covers sources whose fields the march needs (wind, and the fields the failure model judges) share one grid (one
block); :func:`pyroute_rel.routing.cost.geometry_costs` uses the numpy march for everything else.

Numpy twin: :func:`pyroute_rel.boat.march.march` (:attr:`~pyroute_rel.settings.Settings.compiled_march` False);
pinned by ``tests/test_dp_glue.py::test_compiled_bookkeeping_equals_the_numpy_path`` and the Monte Carlo tests there.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
import numpy.typing as npt

from pyroute_rel._kernels.cost import evidence_point, judge_tables, model_rules
from pyroute_rel._kernels.polar import fmax, fold_twa, speed_kn, tables
from pyroute_rel._kernels.sampling import axis_cell, lerp, speed_bearing
from pyroute_rel.boat.march import MIN_STEP_H, SPEED_CHANGE, SPEED_FLOOR_KN, Marched, SpeedNoise, step_hours
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar
from pyroute_rel.reliability.failure import FailureModel
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather.gridded import GriddedWeather, PreparedPoints

__all__ = ["KEPT_FIELDS", "march_gridded", "usable"]

FloatArray = npt.NDArray[np.float64]

#: The :class:`~pyroute_rel.weather.Conditions` fields the kernel reports at each sample (the last step's middle).
KEPT_FIELDS = ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s")

#: How the kernel gets each field: 0 the wind's speed, 1 its direction, 2 a stored column, 3 a direction stored as a
#: sine and a cosine (columns a and b).
_KIND = {"tws_kn": 0, "twd_deg": 1, "hs_m": 2, "wave_period_s": 2, "wave_dir_deg": 3}


def usable(weather: Any, failure: FailureModel | None, wind_only: bool) -> int | None:
    """The block of ``weather`` that holds every field the compiled march needs (its index), or None where it does not
    apply (not gridded, not wind only, or the fields on several grids)."""
    if not wind_only or not isinstance(weather, GriddedWeather) or weather.steady:
        return None
    need = {"wind_u_ms", "wind_v_ms"}
    if failure is not None:
        for name in failure.weather_fields:
            if name in ("tws_kn", "twd_deg"):
                continue
            if name not in weather.fields:
                return None
            need |= {"_wave_sin", "_wave_cos"} if name == "wave_dir_deg" else {name}
    for i, block in enumerate(weather._blocks):
        if need <= set(block.names):
            return i
    return None


def march_gridded(
    weather: GriddedWeather,
    block: int,
    prepared: PreparedPoints,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    t0_h: FloatArray,
    samples: int,
    *,
    departure: np.datetime64,
    polar: Polar,
    beyond: str,
    failure: FailureModel | None,
    apf: float,
    flags: tuple[int, int, int],
    wind_error_kn: tuple[FloatArray, FloatArray] | None = None,
    speed_noise: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[Marched, FloatArray]:
    """:func:`pyroute_rel.boat.march.march` of ``n`` arcs in a gridded weather, in one compiled loop.

    Parameters
    ----------
    weather, block : The source and its block holding every field needed (:func:`usable`).
    prepared : The arcs' sample points located by ``weather.prepare``, ``n * samples`` of them, arc by arc.
    course_deg : The great circle's course at each sample [deg], (n, samples).
    seg_nm, t0_h : Each arc's sub-segment length [nm] and departure [h after ``departure``], (n,).
    samples : Sub-segments per arc.
    departure, polar, beyond, failure, apf : The cost settings.
    flags : The reason bits of no speed, missing weather and a failure above apf.
    wind_error_kn : An error east and north added to the wind at each arc [kn], shape (n,) each, as
        :class:`~pyroute_rel.analysis.monte_carlo.PerturbedWind` adds it (the same arithmetic), or None.
    speed_noise : The gain and spread of a :class:`~pyroute_rel.boat.march.SpeedNoise` at each arc, shape (n,) each,
        applied to every speed taken (the same arithmetic), or None.

    Returns
    -------
    The arcs sailed, and the weather at each sample's last step middle (rows :data:`KEPT_FIELDS`, NaN where not
    sampled), shape (len(KEPT_FIELDS), n * samples).
    """
    b = weather._blocks[block]
    w = prepared.where[block]
    n = t0_h.size
    names = b.names
    col = {name: j for j, name in enumerate(names)}
    wanted = set() if failure is None else set(failure.weather_fields)
    kinds = np.full(len(KEPT_FIELDS), -1, dtype=np.intp)
    col_a = np.zeros(len(KEPT_FIELDS), dtype=np.intp)
    col_b = np.zeros(len(KEPT_FIELDS), dtype=np.intp)
    for r, name in enumerate(KEPT_FIELDS):
        if name in ("tws_kn", "twd_deg") or name in wanted:
            kinds[r] = _KIND[name]
            if kinds[r] == 2:
                col_a[r] = col[name]
            elif kinds[r] == 3:
                col_a[r], col_b[r] = col["_wave_sin"], col["_wave_cos"]
    if failure is None:
        edges = np.zeros((1, 1))
        contrib = np.zeros((1, 1), dtype=np.intp)
        n_edges = np.zeros(1, dtype=np.intp)
        right = np.zeros(1, dtype=np.bool_)
        fill = np.zeros(1, dtype=np.intp)
        source = np.zeros(0, dtype=np.intp)
        relative = np.zeros(0, dtype=np.bool_)
        p_flat, over, bits = np.zeros(1), np.zeros(1, dtype=np.bool_), np.zeros(1, dtype=np.uint32)
    else:
        edges, n_edges, contrib, right, fill, attrs, relative = model_rules(failure)
        source = np.array([KEPT_FIELDS.index(a) for a in attrs], dtype=np.intp)
        p_flat, over, bits = judge_tables(failure, apf)
    shift = (np.datetime64(departure, "ns") - b.t0) / np.timedelta64(1, "s")  # type: ignore[call-overload]  # numpy's stubs have no datetime64(datetime64, unit) overload
    steps_h = step_hours(weather.time_steps, departure)
    if steps_h is None:
        steps_h = np.zeros(0)
    twa_tab, tws_tab, speed_tab, twa_inv, tws_inv = tables(polar)
    field = (b.flat, np.int64(b.n_fields), b.time_s, float(shift), w.base, w.sx, w.sy, w.wx, w.wy, w.ok)
    cols = (np.int64(col["wind_u_ms"]), np.int64(col["wind_v_ms"]), kinds, col_a, col_b)
    pol = (twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, beyond == "forbid", MIN_SPEED_KN)
    model = (source, relative, edges, n_edges, contrib, right, fill, p_flat, over, bits)
    rule = (*(np.uint8(f) for f in flags), SPEED_CHANGE, SPEED_FLOOR_KN, MIN_STEP_H, KN_PER_MS)
    out = (np.empty(n), np.empty((n, samples + 1)), np.empty(n), np.zeros(n, np.uint8), np.zeros(n, np.uint32))
    kept = np.full((len(KEPT_FIELDS), n * samples), np.nan)
    arcs = (
        np.ascontiguousarray(course_deg, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(seg_nm, dtype=np.float64),
        np.ascontiguousarray(t0_h, dtype=np.float64),
        np.int64(samples),
        steps_h,
        *((np.zeros(0), np.zeros(0)) if wind_error_kn is None else wind_error_kn),
        *((np.zeros(0), np.zeros(0)) if speed_noise is None else speed_noise),
        SpeedNoise.FLOOR,
    )
    any_fired = _march_kernel(field, cols, pol, model, rule, arcs, out, kept)
    time_h, marks, p_f, reason, fired = out
    return Marched(time_h=time_h, marks_h=marks, p_f=p_f, reason=reason, fired=fired if any_fired else None), kept


@numba.njit(nogil=True, cache=True, inline="always")
def _time_cell(t_axis, t_first, t_inv, shift, nf, t_h):  # type: ignore[no-untyped-def]  # pragma: no cover
    """(inside, offset, step, weight): where time ``t_h`` [h] falls on the block's time axis, as the sampling kernel
    finds it: whether it is on the axis, the offset of its time index in the stored values (``index * nf``), the
    offset to the next time (0 at the last) and the next time's weight. No time axis: (True, 0, 0, 0.0)."""
    nt = t_axis.size
    if nt == 0:
        return True, np.uint64(0), np.uint64(0), 0.0
    x = t_h * 3600.0 + shift
    if not (t_axis[0] <= x <= t_axis[nt - 1]):
        return False, np.uint64(0), np.uint64(0), 0.0
    it, wt = axis_cell(t_axis, t_first, t_inv, x)
    return True, np.uint64(it * nf), np.uint64(nf) if wt > 0.0 else np.uint64(0), wt


@numba.njit(nogil=True, cache=True, inline="always")
def _column(flat, corners, weights, at, st, wt, c):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Stored column ``c`` at a point whose four corners (offsets) and weights are ``corners``, ``weights``, at the
    time cell ``at``, ``st``, ``wt`` (:func:`_time_cell`): the sampling kernel's trilinear arithmetic."""
    f = at + np.uint64(c)
    return lerp(
        flat,
        corners[0] + f,
        corners[1] + f,
        corners[2] + f,
        corners[3] + f,
        st,
        weights[0],
        weights[1],
        weights[2],
        weights[3],
        1.0 - wt,
        wt,
    )


@numba.njit(nogil=True, cache=True)
def _march_kernel(field, cols, pol, model, rule, arcs, out, kept):  # type: ignore[no-untyped-def]  # noqa: C901  # pragma: no cover
    """:func:`march_gridded` into ``out`` (time, marks, p_f, reason, fired) and ``kept``, arc after arc, sub-segment
    after sub-segment, step after step (:func:`pyroute_rel.boat.march.march`'s steps); returns whether any sample was
    judged above apf (fired criteria). One flat loop: split into helpers taking these tuples, numba compiled it 4x
    slower and ran it 2x slower (measured).

    What the numpy march computes and this loop does not (the same numbers): the sample point's corners and weights
    are found once per sub-segment, the time's cell once per time for every field, the speed at a step's start is
    not sampled again when a step is tried again shorter (the same time), and the fields the failure model judges
    are sampled only at the middle of a step that is taken (not one tried again)."""
    flat, nf, t_axis, shift, base, sx, sy, wx, wy, ok = field
    cu, cv, kinds, col_a, col_b = cols
    twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed = pol
    source, relative, edges, n_edges, contrib, right, fill, p_flat, over, bits = model
    polar_flag, weather_flag, failure_flag, speed_change, floor, min_step, kn = rule
    course, seg, t0, samples, steps_h, err_e, err_n, gain, spread, noise_floor = arcs
    time_out, marks_out, p_out, reason_out, fired_out = out
    n_steps = steps_h.size
    nt = t_axis.size
    t_first = t_axis[0] if nt > 0 else 0.0
    t_inv = (nt - 1) / (t_axis[nt - 1] - t_axis[0]) if nt > 1 else 1.0
    judged = source.size > 0
    no_progress = np.uint8(~(weather_flag | failure_flag) & 0xFF)
    vals = np.empty(kept.shape[0])
    judged_vals = np.empty(source.size)
    any_fired = False
    perturbed = err_e.size > 0
    noisy = gain.size > 0
    for i in range(t0.size):
        de = err_e[i] if perturbed else 0.0
        dn = err_n[i] if perturbed else 0.0
        g = gain[i] if noisy else 1.0
        c_noise = spread[i] if noisy else 0.0
        start = t0[i] if np.isfinite(t0[i]) else 0.0
        e = 0.0
        marks_out[i, 0] = start
        p_arc = 0.0
        flags_arc = np.uint8(0)
        fired_arc = np.uint32(0)
        going = True
        j = 0  # the first time step after the craft's time (times only increase along an arc)
        for k in range(samples):
            if not going:
                marks_out[i, k + 1] = start + e
                continue
            pk = i * samples + k
            # the sample point: its four corners and weights (the same for every step of the sub-segment)
            here = ok[pk]
            ax = wx[pk]
            ay = wy[pk]
            b00 = np.uint64(base[pk])
            b10 = b00 + np.uint64(sx[pk])
            b01 = b00 + np.uint64(sy[pk])
            b11 = b10 + np.uint64(sy[pk])
            corners = (b00, b10, b01, b11)
            weights = ((1.0 - ax) * (1.0 - ay), ax * (1.0 - ay), (1.0 - ax) * ay, ax * ay)
            crs = course[pk]
            r = seg[i]
            cap = np.inf
            t_pred = np.nan  # the time of the last predictor (a step tried again starts at the same time)
            v0 = np.nan
            r0 = np.uint8(0)
            while True:
                tk = start + e
                while j < n_steps and steps_h[j] <= tk:
                    j += 1
                nxt = steps_h[j] if j < n_steps else np.inf
                # predictor: the speed here and now (the wind only)
                if tk != t_pred:
                    wind0 = _wind(
                        flat,
                        corners,
                        weights,
                        here,
                        t_axis,
                        t_first,
                        t_inv,
                        shift,
                        nf,
                        tk,
                        cu,
                        cv,
                        kn,
                        perturbed,
                        de,
                        dn,
                    )
                    tws0, twd0 = wind0[0], wind0[1]
                    v0, r0 = _sog(tws0, twd0, crs, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed)
                    if noisy and v0 > 0.0:  # SpeedNoise.apply
                        v0 = max(g * v0 + c_noise * np.sqrt(v0), noise_floor * v0)
                    t_pred = tk
                hp = r / v0 if v0 > 0.0 else np.inf
                h = min(min(hp, (nxt if v0 < floor else np.inf) - tk), cap)
                cut = h < hp
                stuck = not np.isfinite(h)
                tm = tk if stuck else tk + 0.5 * h
                # corrector: the speed at the step's middle
                tws_m, twd_m, inside, at, st, wt = _wind(
                    flat, corners, weights, here, t_axis, t_first, t_inv, shift, nf, tm, cu, cv, kn, perturbed, de, dn
                )
                vm, rm = _sog(tws_m, twd_m, crs, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed)
                if noisy and vm > 0.0:  # SpeedNoise.apply
                    vm = max(g * vm + c_noise * np.sqrt(vm), noise_floor * vm)
                scale = max(fmax(vm, v0), floor)  # (max drops a NaN scale: then the comparison is False)
                rough = abs(vm - v0) > speed_change * scale and h > min_step and not stuck
                if rough:  # tried again with half the time, from the same start
                    cap = 0.5 * h
                    continue
                # a step taken: what the failure model says where and when the craft is
                vals[0] = tws_m
                vals[1] = twd_m
                _fields(flat, corners, weights, at, st, wt, inside, kinds, col_a, col_b, vals)
                for q in range(kinds.size):
                    kept[q, pk] = vals[q]
                pm = 0.0
                fm = np.uint32(0)
                if judged:
                    for c in range(source.size):
                        judged_vals[c] = vals[source[c]]
                    ev, lost = evidence_point(judged_vals, relative, crs, edges, n_edges, contrib, right, fill)
                    if lost:
                        pm = np.nan
                        rm |= weather_flag
                    else:
                        pm = p_flat[ev]
                        if over[ev]:
                            rm |= failure_flag
                            fm = bits[ev]
                missing = ((r0 | rm) & weather_flag) != 0
                moves = vm > 0.0
                done = moves and ((not cut) or vm * h >= r) and not missing and not stuck
                progress = vm * h if (cut and moves) else 0.0
                if not stuck:
                    if p_arc == p_arc and (pm != pm or pm > p_arc):  # np.maximum: NaN wins
                        p_arc = pm
                    flags_arc |= rm & failure_flag
                    if (rm & failure_flag) != 0:
                        fired_arc |= fm
                        any_fired = True
                wait_for_ever = (
                    (not done) and not missing and (stuck or ((not cut) and (not moves) and not np.isfinite(nxt)))
                )
                if missing:
                    flags_arc |= weather_flag
                if wait_for_ever:
                    why = (r0 if stuck else rm) & no_progress
                    flags_arc |= why if why != 0 else polar_flag
                if missing or wait_for_ever:
                    going = False
                    break
                if done:
                    e = e + r / vm
                    break
                e = e + h
                r = r - progress
                cap = 2.0 * cap if h >= cap else np.inf
            marks_out[i, k + 1] = start + e
        time_out[i] = e if (going and flags_arc == 0) else np.inf
        p_out[i] = p_arc
        reason_out[i] = flags_arc
        fired_out[i] = fired_arc
    return any_fired


@numba.njit(nogil=True, cache=True, inline="always")
def _wind(flat, corners, weights, here, t_axis, t_first, t_inv, shift, nf, t_h, cu, cv, kn, perturbed, de, dn):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The wind's speed [kn] and direction [deg] at a point (``here``: on the block) and time ``t_h`` [h], as the
    sampling kernel turns u and v (NaN outside), with the error east ``de`` and north ``dn`` [kn] added where
    ``perturbed`` (as :class:`~pyroute_rel.analysis.monte_carlo.PerturbedWind` adds it), and the time's cell (inside,
    offset, step, weight)."""
    inside, at, st, wt = _time_cell(t_axis, t_first, t_inv, shift, nf, t_h)
    inside = here and inside
    u = np.nan
    v = np.nan
    if inside:
        u = _column(flat, corners, weights, at, st, wt, cu)
        v = _column(flat, corners, weights, at, st, wt, cv)
    tws, twd = speed_bearing(-1.0 * u, -1.0 * v, kn)
    if perturbed:
        rad = math.radians(twd)
        ue = de - tws * math.sin(rad)  # the wind's velocity (to), east and north [kn]
        vn = dn - tws * math.cos(rad)
        tws = math.hypot(ue, vn)
        twd = math.degrees(math.atan2(-ue, -vn)) % 360.0
    return tws, twd, inside, at, st, wt


@numba.njit(nogil=True, cache=True, inline="always")
def _fields(flat, corners, weights, at, st, wt, inside, kinds, col_a, col_b, vals):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The fields :data:`KEPT_FIELDS` after the wind (rows 2 on) at a point and time cell into ``vals``: a stored
    column, a direction from its sine and cosine, NaN where not wanted (or outside the block)."""
    for q in range(2, kinds.size):
        kind = kinds[q]
        if not inside or kind < 2:
            vals[q] = np.nan
        elif kind == 2:
            vals[q] = _column(flat, corners, weights, at, st, wt, col_a[q])
        else:
            s_ = _column(flat, corners, weights, at, st, wt, col_a[q])
            c_ = _column(flat, corners, weights, at, st, wt, col_b[q])
            vals[q] = speed_bearing(s_, c_, 1.0)[1]


@numba.njit(nogil=True, cache=True, inline="always")
def _sog(tws, twd, course, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Speed along the course [kn] (0 below ``min_speed``, NaN where the wind is missing) and its flags (1 no speed,
    2 missing wind), as :func:`pyroute_rel.routing.cost._sample_speeds` gives them without a current."""
    v = speed_kn(fold_twa(twd, course), tws, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid)
    sog = v if v >= min_speed else (np.nan if v != v else 0.0)
    if not (np.isfinite(tws) and np.isfinite(twd)):
        return sog, np.uint8(2)
    if not sog > 0.0:
        return sog, np.uint8(1)
    return sog, np.uint8(0)
