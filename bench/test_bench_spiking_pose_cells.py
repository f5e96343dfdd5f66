"""Iteration cost of RatSLAM with spiking pose cells against the rate engine (issue 23 item 4).

One ``RatSLAM.step`` on the synthetic 5-loop route of ``examples/ratslam_synthetic.py``
(view ids, ``cansim.studies.ratslam_demo.CONFIG``: 21 x 21 x 36 pose cells of 0.05 m),
after 100 warm-up iterations, cycling through the route's next 300 samples.

Run: ``python -m pytest bench/test_bench_spiking_pose_cells.py --benchmark-only --benchmark-columns=min,median,rounds``.
"""

from dataclasses import replace
from itertools import cycle

import pytest

from cansim.models.ratslam import RatSLAM
from cansim.studies.ratslam_demo import CONFIG, ROUTE
from cansim.testing.worlds import make_run


@pytest.mark.parametrize("engine", ["population", "spiking"])
def test_ratslam_iteration_rate_vs_spiking_pose_cells(benchmark, engine):
    run = make_run(ROUTE, loops=(1,) * 5, seed=0)
    slam = RatSLAM(replace(CONFIG, pose_cells=engine))
    for k in range(100):
        slam.step(float(run.vtrans[k]), float(run.vrot[k]), 1.0, int(run.view_ids[k]))
    samples = cycle([(float(run.vtrans[k]), float(run.vrot[k]), 1.0, int(run.view_ids[k])) for k in range(100, 400)])

    def one():
        slam.step(*next(samples))

    benchmark.pedantic(one, rounds=200 if engine == "spiking" else 2000, iterations=1, warmup_rounds=5)
