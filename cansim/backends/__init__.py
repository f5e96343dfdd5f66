"""Backend registry: choose the implementation of the CAN kernels by name.

``numpy`` is the reference; ``numba`` compiles CPU kernels lazily on first use;
``opencl`` runs pyopencl kernels (PoCL on CPUs, or any OpenCL device). Importing
this package does no work: a backend's module is imported when it is first asked for.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass

from cansim.backends.base import Backend
from cansim.errors import BackendUnavailableError, UnknownBackendError

__all__ = ["Backend", "get_backend", "available_backends", "registered_backends"]


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
    """Names of every backend this version knows, installed or not."""
    return tuple(_REGISTRY)


def available_backends() -> tuple[str, ...]:
    """Names of the backends whose dependencies are importable (nothing is imported)."""
    return tuple(
        name
        for name, e in _REGISTRY.items()
        if all(importlib.util.find_spec(m) is not None for m in e.requires)
        and importlib.util.find_spec(e.module) is not None
    )


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
            f"(installed: {', '.join(available_backends())})"
        )
    missing = [m for m in entry.requires if importlib.util.find_spec(m) is None]
    if missing:
        hint = f'pip install "cansim[{entry.extra}]"' if entry.extra else "pip install " + " ".join(missing)
        raise BackendUnavailableError(
            f"backend {name!r} needs {', '.join(missing)}, which is not installed; run: {hint}"
        )
    module = importlib.import_module(entry.module)
    return getattr(module, entry.cls)()
