"""The issue-23 protocol in cansim and in every installed NIR consumer (snnTorch, Norse, Rockpool).

Two graphs, each imported unmodified into each consumer and run beside cansim's own
simulation of the same graph (``cansim.spiking.NIRGraphSimulator``):

* the 360-cell stationary ring (``cansim.spiking.to_nir``): a Gaussian current (sigma 3
  cells, 2 threshold units) at 90 deg for 100 ms, then 1 s without input; reported: the
  population vector of the spikes 200-500 ms after the kick, the fraction of those spikes
  within 30 cells of it, the largest distance of the 100 ms population vectors from
  cansim's over the 1 s, the bump's width (circular std, cells) and mean rate;
* the path-integrating ring (``cansim.spiking.rotation_ring_graph``, ``--pi-cells`` cells):
  kick, 0.5 s for the bump to settle, then 0.8 s of a turning signal between 0 and 3 rad/s,
  handed to the graph as the command of the ring's turning calibration
  (``cansim.spiking.calibrate_turning``, measured once by cansim's simulation; the same
  commands for every consumer); reported: the RMS distance of the decoded heading from the
  integral of the signal and the angle turned.

Needs the extra ``nir-consumers``. Usage::

    python examples/nir_consumers.py [--pi-cells 120] [--out nir_consumers.json]
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from cansim.axes import Axis
from cansim.spiking import (
    HD_RING_ATTRACTOR,
    NeuronParams,
    NIRGraphSimulator,
    RotationRingParams,
    SpikingParams,
    SpikingPopulation,
    calibrate_turning,
    ring_input,
    rotation_ring_graph,
    to_nir,
)
from cansim.spiking.nir_consumers import NIR_CONSUMERS, ConsumerRunner, consumer_status
from whisker_io.command_line import CommandParser

DT = 1e-4


def _gauss(n: int, centre: float) -> np.ndarray:
    d = (np.arange(n) - centre + n / 2.0) % n - n / 2.0
    return 2.0 * np.exp(-d * d / 18.0)


def _pv_deg(counts: np.ndarray) -> float:
    ang = 2 * np.pi * np.arange(counts.size) / counts.size
    return float(np.degrees(np.arctan2(counts @ np.sin(ang), counts @ np.cos(ang))) % 360.0)


def _cdiff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def stationary(step, n: int = 360) -> dict:
    """Kick protocol on the stationary ring; per-100 ms windows of spike counts."""
    kick = _gauss(n, 90.0 * n / 360.0)
    win, acc = [], np.zeros(n)
    for k in range(int(round(1.1 / DT))):
        acc += step(kick if k < 1000 else np.zeros(n))
        if (k + 1) % 1000 == 0:
            win.append(acc)
            acc = np.zeros(n)
    w = np.array(win)
    late = w[3:6].sum(0)
    pv = _pv_deg(late)
    d = np.abs((np.arange(n) - pv * n / 360.0 + n / 2.0) % n - n / 2.0)
    held = w[1:].sum(0)
    ang = 2 * np.pi * np.arange(n) / n
    rbar = math.hypot(held @ np.cos(ang), held @ np.sin(ang)) / held.sum()
    return {
        "pv_deg": pv,
        "within_30_cells": float(late[d <= 30].sum() / late.sum()),
        "held_pv_deg": [_pv_deg(x) for x in w[1:]],
        "width_cells": math.sqrt(-2 * math.log(rbar)) * n / (2 * math.pi),
        "mean_rate_hz": float(held.sum() / (n * 1.0)),
    }


def turning(step, n: int, cal) -> dict:
    """Kick, settle 0.5 s, then omega(t) = 1.5 + 1.5 sin(2 pi t / 0.4) rad/s for 0.8 s (as ``cal.command``)."""
    kick = _gauss(n, 90.0 * n / 360.0)
    trace, decay = np.zeros(n), math.exp(-DT / 0.05)
    times, heads = [], []
    start = 0.6
    for k in range(int(round((start + 0.8) / DT))):
        t = k * DT
        om = cal.command(1.5 + 1.5 * math.sin(2 * math.pi * (t - start) / 0.4)) if t >= start else 0.0
        trace = trace * decay + step(ring_input(kick if t < 0.1 else 0.0, om, n))
        if (k + 1) % 200 == 0 and t >= start:
            times.append(t + DT - start)
            heads.append(_pv_deg(trace))
    t = np.array(times)
    truth = 90.0 + np.degrees(1.5 * t + 1.5 * 0.4 / (2 * math.pi) * (1 - np.cos(2 * math.pi * t / 0.4)))
    h = np.degrees(np.unwrap(np.radians(heads)))
    return {"rms_error_deg": float(np.sqrt(np.mean((h - truth) ** 2))), "turned_deg": float(h[-1] - h[0]),
            "integral_deg": float(truth[-1] - truth[0])}


def main(argv: list[str] | None = None) -> int:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pi-cells", type=int, default=120)
    ap.add_argument("--out", type=Path, default=Path("nir_consumers.json"))
    ap.add_argument("--no-progress", action="store_true", help="no progress line per simulator")
    args = ap.parse_args(argv)
    nrn = NeuronParams(noise_sigma=0.0, refractory_s=DT, bias_current=0.95)
    pop = SpikingPopulation((Axis.angle("heading", 360),),
                            SpikingParams(attractor=HD_RING_ATTRACTOR, neurons=nrn, recurrent_weight=15.0, global_weight=0.1),
                            dt_s=DT)
    g_still = to_nir(pop)
    pi_params = RotationRingParams(n_cells=args.pi_cells)
    g_pi = rotation_ring_graph(pi_params)
    cal = calibrate_turning(pi_params)
    status = consumer_status()
    runs = {"cansim": (lambda g: NIRGraphSimulator(g).step)}
    for name in NIR_CONSUMERS:
        if status[name][0]:
            runs[name] = (lambda g, name=name: ConsumerRunner(g, name).step)
        else:
            print(f"{name}: not run ({status[name][1]})")
    results = {}
    from tqdm import tqdm

    bar = tqdm(runs.items(), desc="simulators", unit="simulator", disable=args.no_progress)
    for name, make in bar:  # a consumer can take minutes (snnTorch, Norse: ~18 min for 60 s of a ring)
        bar.set_postfix_str(f"{name}: the held and the turning ring")
        t0 = time.perf_counter()
        results[name] = {"stationary": stationary(make(g_still)), "turning": turning(make(g_pi), args.pi_cells, cal)}
        results[name]["wall_s"] = time.perf_counter() - t0
    ref = results["cansim"]
    print("who        pv(deg)  in30   max|held-cansim|(deg)  width(cells)  rate(Hz)  turn RMS err(deg)  turned/integral(deg)  wall(s)")
    for name, r in results.items():
        s, tr = r["stationary"], r["turning"]
        dev = max(_cdiff(a, b) for a, b in zip(s["held_pv_deg"], ref["stationary"]["held_pv_deg"]))
        print(f"{name:9s} {s['pv_deg']:8.2f} {s['within_30_cells']:6.3f} {dev:14.2f} {s['width_cells']:16.2f} "
              f"{s['mean_rate_hz']:9.2f} {tr['rms_error_deg']:14.2f} {tr['turned_deg']:12.1f}/{tr['integral_deg']:.1f} "
              f"{r['wall_s']:10.1f}")
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"Wrote {args.out}.")
    return 0


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "nir_consumers"))
