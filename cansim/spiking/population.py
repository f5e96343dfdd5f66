"""Spiking continuous-attractor population on an N-D periodic grid (LIF or Poisson cells).

One neuron per cell of the grid of :class:`cansim.Population`; the recurrent synapses
are the rate model's excitation / inhibition kernels (:mod:`cansim.spiking.connectivity`)
plus a global inhibition, the cells are :mod:`cansim.spiking.neurons`. The simulation is
clock-driven with a fixed step ``dt_s``; one step, in order:

1. synaptic current ``I <- a_syn I + (1 - a_syn) I_ext + sum_{j spiked last step} W_.j``,
   ``a_syn = exp(-dt / tau_syn)`` (``I_ext`` is an optional external current, held over the step);
2. neurons (LIF or Poisson) update from ``I`` and emit this step's spikes;
3. the spikes are kept for the next step's recurrent input and the decoder.

Path integration (Zhang 1996): :meth:`SpikingPopulation.step` takes a velocity per axis
(units of the axis per second: rad/s on an angular axis); the recurrent kernel is shifted
by ``velocity * velocity_lead_s / step`` cells for that step, so the packet is pushed
ahead and moves. ``velocity_lead_s`` is the gain of that mapping; fit it with
:func:`cansim.spiking.calibrate_velocity_lead`.

Noise is drawn from ``numpy.random.default_rng(seed)`` in Python and handed to the
backend, so the numpy reference and the numba backend see the same numbers and emit the
same spikes for the same seed.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from typing import BinaryIO, Optional, Sequence

import numpy as np

from cansim.axes import Axis
from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.params import AttractorParams
from cansim.spiking.connectivity import RecurrentKernel, scatter_targets
from cansim.spiking.neurons import NeuronParams
from whisker_io.persistence import read_npz, write_npz
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, finite_vector, validate_fields

__all__ = ["SpikingParams", "SpikingPopulation", "SPIKING_BACKENDS"]

#: backends with a spiking implementation (numpy is the reference); the one list, read by
#: SpikingPopulation and by the backend conformance suite (cansim.testing.conformance)
SPIKING_BACKENDS = ("numpy", "numba")


#: Version of the ``.npz`` layout :meth:`SpikingPopulation.save` writes.
_SAVE_FORMAT = 1

#: Narrowest Gaussian of :meth:`SpikingPopulation.kick`, cells: a narrower one underflows (exp(-d^2 / 2 sigma^2) = 0/0).
MIN_KICK_SIGMA_CELLS = 0.05


@dataclass(frozen=True)
class SpikingParams(ConfigDataclass):
    """Network-level parameters of a spiking attractor population.

    Parameters
    ----------
    attractor : AttractorParams
        Excitation / inhibition kernels (the rate model's, unchanged).
    neurons : NeuronParams
        Cell model and its constants.
    recurrent_weight : float
        ``w_rec``: current jump per spike at kernel value 1 (threshold units), >= 0.
    global_weight : float
        ``w_global``: inhibitory current jump every spike sends to every cell, >= 0.
    velocity_lead_s : float
        Seconds of lead of the shifted kernel: the shift is ``velocity * lead / step`` cells.
    lead_table : tuple of (speed_cells_per_s, lead_s) pairs
        Optional lead as a function of the speed along an axis (cells/s, ascending,
        linearly interpolated, held constant outside); overrides ``velocity_lead_s``.
        :func:`cansim.spiking.calibrate_velocity_lead` fills it.
    """

    attractor: AttractorParams = AttractorParams()
    neurons: NeuronParams = NeuronParams()
    recurrent_weight: float = checked(100.0, float, minimum=0, message="{name} must be finite and >= 0, got {value!r}")
    global_weight: float = checked(1.0, float, minimum=0, message="{name} must be finite and >= 0, got {value!r}")
    velocity_lead_s: float = checked(0.01, float, message="{name} must be finite, got {value!r}")
    lead_table: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        validate_fields(self)  # numpy scalars -> Python numbers (as every configuration does), the declared checks
        if not isinstance(self.attractor, AttractorParams):
            raise ConfigError("attractor must be a cansim.AttractorParams")
        if not isinstance(self.neurons, NeuronParams):
            raise ConfigError("neurons must be a cansim.spiking.NeuronParams")
        try:
            table = np.asarray(self.lead_table, dtype=np.float64).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ConfigError("lead_table must be a sequence of (speed_cells_per_s, lead_s) pairs") from None
        if not np.isfinite(table).all() or np.any(np.diff(table[:, 0]) <= 0) or np.any(table[:, 0] < 0):
            raise ConfigError("lead_table speeds must be finite, >= 0 and strictly ascending; leads finite")
        object.__setattr__(self, "lead_table", tuple((float(a), float(b)) for a, b in table))

    def lead_s(self, speed_cells_per_s: np.ndarray) -> np.ndarray:
        """The kernel lead (s) for speeds along the axes (cells/s, any sign), shape as the input."""
        speed = np.abs(np.asarray(speed_cells_per_s, dtype=np.float64))
        if not self.lead_table:
            return np.full(speed.shape, float(self.velocity_lead_s))
        table = np.asarray(self.lead_table)
        return np.interp(speed, table[:, 0], table[:, 1])


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    return int(seed)


class SpikingPopulation:
    """A grid of spiking cells with periodic boundaries and attractor connectivity.

    Parameters
    ----------
    axes : sequence of Axis
        The grid, as for :class:`cansim.Population` (one neuron per cell, C order).
    params : SpikingParams
    dt_s : float
        Simulation step (s), > 0 and not larger than the refractory period.
    seed : int
        Seed of the noise generator (membrane noise or Poisson draws).
    backend : {"numpy", "numba"}
        ``"numpy"`` is the reference; ``"numba"`` gives the same spikes, faster.

    Notes
    -----
    All cells start at rest (``v = v_rest``, ``I = 0``) and silent; with membrane noise or
    Poisson cells and a bias current the packet forms on its own, or seed it with
    :meth:`kick`.
    """

    def __init__(
        self,
        axes: Sequence[Axis],
        params: SpikingParams = SpikingParams(),
        *,
        dt_s: float = 0.001,
        seed: int = 0,
        backend: str = "numba",
    ) -> None:
        axes = tuple(axes)
        if not axes:
            raise ShapeError("a spiking population needs at least one axis; the grid would be empty")
        if any(not isinstance(a, Axis) for a in axes):
            raise InvalidInputError("axes must be cansim.Axis instances")
        if not isinstance(params, SpikingParams):
            raise ConfigError("params must be a cansim.spiking.SpikingParams")
        if backend not in SPIKING_BACKENDS:
            raise ConfigError(f"backend must be one of {SPIKING_BACKENDS}, got {backend!r}")
        _check_seed(seed)
        self._n_ref = params.neurons.refractory_steps(dt_s)  # validates dt_s
        self._axes = axes
        self._shape = tuple(a.size for a in axes)
        self._n = int(np.prod(self._shape))
        self._params = params
        self._dt = float(dt_s)
        self._seed = int(seed)
        self._backend = backend
        nrn = params.neurons
        self._a_syn = math.exp(-self._dt / nrn.tau_syn_s)
        self._a_mem = math.exp(-self._dt / nrn.tau_mem_s)
        self._noise_scale = nrn.noise_sigma * math.sqrt(1.0 - math.exp(-2.0 * self._dt / nrn.tau_mem_s))
        self._kernel = RecurrentKernel.from_params(params.attractor, self._shape, params.recurrent_weight)
        self._steps_per_axis = np.array([a.step for a in axes], dtype=np.float64)
        strides = np.cumprod((1,) + self._shape[::-1])[-2::-1]
        self._strides = np.ascontiguousarray(strides, dtype=np.int64)
        self._shape_arr = np.array(self._shape, dtype=np.int64)
        self._rec = np.zeros(self._n, dtype=np.float64)
        self._out = np.zeros(self._n, dtype=np.int64)
        self._noise = np.zeros(self._n, dtype=np.float64)
        self._empty = np.zeros(0, dtype=np.float64)
        self._shift_key: bytes = b""
        self._shifted = self._kernel
        self.reset()

    # ------------------------------------------------------------ properties
    @property
    def axes(self) -> tuple[Axis, ...]:
        """The axes (C order)."""
        return self._axes

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape."""
        return self._shape

    @property
    def size(self) -> int:
        """Number of neurons."""
        return self._n

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return len(self._axes)

    @property
    def params(self) -> SpikingParams:
        """Network parameters."""
        return self._params

    @property
    def dt_s(self) -> float:
        """Simulation step (s)."""
        return self._dt

    @property
    def seed(self) -> int:
        """Seed of the noise generator."""
        return self._seed

    @property
    def backend(self) -> str:
        """``"numpy"`` or ``"numba"``."""
        return self._backend

    @property
    def kernel(self) -> RecurrentKernel:
        """The stationary (zero-velocity) recurrent kernel."""
        return self._kernel

    @property
    def time_s(self) -> float:
        """Simulated time since the last :meth:`reset` (s)."""
        return self._t * self._dt

    @property
    def v(self) -> np.ndarray:
        """Copy of the membrane potentials, shape :attr:`shape`."""
        return self._v.reshape(self._shape).copy()

    @property
    def synaptic_current(self) -> np.ndarray:
        """Copy of the synaptic currents, shape :attr:`shape`."""
        return self._i.reshape(self._shape).copy()

    @property
    def last_spikes(self) -> np.ndarray:
        """Flat indices of the cells that spiked in the last step (ascending, int64)."""
        return self._spk.copy()

    def set_backend(self, backend: str) -> None:
        """Switch backend; the state and the noise stream are kept."""
        if backend not in SPIKING_BACKENDS:
            raise ConfigError(f"backend must be one of {SPIKING_BACKENDS}, got {backend!r}")
        self._backend = backend

    def reset(self, seed: Optional[int] = None) -> None:
        """All cells at rest and silent, time 0, noise generator re-seeded (``seed`` or the original)."""
        if seed is not None:
            self._seed = _check_seed(seed)
        nrn = self._params.neurons
        self._v = np.full(self._n, nrn.v_rest, dtype=np.float64)
        self._i = np.zeros(self._n, dtype=np.float64)
        self._ref = np.zeros(self._n, dtype=np.int64)
        self._spk = np.zeros(0, dtype=np.int64)
        self._rng = np.random.default_rng(self._seed)
        self._t = 0

    def kick(self, center: Sequence[float], current: float = 10.0, sigma_cells: float = 2.0) -> None:
        """Add a periodic Gaussian bump of synaptic current (peak ``current``) at fractional cell ``center``.

        Used to seed a packet at a known place; it decays with ``tau_syn``.
        """
        c = finite_vector(center, self.ndim, "center (fractional cells, one per axis)")
        cur = finite_scalar(current, "current")
        sig = finite_scalar(sigma_cells, "sigma_cells")
        if not MIN_KICK_SIGMA_CELLS <= sig <= max(self._shape):
            raise InvalidInputError(f"sigma_cells must lie in [{MIN_KICK_SIGMA_CELLS:g}, {max(self._shape)}] cells "
                                    f"(a narrower bump underflows to NaN, a wider one is flat), got {sig!r}")
        g = np.ones((), dtype=np.float64)
        for ax, n in enumerate(self._shape):
            d = (np.arange(n) - c[ax] + n / 2.0) % n - n / 2.0
            g = np.multiply.outer(g, np.exp(-(d * d) / (2.0 * sig * sig)))
        self._i += cur * g.ravel()

    # -------------------------------------------------------------- dynamics
    def _check_velocity(self, velocity) -> Optional[np.ndarray]:
        if velocity is None:
            return None
        # one per axis, units/s; complex numbers, text and NaN are typed errors (the shared validator)
        return finite_vector(velocity, self.ndim, "velocity (one per axis, units/s; check the odometry source)")

    def _check_current(self, current) -> Optional[np.ndarray]:
        if current is None:
            return None
        cur = np.asarray(current, dtype=np.float64)
        if cur.ndim == 0:
            cur = np.full(self._n, float(cur))
        elif cur.shape == self._shape or cur.shape == (self._n,):
            cur = np.ascontiguousarray(cur.reshape(-1))
        else:
            raise ShapeError(f"current must be a scalar or have shape {self._shape}, got {cur.shape}")
        if not np.isfinite(cur).all():
            raise InvalidInputError("current must be finite (no NaN/inf); check the input source")
        return cur

    def step(self, velocity=None, current=None) -> np.ndarray:
        """Advance one step of ``dt_s``.

        Parameters
        ----------
        velocity : float or ndarray, shape (ndim,), optional
            Velocity per axis (axis units per second, rad/s on angular axes) that shifts
            the recurrent kernel for this step (path integration).
        current : float or ndarray, shape :attr:`shape`, optional
            External current (threshold units) entering the synapses for this step.

        Returns
        -------
        ndarray, int64
            Flat indices of the cells that spiked in this step, ascending.

        Raises
        ------
        InvalidInputError, ShapeError
            Non-finite or mis-shaped input; the state is unchanged.
        """
        vel = self._check_velocity(velocity)
        ext = self._check_current(current)
        kernel = self._kernel
        if vel is not None and np.any(vel != 0.0):
            cells_per_s = vel / self._steps_per_axis
            shift = cells_per_s * self._params.lead_s(cells_per_s)
            key = shift.tobytes()
            if key != self._shift_key:  # a constant velocity reuses the last shifted kernel
                self._shift_key, self._shifted = key, kernel.shifted(shift)
            kernel = self._shifted
        nrn = self._params.neurons
        poisson = nrn.model == "poisson"
        if poisson:
            self._rng.random(out=self._noise)
            noise = self._noise
        elif self._noise_scale > 0.0:
            self._rng.standard_normal(out=self._noise)
            noise = self._noise
        else:
            noise = self._empty
        g = self._params.global_weight * len(self._spk)
        args = (
            kernel, ext, g, noise, poisson, nrn.poisson_gain_hz * self._dt,
        )
        if self._backend == "numba":
            spikes = self._step_numba(*args)
        else:
            spikes = self._step_numpy(*args)
        self._spk = spikes
        self._t += 1
        return spikes.copy()

    def _step_numba(self, kernel, ext, g, noise, poisson, gain_dt) -> np.ndarray:
        from cansim.spiking._numba_spiking import step_kernel

        nrn = self._params.neurons
        w = kernel.weights
        nd = self._shape_arr.shape[0]
        kw = np.ones(nd, dtype=np.int64)  # the weights' extent per grid axis (1 past their own axes)
        kw[:min(nd, w.ndim)] = w.shape[:nd]
        count = step_kernel(
            self._v, self._i, self._ref, self._spk, len(self._spk), w.reshape(-1), kw,
            np.asarray(kernel.offset, dtype=np.int64), self._shape_arr, self._strides, self._rec,
            self._a_syn, 1.0 - self._a_syn, ext if ext is not None else self._empty, g,
            nrn.v_rest, nrn.resistance, nrn.bias_current, self._a_mem, noise, self._noise_scale,
            nrn.v_threshold, nrn.v_reset, self._n_ref, poisson, gain_dt, self._out,
        )
        return self._out[:count].copy()

    def _step_numpy(self, kernel, ext, g, noise, poisson, gain_dt) -> np.ndarray:
        """The reference: same operations, same order as the numba kernel."""
        nrn = self._params.neurons
        rec = np.zeros(self._n, dtype=np.float64)
        if len(self._spk):
            targets = scatter_targets(self._spk, kernel).ravel()
            vals = np.broadcast_to(kernel.weights.ravel(), (len(self._spk), kernel.weights.size)).ravel()
            np.add.at(rec, targets, vals)
        e = (1.0 - self._a_syn) * ext if ext is not None else 0.0
        cur = self._a_syn * self._i + e + (rec - g)
        self._i = cur
        refr = self._ref > 0
        free = ~refr
        if poisson:
            fire = free & (noise < gain_dt * np.maximum(cur + nrn.bias_current, 0.0))
            vn = self._v
        else:
            v_inf = nrn.v_rest + nrn.resistance * (cur + nrn.bias_current)
            vn = v_inf + (self._v - v_inf) * self._a_mem
            if noise.shape[0] == self._n:
                vn = vn + self._noise_scale * noise
            fire = free & (vn > nrn.v_threshold)
        v = np.where(fire | refr, nrn.v_reset, vn)
        ref = np.where(refr, self._ref - 1, self._ref)
        ref[fire] = self._n_ref
        self._v, self._ref = v, ref
        return np.flatnonzero(fire).astype(np.int64)

    def run(self, n_steps: int, velocity=None, current=None) -> list[np.ndarray]:
        """:meth:`step` ``n_steps`` times with the same input; returns the spikes of every step."""
        if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
            raise InvalidInputError(f"n_steps must be an integer >= 0, got {n_steps!r}")
        self._check_velocity(velocity)
        self._check_current(current)
        return [self.step(velocity, current) for _ in range(int(n_steps))]

    def state_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The dynamic state (potentials, currents, refractory counters, last spikes, step count
        and the noise generator) as named arrays; :meth:`restore_state` sets it back exactly."""

        return {prefix + "v": self._v.copy(), prefix + "i": self._i.copy(), prefix + "ref": self._ref.copy(),
                prefix + "spk": self._spk.copy(), prefix + "t": np.array(self._t, dtype=np.int64),
                prefix + "rng": np.array(json.dumps(self._rng.bit_generator.state))}

    def restore_state(self, arrays, prefix: str = "") -> None:
        """Set the state written by :meth:`state_arrays` (same grid).

        Raises
        ------
        CorruptFileError
            A field is missing, of the wrong shape or not finite (named).
        """
        from cansim.errors import CorruptFileError

        def need(key: str) -> np.ndarray:
            if prefix + key not in arrays:
                raise CorruptFileError("missing", field=prefix + key)
            return np.asarray(arrays[prefix + key])

        v, i, ref, spk, t = need("v"), need("i"), need("ref"), need("spk"), need("t")
        for key, arr in (("v", v), ("i", i), ("ref", ref)):
            if arr.shape != (self._n,) or not np.all(np.isfinite(arr)):
                raise CorruptFileError(f"expected {self._n} finite values", field=prefix + key)
        if spk.ndim != 1 or spk.dtype.kind not in "iu" or (spk.size and (spk.min() < 0 or spk.max() >= self._n)):
            raise CorruptFileError("expected flat cell indices", field=prefix + "spk")
        if t.shape != () or t.dtype.kind not in "iu" or int(t) < 0:
            raise CorruptFileError("expected a step count >= 0", field=prefix + "t")
        rng = np.random.default_rng()
        try:
            rng.bit_generator.state = json.loads(str(need("rng")))
        except (ValueError, TypeError, KeyError) as exc:
            raise CorruptFileError(f"not a generator state ({exc})", field=prefix + "rng") from exc
        self._v, self._i = v.astype(np.float64), i.astype(np.float64)
        self._ref, self._spk = ref.astype(np.int64), spk.astype(np.int64)
        self._t, self._rng = int(t), rng

    # ----------------------------------------------------------- save / load
    def save(self, path: "str | os.PathLike[str] | BinaryIO") -> None:
        """Write the population - grid, parameters, step, seed, backend and its dynamic state
        (:meth:`state_arrays`: potentials, currents, refractory counters, last spikes, step
        count, noise generator) - to an ``.npz`` file (no pickle).

        :meth:`load` gives a population that continues exactly as this one would (the same
        spikes); a NIR graph (:func:`cansim.spiking.to_nir`) carries the network only.
        A file name is written to a temporary name beside it and renamed, so a crash never
        leaves a half-written file; an open binary file is written as is. As :func:`numpy.savez`,
        ``.npz`` is added to a name without it (``save("ring")`` writes ``ring.npz``).
        """
        from dataclasses import asdict

        description = {
            "axes": [{"name": a.name, "size": a.size, "step": a.step, "angular": a.angular} for a in self._axes],
            "params": asdict(self._params), "dt_s": self._dt, "seed": self._seed, "backend": self._backend,
        }
        write_npz(path, {"spiking_format": np.int64(_SAVE_FORMAT), "population": np.array(json.dumps(description)),
                         **self.state_arrays("state_")})

    @classmethod
    def load(cls, path: "str | os.PathLike[str] | BinaryIO") -> "SpikingPopulation":
        """Read a population written by :meth:`save`, in the state it was saved in.

        Raises
        ------
        CorruptFileError
            The file is unreadable, of another format version, or a field is missing or
            malformed (named in the error).
        """
        from cansim.errors import CansimError, CorruptFileError

        arrays = read_npz(path)
        fmt = arrays.get("spiking_format")
        if fmt is None or fmt.shape != () or fmt.dtype.kind not in "iu" or int(fmt) != _SAVE_FORMAT:
            raise CorruptFileError(f"expected spiking population format {_SAVE_FORMAT}, got "
                                   f"{None if fmt is None else fmt.tolist()!r}", field="spiking_format")
        try:
            d = json.loads(str(arrays["population"]))
            p = dict(d["params"])
            params = SpikingParams(attractor=AttractorParams(**p.pop("attractor")),
                                   neurons=NeuronParams(**p.pop("neurons")), **p)
            axes = [Axis(a["name"], a["size"], a["step"], a["angular"]) for a in d["axes"]]
            population = cls(axes, params, dt_s=d["dt_s"], seed=d["seed"], backend=d["backend"])
        except (KeyError, TypeError, ValueError, AttributeError, CansimError) as exc:
            raise CorruptFileError(f"not a spiking population description ({exc})", field="population") from exc
        population.restore_state(arrays, "state_")
        return population

    def with_params(self, params: SpikingParams) -> "SpikingPopulation":
        """A new population on the same grid, step, seed and backend with other parameters."""
        return SpikingPopulation(self._axes, params, dt_s=self._dt, seed=self._seed, backend=self._backend)

    def __repr__(self) -> str:
        ax = ", ".join(f"{a.name}={a.size}" for a in self._axes)
        return f"SpikingPopulation({ax}, model={self._params.neurons.model!r}, dt_s={self._dt}, backend={self._backend!r})"


