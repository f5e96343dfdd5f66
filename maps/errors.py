"""Typed errors raised by the ``maps`` package.

Every error derives from :class:`MapsError`, itself a
:class:`cansim.errors.CansimError`, so robot code can catch one base class for
the whole distribution. Messages say which field or argument is wrong and what
to do about it; the object that raised keeps the state it had before the call.
"""

from __future__ import annotations

from cansim.errors import CansimError
from cansim.errors import InvalidInputError as _CansimInvalidInputError

__all__ = ["MapsError", "InvalidInputError", "MapFormatError"]


class MapsError(CansimError):
    """Base class of every error raised on purpose by ``maps``."""


class InvalidInputError(MapsError, _CansimInvalidInputError):
    """An argument is out of its domain (NaN odometry, unknown experience id, bad log...)."""


class MapFormatError(MapsError, ValueError):
    """A saved map file is missing a field, or a field has the wrong type, shape or value.

    ``field`` names the offending entry of the file.
    """

    def __init__(self, field: str, problem: str) -> None:
        self.field = field
        super().__init__(
            f"saved file field {field!r}: {problem}; the file is corrupt or was not written by "
            "this library's save() - re-save it or restore a backup"
        )
