"""Figures (matplotlib): the shared axes helper (``axes``, also used by
``whisker_io.radial.plots`` and ``maps.plot_maps``), the 3-D scene and the whisk signals."""
