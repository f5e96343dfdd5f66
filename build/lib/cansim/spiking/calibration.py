"""Fit the velocity-to-shift gain of spiking path integration (the lead table).

How fast the packet moves for a given kernel shift depends on the neuron and synapse
time constants, the weights and the noise, so - as in Burak & Fiete (2009), whose
velocity gain is also set empirically - the gain is measured: the population runs at a
set of constant speeds, the packet's speed is fitted from the decoded spike counts, and
the lead (seconds) of each speed is rescaled by ``commanded / measured``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from cansim.axes import Axis
from cansim.decoding import population_vector_window
from cansim.errors import InvalidInputError
from cansim.spiking.population import SpikingParams, SpikingPopulation
from whisker_io.validation import finite_scalar

__all__ = ["measure_packet_speed", "calibrate_velocity_lead", "MAX_MEASURE_STEPS"]

#: most simulation steps one of ``duration_s``, ``settle_s``, ``bin_s`` may span (1e7 steps of
#: 1 ms are almost 3 hours of simulated time; more is a mistyped argument, not a measurement)
MAX_MEASURE_STEPS = 1e7


def measure_packet_speed(
    pop: SpikingPopulation,
    velocity: Sequence[float],
    axis: int = 0,
    *,
    duration_s: float = 3.0,
    settle_s: float = 0.3,
    bin_s: float = 0.1,
    half_width: int = 10,
) -> float:
    """Speed of the packet along ``axis`` (cells/s) under a constant ``velocity``.

    The population is reset, a packet seeded at the grid centre with :meth:`~SpikingPopulation.kick`,
    left to settle for ``settle_s`` and then driven for ``duration_s``; the packet
    position is decoded from the spike counts of every ``bin_s`` bin and a straight line
    fitted to the unwrapped positions.
    """
    if not (0 <= axis < pop.ndim):
        raise InvalidInputError(f"axis must lie in [0, {pop.ndim}), got {axis}")
    for name, val in (("duration_s", duration_s), ("settle_s", settle_s), ("bin_s", bin_s)):
        if not finite_scalar(val, name) >= 0:
            raise InvalidInputError(f"{name} must be finite and >= 0, got {val!r}")
        if not val / pop.dt_s <= MAX_MEASURE_STEPS:  # a huge finite time would run (and allocate) for ever
            raise InvalidInputError(
                f"{name} = {val!r} s is more than {MAX_MEASURE_STEPS:g} steps of dt_s = {pop.dt_s} s; measure a shorter run"
            )
    n_bin = max(1, int(round(bin_s / pop.dt_s)))
    n_bins = int(duration_s / (n_bin * pop.dt_s))
    if n_bins < 3:
        raise InvalidInputError("duration_s must cover at least three decoding bins")
    pop.reset()
    pop.kick([n / 2.0 for n in pop.shape])
    pop.run(int(round(settle_s / pop.dt_s)))
    n = pop.shape[axis]
    counts = np.zeros(pop.size, dtype=np.int64)
    pos = np.empty(n_bins)
    for b in range(n_bins):
        counts[:] = 0
        for _ in range(n_bin):
            np.add.at(counts, pop.step(velocity), 1)
        if not counts.any():
            raise InvalidInputError("the packet died out during the speed measurement; check the weights and bias")
        pos[b] = population_vector_window(counts.reshape(pop.shape), half_width)[axis]
    unwrapped = np.unwrap(pos * 2.0 * np.pi / n) * n / (2.0 * np.pi)
    t = np.arange(n_bins) * n_bin * pop.dt_s
    return float(np.polyfit(t, unwrapped, 1)[0])


def calibrate_velocity_lead(
    axes: Sequence[Axis],
    params: SpikingParams,
    speeds_cells_per_s: Sequence[float],
    *,
    axis: int = 0,
    iterations: int = 2,
    duration_s: float = 3.0,
    dt_s: float = 0.001,
    seed: int = 0,
    backend: str = "numba",
) -> SpikingParams:
    """``params`` with a :attr:`SpikingParams.lead_table` fitted at the given speeds.

    Parameters
    ----------
    axes, params, dt_s, seed, backend
        The population to calibrate (as :class:`SpikingPopulation`).
    speeds_cells_per_s : sequence of float
        Positive speeds (cells/s) at which to measure, e.g. ``[10, 30, 60, 120, 240]``.
    axis : int
        The axis driven during calibration (the table is used on every axis).
    iterations : int
        Rescaling rounds (>= 1); each reruns every speed with the current table.
    duration_s : float
        Driven time per speed and round (s).

    Returns
    -------
    SpikingParams
        A copy with ``lead_table = ((speed, lead_s), ...)`` ascending.
    """
    speeds = np.sort(np.asarray(speeds_cells_per_s, dtype=np.float64).ravel())
    if speeds.size == 0 or not np.isfinite(speeds).all() or np.any(speeds <= 0) or np.any(np.diff(speeds) <= 0):
        raise InvalidInputError("speeds_cells_per_s must be distinct, finite and > 0")
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise InvalidInputError(f"iterations must be an integer >= 1, got {iterations!r}")
    axes = tuple(axes)
    leads = params.lead_s(speeds)
    cur = params
    for _ in range(iterations):
        cur = replace(params, lead_table=tuple(zip(speeds.tolist(), leads.tolist())))
        pop = SpikingPopulation(axes, cur, dt_s=dt_s, seed=seed, backend=backend)
        for k, s in enumerate(speeds):
            vel = np.zeros(len(axes))
            vel[axis] = s * axes[axis].step
            measured = measure_packet_speed(pop, vel, axis, duration_s=duration_s)
            if measured > 0.05 * s:  # a stalled packet keeps its lead rather than exploding
                leads[k] = leads[k] * s / measured
        cur = replace(params, lead_table=tuple(zip(speeds.tolist(), leads.tolist())))
    return cur
