"""N-dimensional periodic continuous-attractor population (the CAN model page of the docs-1.2, 1.4, 1.6)."""

from __future__ import annotations

import copy
import logging
import math
import os
from typing import BinaryIO, Optional, Sequence, Union

import numpy as np

from cansim._renamed import renamed_keywords
from cansim.axes import Axis
from cansim.backends import Backend, get_backend
from cansim.errors import InvalidInputError, ShapeError, ZeroActivityError
from cansim.grid_inputs import MAX_INJECTION, MAX_SHIFT_CELLS, check_shift, checked_injection, whole_cells  # noqa: F401 (0.1 paths)
from cansim.params import AttractorParams
from cansim.population_run import run_inputs
from whisker_io.validation import finite_array, finite_scalar, finite_vector, whole_number
from cansim.path_integration import (
    MotionModel,
    MotionShifts,
    PlanarMotion,
    SixDofMotion,
    UniformMotion,
    check_motion_shifts,
    shifts_range_checked,
)

__all__ = ["Population"]

log = logging.getLogger(__name__)

IndexLike = Union[Sequence[int], np.ndarray]

#: Default metres per translational cell of :meth:`Population.whisker6d`: the default of
#: ``WhiskerRatSLAMConfig.cell_size_m`` (a test checks that the two agree).
WHISKER6D_CELL_SIZE_M = 0.1

#: Most cells a population may have (2**26: a float64 activity of 512 MiB), checked before
#: anything is allocated; the models' configs refuse larger grids with the same limit.
MAX_CELLS = 2**26


class Population:
    """A grid of rate cells with periodic boundaries on every axis, activity ``A >= 0``.

    One class serves as head-direction ring (1-D), RatSLAM pose cells (3-D), the
    6-D WhiskerRatSLAM grid and any other N. All state is on the instance.

    Parameters
    ----------
    axes : sequence of Axis
        Name, size and physical step of every axis (C order of the activity array).
    params : AttractorParams
        Excitation / inhibition kernels and global inhibition.
    dtype : numpy dtype
        ``np.float32`` (default) or ``np.float64``.
    backend : str or Backend
        ``"numba"`` (default, the fast CPU path), ``"numpy"`` (the reference, slow) or
        ``"opencl"``; see :func:`cansim.available_backends`.
    motion : MotionModel or None
        How odometry becomes shifts in :meth:`integrate` / :meth:`step`;
        default :class:`UniformMotion`.
    decode_window : int
        Half-width of the population-vector box (OpenRatSLAM ``pc_cells_to_avg``, 3).

    Notes
    -----
    A new population holds one active cell (activity 1) at the centre
    ``size // 2`` of every axis.
    """

    def __init__(
        self,
        axes: Sequence[Axis],
        params: AttractorParams = AttractorParams(),
        *,
        dtype: np.dtype | type = np.float32,
        backend: str | Backend = "numba",
        motion: Optional[MotionModel] = None,
        decode_window: int = 3,
    ) -> None:
        axes = tuple(axes)
        if not axes:
            raise ShapeError("a population needs at least one axis; the grid would be empty")
        if any(not isinstance(a, Axis) for a in axes):
            raise InvalidInputError("axes must be cansim.Axis instances")
        names = [a.name for a in axes]
        if len(set(names)) != len(names):
            raise InvalidInputError(f"axis names must be unique, got {names}")
        dt = np.dtype(dtype)
        if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise InvalidInputError(f"dtype must be float32 or float64, got {dt}")
        if not isinstance(decode_window, (int, np.integer)) or decode_window < 0:
            raise InvalidInputError(f"decode_window must be an integer >= 0, got {decode_window!r}")
        size = 1
        for a in axes:  # Python integers: no overflow before the limit is checked
            size *= int(a.size)
        if size > MAX_CELLS:
            raise InvalidInputError(
                f"a grid of {' x '.join(str(a.size) for a in axes)} = {size} cells is more than the limit {MAX_CELLS} "
                "(2**26: a float64 activity of 512 MiB); use fewer cells per axis")
        self._axes = axes
        self._size = size
        self._params = params
        self._dtype = dt
        if motion is not None and not isinstance(motion, MotionModel):
            what = f"the class {motion.__name__}" if isinstance(motion, type) else type(motion).__name__
            raise InvalidInputError(f"motion must be a MotionModel instance (e.g. UniformMotion(), or an instance of a "
                                    f"subclass implementing bind(axes)), got {what}")
        self._motion = motion if motion is not None else UniformMotion()
        self._motion.check_axes(axes)
        self._motion_shifts, self._motion_trusted = self._motion.bind_checked_and_trusted(axes)
        # a built-in model that refuses oversized shifts itself spares the per-step array check
        self._shifts_checked = shifts_range_checked(self._motion_shifts) and shifts_range_checked(self._motion_trusted)
        if type(self._motion) not in (UniformMotion, PlanarMotion, SixDofMotion):  # one's own: its output checked
            self._motion_shifts, self._motion_trusted = (_checking(f, self.shape, type(self._motion).__name__)
                                                         for f in (self._motion_shifts, self._motion_trusted))
        exc, inh = params.kernels(len(axes))
        self._exc = exc.taps
        self._inh = inh.taps
        self._phi = float(params.global_inhibition)
        self._window = int(decode_window)
        self._backend = get_backend(backend)
        self._a = np.zeros(self.shape, dtype=dt)
        self._spare = np.zeros(self.shape, dtype=dt)
        self._regions = self._new_regions()
        self.reset_cell([a.size // 2 for a in axes])
        self._last_decoded: Optional[np.ndarray] = None

    # ------------------------------------------------------------------ presets
    @classmethod
    @renamed_keywords(dim_xy="xy_cells", dim_th="heading_cells", cell_size="cell_size_m")
    def openratslam(
        cls,
        xy_cells: int = 21,
        heading_cells: int = 36,
        cell_size_m: float = 1.0,
        *,
        frame: str = "standard",
        params: Optional[AttractorParams] = None,
        **kwargs,
    ) -> "Population":
        """OpenRatSLAM pose cells: axes (x', y', theta'), default 21 x 21 x 36.

        The names and defaults are :class:`cansim.models.ratslam_config.RatSLAMConfig`'s
        (OpenRatSLAM's ``pc_dim_xy``, ``pc_dim_th``, ``pc_cell_x_size``): ``xy_cells``
        on each of x and y, ``heading_cells`` on theta, ``cell_size_m`` metres per
        translational cell. Kernels 7-wide sigma 1 excitation, 5-wide sigma 2
        inhibition, phi 2e-5. Starts with one cell at
        ``(xy_cells//2, xy_cells//2, heading_cells//2)`` (C++: (10, 10, 18)).
        ``frame="openratslam"`` moves theta index 0 along +y' as the C++ does.
        The 0.1 names ``dim_xy``, ``dim_th``, ``cell_size`` still work until 0.3
        (DeprecationWarning).
        """
        axes = (
            Axis.linear("x", xy_cells, cell_size_m),
            Axis.linear("y", xy_cells, cell_size_m),
            Axis.angle("theta", heading_cells),
        )
        return cls(axes, params or AttractorParams(), motion=PlanarMotion(frame), **kwargs)

    @classmethod
    @renamed_keywords(n="heading_cells")
    def head_direction(cls, heading_cells: int = 360, *, params: Optional[AttractorParams] = None,
                       **kwargs) -> "Population":
        """A 1-D head-direction ring of ``heading_cells`` cells (step ``2*pi/heading_cells`` rad).

        Default kernels are OpenRatSLAM's theta-axis kernels (excitation 7 taps sigma 1,
        inhibition 5 taps sigma 2, phi 2e-5); :meth:`integrate` takes the angular
        velocity in rad/s as ``velocity``.
        """
        return cls((Axis.angle("heading", heading_cells),), params or AttractorParams(), **kwargs)

    @classmethod
    @renamed_keywords(n="grid_cells", n_angle="angle_cells", cell_size="cell_size_m")
    def whisker6d(
        cls,
        grid_cells: int = 5,
        cell_size_m: float = WHISKER6D_CELL_SIZE_M,
        *,
        angle_cells: Optional[int] = None,
        params: Optional[AttractorParams] = None,
        **kwargs,
    ) -> "Population":
        """The thesis' 6-D pose cells (x, y, z, roll, pitch, yaw), ``grid_cells`` per translational axis.

        Kernels per Eq 5.10: width 5 on every axis, excitation variance 1 (sigma 1),
        inhibition variance 2 (sigma sqrt 2), normalised as the printed normal density
        (``kernel_normalisation="pdf"``: over the 5^6 window the excitation sums to 0.9464,
        the inhibition to 0.6430; the thesis tuned its packet with these; the printed
        ``(sigma^2)^6`` in the exponent is a typo for ``sigma^2``); phi 2e-5.

        The names and defaults are
        :class:`cansim.models.whisker_ratslam.WhiskerRatSLAMConfig`'s: ``grid_cells``
        (5, the thesis'), ``cell_size_m`` metres per translational cell (the thesis does
        not give it; 0.1 m, :data:`WHISKER6D_CELL_SIZE_M`, about the Ch.5 step between
        whisks), ``angle_cells`` cells per angular axis, steps ``2*pi/angle_cells``
        (None: ``grid_cells``). The 0.1 names ``n``, ``cell_size``, ``n_angle`` still
        work until 0.3 (DeprecationWarning); 0.1's default cell size was 0.02 m.
        """
        na = grid_cells if angle_cells is None else angle_cells
        axes = (
            Axis.linear("x", grid_cells, cell_size_m),
            Axis.linear("y", grid_cells, cell_size_m),
            Axis.linear("z", grid_cells, cell_size_m),
            Axis.angle("roll", na),
            Axis.angle("pitch", na),
            Axis.angle("yaw", na),
        )
        p = params or AttractorParams(
            exc_width=5, exc_sigma=1.0, inh_width=5, inh_sigma=math.sqrt(2.0), kernel_normalisation="pdf"
        )
        return cls(axes, p, motion=SixDofMotion(), **kwargs)

    # --------------------------------------------------------------- properties
    @property
    def axes(self) -> tuple[Axis, ...]:
        """The axes, in the order of the activity array's dimensions."""
        return self._axes

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape (cells per axis)."""
        return tuple(a.size for a in self._axes)

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return len(self._axes)

    @property
    def size(self) -> int:
        """Total number of cells."""
        return self._size

    @property
    def dtype(self) -> np.dtype:
        """Storage dtype of the activity."""
        return self._dtype

    @property
    def params(self) -> AttractorParams:
        """The attractor parameters."""
        return self._params

    @property
    def motion(self) -> MotionModel:
        """The motion model used by :meth:`integrate` and :meth:`step`."""
        return self._motion

    @property
    def backend(self) -> str:
        """Name of the backend in use."""
        return self._backend.name

    def set_backend(self, backend: str | Backend) -> None:
        """Switch backend; the activity is kept."""
        self._backend = get_backend(backend)
        self._regions = self._new_regions()

    def _new_regions(self) -> Optional[np.ndarray]:
        """Where the two grids can be non-zero, for a backend whose step takes it
        (``regions`` of :meth:`cansim.backends.numba_backend.NumbaBackend.step`): list 0 the
        activity's boxes, list 1 the spare grid's, list 2 the step's result. Starts as the
        whole grid (not known); None for other backends."""
        if not getattr(self._backend, "tracks_regions", False):
            return None
        return self._backend.new_regions(self.shape)

    def _forget_regions(self) -> None:
        """The grids were written by something that does not report where: the whole grid."""
        if self._regions is not None:
            self._backend.forget_regions(self._regions, slice(0, 2), self.shape)

    @property
    def activity(self) -> np.ndarray:
        """A copy of the activity grid, shape :attr:`shape`."""
        return self._a.copy()

    @activity.setter
    def activity(self, value: np.ndarray) -> None:
        arr = np.asarray(value)
        if arr.shape != self.shape:
            raise ShapeError(f"activity must have shape {self.shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError("activity must be finite (no NaN/inf)")
        if np.any(arr < 0):
            raise InvalidInputError("activity must be >= 0")
        self._a = arr.astype(self._dtype, copy=True, order="C")
        self._last_decoded = None
        self._forget_regions()

    @property
    def total(self) -> float:
        """Sum of all activity."""
        return float(self._a.sum(dtype=np.float64))

    # ---------------------------------------------------------------- resetting
    def _check_index(self, index: IndexLike) -> tuple[int, ...]:
        idx = tuple(whole_cells(index, "index (one whole cell number per axis)").ravel().tolist())
        if len(idx) != self.ndim:
            raise ShapeError(f"index must have {self.ndim} entries (one per axis), got {len(idx)}")
        return tuple(i % n for i, n in zip(idx, self.shape))

    def reset_cell(self, index: IndexLike) -> None:
        """Silence all cells and set the cell at ``index`` (wrapped) to 1."""
        idx = self._check_index(index)
        a = np.zeros(self.shape, dtype=self._dtype)
        a[idx] = 1.0
        self._a = a
        self._last_decoded = None
        self._forget_regions()

    def reset_gaussian(self, center: Sequence[float], sigma: float | Sequence[float] = 1.0) -> None:
        """Set a periodic Gaussian packet at fractional cell ``center``, normalised to sum 1.

        Parameters
        ----------
        center : sequence of float, one per axis, in cells.
        sigma : float or sequence of float, standard deviation in cells (> 0).
        """
        c = finite_vector(center, self.ndim, "center")
        s = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (self.ndim,))
        if not np.all(np.isfinite(s)) or np.any(s <= 0):
            raise InvalidInputError(f"sigma must be finite and > 0 cells, got {sigma!r}")
        a = np.ones((), dtype=np.float64)
        for ax, n in enumerate(self.shape):
            d = (np.arange(n) - c[ax] + n / 2.0) % n - n / 2.0  # wrapped distance, Eq 2.22
            a = np.multiply.outer(a, np.exp(-(d * d) / (2.0 * s[ax] ** 2)))
        self._a = (a / a.sum()).astype(self._dtype)
        self._last_decoded = None
        self._forget_regions()

    # ----------------------------------------------------------------- dynamics
    def _commit(self, new: np.ndarray) -> None:
        if new is self._spare:
            self._spare = self._a
        self._a = new
        self._last_decoded = None
        self._forget_regions()

    def inject(self, index: IndexLike, energy: float) -> None:
        """Add ``energy`` (>= 0) to one cell (wrapped index)."""
        idx = self._check_index(index)
        e = finite_scalar(energy, "energy")
        if not 0 <= e <= MAX_INJECTION:
            raise InvalidInputError(f"energy must be finite and in [0, {MAX_INJECTION:g}], got {energy!r}")
        flat = np.array([np.ravel_multi_index(idx, self.shape)], dtype=np.int64)
        self._commit(self._backend.inject(self._a, flat, np.array([e]), out=self._spare))

    def inject_flat(self, flat_index: np.ndarray, values: np.ndarray) -> None:
        """Scatter-add ``values`` (>= 0) at flat C-order indices (e.g. from learnt LV weights)."""
        fi, vals = checked_injection(flat_index, values, self._size)
        if len(fi):
            self._commit(self._backend.inject(self._a, fi, vals, out=self._spare))

    def dynamics(self) -> None:
        """Local excitation, local inhibition, global inhibition, normalisation (Alg 3-5, OpenRatSLAM's step order 2-5).

        Raises
        ------
        ZeroActivityError
            Every cell would be silent; the activity is left as it was.
        """
        new = self._backend.dynamics(self._a, self._exc, self._inh, self._phi, out=self._spare)
        if new is None:
            self._forget_regions()  # the spare grid may have been written
            raise ZeroActivityError(
                "all activity fell below the global inhibition threshold; state left unchanged "
                "(re-seed with reset_cell/reset_gaussian or inject energy)"
            )
        self._commit(new)

    def shift(self, cells: Sequence[float]) -> None:
        """Shift the whole grid by a real number of cells per axis (any magnitude)."""
        s = finite_vector(cells, self.ndim, "shift")
        check_shift(s, "uniform")
        self._commit(self._backend.shift(self._a, s, out=self._spare))

    def shift_conditional(self, shift_axes: Sequence[int], shifts: np.ndarray) -> None:
        """Shift every slice along ``shift_axes`` by its own vector (see ``Backend.shift_conditional``).

        Parameters
        ----------
        shift_axes : sequence of int
            Translated axes, ascending.
        shifts : ndarray, shape ``cond_shape + (len(shift_axes),)``, cells
        """
        ax, sh = self._check_conditional(shift_axes, shifts)
        self._commit(self._backend.shift_conditional(self._a, ax, sh, out=self._spare))

    def _check_conditional(self, shift_axes, shifts) -> tuple[tuple[int, ...], np.ndarray]:
        try:
            if isinstance(shift_axes, (str, bytes)):
                raise TypeError
            ax = tuple(whole_number(a, "shift_axes") for a in shift_axes)
        except TypeError:
            raise InvalidInputError(f"shift_axes must be a sequence of axis indices, got {shift_axes!r}") from None
        if not ax or list(ax) != sorted(set(ax)) or ax[0] < 0 or ax[-1] >= self.ndim:
            raise InvalidInputError(f"shift_axes must be distinct ascending axes in [0, {self.ndim}), got {ax}")
        cond_shape = tuple(n for i, n in enumerate(self.shape) if i not in ax)
        sh = np.ascontiguousarray(finite_array(shifts, cond_shape + (len(ax),), "shifts"))
        check_shift(sh, "conditional")
        return ax, sh

    def integrate(self, velocity=None, omega=None, dt: float = 1.0) -> None:
        """Path integration only (Fig 5.7-5.11) with the population's motion model.

        Parameters
        ----------
        velocity : float or ndarray
            PlanarMotion: forward speed vtrans (m/s). SixDofMotion: (3,) m/s in the
            end-effector frame. UniformMotion: one velocity per axis (units/s).
        omega : float or ndarray
            PlanarMotion: vrot (rad/s). SixDofMotion: (3,) rotation vector rate (rad/s).
        dt : float
            Seconds, >= 0.
        """
        ms = self._motion_shifts(velocity, omega, dt)
        check_shift(ms.cond_shifts, "translation")
        check_shift(ms.uniform, "uniform")
        cur = self._a
        if ms.cond_shifts is not None:
            cur = self._backend.shift_conditional(cur, ms.shift_axes, ms.cond_shifts)
        if ms.uniform is not None:
            cur = self._backend.shift(cur, ms.uniform)
        if cur is not self._a:
            self._commit(cur)

    def decode(self) -> np.ndarray:
        """Population-vector estimate, fractional cell index per axis, shape (ndim,) (Eq 5.11-5.12)."""
        if self._last_decoded is None:
            self._last_decoded = self._backend.decode(self._a, self._window)
        return self._last_decoded.copy()

    def decode_physical(self) -> np.ndarray:
        """:meth:`decode` times each axis' step: metres for linear axes, radians for angular."""
        return self.decode() * np.array([a.step for a in self._axes])

    def step(
        self,
        velocity=None,
        omega=None,
        dt: float = 1.0,
        *,
        injection: Optional[tuple[np.ndarray, np.ndarray]] = None,
    ) -> np.ndarray:
        """One iteration: injection, dynamics, path integration, decoding (Alg 3-5, OpenRatSLAM's step order).

        Parameters
        ----------
        velocity, omega, dt
            As :meth:`integrate`.
        injection : (flat_index, values) or None
            Energy scatter-added before the dynamics (e.g. ``LocalViewCells.injection``).

        Returns
        -------
        ndarray, shape (ndim,)
            The decoded fractional cell index per axis.

        Raises
        ------
        InvalidInputError, ShapeError
            Bad odometry or injection; nothing changed.
        ZeroActivityError
            The dynamics collapsed; nothing changed.
        """
        return self._step_shifts(self._motion_shifts(velocity, omega, dt), injection)

    def _step_validated(self, velocity, omega, dt: float, *, injection=None) -> np.ndarray:
        """:meth:`step` for odometry validated already: the fields of a :class:`maps.odometry.PlanarOdometry`
        or :class:`maps.odometry.SpatialOdometry` (finite floats or float64 (3,) arrays, ``dt >= 0``).

        The loop that built the odometry object (:class:`cansim.models.slam_loop.SlamLoop`) calls
        this, so one step's odometry is checked once. The values are not checked again; the
        shifts they make are (:data:`cansim.grid_inputs.MAX_SHIFT_CELLS` depends on this grid's cell sizes),
        and so is the injection. Same result as :meth:`step`, bit for bit.
        """
        return self._step_shifts(self._motion_trusted(velocity, omega, dt), injection)

    def _step_shifts(self, ms: MotionShifts, injection) -> np.ndarray:
        """The step from its shifts on: the checks of what the kernels can represent, then the backend."""
        if not self._shifts_checked:
            check_shift(ms.cond_shifts, "translation")
            check_shift(ms.uniform, "uniform")
        fi = vals = None
        if injection is not None:
            fi, vals = checked_injection(*injection, self._size)
        regions = self._regions
        new, decoded = self._backend.step(
            self._a, flat_index=fi, values=vals, exc=self._exc, inh=self._inh, phi=self._phi,
            shift_axes=ms.shift_axes, cond_shifts=ms.cond_shifts, uniform_shifts=ms.uniform,
            window=self._window, out=self._spare, **({} if regions is None else {"regions": regions}),
        )
        if new is None:
            if regions is not None:  # the spare grid may have been written
                self._backend.forget_regions(regions, 1, self.shape)
            raise ZeroActivityError(
                "all activity fell below the global inhibition threshold; state left unchanged "
                "(re-seed with reset_cell/reset_gaussian or inject energy)"
            )
        if regions is not None and new is self._spare:  # the grids swap, and so do their regions
            self._spare, self._a = self._a, new
            regions[1] = regions[0]
            regions[0] = regions[2]
        else:
            self._commit(new)
        self._last_decoded = decoded
        return decoded.copy()

    def warm_up(self, velocity=None, omega=None, dt: float = 1.0, *, run: bool = False, progress: bool = False) -> float:
        """Compile (or load from the disk cache) the kernels of :meth:`step` now, not in the loop.

        One :meth:`step` with this odometry and a one-cell injection runs on a scratch copy
        of the activity (and, with ``run``, a one-step :meth:`run`); the population is left
        as it was, bit for bit. Pass the odometry your loop uses (e.g. a non-zero velocity)
        so that the shift kernels it needs are compiled too. Logs one line (and with
        ``progress`` shows one on stderr) when this takes more than a second
        (:class:`cansim.warm_up.WarmUp`).

        Returns
        -------
        float
            Seconds taken (s).
        """
        from cansim.warm_up import WarmUp

        scratch = copy.copy(self)  # shares the backend (its kernel caches), not the activity
        scratch._a, scratch._spare = self._a.copy(), np.empty_like(self._spare)
        scratch._regions = scratch._new_regions()  # its own, the whole grid: nothing shared with self
        with WarmUp(f"population {'x'.join(map(str, self.shape))}", progress=progress) as w:
            w.stage("step")
            scratch.step(velocity, omega, dt, injection=(np.zeros(1, np.int64), np.ones(1)))
            if run:
                w.stage("run")
                scratch.run(None if velocity is None else [velocity], None if omega is None else [omega], [dt],
                            [(np.zeros(1, np.int64), np.ones(1))])
        return w.elapsed_s

    def run(
        self,
        velocity=None,
        omega=None,
        dt: float | np.ndarray = 1.0,
        injections: Optional[Sequence[Optional[tuple[np.ndarray, np.ndarray]]]] = None,
        *,
        n_steps: Optional[int] = None,
        record_activity: bool = False,
    ) -> Union[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """T iterations of :meth:`step` in one backend call (thesis Alg 3-5, Fig 5.11, Eq 5.11-5.12).

        The result equals T calls ``step(velocity[t], omega[t], dt[t], injection=injections[t])``
        bit for bit on every backend; the numba backend runs the whole loop in one compiled
        call, the opencl backend enqueues every step on the device and reads back once, and
        any other backend loops over its ``step`` (:meth:`cansim.backends.Backend.run`).
        The per-step inputs are checked and turned into shifts and injections by
        :func:`cansim.population_run.run_inputs`.

        Parameters
        ----------
        velocity : None or array_like, shape (T,) or (T, k)
            Per-step ``velocity`` of :meth:`step` (row t is step t's; converted to float64).
            UniformMotion: (T,) on a ring, (T, ndim) otherwise (units/s per axis);
            PlanarMotion: (T,) forward speed, m/s; SixDofMotion: (T, 3), m/s. None: no motion.
        omega : None or array_like, shape (T,) or (T, k)
            Per-step ``omega``: PlanarMotion (T,) rad/s, SixDofMotion (T, 3) rad/s.
        dt : float or array_like, shape (T,)
            Seconds per step (>= 0), one for all steps or one per step.
        injections : None or sequence of length T
            Entry t is None (no injection) or a ``(flat_index, values)`` pair injected before
            step t's dynamics, as ``step(injection=...)``; e.g. ``LocalViewCells.injection``.
        n_steps : int or None
            T; needed only when no other argument has a step axis (pure dynamics).
        record_activity : bool
            Also return the activity after every step (``True``/``False`` or a numpy bool;
            anything else, e.g. an array, raises InvalidInputError).

        Returns
        -------
        decoded : ndarray, shape (T, ndim)
            The decoded fractional cell index per axis after every step.
        activity : ndarray, shape (T,) + shape, only when ``record_activity``
            The activity after every step, in the population's dtype.

        Raises
        ------
        InvalidInputError, ShapeError
            A bad per-step input (non-finite, negative dt, wrong shape, lengths that differ,
            a bad injection), named with its step; checked for every step before the first
            one runs, so nothing changes. A ``record_activity`` that is not a bool.
        ZeroActivityError
            The dynamics collapsed at some step; the state is left as it was before the run
            (no step of it is kept).
        """
        if not isinstance(record_activity, (bool, np.bool_)):  # bool(np.array([])) raised numpy's ValueError
            raise InvalidInputError(f"record_activity must be True or False, got {type(record_activity).__name__} "
                                    f"{record_activity!r:.60}")
        inputs = run_inputs(self._motion, self._motion_shifts, self.ndim, self._size,
                            velocity, omega, dt, injections, n_steps)  # cansim.population_run
        res = self._backend.run(self._a, inputs, exc=self._exc, inh=self._inh, phi=self._phi,
                                window=self._window, record_activity=bool(record_activity))
        if res.collapsed_at is not None:
            raise ZeroActivityError(
                f"all activity fell below the global inhibition threshold at step {res.collapsed_at} of the run; "
                "state left as before the run (re-seed with reset_cell/reset_gaussian, inject energy, "
                "or lower the global inhibition)"
            )
        new = res.activity
        if new is self._a:
            new = new.copy()
        self._a = np.ascontiguousarray(new, dtype=self._dtype)
        self._last_decoded = res.decoded[-1].copy()
        self._forget_regions()
        if record_activity:
            return res.decoded, res.history
        return res.decoded

    # ----------------------------------------------------------- save / load
    def _description(self) -> dict:
        """The population's construction (axes, parameters, dtype, backend, motion model, decode window), as JSON."""
        from dataclasses import asdict

        return {"axes": [{"name": a.name, "size": a.size, "step": a.step, "angular": a.angular} for a in self._axes],
                "params": asdict(self._params), "dtype": self._dtype.name, "backend": self.backend,
                "motion": _motion_description(self._motion), "decode_window": self._window}

    def save(self, path: "str | os.PathLike[str] | BinaryIO") -> None:
        """Write the population - grid, kernels, dtype, backend, motion model, decode window and its
        activity - to an ``.npz`` file (no pickle); :meth:`load` gives one that continues exactly as this
        one would. A file name is written to a temporary name beside it and renamed (a crash never
        leaves half a file); an open binary file is written as is. As :func:`numpy.savez`, ``.npz``
        is added to a name without it (``save("run")`` writes ``run.npz``, which ``load("run")`` reads).

        Raises
        ------
        InvalidInputError
            A backend of your own that :func:`cansim.backends.register_backend` has not named
            (the file names the backend), or a motion model of your own (not :class:`UniformMotion`, :class:`PlanarMotion` or
            :class:`SixDofMotion`): it cannot be written without pickle - pickle the population
            (``pickle.dump``), which keeps any picklable motion model.
        """
        import json

        from whisker_io.persistence import write_npz

        from cansim.backends import registered_name

        if registered_name(self._backend) is None:
            raise InvalidInputError(f"the backend {type(self._backend).__name__} (name {self.backend!r}) is not the class "
                                    "the registry builds by its name, so a file cannot name it: register it under a name "
                                    "of its own with cansim.backends.register_backend first (or pickle the population)")
        arrays = {"population_format": np.int64(_SAVE_FORMAT), "population": np.array(json.dumps(self._description())),
                  "activity": self._a}
        if self._last_decoded is not None:
            arrays["decoded"] = self._last_decoded
        write_npz(path, arrays)

    @classmethod
    def load(cls, path: "str | os.PathLike[str] | BinaryIO") -> "Population":
        """Read a population written by :meth:`save`, in the state it was saved in.

        Raises
        ------
        CorruptFileError
            The file is unreadable, of another format version, or a field is missing or malformed
            (named in the error).
        """
        import json

        from cansim.errors import CansimError, CorruptFileError, UnknownBackendError
        from whisker_io.persistence import read_npz

        arrays = read_npz(path)
        fmt = arrays.get("population_format")
        if fmt is None or fmt.shape != () or fmt.dtype.kind not in "iu" or int(fmt) != _SAVE_FORMAT:
            hint = (" (a spiking population: SpikingPopulation.load)" if "spiking_format" in arrays
                    else " (a whole model: RatSLAM.load / WhiskerRatSLAM.load)" if "model" in arrays else "")
            raise CorruptFileError(f"expected population format {_SAVE_FORMAT}, got "
                                   f"{None if fmt is None else fmt.tolist()!r}{hint}", field="population_format")
        try:
            d = json.loads(str(arrays["population"]))
            population = cls([Axis(a["name"], a["size"], a["step"], a["angular"]) for a in d["axes"]],
                             AttractorParams(**d["params"]), dtype=np.dtype(d["dtype"]), backend=d["backend"],
                             motion=_motion_from_description(d["motion"]), decode_window=d["decode_window"])
        except UnknownBackendError as exc:
            raise UnknownBackendError(f"{exc}; a backend of your own is named by cansim.backends.register_backend: "
                                      "register it before loading a population saved with it") from None
        except (KeyError, TypeError, ValueError, AttributeError, CansimError) as exc:
            raise CorruptFileError(f"not a population description ({exc})", field="population") from exc
        if "activity" not in arrays:
            raise CorruptFileError("missing", field="activity")
        try:
            population.activity = arrays["activity"]
        except CansimError as exc:
            raise CorruptFileError(str(exc), field="activity") from exc
        if population._a.dtype != arrays["activity"].dtype:
            raise CorruptFileError(f"dtype {arrays['activity'].dtype}, expected {population._a.dtype}", field="activity")
        if "decoded" in arrays:
            decoded = np.asarray(arrays["decoded"])
            if decoded.shape != (population.ndim,) or not np.all(np.isfinite(decoded)):
                raise CorruptFileError(f"expected {population.ndim} finite numbers", field="decoded")
            population._last_decoded = decoded.copy()
        return population

    def __getstate__(self) -> dict:
        """What pickle and :func:`copy.deepcopy` keep: the construction and the state (not the bound kernels)."""
        from cansim.backends import registered_name

        name = registered_name(self._backend)  # a backend the registry does not build by its name: pickled itself
        return {"axes": self._axes, "params": self._params, "dtype": self._dtype.name,
                "backend": name if name is not None else self._backend,
                "motion": self._motion, "decode_window": self._window, "activity": self._a.copy(),
                "decoded": None if self._last_decoded is None else self._last_decoded.copy()}

    def __setstate__(self, state: dict) -> None:
        Population.__init__(self, state["axes"], state["params"], dtype=np.dtype(state["dtype"]),
                            backend=state["backend"], motion=state["motion"], decode_window=state["decode_window"])
        self.activity = state["activity"]
        self._last_decoded = state["decoded"]

    def __repr__(self) -> str:
        ax = ", ".join(f"{a.name}={a.size}" for a in self._axes)
        return f"Population({ax}, dtype={self._dtype.name}, backend={self.backend!r})"


def _checking(f: object, shape: tuple[int, ...], name: str):
    """A motion model's step function whose every result is checked (:func:`check_motion_shifts`)."""
    if not callable(f):
        raise InvalidInputError(f"{name}.bind(axes) must return a function f(velocity, omega, dt) -> MotionShifts, "
                                f"got {type(f).__name__}")

    def checked(velocity, omega, dt):
        return check_motion_shifts(f(velocity, omega, dt), shape, name)

    return checked


#: Version of :meth:`Population.save`'s file format.
_SAVE_FORMAT = 1


def _motion_description(motion: MotionModel) -> dict:
    """A built-in motion model as JSON; another is refused (module of :meth:`Population.save`)."""
    if type(motion) is UniformMotion:
        return {"kind": "uniform"}
    if type(motion) is PlanarMotion:
        return {"kind": "planar", "frame": motion.frame}
    if type(motion) is SixDofMotion:
        return {"kind": "sixdof"}
    raise InvalidInputError(f"a population with the motion model {type(motion).__name__} cannot be saved to a file "
                            "without pickle (only UniformMotion, PlanarMotion and SixDofMotion); pickle the "
                            "population instead (pickle.dump keeps any picklable motion model)")


def _motion_from_description(d: dict) -> MotionModel:
    kind = d["kind"]
    if kind == "uniform":
        return UniformMotion()
    if kind == "planar":
        return PlanarMotion(d["frame"])
    if kind == "sixdof":
        return SixDofMotion()
    raise ValueError(f"unknown motion model {kind!r}")
