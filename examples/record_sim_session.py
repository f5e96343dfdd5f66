"""Record a simulated exploration of an object through the hardware code path.

A kinematic :class:`~whisker_io.hw.arm.SimArm` (rate-limited, behind the same
safety envelope as the robot) carries the simulated 18-whisker array
(:class:`~whisker_io.hw.usb_array.SimArray`: the
:class:`~whisker_io.sim.simulator.ArraySimulator` with the Ch.4/6 retract-at-maximum
whisking, its samples passed through the USB frame codec) across a raster in
front of an object; :func:`~whisker_io.hw.recorder.explore` takes one whisk per
pose and the :class:`~whisker_io.hw.recorder.Recorder` writes the session
(per-whisk CSVs + pose log) as it goes. Finally the session is replayed from
disk into the contact pipeline and checked to match the live run.

World frame = arm base frame; the object stands on z = 0 centred on the
z-axis, the array looks at it along +y (end-effector z-axis up).

Usage::

    python examples/record_sim_session.py [--object box|MESH_FILE [--scale-to-m M] [--up-axis AXIS]] [--out sim_session] [--seed 0]

Run ``hardware_session.py`` for the same loop on a UR arm and the USB array.
"""

from __future__ import annotations

import sys
from pathlib import Path

from whisker_io.command_line import CommandParser
from whisker_io.contact.detection import detect_contacts
from whisker_io.array.control import RetractAtMax
from whisker_io.hw.arm import SimArm
from whisker_io.errors import CansimError, SafetyViolationError
from whisker_io.hw.platform import session_failure
from whisker_io.pose import Pose
from whisker_io.hw.recorder import Recorder, explore, raster_poses, replay_session
from whisker_io.hw.safety import SafetyEnvelope
from whisker_io.hw.usb_array import SimArray
from cansim.studies.object_options import add_mesh_options, check_mesh_options
from whisker_io.sim.catalogue import resolve_object
from whisker_io.sim.objects import OBJECT_NAMES
from whisker_io.sim.simulator import ArraySimulator


def contacts(cycle):
    """The pipeline fed live and on replay: detected contacts of the 18 modules."""
    return detect_contacts([cycle.records[m] for m in sorted(cycle.records)])


def main() -> None:
    """Run (see the module docstring); Ctrl-C ends with one line and status 130, never a traceback."""
    try:
        _main()
    except KeyboardInterrupt:  # before or after the whisking (the whisking's own says how many whisks were kept)
        print("record_sim_session: interrupted", file=sys.stderr)
        raise SystemExit(130) from None


def _main() -> None:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--object", default="box", metavar="NAME_OR_MESH",
                    help=f"a registered object ({', '.join(sorted(OBJECT_NAMES))}), a procedural shape or a mesh file "
                         "(metres, z up unless --scale-to-m / --up-axis say otherwise); default box")
    add_mesh_options(ap)
    ap.add_argument("--out", type=Path, default=Path("sim_session"), help="session directory")
    ap.add_argument("--distance", type=float, default=0.32,
                    help="end effector to the object's axis, m (0.2-0.6; the whiskers touch a surface up to about "
                         "0.08 m beyond the front bases, 0.28 m from the end effector)")
    ap.add_argument("--nx", type=int, default=5, help="raster poses across")
    ap.add_argument("--nz", type=int, default=4, help="raster poses up")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args()
    try:
        check_mesh_options([args.object], scale_to_m=args.scale_to_m, up_axis=args.up_axis)
        mesh = resolve_object(args.object, scale_to_m=args.scale_to_m, up_axis=args.up_axis).mesh
    except CansimError as exc:  # a misspelt name, a missing or millimetre mesh: one line, exit 2
        ap.error(str(exc))

    # the array looks along +y at the object; its tool z-axis points up
    envelope = SafetyEnvelope(workspace_min=(-0.3, -0.6, 0.02), workspace_max=(0.3, -0.2, 0.5),
                              tool_reference_axis=(0.0, 0.0, 1.0), max_tool_tilt=0.5)
    if not (args.nx >= 1 and args.nz >= 1):
        ap.error(f"--nx and --nz must be >= 1, got {args.nx} and {args.nz}")
    centre = Pose([0.0, -args.distance, 0.18], [0.0, 0.0, 0.0, 1.0])
    targets = raster_poses(centre, width_m=0.16, height_m=0.24, n_x=args.nx, n_z=args.nz)
    try:
        arm = SimArm(targets[0], envelope, rate_limited=True, control_period=0.008)
        for target in targets:
            envelope.check_pose(target)
    except CansimError as exc:  # e.g. --distance 0.19: the raster leaves the workspace
        ap.error(f"--distance {args.distance}: the raster leaves the arm's workspace ({exc}); "
                 "give a distance between 0.2 and 0.6 m")
    simulator = ArraySimulator(seed=args.seed, controller=RetractAtMax())
    array = SimArray.from_simulator(simulator, mesh, arm.pose)
    try:
        recorder = Recorder(args.out, pipeline=contacts)
    except CansimError as exc:  # a folder of whisk files this recorder did not leave: nothing is deleted
        ap.error(f"--out {args.out}: {exc}")
    with recorder:
        try:
            explore(arm, array, recorder, targets, progress=not args.no_progress,
                    description=f"whisking the {args.object}")
        except SafetyViolationError as exc:  # the guard did its job: say so, keep what was recorded
            code, message = session_failure(exc, recorder.n_cycles)
            print(f"record_sim_session: {message}; a larger --distance keeps the array off the object", file=sys.stderr)
            raise SystemExit(code) from None
        except KeyboardInterrupt:
            print(f"record_sim_session: interrupted after {recorder.n_cycles} whisks, kept in {args.out}/ "
                  "(run again to go on)", file=sys.stderr)
            raise SystemExit(130) from None
    live = recorder.results
    n_contacts = sum(c is not None for cycle in live for c in cycle)
    replayed = replay_session(args.out, contacts)[-recorder.n_cycles:]  # this run's cycles (a resumed session has more)
    print(f"{recorder.n_cycles} whisks recorded in {args.out}/ over {arm.time:.1f} s of arm "
          f"motion; {n_contacts} contacts detected; replay identical: {replayed == live}")
    if not n_contacts:
        print(f"warning: no whisker touched the {args.object}: the raster (--distance {args.distance} m from its axis, "
              "0.16 x 0.24 m round 0.18 m high) does not reach it; a smaller --distance, or check its size and "
              "up axis (--scale-to-m, --up-axis)", file=sys.stderr)


if __name__ == "__main__":
    main()
