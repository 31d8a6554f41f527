"""Failure models: criteria on weather quantities, a Bayesian belief network, a compiled lookup table.

A failure model is data, not code (see ``failure_models/README.md``): a TOML file names the network (a
file in one of :data:`NETWORK_FORMATS`: BIF, XMLBIF, GeNIe ``.xdsl`` or Hugin ``.net``), the target node
and its failure state, and the *criteria* that turn environmental quantities (:data:`QUANTITIES`) into
the states of evidence nodes, by a threshold (two-state node) or by bin edges (multi-state node).

The network is compiled once: pgmpy's variable elimination gives the joint distribution of the target
and the criteria nodes, from which ``P(target = fail | evidence)`` follows for every combination of
evidence states (and for every subset left unobserved, used when a quantity is missing and its
criterion says ``if_missing = "prior"``). The table is cached in memory and on disk, keyed by a hash of
the model files and the pgmpy version, so later runs do not import pgmpy at all. The shipped models' tables
come compiled with the package (``failure_models/compiled_tables.json``, keyed by a hash of the model files'
bytes and checked against pgmpy by the tests), so even a first run of a shipped model skips pgmpy (about 5 s
and 300 MB). Routing only gathers from the table (:meth:`FailureModel.p_fail`), never queries the network per
arc.

What a probability means: ``P(target = fail | evidence)`` is the probability of failure over a reference exposure
``exposure_h`` [h] spent in those conditions (a field of the model file, default :data:`DEFAULT_EXPOSURE_H`). The
``apf`` constraint compares it as it stands (``p_f > apf`` forbids an arc, whatever its duration); the voyage's
failure probability adds up exposure (:mod:`pyroute_rel.reliability.exposure`).

Missing values: a NaN quantity is never read as "criterion not met". By default (``if_missing = "nan"``)
the probability of failure is NaN there, and the cost module forbids the arc as missing weather. A
criterion may instead name a state to assume, or ``"prior"`` to leave its node unobserved.

References
----------
Dickson, T., Blake, J. and Sear, D. (2018). Reliability informed routing for Autonomous Sailing Craft.
Proc. International Robotic Sailing Conference 2018, section 2.1, Figure 1, Table 1 and Algorithm 1.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import io
import itertools
import json
import math
import numbers
import os
import re
import tomllib
import warnings
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pyroute_rel import diskcache, geodesy
from pyroute_rel.errors import FailureModelError, brief, check_flag, check_instance, check_numbers
from pyroute_rel.files import brief_path, read_regular_bytes
from pyroute_rel.resources import check_budget, table_estimate
from pyroute_rel.store import Shelf, current_store, file_stamps

if TYPE_CHECKING:
    from pyroute_rel.weather.base import Conditions

__all__ = [
    "QUANTITIES",
    "QUANTITY_RANGES",
    "QUANTITY_UNITS",
    "model_from_bytes",
    "parse_model_toml",
    "QUANTITY_FIELDS",
    "OPERATORS",
    "CLOSED_SIDES",
    "MISSING_RULES",
    "NETWORK_FORMATS",
    "DEFAULT_EXPOSURE_H",
    "Criterion",
    "FailureModel",
    "load_failure_model",
    "list_failure_models",
    "build_network",
    "model_files",
    "check_exposure_h",
]

#: Quantities a criterion may test (the cost module passes arrays of these names, of one shape).
QUANTITIES: dict[str, str] = {
    "hs_m": "significant wave height [m]",
    "awd_deg": "apparent wave direction [deg] in [0, 180], 0 = head seas (waves from dead ahead)",
    "tws_kn": "true wind speed [kn]",
    "twa_deg": "true wind angle [deg] in [0, 180], 0 = wind from dead ahead",
    "wave_period_s": "wave period [s] (NaN when the weather lacks it)",
}
#: The weather field (of :class:`~pyroute_rel.weather.Conditions`) each quantity is computed from, and whether it is
#: that field's angle to the craft's heading (folded to [0, 180] deg) rather than the field itself. The one map from
#: failure quantities to weather fields: the cost function computes quantities with it
#: (:func:`arc_quantities`) and :attr:`FailureModel.fields` tells which fields a model needs.
QUANTITY_FIELDS: dict[str, tuple[str, bool]] = {
    "hs_m": ("hs_m", False),
    "awd_deg": ("wave_dir_deg", True),
    "tws_kn": ("tws_kn", False),
    "twa_deg": ("twd_deg", True),
    "wave_period_s": ("wave_period_s", False),
}
#: Physical range of each quantity [its unit] (angles folded to [0, 180] as the cost module computes them).
QUANTITY_RANGES = {
    "hs_m": (0.0, math.inf),
    "awd_deg": (0.0, 180.0),
    "tws_kn": (0.0, math.inf),
    "twa_deg": (0.0, 180.0),
    "wave_period_s": (0.0, math.inf),
}
#: The unit of each quantity, as messages and descriptions write it.
QUANTITY_UNITS = {"hs_m": "m", "awd_deg": "deg", "tws_kn": "kn", "twa_deg": "deg", "wave_period_s": "s"}

#: Comparison operators of a two-state (threshold) criterion.
OPERATORS = (">=", ">", "<=", "<")
#: Which end of each bin is closed: "left" means [e_i, e_i+1), "right" means (e_i, e_i+1].
CLOSED_SIDES = ("left", "right")
#: Rules for a NaN quantity (besides naming a state of the node to assume).
MISSING_RULES = ("nan", "prior")
#: Network file formats by extension: pgmpy reader and the tools that write them.
NETWORK_FORMATS: dict[str, tuple[str, str]] = {
    ".bif": ("BIFReader", "Interchange Format BIF (pgmpy; R bnlearn read.bif/write.bif)"),
    ".xmlbif": ("XMLBIFReader", "XML BIF 0.3 (pgmpy; JavaBayes, Weka)"),
    ".xdsl": ("XDSLReader", "GeNIe / SMILE"),
    ".net": ("NETReader", "Hugin (R bnlearn read.net)"),
}

#: The reference exposure [h] of a model that does not set ``exposure_h``: the duration of one leg of the paper's own
#: grid (Dickson et al. 2018 apply P(fail) once per arc; on their 160 x 160 grid of the verification course an arc
#: takes 703.9 h / 161 legs = 4.37 h), so a model written for the paper's per-arc reading keeps it.
DEFAULT_EXPOSURE_H = 4.4

_MODEL_KEYS = ("name", "description", "network", "references", "exposure_h", "target", "criteria")
_TARGET_KEYS = ("node", "state")
_CRITERION_KEYS = (
    "node",
    "quantity",
    "operator",
    "threshold",
    "fired",
    "bins",
    "states",
    "closed",
    "nominal",
    "if_missing",
    "note",
)
_PROB_ATOL = 1e-6
_CACHE_FORMAT = "1"
_SHIPPED_TABLES = "compiled_tables.json"  # compiled tables of the shipped models, in failure_models/


def arc_quantities(
    conditions: Conditions, heading_deg: npt.ArrayLike, names: Iterable[str] = tuple(QUANTITIES)
) -> dict[str, FloatArray]:
    """Environmental quantities seen by a craft on a heading (inputs of failure criteria).

    Each is a weather field, or its angle to the heading, as :data:`QUANTITY_FIELDS`
    says.

    Parameters
    ----------
    conditions : Weather at the points.
    heading_deg : The craft's heading, clockwise from north [deg].
    names : Quantities wanted (default all of :data:`QUANTITIES`).

    Returns
    -------
    ``hs_m`` [m], ``awd_deg`` apparent wave direction [deg] in [0, 180] (0 = head seas: waves from
    dead ahead), ``tws_kn`` [kn], ``twa_deg`` true wind angle [deg] in [0, 180], ``wave_period_s`` [s].

    >>> from pyroute_rel.weather import UniformWeather
    >>> c = UniformWeather(tws_kn=10.0, twd_deg=0.0, hs_m=2.0, wave_dir_deg=240.0).sample(0.0, 0.0, 0)
    >>> q = arc_quantities(c, 250.0)
    >>> float(q["awd_deg"]), float(q["twa_deg"])
    (10.0, 110.0)
    """
    out: dict[str, FloatArray] = {}
    for name in names:
        attr, relative = QUANTITY_FIELDS[name]
        value = getattr(conditions, attr)
        out[name] = geodesy.angle_diff_deg(value, heading_deg) if relative else value
    return out


def _compiled_tables() -> Shelf:
    """Compiled tables by hash of the model files, in the current store (:mod:`pyroute_rel.store`)."""
    return current_store().shelf("failure.compiled", limit=64)


def _networks() -> Shelf:
    """Checked pgmpy networks by hash of the network file, in the current store."""
    return current_store().shelf("failure.networks", limit=16)


FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Criterion:
    """How one quantity sets the state of one evidence node.

    The quantity is binned by ``edges`` (bin ``i`` is ``[edges[i-1], edges[i])`` with ``closed="left"``,
    ``(edges[i-1], edges[i]]`` with ``closed="right"``; the outer bins are open-ended) and bin ``i`` puts
    the node in state ``bin_states[i]``.

    Attributes
    ----------
    node : Evidence node of the network.
    quantity : Name in :data:`QUANTITIES`.
    states : The node's states, in network order (the axis of :attr:`FailureModel.table`).
    edges : Increasing bin edges [unit of the quantity].
    bin_states : Node state of each bin (``len(edges) + 1`` names).
    nominal : States in which the criterion has not fired.
    closed : One of :data:`CLOSED_SIDES`.
    operator, threshold : The rule of a two-state criterion as written (None for a binned one).
    if_missing : ``"nan"``, ``"prior"`` or a state assumed when the quantity is NaN.
    """

    node: str
    quantity: str
    states: tuple[str, ...]
    edges: tuple[float, ...]
    bin_states: tuple[str, ...]
    nominal: tuple[str, ...]
    closed: str = "left"
    operator: str | None = None
    threshold: float | None = None
    if_missing: str = "nan"

    def describe(self) -> str:
        """One line, e.g. ``"WH: hs_m >= 4 m"``.

        >>> Criterion("WH", "hs_m", ("false", "true"), (4.0,), ("false", "true"), ("false",),
        ...           operator=">=", threshold=4.0).describe()
        'WH: hs_m >= 4 m'
        """
        unit = QUANTITY_UNITS[self.quantity]
        if self.operator is not None:
            fired = [s for s in self.bin_states if s not in self.nominal]
            tail = "" if fired == ["true"] else f" -> {fired[0]}"
            return f"{self.node}: {self.quantity} {self.operator} {self.threshold:g} {unit}{tail}"
        lo, hi = ("<=", "<") if self.closed == "left" else ("<", "<=")
        q, e, s = self.quantity, self.edges, self.bin_states
        parts = [f"{q} {'<' if self.closed == 'left' else '<='} {e[0]:g} -> {s[0]}"]
        parts += [f"{e[i - 1]:g} {lo} {q} {hi} {e[i]:g} -> {s[i]}" for i in range(1, len(e))]
        parts.append(f"{q} {'>=' if self.closed == 'left' else '>'} {e[-1]:g} -> {s[-1]}")
        return f"{self.node} [{unit}]: " + "; ".join(parts) + f" (nominal: {', '.join(self.nominal)})"

    def classify(self, values: npt.ArrayLike) -> npt.NDArray[np.intp]:
        """Index into :attr:`states` of the node state each value gives (-1 where the value is NaN).

        >>> c = Criterion("WD", "awd_deg", ("false", "true"), (60.0,), ("true", "false"), ("false",))
        >>> c.classify([0.0, 59.9, 60.0, float("nan")]).tolist()
        [1, 1, 0, -1]
        """
        x = np.asarray(values, dtype=float)
        idx = self._lut()[np.searchsorted(self.edges, x, side="right" if self.closed == "left" else "left")]
        return np.where(np.isnan(x), -1, idx)

    def _lut(self) -> npt.NDArray[np.intp]:
        return np.array([self.states.index(s) for s in self.bin_states], dtype=np.intp)


@dataclass(frozen=True, eq=False)
class FailureModel:
    """A compiled failure model (build it with :func:`load_failure_model`).

    Attributes
    ----------
    name : Model name.
    path : The model's TOML file.
    description : Free text.
    network_path : The network file (BIF or another of :data:`NETWORK_FORMATS`).
    target, fail_state : Target node and its failure state.
    criteria : The criteria, in the order of the table's axes.
    nodes : All nodes of the network; ``edges`` its (parent, child) pairs; ``node_states`` their states.
    table : ``P(target = fail_state | evidence)``, shape ``(len(c.states) for c in criteria)``: the probability of
        failure over :attr:`exposure_h` hours spent in those conditions.
    references : Sources of the model.
    exposure_h : The reference exposure of :attr:`table`'s probabilities [h] (finite, > 0; default
        :data:`DEFAULT_EXPOSURE_H`).
    """

    name: str
    path: str
    description: str
    network_path: str
    target: str
    fail_state: str
    criteria: tuple[Criterion, ...]
    nodes: tuple[str, ...]
    edges: tuple[tuple[str, str], ...]
    node_states: Mapping[str, tuple[str, ...]]
    table: FloatArray = field(repr=False)
    #: The table with one more slot per axis: the node left unobserved (its prior).
    _full: FloatArray = field(repr=False)
    references: tuple[str, ...] = ()
    exposure_h: float = DEFAULT_EXPOSURE_H

    def __post_init__(self) -> None:
        check_exposure_h(self.exposure_h, f"failure model '{self.name}': exposure_h")
        object.__setattr__(self, "exposure_h", float(self.exposure_h))

    @property
    def quantities(self) -> frozenset[str]:
        """Names of the quantities :meth:`p_fail` needs."""
        return frozenset(c.quantity for c in self.criteria)

    @property
    def weather_fields(self) -> frozenset[str]:
        """Names of the weather fields (of :class:`~pyroute_rel.weather.Conditions`) its quantities are computed
        from (:data:`QUANTITY_FIELDS`): a weather source must define them (``weather.fields``)."""
        return frozenset(QUANTITY_FIELDS[q][0] for q in self.quantities)

    def _check_quantities(self, quantities: Mapping[str, npt.ArrayLike]) -> None:
        missing = sorted(self.quantities - set(quantities))
        if missing:
            raise FailureModelError(
                f"failure model '{self.name}' needs quantities {missing} (got {sorted(quantities)})"
            )

    def _indices(self, quantities: Mapping[str, npt.ArrayLike]) -> tuple[list[Any], list[Any]]:
        """Per criterion: node-state index (``len(states)`` = unobserved) and where a NaN gives an unknown."""
        self._check_quantities(quantities)
        arrays = np.broadcast_arrays(*[np.asarray(quantities[c.quantity], dtype=float) for c in self.criteria])
        idx, unknown = [], []
        for c, x in zip(self.criteria, arrays, strict=True):
            i = c._lut()[np.searchsorted(c.edges, x, side="right" if c.closed == "left" else "left")]
            nan = np.isnan(x)
            if nan.any():
                if c.if_missing == "nan":
                    unknown.append(nan)
                else:
                    fill = len(c.states) if c.if_missing == "prior" else c.states.index(c.if_missing)
                    i = np.where(nan, fill, i)
            idx.append(i)
        return idx, unknown

    def p_fail(self, quantities: Mapping[str, npt.ArrayLike]) -> FloatArray:
        """Probability of failure for each point, by gathering from the compiled table.

        Parameters
        ----------
        quantities : Arrays (broadcast together) for at least the names in :attr:`quantities`; units as
            in :data:`QUANTITIES`.

        Returns
        -------
        ``P(target = fail_state | evidence)`` [-] in the broadcast shape; NaN where a quantity is NaN and its
        criterion has ``if_missing = "nan"``.

        >>> m = load_failure_model("dickson2018")
        >>> m.p_fail({"hs_m": [3.9, 4.0, 4.0, 5.0], "awd_deg": [90.0, 90.0, 59.0, float("nan")]}).tolist()
        [0.0, 0.9, 1.0, nan]
        """
        check_instance(quantities, Mapping, "p_fail: quantities", FailureModelError, expected="a dict {name: array}")
        self._check_quantities(quantities)
        arrays = {c.quantity: check_numbers(quantities[c.quantity], f"p_fail: {c.quantity}", FailureModelError)
                  for c in self.criteria}  # fmt: skip
        try:
            np.broadcast_shapes(*(a.shape for a in arrays.values()))
        except ValueError:
            shapes = {k: a.shape for k, a in arrays.items()}
            raise FailureModelError(f"p_fail: the quantities must broadcast together (got shapes {shapes})") from None
        quantities = arrays
        for name, (lo, hi) in QUANTITY_RANGES.items():
            if name in quantities:
                v = quantities[name]
                bad = np.isfinite(v) & ((v < lo) | (v > hi))
                if bad.any():
                    raise FailureModelError(
                        f"p_fail: {name} must be in [{lo:g}, {hi:g}] ({QUANTITIES[name]}) (got {v[bad].ravel()[0]:g})"
                    )
        idx, unknown = self._indices(quantities)
        p = self._full[tuple(idx)]
        if unknown:
            p = np.where(np.logical_or.reduce(unknown), np.nan, p)
        return np.asarray(p)

    # --- the cost kernel's path: one flat index into the table per point -----------------------------

    @cached_property
    def _kernel(self) -> _Kernel:
        return _Kernel.build(self)

    @property
    def p_flat(self) -> FloatArray:
        """The table with an "unobserved" slot per axis, flattened: gather it with :meth:`evidence_index`."""
        return self._kernel.p_flat

    @property
    def fired_bits_flat(self) -> npt.NDArray[np.uint32]:
        """Per flat evidence index, bit ``c`` set when criterion ``c`` is in a non-nominal state."""
        return self._kernel.fired_bits

    def evidence_index(
        self, quantities: Mapping[str, npt.ArrayLike]
    ) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.bool_] | None]:
        """Flat index into :attr:`p_flat` of each point's evidence, and where the evidence is unknown.

        The cost kernel's fast path (threshold criteria classify by one comparison, the table is gathered
        once with a flat index): ``p_flat[index]`` equals :meth:`p_fail` except where ``unknown`` (NaN there).

        Returns
        -------
        ``(index, unknown)``: ``index`` in the broadcast shape of the quantities; ``unknown`` is a boolean mask
        of points where a quantity is NaN and its criterion has ``if_missing = "nan"``, or None if there is none.

        >>> m = load_failure_model("dickson2018")
        >>> i, unknown = m.evidence_index({"hs_m": [1.0, 4.0, 4.0], "awd_deg": [90.0, 90.0, 10.0]})
        >>> m.p_flat[i].tolist(), unknown
        ([0.0, 0.9, 1.0], None)
        """
        self._check_quantities(quantities)
        flat: Any = None
        unknown: Any = None
        for c, rule in zip(self.criteria, self._kernel.rules, strict=True):
            x = np.asarray(quantities[c.quantity], dtype=float)
            part = rule.index(x)
            if np.isnan(np.sum(x)):  # one reduction; the NaN mask only when some value is NaN (or +-inf pairs)
                nan = np.isnan(x)
                if nan.any():
                    if rule.fill is None:
                        unknown = nan if unknown is None else unknown | nan
                    else:
                        part = np.where(nan, rule.fill, part)
            flat = part if flat is None else flat + part
        flat = np.asarray(flat, dtype=np.intp)
        if unknown is not None:
            unknown = np.broadcast_to(unknown, flat.shape) if unknown.shape != flat.shape else unknown
        return flat, unknown

    def evidence_rules(
        self,
    ) -> tuple[FloatArray, npt.NDArray[np.intp], npt.NDArray[np.intp], npt.NDArray[np.bool_], npt.NDArray[np.intp]]:
        """:meth:`evidence_index`'s classifiers as arrays for compiled code, one row per criterion (in order):
        ``(edges, n_edges, contrib, right, fill)``: the bin edges (padded with NaN) and their number, each bin's
        contribution to the flat index (padded with 0), whether a value on an edge goes to the upper bin, and the
        contribution of a NaN value (-1: a NaN makes the evidence unknown). A value's bin is the number of edges below
        it (at or below with ``right``); a NaN's, where it is unknown, is the last (numpy's searchsorted puts NaN
        there), or the first for a single edge (a comparison with NaN is false)."""
        rules = self._kernel.rules
        width = max(r.edges.size for r in rules)
        edges = np.full((len(rules), width), np.nan)
        contrib = np.zeros((len(rules), width + 1), dtype=np.intp)
        for i, r in enumerate(rules):
            edges[i, : r.edges.size] = r.edges
            contrib[i, : r.contrib.size] = r.contrib
        n_edges = np.array([r.edges.size for r in rules], dtype=np.intp)
        right = np.array([r.right for r in rules], dtype=np.bool_)
        fill = np.array([-1 if r.fill is None else r.fill for r in rules], dtype=np.intp)
        return edges, n_edges, contrib, right, fill

    @staticmethod
    def _fired_lut(c: Criterion) -> npt.NDArray[np.bool_]:
        return np.array([s not in c.nominal for s in c.states] + [False])

    def fired(self, quantities: Mapping[str, npt.ArrayLike]) -> npt.NDArray[np.bool_]:
        """Which criteria are in a non-nominal state, shape ``(len(criteria), *broadcast shape)``.

        A NaN quantity fires its criterion only if its ``if_missing`` names a non-nominal state (use
        :meth:`p_fail`, NaN there, to find points where the evidence is unknown).

        >>> m = load_failure_model("dickson2018")
        >>> m.fired({"hs_m": [4.0, 1.0, float("nan")], "awd_deg": [60.0, 10.0, 10.0]}).tolist()
        [[True, False, False], [False, True, True]]
        """
        idx, _ = self._indices(quantities)
        arrays = np.broadcast_arrays(*[np.asarray(quantities[c.quantity], dtype=float) for c in self.criteria])
        out = []
        for c, i, x in zip(self.criteria, idx, arrays, strict=True):
            f = self._fired_lut(c)[i]
            out.append(f & ~np.isnan(x) if c.if_missing == "nan" else f)
        return np.stack(out)

    def without(self, node: str) -> FailureModel:
        """The model with one criterion removed: its evidence node always in its first nominal state (observed,
        unobserved or its quantity missing), so it never raises ``p_f``; the criterion is kept, so :meth:`fired`
        still says where its quantity crosses the limit.

        >>> m = load_failure_model("dickson2018").without("WD")
        >>> m.p_fail({"hs_m": [1.0, 4.0, 1.0], "awd_deg": [90.0, 90.0, 10.0]}).tolist()
        [0.0, 0.9, 0.0]
        """
        names = [c.node for c in self.criteria]
        if node not in names:
            raise FailureModelError(f"failure model '{self.name}' has no criterion {node!r} (it has {names})")
        axis = names.index(node)
        c = self.criteria[axis]
        keep = c.states.index(c.nominal[0])
        slots = np.array([i if s in c.nominal else keep for i, s in enumerate(c.states)] + [keep])
        gone = dataclasses.replace(c, if_missing=c.nominal[0])  # a missing quantity is no longer unknown evidence
        return dataclasses.replace(
            self,
            name=f"{self.name} without {node}",
            criteria=(*self.criteria[:axis], gone, *self.criteria[axis + 1 :]),
            table=np.take(self.table, slots[:-1], axis=axis),
            _full=np.take(self._full, slots, axis=axis),
        )

    def evidence_states(self) -> Iterator[dict[str, str]]:
        """Every combination of evidence states, in the table's (C) order.

        >>> [e["WD"] for e in load_failure_model("dickson2018").evidence_states()]
        ['false', 'true', 'false', 'true']
        """
        for combo in itertools.product(*[c.states for c in self.criteria]):
            yield dict(zip([c.node for c in self.criteria], combo, strict=True))

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description: criteria, network, target and the compiled table.

        >>> d = load_failure_model("dickson2018").describe()
        >>> d["criteria"][0]["rule"], d["network"]["edges"], d["table"][1]
        ('hs_m >= 4', [['WH', 'F'], ['WD', 'F']], {'evidence': {'WH': 'false', 'WD': 'true'}, 'p_fail': 0.9})
        """
        crit = []
        for c in self.criteria:
            d: dict[str, Any] = {"node": c.node, "quantity": c.quantity}
            if c.operator is not None:
                d["rule"] = f"{c.quantity} {c.operator} {c.threshold:g}"
            else:
                d["bins"] = list(c.edges)
                d["closed"] = c.closed
                d["bin_states"] = list(c.bin_states)
            d.update(states=list(c.states), nominal=list(c.nominal), if_missing=c.if_missing, description=c.describe())
            crit.append(d)
        table = [
            {"evidence": ev, "p_fail": float(p)}
            for ev, p in zip(self.evidence_states(), self.table.ravel(), strict=True)
        ]
        return {
            "model": self.name,
            "path": self.path,
            "description": self.description,
            "target": {"node": self.target, "state": self.fail_state},
            "criteria": crit,
            "network": {
                "path": self.network_path,
                "nodes": list(self.nodes),
                "states": {n: list(self.node_states[n]) for n in self.nodes},
                "edges": [list(e) for e in self.edges],
            },
            "references": list(self.references),
            "exposure_h": self.exposure_h,
            "table": table,
        }


@dataclass(frozen=True)
class _Rule:
    """One criterion's classifier in the kernel: the contribution ``state index * stride`` to the flat index."""

    edges: npt.NDArray[np.float64]
    contrib: npt.NDArray[np.intp]  # per bin: state index * stride
    right: bool  # bins closed on the left: a value on an edge goes to the upper bin
    fill: int | None  # contribution of a NaN value, None when a NaN makes the evidence unknown

    def index(self, x: FloatArray) -> Any:
        if self.edges.size == 1:  # a threshold: one comparison instead of a binary search
            upper = x >= self.edges[0] if self.right else x > self.edges[0]
            return np.where(upper, self.contrib[1], self.contrib[0])
        return self.contrib[np.searchsorted(self.edges, x, side="right" if self.right else "left")]


@dataclass(frozen=True)
class _Kernel:
    p_flat: FloatArray
    fired_bits: npt.NDArray[np.uint32]
    rules: tuple[_Rule, ...]

    @classmethod
    def build(cls, model: FailureModel) -> _Kernel:
        if len(model.criteria) > 32:
            raise FailureModelError(f"{model.path}: at most 32 criteria are supported (got {len(model.criteria)})")
        full = np.ascontiguousarray(model._full)
        strides = [s // full.itemsize for s in full.strides]
        rules = []
        bits = np.zeros(full.shape, dtype=np.uint32)
        for axis, (c, stride) in enumerate(zip(model.criteria, strides, strict=True)):
            if c.if_missing == "nan":
                fill = None
            else:
                fill = (len(c.states) if c.if_missing == "prior" else c.states.index(c.if_missing)) * stride
            rules.append(
                _Rule(
                    edges=np.asarray(c.edges, dtype=float),
                    contrib=c._lut() * stride,
                    right=c.closed == "left",
                    fill=fill,
                )
            )
            fired = np.uint32(1 << axis) * FailureModel._fired_lut(c).astype(np.uint32)
            shape = [1] * full.ndim
            shape[axis] = -1
            bits |= fired.reshape(shape)
        p_flat = full.ravel()
        p_flat.setflags(write=False)
        bits_flat = bits.ravel()
        bits_flat.setflags(write=False)
        return cls(p_flat=p_flat, fired_bits=bits_flat, rules=tuple(rules))


# ----------------------------------------------------------------------------------------------- loading


def _shipped() -> Traversable:
    return resources.files("failure_models")


def list_failure_models() -> list[str]:
    """Names of the failure models shipped with pyroute_rel.

    >>> "dickson2018" in list_failure_models()
    True
    """
    return sorted(p.name[:-5] for p in _shipped().iterdir() if p.name.endswith(".toml") and p.is_file())


def load_failure_model(name_or_path: str | os.PathLike[str], *, cache: bool = True) -> FailureModel:
    """Load, check and compile a failure model.

    Parameters
    ----------
    name_or_path : A shipped model name (:func:`list_failure_models`) or the path of a model's TOML file.
    cache : Use (and fill) the in-memory and on-disk caches of compiled tables. The disk cache lives in
        ``$PYROUTE_REL_CACHE_DIR``, else ``$XDG_CACHE_HOME/pyroute_rel``, else ``~/.cache/pyroute_rel``;
        it is skipped silently when the folder is not writable.

    Returns
    -------
    The compiled :class:`FailureModel`.

    Raises
    ------
    FailureModelError
        One line naming the file and the problem (missing file, TOML or network syntax, unknown key or
        quantity, node not in the network, missing CPT, probabilities not summing to 1, ...).

    >>> m = load_failure_model("dickson2018")
    >>> [c.describe() for c in m.criteria], m.table.tolist()
    (['WH: hs_m >= 4 m', 'WD: awd_deg < 60 deg'], [[0.0, 0.9], [0.9, 1.0]])
    """
    cache = check_flag(cache, "cache", FailureModelError)
    toml_file = _resolve(name_or_path)
    label = brief_path(str(toml_file))  # for messages: control characters escaped, a long path cut in the middle
    toml_bytes = _read(toml_file, label)
    spec = parse_model_toml(toml_bytes, label, default_name=toml_file.name.removesuffix(".toml"))
    net_file = _sibling(toml_file, spec["network"])
    net_label = str(net_file)
    net_bytes = _read(net_file, f"{label}: network file {spec['network']!r} ({net_label})")
    return model_from_bytes(toml_bytes, net_bytes, spec, path=str(toml_file), net_label=net_label, cache=cache)


def parse_model_toml(toml_bytes: bytes, label: str, *, default_name: str) -> dict[str, Any]:
    """A model's TOML text parsed and checked on its own (:func:`_parse_spec`)."""
    try:
        doc = tomllib.loads(toml_bytes.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise FailureModelError(f"{label}: TOML syntax error: {exc}") from None
    return _parse_spec(doc, label, default_name=default_name)


def model_from_bytes(
    toml_bytes: bytes, net_bytes: bytes, spec: dict[str, Any], *, path: str, net_label: str, cache: bool = True
) -> FailureModel:
    """The compiled :class:`FailureModel` of a model's TOML and network bytes (``spec``: the TOML parsed by
    :func:`parse_model_toml`), its table from the caches (keyed by both files' bytes) or compiled with pgmpy.
    ``path`` and ``net_label`` name the two in messages and in the model (``net_label`` ends with the network
    format's extension)."""
    label = brief_path(path)
    key = _cache_key(toml_bytes, net_bytes)
    compiled = _compiled_tables().get(key) if cache else None
    if compiled is None and cache:
        compiled = _shipped_tables().get(_content_key(toml_bytes, net_bytes))
        if compiled is None:
            compiled = _disk_get(key)
        if compiled is not None and not _fits(compiled, spec):  # a damaged or foreign entry
            compiled = None
    if compiled is None:
        compiled = _compile(net_bytes, net_label, spec, label)
        if cache:
            _disk_put(key, compiled)
    if cache:
        _compiled_tables().put(key, compiled)
    criteria = _check_structure(spec, compiled.states, label, net_label)
    shape = tuple(len(c.states) for c in criteria)
    full = compiled.table
    full.setflags(write=False)
    return FailureModel(
        name=spec["name"],
        path=path,
        description=spec["description"],
        network_path=net_label,
        target=spec["target"]["node"],
        fail_state=spec["target"]["state"],
        criteria=criteria,
        nodes=tuple(compiled.nodes),
        edges=tuple((a, b) for a, b in compiled.edges),
        node_states={n: tuple(s) for n, s in compiled.states.items()},
        table=full[tuple(slice(0, n) for n in shape)],
        references=tuple(spec["references"]),
        _full=full,
        exposure_h=spec["exposure_h"],
    )


def _resolve(name_or_path: str | os.PathLike[str]) -> Traversable:
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise FailureModelError(
            f"a failure model must be given by name or path (str or pathlib.Path) (got {brief(name_or_path)})"
        )
    text = os.fspath(name_or_path)
    shipped = list_failure_models()
    if not text.strip():
        raise FailureModelError(
            f"failure model name is empty: expected a shipped name, one of {shipped}, or the path of a .toml file"
        )
    if text in shipped:
        return _shipped().joinpath(f"{text}.toml")
    path = Path(text).expanduser()
    try:
        exists = path.exists()
    except OSError:  # e.g. a name longer than the file system allows (ENAMETOOLONG)
        exists = False
    if path.suffix.lower() == ".toml" or exists or os.sep in text or "/" in text:
        return path
    raise FailureModelError(
        f"failure model {brief(text)} not found: expected a shipped name, one of {shipped}, or the path of a .toml file"
    )


def model_files(name_or_path: str | os.PathLike[str]) -> list[Path]:
    """The files on disk a failure model is read from: its TOML file and the network file it names (what anything
    computed with the model depends on, e.g. a sweep's keys); [] for a name or path that does not resolve to a file.

    >>> [p.name for p in model_files("dickson2018")]
    ['dickson2018.toml', 'dickson2018.bif']
    """
    try:
        toml_file = _resolve(name_or_path)
    except FailureModelError:
        return []
    if not isinstance(toml_file, Path) or not toml_file.is_file():
        return []
    try:
        network = tomllib.loads(toml_file.read_text(encoding="utf-8")).get("network")
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return [toml_file]
    return [toml_file, *([toml_file.parent / network] if isinstance(network, str) else [])]


def _sibling(toml_file: Traversable, name: str) -> Traversable:
    if isinstance(toml_file, Path):
        return toml_file.parent / name
    return _shipped().joinpath(name)


def _read(file: Traversable, label: str) -> bytes:
    if isinstance(file, Path):  # a user's file: regular files only, at most 10 MB (no hang on a FIFO or /dev/zero)
        return read_regular_bytes(file, limit_bytes=10_000_000, error=FailureModelError, label=label)
    try:
        return file.read_bytes()
    except FileNotFoundError:
        raise FailureModelError(f"{label}: file not found") from None
    except OSError as exc:
        raise FailureModelError(f"{label}: cannot read ({exc.strerror or exc})") from None


def _choices(got: Any, allowed: tuple[str, ...] | list[str]) -> str:
    return f"must be one of {list(allowed)} (got {got!r})"


def _unknown(where: str, key: str, allowed: tuple[str, ...]) -> FailureModelError:
    return FailureModelError(f"{where}: unknown key {key!r} (expected one of {list(allowed)})")


def _text(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise FailureModelError(f"{where} must be a non-empty string (got {value!r})")
    return value


def _parse_spec(doc: dict[str, Any], label: str, *, default_name: str) -> dict[str, Any]:
    """Check the TOML document on its own (no network needed) and normalise it."""
    for key in doc:
        if key not in _MODEL_KEYS:
            raise _unknown(label, key, _MODEL_KEYS)

    if "network" not in doc:
        raise FailureModelError(f"{label}: missing key 'network' (the network file, relative to the TOML)")
    refs = doc.get("references", [])
    if not isinstance(refs, list) or not all(isinstance(r, str) for r in refs):
        raise FailureModelError(f"{label}: 'references' must be a list of strings (got {refs!r})")
    target = doc.get("target")
    if not isinstance(target, dict):
        raise FailureModelError(f"{label}: missing table [target] with 'node' and 'state' (the failure state)")
    for key in target:
        if key not in _TARGET_KEYS:
            raise _unknown(f"{label}: [target]", key, _TARGET_KEYS)
    for key in _TARGET_KEYS:
        if key not in target:
            raise FailureModelError(f"{label}: [target]: missing key {key!r}")
    crits = doc.get("criteria")
    if not isinstance(crits, list) or not crits or not all(isinstance(c, dict) for c in crits):
        raise FailureModelError(f"{label}: needs at least one [[criteria]] table (got {crits!r})")
    if len(crits) > 32:  # before the network is read: its joint table would have 2^33 entries or more
        raise FailureModelError(f"{label}: at most 32 criteria are supported (got {len(crits)})")
    spec: dict[str, Any] = {
        "name": _text(doc.get("name", default_name), f"{label}: 'name'"),
        "description": doc.get("description", ""),
        "network": _text(doc["network"], f"{label}: 'network'"),
        "references": refs,
        "exposure_h": check_exposure_h(doc.get("exposure_h", DEFAULT_EXPOSURE_H), f"{label}: 'exposure_h'"),
        "target": {
            "node": _text(target["node"], f"{label}: [target] 'node'"),
            "state": _text(target["state"], f"{label}: [target] 'state'"),
        },
        "criteria": [],
    }
    try:
        _network_format(spec["network"])
    except ValueError as exc:
        raise FailureModelError(f"{label}: 'network': {exc}") from None
    if not isinstance(spec["description"], str):
        raise FailureModelError(f"{label}: 'description' must be a string (got {spec['description']!r})")
    seen: set[str] = set()
    for i, raw in enumerate(crits):
        c = _parse_criterion(raw, f"{label}: criteria[{i}]")
        # before the network is read (reading it may import pgmpy, seconds): what the TOML alone shows wrong
        if c["node"] in seen:
            raise FailureModelError(f"{c['where']}: node {c['node']!r} is set by two criteria")
        if c["node"] == spec["target"]["node"]:
            raise FailureModelError(
                f"{c['where']}: node {c['node']!r} is the target; a criterion must set another node"
            )
        seen.add(c["node"])
        spec["criteria"].append(c)
    return spec


def check_exposure_h(value: Any, where: str) -> float:
    """``value`` as a reference exposure [h]: a finite number > 0, else a :class:`FailureModelError` naming
    ``where``.

    >>> check_exposure_h(4.4, "exposure_h")
    4.4
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)) or value <= 0:
        raise FailureModelError(
            f"{where} must be a finite number of hours > 0 (the exposure over which p_f applies) (got {value!r})"
        )
    return float(value)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise FailureModelError(f"{where} must be a finite number (got {value!r})")
    return float(value)


def _parse_criterion(raw: dict[str, Any], where: str) -> dict[str, Any]:
    """One ``[[criteria]]`` table checked on its own and normalised (a threshold or a binned criterion)."""
    node = raw.get("node")
    if isinstance(node, str):
        where = f"{where} ({node})"
    for key in raw:
        if key not in _CRITERION_KEYS:
            raise _unknown(where, key, _CRITERION_KEYS)
    for key in ("node", "quantity"):
        if key not in raw:
            raise FailureModelError(f"{where}: missing key {key!r}")
    c: dict[str, Any] = {"node": _text(raw["node"], f"{where}: 'node'")}
    quantity = raw["quantity"]
    if quantity not in QUANTITIES:
        raise FailureModelError(f"{where}: 'quantity' {_choices(quantity, list(QUANTITIES))}")
    c["quantity"] = quantity
    threshold_form = "operator" in raw or "threshold" in raw
    if threshold_form == ("bins" in raw):
        raise FailureModelError(
            f"{where}: give either 'operator' and 'threshold' (two-state node) or 'bins' "
            "(edges of the node's states), not both or neither"
        )
    c.update(_parse_threshold(raw, where) if threshold_form else _parse_bins(raw, where))
    if_missing = raw.get("if_missing", "nan")
    c["if_missing"] = _text(if_missing, f"{where}: 'if_missing'")
    c["where"] = where
    return c


def _parse_threshold(raw: dict[str, Any], where: str) -> dict[str, Any]:
    """The ``operator``, ``threshold`` and ``fired`` state of a threshold criterion (a two-state node)."""
    for key in ("operator", "threshold", "fired"):
        if key not in raw:
            extra = " (the node state when the rule holds)" if key == "fired" else ""
            raise FailureModelError(f"{where}: missing key {key!r}{extra}")
    for key in ("bins", "states", "closed", "nominal"):
        if key in raw:
            raise FailureModelError(f"{where}: key {key!r} belongs to binned criteria, not with 'operator'")
    if raw["operator"] not in OPERATORS:
        raise FailureModelError(f"{where}: 'operator' {_choices(raw['operator'], OPERATORS)}")
    return {
        "operator": raw["operator"],
        "threshold": _number(raw["threshold"], f"{where}: 'threshold'"),
        "fired": _text(raw["fired"], f"{where}: 'fired'"),
    }


def _parse_bins(raw: dict[str, Any], where: str) -> dict[str, Any]:
    """The bin ``edges``, ``closed`` side, ``states`` and ``nominal`` states of a binned criterion."""
    if "fired" in raw:
        raise FailureModelError(f"{where}: key 'fired' belongs to threshold criteria; use 'nominal' with 'bins'")
    bins = raw["bins"]
    if not isinstance(bins, list) or not bins:
        raise FailureModelError(f"{where}: 'bins' must be a non-empty list of increasing numbers (got {bins!r})")
    edges = [_number(b, f"{where}: 'bins'") for b in bins]
    if any(b <= a for a, b in itertools.pairwise(edges)):
        raise FailureModelError(f"{where}: 'bins' must be strictly increasing (got {bins!r})")
    closed = raw.get("closed", "left")
    if closed not in CLOSED_SIDES:
        raise FailureModelError(f"{where}: 'closed' {_choices(closed, CLOSED_SIDES)}")
    states = raw.get("states")
    if states is not None and (not isinstance(states, list) or not all(isinstance(s, str) for s in states)):
        raise FailureModelError(f"{where}: 'states' must be a list of node state names (got {states!r})")
    nominal = raw.get("nominal")
    if isinstance(nominal, str):
        nominal = [nominal]
    if nominal is not None and (
        not isinstance(nominal, list) or not nominal or not all(isinstance(s, str) for s in nominal)
    ):
        raise FailureModelError(f"{where}: 'nominal' must be a state name or a list of them (got {nominal!r})")
    return {"edges": edges, "closed": closed, "states": states, "nominal": nominal}


def _check_structure(
    spec: dict[str, Any], states: Mapping[str, list[str]], label: str, net_label: str
) -> tuple[Criterion, ...]:
    """Check the criteria and the target against the network's nodes and states."""
    nodes = list(states)
    t, fail = spec["target"]["node"], spec["target"]["state"]
    if t not in states:
        raise FailureModelError(f"{label}: [target] node {t!r} is not in the network {net_label} (nodes: {nodes})")
    if fail not in states[t]:
        raise FailureModelError(f"{label}: [target] state {fail!r} is not a state of {t} ({states[t]})")
    seen: set[str] = set()
    out = []
    for c in spec["criteria"]:
        where, node = c["where"], c["node"]
        if node not in states:
            raise FailureModelError(f"{where}: node {node!r} is not in the network {net_label} (nodes: {nodes})")
        if node == t:
            raise FailureModelError(f"{where}: node {node!r} is the target; a criterion must set another node")
        if node in seen:
            raise FailureModelError(f"{where}: node {node!r} is set by two criteria")
        seen.add(node)
        ns = tuple(states[node])
        crit = _threshold_criterion(c, ns) if "operator" in c else _binned_criterion(c, ns)
        if crit.if_missing not in MISSING_RULES and crit.if_missing not in ns:
            raise FailureModelError(
                f"{where}: 'if_missing' must be one of {list(MISSING_RULES)} or a state of "
                f"{node} {list(ns)} (got {crit.if_missing!r})"
            )
        out.append(crit)
    return tuple(out)


def _node_state(c: dict[str, Any], ns: tuple[str, ...], s: str, what: str) -> str:
    """``s``, checked to be one of the node's states ``ns``."""
    if s not in ns:
        raise FailureModelError(f"{c['where']}: {what} {s!r} is not a state of {c['node']} {list(ns)}")
    return s


def _threshold_criterion(c: dict[str, Any], ns: tuple[str, ...]) -> Criterion:
    """A parsed threshold criterion on a node with states ``ns`` (two of them)."""
    where, node = c["where"], c["node"]
    if len(ns) != 2:
        raise FailureModelError(
            f"{where}: wrong cardinality: a threshold criterion needs a two-state "
            f"node but {node} has {len(ns)} states {list(ns)}; use 'bins'"
        )
    fired = _node_state(c, ns, c["fired"], "'fired'")
    other = ns[1 - ns.index(fired)]
    op = c["operator"]
    closed = "left" if op in (">=", "<") else "right"
    bin_states = (other, fired) if op in (">=", ">") else (fired, other)
    return Criterion(
        node, c["quantity"], ns, (c["threshold"],), bin_states, (other,), closed, op, c["threshold"], c["if_missing"]
    )


def _binned_criterion(c: dict[str, Any], ns: tuple[str, ...]) -> Criterion:
    """A parsed binned criterion on a node with states ``ns`` (one per bin unless ``states`` names them)."""
    where, node = c["where"], c["node"]
    n_bins = len(c["edges"]) + 1
    bin_states: tuple[str, ...]
    if c["states"] is None:
        if n_bins != len(ns):
            raise FailureModelError(
                f"{where}: wrong cardinality: {len(c['edges'])} bin edges make {n_bins} "
                f"bins but node {node} has {len(ns)} states {list(ns)}"
            )
        bin_states = ns
    else:
        if len(c["states"]) != n_bins:
            raise FailureModelError(
                f"{where}: wrong cardinality: {len(c['edges'])} bin edges make {n_bins} "
                f"bins but 'states' names {len(c['states'])}"
            )
        bin_states = tuple(_node_state(c, ns, s, "'states' entry") for s in c["states"])
    nominal = tuple(_node_state(c, ns, s, "'nominal' state") for s in (c["nominal"] or [bin_states[0]]))
    return Criterion(
        node, c["quantity"], ns, tuple(c["edges"]), tuple(bin_states), nominal, c["closed"], None, None, c["if_missing"]
    )


# --------------------------------------------------------------------------------------------- compiling


@dataclass(frozen=True)
class _Compiled:
    nodes: list[str]
    edges: list[list[str]]
    states: dict[str, list[str]]
    table: FloatArray  # P(fail | evidence), one extra slot per axis for "unobserved"


def _import_pgmpy() -> Any:
    with warnings.catch_warnings():  # pgmpy warns about its own deprecations on import
        warnings.simplefilter("ignore")
        from pgmpy import readwrite
        from pgmpy.inference import VariableElimination
    return readwrite, VariableElimination


_DECL = re.compile(r"variable\s+([^\s{]+)\s*\{[^}]*?type\s+discrete\s*\[\s*(\d+)\s*\]\s*\{([^}]*)\}", re.S)


def _network_format(name: str) -> str:
    suffix = Path(name).suffix.lower()
    if suffix not in NETWORK_FORMATS:
        raise ValueError(f"the network file's extension {_choices(suffix, list(NETWORK_FORMATS))}")
    return suffix


def _read_network(net_bytes: bytes, net_label: str) -> Any:
    """Parse and check a network with pgmpy (memoised by content); problems become one FailureModelError line."""
    suffix = _network_format(net_label)
    key = hashlib.sha256(suffix.encode() + b"\0" + net_bytes).hexdigest()
    # pgmpy's BIF grammar alone takes ~1 s to build: parse each network once
    return _networks().get_or_make(key, lambda: _parse_network(net_bytes, net_label, suffix))


def _parse_network(net_bytes: bytes, net_label: str, suffix: str) -> Any:
    readwrite, _ = _import_pgmpy()
    reader_cls = getattr(readwrite, NETWORK_FORMATS[suffix][0])
    try:
        text = net_bytes.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FailureModelError(f"{net_label}: network parse failure: not UTF-8 text ({exc})") from None
    if suffix == ".bif":  # pgmpy ignores a declared count that disagrees with the listed states
        for name, n, body in _DECL.findall(re.sub(r"//[^\n]*", "", text)):
            declared = [s.strip() for s in body.split(",") if s.strip()]
            if int(n) != len(declared):
                raise FailureModelError(
                    f"{net_label}: variable {name} declares [ {n} ] states but lists {len(declared)} {declared}"
                )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = reader_cls(string=text).get_model()
    except Exception as exc:  # pgmpy raises KeyError, ValueError, pyparsing and XML errors, ...
        hint = " (a variable used but not declared, or a syntax error near it)" if isinstance(exc, KeyError) else ""
        raise FailureModelError(f"{net_label}: network parse failure: {type(exc).__name__}: {exc}{hint}") from None
    names = [str(n) for n in model.nodes()]
    if not names:
        raise FailureModelError(f"{net_label}: network parse failure: no variables found")
    cpds = {cpd.variable: cpd for cpd in model.get_cpds()}
    for name in names:
        if name not in cpds:
            raise FailureModelError(f"{net_label}: missing CPT: no probability table for {name}")
    for name in names:
        cpd = cpds[name]
        values = np.asarray(cpd.get_values(), dtype=float)
        parents = list(cpd.variables[1:])
        bad = ~np.isfinite(values) | (values < -_PROB_ATOL) | (values > 1 + _PROB_ATOL)
        sums = values.sum(axis=0)
        wrong = np.flatnonzero(bad.any(axis=0) | (np.abs(sums - 1.0) > _PROB_ATOL))
        if wrong.size:
            col = int(wrong[0])
            cards = [len(cpd.state_names[p]) for p in parents]
            at = np.unravel_index(col, cards) if parents else ()
            given = ", ".join(f"{p}={cpd.state_names[p][k]}" for p, k in zip(parents, at, strict=True))
            what = f"P({name} | {given})" if parents else f"P({name})"
            raise FailureModelError(
                f"{net_label}: CPT of {name}: {what} = {values[:, col].tolist()} sums to "
                f"{sums[col]:.6g}; each column must be probabilities summing to 1 "
                f"(tolerance {_PROB_ATOL:g})"
            )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model.check_model()
    except Exception as exc:
        raise FailureModelError(f"{net_label}: invalid network: {exc}") from None
    return model


def _compile(net_bytes: bytes, net_label: str, spec: dict[str, Any], label: str) -> _Compiled:
    """Query the network once for the joint of target and criteria nodes; condition every evidence subset."""
    model = _read_network(net_bytes, net_label)
    _, VariableElimination = _import_pgmpy()
    names = [str(n) for n in model.nodes()]
    cpds = {cpd.variable: cpd for cpd in model.get_cpds()}
    states = {n: [str(s) for s in cpds[n].state_names[n]] for n in names}
    edges = [[p, n] for n in names for p in cpds[n].variables[1:]]
    criteria = _check_structure(spec, states, label, net_label)
    target, fail = spec["target"]["node"], spec["target"]["state"]
    check_budget(
        table_estimate([len(states[c.node]) for c in criteria], len(states[target]), label),
        knobs="use fewer criteria or fewer states per criterion",
    )
    order = [target] + [c.node for c in criteria]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        joint = VariableElimination(model).query(order, joint=True, show_progress=False)
    values = np.asarray(joint.values, dtype=float)
    values = np.transpose(values, [list(joint.variables).index(v) for v in order])
    for axis, v in enumerate(order):  # the factor's state order may differ from the CPT's
        perm = [list(joint.state_names[v]).index(s) for s in states[v]]
        values = np.take(values, perm, axis=axis)
    for axis in range(1, len(order)):  # one more slot per criterion: the node unobserved
        values = np.concatenate([values, values.sum(axis=axis, keepdims=True)], axis=axis)
    evidence = values.sum(axis=0)
    zero = evidence <= 0.0
    if zero.any():
        at = np.unravel_index(int(np.flatnonzero(zero)[0]), zero.shape)
        ev = ", ".join(f"{c.node}={(c.states + ('unobserved',))[k]}" for c, k in zip(criteria, at, strict=True))
        raise FailureModelError(
            f"{net_label}: evidence ({ev}) has probability 0 in the network, so "
            f"P({target}={fail} | evidence) is undefined; give every criterion state a "
            "positive probability"
        )
    table = values[states[target].index(fail)] / evidence
    return _Compiled(nodes=names, edges=edges, states=states, table=np.clip(table, 0.0, 1.0))


def build_network(model: FailureModel | str | os.PathLike[str]) -> Any:
    """The checked pgmpy ``DiscreteBayesianNetwork`` of a failure model (imports pgmpy; for inspection).

    Parameters
    ----------
    model : A loaded model, a shipped model name or the path of a model's TOML file.
    """
    if not isinstance(model, FailureModel):
        model = load_failure_model(model)
    path = Path(model.network_path)
    file: Traversable = path if path.is_file() else _shipped().joinpath(path.name)
    return _read_network(_read(file, model.network_path), model.network_path).copy()


# ------------------------------------------------------------------------------------------------- cache


def _cache_key(toml_bytes: bytes, net_bytes: bytes) -> str:
    try:
        version = importlib.metadata.version("pgmpy")
    except importlib.metadata.PackageNotFoundError:
        version = "none"
    h = hashlib.sha256()
    for part in (_CACHE_FORMAT.encode(), version.encode(), toml_bytes, net_bytes):
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()[:32]


def _content_key(toml_bytes: bytes, net_bytes: bytes) -> str:
    """Hash of a model's two files (any copy of a shipped model with the same bytes has the same key)."""
    h = hashlib.sha256()
    for part in (b"shipped-table-1", toml_bytes, net_bytes):
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()[:32]


def _shipped_tables() -> dict[str, _Compiled]:
    """The compiled tables shipped in ``failure_models/compiled_tables.json``, by :func:`_content_key`; kept in the
    current store by the file's path, size and modification time (an edited file is read again).

    Variable elimination is exact, so a table depends only on the model's files, not on the pgmpy version;
    ``tests/test_failure.py`` compiles every shipped model with pgmpy and compares. A missing or unreadable file
    only means compiling (and the disk cache) as for any other model.
    """
    path = Path(str(_shipped().joinpath(_SHIPPED_TABLES)))
    shelf = current_store().shelf("failure.shipped", limit=1)
    return shelf.get_or_make(file_stamps([path])[0], lambda: _read_shipped_tables(path))  # type: ignore[no-any-return]


def _read_shipped_tables(path: Path) -> dict[str, _Compiled]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        out = {}
        for entry in doc["models"].values():
            table = np.array(entry["table"], dtype=float).reshape(entry["shape"])
            out[entry["key"]] = _Compiled(
                nodes=list(entry["nodes"]),
                edges=[list(e) for e in entry["edges"]],
                states={k: list(v) for k, v in entry["states"].items()},
                table=table,
            )
        return out
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def write_shipped_tables() -> Path:
    """Compile every shipped model with pgmpy and write ``failure_models/compiled_tables.json`` (a developer's
    step after editing a shipped model: ``python -m pyroute_rel.reliability.failure``). Returns the file's path."""
    models = {}
    for name in list_failure_models():
        toml_file = _shipped().joinpath(f"{name}.toml")
        toml_bytes = toml_file.read_bytes()
        spec = _parse_spec(tomllib.loads(toml_bytes.decode("utf-8")), str(toml_file), default_name=name)
        net_file = _sibling(toml_file, spec["network"])
        net_bytes = net_file.read_bytes()
        c = _compile(net_bytes, str(net_file), spec, str(toml_file))
        models[name] = {
            "key": _content_key(toml_bytes, net_bytes),
            "nodes": c.nodes,
            "edges": c.edges,
            "states": c.states,
            "shape": list(c.table.shape),
            "table": c.table.ravel().tolist(),
        }
    doc = {
        "about": "P(fail | evidence) of the shipped failure models, compiled with pgmpy by "
        "`python -m pyroute_rel.reliability.failure`; used only while the model files' hashes match",
        "models": models,
    }
    path = Path(str(_shipped().joinpath(_SHIPPED_TABLES)))
    tmp = path.with_suffix(".tmp")
    lines = [f" {json.dumps(name)}: {json.dumps(entry)}" for name, entry in models.items()]  # a line per model
    text = '{\n"about": ' + json.dumps(doc["about"]) + ',\n"models": {\n' + ",\n".join(lines) + "\n}}\n"
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    current_store().shelf("failure.shipped", limit=1).clear()
    return path


def _fits(compiled: _Compiled, spec: dict[str, Any]) -> bool:
    """Whether a cached entry has the table shape the model's criteria imply."""
    try:
        shape = tuple(len(compiled.states[c["node"]]) + 1 for c in spec["criteria"])
    except KeyError:
        return False
    return compiled.table.shape == shape and bool(np.all((compiled.table >= 0) & (compiled.table <= 1)))


def _disk_get(key: str) -> _Compiled | None:
    def decode(data: bytes) -> _Compiled:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            meta = json.loads(str(npz["meta"]))
            table = np.array(npz["table"], dtype=float)
        return _Compiled(
            nodes=list(meta["nodes"]),
            edges=[list(e) for e in meta["edges"]],
            states={k: list(v) for k, v in meta["states"].items()},
            table=table,
        )

    return diskcache.load(f"failure-{key}.npz", decode)  # None when absent or corrupt: compile again


def _disk_put(key: str, compiled: _Compiled) -> None:
    meta = json.dumps({"nodes": compiled.nodes, "edges": compiled.edges, "states": compiled.states})
    diskcache.write(f"failure-{key}.npz", lambda fh: np.savez(fh, table=compiled.table, meta=np.array(meta)))


if __name__ == "__main__":
    print(write_shipped_tables())
