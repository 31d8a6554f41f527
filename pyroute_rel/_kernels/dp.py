"""Compiled twin of one rank of the forward DP, for steady wind-only problems (issue 18) and, on uniform weather with
patches, with a failure model (issue 32).

Where the arc costs need nothing but the wind (steady weather, no failure model, wave speed loss, current, obstacle
mask, waiting or finish line), :func:`~pyroute_rel.routing.solve.forward_dp` hands each rank to :func:`rank_step`, which
does what the numpy path does operation for operation -- TWA, bilinear polar speed, time per sub-segment
(:mod:`pyroute_rel._kernels.polar`, shared with :mod:`pyroute_rel._kernels.cost`), the arc's reason flags, pruning
(each node's four arcs of smallest lower bound first, then every arc whose bound does not exceed the best of them,
see ``RoutingProblem.prune``), the arrival from each source label with the time of a change of side
(:mod:`pyroute_rel.boat.manoeuvre`: labels (node, side), the plain DP being the case of one label) and the earliest
arrival at each label -- without a temporary array per step. Its results are bit-identical to the numpy path's
(arrival times, back-pointers, labels, counts; property-tested).

Five ways through a rank share the per-arc arithmetic:

- with one label per node and pruning (the paper's square grid) on uniform weather (a :class:`BoxWind`: one wind
  everywhere but in patches), the whole rank is one compiled call, :func:`_boxed_rank`: per node the bounds of its
  arcs, the four of smallest bound costed, then the arcs whose bound does not exceed the best of them (on the square
  160 x 160 grid 0.89 M of 4.07 M arcs), the wind sampled in the kernel and the polar's interpolation along its
  wind-speed axis done once per wind speed (the same arithmetic as
  :func:`~pyroute_rel._kernels.polar.speed_kn`);
- the same with a failure model on uniform weather with patches, :func:`_boxed_fail_rank`: each arc costed is also
  judged at its samples as the cost function judges it, and each node's best arc, where its samples cannot judge it
  alone, on every piece it crosses (:mod:`pyroute_rel._kernels.crossings`, the numbers of
  :func:`~pyroute_rel.reliability.crossings.arc_extremes`), the next best tried while the best is forbidden: the numpy
  path's lazy judgement (:func:`~pyroute_rel.routing.solve._lazy_pieces`), one arc at a time (also on ranks of at most
  four arcs per node, such as the first from one start point, where the first four are every arc). Arrival times,
  back-pointers and the arcs costed are the numpy path's; the arcs counted as forbidden by the failure model are at most
  the eager count (only the arcs judged are counted, as in the numpy path's lazy judgement, which judges in batches).
  In steady weather what an arc meets does not depend on when it is sailed, so its judgements (at its samples: reason
  flags, criteria fired, whether it may wait for its pieces; on its pieces: over apf or not, criteria fired) are kept
  for the next DPs on the same grid, samples per arc, weather, model and apf (:class:`Judged`, their state and the
  criteria fired in a uint16 per arc: 8 MB on the square 160 x 160 grid), recorded where the kernel makes them and
  taken where it would make them again, with the same effects in the same order: a DP taking them finds what a DP
  judging afresh finds, its counts included (:func:`~pyroute_rel.routing.solve.forward_dp` keeps them in the current
  store, :mod:`pyroute_rel.store`; ``kept(False)`` keeps none);
- with side labels on uniform weather, the whole rank is one compiled call too, :func:`_boxed_sides_rank`: per node
  the side of each arc (the wind at its first sample), and with pruning each side's four arcs of smallest bound
  costed, then the arcs whose bound does not exceed their side's best (each label pruned against its own best), the
  wind sampled as in :func:`_boxed_rank` and a manoeuvre's time computed once per wind speed;
- with pruning and one label on other weather, the weather is sampled only where an arc is costed, as the numpy
  path's pruning does, in three short kernels between which the caller samples the wind at the picked arcs;
- otherwise (side labels or no pruning on other weather, or no pruning on uniform weather) the wind is sampled at
  every arc and one kernel does the rank.

Kernels take contiguous, writable arrays (one compiled signature each). numba is imported only by problems this
path serves.

Numpy twin: the numpy rank of :func:`pyroute_rel.routing.solve.forward_dp`
(:attr:`~pyroute_rel.settings.Settings.compiled_rank_step` False); pinned by
``tests/test_dp_compiled.py::test_compiled_rank_step_equals_numpy`` and ``tests/test_dp_compiled_failure.py``; the
judgements kept (a DP taking them equals one judging afresh, each kept input changed gets a fresh judgement) by
``tests/test_dp_judged.py``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import NamedTuple

import numba
import numpy as np
import numpy.typing as npt

from pyroute_rel._kernels import polar as polar_compiled
from pyroute_rel._kernels.crossings import BoxFields, arc_p_f, needs_judging, sample_evidence
from pyroute_rel._kernels.polar import cell, fold_twa, speed_kn, sub_time
from pyroute_rel.boat.manoeuvre import ManoeuvrePenalties
from pyroute_rel.boat.polar import MIN_SPEED_KN, Polar
from pyroute_rel.store import kept_by

__all__ = ["BoxWind", "FailureJudge", "Judged", "RankStep", "rank_step"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
#: ``wind(pick)``: the wind speed [kn] and direction (from) [deg] at the samples of the arcs ``pick`` (flat indices
#: ``node * arcs + arc``: shape (n, samples)) or of every arc (None: shape (nodes, arcs, samples)); None when the
#: weather has a current there (the compiled step does not model it).
WindSampler = Callable[[IntArray | None], tuple[FloatArray, FloatArray] | None]


class BoxWind(NamedTuple):
    """Wind that is one value everywhere but inside lon/lat boxes (a later box wins where two overlap), at the arcs'
    sample points: :class:`~pyroute_rel.weather.uniform.UniformWeather`'s wind
    (:meth:`~pyroute_rel.weather.uniform.UniformWeather.wind_boxes`), sampled in the kernel as the weather samples
    it, value for value."""

    #: The wind everywhere outside the boxes: speed [kn] and direction (from) [deg].
    tws_kn: float
    twd_deg: float
    #: Rows ``(lon_min, lon_max, lat_min, lat_max)`` [deg] of the boxes (closed), shape (boxes, 4).
    boxes: FloatArray
    #: The speed [kn] and direction [deg] inside each box (NaN: the box leaves it as it is), shape (boxes, 2).
    values: FloatArray
    #: The arcs' sample points [deg], shape (nodes, arcs, samples) (the geometry's ``lon_deg``, ``lat_deg``).
    lon_deg: FloatArray
    lat_deg: FloatArray


class RankStep(NamedTuple):
    """What :func:`rank_step` finds for a rank: the earliest arrival at each label and how many arcs were costed."""

    #: Earliest arrival at each label [h] (inf where no arc arrives), shape (nodes, labels).
    t_best: FloatArray
    #: The arc it comes by (first of equal ones; 0 where none), same shape.
    j_best: IntArray
    #: The source label it leaves from (first of equal ones; 0 where none), same shape.
    c_best: IntArray
    #: Arcs that leave a reached label.
    live: int
    #: Of those, arcs costed (the others were pruned).
    costed: int
    # : Of those, arcs forbidden, and arcs with each reason (:data:`~pyroute_rel.routing.cost.REASONS` ``polar``,
    # ``weather``).
    forbidden: int
    no_speed: int
    no_wind: int
    #: Of the forbidden arcs, those forbidden by the failure model, and of those, how many fire each criterion.
    failed: int = 0
    by_criterion: npt.NDArray[np.int64] | None = None


class FailureJudge(NamedTuple):
    """A failure model on uniform weather with patches, as :func:`rank_step` judges arcs with it: the fields and
    classifier (:func:`~pyroute_rel._kernels.crossings.box_fields`), each arc's ends as unit vectors, and the
    judgements of the rank's arcs kept from earlier DPs, if any (:meth:`Judged.rank`)."""

    #: :func:`~pyroute_rel._kernels.crossings.box_fields` of the weather, model and apf.
    fields: BoxFields
    #: Each arc's start, shape (nodes, arcs, 3), and each node's position, shape (nodes, 3) (unit vectors).
    a_xyz: FloatArray
    b_xyz: FloatArray
    #: The rank's kept judgements, one per arc (:class:`Judged`), shape (nodes, arcs), read and filled by the kernel;
    #: None: nothing kept (every arc is judged afresh).
    judged: npt.NDArray[np.uint16] | None = None


# The bits of an arc's kept judgement (:class:`Judged`). Its samples' (set together, the first time the arc is costed):
_SAMPLED = 1  # judged at its samples (the next three bits hold)
_LOST = 2  # a sample's evidence is unknown (the cost function's flag "missing weather")
_OVER = 4  # a sample's p_f exceeds apf (the failure flag); the criteria it fires are in the bits from ``_FIRED``
_BELOW = 8  # the largest p_f at its samples is below the table's largest (it may wait for its pieces)
# Its pieces' (set the first time it is its node's best, allowed, with its samples below the table's largest):
_PIECED = 16  # judged on its pieces, or found not to need them
_FORBID = 32  # p_f along it exceeds apf; the criteria fired along it are in the bits from ``_FIRED``
# The criteria fired (bit c: criterion c), at the samples (``_OVER``) or on the pieces (``_FORBID``; never both: an
# arc waits for its pieces only when its samples forbid nothing), from this bit on.
_FIRED = 6

#: How many next best arcs :func:`_settle_judged` lines up at once after a best found forbidden on its pieces.
_NEXT = 16


class Judged:
    """The judgements :func:`rank_step` made of the arcs of one grid's ranks with one failure model, uniform weather
    with patches and apf, kept for the next DPs on them: in steady weather what an arc meets does not depend on when
    it is sailed, so its judgement at its samples (reason flags, criteria fired, whether it may wait for its pieces)
    and on its pieces (over apf or not, criteria fired) are fixed. Each is recorded where the kernel makes it and,
    once known, taken instead of made again, with the same effects in the same order: a DP with a warm
    :class:`Judged` finds what it finds with a fresh one, counts included (the arcs judged on their pieces are those
    the DP picks, whatever is kept).

    Per rank, made on first use: a uint16 per arc, the bits ``_SAMPLED`` to ``_FORBID`` of this module and the criteria
    fired (:data:`BYTES_PER_ARC`; models of at most :data:`MAX_CRITERIA` criteria). Owned by the caller
    (:func:`~pyroute_rel.routing.solve.forward_dp` keeps one per grid, samples per arc and
    :class:`~pyroute_rel._kernels.crossings.BoxFields` in the current store); a DP uses it while holding
    :attr:`lock` (kernels write to it without the GIL)."""

    #: Bytes kept per arc [bytes].
    BYTES_PER_ARC = 2
    #: The most criteria a model may have for its judgements to be kept (their bits share the arc's uint16).
    MAX_CRITERIA = 16 - _FIRED

    def __init__(self, nbytes: int) -> None:
        #: What it will hold once every rank is filled [bytes] (its size in the store).
        self.nbytes = int(nbytes)
        self.lock = threading.Lock()
        self._ranks: dict[int, npt.NDArray[np.uint16]] = {}

    def rank(self, k: int, shape: tuple[int, int]) -> npt.NDArray[np.uint16]:
        """Rank ``k``'s judgements, shape ``shape`` (nodes, arcs), made empty (nothing judged) on first use."""
        got = self._ranks.get(k)
        if got is None:
            got = self._ranks[k] = np.zeros(shape, dtype=np.uint16)
        assert got.shape == shape  # (the key holds the grid's content: its ranks' shapes do not change)
        return got


def _c(a: npt.ArrayLike, dtype: type = np.float64) -> npt.NDArray:
    if isinstance(a, np.ndarray) and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable:
        return a  # what np.require returns, without its cost (a rank asks for a dozen)
    return np.require(a, dtype, ("C", "W"))


_NO_PENALTIES = ManoeuvrePenalties()


def _penalty_tables(penalties: ManoeuvrePenalties) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The tack and gybe tables (wind speeds [kn], penalties [s]) as the kernels take them, kept by the penalties
    (a :class:`~pyroute_rel.boat.manoeuvre.ManoeuvrePenalties` does not change; :func:`~pyroute_rel.store.kept_by`)."""

    def make() -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        p = penalties
        given = (p.tack_tws_kn, p.tack_penalty_s, p.gybe_tws_kn, p.gybe_penalty_s)
        tack_tws, tack_s, gybe_tws, gybe_s = (_c(np.asarray(a, dtype=float)) for a in given)
        return tack_tws, tack_s, gybe_tws, gybe_s

    return kept_by(penalties, "_kernel_tables", make)  # type: ignore[no-any-return]


def _sides_array(from_sides: tuple[int, ...]) -> npt.NDArray[np.int64]:
    """The source labels' sides as the kernels take them (a rank asks once: made each time)."""
    return np.asarray(from_sides, dtype=np.int64)


def rank_step(
    wind: WindSampler | BoxWind,
    course_deg: FloatArray,
    seg_nm: FloatArray,
    t_prev: FloatArray,
    src: IntArray,
    valid: npt.NDArray[np.bool_],
    polar: Polar,
    *,
    beyond: str,
    bound_kn: float | None,
    from_sides: tuple[int, ...] = (-1,),
    penalties: ManoeuvrePenalties | None = None,
    failure: FailureJudge | None = None,
) -> RankStep | None:
    """One rank of the DP: the earliest arrival at each label [h] and the arc and source label it comes by.

    Parameters
    ----------
    wind : Samples the wind at the arcs (:data:`WindSampler`): at the arcs costed only, when pruning one label per
        node; else at every arc. Or a :class:`BoxWind`, sampled in compiled code (with pruning and one label per
        node, or with side labels, the whole rank is one compiled call).
    course_deg : Great-circle course at the arcs' samples [deg], shape (nodes, arcs, samples).
    seg_nm : Sub-segment length of each arc [nm], shape (nodes, arcs) (the geometry's ``seg_nm[..., 0]``).
    t_prev : Arrival at each label of the previous rank [h] (inf: not reached), shape (source nodes, source labels).
    src, valid : Source node of each arc and whether it exists, shape (nodes, arcs) (``grid.pattern(k)``).
    polar : Boat polar.
    beyond : Polar behaviour outside its table (``"clamp"`` or ``"forbid"``).
    bound_kn : Fastest speed over ground possible [kn], to prune with (``RoutingProblem.prune``; with side labels
        each label's arcs are pruned against that label's best, which the numpy path does not do: it then costs
        every arc, so ``arcs_evaluated`` differs, never the result); None costs every live arc.
    from_sides : Side of each source label (-1: none, no manoeuvre is counted from it).
    penalties : With side labels (:mod:`pyroute_rel.boat.manoeuvre`), the time tacks and gybes cost: each arc's side,
        manoeuvre and its time come from the wind at its first sample, as :func:`~pyroute_rel.boat.manoeuvre.wind_side`,
        :func:`~pyroute_rel.boat.manoeuvre.manoeuvre_kind` and
        :meth:`~pyroute_rel.boat.manoeuvre.ManoeuvrePenalties.penalty_h` compute them (``numpy.interp``'s arithmetic).
        None: one label per node.
    failure : A failure model on uniform weather with patches (``wind`` a :class:`BoxWind`, one label, pruning):
        each arc costed is judged at its samples and, where they cannot judge it alone and it is its node's best, on
        the pieces it crosses (:func:`_boxed_fail_rank`). None: no failure model.

    Returns
    -------
    The :class:`RankStep` (labels: one, or port and starboard with ``penalties``), or None when ``wind`` found a
    current.
    """
    n_dst = seg_nm.shape[0]
    n_out = 1 if penalties is None else 2
    tables = polar_compiled.tables(polar)
    forbid = beyond == "forbid"
    course, seg, tp = _c(course_deg), _c(seg_nm), _c(t_prev)
    src, valid = _c(src, np.intp), _c(valid, np.bool_)
    t_best = np.empty((n_dst, n_out))
    j_best = np.empty((n_dst, n_out), dtype=np.intp)
    c_best = np.zeros((n_dst, n_out), dtype=np.intp)
    counts = np.zeros(6, dtype=np.int64)
    boxed = isinstance(wind, BoxWind)
    if failure is not None:
        assert isinstance(wind, BoxWind) and n_out == 1 and tp.shape[1] == 1 and bound_kn is not None
        f = failure.fields
        judge = (f.base, f.boxes, f.values, f.relative, f.edges, f.n_edges, f.right, f.contrib, f.fill, f.p_flat,
                 f.over, f.bits)  # fmt: skip
        pieces = (f.base, f.boxes, f.values, f.relative, f.edges, f.n_edges, f.right, f.bin_state, f.fill_state,
                  f.n_slots, f.stride, f.p_flat, f.over, f.bits)  # fmt: skip
        by_criterion = np.zeros(f.base.size, dtype=np.int64)
        # at an apf no entry of the table exceeds, no arc waits for its pieces: nothing there can forbid it
        p_max = f.p_max if f.apf < f.p_max else -np.inf
        if failure.judged is None:
            m_state = np.zeros((0, 0), dtype=np.uint16)
        else:
            m_state = failure.judged  # written to in place: as made by :meth:`Judged.rank`
            assert m_state.shape == (n_dst, src.shape[1]) and f.base.size <= Judged.MAX_CRITERIA
        _boxed_fail_rank(  # type: ignore[call-arg]
            tp, src, valid, seg, course, _c(wind.lon_deg), _c(wind.lat_deg), float(bound_kn), wind.tws_kn,
            wind.twd_deg, wind.boxes, wind.values, *tables, forbid, MIN_SPEED_KN, _c(failure.a_xyz),
            _c(failure.b_xyz), judge, pieces, f.lon_lines, f.lat_lines, f.apf, p_max, m_state, t_best,
            j_best, counts, by_criterion,
        )  # fmt: skip
        return RankStep(t_best, j_best, c_best, *_tallies(counts), by_criterion)
    if n_out == 1 and tp.shape[1] == 1 and bound_kn is not None and boxed:
        assert isinstance(wind, BoxWind)
        _boxed_rank(  # type: ignore[call-arg]
            tp, src, valid, seg, course, _c(wind.lon_deg), _c(wind.lat_deg), float(bound_kn), wind.tws_kn,
            wind.twd_deg, wind.boxes, wind.values, *tables, forbid, MIN_SPEED_KN, t_best, j_best, counts,
        )  # fmt: skip
    elif boxed and n_out == 2:
        assert isinstance(wind, BoxWind) and penalties is not None
        _boxed_sides_rank(  # type: ignore[call-arg]
            tp, src, valid, seg, course, _c(wind.lon_deg), _c(wind.lat_deg), -1.0 if bound_kn is None else
            float(bound_kn), wind.tws_kn, wind.twd_deg, wind.boxes, wind.values, *tables, forbid, MIN_SPEED_KN,
            _sides_array(from_sides), *_penalty_tables(penalties), t_best, j_best, c_best, counts,
        )  # fmt: skip
    elif n_out == 1 and tp.shape[1] == 1 and bound_kn is not None:
        assert not isinstance(wind, BoxWind)
        if not _pruned_step(wind, course, seg, tp, src, valid, tables, forbid, float(bound_kn), t_best, j_best, counts):
            return None
    else:
        sampled = _box_sampled(wind, course.shape) if isinstance(wind, BoxWind) else wind(None)
        if sampled is None:
            return None
        tws, twd = (_c(a).reshape(-1, course.shape[2]) for a in sampled)
        _rank_kernel(  # type: ignore[call-arg]
            tws, twd, course, seg, tp, src, valid, *tables, forbid, MIN_SPEED_KN,
            -1.0 if bound_kn is None else float(bound_kn), _sides_array(from_sides),
            *_penalty_tables(penalties or _NO_PENALTIES), t_best, j_best, c_best, counts,
        )  # fmt: skip
    return RankStep(t_best, j_best, c_best, *_tallies(counts)[:5])


def _tallies(counts: npt.NDArray[np.int64]) -> tuple[int, int, int, int, int, int]:
    """A rank kernel's six counters as whole numbers, in :class:`RankStep`'s order (``live`` to ``failed``)."""
    live, costed, forbidden, no_speed, no_wind, failed = (int(n) for n in counts)
    return live, costed, forbidden, no_speed, no_wind, failed


def _box_sampled(wind: BoxWind, shape: tuple[int, ...]) -> tuple[FloatArray, FloatArray]:
    """The wind of a :class:`BoxWind` at every sample point, shape ``shape`` (nodes, arcs, samples)."""
    lon = _c(np.broadcast_to(wind.lon_deg, shape))
    lat = _c(np.broadcast_to(wind.lat_deg, shape))
    tws, twd = np.empty(shape), np.empty(shape)
    _box_wind_all(lon.reshape(-1), lat.reshape(-1), wind.tws_kn, wind.twd_deg, wind.boxes, wind.values,
                  tws.reshape(-1), twd.reshape(-1))  # fmt: skip
    return tws, twd


@numba.njit(nogil=True, cache=True, inline="always")
def _box_wind(lon, lat, tws, twd, boxes, values):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The wind at one point: ``tws``, ``twd`` overridden by each box holding the point (closed; in order) that
    sets them (not NaN), as :meth:`~pyroute_rel.weather.uniform.UniformWeather.sample` does."""
    for p in range(boxes.shape[0]):
        if lon >= boxes[p, 0] and lon <= boxes[p, 1] and lat >= boxes[p, 2] and lat <= boxes[p, 3]:
            if values[p, 0] == values[p, 0]:
                tws = values[p, 0]
            if values[p, 1] == values[p, 1]:
                twd = values[p, 1]
    return tws, twd


@numba.njit(nogil=True, cache=True)
def _box_wind_all(lon, lat, tws0, twd0, boxes, values, tws, twd):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`_box_wind` at every point of the flat arrays ``lon``, ``lat``, into ``tws``, ``twd``."""
    for i in range(lon.size):
        tws[i], twd[i] = _box_wind(lon[i], lat[i], tws0, twd0, boxes, values)


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _columns(tws0, values, twa_tab, tws_tab, speed_tab, tws_inv, forbid):  # type: ignore[no-untyped-def]  # pragma: no cover
    """What :func:`~pyroute_rel._kernels.polar.speed_kn` computes from the wind speed alone, for each speed a
    :class:`BoxWind` has (row 0: ``tws0``, row p + 1: box p's, or ``tws0`` where it sets none): the table
    interpolated along its TWS axis (a speed per TWA row [kn], ``speed_kn``'s arithmetic), the factor below the
    first column (1 where it does not apply: ``v * 1.0`` is ``v``) and the largest TWA sailed (the last row with
    ``forbid``, -inf where ``forbid`` and the speed is beyond the last column, else inf)."""
    n = values.shape[0] + 1
    n_tws = tws_tab.size
    speeds = np.empty(n)
    cols = np.empty((n, twa_tab.size))
    ratio = np.ones(n)
    amax = np.full(n, np.inf)
    for k in range(n):
        w = tws0 if k == 0 or values[k - 1, 0] != values[k - 1, 0] else values[k - 1, 0]
        speeds[k] = w
        j = cell(w, tws_tab, tws_inv)
        fw = (w - tws_tab[j]) / (tws_tab[j + 1] - tws_tab[j])
        fw = min(max(fw, 0.0), 1.0)
        gw = 1.0 - fw
        for r in range(twa_tab.size):
            c = r * n_tws + j
            cols[k, r] = speed_tab[c] * gw + speed_tab[c + 1] * fw
        if tws_tab[0] > 0.0 and w < tws_tab[0]:
            ratio[k] = w / tws_tab[0]
        if forbid:
            amax[k] = -np.inf if w > tws_tab[n_tws - 1] else twa_tab[twa_tab.size - 1]
    return speeds, cols, ratio, amax


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _boxed_time(d, a, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols, ratio, amin,
                amax, min_speed):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """:func:`_arc_time` of arc (d, a) with the wind of a :class:`BoxWind` at its samples, from :func:`_columns`
    (``amin``: the smallest TWA sailed, -inf where the table's first row is at 0 deg): the same numbers as
    :func:`~pyroute_rel._kernels.polar.speed_kn` (where it gives NaN or 0 this gives NaN or 0, both below
    ``min_speed``), the TWS part computed once per wind speed. The speeds of a :class:`BoxWind` are finite."""
    total = 0.0
    flags = 0
    for s in range(course.shape[2]):
        k = 0
        wd = twd0
        for p in range(boxes.shape[0]):  # _box_wind, the speed as the row of ``cols``
            if lon[d, a, s] >= boxes[p, 0] and lon[d, a, s] <= boxes[p, 1]:
                if lat[d, a, s] >= boxes[p, 2] and lat[d, a, s] <= boxes[p, 3]:
                    if values[p, 0] == values[p, 0]:
                        k = p + 1
                    if values[p, 1] == values[p, 1]:
                        wd = values[p, 1]
        ang = fold_twa(wd, course[d, a, s])
        i = cell(ang, twa_tab, twa_inv)
        fa = (ang - twa_tab[i]) / (twa_tab[i + 1] - twa_tab[i])
        fa = min(max(fa, 0.0), 1.0)
        v = (cols[k, i + 1] * fa - cols[k, i] * (fa - 1.0)) * ratio[k]
        if ang < amin or ang > amax[k]:
            v = 0.0
        dt, f = sub_time(seg, v, speeds[k], wd, min_speed)
        flags |= f
        total = dt if s == 0 else total + dt
    if flags != 0:
        total = np.inf
    return total, flags


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _cost_boxed(pick, n, d, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols, ratio, amin,
                amax, min_speed, times, flags):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """:func:`_boxed_time` of the arcs ``pick[:n]`` into node ``d``, into ``times`` and ``flags``."""
    for q in range(n):
        a = pick[q]
        times[q], flags[q] = _boxed_time(d, a, course, lon, lat, seg[d, a], twd0, boxes, values, twa_tab, twa_inv,
                                         speeds, cols, ratio, amin, amax, min_speed)  # fmt: skip


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _boxed_rank(  # type: ignore[no-untyped-def]  # pragma: no cover
    t_prev, src, valid, seg, course, lon, lat, bound, tws0, twd0, boxes, values, twa_tab, tws_tab, speed_tab, twa_inv,
    tws_inv, forbid, min_speed, t_best, j_best, counts,
):  # fmt: skip
    """One rank with one label per node and pruning, the wind of a :class:`BoxWind`, in one pass over the nodes: per
    node its four live arcs of smallest lower bound (``t0 + length / bound``; ties: lowest index) costed, then every
    other live arc whose bound does not exceed the best arrival over those four (what :func:`_first_arcs`,
    :func:`_rest_arcs` and :func:`_best_of_lists` do between samplings), the first earliest arrival kept.
    ``counts``: live, costed, forbidden, no speed, missing wind arcs (added to)."""
    n_dst, width = seg.shape
    speeds, cols, ratio, amax = _columns(tws0, values, twa_tab, tws_tab, speed_tab, tws_inv, forbid)
    amin = twa_tab[0] if twa_tab[0] > 0.0 else -np.inf
    lower = np.empty(width)  # each arc's bound, NaN where not live or among the first four
    t0s = np.empty(width)  # each arc's departure
    pick = np.empty(max(width, 4), dtype=np.intp)
    times = np.empty(width)
    flags = np.empty(width, dtype=np.uint8)
    tally = np.zeros(5, dtype=np.int64)
    for d in range(n_dst):
        live = _bounds(t_prev, src, valid, seg, course.shape[2], bound, d, lower, t0s, pick)
        tally[0] += live
        n = min(live, 4)
        for q in range(n):  # cost the picked arcs in a loop of their own (their latencies overlap), then compare
            lower[pick[q]] = np.nan
        _cost_boxed(pick, n, d, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols, ratio,
                    amin, amax, min_speed, times, flags)  # fmt: skip
        best, jb = _best_picked(pick, n, t0s, times, flags, np.inf, 0, tally)
        m = 0
        for a in range(width):  # the rest are pruned against the best over the first four only (as the numpy path)
            pick[m] = a
            m += lower[a] <= best
        _cost_boxed(pick, m, d, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols, ratio,
                    amin, amax, min_speed, times, flags)  # fmt: skip
        t_best[d, 0], j_best[d, 0] = _best_picked(pick, m, t0s, times, flags, best, jb, tally)
    counts += tally


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _bounds(t_prev, src, valid, seg, samples, bound, d, lower, t0s, first):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Node ``d``'s arcs: departure ``t0s`` and lower bound ``lower`` (``t0 + length / bound``; NaN where not live),
    and the four live ones of smallest bound (ties: the first) in increasing order in ``first[:4]``; returns the
    number of live arcs."""
    n = 0
    i0 = i1 = i2 = i3 = -1
    l0 = l1 = l2 = l3 = np.inf
    for a in range(lower.size):
        t0 = t_prev[src[d, a], 0] if valid[d, a] else np.nan
        t0s[a] = t0
        ok = np.isfinite(t0)
        lw = t0 + seg[d, a] * samples / bound if ok else np.nan
        lower[a] = lw
        n += ok
        if lw < l3:  # among the four so far (NaN never): insert it after the ones it does not beat
            if lw < l0:
                i0, i1, i2, i3 = a, i0, i1, i2
                l0, l1, l2, l3 = lw, l0, l1, l2
            elif lw < l1:
                i1, i2, i3 = a, i1, i2
                l1, l2, l3 = lw, l1, l2
            elif lw < l2:
                i2, i3 = a, i2
                l2, l3 = lw, l2
            else:
                i3 = a
                l3 = lw
    for q, a in enumerate((i0, i1, i2, i3)):
        first[q] = a
    return n


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _best_picked(pick, n, t0s, times, flags, best, jb, tally):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The better of (``best``, ``jb``) and the earliest arrival ``t0s[a] + times[q]`` over the arcs ``a = pick[q]``
    (``q < n``) that can be sailed (first of equal ones: lowest index), and the arcs counted into ``tally[1:]``
    (costed, forbidden, no speed, missing wind)."""
    for q in range(n):
        f = flags[q]
        tally[1] += 1
        if f != 0:
            tally[2] += 1
            tally[3] += f & 1
            tally[4] += (f >> 1) & 1
        else:
            a = pick[q]
            tot = t0s[a] + times[q]
            if tot < best or (tot == best and a < jb):
                best, jb = tot, a
    return best, jb


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _boxed_fail_rank(  # type: ignore[no-untyped-def]  # pragma: no cover
    t_prev, src, valid, seg, course, lon, lat, bound, tws0, twd0, boxes, values, twa_tab, tws_tab, speed_tab, twa_inv,
    tws_inv, forbid, min_speed, a_xyz, b_xyz, judge, pieces, lon_lines, lat_lines, apf, p_max, m_state, t_best, j_best,
    counts, crit_counts,
):  # fmt: skip
    """:func:`_boxed_rank` with a failure model on uniform weather with patches: each arc costed is also judged at its
    samples (:func:`~pyroute_rel._kernels.crossings.sample_evidence`: p_f over apf forbids it, as the cost function's
    flags do); an arc its samples cannot judge alone (:func:`~pyroute_rel._kernels.crossings.needs_judging`) is
    judged on the pieces it crosses (:func:`~pyroute_rel._kernels.crossings.arc_p_f`) when it is its node's earliest
    arrival: among the first four before the rest are pruned against their best, then among all, until the best is
    allowed (the DP's lazy judgement, :func:`~pyroute_rel.routing.solve._lazy_pieces`: the same minimum as judging every
    arc). ``judge``: the fields and classifier (base, boxes, values, relative, edges, n_edges, right, contrib, fill,
    p_flat, over, bits); ``pieces``: those :func:`arc_p_f` takes. ``m_state``: the rank's judgements kept from
    earlier DPs (:class:`Judged`), shape (nodes, arcs), read where known and written where made (shape (0, 0): none
    kept). ``counts``: live, costed, forbidden, no speed, missing weather, failure arcs;
    ``crit_counts``: arcs forbidden for failure with each criterion fired (added to, as each arc is found
    forbidden)."""
    n_dst, width = seg.shape
    speeds, cols, ratio, amax = _columns(tws0, values, twa_tab, tws_tab, speed_tab, tws_inv, forbid)
    amin = twa_tab[0] if twa_tab[0] > 0.0 else -np.inf
    n_crit = judge[0].size
    lower = np.empty(width)
    t0s = np.empty(width)
    pick = np.empty(width + 4, dtype=np.intp)  # the first four costed, then the rest
    times = np.empty(width + 4)
    flags = np.zeros(width + 4, dtype=np.uint8)
    pend = np.zeros(width + 4, dtype=np.bool_)
    nxt_t = np.empty(_NEXT)
    nxt_q = np.empty(_NEXT, dtype=np.intp)
    work = np.empty(n_crit)
    pwork = np.empty((n_crit, 4))
    reach = np.zeros((n_crit, int(pieces[9].max())), dtype=np.bool_)
    cuts = np.empty(3 * lon_lines.size + 2 * lat_lines.size + 4)
    scratch = (work, cuts, pwork, reach, nxt_t, nxt_q)
    tally = np.zeros(6, dtype=np.int64)
    for d in range(n_dst):
        live = _bounds(t_prev, src, valid, seg, course.shape[2], bound, d, lower, t0s, pick)
        tally[0] += live
        n = min(live, 4)
        for q in range(n):
            lower[pick[q]] = np.nan
        _cost_boxed(pick, n, d, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols, ratio,
                    amin, amax, min_speed, times, flags)  # fmt: skip
        best, jb, qb = _judge_samples(pick, 0, n, d, t0s, course, lon, lat, judge, p_max, m_state, work,
                                      times, flags, pend, np.inf, -1, -1, tally, crit_counts)  # fmt: skip
        best, jb, qb, known = _settle_kept(pick, n, d, best, jb, qb, t0s, times, flags, pend, m_state, nxt_t, nxt_q,
                                           tally, crit_counts)  # fmt: skip
        if not known:  # (the judging itself out of line: inlined, it slowed the loops around it by a fifth)
            best, jb, qb = _settle_judged(pick, n, d, best, jb, qb, t0s, times, flags, pend, lon, lat, course, seg,
                                          a_xyz, b_xyz, judge, pieces, lon_lines, lat_lines, apf, m_state, scratch,
                                          tally, crit_counts)  # fmt: skip
        m = n
        for a in range(width):  # the rest are pruned against the best over the first four (judged) only
            pick[m] = a
            m += lower[a] <= best
        _cost_boxed(pick[n:], m - n, d, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols,
                    ratio, amin, amax, min_speed, times[n:], flags[n:])  # fmt: skip
        best, jb, qb = _judge_samples(pick, n, m, d, t0s, course, lon, lat, judge, p_max, m_state, work,
                                      times, flags, pend, best, jb, qb, tally, crit_counts)  # fmt: skip
        best, jb, qb, known = _settle_kept(pick, m, d, best, jb, qb, t0s, times, flags, pend, m_state, nxt_t, nxt_q,
                                           tally, crit_counts)  # fmt: skip
        if not known:  # (the judging itself out of line: inlined, it slowed the loops around it by a fifth)
            best, jb, qb = _settle_judged(pick, m, d, best, jb, qb, t0s, times, flags, pend, lon, lat, course, seg,
                                          a_xyz, b_xyz, judge, pieces, lon_lines, lat_lines, apf, m_state, scratch,
                                          tally, crit_counts)  # fmt: skip
        t_best[d, 0], j_best[d, 0] = (best, jb) if jb >= 0 else (np.inf, 0)
        tally[1] += m
    counts += tally


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _judge_samples(pick, q0, q1, d, t0s, course, lon, lat, judge, p_max, m_state, work, times, flags, pend, best, jb,
                   qb, tally, crit_counts):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """The arcs ``pick[q0:q1]`` into node ``d`` costed already (``times``, ``flags`` at the same positions) judged at
    their samples (:func:`~pyroute_rel._kernels.crossings.sample_evidence`): the cost function's reason flags and
    criteria fired (:func:`~pyroute_rel.routing.cost._sample_speeds`: an arc with a flag takes forever), and whether it
    waits to be judged on its pieces (allowed and below the table's largest p_f at its samples: whether its samples
    cannot judge it alone is asked when it is its node's best). With ``m_state`` (not empty) an arc's judgement kept
    there is taken as it is (it does not depend on time), and one made is kept (:class:`Judged`). An arc forbidden is
    counted into ``tally[2:]`` and ``crit_counts``; returns the earliest arrival over the others and (``best``, arc
    ``jb`` at ``pick[qb]``) so far (first of equal ones: lowest arc; -1 where none)."""
    fbase, fboxes, fvalues, relative, edges, n_edges, right, contrib, fill, p_flat, over, bits = judge
    memo = m_state.shape[0] > 0
    for q in range(q0, q1):
        a = pick[q]
        st = m_state[d, a] if memo else np.uint16(0)
        if st & _SAMPLED:
            g = st & (_LOST | _OVER)
            fb = np.uint32(st >> _FIRED) if st & _OVER else np.uint32(0)
            below = (st & _BELOW) != 0
        else:
            g = np.uint8(0)
            fb = np.uint32(0)
            p_arc = 0.0
            for s in range(course.shape[2]):
                p, ov, b, lost = sample_evidence(lon[d, a, s], lat[d, a, s], course[d, a, s], fbase, fboxes, fvalues,
                                                 relative, edges, n_edges, right, contrib, fill, p_flat, over, bits,
                                                 work)  # fmt: skip
                if s == 0 or p != p or (p_arc == p_arc and p > p_arc):  # numpy.maximum: a NaN stays
                    p_arc = p
                if lost:
                    g |= _LOST
                if ov:
                    g |= _OVER
                    fb |= b
            below = p_arc < p_max
            if memo:
                m_state[d, a] = _SAMPLED | g | (_BELOW if below else 0) | (fb << _FIRED)
        f = flags[q] | g
        flags[q] = f
        pend[q] = f == 0 and below
        if f != 0:
            times[q] = np.inf
            tally[2] += 1
            tally[3] += f & 1
            tally[4] += (f >> 1) & 1
            if f & 4:
                tally[5] += 1
                for c in range(crit_counts.size):
                    crit_counts[c] += (fb >> c) & 1
        else:
            tot = t0s[a] + times[q]
            if tot < best or (tot == best and a < jb):
                best, jb, qb = tot, a, q
    return best, jb, qb


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _settle_kept(pick, m, d, best, jb, qb, t0s, times, flags, pend, m_state, nxt_t, nxt_q, tally, crit_counts):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """:func:`_settle_judged` as far as the judgements kept in ``m_state`` take it: while the best waits for its
    pieces and its judgement on them is kept, that judgement is taken (allowed: done; forbidden: flagged, counted,
    the next best tried). Returns the arrival, arc and position, and False where the best waits for a judgement not
    kept (the caller then calls :func:`_settle_judged` from there)."""
    n_next = 0
    r = 0
    while jb >= 0 and pend[qb]:
        st = m_state[d, jb] if m_state.shape[0] > 0 else np.uint16(0)
        if not st & _PIECED:
            return best, jb, qb, False
        pend[qb] = False
        if not st & _FORBID:
            break
        _forbidden(qb, np.uint32(st >> _FIRED), times, flags, tally, crit_counts)
        if r == n_next:
            n_next = _line_up(pick, m, t0s, times, flags, nxt_t, nxt_q)
            r = 0
        if r == n_next:  # none left
            return np.inf, -1, -1, True
        best, qb = nxt_t[r], nxt_q[r]
        jb = pick[qb]
        r += 1
    return best, jb, qb, True


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _forbidden(q, b, times, flags, tally, crit_counts):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The arc at position ``q`` found forbidden on its pieces, which fire the criteria of bits ``b``: its failure
    flag, and counted (``tally``: forbidden, failed; ``crit_counts``)."""
    flags[q] |= 4
    times[q] = np.inf
    tally[2] += 1
    tally[5] += 1
    for c in range(crit_counts.size):
        crit_counts[c] += (b >> c) & 1


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _settle_judged(pick, m, d, best, jb, qb, t0s, times, flags, pend, lon, lat, course, seg, a_xyz, b_xyz, judge,
                   pieces, lon_lines, lat_lines, apf, m_state, scratch, tally, crit_counts):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """Node ``d``'s earliest arrival over the arcs ``pick[:m]`` costed that can be sailed, from the earliest
    (``best``, arc ``jb`` at ``pick[qb]``; -1 where none: :func:`_judge_samples`): while it waits for its pieces
    (where its samples cannot judge it alone), judged on them (or its judgement kept in ``m_state`` taken); one found
    forbidden gets the failure flag, is counted (``tally``, ``crit_counts``) and the next best is tried, in the order
    of arrival then arc (the next :data:`_NEXT` lined up at once: the order in which rescans for the earliest would
    find them). ``scratch``: ``work``, ``cuts``, ``pwork``, ``reach`` (:func:`arc_p_f`'s) and the line-up's arrivals
    and positions. Returns the arrival, arc and position (-1 where none)."""
    fbase, fboxes, fvalues, relative, edges, n_edges = judge[0], judge[1], judge[2], judge[3], judge[4], judge[5]
    work, cuts, pwork, reach, nxt_t, nxt_q = scratch
    memo = m_state.shape[0] > 0
    n_next = 0
    r = 0
    while jb >= 0 and pend[qb]:
        pend[qb] = False
        st = m_state[d, jb] if memo else np.uint16(0)
        if st & _PIECED:  # kept: what follows, without the judging
            if not st & _FORBID:
                break
            b = np.uint32(st >> _FIRED)
        else:
            if not needs_judging(lon[d, jb], lat[d, jb], course[d, jb], seg[d, jb], fboxes, fbase, fvalues, relative,
                                 edges, n_edges, work):  # fmt: skip
                if memo:
                    m_state[d, jb] = st | _PIECED
                break
            p, b = arc_p_f(a_xyz[d, jb], b_xyz[d], lon_lines, lat_lines, pieces, cuts, pwork, reach)
            if memo:  # (an arc waiting for its pieces fired nothing at its samples: the bits of ``_FIRED`` are free)
                m_state[d, jb] = st | _PIECED | ((_FORBID | (b << _FIRED)) if p > apf else 0)
            if not p > apf:
                break
        _forbidden(qb, b, times, flags, tally, crit_counts)
        if r == n_next:
            n_next = _line_up(pick, m, t0s, times, flags, nxt_t, nxt_q)
            r = 0
        if r == n_next:  # none left
            return np.inf, -1, -1
        best, qb = nxt_t[r], nxt_q[r]
        jb = pick[qb]
        r += 1
    return best, jb, qb


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _line_up(pick, m, t0s, times, flags, nxt_t, nxt_q):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The earliest arrivals ``nxt_t`` over the arcs ``pick[:m]`` that can be sailed, in order (of arrival, then arc),
    and their positions ``nxt_q``, as many as they hold; returns how many (arrivals that are not finite never come)."""
    k = nxt_q.size
    n = 0
    for q in range(m):
        if flags[q] != 0:
            continue
        a = pick[q]
        tot = t0s[a] + times[q]
        if not tot < np.inf:
            continue
        if n == k and not (tot < nxt_t[k - 1] or (tot == nxt_t[k - 1] and a < pick[nxt_q[k - 1]])):
            continue
        i = min(n, k - 1)  # after the ones it does not beat
        while i > 0 and (tot < nxt_t[i - 1] or (tot == nxt_t[i - 1] and a < pick[nxt_q[i - 1]])):
            nxt_t[i] = nxt_t[i - 1]
            nxt_q[i] = nxt_q[i - 1]
            i -= 1
        nxt_t[i] = tot
        nxt_q[i] = q
        n = min(n + 1, k)
    return n


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _boxed_sides_rank(  # type: ignore[no-untyped-def]  # pragma: no cover
    t_prev, src, valid, seg, course, lon, lat, bound, tws0, twd0, boxes, values, twa_tab, tws_tab, speed_tab, twa_inv,
    tws_inv, forbid, min_speed, from_sides, tack_x, tack_y, gybe_x, gybe_y, t_best, j_best, c_best, counts,
):  # fmt: skip
    """One rank with side labels (port, starboard), the wind of a :class:`BoxWind`, in one pass over the nodes: what
    :func:`_rank_kernel` does with ``penalties``, arc for arc (the same arcs costed, the same arrivals and labels),
    without sampling the wind at every arc. Per node each live arc's departures, lower bound and side (the wind at
    its first sample), then with pruning (``bound`` > 0) per side the four live arcs of smallest bound costed, then
    every other live arc whose bound does not exceed the best arrival over its side's four; without, every live arc.
    ``counts``: live, costed, forbidden, no speed, missing wind arcs (added to)."""
    n_dst, width = seg.shape
    speeds, cols, ratio, amax = _columns(tws0, values, twa_tab, tws_tab, speed_tab, tws_inv, forbid)
    amin = twa_tab[0] if twa_tab[0] > 0.0 else -np.inf
    tack_h, gybe_h = np.empty(speeds.size), np.empty(speeds.size)
    for k in range(speeds.size):  # what a change of side costs in each wind speed of the boxes (:func:`_change`)
        w = speeds[k] if np.isfinite(speeds[k]) else 0.0
        tack_h[k] = _interp(w, tack_x, tack_y) / 3600.0
        gybe_h[k] = _interp(w, gybe_x, gybe_y) / 3600.0
    lower = np.empty(width)  # each arc's bound, NaN where not live or among the first costed
    t0s = np.empty((width, t_prev.shape[1]))  # its departure from each source label (inf: none)
    side = np.zeros(width, dtype=np.int8)
    pick = np.empty(max(width, 8), dtype=np.intp)
    times = np.empty(max(width, 8))
    flags = np.empty(max(width, 8), dtype=np.uint8)
    best = np.empty(2)
    jb = np.empty(2, dtype=np.intp)
    cb = np.empty(2, dtype=np.intp)
    tally = np.zeros(5, dtype=np.int64)
    wind = (tws0, twd0, boxes, values, speeds, cols, ratio, amin, amax, tack_h, gybe_h)
    for d in range(n_dst):
        _box_sides(d, course, lon, lat, twd0, boxes, values, side)
        live, n = _side_bounds(t_prev, src, valid, seg, course.shape[2], bound, d, lower, t0s, side, pick)
        tally[0] += live
        best[:] = np.inf
        jb[:] = 0
        cb[:] = 0
        _cost_sides(pick, n, d, course, lon, lat, seg, wind, twa_tab, twa_inv, min_speed, times, flags, t0s, side,
                    from_sides, best, jb, cb, tally)  # fmt: skip
        b0 = best[0] if bound > 0.0 else np.inf  # the rest are pruned against their side's first four only
        b1 = best[1] if bound > 0.0 else np.inf
        m = 0
        for a in range(width):
            pick[m] = a
            m += lower[a] <= (b1 if side[a] else b0)
        _cost_sides(pick, m, d, course, lon, lat, seg, wind, twa_tab, twa_inv, min_speed, times, flags, t0s, side,
                    from_sides, best, jb, cb, tally)  # fmt: skip
        for s in range(2):
            t_best[d, s], j_best[d, s], c_best[d, s] = best[s], jb[s], cb[s]
    counts += tally


@numba.njit(nogil=True, cache=True, inline="always")
def _first_wind(d, a, lon, lat, twd0, boxes, values):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The wind of a :class:`BoxWind` at arc (d, a)'s first sample: the row of :func:`_columns` its speed is
    (0: outside every box setting one) and its direction [deg] (:func:`_box_wind`)."""
    k = 0
    wd = twd0
    for p in range(boxes.shape[0]):
        if lon[d, a, 0] >= boxes[p, 0] and lon[d, a, 0] <= boxes[p, 1]:
            if lat[d, a, 0] >= boxes[p, 2] and lat[d, a, 0] <= boxes[p, 3]:
                if values[p, 0] == values[p, 0]:
                    k = p + 1
                if values[p, 1] == values[p, 1]:
                    wd = values[p, 1]
    return k, wd


@numba.njit(nogil=True, cache=True, inline="always")
def _wind_rel(x):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``numpy.mod(x, 360.0)`` for ``x`` the wind direction less the course [deg]: where the wind lies clockwise of
    the course, in [0, 360) (NaN in, NaN out). Within a turn either way, as courses and wind directions are,
    without the division (``fmod`` is exact: ``x``, or ``x + 360`` rounded below 0)."""
    y = x + 360.0 if x < 0.0 else x
    if not (y >= 0.0 and y < 360.0):  # beyond a turn, NaN, or a tiny negative x that rounds to 360
        y = np.mod(x, 360.0)
    return y


@numba.njit(nogil=True, cache=True, inline="always")
def _box_sides(d, course, lon, lat, twd0, boxes, values, side):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Side of each arc into node ``d`` from the wind of a :class:`BoxWind` and the course at its first sample:
    :func:`_sides`' (:func:`~pyroute_rel.boat.manoeuvre.wind_side`'s) rule, value for value. A loop without a branch
    (within a turn, :func:`_wind_rel`'s first case), then :func:`_wind_rel` again where an angle was not."""
    width = side.size
    odd = False
    if boxes.shape[0] == 0:
        for a in range(width):
            x = twd0 - course[d, a, 0]
            y = x + 360.0 if x < 0.0 else x
            odd |= not (y >= 0.0 and y < 360.0)
            side[a] = y < 180.0
    else:
        for a in range(width):
            x = _first_wind(d, a, lon, lat, twd0, boxes, values)[1] - course[d, a, 0]
            y = x + 360.0 if x < 0.0 else x
            odd |= not (y >= 0.0 and y < 360.0)
            side[a] = y < 180.0
    if odd:
        for a in range(width):
            y = _wind_rel(_first_wind(d, a, lon, lat, twd0, boxes, values)[1] - course[d, a, 0])
            side[a] = 1 if y < 180.0 or y != y else 0  # NaN: starboard


@numba.njit(nogil=True, cache=True, inline="always")
def _insert4(lw, a, l0, l1, l2, l3, i0, i1, i2, i3):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Arc ``a`` of bound ``lw`` into the four smallest bounds so far ``l0 <= l1 <= l2 <= l3`` (arcs ``i0`` to
    ``i3``), after those it does not beat (ties: the first arc stays first); NaN never enters."""
    if lw < l0:
        return lw, l0, l1, l2, a, i0, i1, i2
    if lw < l1:
        return l0, lw, l1, l2, i0, a, i1, i2
    if lw < l2:
        return l0, l1, lw, l2, i0, i1, a, i2
    if lw < l3:
        return l0, l1, l2, lw, i0, i1, i2, a
    return l0, l1, l2, l3, i0, i1, i2, i3


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _side_bounds(t_prev, src, valid, seg, samples, bound, d, lower, t0s, side, pick):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Node ``d``'s arcs: departure from each source label (one or two) ``t0s`` (inf: none) and lower bound
    ``lower`` (``t0 + length / bound``, the earliest departure; NaN where not live); with pruning (``bound`` > 0)
    the four live arcs of smallest bound on each ``side`` (ties: the first) into ``pick``, port's first, their bound
    set to NaN. Returns the number of live arcs and of picked ones."""
    two = t0s.shape[1] == 2
    live = 0
    i0 = i1 = i2 = i3 = j0 = j1 = j2 = j3 = -1
    l0 = l1 = l2 = l3 = m0 = m1 = m2 = m3 = np.inf
    for a in range(lower.size):
        t0 = t1 = np.inf
        if valid[d, a]:
            t0 = t_prev[src[d, a], 0]
            if two:
                t1 = t_prev[src[d, a], 1]
        t0s[a, 0] = t0
        if two:
            t0s[a, 1] = t1
        tm = min(t0, t1)
        if not np.isfinite(tm):
            lower[a] = np.nan
            continue
        live += 1
        if not bound > 0.0:
            lower[a] = tm
            continue
        lw = (
            tm + seg[d, a] * samples / bound
        )  # min over the labels of t + bound: the same number (rounding is monotone)
        lower[a] = lw
        if side[a] == 0 and lw < l3:
            l0, l1, l2, l3, i0, i1, i2, i3 = _insert4(lw, a, l0, l1, l2, l3, i0, i1, i2, i3)
        elif side[a] == 1 and lw < m3:
            m0, m1, m2, m3, j0, j1, j2, j3 = _insert4(lw, a, m0, m1, m2, m3, j0, j1, j2, j3)
    n = 0
    for a in (i0, i1, i2, i3, j0, j1, j2, j3):
        if a >= 0:
            pick[n] = a
            lower[a] = np.nan
            n += 1
    return live, n


@numba.njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _cost_sides(pick, n, d, course, lon, lat, seg, wind, twa_tab, twa_inv, min_speed, times, flags, t0s, side,
                from_sides, best, jb, cb, tally):  # type: ignore[no-untyped-def]  # pragma: no cover  # fmt: skip
    """The arcs ``pick[:n]`` into node ``d`` costed (:func:`_cost_boxed`; ``wind``: the :class:`BoxWind`'s parts and
    :func:`_boxed_sides_rank`'s tables) and counted into ``tally[1:]``; each label's (side's) earliest arrival
    ``best`` over them and its arc ``jb`` and source label ``cb`` updated: first of equal ones in the order of
    :func:`_best_labels` (source labels, then arcs), a change of side costing what :func:`_change` gives."""
    _, twd0, boxes, values, speeds, cols, ratio, amin, amax, tack_h, gybe_h = wind
    _cost_boxed(pick, n, d, course, lon, lat, seg, twd0, boxes, values, twa_tab, twa_inv, speeds, cols, ratio, amin,
                amax, min_speed, times, flags)  # fmt: skip
    for q in range(n):
        f = flags[q]
        _count(f, tally)
        if f != 0:
            continue
        a = pick[q]
        s = side[a]
        k, wd = _first_wind(d, a, lon, lat, twd0, boxes, values)
        rel = _wind_rel(wd - course[d, a, 0])
        change = tack_h[k] if min(rel, 360.0 - rel) < 90.0 else gybe_h[k]  # a tack upwind of the beam
        for c in range(t0s.shape[1]):
            t0 = t0s[a, c]
            if np.isfinite(t0):
                tot = _arrival(t0, times[q], from_sides[c], s, change)
                if tot < best[s] or (tot == best[s] and tot < np.inf and (c < cb[s] or (c == cb[s] and a < jb[s]))):
                    best[s], jb[s], cb[s] = tot, a, c


def _pruned_step(  # type: ignore[no-untyped-def]
    wind: WindSampler, course, seg, tp, src, valid, tables, forbid, bound, t_best, j_best, counts
) -> bool:
    """:func:`rank_step` of one label per node with pruning: the wind sampled at the arcs costed only (False: it
    found a current)."""
    n_dst, width = seg.shape
    first = np.full(n_dst * 4, -1, dtype=np.intp)
    counts[0] = _first_arcs(tp, src, valid, seg, course.shape[2], bound, first)
    picked = first >= 0  # nodes with fewer than four live arcs leave -1s
    costs = _cost_arcs(wind, first[picked], width, course, seg, tables, forbid)
    if costs is None:
        return False
    t_first = (np.full(first.size, np.inf), np.zeros(first.size, dtype=np.uint8))  # laid out as ``first``
    t_first[0][picked], t_first[1][picked] = costs
    rest = np.empty(n_dst * width, dtype=np.intp)
    n_rest = _rest_arcs(tp, src, valid, seg, course.shape[2], bound, first, t_first[0], t_first[1], rest)
    t_rest = _cost_arcs(wind, rest[:n_rest], width, course, seg, tables, forbid)
    if t_rest is None:
        return False
    _best_of_lists(tp, src, first, *t_first, rest[:n_rest], *t_rest, t_best, j_best, counts)
    return True


def _cost_arcs(  # type: ignore[no-untyped-def]
    wind: WindSampler, pick, width, course, seg, tables, forbid
) -> tuple[FloatArray, npt.NDArray[np.uint8]] | None:
    """Time [h] and reason flags of the arcs ``pick`` (flat indices node * width + arc), the wind sampled at them
    (None: a current)."""
    times = np.empty(pick.size)
    flags = np.empty(pick.size, dtype=np.uint8)
    if pick.size == 0:
        return times, flags
    sampled = wind(pick)
    if sampled is None:
        return None
    tws, twd = (_c(a).reshape(pick.size, course.shape[2]) for a in sampled)
    _cost_list(tws, twd, course, seg, pick, *tables, forbid, MIN_SPEED_KN, times, flags)  # type: ignore[call-arg]
    return times, flags


@numba.njit(nogil=True, cache=True, inline="always")
def _arc_time(tws, twd, i, course, d, a, seg, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Sailing time [h] of arc (d, a) of length ``seg`` [nm] per sub-segment, with the wind of row ``i`` of
    ``tws``, ``twd``, and its reason flags (1: no speed, 2: missing wind), as the numpy cost kernel computes them:
    per sample the TWA, bilinear polar and ``seg / speed``, summed over the samples in order."""
    total = 0.0
    flags = 0
    for s in range(tws.shape[1]):
        w = tws[i, s]
        wd = twd[i, s]
        ang = fold_twa(wd, course[d, a, s])
        v = speed_kn(ang, w, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid)
        dt, f = sub_time(seg, v, w, wd, min_speed)
        flags |= f
        total = dt if s == 0 else total + dt
    if flags != 0:
        total = np.inf
    return total, flags


@numba.njit(nogil=True, cache=True)
def _first_arcs(t_prev, src, valid, seg, samples, bound, first):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Each node's four live arcs of smallest lower bound (``t0 + length / bound``; ties: lowest index) as flat
    indices ``node * width + arc`` into ``first[4 * node:]`` (-1: fewer); returns the number of live arcs."""
    n_dst, width = seg.shape
    live = 0
    low = np.empty(4)
    idx = np.empty(4, dtype=np.intp)
    for d in range(n_dst):
        n = 0
        for a in range(width):
            if not valid[d, a]:
                continue
            t0 = t_prev[src[d, a], 0]
            if not np.isfinite(t0):
                continue
            live += 1
            lw = t0 + seg[d, a] * samples / bound
            if n == 4 and not lw < low[3]:
                continue
            q = min(n, 3)
            while q > 0 and lw < low[q - 1]:
                if q < 4:
                    low[q] = low[q - 1]
                    idx[q] = idx[q - 1]
                q -= 1
            low[q] = lw
            idx[q] = a
            n = min(n + 1, 4)
        for q in range(n):
            first[4 * d + q] = d * width + idx[q]
    return live


@numba.njit(nogil=True, cache=True)
def _cost_list(
    tws, twd, course, seg, pick, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed, times, flags
):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Time and flags of each arc of ``pick`` (flat indices, nodes in increasing order), its wind in the same row
    of ``tws``, ``twd``."""
    width = seg.shape[1]
    d = 0
    for q in range(pick.size):
        while pick[q] >= (d + 1) * width:  # the node, without a division
            d += 1
        a = pick[q] - d * width
        t, f = _arc_time(tws, twd, q, course, d, a, seg[d, a], twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid,
                         min_speed)  # fmt: skip
        times[q] = t
        flags[q] = f


@numba.njit(nogil=True, cache=True)
def _rest_arcs(t_prev, src, valid, seg, samples, bound, first, t_first, f_first, rest):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The live arcs not among ``first`` whose lower bound does not exceed the best arrival over a node's first
    arcs (flat indices, in order, into ``rest``); returns their number."""
    n_dst, width = seg.shape
    n = 0
    mine = np.zeros(width, dtype=np.bool_)
    for d in range(n_dst):
        best = np.inf
        for q in range(4 * d, 4 * d + 4):
            if first[q] < 0:
                break
            a = first[q] - d * width
            mine[a] = True
            tot = t_prev[src[d, a], 0] + t_first[q]
            if f_first[q] == 0 and tot < best:
                best = tot
        for a in range(width):
            if valid[d, a] and not mine[a]:
                t0 = t_prev[src[d, a], 0]
                if np.isfinite(t0) and t0 + seg[d, a] * samples / bound <= best:
                    rest[n] = d * width + a
                    n += 1
        for q in range(4 * d, 4 * d + 4):
            if first[q] >= 0:
                mine[first[q] - d * width] = False
    return n


@numba.njit(nogil=True, cache=True)
def _best_of_lists(t_prev, src, first, t_first, f_first, rest, t_rest, f_rest, t_best, j_best, counts):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The earliest arrival at each node over its costed arcs (first of equal ones: lowest arc index), and the
    counts of costed and forbidden arcs."""
    n_dst = t_best.shape[0]
    width = src.shape[1]
    r = 0
    for d in range(n_dst):
        best = np.inf
        jb = 0
        for q in range(4 * d, 4 * d + 4):
            if first[q] >= 0:
                best, jb = _keep_best(t_prev, src, d, first[q] - d * width, t_first[q], f_first[q], best, jb, counts)
        while r < rest.size and rest[r] < (d + 1) * width:
            best, jb = _keep_best(t_prev, src, d, rest[r] - d * width, t_rest[r], f_rest[r], best, jb, counts)
            r += 1
        t_best[d, 0] = best
        j_best[d, 0] = jb


@numba.njit(nogil=True, cache=True, inline="always")
def _keep_best(t_prev, src, d, a, t, f, best, jb, counts):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One costed arc (d, a) of time ``t`` and flags ``f``, counted; the better of it and (``best``, ``jb``)."""
    _count(f, counts)
    if f == 0:
        tot = t_prev[src[d, a], 0] + t
        if tot < best or (tot == best and a < jb):
            return tot, a
    return best, jb


@numba.njit(nogil=True, cache=True, inline="always")
def _count(f, counts):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Count one costed arc with flags ``f``: costed, forbidden, no speed, missing wind (``counts[1:]``)."""
    counts[1] += 1
    if f != 0:
        counts[2] += 1
        counts[3] += f & 1
        counts[4] += (f >> 1) & 1


@numba.njit(nogil=True, cache=True)
def _rank_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    tws, twd, course, seg, t_prev, src, valid, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed,
    bound, from_sides, tack_x, tack_y, gybe_x, gybe_y, t_best, j_best, c_best, counts,
):  # fmt: skip
    """Per node: the arcs' departures from each source label, prune (when ``bound`` > 0, for each label: the four
    arcs of smallest lower bound into it, then those whose bound does not exceed the best arrival over them) or cost
    every live arc, and keep the first earliest arrival at each label. ``tws``, ``twd``: the wind at every arc,
    shape (nodes * arcs, samples); ``counts``: live, costed, forbidden, no speed, missing wind arcs (added to)."""
    n_dst, width = seg.shape
    n_in = t_prev.shape[1]
    n_out = t_best.shape[1]
    times = np.empty(width)
    t_src = np.empty((width, n_in))
    side = np.zeros(width, dtype=np.int8)
    up = np.zeros(width, dtype=np.bool_)
    change = np.zeros(width)
    reason = np.zeros(width, dtype=np.uint8)
    counted = np.zeros(width, dtype=np.bool_)
    live = np.zeros(width, dtype=np.bool_)
    for d in range(n_dst):
        if n_out == 2:
            _sides(twd, course, d, side, up)
        for a in range(width):
            live[a] = False
            counted[a] = False
            reason[a] = 0
            for c in range(n_in):
                t_src[a, c] = t_prev[src[d, a], c] if valid[d, a] else np.inf
                if np.isfinite(t_src[a, c]):
                    live[a] = True
            counts[0] += live[a]
        if bound > 0.0:
            _prune_and_cost(tws, twd, course, seg, t_src, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid,
                            min_speed, bound, from_sides, side, up, tack_x, tack_y, gybe_x, gybe_y, change, d, live,
                            times, reason, counted, n_out)  # fmt: skip
        else:
            for a in range(width):
                if live[a]:
                    counted[a] = True
                    t, f = _arc_time(
                        tws,
                        twd,
                        d * width + a,
                        course,
                        d,
                        a,
                        seg[d, a],
                        twa_tab,
                        tws_tab,
                        speed_tab,
                        twa_inv,
                        tws_inv,
                        forbid,
                        min_speed,
                    )
                    reason[a] = f
                    times[a] = t
        for a in range(width):
            if counted[a]:
                _count(reason[a], counts)
                if n_out == 2 and reason[a] == 0:  # the manoeuvre's time, where an arc can be sailed
                    change[a] = _change(tws, d * width + a, up[a], tack_x, tack_y, gybe_x, gybe_y)
        _best_labels(t_src, from_sides, side, change, d, times, reason, counted, t_best, j_best, c_best)


@numba.njit(nogil=True, cache=True, inline="always")
def _interp(x, xp, fp):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``numpy.interp(x, xp, fp)`` for one finite ``x``, in numpy's arithmetic (constant beyond the ends)."""
    n = xp.size
    if n == 1 or x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    j = 0
    while xp[j + 1] <= x:
        j += 1
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + fp[j]
    if out != out:
        out = slope * (x - xp[j + 1]) + fp[j + 1]
        if out != out and fp[j] == fp[j + 1]:
            out = fp[j]
    return out


@numba.njit(nogil=True, cache=True, inline="always")
def _arrival(t0, t, from_side, side, change):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Arrival over an arc left at ``t0`` taking ``t`` [h], in the numpy path's order of additions: a change of side
    from a source label with a side adds ``change`` after the sailing time (inf where ``t0`` is)."""
    if from_side < 0:
        return t0 + t
    return (t0 + t) + (change if side != from_side else 0.0)


@numba.njit(nogil=True, cache=True, inline="always")
def _sides(twd, course, d, side, up):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Side of each arc into node ``d`` and whether a change of side onto it is a tack (upwind of the beam), from
    the wind direction and course at its first sample: :func:`~pyroute_rel.boat.manoeuvre.wind_side` and
    :func:`~pyroute_rel.boat.manoeuvre.manoeuvre_kind`, operation for operation."""
    width = side.size
    for a in range(width):
        rel = np.mod(twd[d * width + a, 0] - course[d, a, 0], 360.0)
        side[a] = 1 if rel < 180.0 or rel != rel else 0  # NaN: starboard
        up[a] = min(rel, 360.0 - rel) < 90.0


@numba.njit(nogil=True, cache=True, inline="always")
def _change(tws, i, up, tack_x, tack_y, gybe_x, gybe_y):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The time a change of side onto the arc of wind row ``i`` costs [h] (``up``: a tack):
    :meth:`~pyroute_rel.boat.manoeuvre.ManoeuvrePenalties.tables_h` of the wind speed at its first sample."""
    w = tws[i, 0]
    w = w if np.isfinite(w) else 0.0
    if up:
        return _interp(w, tack_x, tack_y) / 3600.0
    return _interp(w, gybe_x, gybe_y) / 3600.0


@numba.njit(nogil=True, cache=True, inline="always")
def _prune_and_cost(  # type: ignore[no-untyped-def]  # pragma: no cover
    tws, twd, course, seg, t_src, twa_tab, tws_tab, speed_tab, twa_inv, tws_inv, forbid, min_speed, bound,
    from_sides, side, up, tack_x, tack_y, gybe_x, gybe_y, change, d, live, times, reason, counted, n_out,
):  # fmt: skip
    """Node ``d``'s arcs that can still win, costed: per label (an arc's side is known before it is costed) the four
    of smallest lower bound, then every one whose bound does not exceed the best arrival over those four (ties:
    lowest index; the numpy path's argpartition may pick another of equal bounds, which changes which arcs are
    costed, never the result)."""
    width = seg.shape[1]
    samples = course.shape[2]
    n_in = t_src.shape[1]
    lower = np.full(width, np.inf)
    for a in range(width):
        for c in range(n_in):
            if np.isfinite(t_src[a, c]):
                lower[a] = min(lower[a], t_src[a, c] + seg[d, a] * samples / bound)
    for s in range(n_out):
        best_first = np.inf
        for _ in range(4):
            m = -1
            for a in range(width):
                mine = n_out == 1 or side[a] == s
                if mine and live[a] and not counted[a] and (m < 0 or lower[a] < lower[m]):
                    m = a
            if m < 0:
                break
            counted[m] = True
            t, f = _arc_time(
                tws,
                twd,
                d * width + m,
                course,
                d,
                m,
                seg[d, m],
                twa_tab,
                tws_tab,
                speed_tab,
                twa_inv,
                tws_inv,
                forbid,
                min_speed,
            )
            reason[m] = f
            times[m] = t
            if n_out == 2:
                change[m] = _change(tws, d * width + m, up[m], tack_x, tack_y, gybe_x, gybe_y)
            for c in range(n_in):
                tot = _arrival(t_src[m, c], t, from_sides[c], side[m], change[m])
                if f == 0 and tot < best_first:
                    best_first = tot
        for a in range(width):
            mine = n_out == 1 or side[a] == s
            if mine and live[a] and not counted[a] and lower[a] <= best_first:
                counted[a] = True
                t, f = _arc_time(
                    tws,
                    twd,
                    d * width + a,
                    course,
                    d,
                    a,
                    seg[d, a],
                    twa_tab,
                    tws_tab,
                    speed_tab,
                    twa_inv,
                    tws_inv,
                    forbid,
                    min_speed,
                )
                reason[a] = f
                times[a] = t


@numba.njit(nogil=True, cache=True, inline="always")
def _best_labels(t_src, from_sides, side, change, d, times, reason, counted, t_best, j_best, c_best):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The earliest arrival at each label of node ``d``: source labels in order, arcs in order, first of equal
    ones."""
    width = times.size
    n_out = t_best.shape[1]
    for s in range(n_out):
        t_best[d, s] = np.inf
        j_best[d, s] = 0
        c_best[d, s] = 0
    for c in range(t_src.shape[1]):
        for a in range(width):
            t0 = t_src[a, c]
            if counted[a] and reason[a] == 0 and np.isfinite(t0):
                tot = _arrival(t0, times[a], from_sides[c], side[a], change[a])
                s = side[a] if n_out == 2 else 0
                if tot < t_best[d, s]:
                    t_best[d, s] = tot
                    j_best[d, s] = a
                    c_best[d, s] = c
