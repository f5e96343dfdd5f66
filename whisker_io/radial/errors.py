"""Typed errors of :mod:`whisker_io.radial`.

All derive from :class:`whisker_io.errors.WhiskerIOError`; those about bad values
also from :class:`ValueError` (through :class:`whisker_io.errors.InvalidInputError`).
"""

from __future__ import annotations

from whisker_io.errors import InvalidInputError, WhiskerIOError

__all__ = [
    "EmptyDatasetError",
    "FeatureMismatchError",
    "ModelFileError",
    "ModelVersionError",
    "NotFittedModelError",
]


class EmptyDatasetError(InvalidInputError):
    """A data set has no rows (or no rows left after filtering); generate or load
    a data set with at least one contact before training or evaluating."""


class FeatureMismatchError(InvalidInputError):
    """The features a model was trained on differ from those supplied or expected.
    The message lists both; retrain the model or pass the matching features."""


class ModelFileError(WhiskerIOError, ValueError):
    """A saved model file is unreadable, not a radial-distance model file, or holds
    types outside the trusted list (nothing from it was executed)."""


class ModelVersionError(ModelFileError):
    """A saved model was written by a different format or library version than the
    one installed; retrain it with the installed versions (the message names them)."""


class NotFittedModelError(WhiskerIOError, RuntimeError):
    """A model was used before ``fit``; call ``fit`` (or load a fitted model) first."""
