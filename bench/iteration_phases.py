"""Where a whole RatSLAM iteration spends its time, per phase (issue 26 items 2-3).

Runs the routes of ``bench/cpp_compare.py`` (trace, circle, walk) through
``RatSLAM(RatSLAMConfig.openratslam(...))`` on the parity preset (exact engine) and
the generic engine, timing each phase of every step with wrappers around the parts:

* ``local view``: ``frontend.match`` + ``local_view.observe`` (+ their loop glue in ``on_view``);
* ``pose cells``: the engine's ``_step_validated`` (injection, dynamics, path integration, decode);
* ``map update``: ``ExperienceMap.update`` minus its relaxation;
* ``relax``: ``ExperienceMap.iterate``;
* ``map odo``: ``ExperienceMap.on_odo`` (dead reckoning);
* ``glue``: the rest of ``RatSLAM.step`` (validation, state, the returned ``SlamState``).

The wrappers add a few microseconds per call (measured: the ``total`` column is the
wrapped loop; ``bare`` the same loop unwrapped). Optional ``--cprofile`` prints the top
functions by own time. It imports cansim from the current directory (run it from a checkout's root, e.g. an exported older commit, with this script's path).

Usage: ``python bench/iteration_phases.py [--steps 2000] [--grid 21 --grid 61]
[--routes trace,circle,walk] [--engines openratslam,population] [--cpu] [--cprofile]``
"""
from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import time

sys.path.insert(0, os.getcwd())
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import cpp_compare as cc  # noqa: E402

sys.path.insert(0, os.getcwd())  # cpp_compare put its own checkout first: time the current directory's cansim


CLOCK = time.perf_counter  # --cpu: time.thread_time (this thread's CPU time, less sensitive to other load)


def _timed(acc: dict, key: str, fn):
    pc = CLOCK

    def wrapper(*a, **k):
        t0 = pc()
        try:
            return fn(*a, **k)
        finally:
            acc[key] += pc() - t0
    return wrapper


def run(rows, grid, cell, engine, phases: bool):
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig

    import cansim

    assert os.path.dirname(os.path.dirname(os.path.abspath(cansim.__file__))) == os.getcwd(), cansim.__file__
    slam = RatSLAM(RatSLAMConfig.openratslam(xy_cells=grid, heading_cells=36, cell_size_m=cell, pose_cells=engine))
    if hasattr(slam, "warm_up"):
        slam.warm_up()
    else:  # older checkouts: warm the kernels on a throw-away model
        RatSLAM(RatSLAMConfig.openratslam(xy_cells=grid, heading_cells=36, cell_size_m=cell,
                                          pose_cells=engine)).step(0.1, 0.0, 1.0, 0)
    acc = dict.fromkeys(("local view", "pose cells", "map update", "relax", "map odo"), 0.0)
    if phases:
        em, pc = slam.experience_map, slam.pose_cells
        slam.frontend.match = _timed(acc, "local view", slam.frontend.match)
        slam.local_view.observe = _timed(acc, "local view", slam.local_view.observe)
        pc._step_validated = _timed(acc, "pose cells", pc._step_validated)
        em.iterate = _timed(acc, "relax", em.iterate)
        em.update = _timed(acc, "map update", em.update)
        em.on_odo = _timed(acc, "map odo", em.on_odo)
    args = [(v, w, dt, (vid, rad) if has_vt else None) for has_vt, vid, rad, v, w, dt in rows]
    t0 = CLOCK()
    for v, w, dt, obs in args:
        slam.step(v, w, dt, obs)
    total = CLOCK() - t0
    acc["map update"] -= acc["relax"]
    acc["glue"] = total - sum(acc.values())
    return total, acc, slam.experience_map.n_experiences


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--grid", type=int, action="append")
    ap.add_argument("--routes", default="trace,circle,walk")
    ap.add_argument("--engines", default="openratslam,population")
    ap.add_argument("--cprofile", action="store_true")
    ap.add_argument("--cpu", action="store_true", help="time this thread's CPU time instead of the wall clock")
    a = ap.parse_args()
    global CLOCK
    if a.cpu:
        CLOCK = time.thread_time
    cases = cc.build_cases(a.routes.split(","), a.grid or [21, 61], a.steps, 0)
    keys = ("local view", "pose cells", "map update", "relax", "map odo", "glue")
    print("| route | engine | bare ms/step | wrapped ms/step | " + " | ".join(keys) + " | experiences |")
    print("|---|---|---|---|" + "---|" * len(keys) + "---|")
    for c in cases:
        for engine in a.engines.split(","):
            bare, _, _ = run(c.rows, c.xy_cells, c.cell_size_m, engine, False)
            total, acc, n_exp = run(c.rows, c.xy_cells, c.cell_size_m, engine, True)
            n = len(c.rows)
            cells = " | ".join(f"{acc[k] / n * 1e3:.3f} ({acc[k] / total * 100:.0f}%)" for k in keys)
            print(f"| {c.route} {c.xy_cells} | {engine} | {bare / n * 1e3:.3f} | {total / n * 1e3:.3f} | {cells} | {n_exp} |",
                  flush=True)
            if a.cprofile:
                prof = cProfile.Profile()
                prof.enable()
                run(c.rows, c.xy_cells, c.cell_size_m, engine, False)
                prof.disable()
                pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(18)


if __name__ == "__main__":
    main()
