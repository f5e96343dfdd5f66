"""Generated numba kernels cached on disk: their source is written as a module, keyed by its hash.

Numba's ``cache=True`` keeps a function's machine code between processes only when the
function lives in a source file (the cache index is stamped with the file's size and
modification time). Kernels generated from source text at run time (the unrolled
small-grid step, :mod:`cansim.backends._numba_small`) therefore get a file of their
own: :func:`cached_module` writes the generated source into the kernel cache folder
as ``<stem>_<hash>.py`` and imports it, and the ``cache=True`` functions in it are
compiled once and loaded from numba's cache by every later process.

Design
------
* **Key**: the SHA-256 of the source text and of the source of the modules it calls
  (``depends``): numba's index does not see a change in a called function in another
  file, so editing a dependency gives a new file name and a fresh compilation. A
  file, once written, is never rewritten while it is intact, so numba's stamp stays
  valid.
* **Where**: ``CANSIM_KERNEL_CACHE`` if set, else ``$NUMBA_CACHE_DIR/cansim_generated``
  when numba's cache folder is set (so one throw-away folder holds the whole cache),
  else ``$XDG_CACHE_HOME/cansim/kernels`` (``~/.cache/cansim/kernels``).
* **Two processes at once**: each writes a private temporary file in the folder and
  links it to the final name (``os.link`` fails if the name exists: the first writer
  wins, the file is never half-written under its final name); where hard links are not
  supported, an atomic ``os.replace`` of identical bytes.
* **Corrupt module** (its bytes are not the expected source, e.g. truncated): replaced
  atomically by a fresh copy, which numba then compiles and caches again.
* **Corrupt numba cache files** of a generated module's functions (index or data that
  cannot be read back): numba itself would raise at every call; the functions of a
  cached module read their cache through :class:`whisker_io.numba_cache.TolerantIndex`, which treats such a
  file as a cache miss (one warning), so the function compiles again and its entry is
  written anew.
* **Read-only or missing folder, or a module that cannot be imported**: the caller
  falls back to compiling the source in memory for this process
  (:func:`cached_module` returns None) after one warning per folder; nothing fails.
"""

from __future__ import annotations

import hashlib
import importlib.util
import logging
import os
import sys
import tempfile
import threading
from pathlib import Path
from types import ModuleType
from typing import Any, Iterable, Optional

from whisker_io.numba_cache import TolerantIndex, tolerate_corrupt_cache

__all__ = ["kernel_cache_dir", "cached_module", "module_key", "TolerantIndex"]

log = logging.getLogger(__name__)

#: folders a warning was given for (one warning per folder and process)
_WARNED: set = set()
_LOCK = threading.Lock()


def kernel_cache_dir() -> Path:
    """The folder generated kernel modules are written to (see the module docstring)."""
    own = os.environ.get("CANSIM_KERNEL_CACHE")
    if own:
        return Path(own)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "cansim_generated"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "cansim" / "kernels"


def module_key(source: str, depends: Iterable[str | os.PathLike] = ()) -> str:
    """Hex key (20 digits) of ``source`` and the contents of the files ``depends``."""
    h = hashlib.sha256(source.encode())
    for path in depends:
        h.update(b"\0" + Path(path).read_bytes())
    return h.hexdigest()[:20]


def _warn_once(folder: Path, why: str) -> None:
    with _LOCK:
        if folder in _WARNED:
            return
        _WARNED.add(folder)
    log.warning("generated kernels are compiled in memory for this process only (not cached on disk): %s. "
                "Set CANSIM_KERNEL_CACHE (or NUMBA_CACHE_DIR) to a writable folder to cache them.", why)


def _write_atomically(path: Path, data: bytes) -> None:
    """Put ``data`` at ``path`` without a half-written file ever being visible there."""
    fd, tmp = tempfile.mkstemp(prefix=path.stem + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a shared cache folder is readable by all
        if path.exists():  # a corrupt copy: replace it
            os.replace(tmp, path)
            return
        try:
            os.link(tmp, path)  # fails if another process put it there first: its copy is kept
        except FileExistsError:
            pass
        except OSError:  # no hard links on this file system
            os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _load(path: Path, name: str) -> ModuleType:
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # numba's cache locates a function through its module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    tolerate_corrupt_cache(module)
    return module


def cached_module(source: str, stem: str, depends: Iterable[str | os.PathLike] = (),
                  folder: Optional[Path] = None) -> Optional[ModuleType]:
    """Import ``source`` as a module stored at ``<folder>/<stem>_<key>.py``; None if that cannot be done.

    Parameters
    ----------
    source : str
        Python source of the module (its numba functions use ``cache=True``).
    stem : str
        File-name prefix (letters, digits, underscores).
    depends : iterable of paths
        Source files whose contents are part of the key (the modules ``source`` imports from).
    folder : Path, optional
        Cache folder; default :func:`kernel_cache_dir`.

    Returns
    -------
    module or None
        None when the folder cannot be created or written, or the module cannot be
        imported: compile ``source`` in memory instead (one warning per folder is logged).
    """
    folder = kernel_cache_dir() if folder is None else Path(folder)
    key = module_key(source, depends)
    path = folder / f"{stem}_{key}.py"
    data = source.encode()
    try:
        try:
            intact = path.read_bytes() == data
        except FileNotFoundError:
            intact = False
        if not intact:
            folder.mkdir(parents=True, exist_ok=True)
            _write_atomically(path, data)
            if path.read_bytes() != data:  # another writer's copy, corrupt
                raise OSError(f"{path} does not hold the generated source")
    except OSError as exc:
        _warn_once(folder, f"cannot write {path} ({exc})")
        return None
    try:
        return _load(path, f"_cansim_kernels_{stem}_{key}")
    except Exception as exc:  # noqa: BLE001 - e.g. numba finds no writable cache for the file
        _warn_once(folder, f"cannot import {path} ({type(exc).__name__}: {exc})")
        return None
