"""Optional hardware modules (the ``hw`` extra): import one or say what to install."""

from __future__ import annotations

import importlib
from types import ModuleType

from whisker_io.errors import MissingDependencyError, missing_extra

__all__ = ["require"]


def require(module: str, what: str) -> ModuleType:
    """Import an optional hardware module or raise :class:`MissingDependencyError`.

    Parameters
    ----------
    module : str
        Module name, e.g. ``"rtde_receive"``.
    what : str
        What needs it, for the message (e.g. ``"URArm"``).
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise missing_extra(what, module, "hw", MissingDependencyError) from exc
