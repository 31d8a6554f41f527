"""Grid convergence: how much of a routed voyage time is discretisation error?

A route planned on a coarse rank digraph is longer (or shorter) than the same route on a fine one. Given a
quantity ``phi`` (voyage time [h], voyage failure probability, ...) computed on a family of grids with a
representative spacing ``h`` (node spacing [km], say), this module estimates the observed order of
convergence, the grid-independent value and an uncertainty band for the finest grid:

- :func:`grid_convergence` -- the three-grid Grid Convergence Index procedure of Celik et al. (2008)
  (Richardson extrapolation with a non-uniform refinement ratio and Roache's safety factor);
- :func:`least_squares_convergence` -- the least-squares procedure of Eça & Hoekstra (2014) for four or
  more grids, which tolerates scatter in the data;
- :func:`convergence_study` -- both, on every consecutive triplet of a sorted family, with a text report.

All functions are pure: they take spacings and values, sort them fine -> coarse themselves and return
frozen result objects whose ``to_dict()`` is JSON-ready (NaN and infinity become ``None``). Relative errors,
GCI values and uncertainties are FRACTIONS of the fine-grid value (0.02 means 2 %), never percent.
Nothing here routes: the study runner that builds the grids and calls the solver sits on top of this.

References
----------
Celik, I. B., Ghia, U., Roache, P. J., Freitas, C. J., Coleman, H. and Raad, P. E. (2008). Procedure for
Estimation and Reporting of Uncertainty Due to Discretization in CFD Applications. J. Fluids Eng. 130(7),
078001, doi:10.1115/1.2960953.

Roache, P. J. (1994). Perspective: A Method for Uniform Reporting of Grid Refinement Studies.
J. Fluids Eng. 116(3), 405-413, doi:10.1115/1.2910291 (GCI, safety factor, asymptotic-range check).

Eça, L. and Hoekstra, M. (2014). A procedure for the estimation of the numerical uncertainty of CFD
calculations based on grid refinement studies. J. Comput. Phys. 262, 104-130,
doi:10.1016/j.jcp.2013.12.029.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq, minimize_scalar

from pyroute_rel.errors import ConvergenceError

__all__ = [
    "CONVERGENCE_LABELS",
    "LS_FITS",
    "LS_WEIGHTINGS",
    "ThreeGridResult",
    "LeastSquaresResult",
    "StudyResult",
    "grid_convergence",
    "least_squares_convergence",
    "convergence_study",
    "P_PLAUSIBLE",
    "ROUNDOFF_REL",
]

FloatArray = npt.NDArray[np.float64]

#: Labels of ``ThreeGridResult.convergence`` (and of ``LeastSquaresResult.convergence``, which uses the
#: first three). With R = eps21 / eps32 and R' = R ln(r32) / ln(r21) (= R for a constant ratio):
#: "monotonic" 0 < R' < 1, "oscillatory" R < 0, "divergent" R' >= 1 (including phi3 == phi2 != phi1),
#: "converged" phi1 == phi2 == phi3 or both differences at round-off level (:data:`ROUNDOFF_REL`),
#: "indeterminate" phi1 == phi2 != phi3 or only |phi2 - phi1| at round-off level.
CONVERGENCE_LABELS = ("monotonic", "oscillatory", "divergent", "converged", "indeterminate")

#: Forms :func:`least_squares_convergence` may fit, in the normalised spacing x = h / h_fine:
#: "power" phi0 + a x^p, "first" phi0 + a x, "second" phi0 + a x^2, "first+second" phi0 + a1 x + a2 x^2,
#: plus "data-range" (no fit, oscillatory data) and "constant" (all values equal).
LS_FITS = ("power", "first", "second", "first+second", "data-range", "constant")

#: Weightings of the least-squares fits; "auto" fits both and keeps the smaller standard deviation.
LS_WEIGHTINGS = ("auto", "weighted", "unweighted")

#: Plausible observed orders of convergence [-]. The voyage time of a rank-digraph route converges at formal
#: order 1 (heading quantised to the grid's arc angles, a finish reached between ranks) to 2 (a smooth track
#: drawn as chords: the length error of a chord of length h is O(h^2)); observed orders scatter around these but
#: an order below 0.5 makes the extrapolated correction more than 1 / (2^0.5 - 1) = 2.4 times the fine-grid
#: difference for r = 2, and one above 8 (four times the highest formal order) means the coarse difference dwarfs
#: the fine one -- a coincidence or round-off, not convergence. Outside this range a study is "indeterminate"
#: (:meth:`StudyResult.verdict`) and a gate that requires convergence fails.
P_PLAUSIBLE = (0.5, 8.0)
#: Differences between grids no larger than this fraction of max |phi| are round-off, not discretisation
#: change: about 4.5e5 units in the last place of a double, far above the ~1e-13 relative error that summing a
#: few thousand arc times accumulates, and far below any discretisation change a gate is meant to judge. A
#: triplet whose fine difference (or both differences) is this small is "indeterminate".
ROUNDOFF_REL = 1e-10

#: Celik et al. (2008) recommend refinement ratios of at least this value.
_R_RECOMMENDED = 1.3
#: Search range of the three-grid apparent order: geometric scan of (P_SCAN_MIN, P_SCAN_MAX].
_P_SCAN_MIN = 1e-9
_P_SCAN_MAX = 1e4
_P_SCAN_N = 4000
#: Default bounds of the observed order in the least-squares power fit.
_LS_P_BOUNDS = (0.01, 10.0)
#: exp() argument above which r^p is treated as infinite (math.exp overflows near 709.8).
_EXP_MAX = 700.0


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def _clean(value: Any) -> Any:
    """JSON-ready copy: numpy scalars -> float/int, NaN/inf -> None, tuples -> lists (recursively)."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_clean(v) for v in value]
    return value


def _fmt(value: float | None, spec: str) -> str:
    """Format a number for the text report: '-' for None, 'inf' for infinity."""
    if value is None:
        return "-"
    if math.isinf(value):
        return "inf"
    return format(value, spec)


def _pct(value: float | None) -> str:
    """Format a fraction as percent for the text report."""
    return _fmt(None if value is None else 100.0 * value, ".3f")


def _validate(
    h: npt.ArrayLike,
    phi: npt.ArrayLike,
    *,
    func: str,
    n_exact: int | None = None,
    n_min: int | None = None,
    names: tuple[str, str] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Check (h, phi) once at the public boundary and return them sorted fine -> coarse.

    ``names``: what the messages call h and phi (e.g. the CLI's ``("--h", "--phi")``, then without the ``func``
    prefix and with 1-based value numbers); default ``'h'`` and ``'phi'`` after ``func:``.
    """
    pre = "" if names else f"{func}: "
    nh, nphi = names if names else ("'h'", "'phi'")

    def at(i: int, n: int) -> str:
        return f"value {i + 1} of {n}" if names else f"position {i}"

    arrays = []
    for name, values in ((nh, h), (nphi, phi)):
        try:
            arr = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            shown = " ".join(repr(values).split())
            shown = shown if len(shown) <= 80 else shown[:77] + "..."
            raise ConvergenceError(f"{pre}{name} must be a sequence of numbers (got {shown})") from None
        if arr.ndim != 1:
            raise ConvergenceError(f"{pre}{name} must be one-dimensional (got shape {arr.shape})")
        arrays.append(arr)
    h_arr, phi_arr = arrays
    if h_arr.size != phi_arr.size:
        raise ConvergenceError(f"{pre}{nh} and {nphi} must have the same length (got {h_arr.size} and {phi_arr.size})")
    n = h_arr.size
    if n_exact is not None and n != n_exact:
        raise ConvergenceError(
            f"{nh} and {nphi} need exactly {n_exact} values each (got {n})"
            if names
            else f"{func} needs exactly {n_exact} grids (got {n})"
        )
    if n_min is not None and n < n_min:
        raise ConvergenceError(
            f"{nh} and {nphi} need at least {n_min} values each, one per grid (got {n})"
            if names
            else f"{func} needs at least {n_min} grids (got {n})"
        )
    bad = np.flatnonzero(~np.isfinite(h_arr) | ~(h_arr > 0.0))
    if bad.size:
        i = int(bad[0])
        what = " (grid spacings)" if names else ""
        raise ConvergenceError(f"{pre}{nh}{what} must be finite and > 0 (got {float(h_arr[i])!r} at {at(i, n)})")
    bad = np.flatnonzero(~np.isfinite(phi_arr))
    if bad.size:
        i = int(bad[0])
        raise ConvergenceError(f"{pre}{nphi} must be finite (got {float(phi_arr[i])!r} at {at(i, n)})")
    if n and not math.isfinite(float(np.max(phi_arr)) - float(np.min(phi_arr))):
        raise ConvergenceError(f"{pre}{nphi} differences overflow the float range (got {phi_arr.tolist()})")
    order = np.argsort(h_arr, kind="stable")
    h_sorted, phi_sorted = h_arr[order], phi_arr[order]
    dup = np.flatnonzero(np.diff(h_sorted) == 0.0)
    if dup.size:
        raise ConvergenceError(
            f"{pre}{nh} values must be distinct (got {float(h_sorted[int(dup[0])])!r} more than once)"
        )
    return h_sorted, phi_sorted


def check_safety_factor(safety_factor: float, func: str, name: str | None = None) -> float:
    try:
        fs = float(safety_factor)
    except (TypeError, ValueError):
        fs = math.nan
    if not (math.isfinite(fs) and fs > 0.0):
        label = name if name else f"{func}: 'safety_factor'"
        raise ConvergenceError(f"{label} must be a finite number > 0 (got {safety_factor!r})")
    return fs


def _rel(num: float, den: float) -> float:
    """|num / den| with 0/0 = 0 and x/0 = inf (a relative error against a zero reference)."""
    if num == 0.0:
        return 0.0
    if den == 0.0:
        return math.inf
    return abs(num / den)


def _no_nan(x: float | None) -> float | None:
    """None for NaN (an undefined value), the value otherwise (inf is kept: a relative error against 0)."""
    return None if x is None or math.isnan(x) else x


def _expm1(x: float) -> float:
    """exp(x) - 1 without OverflowError (inf beyond the float range)."""
    return math.expm1(x) if x < _EXP_MAX else math.inf


def _log_rp_minus_s(p: FloatArray, ln_r: float, s: float) -> FloatArray:
    """ln(r^p - s) for p > 0 and s = +-1, in log space so that no r^p is ever formed."""
    x = p * ln_r
    if s > 0:
        return x + np.log(-np.expm1(-x))  # ln(e^x - 1) = x + ln(1 - e^-x)
    return np.logaddexp(x, 0.0)  # ln(e^x + 1)


# --------------------------------------------------------------------------------------------------
# three grids: Celik et al. (2008)
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ThreeGridResult:
    """Outcome of the three-grid procedure of Celik et al. (2008); built by :func:`grid_convergence`.

    Grids are numbered fine (1) to coarse (3). Relative errors and GCI are fractions of the fine-grid value.
    Fields that the data do not define (the order of a divergent triplet, ...) are ``None``; ``note`` says
    why. A relative error against a zero reference is ``inf`` (``None`` in :meth:`to_dict`).

    Attributes
    ----------
    h : Spacings h1 < h2 < h3 [unit of the input, e.g. km].
    phi : Values on those grids, paired with ``h`` [unit of the input, e.g. h].
    r21, r32 : Refinement ratios h2/h1 and h3/h2 [-].
    p : Apparent order of convergence [-], or None.
    phi_ext : Richardson-extrapolated value from grids 1 and 2 [unit of phi], or None.
    e_a : Approximate relative error |(phi1 - phi2) / phi1| [-].
    e_ext : Extrapolated relative error |(phi_ext - phi1) / phi_ext| [-], or None.
    gci_fine : Fine-grid convergence index Fs e_a / (r21^p - 1) [-], or None.
    gci_coarse : Medium-grid index of the coarse pair, Fs e_a32 / (r32^p - 1) with
        e_a32 = |(phi2 - phi3) / phi2| [-], or None.
    asymptotic_ratio : gci_coarse / (r21^p gci_fine) [-]; close to 1 in the asymptotic range; or None.
    convergence : One of :data:`CONVERGENCE_LABELS`.
    convergence_ratio : R = (phi2 - phi1) / (phi3 - phi2) [-] (inf when phi3 == phi2), or None for 0/0.
    safety_factor : Fs used in the GCI [-].
    method : "celik2008".
    note : Why a field is None, or a caution (small refinement ratio, oscillatory data); "" otherwise.
    """

    h: tuple[float, float, float]
    phi: tuple[float, float, float]
    r21: float
    r32: float
    p: float | None
    phi_ext: float | None
    e_a: float
    e_ext: float | None
    gci_fine: float | None
    gci_coarse: float | None
    asymptotic_ratio: float | None
    convergence: str
    convergence_ratio: float | None
    safety_factor: float
    method: str
    note: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every attribute (floats, lists, str; NaN/inf -> None)."""
        return {f.name: _clean(getattr(self, f.name)) for f in fields(self)}


def _apparent_order(r21: float, r32: float, eps21: float, eps32: float) -> tuple[float | None, str]:
    """Solve Celik's eqs. (5a-c) for the apparent order p; (None, reason) when there is no root.

    f(p) = p - |ln|eps32/eps21| + q(p)| / ln r21 with q(p) = ln((r21^p - s) / (r32^p - s)); for s = +1
    the absolute value is dropped (same root for converging data, where the bracket is positive). For
    converging data f(0+) < 0; the smallest root is bracketed by a geometric scan of (1e-9, 1e4] and
    refined with brentq. For r21 == r32, q = 0 and p is closed form.
    """
    s = math.copysign(1.0, eps21) * math.copysign(1.0, eps32)
    ln21, ln32 = math.log(r21), math.log(r32)
    big_l = math.log(abs(eps32)) - math.log(abs(eps21))  # ln|eps32/eps21| without under/overflow
    if math.isclose(r21, r32, rel_tol=1e-12, abs_tol=0.0):
        return abs(big_l) / ln21, ""

    def f(p: FloatArray) -> FloatArray:
        q = _log_rp_minus_s(p, ln21, s) - _log_rp_minus_s(p, ln32, s)
        # s = +1: the signed form, whose positive root is Celik's root whenever the data converge (and
        # which has none when they diverge); s = -1: Celik's absolute value, as in his Table 1.
        return p - (big_l + q if s > 0 else np.abs(big_l + q)) / ln21

    grid = np.geomspace(_P_SCAN_MIN, _P_SCAN_MAX, _P_SCAN_N)
    values = f(grid)
    if values[0] >= 0.0:
        return 0.0, "the apparent-order equation has its root at p = 0"
    positive = np.flatnonzero(values >= 0.0)
    if positive.size == 0:
        return None, (
            f"the apparent-order equation of Celik et al. (2008) has no root for p in (0, {_P_SCAN_MAX:g}] "
            f"(r21 = {r21:.4g}, r32 = {r32:.4g}, ln|eps32/eps21| = {big_l:.4g}, s = {s:+g})"
        )
    i = int(positive[0])
    if values[i] == 0.0:
        return float(grid[i]), ""
    root = brentq(lambda p: float(f(np.array([p]))[0]), grid[i - 1], grid[i], xtol=1e-14, rtol=1e-15)
    return float(root), ""


def grid_convergence(
    h: Sequence[float] | npt.ArrayLike, phi: Sequence[float] | npt.ArrayLike, *, safety_factor: float = 1.25
) -> ThreeGridResult:
    """Three-grid Grid Convergence Index after Celik et al. (2008).

    With grids sorted fine to coarse (h1 < h2 < h3), r21 = h2/h1, r32 = h3/h2, eps21 = phi2 - phi1,
    eps32 = phi3 - phi2 and s = sign(eps32/eps21), the apparent order p solves (Celik eqs. 5a-c)

        p = |ln|eps32/eps21| + q(p)| / ln r21,   q(p) = ln((r21^p - s) / (r32^p - s)),

    found with a bracketing root finder (closed form when r21 == r32). Then (eqs. 6-8)

        phi_ext = (r21^p phi1 - phi2) / (r21^p - 1),
        e_a = |(phi1 - phi2) / phi1|,  e_ext = |(phi_ext - phi1) / phi_ext|,
        GCI_fine = Fs e_a / (r21^p - 1),  GCI_coarse = Fs e_a32 / (r32^p - 1),

    and Roache's asymptotic-range check GCI_coarse / (r21^p GCI_fine) ~ 1. The triplet is labelled by
    R = eps21/eps32: monotonic (0 < R' < 1), oscillatory (R < 0), divergent (R' >= 1, or
    phi3 == phi2 != phi1), where R' = R ln(r32) / ln(r21) equals Celik's R for a constant ratio and, for
    r21 != r32, moves the boundary to where the apparent order reaches 0 (data phi0 + C h^0.3 on
    r21 = 1.5, r32 = 4/3 converge although R = 1.27); converged (phi1 == phi2 == phi3, or both differences at
    round-off level, at most :data:`ROUNDOFF_REL` max |phi|: p None, phi_ext = phi1, errors and GCI 0) or
    indeterminate (phi1 == phi2 != phi3, or 0 < |phi2 - phi1| <= :data:`ROUNDOFF_REL` max |phi| while phi3 differs
    by more: the fine difference at round-off level, p, phi_ext, e_ext and GCI None). An order
    outside :data:`P_PLAUSIBLE` is reported as computed; :meth:`StudyResult.verdict` judges it. For divergent
    triplets, or when the order equation has no positive root, p and everything derived from it are None;
    ``note`` says why.

    Parameters
    ----------
    h : Representative grid spacings of the three grids, any order, distinct, > 0 [any length unit,
        e.g. km]. Only their ratios matter.
    phi : Values on those grids, paired with ``h`` [any unit, e.g. h].
    safety_factor : Fs of the GCI [-]; 1.25 for three-grid studies (Roache; Celik et al. 2008).

    Returns
    -------
    ThreeGridResult
        Errors and GCI as fractions (0.022 = 2.2 %).

    Raises
    ------
    ConvergenceError
        Not exactly three grids, lengths differ, h not finite and > 0, duplicate h, phi not finite, or a
        bad safety factor.

    References
    ----------
    Celik et al. (2008), J. Fluids Eng. 130(7) 078001, doi:10.1115/1.2960953.
    Roache (1994), J. Fluids Eng. 116(3) 405-413, doi:10.1115/1.2910291.

    Examples
    --------
    Manufactured second-order data phi = 10 + 2 h^2 on h = 1, 2, 4 (given coarse first):

    >>> res = grid_convergence([4.0, 2.0, 1.0], [42.0, 18.0, 12.0])
    >>> res.convergence, round(res.p, 9), round(res.phi_ext, 9)
    ('monotonic', 2.0, 10.0)
    >>> round(res.gci_fine, 6)  # 1.25 * (6/12) / (2^2 - 1)
    0.208333
    """
    func = "grid_convergence"
    fs = check_safety_factor(safety_factor, func)
    h_s, phi_s = _validate(h, phi, func=func, n_exact=3)
    h1, h2, h3 = (float(v) for v in h_s)
    phi1, phi2, phi3 = (float(v) for v in phi_s)
    r21, r32 = h2 / h1, h3 / h2
    eps21, eps32 = phi2 - phi1, phi3 - phi2
    if not (math.isfinite(eps21) and math.isfinite(eps32)):
        raise ConvergenceError(f"{func}: 'phi' differences overflow the float range (got {[phi1, phi2, phi3]})")
    e_a = _rel(eps21, phi1)
    notes = _triplet_notes(phi1, phi2, r21, r32)
    tol = ROUNDOFF_REL * max(abs(phi1), abs(phi2), abs(phi3))
    label, ratio_r, lead = _classify_triplet(eps21, eps32, r21, r32, tol)

    def build(note: list[str], **kw: Any) -> ThreeGridResult:
        return ThreeGridResult(
            h=(h1, h2, h3),
            phi=(phi1, phi2, phi3),
            r21=r21,
            r32=r32,
            e_a=e_a,
            safety_factor=fs,
            method="celik2008",
            note="; ".join(note),
            convergence=label,
            convergence_ratio=ratio_r,
            **kw,
        )

    if label == "converged":
        return build(
            [lead, *notes], p=None, phi_ext=phi1, e_ext=0.0, gci_fine=0.0, gci_coarse=0.0, asymptotic_ratio=None
        )
    if label in ("indeterminate", "divergent"):
        return build([lead, *notes], **_UNDEFINED)
    if label == "oscillatory":
        notes.append(f"oscillatory convergence (R = {ratio_r:.4g}): treat the GCI with caution")
    p, why = _apparent_order(r21, r32, eps21, eps32)
    if p is None or p <= 0.0:
        if p is not None:
            why = f"apparent order p = 0 ({why or '|eps32| == |eps21|'}): Richardson extrapolation undefined"
        return build([why, *notes], **(_UNDEFINED | {"p": p}))
    return build(notes, **_richardson(p, r21, r32, phi1, phi2, e_a, _rel(eps32, phi2), fs))


#: The estimates of a triplet whose apparent order is undefined.
_UNDEFINED: MappingProxyType[str, Any] = MappingProxyType(
    dict(p=None, phi_ext=None, e_ext=None, gci_fine=None, gci_coarse=None, asymptotic_ratio=None)
)


def _triplet_notes(phi1: float, phi2: float, r21: float, r32: float) -> list[str]:
    """Cautions about a triplet's data: a zero fine-grid value, a refinement ratio below the recommended one."""
    notes = []
    if phi1 == 0.0 or phi2 == 0.0:
        notes.append(
            "phi is 0 on a fine grid: relative errors and GCI against it are infinite; judge the absolute "
            "differences (or shift phi away from 0)"
        )
    if min(r21, r32) < _R_RECOMMENDED:
        notes.append(
            f"refinement ratio {min(r21, r32):.4g} is below the {_R_RECOMMENDED} recommended by Celik et al. (2008)"
        )
    return notes


def _classify_triplet(
    eps21: float, eps32: float, r21: float, r32: float, tol: float = 0.0
) -> tuple[str, float | None, str]:
    """(label, convergence ratio R, leading note) of a triplet from its differences and refinement ratios.

    ``tol`` is the round-off level of the differences [unit of phi]: a nonzero ``|eps21| <= tol`` is
    "indeterminate". The note is "" for monotonic and oscillatory triplets, and says why the order is undefined
    otherwise.
    """
    if eps21 == 0.0 and eps32 == 0.0:
        return "converged", None, "converged: phi1 == phi2 == phi3, no discretisation change; apparent order undefined"
    if abs(eps21) <= tol and abs(eps32) <= tol:  # as equal as the arithmetic can tell: the same verdict (issue 34)
        return (
            "converged",
            None,
            f"converged: phi1, phi2, phi3 agree to round-off (differences <= {ROUNDOFF_REL:g} of max |phi|), no "
            "discretisation change measurable; apparent order undefined",
        )
    if eps21 == 0.0:
        return "indeterminate", 0.0, "indeterminate: phi1 == phi2 but phi3 differs; apparent order unbounded, no GCI"
    if abs(eps21) <= tol:
        return (
            "indeterminate",
            eps21 / eps32 if eps32 != 0.0 else math.inf,
            f"indeterminate: phi2 - phi1 = {eps21:.3g} is at round-off level (<= {ROUNDOFF_REL:g} of max |phi|); "
            "apparent order meaningless, no GCI",
        )
    ratio_r = eps21 / eps32 if eps32 != 0.0 else math.inf
    same_sign = eps32 != 0.0 and (eps21 > 0.0) == (eps32 > 0.0)
    # monotonic/divergent boundary: the apparent order reaches 0 where R ln(r32) / ln(r21) = 1 (R = 1 when
    # r21 == r32); a converging phi0 + C h^p with small p and r21 > r32 has R > 1 but a scaled R < 1.
    # Compared in logs so that R itself may under/overflow.
    if eps32 == 0.0 or (
        same_sign and math.log(abs(eps21)) - math.log(abs(eps32)) + math.log(math.log(r32) / math.log(r21)) >= 0.0
    ):
        scaled_r = ratio_r * math.log(r32) / math.log(r21)
        return (
            "divergent",
            ratio_r,
            f"divergent: R ln(r32)/ln(r21) = {scaled_r:.4g} >= 1 (R = {ratio_r:.4g}), the change does not "
            "shrink with refinement; apparent order undefined",
        )
    return ("monotonic" if same_sign else "oscillatory"), ratio_r, ""


def _richardson(
    p: float, r21: float, r32: float, phi1: float, phi2: float, e_a: float, e_a32: float, fs: float
) -> dict[str, float | None]:
    """Celik's eqs. 6-8 and Roache's asymptotic ratio for an apparent order p > 0, free of r^p overflow."""
    x21, x32 = p * math.log(r21), p * math.log(r32)
    d21, d32 = _expm1(x21), _expm1(x32)  # r21^p - 1, r32^p - 1
    phi_ext = phi1 + (phi1 - phi2) / d21  # == (r21^p phi1 - phi2) / (r21^p - 1), no r^p overflow
    # gci_coarse / (r21^p gci_fine) = (e_a32 / e_a) (1 - r21^-p) / (r32^p - 1), free of overflow
    asymptotic = (e_a32 / e_a) * (-math.expm1(-x21)) / d32 if 0.0 < e_a < math.inf else None
    # inf/inf or 0*inf (zero reference values with extreme orders) must not leak out as NaN
    return dict(
        p=p,
        phi_ext=_no_nan(phi_ext),
        e_ext=_no_nan(_rel(phi_ext - phi1, phi_ext)),
        gci_fine=_no_nan(fs * e_a / d21),
        gci_coarse=_no_nan(fs * e_a32 / d32),
        asymptotic_ratio=_no_nan(asymptotic),
    )


# --------------------------------------------------------------------------------------------------
# four or more grids: Eça & Hoekstra (2014)
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LeastSquaresResult:
    """Outcome of :func:`least_squares_convergence` (Eça & Hoekstra 2014, simplified; see there).

    Attributes
    ----------
    h : Spacings, fine to coarse [unit of the input].
    phi : Values paired with ``h`` [unit of phi].
    p : Observed order of the power fit phi0 + a h^p [-]; None for "data-range" and "constant".
    phi_ext : phi0 of the chosen fit, the estimate at h = 0 [unit of phi]; None for "data-range".
    fit : Chosen form, one of :data:`LS_FITS`.
    weighting : "weighted" (w_i ~ 1/h_i) or "unweighted"; "none" when no fit was made.
    coefficients : Coefficients of ``fit`` in x = h / h_ref: (phi0, a, p) for "power", (phi0, a) for
        "first"/"second", (phi0, a1, a2) for "first+second", (phi1,) for "constant", () for "data-range".
    h_ref : Normalising spacing h_ref = h1 [unit of h].
    sigma : Standard deviation of the chosen fit [unit of phi]; None for "data-range".
    data_range : Delta_phi = (max phi - min phi) / (n - 1) [unit of phi].
    max_difference : Delta_M = max phi - min phi [unit of phi].
    error_estimate : epsilon_phi = |phi1 - phi0| of the chosen fit, or Delta_M for "data-range"
        [unit of phi].
    safety_factor : Fs [-]: 1.25 when 0.5 <= p < 2.1 and sigma < data_range, else 3.
    uncertainty_abs : U(phi1) [unit of phi].
    uncertainty : U(phi1) / |phi1| [-] (inf when phi1 == 0).
    convergence : "monotonic", "oscillatory" (differences change sign or vanish) or "converged".
    method : "eca-hoekstra2014".
    note : Which branch of the procedure was taken and why.
    """

    h: tuple[float, ...]
    phi: tuple[float, ...]
    p: float | None
    phi_ext: float | None
    fit: str
    weighting: str
    coefficients: tuple[float, ...]
    h_ref: float
    sigma: float | None
    data_range: float
    max_difference: float
    error_estimate: float
    safety_factor: float
    uncertainty_abs: float
    uncertainty: float
    convergence: str
    method: str
    note: str

    def predict(self, h: npt.ArrayLike) -> FloatArray:
        """Evaluate the chosen fit at spacings ``h`` [unit of h] -> [unit of phi]; NaN for "data-range"."""
        x = np.asarray(h, dtype=float) / self.h_ref
        c = self.coefficients
        if self.fit == "power":
            return c[0] + c[1] * x ** c[2]
        if self.fit == "first":
            return c[0] + c[1] * x
        if self.fit == "second":
            return c[0] + c[1] * x**2
        if self.fit == "first+second":
            return c[0] + c[1] * x + c[2] * x**2
        if self.fit == "constant":
            return np.full_like(x, c[0])
        return np.full_like(x, np.nan)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every attribute (floats, lists, str; NaN/inf -> None)."""
        return {f.name: _clean(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True)
class _Fit:
    form: str
    coefficients: tuple[float, ...]
    fitted: FloatArray
    sigma: float


def _linear_fit(form: str, x: FloatArray, phi: FloatArray, w: FloatArray) -> _Fit:
    """Weighted least squares of a form that is linear in its coefficients."""
    columns = {"first": (x,), "second": (x**2,), "first+second": (x, x**2)}[form]
    a = np.column_stack((np.ones_like(x), *columns))
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(a * sw[:, None], phi * sw, rcond=None)
    fitted = a @ coef
    return _Fit(form, tuple(float(c) for c in coef), fitted, _sigma(phi, fitted, w, a.shape[1]))


def _sigma(phi: FloatArray, fitted: FloatArray, w: FloatArray, n_par: int) -> float:
    """Standard deviation of a fit: sqrt(n sum w_i r_i^2 / (n - n_par)), weights summing to 1."""
    n = phi.size
    return float(math.sqrt(n * float(np.sum(w * (phi - fitted) ** 2)) / (n - n_par)))


def _power_sse(p: FloatArray, x: FloatArray, phi: FloatArray, w: FloatArray) -> tuple[FloatArray, ...]:
    """Weighted sum of squared residuals of phi0 + a x^p for every p (closed-form 2-parameter LS)."""
    xp = x[None, :] ** p[:, None]  # (P, n)
    xm = np.sum(w * xp, axis=1, keepdims=True)
    pm = float(np.sum(w * phi))
    dx = xp - xm
    a = np.sum(w * dx * (phi - pm), axis=1) / np.sum(w * dx * dx, axis=1)
    phi0 = pm - a * xm[:, 0]
    resid = phi[None, :] - phi0[:, None] - a[:, None] * xp
    return np.sum(w * resid * resid, axis=1), phi0, a


def _power_fit(x: FloatArray, phi: FloatArray, w: FloatArray, p_lo: float, p_hi: float) -> _Fit:
    """phi0 + a x^p with p by a grid scan then a bounded 1-D minimisation of the residual."""
    grid = np.linspace(p_lo, p_hi, 401)
    sse, _, _ = _power_sse(grid, x, phi, w)
    i = int(np.argmin(sse))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best_p, best_sse = float(grid[i]), float(sse[i])
    res = minimize_scalar(
        lambda p: float(_power_sse(np.array([p]), x, phi, w)[0][0]),
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 1e-12},
    )
    if float(res.fun) < best_sse:
        best_p = float(res.x)
    _, phi0, a = _power_sse(np.array([best_p]), x, phi, w)
    fitted = phi0[0] + a[0] * x**best_p
    return _Fit("power", (float(phi0[0]), float(a[0]), best_p), fitted, _sigma(phi, fitted, w, 3))


def _select_fit(x: FloatArray, phi: FloatArray, w: FloatArray, p_lo: float, p_hi: float) -> tuple[_Fit, float, str]:
    """Power fit, then the paper's alternatives when its p is outside [0.5, 2]; returns (fit, p, note)."""
    power = _power_fit(x, phi, w, p_lo, p_hi)
    p = power.coefficients[2]
    if 0.5 <= p <= 2.0:
        return power, p, f"power fit, observed order p = {p:.4g}"
    forms = ("second", "first+second") if p > 2.0 else ("first", "second", "first+second")
    candidates = [_linear_fit(form, x, phi, w) for form in forms]
    best = min(candidates, key=lambda c: c.sigma)
    why = "p > 2" if p > 2.0 else "p < 0.5"
    return best, p, f"observed order p = {p:.4g} ({why}): error from the {best.form} fit (smallest sigma)"


def least_squares_convergence(
    h: Sequence[float] | npt.ArrayLike,
    phi: Sequence[float] | npt.ArrayLike,
    *,
    weighting: str = "auto",
    p_bounds: tuple[float, float] = _LS_P_BOUNDS,
) -> LeastSquaresResult:
    """Least-squares grid-convergence uncertainty for four or more grids, after Eça & Hoekstra (2014).

    Procedure (x = h / h1, grids sorted fine -> coarse, weights w_i = (1/h_i) / sum(1/h_j) or 1/n):

    1. Fit phi = phi0 + a x^p by (weighted) least squares, p by a grid scan over ``p_bounds`` refined with
       a bounded 1-D minimisation of the residual; sigma = sqrt(n sum w_i r_i^2 / (n - 3)).
    2. If 0.5 <= p <= 2 keep that fit. If p > 2 use the better (smaller sigma) of phi0 + a x^2 and
       phi0 + a1 x + a2 x^2; if p < 0.5 the best of phi0 + a x, phi0 + a x^2, phi0 + a1 x + a2 x^2
       (two-parameter fits use n - 2 degrees of freedom in sigma).
    3. With ``weighting="auto"`` steps 1-2 run weighted and unweighted; the result with the smaller sigma
       of its chosen fit wins.
    4. Error estimate epsilon = |phi1 - phi0|; data range Delta_phi = (max phi - min phi) / (n - 1);
       Fs = 1.25 if 0.5 <= p < 2.1 and sigma < Delta_phi, else 3 (p is the observed order of step 1).
    5. U = Fs epsilon + sigma + |phi1 - fit(h1)| if sigma < Delta_phi, else
       U = 3 sigma / Delta_phi (epsilon + sigma + |phi1 - fit(h1)|).
    6. Oscillatory or anomalous data (consecutive differences change sign or vanish): no fit, U = 3 Delta_M
       with Delta_M = max phi - min phi ("data-range"). All values equal: U = 0 ("constant").

    Simplifications relative to the paper: (a) the anomalous-behaviour branch is triggered by any change
    of sign (or zero) in the consecutive differences rather than by the paper's inspection of the fits, so
    oscillating data always get the conservative 3 Delta_M; (b) the paper's fixed-order fit phi0 + a h
    is not used when p > 2; (c) Fs uses the observed p of the power fit even when an alternative fit
    supplies the error; (d) p is searched only inside ``p_bounds`` (a fit at a bound is reported as such
    in ``note``); (e) the uncertainty is given for the finest grid only.

    Parameters
    ----------
    h : Representative grid spacings, at least four, any order, distinct, > 0 [any length unit, e.g. km].
    phi : Values paired with ``h`` [any unit, e.g. h].
    weighting : One of :data:`LS_WEIGHTINGS`.
    p_bounds : (lower, upper) bounds of the observed order in the power fit [-], 0 < lower < upper.

    Returns
    -------
    LeastSquaresResult
        ``uncertainty`` is U(phi1) / |phi1| (a fraction); ``uncertainty_abs`` is U in the unit of phi.

    Raises
    ------
    ConvergenceError
        Fewer than four grids, lengths differ, h not finite and > 0, duplicate h, phi not finite, an
        unknown weighting or bad bounds.

    References
    ----------
    Eça and Hoekstra (2014), J. Comput. Phys. 262, 104-130, doi:10.1016/j.jcp.2013.12.029.

    Examples
    --------
    >>> h = [1.0, 1.5, 2.0, 3.0]
    >>> res = least_squares_convergence(h, [5.0 + 0.5 * v**1.5 for v in h])
    >>> res.fit, round(res.p, 6), round(res.phi_ext, 6), res.safety_factor
    ('power', 1.5, 5.0, 1.25)
    """
    func = "least_squares_convergence"
    p_lo, p_hi = _check_ls_options(weighting, p_bounds, func)
    h_s, phi_s = _validate(h, phi, func=func, n_min=4)
    n = h_s.size
    phi1 = float(phi_s[0])
    h_ref = float(h_s[0])
    x = h_s / h_ref
    # keep x^p and its square finite: x_max^p_hi <= e^230 ~ 1e100
    p_hi = min(p_hi, 230.0 / math.log(float(x[-1])))
    if p_hi <= p_lo:
        raise ConvergenceError(f"{func}: spacing ratio {x[-1]:.3g} too large for p_bounds {p_bounds!r}")
    delta_m = float(np.max(phi_s) - np.min(phi_s))
    if not math.isfinite(delta_m):
        raise ConvergenceError(f"{func}: 'phi' differences overflow the float range (got {phi_s.tolist()})")
    delta_phi = delta_m / (n - 1)
    common: dict[str, Any] = dict(
        h=tuple(float(v) for v in h_s),
        phi=tuple(float(v) for v in phi_s),
        h_ref=h_ref,
        data_range=delta_phi,
        max_difference=delta_m,
        method="eca-hoekstra2014",
    )
    roundoff = ROUNDOFF_REL * float(np.max(np.abs(phi_s)))
    without_fit = _without_fit(phi1, delta_m, np.diff(phi_s), common, roundoff)
    if without_fit is not None:
        return without_fit
    fit, p, chosen, note = _best_fit(x, h_s, phi_s, weighting, p_lo, p_hi)
    phi0 = fit.coefficients[0]
    eps = abs(phi1 - phi0)
    sigma = fit.sigma
    good = 0.5 <= p < 2.1 and sigma < delta_phi
    fs = 1.25 if good else 3.0
    misfit = abs(phi1 - float(fit.fitted[0]))
    if sigma < delta_phi:
        u_abs = fs * eps + sigma + misfit
    else:
        u_abs = 3.0 * sigma / delta_phi * (eps + sigma + misfit)
        note += "; sigma >= Delta_phi: U = 3 sigma / Delta_phi (eps + sigma + |phi1 - fit1|)"
    return LeastSquaresResult(
        p=p,
        phi_ext=phi0,
        fit=fit.form,
        weighting=chosen,
        coefficients=fit.coefficients,
        sigma=sigma,
        error_estimate=eps,
        safety_factor=fs,
        uncertainty_abs=u_abs,
        uncertainty=_rel(u_abs, phi1),
        convergence="monotonic",
        note=note,
        **common,
    )


def _check_ls_options(weighting: str, p_bounds: tuple[float, float], func: str) -> tuple[float, float]:
    """Refuse an unknown weighting or bad bounds of the observed order; (lower, upper) as floats."""
    if weighting not in LS_WEIGHTINGS:
        raise ConvergenceError(f"{func}: 'weighting' must be one of {list(LS_WEIGHTINGS)} (got {weighting!r})")
    try:
        p_lo, p_hi = (float(v) for v in p_bounds)
    except (TypeError, ValueError):
        raise ConvergenceError(f"{func}: 'p_bounds' must be two numbers (got {p_bounds!r})") from None
    if not (math.isfinite(p_lo) and math.isfinite(p_hi) and 0.0 < p_lo < p_hi):
        raise ConvergenceError(f"{func}: 'p_bounds' must satisfy 0 < lower < upper (got {p_bounds!r})")
    return p_lo, p_hi


def _without_fit(
    phi1: float, delta_m: float, diffs: FloatArray, common: dict[str, Any], roundoff: float = 0.0
) -> LeastSquaresResult | None:
    """The results made without a fit (step 6): all values equal (to round-off, ``roundoff`` [unit of phi]), or
    oscillatory/anomalous data; else None."""
    if delta_m <= roundoff:
        return LeastSquaresResult(
            p=None,
            phi_ext=phi1,
            fit="constant",
            weighting="none",
            coefficients=(phi1,),
            sigma=0.0,
            error_estimate=0.0,
            safety_factor=1.25,
            uncertainty_abs=0.0,
            uncertainty=0.0,
            convergence="converged",
            note="all values equal"
            + ("" if delta_m == 0.0 else f" to round-off (spread {delta_m:.3g} <= {ROUNDOFF_REL:g} of max |phi|)")
            + ": no discretisation change",
            **common,
        )
    if not (np.all(diffs > 0.0) or np.all(diffs < 0.0)):
        u_abs = 3.0 * delta_m
        return LeastSquaresResult(
            p=None,
            phi_ext=None,
            fit="data-range",
            weighting="none",
            coefficients=(),
            sigma=None,
            error_estimate=delta_m,
            safety_factor=3.0,
            uncertainty_abs=u_abs,
            uncertainty=_rel(u_abs, phi1),
            convergence="oscillatory",
            note="oscillatory/anomalous data (consecutive differences change sign or vanish): U = 3 Delta_M",
            **common,
        )
    return None


def _best_fit(
    x: FloatArray, h_s: FloatArray, phi_s: FloatArray, weighting: str, p_lo: float, p_hi: float
) -> tuple[_Fit, float, str, str]:
    """Steps 1-3: the chosen fit in the unit of phi, the power fit's observed order, the weighting chosen, a note."""
    n = h_s.size
    phi1 = float(phi_s[0])
    delta_m = float(np.max(phi_s) - np.min(phi_s))
    weight_sets = {"unweighted": np.full(n, 1.0 / n), "weighted": (1.0 / h_s) / np.sum(1.0 / h_s)}
    names = ("unweighted", "weighted") if weighting == "auto" else (weighting,)
    # fit z = (phi - phi1) / Delta_M in [-1, 1]: scale-free and safe from overflow; mapped back below
    z = (phi_s - phi1) / delta_m
    outcomes = {name: _select_fit(x, z, weight_sets[name], p_lo, p_hi) for name in names}
    chosen = min(names, key=lambda name: outcomes[name][0].sigma)
    zfit, p, note = outcomes[chosen]
    coef = (phi1 + delta_m * zfit.coefficients[0], *(delta_m * c for c in zfit.coefficients[1:]))
    if zfit.form == "power":
        coef = (*coef[:2], zfit.coefficients[2])  # the order is not scaled
    fit = _Fit(zfit.form, tuple(float(c) for c in coef), phi1 + delta_m * zfit.fitted, delta_m * zfit.sigma)
    if p <= p_lo * (1 + 1e-9) or p >= p_hi * (1 - 1e-9):
        note += f"; the power fit stopped at a bound of p_bounds ({p_lo:g}, {p_hi:g})"
    return fit, p, chosen, note


# --------------------------------------------------------------------------------------------------
# study
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class StudyResult:
    """A grid-convergence study; built by :func:`convergence_study`.

    Attributes
    ----------
    h : Spacings, fine to coarse [unit of the input].
    phi : Values paired with ``h`` [unit of phi].
    triplets : Three-grid results of grids (1, 2, 3), (2, 3, 4), ... (fine to coarse).
    least_squares : Least-squares result for four or more grids, else None.
    """

    h: tuple[float, ...]
    phi: tuple[float, ...]
    triplets: tuple[ThreeGridResult, ...]
    least_squares: LeastSquaresResult | None

    @property
    def finest(self) -> ThreeGridResult:
        """The three-grid result of the three finest grids."""
        return self.triplets[0]

    def verdict(self) -> tuple[str, str]:
        """("converging", "") when the finest triplet's estimates can be trusted, else ("indeterminate", reason).

        Indeterminate: the finest triplet is not monotonic or oscillatory with an order (its label and note say
        why: divergent, round-off level differences, ...), or its observed order lies outside
        :data:`P_PLAUSIBLE` (0.5 to 8; see there for the reason). A converged triplet (phi1 == phi2 == phi3
        exactly) is "converged". Gates that require convergence fail unless the verdict is "converging" or
        "converged".

        >>> convergence_study([1.0, 2.0, 4.0], [700.0, 700.000000000001, 703.0]).verdict()[0]
        'indeterminate'
        """
        fin = self.finest
        if fin.convergence == "converged":
            return "converged", ""
        if fin.convergence not in ("monotonic", "oscillatory") or fin.p is None or fin.p <= 0.0:
            return "indeterminate", f"finest triplet {fin.note or fin.convergence}"
        lo, hi = P_PLAUSIBLE
        if not lo <= fin.p <= hi:
            return "indeterminate", (
                f"observed order p = {fin.p:.4g} on the finest triplet is outside the plausible {lo:g} to {hi:g} "
                "(formal orders 1 to 2 of the route's discretisation): a coincidence of the values, not convergence"
            )
        return "converging", ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: h, phi, finest, triplets, least_squares (None with three grids), verdict and its
        reason (:meth:`verdict`)."""
        verdict, why = self.verdict()
        return {
            "verdict": verdict,
            "verdict_reason": why,
            "h": _clean(self.h),
            "phi": _clean(self.phi),
            "finest": self.finest.to_dict(),
            "triplets": [t.to_dict() for t in self.triplets],
            "least_squares": None if self.least_squares is None else self.least_squares.to_dict(),
        }

    def report(self) -> str:
        """Readable text table of the study (errors, GCI and U in percent of the fine-grid value)."""
        lines = [f"Grid convergence study: {len(self.h)} grids (1 = finest)", ""]
        lines.append(f"{'grid':>4}  {'h':>14}  {'phi':>16}")
        for i, (hv, pv) in enumerate(zip(self.h, self.phi, strict=True), start=1):
            lines.append(f"{i:>4}  {hv:>14.6g}  {pv:>16.8g}")
        lines += ["", "Three-grid GCI (Celik et al. 2008, doi:10.1115/1.2960953); e_a, e_ext, GCI in %:"]
        head = (
            f"{'grids':>7}  {'r21':>6}  {'r32':>6}  {'p':>7}  {'phi_ext':>14}  {'e_a%':>8}  "
            f"{'e_ext%':>8}  {'GCI21%':>8}  {'GCI32%':>8}  {'AR':>7}  convergence"
        )
        lines.append(head)
        for k, t in enumerate(self.triplets, start=1):
            lines.append(
                f"{f'{k}-{k + 1}-{k + 2}':>7}  {t.r21:>6.3f}  {t.r32:>6.3f}  {_fmt(t.p, '.4f'):>7}  "
                f"{_fmt(t.phi_ext, '.8g'):>14}  {_pct(t.e_a):>8}  {_pct(t.e_ext):>8}  "
                f"{_pct(t.gci_fine):>8}  {_pct(t.gci_coarse):>8}  {_fmt(t.asymptotic_ratio, '.4f'):>7}  "
                f"{t.convergence}"
            )
        notes = [(k, t.note) for k, t in enumerate(self.triplets, start=1) if t.note]
        for k, note in notes:
            lines.append(f"  note {k}-{k + 1}-{k + 2}: {note}")
        ls = self.least_squares
        if ls is not None:
            lines += [
                "",
                "Least squares (Eca & Hoekstra 2014, doi:10.1016/j.jcp.2013.12.029):",
                f"  fit = {ls.fit} ({ls.weighting}), p = {_fmt(ls.p, '.4f')}, "
                f"phi_ext = {_fmt(ls.phi_ext, '.8g')}, sigma = {_fmt(ls.sigma, '.4g')}, "
                f"Fs = {ls.safety_factor:g}",
                f"  U(phi1) = {_fmt(ls.uncertainty_abs, '.4g')} = {_pct(ls.uncertainty)} % of phi1 ({ls.convergence})",
                f"  note: {ls.note}",
            ]
        verdict, why = self.verdict()
        if verdict == "indeterminate":
            lines += ["", f"verdict: indeterminate ({why})"]
        return "\n".join(lines)


def convergence_study(
    h: Sequence[float] | npt.ArrayLike,
    phi: Sequence[float] | npt.ArrayLike,
    *,
    safety_factor: float = 1.25,
    names: tuple[str, str, str] | None = None,
) -> StudyResult:
    """Grid-convergence study: Celik's three-grid GCI on every consecutive triplet, least squares for 4+.

    Parameters
    ----------
    h : Representative grid spacings, at least three, any order, distinct, > 0 [any length unit, e.g. km].
    phi : Values paired with ``h`` [any unit, e.g. h].
    safety_factor : Fs of the three-grid GCI [-] (the least-squares procedure picks its own, 1.25 or 3).
    names : What error messages call ``h``, ``phi`` and ``safety_factor``, e.g. the CLI options
        ``("--h", "--phi", "--safety-factor")``; default: the parameter names after ``convergence_study:``.

    Returns
    -------
    StudyResult
        ``triplets[k]`` uses grids k+1, k+2, k+3 counted from the finest; ``finest`` is ``triplets[0]``;
        ``least_squares`` is None with exactly three grids.

    Raises
    ------
    ConvergenceError
        Fewer than three grids or any input rejected by :func:`grid_convergence`.

    References
    ----------
    Celik et al. (2008), doi:10.1115/1.2960953; Eça and Hoekstra (2014), doi:10.1016/j.jcp.2013.12.029.

    Examples
    --------
    >>> study = convergence_study([8.0, 1.0, 4.0, 2.0], [138.0, 12.0, 42.0, 18.0])  # 10 + 2 h^2
    >>> len(study.triplets), round(study.finest.p, 9), study.least_squares.fit
    (2, 2.0, 'power')
    """
    func = "convergence_study"
    fs = check_safety_factor(safety_factor, func, None if names is None else names[2])
    h_s, phi_s = _validate(h, phi, func=func, n_min=3, names=None if names is None else (names[0], names[1]))
    triplets = tuple(grid_convergence(h_s[k : k + 3], phi_s[k : k + 3], safety_factor=fs) for k in range(h_s.size - 2))
    ls = least_squares_convergence(h_s, phi_s) if h_s.size >= 4 else None
    return StudyResult(
        h=tuple(float(v) for v in h_s),
        phi=tuple(float(v) for v in phi_s),
        triplets=triplets,
        least_squares=ls,
    )
