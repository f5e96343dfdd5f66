"""Identification cost per whisk against a library (issue 22 item 5: <= 2 ms at 50 objects).

``maps.surface_match.SurfaceMatcher.step``: one whisk of 8 contacts weighed by every
library object's particle filter (K objects x 1,500 stored points, about 100 experiences
of 15 contacts each, 200 hypotheses per object), K = 12, 25, 50 distinct objects
(ellipsoids of seeded sizes); the library is built once per K (not timed).

* ``steady``: after 30 whisks on object 0 (the window is full and objects whose evidence
  fell ``prune_margin`` below the best are dropped), the cost of one more whisk: what a
  presentation pays per whisk once the library has been narrowed down.
* ``all_active``: the same with pruning off (``prune_margin`` huge): every object's filter
  runs, the cost of the first ``window_whisks`` whisks of a presentation.
* ``refine`` 0 / 1: without / with the registration-refined proposal
  (``SurfaceMatchConfig.refine_iterations=1, refine_prior_scale=4``: one Levenberg-Marquardt
  step per hypothesis and whisk).

Run: ``python -m pytest bench/test_bench_recognition.py --benchmark-only --benchmark-columns=min,median,rounds``
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from maps.odometry import SpatialOdometry
from maps.surface_match import SurfaceLibrary, SurfaceMatchConfig, SurfaceMatcher


def _ellipsoid_points(rng: np.random.Generator, n: int, axes_m: np.ndarray) -> np.ndarray:
    """``n`` points on an ellipsoid with semi-axes ``axes_m`` standing on z = 0, with 3 mm noise, metres."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return d * axes_m + [0.0, 0.0, axes_m[2]] + rng.normal(0.0, 0.003, (n, 3))


def _library(n_objects: int) -> tuple[SurfaceLibrary, np.ndarray]:
    rng = np.random.default_rng(0)
    axes = np.array([0.1, 0.1, 0.175]) * rng.uniform(0.6, 1.4, (n_objects, 3))
    axes[0] = [0.1, 0.1, 0.175]
    lib = SurfaceLibrary([_ellipsoid_points(rng, 1500, a) for a in axes], [f"object{i}" for i in range(n_objects)])
    return lib, axes


_LIBRARIES: dict[int, tuple[SurfaceLibrary, np.ndarray]] = {}


@pytest.mark.parametrize("refine", [0, 1])
@pytest.mark.parametrize("mode", ["steady", "all_active"])
@pytest.mark.parametrize("n_objects", [12, 25, 50])
def test_surface_matcher_step_per_whisk(benchmark, n_objects, mode, refine):
    if n_objects not in _LIBRARIES:
        _LIBRARIES[n_objects] = _library(n_objects)
    lib, axes = _LIBRARIES[n_objects]
    rng = np.random.default_rng(1)
    cfg = SurfaceMatchConfig(refine_iterations=refine, refine_prior_scale=4.0)
    if mode == "all_active":
        cfg = replace(cfg, prune_margin=1e9)
    start = np.array([0.0, -0.3, 0.175, 0.0, 0.0, 0.0, 1.0])
    matcher = SurfaceMatcher(lib, start, cfg)
    still = SpatialOdometry([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0)
    whisk = _ellipsoid_points(rng, 8, axes[0]) - start[:3]  # 8 contacts of object 0 in the end-effector frame
    for _ in range(30):  # the window fills; pruning (steady) narrows the library
        matcher.step(still, whisk)
    impulses = benchmark(matcher.step, still, whisk)
    assert np.asarray(impulses).shape[-1] == n_objects
    benchmark.extra_info["active_objects"] = int(matcher.active.sum())
