"""Plain limits: "no more than 35 kn of wind, 5 m of waves, nothing closer than 40 deg to the wind" as a failure model.

A designer who has hard limits rather than a network writes them in the scenario::

    [failure]
    limits = { tws_kn_max = 35, hs_m_max = 5, twa_deg_min = 40 }

Each key is a quantity of :data:`~pyroute_rel.reliability.failure.QUANTITIES` and ``_max`` (the craft fails above
the value: ``tws_kn_max = 35`` fails at 35.1 kn, not at 35) or ``_min`` (it fails below it: ``twa_deg_min = 40`` is
a no-go zone of 40 deg each side of the wind). They compile to an ordinary failure model (:func:`limits_model`): one
two-state node per limit (``false``, ``true``: the limit is broken), a target ``F`` that fails for certain when any
limit is broken and never otherwise (a deterministic OR), each node a prior of 0.5 (it matters only to a quantity
left unobserved, which a limit never is: a missing quantity forbids the arc as missing weather). Every command then
treats it as it treats a network: arcs that break a limit have ``p_f`` 1 and any ``apf`` below 1 forbids them; the
exposure counts the hours spent beyond each limit, and the voyage ``p_f`` is 1 once any is.

:func:`limits_files` gives the TOML and the BIF network the limits stand for: written out, they are a model file
like any other, a start for a designer who wants probabilities rather than hard limits.

Where other tools anchor the same idea: OpenCPN's weather routing plug-in has per-boat constraints (maximum true wind,
maximum swell, "max latitude", "no upwind below ... deg") that cut a route the same way; PredictWind's comfort limits
cap the wind and waves a route may meet.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pyroute_rel.errors import FailureModelError, brief
from pyroute_rel.reliability.failure import (
    QUANTITIES,
    QUANTITY_RANGES,
    QUANTITY_UNITS,
    FailureModel,
    model_from_bytes,
    parse_model_toml,
)

__all__ = ["LIMIT_KEYS", "limits_files", "limits_model", "check_limits"]

#: The keys of ``[failure].limits``: each quantity's ``_max`` (fails above) and ``_min`` (fails below), and the
#: comparison that breaks it.
LIMIT_KEYS: dict[str, tuple[str, str]] = {
    f"{q}_{end}": (q, ">" if end == "max" else "<") for q in QUANTITIES for end in ("max", "min")
}

_NAMES = {"tws_kn": "TWS", "twa_deg": "TWA", "hs_m": "Hs", "awd_deg": "AWD", "wave_period_s": "Tp"}


def check_limits(raw: Any, where: str) -> tuple[tuple[str, float], ...]:
    """``[failure].limits`` checked: a table of :data:`LIMIT_KEYS` to finite numbers within each quantity's range
    (angles in [0, 180] deg), a quantity's ``_min`` below its ``_max``; returned as ``(key, value)`` pairs in the
    table's order.

    >>> check_limits({"tws_kn_max": 35, "twa_deg_min": 40}, "[failure].limits")
    (('tws_kn_max', 35.0), ('twa_deg_min', 40.0))
    """
    if not isinstance(raw, Mapping) or not raw:
        raise FailureModelError(
            f"{where} must be a table of limits such as {{ tws_kn_max = 35, hs_m_max = 5, twa_deg_min = 40 }} "
            f"(got {brief(raw)})"
        )
    out: dict[str, float] = {}
    for key, value in raw.items():
        if key not in LIMIT_KEYS:
            raise FailureModelError(f"{where}: unknown limit {key!r}; expected one of {sorted(LIMIT_KEYS)}")
        quantity = LIMIT_KEYS[key][0]
        lo, hi = QUANTITY_RANGES[quantity]
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise FailureModelError(
                f"{where}.{key} must be a finite number [{QUANTITY_UNITS[quantity]}] (got {brief(value)})"
            )
        if not lo <= value <= hi:
            span = f"[{lo:g}, {hi:g}]" if math.isfinite(hi) else f">= {lo:g}"
            raise FailureModelError(f"{where}.{key} must be {span} [{QUANTITY_UNITS[quantity]}] (got {value:g})")
        out[key] = float(value)
    for q in QUANTITIES:
        lo_v, hi_v = out.get(f"{q}_min"), out.get(f"{q}_max")
        if lo_v is not None and hi_v is not None and lo_v >= hi_v:
            raise FailureModelError(
                f"{where}: {q}_min ({lo_v:g}) must be below {q}_max ({hi_v:g}), or every condition breaks a limit"
            )
    return tuple(out.items())  # in the file's order: the model's criteria follow it


def _describe(key: str, value: float) -> str:
    quantity, op = LIMIT_KEYS[key]
    return f"{_NAMES[quantity]} {op} {value:g} {QUANTITY_UNITS[quantity]}"


def limits_files(
    limits: Mapping[str, float] | tuple[tuple[str, float], ...], *, name: str = "limits"
) -> tuple[str, str]:
    """The failure model's TOML text and its BIF network that plain limits stand for (see the module notes).

    Parameters
    ----------
    limits : The limits (:func:`check_limits`'s pairs, or a mapping of them).
    name : The model's name; the TOML names the network ``{name}.bif``.

    Returns
    -------
    (TOML text, BIF text).
    """
    pairs = tuple(limits.items()) if isinstance(limits, Mapping) else tuple(limits)
    nodes = [key.upper() for key, _ in pairs]
    said = ", ".join(_describe(k, v) for k, v in pairs)
    toml = [
        f'name = "{name}"',
        f'description = "plain limits: the craft fails for certain when {said}; never otherwise"',
        f'network = "{name}.bif"',
        "",
        "[target]",
        'node = "F"',
        'state = "fail"',
    ]
    for (key, value), node in zip(pairs, nodes, strict=True):
        quantity, op = LIMIT_KEYS[key]
        toml += ["", "[[criteria]]", f'node = "{node}"', f'quantity = "{quantity}"', f'operator = "{op}"',
                 f"threshold = {value!r}", 'fired = "true"']  # fmt: skip
    bif = [f"// Plain limits ({said}): F fails when any limit is broken.", f"network {name} {{", "}"]
    for node in [*nodes, "F"]:
        states = "pass, fail" if node == "F" else "false, true"
        bif += [f"variable {node} {{", f"  type discrete [ 2 ] {{ {states} }};", "}"]
    for node in nodes:
        bif += [f"probability ( {node} ) {{", "  table 0.5, 0.5;", "}"]
    bif.append(f"probability ( F | {', '.join(nodes)} ) {{")
    for i in range(2 ** len(nodes)):
        broken = [(i >> (len(nodes) - 1 - j)) & 1 for j in range(len(nodes))]
        fails = any(broken)
        given = ", ".join("true" if b else "false" for b in broken)
        bif.append(f"  ({given}) {0.0 if fails else 1.0}, {1.0 if fails else 0.0};")
    bif.append("}")
    return "\n".join(toml) + "\n", "\n".join(bif) + "\n"


def limits_model(
    limits: Mapping[str, Any] | tuple[tuple[str, float], ...], *, where: str = "[failure].limits"
) -> FailureModel:
    """Plain limits compiled to a :class:`~pyroute_rel.reliability.failure.FailureModel` (see the module notes):
    the model of :func:`limits_files`, its table kept by content as any model's.

    Parameters
    ----------
    limits : ``[failure].limits`` as read from the file, or :func:`check_limits`'s pairs.
    where : Names the limits in messages and as the model's path (e.g. ``"race.toml: [failure].limits"``).

    >>> m = limits_model({"tws_kn_max": 35, "twa_deg_min": 40})
    >>> [c.describe() for c in m.criteria], m.table.tolist()
    (['TWS_KN_MAX: tws_kn > 35 kn', 'TWA_DEG_MIN: twa_deg < 40 deg'], [[0.0, 1.0], [1.0, 1.0]])
    """
    pairs = check_limits(dict(limits) if not isinstance(limits, Mapping) else limits, where)
    toml_text, bif_text = limits_files(pairs)
    toml_bytes, net_bytes = toml_text.encode(), bif_text.encode()
    spec = parse_model_toml(toml_bytes, where, default_name="limits")
    return model_from_bytes(toml_bytes, net_bytes, spec, path=where, net_label=f"{where}: limits.bif")
