"""Compiled code (numba), private to the package.

Every kernel has a numpy twin in the layer that calls it (the Q-learning loop a route it must find instead); each
module's docstring names the twin and the test that pins the two together. ``sampling`` sits with the weather layer
(it imports nothing of the package); the others sit above the boat and reliability layers whose constants they use.

- ``_kernels.cost``: the arithmetic of :mod:`pyroute_rel.routing.cost` for gridded weather;
- ``_kernels.crossings``: :mod:`pyroute_rel.reliability.crossings` (the largest p_f along an arc, in patches);
- ``_kernels.dp``: one rank of :func:`pyroute_rel.routing.solve.forward_dp`;
- ``_kernels.front``: the voyage front's non-dominated labels (:mod:`pyroute_rel.routing.tradeoff`);
- ``_kernels.march``: :func:`pyroute_rel.boat.march.march` on gridded wind;
- ``_kernels.polar``: the polar lookup of :mod:`pyroute_rel.boat.polar`, for the other kernels;
- ``_kernels.mcts``: the search of :mod:`pyroute_rel.planners.mcts`;
- ``_kernels.qlearning``: the learning loop of :mod:`pyroute_rel.planners.qlearning`;
- ``_kernels.sampling``: gridded weather's sampling and decoding (:mod:`pyroute_rel.weather.gridded`,
  :mod:`pyroute_rel.weather.io.readers`).
"""
