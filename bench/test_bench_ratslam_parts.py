"""Benchmarks of the RatSLAM parts: template matching, experience map, whole iterations, long runs.

Run: ``python -m pytest bench/test_bench_ratslam_parts.py --benchmark-only``.
"""

import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from cansim.frontends.tactile import TactileTemplateConfig, TactileTemplates
from cansim.frontends.visual import VisualTemplateConfig, VisualTemplates
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from cansim.testing.worlds import LoopRoute, make_run
from maps.experience_map import ExperienceMap, MapConfig
from maps.se2 import SE2Geometry

ROUTE = LoopRoute(width_m=4.0, height_m=3.0, corner_radius_m=0.75, step_m=0.05)


def _filled_visual(n, cfg):
    rng = np.random.default_rng(0)
    vt = VisualTemplates(VisualTemplateConfig(**cfg, match_threshold=0.0))
    for _ in range(n):  # similar means: the mean pre-filter skips nothing (worst case)
        vt.match(rng.integers(110, 146, size=(10 * cfg["template_height_blocks"], 4 * cfg["template_width_blocks"]), dtype=np.uint8))
    matcher = VisualTemplates(VisualTemplateConfig(**cfg, match_threshold=0.5))
    matcher.from_arrays(vt.to_arrays())
    probe = rng.integers(110, 146, size=(10 * cfg["template_height_blocks"], 4 * cfg["template_width_blocks"]), dtype=np.uint8)
    return matcher, probe


@pytest.mark.parametrize(
    "name,cfg",
    [
        ("60x10_shift5_step1", dict(template_width_blocks=60, template_height_blocks=10, shift_match_blocks=5, step_match_blocks=1)),
        ("60x10_shift25_step5_openratslam_defaults", dict(template_width_blocks=60, template_height_blocks=10, shift_match_blocks=25, step_match_blocks=5)),
    ],
)
def test_visual_template_match_1000_templates(benchmark, name, cfg):
    matcher, probe = _filled_visual(1000, cfg)
    assert len(matcher) == 1000

    def match():
        matcher.match(probe)
        matcher.store._n = 1000  # keep the store at 1,000 templates between rounds

    benchmark(match)


def test_tactile_template_match_1000_templates(benchmark):
    rng = np.random.default_rng(0)
    tt = TactileTemplates()
    for img in rng.integers(0, 256, size=(1000, 3, 6)):
        tt.store.add(img.astype(np.float64))
    probe = rng.integers(0, 256, size=(3, 6))

    def match():
        tt.match(probe)
        tt.store._n = 1000

    benchmark(match)


def _loop_map(n_exp, budget):
    em = ExperienceMap(MapConfig(relax_budget=budget, pc_shape=(1000, 1000, 36)), SE2Geometry(initial_heading_deg=0.0))
    ang = 2 * np.pi / n_exp
    for k in range(n_exp):
        em.on_odo(0.05, ang, 1.0)
        em.update((float(k), 0.0, 0.0), k, k - 1 if k else 0)
    return em


@pytest.mark.parametrize("budget", [None, 2000], ids=["openratslam_full_relaxation", "budget_2000"])
def test_experience_map_update_and_relax_1000_experiences(benchmark, budget):
    em = _loop_map(1000, budget)
    state = {"k": 0}

    def step():  # a re-localising step around the known loop (CREATE_EDGE + relaxation)
        k = state["k"] = (state["k"] + 1) % 1000
        em.on_odo(0.05, 2 * np.pi / 1000, 1.0)
        em.update((float(k), 0.0, 0.0), k, (k - 1) % 1000)

    benchmark(step)
    assert em.n_experiences == 1000


def _ratslam_with_map(cfg, n_views=1000):
    slam = RatSLAM(cfg)
    for k in range(n_views):  # a straight corridor of 1,000 views -> 1,000 experiences
        slam.step(0.5 * cfg.cell_size_m, 0.0, 1.0, k)
    return slam


@pytest.mark.parametrize(
    "label,cfg",
    [
        ("default_numba_21x21x36", RatSLAMConfig()),
        ("openratslam_parity_21x21x36", RatSLAMConfig.openratslam()),
        ("openratslam_parity_61x61x36", RatSLAMConfig.openratslam(xy_cells=61)),
        ("parity_population_engine_21x21x36", RatSLAMConfig.openratslam(pose_cells="population")),
        ("parity_population_engine_61x61x36", RatSLAMConfig.openratslam(pose_cells="population", xy_cells=61)),
    ],
)
def test_ratslam_iteration_1000_experiences(benchmark, label, cfg):
    slam = _ratslam_with_map(cfg)
    assert slam.experience_map.n_experiences >= 900
    state = {"k": 0}

    def step():
        state["k"] = (state["k"] + 1) % 1000
        slam.step(0.5 * cfg.cell_size_m, 0.0, 1.0, state["k"])

    benchmark(step)


def _long_run(n_steps):
    run = make_run(ROUTE, loops=(1,) * (n_steps // 254 + 2), seed=0)
    slam = RatSLAM(RatSLAMConfig(cell_size_m=0.05, inject_energy=0.05))
    slam.step(0.0, 0.0, 1.0, 0)
    times = np.empty(n_steps)
    for k in range(1, n_steps + 1):
        t = time.perf_counter()
        slam.step(run.vtrans[k], run.vrot[k], run.dt, int(run.view_ids[k]))
        times[k - 1] = time.perf_counter() - t
    return slam, times


def test_ratslam_20000_iterations_time_growth_and_memory(benchmark):
    """Acceptance: per-iteration time at iteration 20,000 <= 2x that at 1,000; < 200 MB."""
    slam, times = benchmark.pedantic(_long_run, args=(20_000,), rounds=1, iterations=1)
    at_1k = float(np.median(times[500:1500]))
    at_20k = float(np.median(times[-1000:]))
    tracemalloc.start()
    _long_run(20_000)
    peak_mb = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    benchmark.extra_info.update(
        median_ms_at_1000=at_1k * 1e3, median_ms_at_20000=at_20k * 1e3, growth=at_20k / at_1k,
        traced_peak_mb=peak_mb, experiences=slam.experience_map.n_experiences, links=slam.experience_map.n_links,
    )
    assert at_20k <= 2.0 * at_1k
    assert peak_mb < 200


def test_ratslam_iteration_tactile_1000_templates(benchmark):
    """The whole iteration the issue targets: Eq 3.1 matching of a 3x6 tactile image against
    1,000 stored templates + pose cells (numba, 21x21x36) + an experience map of ~1,000 experiences."""
    cfg = RatSLAMConfig(frontend=TactileTemplateConfig(match_threshold=20.0))
    slam = RatSLAM(cfg)
    rng = np.random.default_rng(0)
    images = rng.integers(0, 256, size=(1000, 3, 6), dtype=np.uint8)  # far apart: each becomes a template
    for k in range(1000):
        slam.step(0.5 * cfg.cell_size_m, 0.0, 1.0, images[k])
    assert slam.experience_map.n_experiences >= 900
    state = {"k": 0}

    def step():
        state["k"] = (state["k"] + 1) % 1000
        slam.step(0.5 * cfg.cell_size_m, 0.0, 1.0, images[state["k"]])

    benchmark(step)


def _cpp_trace_inputs():
    """Inputs of tests/data/openratslam_cpp_trace.csv (300 steps, OpenRatSLAM defaults, 0.25 m cells)."""
    path = Path(__file__).resolve().parent.parent / "tests" / "data" / "openratslam_cpp_trace.csv"
    rows = []
    with open(path, encoding="ascii") as fh:
        for line in fh:
            f = line.split(",")
            if f[0] == "S":
                hx = float.fromhex
                rows.append((hx(f[4]), hx(f[5]), hx(f[6]), (int(f[2]), hx(f[3])) if f[1] == "1" else None))
    return rows


@pytest.mark.parametrize("engine", ["openratslam", "population"])
def test_replay_cpp_trace_300_steps(benchmark, engine):
    """The 300-step C++ reference trace (revisits, panoramic offsets, ~190 experiences), whole run."""
    rows = _cpp_trace_inputs()

    def replay():
        slam = RatSLAM(RatSLAMConfig.openratslam(cell_size_m=0.25, pose_cells=engine))
        for vtrans, vrot, dt, obs in rows:
            slam.step(vtrans, vrot, dt, obs)
        return slam

    slam = benchmark.pedantic(replay, rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info["experiences"] = slam.experience_map.n_experiences
