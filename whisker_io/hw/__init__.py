"""Hardware layer of :mod:`whisker_io`: the UR arm, the whisker array over USB,
the safety envelope that guards both, and a crash-safe recorder.

Every driver has a simulated twin with the same interface, so one code path
records from the simulator and from the robot:

=====================  ==========================  =================================
 interface              hardware                    simulation / test double
=====================  ==========================  =================================
 :class:`Arm`           :class:`URArm` (ur-rtde)     :class:`SimArm`
 :class:`Array`         :class:`USBArray` (pyusb)    :class:`SimArray`
=====================  ==========================  =================================

Poses cross these interfaces as the package's one pose type,
:class:`whisker_io.pose.Pose`. The test doubles of the devices themselves (a
fake RTDE server, a fake USB backend) live in :mod:`whisker_io.testing`.

Hardware drivers need the optional ``hw`` extra (``pip install cansim[hw]``);
it is imported lazily, so this package imports without it.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from whisker_io.errors import MissingDependencyError


def require(module: str, what: str) -> ModuleType:
    """Import an optional hardware module or raise :class:`MissingDependencyError`.

    Parameters
    ----------
    module : str
        Module name, e.g. ``"rtde_receive"``.
    what : str
        What needs it, for the message (e.g. ``"URArm"``).
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f"{what} needs the Python module {module!r}, which is not installed; "
            "install the hardware extra: pip install cansim[hw]") from exc


# Defined above before the submodules import it (they do ``from whisker_io.hw import ...``).
from whisker_io.hw.safety import SafetyEnvelope  # noqa: E402
from whisker_io.hw.arm import Arm, ArmState, SimArm, URArm, probe_rtde  # noqa: E402
from whisker_io.hw.usb_array import (  # noqa: E402
    Array, FrameLayout, SimArray, USBArray, USBCounters)
from whisker_io.hw.recorder import Recorder, explore, raster_poses, replay_session  # noqa: E402

__all__ = [
    "MissingDependencyError", "require",
    "SafetyEnvelope",
    "Arm", "ArmState", "SimArm", "URArm", "probe_rtde",
    "Array", "FrameLayout", "SimArray", "USBArray", "USBCounters",
    "Recorder", "explore", "raster_poses", "replay_session",
]
