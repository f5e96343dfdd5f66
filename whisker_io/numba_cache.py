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

It also keys those functions' cache on the kernels they may call. Numba stamps a
function's index with its own file's size and modification time only, so a function
that calls a kernel in another file keeps its machine code when that file changes:
after an edit (or an update that rewrote only some files) of
``cansim/backends/_numba_kernels.py`` the cached ``Population.step`` of
``_numba_packets.py`` ran the old passes, silently (measured: a kernel built from two
files, the callee edited, returned the old value in the next process). The stamp of
every function given the tolerant reader is numba's stamp plus a digest of every
Python file mentioning numba in the function's top-level package and in
``whisker_io`` (the layer every kernel may call): editing any kernel file recompiles
the kernels of its package and of the packages above it, in the next process; editing
a file without numba recompiles nothing. A kernel that reads a constant from a module
without numba still keeps the old constant (numba freezes globals at compile time):
keep kernels' constants in kernel modules.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import sys
from pathlib import Path
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


@functools.lru_cache(maxsize=None)
def _kernel_sources_digest(roots: tuple[str, ...]) -> str:
    """SHA-256 (hex) of the path and contents of every ``.py`` file under ``roots`` that mentions numba.

    Memoised per process (one read of the package files, 2-6 ms here): a kernel module
    edited and reloaded (``importlib.reload``) in a running process still finds the
    digest of the sources the process started with - call ``cache_clear()`` first, or
    start a new process. A root that cannot be read (a zip import) adds nothing.
    Every file mentioning numba counts, not only those defining kernels (a plain
    function compiled by a kernel module elsewhere, e.g. ``whisker_io.angles``, is a
    kernel source too): editing such a file recompiles its package's kernels.
    """
    h = hashlib.sha256()
    for root in roots:
        base = Path(root)
        try:
            files = sorted(base.rglob("*.py"))
        except OSError:  # pragma: no cover - not a readable folder
            continue
        for path in files:
            try:
                data = path.read_bytes()
            except OSError:  # pragma: no cover
                continue
            if b"numba" in data:
                h.update(str(path.relative_to(base.parent)).encode())
                h.update(b"\0")
                h.update(hashlib.sha256(data).digest())
    return h.hexdigest()


def _kernel_roots(module: ModuleType) -> tuple[str, ...]:
    """The folders whose kernel sources key ``module``'s cache: its top-level package's and ``whisker_io``'s."""
    roots = [str(Path(__file__).resolve().parent)]
    top = sys.modules.get(module.__name__.split(".")[0])
    top_file = getattr(top, "__file__", None)
    if top is not None and getattr(top, "__path__", None) is not None and top_file:
        root = str(Path(top_file).resolve().parent)
        if root not in roots:
            roots.append(root)
    return tuple(roots)


def tolerate_corrupt_cache(module: ModuleType | str) -> int:
    """Give every cached numba function of ``module`` the :class:`TolerantIndex` reader, keyed on the kernels it may call.

    Each function's cache stamp becomes numba's (its file's size and modification time)
    plus a digest of the kernel sources of its top-level package and of ``whisker_io``
    (module docstring): a change in a kernel it calls from another file is a cache miss.

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
    digest = None
    for value in vars(module).values():
        cache_file = getattr(getattr(value, "_cache", None), "_cache_file", None)
        if cache_file is not None and type(cache_file) is _IndexFile:
            if digest is None:
                digest = _kernel_sources_digest(_kernel_roots(module))
            cache_file.__class__ = TolerantIndex
            cache_file._source_stamp = (cache_file._source_stamp, digest)
            n += 1
    return n
