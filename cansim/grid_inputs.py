"""What a cell grid accepts: whole cell numbers, injected energies and shifts it can represent.

The checks shared by the pose-cell engines (:class:`cansim.population.Population`, its
batch run :mod:`cansim.population_run`, :class:`cansim.models.posecell_network.PosecellNetwork`):
each raises :class:`~cansim.errors.InvalidInputError` or :class:`~cansim.errors.ShapeError`
with a message naming the input, before anything changes.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from cansim.errors import InvalidInputError, ShapeError

__all__ = ["MAX_SHIFT_CELLS", "MAX_INJECTION", "check_shift", "shift_too_large", "whole_cells", "checked_injection"]

#: Largest shift (cells, per axis and step) the kernels represent exactly (integer parts are
#: 32-bit on OpenCL); a larger one comes from corrupt odometry and is refused.
MAX_SHIFT_CELLS = 2.0**30
#: Largest energy one injection may add to a cell; the activity is normalised to sum 1,
#: so anything near this is corrupt input (and could overflow float32).
MAX_INJECTION = 1.0e6


def check_shift(shifts: Optional[np.ndarray], what: str) -> None:
    """Refuse a shift the kernels cannot represent (see :data:`MAX_SHIFT_CELLS`).

    Parameters
    ----------
    shifts : ndarray or None
        Shifts in cells (any shape); None: nothing to check.
    what : str
        The kind of shift, for the message (``"uniform"``, ``"translation"``...).

    Raises
    ------
    InvalidInputError
        The largest absolute shift is not below :data:`MAX_SHIFT_CELLS` (or is NaN).
    """
    if shifts is None:
        return
    biggest = float(np.abs(shifts).max(initial=0.0))
    if not biggest < MAX_SHIFT_CELLS:
        raise shift_too_large(biggest, what)


def shift_too_large(biggest: float, what: str) -> InvalidInputError:
    """The error :func:`check_shift` raises for a largest absolute shift of ``biggest`` cells
    (for a motion model that checks its shifts on scalars, before any array is made)."""
    return InvalidInputError(
        f"the {what} shift is {biggest!r} cells in one step, too large to represent; "
        "check velocity * dt against the cell size (or split the step)"
    )


def whole_cells(value: object, what: str) -> np.ndarray:
    """``value`` as an int64 array of whole cell numbers (an integral float counts), within +-2**62.

    Raises
    ------
    InvalidInputError
        Not numbers (text, ragged lists, bools), NaN/inf, a fraction such as 2.7 (never
        truncated) or a number out of any grid's range; the message names ``what``.
    """
    try:
        arr = np.asarray(value)
        ok = arr.dtype.kind in "iu" or (arr.dtype.kind == "f" and np.isfinite(arr).all() and (arr == np.round(arr)).all())
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InvalidInputError(f"{what} must be whole cell numbers, got {value!r}")
    if arr.size and np.abs(arr.astype(np.float64)).max() > 2**62:
        raise InvalidInputError(f"{what} {value!r} is out of any grid's range")
    return arr.astype(np.int64)


def checked_injection(flat_index: np.ndarray, values: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Validate an injection pair: 1-D int64 flat indices in ``[0, size)`` and float64 energies >= 0.

    Returns the pair as contiguous int64 / float64 arrays (no copy when they already are).

    Raises
    ------
    ShapeError
        The two arrays differ in length.
    InvalidInputError
        An index lies outside the grid or an energy is negative, NaN or infinite.
    """
    fi = flat_index if isinstance(flat_index, np.ndarray) and flat_index.dtype == np.int64 else whole_cells(flat_index, "flat_index")
    if not (isinstance(values, np.ndarray) and values.dtype == np.float64):
        try:
            values = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise InvalidInputError(f"injected values must be numbers, got {values!r}") from None
    vals = values
    fi, vals = fi.ravel(), vals.ravel()
    if fi.shape != vals.shape:
        raise ShapeError(f"flat_index and values must have the same length, got {fi.shape} and {vals.shape}")
    n = len(fi)
    if n <= 8:  # the usual single-cell view injection: plain Python checks are faster
        fl, vl = fi.tolist(), vals.tolist()
        if n and (min(fl) < 0 or max(fl) >= size):
            raise InvalidInputError(f"flat indices must lie in [0, {size})")
        if not all(0.0 <= x <= MAX_INJECTION for x in vl):  # also False for NaN
            raise InvalidInputError(f"injected values must be finite and in [0, {MAX_INJECTION:g}]")
        return fi, vals
    if fi.min() < 0 or fi.max() >= size:
        raise InvalidInputError(f"flat indices must lie in [0, {size})")
    if not np.isfinite(vals).all() or vals.min() < 0 or vals.max() > MAX_INJECTION:
        raise InvalidInputError(f"injected values must be finite and in [0, {MAX_INJECTION:g}]")
    return fi, vals
