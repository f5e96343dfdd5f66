"""The models: SLAM loops composed from the engine, the front ends and the maps.

:mod:`~cansim.models.slam_loop` is the one loop both models share (view -> local view
cells -> pose cells -> experience map); :mod:`~cansim.models.ratslam` (3-DoF,
:mod:`~cansim.models.ratslam_config`, OpenRatSLAM's files through
:mod:`~cansim.models.openratslam_config`) and :mod:`~cansim.models.whisker_ratslam`
(6-DoF, thesis Ch.5) configure it; :mod:`~cansim.models.posecell_network` is the exact
OpenRatSLAM pose-cell engine (bit-identical to its C++). Models import the engine and
the maps, never the explorer, the studies or the tools.
"""
