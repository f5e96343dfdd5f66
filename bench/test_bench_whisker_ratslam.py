"""WhiskerRatSLAM iteration with given features (issue target <= 0.5 ms at 5^6, 1,000 regions, 1,000 experiences).

Run: ``python -m pytest bench/test_bench_whisker_ratslam.py --benchmark-only``.
"""

import numpy as np
import pytest

from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig
from maps.odometry import SpatialOdometry


def _filled(n_regions: int, backend: str, preset: str = "thesis") -> tuple[WhiskerRatSLAM, list]:
    """A model after ``n_regions`` whisks, each a new region and a new experience."""
    rng = np.random.default_rng(0)
    slam = WhiskerRatSLAM(getattr(WhiskerRatSLAMConfig, preset)(backend=backend, relax_budget=2_000))
    regions = [(rng.dirichlet(np.full(81, 0.2)), rng.normal(0, 1, 18)) for _ in range(n_regions)]
    odo = [SpatialOdometry(rng.normal(0, 0.08, 3), rng.normal(0, 0.2, 3), 1.0) for _ in range(n_regions)]
    for o, r in zip(odo, regions):
        slam.step(o, r)
    return slam, regions


@pytest.mark.parametrize("preset", ["thesis", "mapping"])
@pytest.mark.parametrize("backend", ["numba"])
def test_iteration_with_features_1000_regions_1000_experiences(benchmark, backend, preset):
    """``thesis``: Eq 5.5 matching; ``mapping``: with the pose prior (gate over 1,000 experiences)."""
    slam, regions = _filled(1_000, backend, preset)
    assert slam.n_views >= 990 and slam.object_map.n_experiences >= 990
    rng = np.random.default_rng(1)
    odo = SpatialOdometry([0.05, 0.0, 0.0], [0.0, 0.0, 0.1], 1.0)
    probes = [regions[int(k)] for k in rng.integers(0, len(regions), 64)]
    state = {"i": 0}

    def one():
        slam.step(odo, probes[state["i"] % len(probes)])
        state["i"] += 1

    benchmark.pedantic(one, rounds=200, iterations=1, warmup_rounds=5)
