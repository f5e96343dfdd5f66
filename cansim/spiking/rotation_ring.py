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
  increasing angle at a speed that grows with ``omega``.

Linear range. Two constraints bound it. A rotation cell on the bump must fire at
``omega = 0`` (its bias plus the input from its ring cell above threshold), or the bump,
once its rate has settled after the kick, is pinned to the lattice and small rates do not
move it (measured: with bias 0 the settled bump did not turn below 4-6 rad/s). And a
rotation cell off the bump must stay silent: ``rotation_bias + velocity_gain * omega < 1``,
or the whole half fires and pushes the whole ring, which stalls the bump (the first
defaults, bias 0.3 and gain 0.25, hit that at 2.8 rad/s). The defaults keep the bias at 0.3
and use gain 0.08 (stall above 8.75 rad/s) and a rotation-to-ring scale of 9: on 120 cells
(cansim's simulation of the graph, bump settled for 0.5 s, slope over 0.5 s) the bump
turned at 0.70, 1.19, 2.13, 3.74, 4.93 and 6.31 rad/s for 0.5, 1, 2, 4, 6 and 8 rad/s, and
at about 2.7 rad/s for 10 rad/s. These were chosen on constant rates only.
:func:`calibrate_turning` measures that curve on a given ring with cansim's own
simulation of its graph, and :meth:`TurningCalibration.command` inverts it: the angular
velocity handed to the graph (:func:`ring_input`) is the command that makes the bump
turn at the wanted rate, up to the fastest rate measured before the curve falls (the
command saturates there). The inversion is outside the graph, so every consumer gets the
same commands.

The graph's input is ``N + 1`` values: an external current per ring cell (threshold
units) followed by the angular-velocity command (rad/s only on the ring it was
calibrated for: the bump's speed in cells per second, not in rad/s, follows the command,
so the same command turns a ring of half the cells twice as fast in rad/s; give
:meth:`TurningCalibration.command` of the wanted rate); its output is the ring's spikes. All
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
The graph is written by :func:`cansim.spiking.conjunctive.conjunctive_graph` (shared with
the 2-D sheet of :mod:`cansim.spiking.velocity_sheet`).
:class:`cansim.spiking.nir_graph_sim.NIRGraphSimulator` is cansim's own simulation of
the graph.

The default parameters were chosen on constant turning rates of 0.5 to 12 rad/s with the
kick protocol of the tests; the sinusoidal turning signal of the tests and the recorded
rat trajectory were not used for that.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cansim.decoding import circular_mean_index
from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.params import AttractorParams
from cansim.spiking.correspondence import HD_RING_ATTRACTOR
from cansim.spiking.neurons import NeuronParams
from cansim.spiking.conjunctive import (
    check_calibration_arguments,
    check_speed_curve,
    conjunctive_graph,
    invert_speed_curve,
    measure_phase_speed,
)
from cansim.spiking.nir_io import NIR_STEP_S
from cansim.spiking.population import SpikingParams
from whisker_io.validation import ConfigDataclass, checked, validate_fields

__all__ = [
    "RotationRingParams",
    "rotation_ring_graph",
    "ring_input",
    "TurningCalibration",
    "calibrate_turning",
    "ROTATION_RING_FORMAT",
]

#: value of ``graph.metadata["cansim"]["format"]`` in graphs written by :func:`rotation_ring_graph`
ROTATION_RING_FORMAT = "cansim.spiking.rotation_ring/1"

#: the cells of the ring and rotation populations: no noise, a refractory period of one 0.1 ms step
RING_NEURONS = NeuronParams(noise_sigma=0.0, refractory_s=NIR_STEP_S, bias_current=0.95)


@dataclass(frozen=True)
class RotationRingParams(ConfigDataclass):
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
        Current of the rotation cells per unit of the graph's angular-velocity input, >= 0.
        The input is named rad/s, but the bump moves a number of *cells* per second for a
        given input, whatever the ring's size: an input of 2 turned a 60-cell ring at 4.27 rad/s,
        120 cells at 2.13 and 360 cells at 0.71 (a user's check, session 47). Hand the graph
        :meth:`TurningCalibration.command` of the rate wanted (:func:`calibrate_turning` on
        this ring), not the rate itself.
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
    velocity_gain: float = checked(0.08, float, minimum=0)
    rotation_to_ring_weight: float = checked(9.0, float, minimum=0)
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
    if not isinstance(params, RotationRingParams):
        raise ConfigError("params must be a cansim.spiking.rotation_ring.RotationRingParams")
    n = int(params.n_cells)
    nrn = params.neurons
    s = int(params.shift_cells)
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
    return conjunctive_graph(
        shape=(n,),
        attractor=params.ring_params,
        shifts=np.array([[s], [-s]]),
        velocity_map=np.array([[1.0], [-1.0]]),
        velocity_gain=params.velocity_gain,
        direction_bias=params.rotation_bias,
        attractor_to_direction_weight=params.ring_to_rotation_weight,
        direction_to_attractor_weight=params.rotation_to_ring_weight,
        dt_s=dt_s,
        metadata=meta,
    )


@dataclass(frozen=True)
class TurningCalibration:
    """Measured turning rate of the bump against the angular-velocity input, and its inverse.

    Parameters
    ----------
    omega_rad_s : tuple of float
        Inputs (rad/s), ascending, the first 0.
    bump_rad_s : tuple of float
        The bump's measured turning rate at each (rad/s), the first 0.

    Only the rising part of the curve (up to its first maximum) is inverted; the ring is
    mirror-symmetric, so negative rates use the same curve with the sign flipped.
    """

    omega_rad_s: tuple[float, ...]
    bump_rad_s: tuple[float, ...]

    def __post_init__(self) -> None:
        check_speed_curve(self.omega_rad_s, self.bump_rad_s, ("omega_rad_s", "bump_rad_s"), "rad/s", "calibrate_turning")

    @property
    def max_rad_s(self) -> float:
        """The fastest turning rate the ring reaches on the rising part of the curve (rad/s)."""
        return invert_speed_curve(self.omega_rad_s, self.bump_rad_s, np.inf)[1]

    def command(self, omega_rad_s):
        """The input (rad/s) that turns the bump at ``omega_rad_s`` (scalar or array), saturated at :attr:`max_rad_s`.

        Raises
        ------
        InvalidInputError
            Non-finite rates.
        """
        w = np.asarray(omega_rad_s, dtype=np.float64)
        if not np.isfinite(w).all():
            raise InvalidInputError("omega_rad_s must be finite (no NaN/inf)")
        return invert_speed_curve(self.omega_rad_s, self.bump_rad_s, w)[0]


def _population_vector_rad(counts: np.ndarray) -> float:
    """The ring's heading from its counts, rad in ``[0, 2 pi)`` (:func:`cansim.decoding.circular_mean_index`)."""
    return circular_mean_index(counts) * 2.0 * np.pi / counts.size


def calibrate_turning(
    params: RotationRingParams = RotationRingParams(),
    omegas_rad_s=(0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0),
    *,
    dt_s: float = NIR_STEP_S,
    settle_s: float = 0.5,
    measure_s: float = 0.5,
) -> TurningCalibration:
    """Measure the bump's turning rate at constant angular-velocity inputs (cansim's own simulation of the graph).

    For each input: a 100 ms Gaussian kick (sigma 3 cells, 2 threshold units) at 0 deg,
    ``settle_s`` of turning, then the slope (least squares) of the unwrapped population
    vector of the spikes (a 50 ms exponential window, read every 2 ms) over ``measure_s``.

    Parameters
    ----------
    params : RotationRingParams
    omegas_rad_s : sequence of float
        Positive inputs (rad/s), ascending.
    dt_s, settle_s, measure_s : float
        Step and durations (s).

    Returns
    -------
    TurningCalibration

    Raises
    ------
    ConfigError
        Bad parameters, inputs or durations; a bump that dies during the measurement.
    """
    from cansim.spiking.nir_graph_sim import NIRGraphSimulator

    oms = check_calibration_arguments(omegas_rad_s, "omegas_rad_s", "rad/s", settle_s, measure_s)
    sim = NIRGraphSimulator(rotation_ring_graph(params, dt_s=dt_s), dt_s=dt_s)
    n = int(params.n_cells)
    d = (np.arange(n) + n / 2.0) % n - n / 2.0
    kick = ring_input(2.0 * np.exp(-d * d / 18.0), 0.0, n)
    speeds = []
    for om in oms:
        sim.reset()
        speeds.append(measure_phase_speed(sim.step, kick, ring_input(0.0, om, n), _population_vector_rad, dt_s=dt_s,
                                          settle_s=settle_s, measure_s=measure_s, read_every_s=2e-3,
                                          label=f"{om} rad/s"))
    return TurningCalibration((0.0, *oms), (0.0, *speeds))
