"""Arc cost: the paper's Algorithm 1, vectorised over every arc into one rank.

For each arc (a great-circle segment between two nodes) and a departure time:

1. the arc is split into ``samples`` equal sub-segments; wind, waves and current are sampled at each
   sub-segment's midpoint, with the heading the great circle has there;
2. quantities the failure model needs (Hs, apparent wave direction, TWS, TWA, wave period) give the
   failure probability ``p_f`` of each sample; the arc's ``p_f`` is the largest along it;
3. the arc is **forbidden** (infinite time) when ``p_f > apf`` (so ``apf = 1`` accepts any risk and
   ``apf = 0`` only risk-free arcs), when the polar gives no speed, when the weather is missing (NaN)
   anywhere along it, or when the current makes the course impossible to hold;
4. otherwise its time [h] is the sum over sub-segments of length [nm] / speed over ground [kn].

Time along an arc: with steady weather (``weather.steady``) every sample uses the departure time. With
time-varying weather each sample is taken at the time the craft reaches it, found in two passes: the
sub-segments are timed with the speeds at the departure time, then every sample is taken at the departure
time plus the time to sail to it at those speeds (the failure model only acts in the second pass; a
sub-segment the first pass cannot time, no speed or missing weather, leaves its later samples at the
departure time).

Currents (the water's velocity *to*, east/north [m/s]) add to the boat's velocity through the water.
The boat heads off the course by the angle that cancels the cross-course current,
``sin(heading - course) = -c_cross / v``, and makes good ``v cos(heading - course) + c_along`` over the
ground; the polar speed ``v`` is taken at the corrected heading (one fixed-point step). An arc whose
cross current exceeds the boat speed, or whose speed made good is not positive, is forbidden.

References
----------
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft,
Algorithm 1. Proc. International Robotic Sailing Conference 2018.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING, Any, overload

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.boat.crab import steer
from pyroute_rel.boat.march import Marched, SpeedNoise, Step, march, step_hours
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar, boat_speed_kn
from pyroute_rel.errors import ScenarioError
from pyroute_rel.reliability.crossings import arc_extremes, needs_pieces
from pyroute_rel.reliability.failure import FailureModel, arc_quantities
from pyroute_rel.resources import default_workers, row_blocks, thread_map
from pyroute_rel.settings import get_settings
from pyroute_rel.store import kept_by
from pyroute_rel.weather.base import Conditions, WeatherSource

if TYPE_CHECKING:
    from pyroute_rel.weather.gridded import GriddedWeather, PreparedPoints

__all__ = [
    "ArcCosts",
    "ArcGeometry",
    "WaveLoss",
    "arc_geometry",
    "geometry_from_xyz",
    "arc_costs",
    "geometry_costs",
    "deferred_costs",
    "PendingPieces",
    "REASONS",
]


#: Bit flags saying why an arc is forbidden.
REASONS: dict[str, int] = {
    "polar": 1,  # the polar gives no speed (in irons, or outside the table with beyond="forbid")
    "weather": 2,  # wind or a field the failure model needs is NaN (land cell, outside the data)
    "failure": 4,  # p_f > apf
    "current": 8,  # the current makes the course impossible to hold
    "obstacle": 16,  # land, coastal margin or exclusion zone
}

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ArcCosts:
    """Costs of a block of arcs; every array has the block's shape.

    Attributes
    ----------
    time_h : Time to sail the arc [h]; ``inf`` where forbidden.
    p_f : Largest failure probability along the arc, judged on every piece it crosses
        (:mod:`pyroute_rel.reliability.crossings`; an arc its samples already forbid keeps their largest; 0 without a
        failure model; NaN where weather is missing).
    reason : Bit flags of :data:`REASONS` (0 where the arc is allowed).
    fired_bits : With a failure model and some arc it forbids: bit ``c`` is set where criterion ``c`` of the
        model fired somewhere along the arc (read it where ``reason`` has the failure flag); None otherwise.
    marks_h : With time-varying weather, the time the craft reaches each sub-segment end [h after the departure
        origin], shape (..., samples + 1) (:attr:`pyroute_rel.boat.march.Marched.marks_h`); None with steady weather
        (the time along an arc is then its departure plus its share of the arc's time).
    """

    time_h: FloatArray
    p_f: FloatArray
    reason: npt.NDArray[np.uint8]
    fired_bits: npt.NDArray[np.uint32] | None = None
    marks_h: FloatArray | None = None

    def bits(self) -> npt.NDArray[np.uint32]:
        """:attr:`fired_bits` with the block's shape (zeros when there are none)."""
        if self.fired_bits is None:
            return np.zeros(self.time_h.shape, np.uint32)
        return np.broadcast_to(self.fired_bits, self.time_h.shape)


@dataclass(frozen=True)
class WaveLoss:
    """Speed loss in waves: the polar speed is multiplied by ``factor(Hs)``, linear between table points.

    ``hs_m`` [m] strictly increasing from 0; ``factor`` [-] in [0, 1]. Beyond the last point the last factor
    holds. NaN Hs gives NaN speed (the arc is forbidden as missing weather).

    >>> WaveLoss(hs_m=(0.0, 2.0, 6.0), factor=(1.0, 0.9, 0.0)).factor(np.array([1.0, 4.0, 8.0])).tolist()
    [0.95, 0.45, 0.0]
    """

    hs_m: tuple[float, ...]
    factor_: tuple[float, ...]

    def __init__(self, hs_m: Any, factor: Any) -> None:
        h = tuple(float(v) for v in hs_m)
        f = tuple(float(v) for v in factor)
        if len(h) != len(f) or len(h) < 1:
            raise ValueError(f"wave speed loss needs as many factors as Hs values (got {len(h)} and {len(f)})")
        if h[0] != 0.0 or any(b <= a for a, b in zip(h[:-1], h[1:], strict=True)):
            raise ValueError(f"wave speed loss Hs values must start at 0 and increase (got {list(h)})")
        if not all(0.0 <= v <= 1.0 for v in f):
            raise ValueError(f"wave speed loss factors must be in [0, 1] (got {list(f)})")
        object.__setattr__(self, "hs_m", h)
        object.__setattr__(self, "factor_", f)

    def factor(self, hs_m: npt.ArrayLike) -> FloatArray:
        """Speed factor [-] at significant wave heights [m]."""
        hs = np.asarray(hs_m, dtype=float)
        out = np.interp(hs, self.hs_m, self.factor_)
        return np.where(np.isnan(hs), np.nan, out)


@dataclass(frozen=True)
class ArcGeometry:
    """Where and on which course each arc is sampled; depends only on the grid (cache it).

    Attributes
    ----------
    lon_deg, lat_deg : Sample points (sub-segment midpoints) [deg], shape (..., samples).
    course_deg : Great-circle course at each sample point [deg], shape (..., samples).
    seg_nm : Length of each sub-segment [nm], shape (..., 1).
    a_xyz, b_xyz : Unit vectors of the arcs' ends, shape (..., 3) (broadcast to the block), or None: then the arcs
        are judged at their samples only, not on every piece they cross (:mod:`pyroute_rel.reliability.crossings`).

    The arrays are never written to: the cost kernel keeps, with the geometry, its sample points located on the
    weather grids it was costed on (see :attr:`~pyroute_rel.settings.Settings.locate_cache`).
    """

    lon_deg: FloatArray
    lat_deg: FloatArray
    course_deg: FloatArray
    seg_nm: FloatArray
    a_xyz: FloatArray | None = None
    b_xyz: FloatArray | None = None
    #: The sample points located on weather grids (``weather.prepare``), most recent first (:func:`_located`).
    _located: list[Any] = field(default_factory=list, init=False, compare=False, repr=False)
    #: The geometry split between threads, per number of parts (:func:`_threaded_costs`).
    _parts: dict[int, list[ArcGeometry]] = field(default_factory=dict, init=False, compare=False, repr=False)

    def __getstate__(self) -> dict[str, Any]:
        """Pickled (and copied) without the points located on weather grids: they are a cache."""
        return {**self.__dict__, "_located": [], "_parts": {}}

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the block of arcs (without the samples axis)."""
        return tuple(self.lon_deg.shape[:-1])

    @property
    def samples(self) -> int:
        """Sub-segments per arc."""
        return int(self.lon_deg.shape[-1])


def arc_geometry(
    lon0_deg: npt.ArrayLike,
    lat0_deg: npt.ArrayLike,
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    *,
    samples: int = 1,
) -> ArcGeometry:
    """Sample points, courses and sub-segment lengths of great-circle arcs (broadcast over the inputs).

    >>> g = arc_geometry(0.0, 0.0, 2.0, 0.0, samples=2)
    >>> g.lon_deg.round(6).tolist(), g.course_deg.round(6).tolist(), round(float(g.seg_nm[0]), 3)
    ([0.5, 1.5], [90.0, 90.0], 60.04)
    """
    a = geodesy.to_xyz(lon0_deg, lat0_deg)
    b = geodesy.to_xyz(lon1_deg, lat1_deg)
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 1:
        raise ScenarioError(f"samples must be a whole number >= 1 (sub-segments per arc) (got {samples!r})")
    return geometry_from_xyz(a, b, samples=samples)


def geometry_from_xyz(
    a_xyz: FloatArray, b_xyz: FloatArray, *, samples: int = 1, workers: int | None = 1
) -> ArcGeometry:
    """:func:`arc_geometry` from unit vectors of the end points (shape (..., 3), broadcast together).

    Sample points by repeated halving of the arc (``samples`` a power of two) or spherical linear interpolation;
    the course at a point p towards b is
    ``atan2(b . east(p), b . north(p))``; the arc length is the central angle times the Earth radius.
    ``workers`` > 1 (None: :func:`~pyroute_rel.resources.default_workers`) splits a large block along its first
    axis between threads (trigonometry on arrays releases the GIL); every arc's numbers are the same either way.
    """
    a, b = np.broadcast_arrays(a_xyz, b_xyz)
    # kept as given where they have the full shape (a writable array, not a view flagged by broadcast_arrays)
    keep_a = a_xyz if isinstance(a_xyz, np.ndarray) and a_xyz.shape == a.shape else a
    keep_b = b_xyz if isinstance(b_xyz, np.ndarray) and b_xyz.shape == b.shape else b
    n = default_workers() if workers is None else int(workers)
    if n > 1 and a.ndim > 1 and a.size // 3 * samples >= PARALLEL_MIN_ARCS:
        parts = thread_map(
            lambda rows: geometry_from_xyz(a[rows], b[rows], samples=samples, workers=1), row_blocks(a.shape[0], n), n
        )
        return ArcGeometry(
            lon_deg=np.concatenate([g.lon_deg for g in parts]),
            lat_deg=np.concatenate([g.lat_deg for g in parts]),
            course_deg=np.concatenate([g.course_deg for g in parts]),
            seg_nm=np.concatenate([g.seg_nm for g in parts]),
            a_xyz=keep_a,
            b_xyz=keep_b,
        )
    # component by component: numpy's reductions over a last axis of 3 cost more than the arithmetic
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    dx, dy, dz = ax - bx, ay - by, az - bz
    chord = np.sqrt(dx * dx + dy * dy + dz * dz)
    omega = 2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))
    seg_nm = (omega * (geodesy.EARTH_RADIUS_KM / geodesy.KM_PER_NM) / samples)[..., None]
    if samples & (samples - 1) == 0:
        # a power of two: halve the arc until its pieces are 1/samples long, then take their midpoints; the
        # midpoint of a short arc is the normalised sum of its ends, so this needs no trigonometry
        nodes = [(ax, ay, az), (bx, by, bz)]
        while len(nodes) - 1 < samples:
            mids = [_midpoint(p0, p1) for p0, p1 in zip(nodes[:-1], nodes[1:], strict=True)]
            nodes = [q for pair in zip(nodes[:-1], mids, strict=True) for q in pair] + [nodes[-1]]
        points = [_midpoint(p0, p1) for p0, p1 in zip(nodes[:-1], nodes[1:], strict=True)]
        x, y, z = (np.stack([q[i] for q in points], axis=-1) for i in range(3))
    else:
        frac = (np.arange(samples) + 0.5) / samples
        om = omega[..., None]
        with np.errstate(invalid="ignore", divide="ignore"):
            so = np.sin(om)
            small = om < 1e-9
            wa = np.where(small, 1.0 - frac, np.sin((1.0 - frac) * om) / np.where(small, 1.0, so))
            wb = np.where(small, frac, np.sin(frac * om) / np.where(small, 1.0, so))
        x, y, z = (wa * pa[..., None] + wb * pb[..., None] for pa, pb in ((ax, bx), (ay, by), (az, bz)))
    bx, by, bz = bx[..., None], by[..., None], bz[..., None]
    rho2 = x * x + y * y
    course = geodesy.bearing_deg(x * by - y * bx, rho2 * bz - z * (x * bx + y * by))
    lon = np.degrees(np.arctan2(y, x))
    lat = np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))  # asin is twice as fast as atan2 here
    return ArcGeometry(lon_deg=lon, lat_deg=lat, course_deg=course, seg_nm=seg_nm, a_xyz=keep_a, b_xyz=keep_b)


def _midpoint(
    p: tuple[FloatArray, FloatArray, FloatArray], q: tuple[FloatArray, FloatArray, FloatArray]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Midpoints of the minor arcs between unit vectors given as (x, y, z) components."""
    x, y, z = p[0] + q[0], p[1] + q[1], p[2] + q[2]
    r = 1.0 / np.sqrt(x * x + y * y + z * z)
    return x * r, y * r, z * r


def arc_costs(
    lon0_deg: npt.ArrayLike,
    lat0_deg: npt.ArrayLike,
    lon1_deg: npt.ArrayLike,
    lat1_deg: npt.ArrayLike,
    t0_h: npt.ArrayLike,
    *,
    departure: np.datetime64,
    weather: WeatherSource,
    polar: Polar,
    failure: FailureModel | None = None,
    apf: float = 1.0,
    samples: int = 1,
    beyond: str = "clamp",
    wave_loss: WaveLoss | None = None,
) -> ArcCosts:
    """Cost of sailing great-circle arcs, vectorised (Algorithm 1 of Dickson et al. 2018).

    Parameters
    ----------
    lon0_deg, lat0_deg, lon1_deg, lat1_deg : Arc end points [deg]; broadcast together.
    t0_h : Departure time of each arc, hours after ``departure`` [h] (finite).
    departure : Time origin (UTC).
    weather : Any :class:`~pyroute_rel.weather.WeatherSource`.
    polar : Boat polar.
    failure : Compiled failure model, or None (no failure model: ``p_f = 0``).
    apf : Acceptable probability of failure in [0, 1]; arcs with ``p_f > apf`` are forbidden.
    samples : Sub-segments per arc (>= 1).
    beyond : Polar behaviour outside its table, ``"clamp"`` or ``"forbid"``.
    wave_loss : Optional speed loss in waves: the polar speed is multiplied by a factor of Hs.

    Returns
    -------
    ArcCosts

    Examples
    --------
    >>> from pyroute_rel.boat.polar import get_polar
    >>> from pyroute_rel.weather import UniformWeather
    >>> w = UniformWeather(tws_kn=12.0, twd_deg=0.0)  # 12 kn from the north: an eastward arc has TWA 90
    >>> c = arc_costs(0.0, 0.0, 1.0, 0.0, 0.0, departure=np.datetime64("2018-06-01T00:00"),
    ...               weather=w, polar=get_polar("maribot_vane"))
    >>> round(float(c.time_h), 3)  # 60.04 nm at 4.1667 kn (bilinear between TWA 85 and 100)
    14.409
    """
    if not (0.0 <= apf <= 1.0):  # also refuses NaN
        raise ScenarioError(f"apf must be a probability in [0, 1] (got {apf!r})")
    geom = arc_geometry(lon0_deg, lat0_deg, lon1_deg, lat1_deg, samples=samples)
    t0 = np.broadcast_to(np.asarray(t0_h, dtype=float), geom.shape) if geom.shape else np.asarray(t0_h, float)
    return geometry_costs(
        geom,
        t0,
        departure=departure,
        weather=weather,
        polar=polar,
        failure=failure,
        apf=apf,
        beyond=beyond,
        wave_loss=wave_loss,
    )


#: Arcs (times samples) per block below which the cost and geometry kernels do not split work between threads.
PARALLEL_MIN_ARCS = 8192

# : The same for arcs sailed through time-varying weather (:mod:`pyroute_rel.boat.march`): each costs several
# samplings,
#: so smaller blocks pay for the threads (the default grid over an hourly 0.25 deg file, 4,200 arcs a rank: 0.89 s
#: a route in one thread, 0.67 s in two, measured).
PARALLEL_MIN_MARCHED = 1024


def geometry_costs(
    geom: ArcGeometry,
    t0_h: npt.ArrayLike,
    *,
    departure: np.datetime64,
    weather: WeatherSource,
    polar: Polar,
    failure: FailureModel | None = None,
    apf: float = 1.0,
    beyond: str = "clamp",
    wave_loss: WaveLoss | None = None,
    workers: int | None = None,
    exact_p_f: bool = True,
    speed_noise: SpeedNoise | None = None,
) -> ArcCosts:
    """:func:`arc_costs` on precomputed :class:`ArcGeometry` (the solver caches geometry per grid).

    Arcs are judged on every piece they cross (:mod:`pyroute_rel.reliability.crossings`) when the geometry has their end
    points. ``exact_p_f=False`` (the DP's choice) skips that where it cannot forbid anything (``apf`` at or above the
    failure table's largest ``p_f``): the arcs' ``p_f`` is then their samples' largest; their times are the same.

    With time-varying weather, a large block is split along its first axis between ``workers`` threads (default
    :func:`~pyroute_rel.resources.default_workers`): the compiled sampling kernels and numpy's ufuncs release the
    GIL, so the parts run in parallel. Each arc's cost depends on that arc alone, so the result is the same as in
    one piece.

    ``speed_noise``: a noise on the speed of each arc (:class:`SpeedNoise`), applied to the speed at every step the
    craft sails (Monte Carlo's noisy boat); such a block is not split between threads.
    """
    options = _CostOptions(departure, weather, polar, failure, apf, beyond, wave_loss, exact_p_f, speed_noise)
    return _geometry_costs(geom, t0_h, options, workers, defer=False)[0]


def deferred_costs(
    geom: ArcGeometry,
    t0_h: npt.ArrayLike,
    *,
    departure: np.datetime64,
    weather: WeatherSource,
    polar: Polar,
    failure: FailureModel | None = None,
    apf: float = 1.0,
    beyond: str = "clamp",
    wave_loss: WaveLoss | None = None,
    workers: int | None = None,
) -> tuple[ArcCosts, PendingPieces | None]:
    """:func:`geometry_costs` (with ``exact_p_f=False``) that leaves the judgement on pieces to the caller.

    The arcs are costed on their samples; those :func:`geometry_costs` could then judge on every piece they cross
    are returned as :class:`PendingPieces` (None: there are none), to be judged when the caller needs them: the DP
    judges only the arcs it would pick (:mod:`pyroute_rel.routing.solve`). An arc judged this way gets the verdict and
    criteria :func:`geometry_costs` gives it; an arc not judged keeps its samples' time, p_f and flags (its time
    may then be finite where :func:`geometry_costs` forbids it).
    """
    options = _CostOptions(departure, weather, polar, failure, apf, beyond, wave_loss, exact_p_f=False)
    t0 = t0_h  # the DP's departures have the block's shape: taken as they are
    if not (type(t0) is np.ndarray and t0.dtype == np.float64 and t0.shape == geom.shape):
        t0 = np.broadcast_to(np.asarray(t0_h, dtype=float), geom.shape)
    costs, todo = _geometry_costs(geom, t0, options, workers, defer=True)
    if todo is None or not todo.any():
        return costs, None
    time_h = np.broadcast_to(costs.time_h, geom.shape)
    return costs, PendingPieces(np.flatnonzero(todo), geom, t0, time_h, options, marks_h=costs.marks_h)


@dataclass
class PendingPieces:
    """Arcs of a block costed on their samples whose judgement on the pieces they cross is still to come
    (:func:`deferred_costs`); :meth:`judge` judges some, as :func:`geometry_costs` would.

    Attributes
    ----------
    index : Flat indices (C order) of the arcs still to judge in the caller's block, increasing.
    geom : The geometry of the block costed (:meth:`moved` lays it in a larger one: ``local`` then holds the arcs'
        flat indices in ``geom``).
    t0_h, time_h : Departure [h after departure] and the samples' sailing time [h] of each arc of ``geom``.
    options : The cost settings.
    marks_h : With time-varying weather, when the craft reaches each sub-segment end of each arc of ``geom``
        (:attr:`ArcCosts.marks_h`).
    """

    index: npt.NDArray[np.intp]
    geom: ArcGeometry
    t0_h: FloatArray
    time_h: FloatArray
    options: _CostOptions
    local: npt.NDArray[np.intp] | None = None
    done: npt.NDArray[np.bool_] | None = None
    marks_h: FloatArray | None = None

    def __post_init__(self) -> None:
        if self.local is None:
            self.local = self.index
        if self.done is None:
            self.done = np.zeros(self.index.size, dtype=bool)

    def waiting(self, size: int) -> npt.NDArray[np.bool_]:
        """Flat mask over the caller's block of ``size`` arcs: the arcs not judged yet."""
        assert self.done is not None  # (set by __post_init__)
        out = np.zeros(size, dtype=bool)
        out[self.index[~self.done]] = True
        return out

    def judge(self, flat: npt.NDArray[np.intp]) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.uint32]]:
        """Judge the arcs at flat indices ``flat`` of the caller's block (all waiting) on every piece they cross;
        returns, for each, whether that forbids it (the largest p_f met along it exceeds apf) and the criteria fired
        in the states above apf met along it (what :func:`geometry_costs` or-s into its flags; 0 where allowed)."""
        assert self.done is not None and self.local is not None
        at = np.searchsorted(self.index, flat)
        if at.size and (
            np.any(at >= self.index.size) or np.any(self.index[np.minimum(at, self.index.size - 1)] != flat)
        ):
            raise ValueError("PendingPieces.judge: an arc that is not waiting to be judged")
        if np.any(self.done[at]):
            raise ValueError("PendingPieces.judge: an arc judged already")
        self.done[at] = True
        g, o = self.geom, self.options
        shape = g.shape
        sel = np.unravel_index(self.local[at], shape)
        assert o.failure is not None and g.a_xyz is not None and g.b_xyz is not None
        ext = arc_extremes(
            np.broadcast_to(g.a_xyz, shape + (3,))[sel],
            np.broadcast_to(g.b_xyz, shape + (3,))[sel],
            self.t0_h[sel],
            self.time_h[sel],
            departure=o.departure,
            weather=o.weather,
            polar=o.polar,
            failure=o.failure,
            apf=o.apf,
            beyond=o.beyond,
            speed_factor=None if o.wave_loss is None else o.wave_loss.factor,
            marks_h=None if self.marks_h is None else self.marks_h.reshape(-1, g.samples + 1)[self.local[at]],
        )
        over = ext.p_f > o.apf
        return over, np.where(over, ext.fired_bits, 0).astype(np.uint32)

    def moved(self, where: npt.NDArray[np.intp]) -> PendingPieces:
        """These arcs laid out in a larger block: arc ``i`` of this one is ``where[i]`` there (increasing)."""
        assert self.done is not None
        return replace(self, index=where[self.index], local=self.local, done=self.done.copy())


def _geometry_costs(
    geom: ArcGeometry, t0_h: npt.ArrayLike, options: _CostOptions, workers: int | None, *, defer: bool
) -> tuple[ArcCosts, npt.NDArray[np.bool_] | None]:
    """:func:`geometry_costs`; ``defer``: the arcs are not judged on pieces; the mask (block shape) of those to
    judge is returned instead (None: none)."""
    shape = geom.shape
    weather = options.weather
    steady = bool(weather.steady)
    n = 1 if workers is None else int(workers)
    # steady weather is sampled once and cheaply: there the threads cost more than they save (measured)
    aligned = _rows_aligned(weather) or options.noise is not None  # (each row its own run)
    if shape and not steady and math.prod(shape) >= PARALLEL_MIN_MARCHED and not aligned:
        n = default_workers() if workers is None else n  # (looked up only where threads may be used)
        if n > 1:
            return _threaded_costs(geom, np.broadcast_to(np.asarray(t0_h, dtype=float), shape), options, n, defer)
    if steady:
        dt, p_f, reason, fired, cond = _steady_costs(geom, options)
        costs = _arc_totals(dt, p_f, reason, fired)
    else:
        # time-varying weather: every arc is sailed sub-segment by sub-segment (pyroute_rel.boat.march)
        costs, cond = _marched_costs(geom, np.broadcast_to(np.asarray(t0_h, dtype=float), shape), options)
    if options.failure is None or geom.a_xyz is None or geom.b_xyz is None:
        return costs, None
    t0 = np.asarray(t0_h, dtype=float)
    todo = _pieces_todo(geom, t0, costs, options, cond)
    if defer:
        return costs, None if todo is None else todo.reshape(shape)
    return (costs if todo is None else _judge_pieces(geom, t0, costs, options, todo)), None


def _marched_costs(geom: ArcGeometry, t0_h: FloatArray, options: _CostOptions) -> tuple[ArcCosts, Conditions]:
    """Arcs of time-varying weather sailed by :func:`pyroute_rel.boat.march.march`: their costs (with the marks) and
    the weather at their samples when the craft was last there (for :func:`_pieces_todo`)."""
    o, weather = options, options.weather
    shape, samples = geom.shape, geom.samples
    n = math.prod(shape)
    course = np.broadcast_to(geom.course_deg, shape + (samples,)).reshape(n, samples)
    seg = np.broadcast_to(geom.seg_nm[..., 0], shape).reshape(n)
    if get_settings().compiled_march:  # (the numpy march below: the same numbers)
        from pyroute_rel._kernels.march import usable

        inner, errors = _wind_errors(weather, shape)
        points_from = None
        view = inner.compiled_source  # rows from stacked members (pyroute_rel.analysis.evaluate)
        if view is not None and errors is None:
            joined = view()
            inner, points_from = (inner, None) if joined is None else (joined, inner)
        block = usable(inner, o.failure, _wind_only(o))
        if block is not None:
            return _compiled_march(geom, t0_h, options, inner, block, course, seg, errors, points_from)
    timing = _TIMING_FIELDS + (("hs_m",) if o.wave_loss is not None else ())
    judged = timing if o.failure is None else timing + tuple(sorted(o.failure.weather_fields - set(timing)))
    sample = _column_sampler(geom, weather, o.departure)
    names = [f.name for f in dataclass_fields(Conditions)]
    kept = {name: np.full((n, samples), 0.0 if name.startswith("current") else np.nan) for name in names}

    noisy = None if o.noise is None else o.noise.flat(n)
    wind_only = _wind_only(o)
    if wind_only:  # TWA and polar speed in compiled code, as the compiled march has them (pyroute_rel._kernels.cost)
        from pyroute_rel._kernels.cost import sail_wind

    def speed(k: int, idx: npt.NDArray[np.intp] | None, t_h: FloatArray, judge: bool) -> Step:
        cond = sample(k, idx, t_h, judged if judge else timing)
        c = np.ascontiguousarray(course[:, k] if idx is None else course[idx, k])
        wind = sail_wind(cond.tws_kn, cond.twd_deg, c, _ONE_NM, o.polar, beyond=o.beyond)[:2] if wind_only else None
        sog, p, reason, fired = _sample_speeds(
            cond, c, o.polar, o.failure if judge else None, o.apf, o.beyond, o.wave_loss, wind=wind
        )
        if noisy is not None:
            sog = o.noise.apply(sog, *((a if idx is None else a[idx]) for a in noisy))  # type: ignore[union-attr]
        if judge:
            at = slice(None) if idx is None else idx
            for name in names:
                kept[name][at, k] = getattr(cond, name)
        return Step(sog_kn=sog, p_f=p, reason=reason, fired=fired)

    m = march(
        t0_h.reshape(n),
        seg,
        samples,
        speed,
        step_hours(weather.time_steps, o.departure),
        missing_flag=REASONS["weather"],
        failure_flag=REASONS["failure"],
        polar_flag=REASONS["polar"],
    )
    cond = Conditions(**{name: kept[name].reshape(shape + (samples,)) for name in names})
    return _sailed_costs(m, shape), cond


def _sailed_costs(m: Marched, shape: tuple[int, ...]) -> ArcCosts:
    """The costs of arcs sailed by the march (flat), laid out in the block's ``shape``."""
    return ArcCosts(
        time_h=m.time_h.reshape(shape),
        p_f=m.p_f.reshape(shape),
        reason=m.reason.reshape(shape),
        fired_bits=None if m.fired is None else m.fired.reshape(shape),
        marks_h=m.marks_h.reshape(shape + (m.marks_h.shape[-1],)),
    )


#: A sub-segment length [nm] for :func:`~pyroute_rel._kernels.cost.sail_wind` where only its speeds are wanted.
_ONE_NM = np.ones(1)


def _rows_aligned(weather: WeatherSource) -> bool:
    """Whether the source answers each row of a query (first axis) from its own run or member (Monte Carlo's
    perturbed wind, members sailed side by side): a block split between threads would misalign its rows."""
    return bool(weather.rows_aligned)


def _wind_errors(weather: WeatherSource, shape: tuple[int, ...]) -> tuple[Any, tuple[FloatArray, FloatArray] | None]:
    """The source the compiled march samples and the wind error east and north [kn] it adds at each arc (flat), for
    a source that offsets its wind per row of the query
    (:meth:`pyroute_rel.analysis.monte_carlo.PerturbedWind.wind_errors`; None: no error)."""
    inner, east, north = weather.wind_errors()
    if east is None or north is None:  # no error: the wrapped source's conditions, unchanged
        return inner, None
    n = math.prod(shape)
    rows = (slice(None),) + (None,) * (len(shape) - 1)
    east_kn, north_kn = (
        np.ascontiguousarray(np.broadcast_to(np.asarray(e, dtype=float)[rows], shape).reshape(n)) for e in (east, north)
    )
    return inner, (east_kn, north_kn)


def _compiled_march(
    geom: ArcGeometry,
    t0_h: FloatArray,
    options: _CostOptions,
    weather: Any,
    block: int,
    course: FloatArray,
    seg: FloatArray,
    errors: tuple[FloatArray, FloatArray] | None,
    points_from: Any = None,
) -> tuple[ArcCosts, Conditions]:
    """:func:`_marched_costs` by :func:`pyroute_rel._kernels.march.march_gridded` over ``weather`` (the options'
    source, or the source it wraps, whose wind it offsets by ``errors`` [kn] at each arc; or the data of stacked
    members, whose points ``points_from`` locates, each row in its member's data)."""
    from pyroute_rel._kernels.march import KEPT_FIELDS, march_gridded

    o = options
    assert type(weather).__name__ == "GriddedWeather"  # (usable() checked it; gridded is imported lazily, with numba)
    shape, samples = geom.shape, geom.samples
    n = math.prod(shape)
    if points_from is None:
        prepared = _located(geom, weather)
    else:
        prepared = points_from.prepare(np.broadcast_to(geom.lon_deg, shape + (samples,)), geom.lat_deg)
    m, kept = march_gridded(
        weather,
        block,
        prepared,
        course,
        seg,
        t0_h.reshape(n),
        samples,
        departure=o.departure,
        polar=o.polar,
        beyond=o.beyond,
        failure=o.failure,
        apf=o.apf,
        flags=(REASONS["polar"], REASONS["weather"], REASONS["failure"]),
        wind_error_kn=errors,
        speed_noise=None if o.noise is None else o.noise.flat(n),
    )
    values = {name: kept[r].reshape(shape + (samples,)) for r, name in enumerate(KEPT_FIELDS)}
    zeros = np.zeros(shape + (samples,))
    return _sailed_costs(m, shape), Conditions(**values, current_u_ms=zeros, current_v_ms=zeros)


def _column_sampler(geom: ArcGeometry, weather: WeatherSource, departure: np.datetime64) -> Any:
    """``sample(k, idx, t_h, fields)``: the weather at sample ``k`` of the arcs ``idx`` (flat; None: all) at times
    ``t_h`` [h after ``departure``], as flat :class:`Conditions`.

    A gridded source samples just those points (located once per geometry and kept, :func:`_located`); any other
    source is asked for the whole column of the block, in the block's shape (a source may answer each row of a
    query from its own member or run), and the points wanted are taken from its answer."""
    shape, samples = geom.shape, geom.samples
    n = math.prod(shape)
    # here: importing it loads numba, which steady routes never need
    from pyroute_rel.weather.gridded import GriddedWeather

    if isinstance(weather, GriddedWeather):
        prepared = _located(geom, weather)
        columns: dict[int, Any] = {}

        def gridded(k: int, idx: Any, t_h: FloatArray, fields: tuple[str, ...]) -> Conditions:
            if idx is None:
                points = columns.get(k)
                if points is None:
                    points = columns[k] = weather.take(prepared, np.arange(n, dtype=np.intp) * samples + k)
            else:
                points = weather.take(prepared, idx * samples + k)
            return weather.sample_at(points, departure, offset_h=np.ascontiguousarray(t_h), fields=fields)

        return gridded
    prepared_columns: dict[int, Any] = {}

    def any_source(k: int, idx: Any, t_h: FloatArray, fields: tuple[str, ...]) -> Conditions:
        points = prepared_columns.get(k)
        if points is None:
            points = prepared_columns[k] = weather.prepare(geom.lon_deg[..., k], geom.lat_deg[..., k])
        offset = np.zeros(n)
        offset[slice(None) if idx is None else idx] = t_h
        cond = weather.sample_at(points, departure, offset_h=offset.reshape(shape), fields=fields)
        at = slice(None) if idx is None else idx
        return Conditions(
            **{f.name: np.broadcast_to(getattr(cond, f.name), shape).reshape(n)[at] for f in dataclass_fields(cond)}
        )

    return any_source


#: Grids whose located points are kept per geometry (the most recently used): each costs about 40 bytes a sample
#: point, 1.7 times the geometry's own arrays.
LOCATED_PER_GEOMETRY = 2


@overload
def _located(geom: ArcGeometry, weather: GriddedWeather) -> PreparedPoints: ...
@overload
def _located(geom: ArcGeometry, weather: WeatherSource) -> object: ...
def _located(geom: ArcGeometry, weather: WeatherSource) -> object:
    """``weather.prepare`` of the geometry's sample points, kept with the geometry where the source can reuse points
    located on its grid by another source (a process routing many members of one ensemble file, or many departures,
    locates them once; :attr:`~pyroute_rel.settings.Settings.locate_cache` False: located every time)."""
    reuse = weather.reuse
    if reuse is None or not get_settings().locate_cache:
        return weather.prepare(geom.lon_deg, geom.lat_deg)
    kept = geom._located
    for i, points in enumerate(kept):
        mine = reuse(points)
        if mine is not None:
            if i:
                kept.insert(0, kept.pop(i))
            return mine
    points = weather.prepare(geom.lon_deg, geom.lat_deg)
    kept.insert(0, points)
    del kept[LOCATED_PER_GEOMETRY:]
    return points


def _pieces_todo(
    geom: ArcGeometry,
    t0_h: FloatArray,
    costs: ArcCosts,
    options: _CostOptions,
    cond: Conditions,
) -> npt.NDArray[np.bool_] | None:
    """Flat mask of the arcs to judge on every piece they cross (None: none): those still allowed whose samples
    did not meet the table's largest p_f and that may meet more than their samples
    (:func:`~pyroute_rel.reliability.crossings.needs_pieces`, decided from ``cond``, the weather at the samples). None
    too where no arc can be forbidden by it and ``exact_p_f`` is False."""
    model = options.failure
    assert model is not None
    p_max = _p_max(model)
    if not options.exact_p_f and options.apf >= p_max:
        return None  # nothing to forbid
    shape = geom.shape
    time_h = np.broadcast_to(costs.time_h, shape).reshape(-1)
    p_f = np.broadcast_to(costs.p_f, shape).reshape(-1)
    # arcs already forbidden stay so; an arc whose samples met the table's largest p_f cannot meet more; an arc
    # far from any change of conditions and of criteria is judged by its samples
    todo = np.isfinite(time_h) & (p_f < p_max)
    close = needs_pieces(
        geom.lon_deg,
        geom.lat_deg,
        geom.course_deg,
        geom.seg_nm,
        np.broadcast_to(t0_h, shape),
        np.broadcast_to(costs.time_h, shape),
        weather=options.weather,
        failure=model,
        departure=options.departure,
        cond=cond,
    )
    if close is not None:
        todo &= np.broadcast_to(close, shape).reshape(-1)
    return todo if todo.any() else None


def _p_max(model: FailureModel) -> float:
    """The largest p_f of a model's table (kept while the model lives: :func:`_pieces_todo` asks at every rank)."""
    return kept_by(model, "_p_max", lambda: float(np.max(model.p_flat)))  # type: ignore[no-any-return]


def _judge_pieces(
    geom: ArcGeometry, t0_h: FloatArray, costs: ArcCosts, options: _CostOptions, todo: npt.NDArray[np.bool_]
) -> ArcCosts:
    """``costs`` with the arcs of ``todo`` (a flat mask, :func:`_pieces_todo`) judged on every piece they cross
    (:func:`~pyroute_rel.reliability.crossings.arc_extremes`): their p_f is the largest met anywhere along them, and
    they are forbidden where that exceeds apf."""
    model = options.failure
    assert model is not None and geom.a_xyz is not None and geom.b_xyz is not None
    shape = geom.shape
    time_h = np.broadcast_to(costs.time_h, shape).reshape(-1)
    p_f = np.broadcast_to(costs.p_f, shape).reshape(-1)
    pick = np.flatnonzero(todo)
    ext = arc_extremes(
        np.broadcast_to(geom.a_xyz, shape + (3,)).reshape(-1, 3)[pick],
        np.broadcast_to(geom.b_xyz, shape + (3,)).reshape(-1, 3)[pick],
        np.broadcast_to(t0_h, shape).reshape(-1)[pick],
        time_h[pick],
        departure=options.departure,
        weather=options.weather,
        polar=options.polar,
        failure=model,
        apf=options.apf,
        beyond=options.beyond,
        speed_factor=None if options.wave_loss is None else options.wave_loss.factor,
        marks_h=None if costs.marks_h is None else costs.marks_h.reshape(-1, geom.samples + 1)[pick],
    )
    new_p = p_f.copy()
    new_p[pick] = np.maximum(p_f[pick], ext.p_f)
    over = np.zeros(p_f.shape, dtype=bool)
    over[pick] = ext.p_f > options.apf
    if not over.any():
        return replace(costs, p_f=new_p.reshape(shape))
    reason = np.broadcast_to(costs.reason, shape).reshape(-1).copy()
    reason[over] |= np.uint8(REASONS["failure"])
    bits = np.broadcast_to(costs.bits(), shape).reshape(-1).copy()
    more = np.zeros(p_f.shape, dtype=np.uint32)
    more[pick] = ext.fired_bits
    bits |= np.where(over, more, 0).astype(np.uint32)
    return ArcCosts(
        time_h=np.where(over, np.inf, time_h).reshape(shape),
        p_f=new_p.reshape(shape),
        reason=reason.reshape(shape),
        fired_bits=bits.reshape(shape),
        marks_h=costs.marks_h,
    )


@dataclass(frozen=True)
class _CostOptions:
    """The arguments of :func:`geometry_costs` besides the arcs (see there)."""

    departure: np.datetime64
    weather: WeatherSource
    polar: Polar
    failure: FailureModel | None
    apf: float
    beyond: str
    wave_loss: WaveLoss | None
    exact_p_f: bool = True
    noise: SpeedNoise | None = None


def _threaded_costs(
    geom: ArcGeometry, t0: FloatArray, options: _CostOptions, n: int, defer: bool
) -> tuple[ArcCosts, npt.NDArray[np.bool_] | None]:
    """:func:`_geometry_costs` of a large block split along its first axis between ``n`` threads."""
    blocks = row_blocks(geom.shape[0], n)
    parts = geom._parts.get(n)
    if parts is None:  # kept with the geometry, so that each part keeps its located points (_located)
        split_seg = geom.seg_nm.shape[:1] == geom.shape[:1]
        parts = geom._parts[n] = [
            ArcGeometry(
                lon_deg=geom.lon_deg[rows],
                lat_deg=geom.lat_deg[rows],
                course_deg=geom.course_deg[rows],
                seg_nm=geom.seg_nm[rows] if split_seg else geom.seg_nm,
                a_xyz=None if geom.a_xyz is None else np.broadcast_to(geom.a_xyz, geom.shape + (3,))[rows],
                b_xyz=None if geom.b_xyz is None else np.broadcast_to(geom.b_xyz, geom.shape + (3,))[rows],
            )
            for rows in blocks
        ]

    def part(i: int) -> tuple[ArcCosts, npt.NDArray[np.bool_] | None]:
        return _geometry_costs(parts[i], t0[blocks[i]], options, 1, defer=defer)

    results = thread_map(part, range(len(blocks)), n)
    done = [c for c, _ in results]
    bits = None
    if any(c.fired_bits is not None for c in done):
        bits = np.concatenate([c.bits() for c in done])
    todo = None
    if any(t is not None for _, t in results):
        todo = np.concatenate([np.zeros(c.time_h.shape, bool) if t is None else t for c, t in results])
    costs = ArcCosts(
        time_h=np.concatenate([c.time_h for c in done]),
        p_f=np.concatenate([c.p_f for c in done]),
        reason=np.concatenate([c.reason for c in done]),
        fired_bits=bits,
        marks_h=None if done[0].marks_h is None else np.concatenate([c.marks_h for c in done]),  # type: ignore[misc]
    )
    return costs, todo


def _steady_costs(
    geom: ArcGeometry, options: _CostOptions
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.uint8], Any, Conditions]:
    """Steady weather: per-sample time [h], p_f, reasons and fired criteria (:func:`_sample_costs`), and the weather,
    sampled once (any time will do)."""
    o = options
    cond = o.weather.sample(geom.lon_deg, geom.lat_deg, o.departure)
    noise = None
    if o.noise is not None:
        gain, spread = o.noise.flat(math.prod(geom.shape))
        noise = (o.noise, gain.reshape(geom.shape + (1,)), spread.reshape(geom.shape + (1,)))
    costs = _sample_costs(
        cond, geom.course_deg, geom.seg_nm, o.polar, o.failure, o.apf, o.beyond, o.wave_loss, noise=noise
    )
    return (*costs, cond)


def _wind_only(options: _CostOptions) -> bool:
    """True where the speed comes from the wind alone: no wave speed loss, no current in the weather (the case
    :func:`pyroute_rel._kernels.cost.sail_wind` covers)."""
    return options.wave_loss is None and not {"current_u_ms", "current_v_ms"} & options.weather.fields


def _arc_totals(
    dt: FloatArray, p_f: FloatArray, reason: npt.NDArray[np.uint8], fired: npt.NDArray[np.uint32] | None
) -> ArcCosts:
    """Per-arc costs from per-sample ones (last axis): times summed, largest p_f, flags and criteria or-ed; an arc
    with any flag takes forever."""
    if dt.shape[-1] == 1:
        arc_fired = None if fired is None else fired[..., 0]
        return ArcCosts(time_h=dt[..., 0], p_f=p_f[..., 0], reason=reason[..., 0], fired_bits=arc_fired)
    # reduced over the samples axis one sample at a time: numpy reduces a short last axis slowly
    time_h, arc_p, arc_reason = dt[..., 0].copy(), p_f[..., 0].copy(), reason[..., 0].copy()
    arc_fired = None if fired is None else fired[..., 0].copy()
    for s in range(1, dt.shape[-1]):
        time_h += dt[..., s]
        np.maximum(arc_p, p_f[..., s], out=arc_p)
        arc_reason |= reason[..., s]
        if arc_fired is not None:
            arc_fired |= fired[..., s]  # type: ignore[index]
    time_h[arc_reason != 0] = np.inf
    return ArcCosts(time_h=time_h, p_f=arc_p, reason=arc_reason, fired_bits=arc_fired)


def _flag(mask: Any, reason: str) -> Any:
    """``REASONS[reason]`` where ``mask`` is true, else 0, as uint8 (a view of the mask times the flag: no int64
    temporary)."""
    return np.asarray(mask, dtype=bool).view(np.uint8) * np.uint8(REASONS[reason])


#: Conditions the timing pass of time-varying weather needs (with a wave speed loss, ``hs_m`` too).
_TIMING_FIELDS = ("tws_kn", "twd_deg", "current_u_ms", "current_v_ms")


def _sample_costs(
    cond: Conditions,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    polar: Polar,
    failure: FailureModel | None,
    apf: float,
    beyond: str,
    wave_loss: WaveLoss | None = None,
    *,
    wind: tuple[FloatArray, FloatArray] | None = None,
    noise: tuple[SpeedNoise, FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.uint8], npt.NDArray[np.uint32] | None]:
    """Per-sample time [h], p_f, reason flags and (with a failure model) the criteria fired where p_f > apf.

    ``wind``: TWA [deg] and polar speed [kn] already computed for the course (no current), e.g. by
    :func:`pyroute_rel._kernels.cost.sail_wind`. ``noise``: a :class:`SpeedNoise` and its gain and spread,
    broadcast against the samples.
    """
    sog, p, reason, fired = _sample_speeds(cond, course_deg, polar, failure, apf, beyond, wave_loss, wind=wind)
    if noise is not None:
        sog = noise[0].apply(sog, noise[1], noise[2])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        dt = seg_nm / sog
    dt = np.where(reason != 0, np.inf, dt)
    return dt, p, reason, fired


def _sample_speeds(
    cond: Conditions,
    course_deg: FloatArray,
    polar: Polar,
    failure: FailureModel | None,
    apf: float,
    beyond: str,
    wave_loss: WaveLoss | None = None,
    *,
    wind: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.uint8], npt.NDArray[np.uint32] | None]:
    """Per-sample speed over ground along the course [kn] (0 below :data:`~pyroute_rel.boat.polar.MIN_SPEED_KN`, NaN
    where the weather is missing), p_f, reason flags and fired criteria (:func:`_sample_costs`)."""
    reason = np.zeros(course_deg.shape, dtype=np.uint8)
    heading = course_deg
    current = cond.has_current
    factor = None if wave_loss is None else wave_loss.factor(cond.hs_m)
    if current:  # the heading that holds the course in the current (exact crab angle, pyroute_rel.boat.crab)
        crab = steer(cond, course_deg, polar, beyond=beyond, speed_factor=1.0 if factor is None else factor)
        heading, twa, v, sog = crab.heading_deg, crab.twa_deg, crab.boat_speed_kn, crab.sog_kn
        cannot = ~crab.ok & np.isfinite(v) & (v > 0)  # the boat sails, but no heading holds the course
        reason |= _flag(cannot, "current")
    else:
        if wind is not None:
            twa, v = wind
        else:
            twa = geodesy.angle_diff_deg(cond.twd_deg, heading)
            v = boat_speed_kn(polar, twa, cond.tws_kn, beyond=beyond)
        if factor is not None:
            v = v * factor
        sog = v
    sog = np.where(sog >= MIN_SPEED_KN, sog, np.where(np.isnan(sog), np.nan, 0.0))
    # without a current the speed over ground is the boat speed: the same numbers, computed once
    v = np.where(v >= MIN_SPEED_KN, v, np.where(np.isnan(v), np.nan, 0.0)) if current else sog
    missing = ~np.isfinite(cond.tws_kn) | ~np.isfinite(cond.twd_deg)
    if current:
        missing |= ~np.isfinite(cond.current_u_ms) | ~np.isfinite(cond.current_v_ms)
    reason |= _flag(~missing & ~(v > 0), "polar")
    if current:
        reason |= _flag(~missing & (v > 0) & ~(sog > 0), "current")
    fired = None
    if failure is not None:
        # only what the model uses; TWA is already known
        q: dict[str, Any] = arc_quantities(cond, heading, failure.quantities - {"twa_deg"})
        if "twa_deg" in failure.quantities:
            q["twa_deg"] = twa
        flat, unknown = failure.evidence_index(q)
        flat = np.broadcast_to(flat, course_deg.shape)
        p = failure.p_flat.take(flat)
        if unknown is not None:
            unknown = np.broadcast_to(unknown, course_deg.shape)
            p[unknown] = np.nan
            missing |= unknown
        over_table = failure.p_flat > apf
        if over_table.any():  # a gather of the small table instead of comparing every point with apf
            over = over_table.take(flat)
            if unknown is not None:
                over &= ~unknown
            if over.any():
                reason |= over.view(np.uint8) * np.uint8(REASONS["failure"])
                fired = np.where(over, failure.fired_bits_flat.take(flat), np.uint32(0))  # in states above apf
    else:
        p = np.zeros(course_deg.shape)
    reason |= _flag(missing, "weather")
    return sog, p, reason, fired
