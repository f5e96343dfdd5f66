"""The real platform in one block: the UR arm and the USB whisker array, connected in order.

:func:`open_platform` connects the arm (through its safety envelope), then the array,
and closes both on leaving the block (the array first). A failure to connect names the
device: :class:`~whisker_io.errors.RobotUnreachableError` or
:class:`~whisker_io.errors.ArrayNotFoundError` (both
:class:`~whisker_io.errors.ConnectionFailedError`), and a missing ``hw`` extra is
:class:`~whisker_io.errors.MissingDependencyError`, so a script can tell its user
which cable or package to check::

    with open_platform("192.168.1.10", SafetyEnvelope()) as (arm, array):
        with array.whisking(mode="retract_on_max", rcp_threshold_counts=2000.0):
            ...
"""

from __future__ import annotations

import argparse
import contextlib
from typing import Any, Callable, Iterator, NamedTuple, Optional

from whisker_io.errors import (ArrayNotFoundError, ConnectionFailedError, HardwareError, MissingDependencyError,
                               RobotUnreachableError)
from whisker_io.hw.arm import URArm
from whisker_io.hw.safety import SafetyEnvelope
from whisker_io.hw.usb_array import FrameLayout, USBArray

__all__ = ["EXIT_NO_ARRAY", "EXIT_NO_EXTRA", "EXIT_NO_ROBOT", "EXIT_STOPPED", "Platform", "add_envelope_options",
           "envelope_from_options", "open_platform", "session_failure"]

#: Exit statuses of the hardware scripts (``examples/hardware_*.py``) for a hardware fault.
EXIT_NO_ROBOT, EXIT_NO_ARRAY, EXIT_STOPPED, EXIT_NO_EXTRA = 3, 4, 5, 6


class Platform(NamedTuple):
    """The connected devices."""

    arm: URArm
    array: USBArray


@contextlib.contextmanager
def open_platform(
    robot_ip: str,
    envelope: SafetyEnvelope,
    layout: Optional[FrameLayout] = None,
    *,
    control_factory: Optional[Callable[[str], Any]] = None,
    usb_backend: Any = None,
) -> Iterator[Platform]:
    """Connect the arm, then the whisker array; close both when the block ends.

    Parameters
    ----------
    robot_ip : str
        The arm controller's address.
    envelope : SafetyEnvelope
        Checked on every arm command (:class:`whisker_io.hw.safety.SafetyEnvelope`).
    layout : FrameLayout, optional
        USB ids and frame format of the array (default :class:`FrameLayout()`).
    control_factory, usb_backend : optional
        Test doubles: an RTDE control factory for :class:`~whisker_io.hw.arm.URArm`
        and a pyusb backend for :class:`~whisker_io.hw.usb_array.USBArray`
        (:mod:`whisker_io.testing`).

    Yields
    ------
    Platform
        ``(arm, array)``.

    Raises
    ------
    MissingDependencyError
        The ``hw`` extra is not installed.
    RobotUnreachableError
        No arm answered at ``robot_ip`` (nothing is left open).
    ArrayNotFoundError
        No array with the layout's ids on USB (the arm is closed again).
    """
    try:
        arm = URArm(robot_ip, envelope, control_factory=control_factory)
    except ConnectionFailedError as exc:
        raise RobotUnreachableError(f"no robot reachable at {robot_ip}: {exc}") from exc
    with arm:
        try:
            array = USBArray(layout, backend=usb_backend)
        except ConnectionFailedError as exc:
            raise ArrayNotFoundError(f"no whisker array found: {exc}") from exc
        with array:
            yield Platform(arm, array)


def session_failure(exc: HardwareError, whisks_done: int) -> tuple[int, str]:
    """The exit status and one-line message of a hardware session that ended on ``exc``.

    * :class:`MissingDependencyError` -> :data:`EXIT_NO_EXTRA`, the message says which extra to install;
    * :class:`RobotUnreachableError` -> :data:`EXIT_NO_ROBOT`, with the address tried;
    * :class:`ArrayNotFoundError` -> :data:`EXIT_NO_ARRAY`, with the USB ids;
    * any other :class:`HardwareError` -> :data:`EXIT_STOPPED`: the whisks kept, then the fault.

    Parameters
    ----------
    exc : HardwareError
        What ended the session.
    whisks_done : int
        Whisks recorded before it (they are on disk).
    """
    if isinstance(exc, MissingDependencyError):
        return EXIT_NO_EXTRA, str(exc)
    if isinstance(exc, RobotUnreachableError):
        return EXIT_NO_ROBOT, str(exc)
    if isinstance(exc, ArrayNotFoundError):
        return EXIT_NO_ARRAY, str(exc)
    return EXIT_STOPPED, f"stopped after {whisks_done} whisks ({type(exc).__name__}): {exc}"


def add_envelope_options(parser: argparse.ArgumentParser) -> None:
    """Give a hardware command line its safety-envelope options: ``--envelope FILE`` (a JSON file of
    :class:`SafetyEnvelope` fields, :meth:`SafetyEnvelope.load`; the lab's cell: workspace box, tilt,
    speeds) and ``--tool-axis X Y Z`` (the nominal tool z-axis, base frame; default straight down)."""
    parser.add_argument("--envelope", default=None, metavar="FILE",
                        help="safety limits of your cell: a JSON object of SafetyEnvelope fields, e.g. "
                             '{"workspace_min": [0.2, -0.4, 0.02], "workspace_max": [0.8, 0.4, 0.6], '
                             '"max_tool_tilt": 2.0} (fields left out keep their defaults)')
    parser.add_argument("--tool-axis", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                        help="nominal tool z-axis in the base frame (safety envelope; default 0 0 -1, or the "
                             "--envelope file's tool_reference_axis)")


def envelope_from_options(args: argparse.Namespace) -> SafetyEnvelope:
    """The envelope :func:`add_envelope_options`' options describe: the ``--envelope`` file's (or the
    defaults), with ``--tool-axis`` given in place of its tool axis.

    Raises
    ------
    ConfigError
        The file or the axis breaks a limit, or the file and ``--tool-axis`` name different axes (the
        message names the option to mend).
    CorruptFileError, OSError
        The ``--envelope`` file is unreadable or not a JSON object of limits.
    """
    import dataclasses

    import numpy as np

    from whisker_io.errors import ConfigError
    from whisker_io.hw.safety import read_limits

    limits = read_limits(args.envelope) if args.envelope is not None else {}  # the file read once
    envelope = SafetyEnvelope.from_limits(limits, source=args.envelope or "")
    if args.tool_axis is None:
        return envelope
    try:
        axis = SafetyEnvelope(tool_reference_axis=tuple(args.tool_axis)).tool_reference_axis
    except ConfigError as exc:
        raise ConfigError(f"--tool-axis: {exc}") from None
    if "tool_reference_axis" in limits:  # only an axis the file names can disagree with --tool-axis
        unit = [np.asarray(a, dtype=float) / np.linalg.norm(a) for a in (axis, envelope.tool_reference_axis)]
        if not np.allclose(*unit, atol=1e-9):
            raise ConfigError(f"--tool-axis {' '.join(f'{v:g}' for v in axis)} and the --envelope file's "
                              f"tool_reference_axis {list(envelope.tool_reference_axis)} differ: give the axis in one place")
    return dataclasses.replace(envelope, tool_reference_axis=axis)
