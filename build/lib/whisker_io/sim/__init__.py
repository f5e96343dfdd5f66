"""Simulated whisking: trimesh objects, the rigid sweep of every whisker against
them, the tapered-cantilever deflection signals, and the array simulator that
turns one whisk into per-module records."""
