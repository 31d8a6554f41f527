"""Figures of the many-route capabilities (sweep, ensemble, tradeoff, planners), drawn with matplotlib's object API."""
