"""The weather, failure model, land and zones of a planning problem on a lattice, for the compiled MCTS search.

:func:`build_lattice` samples, once per voyage, what :mod:`pyroute_rel._kernels.mcts` reads at every
simulated step: on a lon/lat lattice of ``spacing_deg`` over the planning box
(:meth:`~pyroute_rel.planners.base.PlanningProblem.box`), at slices ``slice_h`` apart (one slice when nothing
changes in time):

- the wind's "from" components ``u = tws sin(twd)``, ``v = tws cos(twd)`` [kn] and the wave speed factor [-]
  (:class:`~pyroute_rel.routing.cost.WaveLoss`, 1 without) of each weather source (the scenario's, or each member);
- whether the failure model allows each heading (a :data:`~pyroute_rel.planners.base.PROBE_NM` leg costed like
  every arc has ``p_f <= apf``; all allowed when no failure model can forbid anything at this apf);
- which cells are open water: neither of the cell's diagonals touches land (grown by the scenario's margin) nor a
  zone active during the slice;
- in ``"perturbed"`` weather, the standard deviation of each wind component [kn]: the members' spread when there
  are members (and their mean as the wind), else :class:`~pyroute_rel.analysis.monte_carlo.MonteCarloSettings`'
  documented forecast error growing with lead time (one value per slice).

The lattice is the search's model of the problem only: the step the craft sails after each decision is costed by
:meth:`~pyroute_rel.planners.base.PlanningProblem.sail` (the DP's arc cost, land and zones, exactly).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.analysis.monte_carlo import MonteCarloSettings
from pyroute_rel.errors import ScenarioError
from pyroute_rel.obstacles.areas import arcs_blocked
from pyroute_rel.obstacles.zones import arcs_blocked_by_zones
from pyroute_rel.planners.base import PROBE_NM, PlanningProblem
from pyroute_rel.times import hours_after
from pyroute_rel.units import KM_PER_NM, KN_PER_MS

__all__ = ["Lattice", "build_lattice", "WEATHER_MODES"]

#: How the search samples the weather: the scenario's (``"forecast"``), a member per iteration (``"members"``), or
#: each wind component drawn from N(mean, sigma^2) at each step (``"perturbed"``, Barde 2023).
WEATHER_MODES = ("forecast", "members", "perturbed")


@dataclass(frozen=True)
class Lattice:
    """The problem on a lattice (see the module notes); arrays as ``pyroute_rel._kernels.mcts.search`` takes them.

    Attributes
    ----------
    lon0, lat0 : The lattice's south-west point [deg].
    spacing_deg : Its spacing [deg].
    slice_h : Time between slices [h].
    u, v : Wind "from" components [kn], shape (members, K, NY, NX).
    factor : Wave speed factor [-], same shape.
    sigma_u, sigma_v : Standard deviation of each component [kn], shape (K, NY, NX) or (K, 1, 1).
    okh : 1 where the failure model allows the heading, shape (members, K, NY, NX, headings).
    open : 1 for open water, shape (K, NY, NX).
    perturbed : Whether the kernel adds noise.
    """

    lon0: float
    lat0: float
    spacing_deg: float
    slice_h: float
    u: npt.NDArray[np.float32]
    v: npt.NDArray[np.float32]
    factor: npt.NDArray[np.float32]
    sigma_u: npt.NDArray[np.float32]
    sigma_v: npt.NDArray[np.float32]
    okh: npt.NDArray[np.uint8]
    open: npt.NDArray[np.uint8]
    perturbed: bool

    @property
    def weather(self) -> tuple[Any, ...]:
        """``W`` of ``pyroute_rel._kernels.mcts.search``."""
        return (self.u, self.v, self.factor, self.sigma_u, self.sigma_v)


def _slices(n: int, slice_h: float) -> np.ndarray:
    return np.arange(n) * slice_h


def _wind(problem: Any, lon: np.ndarray, lat: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, ...]:
    """u, v [kn] and the wave factor of one source at every slice, shape (K, NY, NX)."""
    u, v, f = (np.empty((times.size, *lon.shape), dtype=np.float32) for _ in range(3))
    for k, t in enumerate(times):
        cond = problem.weather_at(lon, lat, float(t))
        if cond.has_current:
            raise ScenarioError(
                "[planner.mcts].engine = 'lattice' does not model currents; the weather has some "
                "(use engine = 'python')"
            )
        tws, twd = np.asarray(cond.tws_kn, dtype=float), np.radians(np.asarray(cond.twd_deg, dtype=float))
        u[k], v[k] = tws * np.sin(twd), tws * np.cos(twd)
        f[k] = 1.0 if problem.wave_loss is None else problem.wave_loss.factor(cond.hs_m)
    return u, v, f


def _allowed(problem: Any, lon: np.ndarray, lat: np.ndarray, times: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """1 where the failure model allows a probe leg on each heading, shape (K, NY, NX, H)."""
    fm = problem.failure
    if fm is None or problem.apf >= float(np.max(fm.p_flat)):
        return np.ones((1, *lon.shape, headings.size), dtype=np.uint8)
    one = replace(problem, samples=1)
    lo, la, hd = np.broadcast_arrays(lon[..., None], lat[..., None], headings)
    lon1, lat1 = geodesy.destination_point(lo, la, hd, PROBE_NM * KM_PER_NM)
    out = np.empty((times.size, *lo.shape), dtype=np.uint8)
    for k, t in enumerate(times):
        p_f = np.asarray(one.costs(lo, la, lon1, lat1, np.full(lo.shape, float(t))).p_f)
        out[k] = ~(p_f > problem.apf)
    return out


def _open(
    pp: PlanningProblem, lon: np.ndarray, lat: np.ndarray, n_slices: int, slice_h: float, half: float
) -> np.ndarray:
    """1 for cells whose diagonals touch neither land nor a zone active during the slice, shape (K or 1, NY, NX)."""
    diag = [(lon - half, lat - half, lon + half, lat + half), (lon - half, lat + half, lon + half, lat - half)]
    land = pp.land()
    closed = np.zeros(lon.shape, dtype=bool)
    if land is not None:
        for d in diag:
            closed |= arcs_blocked(*d, land).reshape(lon.shape)
    zones = pp.scenario.avoid.zones
    timed = any(z.valid_from is not None or z.valid_to is not None for z in zones)
    out = np.empty((n_slices if timed else 1, *lon.shape), dtype=np.uint8)
    for k in range(out.shape[0]):
        shut = closed.copy()
        if zones:
            t0 = hours_after(pp.departure, np.full(lon.shape, max((k - 0.5) * slice_h, 0.0)))
            t1 = hours_after(pp.departure, np.full(lon.shape, (k + 0.5) * slice_h))
            for d in diag:
                shut |= arcs_blocked_by_zones(*d, zones, t0, time_end=t1).reshape(lon.shape)
        out[k] = ~shut
    return out


def build_lattice(
    pp: PlanningProblem,
    headings_deg: npt.ArrayLike,
    *,
    spacing_deg: float,
    slice_h: float,
    until_h: float,
    weather: str = "forecast",
    sigma_scale: float = 1.0,
) -> Lattice:
    """Sample the problem on a lattice (see the module notes).

    Parameters
    ----------
    pp : The planning problem.
    headings_deg : The search's headings [deg].
    spacing_deg : Lattice spacing [deg].
    slice_h : Time between slices [h].
    until_h : Last time the search may simulate [h after departure] (TimeMax).
    weather : One of :data:`WEATHER_MODES`; ``"members"`` needs the problem's members.
    sigma_scale : ``"perturbed"``: the standard deviations are multiplied by this [-].
    """
    if weather not in WEATHER_MODES:
        raise ScenarioError(f"[planner.mcts].weather must be one of {list(WEATHER_MODES)} (got {weather!r})")
    pp.check_members(weather)
    headings = np.asarray(headings_deg, dtype=float)
    w, s, e, n = pp.box()
    lon_ax = w + spacing_deg * np.arange(int(np.floor((e - w) / spacing_deg)) + 2)
    lat_ax = s + spacing_deg * np.arange(int(np.floor((n - s) / spacing_deg)) + 2)
    lon, lat = np.meshgrid(lon_ax, lat_ax)
    problem = pp.problem
    sources = list(pp.members) if weather == "members" or (weather == "perturbed" and pp.members) else []
    steady = all(src.steady for src in [problem.weather, *sources])
    times = _slices(1 if steady else int(np.ceil(until_h / slice_h)) + 1, slice_h)
    n_all = int(np.ceil(until_h / slice_h)) + 1
    per_source = [_wind(replace(problem, weather=src), lon, lat, times) for src in sources or [problem.weather]]
    u, v, f = (np.stack([p[i] for p in per_source]) for i in range(3))
    okh = np.stack(
        [_allowed(replace(problem, weather=src), lon, lat, times, headings) for src in sources or [problem.weather]]
    )
    perturbed = weather == "perturbed"
    if perturbed and sources:  # N(members' mean, members' spread^2); the factor and failure of the scenario's weather
        sig_u = u.std(axis=0, ddof=1 if len(sources) > 1 else 0).astype(np.float32)
        sig_v = v.std(axis=0, ddof=1 if len(sources) > 1 else 0).astype(np.float32)
        u, v = u.mean(axis=0, keepdims=True), v.mean(axis=0, keepdims=True)
        _, _, f1 = _wind(problem, lon, lat, times)
        f = f1[None]
        okh = _allowed(problem, lon, lat, times, headings)[None]
    elif perturbed:
        sig = MonteCarloSettings().sigma_ms(_slices(n_all, slice_h)) * KN_PER_MS
        sig_u = sig_v = sig.astype(np.float32).reshape(-1, 1, 1)
    else:
        sig_u = sig_v = np.zeros((1, 1, 1), dtype=np.float32)
    opened = _open(pp, lon, lat, n_all, slice_h, spacing_deg / 2.0)
    return Lattice(
        lon0=float(lon_ax[0]),
        lat0=float(lat_ax[0]),
        spacing_deg=spacing_deg,
        slice_h=slice_h,
        u=np.ascontiguousarray(u, dtype=np.float32),
        v=np.ascontiguousarray(v, dtype=np.float32),
        factor=np.ascontiguousarray(f, dtype=np.float32),
        sigma_u=np.ascontiguousarray(sig_u * sigma_scale, dtype=np.float32),
        sigma_v=np.ascontiguousarray(sig_v * sigma_scale, dtype=np.float32),
        okh=np.ascontiguousarray(okh, dtype=np.uint8),
        open=np.ascontiguousarray(opened, dtype=np.uint8),
        perturbed=perturbed,
    )
