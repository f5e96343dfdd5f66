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

Hardware drivers need the optional ``hw`` extra (``pip install "cansim[hw]"``);
it is imported lazily, so this package imports without it.
"""

from __future__ import annotations

from whisker_io._lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "MissingDependencyError": "whisker_io.errors",
    "require": "whisker_io.hw.optional",
    "SafetyEnvelope": "whisker_io.hw.safety",
    **{name: "whisker_io.hw.arm" for name in ("Arm", "ArmState", "SimArm", "URArm", "probe_rtde")},
    **{name: "whisker_io.hw.usb_array" for name in ("Array", "FrameLayout", "SimArray", "USBArray", "USBCounters")},
    **{name: "whisker_io.hw.recorder" for name in ("Recorder", "explore", "raster_poses", "replay_session")},
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
