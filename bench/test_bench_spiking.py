"""One step of a spiking attractor population (cansim.spiking), numba and the numpy reference.

Each round is one ``SpikingPopulation.step`` with a non-zero velocity (so the recurrent
kernel is shifted every step, as during path integration) and membrane noise: drawing
the noise, scattering the last step's spikes through the kernel, the synaptic and
membrane update of every cell. The packet is seeded and settled first, so the work is
that of a live packet. The spikes per step are recorded in ``extra_info``.

Run: ``python -m pytest bench/test_bench_spiking.py --benchmark-only``
(names read ``test_spiking_step[<backend>-<grid>-<noise>]``; ``noiseless`` sets
``noise_sigma = 0`` to show what drawing the Gaussian membrane noise costs).
"""

from __future__ import annotations

import numpy as np
import pytest

from cansim.population import Population
from cansim.spiking import HD_RING_ATTRACTOR, NeuronParams, spiking_from_rate

#: name -> (rate population whose axes and kernels the spiking one takes, velocity per axis)
GRIDS = {
    "ring360": (lambda: Population.head_direction(360, params=HD_RING_ATTRACTOR), np.array([np.radians(60.0)])),
    "21x21x36": (lambda: Population.openratslam(21, 36), np.array([0.5, -0.3, np.radians(20.0)])),
}
NOISE = {"noise": 0.2, "noiseless": 0.0}


@pytest.mark.parametrize("noise", list(NOISE))
@pytest.mark.parametrize("grid", list(GRIDS))
@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_spiking_step(benchmark, grid, backend, noise):
    make, velocity = GRIDS[grid]
    pop = spiking_from_rate(make(), NeuronParams(noise_sigma=NOISE[noise]), seed=0, backend="numba")
    pop.kick([n / 2.0 for n in pop.shape])
    spikes = sum(len(pop.step(velocity)) for _ in range(500))  # settle (and compile)
    pop.set_backend(backend)
    pop.step(velocity)
    benchmark.extra_info["spikes_per_step_settled"] = spikes / 500
    benchmark.extra_info["cells"] = pop.size
    benchmark(pop.step, velocity)
