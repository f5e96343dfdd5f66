"""The path-integrating NIR ring driven by a recorded rat's turning (Sargolini et al. 2006, via ratinabox).

The heading is the rat's movement direction (velocity of the recorded positions, smoothed
over 0.5 s); its derivative is the angular velocity fed to the graph
(``cansim.spiking.rotation_ring_graph``) after a 100 ms kick at the first heading, with no
landmarks. The ring runs in cansim's own simulation (``--who cansim``) or in a consumer
(``--who snntorch|norse|rockpool``, extra ``nir-consumers``). Prints and writes the RMS
heading error of the population vector (50 ms spike window, read every 20 ms) against the
recorded heading. The recording is read from the installed ``ratinabox`` package at run
time (``ratinabox/data/sargolini.npz``: 600 s at 50 Hz).

Usage::

    python examples/nir_ring_rat_heading.py --who cansim --cells 120 --seconds 60 [--out rat_heading.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from cansim.spiking import NIRGraphSimulator, RotationRingParams, ring_input, rotation_ring_graph

DT = 1e-4


def rat_heading(seconds: float, smooth_samples: int = 25) -> tuple[np.ndarray, np.ndarray]:
    """``(time_s, heading_rad)`` (unwrapped movement direction) of the first ``seconds`` of the recording."""
    import ratinabox

    d = np.load(os.path.join(os.path.dirname(ratinabox.__file__), "data", "sargolini.npz"))
    t, pos = d["t"], d["pos"]
    vel = np.gradient(pos, t, axis=0)
    k = np.ones(smooth_samples) / smooth_samples
    head = np.unwrap(np.arctan2(np.convolve(vel[:, 1], k, "same"), np.convolve(vel[:, 0], k, "same")))
    sel = t < t[0] + seconds + 1e-9
    return t[sel] - t[0], head[sel]


def run(who: str, cells: int, seconds: float) -> dict:
    """Drive the ring with the rat's angular velocity; returns the RMS heading error and timing."""
    t, head = rat_heading(seconds)
    omega = np.gradient(head, t)
    g = rotation_ring_graph(RotationRingParams(n_cells=cells))
    if who == "cansim":
        step = NIRGraphSimulator(g).step
    else:
        from cansim.spiking.nir_consumers import ConsumerRunner

        step = ConsumerRunner(g, who).step
    d = (np.arange(cells) - (math.degrees(head[0]) % 360.0) * cells / 360.0 + cells / 2) % cells - cells / 2
    kick = 2.0 * np.exp(-d * d / 18.0)
    ang = 2 * np.pi * np.arange(cells) / cells
    trace, decay = np.zeros(cells), math.exp(-DT / 0.05)
    out_t, out_h = [], []
    t0 = time.perf_counter()
    for s in range(int(round((0.1 + seconds) / DT))):
        tt = s * DT
        x = ring_input(kick, 0.0, cells) if tt < 0.1 else ring_input(0.0, float(np.interp(tt - 0.1, t, omega)), cells)
        trace = trace * decay + step(x)
        if (s + 1) % 200 == 0 and tt >= 0.1:
            out_t.append(tt + DT - 0.1)
            out_h.append(math.atan2(trace @ np.sin(ang), trace @ np.cos(ang)))
    err = (np.array(out_h) - np.interp(out_t, t, head) + np.pi) % (2 * np.pi) - np.pi
    return {
        "who": who, "cells": cells, "seconds": seconds,
        "rms_heading_error_deg": float(np.degrees(np.sqrt(np.mean(err**2)))),
        "mean_abs_omega_rad_s": float(np.abs(omega).mean()), "max_abs_omega_rad_s": float(np.abs(omega).max()),
        "wall_s": time.perf_counter() - t0,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--who", default="cansim", choices=["cansim", "snntorch", "norse", "rockpool"])
    ap.add_argument("--cells", type=int, default=120)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--out", type=Path, default=Path("rat_heading.json"))
    args = ap.parse_args(argv)
    if not (math.isfinite(args.seconds) and 0 < args.seconds <= 590):
        ap.error("--seconds must lie in (0, 590]")
    res = run(args.who, args.cells, args.seconds)
    print(json.dumps(res))
    args.out.write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
