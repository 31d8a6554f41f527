"""Sampling ensemble members together (issue 19's re-evaluation): a MemberStack answers each row from its member
with the numbers that member's own weather gives (the reference: each member's GriddedWeather.sample_at, called
alone), bit for bit; weathers on different grids are not stacked; sailing in members is the same with or without
the stack, and in groups when the stack would be too large."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_evaluate import load_example

from pyroute_rel import load_scenario
from pyroute_rel.analysis import evaluate
from pyroute_rel.errors import WeatherError
from pyroute_rel.weather.gridded import MemberStack, stack_members
from pyroute_rel.weather.io.readers import weather_from_dataset
from pyroute_rel.weather.uniform import UniformWeather

FIELDS = ("tws_kn", "twd_deg", "hs_m", "wave_dir_deg", "wave_period_s", "current_u_ms", "current_v_ms")


def _members(n: int = 4, **options: object) -> list:
    make = load_example("make_ensemble_example")
    ds = make.make_ensemble(n, resolution_deg=2.0, step_h=12.0, days=16.0, **options)
    return [weather_from_dataset(ds, member=k) for k in range(n)]


MEMBERS = _members()
DEPARTURE = np.datetime64("2018-06-01T00:00", "ns")


@settings(max_examples=25, deadline=None)
@given(
    member=st.lists(st.integers(0, len(MEMBERS) - 1), min_size=1, max_size=12),
    seed=st.integers(0, 2**31 - 1),
    samples=st.integers(1, 5),
)
def test_stack_answers_each_row_as_its_member_does(member: list[int], seed: int, samples: int):
    rng = np.random.default_rng(seed)
    rows = len(member)
    lon = rng.uniform(-42.0, 2.0, (rows, samples))  # a little outside the data too (NaN there)
    lat = rng.uniform(18.0, 57.0, (rows, samples))
    off = rng.uniform(-5.0, 400.0, (rows, samples))  # past the data too
    off[rng.random((rows, samples)) < 0.1] = np.nan
    stack = stack_members(MEMBERS)
    assert isinstance(stack, MemberStack) and stack.n_members == len(MEMBERS)
    got = stack.sample_at(stack.prepare(lon, lat, member), DEPARTURE, offset_h=off)
    for r, m in enumerate(member):
        w = MEMBERS[m]
        want = w.sample_at(w.prepare(lon[r], lat[r]), DEPARTURE, offset_h=off[r])
        for name in FIELDS:
            a, b = getattr(got, name)[r], getattr(want, name)
            assert np.array_equal(a, b, equal_nan=True), (name, r, m)


def test_stack_refuses_other_grids_and_kinds():
    other = _members(2, lon=(-38.0, 0.0))  # a different grid
    assert stack_members([MEMBERS[0], other[0]]) is None
    assert stack_members([MEMBERS[0], UniformWeather(tws_kn=10.0, twd_deg=0.0)]) is None
    assert stack_members([]) is None
    stack = stack_members(MEMBERS[:2])
    assert stack is not None and stack.nbytes == MEMBERS[0].nbytes + MEMBERS[1].nbytes
    with pytest.raises(WeatherError, match=r"member must give one member index in \[0, 1\] per row"):
        stack.prepare(np.zeros((3, 2)), np.zeros((3, 2)), [0, 1, 2])


@pytest.mark.slow
def test_sailing_in_members_is_the_same_stacked_unstacked_and_in_groups(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Tracks sailed in 4 members: with the stack, without it (each member sampled alone) and in groups of 2 (the
    memory bound) give the same numbers, each equal to sailing the tracks in that member alone (sail_tracks)."""
    (tmp_path / "s.toml").write_text(
        '[route]\nstart = [-14.0, 31.0]\nfinish = [-26.0, 22.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
        '[grid]\nn_ranks = 8\n[avoid]\nland = false\n[weather]\nkind = "uniform"\ntws_kn = 12.0\ntwd_deg = 0.0\n'
        '[failure]\nmodel = "dickson2018"\napf = 0.5\n'
    )
    problem = evaluate.evaluation_problem(load_scenario(tmp_path / "s.toml"))
    problems = [replace(problem, weather=w) for w in MEMBERS]  # the same problem in each member's weather
    lon = np.linspace(-14.0, -26.0, 9)
    # the third track leaves the data west of 40 W: stopped there by missing weather (a craft in irons or a calm
    # waits for the wind instead, pyroute_rel.boat.march, so only missing weather stops a track)
    west = np.array([[-14.0, 31.0], [-30.0, 27.0], [-48.0, 27.0]])
    tracks = [np.column_stack([lon, np.linspace(31.0, 22.0, 9)]), np.column_stack([lon[:6], np.full(6, 30.0)]), west]

    def table(out: list) -> str:
        return repr([(s.elapsed_h.tolist(), s.costs.p_f.tolist(), s.costs.reason.tolist()) for row in out for s in row])

    stacked = table(evaluate.sail_in_members(problems, tracks))
    with monkeypatch.context() as m:
        m.setattr(evaluate, "_member_stack", lambda problems: None)
        alone = table(evaluate.sail_in_members(problems, tracks))
    with monkeypatch.context() as m:
        m.setattr(evaluate, "STACK_MAX_BYTES", 2 * MEMBERS[0].nbytes)
        assert [len(g) for g in evaluate._member_groups(problems)] == [2, 2]
        grouped = table(evaluate.sail_in_members(problems, tracks))
    one = table([evaluate.sail_tracks(p, tracks) for p in problems])
    finished = [np.isfinite(s.voyage_time_h) for p in problems for s in evaluate.sail_tracks(p, tracks)]
    assert 4 <= sum(finished) < len(finished)  # tracks that arrive, and some stopped on the way: both compared
    assert stacked == alone == grouped == one
