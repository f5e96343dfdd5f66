"""Path integration by conjunctive cells, as one NIR graph: the builder shared by the ring and the sheet.

A continuous attractor moves its bump when cells that are conjunctive for *position and
direction of motion* push it (Skaggs et al. 1995; Zhang 1996; Burak & Fiete 2009):
beside the attractor sit ``D`` direction populations, each a copy of the attractor's
grid. Cell ``j`` of direction population ``d`` gets a one-to-one input from attractor cell
``j``, a bias, and a current proportional to the velocity component along ``d``; it
excites the attractor around ``j + shift_d`` through the attractor's (sum-normalised)
excitation kernel. At rest all directions fire alike and their pushes cancel; motion
makes the populations along it fire more, and the bump follows.

:func:`conjunctive_graph` writes that network as one CubaLIF node and one chain, the
layout every consumer of :mod:`cansim.spiking.nir_io` reads (why one node and one chain:
:mod:`cansim.spiking.rotation_ring`)::

    input -> input_map (Affine) -> cells -> readout (Linear) -> output
    cells -> excitation (Linear) -> inhibition (Linear) -> cells

The cells are ``[attractor (S); direction 0 (S); ...; direction D-1 (S); pool (P)]``.
``excitation`` gives ``[C_E z_attractor; z_all]`` and ``inhibition`` maps that to the
currents: onto the attractor ``M C_E z_attractor`` (its own recurrent matrix, factored as
:func:`cansim.spiking.nir_io.factored_recurrent` does), the shifted pushes of the
direction cells and ``-pool_to_attractor_weight`` per pool spike; onto each direction
population ``attractor_to_direction_weight`` times its attractor cell's spikes; onto each
pool cell ``attractor_to_pool_weight`` times the attractor's total spikes.

The optional *pool* of ``P`` inhibitory cells holds the bump's rate. Without refractory
periods (the consumers have none) an LIF cell's rate grows linearly with its current, so
a recurrent gain strong enough to hold a 2-D bump runs it up to one spike per step, and
one a little weaker lets it die (measured on a 16 x 16 sheet: recurrent weight 14.7 dies,
15 fires every few steps); pool cells that fire only once the attractor's total rate
passes their bias and inhibit every attractor cell make the feedback concave, so the
bump settles at a moderate rate (:mod:`cansim.spiking.velocity_sheet`). The ring of
:mod:`cansim.spiking.rotation_ring` needs none (``P = 0``).

Weights are in cansim's units (a current jump per spike, threshold units) and converted
to the consumers' convention here (:func:`cansim.spiking.nir_io.current_gain`,
:func:`cansim.spiking.nir_io.input_gain`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cansim.errors import ConfigError
from cansim.spiking.nir_io import _nir, circulant, cuba_lif_node, current_gain, factored_recurrent, input_gain
from cansim.spiking.population import SpikingParams

__all__ = [
    "conjunctive_graph",
    "invert_speed_curve",
    "check_speed_curve",
    "check_calibration_arguments",
    "measure_phase_speed",
]


def conjunctive_graph(
    *,
    shape: tuple[int, ...],
    attractor: SpikingParams,
    shifts: np.ndarray,
    velocity_map: np.ndarray,
    velocity_gain: float,
    direction_bias: float,
    attractor_to_direction_weight: float,
    direction_to_attractor_weight: float,
    pool_cells: int = 0,
    pool_bias: float = 0.0,
    attractor_to_pool_weight: float = 0.0,
    pool_to_attractor_weight: float = 0.0,
    dt_s: float,
    metadata: dict,
) -> Any:
    """The ``nir.NIRGraph`` of an attractor moved by conjunctive direction populations (module docstring).

    Parameters
    ----------
    shape : tuple of int
        The attractor's periodic grid (``S = prod(shape)`` cells).
    attractor : SpikingParams
        The stationary attractor: its kernels (factored as
        :func:`cansim.spiking.nir_io.factored_recurrent`; the excitation kernel, sum-normalised,
        is also the pushes' profile), weights and neurons (the LIF cells of every population;
        their ``bias_current`` is the attractor cells' bias).
    shifts : ndarray (D, len(shape)) int
        Where each direction population pushes, cells per axis.
    velocity_map : ndarray (D, V)
        Velocity input component ``v`` reaching direction ``d`` with factor
        ``velocity_map[d, v] * velocity_gain``.
    velocity_gain, direction_bias : float
        Threshold units per unit of velocity input; the direction cells' bias.
    attractor_to_direction_weight, direction_to_attractor_weight : float
        Current jump per spike of the one-to-one input and peak scale of the pushes.
    pool_cells, pool_bias, attractor_to_pool_weight, pool_to_attractor_weight
        The inhibitory pool (none when ``pool_cells`` is 0).
    dt_s : float
        The consumers' step (s).
    metadata : dict
        Stored as ``graph.metadata["cansim"]``.

    Raises
    ------
    ConfigError
        A step the neurons cannot use.

    Returns
    -------
    nir.NIRGraph
        Input ``S + V`` values (attractor currents, then the velocity components);
        output the attractor's ``S`` spikes.
    """
    nir = _nir()
    neurons = attractor.neurons
    s_cells = int(np.prod(shape))
    cuba_lif_node(neurons, s_cells, dt_s)  # validates the step
    exc, _ = attractor.attractor.kernels(len(shape))
    excitation_taps = exc.dense() / float(np.sum(exc.dense()))
    shifts = np.asarray(shifts, dtype=np.int64)
    vmap = np.asarray(velocity_map, dtype=np.float64)
    n_dir, n_vel = vmap.shape
    p = int(pool_cells)
    total = (1 + n_dir) * s_cells + p
    ce, m = factored_recurrent(attractor, tuple(shape))
    c_gain, g_in = current_gain(neurons, dt_s), input_gain(neurons, dt_s)
    eye = np.eye(s_cells)
    w_in = np.zeros((total, s_cells + n_vel))
    w_in[:s_cells, :s_cells] = g_in * eye
    for d in range(n_dir):
        w_in[(1 + d) * s_cells : (2 + d) * s_cells, s_cells:] = g_in * velocity_gain * vmap[d]
    b_in = g_in * np.concatenate([np.full(s_cells, neurons.bias_current), np.full(n_dir * s_cells, direction_bias),
                                  np.full(p, pool_bias)])
    w_exc = np.zeros((s_cells + total, total))  # [C_E z_attractor; z_all]
    w_exc[:s_cells, :s_cells] = ce
    w_exc[s_cells:] = np.eye(total)
    w_inh = np.zeros((total, s_cells + total))
    w_inh[:s_cells, :s_cells] = m
    z = s_cells  # column of z_all's first cell
    for d in range(n_dir):
        cols = slice(z + (1 + d) * s_cells, z + (2 + d) * s_cells)
        w_inh[:s_cells, cols] = direction_to_attractor_weight * circulant(excitation_taps, tuple(shape), tuple(shifts[d]))
        w_inh[(1 + d) * s_cells : (2 + d) * s_cells, z : z + s_cells] = attractor_to_direction_weight * eye
    if p:
        w_inh[:s_cells, z + (1 + n_dir) * s_cells :] = -pool_to_attractor_weight
        w_inh[(1 + n_dir) * s_cells :, z : z + s_cells] = attractor_to_pool_weight
    readout = np.hstack([eye, np.zeros((s_cells, total - s_cells))])
    nodes = {
        "input": nir.Input(input_type={"input": np.array([s_cells + n_vel])}),
        "input_map": nir.Affine(weight=w_in, bias=b_in),
        "cells": cuba_lif_node(neurons, total, dt_s),
        "excitation": nir.Linear(weight=w_exc),
        "inhibition": nir.Linear(weight=w_inh * c_gain),
        "readout": nir.Linear(weight=readout),
        "output": nir.Output(output_type={"output": np.array([s_cells])}),
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
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata={"cansim": dict(metadata)})


def invert_speed_curve(inputs: Any, speeds: Any, wanted: Any) -> tuple[Any, float]:
    """The inputs that move a bump at ``wanted`` speeds, from a measured curve; and the fastest speed.

    Only the rising part of the curve (up to its first maximum) is inverted, linearly
    between the measured points; speeds beyond its top saturate there; the sign of
    ``wanted`` is kept (the networks are mirror-symmetric).

    Parameters
    ----------
    inputs, speeds : sequence of float
        The measured curve (validated by the calibration classes that hold it), both starting at 0.
    wanted : float or ndarray
        Wanted speeds (any sign; ``inf`` reads the top).

    Returns
    -------
    (float or ndarray, float)
        The inputs, shaped as ``wanted``; the top of the rising part.
    """
    sp = np.asarray(speeds, dtype=np.float64)
    k = 1
    while k + 1 < sp.size and sp[k + 1] > sp[k]:
        k += 1
    inp, sp = np.asarray(inputs, dtype=np.float64)[: k + 1], sp[: k + 1]
    w = np.asarray(wanted, dtype=np.float64)
    out = np.sign(w) * np.interp(np.minimum(np.abs(w), sp[-1]), sp, inp)
    return (float(out) if out.ndim == 0 else out), float(sp[-1])


def check_speed_curve(inputs: Any, speeds: Any, names: tuple[str, str], unit: str, remeasure: str) -> None:
    """Refuse a calibration curve that :func:`invert_speed_curve` cannot invert (ConfigError naming ``names``).

    A curve is two sequences of the same length >= 2, finite, the inputs starting at 0 and
    ascending, the speeds starting at 0 and positive at the second point.
    """
    inp = np.asarray(inputs, dtype=np.float64)
    sp = np.asarray(speeds, dtype=np.float64)
    if inp.ndim != 1 or inp.shape != sp.shape or inp.size < 2:
        raise ConfigError(f"{names[0]} and {names[1]} must be two sequences of the same length >= 2")
    if not (np.isfinite(inp).all() and np.isfinite(sp).all()):
        raise ConfigError(f"a calibration must be finite (no NaN/inf); re-measure with {remeasure}")
    if inp[0] != 0.0 or sp[0] != 0.0 or np.any(np.diff(inp) <= 0):
        raise ConfigError(f"{names[0]} must start at 0 and ascend, {names[1]} must start at 0")
    if sp[1] <= 0:
        raise ConfigError(f"the bump did not move at {inp[1]} {unit} ({sp[1]} {unit}): nothing to invert")


def check_calibration_arguments(values: Any, name: str, unit: str, settle_s: Any, measure_s: Any) -> list[float]:
    """The calibration inputs as floats (positive, finite, ascending) after checking the durations (ConfigError)."""
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a sequence of numbers ({unit})") from None
    if not out or not all(math.isfinite(v) and v > 0 for v in out) or any(b <= a for a, b in zip(out, out[1:])):
        raise ConfigError(f"{name} must be positive, finite and ascending, got {values!r}")
    for label, v in (("settle_s", settle_s), ("measure_s", measure_s)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
            raise ConfigError(f"{label} must be a finite number of seconds > 0, got {v!r}")
    return out


def measure_phase_speed(step: Callable[[np.ndarray], np.ndarray], kick: np.ndarray, drive: np.ndarray,
                        phase: Callable[[np.ndarray], float], *, dt_s: float, settle_s: float, measure_s: float,
                        read_every_s: float, label: str) -> float:
    """The slope (rad/s, least squares) of a bump's unwrapped phase under a constant drive, after a 100 ms kick.

    Parameters
    ----------
    step : callable
        One simulation step (input -> output spikes), from a freshly reset simulation.
    kick, drive : ndarray
        The graph's input during the kick and afterwards.
    phase : callable
        The bump's phase (rad) from the spikes of a 50 ms exponential window.
    dt_s, settle_s, measure_s, read_every_s : float
        The step; the time left to settle after the kick; the time measured; how often the phase is read (s).
    label : str
        Names the drive in the error.

    Raises
    ------
    ConfigError
        The bump died while measured; fewer than two readings.
    """
    kick_steps, settle_steps = int(round(0.1 / dt_s)), int(round(settle_s / dt_s))
    read_every = max(1, int(round(read_every_s / dt_s)))
    decay = math.exp(-dt_s / 0.05)
    trace = np.zeros(0)
    times, phases = [], []
    for k in range(kick_steps + settle_steps + int(round(measure_s / dt_s))):
        out = step(kick if k < kick_steps else drive)
        trace = out if k == 0 else trace * decay + out
        if k >= kick_steps + settle_steps and (k + 1) % read_every == 0:
            if not trace.any():
                raise ConfigError(f"the bump died while moving at {label}; these parameters cannot be calibrated")
            times.append(k * dt_s)
            phases.append(phase(trace))
    if len(times) < 2:
        raise ConfigError(f"measure_s is too short for two readings (every {read_every_s * 1e3:g} ms)")
    return float(np.polyfit(times, np.unwrap(phases), 1)[0])
