"""Several packets against one (issue 26 item 2), runnable in any checkout (old commits included).

Each loop is ``N`` ``Population.openratslam(xy, 36, backend="numba")`` steps with odometry
``(0.3, +-0.2 cells of heading)`` whose sign alternates every step (the packets stay where
they are, as a robot revisiting places), after a warm-up; ``single`` holds one packet (a
local-view injection at it every step), ``multi`` two packets far apart (one injection at
each, every step: two places recognised at once, as RatSLAM's random-walk route makes).
``step`` calls ``Population.step`` N times; ``run`` makes the same N steps in one
``Population.run``. Prints one line per case: ``case ms_per_step decoded``, the minimum of
``LOOP_REPS`` repetitions (default 5) on fresh populations, and the multi/single ratios.

It imports cansim from the CURRENT DIRECTORY (run it from the checkout's root). Not
collected by pytest (no ``test_`` prefix).

``walk`` (given as an argument, e.g. ``walk21``) times ``WALK`` whole ``RatSLAM.step`` calls of
the default (generic ``Population``) engine on a seeded random walk in a 12 m x 12 m room
whose view id is the 2 m x 2 m tile the robot stands on: revisited tiles inject at their
learnt places while the packet is elsewhere, so several packets live at once (the kind of
route issue 26 measured); prints ms per step and the final experience count.

Usage: ``cd CHECKOUT && LOOP_REPS=5 python /path/to/bench/packets_loop.py [21|61|walk21|walk61 ...]``
"""
import os, re, sys, time
from _script_args import script_args
ARGS = script_args(__doc__, "LOOP_REPS=5 python bench/packets_loop.py [21|61|walk21|walk61 ...] (grid sizes >= 7)",
                   lambda a: all(re.fullmatch(r"(walk)?\d+", x) and int(x.removeprefix("walk")) >= 7 for x in a))
sys.path.insert(0, os.getcwd())  # the tree we stand in, not the installed checkout
import numpy as np
import cansim
if os.path.dirname(os.path.dirname(os.path.abspath(cansim.__file__))) != os.getcwd():
    raise SystemExit(f"run this from a checkout's root: it times the cansim of the current directory, and here "
                     f"{os.getcwd()} has none (cansim came from {cansim.__file__})")
from cansim import Population

N, WARM = 500, 40
REPS = int(os.environ.get("LOOP_REPS", "5"))


def setup(xy, n_packets):
    pop = Population.openratslam(xy, 36, backend="numba")
    places = [(xy // 4, xy // 4, 9), (3 * xy // 4, 3 * xy // 4, 27)][:n_packets]
    flat = np.array([np.ravel_multi_index(p, pop.shape) for p in places], dtype=np.int64)
    a = np.zeros(pop.shape, dtype=np.float32)
    for p in places:
        a[p] = 1.0
    pop.activity = a / a.sum()
    inj = (flat, np.full(len(flat), 0.1))
    w = 0.2 * 2 * np.pi / 36
    moves = [(0.3, w), (-0.3, -w)]
    for k in range(WARM):
        pop.step(*moves[k & 1], 1.0, injection=inj)
    return pop, moves, inj


def loop(xy, n_packets, how):
    best = np.inf
    if how == "run":  # the run kernel compiled (or loaded) before the timing, as the step's is by setup's warm-up
        pop, moves, inj = setup(xy, n_packets)
        pop.run(np.array([moves[0][0], moves[1][0]]), np.array([moves[0][1], moves[1][1]]), 1.0, [inj] * 2)
    for _ in range(REPS):
        pop, moves, inj = setup(xy, n_packets)
        if how == "step":
            t0 = time.perf_counter()
            for k in range(N):
                pop.step(*moves[k & 1], 1.0, injection=inj)
            dt = time.perf_counter() - t0
        else:
            v = np.array([moves[k & 1][0] for k in range(N)])
            w = np.array([moves[k & 1][1] for k in range(N)])
            t0 = time.perf_counter()
            pop.run(v, w, 1.0, [inj] * N)
            dt = time.perf_counter() - t0
        best = min(best, dt)
    return best / N * 1e3, pop.decode()


WALK = 1500


def walk(xy):
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig

    best = np.inf
    for _ in range(REPS):
        rng = np.random.default_rng(3)
        slam = RatSLAM(RatSLAMConfig(xy_cells=xy))
        x = y = 6.0
        th = 0.0
        steps = []
        for k in range(WALK + WARM):
            v = 0.3
            w = float(rng.normal(0.0, 0.4))
            th += w
            x = (x + v * np.cos(th)) % 12.0
            y = (y + v * np.sin(th)) % 12.0
            steps.append((v, w, int(x // 2) * 6 + int(y // 2)))
        for v, w, view in steps[:WARM]:
            slam.step(v, w, 1.0, view)
        t0 = time.perf_counter()
        for v, w, view in steps[WARM:]:
            s = slam.step(v, w, 1.0, view)
        best = min(best, time.perf_counter() - t0)
    return best / WALK * 1e3, s


args = ARGS or ["21", "61"]
for a in [g for g in args if g.startswith("walk")]:
    t, s = walk(int(a[4:]))
    print(f"{a[4:]}x{a[4:]}x36 walk {t:.4f} ms per RatSLAM step  experiences {s.exp_id} "
          f"decoded {np.round(s.best_pc, 3).tolist()}", flush=True)
grids = [int(g) for g in args if not g.startswith("walk")]
for xy in grids:
    for how in ("step", "run"):
        t1, d1 = loop(xy, 1, how)
        t2, d2 = loop(xy, 2, how)
        print(f"{xy}x{xy}x36 {how} single {t1:.4f} ms  multi {t2:.4f} ms  multi/single {t2 / t1:.2f}  "
              f"decoded {np.round(d1, 3).tolist()} {np.round(d2, 3).tolist()}", flush=True)
