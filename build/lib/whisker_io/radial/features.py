"""Contact-feature names, units and the validated table the radial models consume.

The seven contact features of Sec 4.1.2.4 of the thesis, in the column order
used everywhere in :mod:`whisker_io.radial`:

====  ============================  ===========
name  meaning                       unit
====  ============================  ===========
CP    contact period (onset->peak)  s
CA    contact amplitude             ADC counts
DV    deflection velocity           counts/s
DA    deflection acceleration       counts/s^2
AV    angular velocity              rad/s
AA    angular acceleration          rad/s^2
WL    whisker length                m
====  ============================  ===========
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

# one definition of the columns: the contact-feature extractor's (Sec 4.1.2.4)
from whisker_io.contact.features import FEATURE_NAMES, FEATURE_UNITS
from whisker_io.errors import InvalidInputError
from whisker_io.radial.errors import EmptyDatasetError, FeatureMismatchError

__all__ = ["FEATURE_NAMES", "FEATURE_UNITS", "RadialDataset", "feature_indices"]


def feature_indices(features: Sequence[str]) -> tuple[int, ...]:
    """Column indices of ``features`` in :data:`FEATURE_NAMES`.

    Raises
    ------
    FeatureMismatchError
        If a name is unknown or repeated.
    """
    names = tuple(features)
    unknown = [f for f in names if f not in FEATURE_NAMES]
    if unknown or len(set(names)) != len(names) or not names:
        raise FeatureMismatchError(
            f"features {names!r} must be a non-empty list of distinct names from {FEATURE_NAMES}"
            + (f"; unknown: {unknown}" if unknown else "")
        )
    return tuple(FEATURE_NAMES.index(f) for f in names)


def _as_finite(name: str, value: object, shape: tuple[int | None, ...]) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise InvalidInputError(f"{name} must have shape {shape} (None = any), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise InvalidInputError(
            f"{name} holds NaN/inf (first at index {tuple(int(i) for i in bad)}); "
            "drop or repair those contacts before building the data set"
        )
    return arr


@dataclass(frozen=True)
class RadialDataset:
    """Contacts with their features and ground-truth radial distance.

    Parameters
    ----------
    features : ndarray, shape (n, 7)
        Contact features in :data:`FEATURE_NAMES` order and :data:`FEATURE_UNITS`.
    radial_distance_m : ndarray, shape (n,)
        Ground-truth radial distance from the whisker base to the contact, m.
    name : str
        Label used in tables and figures.
    meta : mapping of str to ndarray, optional
        Per-contact metadata arrays whose first axis has length n (for example
        ``"frequency_hz"``, ``"speed_m_s"``, ``"module"``, ``"pose"`` (n, 4, 4),
        ``"angle_rad"``).

    Raises
    ------
    InvalidInputError
        On NaN/inf features or distances, wrong shapes, non-positive whisker length,
        or metadata of the wrong length. The error names the offending array.
    """

    features: np.ndarray
    radial_distance_m: np.ndarray
    name: str = "dataset"
    meta: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        x = _as_finite("features", self.features, (None, len(FEATURE_NAMES)))
        y = _as_finite("radial_distance_m", self.radial_distance_m, (x.shape[0],))
        if np.any(x[:, FEATURE_NAMES.index("WL")] <= 0):
            raise InvalidInputError("feature WL (whisker length, m) must be > 0 for every contact")
        meta = {}
        for key, val in dict(self.meta).items():
            arr = np.asarray(val)
            if arr.ndim == 0 or arr.shape[0] != x.shape[0]:
                raise InvalidInputError(
                    f"meta[{key!r}] must have first dimension {x.shape[0]}, got shape {arr.shape}"
                )
            arr = arr.copy()
            arr.setflags(write=False)
            meta[key] = arr
        x = x.copy()
        y = y.copy()
        x.setflags(write=False)
        y.setflags(write=False)
        object.__setattr__(self, "features", x)
        object.__setattr__(self, "radial_distance_m", y)
        object.__setattr__(self, "meta", MappingProxyType(meta))

    def __len__(self) -> int:
        return int(self.features.shape[0])

    @property
    def whisker_length_m(self) -> np.ndarray:
        """Whisker length of each contact (the WL column), m, shape (n,)."""
        return self.features[:, FEATURE_NAMES.index("WL")]

    def columns(self, features: Sequence[str]) -> np.ndarray:
        """Feature columns ``features`` in the given order, shape (n, len(features))."""
        return self.features[:, list(feature_indices(features))]

    def subset(self, mask: np.ndarray, name: str | None = None) -> "RadialDataset":
        """Rows selected by a boolean mask or an index array (a new data set)."""
        idx = np.asarray(mask)
        if idx.dtype == bool and idx.shape != (len(self),):
            raise InvalidInputError(f"boolean mask must have shape ({len(self)},), got {idx.shape}")
        return RadialDataset(
            self.features[idx],
            self.radial_distance_m[idx],
            name=self.name if name is None else name,
            meta={k: v[idx] for k, v in self.meta.items()},
        )

    def require_nonempty(self, what: str = "this operation") -> None:
        """Raise :class:`EmptyDatasetError` if the data set has no rows."""
        if len(self) == 0:
            raise EmptyDatasetError(
                f"data set {self.name!r} is empty; {what} needs at least one contact"
            )

    def fingerprint(self) -> str:
        """SHA-256 of the feature names, features and targets (hex), identifying a training set."""
        h = hashlib.sha256()
        h.update(",".join(FEATURE_NAMES).encode())
        h.update(np.ascontiguousarray(self.features, dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(self.radial_distance_m, dtype="<f8").tobytes())
        return h.hexdigest()

    @staticmethod
    def concatenate(parts: Sequence["RadialDataset"], name: str) -> "RadialDataset":
        """Stack data sets row-wise; metadata keys present in every part are kept."""
        if not parts:
            raise EmptyDatasetError("concatenate needs at least one data set")
        keys = set(parts[0].meta)
        for p in parts[1:]:
            keys &= set(p.meta)
        return RadialDataset(
            np.concatenate([p.features for p in parts]),
            np.concatenate([p.radial_distance_m for p in parts]),
            name=name,
            meta={k: np.concatenate([p.meta[k] for p in parts]) for k in sorted(keys)},
        )
