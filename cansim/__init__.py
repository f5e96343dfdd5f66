"""cansim: continuous-attractor networks, RatSLAM and WhiskerRatSLAM.

Importing cansim does no work beyond binding names; backends are imported, and
numba/OpenCL kernels compiled, on first use.
"""

from __future__ import annotations

from cansim.axes import Axis
from cansim.backends import available_backends, get_backend, registered_backends
from cansim.errors import (
    BackendUnavailableError,
    CansimError,
    ConfigError,
    InvalidInputError,
    ShapeError,
    UnknownBackendError,
    ZeroActivityError,
)
from cansim.params import AttractorParams
from cansim.population import Population

__version__ = "0.1.0"

__all__ = [
    "Axis",
    "AttractorParams",
    "Population",
    "available_backends",
    "get_backend",
    "registered_backends",
    "CansimError",
    "InvalidInputError",
    "ShapeError",
    "ZeroActivityError",
    "UnknownBackendError",
    "BackendUnavailableError",
    "ConfigError",
]
