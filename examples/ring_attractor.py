"""Head-direction ring demo: integrate a turning signal, drift under noise, re-anchor on a learnt view.

A 360-cell head-direction ring (cansim.Population.head_direction) integrates an
angular-velocity signal. During a first, calibration lap the gyro is clean and the
agent learns a local-view cell for each of 8 landmarks (Eq 2.18: LV->ring weights
from the current packet). Afterwards the gyro is noisy and biased, so pure dead
reckoning drifts; each time the agent faces a known landmark the learnt view
injects energy at the remembered heading (Eq 2.17) and pulls the packet back.

Writes ``ring_attractor.png`` (activity over time with true, dead-reckoned and
decoded heading) into the output folder and prints the heading errors.

Usage::

    python examples/ring_attractor.py [--steps 1200] [--seed 0] [--backend numpy] [--out .]
"""

from __future__ import annotations

import logging
import math
import sys
from pathlib import Path

import numpy as np

from cansim import Population, registered_backends
from cansim.backends import backend_status
from cansim.local_view import LocalViewCells, LocalViewParams
from whisker_io.command_line import CommandParser

log = logging.getLogger("ring_attractor")


def wrap_deg(x: np.ndarray) -> np.ndarray:
    """Wrap angles in degrees to [-180, 180)."""
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


def run(steps: int = 1200, seed: int = 0, backend: str = "numpy", dt: float = 0.05) -> dict[str, np.ndarray]:
    """Simulate the ring; returns time series (degrees) and the activity raster."""
    rng = np.random.default_rng(seed)
    ring = Population.head_direction(360, backend=backend)
    ring.reset_cell([0])
    views = LocalViewCells(ring.shape, LocalViewParams(mode="learnt", inject_energy=1.0))
    landmarks = np.arange(0, 360, 45)  # a landmark every 45 deg of true heading
    seen: dict[int, int] = {}
    omega_true = math.radians(40.0)  # rad/s: one lap in 9 s
    true = np.zeros(steps)
    decoded = np.zeros(steps)
    dead = np.zeros(steps)
    raster = np.zeros((steps, 360), dtype=np.float32)
    anchors = []
    heading = 0.0
    dr = 0.0
    for t in range(steps):
        heading = (heading + math.degrees(omega_true) * dt) % 360.0
        lap = int((t * math.degrees(omega_true) * dt) // 360)
        # gyro: clean on the calibration lap, then 8 % scale error, bias and white noise
        omega_meas = omega_true
        if lap >= 1:
            omega_meas = omega_true * 1.08 + math.radians(2.0) + rng.normal(0.0, math.radians(10.0))
        dr = (dr + math.degrees(omega_meas) * dt) % 360.0
        injection = None
        near = np.abs(wrap_deg(landmarks - heading)) < 5.0
        if near.any():
            lm = int(np.flatnonzero(near)[0])
            if lm not in seen:
                seen[lm] = len(seen)
                views.observe(seen[lm], ring.decode())
                views.learn(ring.activity)  # first lap: associate view with the current packet
            elif lap >= 1:
                injection = views.observe(seen[lm], ring.decode())
                anchors.append(t)
        d = ring.step(velocity=omega_meas, dt=dt, injection=injection)
        true[t], dead[t] = heading, dr
        decoded[t] = math.degrees(d[0] * ring.axes[0].step)
        raster[t] = ring.activity
    return {"true": true, "decoded": decoded, "dead_reckoning": dead, "raster": raster, "anchors": np.array(anchors), "dt": dt}


def plot(res: dict[str, np.ndarray], path: Path) -> None:
    """Activity raster alone (top), true / dead-reckoned / decoded heading, error panel with re-anchorings."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    t = np.arange(len(res["true"])) * res["dt"]
    fig, (ax_a, ax0, ax1) = plt.subplots(
        3, 1, figsize=(10, 8.5), sharex=True, gridspec_kw={"height_ratios": [2, 2, 1]}
    )
    # the activity itself, nothing drawn over it: one column per step, one row per cell (1 deg)
    raster = res["raster"].T
    im = ax_a.imshow(
        raster, aspect="auto", origin="lower", interpolation="nearest",
        extent=(t[0], t[-1] + res["dt"], 0, raster.shape[0]), cmap="magma_r",
        vmin=0.0, vmax=float(np.percentile(raster, 99.9)),
    )
    ax_a.set_ylabel("ring cell = heading (deg)")
    ax_a.set_title("Activity of the 360-cell head-direction ring (darker = more active)")
    cbar = fig.colorbar(im, ax=ax_a, pad=0.01, fraction=0.03)
    cbar.set_label("cell activity\n(fraction of total)")
    ax0.plot(t, res["true"], ".", ms=1.5, color="tab:green", label="true heading")
    ax0.plot(t, res["dead_reckoning"], ".", ms=1.5, color="tab:red", label="gyro dead reckoning")
    ax0.plot(t, res["decoded"], ".", ms=1.5, color="tab:blue", label="decoded from the ring (Eq 5.11-5.12)")
    ax0.set_ylim(0, 360)
    ax0.set_ylabel("heading (deg)")
    ax0.legend(loc="upper right", markerscale=6, fontsize=8)
    ax0.set_title("Path integration: clean gyro for the first lap, then biased and noisy")
    ax1.plot(t, np.abs(wrap_deg(res["dead_reckoning"] - res["true"])), color="tab:red", lw=1)
    ax1.plot(t, np.abs(wrap_deg(res["decoded"] - res["true"])), color="tab:blue", lw=1)
    for a in res["anchors"][::4]:
        ax1.axvline(a * res["dt"], color="0.85", lw=0.5, zorder=0)
    ax1.set_ylabel("|heading error| (deg)")
    ax1.set_xlabel("time (s)")
    ax1.set_title("Heading error; learnt views re-anchor the ring at landmarks", fontsize=10)
    handles = [
        Line2D([], [], color="tab:red", lw=1, label="dead reckoning"),
        Line2D([], [], color="tab:blue", lw=1, label="ring"),
        Line2D([], [], color="0.75", lw=1, label="learnt-view injection (every 4th shown)"),
    ]
    ax1.legend(handles=handles, loc="upper left", fontsize=8)
    fig.colorbar(im, ax=[ax0, ax1], pad=0.01, fraction=0.03).remove()  # keep the x axes aligned
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--backend", default="numpy", choices=registered_backends())
    ap.add_argument("--out", type=Path, default=Path("."))
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")  # the library's INFO lines (another backend's
    log.setLevel(logging.INFO)  # probe building its OpenCL program) are not this example's; its own are
    usable, reason = backend_status()[args.backend]
    if not usable:  # one line, no traceback
        print(f"ring_attractor: backend {args.backend!r} cannot run here: {reason}", file=sys.stderr)
        return 1
    res = run(args.steps, args.seed, args.backend)
    args.out.mkdir(parents=True, exist_ok=True)
    png = args.out / "ring_attractor.png"
    plot(res, png)
    late = slice(len(res["true"]) // 2, None)
    err_ring = np.abs(wrap_deg(res["decoded"] - res["true"]))[late].mean()
    err_dr = np.abs(wrap_deg(res["dead_reckoning"] - res["true"]))[late].mean()
    print(f"mean |heading error| over the second half: ring {err_ring:.1f} deg, dead reckoning {err_dr:.1f} deg")
    print(f"wrote {png}")
    return 0


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "ring_attractor"))
