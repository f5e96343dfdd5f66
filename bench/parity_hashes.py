"""SHA-256 of every ``cpp_compare.py`` route's outputs on the exact engine (bit-identity check across commits).

Runs each route (trace; circle and walk at 21 and 61, 2,000 steps, seed 0) through
``RatSLAM(RatSLAMConfig.openratslam(...))`` (``pose_cells="openratslam"`` unless
``--engine`` says otherwise) and prints one line per route: the SHA-256 of the per-step
decoded pose (float64 bytes), the per-step experience id / counts / action (int64
bytes) and the final map's poses and links. Run it from a checkout's root (it imports
that checkout's cansim, like ``iteration_phases.py``) in two checkouts and compare the
lines: equal lines mean bit-identical runs.

Usage: ``python bench/parity_hashes.py [--steps 2000] [--engine openratslam]``
"""
from __future__ import annotations

import argparse
import hashlib
import os
import sys

sys.path.insert(0, os.getcwd())
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import cpp_compare as cc  # noqa: E402

sys.path.insert(0, os.getcwd())  # cpp_compare put its own checkout first: hash the current directory's cansim


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--engine", default="openratslam")
    a = ap.parse_args()
    import cansim

    print(f"# cansim from {os.path.dirname(cansim.__file__)}")
    for c in cc.build_cases(["trace", "circle", "walk"], [21, 61], a.steps, 0):
        _, out = cc.run_cansim(c.rows, c.xy_cells, c.heading_cells, c.cell_size_m, a.engine)
        h = hashlib.sha256()
        for arr in (out.best, out.counts, out.poses, out.links):
            h.update(str(arr.shape).encode())
            h.update(arr.tobytes())
        print(f"{c.route} {c.xy_cells}: {h.hexdigest()}  ({out.poses.shape[0]} experiences)", flush=True)


if __name__ == "__main__":
    main()
