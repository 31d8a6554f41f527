"""Polar files as people have them (issue 17 item 9): the layouts of the .pol files shipped with OpenCPN's weather
routing plugin and written by other tools, each written here by hand, read into the same table.

Reference table (TWA 0/60/120/180 deg x TWS 6/12 kn), written out by hand in every layout below.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pyroute_rel.boat.polar import read_pol, read_polar
from pyroute_rel.errors import PolarError, PolarWarning

TWS = [6.0, 12.0]
TWA = [0.0, 60.0, 120.0, 180.0]
TABLE = [[0.0, 0.0], [3.5, 5.25], [4.0, 6.5], [2.5, 4.0]]

LAYOUTS = {
    "tab, TWA\\TWS": "TWA\\TWS\t6\t12\n0\t0\t0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\t4\n",
    "tab, corner 'TWA' alone": "TWA\t6\t12\n0\t0\t0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\t4\n",
    "tab, corner 'twa' lower case": "twa\t6\t12\n0\t0\t0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\t4\n",
    "tab, corner 'TWS' alone": "TWS\t6\t12\n0\t0\t0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\t4\n",
    "tab, corner TWA/TWS": "TWA/TWS\t6\t12\n0\t0\t0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\t4\n",
    "tab, empty corner": "\t6\t12\n0\t0\t0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\t4\n",
    "semicolons": "TWA\\TWS;6;12\n0;0;0\n60;3.5;5.25\n120;4;6.5\n180;2.5;4\n",
    "semicolons with spaces and a trailing one": "TWA\\TWS ; 6 ; 12 ;\n0;0;0;\n60 ; 3.5 ; 5.25\n120;4;6.5\n180;2.5;4\n",
    "commas": "TWA\\TWS,6,12\n0,0,0\n60,3.5,5.25\n120,4,6.5\n180,2.5,4\n",
    "spaces": "TWA\\TWS   6   12\n0 0 0\n60  3.5  5.25\n120 4 6.5\n180 2.5 4\n",
    "windows line ends": "TWA\\TWS\t6\t12\r\n0\t0\t0\r\n60\t3.5\t5.25\r\n120\t4\t6.5\r\n180\t2.5\t4\r\n",
    "comments and blank lines": "# my boat\n\nTWA\\TWS\t6\t12\n# upwind\n0\t0\t0\n60\t3.5\t5.25\n\n120\t4\t6.5\n"
    "180\t2.5\t4\n",
}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_every_layout_reads_the_same_table(tmp_path, layout) -> None:
    path = tmp_path / "boat.pol"
    path.write_bytes(LAYOUTS[layout].encode())
    polar = read_pol(path)
    np.testing.assert_array_equal(polar.tws_kn, TWS)
    np.testing.assert_array_equal(polar.twa_deg, TWA)
    np.testing.assert_array_equal(polar.speed_kn, TABLE)


def test_a_byte_order_mark_and_a_txt_suffix(tmp_path) -> None:
    path = tmp_path / "boat.txt"
    path.write_bytes(b"\xef\xbb\xbf" + LAYOUTS["tab, TWA\\TWS"].replace("\n", "\r\n").encode())
    np.testing.assert_array_equal(read_polar(path).speed_kn, TABLE)


def test_empty_cells_inside_a_column_are_interpolated_in_twa(tmp_path) -> None:
    # 60 deg at 6 kn and 120 deg at 12 kn are empty: linear in TWA between the rows above and below
    path = tmp_path / "gaps.pol"
    path.write_text("TWA\\TWS\t6\t12\n0\t0\t0\n60\t\t5.25\n120\t4\t\n180\t2.5\t4\n")
    with pytest.warns(PolarWarning, match=r"2 empty or missing speed cell\(s\) filled \(first: line 3, column 2\)"):
        polar = read_pol(path)
    expected = np.array(TABLE)
    expected[1, 0] = 0.0 + (4.0 - 0.0) * (60.0 - 0.0) / (120.0 - 0.0)  # 2.0 kn
    expected[2, 1] = 5.25 + (4.0 - 5.25) * (120.0 - 60.0) / (180.0 - 60.0)  # 4.625 kn
    np.testing.assert_allclose(polar.speed_kn, expected, rtol=0, atol=1e-15)


def test_a_short_row_and_empty_end_cells_are_no_speed(tmp_path) -> None:
    # the 0-deg row has no speeds at all, the last row stops after its first speed: nothing is given further up
    # or down those columns, so the boat has no speed there (0 kn)
    path = tmp_path / "short.pol"
    path.write_text("TWA\\TWS\t6\t12\n0\n60\t3.5\t5.25\n120\t4\t6.5\n180\t2.5\n")
    with pytest.warns(PolarWarning, match=r"3 empty or missing .* 0 interpolated .* 3 set to 0 kn"):
        polar = read_pol(path)
    expected = np.array(TABLE)
    expected[3, 1] = 0.0
    np.testing.assert_array_equal(polar.speed_kn, expected)


def test_an_edge_gap_with_speeds_beside_it_in_its_row_is_interpolated_in_tws(tmp_path) -> None:
    # OpenCPN's Figaro_1-1.pol lost one cell of its last row (TWA 180, TWS 10) between two 4.9 kn cells: nothing
    # lies below it in its column, but its row is rated on both sides, so it is interpolated in TWS (was 0 kn); the
    # last cell of the 180-deg row has nothing to its right: 0 kn
    path = tmp_path / "figaro.pol"
    path.write_text("TWA\\TWS\t6\t10\t14\t20\n0\t0\t0\t0\t0\n90\t5\t6\t7\t7.5\n180\t4.5\t\t5.3\t\n")
    with pytest.warns(PolarWarning, match=r"2 empty .* 0 interpolated in TWA .* 1 in TWS .* 1 set to 0 kn"):
        polar = read_pol(path)
    assert polar.speed_kn[2, 1] == pytest.approx(4.5 + (5.3 - 4.5) * (10 - 6) / (14 - 6), rel=1e-15)  # 4.9 kn
    assert polar.speed_kn[2, 3] == 0.0 and polar.speed_kn[1, 3] == 7.5


def test_a_complete_file_gives_no_warning(tmp_path) -> None:
    path = tmp_path / "boat.pol"
    path.write_text(LAYOUTS["tab, TWA\\TWS"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_pol(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("TWA\\TWS\t6\t12\n0\t\t0\n60\t\t5\n", r"line 1: column 2: no boat speed in any row"),
        ("TWA\\TWS\t6\t12\n0\t0\t0\t0\n60\t1\t2\n", r"line 2: expected 3 cells .* found 4"),
        ("TWA\\TWS\t6\t12\n0\t0\t0\n60\t1\tfast\n", r"line 3: column 3: expected a number \(speed \[kn\]\)"),
        ("Boat speed table\n0\t0\t0\n", r"line 1: expected 'TWA\\TWS'"),
    ],
)
def test_what_is_truly_unreadable_is_still_refused(tmp_path, text, message) -> None:
    path = tmp_path / "bad.pol"
    path.write_text(text)
    with pytest.raises(PolarError, match=message):
        read_pol(path)


def test_the_cli_says_so_in_one_line(tmp_path, capsys) -> None:
    """pyroute-rel prints a filled polar's warning as one line on stderr, and routes."""
    from pathlib import Path

    from pyroute_rel.cli import main

    (tmp_path / "b.pol").write_text("TWA\\TWS\t6\t12\t20\n0\t0\t0\t0\n40\t2\t\t4\n90\t4\t6\t7\n150\t3\t5\n")
    control = (Path(__file__).resolve().parents[1] / "examples" / "microtransat_control.toml").read_text()
    assert 'polar = "maribot_vane"' in control
    (tmp_path / "s.toml").write_text(control.replace('polar = "maribot_vane"', 'polar = "b.pol"'))
    code = main(["route", str(tmp_path / "s.toml"), "--quiet", "--n-ranks", "20"])
    err = capsys.readouterr().err.splitlines()
    assert code == 0
    warned = [line for line in err if "warning" in line]
    assert len(warned) == 1 and warned[0].startswith("pyroute-rel: warning: polar file ")
    assert "2 empty or missing speed cell(s) filled" in warned[0]
