"""Every figure, drawn with matplotlib's object API on an Agg canvas (pyplot is never imported): route maps
(:mod:`~pyroute_rel.viz.maps`), grid convergence, and the many-route capabilities (sweep, ensemble, tradeoff,
planners)."""
