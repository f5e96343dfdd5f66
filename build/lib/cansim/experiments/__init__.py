"""Canonical attractor experiments: one sweep cell each, ``run(params, seed) -> dict``.

Each module is one experiment with ``DEFAULTS`` (the parameters, units in their names),
``run(params, seed)`` returning flat metrics (and the parameters it used) for one
parameter set, deterministic for a seed, and ``figure(results)`` plotting a list of
``run`` results. A sweep spec names one as ``experiment = "cansim.experiments.NAME:run"``;
``examples/sweeps/NAME.toml`` holds a small grid for each.

* :mod:`~cansim.experiments.bump` - packet width and amplitude vs kernel widths and
  global inhibition (Alg 3-5);
* :mod:`~cansim.experiments.diffusion` - drift and diffusion of the packet under input noise;
* :mod:`~cansim.experiments.integration_gain` - path-integration linearity and gain in
  1-D, 3-D and 6-D, with shifts alone and with attractor dynamics (Fig 5.11);
* :mod:`~cansim.experiments.reanchoring` - re-anchoring time after a view injection vs
  its energy and offset (Eq 5.8);
* :mod:`~cansim.experiments.lv_interference` - interference of learnt LV -> pose-cell
  weights as the number of stored views grows (Eq 2.17-2.18).

Importing this package imports none of them.
"""

__all__ = ["bump", "diffusion", "integration_gain", "reanchoring", "lv_interference"]
