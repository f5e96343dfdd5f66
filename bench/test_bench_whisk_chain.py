"""Benchmarks of the whisk chain (issue 11 item 4): whole simulated whisks from an arm pose to
RegionFeatures, over one loop of trajectory A around an object.

* signal path: sweep + 2 kHz signals + contact detection + radial distance (tip) + FK +
  PFH/SDA, with the Sec 6.1.3.1.2 contact noise; target >= 200 whisks/s;
* sweep-only path: sweep + FK + PFH/SDA (no signal simulation), for the Ch.5/6 studies.

Each round runs every pose of the loop once; whisks/s = poses / round time (also stored in
the benchmark's extra_info).
Run: ``python -m pytest bench/test_bench_whisk_chain.py --benchmark-only``
"""

from __future__ import annotations

import numpy as np
import pytest

from whisker_io.sim.objects import make_object
from whisker_io.sim.trajectories import object_trajectory
from whisker_io.sim.whisk_chain import WhiskChain

CASES = [
    pytest.param("mug", True, id="signals-mug"),
    pytest.param("kettle", True, id="signals-kettle"),
    pytest.param("mug", False, id="sweep-mug"),
    pytest.param("kettle", False, id="sweep-kettle"),
]


@pytest.mark.parametrize("name,signals", CASES)
def test_whisk_chain_loop(benchmark, name, signals):
    mesh = make_object(name)
    poses = object_trajectory(mesh, "A", n_loops=1)
    chain = WhiskChain(mesh, signals=signals, contact_model="tip")
    rng = np.random.default_rng(0)

    def loop():
        return [chain.features(p, rng) for p in poses]

    loop()  # build the BVH and warm caches outside the timing
    benchmark.name = f"whisk_chain[{'signals' if signals else 'sweep'}-{name}-{len(poses)}whisks]"
    feats = benchmark(loop)
    stats = benchmark.stats.stats
    benchmark.extra_info["whisks"] = len(poses)
    benchmark.extra_info["whisks_per_s_min_time"] = len(poses) / stats.min
    benchmark.extra_info["whisks_per_s_median_time"] = len(poses) / stats.median
    assert sum(f.is_observation for f in feats) >= len(poses) // 3
