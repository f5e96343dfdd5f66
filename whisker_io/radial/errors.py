"""Typed errors of :mod:`whisker_io.radial`, on the one error tree of :mod:`whisker_io.errors`.

A saved model file that cannot be read raises :class:`whisker_io.errors.CorruptFileError`
(:class:`ModelVersionError` when it was written by another format or library version).
"""

from __future__ import annotations

from whisker_io.errors import CansimError, CorruptFileError, InvalidInputError

__all__ = [
    "CorruptFileError",
    "EmptyDatasetError",
    "ExtrapolationWarning",
    "FeatureMismatchError",
    "ModelVersionError",
    "NotFittedModelError",
]


class EmptyDatasetError(InvalidInputError):
    """A data set has no rows (or no rows left after filtering); generate or load
    a data set with at least one contact before training or evaluating."""


class FeatureMismatchError(InvalidInputError):
    """The features a model was trained on differ from those supplied or expected.
    The message lists both; retrain the model or pass the matching features."""


class ModelVersionError(CorruptFileError):
    """A saved model was written by a different format or library version than the
    one installed; retrain it with the installed versions (the message names them)."""


class NotFittedModelError(CansimError, RuntimeError):
    """A model was used before ``fit``; call ``fit`` (or load a fitted model) first."""


class ExtrapolationWarning(UserWarning):
    """A trained model was given contacts outside the data it was trained on (:meth:`TrainedModel.predict`:
    once per model); its estimates there are extrapolations. A study that extrapolates on purpose filters
    this category and says so once."""
