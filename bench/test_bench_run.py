"""``Population.run``: 1,000 steps in one compiled call (numba), next to canns' compiled loop.

Workloads: a 360-cell head-direction ring moving 0.3 cells per step, and a 32 x 32
sheet (two linear axes, OpenRatSLAM's kernels) moving (0.3, 0.1) cells per step; each
round is one ``Population.run`` of 1,000 steps (dynamics, shift and decoding every step).

``test_run`` times cansim alone with pytest-benchmark. ``test_run_vs_canns`` measures
both systems side by side in one session: cansim's best of several 1,000-step runs,
then canns' ``bm.jit``-compiled ``bm.for_loop`` of 1,000 ``update`` calls of ``CANN1D``
(360 neurons) and ``CANN2D`` (32 x 32) in its dense and exact-FFT modes
(``bench/canns_loop.py``, run with ``$CANNS_PYTHON``, a Python with canns installed:
canns pulls in jax and brainpy, so it lives in its own environment), then cansim again;
it records both per-step times and their ratio in ``extra_info`` (``--benchmark-json``)
and prints them. The models differ (canns integrates a rate CANN with divisive
normalisation, cansim the RatSLAM-style iteration); the workload sizes and the loop
structure are the same.

Run::

    CANNS_PYTHON=/path/to/canns-venv/bin/python \\
        .venv/bin/python -m pytest bench/test_bench_run.py --benchmark-only -s -q
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cansim.axes import Axis
from cansim.backends import available_backends
from cansim.population import Population

STEPS = 1000
HERE = Path(__file__).resolve().parent

pytestmark = pytest.mark.skipif("numba" not in available_backends(), reason="needs the numba backend")


def _ring() -> tuple[Population, np.ndarray]:
    pop = Population.head_direction(360, backend="numba")
    return pop, np.full(STEPS, 0.3 * pop.axes[0].step)  # rad/s at dt 1: 0.3 cells per step


def _sheet() -> tuple[Population, np.ndarray]:
    pop = Population([Axis.linear("x", 32, 1.0), Axis.linear("y", 32, 1.0)], backend="numba")
    return pop, np.tile([0.3, 0.1], (STEPS, 1))


WORKLOADS = {"ring360": (_ring, "ring360"), "sheet32": (_sheet, "sheet32")}


def _prepared(name: str):
    pop, velocity = WORKLOADS[name][0]()
    pop.run(velocity[:50])  # settle the packet and compile
    return pop, velocity


def _best_us_per_step(pop, velocity, repeats: int = 7) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        pop.run(velocity)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / len(velocity)


@pytest.mark.parametrize("name", sorted(WORKLOADS))
def test_run(benchmark, name):
    pop, velocity = _prepared(name)
    benchmark.extra_info["steps_per_round"] = STEPS
    decoded = benchmark.pedantic(pop.run, args=(velocity,), rounds=20, iterations=1, warmup_rounds=1)
    assert decoded.shape == (STEPS, pop.ndim)


def _canns(only: str) -> dict:
    python = os.environ.get("CANNS_PYTHON", "/work/canns-venv/bin/python")
    if not Path(python).exists():
        pytest.skip(f"canns side-by-side needs $CANNS_PYTHON (a Python with canns installed); {python} does not exist")
    proc = subprocess.run([python, str(HERE / "canns_loop.py"), "--steps", str(STEPS), "--only", only],
                          capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        pytest.skip(f"canns_loop.py failed: {proc.stderr.strip().splitlines()[-1:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("name", sorted(WORKLOADS))
def test_run_vs_canns(benchmark, name):
    pop, velocity = _prepared(name)
    canns_names = f"{name}-normal,{name}-fft"
    first = _best_us_per_step(pop, velocity)
    canns = _canns(canns_names)
    second = _best_us_per_step(pop, velocity)
    cansim_us = min(first, second)
    info = {"cansim_us_per_step": cansim_us, "canns": canns}
    for mode in ("normal", "fft"):
        canns_us = canns[f"{name}-{mode}"]["us_per_step"]
        info[f"canns_{mode}_us_per_step"] = canns_us
        info[f"speedup_vs_canns_{mode}"] = canns_us / cansim_us
    benchmark.extra_info.update(info)
    print(f"\n{name}: cansim {cansim_us:.2f} us/step; canns dense {info['canns_normal_us_per_step']:.2f} "
          f"(x{info['speedup_vs_canns_normal']:.2f}), canns fft {info['canns_fft_us_per_step']:.2f} "
          f"(x{info['speedup_vs_canns_fft']:.2f}); {canns['_versions']}", file=sys.stderr)
    benchmark.pedantic(pop.run, args=(velocity,), rounds=5, iterations=1)
