"""Record an exploration on the real platform: a UR arm (ur-rtde) + the USB whisker array.

Same loop as ``record_sim_session.py`` (:func:`whisker_io.hw.recorder.explore`),
with :class:`~whisker_io.hw.arm.URArm` and :class:`~whisker_io.hw.usb_array.USBArray`
instead of the simulated twins. The arm explores a raster around its current
pose (in the plane perpendicular to the array axis), every command checked by
the safety envelope inside the driver; each whisk is on disk (CSV + pose log)
before the next move. Needs the ``hw`` extra: ``pip install "cansim[hw]"``.

Usage::

    python examples/hardware_session.py --robot-ip 192.168.1.10 [--out hw_session]

Exit status (one line on stderr says why, never a traceback):

=====  =====================================================================
0      done
1      any other failure reported by the library (a typed ``CansimError``)
2      usage error: bad command line, invalid safety-envelope arguments, an ``--out`` folder that is no session
3      no robot reachable at ``--robot-ip``
4      no whisker array found on USB
5      the session stopped on a fault or a safety refusal (completed whisks are kept)
6      the ``hw`` extra (ur-rtde, pyusb) is not installed
130    interrupted (Ctrl-C): the arm and array are stopped, completed whisks are kept
=====  =====================================================================
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from whisker_io.array.control import WhiskPattern
from whisker_io.command_line import CommandParser
from whisker_io.errors import CansimError, HardwareError
from whisker_io.hw.platform import (EXIT_NO_ARRAY, EXIT_NO_EXTRA, EXIT_NO_ROBOT, EXIT_STOPPED,  # noqa: F401 - the exit table
                                    add_envelope_options, envelope_from_options, open_platform, session_failure)
from whisker_io.hw.recorder import Recorder, explore, raster_poses
from whisker_io.hw.usb_array import PATTERN_MODES, FrameLayout


EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130  # 3-6: whisker_io.hw.platform (a hardware fault)


def fail(status: int, message: str) -> int:
    print(f"hardware_session: {message}", file=sys.stderr)
    return status


def main(argv: list[str] | None = None, *, control_factory: Any = None, usb_backend: Any = None) -> int:
    """Run (see the module docstring). ``control_factory`` and ``usb_backend`` are test doubles
    (:mod:`whisker_io.testing`), as in ``hardware_exploration.main``."""
    try:
        return _session(argv, control_factory, usb_backend)
    except CansimError as exc:  # anything the library reports that is not handled below
        return fail(EXIT_FAILURE, f"{type(exc).__name__}: {exc}")
    except KeyboardInterrupt:  # before or after the session (the session's own says how many whisks were kept)
        return fail(EXIT_INTERRUPTED, "interrupted")


def _session(argv: list[str] | None, control_factory: Any = None, usb_backend: Any = None) -> int:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot-ip", required=True, help="UR controller address")
    ap.add_argument("--vendor-id", type=lambda s: int(s, 0), default=FrameLayout.vendor_id)
    ap.add_argument("--product-id", type=lambda s: int(s, 0), default=FrameLayout.product_id)
    ap.add_argument("--out", type=Path, default=Path("hw_session"), help="session directory")
    ap.add_argument("--width", type=float, default=0.06, help="raster width, m")
    ap.add_argument("--height", type=float, default=0.06, help="raster height, m")
    ap.add_argument("--nx", type=int, default=4)
    ap.add_argument("--nz", type=int, default=3)
    ap.add_argument("--mode", choices=PATTERN_MODES, default="retract_on_max")
    ap.add_argument("--rcp-threshold", type=float, default=2000.0, help="counts")
    add_envelope_options(ap)
    args = ap.parse_args(argv)  # exits with status 2 on a usage error

    try:
        envelope = envelope_from_options(args)
    except (CansimError, OSError) as exc:
        return fail(EXIT_USAGE, f"invalid safety envelope: {exc}")
    try:  # before connecting: a folder that is no session of a recorder is refused with nothing deleted
        Recorder.check_folder(args.out)
    except (CansimError, OSError) as exc:
        return fail(EXIT_USAGE, f"--out {args.out}: {exc}")
    recorder = None
    try:
        with open_platform(args.robot_ip, envelope, FrameLayout(vendor_id=args.vendor_id, product_id=args.product_id),
                           control_factory=control_factory, usb_backend=usb_backend) as (arm, array):
            with array.whisking(WhiskPattern(), args.mode, args.rcp_threshold):
                targets = raster_poses(arm.pose(), args.width, args.height, args.nx, args.nz)
                with Recorder(args.out) as recorder:
                    explore(arm, array, recorder, targets, description="exploring")
    except HardwareError as exc:
        return fail(*session_failure(exc, recorder.n_cycles if recorder is not None else 0))
    except KeyboardInterrupt:  # the platform's exit has stopped the arm and the array
        return fail(EXIT_INTERRUPTED, f"interrupted after {recorder.n_cycles if recorder is not None else 0} whisks, kept in {args.out}/")
    print(f"{recorder.n_cycles} whisks recorded in {args.out}/")
    return EXIT_OK


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "hardware_session"))
