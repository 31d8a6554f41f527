"""Other planners on the same routing problem as the DP: MCTS-UCT, tabular Q-learning and a DQN.

One module per planner (:mod:`.dp`, :mod:`.mcts`, :mod:`.qlearning`, :mod:`.dqn`), what they share in
:mod:`.base` (the :class:`~pyroute_rel.planners.base.Planner` protocol), their settings (the scenario's
``[planner]`` table) in :mod:`.settings`, and :func:`pyroute_rel.planners.plan.plan` to run the scenario's planner.
Each returns a track; :func:`pyroute_rel.analysis.evaluate.evaluate_track` re-times it, so their figures compare.

This package's ``__init__`` imports nothing: the scenario reader uses :mod:`.settings` alone.
"""
