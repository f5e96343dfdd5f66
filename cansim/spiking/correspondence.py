"""Rate <-> spike correspondence: a spiking population built from a rate population.

What corresponds to what (rate :class:`cansim.Population` -> :class:`SpikingPopulation`):

==========================================  ==================================================
rate population                             spiking population
==========================================  ==================================================
axes, one rate cell per grid cell            the same axes, one LIF / Poisson neuron per cell
excitation kernel ``K_E`` (Eq 2.19, 5.10)     the same taps, as excitatory synapses
inhibition ``e - e * K_I`` on the excited     the same taps: synaptic kernel
activity (Alg 4)                              ``w_rec * K_E * (delta_0 - K_I)``
normalisation ``A / sum(A)`` (Alg 5)          global inhibition: each spike inhibits every cell
                                              by ``w_global``, which bounds the total rate
global inhibition ``phi`` (Alg 5)             a constant inhibitory current ``phi * w_rec``
                                              subtracted from the bias (negligible at 2e-5)
activity ``A_i`` (sums to 1)                  the fraction of the window's spikes fired by cell i
one iteration of the dynamics                 the synaptic time constant ``tau_syn``: the
                                              packet relaxes over ~``tau_syn + tau_mem``
shift by ``v dt / step`` cells (Fig 5.11)     kernel shifted by ``v * lead(v) / step`` cells,
                                              same linear split; ``lead`` is calibrated
population vector, +-3-cell box (Sec 1.6)     the same decoder on sliding-window spike counts
==========================================  ==================================================

The rate model's packet is as wide as its kernels; a spiking packet is only as wide
as the positive centre of ``K_E * (delta_0 - K_I)`` (about 3 cells for OpenRatSLAM's
7-tap sigma-1 excitation). Such a narrow spiking packet pins to the lattice and moves
only above a threshold speed, so rings meant for spiking path integration use wider
kernels on both models, e.g. :data:`HD_RING_ATTRACTOR`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Optional, Sequence

from cansim.errors import ConfigError
from cansim.params import AttractorParams
from cansim.population import Population
from cansim.spiking.calibration import calibrate_velocity_lead
from cansim.spiking.neurons import NeuronParams
from cansim.spiking.population import SpikingParams, SpikingPopulation

__all__ = ["HD_RING_ATTRACTOR", "SHEET_ATTRACTOR", "spiking_params_from_rate", "spiking_from_rate"]

#: kernels of a 360-cell head-direction ring that both the rate and the spiking model
#: path-integrate well: excitation 21 taps sigma 4 cells, inhibition 31 taps sigma 8 cells
HD_RING_ATTRACTOR = AttractorParams(exc_width=21, exc_sigma=4.0, inh_width=31, inh_sigma=8.0)

#: kernels of a spiking 2-D place sheet: excitation 11 taps sigma 2 cells, inhibition 15 taps sigma 4 cells
#: (the spiking pose cells' sheet, :mod:`cansim.models.spiking_pose_cells`, and :mod:`cansim.spiking.velocity_sheet`)
SHEET_ATTRACTOR = AttractorParams(exc_width=11, exc_sigma=2.0, inh_width=15, inh_sigma=4.0)


def spiking_params_from_rate(
    params: AttractorParams,
    neurons: Optional[NeuronParams] = None,
    *,
    recurrent_weight: float = 100.0,
    global_weight: float = 1.0,
    velocity_lead_s: float = 0.01,
) -> SpikingParams:
    """The :class:`SpikingParams` corresponding to a rate model's :class:`AttractorParams`.

    The kernels are taken unchanged; the rate model's ``phi`` lowers the neurons' bias
    current by ``phi * recurrent_weight`` (see the module table).
    """
    if not isinstance(params, AttractorParams):
        raise ConfigError("params must be a cansim.AttractorParams")
    nrn = neurons if neurons is not None else NeuronParams()
    if not isinstance(nrn, NeuronParams):
        raise ConfigError("neurons must be a cansim.spiking.NeuronParams")
    nrn = replace(nrn, bias_current=nrn.bias_current - params.global_inhibition * float(recurrent_weight))
    return SpikingParams(
        attractor=params,
        neurons=nrn,
        recurrent_weight=recurrent_weight,
        global_weight=global_weight,
        velocity_lead_s=velocity_lead_s,
    )


def spiking_from_rate(
    population: Population,
    neurons: Optional[NeuronParams] = None,
    *,
    recurrent_weight: float = 100.0,
    global_weight: float = 1.0,
    dt_s: float = 0.001,
    seed: int = 0,
    backend: str = "numba",
    calibrate_speeds_cells_per_s: Optional[Sequence[float]] = None,
) -> SpikingPopulation:
    """A spiking population on a rate population's axes and kernels.

    Parameters
    ----------
    population : cansim.Population
        The rate population (its axes and :attr:`~cansim.Population.params` are used).
    neurons : NeuronParams, optional
        Cell model; default :class:`NeuronParams()`.
    recurrent_weight, global_weight
        ``w_rec`` and ``w_global`` of :class:`SpikingParams`.
    dt_s, seed, backend
        As :class:`SpikingPopulation`.
    calibrate_speeds_cells_per_s : sequence of float, optional
        When given, the velocity lead table is fitted at these speeds
        (:func:`cansim.spiking.calibrate_velocity_lead` along axis 0, a few seconds).
    """
    if not isinstance(population, Population):
        raise ConfigError("population must be a cansim.Population")
    params = spiking_params_from_rate(
        population.params, neurons, recurrent_weight=recurrent_weight, global_weight=global_weight
    )
    if calibrate_speeds_cells_per_s is not None:
        params = calibrate_velocity_lead(
            population.axes, params, calibrate_speeds_cells_per_s, dt_s=dt_s, seed=seed, backend=backend
        )
    return SpikingPopulation(population.axes, params, dt_s=dt_s, seed=seed, backend=backend)
