"""The 10^6-cell 6-D step against a memory-bandwidth bound measured in the same run (issue 26 item 5).

Times ``Population.whisker6d(10, 0.02, backend="numba").step`` (the generic N-D pipeline,
``bench/test_bench_step.py``'s 10^6 case: a settled packet, injection at the centre,
translation and rotation alternating in sign) and a STREAM-like copy, alternately in one
process: ``ROUNDS`` rounds of (``COPIES`` copies, ``STEPS`` steps), the minimum of each per
round. Not collected by pytest (no ``test_`` prefix). It imports cansim from the current
directory (run it from a checkout's root to time that checkout, as ``packets_loop.py`` and
``iteration_phases.py`` do).

Bytes per step are counted from the kernel's passes (``cansim/backends/_numba_kernels.py``,
``pipeline``): every pass streams its input box in and its output box out, float64 in the
three box buffers, float32 in the grid. The boxes are measured on the state before the
step: the start box (non-zero cells and the injection, as ``start_box`` finds it), the
excitation's box (the start box grown by 2 cells a side per axis, at most the grid), the
dynamics' result box (``Population``'s dynamics on the injected state), and the step's
output box. Passes counted, in cells of the box they read and write:

* start: occupancy scan of the grid (4 B/cell read), crop into the box (4 B read, 8 B write);
* injection: rounding of the start box to float32 (8 B read + 8 B write);
* 6 excitation passes (the box grows axis by axis), 6 inhibition passes on the excitation box,
  each 8 B read + 8 B write per cell of its input and output box;
* global inhibition: e and e (*) I read, e written (24 B); normalisation: divide (16 B), round
  (16 B), occupancy scan (8 B), crop to the result box (8 B + 8 B per result cell);
* path integration: 6 passes (one per axis; the box grows on the shifted axes), 8 + 8 B per
  cell, and the rounding at the end (16 B per output cell);
* scatter: the grid zeroed (4 B/cell) and the output box placed (8 B read, 4 B write per cell).

The copy: ``np.copyto`` of a float64 array of 10^6 cells (8 MB, one box buffer: the bound is
judged against it), counted as 16 B per cell (read + write, STREAM's convention, no
write-allocate); also of 2 x 10^6 cells (16 MB arrays, a 32 MB footprint like the step's
three 8 MB box buffers and two 4 MB grids) and of 32 x 10^6 cells (256 MB, main memory).

Times are thread CPU time by default (``CLOCK=wall`` for wall time; see :func:`_timed`).

Usage: ``python bench/step_bandwidth.py`` (env ``ROUNDS`` default 7, ``STEPS`` 20, ``CLOCK`` cpu).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.getcwd())  # the checkout this is run from, not the installed one

import cansim  # noqa: E402

assert os.path.dirname(os.path.dirname(os.path.abspath(cansim.__file__))) == os.getcwd(), (
    f"run this from a checkout's root: cansim was imported from {cansim.__file__}")

from cansim.population import Population  # noqa: E402

ROUNDS = int(os.environ.get("ROUNDS", "7"))
STEPS = int(os.environ.get("STEPS", "20"))
COPIES = 20
CLOCK = os.environ.get("CLOCK", "cpu")


def _arc(occ: np.ndarray) -> int:
    """Length of the shortest cyclic arc covering the occupied cells of one axis."""
    n = occ.size
    idx = np.flatnonzero(occ)
    if idx.size == 0:
        return 0
    gaps = np.diff(np.concatenate([idx, [idx[0] + n]]))
    return int(n - (gaps.max() - 1))


def box(a: np.ndarray, extra: tuple[int, ...] | None = None) -> np.ndarray:
    """Extent per axis of the tight cyclic box of the non-zero cells (and of one extra cell)."""
    nz = a != 0
    out = []
    for k in range(a.ndim):
        occ = nz.any(axis=tuple(j for j in range(a.ndim) if j != k))
        if extra is not None:
            occ = occ.copy()
            occ[extra[k]] = True
        out.append(_arc(occ))
    return np.array(out)


def bytes_per_step(n: np.ndarray, b0: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> tuple[float, dict]:
    """Bytes the pipeline's passes stream for start box b0, dynamics result box b1, output box b2."""
    N = float(np.prod(n))
    parts = {}
    c0 = float(np.prod(b0))
    parts["start + inject"] = 4 * N + (4 + 8) * c0 + 16 * c0
    m = b0.copy()
    exc = 0.0
    for k in range(len(n)):
        cin = float(np.prod(m))
        m[k] = min(n[k], m[k] + 4)
        exc += 8 * cin + 8 * float(np.prod(m))
    parts["excitation (6 passes)"] = exc
    E = float(np.prod(m))
    parts["inhibition (6 passes)"] = 6 * 16 * E
    c1 = float(np.prod(b1))
    parts["global inhibition + normalisation"] = 24 * E + 16 * E + 16 * E + 8 * E + (16 * c1 if c1 < E else 0.0)
    m = b1.copy()
    sh = 0.0
    for k in range(len(n)):
        cin = float(np.prod(m))
        m[k] = max(m[k], b2[k])
        sh += 8 * cin + 8 * float(np.prod(m))
    c2 = float(np.prod(b2))
    parts["path integration (6 passes + round)"] = sh + 16 * c2
    parts["scatter"] = (4 * N + 12 * c2) if c2 < N else 12 * N
    return sum(parts.values()), parts


def main() -> None:
    v, w = np.array([0.003, 0.002, 0.001]), np.array([0.1, 0.05, 0.02])
    pop = Population.whisker6d(10, 0.02, backend="numba")
    centre = tuple(k // 2 for k in pop.shape)
    flat = np.array([np.ravel_multi_index(centre, pop.shape)], dtype=np.int64)
    inj = (flat, np.array([0.1]))
    moves = [dict(velocity=v, omega=w, injection=inj), dict(velocity=-v, omega=-w, injection=inj)]
    for i in range(40):
        pop.step(**moves[i & 1])
    n = np.array(pop.shape)
    a = pop.activity.copy()
    b0 = box(a, centre)
    injected = a.astype(np.float64)
    injected[centre] += 0.1
    dyn = pop._backend.dynamics(injected.astype(a.dtype), pop._exc, pop._inh, pop._phi)
    b1 = box(dyn)
    count = [0]

    def step() -> None:
        count[0] += 1
        pop.step(**moves[count[0] & 1])

    step()
    b2 = box(pop.activity)
    total, parts = bytes_per_step(n, b0, b1, b2)
    src, dst = np.random.default_rng(0).random(pop.size), np.empty(pop.size)
    ws_src, ws_dst = np.ones(2 * pop.size), np.empty(2 * pop.size)
    big_src, big_dst = np.ones(32 * pop.size), np.empty(32 * pop.size)
    print(f"grid {tuple(int(k) for k in n)}, boxes: start {b0.tolist()}, dynamics result {b1.tolist()}, "
          f"output {b2.tolist()}")
    for k, val in parts.items():
        print(f"  {k:40s} {val / 1e6:8.1f} MB")
    print(f"bytes per step (passes): {total / 1e6:.1f} MB; compulsory (read + write the float32 grid once): "
          f"{8 * pop.size / 1e6:.1f} MB")
    ratios, rows = [], []
    for r in range(ROUNDS):
        tc = min(_timed(lambda: np.copyto(dst, src)) for _ in range(COPIES))
        tw = min(_timed(lambda: np.copyto(ws_dst, ws_src)) for _ in range(COPIES // 2))
        tb = min(_timed(lambda: np.copyto(big_dst, big_src)) for _ in range(3))
        ts = min(_timed(step) for _ in range(STEPS))
        bw, bw_ws, bw_big = 16 * pop.size / tc, 16 * ws_src.size / tw, 16 * big_src.size / tb
        bound = total / bw
        ratios.append((ts / bound, ts / (total / bw_ws), ts / (total / bw_big), ts / (8 * pop.size / bw)))
        print(f"round {r}: step {ts * 1e3:.2f} ms; copy GB/s 8 MB {bw / 1e9:.1f}, 16 MB {bw_ws / 1e9:.1f}, "
              f"256 MB {bw_big / 1e9:.1f}; bound (8 MB copy) {bound * 1e3:.2f} ms; step/bound "
              f"{ratios[-1][0]:.2f} (8 MB), {ratios[-1][1]:.2f} (16 MB), {ratios[-1][2]:.2f} (256 MB); "
              f"step/compulsory {ratios[-1][3]:.0f}")
    med = np.median(np.array(ratios), axis=0)
    print(f"median step/bound: {med[0]:.2f} against the 8 MB copy, {med[1]:.2f} against the 16 MB copy "
          f"(32 MB footprint, the step's working set), {med[2]:.2f} against the 256 MB copy; "
          f"{med[3]:.0f}x the compulsory bound; clock {CLOCK}; load {os.getloadavg()[0]:.2f}")


def _timed(fn) -> float:
    """Seconds of ``fn()``: thread CPU time (``CLOCK`` = "cpu", the default: a 25-ms step on a
    shared machine is preempted where a 0.2-ms copy is not, which wall time would charge to the
    step) or wall time (``CLOCK`` = "wall")."""
    clock = time.perf_counter if CLOCK == "wall" else time.thread_time
    t0 = clock()
    fn()
    return clock() - t0


if __name__ == "__main__":
    from _script_args import script_args

    script_args(__doc__, "python bench/step_bandwidth.py (no arguments; run from a checkout's root)")
    main()
