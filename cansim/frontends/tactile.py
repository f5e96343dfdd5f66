"""Tactile view templates of Ch.3: the whisker array's 6 x 3 tactile image is the template.

The tactile image (Fig 3.2) has 3 rows x 6 columns (whisker columns A-F),
8-bit values. It is used as is (no down-sampling, no shifts), and two images
are compared with Eq 3.1 of the thesis::

    S(A, B) = sum_ij sqrt(|a_ij - b_ij|)

on the raw 0-255 values. The smallest ``S`` over the stored templates is a
match when ``S <= match_threshold`` (ties -> the lowest id); otherwise the
image becomes a new template. The thesis tuned the threshold per setup and
does not print it; the default here (20) accepts e.g. four pixels differing
by 25 levels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from whisker_io.errors import InvalidInputError, ShapeError
from cansim.frontends.store import TemplateMatch, TemplateStore
from whisker_io.validation import ConfigDataclass, checked, validate_fields

__all__ = ["TACTILE_SHAPE", "TactileTemplateConfig", "TactileTemplates", "tactile_similarity"]

TACTILE_SHAPE = (3, 6)
"""Shape of a tactile image: 3 rows x 6 whisker columns (A-F)."""


def tactile_similarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Eq 3.1: ``S(A, B) = sum_ij sqrt(|a_ij - b_ij|)`` over the last two axes.

    Parameters
    ----------
    a, b : array (..., 3, 6)
        Tactile images (0-255 values); broadcast against each other.

    Returns
    -------
    ndarray
        ``S`` per broadcast image pair (0 = identical).
    """
    diff = np.abs(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))
    return np.sqrt(diff).sum(axis=(-2, -1))


@dataclass(frozen=True)
class TactileTemplateConfig(ConfigDataclass):
    """Parameters of :class:`TactileTemplates`.

    Parameters
    ----------
    match_threshold : float
        Largest Eq 3.1 dissimilarity ``S(A, B) = sum_ij sqrt(|a_ij - b_ij|)`` counted as
        a match, in sqrt(grey level) (8-bit levels); >= 0, default 20 (OpenRatSLAM's
        ``vt_match_threshold`` plays this part for camera images).
    """

    match_threshold: float = checked(20.0, float, minimum=0, hint="an Eq 3.1 dissimilarity in sqrt(level)")

    def __post_init__(self) -> None:
        validate_fields(self)  # the declared fields; numpy scalars -> Python numbers (saved as JSON with the model)


class TactileTemplates:
    """Tactile local-view matching of Ch.3 (Eq 3.1, no shifts).

    Parameters
    ----------
    config : TactileTemplateConfig, optional
    """

    def __init__(self, config: TactileTemplateConfig | None = None) -> None:
        self.config = config if config is not None else TactileTemplateConfig()
        self.store = TemplateStore(TACTILE_SHAPE)

    def __len__(self) -> int:
        return len(self.store)

    def match(self, image: np.ndarray) -> TemplateMatch:
        """Match a tactile image against the stored templates (new template if none matches).

        Parameters
        ----------
        image : array (3, 6) of integers in [0, 255]
            Tactile image, rows x whisker columns A-F.

        Returns
        -------
        TemplateMatch
            ``error`` is the smallest ``S`` (``inf`` with no stored template).
        """
        img = np.asarray(image)
        if img.shape != TACTILE_SHAPE:
            raise ShapeError(f"tactile image must have shape {TACTILE_SHAPE} (3 rows x 6 whisker columns), got {img.shape}")
        if not np.issubdtype(img.dtype, np.integer) or img.min() < 0 or img.max() > 255:
            raise InvalidInputError(f"tactile image must hold 8-bit integers 0-255, got dtype {img.dtype}")
        n = len(self.store)
        err, best = math.inf, 0
        if n:
            from cansim.frontends._tactile_numba import SQRT_LEVELS, best_tactile_match

            flat = self.store._data.reshape(self.store._data.shape[0], -1)
            best, err = best_tactile_match(flat, n, img.astype(np.float64).ravel(), SQRT_LEVELS)
            best, err = int(best), float(err)
        if err <= self.config.match_threshold:
            self.store.set_current(best)
            return TemplateMatch(best, False, err)
        new_id = self.store.add(img.astype(np.float64))
        self.store.set_current(new_id)
        return TemplateMatch(new_id, True, err)

    def to_arrays(self, prefix: str = "vt_") -> dict[str, Any]:
        """State as named arrays for an ``.npz`` file."""
        return self.store.to_arrays(prefix)

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str = "vt_") -> None:
        """Restore the state written by :meth:`to_arrays`."""
        store = TemplateStore(TACTILE_SHAPE)
        store.from_arrays(arrays, prefix)
        self.store = store
