"""One full CAN step for every backend and grid: injection, dynamics, path integration, decoding.

Each round is one ``Population.step`` call (Alg 3-5, OpenRatSLAM's step order): a local-view injection at the
packet, excitation, inhibition, global inhibition, normalisation, heading-conditional
translation plus rotation (non-zero velocity and angular velocity) and population-vector
decoding. The motion alternates its sign every step so the packet stays where the
injection is, as a robot revisiting a place; the work per step is that of a moving packet.

Run: ``python -m pytest bench/test_bench_step.py --benchmark-only``
(one backend: add ``-k numba``; names read ``test_step[<backend>-<shape>]``; ``-k`` cannot
spell the ``^`` of ``5^6`` / ``10^6``: give those as node ids,
``"bench/test_bench_step.py::test_step[numba-5^6]"``; a backend that cannot run here is a
skipped row saying why; ``test_step_threaded`` runs numba with threaded passes on the 10^6 grid).
"""

from __future__ import annotations

import numpy as np
import pytest

from cansim.backends import available_backends, backend_status, registered_backends
from cansim.errors import BackendUnavailableError
from cansim.population import Population

#: name -> (constructor, forward odometry (velocity, omega))
GRIDS = {
    "ring360": (lambda b: Population.head_direction(360, backend=b), (np.array([0.3 * 2 * np.pi / 360]), None)),
    "21x21x36": (lambda b: Population.openratslam(21, 36, backend=b), (0.3, 0.2 * 2 * np.pi / 36)),
    "61x61x36": (lambda b: Population.openratslam(61, 36, backend=b), (0.3, 0.2 * 2 * np.pi / 36)),
    "5^6": (lambda b: Population.whisker6d(5, 0.02, backend=b), (np.array([0.003, 0.002, 0.001]), np.array([0.1, 0.05, 0.02]))),
    "10^6": (lambda b: Population.whisker6d(10, 0.02, backend=b), (np.array([0.003, 0.002, 0.001]), np.array([0.1, 0.05, 0.02]))),
}


def _negate(x):
    if x is None:
        return None
    return -x if np.isscalar(x) else -np.asarray(x, dtype=np.float64)


def _run(benchmark, grid, backend, label):
    """Settle a packet on ``grid`` (with numba when available), switch to ``backend``, bench one step."""
    make, (velocity, omega) = GRIDS[grid]
    warm = "numba" if "numba" in available_backends() else backend
    pop = make(warm)
    centre = tuple(n // 2 for n in pop.shape)
    flat = np.array([np.ravel_multi_index(centre, pop.shape)], dtype=np.int64)
    injection = (flat, np.array([0.1]))
    moves = [dict(velocity=velocity, omega=omega, injection=injection),
             dict(velocity=_negate(velocity), omega=_negate(omega), injection=injection)]
    for i in range(40):  # settle into the steady packet (and compile)
        pop.step(**moves[i & 1])
    try:
        pop.set_backend(backend)
    except BackendUnavailableError as exc:  # e.g. opencl without a device
        pytest.skip(str(exc))
    pop.step(**moves[0])
    pop.step(**moves[1])
    count = [0]

    def one_step():
        count[0] += 1
        return pop.step(**moves[count[0] & 1])

    benchmark.extra_info.update(backend=label, grid=grid, cells=pop.size)
    decoded = benchmark(one_step)
    assert np.all(np.isfinite(decoded))
    assert abs(pop.total - 1.0) < 1e-4


@pytest.mark.parametrize("grid", list(GRIDS))
@pytest.mark.parametrize("backend", registered_backends())
def test_step(benchmark, backend, grid):
    usable, why = backend_status()[backend]
    if not usable:  # a row that says why, not a row that is missing
        pytest.skip(f"{backend}: {why}")
    _run(benchmark, grid, backend, backend)


@pytest.mark.parametrize("grid", ["10^6"])
def test_step_threaded(benchmark, grid):
    """numba with every pass of >= 1e6 multiply-adds on all threads (the default keeps these serial)."""
    pytest.importorskip("numba")
    from cansim.backends.numba_backend import NumbaBackend

    _run(benchmark, grid, NumbaBackend(parallel_work=1_000_000), "numba-threaded")
