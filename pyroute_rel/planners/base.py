"""What every planner shares: the routing problem it is given, the track it returns, and the :class:`Planner`
protocol.

A planner takes the same routing problem as the DP - the scenario's course, weather, polar, failure model, apf,
land and zones (:class:`PlanningProblem`) - and returns a track (:class:`PlannedTrack`). The evaluator
(:func:`pyroute_rel.analysis.evaluate.evaluate_track`) re-times any track in the scenario's weather, so every planner's
figures are measured the same way.

Sailing a leg (:meth:`PlanningProblem.sail`) is the DP's arc cost
(:meth:`pyroute_rel.routing.solve.RoutingProblem.costs`: polar, weather sampled along the leg, failure model with its
apf) plus the obstacles the DP avoids: land grown by the scenario's margin
(:func:`pyroute_rel.obstacles.land.land_geometry` of the planning box, tested with
:func:`pyroute_rel.obstacles.areas.arcs_blocked`) and the zones active while the leg is sailed
(:func:`pyroute_rel.obstacles.zones.arcs_blocked_by_zones`). A leg that any of them forbids takes ``inf``. Planners stay
in the planning box: the DP grid's bounding box grown by :data:`BOX_PAD_DEG`; a leg that leaves it is forbidden too.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import ScenarioError, TrackError, check_flag, check_instance, check_numbers
from pyroute_rel.obstacles.areas import arcs_blocked
from pyroute_rel.obstacles.land import land_geometry
from pyroute_rel.obstacles.zones import arcs_blocked_by_zones
from pyroute_rel.planners.settings import PlannerSettings
from pyroute_rel.times import hours_after
from pyroute_rel.units import KM_PER_NM

if TYPE_CHECKING:
    from pyroute_rel.routing.grid import Grid
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.scenario import Scenario
    from pyroute_rel.weather import WeatherSource

__all__ = ["PlanningProblem", "PlannedTrack", "Planner", "SailedLegs"]

FloatArray = npt.NDArray[np.float64]

#: The planning box is the DP grid's bounding box grown by this much [deg].
BOX_PAD_DEG = 1.0
#: Length of the short leg whose cost gives the speed over ground at a point on a course [nm].
PROBE_NM = 0.01


@dataclass(frozen=True)
class SailedLegs:
    """Legs sailed by a planner (arrays of the legs' shape).

    Attributes
    ----------
    time_h : Sailing time [h]; ``inf`` where the leg is forbidden.
    p_f : The leg's largest failure probability [-].
    ok : True where the leg may be sailed (polar, weather, failure model, land, zones).
    """

    time_h: FloatArray
    p_f: FloatArray
    ok: npt.NDArray[np.bool_]


@dataclass(frozen=True)
class PlanningProblem:
    """The routing problem every planner solves: the scenario and what it routes with.

    Build it with :meth:`of`. Planners other than the DP route from ``start`` to ``finish`` (no waypoints, start
    or finish lines, time lattice); the DP routes any scenario.

    Attributes
    ----------
    scenario : The scenario (course, departure, avoid).
    grid : The scenario's rank digraph (the DP's graph: Q-learning on the graph and MCTS with ``graph = true``
        search it).
    problem : The routing problem on that grid (weather, polar, failure model, apf, obstacle mask).
    settings : The ``[planner]`` table.
    members : Weather members to sample from when the weather is uncertain (empty: the scenario's weather only).
    """

    scenario: Scenario
    grid: Grid
    problem: RoutingProblem
    settings: PlannerSettings = field(default_factory=PlannerSettings)
    members: tuple[WeatherSource, ...] = ()
    _land: Any = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def of(
        cls,
        scenario: Scenario,
        *,
        settings: PlannerSettings | None = None,
        members: tuple[WeatherSource, ...] | list[WeatherSource] = (),
    ) -> PlanningProblem:
        """The planning problem of a scenario (its grid and routing problem are built here, once)."""
        grid = scenario.make_grid()
        problem = scenario.problem(grid=grid)
        return cls(
            scenario=scenario,
            grid=grid,
            problem=problem,
            settings=scenario.planner if settings is None else settings,
            members=tuple(members),
        )

    def check_simple_course(self, planner: str) -> None:
        """Refuse what only the DP routes: waypoints, start or finish lines, the time lattice."""
        sc = self.scenario
        for bad, what in (
            (sc.waypoints, "waypoints"),
            (sc.start_line, "a start line"),
            (sc.finish_line, "a finish line"),
            (sc.time_step_h, "a time lattice (time_step_h)"),
        ):
            if bad:
                raise ScenarioError(
                    f"{sc.source}: planner {planner!r} routes from [route].start to [route].finish only; the scenario "
                    f"has {what} (use the DP: --planner dp)"
                )

    def check_members(self, weather: str) -> None:
        """Refuse MCTS's ``weather = "members"`` without members, naming the scenario's file."""
        if weather == "members" and not self.members:
            raise ScenarioError(
                f"{self.scenario.source}: [planner.mcts].weather = 'members' needs ensemble members (there are none: "
                "route --planner samples the scenario's weather alone; use 'perturbed', or pass members to "
                "PlanningProblem.of)"
            )

    @property
    def start(self) -> tuple[float, float]:
        """Start (lon, lat) [deg]."""
        return self.scenario.start

    @property
    def finish(self) -> tuple[float, float]:
        """Finish (lon, lat) [deg]."""
        return self.scenario.finish

    @property
    def departure(self) -> np.datetime64:
        """Departure (UTC)."""
        return self.problem.departure

    def great_circle_km(self) -> float:
        """Start to finish along the great circle [km]."""
        return float(geodesy.distance_km(*self.start, *self.finish))

    def box(self) -> tuple[float, float, float, float]:
        """The planning box (west, south, east, north) [deg]: the DP grid's bounding box grown by
        :data:`BOX_PAD_DEG`."""
        g = self.grid
        lon = np.concatenate([g.lon_deg.ravel(), [g.start[0], g.finish[0]]])
        lat = np.concatenate([g.lat_deg.ravel(), [g.start[1], g.finish[1]]])
        return (
            max(float(lon.min()) - BOX_PAD_DEG, -180.0),
            max(float(lat.min()) - BOX_PAD_DEG, -89.0),
            min(float(lon.max()) + BOX_PAD_DEG, 180.0),
            min(float(lat.max()) + BOX_PAD_DEG, 89.0),
        )

    def land(self) -> Any:
        """Land in the planning box grown by the scenario's margin (read once), or None without land avoidance."""
        avoid = self.scenario.avoid
        if not avoid.land:
            return None
        if self._land is None:
            geom = land_geometry(self.box(), margin_km=avoid.margin_km, resolution=avoid.resolution)
            object.__setattr__(self, "_land", geom)
        return self._land

    def speed_kn(
        self,
        lon_deg: npt.ArrayLike,
        lat_deg: npt.ArrayLike,
        course_deg: npt.ArrayLike,
        t_h: float,
        *,
        weather: WeatherSource | None = None,
    ) -> FloatArray:
        """Speed over ground on courses at points [kn]: a :data:`PROBE_NM` leg costed like every arc (polar, waves,
        currents, one weather sample at the point); 0 where it cannot be sailed."""
        problem = replace(self.problem, samples=1)
        if weather is not None:
            problem = replace(problem, weather=weather)
        lon, lat, course = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (lon_deg, lat_deg, course_deg)))
        lon1, lat1 = geodesy.destination_point(lon, lat, course, PROBE_NM * KM_PER_NM)
        legs = problem.costs(lon, lat, lon1, lat1, t_h)
        d = geodesy.distance_nm(lon, lat, lon1, lat1)
        with np.errstate(divide="ignore"):
            return np.where(np.isfinite(legs.time_h), d / np.asarray(legs.time_h), 0.0)

    def headings_step(
        self, lon: float, lat: float, t_h: float, headings_deg: FloatArray, step_h: float, *, weather: Any = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, SailedLegs]:
        """Sail each heading for ``step_h`` at the speed over ground on it at the step's start, and the leg straight
        to the finish: the headings' true wind angles [deg], end points [deg] and the legs (:meth:`sail`; the last
        leg is the one to the finish)."""
        problem = self.problem if weather is None else replace(self.problem, weather=weather)
        cond = problem.weather_at(lon, lat, t_h)
        twa = geodesy.angle_diff_deg(np.asarray(cond.twd_deg, dtype=float), headings_deg)
        if cond.has_current:
            v = self.speed_kn(lon, lat, headings_deg, t_h, weather=weather)
        else:  # the boat's speed through the water at the step's start: the polar, slowed in waves
            v = np.nan_to_num(problem.polar.speed(twa, np.asarray(cond.tws_kn, dtype=float), beyond=problem.beyond))
            if problem.wave_loss is not None:
                v = v * problem.wave_loss.factor(cond.hs_m)
        v = np.where(v > 0, v, 0.0)
        lon1, lat1 = geodesy.destination_point(lon, lat, headings_deg, np.maximum(v, 1e-6) * step_h * KM_PER_NM)
        legs = self.sail(
            lon, lat, np.append(lon1, self.finish[0]), np.append(lat1, self.finish[1]), t_h, weather=weather
        )
        ok = legs.ok & np.append(v > 0, True)
        return twa, lon1, lat1, SailedLegs(np.where(ok, legs.time_h, np.inf), legs.p_f, ok)

    def sail(
        self,
        lon0: npt.ArrayLike,
        lat0: npt.ArrayLike,
        lon1: npt.ArrayLike,
        lat1: npt.ArrayLike,
        t0_h: npt.ArrayLike,
        *,
        weather: WeatherSource | None = None,
    ) -> SailedLegs:
        """Sail great-circle legs leaving at ``t0_h`` [h after departure]: the DP's arc cost, land and zones.

        Parameters
        ----------
        lon0, lat0, lon1, lat1 : Legs' end points [deg]; broadcast together.
        t0_h : Departure time of each leg [h after the scenario's departure].
        weather : Another weather source (an ensemble member); default the scenario's.
        """
        problem = self.problem if weather is None else replace(self.problem, weather=weather)
        a = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (lon0, lat0, lon1, lat1, t0_h)))
        costs = problem.costs(a[0], a[1], a[2], a[3], a[4])
        time = np.array(costs.time_h, dtype=float, ndmin=1).reshape(a[0].shape)
        avoid = self.scenario.avoid
        w, s, e, n = self.box()
        ok = np.isfinite(time) & (a[2] >= w) & (a[2] <= e) & (a[3] >= s) & (a[3] <= n)
        land = self.land()
        if land is not None and ok.any():
            flat = ok.ravel().copy()
            pick = np.flatnonzero(flat)
            lon0, lat0, lon1, lat1 = (v.ravel()[pick] for v in a[:4])
            flat[pick[arcs_blocked(lon0, lat0, lon1, lat1, land)]] = False
            ok = flat.reshape(ok.shape)
        if avoid.zones and ok.any():
            t_start = hours_after(problem.departure, a[4])
            t_end = hours_after(problem.departure, a[4] + np.where(ok, time, 0.0))
            ok &= ~arcs_blocked_by_zones(a[0], a[1], a[2], a[3], avoid.zones, t_start, time_end=t_end)
        return SailedLegs(
            time_h=np.where(ok, time, np.inf), p_f=np.array(costs.p_f, dtype=float).reshape(time.shape), ok=ok
        )

    def retime(self, lon_deg: npt.ArrayLike, lat_deg: npt.ArrayLike) -> tuple[FloatArray, bool]:
        """Sail a track leg after leg: the time at each point [h after departure] and whether every leg may be
        sailed (:meth:`sail`)."""
        lon, lat = np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float)
        elapsed = np.zeros(lon.size)
        ok = True
        for i in range(lon.size - 1):
            leg = self.sail(lon[i], lat[i], lon[i + 1], lat[i + 1], elapsed[i])
            ok &= bool(leg.ok.all())
            elapsed[i + 1] = elapsed[i] + float(leg.time_h.ravel()[0])
        return elapsed, ok


@dataclass(frozen=True)
class PlannedTrack:
    """A planner's answer: its track, the times it sailed it in, and what it cost to find.

    Attributes
    ----------
    planner : The planner's name (:data:`~pyroute_rel.planners.settings.PLANNERS`).
    lon_deg, lat_deg : Track points [deg], from the start; at the finish when :attr:`reached`.
    elapsed_h : Time at each point as the planner sailed it [h after departure].
    reached : True when the track ends at the finish.
    stats : What the planner did: ``runtime_s`` [s] and, by planner, ``iterations``, ``episodes``,
        ``training_s`` [s], ``decisions``, ... (plain JSON values).
    """

    planner: str
    lon_deg: FloatArray
    lat_deg: FloatArray
    elapsed_h: FloatArray
    reached: bool
    stats: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_instance(self.planner, str, "PlannedTrack.planner", TrackError)
        object.__setattr__(self, "reached", check_flag(self.reached, "PlannedTrack.reached", TrackError))
        check_instance(self.stats, dict, "PlannedTrack.stats", TrackError)
        size = None
        for name in ("lon_deg", "lat_deg", "elapsed_h"):
            values = check_numbers(getattr(self, name), f"PlannedTrack.{name}", TrackError, infinite=True)
            size = values.size if size is None else size
            if values.ndim != 1 or values.size != size or values.size < 1:
                raise TrackError(f"PlannedTrack.{name} must be a 1-D array, one value per track point")
            object.__setattr__(self, name, values)

    @property
    def voyage_time_h(self) -> float:
        """Time at the last point [h] (the voyage time when :attr:`reached`)."""
        return float(self.elapsed_h[-1])

    def points(self) -> FloatArray:
        """The track as an (N, 2) array of (lon, lat) [deg], what :func:`pyroute_rel.analysis.evaluate.evaluate_track`
        takes."""
        return np.column_stack([self.lon_deg, self.lat_deg])


@runtime_checkable
class Planner(Protocol):
    """A planner: takes the routing problem, returns a track (the evaluator re-times it)."""

    name: str

    def plan(self, problem: PlanningProblem, *, progress: bool = False) -> PlannedTrack:
        """Plan a track from the problem's start to its finish."""
        ...
