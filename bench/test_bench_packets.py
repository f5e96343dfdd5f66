"""Several packets against one (issue 26 item 2): one numba step and one 200-step run.

``single`` settles one packet, ``multi`` two packets far apart (at a quarter and three
quarters of the x and y axes, headings 9 and 27); every step injects 0.1 at each packet
(two places recognised at once, as on RatSLAM's random-walk route) and moves by
``(0.3, +-0.2 heading cells)`` with the sign alternating, so the packets stay put. The
numba backend runs each far-apart packet on its own box
(:mod:`cansim.backends._numba_packets`), so ``multi`` should cost about twice ``single``
(it cost 5-26x before).

Run: ``python -m pytest bench/test_bench_packets.py --benchmark-only``
(names read ``test_packets_step[<grid>-<single|multi>]`` and ``test_packets_run[...]``).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from cansim.population import Population  # noqa: E402

GRIDS = [21, 61]
RUN_STEPS = 200


def _settled(xy, n_packets):
    pop = Population.openratslam(xy, 36, backend="numba")
    places = [(xy // 4, xy // 4, 9), (3 * xy // 4, 3 * xy // 4, 27)][:n_packets]
    a = np.zeros(pop.shape, dtype=np.float32)
    for p in places:
        a[p] = 1.0
    pop.activity = a / a.sum()
    flat = np.array([np.ravel_multi_index(p, pop.shape) for p in places], dtype=np.int64)
    inj = (flat, np.full(len(flat), 0.1))
    w = 0.2 * 2 * np.pi / 36
    moves = [(0.3, w), (-0.3, -w)]
    for k in range(40):  # settle (and compile)
        pop.step(*moves[k & 1], 1.0, injection=inj)
    return pop, moves, inj


@pytest.mark.parametrize("packets", ["single", "multi"])
@pytest.mark.parametrize("xy", GRIDS, ids=[f"{g}x{g}x36" for g in GRIDS])
def test_packets_step(benchmark, xy, packets):
    pop, moves, inj = _settled(xy, 1 if packets == "single" else 2)
    count = [0]

    def one_step():
        count[0] += 1
        pop.step(*moves[count[0] & 1], 1.0, injection=inj)

    benchmark(one_step)
    assert pop.total == pytest.approx(1.0, abs=1e-5)


@pytest.mark.parametrize("packets", ["single", "multi"])
@pytest.mark.parametrize("xy", GRIDS, ids=[f"{g}x{g}x36" for g in GRIDS])
def test_packets_run(benchmark, xy, packets):
    pop, moves, inj = _settled(xy, 1 if packets == "single" else 2)
    v = np.array([moves[k & 1][0] for k in range(RUN_STEPS)])
    w = np.array([moves[k & 1][1] for k in range(RUN_STEPS)])
    injections = [inj] * RUN_STEPS
    benchmark(pop.run, v, w, 1.0, injections)
    assert pop.total == pytest.approx(1.0, abs=1e-5)
