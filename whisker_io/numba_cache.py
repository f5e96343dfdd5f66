"""Numba's on-disk cache read tolerantly: a corrupt cache file is a cache miss, not a crash.

Every compiled kernel of the library is declared with ``cache=True``, so numba keeps its
machine code in an index (``.nbi``) and data (``.nbc``) file per function, beside the
source (``__pycache__``) or under ``NUMBA_CACHE_DIR``. Numba's reader raises on a file
it cannot unpickle (a truncated write, a disk error, garbage): every later call of the
function fails, in every process, until someone deletes the file by hand.

:func:`tolerate_corrupt_cache` gives the cached functions of a module the
:class:`TolerantIndex` reader: an index or data file that cannot be read back is
treated as a cache miss (one warning naming the file), so the function compiles again
and numba writes its entry anew; the next process loads it. Each kernel module calls
it once, at its end, for its own functions; nothing outside the library is changed.
"""

from __future__ import annotations

import logging
import sys
from types import ModuleType
from typing import Any

__all__ = ["TolerantIndex", "tolerate_corrupt_cache"]

log = logging.getLogger(__name__)

try:  # numba's on-disk cache file (index + data); its reader raises on a corrupt file
    from numba.core.caching import IndexDataCacheFile as _IndexFile
except ImportError:  # pragma: no cover - numba's layout changed: no tolerance, numba's own behaviour
    _IndexFile = None


if _IndexFile is not None:

    class TolerantIndex(_IndexFile):  # type: ignore[misc, valid-type]
        """Numba's cache file, reading a corrupt index or data file as a cache miss (the function recompiles)."""

        def _load_index(self) -> dict:
            try:
                return super()._load_index()
            except Exception as exc:  # noqa: BLE001 - unpickling garbage raises anything
                log.warning("corrupt numba cache index %s (%s): recompiling", self._index_path, type(exc).__name__)
                return {}

        def load(self, key: Any) -> Any:
            try:
                return super().load(key)
            except Exception as exc:  # noqa: BLE001
                log.warning("corrupt numba cache data next to %s (%s): recompiling", self._index_path, type(exc).__name__)
                return None
else:  # pragma: no cover
    TolerantIndex = None  # type: ignore[assignment, misc]


def tolerate_corrupt_cache(module: ModuleType | str) -> int:
    """Give every cached numba function of ``module`` the :class:`TolerantIndex` reader.

    Parameters
    ----------
    module : module or str
        The module (or its name in ``sys.modules``, e.g. ``__name__`` from inside it).

    Returns
    -------
    int
        Number of functions given the tolerant reader.
    """
    if isinstance(module, str):
        module = sys.modules[module]
    if TolerantIndex is None:  # pragma: no cover
        return 0
    n = 0
    for value in vars(module).values():
        cache_file = getattr(getattr(value, "_cache", None), "_cache_file", None)
        if cache_file is not None and type(cache_file) is _IndexFile:
            cache_file.__class__ = TolerantIndex
            n += 1
    return n
