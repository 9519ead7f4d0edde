"""The trade-off: sweeps, Pareto fronts, cost models, scene analysis and advice (DESIGN.md §15)."""
