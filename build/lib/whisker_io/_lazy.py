"""Lazy package exports: a name is imported from its submodule on first access.

A package ``__init__`` lists its public names and the module that defines each,
and gets ``__getattr__`` / ``__dir__`` (PEP 562) from :func:`lazy_exports`, so
``import package`` costs nothing and ``from package import Name`` still works::

    __getattr__, __dir__ = lazy_exports(__name__, globals(), {"Pose": "whisker_io.pose"})
    __all__ = sorted(_EXPORTS)

Written once here (the lowest package of the data flow) and used by
``whisker_io``, ``maps`` and ``cansim``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str,
    module_globals: MutableMapping[str, Any],
    exports: Mapping[str, str],
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """Build a package's ``__getattr__`` and ``__dir__`` for lazily loaded names.

    Parameters
    ----------
    package : str
        The package's ``__name__``, used in the ``AttributeError`` message.
    module_globals : MutableMapping
        The package's ``globals()``; a loaded name is cached there, so the
        submodule is imported once.
    exports : Mapping[str, str]
        Public name -> absolute name of the module that defines it
        (e.g. ``{"ArraySimulator": "whisker_io.sim.simulator"}``).

    Returns
    -------
    (__getattr__, __dir__)
        Assign both at module level in the package ``__init__``.
    """
    table = dict(exports)

    def __getattr__(name: str) -> Any:
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        module_globals[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(module_globals) | set(table))

    return __getattr__, __dir__
