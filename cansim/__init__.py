"""cansim: continuous-attractor networks, RatSLAM and WhiskerRatSLAM.

Importing cansim does no work beyond binding names: every public name below is loaded
from its module on first access (so ``import cansim.frontends.whisk`` does not load the
engine), backends are imported, and numba/OpenCL kernels compiled, on first use.

The package is laid out by stage, in data-flow order (``CONTRIBUTING.md``): front ends
(:mod:`cansim.frontends`) -> the attractor engine (this package's top level: axes,
params, kernels, backends, :mod:`cansim.population`, path integration, decoding, local
view cells, :mod:`cansim.spiking`) -> maps (the ``maps`` package) -> models
(:mod:`cansim.models`: the SLAM loop, RatSLAM, WhiskerRatSLAM, the exact OpenRatSLAM
engine) -> explorer (:mod:`cansim.explore`) -> studies (:mod:`cansim.studies`) -> tools
(:mod:`cansim.tools`: command line, sweeps, bag replay, benchmark).
"""

from __future__ import annotations

from cansim.errors import (
    BackendUnavailableError,
    CansimError,
    ConfigError,
    CorruptFileError,
    InvalidInputError,
    ShapeError,
    UnknownBackendError,
    UnknownFieldError,
    ZeroActivityError,
)
from whisker_io._lazy import lazy_exports

__version__ = "0.1.0"

_LAZY = {
    "Axis": "cansim.axes",
    "AttractorParams": "cansim.params",
    "Population": "cansim.population",
    "LocalViewCells": "cansim.local_view",
    "LocalViewParams": "cansim.local_view",
    "available_backends": "cansim.backends",
    "get_backend": "cansim.backends",
    "registered_backends": "cansim.backends",
    "RatSLAM": "cansim.models.ratslam",
    "RatSLAMConfig": "cansim.models.ratslam_config",
    "WhiskerRatSLAM": "cansim.models.whisker_ratslam",
    "WhiskerRatSLAMConfig": "cansim.models.whisker_ratslam",
    "SlamLoop": "cansim.models.slam_loop",
    "SlamState": "cansim.models.slam_loop",
    "SlamLog": "cansim.models.slam_loop",
    "PlanarOdometry": "maps.odometry",
    "SpatialOdometry": "maps.odometry",
    "PosecellNetwork": "cansim.models.posecell_network",
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
    "UnknownFieldError",
    "CorruptFileError",
]
