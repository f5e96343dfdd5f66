"""The one error tree of the whole distribution (``whisker_io``, ``maps``, ``cansim``).

Every error raised on purpose derives from :class:`CansimError`, so robot code can
catch one base class for everything. It is defined here, in the lowest package of the
data flow (sensor -> front end -> attractor -> map -> model), so that ``whisker_io``
and ``maps`` need nothing of the CAN engine; ``cansim.errors`` re-exports it as
``cansim.CansimError``.

One class per concept:

* :class:`InvalidInputError` (a ``ValueError``) - a value outside its domain (NaN/inf,
  negative dt, unknown name); :class:`ShapeError` for a wrong shape;
  :class:`ConfigError` for a malformed parameter or configuration entry (the
  message names the key), :class:`UnknownFieldError` for an argument that names no
  field of a configuration (also a ``TypeError``, as Python's own refusal of a keyword).
* :class:`CorruptFileError` (a ``ValueError``) - a saved or recorded file that cannot
  be read back: a saved model, map or whisk recording; ``path``, ``field`` and
  ``line`` say where.
* :class:`HardwareError` (a ``RuntimeError``) and its subclasses - faults reported by
  the arm and array drivers; :class:`SafetyViolationError` for a refused command.
* :class:`MissingExtraError` (an ``ImportError``) - an optional dependency is not
  installed; the message names the pip extra to install (``pip install "cansim[sweep]"``).
  :class:`MissingDependencyError` is the hardware extra's.

Each message says what went wrong and what to do about it; the object that raised
keeps the state it had before the call.
"""

from __future__ import annotations

import os
from typing import Any

__all__ = [
    "CansimError",
    "InvalidInputError",
    "ShapeError",
    "ConfigError",
    "UnknownFieldError",
    "CorruptFileError",
    "MissingExtraError",
    "HardwareError",
    "MissingDependencyError",
    "ConnectionFailedError",
    "RobotUnreachableError",
    "ArrayNotFoundError",
    "CommandFailedError",
    "StaleStateError",
    "SafetyViolationError",
    "USBFrameError",
    "ShortFrameError",
    "CRCMismatchError",
    "SequenceGapError",
    "DeviceRemovedError",
    "DeviceTimeoutError",
]


class CansimError(Exception):
    """Base class of every error raised on purpose by cansim, whisker_io and maps."""


class InvalidInputError(CansimError, ValueError):
    """A value is out of its domain (NaN/inf, negative dt, unknown id or name...).

    The message names the argument and the expected form.
    """


class ShapeError(InvalidInputError):
    """An array has the wrong shape or number of dimensions."""


class ConfigError(InvalidInputError):
    """A parameter or configuration entry is unknown or malformed; the message names the key."""


class UnknownFieldError(ConfigError, TypeError):
    """An argument names no field of a configuration, or there are more positional arguments than fields.

    A ``TypeError`` too, as Python's own refusal of an unexpected keyword, so code that
    catches that keeps working (:class:`whisker_io.validation.ConfigDataclass`).
    """


class CorruptFileError(CansimError, ValueError):
    """A saved or recorded file is unreadable, truncated, or has a malformed field.

    Parameters
    ----------
    problem : str
        What is wrong.
    path : str, os.PathLike or file object, optional
        The file (an open file is named by its ``name``, else by its type).
    field : str, optional
        The offending entry of the file (an ``.npz`` member, a JSON key, a column).
    line : int, optional
        1-based line number in a text file.

    Attributes
    ----------
    path : str or None
    field : str or None
    line : int or None
    """

    def __init__(
        self,
        problem: str,
        *,
        path: str | os.PathLike[str] | None = None,
        field: str | None = None,
        line: int | None = None,
    ) -> None:
        if path is None or isinstance(path, (str, os.PathLike)):
            self.path = None if path is None else os.fspath(path)
        else:  # an open file (e.g. a model loaded from io.BytesIO): its name if it has one
            name = getattr(path, "name", None)
            self.path = name if isinstance(name, str) else f"<{type(path).__name__}>"
        self.field = field
        self.line = line
        where = []
        if self.path is not None:
            where.append(self.path)
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field {field!r}")
        message = ": ".join(where + [problem])
        if field is not None:
            message += "; the file is corrupt or was not written by this library - re-save it or restore a backup"
        self.problem = problem
        super().__init__(message)

    def located(self, path: str | os.PathLike[str] | Any) -> "CorruptFileError":
        """This error naming ``path`` (itself when it already names a file): for a loader that read the
        arrays first and met the fault while rebuilding the object from them."""
        if self.path is not None:
            return self
        located = type(self)(self.problem, path=path, field=self.field, line=self.line)
        located.__cause__ = self.__cause__
        return located



class HardwareError(CansimError, RuntimeError):
    """Base class of faults reported by a hardware driver (arm or array)."""


class MissingExtraError(CansimError, ImportError):
    """An optional dependency is not installed: the message names the extra that brings it
    (e.g. ``pip install "cansim[sweep]"``) - see :func:`missing_extra`."""


def missing_extra(what: str, module: str, extra: str, error: type[MissingExtraError] | None = None) -> MissingExtraError:
    """The error for ``what`` needing ``module``, which the pip extra ``extra`` installs (raise it
    ``from None`` or from the ``ImportError``); ``error`` a kind of :class:`MissingExtraError` (default itself,
    e.g. :class:`MissingDependencyError` for the hardware extra)."""
    return (error or MissingExtraError)(f"{what} needs the Python module {module!r}, which is not installed: "
                                        f'pip install "cansim[{extra}]"')


class MissingDependencyError(HardwareError, MissingExtraError):
    """An optional hardware dependency (ur-rtde, pyusb) is not installed.

    Install the ``hw`` extra: ``pip install "cansim[hw]"``.
    """


class ConnectionFailedError(HardwareError):
    """The driver could not connect to (or lost) the device; check cabling/IP."""


class RobotUnreachableError(ConnectionFailedError):
    """:func:`whisker_io.hw.platform.open_platform` could not reach the arm; check its IP and network."""


class ArrayNotFoundError(ConnectionFailedError):
    """:func:`whisker_io.hw.platform.open_platform` found no whisker array on USB; check the cable and ids."""


class CommandFailedError(HardwareError):
    """The controller refused or failed to execute a command that passed the
    safety envelope (ur-rtde returned False, or the robot is not in remote
    control). Check the teach pendant for a protective stop."""


class StaleStateError(HardwareError):
    """The last state received from the device is older than allowed."""


class SafetyViolationError(HardwareError, ValueError):
    """A command was refused because it leaves the safety envelope (workspace
    box, speed limit, deflection overload). Nothing was sent to the device."""


class USBFrameError(HardwareError):
    """A USB packet from the array did not match the expected frame layout."""


class ShortFrameError(USBFrameError):
    """A USB frame was shorter than its header or its declared sample count."""


class CRCMismatchError(USBFrameError):
    """A USB frame's CRC-32 does not match its bytes (corrupted transfer)."""


class SequenceGapError(USBFrameError):
    """Frames were lost: the sequence number jumped (``lost`` frames)."""

    def __init__(self, message: str, lost: int) -> None:
        super().__init__(message)
        self.lost = lost


class DeviceRemovedError(HardwareError):
    """The USB device disappeared while in use."""


class DeviceTimeoutError(HardwareError):
    """The device did not answer within the configured timeout."""
