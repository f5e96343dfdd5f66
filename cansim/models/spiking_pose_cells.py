"""Spiking 3-DoF pose cells for RatSLAM: a spiking head-direction ring and a spiking place sheet.

RatSLAM's pose cells code (x', y', theta') conjunctively and translate each theta layer
along its own heading (:class:`cansim.path_integration.PlanarMotion`). A spiking
population can only shift its synapses uniformly (Zhang 1996), so here the pose is
factorised (the "head-direction + place population" variant of issue 23): a spiking HD
ring integrates the yaw rate, and a spiking 2-D sheet integrates the velocity
``vtrans * (cos theta, sin theta)`` with ``theta`` the ring's decoded heading. Both are
:class:`cansim.spiking.SpikingPopulation` with calibrated velocity leads.

One SLAM iteration runs ``network_s_per_iteration`` seconds of network time (steps of
``dt_s``); the odometry is scaled to it (an iteration's displacement in network time),
so the packets move at speeds where a spiking packet does not pin to the lattice.

:class:`SpikingPoseCells` has the pose-cell interface :class:`cansim.models.slam_loop.SlamLoop`
uses: ``shape`` (xy, xy, heading) in pose-cell units, ``decode`` (fractional pose cells),
``activity`` (the outer product of the sheet's and the ring's spike counts, binned to
the pose grid, sum 1: what learnt LV weights learn, Eq 2.18) and ``step`` (an injection
- stored-location Eq 5.8 or learnt Eq 2.17 energy on the pose grid - becomes currents:
its marginal over heading into the sheet, its marginal over (x, y) into the ring).

Measured on the synthetic 5-loop route of ``examples/ratslam_synthetic.py`` (map ATE,
m; spiking / rate / dead reckoning): seed 0 0.071 / 0.046 / 0.273; held-out seeds 1 and 2
0.074 / 0.048 / 0.227 and 0.069 / 0.055 / 0.237. Tuned on seed 0: the view current (a
current of 3-60 threshold units did not move the sheet's packet, 150 moves it 3 cells in
two iterations) and the sheet's recurrent weight (100, the ring's, lets a 2-D packet die;
300 holds it). Limits: the velocity leads are calibrated along one axis at 10-80 cells/s,
and a sheet packet pins to the lattice below ~5 cells/s per axis, so the decoded (x', y')
wander from the rate model's: on that route (seed 0) by a median 2.8 cells in x' and 7.7 in
y', where random points of the 21 x 21 grid lie 8.4 apart - between views y' is not
tracked (a user's check, session 49); the map still closes its loops because the views
re-anchor the packets (1,002 re-localisations against the rate model's 899). A population
too weak to hold its packet raises :class:`~cansim.errors.ZeroActivityError`: when made, if
its kicked packet does not settle (:data:`MIN_SETTLED_SPIKES` in the decoding window; noise
alone gives ~5, and a ``sheet_recurrent_weight`` of 0 once decoded poses from them), and in a
step whose window falls under :data:`MIN_LIVING_SHARE` of its settled count (on the route the
windows keep 85-95 % of it, seeds 0, 3 and 5). Cost: 10.2 ms an iteration
against the rate engine's 0.11 ms (~90x; the route 15 s against 0.2 s; ``bench/README.md``).
Export: :func:`cansim.spiking.to_nir` takes the ring (``.ring``) and the sheet (``.sheet``)
one at a time, each a still attractor; the ring-to-sheet coupling, the velocity shifts and
the view currents have no NIR form, and NIR's LIF cell drops the 2 ms refractory period
(``to_nir`` warns: their rates outside cansim are many times these).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from cansim.axes import Axis
from cansim.errors import ConfigError, CorruptFileError, InvalidInputError, ShapeError, ZeroActivityError
from cansim.spiking import (
    HD_RING_ATTRACTOR,
    SHEET_ATTRACTOR,
    SpikeCountDecoder,
    SpikingPopulation,
    calibrate_velocity_lead,
    spiking_params_from_rate,
)
from whisker_io.validation import ConfigDataclass, checked, config_field, validate_fields

__all__ = ["SpikingPoseCellParams", "SpikingPoseCells"]



#: A packet whose decoding window holds under this share of the spikes it held when it settled has died out.
MIN_LIVING_SHARE = 0.1
#: Fewest spikes in the decoding window of a packet that settled: below it the kick did not hold (noise alone gives
#: ~5 in the 50 ms window; the default ring's packet 145, the sheet's 680; a sheet of weight 100 still 198).
MIN_SETTLED_SPIKES = 20


@dataclass(frozen=True)
class SpikingPoseCellParams(ConfigDataclass):
    """Parameters of :class:`SpikingPoseCells`.

    Parameters
    ----------
    ring_cells_per_heading_cell : int
        HD-ring neurons per pose-cell heading step (10: 360 neurons for 36 heading cells).
    sheet_cells_per_cell : int
        Sheet neurons per pose cell along x and y (2).
    ring_recurrent_weight, sheet_recurrent_weight : float
        ``w_rec`` of the ring (100, :data:`cansim.spiking.HD_RING_ATTRACTOR`'s) and the sheet (300).
    network_s_per_iteration : float
        Network time of one SLAM iteration (s, 0.1).
    dt_s : float
        Spiking step (s, 0.001).
    view_current_per_energy : float
        Peak current (threshold units) per unit of injected energy, held for the iteration
        (2000: a stored view's 0.05 gives 100; the packet's own global inhibition is of that
        order, ~14 spikes a step of weight 1 through a 5 ms synapse, so a weaker input is not felt).
    max_view_current : float
        Cap of that current (threshold units, 150).
    calibration_speeds_cells_per_s : tuple of float
        Speeds (cells/s of each population) at which the velocity leads are calibrated.
    seed : int
        Noise seed of both populations.
    """

    ring_cells_per_heading_cell: int = checked(10, int, minimum=1)
    sheet_cells_per_cell: int = checked(2, int, minimum=1)
    ring_recurrent_weight: float = checked(100.0, float, minimum=0)
    sheet_recurrent_weight: float = checked(300.0, float, minimum=0)
    network_s_per_iteration: float = checked(0.1, float, above=0)
    dt_s: float = checked(0.001, float, above=0)
    view_current_per_energy: float = checked(2000.0, float, minimum=0)
    max_view_current: float = checked(150.0, float, minimum=0)
    calibration_speeds_cells_per_s: tuple[float, ...] = (10.0, 20.0, 40.0, 80.0)
    seed: int = checked(0, int, minimum=0)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not self.network_s_per_iteration >= self.dt_s or self.network_s_per_iteration / self.dt_s > 1e5:
            raise ConfigError("network_s_per_iteration must hold between 1 and 1e5 steps of dt_s")
        speeds = tuple(float(s) for s in self.calibration_speeds_cells_per_s)
        if not speeds or any(not (math.isfinite(s) and s > 0) for s in speeds) or list(speeds) != sorted(set(speeds)):
            raise ConfigError("calibration_speeds_cells_per_s must be distinct, ascending, finite and > 0")
        object.__setattr__(self, "calibration_speeds_cells_per_s", speeds)


class SpikingPoseCells:
    """Spiking pose cells on an ``(xy_cells, xy_cells, heading_cells)`` grid (see the module docstring).

    Parameters
    ----------
    xy_cells, heading_cells : int
        The pose grid (as :meth:`cansim.Population.openratslam`).
    cell_size_m : float
        Metres per translational pose cell.
    params : SpikingPoseCellParams
    frame : {"standard"}
        Heading 0 moves along +x' (the only frame: OpenRatSLAM's is for the C++ parity engine).

    Notes
    -----
    The packets start at the grid centre ``(xy//2, xy//2, heading//2)`` as the rate pose
    cells; construction calibrates both velocity leads (a few seconds).
    """

    def __init__(self, xy_cells: int, heading_cells: int, cell_size_m: float,
                 params: SpikingPoseCellParams = SpikingPoseCellParams(), *, frame: str = "standard") -> None:
        if not isinstance(params, SpikingPoseCellParams):
            raise ConfigError("params must be a SpikingPoseCellParams")
        if frame != "standard":
            raise ConfigError("spiking pose cells use frame='standard' (heading 0 along +x')")
        config_field(xy_cells, "xy_cells", int, minimum=4)
        config_field(heading_cells, "heading_cells", int, minimum=4)
        config_field(cell_size_m, "cell_size_m", float, above=0)
        self._params = params
        self._shape = (int(xy_cells), int(xy_cells), int(heading_cells))
        self._k = params.sheet_cells_per_cell
        self._r = params.ring_cells_per_heading_cell
        self._n_sub = int(round(params.network_s_per_iteration / params.dt_s))
        ring_axes = (Axis.angle("heading", heading_cells * self._r),)
        sheet_step = cell_size_m / self._k
        sheet_axes = (Axis.linear("x", xy_cells * self._k, sheet_step), Axis.linear("y", xy_cells * self._k, sheet_step))
        speeds = params.calibration_speeds_cells_per_s
        ring_p = calibrate_velocity_lead(ring_axes, spiking_params_from_rate(
            HD_RING_ATTRACTOR, recurrent_weight=params.ring_recurrent_weight), speeds, dt_s=params.dt_s, duration_s=1.0,
            iterations=1)
        sheet_p = calibrate_velocity_lead(sheet_axes, spiking_params_from_rate(
            SHEET_ATTRACTOR, recurrent_weight=params.sheet_recurrent_weight), speeds, dt_s=params.dt_s, duration_s=1.0,
            iterations=1)
        self._ring = SpikingPopulation(ring_axes, ring_p, dt_s=params.dt_s, seed=params.seed)
        self._sheet = SpikingPopulation(sheet_axes, sheet_p, dt_s=params.dt_s, seed=params.seed + 1)
        self._window = max(1, int(round(0.05 / params.dt_s)))
        self.reset()

    # ------------------------------------------------------------ state
    def reset(self) -> None:
        """Packets at the grid centre, settled for 0.3 s of network time."""
        nx, _, nh = self._shape
        self._ring.reset()
        self._sheet.reset()
        self._ring_dec = SpikeCountDecoder(self._ring.axes, self._window, half_width=10)
        self._sheet_dec = SpikeCountDecoder(self._sheet.axes, self._window, half_width=3 * self._k)
        self._ring.kick([(nh // 2) * self._r])
        self._sheet.kick([(nx // 2) * self._k] * 2)
        for _ in range(int(round(0.3 / self._params.dt_s))):
            self._ring_dec.add(self._ring.step())
            self._sheet_dec.add(self._sheet.step())
        settled = (int(self._ring_dec.counts.sum()), int(self._sheet_dec.counts.sum()))
        for name, count, weight in (("ring", settled[0], "ring_recurrent_weight"), ("sheet", settled[1], "sheet_recurrent_weight")):
            if count < MIN_SETTLED_SPIKES:  # noise alone: the kicked packet did not hold (a silent sheet gives ~5)
                raise ZeroActivityError(f"the spiking pose cells' {name} did not hold its packet: {count} spikes in the "
                                        f"{self._window}-step window after settling; raise {weight} (its default holds it)")
        self._settled = None
        self._best = self._decode()
        self._settled = settled  # the settled packets' window counts: what a living packet's are measured against

    @property
    def shape(self) -> tuple[int, int, int]:
        """The pose grid (xy, xy, heading)."""
        return self._shape

    @property
    def size(self) -> int:
        """Cells of the pose grid."""
        return int(np.prod(self._shape))

    @property
    def dtype(self) -> np.dtype:
        """float64 (the activity's)."""
        return np.dtype(np.float64)

    @property
    def params(self) -> SpikingPoseCellParams:
        """The parameters."""
        return self._params

    @property
    def ring(self) -> SpikingPopulation:
        """The spiking head-direction ring."""
        return self._ring

    @property
    def sheet(self) -> SpikingPopulation:
        """The spiking place sheet."""
        return self._sheet

    @property
    def activity(self) -> np.ndarray:
        """Outer product of the sheet's and the ring's window spike counts on the pose grid, sum 1 (a copy)."""
        nx, ny, nh = self._shape
        s = self._sheet_dec.counts.reshape(nx, self._k, ny, self._k).sum(axis=(1, 3)).astype(np.float64)
        r = self._ring_dec.counts.reshape(nh, self._r).sum(axis=1).astype(np.float64)
        a = s[:, :, None] * r[None, None, :]
        total = a.sum()
        return a / total if total > 0 else a

    @activity.setter
    def activity(self, value: np.ndarray) -> None:
        # the spiking state is restored by from_arrays; a saved activity is only checked here
        arr = np.asarray(value)
        if arr.shape != self._shape or not np.all(np.isfinite(arr)):
            raise ShapeError(f"activity must be finite with shape {self._shape}")

    # ---------------------------------------------------------- dynamics
    def _decode(self) -> np.ndarray:
        if self._settled is not None:  # a few noise spikes would still decode: a packet under a tenth of its settled
            # window count has died out (a sheet_recurrent_weight of 0 decoded poses from 4-5 spikes)
            for name, dec, settled in (("ring", self._ring_dec, self._settled[0]), ("sheet", self._sheet_dec, self._settled[1])):
                if dec.counts.sum() < MIN_LIVING_SHARE * settled:
                    raise ZeroActivityError(f"the spiking pose cells' {name} packet died out ({int(dec.counts.sum())} spikes "
                                            f"in its window against {settled} when it settled); raise its recurrent weight")
        try:
            xy = self._sheet_dec.decode() / self._k
            th = self._ring_dec.decode()[0] / self._r
        except ZeroActivityError:
            raise ZeroActivityError("a spiking pose-cell packet died out; raise the recurrent weights") from None
        return np.array([xy[0], xy[1], th], dtype=np.float64)

    def decode(self) -> np.ndarray:
        """Decoded pose, fractional pose cells (x', y', theta'), shape (3,)."""
        return self._best.copy()

    def _currents(self, injection) -> tuple[Optional[np.ndarray], Optional[np.ndarray]]:
        if injection is None:
            return None, None
        idx = np.asarray(injection[0], dtype=np.int64)
        val = np.asarray(injection[1], dtype=np.float64)
        if idx.shape != val.shape or idx.ndim != 1 or (len(idx) and (idx.min() < 0 or idx.max() >= self.size)) \
                or not np.all(np.isfinite(val)) or np.any(val < 0):
            raise InvalidInputError("injection must be (flat indices on the pose grid, finite energies >= 0)")
        if not len(idx):
            return None, None
        from scipy.ndimage import gaussian_filter, gaussian_filter1d

        grid = np.zeros(self.size)
        np.add.at(grid, idx, val)
        grid = grid.reshape(self._shape)
        p = self._params
        peak = min(float(grid.sum()) * p.view_current_per_energy, p.max_view_current)
        # each marginal, on the populations' cells, spread as wide as their packets (the
        # excitation sigma) and scaled to the peak current: a packet-shaped input recruits a packet
        sheet = gaussian_filter(np.kron(grid.sum(axis=2), np.ones((self._k, self._k))),
                                SHEET_ATTRACTOR.exc_sigma, mode="wrap")
        ring = gaussian_filter1d(np.repeat(grid.sum(axis=(0, 1)), self._r), HD_RING_ATTRACTOR.exc_sigma, mode="wrap")
        return sheet * (peak / sheet.max()), ring * (peak / ring.max())

    def step(self, velocity: Any, omega: Any, dt: float, *, injection: Any = None) -> np.ndarray:
        """One SLAM iteration: ``velocity`` m/s forward, ``omega`` rad/s yaw, over ``dt`` s of odometry.

        The iteration runs ``network_s_per_iteration`` of network time with the odometry
        scaled to it; an ``injection`` (flat pose-grid indices, energies) is held as current
        for the whole iteration. Returns the decoded pose (fractional pose cells).

        Raises
        ------
        InvalidInputError
            Non-finite odometry, ``dt <= 0``, a step of half the grid or more (m or rad) or a
            bad injection; nothing changed.
        ZeroActivityError
            A packet died out (the recurrent weights are too weak for the input).
        """
        v, w, d = (float(x) for x in (velocity, omega, dt))
        if not (math.isfinite(v) and math.isfinite(w) and math.isfinite(d) and d > 0):
            raise InvalidInputError(f"odometry must be finite with dt > 0, got v={velocity!r}, omega={omega!r}, dt={dt!r}")
        half_m = self._shape[0] * self._sheet.axes[0].step * self._k / 2.0
        if abs(v * d) >= half_m or abs(w * d) >= math.pi:
            raise InvalidInputError(f"one iteration moves {v * d:g} m and turns {w * d:g} rad: more than half the pose grid "
                                    f"({half_m:g} m, pi rad) is not path integration; split the odometry sample")
        sheet_cur, ring_cur = self._currents(injection)
        scale = d / self._params.network_s_per_iteration
        w_net, v_net = w * scale, v * scale
        nh = self._shape[2]
        theta = self._best[2] * 2.0 * math.pi / nh
        vel = np.zeros(2)
        for j in range(self._n_sub):
            if j % 10 == 0:
                theta = self._ring_dec.decode()[0] * 2.0 * math.pi / (nh * self._r)
                vel[0], vel[1] = v_net * math.cos(theta), v_net * math.sin(theta)
            self._ring_dec.add(self._ring.step(w_net, ring_cur))
            self._sheet_dec.add(self._sheet.step(vel, sheet_cur))
        self._best = self._decode()
        return self._best.copy()

    # ------------------------------------------------------ save / load
    def state_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """Both populations' and decoders' state and the decoded pose, for a saved model."""
        out = {prefix + "best": self._best.copy()}
        out.update(self._ring.state_arrays(prefix + "ring_"))
        out.update(self._sheet.state_arrays(prefix + "sheet_"))
        out.update(self._ring_dec.state_arrays(prefix + "ringdec_"))
        out.update(self._sheet_dec.state_arrays(prefix + "sheetdec_"))
        return out

    def restore_state(self, arrays, prefix: str = "") -> None:
        """Set what :meth:`state_arrays` wrote (a model built with the same parameters); CorruptFileError names a bad field."""
        best = np.asarray(arrays.get(prefix + "best", np.zeros(0)))
        if best.shape != (3,) or not np.all(np.isfinite(best)):
            raise CorruptFileError("expected 3 finite numbers", field=prefix + "best")
        self._ring.restore_state(arrays, prefix + "ring_")
        self._sheet.restore_state(arrays, prefix + "sheet_")
        self._ring_dec.restore_state(arrays, prefix + "ringdec_")
        self._sheet_dec.restore_state(arrays, prefix + "sheetdec_")
        self._best = best.astype(np.float64)

    def __repr__(self) -> str:
        return f"SpikingPoseCells(shape={self._shape}, ring={self._ring.size}, sheet={self._sheet.size} neurons)"
