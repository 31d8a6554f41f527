"""An independent continuous march of a track through time-varying weather: the reference of issue 32's tests.

A craft sails each leg of a track along its great circle, continuously: its position ``s`` along the leg [km] obeys
``ds/dt = V(s, t)``, ``V`` the polar speed [km/h] at the wind where and when the craft is, on the course the great
circle has there. The march integrates that with the explicit midpoint rule (a predictor step to the middle of the
step in space and time, then the whole step at the speed there), in steps of at most :data:`STEP_KM` along the leg
and at most :data:`STEP_H` in time. The time cap is what keeps a craft that crawls (near calm, in irons) from
borrowing a later wind: a step never looks further ahead than ``STEP_H``. Where the polar gives less than
:data:`~pyroute_rel.boat.polar.MIN_SPEED_KN` the craft makes no progress: it holds its position while time goes on,
until the wind lets it go.

It uses only the weather source's ``sample(lon, lat, time)`` (the interpolant of the data), the polar look-up
:func:`~pyroute_rel.boat.polar.boat_speed_kn` and the unit constants; the great-circle geometry is written out here with
numpy. Nothing of the product's arc costing (``cost``, ``crossings``, ``exposure``, ``evaluate``'s timing) is called.
No currents and no speed loss in waves: the tests' weather has no current and their scenarios no wave loss.

Legs are marched side by side (one lane each, vectorised over lanes) when they are independent, as the property
test's random legs are. A track's legs are marched one after the other, each leaving when the last arrived (or later,
when the route waits at the node); or, given a guess of the times, side by side until the legs' departures and
arrivals chain up (:func:`march_track`): the same marches, far fewer calls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pyroute_rel.boat.polar import MIN_SPEED_KN, boat_speed_kn
from pyroute_rel.units import EARTH_RADIUS_KM, KM_PER_NM

#: Longest step along a leg [km] (100 m).
STEP_KM = 0.1
#: Longest step in time [h] (3 min): how far ahead a crawling or held craft looks for its next wind.
STEP_H = 0.05
_NS_PER_H = 3.6e12


def _hours(departure: np.datetime64, time_h: np.ndarray) -> np.ndarray:
    """The instants ``time_h`` [h] after ``departure``, to the nanosecond."""
    return np.datetime64(departure, "ns") + np.round(np.asarray(time_h, float) * _NS_PER_H).astype("timedelta64[ns]")


def _xyz(lon_deg, lat_deg) -> np.ndarray:
    lon, lat = np.radians(np.asarray(lon_deg, float)), np.radians(np.asarray(lat_deg, float))
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


@dataclass(frozen=True)
class GreatCircles:
    """Great circles from ``a`` to ``b`` (one per lane): ``p(theta) = a cos(theta) + u sin(theta)``, ``u`` the unit
    vector at right angles to ``a`` towards ``b``, ``theta`` in [0, omega]."""

    a: np.ndarray  # (n, 3)
    u: np.ndarray  # (n, 3)
    length_km: np.ndarray  # (n,)

    @classmethod
    def of(cls, lon0, lat0, lon1, lat1) -> GreatCircles:
        a, b = np.broadcast_arrays(_xyz(lon0, lat0).reshape(-1, 3), _xyz(lon1, lat1).reshape(-1, 3))
        omega = np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))
        u = b - a * np.cos(omega)[:, None]
        norm = np.linalg.norm(u, axis=-1, keepdims=True)
        u = np.divide(u, norm, out=np.zeros_like(u), where=norm > 0.0)  # a leg of no length is never sailed
        return cls(a=a, u=u, length_km=omega * EARTH_RADIUS_KM)

    def at(self, s_km: np.ndarray, lanes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (lon, lat [deg]) and course (the great circle's, clockwise from north [deg]) of lanes ``lanes``
        at ``s_km`` along their legs."""
        theta = (s_km / EARTH_RADIUS_KM)[:, None]
        a, u = self.a[lanes], self.u[lanes]
        p = a * np.cos(theta) + u * np.sin(theta)
        v = u * np.cos(theta) - a * np.sin(theta)  # the direction of travel (unit tangent)
        lon = np.arctan2(p[:, 1], p[:, 0])
        lat = np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1]))
        east = -np.sin(lon) * v[:, 0] + np.cos(lon) * v[:, 1]
        north = -np.sin(lat) * (np.cos(lon) * v[:, 0] + np.sin(lon) * v[:, 1]) + np.cos(lat) * v[:, 2]
        return np.degrees(lon), np.degrees(lat), np.degrees(np.arctan2(east, north)) % 360.0


def twa_deg(twd_deg, course_deg) -> np.ndarray:
    """True wind angle [deg] in [0, 180]: the angle between where the wind comes from and the course."""
    return np.abs((np.asarray(twd_deg, float) - np.asarray(course_deg, float) + 180.0) % 360.0 - 180.0)


@dataclass(frozen=True)
class Sailor:
    """What the march needs: the weather (its ``sample``), the departure the times count from, the polar and its
    ``beyond`` setting."""

    weather: object
    departure: np.datetime64
    polar: object
    beyond: str = "clamp"

    def speed_kmh(self, lon, lat, course, time_h) -> np.ndarray:
        """Speed along the course [km/h]: the polar's at the wind there and then, 0 below ``MIN_SPEED_KN`` (no
        progress), NaN where the weather is missing."""
        c = self.weather.sample(lon, lat, _hours(self.departure, time_h))
        kn = boat_speed_kn(self.polar, twa_deg(c.twd_deg, course), c.tws_kn, beyond=self.beyond)  # NaN in, NaN out
        return np.where(kn < MIN_SPEED_KN, 0.0, kn) * KM_PER_NM


@dataclass(frozen=True)
class Path:
    """Where the march went: the start of every step and each leg's end, with the time there [h after departure]
    and the course [deg]; ``lane`` says whose step it was."""

    lon_deg: np.ndarray
    lat_deg: np.ndarray
    time_h: np.ndarray
    course_deg: np.ndarray
    lane: np.ndarray


def march_legs(sailor: Sailor, lon0, lat0, lon1, lat1, start_h, *, record: bool = False):
    """Sail independent legs side by side, each from ``(lon0, lat0)`` at ``start_h`` [h after departure] to
    ``(lon1, lat1)``.

    Returns the arrival time of each leg [h after departure] (inf where the weather runs out on the way), and with
    ``record`` the :class:`Path` sailed.
    """
    gc = GreatCircles.of(lon0, lat0, lon1, lat1)
    n = gc.length_km.size
    s = np.zeros(n)
    t = np.broadcast_to(np.asarray(start_h, float), (n,)).copy()
    arrival = np.full(n, np.inf)
    live = np.flatnonzero(gc.length_km > 0.0)
    arrival[gc.length_km <= 0.0] = t[gc.length_km <= 0.0]
    seen: list[tuple[np.ndarray, ...]] = []
    while live.size:
        lon, lat, course = gc.at(s[live], live)
        if record:
            seen.append((lon, lat, t[live].copy(), course, live))
        k1 = sailor.speed_kmh(lon, lat, course, t[live])  # predictor: the speed here and now
        lost = np.isnan(k1)  # no weather here and now: the leg cannot be finished
        k1[lost] = 0.0
        h = np.minimum(STEP_H, STEP_KM / np.maximum(k1, 1e-300))  # at most 100 m at that speed, at most 3 min
        k2 = _midpoint_speed(sailor, gc, live, s, t, k1, h)
        fast = k2 * h > STEP_KM  # the wind picked up within the step: shorten it to 100 m at the faster speed
        if fast.any():
            h[fast] = STEP_KM / k2[fast]
            k2[fast] = _midpoint_speed(sailor, gc, live[fast], s, t, k1[fast], h[fast])
        lost |= np.isnan(k2)
        step = np.where(lost, 0.0, k2 * h)
        left = gc.length_km[live] - s[live]
        done = ~lost & (step >= left)
        if done.any():  # the last step, part of a whole one: timed again at the middle of that part
            d = live[done]
            part = left[done] / k2[done]
            k3 = _midpoint_speed(sailor, gc, d, s, t, k1[done], part)
            arrival[d] = t[d] + left[done] / np.where(k3 > 0.0, k3, k2[done])
        s[live] += step
        t[live] += h
        live = live[~done & ~lost]
    if not record:
        return arrival
    ends = np.flatnonzero(np.isfinite(arrival))  # the legs finished, at their ends
    lon_e, lat_e, course_e = gc.at(gc.length_km[ends], ends)
    seen.append((lon_e, lat_e, arrival[ends], course_e, ends))
    cols = [np.concatenate(c) for c in zip(*seen, strict=True)]
    return arrival, Path(*cols)


def _midpoint_speed(sailor: Sailor, gc: GreatCircles, lanes, s, t, k1, h) -> np.ndarray:
    """The corrector: the speed at the step's middle in space and time, reached at the predictor's speed ``k1``
    (capped at the leg's end)."""
    mid = np.minimum(s[lanes] + 0.5 * k1 * h, gc.length_km[lanes])
    lon, lat, course = gc.at(mid, lanes)
    return sailor.speed_kmh(lon, lat, course, t[lanes] + 0.5 * h)


def march_track(sailor: Sailor, lon_deg, lat_deg, *, leave_h=None, guess_h=None, record: bool = False):
    """Sail a track's legs one after the other from time 0 (the departure).

    ``leave_h`` (optional, one per leg): the earliest time each leg may leave [h after departure], where the route
    waits at its start node; a leg leaves when the last arrived or then, whichever is later. Returns the time at
    each point of the track [h after departure] (inf from the first leg the weather does not let it finish), and
    with ``record`` the :class:`Path` of every leg joined, in the track's order.

    With ``guess_h`` (a guess of the time at each point, e.g. a route's), the legs are marched side by side instead
    (:func:`_chain`): the same chain of marches, each leg leaving within ``CHAIN_TOL_H`` of the last one's arrival.
    """
    lon, lat = np.asarray(lon_deg, float), np.asarray(lat_deg, float)
    n = lon.size - 1
    earliest = np.full(n, -np.inf) if leave_h is None else np.asarray(leave_h, float)
    if guess_h is not None:
        leave, arrival = _chain(sailor, lon, lat, earliest, np.asarray(guess_h, float)[:n])
    else:  # one leg after the other: each leaves when the last arrived
        leave, arrival = np.full(n, np.inf), np.full(n, np.inf)
        for i in range(n):
            leave[i] = max(0.0 if i == 0 else arrival[i - 1], earliest[i])
            arrival[i] = march_legs(sailor, lon[i], lat[i], lon[i + 1], lat[i + 1], leave[i])[0]
            if not np.isfinite(arrival[i]):
                break
    times = np.concatenate([[0.0], arrival])
    if not record:
        return times
    ok = np.isfinite(leave)  # the legs again, side by side, to record them
    _, path = march_legs(sailor, lon[:-1][ok], lat[:-1][ok], lon[1:][ok], lat[1:][ok], leave[ok], record=True)
    order = np.lexsort((path.time_h, path.lane))  # leg by leg, each in time
    return times, Path(*(a[order] for a in vars(path).values()))


#: How far a leg marched side by side may leave from the arrival of the leg before it [h].
CHAIN_TOL_H = 1e-7


def _chain(sailor: Sailor, lon, lat, earliest, guess, passes: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Departure and arrival of each leg [h] such that each leaves when the one before arrives (or at ``earliest``),
    found by marching every leg side by side: from guessed departures first, then from the chain of arrivals those
    marches give, each leg's arrival extrapolated linearly in its departure (the slope of its last two marches, 1 at
    first) where the departure before it moved, until every leg leaves within ``CHAIN_TOL_H`` of that arrival. The
    legs are then the sequential march's: only the last pass's marches count, and they are consistent."""
    n = lon.size - 1
    depart = np.maximum(np.where(np.isfinite(guess), guess, 0.0), earliest)
    depart[0] = max(0.0, earliest[0])
    arrive = march_legs(sailor, lon[:-1], lat[:-1], lon[1:], lat[1:], depart)
    slope = np.ones(n)
    for _ in range(passes):
        stuck = np.flatnonzero(~np.isfinite(arrive))
        last = n - 1 if stuck.size == 0 else int(stuck[0])  # legs after the first unfinished one are not sailed
        want = np.maximum(arrive[:last], earliest[1 : last + 1])
        if np.all(np.abs(want - depart[1 : last + 1]) <= CHAIN_TOL_H):
            depart[last + 1 :], arrive[last + 1 :] = np.inf, np.inf
            return depart, arrive
        new = depart.copy()
        for i in range(1, last + 1):  # the chain, each arrival extrapolated to its leg's new departure
            new[i] = max(earliest[i], arrive[i - 1] + slope[i - 1] * (new[i - 1] - depart[i - 1]))
        moved = np.flatnonzero(new[: last + 1] != depart[: last + 1])
        again = march_legs(sailor, lon[moved], lat[moved], lon[moved + 1], lat[moved + 1], new[moved])
        step = new[moved] - depart[moved]
        fine = np.isfinite(again) & np.isfinite(arrive[moved]) & (np.abs(step) > 1e-9)
        slope[moved[fine]] = np.clip((again - arrive[moved])[fine] / step[fine], 0.0, 10.0)  # FIFO: never < 0
        depart[moved], arrive[moved] = new[moved], again
    raise AssertionError(f"the legs' chain did not settle in {passes} passes")


def route_leave_h(route) -> np.ndarray:
    """When the route has each leg leave [h after departure], for :func:`march_track`: the time at its start node
    plus its wait there. In continuous time only legs after a wait are held (``-inf`` elsewhere: the march leaves
    when it arrives, so a route that reports its nodes late is not excused); on the time lattice of the time-expanded
    DP every node time is a lattice time the craft waits for (the DP rounds arrivals up to the lattice)."""
    leave = np.asarray(route.elapsed_h, float)[:-1] + np.asarray(route.legs.wait_h, float)
    if route.problem.time_step_h is None:
        leave = np.where(np.asarray(route.legs.wait_h, float) > 0.0, leave, -np.inf)
    return leave
