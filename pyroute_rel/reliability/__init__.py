"""Reliability: failure models (criteria, Bayesian belief network, compiled tables), the largest p_f met along
arcs, exposure-based p_f and the risk field a map shades."""
