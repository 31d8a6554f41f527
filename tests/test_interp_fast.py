"""The compiled sampling kernels of :mod:`pyroute_rel.weather.gridded` give the same bits as a plain-Python copy of
their arithmetic (the kernels as they were before their unrolled paths, unsigned indices and the time cell's guess by
a product; NaN only has to be NaN), on random blocks with NaN and calm corners, points and times inside, on and
outside the grid, steady, one-time, regular and irregular time axes, and the column sets the sampler asks for (wind;
wind, a scalar and the wave direction; any other)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyroute_rel._kernels import sampling
from pyroute_rel.weather import gridded

KN = 3600.0 / 1852.0


def _ref_cell(axis: np.ndarray, x: float) -> tuple[int, float]:
    """The cell ``clip(searchsorted(axis, x, "right") - 1, 0, n - 1)`` and the weight of its upper line."""
    n = axis.size
    if x != x:
        return 0, x
    i = min(max(int(np.searchsorted(axis, x, "right")) - 1, 0), n - 1)
    a = float(axis[i])
    if i == n - 1:
        return i, 0.0 if x == a else (x - a) / math.inf
    return i, (x - a) / (float(axis[i + 1]) - a)


def _ref_speed_bearing(e: float, n: float, scale: float) -> tuple[float, float]:
    ae, an = abs(e), abs(n)
    hi = max(ae, an)
    if 0.0 < hi < math.inf and e == e and n == n:
        r = math.degrees(math.atan(min(ae, an) / hi))
        r = 90.0 - r if ae > an else r
        r = 180.0 - r if n < 0.0 else r
        d = 360.0 - r if e < 0.0 else r
    else:
        d = math.degrees(math.atan2(e, n))
        if d < 0.0:
            d += 360.0
    if d >= 360.0:
        d = 0.0
    return math.sqrt(e * e + n * n) * scale, d + 0.0


def _ref_interpolate(flat, nf, columns, base, sx, sy, wx, wy, ok, t, scale, shift, t_axis, ru, rv, rs, rc, kn, out):  # type: ignore[no-untyped-def]
    """``_kernels.sampling.interpolate`` in plain Python, operation for operation."""
    nt = t_axis.size
    t_first = float(t_axis[0]) if nt else 0.0
    t_last = float(t_axis[-1]) if nt else 0.0
    for k in range(base.size):
        good, it, wt = bool(ok[k]), 0, 0.0
        if good and nt > 0:
            x = float(t[k]) * scale + shift
            good = t_first <= x <= t_last
            if good:
                it, wt = _ref_cell(t_axis, x)
        if not good:
            out[:, k] = np.nan
        else:
            st_ = nf if wt > 0.0 else 0
            b = int(base[k]) + it * nf
            ax, ay = float(wx[k]), float(wy[k])
            corners = [
                (b, (1.0 - ax) * (1.0 - ay)),
                (b + int(sx[k]), ax * (1.0 - ay)),
                (b + int(sy[k]), (1.0 - ax) * ay),
                (b + int(sx[k]) + int(sy[k]), ax * ay),
            ]
            for c, f in enumerate(columns):
                total = 0.0
                for i, (p, w) in enumerate(corners):
                    term = w * ((1.0 - wt) * float(flat[p + f]) + wt * float(flat[p + st_ + f]))
                    total = term if i == 0 else total + term
                out[c, k] = total
        if ru >= 0:
            out[ru, k], out[rv, k] = _ref_speed_bearing(-1.0 * out[ru, k], -1.0 * out[rv, k], kn)
        if rs >= 0:
            out[rs, k] = _ref_speed_bearing(out[rs, k], out[rc, k], 1.0)[1]


def _time_axis(rng: np.random.Generator, nt: int, regular: bool) -> np.ndarray:
    if nt == 0:
        return np.zeros(0)
    steps = np.full(nt - 1, 21600.0) if regular else rng.uniform(0.1, 3.0, nt - 1) * 3600.0
    return np.concatenate([[0.0], np.cumsum(steps)])


def _points(rng: np.random.Generator, axis: np.ndarray, n: int) -> np.ndarray:
    """Points on, between, just outside and far outside the grid lines of ``axis``, and NaN."""
    span = axis[-1] - axis[0]
    x = rng.uniform(axis[0] - 0.1 * span, axis[-1] + 0.1 * span, n)
    on = rng.random(n) < 0.3
    x[on] = rng.choice(axis, on.sum())
    x[rng.random(n) < 0.05] = np.nan
    return x


# (columns, convert rows): the sampler's two fused calls, the same with another first column, and others
CALLS = [
    ([0, 1], (0, 1, -1, -1)),
    ([0, 1, 2, 3, 4], (0, 1, 3, 4)),
    ([1, 2], (0, 1, -1, -1)),
    ([1, 2, 3, 4, 5], (0, 1, 3, 4)),
    ([0, 1, 2, 3, 4], (-1, -1, -1, -1)),
    ([0, 2, 4], (-1, -1, 1, 2)),
    ([3, 0, 1], (1, 2, -1, -1)),
    ([5], (-1, -1, -1, -1)),
    ([0, 1, 2, 3, 4, 5], (0, 1, 3, 4)),
]


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    call=st.sampled_from(CALLS),
    nt=st.sampled_from([0, 1, 2, 5]),
    regular=st.booleans(),
    same_times=st.booleans(),
)
def test_interpolate_kernel_equals_reference_bits(seed, call, nt, regular, same_times):  # type: ignore[no-untyped-def]
    args, convert, shape = _case(seed, call, nt, regular, same_times)
    expected = np.full(shape, 5.0)
    got = np.full(shape, 5.0)
    _ref_interpolate(*args, *convert, KN, expected)
    sampling.interpolate(*args, *convert, KN, got)
    _assert_same_bits(got, expected)


def _case(seed: int, call: tuple, nt: int, regular: bool, same_times: bool) -> tuple[tuple, tuple, tuple[int, int]]:
    """The kernel's arguments (up to the converted rows), the converted rows and the output's shape."""
    rng = np.random.default_rng(seed)
    columns, convert = call
    ny, nx, nf = int(rng.integers(2, 5)), int(rng.integers(2, 5)), 6
    data = rng.normal(0.0, 8.0, (ny, nx, max(nt, 1), nf)).astype(np.float32)
    data[rng.random(data.shape) < 0.05] = np.nan
    data[rng.random(data.shape[:3]) < 0.15, :] = 0.0  # calm corners: zero vectors
    lon = np.sort(rng.choice(np.arange(20.0), nx, replace=False))
    lat = np.sort(rng.choice(np.arange(20.0), ny, replace=False))
    t_axis = _time_axis(rng, nt, regular)
    n = 40
    strides = (nf, nx * max(nt, 1) * nf, max(nt, 1) * nf)
    ix, wx, sx, okx = gridded._locate(lon, _points(rng, lon, n), strides[2])
    iy, wy, sy, oky = gridded._locate(lat, _points(rng, lat, n), strides[1])
    base = iy * strides[1] + ix * strides[2]
    ok = okx & oky
    if nt:
        t = _points(rng, t_axis, n) if nt > 1 else np.where(rng.random(n) < 0.7, 0.0, rng.normal(0, 100.0, n))
    else:
        t = rng.normal(0.0, 1e5, n)
    if same_times:  # runs of points sharing a time, as the points of one arc
        t = np.repeat(t[::6], 6)[:n]
    t = np.ascontiguousarray(t / 2.0)  # times as the kernel takes them: t * 2.0 + 0.0 [s], exactly
    cols = np.asarray(columns, dtype=np.intp)
    args = (data.reshape(-1), nf, cols, base, sx, sy, wx, wy, ok, t, 2.0, 0.0, t_axis)
    return args, convert, (cols.size, n)


def _assert_same_bits(got: np.ndarray, expected: np.ndarray) -> None:
    """The same bits but in NaN, which only has to be NaN in both (its sign is the arithmetic's choice)."""
    nan = np.isnan(expected)
    assert np.array_equal(np.isnan(got), nan)
    assert got[~nan].tobytes() == expected[~nan].tobytes()


@pytest.mark.parametrize("regular", [True, False])
def test_locate_kernel_is_the_binary_search(regular):  # type: ignore[no-untyped-def]
    """Cells and weights of points on, between and outside the lines of regular and irregular axes (with steps
    whose mean spacing's inverse is inexact) are those of ``searchsorted``."""
    rng = np.random.default_rng(1 if regular else 2)
    for n in (2, 3, 7, 181):
        axis = (
            -30.1 + 0.1 * np.arange(n)
            if regular
            else np.concatenate([[-3.0], -3.0 + np.cumsum(rng.uniform(0.01, 1.0, n - 1))])
        )
        x = np.concatenate([_points(rng, axis, 400), axis, np.nextafter(axis, np.inf), np.nextafter(axis, -np.inf)])
        i, w, step, ok = gridded._locate(axis, x, 5)
        cells = [_ref_cell(axis, float(v)) for v in x]
        assert i.tolist() == [c[0] for c in cells]
        _assert_same_bits(w, np.array([c[1] for c in cells]))
        assert step.tolist() == [5 if c[1] > 0.0 else 0 for c in cells]
        assert ok.tolist() == [bool(axis[0] <= v <= axis[-1]) for v in x]
