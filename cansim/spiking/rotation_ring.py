"""A spiking head-direction ring that path-integrates with neurons and synapses, as a NIR graph.

The kernel-shift path integration of :class:`cansim.spiking.SpikingPopulation` gates
synapses by the velocity, which NIR cannot express. Here the turning is done the way
Skaggs et al. (1995) proposed and Zhang (1996) and Song & Wang (2005) modelled it: two
populations of *rotation* cells, conjunctive for head direction and turning, sit beside
the ring.

* ``ring`` (``N`` LIF cells): the stationary attractor of :mod:`cansim.spiking.nir_io`
  (excitation then inhibition, ``w_rec K - w_global``), plus a bias current.
* ``rotation`` (``2 N`` LIF cells; the first ``N`` turn towards increasing angle, the last
  ``N`` towards decreasing angle): cell ``j`` of each half gets a one-to-one input
  ``ring_to_rotation_weight`` from ring cell ``j``, a bias ``rotation_bias`` and the
  angular-velocity current ``+- velocity_gain * omega`` (threshold units per rad/s).
* rotation cell ``j`` of the first half excites ring cells around ``j + shift`` with
  ``rotation_to_ring_weight`` times the (sum-normalised) excitation kernel, the second
  half around ``j - shift``. At ``omega = 0`` both halves fire alike and the pushes
  cancel; a positive ``omega`` makes the first half fire more, and the bump moves towards
  increasing angle at a speed that grows with ``omega``. The gain is not calibrated to one:
  on 360 cells (measured with Euler steps of the graph's equations) the bump turned at 0.88, 0.79
  and 0.58 times ``omega`` for 0.5, 1 and 2 rad/s; the speed is set in cells per second,
  so on fewer cells the gain in degrees is larger (about 1.3 on 120 cells for a 0-3 rad/s
  sinusoid). Above about 2 rad/s the rotation cells saturate.

The graph's input is ``N + 1`` values: an external current per ring cell (threshold
units) followed by the angular velocity (rad/s); its output is the ring's spikes. All
weights here are in cansim's units (a current jump per spike, threshold units); the graph
holds them converted as :mod:`cansim.spiking.nir_io` describes. Both populations are one
CubaLIF node ``cells`` of ``3 N`` cells (ring, then the two rotation halves)::

    input -> input_map (Affine) -> cells -> readout (Linear) -> output
    cells -> excitation (Linear) -> inhibition (Linear) -> cells

``input_map`` routes the ring current and ``+- velocity_gain * omega`` plus the biases;
``excitation`` (``4 N x 3 N``) gives ``[C_E z_ring; z_ring; z_rotation]`` and
``inhibition`` (``3 N x 4 N``) maps that to the currents: ``M C_E z_ring`` plus the
shifted rotation-to-ring excitation onto the ring, the one-to-one ring-to-rotation
input onto the rotation cells (``M`` and ``C_E`` as in :mod:`cansim.spiking.nir_io`);
``readout`` picks the ring's spikes. Why one node and one chain: Norse 1.1 and Rockpool
3.1 run graphs with nirtorch's ``GraphExecutor``, which hands the input to the first
node only and returns the output of the last node of a depth-first walk from the input,
so a graph whose input fans out to two populations loses an input or returns the wrong
node; and snnTorch needs the three-node loop (:mod:`cansim.spiking.nir_io`).
:class:`cansim.spiking.nir_graph_sim.NIRGraphSimulator` is cansim's own simulation of
the graph.

The default parameters were chosen on constant turning rates of 0.5, 1 and 2 rad/s with
the kick protocol of the tests; the sinusoidal turning signal of the tests and the
recorded rat trajectory were not used for that.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.params import AttractorParams
from cansim.spiking.correspondence import HD_RING_ATTRACTOR
from cansim.spiking.neurons import NeuronParams
from cansim.spiking.nir_io import (
    NIR_STEP_S,
    _nir,
    circulant,
    cuba_lif_node,
    current_gain,
    factored_recurrent,
    input_gain,
)
from cansim.spiking.population import SpikingParams
from whisker_io.validation import checked, validate_fields

__all__ = ["RotationRingParams", "rotation_ring_graph", "ring_input", "ROTATION_RING_FORMAT"]

#: value of ``graph.metadata["cansim"]["format"]`` in graphs written by :func:`rotation_ring_graph`
ROTATION_RING_FORMAT = "cansim.spiking.rotation_ring/1"

#: the cells of the ring and rotation populations: no noise, a refractory period of one 0.1 ms step
RING_NEURONS = NeuronParams(noise_sigma=0.0, refractory_s=NIR_STEP_S, bias_current=0.95)


@dataclass(frozen=True)
class RotationRingParams:
    """Parameters of the path-integrating ring (see the module docstring).

    Parameters
    ----------
    n_cells : int
        Ring cells ``N`` (>= 8); cell ``i`` prefers heading ``360 i / N`` deg.
    attractor : AttractorParams
        Kernels of the ring.
    neurons : NeuronParams
        LIF cells of both populations (``bias_current`` is the ring's bias).
    recurrent_weight, global_weight : float
        ``w_rec`` and ``w_global`` of the ring (as :class:`cansim.spiking.SpikingParams`).
    rotation_bias : float
        Bias current of the rotation cells (threshold units).
    ring_to_rotation_weight : float
        Current jump of a rotation cell per spike of its ring cell, >= 0.
    velocity_gain : float
        Current of the rotation cells per rad/s of angular velocity, >= 0.
    rotation_to_ring_weight : float
        Peak scale of the shifted excitation from rotation cells to the ring, >= 0.
    shift_cells : int
        Offset of those projections (cells), 1 <= shift < N / 2.
    """

    n_cells: int = 360
    attractor: AttractorParams = HD_RING_ATTRACTOR
    neurons: NeuronParams = field(default_factory=lambda: RING_NEURONS)
    recurrent_weight: float = checked(15.0, float, minimum=0)
    global_weight: float = checked(0.1, float, minimum=0)
    rotation_bias: float = checked(0.3, float)
    ring_to_rotation_weight: float = checked(1.0, float, minimum=0)
    velocity_gain: float = checked(0.25, float, minimum=0)
    rotation_to_ring_weight: float = checked(6.0, float, minimum=0)
    shift_cells: int = 10

    def __post_init__(self) -> None:
        validate_fields(self)
        if isinstance(self.n_cells, bool) or not isinstance(self.n_cells, (int, np.integer)) or not 8 <= self.n_cells <= 4096:
            raise ConfigError(f"n_cells must be an integer in [8, 4096], got {self.n_cells!r}")
        if not isinstance(self.attractor, AttractorParams):
            raise ConfigError("attractor must be a cansim.AttractorParams")
        if not isinstance(self.neurons, NeuronParams) or self.neurons.model != "lif":
            raise ConfigError("neurons must be a cansim.spiking.NeuronParams with model='lif'")
        s = self.shift_cells
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or not 1 <= s < self.n_cells / 2:
            raise ConfigError(f"shift_cells must be an integer in [1, n_cells / 2), got {s!r}")

    @property
    def ring_params(self) -> SpikingParams:
        """The ring's :class:`SpikingParams` (its stationary network)."""
        return SpikingParams(
            attractor=self.attractor, neurons=self.neurons,
            recurrent_weight=float(self.recurrent_weight), global_weight=float(self.global_weight),
        )


def ring_input(current, omega_rad_s: float, n_cells: int) -> np.ndarray:
    """The graph's input vector: ring current (scalar or shape ``(n_cells,)``, threshold units) then ``omega``.

    Raises
    ------
    ShapeError, InvalidInputError
        A current of another shape; non-finite values.
    """
    cur = np.asarray(current, dtype=np.float64)
    if cur.ndim == 0:
        cur = np.full(int(n_cells), float(cur))
    if cur.shape != (int(n_cells),):
        raise ShapeError(f"current must be a scalar or have shape ({n_cells},), got {cur.shape}")
    try:
        om = float(omega_rad_s)
    except (TypeError, ValueError):
        raise InvalidInputError(f"omega_rad_s must be a number (rad/s), got {omega_rad_s!r}") from None
    out = np.append(cur, om)
    if not np.isfinite(out).all():
        raise InvalidInputError("current and omega_rad_s must be finite (no NaN/inf)")
    return out


def rotation_ring_graph(params: RotationRingParams = RotationRingParams(), *, dt_s: float = NIR_STEP_S) -> Any:
    """The ``nir.NIRGraph`` of the path-integrating ring (layout and units: the module docstring).

    Parameters
    ----------
    params : RotationRingParams
    dt_s : float
        The step the consumers will use (s); snnTorch always uses ``1e-4``.

    Raises
    ------
    ConfigError
        Bad parameters or step.
    """
    nir = _nir()
    if not isinstance(params, RotationRingParams):
        raise ConfigError("params must be a cansim.spiking.rotation_ring.RotationRingParams")
    n = int(params.n_cells)
    nrn = params.neurons
    cuba_lif_node(nrn, n, dt_s)  # validates the step
    ce, m = factored_recurrent(params.ring_params, (n,))
    c_gain, g_in = current_gain(nrn, dt_s), input_gain(nrn, dt_s)
    exc, _ = params.attractor.kernels(1)
    taps = exc.dense() / float(np.sum(exc.dense()))
    eye, zero = np.eye(n), np.zeros((n, n))
    w_in = np.zeros((3 * n, n + 1))
    w_in[:n, :n] = g_in * eye
    w_in[n : 2 * n, n] = g_in * params.velocity_gain
    w_in[2 * n :, n] = -g_in * params.velocity_gain
    b_in = g_in * np.concatenate([np.full(n, nrn.bias_current), np.full(2 * n, params.rotation_bias)])
    # excitation: [C_E z_ring; z_ring; z_rotation] (4N x 3N)
    w_exc = np.zeros((4 * n, 3 * n))
    w_exc[:n, :n] = ce
    w_exc[n : 2 * n, :n] = eye
    w_exc[2 * n :, n:] = np.eye(2 * n)
    # inhibition: ring <- M C_E z_ring + rotation -> ring; rotation <- ring one-to-one (3N x 4N)
    s = int(params.shift_cells)
    w_inh = np.zeros((3 * n, 4 * n))
    w_inh[:n, :n] = m
    w_inh[:n, 2 * n : 3 * n] = params.rotation_to_ring_weight * circulant(taps, (n,), (s,))
    w_inh[:n, 3 * n :] = params.rotation_to_ring_weight * circulant(taps, (n,), (-s,))
    w_inh[n : 2 * n, n : 2 * n] = params.ring_to_rotation_weight * eye
    w_inh[2 * n :, n : 2 * n] = params.ring_to_rotation_weight * eye
    readout = np.hstack([eye, zero, zero])
    meta = {
        "format": ROTATION_RING_FORMAT,
        "nir_step_s": float(dt_s),
        "n_cells": n,
        "recurrent_weight": float(params.recurrent_weight),
        "global_weight": float(params.global_weight),
        "rotation_bias": float(params.rotation_bias),
        "ring_to_rotation_weight": float(params.ring_to_rotation_weight),
        "velocity_gain": float(params.velocity_gain),
        "rotation_to_ring_weight": float(params.rotation_to_ring_weight),
        "shift_cells": s,
        "refractory_s": float(nrn.refractory_s),
        "noise_sigma": float(nrn.noise_sigma),
    }
    nodes = {
        "input": nir.Input(input_type={"input": np.array([n + 1])}),
        "input_map": nir.Affine(weight=w_in, bias=b_in),
        "cells": cuba_lif_node(nrn, 3 * n, dt_s),
        "excitation": nir.Linear(weight=w_exc),
        "inhibition": nir.Linear(weight=w_inh * c_gain),
        "readout": nir.Linear(weight=readout),
        "output": nir.Output(output_type={"output": np.array([n])}),
    }
    edges = [
        ("input", "input_map"),
        ("input_map", "cells"),
        ("cells", "excitation"),
        ("excitation", "inhibition"),
        ("inhibition", "cells"),
        ("cells", "readout"),
        ("readout", "output"),
    ]
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata={"cansim": meta})
