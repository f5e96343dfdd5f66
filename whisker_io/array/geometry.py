"""Geometry of a whisker array: where each whisker module sits and how it whisks.

The default array is the 18-module array of Fig 2.15 of the thesis (Pearson et
al. 2013 CAD model): columns A-F around the array axis, rows 1-3 from rostral to
caudal, whisker lengths 60, 100 and 160 mm by row. Any other morphology (a
replaced whisker of another length, fewer modules, another layout) is described
by building a :class:`WhiskerArray` from :class:`WhiskerModule` objects.

Units: metres and radians everywhere. The thesis table is in millimetres and is
converted once, here.

Frames (Fig 2.15 decision; the thesis gives positions, not orientations)
--------------------------------------------------------------------------
* ``E`` is the end-effector / array-adapter frame (point O of Fig 2.15); the
  array axis is ``+y`` (rostral).
* Each module ``i`` has a base frame ``W_i`` at its whisk pivot with

  - ``z``: tangent to the module's ring around the array axis, the whisk
    rotation axis, ``z = r_hat x y_E``;
  - ``y``: along the shaft at whisk angle ``theta = 0``, pointing radially
    outward from the array axis (``r_hat``);
  - ``x = y x z = -y_E``.

  Rotating by ``Rz(theta)`` (Eq 5.1) turns the shaft toward ``-x = +y_E``, so
  ``theta = +50 deg`` is full protraction (toward the array's front) and
  ``theta = -50 deg`` full retraction (Sec 5.1.1.1.2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from whisker_io.errors import ConfigError, InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_scalar, finite_vector, validate_fields

__all__ = [
    "COLUMNS",
    "ROWS",
    "THESIS_POSITIONS_MM",
    "THESIS_LENGTHS_M",
    "WhiskerModule",
    "WhiskerArray",
    "radial_base_rotation",
    "thesis_array",
]

COLUMNS: tuple[str, ...] = ("A", "B", "C", "D", "E", "F")
"""Column labels around the array axis (Fig 2.15, Fig 3.2)."""

ROWS: tuple[int, ...] = (1, 2, 3)
"""Row numbers from rostral (1) to caudal (3)."""

THESIS_POSITIONS_MM: Mapping[str, tuple[float, float, float]] = {
    "A1": (48.752, 201.860, -23.455),
    "A2": (58.967, 181.903, -30.607),
    "A3": (69.181, 161.946, -37.760),
    "B1": (49.305, 201.860, 22.270),
    "B2": (61.350, 181.903, 25.497),
    "B3": (73.394, 161.946, 28.725),
    "C1": (14.633, 201.860, 52.084),
    "C2": (19.903, 181.903, 63.386),
    "C3": (25.173, 161.946, 74.687),
    "D1": (-30.493, 201.860, 44.689),
    "D2": (-35.763, 181.903, 55.990),
    "D3": (-41.033, 161.946, 67.291),
    "E1": (-53.834, 201.860, 5.366),
    "E2": (-65.879, 181.903, 8.594),
    "E3": (-77.924, 161.946, 11.821),
    "F1": (-38.715, 201.860, -37.790),
    "F2": (-48.929, 181.903, -44.942),
    "F3": (-59.144, 161.946, -52.095),
}
"""Whisk pivot positions relative to the adapter O, in **mm** (Fig 2.15)."""

THESIS_LENGTHS_M: Mapping[int, float] = {1: 0.060, 2: 0.100, 3: 0.160}
"""Whisker length by row in metres (Sec 6.1.3.1.2: 60, 100, 160 mm, rostral to caudal)."""

_ARRAY_AXIS = np.array([0.0, 1.0, 0.0])


def radial_base_rotation(base_position_m: ArrayLike) -> NDArray[np.float64]:
    """Base-frame orientation of a module at ``base_position_m`` (Fig 2.15).

    Parameters
    ----------
    base_position_m : array_like, shape (3,)
        Pivot position in the end-effector frame E, metres. Must not lie on
        the array axis (+y).

    Returns
    -------
    ndarray, shape (3, 3)
        Rotation ``R_EW`` whose columns are the base frame's x, y, z axes in E:
        ``y`` radially outward, ``z = y x y_E`` (whisk axis), ``x = -y_E``.
    """
    p = np.asarray(base_position_m, dtype=float)
    radial = np.array([p[0], 0.0, p[2]])
    norm = np.linalg.norm(radial)
    if not np.isfinite(norm) or norm < 1e-9:
        raise ConfigError(
            f"base position {p.tolist()} lies on the array axis (+y); the radial "
            "direction is undefined. Give an explicit base_rotation for this module."
        )
    y = radial / norm
    z = np.cross(y, _ARRAY_AXIS)
    x = np.cross(y, z)
    return np.column_stack([x, y, z])


@dataclass(frozen=True, eq=False)
class WhiskerModule(ConfigDataclass):
    """One whisker module: a straight whisker whisking about its base frame's z-axis.

    Parameters
    ----------
    name : str
        Unique label, e.g. ``"C2"``.
    column : str
        Column label (``"A"``-``"F"`` for the thesis array); used for the tactile image.
    row : int
        Row number, 1 = rostral (thesis array: 1-3).
    base_position_m : array_like, shape (3,)
        Whisk pivot in the end-effector frame E, metres.
    length_m : float
        Whisker length in metres (> 0).
    base_rotation : array_like (3, 3) or scipy Rotation, optional
        Orientation ``R_EW`` of the base frame in E (columns = x, y, z axes) at
        whisk angle 0. Default: :func:`radial_base_rotation` of the position.
    """

    name: str
    column: str
    row: int = checked(kind=int, label="module {config.name!r}: row", hint="rows are numbered 1, 2, ... from rostral")
    base_position_m: NDArray[np.float64]
    length_m: float = checked(kind=float, above=0, label="module {config.name!r}: length_m", hint="give metres",
                              store=True)
    base_rotation: NDArray[np.float64] | Rotation | None = None

    def __post_init__(self) -> None:
        given_position, given_rotation = self.base_position_m, self.base_rotation  # as given, for the messages
        validate_fields(self)  # row, length_m; the vector and the rotation below
        try:
            pos = finite_vector(self.base_position_m, 3, "base_position_m")
        except InvalidInputError:
            raise ConfigError(
                f"module {self.name!r}: base_position_m must be 3 finite numbers (metres), "
                f"got {given_position!r}"
            ) from None
        length = self.length_m
        rot = self.base_rotation
        if rot is None:
            mat = radial_base_rotation(pos)
        elif isinstance(rot, Rotation):
            mat = rot.as_matrix()
        else:
            try:
                mat = finite_array(rot, (3, 3), "base_rotation")
            except InvalidInputError:
                raise ConfigError(
                    f"module {self.name!r}: base_rotation must be a 3x3 matrix of finite numbers or a "
                    f"scipy Rotation, got {given_rotation!r}"
                ) from None
            if (
                not np.allclose(mat.T @ mat, np.eye(3), atol=1e-6)
                or np.linalg.det(mat) < 0.0
            ):
                raise ConfigError(
                    f"module {self.name!r}: base_rotation is not a proper rotation "
                    "(orthonormal, det +1); orthonormalise it or pass a scipy Rotation"
                )
        pos.setflags(write=False)
        mat = np.array(mat, dtype=float)
        mat.setflags(write=False)
        object.__setattr__(self, "base_position_m", pos)
        object.__setattr__(self, "length_m", length)
        object.__setattr__(self, "base_rotation", mat)
        object.__setattr__(self, "name", str(self.name))
        object.__setattr__(self, "column", str(self.column))
        object.__setattr__(self, "row", int(self.row))

    @property
    def T_EW(self) -> NDArray[np.float64]:
        """Homogeneous transform ``T_EWi`` (4, 4) of the base frame in E (Eq 5.1 context)."""
        T = np.eye(4)
        T[:3, :3] = self.base_rotation
        T[:3, 3] = self.base_position_m
        return T


@dataclass(frozen=True, eq=False)
class WhiskerArray:
    """An array of whisker modules and its whisk range.

    Parameters
    ----------
    modules : tuple of WhiskerModule
        At least one module; names must be unique.
    retraction_rad : float
        Whisk angle of full retraction, radians (thesis: -50 deg).
    protraction_rad : float
        Whisk angle of full protraction, radians (thesis: +50 deg).

    Raises
    ------
    ConfigError
        Empty array, duplicate module names, or a whisk range that is not
        ``-pi < retraction < protraction < pi``.

    Examples
    --------
    >>> arr = WhiskerArray.thesis()
    >>> arr.names[:3]
    ('A1', 'A2', 'A3')
    >>> longer = arr.with_lengths({"C3": 0.150})
    """

    modules: tuple[WhiskerModule, ...]
    retraction_rad: float = float(np.deg2rad(-50.0))
    protraction_rad: float = float(np.deg2rad(50.0))
    _index: dict[str, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        modules = tuple(self.modules)
        if not modules:
            raise ConfigError("a WhiskerArray needs at least one module")
        for m in modules:
            if not isinstance(m, WhiskerModule):
                raise ConfigError(
                    f"modules must be WhiskerModule instances, got {type(m).__name__}"
                )
        seen: dict[str, int] = {}
        for i, m in enumerate(modules):
            if m.name in seen:
                raise ConfigError(
                    f"duplicate module name {m.name!r} (entries {seen[m.name]} and {i}); "
                    "every module needs a unique name"
                )
            seen[m.name] = i
        lo, hi = float(self.retraction_rad), float(self.protraction_rad)
        if not (np.isfinite(lo) and np.isfinite(hi) and -np.pi < lo < hi < np.pi):
            raise ConfigError(
                f"whisk range must satisfy -pi < retraction_rad < protraction_rad < pi, "
                f"got ({lo}, {hi})"
            )
        object.__setattr__(self, "modules", modules)
        object.__setattr__(self, "retraction_rad", lo)
        object.__setattr__(self, "protraction_rad", hi)
        object.__setattr__(self, "_index", seen)

    # ------------------------------------------------------------------ build
    @classmethod
    def thesis(cls) -> "WhiskerArray":
        """The 18-module array of Fig 2.15 (lengths 60/100/160 mm by row)."""
        return thesis_array()

    def with_lengths(self, lengths_m: Mapping[str, float]) -> "WhiskerArray":
        """A copy with some whisker lengths replaced (e.g. after a whisker broke).

        Parameters
        ----------
        lengths_m : mapping name -> length in metres
        """
        unknown = set(lengths_m) - set(self._index)
        if unknown:
            raise ConfigError(
                f"unknown module name(s) {sorted(unknown)}; known: {list(self.names)}"
            )
        mods = tuple(
            WhiskerModule(
                m.name,
                m.column,
                m.row,
                m.base_position_m,
                lengths_m.get(m.name, m.length_m),
                m.base_rotation,
            )
            for m in self.modules
        )
        return WhiskerArray(mods, self.retraction_rad, self.protraction_rad)

    # ------------------------------------------------------------------ views
    def __len__(self) -> int:
        return len(self.modules)

    def index(self, name: str) -> int:
        """Position of module ``name`` in :attr:`modules`."""
        try:
            return self._index[name]
        except KeyError:
            raise ConfigError(
                f"unknown module name {name!r}; known: {list(self.names)}"
            ) from None

    @property
    def names(self) -> tuple[str, ...]:
        """Module names in array order."""
        return tuple(m.name for m in self.modules)

    @property
    def positions_m(self) -> NDArray[np.float64]:
        """Base pivot positions in E, shape (N, 3), metres."""
        return np.array([m.base_position_m for m in self.modules])

    @property
    def lengths_m(self) -> NDArray[np.float64]:
        """Whisker lengths, shape (N,), metres."""
        return np.array([m.length_m for m in self.modules])

    @property
    def rotations(self) -> NDArray[np.float64]:
        """Base orientations ``R_EWi``, shape (N, 3, 3)."""
        return np.array([m.base_rotation for m in self.modules])

    @property
    def T_EW(self) -> NDArray[np.float64]:
        """Base transforms ``T_EWi``, shape (N, 4, 4)."""
        T = np.zeros((len(self.modules), 4, 4))
        T[:, :3, :3] = self.rotations
        T[:, :3, 3] = self.positions_m
        T[:, 3, 3] = 1.0
        return T

    def whisk_angles(self, step_rad: float = float(np.deg2rad(1.0))) -> NDArray[np.float64]:
        """Angles from retraction to protraction (both included) in steps of ``step_rad``.

        The last step is shortened if the range is not a multiple of the step.
        """
        try:
            step = finite_scalar(step_rad, "step_rad")
        except InvalidInputError as exc:
            raise ConfigError(str(exc)) from None
        if step <= 0.0:
            raise ConfigError(f"step_rad must be positive, got {step_rad!r}")
        span = self.protraction_rad - self.retraction_rad
        if not span / step <= 1e7:
            raise ConfigError(f"step_rad {step_rad!r} gives more than 1e7 angles; use a larger step")
        n = int(np.ceil(span / step - 1e-9))
        angles = self.retraction_rad + step * np.arange(n + 1)
        angles[-1] = self.protraction_rad
        return angles


def thesis_array() -> WhiskerArray:
    """Build the 18-module array of Fig 2.15 in metres (see module docstring for frames)."""
    mods = []
    for name, pos_mm in THESIS_POSITIONS_MM.items():
        row = int(name[1])
        mods.append(
            WhiskerModule(
                name=name,
                column=name[0],
                row=row,
                base_position_m=np.asarray(pos_mm) * 1e-3,
                length_m=THESIS_LENGTHS_M[row],
            )
        )
    return WhiskerArray(tuple(mods))
