"""Module attributes renamed in 0.2 (the Params / Config / Spec naming rule, CONTRIBUTING.md), kept until 0.3.

A module whose public class was renamed sets ``__getattr__ = renamed_attributes(__name__,
{"OldName": "NewName"}, globals())``: the old name still gives the new object, with a
:class:`DeprecationWarning` naming the new one.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["renamed_attributes", "REMOVED_IN"]

#: The release in which the old names stop working.
REMOVED_IN = "0.3"


def renamed_attributes(module: str, renames: Mapping[str, str], namespace: Mapping[str, Any]) -> Callable[[str], Any]:
    """A module ``__getattr__`` serving each old name of ``renames`` (old -> new) from ``namespace``, with a warning."""

    def __getattr__(name: str) -> Any:
        if name in renames:
            new = renames[name]
            warnings.warn(f"{module}.{name} is now {new} (the Params / Config / Spec naming rule, CONTRIBUTING.md); "
                          f"the old name goes in {REMOVED_IN}", DeprecationWarning, stacklevel=2)
            return namespace[new]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__
