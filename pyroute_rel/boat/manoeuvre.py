"""Tacks and gybes: the side of the wind each arc is sailed on, which change of side is which manoeuvre, and the
time a manoeuvre costs.

The side
    An arc is sailed on **starboard** when the true wind comes over the starboard side, i.e. the wind direction
    (from) lies clockwise of the course by ``[0, 180)`` degrees, and on **port** otherwise (``[180, 360)``). The
    angle is taken where the cost kernel takes the arc's first weather sample (the midpoint of its first
    sub-segment) with the course of the great circle there, at the arc's departure time. Dead upwind counts as
    starboard and dead downwind as port (a convention: the DP gives such arcs no speed or a side like any other).
    With currents the side is that of the course over ground (the crab angle is left out).

The manoeuvre
    When the side of an arc differs from the side of the arc before it, the craft manoeuvres at the node between
    them. It is a **tack** when the new arc is upwind of the beam (``|TWA| < 90`` deg) and a **gybe** when it is
    on the beam or downwind of it (``|TWA| >= 90`` deg). So a change between two upwind arcs is a tack, between two
    downwind arcs a gybe, and when one of the two arcs is on the beam or on the other point of sail, the new arc
    decides. Deciding by the new arc alone keeps the DP's label (node, side) -- the state the issue asks for, and
    Tagliaferri's and Vanderbei's DPs keep -- sufficient: the cost of an arc depends on its source label and on the
    arc only, so the DP stays exact on the enlarged graph.

The time
    A manoeuvre costs ``tack_penalty_s`` or ``gybe_penalty_s`` of the boat's table (``[boat] tack_penalty_s =
    [[tws_kn, s], ...]``), linear in the true wind speed of the new arc (its first sample), constant beyond the
    table's ends. The DP adds it to the arc's arrival (the arc is sailed with the weather at its departure, as
    without manoeuvres), so on the time lattice the arrival ``(t0 + sail) + penalty`` is rounded up as a whole.
    The first arc of a voyage starts on either side at no cost; on a course through waypoints each leg starts on
    the side the previous leg ended on.

References
----------
Tagliaferri, F. (2015). Dynamic programming for sailing strategy with uncertainty. University of Edinburgh (a tack
costs about 20 s at 10 m/s of wind and 30 s at 5 m/s).
Vanderbei, R. J. Sailing strategies: an application involving stochastics, optimization, and statistics (the
state of the DP is (location, previous tack)).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel.errors import ScenarioError, brief, check_instance

__all__ = [
    "PORT",
    "STARBOARD",
    "NO_MANOEUVRE",
    "TACK",
    "GYBE",
    "KIND_NAMES",
    "SIDE_NAMES",
    "ManoeuvrePenalties",
    "wind_side",
    "manoeuvre_kind",
    "TrackManoeuvres",
    "track_manoeuvres",
    "charge_manoeuvres",
]

FloatArray = npt.NDArray[np.float64]

#: Sides of the wind (the label's second component in the DP).
PORT, STARBOARD = 0, 1
#: Manoeuvre kinds.
NO_MANOEUVRE, TACK, GYBE = 0, 1, 2
#: Names of the sides and kinds, for outputs.
SIDE_NAMES = ("port", "starboard")
KIND_NAMES = ("", "tack", "gybe")


def _table(raw: Any, where: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A penalty table ``[[tws_kn, s], ...]`` read into (wind speeds [kn], penalties [s]); checked."""
    try:
        rows = [tuple(r) for r in raw]
    except TypeError:
        rows = []
    if not rows or not all(len(r) == 2 for r in rows):
        raise ScenarioError(f"{where} must be a list of [tws_kn, seconds] pairs (got {raw!r})")
    tws, sec = [], []
    for a, b in rows:
        for v in (a, b):
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating) or not np.isfinite(v):
                raise ScenarioError(f"{where} must hold finite numbers (got {raw!r})")
        tws.append(float(a))
        sec.append(float(b))
    if any(b <= a for a, b in zip(tws[:-1], tws[1:], strict=True)) or tws[0] < 0.0:
        raise ScenarioError(f"{where}: wind speeds must be >= 0 [kn] and increase (got {tws})")
    if any(s < 0.0 or s > 86400.0 for s in sec):
        raise ScenarioError(f"{where}: penalties must be in [0, 86400] [s] (got {sec})")
    return tuple(tws), tuple(sec)


@dataclass(frozen=True)
class ManoeuvrePenalties:
    """Time lost by a tack and by a gybe, as tables of true wind speed [kn] against seconds [s].

    Parameters
    ----------
    tack_s, gybe_s : ``[[tws_kn, s], ...]`` (wind speeds increasing), linear in between and constant beyond the
        ends; None: no penalty.

    Examples
    --------
    >>> p = ManoeuvrePenalties(tack_s=[[9.72, 30.0], [19.44, 20.0]])  # Tagliaferri: 5 m/s -> 30 s, 10 m/s -> 20 s
    >>> p.penalty_h(np.array([TACK, TACK, GYBE]), np.array([5.0, 14.58, 14.58])).round(6).tolist()
    [0.008333, 0.006944, 0.0]
    """

    tack_tws_kn: tuple[float, ...] = (0.0,)
    tack_penalty_s: tuple[float, ...] = (0.0,)
    gybe_tws_kn: tuple[float, ...] = (0.0,)
    gybe_penalty_s: tuple[float, ...] = (0.0,)

    def __init__(self, tack_s: Any = None, gybe_s: Any = None, *, where: str = "[boat]") -> None:
        check_instance(where, str, "ManoeuvrePenalties where", ScenarioError, expected="a str (the table's name)")
        for name, raw in (("tack", tack_s), ("gybe", gybe_s)):
            tws, sec = ((0.0,), (0.0,)) if raw is None else _table(raw, f"{where}.{name}_penalty_s")
            object.__setattr__(self, f"{name}_tws_kn", tws)
            object.__setattr__(self, f"{name}_penalty_s", sec)

    @property
    def active(self) -> bool:
        """True when any manoeuvre costs time (the DP then keeps the side as state)."""
        return any(self.tack_penalty_s) or any(self.gybe_penalty_s)

    def penalty_h(self, kind: npt.ArrayLike, tws_kn: npt.ArrayLike) -> FloatArray:
        """Time lost [h] by manoeuvres of the given kinds (:data:`TACK`, :data:`GYBE`, or none: 0) in wind of
        ``tws_kn`` [kn] (NaN wind: 0, the arc is forbidden anyway)."""
        kind = np.asarray(kind)
        tack, gybe = self.tables_h(tws_kn)
        return np.asarray(np.where(kind == TACK, tack, np.where(kind == GYBE, gybe, 0.0)), dtype=float)

    def tables_h(self, tws_kn: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Time a tack and a gybe would cost [h] in wind of ``tws_kn`` [kn] (NaN wind: 0)."""
        try:
            tws = np.asarray(tws_kn, dtype=float)
        except (TypeError, ValueError):  # the only check: the DP calls this every rank with its own arrays
            raise ScenarioError(f"tws_kn must be wind speeds [kn] (got {brief(tws_kn)})") from None
        safe = np.where(np.isfinite(tws), tws, 0.0)
        tack = np.interp(safe, self.tack_tws_kn, self.tack_penalty_s) / 3600.0
        gybe = np.interp(safe, self.gybe_tws_kn, self.gybe_penalty_s) / 3600.0
        return np.asarray(tack, dtype=float), np.asarray(gybe, dtype=float)

    def describe(self) -> dict[str, list[list[float]]]:
        """The tables as ``{"tack_penalty_s": [[tws_kn, s], ...], "gybe_penalty_s": ...}`` (JSON)."""
        return {
            "tack_penalty_s": [[a, b] for a, b in zip(self.tack_tws_kn, self.tack_penalty_s, strict=True)],
            "gybe_penalty_s": [[a, b] for a, b in zip(self.gybe_tws_kn, self.gybe_penalty_s, strict=True)],
        }


def wind_side(twd_deg: npt.ArrayLike, course_deg: npt.ArrayLike) -> tuple[npt.NDArray[np.int8], FloatArray]:
    """The side each course is sailed on (:data:`PORT` or :data:`STARBOARD`) and the true wind angle [deg] in
    [0, 180], for wind from ``twd_deg`` [deg] (NaN wind: starboard, angle NaN).

    >>> side, twa = wind_side([0.0, 0.0, 0.0], [90.0, 270.0, 180.0])
    >>> side.tolist(), twa.tolist()
    ([0, 1, 0], [90.0, 90.0, 180.0])
    """
    rel = np.mod(np.asarray(twd_deg, dtype=float) - np.asarray(course_deg, dtype=float), 360.0)
    side = np.where(rel < 180.0, STARBOARD, PORT).astype(np.int8)
    side[np.isnan(rel)] = STARBOARD
    return side, np.minimum(rel, 360.0 - rel)


def manoeuvre_kind(twa_deg: npt.ArrayLike) -> npt.NDArray[np.int8]:
    """The manoeuvre that puts the craft on an arc of true wind angle ``twa_deg`` [deg] from the other side:
    :data:`TACK` upwind of the beam, :data:`GYBE` on the beam or downwind of it."""
    return np.where(np.asarray(twa_deg, dtype=float) < 90.0, TACK, GYBE).astype(np.int8)


@dataclass(frozen=True)
class TrackManoeuvres:
    """The manoeuvres along a track, one value per leg.

    Attributes
    ----------
    side : Side of each leg (:data:`PORT`, :data:`STARBOARD`).
    kind : Manoeuvre at each leg's start (:data:`NO_MANOEUVRE`, :data:`TACK`, :data:`GYBE`).
    penalty_h : Time it costs [h].
    """

    side: npt.NDArray[np.int8]
    kind: npt.NDArray[np.int8]
    penalty_h: FloatArray

    @property
    def tacks(self) -> int:
        """Number of tacks."""
        return int(np.count_nonzero(self.kind == TACK))

    @property
    def gybes(self) -> int:
        """Number of gybes."""
        return int(np.count_nonzero(self.kind == GYBE))

    def summary(self) -> dict[str, Any]:
        """``{"tacks", "gybes", "penalty_h"}`` (the route's JSON)."""
        return {"tacks": self.tacks, "gybes": self.gybes, "penalty_h": float(np.sum(self.penalty_h))}


def track_manoeuvres(
    side: Sequence[int] | npt.ArrayLike,
    twa_deg: npt.ArrayLike,
    tws_kn: npt.ArrayLike,
    penalties: ManoeuvrePenalties | None,
    *,
    initial_side: int | None = None,
) -> TrackManoeuvres:
    """The manoeuvres of a track from the side, true wind angle [deg] and wind speed [kn] of each leg (at the legs'
    first weather sample); ``initial_side``: the side the track starts on (None: either, at no cost).

    >>> m = track_manoeuvres([1, 0, 0, 1], [45.0, 45.0, 150.0, 150.0], [15.0] * 4, None)
    >>> m.kind.tolist(), m.tacks, m.gybes
    ([0, 1, 0, 2], 1, 1)
    """
    s = np.asarray(side, dtype=np.int8)
    prev = np.concatenate([[s[0] if initial_side is None else initial_side], s[:-1]]) if s.size else s
    kind, pen = charge_manoeuvres(s, twa_deg, tws_kn, prev, penalties)
    return TrackManoeuvres(side=s, kind=kind, penalty_h=pen)


def charge_manoeuvres(
    side: npt.ArrayLike,
    twa_deg: npt.ArrayLike,
    tws_kn: npt.ArrayLike,
    prev_side: npt.ArrayLike,
    penalties: ManoeuvrePenalties | None,
) -> tuple[npt.NDArray[np.int8], FloatArray]:
    """The manoeuvre at the start of legs on ``side`` (true wind angle [deg] and wind speed [kn] at their first
    weather sample) after legs on ``prev_side`` (-1: none, or either side at no cost), and the time it costs [h]
    (zero without ``penalties``). Element by element: legs of many tracks at once, or one leg of each.

    >>> kind, pen = charge_manoeuvres([1, 0, 0], [45.0, 45.0, 150.0], [15.0] * 3, [-1, 1, 1], None)
    >>> kind.tolist(), pen.tolist()
    ([0, 1, 2], [0.0, 0.0, 0.0])
    """
    s = np.asarray(side)
    prev = np.asarray(prev_side)
    kind = np.where((prev >= 0) & (s != prev), manoeuvre_kind(twa_deg), NO_MANOEUVRE).astype(np.int8)
    pen = (penalties or ManoeuvrePenalties()).penalty_h(kind, tws_kn)
    return kind, np.asarray(pen, dtype=float)
