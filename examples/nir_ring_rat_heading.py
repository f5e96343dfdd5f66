"""The path-integrating NIR ring driven by a recorded rat's turning (Sargolini et al. 2006; Tanni et al. 2022; via ratinabox).

The heading is the rat's movement direction: the direction of its velocity (finite
differences of the recorded positions) averaged over ``--smooth-s``, held while the
averaged speed is below ``--min-speed-m-s`` (the direction of a rat that stands still is
noise: with no hold and 0.5 s of averaging it jumps at up to 85 rad/s), then low-passed
with ``--lowpass-s``. Its derivative is the angular velocity. The ring
(``cansim.spiking.rotation_ring_graph``) gets a 100 ms kick at the first heading and then
the angular velocity, with no landmarks, as the command of a turning calibration
measured on the same ring by cansim's own simulation (``calibrate_turning``; off with
``--no-calibration``). The ring runs in cansim's own simulation (``--who cansim``) or in a
consumer (``--who snntorch|norse|rockpool``, extra ``nir-consumers``; ``--precision
float64`` runs snnTorch's or Norse's module in cansim's precision), all with the same
commands. Prints and writes the RMS heading error of the population vector (50 ms spike
window, read every 20 ms) against the heading. The recordings are read from the
installed ``ratinabox`` package at run time (``ratinabox/data/<name>.npz``).

The heading's defaults (1 s, 3 cm/s, 0.2 s) were chosen on the first 60 s of Sargolini;
other stretches (``--start-s``) and Tanni are held out.

Usage::

    python examples/nir_ring_rat_heading.py --who cansim --cells 120 --seconds 60 [--start-s 300] [--data tanni]
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np

from cansim.spiking import NIRGraphSimulator, RotationRingParams, calibrate_turning, ring_input, rotation_ring_graph
from whisker_io.command_line import CommandParser

DT = 1e-4


def rat_heading(
    seconds: float,
    *,
    start_s: float = 0.0,
    data: str = "sargolini",
    smooth_s: float = 1.0,
    min_speed_m_s: float = 0.03,
    lowpass_s: float = 0.2,
) -> tuple[np.ndarray, np.ndarray]:
    """``(time_s, heading_rad)`` (unwrapped movement direction, see the module docstring) of ``seconds`` from ``start_s``."""
    try:
        import ratinabox
    except ImportError:
        from whisker_io.errors import missing_extra

        raise missing_extra("the recorded rat heading (ratinabox's data)", "ratinabox", "rat") from None

    d = np.load(os.path.join(os.path.dirname(ratinabox.__file__), "data", f"{data}.npz"))
    t, pos = d["t"] - d["t"][0], d["pos"]
    dt = float(np.median(np.diff(t)))
    vel = np.gradient(pos, t, axis=0)
    n = max(1, int(round(smooth_s / dt)))
    k = np.ones(n) / n
    vx, vy = np.convolve(vel[:, 0], k, "same"), np.convolve(vel[:, 1], k, "same")
    direction, moving = np.arctan2(vy, vx), np.hypot(vx, vy) >= min_speed_m_s
    head = np.empty_like(direction)
    head[0] = direction[0]
    for i in range(1, head.size):  # hold while still; otherwise the shortest turn to the new direction
        step = (direction[i] - head[i - 1] + np.pi) % (2 * np.pi) - np.pi
        head[i] = head[i - 1] + (step if moving[i] else 0.0)
    if lowpass_s > 0:
        a = math.exp(-dt / lowpass_s)
        for i in range(1, head.size):
            head[i] = a * head[i - 1] + (1 - a) * head[i]
    sel = (t >= start_s - 1e-9) & (t < start_s + seconds + 1e-9)
    return t[sel] - t[sel][0], head[sel]


def run(who: str, cells: int, seconds: float, *, calibrated: bool = True, integration: str = "exact",
        precision: str = "float32", keep_trace: bool = False, **heading) -> dict:
    """Drive the ring with the rat's angular velocity; returns the RMS heading error and timing."""
    t, head = rat_heading(seconds, **heading)
    omega = np.gradient(head, t)
    params = RotationRingParams(n_cells=cells)
    cal = calibrate_turning(params) if calibrated else None
    command = cal.command(omega) if cal is not None else omega
    g = rotation_ring_graph(params)
    if who == "cansim":
        step = NIRGraphSimulator(g, integration=integration).step
    else:
        from cansim.spiking.nir_consumers import ConsumerRunner

        step = ConsumerRunner(g, who, precision=precision).step
    d = (np.arange(cells) - (math.degrees(head[0]) % 360.0) * cells / 360.0 + cells / 2) % cells - cells / 2
    kick = 2.0 * np.exp(-d * d / 18.0)
    ang = 2 * np.pi * np.arange(cells) / cells
    trace, decay = np.zeros(cells), math.exp(-DT / 0.05)
    out_t, out_h = [], []
    t0 = time.perf_counter()
    for s in range(int(round((0.1 + seconds) / DT))):
        tt = s * DT
        x = ring_input(kick, 0.0, cells) if tt < 0.1 else ring_input(0.0, float(np.interp(tt - 0.1, t, command)), cells)
        trace = trace * decay + step(x)
        if (s + 1) % 200 == 0 and tt >= 0.1:
            out_t.append(tt + DT - 0.1)
            out_h.append(math.atan2(trace @ np.sin(ang), trace @ np.cos(ang)))
    err = (np.array(out_h) - np.interp(out_t, t, head) + np.pi) % (2 * np.pi) - np.pi
    return {
        "who": who, "cells": cells, "seconds": seconds, "calibrated": calibrated,
        "integration": integration if who == "cansim" else "consumer's own", **heading,
        "precision": "float64" if who == "cansim" else precision,
        "rms_heading_error_deg": float(np.degrees(np.sqrt(np.mean(err**2)))),
        "mean_abs_omega_rad_s": float(np.abs(omega).mean()), "max_abs_omega_rad_s": float(np.abs(omega).max()),
        "calibration_max_rad_s": None if cal is None else cal.max_rad_s,
        "wall_s": time.perf_counter() - t0,
        **({"time_s": [round(v, 4) for v in out_t], "decoded_heading_rad": out_h} if keep_trace else {}),
    }


def main(argv: list[str] | None = None) -> int:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--who", default="cansim", choices=["cansim", "snntorch", "norse", "rockpool"],
                    help="who runs the NIR graph (default cansim's own simulation of it)")
    ap.add_argument("--cells", type=int, default=120, help="cells of the turning ring (default 120)")
    ap.add_argument("--seconds", type=float, default=60.0, help="seconds of the recorded trajectory to run (default 60)")
    ap.add_argument("--start-s", type=float, default=0.0, help="where in the recording to start, s (default 0)")
    ap.add_argument("--data", default="sargolini", choices=["sargolini", "tanni"],
                    help="the recorded rat trajectory (default sargolini)")
    ap.add_argument("--smooth-s", type=float, default=1.0, help="the velocity's direction averaged over this, s (default 1)")
    ap.add_argument("--min-speed-m-s", type=float, default=0.03,
                    help="below this averaged speed the heading is held, m/s (default 0.03)")
    ap.add_argument("--lowpass-s", type=float, default=0.2, help="low-pass of the heading before its derivative is taken, s (default 0.2)")
    ap.add_argument("--no-calibration", action="store_true",
                    help="hand the graph the angular velocity itself, not TurningCalibration.command of it")
    ap.add_argument("--integration", default="exact", choices=["exact", "euler"],
                    help="cansim's discretisation (euler: the consumers'; --who cansim only)")
    ap.add_argument("--precision", default="float32", choices=["float32", "float64"],
                    help="a consumer's arithmetic (float64: the same as cansim's; --who snntorch|norse|rockpool)")
    ap.add_argument("--trace", action="store_true",
                    help="also write the decoded heading every 20 ms (time_s, decoded_heading_rad) to --out")
    ap.add_argument("--out", type=Path, default=Path("rat_heading.json"))
    args = ap.parse_args(argv)
    if not (math.isfinite(args.seconds) and 0 < args.seconds <= 590):
        ap.error("--seconds must lie in (0, 590]")
    if not (math.isfinite(args.start_s) and args.start_s >= 0):
        ap.error("--start-s must be >= 0")
    if not (args.smooth_s > 0 and args.min_speed_m_s >= 0 and args.lowpass_s >= 0):
        ap.error("--smooth-s must be > 0, --min-speed-m-s and --lowpass-s >= 0")
    res = run(
        args.who, args.cells, args.seconds, calibrated=not args.no_calibration, integration=args.integration,
        precision=args.precision, keep_trace=args.trace,
        start_s=args.start_s, data=args.data,
        smooth_s=args.smooth_s, min_speed_m_s=args.min_speed_m_s, lowpass_s=args.lowpass_s,
    )
    print(json.dumps({k: v for k, v in res.items() if k not in ("time_s", "decoded_heading_rad")}))
    args.out.write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "nir_ring_rat_heading"))
