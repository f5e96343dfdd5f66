"""Typed errors raised by :mod:`whisker_io`.

Every error a user can provoke on purpose derives from :class:`WhiskerIOError`,
so robot code can catch one base class. Errors about bad values also derive
from :class:`ValueError`, hardware faults from :class:`RuntimeError`, so code
written against the standard exceptions keeps working. Each message says what
went wrong and what to do about it; the object that raised it is left unchanged.

``whisker_io`` does not depend on :mod:`cansim` (issue 6: numpy/scipy/trimesh
only), hence its own base class.
"""

from __future__ import annotations

__all__ = [
    "WhiskerIOError",
    "InvalidArrayError",
    "InvalidInputError",
    "RecordingFormatError",
    "HardwareError",
    "ConnectionFailedError",
    "StaleStateError",
    "SafetyViolationError",
    "USBFrameError",
    "DeviceRemovedError",
    "DeviceTimeoutError",
]


class WhiskerIOError(Exception):
    """Base class of every error raised on purpose by :mod:`whisker_io`."""


class InvalidArrayError(WhiskerIOError, ValueError):
    """An array definition is inconsistent (duplicate module names, bad length,
    non-orthonormal base rotation, ...). The message names the module."""


class InvalidInputError(WhiskerIOError, ValueError):
    """A value is outside its domain: NaN/inf samples, wrong shape, negative
    length, unknown name. The message names the argument and the expected form."""


class RecordingFormatError(WhiskerIOError, ValueError):
    """A recording (whisk CSV or pose log) is malformed. The message names the
    file and the 1-based line number where the problem is."""


class HardwareError(WhiskerIOError, RuntimeError):
    """Base class of faults reported by a hardware driver (arm or array)."""


class ConnectionFailedError(HardwareError):
    """The driver could not connect to (or lost) the device; check cabling/IP."""


class StaleStateError(HardwareError):
    """The last state received from the device is older than allowed."""


class SafetyViolationError(HardwareError, ValueError):
    """A command was refused because it leaves the safety envelope (workspace
    box, speed limit, deflection overload). Nothing was sent to the device."""


class USBFrameError(HardwareError):
    """A USB packet from the array did not match the expected frame layout."""


class DeviceRemovedError(HardwareError):
    """The USB device disappeared while in use."""


class DeviceTimeoutError(HardwareError):
    """The device did not answer within the configured timeout."""
