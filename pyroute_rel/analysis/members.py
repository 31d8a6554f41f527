"""Ensemble members of a scenario's weather: one scenario per member, and one on the ensemble mean.

A scenario whose ``[weather]`` files hold an ensemble dimension (``number`` in ERA5 and ECMWF ENS, ``realization``,
``member``: :func:`~pyroute_rel.weather.io.readers.ensemble_size`) routes one member with ``[weather] member = k``, or
the ensemble mean with ``member = "mean"``. Members may also be separate files, one per member (``member_files``):
member ``k`` then reads ``[weather].paths`` with its first file replaced by ``member_files[k]`` (wind in the member
files; waves or currents, if any, from the other files, common to all members). Their ensemble mean
(:func:`mean_of_files`) is a file like them whose every variable is the mean over the files (wind as its u and v
components, as ``member = "mean"`` averages a member dimension), read in their place; the files must share their
variables and grid (coordinates, values equal), else a ScenarioError names the first file that differs.

Each member's weather is read exactly as ``pyroute-rel route`` reads it with ``[weather] member = k`` (the
scenario's TOML read again with that key), so that a member's route is that route.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pyroute_rel.errors import PyrouteError, ScenarioError, brief
from pyroute_rel.files import brief_path, check_regular_file, read_regular_bytes
from pyroute_rel.scenario import SCENARIO_MAX_BYTES, Scenario, scenario_from_mapping
from pyroute_rel.store import Shelf, current_store

__all__ = ["scenario_table", "member_count", "member_scenario", "mean_scenario", "mean_of_files"]


def scenario_table(path: str | Path) -> dict[str, Any]:
    """A scenario file's TOML tables, unvalidated (:func:`~pyroute_rel.scenario.load_scenario` validates them)."""
    p = Path(path)
    data = read_regular_bytes(
        p, limit_bytes=SCENARIO_MAX_BYTES, error=ScenarioError, label=brief_path(p), what="scenario file"
    )
    try:
        return tomllib.loads(data.decode("utf-8-sig"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ScenarioError(f"{brief_path(p)}: not a valid TOML scenario file ({' '.join(str(exc).split())})") from None


def _source(scenario: Scenario | str | Path) -> tuple[dict[str, Any], Path, str]:
    """(tables, base folder, name) of a scenario file, or of the file a Scenario was read from."""
    if isinstance(scenario, Scenario):
        path = Path(scenario.source)
        if not path.is_file():
            raise ScenarioError(
                f"{scenario.source}: ensemble members are read from the scenario's file (this scenario was built in "
                "code: write it to a TOML file)"
            )
    else:
        path = Path(scenario)
    return scenario_table(path), path.parent, str(path)


def _weather_table(tables: Mapping[str, Any], name: str) -> dict[str, Any]:
    weather = tables.get("weather")
    if not isinstance(weather, Mapping) or weather.get("kind") != "file":
        raise ScenarioError(
            f'{name}: an ensemble needs [weather] kind = "file" (files with a member dimension, or member files)'
        )
    if not isinstance(weather.get("paths"), list) or not weather["paths"]:
        raise ScenarioError(f"{name}: [weather].paths must be a non-empty array of file names")
    return dict(weather)


def member_count(scenario: Scenario | str | Path, *, member_files: Sequence[str | Path] | None = None) -> int:
    """How many members a scenario's ensemble has: ``len(member_files)``, else the size of the member dimension of
    its ``[weather]`` files.

    Raises
    ------
    ScenarioError
        The weather is not read from files, or no file has a member dimension.
    """
    if member_files is not None:
        if not member_files:
            raise ScenarioError("member files: expected one weather file per member (got none)")
        return len(member_files)
    from pyroute_rel.weather.io.readers import ensemble_size

    tables, base, name = _source(scenario)
    weather = _weather_table(tables, name)
    paths = [q if q.is_absolute() else base / q for q in (Path(str(s)).expanduser() for s in weather["paths"])]
    n = ensemble_size(paths)
    if n is None:
        raise ScenarioError(
            f"{name}: no [weather] file has an ensemble dimension (number, realization, member); give one file per "
            "member instead"
        )
    return n


def member_scenario(
    scenario: Scenario | str | Path,
    member: int | str,
    *,
    member_files: Sequence[str | Path] | None = None,
) -> Scenario:
    """The scenario in the weather of one ensemble member (``"mean"``: the ensemble mean).

    Parameters
    ----------
    scenario : The scenario file, or a Scenario read from one (its other settings, e.g. options changed with
        :meth:`~pyroute_rel.scenario.Scenario.with_options`, are kept).
    member : Member index from 0, or ``"mean"``.
    member_files : One weather file per member (see the module notes); None: the member dimension of the files.
    """
    key = _kept_key(scenario, member, member_files)
    entry = None if key is None else _kept().get(key)
    if entry is not None:
        return _kept_member(entry, member)
    tables, base, name = _source(scenario)
    weather = _weather_table(tables, name)
    if member_files is not None and member == "mean":
        return _mean_of_files_scenario(scenario, tables, base, name, weather, member_files)
    if member_files is not None:
        if isinstance(member, bool) or not isinstance(member, int) or not 0 <= member < len(member_files):
            raise ScenarioError(f"member must be in [0, {len(member_files) - 1}] (got {member!r})")
        weather["paths"] = [str(Path(member_files[member]).resolve()), *list(weather["paths"])[1:]]
        weather.pop("member", None)
    else:
        weather["member"] = member
    tables["weather"] = weather
    other = scenario_from_mapping(tables, base_dir=base, source=name)
    if isinstance(scenario, Scenario):
        return replace(scenario, weather=other.weather)
    if key is not None:
        from pyroute_rel.config import weather_course

        _kept().put(key, (tables, other, base, weather_course(tables)))
    return other


def _kept() -> Shelf:
    """A scenario file's settings kept (in the current store, :mod:`pyroute_rel.store`) while weather files are kept
    open (:func:`~pyroute_rel.weather.io.readers.keep_files_open`), by :func:`_kept_key`: (the file's tables, a member's
    scenario read with them, its folder, the box and departure its weather is read for). One file at a time."""
    return current_store().shelf("members.settings", limit=1)


def _kept_key(
    scenario: Scenario | str | Path, member: int | str, member_files: Sequence[str | Path] | None
) -> tuple[int, str, int, int] | None:
    """Where :func:`member_scenario` keeps a scenario file's settings while the weather files are kept open: (the
    number :func:`~pyroute_rel.weather.io.readers.files_kept_open` gives, the file's path, size and modification time),
    taken before the file is read; None when they are not kept (a Scenario, member files, the mean, files not kept
    open, a file that cannot be examined). Settings kept under another key are dropped."""
    from pyroute_rel.weather.cache import file_stamps
    from pyroute_rel.weather.io.readers import files_kept_open

    calls = files_kept_open()
    if calls is None or isinstance(scenario, Scenario) or member_files is not None:
        _kept().clear()
        return None
    if isinstance(member, bool) or not isinstance(member, int):
        return None
    path, size, mtime = file_stamps([scenario])[0]
    key = (calls, path, size, mtime)
    if key not in _kept():
        _kept().clear()
    return key if size >= 0 else None


def _kept_member(entry: tuple[dict[str, Any], Scenario, Path, Any], member: int | str) -> Scenario:
    """Member ``member`` of the scenario file kept as ``entry`` (see :func:`_kept`): only its weather read, as
    :func:`~pyroute_rel.scenario.scenario_from_mapping` reads it (the other settings do not depend on the weather)."""
    from pyroute_rel.config import parse_weather

    tables, first, base, (bbox, departure) = entry
    weather = _weather_table(tables, first.source)
    weather["member"] = member
    try:
        return replace(first, weather=parse_weather(weather, base, bbox=bbox, departure=departure))
    except PyrouteError as exc:  # named as scenario_from_mapping names it
        if not str(exc).startswith(first.source):
            raise type(exc)(f"{first.source}: {exc}") from None
        raise


def mean_scenario(scenario: Scenario | str | Path, *, member_files: Sequence[str | Path] | None = None) -> Scenario:
    """The scenario on the ensemble-mean weather (``[weather] member = "mean"``, or the mean of the member files)."""
    return member_scenario(scenario, "mean", member_files=member_files)


def _mean_of_files_scenario(
    scenario: Scenario | str | Path,
    tables: dict[str, Any],
    base: Path,
    name: str,
    weather: dict[str, Any],
    member_files: Sequence[str | Path],
) -> Scenario:
    """The scenario with the mean of the member files (written to a temporary file, read as a member file is, then
    deleted: the weather is read into memory)."""
    import tempfile

    if not member_files:
        raise ScenarioError("member files: expected one weather file per member (got none)")
    with tempfile.TemporaryDirectory(prefix="pyroute_rel_mean_") as tmp:
        mean = mean_of_files(member_files, Path(tmp) / "ensemble_mean.nc")
        weather["paths"] = [str(mean), *list(weather["paths"])[1:]]
        weather.pop("member", None)
        tables["weather"] = weather
        other = scenario_from_mapping(tables, base_dir=base, source=name)
    if isinstance(scenario, Scenario):
        return replace(scenario, weather=other.weather)
    return other


def mean_of_files(member_files: Sequence[str | Path], out: str | Path) -> Path:
    """Write the ensemble mean of weather files, one per member, to a NetCDF file ``out`` and return its path.

    Every data variable is averaged over the files as ``member = "mean"`` averages a member dimension: the float64
    sum, in the order of the files, of the decoded values that are not missing (NaN, or outside the variable's CF
    valid range as :func:`~pyroute_rel.weather.io.readers.open_weather` reads it), divided by how many files have a
    value there; missing (NaN) where none has. Wind is averaged as the u and v components the files hold; a direction
    variable, such as a mean wave direction, as the numbers stored. The mean is written unpacked (float64), without
    the valid range (already applied). The files must hold the same variables on the same coordinates.

    Raises
    ------
    ScenarioError
        One line naming the first file that cannot be read, or whose variables or coordinates differ from the first
        file's.
    """
    import xarray as xr

    from pyroute_rel.weather.io.readers import accumulate_member, member_mean, valid_range

    if isinstance(member_files, str | Path) or not member_files:
        raise ScenarioError(f"member_files must be a list of one or more weather files (got {brief(member_files)})")
    paths = [Path(f) for f in member_files]
    sums: dict[Any, tuple[np.ndarray, np.ndarray]] = {}
    ref: xr.Dataset | None = None
    for p in paths:
        check_regular_file(p, error=ScenarioError, label=f"member file '{brief_path(p)}'")  # (a FIFO: issue 34)
        try:
            ds = xr.open_dataset(p, decode_timedelta=False)
        except Exception as exc:  # netCDF4/HDF5 raise many types for damaged files
            raise ScenarioError(f"member file '{p}': cannot read it ({type(exc).__name__}: {exc})") from None
        with ds:
            if ref is None:
                ref = ds.load()
            else:
                _check_same_grid(ds, ref, p, paths[0])
            for v in ref.data_vars:
                total, count = sums.setdefault(v, (np.full(ref[v].shape, -0.0), np.zeros(ref[v].shape, np.int32)))
                valid = valid_range(ds[v], f"member file '{p}' variable '{v}'")
                accumulate_member(total, count, np.asarray(ds[v].values), valid)
    assert ref is not None
    mean = ref[list(ref.data_vars)]
    for v, (total, count) in sums.items():
        attrs = {k: a for k, a in ref[v].attrs.items() if k not in ("valid_range", "valid_min", "valid_max")}
        mean[v] = xr.Variable(ref[v].dims, member_mean(total, count), attrs)
    mean.attrs = {**ref.attrs, "history": f"ensemble mean of {len(paths)} member files (pyroute_rel)"}
    mean.to_netcdf(out)
    return Path(out)


def _check_same_grid(ds: Any, ref: Any, path: Path, first: Path) -> None:
    """ScenarioError unless ``ds`` has ``ref``'s data variables and coordinates (names, sizes and values)."""
    if set(ds.data_vars) != set(ref.data_vars):
        raise ScenarioError(
            f"member file '{path}' holds variables {sorted(map(str, ds.data_vars))}, but '{first}' holds "
            f"{sorted(map(str, ref.data_vars))}: member files must hold the same variables on the same grid"
        )
    for c in ref.coords:
        same = c in ds.coords and ds[c].shape == ref[c].shape and bool(np.array_equal(ds[c].values, ref[c].values))
        if not same:
            raise ScenarioError(
                f"member file '{path}': its coordinate '{c}' differs from '{first}' "
                f"({_describe(ds, c)} against {_describe(ref, c)}): member files must share one grid"
            )


def _describe(ds: Any, c: Any) -> str:
    if c not in ds.coords:
        return "missing"
    v = np.asarray(ds[c].values)
    return f"{v.size} values" + (f" from {v.min()} to {v.max()}" if v.size else "")
