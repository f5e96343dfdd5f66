"""Keyword arguments renamed before the first release (issue 21: one name per concept), accepted for one release.

The names in the configs are the names everywhere (``xy_cells``, ``heading_cells``,
``cell_size_m``, ``grid_cells``, ``angle_cells``, ``inject_energy``). A function or class
whose keywords were renamed is wrapped by :func:`renamed_keywords`: an old keyword still
works, with a :class:`DeprecationWarning` naming the new one, until 0.3. Positional
arguments are unaffected (their order did not change).
"""

from __future__ import annotations

import functools
import warnings
from typing import Any, Callable, Mapping, TypeVar

from cansim.errors import ConfigError

__all__ = ["renamed_keywords", "take_renamed", "REMOVED_IN"]

#: The release in which the old keyword names stop working.
REMOVED_IN = "0.3"

F = TypeVar("F", bound=Callable[..., Any])


def take_renamed(kwargs: Mapping[str, Any], renames: Mapping[str, str], owner: str, *, stacklevel: int = 3) -> dict[str, Any]:
    """``kwargs`` with every old name of ``renames`` (old -> new) replaced by its new name.

    Parameters
    ----------
    kwargs : mapping
        Keyword arguments as the caller gave them.
    renames : mapping of str to str
        Old keyword name -> new keyword name.
    owner : str
        What the keywords belong to, for the messages (e.g. ``"Population.openratslam"``).
    stacklevel : int
        Passed to :func:`warnings.warn` (3: the caller of the function calling this).

    Returns
    -------
    dict
        A new dict; ``kwargs`` is not modified.

    Raises
    ------
    ConfigError
        An old name and its new name are both given.

    Warns
    -----
    DeprecationWarning
        Once per old name used.
    """
    out = dict(kwargs)
    for old, new in renames.items():
        if old not in out:
            continue
        if new in out:
            raise ConfigError(f"{owner}: {old} is the old name of {new}; give {new} only")
        warnings.warn(
            f"{owner}: the keyword {old} is now {new} (renamed before the first release, the old name goes in {REMOVED_IN})",
            DeprecationWarning, stacklevel=stacklevel,
        )
        out[new] = out.pop(old)
    return out


def renamed_keywords(**renames: str) -> Callable[[F], F]:
    """Decorator: let a function (or a class, through its ``__init__``) take old keyword names.

    ``@renamed_keywords(dim_xy="xy_cells")`` makes ``f(dim_xy=3)`` call ``f(xy_cells=3)``
    with a :class:`DeprecationWarning` (see :func:`take_renamed`). Put it under
    ``@classmethod`` / ``@staticmethod``. The wrapped callable keeps its name, docstring
    and signature (``functools.wraps``); the renames are listed in its
    ``__renamed_keywords__`` attribute.
    """

    def decorate(target: F) -> F:
        if isinstance(target, type):
            target.__init__ = decorate(target.__init__)  # type: ignore[misc]
            target.__renamed_keywords__ = dict(renames)  # type: ignore[attr-defined]
            return target
        owner = target.__qualname__.removesuffix(".__init__")

        @functools.wraps(target)
        def call(*args: Any, **kwargs: Any) -> Any:
            if kwargs and not renames.keys().isdisjoint(kwargs):
                kwargs = take_renamed(kwargs, renames, owner)
            return target(*args, **kwargs)

        call.__renamed_keywords__ = dict(renames)  # type: ignore[attr-defined]
        return call  # type: ignore[return-value]

    return decorate
