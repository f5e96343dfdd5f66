"""A population's batch run: T iterations in one backend call (thesis Alg 3-5, Fig 5.11, Eq 5.11-5.12).

:meth:`cansim.population.Population.run` takes per-step odometry, time steps and
injections for T steps; :func:`run_inputs` checks them all and turns them into the
per-step shifts (cells) and injections of a :class:`cansim.backends.base.RunInputs`,
which the backend runs in one call (:meth:`cansim.backends.Backend.run`). The result
equals T calls of :meth:`~cansim.population.Population.step`, bit for bit: the built-in
:class:`~cansim.path_integration.UniformMotion` and
:class:`~cansim.path_integration.PlanarMotion` are evaluated for all steps at once with
the same floating-point operations as their per-step function; any other motion model
is called once per step.
"""

from __future__ import annotations

from typing import Callable, Optional

import numpy as np

from cansim.backends.base import RunInputs
from cansim.errors import InvalidInputError, ShapeError
from cansim.grid_inputs import MAX_SHIFT_CELLS, checked_injection
from cansim.path_integration import MotionModel, MotionShifts, PlanarMotion, UniformMotion

__all__ = ["run_inputs"]

#: A motion model bound to a grid's axes: ``f(velocity, omega, dt) -> MotionShifts`` (validating).
ShiftFunction = Callable[..., MotionShifts]


def run_inputs(motion: MotionModel, motion_shifts: ShiftFunction, ndim: int, size: int,
               velocity, omega, dt, injections, n_steps: Optional[int]) -> RunInputs:
    """Check a run's per-step inputs and turn them into a backend's :class:`~cansim.backends.base.RunInputs`.

    Parameters
    ----------
    motion : MotionModel
        The population's motion model (its type selects the vectorised path).
    motion_shifts : callable
        ``motion`` bound to the population's axes (``MotionModel.bind``): one step's
        ``(velocity, omega, dt) -> MotionShifts``.
    ndim, size : int
        The grid's number of axes and of cells.
    velocity, omega, dt, injections, n_steps
        As :meth:`cansim.population.Population.run`.

    Returns
    -------
    RunInputs
        T, the injections as offsets / flat indices / energies, the conditional and
        uniform shifts (cells) with their per-step masks.

    Raises
    ------
    InvalidInputError, ShapeError
        A bad per-step input, named with its step; every step is checked before any runs.
    """
    T = _run_length(velocity, omega, dt, injections, n_steps)
    dts = _run_dt(dt, T)
    shift_axes, cond, has_cond, uni, has_uni = _run_shifts(motion, motion_shifts, ndim, velocity, omega, dts, T)
    offsets, index, values = _run_injections(size, injections, T)
    return RunInputs(T, offsets, index, values, shift_axes, cond, has_cond, uni, has_uni)


def _per_step_array(x, name: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be an array of real numbers with one row per step") from None
    if arr.ndim not in (1, 2):
        raise ShapeError(f"{name} must have shape (T,) or (T, k), one row per step; got {arr.shape}")
    return arr

def _run_length(velocity, omega, dt, injections, n_steps) -> int:
    lengths = {}
    for name, x in (("velocity", velocity), ("omega", omega)):
        if x is not None:
            lengths[name] = len(_per_step_array(x, name))
    if np.ndim(dt) != 0:
        lengths["dt"] = len(np.atleast_1d(np.asarray(dt, dtype=object)))
    if injections is not None:
        try:
            lengths["injections"] = len(injections)
        except TypeError:
            raise InvalidInputError("injections must be a sequence with one entry (or None) per step") from None
    if n_steps is not None:
        if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)):
            raise InvalidInputError(f"n_steps must be an integer >= 1, got {n_steps!r}")
        lengths["n_steps"] = int(n_steps)
    if not lengths:
        raise InvalidInputError("run needs per-step inputs or n_steps to know how many steps to run")
    if len(set(lengths.values())) != 1:
        raise ShapeError(f"per-step inputs must all have T rows, got {lengths}")
    T = next(iter(lengths.values()))
    if T < 1:
        raise InvalidInputError(f"run needs at least one step, got T = {T} ({lengths})")
    return T

def _run_dt(dt, T: int) -> np.ndarray:
    try:
        arr = np.asarray(dt, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"dt must be a number or one number per step (seconds), got {dt!r}") from None
    if arr.ndim > 1:
        raise ShapeError(f"dt must be a scalar or have shape (T,), got {arr.shape}")
    arr = np.broadcast_to(arr, (T,))
    bad = np.flatnonzero(~(np.isfinite(arr) & (arr >= 0)))
    if len(bad):
        raise InvalidInputError(f"dt must be finite and >= 0 seconds; step {bad[0]} has {arr[bad[0]]!r}")
    return arr

def _run_shifts(motion: MotionModel, motion_shifts: ShiftFunction, ndim: int, velocity, omega, dts: np.ndarray, T: int):
    """Per-step shifts in cells: (shift_axes, cond (T, ...) or None, has_cond, uniform (T, ndim) or None, has_uniform).

    The built-in UniformMotion and PlanarMotion are evaluated for all steps at once with
    the same floating-point operations as their per-step function (whose tables it
    reads by calling it with unit inputs); any other model is called once per step.
    """
    v = None if velocity is None else _per_step_array(velocity, "velocity")
    w = None if omega is None else _per_step_array(omega, "omega")
    model = type(motion)
    if model is UniformMotion and w is None and (v is None or v.ndim == 2 or ndim == 1):
        return _run_uniform(motion_shifts, ndim, v, dts, T)
    if model is PlanarMotion and (v is None or v.ndim == 1) and (w is None or w.ndim == 1):
        return _run_planar(motion_shifts, v, w, dts, T)
    return _run_per_step(motion_shifts, ndim, v, w, dts, T)

def _run_finite(x: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        t = int(np.argwhere(bad)[0][0])
        raise InvalidInputError(f"{name} must be finite; step {t} has {x[t].tolist()!r} (check the odometry source)")

def _run_checked_shifts(shifts: Optional[np.ndarray], mask: np.ndarray, what: str) -> None:
    # a shift the kernels cannot represent (their integer parts are 32-bit on opencl)
    if shifts is None:
        return
    s = np.abs(shifts.reshape(len(shifts), -1)).max(axis=1)
    bad = np.flatnonzero(mask & ~(s < MAX_SHIFT_CELLS))
    if len(bad):
        raise InvalidInputError(
            f"the {what} shift of step {bad[0]} is {s[bad[0]]!r} cells, too large to represent; "
            "check velocity * dt against the cell size"
        )

def _run_uniform(motion_shifts: ShiftFunction, ndim: int, v, dts, T):
    uni = has = None
    if v is not None:
        _run_finite(v, "velocity")
        if v.ndim == 1:  # ring: step() gets a float and computes velocity * dt * (1 / step)
            inv0 = motion_shifts(1.0, None, 1.0).uniform[0]
            uni = ((v * dts) * inv0)[:, None]
        else:  # step() gets a vector and computes velocity * (dt * (1 / step))
            if v.shape[1] != ndim:
                raise ShapeError(f"velocity must have shape (T, {ndim}), one value per axis; got {v.shape}")
            inv = motion_shifts(np.ones(ndim), None, 1.0).uniform
            uni = v * (dts[:, None] * inv)
        has = np.ones(T, dtype=bool)
        _run_checked_shifts(uni, has, "uniform")
    return None, None, np.zeros(T, dtype=bool), uni, (has if has is not None else np.zeros(T, dtype=bool))

def _run_planar(motion_shifts: ShiftFunction, v, w, dts, T):
    cond = uni = None
    has_cond = np.zeros(T, dtype=bool)
    has_uni = np.zeros(T, dtype=bool)
    if v is not None:
        _run_finite(v, "velocity (vtrans)")
        directions = motion_shifts(1.0, None, 1.0).cond_shifts  # (1 * 1) * directions
        cond = (v * dts)[:, None, None] * directions
        has_cond = v != 0.0
        _run_checked_shifts(cond, has_cond, "translation")
    if w is not None:
        _run_finite(w, "omega (vrot)")
        inv_th = motion_shifts(None, 1.0, 1.0).uniform[2]
        rot = (w * dts) * inv_th
        uni = np.zeros((T, 3))
        uni[:, 2] = rot
        has_uni = rot != 0.0
        _run_checked_shifts(uni, has_uni, "rotation")
    return ((0, 1) if has_cond.any() else None), (cond if has_cond.any() else None), has_cond, \
        (uni if has_uni.any() else None), has_uni

def _run_per_step(motion_shifts: ShiftFunction, ndim: int, v, w, dts, T):
    steps: list[MotionShifts] = []
    for t in range(T):
        try:
            steps.append(motion_shifts(None if v is None else v[t], None if w is None else w[t], float(dts[t])))
        except (InvalidInputError, ShapeError) as exc:
            raise type(exc)(f"step {t}: {exc}") from None
    has_cond = np.array([ms.cond_shifts is not None for ms in steps])
    has_uni = np.array([ms.uniform is not None for ms in steps])
    axes = {ms.shift_axes for ms in steps if ms.cond_shifts is not None}
    if len(axes) > 1:
        raise InvalidInputError(f"the motion model translated different axes at different steps ({sorted(axes)}); "
                                "run() needs one layout: call step() per step instead")
    shift_axes = axes.pop() if axes else None
    cond = uni = None
    if has_cond.any():
        proto = next(ms.cond_shifts for ms in steps if ms.cond_shifts is not None)
        cond = np.zeros((T,) + proto.shape)
        for t, ms in enumerate(steps):
            if ms.cond_shifts is not None:
                cond[t] = ms.cond_shifts
        _run_checked_shifts(cond, has_cond, "conditional")
    if has_uni.any():
        uni = np.zeros((T, ndim))
        for t, ms in enumerate(steps):
            if ms.uniform is not None:
                uni[t] = ms.uniform
        _run_checked_shifts(uni, has_uni, "uniform")
    return shift_axes, cond, has_cond, uni, has_uni

def _run_injections(size: int, injections, T: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    offsets = np.zeros(T + 1, dtype=np.int64)
    if injections is None:
        return offsets, np.empty(0, dtype=np.int64), np.empty(0, dtype=np.float64)
    idx, vals = [], []
    for t, inj in enumerate(injections):
        n = 0
        if inj is not None:
            try:
                fi, vv = inj
            except (TypeError, ValueError):
                raise InvalidInputError(f"injections[{t}] must be None or a (flat_index, values) pair") from None
            try:
                fi, vv = checked_injection(fi, vv, size)
            except (InvalidInputError, ShapeError) as exc:
                raise type(exc)(f"injections[{t}]: {exc}") from None
            except (TypeError, ValueError):
                raise InvalidInputError(f"injections[{t}] must hold integer indices and real values") from None
            idx.append(fi)
            vals.append(vv)
            n = len(fi)
        offsets[t + 1] = offsets[t] + n
    if not idx:
        return offsets, np.empty(0, dtype=np.int64), np.empty(0, dtype=np.float64)
    return offsets, np.ascontiguousarray(np.concatenate(idx)), np.ascontiguousarray(np.concatenate(vals))
