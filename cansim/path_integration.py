"""Path integration by weighted shifts of activity (Fig 5.7-5.11, thesis Sec 5.1.2.3.3).

RatSLAM moves the activity packet rather than integrating velocity. A shift by a
real number ``s`` of cells along one axis is an integer roll by ``floor(s)`` plus
the linear split ``(1 - frac, frac)`` of Fig 5.11; a shift over several axes is the
product of the 1-D splits (bilinear in 2-D = the four areas of Fig 5.7-5.10,
trilinear in 3-D).

A *motion model* turns odometry into shifts for a given axis layout:

* :class:`UniformMotion` - every axis shifts by ``velocity * dt / step`` (rings, any N-D grid);
* :class:`PlanarMotion` - RatSLAM's (x', y', theta'): each theta layer translates its
  (x', y') plane along its own heading, then theta shifts by ``vrot * dt / step``;
* :class:`SixDofMotion` - WhiskerRatSLAM's (x, y, z, roll, pitch, yaw): each orientation
  voxel translates its (x, y, z) block by ``R(roll, pitch, yaw) @ v * dt / step``.

Euler convention (stated once, used everywhere in cansim): ``R(roll, pitch, yaw) =
scipy.spatial.transform.Rotation.from_euler("xyz", [roll, pitch, yaw])`` - extrinsic
rotations about the fixed x, y, z axes, in that order. The rotational part of 6-DoF
odometry, a rotation vector ``omega`` (Eq 5.7), is read as Euler-rate increments
``(d roll, d pitch, d yaw) = omega * dt`` as the thesis does; this is an approximation
that is exact for rotations about a single axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, NamedTuple, Optional, Sequence

import numpy as np

from cansim.axes import Axis
from cansim.errors import InvalidInputError, ShapeError
from cansim.grid_inputs import MAX_SHIFT_CELLS, check_shift, shift_too_large
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, finite_vector, validate_fields

__all__ = [
    "split_weights",
    "MotionShifts",
    "check_motion_shifts",
    "MotionModel",
    "UniformMotion",
    "PlanarMotion",
    "SixDofMotion",
    "euler_grid_rotations",
    "EULER_CONVENTION",
]

#: scipy ``Rotation.from_euler`` sequence used for the pose-cell orientation axes
EULER_CONVENTION = "xyz"


def split_weights(shift_cells: float) -> tuple[int, float, float]:
    """Integer offset and the two weights of a fractional 1-D shift (Fig 5.11).

    Parameters
    ----------
    shift_cells : float
        Shift in cells (any sign or magnitude).

    Returns
    -------
    (lo, w_lo, w_hi) : (int, float, float)
        Activity moves ``lo`` cells with weight ``w_lo = 1 - frac`` and ``lo + 1``
        cells with weight ``w_hi = frac``, ``frac = s - floor(s)``.

    Examples
    --------
    158 deg at 72 deg per cell (Fig 5.11) moves 2 cells with 0.8 and 3 cells with 0.2:

    >>> lo, w_lo, w_hi = split_weights(158 / 72)
    >>> lo, round(w_lo, 6), round(w_hi, 6)
    (2, 0.805556, 0.194444)
    """
    finite_scalar(shift_cells, "shift")
    lo = math.floor(shift_cells)
    frac = shift_cells - lo
    return int(lo), 1.0 - frac, frac


def check_dt(dt: float) -> float:
    """Validate a time step in seconds: finite and >= 0."""
    dtf = finite_scalar(dt, "dt")
    if dtf < 0:
        raise InvalidInputError(f"dt must be >= 0 seconds, got {dtf}")
    return dtf


def _range_checked(shift_function: Callable[..., MotionShifts]) -> Callable[..., MotionShifts]:
    """Mark a bound shift function that refuses shifts beyond :data:`cansim.grid_inputs.MAX_SHIFT_CELLS`
    itself (see :func:`shifts_range_checked`)."""
    shift_function.range_checked = True  # type: ignore[attr-defined]
    return shift_function


def shifts_range_checked(shift_function: Callable[..., object]) -> bool:
    """Whether ``shift_function`` (from :meth:`MotionModel.bind_checked_and_trusted`) refuses every
    shift :func:`cansim.grid_inputs.check_shift` would refuse, with its error, so the caller
    need not check its shifts again (a user's model: False, its shifts are checked)."""
    return getattr(shift_function, "range_checked", False) is True


class MotionShifts(NamedTuple):
    """Shifts for one path-integration step, in cells.

    Attributes
    ----------
    shift_axes : tuple of int or None
        Axes translated per slice (conditional shift), or None.
    cond_shifts : ndarray or None
        Shape ``cond_shape + (len(shift_axes),)`` (see ``Backend.shift_conditional``).
    uniform : ndarray or None
        Shape ``(ndim,)``: a shift applied to the whole grid after the conditional one.
    """

    shift_axes: Optional[tuple[int, ...]]
    cond_shifts: Optional[np.ndarray]
    uniform: Optional[np.ndarray]


class MotionModel:
    """Turns odometry into :class:`MotionShifts` for a particular axis layout.

    Subclasses implement :meth:`bind`, which precomputes the tables of one grid and
    returns the per-step function; :meth:`shifts` is the one-off convenience form.
    """

    def check_axes(self, axes: Sequence[Axis]) -> None:
        """Raise :class:`ShapeError` if the model cannot drive a grid with these axes."""

    def bind(self, axes: Sequence[Axis]) -> Callable[..., MotionShifts]:
        """Return ``f(velocity, omega, dt) -> MotionShifts`` for a grid with ``axes``; ``f`` validates its inputs."""
        return self._bind_pair(axes)[0]

    def bind_checked_and_trusted(
        self, axes: Sequence[Axis]
    ) -> tuple[Callable[..., MotionShifts], Callable[..., MotionShifts]]:
        """:meth:`bind`'s function and a twin for inputs validated already, e.g. the fields of a
        :class:`maps.odometry.PlanarOdometry` / :class:`maps.odometry.SpatialOdometry`
        (finite floats or float64 (3,) arrays, ``dt >= 0``).

        The built-in models' twin computes the same shifts (the same bits) without checking
        the values again; an input not of that form (another type, shape or dtype) is
        checked as :meth:`bind`'s function checks it. A model that implements (or
        overrides) :meth:`bind` gets its checked function twice.
        """
        mro = type(self).__mro__
        binder = next(c for c in mro if "bind" in c.__dict__)
        pairer = next(c for c in mro if "_bind_pair" in c.__dict__)
        if binder is not MotionModel and mro.index(binder) <= mro.index(pairer):
            f = self.bind(axes)
            return f, f
        return self._bind_pair(axes)

    def _bind_pair(self, axes: Sequence[Axis]) -> tuple[Callable[..., MotionShifts], Callable[..., MotionShifts]]:
        raise NotImplementedError(f"{type(self).__name__} must implement bind(axes)")

    def shifts(self, axes: Sequence[Axis], velocity, omega, dt: float) -> MotionShifts:
        """Shifts in cells for linear ``velocity``, angular ``omega`` over ``dt`` seconds."""
        self.check_axes(axes)
        return self.bind(axes)(velocity, omega, dt)


_NO_MOTION = MotionShifts(None, None, None)


def check_motion_shifts(ms: object, shape: tuple[int, ...], model: str = "the motion model") -> MotionShifts:
    """What a motion model of one's own returned for one step, checked against the grid and as float64 arrays.

    The rule (:class:`MotionShifts`): ``shift_axes`` and ``cond_shifts`` are both None or both
    given - ``shift_axes`` distinct ascending axis indices, ``cond_shifts`` of shape
    ``cond_shape + (len(shift_axes),)`` with ``cond_shape`` the grid's shape without those
    axes; ``uniform`` None or of shape ``(ndim,)``. Backends do not check it (numpy and numba
    differed on a wrong one: an error against a silent shift), so :class:`cansim.Population`
    checks every step of a motion model that is not built in.

    Raises
    ------
    ShapeError
        Anything else, with the rule.
    """
    ndim = len(shape)
    rule = (f"{model}'s step function must return MotionShifts(shift_axes, cond_shifts, uniform): shift_axes and "
            f"cond_shifts both None or both given (distinct ascending axes of the {ndim}-D grid; shifts of shape "
            f"<the grid's shape without those axes> + (len(shift_axes),)), uniform None or of shape ({ndim},)")
    if not (isinstance(ms, tuple) and len(ms) == 3):
        raise ShapeError(f"{rule}; got {type(ms).__name__}")
    axes, cond, uniform = ms
    if (axes is None) != (cond is None):
        raise ShapeError(f"{rule}; got shift_axes {axes!r} with cond_shifts {'None' if cond is None else 'given'}")
    if axes is not None:
        if (isinstance(axes, (str, bytes)) or not isinstance(axes, Sequence) or not axes
                or not all(isinstance(k, (int, np.integer)) and not isinstance(k, (bool, np.bool_)) for k in axes)
                or list(axes) != sorted(set(axes)) or not all(0 <= k < ndim for k in axes)):
            raise ShapeError(f"{rule}; got shift_axes {axes!r}")
        want = tuple(n for k, n in enumerate(shape) if k not in axes) + (len(axes),)
        cond = np.asarray(cond, dtype=np.float64)
        if cond.shape != want:
            raise ShapeError(f"{rule}; got cond_shifts of shape {cond.shape} for shift_axes {axes} (expected {want})")
        axes = tuple(int(k) for k in axes)
    if uniform is not None:
        uniform = np.asarray(uniform, dtype=np.float64)
        if uniform.shape != (ndim,):
            raise ShapeError(f"{rule}; got uniform of shape {uniform.shape}")
    return MotionShifts(axes, cond, uniform)


def _is_vector(x, n: int) -> bool:
    """Whether ``x`` has the validated form of a vector field: a float64 array of shape (n,)."""
    return isinstance(x, np.ndarray) and x.dtype == np.float64 and x.shape == (n,)


@dataclass(frozen=True)
class UniformMotion(MotionModel):
    """Every axis shifts by ``velocity_k * dt / step_k`` cells.

    ``velocity`` is one value per axis in the axis' physical units per second (m/s
    or rad/s). There is no rotation input: ``omega`` must be None (an argument that
    does not apply is an error, never ignored). A head-direction ring is driven by its
    angular velocity as ``velocity``.
    """

    def _bind_pair(self, axes):
        n = len(axes)
        inv = 1.0 / np.array([a.step for a in axes])
        inv0 = float(inv[0])

        def no_omega(omega):
            if omega is not None:  # a model mismatch, not a bad value: refused on both paths
                raise InvalidInputError(
                    "this population's axes move uniformly and take no omega; pass the angular "
                    "velocity of a ring as velocity (rad/s)"
                )

        def compute(velocity, dt):
            # check_shift's refusal without a numpy reduction: a ring's one shift is a float,
            # a grid's few shifts are compared in Python (NaN fails the comparison: refused)
            if velocity is None:
                return _NO_MOTION
            if n == 1 and isinstance(velocity, float):
                s = velocity * dt * inv0
                if not abs(s) < MAX_SHIFT_CELLS:
                    raise shift_too_large(abs(s), "uniform")
                return MotionShifts(None, None, np.array([s]))
            u = velocity * (dt * inv)
            if not all(abs(x) < MAX_SHIFT_CELLS for x in u.tolist()):
                check_shift(u, "uniform")  # raises, with the largest shift in the message
            return MotionShifts(None, None, u)

        def shifts(velocity, omega, dt):
            dt = check_dt(dt)
            no_omega(omega)
            if velocity is None or (n == 1 and isinstance(velocity, float)):
                if velocity is not None and not math.isfinite(velocity):
                    raise InvalidInputError(f"velocity must be finite, got {velocity!r}; check the odometry source")
                return compute(velocity, dt)
            return compute(finite_vector(velocity, n, "velocity"), dt)

        def trusted(velocity, omega, dt):
            no_omega(omega)
            if velocity is None or (n == 1 and isinstance(velocity, float)) or _is_vector(velocity, n):
                return compute(velocity, dt)
            return shifts(velocity, omega, dt)  # not of a validated form: check it

        return _range_checked(shifts), _range_checked(trusted)


@dataclass(frozen=True)
class PlanarMotion(MotionModel, ConfigDataclass):
    """RatSLAM's heading-conditional translation on a (x', y', theta') grid (3-DoF).

    Each theta layer ``k`` (heading ``th_k = k * step_theta``) shifts its plane by
    ``vtrans * dt * (cos th_k, sin th_k) / (step_x, step_y)`` cells; then the whole grid
    shifts along theta by ``vrot * dt / step_theta`` (translate first, as OpenRatSLAM).

    Parameters
    ----------
    frame : {"standard", "openratslam"}
        ``"standard"``: heading 0 moves along +x', 90 deg along +y'.
        ``"openratslam"``: the C++ frame, heading 0 moves along +y' and 90 deg along +x',
        i.e. ``(sin th, cos th)``; decoded (x, y) are mirrored against a standard frame.
    """

    frame: str = checked("standard", str, choices=("standard", "openratslam"), error=InvalidInputError,
                         message="{name} must be 'standard' or 'openratslam', got {value!r}")

    def __post_init__(self) -> None:
        validate_fields(self)

    def check_axes(self, axes):
        if len(axes) != 3 or axes[0].angular or axes[1].angular or not axes[2].angular:
            raise ShapeError("PlanarMotion needs axes (x linear, y linear, theta angular)")

    def _bind_pair(self, axes):
        th = np.arange(axes[2].size) * axes[2].step
        if self.frame == "standard":
            d = np.stack([np.cos(th), np.sin(th)], axis=1)
        else:
            d = np.stack([np.sin(th), np.cos(th)], axis=1)
        directions = d / np.array([axes[0].step, axes[1].step])
        inv_th = 1.0 / axes[2].step
        d_max = float(np.abs(directions).max())

        def compute(v, w, dt):
            # check_shift's refusal on scalars, before any array is made: rounding is monotone, so
            # the largest |(v * dt) * directions| is exactly abs(v * dt) * d_max (inf or nan: refused)
            cond = None
            if v != 0.0:
                s = v * dt
                biggest = abs(s) * d_max
                if not biggest < MAX_SHIFT_CELLS:
                    raise shift_too_large(biggest, "translation")
                cond = s * directions
            rot = w * dt * inv_th
            if not abs(rot) < MAX_SHIFT_CELLS:
                raise shift_too_large(abs(rot), "uniform")
            uniform = np.array([0.0, 0.0, rot]) if rot != 0.0 else None
            return MotionShifts((0, 1) if cond is not None else None, cond, uniform)

        def shifts(velocity, omega, dt):
            v = finite_scalar(0.0 if velocity is None else velocity, "vtrans")
            w = finite_scalar(0.0 if omega is None else omega, "vrot")
            return compute(v, w, check_dt(dt))

        def trusted(velocity, omega, dt):
            if isinstance(velocity, float) and isinstance(omega, float) and isinstance(dt, float):
                return compute(velocity, omega, dt)
            return shifts(velocity, omega, dt)  # not of a validated form: check it

        return _range_checked(shifts), _range_checked(trusted)


def euler_grid_rotations(angle_axes: Sequence[Axis], convention: str = EULER_CONVENTION) -> np.ndarray:
    """Rotation matrix of every (roll, pitch, yaw) cell of three angular axes.

    Returns
    -------
    ndarray, shape (n_roll, n_pitch, n_yaw, 3, 3)
        ``R[i, j, k] = Rotation.from_euler(convention, [i*step_r, j*step_p, k*step_y])``.
    """
    from scipy.spatial.transform import Rotation

    grids = np.meshgrid(*[np.arange(a.size) * a.step for a in angle_axes], indexing="ij")
    eul = np.stack([g.ravel() for g in grids], axis=1)
    mats = Rotation.from_euler(convention, eul).as_matrix()
    return mats.reshape(tuple(a.size for a in angle_axes) + (3, 3))


@dataclass(frozen=True)
class SixDofMotion(MotionModel):
    """WhiskerRatSLAM's 6-DoF path integration on (x, y, z, roll, pitch, yaw).

    Each orientation voxel shifts its (x, y, z) block by ``R(roll, pitch, yaw) @ v * dt``
    divided by the cell sizes (``R`` per :data:`EULER_CONVENTION`), then each angular
    axis shifts by ``omega_k * dt / step_k`` (``omega`` read as Euler-rate increments).
    ``velocity`` is in m/s in the end-effector frame, ``omega`` in rad/s.
    """

    def check_axes(self, axes):
        if len(axes) != 6 or any(a.angular for a in axes[:3]) or not all(a.angular for a in axes[3:]):
            raise ShapeError("SixDofMotion needs axes (x, y, z linear; roll, pitch, yaw angular)")

    def _bind_pair(self, axes):
        rot = euler_grid_rotations(axes[3:]) / np.array([a.step for a in axes[:3]])[:, None]
        rot = np.ascontiguousarray(rot.reshape(-1, 3))  # (n_r*n_p*n_y*3, 3): one gemv per step
        cond_shape = tuple(a.size for a in axes[3:]) + (3,)
        inv_ang = 1.0 / np.array([a.step for a in axes[3:]])

        def compute(v, w, dt):
            cond = uniform = None
            if v is not None and v.any():
                cond = (rot @ (v * dt)).reshape(cond_shape)
            if w is not None and w.any():
                uniform = np.zeros(6)
                uniform[3:] = w * (dt * inv_ang)
            return MotionShifts((0, 1, 2) if cond is not None else None, cond, uniform)

        def shifts(velocity, omega, dt):
            dt = check_dt(dt)
            v = None if velocity is None else finite_vector(velocity, 3, "velocity")
            w = None if omega is None else finite_vector(omega, 3, "omega")
            return compute(v, w, dt)

        def trusted(velocity, omega, dt):
            if _is_vector(velocity, 3) and _is_vector(omega, 3) and isinstance(dt, float):
                return compute(velocity, omega, dt)
            return shifts(velocity, omega, dt)  # not of a validated form: check it

        return shifts, trusted
