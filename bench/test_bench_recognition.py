"""Identification cost per whisk against a library (issue 22 item 5: <= 2 ms at 50 objects).

``maps.surface_match.SurfaceMatcher.step``: one whisk of 8 contacts registered to every
library object's stored surface (K objects x 1,500 stored points, about 100 experiences
of 15 contacts each), K = 12, 25, 50; the library is built once per K (not timed).

Run: ``python -m pytest bench/test_bench_recognition.py --benchmark-only --benchmark-columns=min,median,rounds``
"""

from __future__ import annotations

import numpy as np
import pytest

from maps.odometry import SpatialOdometry
from maps.surface_match import SurfaceLibrary, SurfaceMatcher


def _ellipsoid_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` points on an object-sized ellipsoid (0.2 x 0.2 x 0.35 m) with 3 mm noise, metres."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return d * [0.1, 0.1, 0.175] + [0.0, 0.0, 0.175] + rng.normal(0.0, 0.003, (n, 3))


@pytest.mark.parametrize("n_objects", [12, 25, 50])
def test_surface_matcher_step_per_whisk(benchmark, n_objects):
    rng = np.random.default_rng(0)
    library = SurfaceLibrary([_ellipsoid_points(rng, 1500) for _ in range(n_objects)],
                             [f"object{i}" for i in range(n_objects)])
    matcher = SurfaceMatcher(library, [0.0, -0.3, 0.175, 0.0, 0.0, 0.0, 1.0])
    odometry = SpatialOdometry([0.005, 0.0, 0.0], [0.0, 0.0, 0.01], 1.0)
    whisk = _ellipsoid_points(rng, 8) - [0.0, -0.3, 0.175]  # 8 contacts in the end-effector frame
    for _ in range(5):  # warm-up: the tracked corrections settle
        matcher.step(odometry, whisk)
    impulses = benchmark(matcher.step, odometry, whisk)
    assert np.asarray(impulses).shape[-1] == n_objects
