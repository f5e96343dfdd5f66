"""The per-step loops of issue 26 item 1, runnable in any checkout (old commits included).

Times 2,000 ``Population.openratslam(backend="numba").step(0.5, 0.1, 1.0)`` (a circle of
radius 5 cells) and 2,000 ``RatSLAM(RatSLAMConfig.openratslam()).step(0.5, 0.1, 1.0, view)``
on the same circle (one view id per 12 degrees of it), each after a 50-step warm-up on a
fresh model, ``LOOP_REPS`` times (default 3, fresh models each time); prints the minimum
(ms) and the final decoded packet, so two checkouts can be compared on the same work.
It imports cansim from the CURRENT DIRECTORY (run it from the checkout's root), which
lets one script time commits that predate it. Not collected by pytest (no ``test_`` prefix).

Usage: ``cd CHECKOUT && LOOP_REPS=5 python /path/to/bench/step_loop.py [pop|slam|both]``
"""
import os, sys, time, math
from _script_args import script_args
ARGS = script_args(__doc__, "LOOP_REPS=5 python bench/step_loop.py [pop|slam|both]",
                   lambda a: len(a) <= 1 and all(x in ("pop", "slam", "both") for x in a))
sys.path.insert(0, os.getcwd())  # the tree we stand in, not the installed checkout
import numpy as np
import cansim
if os.path.dirname(os.path.dirname(os.path.abspath(cansim.__file__))) != os.getcwd():
    raise SystemExit(f"run this from a checkout's root: it times the cansim of the current directory, and here "
                     f"{os.getcwd()} has none (cansim came from {cansim.__file__})")
from cansim import Population
try:
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig
except ImportError:
    from cansim.ratslam import RatSLAM, RatSLAMConfig

N, WARM = 2000, 50
REPS = int(os.environ.get("LOOP_REPS", "3"))  # fresh model per repetition; the minimum is printed


def view(k):
    """A view id per 12 degrees of the circle (the place on it)."""
    return int(((0.1 * k) % (2 * math.pi)) / (2 * math.pi) * 30) % 30


which = ARGS[0] if ARGS else "both"
out = []
if which in ("both", "pop"):
    ts = []
    for r in range(REPS):
        pop = Population.openratslam(backend="numba")
        for k in range(WARM):
            pop.step(0.5, 0.1, 1.0)
        t0 = time.perf_counter()
        for k in range(N):
            best = pop.step(0.5, 0.1, 1.0)
        ts.append(time.perf_counter() - t0)
    out.append(f"pop {min(ts)*1e3:.1f} ms for {N} steps ({min(ts) / N * 1e6:.1f} us a step, min of {REPS}) "
               f"decoded {best.round(6).tolist()}")
if which in ("both", "slam"):
    ts = []
    for r in range(REPS):
        slam = RatSLAM(RatSLAMConfig.openratslam())
        for k in range(WARM):
            slam.step(0.5, 0.1, 1.0, view(k))
        t0 = time.perf_counter()
        for k in range(N):
            s = slam.step(0.5, 0.1, 1.0, view(WARM + k))
        ts.append(time.perf_counter() - t0)
    out.append(f"slam {min(ts)*1e3:.1f} ms for {N} steps ({min(ts) / N * 1e6:.1f} us a step, min of {REPS}) "
               f"experience {s.exp_id} packet {np.round(s.best_pc, 6).tolist()}")
print(" | ".join(out))
