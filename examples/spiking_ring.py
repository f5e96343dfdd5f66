"""Spiking head-direction ring beside the rate ring: path integration of a turning signal.

A 360-neuron LIF ring (cansim.spiking) and the 360-cell rate ring
(``cansim.Population.head_direction(360)``) share one set of excitation / inhibition
kernels (``cansim.spiking.HD_RING_ATTRACTOR``). Both integrate the same angular
velocity for 60 s: the rate ring by shifting its packet (Fig 5.11), the spiking ring by
velocity-shifted recurrent synapses (Zhang 1996) whose gain is calibrated first. The
spiking heading is the population vector of the spike counts in a 50 ms sliding window.

Writes into the output folder:

* ``spiking_ring.png`` - spike raster with the true heading and both decoded headings,
  and the heading errors;
* ``spiking_ring.nir`` - the spiking ring's stationary network as a NIR graph
  (``cansim.spiking.to_nir``), written in the conventions snnTorch, Norse and Rockpool
  read: load it with ``snntorch.import_nir.import_from_nir(graph)``,
  ``norse.torch.from_nir(graph, dt=1e-4)`` or ``rockpool.nn.modules.torch.nir.from_nir(graph)``;
  its input is a current per cell (threshold units), its output the spikes, one step 0.1 ms;
* ``spiking_ring_pi.nir`` - a 360-cell ring that path-integrates inside the graph
  (``cansim.spiking.rotation_ring_graph``: rotation cells driven by the angular velocity);
  input: a current per ring cell, then the angular velocity (rad/s);
* ``spiking_ring_metrics.json`` - ``rms_vs_true_deg``, ``rms_vs_rate_deg``,
  ``rate_rms_vs_true_deg``, spike counts and timing.

Usage::

    python examples/spiking_ring.py [--duration-s 60] [--seed 0] [--quick] [--out .]
"""

from __future__ import annotations

import importlib.util
import json
import logging
import math
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from cansim import Population
from cansim.spiking import HD_RING_ATTRACTOR, RotationRingParams, SpikeCountDecoder, rotation_ring_graph, spiking_from_rate, to_nir
from whisker_io.command_line import CommandParser

log = logging.getLogger("spiking_ring")

#: speeds (cells/s = deg/s on a 360-cell ring) at which the velocity gain is calibrated
CALIBRATION_SPEEDS = (3.0, 6.0, 10.0, 20.0, 40.0, 70.0, 110.0, 160.0, 240.0)


def turning_signal_rad_s(time_s: np.ndarray) -> np.ndarray:
    """The agent's angular velocity (rad/s): two sinusoids of 90 and 40 deg/s on a 10 deg/s drift."""
    t = np.asarray(time_s, dtype=np.float64)
    return np.radians(90.0 * np.sin(2 * np.pi * t / 12.0) + 40.0 * np.sin(2 * np.pi * t / 5.0 + 1.0) + 10.0)


def wrap_deg(x: np.ndarray) -> np.ndarray:
    """Angles in degrees wrapped to [-180, 180)."""
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


def run(duration_s: float = 60.0, seed: int = 0, quick: bool = False, progress: bool = True) -> dict:
    """Simulate both rings; returns time series in degrees, the spikes and the spiking population."""
    dt_s, rate_every, decode_every = 0.001, 10, 50  # steps: rate ring at 100 Hz, decoding at 20 Hz
    ring = Population.head_direction(360, params=HD_RING_ATTRACTOR, backend="numba")
    speeds = CALIBRATION_SPEEDS[::2] if quick else CALIBRATION_SPEEDS
    t_cal = time.perf_counter()
    spk = spiking_from_rate(ring, dt_s=dt_s, seed=seed, calibrate_speeds_cells_per_s=speeds)
    t_cal = time.perf_counter() - t_cal
    decoder = SpikeCountDecoder(spk.axes, window_steps=50, half_width=10)
    ring.reset_cell([0])
    spk.kick([0.0])
    for _ in range(300):  # let the spiking packet settle at 0 deg before the agent moves
        decoder.add(spk.step())
    n = int(round(duration_s / dt_s))
    omega = turning_signal_rad_s(np.arange(n) * dt_s)
    true = np.degrees(np.cumsum(omega) * dt_s) % 360.0
    times, spiking, rate, truth = [], [], [], []
    spike_t, spike_i = [], []
    rate_deg = 0.0
    t_run = time.perf_counter()
    for k in tqdm(range(n), desc="spiking ring", unit="step", unit_scale=True, disable=not progress, mininterval=0.5):
        s = spk.step(omega[k])
        decoder.add(s)
        spike_t.append(np.full(len(s), k * dt_s))
        spike_i.append(s)
        if (k + 1) % rate_every == 0:
            d = ring.step(velocity=float(omega[k + 1 - rate_every : k + 1].mean()), dt=rate_every * dt_s)
            rate_deg = float(np.degrees(d[0] * ring.axes[0].step))
        if (k + 1) % decode_every == 0:
            times.append((k + 1) * dt_s)
            spiking.append(float(np.degrees(decoder.decode_physical()[0])))
            rate.append(rate_deg)
            truth.append(true[k])
    t_run = time.perf_counter() - t_run
    spiking_a, rate_a, truth_a = map(np.array, (spiking, rate, truth))
    return {
        "time_s": np.array(times),
        "spiking_deg": spiking_a,
        "rate_deg": rate_a,
        "true_deg": truth_a,
        "spike_time_s": np.concatenate(spike_t),
        "spike_cell": np.concatenate(spike_i),
        "population": spk,
        "metrics": {
            "rms_vs_true_deg": float(np.sqrt(np.mean(wrap_deg(spiking_a - truth_a) ** 2))),
            "rms_vs_rate_deg": float(np.sqrt(np.mean(wrap_deg(spiking_a - rate_a) ** 2))),
            "rate_rms_vs_true_deg": float(np.sqrt(np.mean(wrap_deg(rate_a - truth_a) ** 2))),
            "duration_s": float(duration_s),
            "n_neurons": spk.size,
            "n_spikes": int(sum(len(s) for s in spike_i)),
            "mean_rate_hz": float(sum(len(s) for s in spike_i) / (spk.size * duration_s)),
            "calibration_wall_s": t_cal,
            "simulation_wall_s": t_run,
            "seed": seed,
            "quick": quick,
        },
    }


def plot(res: dict, path: Path) -> None:
    """Spike raster (top), true and decoded headings (middle), heading errors (bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = res["time_s"]
    fig, (ax_r, ax0, ax1) = plt.subplots(3, 1, figsize=(11, 8.5), sharex=True, gridspec_kw={"height_ratios": [2, 2, 1]})
    ax_r.scatter(res["spike_time_s"], res["spike_cell"], s=0.6, c="k", marker=".", lw=0)
    ax_r.set_ylim(0, 360)
    ax_r.set_ylabel("cell (= preferred heading, deg)")
    ax0.plot(t, res["true_deg"], ".", ms=2.0, color="tab:green", label="true heading")
    ax0.plot(t, res["rate_deg"], ".", ms=1.6, color="tab:orange", label="rate ring (decoded)")
    ax0.plot(t, res["spiking_deg"], ".", ms=1.6, color="tab:blue", label="spiking ring (decoded, 50 ms window)")
    ax0.set_ylim(0, 360)
    ax0.set_ylabel("heading (deg)")
    ax0.legend(loc="upper right", markerscale=5, fontsize=8)
    ax0.set_title("true heading and the heading decoded from each ring", fontsize=10)
    m = res["metrics"]
    ax_r.set_title(
        f"spike raster (one dot per spike); 360-neuron spiking HD ring vs rate ring: RMS {m['rms_vs_true_deg']:.1f} deg vs true, "
        f"{m['rms_vs_rate_deg']:.1f} deg vs rate"
    )
    ax1.plot(t, wrap_deg(res["spiking_deg"] - res["true_deg"]), color="tab:blue", lw=1, label="spiking - true")
    ax1.plot(t, wrap_deg(res["rate_deg"] - res["true_deg"]), color="tab:orange", lw=1, label="rate - true")
    ax1.axhline(0, color="0.7", lw=0.5)
    ax1.set_ylabel("error (deg)")
    ax1.set_xlabel("time (s)")
    ax1.legend(loc="upper left", fontsize=8)
    ax1.set_title("decoded minus true heading", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_graphs(out: Path, population) -> list[Path]:
    """Write ``spiking_ring.nir`` (``to_nir(population)``) and ``spiking_ring_pi.nir`` (the rotation ring) into ``out``
    (needs the ``spiking`` extra: ``main`` checks it before simulating)."""
    import nir

    paths = [out / "spiking_ring.nir", out / "spiking_ring_pi.nir"]
    nir.write(paths[0], to_nir(population))
    nir.write(paths[1], rotation_ring_graph(RotationRingParams(n_cells=360)))
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=None, help="simulated seconds (default 60, 10 with --quick)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="10 s and a coarser calibration (for tests)")
    ap.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ap.add_argument("--out", type=Path, default=Path("."))
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    duration = args.duration_s if args.duration_s is not None else (10.0 if args.quick else 60.0)
    if not (math.isfinite(duration) and duration > 0):
        ap.error("--duration-s must be a positive number of seconds")
    with_nir = importlib.util.find_spec("nir") is not None  # checked before the simulation, not after it
    if not with_nir:
        print('spiking_ring: the NIR files need the spiking extra (pip install "cansim[spiking]"); '
              "writing the figure and the metrics only", file=sys.stderr)
    res = run(duration, args.seed, args.quick, progress=not args.no_progress)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(res, args.out / "spiking_ring.png")
    if with_nir:
        write_graphs(args.out, res["population"])
    (args.out / "spiking_ring_metrics.json").write_text(json.dumps(res["metrics"], indent=2) + "\n")
    m = res["metrics"]
    print(f"The spiking ring tracked the heading with an RMS error of {m['rms_vs_true_deg']:.2f} deg "
          f"({m['rms_vs_rate_deg']:.2f} deg from the rate ring, which is {m['rate_rms_vs_true_deg']:.2f} deg from the truth); "
          f"{m['n_spikes']} spikes, {m['mean_rate_hz']:.1f} Hz mean rate.")
    files = ("spiking_ring.png",) + (("spiking_ring.nir", "spiking_ring_pi.nir") if with_nir else ()) + ("spiking_ring_metrics.json",)
    print("Wrote " + ", ".join(str(args.out / f) for f in files) + ".")
    return 0


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "spiking_ring"))
