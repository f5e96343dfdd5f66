"""A spiking 2-D sheet that path-integrates velocity with neurons and synapses, as a NIR graph.

The 2-D counterpart of :mod:`cansim.spiking.rotation_ring` (issue 23, item 2), in the
style of Burak & Fiete (2009): a periodic ``n x n`` sheet of LIF cells holds a bump (the
position, one cell = ``cell_size_m``), and four direction populations (+x, -x, +y, -y),
each a copy of the sheet, move it. Direction cell ``j`` gets a one-to-one input from sheet
cell ``j``, a bias and ``velocity_gain`` times the velocity component along its direction
(m/s); it excites the sheet around ``j + shift_cells`` along its direction. A pool of
inhibitory cells holds the bump's rate (why a 2-D sheet needs it and a ring does not:
:mod:`cansim.spiking.conjunctive`, which writes the graph).

The graph's input is ``n^2 + 2`` values: an external current per sheet cell (threshold
units, C order: cell ``(i, j)`` at ``i n + j``, ``i`` along x) followed by the velocity
``(v_x, v_y)`` in m/s; its output is the sheet's spikes. :func:`sheet_input` builds the
input, :func:`sheet_position_cells` decodes a position from spike counts (the population
vector per axis), :func:`calibrate_sheet_speed` measures the bump's speed against the
input with cansim's own simulation of the graph
(:class:`cansim.spiking.nir_graph_sim.NIRGraphSimulator`) and
:meth:`SheetCalibration.command` inverts it, so every consumer gets the same commands.

The defaults were chosen on a 16 x 16 sheet with constant velocities along +x (measured
with cansim's simulation, 0.1 ms step): recurrent weight 14.7 with no pool lets the
kicked bump die and 15 runs it at ~2.5 kHz per cell (global weights of 0.3-5 and kicks of
up to 8 threshold units did not help); with the pool (8 cells, bias -0.35, 0.02 per sheet
spike in, 1.0 per pool spike out) and recurrent weight 20 the bump holds at ~500 Hz over
~37 cells, and direction currents of 0.24, 0.32 and 0.64 threshold units along x moved it at
about 4.3, 6 and 11 cells/s, along +x only (0.32 on both axes: equally along both).
With the defaults, :func:`calibrate_sheet_speed` measured inputs of 0.1, 0.2, 0.4, 0.6,
0.8, 1.0 and 1.2 m/s moving the bump at 0.03, 0.05, 0.36, 0.58, 0.76, 0.90 and 1.06 m/s:
below ~0.3 m/s the lattice holds the bump back, which the calibration's inverse makes up for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cansim.decoding import circular_mean_index
from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.params import AttractorParams
from cansim.spiking.conjunctive import (
    check_calibration_arguments,
    check_speed_curve,
    conjunctive_graph,
    invert_speed_curve,
    measure_phase_speed,
)
from cansim.spiking.correspondence import SHEET_ATTRACTOR
from cansim.spiking.neurons import NeuronParams
from cansim.spiking.nir_io import NIR_STEP_S
from cansim.spiking.population import SpikingParams
from cansim.spiking.rotation_ring import RING_NEURONS
from whisker_io.validation import ConfigDataclass, checked, config_field, validate_fields

__all__ = [
    "VelocitySheetParams",
    "velocity_sheet_graph",
    "sheet_input",
    "sheet_kick",
    "sheet_position_cells",
    "SheetCalibration",
    "calibrate_sheet_speed",
    "VELOCITY_SHEET_FORMAT",
]

#: value of ``graph.metadata["cansim"]["format"]`` in graphs written by :func:`velocity_sheet_graph`
VELOCITY_SHEET_FORMAT = "cansim.spiking.velocity_sheet/1"

#: directions of the four populations (unit vectors along x, y), in the graph's order
DIRECTIONS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])


@dataclass(frozen=True)
class VelocitySheetParams(ConfigDataclass):
    """Parameters of the path-integrating sheet (module docstring).

    Parameters
    ----------
    n_cells : int
        Sheet cells per side ``n`` (12-32; ``5 n^2 + pool_cells`` neurons, dense weights).
    cell_size_m : float
        Distance one sheet cell stands for (m); the sheet wraps every ``n cell_size_m``.
    attractor : AttractorParams
        Kernels of the sheet (:data:`cansim.spiking.SHEET_ATTRACTOR`).
    neurons : NeuronParams
        LIF cells of every population (``bias_current`` is the sheet's bias).
    recurrent_weight, global_weight : float
        ``w_rec`` and ``w_global`` of the sheet (as :class:`cansim.spiking.SpikingParams`).
    direction_bias : float
        Bias current of the direction cells (threshold units).
    sheet_to_direction_weight : float
        Current jump of a direction cell per spike of its sheet cell, >= 0.
    velocity_gain : float
        Current of a direction cell per m/s of velocity along its direction, >= 0.
    direction_to_sheet_weight : float
        Peak scale of the shifted excitation from direction cells to the sheet, >= 0.
    shift_cells : int
        Offset of those projections (cells), 1 <= shift < n / 2.
    pool_cells : int
        Inhibitory pool cells (0: none).
    pool_bias : float
        Bias current of the pool cells (threshold units; below 1: they fire only once the
        sheet's total rate drives them).
    sheet_to_pool_weight, pool_to_sheet_weight : float
        Current jump of every pool cell per sheet spike, and of every sheet cell per pool
        spike (an inhibition), >= 0.
    """

    n_cells: int = checked(16, int, minimum=12, maximum=32)
    cell_size_m: float = checked(0.1, float, above=0, maximum=100.0)
    attractor: AttractorParams = SHEET_ATTRACTOR
    neurons: NeuronParams = field(default_factory=lambda: RING_NEURONS)
    recurrent_weight: float = checked(20.0, float, minimum=0)
    global_weight: float = checked(0.1, float, minimum=0)
    direction_bias: float = checked(0.3, float)
    sheet_to_direction_weight: float = checked(0.3, float, minimum=0)
    velocity_gain: float = checked(0.5, float, minimum=0)
    direction_to_sheet_weight: float = checked(9.0, float, minimum=0)
    shift_cells: int = checked(3, int, minimum=1)
    pool_cells: int = checked(8, int, minimum=0, maximum=1024)
    pool_bias: float = checked(-0.35, float)
    sheet_to_pool_weight: float = checked(0.02, float, minimum=0)
    pool_to_sheet_weight: float = checked(1.0, float, minimum=0)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.attractor, AttractorParams):
            raise ConfigError("attractor must be a cansim.AttractorParams")
        if not isinstance(self.neurons, NeuronParams) or self.neurons.model != "lif":
            raise ConfigError("neurons must be a cansim.spiking.NeuronParams with model='lif'")
        if not self.shift_cells < self.n_cells / 2:
            raise ConfigError(f"shift_cells must be below n_cells / 2 ({self.n_cells / 2}), got {self.shift_cells}")

    @property
    def sheet_params(self) -> SpikingParams:
        """The sheet's :class:`SpikingParams` (its stationary network)."""
        return SpikingParams(attractor=self.attractor, neurons=self.neurons,
                             recurrent_weight=float(self.recurrent_weight), global_weight=float(self.global_weight))


def velocity_sheet_graph(params: VelocitySheetParams = VelocitySheetParams(), *, dt_s: float = NIR_STEP_S) -> Any:
    """The ``nir.NIRGraph`` of the path-integrating sheet (layout and units: the module docstring).

    Parameters
    ----------
    params : VelocitySheetParams
    dt_s : float
        The step the consumers will use (s); snnTorch always uses ``1e-4``.

    Raises
    ------
    ConfigError
        Bad parameters or step.
    """
    if not isinstance(params, VelocitySheetParams):
        raise ConfigError("params must be a cansim.spiking.velocity_sheet.VelocitySheetParams")
    n = int(params.n_cells)
    nrn = params.neurons
    meta = {
        "format": VELOCITY_SHEET_FORMAT,
        "nir_step_s": float(dt_s),
        "n_cells": n,
        "cell_size_m": float(params.cell_size_m),
        "directions": DIRECTIONS.tolist(),
        "recurrent_weight": float(params.recurrent_weight),
        "global_weight": float(params.global_weight),
        "direction_bias": float(params.direction_bias),
        "sheet_to_direction_weight": float(params.sheet_to_direction_weight),
        "velocity_gain": float(params.velocity_gain),
        "direction_to_sheet_weight": float(params.direction_to_sheet_weight),
        "shift_cells": int(params.shift_cells),
        "pool_cells": int(params.pool_cells),
        "pool_bias": float(params.pool_bias),
        "sheet_to_pool_weight": float(params.sheet_to_pool_weight),
        "pool_to_sheet_weight": float(params.pool_to_sheet_weight),
        "refractory_s": float(nrn.refractory_s),
    }
    return conjunctive_graph(
        shape=(n, n),
        attractor=params.sheet_params,
        shifts=int(params.shift_cells) * DIRECTIONS,
        velocity_map=DIRECTIONS.astype(np.float64),
        velocity_gain=params.velocity_gain,
        direction_bias=params.direction_bias,
        attractor_to_direction_weight=params.sheet_to_direction_weight,
        direction_to_attractor_weight=params.direction_to_sheet_weight,
        pool_cells=params.pool_cells,
        pool_bias=params.pool_bias,
        attractor_to_pool_weight=params.sheet_to_pool_weight,
        pool_to_attractor_weight=params.pool_to_sheet_weight,
        dt_s=dt_s,
        metadata=meta,
    )


def _cells(value: Any) -> int:
    """``n_cells`` of the helper functions: an integer in [1, 4096] (InvalidInputError otherwise)."""
    return config_field(value, "n_cells", int, minimum=1, maximum=4096, error=InvalidInputError)


def sheet_input(current: Any, velocity_m_s: Any, n_cells: int) -> np.ndarray:
    """The graph's input vector: sheet current then ``(v_x, v_y)`` (m/s).

    Parameters
    ----------
    current : float or array_like (n_cells, n_cells) or (n_cells**2,)
        External current per sheet cell (threshold units); a scalar for every cell.
    velocity_m_s : array_like (2,)
        Velocity along x and y (m/s).
    n_cells : int
        Sheet cells per side.

    Returns
    -------
    ndarray (n_cells**2 + 2,)

    Raises
    ------
    ShapeError, InvalidInputError
        Another shape; non-finite values; a bad ``n_cells``.
    """
    n = _cells(n_cells)
    try:
        cur = np.asarray(current, dtype=np.float64)
        vel = np.asarray(velocity_m_s, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError("current and velocity_m_s must be numbers") from None
    if cur.ndim == 0:
        cur = np.full(n * n, float(cur))
    if cur.shape not in ((n, n), (n * n,)):
        raise ShapeError(f"current must be a scalar or have shape ({n}, {n}) or ({n * n},), got {cur.shape}")
    if vel.shape != (2,):
        raise ShapeError(f"velocity_m_s must be (v_x, v_y), shape (2,), got {vel.shape}")
    out = np.concatenate([cur.reshape(-1), vel])
    if not np.isfinite(out).all():
        raise InvalidInputError("current and velocity_m_s must be finite (no NaN/inf)")
    return out


def sheet_kick(n_cells: int, centre_cells: Any, *, peak: float = 2.0, sigma_cells: float = 2.0) -> np.ndarray:
    """A Gaussian current (n_cells, n_cells) centred on ``centre_cells`` (x, y; periodic), threshold units.

    Raises
    ------
    InvalidInputError, ShapeError
        A bad size, a centre that is not 2 finite numbers, a non-positive width.
    """
    n = _cells(n_cells)
    c = np.asarray(centre_cells, dtype=np.float64)
    if c.shape != (2,) or not np.isfinite(c).all():
        raise ShapeError(f"centre_cells must be 2 finite numbers (x, y cells), got {centre_cells!r}")
    if not (math.isfinite(peak) and math.isfinite(sigma_cells) and sigma_cells > 0):
        raise InvalidInputError(f"peak must be finite and sigma_cells > 0, got {peak!r}, {sigma_cells!r}")
    i = np.arange(n)
    dx = (i - c[0] + n / 2.0) % n - n / 2.0
    dy = (i - c[1] + n / 2.0) % n - n / 2.0
    return peak * np.exp(-(dx[:, None] ** 2 + dy[None, :] ** 2) / (2.0 * sigma_cells**2))


def sheet_position_cells(counts: Any, n_cells: int) -> np.ndarray:
    """The bump's position (x, y) in cells, in ``[0, n_cells)``: the population vector of the counts per axis.

    Parameters
    ----------
    counts : array_like (n_cells, n_cells) or (n_cells**2,)
        Spike counts (or any non-negative activity) per sheet cell.

    Raises
    ------
    ShapeError, InvalidInputError
        Another shape; negative or non-finite counts; no activity at all.
    """
    n = _cells(n_cells)
    c = np.asarray(counts, dtype=np.float64)
    if c.shape not in ((n, n), (n * n,)):
        raise ShapeError(f"counts must have shape ({n}, {n}) or ({n * n},), got {c.shape}")
    c = c.reshape(n, n)
    if not np.isfinite(c).all() or (c < 0).any():
        raise InvalidInputError("counts must be finite and >= 0")
    if not c.any():
        raise InvalidInputError("no activity: the sheet has no bump to read")
    return np.array([circular_mean_index(c.sum(axis=1)), circular_mean_index(c.sum(axis=0))])


@dataclass(frozen=True)
class SheetCalibration:
    """Measured speed of the sheet's bump against the velocity input, and its inverse.

    Parameters
    ----------
    input_m_s : tuple of float
        Input speeds (m/s) along +x, ascending, the first 0.
    bump_m_s : tuple of float
        The bump's measured speed at each (m/s: cells/s times ``cell_size_m``), the first 0.

    Only the rising part of the curve is inverted. The sheet is symmetric under the four
    directions, so :meth:`command` scales a velocity's magnitude and keeps its direction.
    """

    input_m_s: tuple[float, ...]
    bump_m_s: tuple[float, ...]

    def __post_init__(self) -> None:
        check_speed_curve(self.input_m_s, self.bump_m_s, ("input_m_s", "bump_m_s"), "m/s", "calibrate_sheet_speed")

    @property
    def max_m_s(self) -> float:
        """The fastest speed the bump reaches on the rising part of the curve (m/s)."""
        return invert_speed_curve(self.input_m_s, self.bump_m_s, np.inf)[1]

    def command(self, velocity_m_s: Any) -> np.ndarray:
        """The input velocity (m/s) that moves the bump at ``velocity_m_s``: shape (2,) or (T, 2).

        The magnitude goes through the inverted curve (saturating at :attr:`max_m_s`),
        the direction is kept.

        Raises
        ------
        ShapeError, InvalidInputError
            Not (2,) or (T, 2); non-finite values.
        """
        v = np.asarray(velocity_m_s, dtype=np.float64)
        if v.ndim not in (1, 2) or v.shape[-1] != 2:
            raise ShapeError(f"velocity_m_s must have shape (2,) or (T, 2), got {v.shape}")
        if not np.isfinite(v).all():
            raise InvalidInputError("velocity_m_s must be finite (no NaN/inf)")
        speed = np.linalg.norm(v, axis=-1, keepdims=True)
        wanted, _ = invert_speed_curve(self.input_m_s, self.bump_m_s, speed)
        return v * np.divide(wanted, speed, out=np.zeros_like(speed), where=speed > 0)


def calibrate_sheet_speed(
    params: VelocitySheetParams = VelocitySheetParams(),
    speeds_m_s: Any = (0.1, 0.2, 0.4, 0.6, 0.8, 1.0),
    *,
    dt_s: float = NIR_STEP_S,
    settle_s: float = 0.3,
    measure_s: float = 0.4,
) -> SheetCalibration:
    """Measure the bump's speed at constant inputs along +x (cansim's own simulation of the graph).

    For each input: a 100 ms Gaussian kick (sigma 2 cells, 2 threshold units) at the
    sheet's centre, ``settle_s`` of motion, then the slope (least squares) of the unwrapped
    x position (:func:`sheet_position_cells` of the spikes in a 50 ms exponential window,
    read every 5 ms) over ``measure_s``.

    Raises
    ------
    ConfigError
        Bad parameters, speeds or durations; a bump that dies during the measurement.
    """
    from cansim.spiking.nir_graph_sim import NIRGraphSimulator

    speeds = check_calibration_arguments(speeds_m_s, "speeds_m_s", "m/s", settle_s, measure_s)
    if not isinstance(params, VelocitySheetParams):
        raise ConfigError("params must be a cansim.spiking.velocity_sheet.VelocitySheetParams")
    n = int(params.n_cells)
    sim = NIRGraphSimulator(velocity_sheet_graph(params, dt_s=dt_s), dt_s=dt_s)
    kick = sheet_input(sheet_kick(n, (n / 2.0, n / 2.0)), (0.0, 0.0), n)
    measured = []
    for v in speeds:
        sim.reset()
        rad_s = measure_phase_speed(sim.step, kick, sheet_input(0.0, (v, 0.0), n),
                                    lambda counts: circular_mean_index(counts.reshape(n, n).sum(axis=1)) * 2.0 * np.pi / n,
                                    dt_s=dt_s,
                                    settle_s=settle_s, measure_s=measure_s, read_every_s=5e-3, label=f"{v} m/s")
        measured.append(rad_s * n / (2.0 * np.pi) * float(params.cell_size_m))
    return SheetCalibration((0.0, *speeds), (0.0, *measured))
