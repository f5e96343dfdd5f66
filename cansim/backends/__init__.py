"""Backend registry: choose the implementation of the CAN kernels by name.

``numpy`` is the reference; ``numba`` compiles CPU kernels lazily on first use;
``opencl`` runs pyopencl kernels (PoCL on CPUs, Intel's CPU runtime where PoCL cannot
compile, or any OpenCL device). Importing this package does no work: a backend's
module is imported when it is first asked for.

:func:`available_backends` names the backends that can run on this machine and
:func:`backend_status` says why each other one cannot. Both probe each backend once,
on first call (import it, and for ``opencl`` open a device and build the kernels, a
fraction of a second with pyopencl's on-disk cache), and remember the answer for the
life of the process; ``backend_status(refresh=True)`` probes again.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import threading
from dataclasses import dataclass
from typing import Callable

from cansim.backends.base import Backend
from cansim.errors import BackendUnavailableError, InvalidInputError, UnknownBackendError

__all__ = ["Backend", "get_backend", "available_backends", "backend_status", "register_backend", "registered_backends", "registered_name"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class _Entry:
    module: str
    cls: str
    requires: tuple[str, ...]
    extra: str


_REGISTRY: dict[str, _Entry] = {
    "numpy": _Entry("cansim.backends.numpy_backend", "NumpyBackend", ("numpy",), ""),
    "numba": _Entry("cansim.backends.numba_backend", "NumbaBackend", ("numba",), "numba"),
    "opencl": _Entry("cansim.backends.opencl_backend", "OpenCLBackend", ("pyopencl",), "opencl"),
}


def registered_backends() -> tuple[str, ...]:
    """Names of every backend this version knows, installed or not (and those :func:`register_backend` added)."""
    return tuple(_REGISTRY)


def _importable(module: str, qualname: str) -> type | None:
    """The class ``module.qualname`` (nested classes too), as the registry imports it again; None if absent."""
    found: object = importlib.import_module(module)
    for part in qualname.split("."):
        found = getattr(found, part, None)
    return found  # type: ignore[return-value]


def registered_name(backend: Backend) -> str | None:
    """The name under which the registry builds exactly this backend's class, or None (a class of one's own not
    registered, or a subclass of a registered one that keeps its ``name``): what a saved file may name it by."""
    entry = _REGISTRY.get(getattr(backend, "name", None))  # type: ignore[arg-type]
    cls = type(backend)
    if entry is None or (entry.module, entry.cls) != (cls.__module__, cls.__qualname__):
        return None
    return backend.name


def register_backend(name: str, cls: type[Backend], *, requires: tuple[str, ...] = (), extra: str = "") -> None:
    """Make a backend of your own a named one, as ``"numpy"`` or ``"numba"`` are.

    After this, ``Population(..., backend=name)``, ``RatSLAMConfig(backend=name)``, the
    conformance suite (``pytest --pyargs cansim.testing.conformance --cansim-backend name``),
    :func:`backend_status` and saved files that name it all work with it. A process that loads
    a saved model or population naming it must register it first (worker processes too: register
    it where the class is defined, at import).

    Parameters
    ----------
    name : str
        The backend's name; not one of the built-in ones.
    cls : type
        A subclass of :class:`Backend` implementing its abstract kernels (its docstring lists them),
        constructible without arguments, defined at the top level of an importable module (it is
        imported again by name).
    requires : tuple of str
        Modules it needs; a missing one makes it unavailable with a message naming ``extra``.
    extra : str
        The pip extra (or package) that installs ``requires``.

    Raises
    ------
    InvalidInputError
        A name that is empty or built in, or ``cls`` not such a class.
    """
    if not isinstance(name, str) or not name.strip() or name in ("numpy", "numba", "opencl"):
        raise InvalidInputError(f"a backend's name must be a non-empty string other than numpy, numba and opencl; "
                                f"got {name!r}")
    if not (isinstance(cls, type) and issubclass(cls, Backend)):
        raise InvalidInputError(f"cls must be a subclass of cansim.backends.Backend, got {cls!r}")
    if "<locals>" in cls.__qualname__ or _importable(cls.__module__, cls.__qualname__) is not cls:
        raise InvalidInputError(f"{cls.__qualname__} must be defined at the top level of an importable module "
                                f"({cls.__module__}), so that it can be imported again by name")
    if getattr(cls, "name", None) != name:
        raise InvalidInputError(f"{cls.__name__}.name is {getattr(cls, 'name', None)!r}: set the class attribute "
                                f"name = {name!r} (saved files and configurations name the backend by it)")
    if cls.__abstractmethods__:
        raise InvalidInputError(f"{cls.__name__} does not implement {', '.join(sorted(cls.__abstractmethods__))} "
                                "(the abstract kernels of cansim.backends.Backend)")
    if not (isinstance(requires, tuple) and all(isinstance(m, str) and m for m in requires)):
        raise InvalidInputError(f"requires must be a tuple of module names, got {requires!r}")
    with _status_lock:
        _REGISTRY[name] = _Entry(cls.__module__, cls.__qualname__, requires, str(extra))
        _status_cache.pop(name, None)


def _missing(entry: _Entry) -> list[str]:
    return [m for m in entry.requires if importlib.util.find_spec(m) is None]


def _install_hint(entry: _Entry, missing: list[str]) -> str:
    return f'pip install "cansim[{entry.extra}]"' if entry.extra else "pip install " + " ".join(missing)


def _probe_numba(backend: Backend) -> str:
    import numba

    @numba.njit(cache=False)
    def _one(x):  # proves numba's LLVM can compile and run code on this CPU
        return x + 1

    if _one(1) != 2:  # pragma: no cover - a broken compiler
        raise BackendUnavailableError("numba compiled a function that returned a wrong result")
    if numba.config.DISABLE_JIT:
        return (f"numba {numba.__version__} with NUMBA_DISABLE_JIT set: its kernels run as interpreted Python, "
                "10-100x slower than compiled (unset NUMBA_DISABLE_JIT to compile them)")
    return f"numba {numba.__version__} compiles for this CPU"


def _probe_opencl(backend: Backend) -> str:
    import numpy as np

    backend.prepare(np.float32)  # type: ignore[attr-defined]  # opens the device and builds the kernels
    dev = backend.device  # type: ignore[attr-defined]
    return f"OpenCL device {dev.name.strip()!r} on {dev.platform.name.strip()!r} builds the kernels"


_PROBES: dict[str, Callable[[Backend], str]] = {
    "numpy": lambda b: "the numpy reference",
    "numba": _probe_numba,
    "opencl": _probe_opencl,
}

_status_lock = threading.Lock()
_status_cache: dict[str, tuple[bool, str]] = {}


def _probe(name: str) -> tuple[bool, str]:
    entry = _REGISTRY[name]
    missing = _missing(entry)
    if missing:
        return False, f"needs {', '.join(missing)}, which is not installed; run: {_install_hint(entry, missing)}"
    try:
        backend = get_backend(name)
        return True, _PROBES.get(name, lambda b: "imports")(backend)
    except BackendUnavailableError as exc:
        return False, str(exc)
    except Exception as exc:  # a broken install must not escape a status query
        log.debug("probing backend %r failed", name, exc_info=True)
        return False, f"probing it failed with {type(exc).__name__}: {exc}"


def backend_status(*, refresh: bool = False) -> dict[str, tuple[bool, str]]:
    """Whether each registered backend can run on this machine, and why (not).

    Each backend is probed once per process, on the first call that needs it: its
    optional dependency is looked up, the backend is constructed and, for ``numba``,
    a one-line function compiled; for ``opencl``, a device is opened and the kernels
    built for float32 (which also registers an installed Intel CPU runtime, see
    :mod:`cansim.backends.opencl_runtime`). The answer is cached.

    Parameters
    ----------
    refresh : bool
        Probe again instead of using the cached answer (e.g. after installing an extra).

    Returns
    -------
    dict
        ``name -> (usable, reason)`` for every name of :func:`registered_backends`;
        ``reason`` is one sentence: what runs, or why not and what to install.
    """
    if not isinstance(refresh, bool):
        raise InvalidInputError(f"refresh must be True or False, got {refresh!r}")
    with _status_lock:
        if refresh:
            _status_cache.clear()
        for name in _REGISTRY:
            if name not in _status_cache:
                _status_cache[name] = _probe(name)
        return dict(_status_cache)


def available_backends() -> tuple[str, ...]:
    """Names of the backends that can run on this machine, in registry order.

    A backend is listed when its optional dependency is installed and its probe (see
    :func:`backend_status`, cached after the first call) succeeded; ``numpy`` always is.
    """
    status = backend_status()
    return tuple(name for name, e in _REGISTRY.items() if not _missing(e) and status[name][0])


def get_backend(name: str | Backend) -> Backend:
    """Return a fresh backend instance for ``name`` (or ``name`` itself if it is a Backend).

    Raises
    ------
    UnknownBackendError
        ``name`` is not a registered backend.
    BackendUnavailableError
        Its optional dependency is missing; the message names the extra to install.
    """
    if isinstance(name, Backend):
        return name
    entry = _REGISTRY.get(name) if isinstance(name, str) else None
    if entry is None:
        raise UnknownBackendError(
            f"unknown backend {name!r}; choose one of {', '.join(_REGISTRY)} "
            f"(usable here: {', '.join(available_backends())})"
        )
    missing = _missing(entry)
    if missing:
        raise BackendUnavailableError(
            f"backend {name!r} needs {', '.join(missing)}, which is not installed; run: "
            f"{_install_hint(entry, missing)}"
        )
    return _importable(entry.module, entry.cls)()
