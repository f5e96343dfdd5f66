"""Benchmarks of the whisker simulator (issue 6 part A): one whole-array sweep against the
Kettle mesh (18 whiskers x 101 angles + refinement) per ray engine, and the PFH of 18 points.

Targets: sweep <= 2 ms with Embree; PFH <= 0.5 ms.
Run: ``python -m pytest bench/test_bench_whisker_sim.py --benchmark-only``
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from whisker_io.array.geometry import WhiskerArray
from whisker_io.sim.objects import make_object
from whisker_io.features.pfh import point_feature_histogram
from whisker_io.sim.sweep import MeshTarget, embree_available, sweep_array


def _kettle_pose() -> np.ndarray:
    """Array aimed at the kettle's middle from 0.30 m; 12 of 18 whiskers touch."""
    R = Rotation.random(random_state=262).as_matrix()
    pose = np.eye(4)
    pose[:3, :3] = R
    pose[:3, 3] = np.array([0.0, 0.0, 0.15]) - R[:, 1] * 0.30
    return pose


ENGINES = [
    pytest.param("embree", marks=pytest.mark.skipif(not embree_available(), reason="embreex not installed")),
    "triangle",
]


@pytest.mark.parametrize("engine", ENGINES)
def test_sweep_kettle(benchmark, engine):
    arr = WhiskerArray.thesis()
    mesh = make_object("kettle")
    target = MeshTarget(mesh, engine)
    pose = _kettle_pose()
    sweep_array(arr, target, pose)  # build the BVH / r-tree outside the timing
    benchmark.name = f"sweep[{engine}-kettle-{len(mesh.faces)}faces-18x101]"
    contacts = benchmark(sweep_array, arr, target, pose)
    assert sum(c is not None for c in contacts) >= 6


def test_pfh_18_points(benchmark):
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.1, 0.1, (18, 3)) + [0.0, 0.25, 0.0]
    benchmark.name = "pfh[18points-81bins]"
    h = benchmark(point_feature_histogram, pts, np.zeros(3))
    assert h.valid
