"""Figures (matplotlib): the shared axes helper, the 3-D scene and the whisk signals."""
