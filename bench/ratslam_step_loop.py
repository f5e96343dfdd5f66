"""ms per RatSLAM.step (thread CPU), default config, ids front end, a 3,000-step loop route.

Run from a checkout to time it: ``PYTHONPATH=CHECKOUT NUMBA_NUM_THREADS=1 python bench/ratslam_step_loop.py``;
alternate two checkouts for a ratio (bench/README.md, "Per-step Python checks")."""
import math
import time

from _script_args import script_args

script_args(__doc__, "NUMBA_NUM_THREADS=1 python bench/ratslam_step_loop.py (no arguments)")

import numpy as np
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
slam = RatSLAM(RatSLAMConfig(frontend="ids"))
rng = np.random.default_rng(0)
steps = [(0.08 + 0.01 * rng.standard_normal(), 0.1 + 0.02 * rng.standard_normal(), 1.0, (k // 5) % 60) for k in range(3000)]
for s in steps[:200]:
    slam.step(*s)
best = math.inf
for rep in range(3):
    t = time.thread_time()
    for s in steps[200:]:
        slam.step(*s)
    best = min(best, (time.thread_time() - t) / 2800 * 1e3)
print(f"{best:.4f} ms per RatSLAM.step (thread CPU, minimum of 3 passes over 2,800 steps)")
