"""Routing: the rank digraph, arc costs, the forward DP, the Route result, corridor refinement and Pareto fronts."""
