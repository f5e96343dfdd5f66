"""Deprecated import paths of modules that moved before the first release (issue 21: folders by stage).

Each old module (``cansim/ratslam.py`` ...) is a three-line stub that calls
:func:`alias_module`: it warns once and puts the new module in ``sys.modules`` under the
old name, so ``import cansim.ratslam`` and ``from cansim.ratslam import RatSLAM`` keep
working (the same module object, not a copy) until the stubs are removed in 0.3.
"""

from __future__ import annotations

import importlib
import sys
import warnings

__all__ = ["alias_module", "MOVED"]

#: Old module -> new module (CHANGELOG 0.2.0).
MOVED: dict[str, str] = {
    "cansim.slam_loop": "cansim.models.slam_loop",
    "cansim.ratslam": "cansim.models.ratslam",
    "cansim.ratslam_config": "cansim.models.ratslam_config",
    "cansim.openratslam_config": "cansim.models.openratslam_config",
    "cansim.whisker_ratslam": "cansim.models.whisker_ratslam",
    "cansim.posecell_network": "cansim.models.posecell_network",
    "cansim._posecell_kernels": "cansim.models._posecell_kernels",
    "cansim.cli": "cansim.tools.cli",
    "cansim.sweep": "cansim.tools.sweep",
    "cansim.bag_replay": "cansim.tools.bag_replay",
    "cansim.benchmark": "cansim.tools.benchmark",
}


def alias_module(old: str) -> None:
    """Make the moved module importable under its old name ``old``, with a DeprecationWarning."""
    new = MOVED[old]
    warnings.warn(f"{old} moved to {new} (before the first release); import {new} (the old path goes in 0.3)",
                  DeprecationWarning, stacklevel=3)
    sys.modules[old] = importlib.import_module(new)
