"""The central data types of a whisk session: one module's whisk and one pose-log line.

A :class:`WhiskRecord` is what a whisker module delivers over one whisk cycle
(angle and x/y deflection samples at 2 kHz, Sec 3.1.3); a :class:`PoseEntry` is the
end-effector pose when a cycle was completed. The simulator
(:mod:`whisker_io.sim.simulator`), the hardware recorder (:mod:`whisker_io.hw.recorder`)
and the contact pipeline (:mod:`whisker_io.contact`) all exchange these; the file
format that stores them is in :mod:`whisker_io.records.recording`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.pose import Pose, as_pose
from whisker_io.validation import finite_scalar, finite_vector

__all__ = ["SAMPLE_RATE_HZ", "MODULE_NAME_RE", "WhiskRecord", "PoseEntry"]

#: Sampling rate of every whisker module, Hz (Sec 2.2: "maximum sensory sampling rate of 2kHz").
SAMPLE_RATE_HZ: float = 2000.0
#: A module name: letters and digits (it becomes part of a file name), e.g. ``"C2"``.
MODULE_NAME_RE = re.compile(r"^[A-Za-z0-9]+$")
_STEM_RE = re.compile(r"^[A-Za-z0-9_.-]+$")


def _samples(name: str, value: object) -> np.ndarray:
    arr = finite_vector(value, None, name)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class WhiskRecord:
    """One module's samples over one whisk cycle: the in-memory unit of a whisk file.

    Parameters
    ----------
    module : str
        Module name, e.g. ``"C2"`` (letters and digits only, it becomes part of a file name).
    angle_rad : array_like, shape (T,)
        Whisk angle theta per sample, radians (Fig 2.15).
    x_counts, y_counts : array_like, shape (T,)
        Deflection along the sensor x- and y-axes, ADC counts. The y-axis is the
        whisking direction (Sec 5.1.1.1.1).
    sample_rate_hz : float, default 2000
        Sampling rate, Hz.
    cycle : int, default 0
        Whisk cycle index within the session (>= 0).
    spare : array_like, shape (T,), optional
        The spare column (zeros when ``None``).

    Records hold arrays, so ``==`` compares identity; compare the arrays.

    Raises
    ------
    InvalidInputError
        Non-finite samples (naming the first bad sample), arrays of unequal
        length or other than 1-D, an empty record, a bad module name, cycle < 0 or
        a non-positive sampling rate. The arrays are copied and made read-only.
    """

    module: str
    angle_rad: np.ndarray
    x_counts: np.ndarray
    y_counts: np.ndarray
    sample_rate_hz: float = SAMPLE_RATE_HZ
    cycle: int = 0
    spare: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.module, str) or not MODULE_NAME_RE.match(self.module):
            raise InvalidInputError(
                f"module name {self.module!r} must be a non-empty string of letters and digits, e.g. 'C2'"
            )
        arrays = {
            "angle_rad": self.angle_rad,
            "x_counts": self.x_counts,
            "y_counts": self.y_counts,
        }
        if self.spare is not None:
            arrays["spare"] = self.spare
        checked = {k: _samples(f"{self.module}.{k}", v) for k, v in arrays.items()}
        lengths = {k: v.size for k, v in checked.items()}
        if len(set(lengths.values())) != 1:
            raise InvalidInputError(f"whisk record {self.module}: columns have different lengths {lengths}")
        if lengths["angle_rad"] == 0:
            raise InvalidInputError(f"whisk record {self.module}: no samples")
        if not (isinstance(self.cycle, (int, np.integer)) and self.cycle >= 0):
            raise InvalidInputError(f"cycle must be an integer >= 0, got {self.cycle!r}")
        rate = finite_scalar(self.sample_rate_hz, "sample_rate_hz")
        if not rate > 0:
            raise InvalidInputError(f"sample_rate_hz must be a positive number, got {self.sample_rate_hz!r}")
        for k, v in checked.items():
            object.__setattr__(self, k, v)
        object.__setattr__(self, "cycle", int(self.cycle))
        object.__setattr__(self, "sample_rate_hz", rate)

    @classmethod
    def from_float_arrays(
        cls,
        module: str,
        angle_rad: np.ndarray,
        x_counts: np.ndarray,
        y_counts: np.ndarray,
        sample_rate_hz: float = SAMPLE_RATE_HZ,
        cycle: int = 0,
    ) -> WhiskRecord:
        """A record from 1-D float64 sample arrays, taken as read-only views (no copy).

        The fast constructor of the simulator: the same checks as the constructor
        (finite samples, equal non-zero lengths, module name, cycle, rate) without
        copying the columns. The caller must not modify the arrays afterwards.
        Anything that is not a 1-D float64 array goes through the constructor.

        Raises
        ------
        InvalidInputError
            As the constructor.
        """
        cols = (angle_rad, x_counts, y_counts)
        if not all(isinstance(c, np.ndarray) and c.dtype == np.float64 and c.ndim == 1 for c in cols):
            return cls(module, angle_rad, x_counts, y_counts, sample_rate_hz, cycle)
        if not isinstance(module, str) or not MODULE_NAME_RE.match(module):
            raise InvalidInputError(
                f"module name {module!r} must be a non-empty string of letters and digits, e.g. 'C2'")
        if not (angle_rad.size == x_counts.size == y_counts.size) or angle_rad.size == 0:
            raise InvalidInputError(f"whisk record {module}: columns must be non-empty and of equal length")
        if not (isinstance(cycle, (int, np.integer)) and cycle >= 0):
            raise InvalidInputError(f"cycle must be an integer >= 0, got {cycle!r}")
        rate = finite_scalar(sample_rate_hz, "sample_rate_hz")
        if not rate > 0:
            raise InvalidInputError(f"sample_rate_hz must be a positive number, got {sample_rate_hz!r}")
        for name, col in zip(("angle_rad", "x_counts", "y_counts"), cols):
            if not np.isfinite(col).all():
                _samples(f"{module}.{name}", col)  # raises, naming the first bad sample
        rec = object.__new__(cls)
        for name, col in zip(("angle_rad", "x_counts", "y_counts"), cols):
            view = col.view()
            view.setflags(write=False)
            object.__setattr__(rec, name, view)
        object.__setattr__(rec, "module", module)
        object.__setattr__(rec, "sample_rate_hz", rate)
        object.__setattr__(rec, "cycle", int(cycle))
        object.__setattr__(rec, "spare", None)
        return rec

    @classmethod
    def from_float_rows(
        cls,
        modules: Sequence[str],
        angle_rad: np.ndarray,
        x_counts: np.ndarray,
        y_counts: np.ndarray,
        sample_rate_hz: float = SAMPLE_RATE_HZ,
        cycle: int = 0,
    ) -> list[WhiskRecord]:
        """One record per row of (n, T) float64 arrays (the n modules of one cycle), as read-only views.

        :meth:`from_float_arrays` for a whole array cycle, with the checks made once on the
        (n, T) arrays instead of once per column. The caller must not modify float64 arrays
        afterwards (they are viewed, not copied); other input is copied to float64 first.

        Parameters
        ----------
        modules : sequence of str, length n
            Module names, one per row.
        angle_rad, x_counts, y_counts : ndarray, shape (n, T)
            Radians, counts, counts.
        sample_rate_hz : float, default 2000
        cycle : int, default 0

        Returns
        -------
        list of WhiskRecord, length n

        Raises
        ------
        InvalidInputError
            As :meth:`from_float_arrays` (naming the first bad sample), arrays that are not
            (n, T) of one shape, or a number of module names other than n.
        """
        if isinstance(modules, str) or not isinstance(modules, Sequence):
            raise InvalidInputError(f"modules must be a sequence of module names, got {modules!r}")
        names = list(modules)
        cols = (angle_rad, x_counts, y_counts)
        if not all(isinstance(c, np.ndarray) and c.dtype == np.float64 for c in cols):
            try:  # copies: the caller's lists or other dtypes are not viewed
                cols = tuple(np.array(c, dtype=np.float64) for c in cols)
            except (TypeError, ValueError):
                raise InvalidInputError("angle_rad, x_counts and y_counts must be (n, T) arrays of numbers") from None
        shape = cols[0].shape
        if not all(c.ndim == 2 and c.shape == shape for c in cols) or shape[0] != len(names):
            raise InvalidInputError(f"angle_rad, x_counts and y_counts must be (n, T) arrays of one shape with one "
                                    f"row per module name ({len(names)}), got {[c.shape for c in cols]}")
        if shape[1] == 0:
            raise InvalidInputError("whisk records need samples: columns must be non-empty and of equal length")
        for col_name, c in zip(("angle_rad", "x_counts", "y_counts"), cols):
            if not np.isfinite(c).all():
                row = int(np.flatnonzero(~np.isfinite(c).all(axis=1))[0])
                _samples(f"{names[row]}.{col_name}", c[row])  # raises, naming the first bad sample
        for m in names:
            if not isinstance(m, str) or not MODULE_NAME_RE.match(m):
                raise InvalidInputError(
                    f"module name {m!r} must be a non-empty string of letters and digits, e.g. 'C2'")
        if not (isinstance(cycle, (int, np.integer)) and cycle >= 0):
            raise InvalidInputError(f"cycle must be an integer >= 0, got {cycle!r}")
        rate = finite_scalar(sample_rate_hz, "sample_rate_hz")
        if not rate > 0:
            raise InvalidInputError(f"sample_rate_hz must be a positive number, got {sample_rate_hz!r}")
        views = []
        for c in cols:
            v = c.view()
            v.setflags(write=False)
            views.append(v)
        out: list[WhiskRecord] = []
        for i, m in enumerate(names):
            rec = object.__new__(cls)
            object.__setattr__(rec, "module", m)
            object.__setattr__(rec, "angle_rad", views[0][i])
            object.__setattr__(rec, "x_counts", views[1][i])
            object.__setattr__(rec, "y_counts", views[2][i])
            object.__setattr__(rec, "sample_rate_hz", rate)
            object.__setattr__(rec, "cycle", int(cycle))
            object.__setattr__(rec, "spare", None)
            out.append(rec)
        return out

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return int(self.angle_rad.size)

    @property
    def time_s(self) -> np.ndarray:
        """Sample times from the start of the cycle, shape (T,), seconds."""
        return np.arange(self.n_samples) / self.sample_rate_hz

    def as_columns(self) -> np.ndarray:
        """The four file columns (angle, x, y, spare) as an array of shape (T, 4)."""
        spare = np.zeros(self.n_samples) if self.spare is None else self.spare
        return np.column_stack([self.angle_rad, self.x_counts, self.y_counts, spare])


@dataclass(frozen=True, eq=False)
class PoseEntry:
    """One pose-log line: the end-effector pose when a whisk cycle was completed.

    Parameters
    ----------
    time_s : float
        Time stamp, seconds (finite).
    pose : PoseLike
        End-effector pose ``T_BE`` in the arm base frame; converted by
        :func:`whisker_io.pose.as_pose` (so a quaternion obeys the one
        quaternion rule of :mod:`whisker_io.pose`).
    whisk_file : str
        Stem of the cycle's whisk files (``{whisk_file}_{module}.csv``).

    Attributes
    ----------
    time_s : float
    pose : Pose
    whisk_file : str

    Raises
    ------
    InvalidInputError
        A non-finite time, a bad pose or a whisk-file stem that is not a plain
        file stem.
    """

    time_s: float
    pose: Pose
    whisk_file: str

    def __post_init__(self) -> None:
        t = finite_scalar(self.time_s, "pose time_s")
        pose = as_pose(self.pose)
        if not isinstance(self.whisk_file, str) or not _STEM_RE.match(self.whisk_file):
            raise InvalidInputError(
                f"whisk_file {self.whisk_file!r} must be a file stem of letters, digits, '_', '.', '-'"
            )
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "pose", pose)
