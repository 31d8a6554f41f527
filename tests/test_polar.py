"""Tests of pyroute_rel.boat.polar: the table, its bilinear lookup, the .pol/.csv files and the built-in boat."""

from __future__ import annotations

import os
import re
import stat
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from scipy.interpolate import RegularGridInterpolator

from pyroute_rel.boat import polar as polar_mod
from pyroute_rel.boat.polar import (
    BEYOND_MODES,
    BUILTIN_POLARS,
    Polar,
    boat_speed_kn,
    fold_twa_deg,
    get_polar,
    read_pol,
    read_polar,
    read_polar_csv,
    write_pol,
    write_polar_csv,
)
from pyroute_rel.errors import PolarError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# Maribot Vane boat speed [kn], transcribed from /work/shared/design.md: Dhomé (2017), "Further development
# and performance evaluation of the autonomous sailing boat Maribot Vane", KTH, as tabulated with Dickson,
# Blake and Sear (2018), IRSC. Rows TWS [kn], columns TWA [deg].
PUB_TWS = [0, 4, 8, 12, 16, 20]
PUB_TWA = [0, 25, 40, 55, 70, 85, 100, 115, 130, 145, 160]
PUB_SPEED_BY_TWS = [
    [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
    [0, 0.9, 1.2, 1.4, 1.4, 1.4, 1.4, 1.2, 1.1, 1.0, 0.7],
    [0, 1.8, 2.4, 2.8, 2.9, 2.9, 2.8, 2.6, 2.2, 1.9, 1.5],
    [0, 2.75, 3.6, 4.0, 4.2, 4.2, 4.1, 3.8, 3.4, 2.9, 2.2],
    [0, 3.6, 4.4, 4.6, 4.6, 4.7, 4.6, 4.5, 4.3, 3.8, 3.0],
    [0, 4.1, 4.75, 5.0, 5.1, 5.2, 5.1, 5.0, 4.7, 4.4, 3.6],
]
VANE = BUILTIN_POLARS["maribot_vane"]


def pub(twa: float, tws: float) -> float:
    """A node of the published table."""
    return PUB_SPEED_BY_TWS[PUB_TWS.index(tws)][PUB_TWA.index(twa)]


# ---------------------------------------------------------------------------------------------------------
# Strategies


@st.composite
def polars(draw: st.DrawFn, *, max_n: int = 7) -> Polar:
    """Random valid polars (any axes within the allowed ranges, speeds >= 0)."""
    twa = sorted(draw(st.lists(st.floats(0.0, 180.0), min_size=2, max_size=max_n, unique=True)))
    tws = sorted(draw(st.lists(st.floats(0.0, 60.0), min_size=2, max_size=max_n, unique=True)))
    flat = draw(st.lists(st.floats(0.0, 30.0), min_size=len(twa) * len(tws), max_size=len(twa) * len(tws)))
    return Polar("random", twa_deg=twa, tws_kn=tws, speed_kn=np.reshape(flat, (len(twa), len(tws))))


# ---------------------------------------------------------------------------------------------------------
# The built-in table and the Polar class


def test_builtin_is_the_published_table():
    assert VANE.name == "maribot_vane"
    assert_array_equal(VANE.twa_deg, PUB_TWA)
    assert_array_equal(VANE.tws_kn, PUB_TWS)
    assert_array_equal(VANE.speed_kn, np.array(PUB_SPEED_BY_TWS).T)


def test_polar_copies_to_readonly_float_arrays():
    twa = np.array([0.0, 90.0, 180.0])
    p = Polar("x", twa_deg=twa, tws_kn=[0, 10], speed_kn=[[0, 0], [0, 5], [0, 4]])
    twa[1] = 45.0  # the caller's array stays theirs
    assert p.twa_deg[1] == 90.0
    assert p.tws_kn.dtype == np.float64
    for arr in (p.twa_deg, p.tws_kn, p.speed_kn):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0


def test_polar_equality_and_hash():
    same = Polar("maribot_vane", PUB_TWA, PUB_TWS, np.array(PUB_SPEED_BY_TWS).T)
    assert same == VANE and hash(same) == hash(VANE)
    other = Polar("maribot_vane", PUB_TWA, PUB_TWS, np.array(PUB_SPEED_BY_TWS).T * 1.01)
    assert other != VANE
    assert Polar("other", PUB_TWA, PUB_TWS, np.array(PUB_SPEED_BY_TWS).T) != VANE


GOOD = {"twa_deg": [0.0, 90.0, 180.0], "tws_kn": [0.0, 10.0], "speed_kn": [[0, 0], [0, 5], [0, 4]]}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"name": ""}, r"'name' must be a non-empty string"),
        ({"twa_deg": [0.0, 90.0, 90.0]}, r"'twa_deg' must be strictly increasing \[deg\]"),
        ({"twa_deg": [0.0, 90.0, 190.0]}, r"'twa_deg' must lie within \[0, 180\] \[deg\] \(got 0 to 190\)"),
        ({"twa_deg": [-5.0, 90.0, 180.0]}, r"'twa_deg' must lie within \[0, 180\]"),
        ({"twa_deg": [0.0, np.nan, 180.0]}, r"'twa_deg' must be finite"),
        ({"tws_kn": [10.0, 0.0]}, r"'tws_kn' must be strictly increasing \[kn\]"),
        ({"tws_kn": [-1.0, 10.0]}, r"'tws_kn' must be >= 0 \[kn\] \(got -1\)"),
        ({"tws_kn": [10.0], "speed_kn": [[0], [5], [4]]}, r"'tws_kn' must be 1-D with at least 2 values"),
        ({"twa_deg": [[0.0, 90.0, 180.0]]}, r"'twa_deg' must be 1-D"),
        (
            {"speed_kn": [[0, 0, 0], [5, 0, 4]]},
            r"'speed_kn' must have shape \(n_twa, n_tws\) = \(3, 2\) \(got \(2, 3\)\)",
        ),
        (
            {"speed_kn": [[0, 0], [0, np.nan], [0, 4]]},
            r"'speed_kn' must be finite \[kn\] \(got nan at TWA 90 deg, TWS 10",
        ),
        (
            {"speed_kn": [[0, 0], [0, 5], [-0.5, 4]]},
            r"'speed_kn' must be >= 0 \[kn\] \(got -0.5 at TWA 180 deg, TWS 0",
        ),
        ({"speed_kn": [[0, 0], [0], [0, 4]]}, r"'speed_kn' must be an array of numbers"),
    ],
)
def test_polar_validation(changes, message):
    kwargs = {"name": "bad", **GOOD, **changes}
    with pytest.raises(PolarError, match=message):
        Polar(**kwargs)


# ---------------------------------------------------------------------------------------------------------
# Lookup


def test_lookup_reproduces_every_node_exactly():
    twa, tws = np.meshgrid(PUB_TWA, PUB_TWS, indexing="ij")
    for mode in BEYOND_MODES:
        assert_array_equal(boat_speed_kn(VANE, twa, tws, beyond=mode), np.array(PUB_SPEED_BY_TWS).T)


@pytest.mark.slow
@given(polars())
@settings(max_examples=60, deadline=None)
def test_lookup_reproduces_nodes_of_random_polars(p):
    twa, tws = np.meshgrid(p.twa_deg, p.tws_kn, indexing="ij")
    assert_array_equal(boat_speed_kn(p, twa, tws, beyond="forbid"), p.speed_kn)
    assert_array_equal(boat_speed_kn(p, twa, tws), p.speed_kn)


@pytest.mark.parametrize(
    ("twa", "tws", "expected"),
    [
        # midway in both: mean of the four corners TWA 40/55 x TWS 8/12
        (47.5, 10.0, (pub(40, 8) + pub(55, 8) + pub(40, 12) + pub(55, 12)) / 4),  # = 3.2
        # on a TWA row, midway between two TWS columns
        (40.0, 10.0, (pub(40, 8) + pub(40, 12)) / 2),  # = 3.0
        # on a TWS column, midway between two TWA rows
        (62.5, 12.0, (pub(55, 12) + pub(70, 12)) / 2),  # = 4.1
        # one third of the way from TWA 145 to 160, halfway from TWS 16 to 20
        (
            150.0,
            18.0,
            (2 / 3) * (pub(145, 16) + pub(145, 20)) / 2 + (1 / 3) * (pub(160, 16) + pub(160, 20)) / 2,
        ),
        # a quarter of the way from TWA 0 to 25 and from TWS 4 to 8 (the TWA-0 row is 0 kn)
        (6.25, 5.0, 0.75 * 0.25 * pub(25, 4) + 0.25 * 0.25 * pub(25, 8)),
    ],
)
def test_bilinear_against_hand_arithmetic(twa, tws, expected):
    for mode in BEYOND_MODES:
        assert_allclose(boat_speed_kn(VANE, twa, tws, beyond=mode), expected, rtol=0, atol=1e-12)
    assert_allclose(VANE.speed(twa, tws), expected, rtol=0, atol=1e-12)


@pytest.mark.slow
@given(
    polars(),
    st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=1, max_size=20),
)
@settings(max_examples=80, deadline=None)
def test_inside_table_modes_agree_and_stay_within_cell(p, unit_points):
    u = np.array(unit_points)
    twa = p.twa_deg[0] + u[:, 0] * (p.twa_deg[-1] - p.twa_deg[0])
    tws = p.tws_kn[0] + u[:, 1] * (p.tws_kn[-1] - p.tws_kn[0])
    twa = np.clip(twa, p.twa_deg[0], p.twa_deg[-1])  # guard the last ulp of the affine map
    tws = np.clip(tws, p.tws_kn[0], p.tws_kn[-1])
    clamp = boat_speed_kn(p, twa, tws, beyond="clamp")
    assert_array_equal(clamp, boat_speed_kn(p, twa, tws, beyond="forbid"))
    # brute force: the cell of each point by a linear scan, then its four nodes
    for a, w, s in zip(twa, tws, clamp, strict=True):
        i = max(k for k in range(p.twa_deg.size - 1) if p.twa_deg[k] <= a)
        j = max(k for k in range(p.tws_kn.size - 1) if p.tws_kn[k] <= w)
        corners = p.speed_kn[i : i + 2, j : j + 2]
        assert corners.min() - 1e-12 <= s <= corners.max() + 1e-12
    # an independent bilinear implementation
    reference = RegularGridInterpolator((p.twa_deg, p.tws_kn), p.speed_kn, method="linear")
    assert_allclose(clamp, reference(np.column_stack([twa, tws])), rtol=1e-12, atol=1e-12)


@pytest.mark.slow
@given(st.floats(0.0, 180.0), st.floats(0.0, 30.0))
@settings(max_examples=100, deadline=None)
def test_port_starboard_symmetry(twa, tws):
    ref = boat_speed_kn(VANE, twa, tws)
    assert boat_speed_kn(VANE, -twa, tws) == ref  # |angle| is exact
    # 360 - twa and twa + 720 fold back with at most an ulp of 360 deg of rounding;
    # the table's steepest slope is < 0.1 kn/deg, so 1e-10 kn is far above that and far below any real error.
    for other in (360.0 - twa, twa + 720.0, -360.0 - twa):
        assert_allclose(boat_speed_kn(VANE, other, tws), ref, rtol=0, atol=1e-10)


def test_fold_twa():
    assert_array_equal(
        fold_twa_deg([0, 30, -30, 330, 180, -180, 190, 360, 540, 721]),
        [0, 30, 30, 30, 180, 180, 170, 0, 180, 1],
    )


@pytest.mark.parametrize(
    ("twa", "tws", "clamp"),
    [
        (170.0, 25.0, pub(160, 20)),  # both axes beyond: the corner node
        (180.0, 20.0, pub(160, 20)),
        (170.0, 10.0, (pub(160, 8) + pub(160, 12)) / 2),  # TWA beyond: the TWA-160 row
        (-175.0, 4.0, pub(160, 4)),
        (100.0, 25.0, pub(100, 20)),  # TWS beyond: the 20-kn column
        (92.5, 1e9, (pub(85, 20) + pub(100, 20)) / 2),
        (92.5, np.inf, (pub(85, 20) + pub(100, 20)) / 2),
    ],
)
def test_clamp_and_forbid_outside_table(twa, tws, clamp):
    assert_allclose(boat_speed_kn(VANE, twa, tws, beyond="clamp"), clamp, rtol=0, atol=1e-12)
    assert boat_speed_kn(VANE, twa, tws, beyond="forbid") == 0.0


def test_table_edges_are_inside():
    for mode in BEYOND_MODES:
        assert boat_speed_kn(VANE, 160.0, 20.0, beyond=mode) == pub(160, 20)
        assert boat_speed_kn(VANE, -160.0, 12.0, beyond=mode) == pub(160, 12)


SPARSE = Polar(
    "sparse",
    twa_deg=[40.0, 90.0, 150.0],
    tws_kn=[6.0, 12.0],
    speed_kn=[[2.0, 3.0], [4.0, 6.0], [3.0, 5.0]],
)


@pytest.mark.parametrize("mode", BEYOND_MODES)
def test_light_air_below_first_column_ramps_to_zero(mode):
    # speed at TWS w < 6 kn is (w / 6) times the 6-kn speed at the same TWA
    assert boat_speed_kn(SPARSE, 90.0, 3.0, beyond=mode) == 0.5 * 4.0
    assert boat_speed_kn(SPARSE, 65.0, 1.5, beyond=mode) == 0.25 * (2.0 + 4.0) / 2
    assert boat_speed_kn(SPARSE, 90.0, 0.0, beyond=mode) == 0.0
    assert boat_speed_kn(SPARSE, 90.0, 6.0, beyond=mode) == 4.0


@pytest.mark.parametrize("mode", BEYOND_MODES)
def test_angles_closer_than_first_row_are_no_go(mode):
    assert_array_equal(boat_speed_kn(SPARSE, [0.0, 39.9, -20.0, 340.0], 8.0, beyond=mode), 0.0)
    assert boat_speed_kn(SPARSE, 40.0, 12.0, beyond=mode) == 3.0


def test_nan_in_nan_out_and_shapes():
    out = boat_speed_kn(VANE, [np.nan, 90.0, 90.0, np.nan], [10.0, np.nan, 10.0, np.nan], beyond="forbid")
    assert np.isnan(out).tolist() == [True, True, False, True]
    assert np.isnan(boat_speed_kn(SPARSE, np.nan, 3.0))
    assert np.isnan(boat_speed_kn(VANE, np.inf, 10.0))
    scalar = boat_speed_kn(VANE, 90.0, 10.0)
    assert isinstance(scalar, np.ndarray) and scalar.shape == ()


def test_broadcasting_matches_pointwise():
    twa = np.array([[-170.0], [0.0], [47.5], [200.0]])
    tws = np.array([0.0, 3.0, 10.0, 21.0, 30.0])
    grid = boat_speed_kn(VANE, twa, tws, beyond="forbid")
    assert grid.shape == (4, 5)
    for r in range(4):
        for c in range(5):
            assert grid[r, c] == boat_speed_kn(VANE, twa[r, 0], tws[c], beyond="forbid")


def test_bad_mode_and_negative_tws():
    with pytest.raises(ValueError, match=re.escape("'beyond' must be one of ['clamp', 'forbid'] (got 'extrapolate')")):
        boat_speed_kn(VANE, 90.0, 10.0, beyond="extrapolate")
    with pytest.raises(ValueError, match=re.escape("'beyond' must be one of ['clamp', 'forbid']")):
        VANE.speed(90.0, 10.0, beyond="Clamp")
    with pytest.raises(ValueError, match=r"'tws_kn' must be >= 0 \[kn\] \(got -2\)"):
        boat_speed_kn(VANE, [90.0, 90.0], [10.0, -2.0])


# ---------------------------------------------------------------------------------------------------------
# Files


@pytest.mark.slow
@given(polars(max_n=9))
@settings(max_examples=40, deadline=None)
def test_pol_round_trip(p):
    with tempfile.TemporaryDirectory() as tmp:
        path = write_pol(p, Path(tmp) / "random.pol")
        back = read_pol(path)
        assert back == p
        assert read_polar(path) == p
        header = path.read_text().splitlines()[0]
        assert header.startswith("TWA\\TWS\t")


@pytest.mark.slow
@given(polars(max_n=9))
@settings(max_examples=40, deadline=None)
def test_csv_round_trip(p):
    with tempfile.TemporaryDirectory() as tmp:
        path = write_polar_csv(p, Path(tmp) / "random.csv")
        assert path.read_text().splitlines()[0].startswith("twa_deg\\tws_kn,")
        assert read_polar_csv(path) == p
        assert read_polar(path) == p


SMALL = Polar(
    "small",
    twa_deg=[0.0, 52.0, 180.0],
    tws_kn=[6.0, 10.0, 15.5],
    speed_kn=[[0, 0, 0], [4.1, 5.5, 6.25], [3, 4, 5.0]],
)


@pytest.mark.parametrize(
    "text",
    [
        "TWA\\TWS\t6\t10\t15.5\n0\t0\t0\t0\n52\t4.1\t5.5\t6.25\n180\t3\t4\t5\n",  # tabs
        "TWA\\TWS 6 10 15.5\n0   0 0   0\n52 4.1 5.5 6.25\n180 3 4 5\n",  # runs of spaces
        "TWA/TWS;6;10;15.5\n0;0;0;0\n52;4.1;5.5;6.25\n180;3;4;5\n",  # semicolons (VLM)
        "twa\\tws,6,10,15.5\n0,0,0,0\n52,4.1,5.5,6.25\n180,3,4,5\n",  # commas, lower-case label
        # ', ' and other spellings of the same numbers
        "twa/tws, 6, 10, 15.5\n0, 0, 0, 0\n52, 4.10, 5.50, 6.250\n180, 3.0, 4e0, 0.5e1\n",
        "TWA\\TWS;6;10;15.5;\n0;0;0;0;\n52;4.1;5.5;6.25;\n180;3;4;5;\n",  # trailing separator
        "TWA\\TWS\t6\t10\t15.5\t\n0\t0\t0\t0\t\n52\t4.1\t5.5\t6.25\t\n180\t3\t4\t5\t\n",  # trailing tab
        ";6;10;15.5\n0;0;0;0\n52;4.1;5.5;6.25\n180;3;4;5\n",  # empty first cell
        "\t6\t10\t15.5\n0\t0\t0\t0\n52\t4.1\t5.5\t6.25\n180\t3\t4\t5\n",  # empty first cell, tabs
        "# comment\n\nTWA\\TWS\t6\t10\t15.5\n\n# another\n0\t0\t0\t0\n52\t4.1\t5.5\t6.25\n   \n180\t3\t4\t5",
        "\ufeffTWA\\TWS\t6\t10\t15.5\r\n0\t0\t0\t0\r\n52\t4.1\t5.5\t6.25\r\n180\t3\t4\t5\r\n",  # BOM, CRLF
        "TWA\\TWS \t6\t 10\t15.5\n0\t0 \t0\t0\n52\t4.1\t5.5\t6.25\n180\t3\t4\t5\n",  # stray spaces round tabs
    ],
)
def test_pol_separators_and_spellings(tmp_path, text):
    path = tmp_path / "small.pol"
    path.write_text(text, encoding="utf-8", newline="")
    assert read_pol(path) == SMALL


def test_qtvlm_like_sample(tmp_path):
    # the shape qtVlm exports: tab-separated, CRLF, a TWA-0 row, speeds at 2-kn steps, integer angles
    sample = (
        "TWA\\TWS\t0\t2\t4\t6\t8\t10\r\n"
        "0\t0\t0\t0\t0\t0\t0\r\n"
        "30\t0\t0.45\t1.02\t1.6\t2.05\t2.3\r\n"
        "45\t0\t0.82\t1.75\t2.6\t3.2\t3.55\r\n"
        "60\t0\t0.95\t1.98\t2.88\t3.5\t3.9\r\n"
        "90\t0\t1\t2.05\t3\t3.7\t4.15\r\n"
        "120\t0\t0.9\t1.85\t2.75\t3.45\t3.95\r\n"
        "150\t0\t0.7\t1.45\t2.2\t2.85\t3.35\r\n"
        "180\t0\t0.55\t1.15\t1.75\t2.3\t2.75\r\n"
    )
    path = tmp_path / "qtvlm_boat.pol"
    path.write_bytes(sample.encode("ascii"))
    p = read_pol(path)
    assert p.name == "qtvlm_boat"
    assert_array_equal(p.tws_kn, [0, 2, 4, 6, 8, 10])
    assert_array_equal(p.twa_deg, [0, 30, 45, 60, 90, 120, 150, 180])
    assert p.speed_kn[4, 3] == 3.0 and p.speed_kn[2, 5] == 3.55 and p.speed_kn[7, 1] == 0.55
    # midway between 90/120 deg and 6/8 kn: (3 + 3.7 + 2.75 + 3.45) / 4
    assert_allclose(p.speed(105.0, 7.0), (3 + 3.7 + 2.75 + 3.45) / 4, rtol=0, atol=1e-12)
    assert_allclose(p.speed(-105.0, 7.0), (3 + 3.7 + 2.75 + 3.45) / 4, rtol=0, atol=1e-12)


def test_latin1_comment_is_read(tmp_path):
    path = tmp_path / "old.pol"
    path.write_bytes(
        "# 52\xb0 close-hauled\nTWA\\TWS\t6\t10\t15.5\n0\t0\t0\t0\n52\t4.1\t5.5\t6.25\n180\t3\t4\t5\n".encode("latin-1")
    )
    assert read_pol(path, name="small") == SMALL


HEADER = "TWA\\TWS\t6\t10\n"
MALFORMED = [
    ("", 1, r"expected a header row starting with 'TWA\\TWS'.*found end of file"),
    ("# only a comment\n\n", 3, r"found end of file"),
    (
        "TWA-TWS\t6\t10\n0\t0\t0\n90\t1\t2\n",
        1,
        r"expected 'TWA\\TWS' \(or 'TWA/TWS' or an empty cell\) as the first header cell, found 'TWA-TWS'",
    ),
    ("TWA\\TWS\t6\n0\t0\n90\t1\n", 1, r"expected at least 2 TWS \[kn\] in the header row, found 1"),
    (
        "TWA\\TWS\t6\t6\n0\t0\t0\n90\t1\t2\n",
        1,
        r"column 3: expected TWS \[kn\] strictly increasing, found '6' after 6",
    ),
    (
        "TWA\\TWS\t10\t6\n0\t0\t0\n90\t1\t2\n",
        1,
        r"column 3: expected TWS \[kn\] strictly increasing, found '6' after 10",
    ),
    ("TWA\\TWS\t-2\t6\n0\t0\t0\n90\t1\t2\n", 1, r"column 2: expected a TWS >= 0 \[kn\], found '-2'"),
    ("TWA\\TWS\t6\tten\n0\t0\t0\n90\t1\t2\n", 1, r"column 3: expected a number \(TWS \[kn\]\), found 'ten'"),
    (HEADER + "0\t0\t0\n90\t1\tx2\n", 3, r"column 3: expected a number \(speed \[kn\]\), found 'x2'"),
    (HEADER + "0\t0\t0\n90\t1_0\t2\n", 3, r"column 2: expected a number \(speed \[kn\]\), found '1_0'"),
    (
        HEADER + "0\t0\t0\n90\t1\t2\t3\n",
        3,
        r"expected 3 cells \(a TWA \[deg\] and 2 speeds \[kn\], as the header on line 1; a row may end early or "
        r"leave cells empty\), found 4",
    ),
    (HEADER + "0\t0\t0\n90\t1,5\t2,5\n", 3, r"column 2: .*found '1,5' \(decimal commas are not supported\)"),
    (HEADER + "0\t\t\n90\t\t2\n", 1, r"column 2: no boat speed in any row"),
    (
        HEADER + "0\t0\t0\n90\t1\t2\n60\t1\t2\n",
        4,
        r"column 1: expected TWA \[deg\] strictly increasing down the file, found '60' after 90",
    ),
    (HEADER + "0\t0\t0\n0\t1\t2\n", 3, r"strictly increasing down the file, found '0' after 0"),
    (HEADER + "0\t0\t0\n90\t1\t-0.5\n", 3, r"column 3: expected a boat speed >= 0 \[kn\], found '-0.5'"),
    (
        HEADER + "0\t0\t0\n90\tNaN\t2\n",
        3,
        r"column 2: expected a finite number \(speed \[kn\]\), found 'NaN'",
    ),
    (
        HEADER + "0\t0\t0\n90\t1\t1e999\n",
        3,
        r"column 3: expected a finite number \(speed \[kn\]\), found '1e999'",
    ),
    (HEADER + "0\t0\t0\nnan\t1\t2\n", 3, r"column 1: expected a finite number \(TWA \[deg\]\), found 'nan'"),
    (HEADER + "0\t0\t0\n190\t1\t2\n", 3, r"column 1: expected a TWA in \[0, 180\] \[deg\], found '190'"),
    (HEADER + "-10\t0\t0\n90\t1\t2\n", 2, r"column 1: expected a TWA in \[0, 180\] \[deg\], found '-10'"),
    (HEADER + "0\t0\t0\n", 1, r"expected at least 2 TWA rows after this header, found 1"),
    (HEADER, 1, r"expected at least 2 TWA rows after this header, found 0"),
    ("# x\nTWA\\TWS;6;;10\n0;0;0\n90;1;2\n", 2, r"column 3: expected a number \(TWS \[kn\]\), found ''"),
    (HEADER + "0\t0\t0\n90\t1\t" + "\x00" * 100 + "\n", 3, r"found '(\\x00){40}\.\.\.'$"),
]


@pytest.mark.parametrize(("text", "line", "message"), MALFORMED)
def test_malformed_pol_names_file_and_line(tmp_path, text, line, message):
    path = tmp_path / "bad.pol"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(PolarError) as info:
        read_pol(path)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"polar file '{path}', line {line}: "), text
    assert re.search(message, text), text


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("", 1, r"expected a header row starting with 'twa_deg\\tws_kn'"),
        (
            "6,10\n0,0,0\n90,1,2\n",
            1,
            r"expected 'twa_deg\\tws_kn' \(or 'TWA\\TWS' or an empty cell\) as the first header cell, "
            r"found '6'",
        ),
        ("twa_deg\\tws_kn,6,10\n0,0,0\n90;1;2\n", 3, r"column 1: expected a number \(TWA \[deg\]\), found '90;1;2'"),
        (
            "twa_deg\\tws_kn,6,10\n0,0,0\n90,1 2,3\n",
            3,
            r"column 2: expected a number \(speed \[kn\]\), found '1 2'",
        ),
        ("twa_deg\\tws_kn,6,10\n0,0,0\n90,1,-2\n", 3, r"column 3: expected a boat speed >= 0"),
    ],
)
def test_malformed_csv_names_file_and_line(tmp_path, text, line, message):
    path = tmp_path / "bad.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(PolarError) as info:
        read_polar_csv(path)
    assert str(info.value).startswith(f"polar file '{path}', line {line}: "), str(info.value)
    assert re.search(message, str(info.value)), str(info.value)


def test_csv_reads_its_documented_form_and_pol_label(tmp_path):
    path = tmp_path / "small.csv"
    path.write_text('# small\n"twa_deg\\tws_kn",6,10,15.5,\n0,0,0,0\n52,4.1,5.5,6.25\n180,3,4,5\n')
    assert read_polar_csv(path) == SMALL
    path.write_text("TWA\\TWS,6,10,15.5\n0,0,0,0\n52,4.1,5.5,6.25\n180,3,4,5\n")
    assert read_polar(path) == SMALL


def test_missing_file_and_bad_suffix(tmp_path):
    missing = tmp_path / "nope.pol"
    with pytest.raises(PolarError, match=rf"polar file '{re.escape(str(missing))}': cannot be read"):
        read_pol(missing)
    with pytest.raises(PolarError, match=r"suffix must be one of \['.pol', '.txt', '.csv'\] \(got '.xlsx'\)"):
        read_polar(tmp_path / "boat.xlsx")


def test_read_polar_dispatches_by_suffix(tmp_path):
    for suffix in (".pol", ".txt", ".POL"):
        write_pol(SMALL, tmp_path / f"small{suffix}")
        assert read_polar(tmp_path / f"small{suffix}") == SMALL
    write_polar_csv(SMALL, tmp_path / "small.csv")
    assert read_polar(tmp_path / "small.csv") == SMALL
    assert read_polar(tmp_path / "small.csv", name="other").name == "other"


def test_writers_are_atomic(tmp_path, monkeypatch):
    target = tmp_path / "boat.pol"
    target.write_text("old contents\n")

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(polar_mod.os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        write_pol(SMALL, target)
    assert target.read_text() == "old contents\n"
    assert sorted(os.listdir(tmp_path)) == ["boat.pol"]  # the temporary file is gone
    monkeypatch.undo()

    write_pol(SMALL, target)
    write_polar_csv(SMALL, tmp_path / "boat.csv")
    assert sorted(os.listdir(tmp_path)) == ["boat.csv", "boat.pol"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask  # as a plain open() would create it


# ---------------------------------------------------------------------------------------------------------
# Built-ins and the example file


def test_get_polar(tmp_path):
    assert get_polar("maribot_vane") is VANE
    assert get_polar(SMALL) is SMALL
    write_pol(SMALL, tmp_path / "small.pol")
    assert get_polar("small.pol", base_dir=tmp_path) == SMALL
    assert get_polar(tmp_path / "small.pol") == SMALL
    assert get_polar(str(tmp_path / "small.pol"), base_dir="/elsewhere") == SMALL  # absolute wins
    with pytest.raises(
        PolarError,
        match=r"unknown polar 'maribot_vain': expected one of the built-in polars \['maribot_vane'\]",
    ):
        get_polar("maribot_vain")
    with pytest.raises(PolarError, match=r"polar must be a built-in name \['maribot_vane'\] or a path .*\(got int 3\)"):
        get_polar(3)  # type: ignore[arg-type]
    with pytest.raises(PolarError, match=r"polar file '.*missing.pol': cannot be read"):
        get_polar("missing.pol", base_dir=tmp_path)


def test_example_file_is_the_builtin_written_by_write_pol(tmp_path):
    example = EXAMPLES / "maribot_vane.pol"
    assert read_pol(example) == VANE
    assert example.read_text().splitlines()[0] == "TWA\\TWS\t0\t4\t8\t12\t16\t20"
    assert example.read_bytes() == write_pol(VANE, tmp_path / "maribot_vane.pol").read_bytes()


def test_polar_errors_are_domain_errors(tmp_path) -> None:
    from pyroute_rel.boat.polar import boat_speed_kn, get_polar, write_pol
    from pyroute_rel.errors import OutputError, PolarError

    vane = get_polar("maribot_vane")
    with pytest.raises(PolarError, match=r"'tws_kn' must be >= 0"):
        boat_speed_kn(vane, 90.0, -1.0)
    with pytest.raises(OutputError, match=r"cannot write polar file .*missing_dir"):
        write_pol(vane, tmp_path / "missing_dir" / "v.pol")


def test_beyond_is_checked_in_one_place_with_one_error():
    from pyroute_rel._kernels.cost import sail_wind
    from pyroute_rel.boat.polar import check_beyond
    from pyroute_rel.errors import PolarError
    from pyroute_rel.routing.solve import RoutingProblem
    from pyroute_rel.weather import UniformWeather

    assert [check_beyond(b) for b in ("clamp", "forbid")] == ["clamp", "forbid"]
    one = np.ones((1, 1))
    for call, name in (
        (lambda: check_beyond(["clamp"]), "'beyond'"),
        (lambda: boat_speed_kn(VANE, 90.0, 10.0, beyond="wrap"), "'beyond'"),
        (lambda: sail_wind(one, one, one, one, VANE, beyond="wrap"), "'beyond'"),
        (
            lambda: RoutingProblem(
                departure=np.datetime64("2018-06-01"),
                weather=UniformWeather(tws_kn=10.0, twd_deg=0.0),
                polar=VANE,
                beyond="wrap",
            ),
            "RoutingProblem.beyond",
        ),
    ):
        with pytest.raises(PolarError, match=re.escape(f"{name} must be one of ['clamp', 'forbid']")):
            call()


def test_an_unknown_polar_name_is_cut_in_the_message() -> None:
    # A 5000-character name was echoed whole: one error "line" of over 5000 characters.
    with pytest.raises(PolarError, match=r"unknown polar 'xxx+\.\.\.: expected one of the built-in polars") as info:
        get_polar("x" * 5000)
    assert len(str(info.value)) < 200


@pytest.mark.parametrize("fast", [300.0, 1e30])
def test_a_polar_faster_than_any_sailing_craft_is_refused(tmp_path, fast) -> None:
    """Issue 34: a 300 kn (or 1e30 kn) polar crossed 534 nm in 1.78 h. 100 kn is accepted (an edge of the rule), more
    is refused with the cell named, from a file as from arrays."""
    from pyroute_rel.boat.polar import MAX_SPEED_KN, Polar, read_polar
    from pyroute_rel.errors import PolarError

    twa, tws = np.array([0.0, 90.0, 180.0]), np.array([0.0, 10.0])
    assert Polar("edge", twa, tws, np.array([[0.0, MAX_SPEED_KN], [0.0, 5.0], [0.0, 4.0]])).speed_kn.max() == 100.0
    with pytest.raises(
        PolarError, match=re.escape(f"must be at most 100 [kn] (got {fast:g} at TWA 90 deg, TWS 10 kn)")
    ):
        Polar("fast", twa, tws, np.array([[0.0, 1.0], [0.0, fast], [0.0, 4.0]]))
    path = tmp_path / "fast.pol"
    path.write_text(f"TWA\\TWS\t0\t10\n0\t0\t1\n90\t0\t{fast:g}\n180\t0\t4\n")
    with pytest.raises(PolarError, match="is the table in another unit"):
        read_polar(path)


def test_an_empty_tws_column_is_dropped_with_a_warning_while_two_remain(tmp_path) -> None:
    """Issue 34: 2 of the 714 polar files of OpenCPN's weather routing plugin were refused, one for a TWS column whose
    every cell is empty (Example-24-60.pol); OpenCPN reads them. The column is dropped with a warning naming it, the
    others read as written; a table left with one column is still refused."""
    from pyroute_rel.boat.polar import read_polar
    from pyroute_rel.errors import PolarError, PolarWarning

    path = tmp_path / "gap.pol"
    path.write_text("TWA\\TWS\t6\t10\t14\n0\t0\t\t0\n90\t4\t\t6\n180\t3\t\t4.5\n")
    with pytest.warns(PolarWarning, match=r"TWS column\(s\) 10 kn have no boat speed in any row: dropped"):
        p = read_polar(path)
    assert p.tws_kn.tolist() == [6.0, 14.0] and p.speed_kn.tolist() == [[0.0, 0.0], [4.0, 6.0], [3.0, 4.5]]
    path.write_text("TWA\\TWS\t6\t10\t14\n0\t0\t\t\n90\t4\t\t\n")
    with pytest.raises(PolarError, match=r"column 3: no boat speed in any row"):
        read_polar(path)
