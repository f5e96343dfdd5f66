"""Whisks/s of the whisk chain's signal path, runnable in any checkout (issue 26 item 5).

The loop of ``bench/test_bench_whisk_chain.py`` (``WhiskChain(mesh, signals=True,
contact_model="tip").features`` at every pose of one loop of trajectory A, seed 0), after one
uncounted loop; prints whisks / (minimum CPU time of ``ROUNDS`` loops) per object. CPU time
(``time.process_time``), not wall time, because the machine it was measured on was shared
(load average 3-6 on 2 cores): wall time then measures the share of the CPU, not the code.
It imports the packages of the CURRENT DIRECTORY (run it from the checkout's root), so two
checkouts can be run alternately on the same work. Not collected by pytest.

Usage: ``cd CHECKOUT && python /path/to/bench/whisk_rate.py [mug,kettle] [ROUNDS]``
"""
import os
import re
import sys
import time

from _script_args import script_args

ARGS = script_args(__doc__, "python bench/whisk_rate.py [OBJECT,OBJECT,...] [ROUNDS]",
                   lambda a: len(a) <= 2 and (len(a) < 2 or bool(re.fullmatch(r"[1-9]\d*", a[1]))))

sys.path.insert(0, os.getcwd())  # the tree we stand in, not the installed checkout
import numpy as np  # noqa: E402

import whisker_io  # noqa: E402

if os.path.dirname(os.path.dirname(os.path.abspath(whisker_io.__file__))) != os.getcwd():
    raise SystemExit(f"run this from a checkout's root: it times the whisker_io of the current directory, and here "
                     f"{os.getcwd()} has none (whisker_io came from {whisker_io.__file__})")
from whisker_io.sim.objects import make_object  # noqa: E402
from whisker_io.sim.trajectories import object_trajectory  # noqa: E402
from whisker_io.sim.whisk_chain import WhiskChain  # noqa: E402

names = ARGS[0].split(",") if ARGS else ["mug", "kettle"]
rounds = int(ARGS[1]) if len(ARGS) > 1 else 5
out = []
for name in names:
    mesh = make_object(name)
    poses = object_trajectory(mesh, "A", n_loops=1)
    chain = WhiskChain(mesh, signals=True, contact_model="tip")
    rng = np.random.default_rng(0)
    [chain.features(p, rng) for p in poses]
    best = np.inf
    for _ in range(rounds):
        t0 = time.process_time()
        [chain.features(p, rng) for p in poses]
        best = min(best, time.process_time() - t0)
    out.append(f"{name}={len(poses) / best:.1f}")
print(" ".join(out))
