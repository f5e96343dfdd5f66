"""RatSLAM on a synthetic 5-loop route with the thesis' Ch.3 odometry noise.

Runs a clean and a kidnapped variant (Fig 3.5: the agent is carried 10 places
forward three times), prints the Experience Metric (ARR, ARCR, Alg 1), the
Energy Metric (Eq 3.2) and the absolute trajectory errors of the relaxed
experience map and of dead reckoning, writes two figures (PNG) and
``ratslam_metrics.json`` in the working directory (or ``--out``).

Usage::

    python examples/ratslam_synthetic.py [--seed 0] [--out DIR]
    cansim demo [--seed 0] [--out DIR]          # the same, from the command line
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from cansim.testing.worlds import LoopRoute, SyntheticRun, make_run
from maps.metrics import absolute_trajectory_error, energy_metric, experience_metric
from maps.plot_maps import plot_experience_ids, plot_experience_map
from whisker_io.command_line import CommandParser

ROUTE = LoopRoute(width_m=4.0, height_m=3.0, corner_radius_m=0.75, step_m=0.05)
CONFIG = RatSLAMConfig(cell_size_m=0.05, xy_cells=21, inject_energy=0.05)


def evaluate(run: SyntheticRun, seed_label: str) -> tuple[dict, RatSLAM, np.ndarray, object]:
    """Run RatSLAM over ``run``; return the metrics, the model, the experience log and Alg 1's result."""
    slam = RatSLAM(CONFIG)
    log = slam.run(run.vtrans, run.vrot, run.dt, run.view_ids)
    estimate = slam.experience_map.poses[log.exp_ids]  # relaxed map pose of the active experience
    exm = experience_metric(log.exp_ids, run.truth, base_end=run.n_places + 1)
    metrics = {
        "ARR": exm.arr,
        "ARCR": exm.arcr,
        "EM": energy_metric(estimate, run.truth).energy,
        "ate_map": absolute_trajectory_error(estimate, run.truth).rmse,
        "ate_dead_reckoning": absolute_trajectory_error(run.dead_reckoning, run.truth).rmse,
        "experiences": slam.experience_map.n_experiences,
        "links": slam.experience_map.n_links,
        "templates": slam.n_views,
        "iterations": len(run),
    }
    print(
        f"{seed_label:>10}: ARR {metrics['ARR']:.3f}  ARCR {metrics['ARCR']:.3f}  EM {metrics['EM']:.3e}  "
        f"ATE map {metrics['ate_map']:.3f} m  ATE dead reckoning {metrics['ate_dead_reckoning']:.3f} m  "
        f"({metrics['experiences']} experiences, {metrics['links']} links)"
    )
    return metrics, slam, log.exp_ids, exm


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of the route's odometry noise and landmarks (default 0)")
    parser.add_argument("--out", type=Path, default=Path.cwd(), help="output folder (default: working directory)")
    args = parser.parse_args(argv)
    if args.seed < 0:  # numpy's default_rng raised ValueError (a traceback, exit 1)
        parser.error(f"--seed must be >= 0, got {args.seed}")
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    clean = make_run(ROUTE, loops=(1,) * 5, seed=args.seed)
    n = clean.n_places
    kidnaps = [(int((1.3 + 1.25 * j) * n), 10) for j in range(3)]
    kidnapped = make_run(ROUTE, loops=(1,) * 5, seed=args.seed, kidnap=kidnaps)

    metrics, slam, exp_log, exm = evaluate(clean, "clean")
    kid_metrics, _, kid_log, kid_exm = evaluate(kidnapped, "kidnapped")

    import matplotlib

    matplotlib.use("Agg")
    fig = plot_experience_map(slam.experience_map, clean.truth, clean.dead_reckoning, exp_log)
    fig.axes[0].set_title("Experience map after relaxation - clean run (no kidnapping)")
    fig.savefig(out / "ratslam_map.png", dpi=120)
    step = f"iteration (one odometry sample of {float(np.mean(clean.dt)):g} s)"
    fig = plot_experience_ids(exp_log, exm.relocalisation_indices, n + 1, correct_indices=exm.correct_indices)
    fig.axes[0].set_title("Experience id over time - clean run (no kidnapping)")
    fig.axes[0].set_xlabel(step)
    fig.savefig(out / "ratslam_experience_ids.png", dpi=120)
    fig = plot_experience_ids(kid_log, kid_exm.relocalisation_indices, n + 1, correct_indices=kid_exm.correct_indices)
    ax = fig.axes[0]
    for j, k in enumerate(kidnapped.kidnap_indices):
        ax.axvline(k, color="tab:purple", lw=0.8, label="kidnap (carried 10 places ahead)" if j == 0 else None)
    ax.legend(loc="upper left", fontsize="small")  # again, so that the kidnap lines are in it
    ax.set_title(f"Experience id over time - kidnapped run ({len(kidnapped.kidnap_indices)} kidnaps)")
    ax.set_xlabel(step)
    fig.savefig(out / "ratslam_experience_ids_kidnapped.png", dpi=120)

    summary = {key: float(metrics[key]) for key in ("ARR", "ARCR", "EM", "ate_map", "ate_dead_reckoning")}
    summary["kidnapped"] = {key: float(kid_metrics[key]) for key in ("ARR", "ARCR", "EM", "ate_map", "ate_dead_reckoning")}
    with open(out / "ratslam_metrics.json", "w", encoding="utf-8") as fh:
        json.dump(summary, fh, indent=2)
    print(f"map error / dead-reckoning error = {metrics['ate_map'] / metrics['ate_dead_reckoning']:.2f}")
    print(f"wrote ratslam_map.png, ratslam_experience_ids*.png, ratslam_metrics.json in {out} "
          f"in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "ratslam_demo"))
