"""Simulated whisking: trimesh objects (the thesis objects, the user's own meshes
and the procedural shapes of the recognition library), the rigid sweep of every
whisker against them, the tapered-cantilever deflection signals, and the array
simulator that turns one whisk into per-module records."""
