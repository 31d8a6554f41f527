"""The compiled MCTS-UCT search (numba): the tree and the rollouts of one decision, over the weather on a lattice.

:class:`~pyroute_rel.planners.mcts.MCTSPlanner` with ``engine = "lattice"`` (the default) runs each decision's
``iterations`` here. What the Python engine asks of the weather, polar, failure model, land and zones at every
simulated step is read from a :class:`~pyroute_rel.planners.mcts_lattice.Lattice` built once per voyage: the wind
(two components, bilinear in space, the nearest time slice), the wave speed factor, which headings the failure
model allows (apf) and which cells are open water (land, zones, the planning box), at the nearest lattice point.
One step from ``(lon, lat, t)`` on heading ``h``:

- the wind there, plus ``sigma * N(0, 1)`` per component in ``"perturbed"`` weather (one draw per step and
  component, as Barde samples the weather at each step);
- the heading may be sailed when its true wind angle is within [``nogo_min``, ``nogo_max``], the failure model
  allows it at the step's start, middle and end (as the DP judges a leg all along it), the polar (the DP's own
  lookup, :func:`pyroute_rel._kernels.polar.speed_kn`) times the wave factor gives at least
  :data:`~pyroute_rel.boat.polar.MIN_SPEED_KN`, and the step's middle and end are in open cells;
- the craft sails ``speed * step_h`` along the great circle (spherical Earth, as :mod:`pyroute_rel.geodesy`) and
  the step takes ``step_h``;
- when the finish is within ``speed * step_h`` on its bearing, sailing straight to it is the only action (it takes
  ``distance / speed``).

The tree is open-loop: a node is a sequence of actions; every iteration re-simulates its path from the root in the
iteration's weather (a member drawn at random with ``members``, fresh noise with ``"perturbed"``), so one tree
serves every weather sample. Selection (UCB1, ``W/N + 2 C_p sqrt(2 ln N_parent / N)``), expansion of one untried
valid action at random, rollout and backup are those of :mod:`pyroute_rel.planners.mcts`. The rollout draws a
heading uniformly among the valid ones within 90 deg of the finish's bearing (any valid one when none is): the
candidates are tried in a random order and the first valid one is sailed, which has that distribution and skips
the others' geometry.

Random numbers come from two splitmix64 streams held in a ``uint64[2]`` array: stream 0 for the tree and rollout
choices and the member draws, stream 1 for the weather noise, so ``sigma = 0`` gives the same search as
``"forecast"``, and a seed gives the same search on every machine.

Twin: the Python engine of :mod:`pyroute_rel.planners.mcts` (``engine = "python"``); pinned by
``tests/test_planners_mcts.py`` (a full search finds the brute-force best of each first heading, steps sail at the
DP's polar speeds, land, zones and apf are respected).

References
----------
Steele, G. L., Lea, D. and Flood, C. H. (2014). Fast splittable pseudorandom number generators. OOPSLA 2014,
doi:10.1145/2660193.2660195 (splitmix64).
"""

from __future__ import annotations

import math
from typing import TypedDict

import numba
import numpy as np

from pyroute_rel._kernels.polar import speed_kn
from pyroute_rel.units import EARTH_RADIUS_KM, KM_PER_NM

__all__ = ["search", "sailing_speeds", "PARAMS", "N_PARAMS"]

#: Names of the scalar parameters of :func:`search`, in the order of its ``params`` array.
PARAMS = (
    "lon0",  # lattice origin (west) [deg]
    "lat0",  # lattice origin (south) [deg]
    "dlon",  # lattice spacing [deg]
    "dlat",
    "slice_h",  # time between the lattice's slices [h]
    "step_h",  # time between decisions [h]
    "nogo_min",  # [deg]
    "nogo_max",  # [deg]
    "finish_lon",
    "finish_lat",
    "time_max",  # TimeMax [h]
    "time_min",  # TimeMin [h]
    "reward_c",
    "top_kn",  # top speed over ground (a rollout stopped short is dated t + rest / top) [kn]
    "rollout_h",  # longest rollout [h]; 0: to the time limit
    "cp",  # C_p
    "min_speed",  # slowest speed that sails [kn]
    "forbid_beyond",  # 1: the polar gives no speed beyond its table, 0: clamp
    "perturbed",  # 1: add sigma * N(0, 1) to each wind component at each step
)
N_PARAMS = len(PARAMS)
_LON0, _LAT0, _DLON, _DLAT, _SLICE, _STEP, _NOGO0, _NOGO1, _FLON, _FLAT = range(10)
_TMAX, _TMIN, _C, _TOP, _ROLL, _CP, _VMIN, _FORBID, _PERT = range(10, 19)

_R_NM = EARTH_RADIUS_KM / KM_PER_NM
_D2R = math.pi / 180.0
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)


class _JitOptions(TypedDict):
    """The options every kernel here is compiled with (typed, so numba's stubs check them as keywords)."""

    nogil: bool
    cache: bool


_JIT: _JitOptions = {"nogil": True, "cache": True}


@numba.njit(inline="always", **_JIT)
def _next(rng, k):  # type: ignore[no-untyped-def]  # pragma: no cover
    """splitmix64: the next 64 random bits of stream ``k``."""
    z = rng[k] + _GOLDEN
    rng[k] = z
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@numba.njit(inline="always", **_JIT)
def _uniform(rng, k):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Uniform in [0, 1) with 53 random bits."""
    return float(_next(rng, k) >> _S11) * (1.0 / 9007199254740992.0)


@numba.njit(**_JIT)
def _below(rng, n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Uniform whole number in [0, n) from stream 0."""
    return min(int(_uniform(rng, 0) * n), n - 1)


@numba.njit(**_JIT)
def _normal(rng):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Standard normal from stream 1 (Box-Muller, one of the pair)."""
    u1 = 1.0 - _uniform(rng, 1)
    u2 = _uniform(rng, 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@numba.njit(inline="always", **_JIT)
def _fold(a):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The angle between two directions [deg], in [0, 180]."""
    a = abs(a) % 360.0
    return min(a, 360.0 - a)


@numba.njit(inline="always", **_JIT)
def _speed(twa, tws, polar, P):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Boat speed [kn] at ``twa`` [deg] in [0, 180] and ``tws`` [kn]: the DP's lookup
    (:func:`pyroute_rel._kernels.polar.speed_kn`) in the tables of :func:`pyroute_rel._kernels.polar.tables`."""
    return speed_kn(twa, tws, polar[0], polar[1], polar[2], polar[3], polar[4], P[_FORBID] != 0.0)


@numba.njit(**_JIT)
def sailing_speeds(twa, tws, polar, forbid):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The boat speeds [kn] the search sails at, at each true wind angle ``twa`` [deg] in [0, 180] and speed
    ``tws`` [kn] (float64 arrays of one size), with the polar's ``tables`` (:func:`pyroute_rel._kernels.polar.tables`);
    ``forbid``: 0 kn beyond the table (else clamp)."""
    P = np.zeros(N_PARAMS)
    P[_FORBID] = 1.0 if forbid else 0.0
    out = np.empty(twa.size)
    for n in range(twa.size):
        out[n] = _speed(twa[n], tws[n], polar, P)
    return out


@numba.njit(inline="always", **_JIT)
def _destination(lon, lat, course, dist_nm):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The point ``dist_nm`` from (lon, lat) on ``course`` along the great circle [deg]."""
    p, th, d = lat * _D2R, course * _D2R, dist_nm / _R_NM
    lat1 = math.asin(min(max(math.sin(p) * math.cos(d) + math.cos(p) * math.sin(d) * math.cos(th), -1.0), 1.0))
    lon1 = lon + math.atan2(math.sin(th) * math.sin(d) * math.cos(p), math.cos(d) - math.sin(p) * math.sin(lat1)) / _D2R
    return (lon1 + 540.0) % 360.0 - 180.0, lat1 / _D2R


@numba.njit(inline="always", **_JIT)
def _distance_bearing(lon0, lat0, lon1, lat1):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Great-circle distance [nm] (haversine) and initial bearing [deg] from point 0 to point 1."""
    p0, p1, dl = lat0 * _D2R, lat1 * _D2R, (lon1 - lon0) * _D2R
    h = math.sin((p1 - p0) / 2.0) ** 2 + math.cos(p0) * math.cos(p1) * math.sin(dl / 2.0) ** 2
    dist = 2.0 * _R_NM * math.asin(min(math.sqrt(h), 1.0))
    y = math.sin(dl) * math.cos(p1)
    x = math.cos(p0) * math.sin(p1) - math.sin(p0) * math.cos(p1) * math.cos(dl)
    return dist, (math.atan2(y, x) / _D2R) % 360.0


@numba.njit(inline="always", **_JIT)
def _open(lon, lat, k, m, h, okh, open_, P):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Whether a point is in an open cell of slice ``k`` (inside the lattice, not land nor an active zone) where the
    failure model allows heading ``h`` (``h < 0``: any)."""
    fx = (lon - P[_LON0]) / P[_DLON]
    fy = (lat - P[_LAT0]) / P[_DLAT]
    ny, nx = open_.shape[1], open_.shape[2]
    if not (fx >= -0.5 and fy >= -0.5 and fx < nx - 0.5 and fy < ny - 0.5):
        return False
    j, i = int(fy + 0.5), int(fx + 0.5)
    if open_[min(k, open_.shape[0] - 1), j, i] == 0:
        return False
    return h < 0 or okh[m, min(k, okh.shape[1] - 1), j, i, h] != 0


@numba.njit(**_JIT)
def _conditions(lon, lat, t, m, W, P, rng):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The weather a step starts in: (ok, k, j, i, tws [kn], twd [deg], wave factor); noise drawn when perturbed."""
    u_, v_, f_, sig_u, sig_v = W[0], W[1], W[2], W[3], W[4]
    ny, nx = u_.shape[2], u_.shape[3]
    k = max(int(t / P[_SLICE] + 0.5), 0)  # each array is read at its own last slice after that
    kw = min(k, u_.shape[1] - 1)
    fx = (lon - P[_LON0]) / P[_DLON]
    fy = (lat - P[_LAT0]) / P[_DLAT]
    eu, ev = 0.0, 0.0
    if P[_PERT] != 0.0:
        eu, ev = _normal(rng), _normal(rng)
    if not (fx >= 0.0 and fy >= 0.0 and fx <= nx - 1 and fy <= ny - 1):
        return False, k, 0, 0, 0.0, 0.0, 0.0
    i0, j0 = min(int(fx), nx - 2), min(int(fy), ny - 2)
    ax, ay = fx - i0, fy - j0
    u = (u_[m, kw, j0, i0] * (1 - ax) + u_[m, kw, j0, i0 + 1] * ax) * (1 - ay) + (
        u_[m, kw, j0 + 1, i0] * (1 - ax) + u_[m, kw, j0 + 1, i0 + 1] * ax
    ) * ay
    v = (v_[m, kw, j0, i0] * (1 - ax) + v_[m, kw, j0, i0 + 1] * ax) * (1 - ay) + (
        v_[m, kw, j0 + 1, i0] * (1 - ax) + v_[m, kw, j0 + 1, i0 + 1] * ax
    ) * ay
    i, j = int(fx + 0.5), int(fy + 0.5)
    if P[_PERT] != 0.0:  # sigma may be one value per slice (shape (K, 1, 1))
        ks = min(k, sig_u.shape[0] - 1)
        js, is_ = min(j, sig_u.shape[1] - 1), min(i, sig_u.shape[2] - 1)
        u += sig_u[ks, js, is_] * eu
        v += sig_v[ks, js, is_] * ev
    f = f_[m, min(k, f_.shape[1] - 1), j, i]
    if not (np.isfinite(u) and np.isfinite(v) and np.isfinite(f)):
        return False, k, j, i, 0.0, 0.0, 0.0
    return True, k, j, i, math.hypot(u, v), (math.atan2(u, v) / _D2R) % 360.0, f


@numba.njit(**_JIT)
def _try_heading(lon, lat, h, hdg, cond, m, W, okh, open_, polar, P):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Sail heading ``h`` for a step from (lon, lat) in ``cond``: (ok, lon1, lat1)."""
    _, k, j, i, tws, twd, f = cond
    twa = _fold(twd - hdg[h])
    if okh[m, min(k, okh.shape[1] - 1), j, i, h] == 0 or twa < P[_NOGO0] or twa > P[_NOGO1]:
        return False, lon, lat
    speed = _speed(twa, tws, polar, P) * f
    if not speed >= P[_VMIN]:
        return False, lon, lat
    dist = speed * P[_STEP]
    lon1, lat1 = _destination(lon, lat, hdg[h], dist)
    # the middle of a step (a few nm, well inside a cell) as the mean of its ends
    if not (
        _open(lon1, lat1, k, m, h, okh, open_, P)
        and _open(0.5 * (lon + lon1), 0.5 * (lat + lat1), k, m, h, okh, open_, P)
    ):
        return False, lon, lat
    return True, lon1, lat1


@numba.njit(**_JIT)
def _finish_in_reach(lon, lat, dist, bearing, cond, hdg, m, okh, open_, polar, P):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The time to sail straight to the finish, ``dist`` [nm] away on ``bearing`` [deg], when it is within a step
    [h], else inf."""
    _, k, j, i, tws, twd, f = cond
    if dist > P[_TOP] * P[_STEP]:  # out of reach at the top speed
        return math.inf
    h = int(bearing / (360.0 / hdg.size) + 0.5) % hdg.size  # the failure model's verdict of the nearest heading
    speed = _speed(_fold(twd - bearing), tws, polar, P) * f
    if not speed >= P[_VMIN] or dist > speed * P[_STEP] or okh[m, min(k, okh.shape[1] - 1), j, i, h] == 0:
        return math.inf
    if not _open(0.5 * (lon + P[_FLON]), 0.5 * (lat + P[_FLAT]), k, m, h, okh, open_, P):
        return math.inf
    return dist / speed


@numba.njit(**_JIT)
def _moves(lon, lat, t, m, hdg, W, okh, open_, polar, P, rng, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Every action from a state: ``out[a] = (ok, lon1, lat1, dt)`` for the headings and the finish (last row);
    when the finish is in reach it is the only action. Returns the number of valid actions."""
    n_h = hdg.size
    out[:, 0] = 0.0
    cond = _conditions(lon, lat, t, m, W, P, rng)
    if not cond[0]:
        return 0
    dist, bearing = _distance_bearing(lon, lat, P[_FLON], P[_FLAT])
    dt = _finish_in_reach(lon, lat, dist, bearing, cond, hdg, m, okh, open_, polar, P)
    if dt < math.inf:
        out[n_h, 0], out[n_h, 1], out[n_h, 2], out[n_h, 3] = 1.0, P[_FLON], P[_FLAT], dt
        return 1
    count = 0
    for h in range(n_h):
        ok, lon1, lat1 = _try_heading(lon, lat, h, hdg, cond, m, W, okh, open_, polar, P)
        if ok:
            out[h, 0], out[h, 1], out[h, 2], out[h, 3] = 1.0, lon1, lat1, P[_STEP]
            count += 1
    return count


@numba.njit(**_JIT)
def _rollout(lon, lat, t, m, hdg, W, okh, open_, polar, P, rng, order):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The date a random rollout from (lon, lat, t) arrives [h] (inf: a dead end; see the module notes)."""
    n_h = hdg.size
    limit = P[_TMAX] if P[_ROLL] <= 0.0 else min(P[_TMAX], t + P[_ROLL])
    while True:
        dist, bearing = _distance_bearing(lon, lat, P[_FLON], P[_FLAT])
        if t >= limit:
            return t + dist / P[_TOP]
        cond = _conditions(lon, lat, t, m, W, P, rng)
        if not cond[0]:
            return math.inf
        dt = _finish_in_reach(lon, lat, dist, bearing, cond, hdg, m, okh, open_, polar, P)
        if dt < math.inf:
            return t + dt
        moved = False
        for gain in (True, False):
            n = 0
            for h in range(n_h):
                if (_fold(hdg[h] - bearing) < 90.0) == gain or not gain:
                    order[n] = h
                    n += 1
            while n > 0 and not moved:  # the first valid candidate of a random order
                r = _below(rng, n)
                h = order[r]
                order[r] = order[n - 1]
                n -= 1
                ok, lon1, lat1 = _try_heading(lon, lat, h, hdg, cond, m, W, okh, open_, polar, P)
                if ok:
                    lon, lat, t, moved = lon1, lat1, t + P[_STEP], True
            if moved:
                break
        if not moved:
            return math.inf


@numba.njit(**_JIT)
def _reward(date, P):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Barde's reward ``exp((TimeMax c - date) / (TimeMax c - TimeMin))``, 0 for a dead end."""
    if not date < math.inf:
        return 0.0
    top = P[_TMAX] * P[_C]
    return math.exp((top - date) / (top - P[_TMIN]))


@numba.njit(**_JIT)
def _select(node, out, children, visits, wins, cp):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The valid action of ``node`` to descend: an untried one (negative: ``-1 - count`` untried) or UCB1's."""
    n_a = children.shape[1]
    untried = 0
    for a in range(n_a):
        if out[a, 0] != 0.0 and children[node, a] < 0:
            untried += 1
    if untried:
        return -1 - untried
    log_n = math.log(max(visits[node], 1))
    best, pick = -math.inf, -1
    for a in range(n_a):
        if out[a, 0] != 0.0:
            c = children[node, a]
            ucb = wins[c] / visits[c] + 2.0 * cp * math.sqrt(2.0 * log_n / visits[c])
            if ucb > best:
                best, pick = ucb, a
    return pick


@numba.njit(**_JIT)
def _iterate(root, hdg, W, okh, open_, polar, P, rng, tree, out, path, order):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One UCT iteration from ``root = (lon, lat, t)``: selection, expansion, rollout, backup."""
    children, visits, wins, best, size = tree
    n_members = W[0].shape[0]
    m = _below(rng, n_members) if n_members > 1 else 0
    lon, lat, t = root[0], root[1], root[2]
    node, depth, date = 0, 1, math.inf
    path[0] = 0
    n_h = hdg.size
    while True:
        if t > P[_TMAX] or _moves(lon, lat, t, m, hdg, W, okh, open_, polar, P, rng, out) == 0:
            break  # too late or a dead end
        a = _select(node, out, children, visits, wins, P[_CP])
        if a < 0:  # expand an untried action at random
            r = _below(rng, -1 - a)
            for a in range(n_h + 1):
                if out[a, 0] != 0.0 and children[node, a] < 0:
                    if r == 0:
                        break
                    r -= 1
            child = size[0]
            size[0] += 1
            children[node, a] = child
        else:
            child = children[node, a]
        path[depth] = child
        depth += 1
        node, lon, lat, t = child, out[a, 1], out[a, 2], t + out[a, 3]
        if a == n_h:  # at the finish
            date = t
            break
        if visits[child] == 0:  # just expanded: roll out from it
            date = _rollout(lon, lat, t, m, hdg, W, okh, open_, polar, P, rng, order)
            break
    r = _reward(date, P)
    for d in range(depth):
        v = path[d]
        visits[v] += 1
        wins[v] += r
        best[v] = max(best[v], r)


#: Iterations run per compiled call of :func:`search` (between calls it reports its progress).
CHUNK = 20_000


def search(root, iterations, hdg, W, okh, open_, polar, P, rng, progress=None):  # type: ignore[no-untyped-def]
    """Run ``iterations`` UCT iterations from ``root = (lon [deg], lat [deg], t [h])``.

    Parameters
    ----------
    root : float64[3].
    iterations : Number of iterations.
    hdg : The headings [deg], float64[H].
    W : Wind "from" components u = tws sin(twd), v = tws cos(twd) [kn], float32[M, K, NY, NX] each; wave speed
        factor float32[M, K, NY, NX]; sigma of each component [kn] float32[K, NY, NX] or [K, 1, 1] (twice). Each
        array has its own number of time slices K (1: steady); past its last slice it is read at the last.
    okh : Whether the failure model allows each heading, uint8[M, K, NY, NX, H].
    open_ : Open cells, uint8[K, NY, NX].
    polar : The polar's tables, as :func:`pyroute_rel._kernels.polar.tables` gives them.
    P : The scalar parameters (:data:`PARAMS`), float64.
    rng : The two random streams, uint64[2] (advanced in place).
    progress : Called with the number of iterations run, every :data:`CHUNK` of them and at the end (a long
        decision shows its progress; the tree and the random streams are those of one call: chunks change nothing).

    Returns
    -------
    visits, wins, best : Of each root action (the headings, then the finish) [-]; 0 for those never tried.
    """
    n_a = hdg.size + 1
    tree, scratch = _new_tree(int(iterations), n_a, hdg.size)
    done = 0
    while done < iterations:
        n = min(CHUNK, int(iterations) - done)
        _grow(root, n, hdg, W, okh, open_, polar, P, rng, tree, *scratch)
        done += n
        if progress is not None:
            progress(n)
    return _root_stats(tree[0], tree[1], tree[2], tree[3], n_a)


@numba.njit(**_JIT)
def _new_tree(iterations, n_a, n_h):  # type: ignore[no-untyped-def]  # pragma: no cover
    """A tree of room for ``iterations`` iterations (children, visits, wins, best, size) and the scratch of one
    iteration (out, path, order)."""
    cap = iterations + 2
    children = np.full((cap, n_a), -1, dtype=np.int64)
    visits = np.zeros(cap, dtype=np.int64)
    wins = np.zeros(cap)
    best = np.zeros(cap)
    size = np.ones(1, dtype=np.int64)
    return (children, visits, wins, best, size), (np.zeros((n_a, 4)), np.zeros(cap + 1, dtype=np.int64),
                                                  np.zeros(n_h, dtype=np.int64))  # fmt: skip


@numba.njit(**_JIT)
def _grow(root, n, hdg, W, okh, open_, polar, P, rng, tree, out, path, order):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``n`` more iterations of :func:`_iterate` on ``tree``."""
    for _ in range(n):
        _iterate(root, hdg, W, okh, open_, polar, P, rng, tree, out, path, order)


@numba.njit(**_JIT)
def _root_stats(children, visits, wins, best, n_a):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Visits, wins and best reward of each root action (0 for those never tried)."""
    v, w, b = np.zeros(n_a, dtype=np.int64), np.zeros(n_a), np.zeros(n_a)
    for a in range(n_a):
        c = children[0, a]
        if c >= 0:
            v[a], w[a], b[a] = visits[c], wins[c], best[c]
    return v, w, b
