r"""Boat polars: boat speed [kn] as a table over true wind angle [deg] and true wind speed [kn].

A :class:`Polar` is a matrix of boat speeds ``speed_kn[i, j]`` at true wind angle ``twa_deg[i]`` and
true wind speed ``tws_kn[j]``. :func:`boat_speed_kn` interpolates it bilinearly, vectorised over any
broadcastable arrays of TWA and TWS; the router calls it once per rank of arcs.

File formats
------------
``.pol`` / ``.txt`` (:func:`read_pol`, :func:`write_pol`)
    The TWA\TWS matrix read by OpenCPN weather routing, qtVlm and VLM::

        TWA\TWS	0	4	8
        0	0	0	0
        40	0	1.2	2.4
        160	0	0.7	1.5

    The first cell of the header row is ``TWA\TWS`` (also ``TWA/TWS``, ``TWA`` or ``TWS`` alone, any case, or
    empty); the rest of the header are TWS [kn], strictly increasing. Each following row is a TWA [deg] in
    [0, 180], strictly increasing down the file, then one boat speed [kn] per TWS. A line's cells are separated by
    tabs if it has any, else by ``;``, else by ``,``, else by spaces (decimal point ``.``; decimal commas are not
    read); a trailing separator is allowed; blank lines and lines starting with ``#`` are skipped; a UTF-8 byte
    order mark and Windows line ends are fine. :func:`write_pol` writes tabs.

    **Empty or missing speeds** (an empty cell between two separators, or a row shorter than the header, as some
    of the polars shipped with OpenCPN's weather routing have) are filled, with a
    :class:`~pyroute_rel.errors.PolarWarning` saying how many and where: within a TWS column, a gap between two
    given speeds is interpolated linearly in TWA; a gap above the first or below the last given speed of its column
    is interpolated linearly in TWS when its row gives speeds on both sides of it (as OpenCPN fills it), else it is
    0 kn (no speed there, so a route never sails there). A TWS column with no speed at all is refused.
``.csv`` (:func:`read_polar_csv`, :func:`write_polar_csv`)
    The same matrix, comma-separated, with the header cell ``twa_deg\tws_kn`` (a literal backslash)::

        twa_deg\tws_kn,0,4,8
        0,0,0,0
        40,0,1.2,2.4

:func:`read_polar` picks the reader from the suffix; :func:`get_polar` also knows the built-in boats of
:data:`BUILTIN_POLARS`. Every malformed file raises :class:`~pyroute_rel.errors.PolarError` with one line
naming the file, the line and what was expected and found. Writers replace the target atomically
(temporary file in the same folder, then :func:`os.replace`).

Outside the table
-----------------
TWA is folded into [0, 180] first (``|angle|`` wrapped, so -30 and 330 both read as 30): a polar is
symmetric between port and starboard tack. Then, with ``beyond`` one of :data:`BEYOND_MODES`:

- Inside the table (TWA and TWS both within the first and last row/column, edges included) the speed is
  the bilinear interpolation of the four surrounding nodes, whatever ``beyond`` says.
- TWA above the last row (e.g. (160, 180] for the Maribot Vane) or TWS above the last column (> 20 kn):
  ``"clamp"`` (default) sails at the nearest edge of the table (the TWA-160 speed, the 20-kn speed);
  ``"forbid"`` returns 0 kn, which the cost turns into an infinite (forbidden) arc.
- TWS below the first column, when that column is above 0 kn: the speed falls linearly from the
  first-column value to 0 kn at TWS 0, in both modes (light air is slow, not forbidden).
- TWA below the first row, when that row is above 0 deg: 0 kn in both modes. A table that does not list
  the angles nearest the wind is read as not sailing them (the no-go zone); clamping there would let a
  boat sail straight into the wind at its close-hauled speed.
- NaN in TWA or TWS gives NaN out. Negative TWS raises :class:`ValueError`.

References
----------
Dhomé, U. (2017). Further development and performance evaluation of the autonomous sailing boat Maribot
Vane. Technical report, KTH Royal Institute of Technology (measured polar of the Maribot Vane).
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft.
Proc. International Robotic Sailing Conference 2018, section 3.1 (use of that polar; linear interpolation
of boat speed from performance data, Algorithm 1).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import geodesy
from pyroute_rel.errors import (
    OutputError,
    PolarError,
    PolarWarning,
    brief,
    check_instance,
    check_numbers,
    check_path,
    show,
)
from pyroute_rel.files import atomic_write_text, read_regular_bytes

__all__ = [
    "Polar",
    "MIN_SPEED_KN",
    "MAX_SPEED_KN",
    "BEYOND_MODES",
    "check_beyond",
    "POLAR_SUFFIXES",
    "BUILTIN_POLARS",
    "boat_speed_kn",
    "fold_twa_deg",
    "read_pol",
    "write_pol",
    "read_polar_csv",
    "write_polar_csv",
    "read_polar",
    "get_polar",
]

#: Slowest useful speed over ground [kn]: below it (near-calm air, a current almost as strong as the boat) an arc
#: is forbidden as "no speed" rather than sailed for thousands of hours.
MIN_SPEED_KN = 0.01
#: Largest boat speed a polar may hold [kn]: the fastest sailing craft make about 65 kn (Sailrocket 2, 2012), so a
#: larger one is a table in another unit or a typo, never a craft (issue 34: 300 kn crossed 534 nm in 1.78 h).
MAX_SPEED_KN = 100.0

FloatArray = npt.NDArray[np.float64]

#: How :func:`boat_speed_kn` treats TWA above the last row and TWS above the last column.
BEYOND_MODES = ("clamp", "forbid")


def check_beyond(beyond: object, where: str = "'beyond'") -> str:
    """``beyond`` checked to be one of :data:`BEYOND_MODES` (the one check of the option, wherever it is given).

    Parameters
    ----------
    beyond : The value given.
    where : How messages name the option, e.g. ``"[boat].beyond"``.

    Raises
    ------
    PolarError
        When it is not one of :data:`BEYOND_MODES`.

    >>> check_beyond("forbid")
    'forbid'
    """
    if not isinstance(beyond, str) or beyond not in BEYOND_MODES:
        raise PolarError(f"{where} must be one of {list(BEYOND_MODES)} (got {beyond!r})")
    return beyond


#: File suffixes :func:`read_polar` understands (``.csv``: the CSV form, the others: ``.pol``).
POLAR_SUFFIXES = (".pol", ".txt", ".csv")

#: First header cells accepted by :func:`read_pol` (lower case, ``/`` read as ``\``).
_POL_LABELS = frozenset({"twa\\tws", "twa", "tws", ""})
#: First header cells accepted by :func:`read_polar_csv`.
_CSV_LABELS = frozenset({"twa_deg\\tws_kn", "twa\\tws", "twa", "tws", ""})
_CSV_HEADER = "twa_deg\\tws_kn"

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)


# ---------------------------------------------------------------------------------------------------------
# The table


@dataclass(frozen=True, eq=False)
class Polar:
    """A boat polar: boat speed [kn] over true wind angle [deg] and true wind speed [kn].

    Arrays are copied to read-only float64 on construction and validated; a bad table raises
    :class:`~pyroute_rel.errors.PolarError`. Two polars are equal when name and all arrays are equal.

    Parameters
    ----------
    name : Name of the boat or table (file stem when read from a file).
    twa_deg : True wind angles of the rows [deg], 1-D, strictly increasing, within [0, 180], >= 2 values.
    tws_kn : True wind speeds of the columns [kn], 1-D, strictly increasing, >= 0, >= 2 values.
    speed_kn : Boat speed through the water [kn], shape ``(len(twa_deg), len(tws_kn))``, finite, >= 0.

    Examples
    --------
    >>> p = Polar("toy", twa_deg=[0.0, 90.0, 180.0], tws_kn=[0.0, 10.0],
    ...           speed_kn=[[0.0, 0.0], [0.0, 6.0], [0.0, 4.0]])
    >>> p.speed([45.0, 135.0], 10.0).tolist()
    [3.0, 5.0]
    """

    name: str
    twa_deg: FloatArray
    tws_kn: FloatArray
    speed_kn: FloatArray

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise PolarError(f"polar 'name' must be a non-empty string (got {self.name!r})")
        where = f"polar {self.name!r}"
        twa = _as_readonly(self.twa_deg, "twa_deg", where)
        tws = _as_readonly(self.tws_kn, "tws_kn", where)
        speed = _as_readonly(self.speed_kn, "speed_kn", where)
        for label, axis, unit in (("twa_deg", twa, "deg"), ("tws_kn", tws, "kn")):
            if axis.ndim != 1 or axis.size < 2:
                raise PolarError(
                    f"{where}: '{label}' must be 1-D with at least 2 values [{unit}] (got shape {axis.shape})"
                )
            if not np.all(np.isfinite(axis)):
                raise PolarError(f"{where}: '{label}' must be finite [{unit}] (got {axis.tolist()})")
            if not np.all(np.diff(axis) > 0):
                raise PolarError(f"{where}: '{label}' must be strictly increasing [{unit}] (got {axis.tolist()})")
        if twa[0] < 0.0 or twa[-1] > 180.0:
            raise PolarError(f"{where}: 'twa_deg' must lie within [0, 180] [deg] (got {twa[0]:g} to {twa[-1]:g})")
        if tws[0] < 0.0:
            raise PolarError(f"{where}: 'tws_kn' must be >= 0 [kn] (got {tws[0]:g})")
        expected = (twa.size, tws.size)
        if speed.shape != expected:
            raise PolarError(f"{where}: 'speed_kn' must have shape (n_twa, n_tws) = {expected} (got {speed.shape})")
        too_fast = np.isfinite(speed) & (speed > MAX_SPEED_KN)
        rules = ((~np.isfinite(speed), "finite"), (speed < 0.0, ">= 0"), (too_fast, f"at most {MAX_SPEED_KN:g}"))
        for bad, rule in rules:
            if np.any(bad):
                i, j = np.argwhere(bad)[0]
                raise PolarError(
                    f"{where}: 'speed_kn' must be {rule} [kn] "
                    f"(got {speed[i, j]:g} at TWA {twa[i]:g} deg, TWS {tws[j]:g} kn)"
                    + (
                        "; the fastest sailing craft make about 65 kn: is the table in another unit?"
                        if bad is too_fast
                        else ""
                    )
                )
        object.__setattr__(self, "twa_deg", twa)
        object.__setattr__(self, "tws_kn", tws)
        object.__setattr__(self, "speed_kn", speed)

    def speed(self, twa_deg: npt.ArrayLike, tws_kn: npt.ArrayLike, *, beyond: str = "clamp") -> FloatArray:
        """Boat speed [kn] at true wind angles [deg] and speeds [kn]; see :func:`boat_speed_kn`."""
        return boat_speed_kn(self, twa_deg, tws_kn, beyond=beyond)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Polar):
            return NotImplemented
        return (
            self.name == other.name
            and np.array_equal(self.twa_deg, other.twa_deg)
            and np.array_equal(self.tws_kn, other.tws_kn)
            and np.array_equal(self.speed_kn, other.speed_kn)
        )

    def __hash__(self) -> int:
        return hash((self.name, self.twa_deg.tobytes(), self.tws_kn.tobytes(), self.speed_kn.tobytes()))

    def __repr__(self) -> str:
        twa, tws = self.twa_deg, self.tws_kn
        return (
            f"Polar(name={self.name!r}, twa_deg=[{twa[0]:g} .. {twa[-1]:g}] ({twa.size} rows), "
            f"tws_kn=[{tws[0]:g} .. {tws[-1]:g}] ({tws.size} columns))"
        )


def _as_readonly(value: Any, label: str, where: str) -> FloatArray:
    try:
        arr = np.array(value, dtype=np.float64)  # always a copy: the caller's array stays theirs
    except (TypeError, ValueError) as exc:
        raise PolarError(f"{where}: '{label}' must be an array of numbers (got {type(value).__name__})") from exc
    arr.setflags(write=False)
    return arr


# ---------------------------------------------------------------------------------------------------------
# Lookup


def fold_twa_deg(twa_deg: npt.ArrayLike) -> FloatArray:
    """Fold any angle off the wind into a true wind angle in [0, 180] [deg] (port = starboard).

    Parameters
    ----------
    twa_deg : Signed or unsigned angle between heading and the true wind direction [deg].

    Returns
    -------
    True wind angle in [0, 180] [deg]; NaN (and +-inf) give NaN.

    Examples
    --------
    >>> fold_twa_deg([-30.0, 330.0, 190.0, 540.0]).tolist()
    [30.0, 30.0, 170.0, 180.0]
    """
    return geodesy.fold_angle_deg(twa_deg)


def boat_speed_kn(
    polar: Polar,
    twa_deg: npt.ArrayLike,
    tws_kn: npt.ArrayLike,
    *,
    beyond: str = "clamp",
) -> FloatArray:
    """Boat speed [kn] from a polar by bilinear interpolation in (TWA, TWS), vectorised.

    Parameters
    ----------
    polar : The boat's polar table.
    twa_deg : True wind angle [deg]; folded into [0, 180] (-30 and 330 read as 30).
    tws_kn : True wind speed [kn], >= 0. Broadcast against ``twa_deg``.
    beyond : One of :data:`BEYOND_MODES`: what to do at TWA above the last row or TWS above the last
        column. ``"clamp"`` uses the nearest edge of the table; ``"forbid"`` returns 0 kn there. Points
        inside the table are never affected. See the module section *Outside the table*, which also
        covers TWS below the first column (linear to 0 kn at TWS 0) and TWA below the first row (0 kn).

    Returns
    -------
    Boat speed [kn], with the broadcast shape of the inputs (a 0-d array for scalars); NaN where
    either input is NaN.

    Raises
    ------
    PolarError (a ValueError)
        ``beyond`` is not one of :data:`BEYOND_MODES`; ``polar`` is not a :class:`Polar`; an angle or speed is
        not a number, some TWS is negative, or the shapes do not broadcast.

    References
    ----------
    Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing
    Craft. Proc. IRSC 2018, Algorithm 1 (boat speed interpolated from performance data).

    Examples
    --------
    TWA 47.5 deg, TWS 10 kn lies midway between TWA 40/55 and TWS 8/12, so the speed is the mean of the
    four surrounding nodes, (2.4 + 2.8 + 3.6 + 4.0) / 4:

    >>> vane = BUILTIN_POLARS["maribot_vane"]
    >>> float(boat_speed_kn(vane, 47.5, 10.0))
    3.2

    Beyond the table (TWA 170 deg on either tack, TWS 25 kn) "clamp" sails at the TWA-160, 20-kn speed:

    >>> boat_speed_kn(vane, [170.0, -170.0], 25.0).tolist()
    [3.6, 3.6]
    >>> boat_speed_kn(vane, [170.0, 100.0], 25.0, beyond="forbid").tolist()
    [0.0, 0.0]
    """
    check_instance(polar, Polar, "polar", PolarError)
    check_beyond(beyond)
    twa = check_numbers(twa_deg, "twa_deg", PolarError, infinite=True, unit="deg")
    tws = check_numbers(tws_kn, "tws_kn", PolarError, infinite=True, unit="kn")
    try:
        a, w = np.broadcast_arrays(fold_twa_deg(twa), tws)
    except ValueError:
        raise PolarError(f"twa_deg and tws_kn must broadcast (got shapes {twa.shape} and {tws.shape})") from None
    shape = a.shape
    a = a.reshape(-1)  # 1-D (a copy when broadcast) so that every step below works in place
    w = w.reshape(-1)
    if np.any(w < 0.0):
        raise PolarError(f"'tws_kn' must be >= 0 [kn] (got {np.nanmin(w):g})")

    twa, tws, table = polar.twa_deg, polar.tws_kn, polar.speed_kn
    n_tws = tws.size
    # Cell indices: row i in [0, n_twa - 2], column j in [0, n_tws - 2]; fractions clipped to [0, 1] so
    # points past either edge take that edge's value (NaN passes through searchsorted and the clip).
    i = np.searchsorted(twa, a, side="right")
    i -= 1
    np.clip(i, 0, twa.size - 2, out=i)
    j = np.searchsorted(tws, w, side="right")
    j -= 1
    np.clip(j, 0, n_tws - 2, out=j)
    fa = a - twa[i]
    fa /= np.diff(twa)[i]
    np.clip(fa, 0.0, 1.0, out=fa)
    fw = w - tws[j]
    fw /= np.diff(tws)[j]
    np.clip(fw, 0.0, 1.0, out=fw)

    k = i * n_tws
    k += j
    flat = table.ravel()
    s00 = flat.take(k)
    s01 = flat.take(k + 1)
    k += n_tws
    s10 = flat.take(k)
    s11 = flat.take(k + 1)
    # low = (1 - fw) s00 + fw s01, high = (1 - fw) s10 + fw s11, speed = (1 - fa) low + fa high; this form
    # gives every node of the table exactly, the last row and column included (fraction 1).
    gw = 1.0 - fw
    s00 *= gw
    s01 *= fw
    s00 += s01
    s10 *= gw
    s11 *= fw
    s10 += s11
    s10 *= fa
    fa -= 1.0
    s00 *= fa
    s10 -= s00
    speed = s10

    if tws[0] > 0.0:  # light air below the table: linear to 0 kn at TWS 0
        low = w < tws[0]
        if np.any(low):
            speed[low] *= w[low] / tws[0]
    if twa[0] > 0.0:  # angles closer to the wind than the table lists: no-go
        speed[a < twa[0]] = 0.0
    if beyond == "forbid":
        speed[(a > twa[-1]) | (w > tws[-1])] = 0.0
    return speed.reshape(shape)


# ---------------------------------------------------------------------------------------------------------
# Built-in boats

#: Maribot Vane boat speed [kn]; rows TWS [kn] = 0, 4, 8, 12, 16, 20, columns TWA [deg] = 0, 25, ..., 160.
#: Source: Dhomé (2017), as tabulated for Dickson, Blake and Sear (2018) (see module References).
_MARIBOT_VANE_TWS_BY_TWA = (
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (0.0, 0.9, 1.2, 1.4, 1.4, 1.4, 1.4, 1.2, 1.1, 1.0, 0.7),
    (0.0, 1.8, 2.4, 2.8, 2.9, 2.9, 2.8, 2.6, 2.2, 1.9, 1.5),
    (0.0, 2.75, 3.6, 4.0, 4.2, 4.2, 4.1, 3.8, 3.4, 2.9, 2.2),
    (0.0, 3.6, 4.4, 4.6, 4.6, 4.7, 4.6, 4.5, 4.3, 3.8, 3.0),
    (0.0, 4.1, 4.75, 5.0, 5.1, 5.2, 5.1, 5.0, 4.7, 4.4, 3.6),
)

#: Built-in polars by name. ``maribot_vane``: the Maribot Vane autonomous sailing boat (Dhomé 2017, as
#: used by Dickson et al. 2018); TWA 0-160 deg, TWS 0-20 kn.
BUILTIN_POLARS: Mapping[str, Polar] = MappingProxyType(
    {
        "maribot_vane": Polar(
            name="maribot_vane",
            twa_deg=np.array([0.0, 25.0, 40.0, 55.0, 70.0, 85.0, 100.0, 115.0, 130.0, 145.0, 160.0]),
            tws_kn=np.array([0.0, 4.0, 8.0, 12.0, 16.0, 20.0]),
            speed_kn=np.array(_MARIBOT_VANE_TWS_BY_TWA).T,
        ),
    }
)


def get_polar(
    name_or_path: str | os.PathLike[str] | Polar,
    *,
    base_dir: str | os.PathLike[str] | None = None,
) -> Polar:
    """A built-in polar by name, or a polar read from a file.

    Parameters
    ----------
    name_or_path : A key of :data:`BUILTIN_POLARS`, or a path to a ``.pol``/``.txt``/``.csv`` file
        (a :class:`Polar` is returned unchanged).
    base_dir : Folder that relative paths are resolved against (e.g. the scenario file's folder);
        default the current directory.

    Raises
    ------
    PolarError
        Unknown name (the message lists the built-ins), unreadable or malformed file.

    Examples
    --------
    >>> get_polar("maribot_vane").tws_kn.tolist()
    [0.0, 4.0, 8.0, 12.0, 16.0, 20.0]
    """
    if isinstance(name_or_path, Polar):
        return name_or_path
    if base_dir is not None:
        check_path(base_dir, "base_dir", PolarError)
    if isinstance(name_or_path, str) and name_or_path in BUILTIN_POLARS:
        return BUILTIN_POLARS[name_or_path]
    try:
        text = os.fspath(name_or_path)
        if not isinstance(text, str):  # bytes
            raise TypeError
    except TypeError:
        raise PolarError(
            f"polar must be a built-in name {sorted(BUILTIN_POLARS)} or a path to a polar file "
            f"(got {type(name_or_path).__name__} {brief(name_or_path)})"
        ) from None
    looks_like_path = (
        not isinstance(name_or_path, str)
        or Path(text).suffix.lower() in POLAR_SUFFIXES
        or "/" in text
        or os.sep in text
    )
    if not looks_like_path:
        raise PolarError(
            f"unknown polar {brief(text)}: expected one of the built-in polars {sorted(BUILTIN_POLARS)} "
            f"or a path to a {'/'.join(POLAR_SUFFIXES)} file"
        )
    path = Path(text).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    return read_polar(path)


# ---------------------------------------------------------------------------------------------------------
# Files


def read_polar(path: str | os.PathLike[str], *, name: str | None = None) -> Polar:
    """Read a polar file, choosing the format from its suffix (``.pol``/``.txt``: :func:`read_pol`,
    ``.csv``: :func:`read_polar_csv`).

    Raises
    ------
    PolarError
        Unknown suffix, unreadable or malformed file.
    """
    path = Path(check_path(path, "polar file", PolarError))
    if name is not None:
        check_instance(name, str, "name", PolarError)
    suffix = path.suffix.lower()
    if suffix not in POLAR_SUFFIXES:
        raise PolarError(
            f"polar file '{show(path)}': suffix must be one of {list(POLAR_SUFFIXES)} (got {path.suffix!r})"
        )
    if suffix == ".csv":
        return read_polar_csv(path, name=name)
    return read_pol(path, name=name)


def read_pol(path: str | os.PathLike[str], *, name: str | None = None) -> Polar:
    r"""Read a TWA\TWS polar file (OpenCPN / qtVlm / VLM ``.pol``); see the module section *File formats*.

    Parameters
    ----------
    path : The file.
    name : Name of the polar; default the file stem.

    Raises
    ------
    PolarError
        The file cannot be read or is malformed (one line naming the file and line).
    """
    path = Path(path)
    return _parse_matrix(_read_lines(path), path, name or path.stem, split=_split_pol, labels=_POL_LABELS, csv=False)


def read_polar_csv(path: str | os.PathLike[str], *, name: str | None = None) -> Polar:
    r"""Read a polar from the CSV form: header ``twa_deg\tws_kn,<TWS [kn]>,...``, then rows
    ``<TWA [deg]>,<speed [kn]>,...`` (see the module section *File formats*).

    Raises
    ------
    PolarError
        The file cannot be read or is malformed (one line naming the file and line).
    """
    path = Path(path)
    return _parse_matrix(_read_lines(path), path, name or path.stem, split=_split_csv, labels=_CSV_LABELS, csv=True)


def write_pol(polar: Polar, path: str | os.PathLike[str]) -> Path:
    r"""Write a polar as a tab-separated TWA\TWS ``.pol`` file, atomically; returns the path.

    Numbers are written in their shortest exact form, so :func:`read_pol` gives back the same table.
    """
    return _write_matrix(polar, Path(path), "TWA\\TWS", "\t")


def write_polar_csv(polar: Polar, path: str | os.PathLike[str]) -> Path:
    r"""Write a polar in the CSV form (header ``twa_deg\tws_kn,...``), atomically; returns the path."""
    return _write_matrix(polar, Path(path), _CSV_HEADER, ",")


def _fmt(x: float) -> str:
    r = repr(float(x) + 0.0)  # + 0.0 turns -0.0 into 0.0
    return r[:-2] if r.endswith(".0") else r


def _write_matrix(polar: Polar, path: Path, label: str, sep: str) -> Path:
    lines = [sep.join([label, *map(_fmt, polar.tws_kn)])]
    for twa, row in zip(polar.twa_deg, polar.speed_kn, strict=True):
        lines.append(sep.join([_fmt(twa), *map(_fmt, row)]))
    try:
        atomic_write_text(path, "\n".join(lines) + "\n")
    except OSError as exc:
        raise OutputError(f"cannot write polar file {show(path)} ({exc.strerror or exc})") from None
    return path


def _read_lines(path: Path) -> list[str]:
    # regular files only, at most 10 MB (a polar is a few kB): no hang on a FIFO, no read of a device
    data = read_regular_bytes(
        path, limit_bytes=10_000_000, error=PolarError, label=f"polar file '{show(path)}': cannot be read", what="file"
    )
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")  # comments in old files; numbers are ASCII either way
    return text.splitlines()


def _split_pol(line: str) -> list[str]:
    """A line's cells: split at tabs when it has any, else at ``;``, else at ``,``, else at runs of spaces. With a
    tab, ``;`` or ``,`` an empty cell between two separators stays an empty cell (a missing speed)."""
    for sep in ("\t", ";", ","):
        if sep in line:
            cells = [c.strip() for c in line.split(sep)]
            break
    else:
        cells = line.split()
    if len(cells) > 1 and cells[-1] == "":
        cells.pop()  # trailing separator
    return cells


def _split_csv(line: str) -> list[str]:
    cells = [c.strip().strip('"') for c in line.split(",")]
    if len(cells) > 1 and cells[-1] == "":
        cells.pop()
    return cells


def _parse_matrix(
    raw_lines: Sequence[str],
    path: Path,
    name: str,
    *,
    split: Callable[[str], list[str]],
    labels: frozenset[str],
    csv: bool,
) -> Polar:
    """Parse a TWA\\TWS matrix; every problem is a one-line :class:`PolarError` naming file and line."""
    rows: Iterable[tuple[int, list[str]]] = (
        (n, split(s)) for n, s in enumerate((ln.strip() for ln in raw_lines), start=1) if s and not s.startswith("#")
    )
    rows = iter(rows)
    expected_label = (
        "'twa_deg\\tws_kn' (or 'TWA\\TWS' or an empty cell)" if csv else "'TWA\\TWS' (or 'TWA/TWS' or an empty cell)"
    )

    def fail(line_no: int, message: str) -> PolarError:
        return PolarError(f"polar file '{show(path)}', line {line_no}: {message}")

    def number(line_no: int, column: int, cell: str, what: str) -> float:
        value = _number(cell, what)
        if isinstance(value, str):
            raise fail(line_no, f"column {column}: {value}")
        return value

    header = next(rows, None)
    if header is None:
        raise fail(
            len(raw_lines) + 1 if raw_lines else 1,
            f"expected a header row starting with {expected_label}, found end of file (no data lines)",
        )
    header_no, cells = header
    first = cells[0].strip("\"'").lower().replace("/", "\\")
    if first in labels:
        tws_cells = cells[1:]
        col0 = 2
    elif not csv and _NUMBER.fullmatch(cells[0]):
        tws_cells = cells  # empty first cell in a space-separated file
        col0 = 1
    else:
        raise fail(header_no, f"expected {expected_label} as the first header cell, found {_show(cells[0])}")
    if len(tws_cells) < 2:
        raise fail(header_no, f"expected at least 2 TWS [kn] in the header row, found {len(tws_cells)}")
    tws: list[float] = []
    for c, cell in enumerate(tws_cells, start=col0):
        value = number(header_no, c, cell, "TWS [kn]")
        if value < 0.0:
            raise fail(header_no, f"column {c}: expected a TWS >= 0 [kn], found {cell!r}")
        if tws and value <= tws[-1]:
            raise fail(
                header_no,
                f"column {c}: expected TWS [kn] strictly increasing, found {cell!r} after {_fmt(tws[-1])}",
            )
        tws.append(value)

    n_cells = len(tws) + 1
    gaps: list[tuple[int, int]] = []  # (line, column) of the empty or missing speeds
    twa: list[float] = []
    speed: list[list[float]] = []
    for line_no, cells in rows:
        if len(cells) > n_cells:
            raw = raw_lines[line_no - 1]
            hint = " (decimal commas are not supported)" if "," in raw and (";" in raw or "\t" in raw) else ""
            raise fail(
                line_no,
                f"expected {n_cells} cells (a TWA [deg] and {len(tws)} speeds [kn], as the header on line "
                f"{header_no}; a row may end early or leave cells empty), found {len(cells)}{hint}",
            )
        angle = number(line_no, 1, cells[0], "TWA [deg]")
        if not 0.0 <= angle <= 180.0:
            raise fail(line_no, f"column 1: expected a TWA in [0, 180] [deg], found {cells[0]!r}")
        if twa and angle <= twa[-1]:
            raise fail(
                line_no,
                f"column 1: expected TWA [deg] strictly increasing down the file, found {cells[0]!r} "
                f"after {_fmt(twa[-1])}",
            )
        row = [_speed_cell(cell, line_no, c, fail) for c, cell in enumerate(cells[1:], start=2)]
        row += [math.nan] * (n_cells - len(cells))  # a row that ends early: its last speeds are missing
        gaps += [(line_no, c + 2) for c, v in enumerate(row) if math.isnan(v)]
        twa.append(angle)
        speed.append(row)
    if len(twa) < 2:
        raise fail(header_no, f"expected at least 2 TWA rows after this header, found {len(twa)}")
    table, tws_kn, gaps = _drop_empty_columns(np.array(speed), np.array(tws), gaps, path)
    if gaps:
        table = _fill_gaps(np.array(twa), tws_kn, table, gaps, fail, header_no, path)
    return Polar(name=name, twa_deg=np.array(twa), tws_kn=tws_kn, speed_kn=table)


def _drop_empty_columns(
    table: FloatArray, tws_kn: FloatArray, gaps: list[tuple[int, int]], path: Path
) -> tuple[FloatArray, FloatArray, list[tuple[int, int]]]:
    """The table without its TWS columns that have no speed in any row, while two columns remain (OpenCPN reads such
    files: issue 34 found 2 of its 714 polars refused), with a warning naming them; else as it is."""
    empty = ~np.isfinite(table).any(axis=0)
    if not empty.any() or int((~empty).sum()) < 2:
        return table, tws_kn, gaps
    warnings.warn(
        f"polar file '{show(path)}': TWS column(s) {', '.join(f'{v:g}' for v in tws_kn[empty])} kn have no boat "
        "speed in any row: dropped",
        PolarWarning,
        stacklevel=4,
    )
    dropped = {int(j) + 2 for j in np.flatnonzero(empty)}  # (the file's column numbers)
    return table[:, ~empty], tws_kn[~empty], [g for g in gaps if g[1] not in dropped]


def _fill_gaps(
    twa: FloatArray,
    tws: FloatArray,
    table: FloatArray,
    gaps: list[tuple[int, int]],
    fail: Callable[[int, str], PolarError],
    header_no: int,
    path: Path,
) -> FloatArray:
    """Fill the empty or missing speeds of a polar table (NaN) as the module notes say, warning once.

    Within a TWS column, a gap between two given speeds is interpolated linearly in TWA. A gap above the first or
    below the last given speed of its column is interpolated linearly in TWS when its row gives speeds on both sides
    of it (a rated angle missing one cell, as OpenCPN fills it: a lost 4.9 kn at TWA 180 between two 4.9 kn cells of
    ``Figaro_1-1.pol`` was 0 kn), else it is 0 kn (no speed: the boat is not rated there, so it never sails there).
    A column with no speed at all is refused (the reader drops such columns first while two others remain).
    """
    out = table.copy()
    for j in range(out.shape[1]):
        known = np.isfinite(table[:, j])
        if not known.any():
            raise fail(header_no, f"column {j + 2}: no boat speed in any row (every cell of this TWS is empty)")
        missing = ~known
        out[missing, j] = np.interp(twa[missing], twa[known], table[known, j], left=np.nan, right=np.nan)
    n_twa = int(np.count_nonzero(np.isfinite(out) & np.isnan(table)))
    for i, j in zip(*np.nonzero(np.isnan(out)), strict=True):  # edge gaps of their column
        given = np.flatnonzero(np.isfinite(table[i]))
        if given.size and given[0] < j < given[-1]:
            out[i, j] = np.interp(tws[j], tws[given], table[i, given])
    n_tws = int(np.count_nonzero(np.isfinite(out) & np.isnan(table))) - n_twa
    out[np.isnan(out)] = 0.0
    n_zero = len(gaps) - n_twa - n_tws
    line, col = gaps[0]
    warnings.warn(
        f"polar file '{show(path)}': {len(gaps)} empty or missing speed cell(s) filled (first: line {line}, column "
        f"{col}): {n_twa} interpolated in TWA between the speeds above and below, {n_tws} in TWS between the speeds "
        f"beside them in their row, {n_zero} set to 0 kn (no speed given further up or down that TWS column, nor "
        "on both sides in its row)",
        PolarWarning,
        stacklevel=4,
    )
    return out


def _speed_cell(cell: str, line_no: int, column: int, fail: Callable[[int, str], PolarError]) -> float:
    """A boat speed cell [kn]: its value, NaN when empty (filled later), or a one-line error."""
    if cell == "":
        return math.nan
    if "," in cell and _NUMBER.fullmatch(cell.replace(",", ".")):
        raise fail(
            line_no,
            f"column {column}: expected a number (speed [kn]), found {_show(cell)} (decimal commas are not supported)",
        )
    value = _number(cell, "speed [kn]")
    if isinstance(value, str):
        raise fail(line_no, f"column {column}: {value}")
    if value < 0.0:
        raise fail(line_no, f"column {column}: expected a boat speed >= 0 [kn], found {cell!r}")
    return value


def _number(cell: str, what: str) -> float | str:
    """The value of a numeric cell, or a message saying what is wrong with it."""
    if _NUMBER.fullmatch(cell):
        value = float(cell)
        if math.isfinite(value):
            return value
    elif not _NONFINITE.fullmatch(cell):
        return f"expected a number ({what}), found {_show(cell)}"
    return f"expected a finite number ({what}), found {_show(cell)}"


def _show(cell: str, limit: int = 40) -> str:
    """A cell for an error message: quoted, escaped, and cut short if long (binary or mangled files)."""
    return repr(cell if len(cell) <= limit else cell[:limit] + "...")
