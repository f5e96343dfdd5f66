"""Active exploration for fast recognition (thesis Ch.6): the last stage of the data flow.

* :mod:`cansim.explore.placement` - the surface placement controller (SPC, Alg 7-8);
* :mod:`cansim.explore.contact_seeking` - reaching and keeping a surface of unknown shape
  from contact feedback (advance until whiskers touch, back off when pressed);
* :mod:`cansim.explore.search` - the region-search strategies (default sphere faces,
  follow experience history, least similar region; Sec 6.1.2);
* :mod:`cansim.explore.explorer` - the loop: whisk, WhiskerRatSLAM per known object,
  recognition by integrated confidence, strategy, SPC, arm (through its safety envelope).
"""

from cansim.explore.contact_seeking import ContactSeekingParams, seek_contact
from cansim.explore.explorer import ExplorationResult, Explorer, KnownObject, build_object_model
from cansim.explore.placement import DEFAULT_CONE_HALF_ANGLE_RAD, PlacementParams, maintain_yaw, place, ring_half_angle_rad
from cansim.explore.search import DefaultSearch

__all__ = ["ContactSeekingParams", "DEFAULT_CONE_HALF_ANGLE_RAD", "DefaultSearch", "ExplorationResult", "Explorer",
           "KnownObject", "PlacementParams", "build_object_model", "maintain_yaw", "place", "ring_half_angle_rad",
           "seek_contact"]
