"""Monte-Carlo evaluation of a track: its voyage time and risk when the forecast and the boat are uncertain.

Each run sails the track leg after leg (:mod:`pyroute_rel.analysis.evaluate`: every leg costed as the router costs an
arc, all runs of a leg in one vectorised call) in the scenario's weather perturbed as follows.

Wind error (per run, per wind component, the same along a leg)
    An AR(1) process in time, ``e_k = phi_k (s_k / s_(k-1)) e_(k-1) + sqrt(1 - phi_k**2) s_k xi_k`` with
    ``xi_k ~ N(0, 1)``, ``phi_k = exp(-dt_k / tau)`` (``dt_k`` the time between the midpoints of legs ``k - 1`` and
    ``k`` as the deterministic voyage sails them) so that ``e_k`` has standard deviation ``s_k`` whatever the legs'
    lengths. The standard deviation grows with lead time ``t`` (hours after the departure, taken as the forecast's
    issue): ``s = min(sigma0 + growth * t, sigma_max)`` [m/s]. Defaults (:class:`MonteCarloSettings`) are
    assumptions of the order of the GEFS 10 m wind spread (about 1 m/s at the analysis, 3-4 m/s at a week): 1.0 m/s,
    0.015 m/s per hour, at most 4 m/s, correlation time 24 h. When the scenario's weather has ensemble members
    (:func:`spread_from_members`), ``s_k`` is instead each leg's ensemble standard deviation of the u and v
    components at its midpoint and mid-time.
Boat-speed noise (per run, per leg, AR(1) in time)
    The speed over ground ``V`` becomes ``V' = V + sqrt(kappa V) eta_k`` (variance ``kappa V`` [kn**2]), floored
    at 10 % of ``V``: ``kappa = 0.2`` kn as in the MCTS-UCT router of Barde (ISAE 2023), which draws the boat speed
    with variance ``kappa V`` with ``kappa = 20 %``. It applies to the speed at every step of the march
    (:class:`~pyroute_rel.boat.march.SpeedNoise`), ``V`` the speed where and when the run's craft is: a slower craft
    sails on into the wind of its own, later times (in steady weather with a speed constant along a leg, the
    leg's time is ``t V / V'``). ``eta_k`` is a unit AR(1)
    process along the legs, ``eta_k = psi_k eta_(k-1) + sqrt(1 - psi_k**2) xi_k``, ``psi_k = exp(-dt_k /
    tau_speed)`` (``dt_k`` as for the wind): a boat slower than its polar stays slower for a while (a fouled hull,
    a sea state the polar does not know, a sail plan), so the spread of the voyage time does not shrink as the
    legs get shorter, as it would with a noise drawn afresh on every leg (Barde draws it per decision step). The
    correlation time ``tau_speed_h = 12`` h is an assumption (no published value): of the order of the time over
    which the sea state and the craft's trim change. Each ``eta_k`` is N(0, 1), so the mean voyage time is the
    same whatever ``tau_speed_h`` (the expectation of a sum is the sum of the expectations); only the spread
    depends on it. The mean time of a leg is above ``t`` (Jensen: ``E[1 / V'] > 1 / E[V']``): by a little more
    than ``kappa / V`` of it (6 % at 4 kn), an effect of a symmetric noise on the speed, not of the sampling
    (:func:`expected_speed_factor` gives it exactly; the tests check the runs' mean against it).
Polar scaling (per run, optional)
    The polar's speeds scaled by ``a = 1 + polar_sd * zeta``, ``zeta ~ N(0, 1)`` (Dickson et al. 2019 studied a
    2.5 % polar uncertainty): ``V`` above is multiplied by it, ``V' = a V + sqrt(kappa a V) eta_k``.

Each run's draws are kept in the result (:attr:`MonteCarloResult.polar_scale`, :attr:`MonteCarloResult.speed_eta`),
so that any run can be sailed again by hand.

With every noise zero each run is the deterministic evaluation, exactly. The probability that the track meets
``p_f > apf`` is the fraction of runs in which some leg does, with a Wilson score interval (95 %).

References
----------
Barde, A. (2023). Routage de voiliers autonomes par MCTS-UCT. ISAE-SUPAERO (GEFS spread, kappa = 20 %).
Dickson, T. et al. (2019). Uncertainty in marine weather routing. Applied Ocean Research 88, 138-146.
Wilson, E. B. (1927). Probable inference, the law of succession, and statistical inference. JASA 22, 209-212.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel.analysis.evaluate import Track, as_track, evaluation_problem, sail_tracks
from pyroute_rel.boat.march import SpeedNoise
from pyroute_rel.errors import ScenarioError, brief, check_fields, check_instance, check_numbers
from pyroute_rel.resources import MemoryEstimate, check_budget
from pyroute_rel.routing.cost import ArcGeometry, arc_geometry, geometry_costs
from pyroute_rel.units import KN_PER_MS
from pyroute_rel.weather.base import Conditions, WeatherBase

if TYPE_CHECKING:
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.scenario import Scenario

__all__ = [
    "MonteCarloSettings",
    "MonteCarloResult",
    "PerturbedWind",
    "monte_carlo",
    "wind_errors",
    "wilson_interval",
    "spread_from_members",
    "expected_speed_factor",
    "run_estimate",
]

FloatArray = npt.NDArray[np.float64]


#: Most Monte-Carlo runs of one call (each run sails every leg: the run arrays hold runs x legs values).
MAX_RUNS = 10_000_000


#: Largest wind error standard deviation [m/s]: a hurricane's whole wind, far beyond any forecast's error (issue 34:
#: 1e6 m/s was accepted).
MAX_WIND_SD_MS = 50.0
#: Largest boat-speed variance per unit speed [kn]: 50 times the published 0.2 (Barde 2023), a speed noise larger than
#: any boat's speed (1e308 was accepted).
MAX_KAPPA_KN = 10.0
_TAU = ("float", 0.0, math.inf, True, "> 0 [h]")  # infinite: one error all along
#: The rules of :class:`MonteCarloSettings`' numbers (:func:`~pyroute_rel.errors.check_fields`).
_LIMITS = {
    **dict.fromkeys(
        ("sigma0_ms", "sigma_max_ms"), ("float", 0.0, MAX_WIND_SD_MS, False, f"in [0, {MAX_WIND_SD_MS:g}] [m/s]")
    ),
    "growth_ms_per_h": ("float", 0.0, 1.0, False, "in [0, 1] [m/s per h]"),
    "kappa": ("float", 0.0, MAX_KAPPA_KN, False, f"in [0, {MAX_KAPPA_KN:g}] [kn]"),
    "polar_sd": ("float", 0.0, 1.0, False, "in [0, 1] (a share of the polar's speed)"),
    **dict.fromkeys(("tau_h", "tau_speed_h"), _TAU),
}


@dataclass(frozen=True)
class MonteCarloSettings:
    """The uncertainties of a Monte-Carlo evaluation (see the module notes).

    Attributes
    ----------
    sigma0_ms : Wind error standard deviation per component at the departure [m/s].
    growth_ms_per_h : Its growth with lead time [m/s per h].
    sigma_max_ms : Its largest value [m/s].
    tau_h : Correlation time of the wind error [h] (> 0).
    kappa : Boat-speed variance per unit speed, ``Var(V') = kappa V`` [kn] (Barde 2023: 0.2).
    tau_speed_h : Correlation time of the boat-speed noise [h] (> 0; an assumption, see the module notes).
    polar_sd : Standard deviation of the polar's scale factor [-] (0: none).
    spread_ms : Per-leg wind error standard deviations [m/s] replacing ``sigma0``/``growth`` (e.g. from the ensemble
        spread, :func:`spread_from_members`), or None.
    """

    sigma0_ms: float = 1.0
    growth_ms_per_h: float = 0.015
    sigma_max_ms: float = 4.0
    tau_h: float = 24.0
    kappa: float = 0.2
    polar_sd: float = 0.0
    spread_ms: FloatArray | None = None
    tau_speed_h: float = 12.0

    def __post_init__(self) -> None:
        check_fields(self, _LIMITS, where="Monte-Carlo ")
        if self.spread_ms is not None:
            spread = check_numbers(self.spread_ms, "Monte-Carlo spread_ms", ScenarioError, missing=False, unit="m/s")
            if spread.ndim != 1 or (spread < 0.0).any() or (spread > MAX_WIND_SD_MS).any():
                raise ScenarioError(
                    f"Monte-Carlo spread_ms must be one value in [0, {MAX_WIND_SD_MS:g}] per leg [m/s] "
                    f"(got {brief(spread)})"
                )
            object.__setattr__(self, "spread_ms", spread)

    @classmethod
    def zero(cls) -> MonteCarloSettings:
        """No noise at all: every run is the deterministic evaluation."""
        return cls(sigma0_ms=0.0, growth_ms_per_h=0.0, sigma_max_ms=0.0, kappa=0.0, polar_sd=0.0)

    def sigma_ms(self, lead_h: npt.ArrayLike) -> FloatArray:
        """Wind error standard deviation at lead times [h] [m/s]."""
        return np.minimum(self.sigma0_ms + self.growth_ms_per_h * np.asarray(lead_h, dtype=float), self.sigma_max_ms)

    def describe_values(self) -> dict[str, float]:
        """The scalar settings by name (to build changed settings)."""
        return {
            k: getattr(self, k)
            for k in ("sigma0_ms", "growth_ms_per_h", "sigma_max_ms", "tau_h", "kappa", "polar_sd", "tau_speed_h")
        }

    def describe(self) -> dict[str, Any]:
        """The settings as plain JSON values."""
        return {
            "sigma0_ms": self.sigma0_ms,
            "growth_ms_per_h": self.growth_ms_per_h,
            "sigma_max_ms": self.sigma_max_ms,
            "tau_h": self.tau_h,
            "kappa": self.kappa,
            "tau_speed_h": self.tau_speed_h,
            "polar_sd": self.polar_sd,
            "wind_spread": "ensemble members" if self.spread_ms is not None else "lead-time growth",
        }


def wind_errors(
    rng: np.random.Generator, n_runs: int, sigma_ms: npt.ArrayLike, step_h: npt.ArrayLike, tau_h: float
) -> FloatArray:
    """AR(1) wind errors [m/s], shape (n_runs, n_legs), one component (see the module notes).

    ``sigma_ms`` is each leg's standard deviation, ``step_h`` the time from the previous leg (the first ignored).
    """
    s = np.asarray(sigma_ms, dtype=float)
    phi = np.exp(-np.asarray(step_h, dtype=float) / tau_h)
    xi = rng.standard_normal((n_runs, s.size))
    e = np.empty((n_runs, s.size))
    if s.size == 0:
        return e
    e[:, 0] = s[0] * xi[:, 0]
    for k in range(1, s.size):
        ratio = s[k] / s[k - 1] if s[k - 1] > 0 else 0.0
        e[:, k] = phi[k] * ratio * e[:, k - 1] + math.sqrt(max(1.0 - phi[k] ** 2, 0.0)) * s[k] * xi[:, k]
    return e


class PerturbedWind(WeatherBase):
    rows_aligned = True  # (each row its run's error)

    """A weather source whose wind is offset by a per-run error: queries whose first axis is the run.

    Wraps a :class:`~pyroute_rel.weather.WeatherSource`; ``east_ms``/``north_ms`` (one value per run [m/s]) are added
    to the wind's (u, v) components of every point of run ``r`` (row ``r`` of the query). When every error is 0 the
    conditions are the wrapped source's, unchanged.
    """

    def __init__(self, inner: Any, east_ms: FloatArray, north_ms: FloatArray) -> None:
        self.inner = inner
        self.east_ms = np.asarray(east_ms, dtype=float)
        self.north_ms = np.asarray(north_ms, dtype=float)

    @property
    def steady(self) -> bool:
        """As the wrapped source."""
        return bool(self.inner.steady)

    @property
    def fields(self) -> frozenset[str]:
        """As the wrapped source."""
        return frozenset(self.inner.fields)

    @property
    def time_steps(self) -> Any:
        """As the wrapped source."""
        return self.inner.time_steps

    @property
    def max_current_ms(self) -> float:
        """As the wrapped source."""
        return float(self.inner.max_current_ms)

    def check_coverage(self, *args: Any, **kwargs: Any) -> None:
        """As the wrapped source."""
        self.inner.check_coverage(*args, **kwargs)

    def wind_errors(self) -> tuple[Any, FloatArray | None, FloatArray | None]:
        """The wrapped source and each run's error east and north [kn] (what :meth:`sample_at` adds to the wind's
        components; None when every error is 0: the wrapped source's conditions, unchanged): how the compiled march
        (:mod:`pyroute_rel._kernels.march`) samples this source, with the same arithmetic."""
        if not (self.east_ms.any() or self.north_ms.any()):
            return self.inner, None, None
        return self.inner, self.east_ms * KN_PER_MS, self.north_ms * KN_PER_MS

    def _perturb(self, cond: Conditions) -> Conditions:
        if not (self.east_ms.any() or self.north_ms.any()):
            return cond
        tws, twd = np.asarray(cond.tws_kn, dtype=float), np.asarray(cond.twd_deg, dtype=float)
        extra = (slice(None),) + (None,) * (tws.ndim - 1)
        de, dn = self.east_ms[extra] * KN_PER_MS, self.north_ms[extra] * KN_PER_MS
        rad = np.radians(twd)
        u = de - tws * np.sin(rad)  # the wind's velocity (to), east and north [kn]
        v = dn - tws * np.cos(rad)
        speed = np.hypot(u, v)
        direction = np.degrees(np.arctan2(-u, -v))
        direction %= 360.0
        return replace(cond, tws_kn=speed, twd_deg=direction)

    def sample(self, lon_deg: Any, lat_deg: Any, time: Any) -> Conditions:
        """The wrapped source's conditions with each run's wind error added."""
        return self._perturb(self.inner.sample(lon_deg, lat_deg, time))

    def prepare(self, lon_deg: Any, lat_deg: Any) -> object:
        """As the wrapped source."""
        return self.inner.prepare(lon_deg, lat_deg)

    def sample_at(
        self, prepared: Any, departure: Any, *, offset_h: Any = None, fields: Collection[str] | None = None
    ) -> Conditions:
        """The wrapped source's conditions with each run's wind error added."""
        return self._perturb(self.inner.sample_at(prepared, departure, offset_h=offset_h, fields=fields))


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """The runs of a Monte-Carlo evaluation (:func:`monte_carlo`).

    Attributes
    ----------
    voyage_time_h : Each run's voyage time [h] (``inf`` where a leg cannot be sailed).
    max_p_f : Each run's largest leg ``p_f``.
    p_fail : Whether each run meets ``p_f > apf`` on some leg.
    deterministic_h : The deterministic evaluation's voyage time [h].
    apf : The bound.
    seed : The random seed.
    settings : The uncertainties.
    polar_scale : Each run's factor ``a`` on the polar's speeds [-] (None: not kept).
    speed_eta : Each run's unit boat-speed noise ``eta_k`` on each leg [-], shape (runs, legs) (None: not kept).
    wind_error_ms : Each run's wind error east and north on each leg [m/s], shape (2, runs, legs) (None: not kept).
    """

    voyage_time_h: FloatArray
    max_p_f: FloatArray
    p_fail: npt.NDArray[np.bool_]
    deterministic_h: float
    apf: float
    seed: int | None
    settings: MonteCarloSettings = field(default_factory=MonteCarloSettings)
    polar_scale: FloatArray | None = None
    speed_eta: FloatArray | None = None
    wind_error_ms: FloatArray | None = None

    @property
    def n_runs(self) -> int:
        """Number of runs."""
        return int(self.voyage_time_h.size)

    @property
    def p_fail_fraction(self) -> float:
        """Fraction of runs meeting ``p_f > apf``."""
        return float(self.p_fail.mean())

    @property
    def p_fail_interval(self) -> tuple[float, float]:
        """Wilson 95 % interval of the probability of meeting ``p_f > apf``."""
        return wilson_interval(int(self.p_fail.sum()), self.n_runs)

    def summary(self) -> dict[str, Any]:
        """The JSON of ``pyroute-rel evaluate --monte-carlo``."""
        from pyroute_rel.analysis.ensemble import arrival_stats

        lo, hi = self.p_fail_interval
        t = self.voyage_time_h
        return {
            "runs": self.n_runs,
            "seed": self.seed,
            "settings": self.settings.describe(),
            "deterministic_h": _num(self.deterministic_h),
            "arrival_h": {k: _num(v) for k, v in arrival_stats(t, 0.9).items()},
            "sd_h": _num(float(np.std(t, ddof=1))) if self.n_runs > 1 and np.isfinite(t).all() else None,
            "completed": float(np.isfinite(t).mean()),
            "arrived_h": _of_arrived(t),
            "apf": self.apf,
            "p_fail_conditions": self.p_fail_fraction,
            "p_fail_conditions_ci95": [lo, hi],
        }


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _of_arrived(t: FloatArray) -> dict[str, Any]:
    """The arrival distribution of the runs that arrive [h] (a run that meets a leg it cannot sail, below
    :data:`~pyroute_rel.boat.polar.MIN_SPEED_KN`, never arrives): their count, mean, standard deviation, P5, P50, P95,
    CVaR 0.9 and worst (None without two runs)."""
    from pyroute_rel.analysis.ensemble import arrival_stats

    done = t[np.isfinite(t)]
    out: dict[str, Any] = {"runs": int(done.size)}
    if done.size < 2:
        return {**out, **dict.fromkeys(("mean", "sd", "p5", "p50", "p95", "cvar", "worst"))}
    stats = {k: _num(v) for k, v in arrival_stats(done, 0.9).items()}
    return {**out, "mean": stats["mean"], "sd": float(np.std(done, ddof=1)),
            **{k: stats[k] for k in ("p5", "p50", "p95", "cvar", "worst")}}  # fmt: skip


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (95 % by default).

    >>> [round(v, 4) for v in wilson_interval(0, 100)], [round(v, 4) for v in wilson_interval(50, 100)]
    ([0.0, 0.037], [0.4038, 0.5962])
    """
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def monte_carlo(
    scenario: Scenario,
    track: Track | npt.ArrayLike,
    *,
    runs: int = 1000,
    seed: int | None = 0,
    settings: MonteCarloSettings | None = None,
    departure: Any = None,
    problem: RoutingProblem | None = None,
) -> MonteCarloResult:
    """Sail a track ``runs`` times in perturbed weather with a noisy boat (see the module notes).

    Parameters
    ----------
    scenario : The scenario (weather, polar, failure model, apf).
    track : The track (:class:`~pyroute_rel.analysis.evaluate.Track` or (N, 2) lon, lat [deg]).
    runs : Number of runs (>= 1).
    seed : Random seed (None: fresh entropy).
    settings : The uncertainties (default :class:`MonteCarloSettings`).
    departure : Departure time (default: the track's first time, else the scenario's).
    problem : The routing problem to sail in (default :func:`~pyroute_rel.analysis.evaluate.evaluation_problem`).
    """
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ScenarioError(f"--monte-carlo needs a whole number of runs >= 1 (got {runs!r})")
    if runs > MAX_RUNS:
        raise ScenarioError(f"--monte-carlo runs must be at most {MAX_RUNS} (got {runs})")
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.scenario import Scenario

    check_instance(scenario, Scenario, "scenario", ScenarioError, expected="a Scenario (pyroute_rel.load_scenario)")
    trk = as_track(track)
    s = (
        MonteCarloSettings()
        if settings is None
        else check_instance(settings, MonteCarloSettings, "settings", ScenarioError)
    )
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0):
        raise ScenarioError(f"seed must be a whole number >= 0 or None (got {brief(seed)})")
    if departure is None and trk.time is not None:
        departure = trk.time[0]
    if problem is not None:
        check_instance(problem, RoutingProblem, "problem", ScenarioError, expected="a RoutingProblem or None")
    prob = problem or evaluation_problem(scenario, departure=departure)
    n_legs = trk.lon_deg.size - 1
    check_budget(run_estimate(runs, n_legs, prob.samples), knobs="use fewer runs")  # (issue 34: 1.2 GB a million)
    base = sail_tracks(prob, [trk])[0]
    mid_h = base.elapsed_h[:-1] + 0.5 * np.where(np.isfinite(base.costs.time_h), base.costs.time_h, 0.0)
    mid_h = np.where(np.isfinite(mid_h), mid_h, base.elapsed_h[np.isfinite(base.elapsed_h)][-1])
    sigma = s.sigma_ms(mid_h) if s.spread_ms is None else np.asarray(s.spread_ms, dtype=float)
    if sigma.shape != (n_legs,):
        raise ScenarioError(f"spread_ms must hold one value per leg ({n_legs}) (got {sigma.shape})")
    rng = np.random.default_rng(seed)
    step = np.diff(mid_h, prepend=mid_h[:1])
    east = wind_errors(rng, runs, sigma, step, s.tau_h)
    north = wind_errors(rng, runs, sigma, step, s.tau_h)
    eta = wind_errors(rng, runs, np.ones(n_legs), step, s.tau_speed_h)  # a unit AR(1) process
    scale = 1.0 + s.polar_sd * rng.standard_normal(runs)
    times, p_max = _sail_runs(prob, trk, east, north, eta, scale, s.kappa)
    with np.errstate(invalid="ignore"):
        over = np.any(p_max > prob.apf, axis=1)
    return MonteCarloResult(
        voyage_time_h=times,
        max_p_f=np.nan_to_num(np.nanmax(np.where(np.isnan(p_max), -np.inf, p_max), axis=1), neginf=0.0),
        p_fail=over,
        deterministic_h=base.voyage_time_h,
        apf=float(prob.apf),
        seed=seed,
        settings=s,
        polar_scale=scale,
        speed_eta=eta,
        wind_error_ms=np.stack([east, north]),
    )


def _sail_runs(
    problem: RoutingProblem,
    track: Track,
    east: FloatArray,
    north: FloatArray,
    eta: FloatArray,
    scale: FloatArray,
    kappa: float,
) -> tuple[FloatArray, FloatArray]:
    """Every run sailed leg after leg: (voyage time [h] per run, p_f per run and leg). A boat with manoeuvre
    penalties is charged each tack and gybe as :func:`~pyroute_rel.analysis.evaluate.sail_tracks` charges it, the side
    of each leg found in the run's wind."""
    from pyroute_rel.boat.manoeuvre import charge_manoeuvres
    from pyroute_rel.routing.solve import first_sample_wind

    runs, n_legs = eta.shape
    lon, lat, waits = track.lon_deg, track.lat_deg, track.waits_h
    elapsed = np.zeros(runs)
    p_f = np.full((runs, n_legs), np.nan)
    side = np.full(runs, -1 if problem.initial_side is None else int(problem.initial_side), dtype=np.int8)
    for k in range(n_legs):
        go = np.isfinite(elapsed)
        if not go.any():
            break
        idx = np.flatnonzero(go)
        elapsed[idx] += waits[k]  # the track's wait before the leg (as sail_tracks waits)
        weather = PerturbedWind(problem.weather, east[idx, k], north[idx, k])
        one = arc_geometry(lon[k], lat[k], lon[k + 1], lat[k + 1], samples=problem.samples)  # the same arc for all
        geom = ArcGeometry(
            *(np.broadcast_to(a, (idx.size, *a.shape)) for a in (one.lon_deg, one.lat_deg, one.course_deg, one.seg_nm))
        )
        gain = scale[idx]
        noise = SpeedNoise(gain=gain, spread=np.sqrt(kappa * np.maximum(gain, 0.0)) * eta[idx, k])
        c = geometry_costs(
            geom,
            elapsed[idx],
            departure=problem.departure,
            weather=weather,  # type: ignore[arg-type]
            polar=problem.polar,
            failure=problem.failure,
            apf=1.0,
            beyond=problem.beyond,
            wave_loss=problem.wave_loss,
            workers=1,  # the rows are the runs: never split
            speed_noise=noise,  # the run's boat, at every step: a slower boat meets the wind of its own times
        )
        t = c.time_h
        p_f[idx, k] = c.p_f
        if not problem.sides:
            elapsed[idx] = problem.arrive(elapsed[idx] + t)
            continue
        now, twa, tws = first_sample_wind(replace(problem, weather=weather), geom, elapsed[idx])  # type: ignore[arg-type]
        _, pen = charge_manoeuvres(now, twa, tws, side[idx], problem.manoeuvres)
        side[idx] = now
        elapsed[idx] = problem.arrive((elapsed[idx] + t) + pen)
    return elapsed, p_f


#: Float64 arrays of runs x samples the cost kernel holds for one leg of every run at once, in :func:`monte_carlo`:
#: its peak resident memory grew 2.6 kB a run on a 2-leg track of 16 samples a leg (100 000 against 300 000 runs),
#: 2.66 kB as :func:`run_estimate` counts it.
RUN_LEG_ARRAYS = 20


def run_estimate(runs: int, n_legs: int, samples: int) -> MemoryEstimate:
    """The memory :func:`monte_carlo` needs at its peak [bytes]: six float64 arrays of runs x legs (the wind errors
    east and north, their draws, the speed noise, the legs' p_f and times) and one leg of every run at work in the cost
    kernel (:data:`RUN_LEG_ARRAYS` arrays of runs x samples)."""
    return MemoryEstimate(
        parts={"run arrays": 6 * 8 * runs * n_legs, "one leg at work": 8 * RUN_LEG_ARRAYS * runs * samples},
        what=f"{runs} runs x {n_legs} legs, {samples} samples per leg",
        subject="this Monte-Carlo evaluation",
    )


def expected_speed_factor(kappa: float, speed_kn: npt.ArrayLike) -> FloatArray:
    """``E[V / V']`` of the boat-speed noise (see the module notes): the factor by which the noise stretches a leg's
    time on average, ``E[1 / max(1 + s eta, 0.1)]`` with ``s = sqrt(kappa / V)``, ``eta ~ N(0, 1)``, by
    the floor in closed form and the rest by Gauss-Legendre quadrature (:func:`_factor`).

    >>> float(expected_speed_factor(0.0, 4.0)), round(float(expected_speed_factor(0.2, 4.0)), 4)
    (1.0, 1.0606)
    """
    v = np.asarray(speed_kn, dtype=float)
    s = np.sqrt(kappa / v)
    out = np.ones(v.shape)
    flat = out.reshape(-1)
    for i, si in enumerate(np.broadcast_to(s, v.shape).reshape(-1)):
        if si > 0.0:
            flat[i] = _factor(float(si))
    return out


def _factor(s: float) -> float:
    """``E[1 / max(1 + s eta, 0.1)]``: the floor's part in closed form, the rest by Gauss-Legendre quadrature on the
    normal density above the kink ``eta = -0.9 / s`` (to 12 standard deviations)."""
    from scipy.special import ndtr

    kink = -0.9 / s
    x, w = np.polynomial.legendre.leggauss(200)
    lo, hi = kink, max(kink, 0.0) + 12.0
    eta = 0.5 * (hi - lo) * x + 0.5 * (hi + lo)
    density = np.exp(-0.5 * eta * eta) / math.sqrt(2.0 * math.pi)
    upper = 0.5 * (hi - lo) * float(np.sum(w * density / (1.0 + s * eta)))
    return upper + float(ndtr(kink)) / 0.1


def spread_from_members(
    path: Any, track: Track | npt.ArrayLike, *, departure: Any = None, member_files: Any = None
) -> FloatArray:
    """Each leg's wind error standard deviation from an ensemble [m/s]: the standard deviation over the members of
    the u and v wind components (averaged over the two) at the leg's midpoint, at the time the ensemble-mean weather
    sails it.

    Parameters
    ----------
    path : The scenario file (its ``[weather]`` files with a member dimension, or ``member_files``).
    track : The track.
    departure : Departure time (default the scenario's).
    member_files : One weather file per member.
    """
    from pyroute_rel import geodesy
    from pyroute_rel.analysis.members import mean_scenario, member_count, member_scenario
    from pyroute_rel.times import hours_after

    trk = as_track(track)
    n = member_count(path, member_files=member_files)
    ref = mean_scenario(path, member_files=member_files)
    prob = evaluation_problem(ref, departure=departure)
    base = sail_tracks(prob, [trk])[0]
    t_leg = np.where(np.isfinite(base.costs.time_h), base.costs.time_h, 0.0)
    start = np.where(np.isfinite(base.elapsed_h[:-1]), base.elapsed_h[:-1], 0.0)
    lon, lat = trk.lon_deg, trk.lat_deg
    mlon, mlat = geodesy.intermediate_point(lon[:-1], lat[:-1], lon[1:], lat[1:], 0.5)
    when = hours_after(prob.departure, start + 0.5 * t_leg)
    u, v = [], []
    for m in range(n):
        w = member_scenario(path, m, member_files=member_files).weather
        c = w.sample(mlon, mlat, when)
        rad = np.radians(np.asarray(c.twd_deg, dtype=float))
        speed = np.asarray(c.tws_kn, dtype=float) / KN_PER_MS
        u.append(-speed * np.sin(rad))
        v.append(-speed * np.cos(rad))
    spread = np.asarray(0.5 * (np.std(u, axis=0, ddof=1) + np.std(v, axis=0, ddof=1)), dtype=float)
    _check_spread(spread, mlon, mlat, when, w)
    return spread


def _wind_extent(weather: Any) -> str:
    """The extent of a gridded source's wind field (its ``describe()``), else its type's name."""
    from pyroute_rel.weather.gridded import GriddedWeather

    if isinstance(weather, GriddedWeather) and "wind_u_ms" in weather.field_info:
        return str(weather.field_info["wind_u_ms"].describe())
    return type(weather).__name__


def _check_spread(spread: FloatArray, lon: FloatArray, lat: FloatArray, when: Any, weather: Any) -> None:
    """ScenarioError naming the first leg whose midpoint the members have no wind at (outside their data)."""
    bad = np.flatnonzero(~np.isfinite(spread))
    if bad.size:
        k = int(bad[0])
        raise ScenarioError(
            f"the ensemble's members have no wind at the midpoint of leg {k + 1} of {spread.size} (lon "
            f"{lon[k]:.2f}, lat {lat[k]:.2f} [deg], {str(when[k])[:16]}): the track leaves the members' data "
            f"(wind: {_wind_extent(weather)}); {bad.size} legs in all"
        )
