"""Ensembles given as member files (issue 19): their ensemble mean is the mean of the files' fields, computed here by
hand from the arrays written, and the mean-field candidate is routed on it; files on different grids are refused in
one line naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_evaluate import load_example

from pyroute_rel import load_scenario
from pyroute_rel.analysis.ensemble import route_ensemble
from pyroute_rel.analysis.members import mean_of_files, mean_scenario
from pyroute_rel.errors import ScenarioError

SCENARIO = (
    '[route]\nstart = [-14.0, 31.0]\nfinish = [-22.0, 25.0]\ndeparture = "2018-06-01T00:00:00Z"\n'
    '[grid]\nn_ranks = 16\n[avoid]\nland = false\n[weather]\nkind = "file"\npaths = ["{first}"]\n'
    '[failure]\nmodel = "dickson2018"\napf = 0.5\n'
)


def _member_files(folder: Path, n: int = 3) -> tuple[list[Path], object]:
    """n single-member files (float32, unpacked: the values written are the arrays' own) and the dataset."""
    make = load_example("make_ensemble_example")
    ds = make.make_ensemble(n, resolution_deg=2.0, step_h=12.0)
    paths = []
    for k in range(n):
        p = folder / f"member{k}.nc"
        ds.isel(number=k).drop_vars("number").to_netcdf(p)
        paths.append(p)
    return paths, ds


def test_mean_of_member_files_is_the_hand_computed_mean(tmp_path: Path):
    import xarray as xr

    paths, ds = _member_files(tmp_path)
    out = mean_of_files(paths, tmp_path / "mean.nc")
    with xr.open_dataset(out) as mean:
        for v in ("u10", "v10", "swh", "mwd"):
            a = np.asarray(ds[v].values, dtype=np.float64)  # (member, time, lat, lon) as written
            hand = (a[0] + a[1] + a[2]) / 3.0
            np.testing.assert_allclose(mean[v].values, hand, rtol=1e-15, atol=1e-12, err_msg=v)
            assert mean[v].attrs["units"] == ds[v].attrs["units"]
        assert np.array_equal(mean["latitude"].values, ds["latitude"].values)


@pytest.mark.slow
def test_mean_field_candidate_of_member_files_is_the_route_on_their_mean(tmp_path: Path):
    """The ensemble's mean-field route equals `route` on a file holding the hand-computed mean (a scenario of its
    own), and the mean scenario samples that file's weather exactly."""
    paths, ds = _member_files(tmp_path)
    hand = ds.astype(np.float64).mean("number")  # xarray's own mean, a second computation
    for v in hand.data_vars:
        hand[v].attrs = ds[v].attrs
    hand.to_netcdf(tmp_path / "hand_mean.nc")
    scenario = tmp_path / "ens.toml"
    scenario.write_text(SCENARIO.format(first="member0.nc"))
    reference = tmp_path / "hand.toml"
    reference.write_text(SCENARIO.format(first="hand_mean.nc"))
    ref = load_scenario(reference)
    sc = mean_scenario(scenario, member_files=paths)
    lon, lat = np.linspace(-14.0, -22.0, 7), np.linspace(31.0, 25.0, 7)
    when = np.datetime64("2018-06-01T00:00") + np.arange(7) * np.timedelta64(13, "h")
    a, b = sc.weather.sample(lon, lat, when), ref.weather.sample(lon, lat, when)
    np.testing.assert_allclose(a.tws_kn, b.tws_kn, rtol=1e-12)
    np.testing.assert_allclose(a.hs_m, b.hs_m, rtol=1e-12)
    res = route_ensemble(scenario, member_files=paths, workers=1, risk="mean")
    assert res.names[-1] == "mean" and res.mean_route is not None and res.mean_route.ok
    expected = ref.route()
    np.testing.assert_allclose(res.mean_route.lon_deg, expected.lon_deg, atol=1e-9)
    np.testing.assert_allclose(res.mean_route.lat_deg, expected.lat_deg, atol=1e-9)
    assert res.mean_route.voyage_time_h == pytest.approx(expected.voyage_time_h, rel=1e-9)


def test_member_files_on_different_grids_are_refused_naming_the_file(tmp_path: Path):
    paths, ds = _member_files(tmp_path, n=2)
    odd = tmp_path / "odd.nc"
    shifted = ds.isel(number=0).drop_vars("number")
    shifted = shifted.assign_coords(longitude=shifted["longitude"] + 0.5)
    shifted.to_netcdf(odd)
    with pytest.raises(ScenarioError) as err:
        mean_of_files([paths[0], odd, paths[1]], tmp_path / "mean.nc")
    msg = str(err.value)
    assert "\n" not in msg and str(odd) in msg and "'longitude'" in msg
    missing = tmp_path / "fewer.nc"
    ds.isel(number=0).drop_vars(["number", "mwd"]).to_netcdf(missing)
    with pytest.raises(ScenarioError, match="fewer.nc' holds variables"):
        mean_of_files([paths[0], missing], tmp_path / "mean2.nc")
    assert not (tmp_path / "mean.nc").exists() and not (tmp_path / "mean2.nc").exists()


def test_a_member_file_that_is_a_fifo_or_missing_is_one_line_not_a_hang(tmp_path):
    """Issue 34: a FIFO given as a member file hung the mean (the open waited for a writer)."""
    import os
    import time

    from pyroute_rel.analysis.members import mean_of_files
    from pyroute_rel.errors import ScenarioError

    fifo = tmp_path / "fifo.nc"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with pytest.raises(ScenarioError, match=r"member file '.*fifo\.nc': not a regular file"):
        mean_of_files([fifo], tmp_path / "mean.nc")
    with pytest.raises(ScenarioError, match=r"member file '.*gone\.nc': not found"):
        mean_of_files([tmp_path / "gone.nc"], tmp_path / "mean.nc")
    assert time.perf_counter() - t0 < 5.0 and not (tmp_path / "mean.nc").exists()
