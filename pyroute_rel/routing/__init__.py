"""Routing: the rank digraph, marching arcs through time-varying weather, arc costs, the forward DP, the Route
result, corridor refinement, Pareto fronts and the memory budget."""
