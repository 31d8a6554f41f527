"""Grid convergence: the GCI numbers and studies routed over families of grids.

Their plots are drawn by :func:`pyroute_rel.viz.convergence.plot_convergence`.

=================  ======================================================================================
module             holds
=================  ======================================================================================
``gci.numbers``    :func:`grid_convergence` (Celik et al. 2008), :func:`least_squares_convergence`
                   (Eca and Hoekstra 2014), :func:`convergence_study`
``gci.study``      families of grids (:func:`angular_levels`, :func:`square_levels`) routed by :func:`run_study`
=================  ======================================================================================
"""

from __future__ import annotations

import importlib
from typing import Any

from pyroute_rel.gci.numbers import (
    CONVERGENCE_LABELS,
    LeastSquaresResult,
    StudyResult,
    ThreeGridResult,
    convergence_study,
    grid_convergence,
    least_squares_convergence,
)

__all__ = [
    "CONVERGENCE_LABELS",
    "LeastSquaresResult",
    "StudyResult",
    "ThreeGridResult",
    "convergence_study",
    "grid_convergence",
    "least_squares_convergence",
    "RoutedStudy",
    "angular_levels",
    "square_levels",
    "run_study",
]

_LAZY = {
    "RoutedStudy": ".study",
    "angular_levels": ".study",
    "square_levels": ".study",
    "run_study": ".study",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
