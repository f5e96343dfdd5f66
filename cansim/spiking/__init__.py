"""Spiking continuous-attractor populations (LIF / Poisson) on the rate model's connectivity.

See :mod:`cansim.spiking.population` for the model, :mod:`cansim.spiking.correspondence`
for what corresponds to what between the rate and the spiking population, and
:mod:`cansim.spiking.nir_io` for export to / import from NIR (in the conventions snnTorch,
Norse and Rockpool read), :mod:`cansim.spiking.rotation_ring` for a ring and
:mod:`cansim.spiking.velocity_sheet` for a 2-D sheet that path-integrate with neurons and
synapses (expressible in NIR), :mod:`cansim.spiking.nir_graph_sim` for
cansim's own simulation of such graphs and :mod:`cansim.spiking.nir_consumers` for running
them in those toolchains.
"""

from __future__ import annotations

from cansim.spiking.connectivity import RecurrentKernel, composite_kernel
from cansim.spiking.neurons import NeuronParams, analytic_lif_rate_hz
from cansim.spiking.population import SPIKING_BACKENDS, SpikingParams, SpikingPopulation
from cansim.spiking.decoding import SpikeCountDecoder
from cansim.spiking.calibration import calibrate_velocity_lead, measure_packet_speed
from cansim.spiking.correspondence import HD_RING_ATTRACTOR, SHEET_ATTRACTOR, spiking_from_rate, spiking_params_from_rate
from cansim.spiking.nir_io import NIR_FORMAT, NIR_STEP_S, from_nir, to_nir
from cansim.spiking.nir_graph_sim import NIRGraphSimulator
from cansim.spiking.rotation_ring import (
    RotationRingParams,
    TurningCalibration,
    calibrate_turning,
    ring_input,
    rotation_ring_graph,
)
from cansim.spiking.velocity_sheet import (
    SheetCalibration,
    VelocitySheetParams,
    calibrate_sheet_speed,
    sheet_input,
    sheet_kick,
    sheet_position_cells,
    velocity_sheet_graph,
)

__all__ = [
    "NeuronParams",
    "analytic_lif_rate_hz",
    "RecurrentKernel",
    "composite_kernel",
    "SpikingParams",
    "SpikingPopulation",
    "SPIKING_BACKENDS",
    "SpikeCountDecoder",
    "calibrate_velocity_lead",
    "measure_packet_speed",
    "HD_RING_ATTRACTOR",
    "SHEET_ATTRACTOR",
    "spiking_from_rate",
    "spiking_params_from_rate",
    "to_nir",
    "from_nir",
    "NIR_FORMAT",
    "NIR_STEP_S",
    "NIRGraphSimulator",
    "RotationRingParams",
    "rotation_ring_graph",
    "ring_input",
    "TurningCalibration",
    "calibrate_turning",
    "VelocitySheetParams",
    "velocity_sheet_graph",
    "sheet_input",
    "sheet_kick",
    "sheet_position_cells",
    "SheetCalibration",
    "calibrate_sheet_speed",
]
