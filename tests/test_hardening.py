"""Hardening, round 2 (issue 17): GCI gates that cannot pass by accident, all-or-nothing outputs, coordinates and
zones that look wrong, and exit 2 with one line for user mistakes that used to be internal errors (exit 3)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pyroute_rel.cli import main
from pyroute_rel.gci.numbers import P_PLAUSIBLE, ROUNDOFF_REL, convergence_study, grid_convergence

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "microtransat_control.toml"
SMALL = ["--layout", "square", "--n-nodes", "7", "--n-ranks", "7", "--no-land", "--quiet"]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's usage errors
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def cli(*args: str, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pyroute_rel.cli", *args], capture_output=True, text=True, env=ENV, timeout=120, **kw
    )


# --------------------------------------------------------------------------------------------------
# item 6: GCI gates
# --------------------------------------------------------------------------------------------------


def test_roundoff_differences_make_the_triplet_indeterminate() -> None:
    # eps21 = 1e-300, max|phi| = 1: far below 1e-10 * 1, so no order (it used to be p = 996.6)
    res = grid_convergence([1.0, 2.0, 4.0], [0.0, 1e-300, 1.0])
    assert res.convergence == "indeterminate" and res.p is None and res.gci_fine is None
    assert "round-off" in res.note
    # 700 vs 700.000000000001: eps21 = 1.02e-12 <= 1e-10 * 703 = 7.03e-8
    res = grid_convergence([1.0, 2.0, 4.0], [700.0, 700.000000000001, 703.0])
    assert res.convergence == "indeterminate" and res.p is None
    # just above the threshold the triplet is judged as before: eps21 = 2e-10 * 703 > tol
    eps = 2 * ROUNDOFF_REL * 703.0
    res = grid_convergence([1.0, 2.0, 4.0], [700.0, 700.0 + eps, 703.0])
    assert res.convergence == "monotonic" and res.p is not None


@pytest.mark.parametrize(
    ("phi", "verdict"),
    [
        ([12.0, 18.0, 42.0], "converging"),  # 10 + 2 h^2: p = 2
        ([10.0 + 2.0 * h**0.45 for h in (1.0, 2.0, 4.0)], "indeterminate"),  # p = 0.45 < 0.5
        ([10.0 + 2.0 * h**0.55 for h in (1.0, 2.0, 4.0)], "converging"),  # p = 0.55
        ([10.0 + 1e-3 * h**7.9 for h in (1.0, 2.0, 4.0)], "converging"),  # p = 7.9
        ([10.0 + 1e-3 * h**8.1 for h in (1.0, 2.0, 4.0)], "indeterminate"),  # p = 8.1 > 8
        ([5.0, 5.0, 5.0], "converged"),
        ([1.0, 3.0, 4.0], "indeterminate"),  # divergent
    ],
)
def test_study_verdict_on_the_plausible_order_range(phi: list[float], verdict: str) -> None:
    assert P_PLAUSIBLE == (0.5, 8.0)
    study = convergence_study([1.0, 2.0, 4.0], phi)
    assert study.verdict()[0] == verdict
    assert study.to_dict()["verdict"] == verdict


def test_issue_case_gate_fails_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["gci", "--h", "1,2,4", "--phi", "700,700.000000000001,703", "--max-gci", "0.01", "--require-asymptotic"]
    code, _, err = run(args, capsys)
    assert code == 1 and err.count("\n") == 1
    assert "indeterminate" in err and "round-off" in err
    # an implausible order (p = 9.964 from 10, 10.001, 11: |eps32/eps21| = 0.999 / 0.001 = 999 = 2^9.964)
    code, _, err = run(["gci", "--h", "1,2,4", "--phi", "10,10.001,11", "--max-gci", "0.5"], capsys)
    assert code == 1 and "outside the plausible 0.5 to 8" in err
    # without a gate the study is reported, exit 0
    code, out, _ = run(["gci", "--h", "1,2,4", "--phi", "10,10.001,11", "--json"], capsys)
    assert code == 0 and json.loads(out)["verdict"] == "indeterminate"


@pytest.mark.parametrize("json_flag", [["--json"], []])
def test_gate_failure_survives_a_closed_pipe(json_flag: list[str]) -> None:
    cmd = [sys.executable, "-m", "pyroute_rel.cli", "gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8"]
    cmd += ["--max-gci", "0.0001", *json_flag]
    alone = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=60)
    assert alone.returncode == 1
    # the reader closes the pipe at once; the gate's verdict must still be the exit code
    code, err = _closed_pipe(cmd)
    assert code == 1
    assert "gate failed" in err and "Traceback" not in err and "Exception ignored" not in err
    # a passing gate with a closed pipe is still 0
    ok = [*cmd[: -2 - len(json_flag)], "--max-gci", "0.5", *json_flag]
    assert _closed_pipe(ok) == (0, "")


def _closed_pipe(cmd: list[str]) -> tuple[int, str]:
    """Run ``cmd`` with its stdout read by no one (closed at once): exit code, stderr."""
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV) as proc:
        proc.stdout.close()
        err = proc.stderr.read().decode()
        return proc.wait(timeout=60), err


# --------------------------------------------------------------------------------------------------
# item 5: all-or-nothing outputs
# --------------------------------------------------------------------------------------------------


def listing(folder: Path) -> dict[str, str]:
    """Every entry under ``folder`` (recursively) with its content ('<dir>' for folders, sizes of big files)."""

    def content(p: Path) -> str:
        if p.is_symlink() or not (p.is_file() or p.is_dir()):
            return "<special>"
        if p.is_dir():
            return "<dir>"
        size = p.stat().st_size
        return p.read_text(errors="replace") if size < 100_000 else f"<{size} bytes>"

    return {str(p.relative_to(folder)): content(p) for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("in_the_way", ["route.csv", "route.png", "summary.json"])
def test_route_refuses_a_folder_where_a_file_goes(
    in_the_way: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    (out / in_the_way).mkdir(parents=True)
    (out / "route.gpx").write_text("an earlier run's gpx")
    before = listing(out)
    code, outtext, err = run(["route", str(EXAMPLE), *SMALL, "--out", str(out)], capsys)
    assert code == 2 and err.count("\n") == 1 and outtext == ""
    assert f"{in_the_way} is a folder" in err and "nothing was written" in err
    assert listing(out) == before  # nothing written, nothing removed, no staging folder


@pytest.mark.parametrize("in_the_way", ["gci.json", "gci.png"])
def test_gci_refuses_a_folder_where_a_file_goes(
    in_the_way: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "g"
    (out / in_the_way).mkdir(parents=True)
    before = listing(out)
    code, _, err = run(["gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8", "--out", str(out)], capsys)
    assert code == 2 and err.count("\n") == 1 and f"{in_the_way} is a folder" in err
    assert listing(out) == before


def test_write_together_checks_every_target_first(tmp_path: Path) -> None:
    from pyroute_rel.errors import OutputError
    from pyroute_rel.files import write_together

    (tmp_path / "c.txt").mkdir()
    calls = []
    writers = {n: (lambda p, n=n: (calls.append(n), p.write_text(n))) for n in ("a.txt", "b.txt", "c.txt")}
    with pytest.raises(OutputError, match="c.txt is a folder"):
        write_together(tmp_path, writers)
    assert calls == [] and listing(tmp_path) == {"c.txt": "<dir>"}


def test_a_failed_publish_restores_the_previous_set(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from pyroute_rel.errors import OutputError
    from pyroute_rel.files import write_together

    for n in ("a.txt", "b.txt", "c.txt"):
        (tmp_path / n).write_text(f"old {n}")
    real_replace = os.replace
    published = []

    def replace(src, dst):  # the third rename into the folder fails (a disk error, say)
        if Path(dst).parent == tmp_path and not Path(src).name.startswith(".old-"):
            if len(published) == 2:
                raise OSError(5, "Input/output error")
            published.append(dst)
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OutputError, match="Input/output error"):
        write_together(tmp_path, {n: (lambda p, n=n: p.write_text(f"new {n}")) for n in ("a.txt", "b.txt", "c.txt")})
    assert len(published) == 2  # two were published, then put back
    assert listing(tmp_path) == {n: f"old {n}" for n in ("a.txt", "b.txt", "c.txt")}


SLOW_WRITER = """
import sys, time
from pathlib import Path
from pyroute_rel.files import write_together

def slow(p: Path) -> None:
    p.write_text("partial")
    print("writing", flush=True)
    time.sleep(60)

write_together(sys.argv[1], {"a.txt": lambda p: p.write_text("a"), "b.txt": slow})
"""


def _start_slow_writer(out: Path) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, "-c", SLOW_WRITER, str(out)], stdout=subprocess.PIPE, text=True, env=ENV)
    assert proc.stdout.readline() == "writing\n"  # inside the second writer: a.txt and b.txt are staged
    return proc


def test_a_killed_run_leaves_staging_that_the_next_run_removes(tmp_path: Path) -> None:
    from pyroute_rel.files import STAGING_MARKER, STAGING_PREFIX

    out = tmp_path / "g"
    out.mkdir()
    with _start_slow_writer(out) as proc:
        proc.kill()  # SIGKILL: nothing of ours runs
        proc.wait(timeout=30)
    (staging,) = [p for p in out.iterdir()]
    assert staging.name.startswith(STAGING_PREFIX)
    assert sorted(p.name for p in staging.iterdir()) == sorted([STAGING_MARKER, "a.txt", "b.txt"])
    # a folder of the same prefix that is not ours (no marker) and one of a live writer (this test's pid) stay
    foreign = out / f"{STAGING_PREFIX}mine"
    foreign.mkdir()
    (foreign / "keep.txt").write_text("user data")
    live = out / f"{STAGING_PREFIX}live"
    live.mkdir()
    (live / STAGING_MARKER).write_text(f"pyroute-rel staging\npid {os.getpid()}\n")
    done = cli("gci", "--h", "1,2,4", "--phi", "700.3,701.2,704.8", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert not staging.exists()
    assert sorted(p.name for p in out.iterdir()) == sorted(["gci.csv", "gci.json", "gci.png", foreign.name, live.name])
    assert (foreign / "keep.txt").read_text() == "user data"


@pytest.mark.slow
def test_sigterm_while_writing_leaves_nothing(tmp_path: Path) -> None:
    import signal

    out = tmp_path / "g"  # created by the writer: removed again, as nothing was published
    with _start_slow_writer(out) as proc:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    assert not out.exists()


def test_empty_out_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(["route", str(EXAMPLE), *SMALL, "--out", ""], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and "--out needs a folder name" in err
    code, out, err = run(["gci", "--h", "1,2,4", "--phi", "1,2,4", "--out", ""], capsys)
    assert code == 2 and "--out needs a folder name" in err


def test_file_mode_never_sets_the_umask(monkeypatch: pytest.MonkeyPatch) -> None:
    from pyroute_rel import files

    mask = os.umask(0o027)  # the test's own reference: a umask other than the usual 022
    try:

        def no_umask(_: int) -> int:
            raise AssertionError("file_mode() changed the umask")

        monkeypatch.setattr(os, "umask", no_umask)
        files.file_mode.cache_clear()
        assert files.file_mode() == 0o640  # 0o666 & ~0o027
        # without /proc: the probe file's mode
        real_read_text = Path.read_text

        def no_proc(self: Path, *a, **k) -> str:
            if str(self) == "/proc/self/status":
                raise OSError(2, "No such file or directory")
            return real_read_text(self, *a, **k)

        monkeypatch.setattr(Path, "read_text", no_proc)
        files.file_mode.cache_clear()
        assert files.file_mode() == 0o640
    finally:
        monkeypatch.undo()
        os.umask(mask)
        files.file_mode.cache_clear()


# --------------------------------------------------------------------------------------------------
# item 3: exit 2 and one line for user mistakes that used to be internal errors (or hangs)
# --------------------------------------------------------------------------------------------------

BASE = EXAMPLE.read_text()
SQUARE = POLY = {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 0]]]}


def _scenario(tmp: Path, text: str, name: str = "s.toml") -> str:
    (tmp / name).write_text(text)
    return str(tmp / name)


def _with_zone(tmp: Path, zone_file: str, content: object = None, raw: bytes | None = None) -> str:
    """A scenario whose [avoid].zones lists ``zone_file`` (written from ``content`` or ``raw`` when given)."""
    if raw is not None:
        (tmp / zone_file).write_bytes(raw)
    elif content is not None:
        (tmp / zone_file).write_text(json.dumps(content))
    return _scenario(tmp, BASE + f'\n[avoid]\nland = false\nzones = ["{zone_file}"]\n')


def _feature(**props: object) -> dict:
    return {"type": "Feature", "properties": props, "geometry": SQUARE}


def _fifo(tmp: Path, name: str) -> str:
    os.mkfifo(tmp / name)
    return str(tmp / name)


def _sparse(tmp: Path, name: str, size: int, head: bytes = b"") -> str:
    with open(tmp / name, "wb") as fh:
        fh.write(head)
        fh.truncate(size)
    return str(tmp / name)


def _route(scenario: str, *extra: str) -> list[str]:
    return ["route", scenario, *SMALL, *extra]


#: (builder of the arguments, a fragment the one-line message must hold); the first 11 are the issue's cases, the
#: others (62) our own.
MISTAKES = {
    "toml 5000 nested arrays": (
        lambda t: ["route", _scenario(t, "x = " + "[" * 5000 + "]" * 5000 + "\n")],
        "nested too deeply",
    ),
    "toml 3000 nested tables": (
        lambda t: ["route", _scenario(t, "[" + ".".join(["a"] * 3000) + "]\n")],
        "nested 3001 levels deep",
    ),
    "geojson nested 1e5 deep": (
        lambda t: _route(_with_zone(t, "z.geojson", raw=b"[" * 10**5 + b"]" * 10**5)),
        "nested too deeply",
    ),
    "zone crs.properties = [1]": (
        lambda t: _route(_with_zone(t, "z.geojson", {**SQUARE, "crs": {"type": "name", "properties": [1]}})),
        "WGS84 lon/lat",
    ),
    "zone valid_from year 1 +05:00": (
        lambda t: _route(_with_zone(t, "z.geojson", _feature(valid_from="0001-01-01T00:00:00+05:00"))),
        "'valid_from' is out of range in UTC",
    ),
    "--out component of 300 characters": (
        lambda t: _route(str(EXAMPLE), "--out", str(t / ("x" * 300))),
        "File name too long",
    ),
    "--out path of 5000 characters": (
        lambda t: _route(str(EXAMPLE), "--out", str(t / "/".join(["abcdefghi"] * 500))),
        "File name too long",
    ),
    "scenario /dev/zero": (lambda t: ["route", "/dev/zero"], "not a regular file (a character device)"),
    "scenario FIFO without a writer": (lambda t: ["route", _fifo(t, "s.toml")], "not a regular file (a FIFO)"),
    "polar name of 5 MB": (
        lambda t: _route(_scenario(t, BASE.replace('"maribot_vane"', '"' + "p" * 5_000_000 + '"'))),
        "unknown polar 'ppppppppp",  # the name is cut where the message is made (no need for the CLI's cap)
    ),
    "polar name of 10 MB (file over the limit)": (
        lambda t: _route(_scenario(t, BASE.replace('"maribot_vane"', '"' + "p" * 10_000_000 + '"'))),
        "larger than the 10 MB limit",
    ),
    # --- our own ---
    "toml 3000 nested inline tables": (
        lambda t: ["route", _scenario(t, "x = " + "{a=" * 3000 + "1" + "}" * 3000 + "\n")],
        "nested too deeply",
    ),
    "zone valid_to year 9999 -05:00": (
        lambda t: _route(_with_zone(t, "z.geojson", _feature(valid_to="9999-12-31T23:00:00-05:00"))),
        "'valid_to' is out of range in UTC",
    ),
    "zone crs.properties a string": (
        lambda t: _route(_with_zone(t, "z.geojson", {**SQUARE, "crs": {"properties": "x" * 10**5}})),
        "WGS84 lon/lat",
    ),
    "gci --out component of 300 characters": (
        lambda t: ["gci", "--h", "1,2,4", "--phi", "1,2,4", "--out", str(t / ("x" * 300))],
        "File name too long",
    ),
    "scenario is a folder": (lambda t: ["route", str(t)], "not a regular file (a folder)"),
    "scenario of 11 MB": (lambda t: ["route", _sparse(t, "s.toml", 11_000_000)], "larger than the 10 MB limit"),
    "scenario not UTF-8": (lambda t: ["route", _sparse(t, "s.toml", 8, b"\xff\xfe\x00\x80")], "not UTF-8 text"),
    "scenario a symlink loop": (
        lambda t: (os.symlink(t / "loop.toml", t / "loop.toml"), ["route", str(t / "loop.toml")])[1],
        "Too many levels of symbolic links",
    ),
    "unknown key of 100 kB": (
        lambda t: _route(_scenario(t, BASE.replace("[grid]\n", "[grid]\n" + "k" * 100_000 + " = 1\n"))),
        "characters cut",
    ),
    "zone file /dev/zero": (lambda t: _route(_with_zone(t, "/dev/zero")), "zone file is not a regular file"),
    "zone file a FIFO": (lambda t: (_fifo(t, "z.geojson"), _route(_with_zone(t, "z.geojson")))[1], "(a FIFO)"),
    "zone file of 101 MB": (
        lambda t: (_sparse(t, "z.geojson", 101_000_000), _route(_with_zone(t, "z.geojson")))[1],
        "larger than the 100 MB limit",
    ),
    "zone file not UTF-8": (lambda t: _route(_with_zone(t, "z.geojson", raw=b'{"type": "\xff"}')), "not UTF-8"),
    "zone polygon crossing itself": (
        lambda t: _route(
            _with_zone(t, "z.geojson", {"type": "Polygon", "coordinates": [[[0, 0], [2, 2], [2, 0], [0, 2], [0, 0]]]})
        ),
        "edges cross at lon 1, lat 1",
    ),
    "failure model /dev/zero": (lambda t: _route(str(EXAMPLE), "--failure-model", "/dev/zero"), "not a regular file"),
    "failure model a FIFO": (
        lambda t: _route(str(EXAMPLE), "--failure-model", _fifo(t, "m.toml")),
        "not a regular file (a FIFO)",
    ),
    "polar file a FIFO": (
        lambda t: (_fifo(t, "b.pol"), _route(_scenario(t, BASE.replace('"maribot_vane"', '"b.pol"'))))[1],
        "not a regular file (a FIFO)",
    ),
    "--out a FIFO": (lambda t: _route(str(EXAMPLE), "--out", _fifo(t, "o")), "is a file, not a folder"),
    "--out with route.csv a FIFO": (
        lambda t: ((t / "o").mkdir(), _fifo(t / "o", "route.csv"), _route(str(EXAMPLE), "--out", str(t / "o")))[2],
        "route.csv is not a regular file",
    ),
    "gci --h of 100 kB garbage": (lambda t: ["gci", "--h", "x" * 100_000, "--phi", "1,2,3"], "characters cut"),
    "--departures of 100 kB garbage": (
        lambda t: _route(str(EXAMPLE), "--departures", "x" * 100_000),
        "characters cut",
    ),
    "departure year 1 +05:00": (
        lambda t: _route(_scenario(t, BASE.replace('"2018-06-01T00:00:00Z"', '"0001-01-01T00:00:00+05:00"'))),
        "out of range",
    ),
    # --- our own, round 3: failure models
    "failure model criterion on an unknown quantity": (
        lambda t: _route(str(EXAMPLE), "--failure-model", _model(t, MODEL.replace('"hs_m"', '"wind_gust"'))),
        "criteria[0] (WH): 'quantity' must be one of ['hs_m'",
    ),
    "failure model probability = 1.5 in a criterion": (
        lambda t: _route(
            str(EXAMPLE), "--failure-model", _model(t, MODEL.replace("= 4.0", "= 4.0\nprobability = 1.5"))
        ),
        "criteria[0] (WH): unknown key 'probability'",
    ),
    "failure model two criteria on one node": (
        lambda t: _route(str(EXAMPLE), "--failure-model", _model(t, MODEL.replace('node = "WD"', 'node = "WH"'))),
        "criteria[1] (WH): node 'WH' is set by two criteria",
    ),
    "failure model exposure_h = -1": (
        lambda t: _route(
            str(EXAMPLE), "--failure-model", _model(t, MODEL.replace("exposure_h = 4.4", "exposure_h = -1"))
        ),
        "'exposure_h' must be a finite number of hours > 0",
    ),
    "failure model threshold = nan": (
        lambda t: _route(str(EXAMPLE), "--failure-model", _model(t, MODEL.replace("= 4.0", "= nan"))),
        "criteria[0] (WH): 'threshold' must be a finite number (got nan)",
    ),
    "failure model an empty file": (
        lambda t: _route(str(EXAMPLE), "--failure-model", _model(t, "")),
        "m.toml: missing key 'network'",
    ),
    # polars
    "polar negative speed": (
        lambda t: _route(_polar(t, POL.replace("\t5\t6", "\t-5\t6"))),
        "b.pol', line 3: column 3: expected a boat speed >= 0 [kn], found '-5'",
    ),
    "polar TWA 190": (
        lambda t: _route(_polar(t, POL.replace("180\t", "190\t"))),
        "line 4: column 1: expected a TWA in [0, 180] [deg], found '190'",
    ),
    "polar an empty file": (lambda t: _route(_polar(t, "")), "b.pol', line 1: expected a header row"),
    "polar a header alone": (lambda t: _route(_polar(t, "TWA\\TWS\t0\t10\n")), "expected at least 2 TWA rows"),
    "polar speed nan": (
        lambda t: _route(_polar(t, POL.replace("\t5\t6", "\tnan\t6"))),
        "line 3: column 3: expected a finite number (speed [kn]), found 'nan'",
    ),
    "polar unknown name": (
        lambda t: _route(_scenario(t, BASE.replace('"maribot_vane"', '"nosuch"'))),
        "unknown polar 'nosuch': expected one of the built-in polars",
    ),
    # zones
    "zone a Point": (
        lambda t: _route(_with_zone(t, "z.geojson", {"type": "Point", "coordinates": [0, 0]})),
        "expected GeoJSON type FeatureCollection, Feature, Polygon or MultiPolygon (got 'Point')",
    ),
    "zone an empty FeatureCollection": (
        lambda t: _route(_with_zone(t, "z.geojson", {"type": "FeatureCollection", "features": []})),
        "FeatureCollection has no features",
    ),
    "zone latitude 95": (
        lambda t: _route(
            _with_zone(t, "z.geojson", {"type": "Polygon", "coordinates": [[[0, 0], [1, 95], [1, 0], [0, 0]]]})
        ),
        "lat in [-90, 90] [deg] (got [1, 95])",
    ),
    "zone file missing": (lambda t: _route(_with_zone(t, "nosuch.geojson")), "nosuch.geojson: zone file not found"),
    # command-line values
    "--apf 1.5": (lambda t: _route(str(EXAMPLE), "--apf", "1.5"), "--apf must be a probability in [0, 1] (got 1.5)"),
    "--apf -0.1": (lambda t: _route(str(EXAMPLE), "--apf", "-0.1"), "--apf must be a probability in [0, 1] (got -0.1)"),
    "--apf nan": (lambda t: _route(str(EXAMPLE), "--apf", "nan"), "--apf must be a probability in [0, 1] (got nan)"),
    "--n-ranks 0": (lambda t: _route(str(EXAMPLE), "--n-ranks", "0"), "--n-ranks must be >= 1 (got 0)"),
    "--n-ranks 1e9": (lambda t: _route(str(EXAMPLE), "--n-ranks", "1000000000"), "--n-ranks must be at most 100000"),
    "--max-memory 1x": (lambda t: _route(str(EXAMPLE), "--max-memory", "1x"), "--max-memory must be a memory size"),
    "--max-deviation 95": (
        lambda t: _route(str(EXAMPLE), "--max-deviation", "95"),
        "max_deviation_deg must be in (0, 90) [deg] (got 95.0)",
    ),
    "--aspect 0 on the square layout": (lambda t: _route(str(EXAMPLE), "--aspect", "0"), "aspect (rank spacing"),
    "--departures repeated": (
        lambda t: _route(str(EXAMPLE), "--departures", "2018-06-01T00:00Z,2018-06-02T00:00Z,2018-06-01T00:00Z"),
        "--departures lists 2018-06-01T00:00:00Z more than once",
    ),
    "--out a file": (
        lambda t: ((t / "f").write_text("x"), _route(str(EXAMPLE), "--out", str(t / "f")))[1],
        "f is a file, not a folder",
    ),
    "--out under a file": (
        lambda t: ((t / "f").write_text("x"), _route(str(EXAMPLE), "--out", str(t / "f" / "sub")))[1],
        "f/sub: ",
    ),
    "gci --phi with nan": (lambda t: ["gci", "--h", "1,2,4", "--phi", "1,nan,3"], "--phi must be finite (got nan"),
    # scenarios
    "start equal to finish": (
        lambda t: _route(_scenario(t, BASE.replace("finish = [-60.0, 17.5]", "finish = [-12.0, 45.0]"))),
        "[route].start [-12.0, 45.0] and [route].finish [-12.0, 45.0] are the same point",
    ),
    "waypoint equal to start": (
        lambda t: _route(
            _scenario(t, BASE.replace("finish = [-60.0, 17.5]", "finish = [-60.0, 17.5]\nwaypoints = [[-12.0, 45.0]]"))
        ),
        "[route].start [-12.0, 45.0] and [route].waypoints[0] [-12.0, 45.0] are the same point",
    ),
    "start latitude 95": (
        lambda t: _route(_scenario(t, BASE.replace("start = [-12.0, 45.0]", "start = [-12.0, 95.0]"))),
        "[route].start latitude must be in [-90, 90] [deg] (got 95)",
    ),
    "start a place name": (
        lambda t: _route(_scenario(t, BASE.replace("start = [-12.0, 45.0]", 'start = "Brest"'))),
        "[route].start must be [lon, lat] in degrees (got 'Brest')",
    ),
    "departure 'tomorrow'": (
        lambda t: _route(_scenario(t, BASE.replace('"2018-06-01T00:00:00Z"', '"tomorrow"'))),
        "[route].departure must be an ISO 8601 time",
    ),
    "an unknown table": (
        lambda t: _route(_scenario(t, BASE + "\n[boat2]\nx = 1\n")),
        "unknown table [boat2]",
    ),
    "tws_kn a string": (
        lambda t: _route(_scenario(t, BASE.replace("tws_kn = 15.0", 'tws_kn = "15"'))),
        "[weather].tws_kn must be a number",
    ),
    "patch lon reversed": (
        lambda t: _route(_scenario(t, BASE.replace("lon = [-45.0, -35.0]", "lon = [-35.0, -45.0]"))),
        "[weather].patch[0].lon must satisfy -180 <= min < max <= 180",
    ),
    "scenario path in unicode, missing": (
        lambda t: ["route", str(t / "Ünïcødé ✈ route.toml")],
        "Ünïcødé ✈ route.toml: scenario file not found",
    ),
    "scenario of every byte": (
        lambda t: ((t / "s.toml").write_bytes(bytes(range(256))), ["route", str(t / "s.toml")])[1],
        "not UTF-8 text: byte 0x80 at offset 128",
    ),
    "weather file with a repeated time": (
        lambda t: _route(_wind_scenario(t, repeat_time=True)),
        "variable 'u10' has repeated times",
    ),
    "weather file missing": (
        lambda t: _route(_scenario(t, BASE.split("[weather]")[0] + '[weather]\nkind = "file"\npaths = ["no.nc"]\n')),
        "no.nc': not found",
    ),
}

MODEL = (ROOT / "failure_models" / "dickson2018.toml").read_text()
POL = "TWA\\TWS\t0\t10\t20\n0\t0\t0\t0\n90\t0\t5\t6\n180\t0\t4\t5\n"


def _model(tmp: Path, text: str) -> str:
    """A failure model file ``m.toml`` (beside a copy of the shipped network) holding ``text``."""
    (tmp / "dickson2018.bif").write_bytes((ROOT / "failure_models" / "dickson2018.bif").read_bytes())
    (tmp / "m.toml").write_text(text)
    return str(tmp / "m.toml")


def _polar(tmp: Path, text: str) -> str:
    """A scenario whose polar is the file ``b.pol`` holding ``text``."""
    (tmp / "b.pol").write_text(text)
    return _scenario(tmp, BASE.replace('"maribot_vane"', '"b.pol"'))


def _wind_file(path: Path, *, lat: list[float], lon: list[float], repeat_time: bool = False) -> None:
    """A NetCDF wind file (10 m u = 5, v = 5 m/s, from the south-west) over the control course at three times."""
    import numpy as np
    import xarray as xr

    time = np.datetime64("2018-05-31T00:00", "ns") + np.arange(3) * np.timedelta64(30, "D")
    if repeat_time:
        time[1] = time[0]
    dims, w = ("time", "latitude", "longitude"), np.full((3, len(lat), len(lon)), 5.0, np.float32)
    xr.Dataset(
        {"u10": (dims, w, {"units": "m s-1"}), "v10": (dims, w, {"units": "m s-1"})},
        coords={"time": time, "latitude": lat, "longitude": lon},
    ).to_netcdf(path)


def _wind_scenario(tmp: Path, *, lat: list[float] | None = None, lon: list[float] | None = None, **kw) -> str:
    _wind_file(tmp / "w.nc", lat=lat or [10.0, 30.0, 50.0], lon=lon or [-70.0, -40.0, -10.0], **kw)
    return _scenario(
        tmp, BASE.split("[weather]")[0] + '[weather]\nkind = "file"\npaths = ["w.nc"]\n\n[failure]\nmodel = "none"\n'
    )


@pytest.mark.parametrize("case", list(MISTAKES))
def test_user_mistake_is_exit_2_with_one_line(case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build, needle = MISTAKES[case]
    work = tmp_path / "w"
    work.mkdir()
    args = build(work)
    before = listing(work)
    code, out, err = run(args, capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("pyroute-rel") and "Traceback" not in err
    assert len(err) <= 1100  # MESSAGE_MAX_CHARS plus the prefix
    assert needle in err
    assert out == ""
    assert listing(work) == before  # nothing written: no --out folder, no staging


# --------------------------------------------------------------------------------------------------
# item 7: coordinates that look swapped, zones that miss the course
# --------------------------------------------------------------------------------------------------


def test_summary_echoes_marks_with_hemispheres(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = BASE.replace("finish = [-60.0, 17.5]", "finish = [-60.0, 17.5]\nwaypoints = [[-30.0, -5.0]]")
    code, out, err = run(_route(_scenario(tmp_path, text)), capsys)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == "start            45.00°N 12.00°W  ([lon, lat] = [-12, 45])"
    assert lines[1] == "waypoint[0]      5.00°S 30.00°W  ([lon, lat] = [-30, -5])"
    assert lines[2] == "finish           17.50°N 60.00°W  ([lon, lat] = [-60, 17.5])"
    # the JSON keeps its fields
    code, out, _ = run([*_route(str(EXAMPLE)), "--json"], capsys)
    assert code == 0 and "start" not in json.loads(out) and json.loads(out)["track"][0]["lon"] == -12.0


def test_swapped_start_and_finish_show_in_the_echo(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # [lat, lon] by mistake: [45, -12] is a valid [lon, lat] (45 E, 12 S, off Madagascar), so no check can refuse
    # it; the echo names the hemispheres that give it away
    text = BASE.replace(
        "start = [-12.0, 45.0]\nfinish = [-60.0, 17.5]", "start = [45.0, -12.0]\nfinish = [50.0, -40.0]"
    )
    code, out, err = run(_route(_scenario(tmp_path, text)), capsys)
    assert code == 0, err  # uniform weather covers everything: the wrong course is routed...
    # ...but the summary says where it goes: southern and eastern hemispheres, not the intended 45 N 12 W
    assert out.splitlines()[:2] == [
        "start            12.00°S 45.00°E  ([lon, lat] = [45, -12])",
        "finish           40.00°S 50.00°E  ([lon, lat] = [50, -40])",
    ]


def _zone_scenario(tmp: Path, ring: list[list[float]]) -> str:
    return _with_zone(tmp, "z.geojson", {"type": "Polygon", "coordinates": [ring]})


def test_zone_wholly_outside_the_routing_area_warns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a box at 35-36 E, 30-31 S: the same box as a mistaken [lat, lon] of 30-31 N, 35-36 W, which is on the course
    far = [[35.0, -30.0], [36.0, -30.0], [36.0, -31.0], [35.0, -31.0], [35.0, -30.0]]
    code, _, err = run(_route(_zone_scenario(tmp_path, far)), capsys)
    assert code == 0
    (line,) = [row for row in err.splitlines() if "warning" in row]
    assert line.startswith("pyroute-rel: warning: ") and "zone 'z' (lon 35 to 36, lat -31 to -30 [deg])" in line
    assert "wholly outside the routing area" in line and "[lon, lat]" in line
    near = [[-36.0, 30.0], [-35.0, 30.0], [-35.0, 31.0], [-36.0, 31.0], [-36.0, 30.0]]
    code, _, err = run(_route(_zone_scenario(tmp_path, near)), capsys)
    assert code == 0 and "warning" not in err


def test_zones_outside_against_a_hand_made_hull() -> None:
    import shapely

    from pyroute_rel.obstacles.zones import Zone, zones_outside

    # the hull of (0,0), (10,0), (0,10) is the triangle x + y <= 10 (x, y >= 0)
    lon, lat = [0.0, 10.0, 0.0], [0.0, 0.0, 10.0]
    inside = Zone("inside", shapely.box(1.0, 1.0, 2.0, 2.0))
    straddles = Zone("straddles", shapely.box(4.0, 4.0, 7.0, 7.0))  # (4, 4) has x + y = 8 <= 10
    beyond = Zone("beyond", shapely.box(6.0, 6.0, 7.0, 7.0))  # nearest corner (6, 6): x + y = 12 > 10
    assert [z.name for z in zones_outside([inside, straddles, beyond], lon, lat)] == ["beyond"]


@pytest.mark.parametrize("path", [None, 5, ["out"]])
def test_an_output_folder_of_the_wrong_type_is_an_output_error(path: object) -> None:
    # write_outputs(route, None) raised TypeError from pathlib (str(None) = "None" passed the empty-name check).
    from pyroute_rel.errors import OutputError
    from pyroute_rel.files import check_out_dir

    with pytest.raises(OutputError, match=r"--out must be a folder name \(str or pathlib.Path\)"):
        check_out_dir(path)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------------
# CF valid_range / valid_min / valid_max: values outside are missing, like declared fill values
# --------------------------------------------------------------------------------------------------

T0 = "2018-06-01T00:00"
GRID_LON, GRID_LAT = [-20.0, -19.0, -18.0, -17.0], [40.0, 41.0, 42.0]


def _waves(hs: list[list[list[float]]], attrs: dict, encoding: dict | None = None, *, path: Path) -> Path:
    """A NetCDF file with ``swh`` [m] (and a steady 5 m/s wind) on (time, latitude, longitude), written by xarray;
    ``hs`` (one time) is stored at two times 6 h apart (one time would make steady weather, with a warning)."""
    import numpy as np
    import xarray as xr

    hs = [*hs, *hs]
    time = np.datetime64(T0, "ns") + np.arange(len(hs)) * np.timedelta64(6, "h")
    dims, wind = ("time", "latitude", "longitude"), np.full((2, 3, 4), 5.0, np.float32)
    ds = xr.Dataset(
        {
            "swh": (dims, np.asarray(hs, np.float32), {"units": "m", **attrs}),
            "u10": (dims, wind, {"units": "m s-1"}),
            "v10": (dims, wind, {"units": "m s-1"}),
        },
        coords={"time": time, "latitude": GRID_LAT, "longitude": GRID_LON},
    )
    ds.to_netcdf(path, encoding={"swh": encoding or {"_FillValue": None}})
    return path


def _raw(path: Path) -> list:
    """The variable as stored, without any masking or unpacking (netCDF4 with auto mask and scale off)."""
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        return nc["swh"][:].tolist()


def _hs_grid(w) -> list:
    import numpy as np

    lon, lat = np.meshgrid(GRID_LON, GRID_LAT)
    return w.sample(lon, lat, np.datetime64(T0)).hs_m.tolist()


@pytest.mark.parametrize(
    ("attrs", "missing"),
    [
        # 25 m is a plausible wave height (RANGES allows 0..30 m): only the declared range makes it missing
        ({"valid_range": [0.0, 20.0]}, {(0, 1), (2, 3)}),
        ({"valid_min": 0.5}, {(2, 3), (1, 0)}),
        ({"valid_max": 20.0}, None),  # -1 m is inside this declared range: the plausibility check refuses it
        ({"valid_min": 0.5, "valid_max": 20.0}, {(0, 1), (2, 3), (1, 0)}),
        ({"valid_range": [0.0, 30.0], "valid_min": 5.0}, {(2, 3)}),  # valid_range wins over valid_min
    ],
)
def test_values_outside_the_cf_valid_range_are_missing(attrs: dict, missing: set | None, tmp_path: Path) -> None:
    import math
    import warnings

    from pyroute_rel.errors import WeatherError
    from pyroute_rel.weather.io.readers import open_weather

    hs = [[[2.0, 25.0, 3.0, 4.0], [0.25, 1.0, 2.0, 3.0], [1.0, 2.0, 3.0, -1.0]]]
    path = _waves(hs, attrs, path=tmp_path / "w.nc")
    assert _raw(path) == [*hs, *hs]  # the file holds the values unmasked
    if missing is None:
        with pytest.raises(WeatherError, match=r"variable 'swh': 2 values outside the plausible range .*e\.g\. -1 "):
            open_weather(path)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # missing by declaration: no warning, no error (-1 m would be refused)
        w = open_weather(path)
    got = _hs_grid(w)
    for iy in range(3):
        for ix in range(4):
            if (iy, ix) in missing:
                assert math.isnan(got[iy][ix]), (iy, ix)
            else:
                assert got[iy][ix] == hs[0][iy][ix], (iy, ix)


def test_a_packed_variable_has_its_valid_range_in_packed_units(tmp_path: Path) -> None:
    # CF 2.5.1 / 8.1: for a packed variable valid_range is in the packed type: [0, 2000] * 0.01 m = [0, 20] m
    import math

    import numpy as np

    from pyroute_rel.weather.io.readers import open_weather

    hs = [[[2.0, 25.0, 3.0, 4.0], [0.5, 1.0, 2.0, 3.0], [1.0, 2.0, 19.99, 20.01]]]
    enc = {"dtype": "int16", "scale_factor": 0.01, "_FillValue": np.int16(-32767)}
    path = _waves(hs, {"valid_range": np.array([0, 2000], np.int16)}, enc, path=tmp_path / "p.nc")
    assert _raw(path)[0][0][1] == 2500 and _raw(path)[0][2][3] == 2001  # stored packed
    got = _hs_grid(open_weather(path))
    assert math.isnan(got[0][1]) and math.isnan(got[2][3])
    assert got[2][2] == pytest.approx(19.99, abs=1e-5) and got[0][0] == pytest.approx(2.0, abs=1e-6)


@pytest.mark.parametrize(
    ("attrs", "needle"),
    [
        ({"valid_range": [0.0, 1.0, 2.0]}, "valid_range must be two numbers"),
        ({"valid_range": [20.0, 0.0]}, "min 20 > max 0"),
        ({"valid_min": "low"}, "valid_min attribute that is not a number"),
    ],
)
def test_a_malformed_valid_range_is_a_weather_error(attrs: dict, needle: str, tmp_path: Path) -> None:
    from pyroute_rel.errors import WeatherError
    from pyroute_rel.weather.io.readers import open_weather

    path = _waves([[[1.0] * 4] * 3], attrs, path=tmp_path / "w.nc")
    with pytest.raises(WeatherError, match=f"variable 'swh'.*{needle}"):
        open_weather(path)


# --------------------------------------------------------------------------------------------------
# odd but valid inputs: accepted, and the same as their plain form
# --------------------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    ("lat", "lon"),
    [
        ([50.0, 30.0, 10.0], None),  # latitude descending (as ERA5 stores it)
        (None, [290.0, 320.0, 350.0]),  # longitude 0..360 (as GFS stores it)
        ([50.0, 30.0, 10.0], [350.0, 320.0, 290.0]),  # both, and longitude descending too
    ],
)
def test_weather_files_laid_out_differently_route_alike(
    lat: list[float] | None, lon: list[float] | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "plain").mkdir()
    (tmp_path / "odd").mkdir()
    plain = _wind_scenario(tmp_path / "plain")
    odd = _wind_scenario(tmp_path / "odd", lat=lat, lon=lon)
    times = []
    for scenario in (plain, odd):
        code, out, err = run([*_route(scenario), "--json"], capsys)
        assert code == 0, err
        times.append(json.loads(out)["voyage_time_h"])
    assert times[1] == times[0]


def test_departures_out_of_order_are_routed_in_the_order_given(capsys: pytest.CaptureFixture[str]) -> None:
    given = ["2018-06-03T00:00:00Z", "2018-06-01T00:00:00Z", "2018-06-02T00:00:00Z"]
    code, out, err = run([*_route(str(EXAMPLE)), "--departures", ",".join(given), "--json"], capsys)
    assert code == 0, err
    assert [row["departure"] for row in json.loads(out)["departures"]] == given


# --------------------------------------------------------------------------------------------------
# session 8 adversarial pass: Monte-Carlo options of `evaluate`, the mean of member files
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--speed-tau", "-3"], "--speed-tau set the Monte-Carlo runs: add --monte-carlo N"),  # ignored before
        (["--kappa", "0.1", "--wind-sd", "2"], "--kappa, --wind-sd set the Monte-Carlo runs"),
        (["--monte-carlo", "5", "--speed-tau", "nan"], "--speed-tau: Monte-Carlo tau_speed_h must be > 0 [h]"),
        (["--monte-carlo", "5", "--speed-tau", "0"], "--speed-tau: Monte-Carlo tau_speed_h must be > 0 [h]"),
        (["--monte-carlo", "5", "--wind-growth", "-1"], "--wind-growth: Monte-Carlo growth_ms_per_h must be"),
        (["--monte-carlo", "0"], "--monte-carlo needs a whole number of runs >= 1 (got 0)"),
    ],
)
def test_evaluate_monte_carlo_options_are_checked_first(
    args: list[str], expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Refused before the scenario or the track is read (the track does not exist), naming the option; nothing
    written to --out."""
    out = tmp_path / "out"
    code, stdout, err = run(["evaluate", str(EXAMPLE), str(tmp_path / "none.gpx"), *args, "--out", str(out)], capsys)
    assert code == 2 and stdout == ""
    assert expected in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("given", [[], (), "m0.nc"])
def test_mean_of_no_member_files_is_refused(given: object, tmp_path: Path) -> None:
    """An empty list was an AssertionError, a single name was read letter by letter ('m', '0', ...)."""
    from pyroute_rel.analysis.members import mean_of_files
    from pyroute_rel.errors import ScenarioError

    with pytest.raises(ScenarioError, match="member_files must be a list of one or more weather files"):
        mean_of_files(given, tmp_path / "mean.nc")  # type: ignore[arg-type]
    assert not (tmp_path / "mean.nc").exists()


def test_ensemble_workers_error_names_the_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(["ensemble", str(EXAMPLE), "--workers", "0", "--quiet"], capsys)
    assert code == 2 and out == ""
    assert "--workers must be a whole number >= 1 (got 0)" in err and len(err.strip().splitlines()) == 1


def _strict_json(text: str) -> object:
    def refuse(constant: str) -> None:
        raise AssertionError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.slow
def test_tradeoff_json_is_strict_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The control course's fastest route meets p_f = 1 (hazard inf): printed and written as null, not Infinity."""
    out = tmp_path / "t"
    code, stdout, err = run(
        ["tradeoff", str(EXAMPLE), "--n-ranks", "12", "--quiet", "--json", "--out", str(out)], capsys
    )
    assert code == 0, err
    doc = _strict_json(stdout)
    assert _strict_json((out / "tradeoff.json").read_text()) == doc
    pf = [p["max_failure_probability"] for p in doc["front"]]  # type: ignore[index]
    hazards = [p["hazard"] for p in doc["front"]]  # type: ignore[index]
    assert 1.0 in pf and [h is None for h in hazards] == [x == 1.0 for x in pf]
