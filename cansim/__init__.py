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
    CorruptFileError,
    InvalidInputError,
    ShapeError,
    UnknownBackendError,
    ZeroActivityError,
)
from cansim.params import AttractorParams
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.population import Population
from whisker_io._lazy import lazy_exports

__version__ = "0.1.0"

# Heavier model-level names are loaded on first access (networkx, scipy, numba kernels).
_LAZY = {
    "RatSLAM": "cansim.ratslam",
    "RatSLAMConfig": "cansim.ratslam_config",
    "WhiskerRatSLAM": "cansim.whisker_ratslam",
    "WhiskerRatSLAMConfig": "cansim.whisker_ratslam",
    "SlamLoop": "cansim.slam_loop",
    "SlamState": "cansim.slam_loop",
    "SlamLog": "cansim.slam_loop",
    "PlanarOdometry": "maps.odometry",
    "SpatialOdometry": "maps.odometry",
    "PosecellNetwork": "cansim.posecell_network",
    "SpikingPopulation": "cansim.spiking",
    "SpikingParams": "cansim.spiking",
    "NeuronParams": "cansim.spiking",
    "SpikeCountDecoder": "cansim.spiking",
    "spiking_from_rate": "cansim.spiking",
    "to_nir": "cansim.spiking",
    "from_nir": "cansim.spiking",
}


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = [
    "Axis",
    "AttractorParams",
    "Population",
    "LocalViewCells",
    "LocalViewParams",
    "RatSLAM",
    "RatSLAMConfig",
    "WhiskerRatSLAM",
    "WhiskerRatSLAMConfig",
    "SlamLoop",
    "SlamState",
    "SlamLog",
    "PlanarOdometry",
    "SpatialOdometry",
    "PosecellNetwork",
    "SpikingPopulation",
    "SpikingParams",
    "NeuronParams",
    "SpikeCountDecoder",
    "spiking_from_rate",
    "to_nir",
    "from_nir",
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
    "CorruptFileError",
]
