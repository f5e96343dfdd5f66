"""Active exploration (thesis Ch.6) on the real platform: a UR arm + the USB whisker array.

The explorer of :mod:`cansim.explore.explorer` drives a :class:`~whisker_io.hw.arm.URArm`
(every command through its safety envelope; a refused command is counted and re-planned)
with the Ch.6 settings: the array whisks with RCP retract-at-maximum, each cycle is
recorded (CSV + pose log, :class:`~whisker_io.hw.recorder.Recorder`) and turned into
region features by :class:`~whisker_io.sim.whisk_chain.RecordedChain` with an SVR radial
model (``svr10`` of Table 4.1, ``--radial-model``). The known objects are mapped objects
saved with ``KnownObject.save`` or bare WhiskerRatSLAM models saved with
``WhiskerRatSLAM.save`` (``--map NAME=PATH``, at least one). The
default search visits the faces of a sphere of ``--object-radius`` around
``--object-centre`` (base frame). ``--matcher surface`` takes its impulses from the
known objects' stored surfaces (:class:`maps.surface_match.SurfaceMatcher`) instead of the
thesis' region match; it needs maps saved with ``KnownObject.save`` (the model and its
mapping log; the object where it was mapped), bare model files are refused (status 2). Odometry is the arm's (exact). The run stops at the IC
threshold or after ``--iterations`` whisks; ``exploration.csv`` in ``--out`` holds the
per-whisk raw and integrated confidence of every known object.
Needs the ``hw`` extra: ``pip install "cansim[hw]"``.

Usage::

    python examples/hardware_exploration.py --robot-ip 192.168.1.10 --radial-model svr10.skops \\
        --map box=box.npz --map box_stack=box_stack.npz --object-centre 0.4 0 0.2 [--out hw_explore]

Replay a recorded session through the same code: ``--replay DIR`` (no robot needed).
Give your cell's safety limits with ``--envelope cell.json`` (a JSON object of
:class:`~whisker_io.hw.safety.SafetyEnvelope` fields, fields left out keep their
defaults; with the defaults many of the search's faces round the default object centre
are refused and re-planned).

Exit status (one line on stderr says why, never a traceback):

=====  =====================================================================
0      done
1      any other failure reported by the library (a typed ``CansimError``)
2      usage error: bad command line, envelope, map or radial-model argument
3      no robot reachable at ``--robot-ip``
4      no whisker array found on USB
5      the session stopped on a fault (completed whisks are kept on disk)
6      the ``hw`` extra (ur-rtde, pyusb) is not installed
130    interrupted (Ctrl-C): the arm and array are stopped, completed whisks are kept on disk
=====  =====================================================================

The last line names the decision: the known object whose integrated confidence reached
``--threshold`` first (:func:`maps.recognition.decide`), or "nothing".
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from whisker_io.command_line import CommandParser
from whisker_io.errors import CansimError, HardwareError
from whisker_io.hw.platform import (EXIT_NO_ARRAY, EXIT_NO_EXTRA, EXIT_NO_ROBOT, EXIT_STOPPED,  # noqa: F401 - the exit table
                                    add_envelope_options, envelope_from_options)

EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130  # 3-6: whisker_io.hw.platform (a hardware fault)
#: RCP retract-at-maximum threshold (counts; 98 % of the 2047-count maximum, Sec 4.1.1).
RCP_THRESHOLD = 2000.0


def fail(status: int, message: str) -> int:
    print(f"hardware_exploration: {message}", file=sys.stderr)
    return status


def exact_odometry() -> Callable[[Any, Any], tuple[np.ndarray, np.ndarray, float]]:
    """The arm's odometry between two poses (Eq 6.4-6.11 with every noise term zero)."""
    from whisker_io.sim.odometry_noise import OdometryNoise, noisy_odometry

    params = OdometryNoise(angular_speed_std_rad_s=0.0, euler_std_rad=0.0, displacement_std_m=0.0)
    rng = np.random.default_rng(0)
    return lambda a, b: noisy_odometry(a, b, rng, params)


def load_known(specs: Sequence[str]) -> list[Any]:
    """``NAME=PATH`` -> :class:`~cansim.explore.explorer.KnownObject` (:meth:`KnownObject.load`: a mapped object
    saved with ``KnownObject.save``, or a bare ``WhiskerRatSLAM.save`` model)."""
    from cansim.explore.explorer import KnownObject

    known = []
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep or not name or not path:
            raise ValueError(f"--map takes NAME=PATH, got {spec!r}")
        if name in [k.name for k in known]:
            raise ValueError(f"{name} is given twice; give each known object once, with its own name")
        obj = KnownObject.load(path, name=name)
        if obj.model.object_map.n_experiences == 0:
            raise ValueError(f"{name}={path}: the map holds no experience (its mapping never observed a region); "
                             "map the object again closer to it")
        known.append(obj)
    return known


def decision(names: Sequence[str], result: Any, threshold: float) -> str:
    """The run's decision in words: the object whose IC reached ``threshold`` first, or nothing."""
    from maps.recognition import decide

    k = decide(np.asarray(result.ic, dtype=float).reshape(len(result.ic), len(names)), threshold) if len(result.ic) else None
    return f"decided: {names[k]} (IC >= {threshold:g})" if k is not None else f"decided: nothing (no IC reached {threshold:g})"


def write_trace(path: Path, names: Sequence[str], result: Any) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["iteration", "source"] + [f"confidence_{n}" for n in names] + [f"ic_{n}" for n in names])
        for i in range(len(result.ic)):
            w.writerow([i, result.strategies[i]] + [f"{v:.6g}" for v in result.confidence[i]] + [f"{v:.6g}" for v in result.ic[i]])


def _parser() -> argparse.ArgumentParser:
    ap = CommandParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot-ip", help="UR controller address (not needed with --replay)")
    ap.add_argument("--radial-model", required=True, help="Ch.4 svr10 model (.skops)")
    ap.add_argument("--map", action="append", default=[], metavar="NAME=PATH", help="a known object's saved model")
    ap.add_argument("--object-centre", type=float, nargs=3, default=(0.4, 0.0, 0.2), help="base frame, m")
    ap.add_argument("--object-radius", type=float, default=0.15, help="default-search sphere radius, m")
    ap.add_argument("--strategy", choices=("default", "feh", "lsr"), default="lsr")
    ap.add_argument("--matcher", choices=("thesis", "surface"), default="thesis",
                    help="impulse source: the thesis' region match, or the stored surfaces (maps saved with KnownObject.save)")
    ap.add_argument("--spc", choices=("on", "off"), default="on")
    ap.add_argument("--threshold", type=float, default=300.0, help="IC threshold")
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--time-limit", type=float, default=math.inf, help="s")
    ap.add_argument("--seed", type=int, default=0, help="picks the default search's first face")
    ap.add_argument("--out", type=Path, default=None,
                    help="session directory (default hw_explore; with --replay: where exploration_replay.csv goes, "
                         "default the recorded session's directory)")
    ap.add_argument("--replay", type=Path, default=None,
                    help="replay a recorded session directory instead (its first --iterations whisks, stopping at "
                         "--threshold as a live run does)")
    ap.add_argument("--vendor-id", type=lambda s: int(s, 0), default=None)
    ap.add_argument("--product-id", type=lambda s: int(s, 0), default=None)
    add_envelope_options(ap)
    return ap


def main(argv: Sequence[str] | None = None, *, control_factory: Callable[[str], Any] | None = None,
         usb_backend: Any = None) -> int:
    """Run (see the module docstring). ``control_factory`` and ``usb_backend`` are test doubles."""
    try:
        return _session(argv, control_factory, usb_backend)
    except CansimError as exc:
        return fail(EXIT_FAILURE, f"{type(exc).__name__}: {exc}")
    except KeyboardInterrupt:  # loading maps, a replay, writing the trace (a live run's own says what was kept)
        return fail(EXIT_INTERRUPTED, "interrupted")


def _session(argv: Sequence[str] | None, control_factory: Any, usb_backend: Any) -> int:
    args = _parser().parse_args(list(argv) if argv is not None else None)  # exits 2 on a usage error
    from cansim.explore.explorer import Explorer
    from cansim.explore.placement import PlacementParams
    from cansim.explore.search import DefaultSearch
    from whisker_io.sim.whisk_chain import RecordedChain

    if not (args.iterations >= 1 and args.threshold > 0 and args.object_radius > 0):
        return fail(EXIT_USAGE, "--iterations >= 1, --threshold > 0 and --object-radius > 0 are needed")
    try:
        envelope = envelope_from_options(args)
    except (CansimError, OSError) as exc:
        return fail(EXIT_USAGE, f"invalid safety envelope: {exc}")
    if not args.map:
        return fail(EXIT_USAGE, "give at least one known object with --map NAME=PATH")
    try:
        known = load_known(args.map)
    except (ValueError, OSError, CansimError) as exc:
        return fail(EXIT_USAGE, f"invalid --map: {exc}")
    if args.matcher == "surface":
        bare = [k.name for k in known if k.mapping_log is None]
        if bare:
            return fail(EXIT_USAGE, f"--matcher surface needs maps saved with KnownObject.save (a mapping log); "
                                    f"bare models: {', '.join(bare)}")
    try:
        chain = RecordedChain(contact_model="svr", radial_model=args.radial_model)
    except (OSError, CansimError) as exc:
        return fail(EXIT_USAGE, f"invalid --radial-model: {exc}")
    search = DefaultSearch(args.object_centre, args.object_radius, seed=args.seed)
    placement = PlacementParams(roll_rad=math.pi / 2) if args.spc == "on" else None

    def make_explorer(sensor: Any, arm: Any) -> Explorer:
        return Explorer(known, sensor, arm, exact_odometry(), search, strategy=args.strategy, placement=placement,
                        stop_threshold=args.threshold, max_iterations=args.iterations, time_limit_s=args.time_limit,
                        matcher=args.matcher)

    names = [k.name for k in known]
    if args.replay is not None:
        from itertools import islice

        from whisker_io.records.recording import replay

        if not args.replay.is_dir():
            return fail(EXIT_USAGE, f"--replay {args.replay}: no such session directory (a live run's --out)")
        cycles = [chain(c) for c in islice(replay(args.replay), args.iterations)]  # the features of those whisks only
        if not cycles:
            return fail(EXIT_USAGE, f"--replay {args.replay}: the session holds no whisk")
        result = make_explorer(None, None).replay(cycles, stop_at_threshold=True)  # as a live run: until the threshold
        out = args.out if args.out is not None else args.replay
        out.mkdir(parents=True, exist_ok=True)
        write_trace(out / "exploration_replay.csv", names, result)
        print(f"replayed {len(result.ic)} whisks ({result.stop_reason}); final IC "
              + ", ".join(f"{n} {v:.1f}" for n, v in zip(names, result.ic[-1])))
        print(decision(names, result, args.threshold))
        return EXIT_OK
    if not args.robot_ip:
        return fail(EXIT_USAGE, "--robot-ip is needed (or --replay DIR)")
    args.out = args.out if args.out is not None else Path("hw_explore")

    from whisker_io.array.control import WhiskPattern
    from whisker_io.hw.platform import open_platform, session_failure
    from whisker_io.hw.recorder import Recorder
    from whisker_io.hw.usb_array import FrameLayout

    layout = FrameLayout(**{k: v for k, v in (("vendor_id", args.vendor_id), ("product_id", args.product_id)) if v is not None})
    try:  # before connecting: a folder that is no session of a recorder is refused with nothing deleted
        Recorder.check_folder(args.out)
    except (CansimError, OSError) as exc:
        return fail(EXIT_USAGE, f"--out {args.out}: {exc}")
    recorder = None
    try:
        with open_platform(args.robot_ip, envelope, layout, control_factory=control_factory,
                           usb_backend=usb_backend) as (arm, array):
            with array.whisking(WhiskPattern(), "retract_on_max", RCP_THRESHOLD), Recorder(args.out) as recorder:
                def sensor(pose: Any) -> Any:
                    # the state with the pose the explorer whisks at, so a replay sees the same poses
                    cycle = recorder.record(dataclasses.replace(arm.state(), pose=pose), array.read_whisk_retrying())
                    return chain(cycle)[1]

                result = make_explorer(sensor, arm).run()
    except HardwareError as exc:
        return fail(*session_failure(exc, recorder.n_cycles if recorder is not None else 0))
    except KeyboardInterrupt:  # the platform's exit has stopped the arm and the array
        return fail(EXIT_INTERRUPTED, f"interrupted after {recorder.n_cycles if recorder is not None else 0} whisks, kept in {args.out}; "
                                      f"their trace: --replay {args.out}")
    write_trace(args.out / "exploration.csv", names, result)
    print(f"{len(result.ic)} whisks ({result.stop_reason}), {result.refused_commands} refused commands; final IC "
          + ", ".join(f"{n} {v:.1f}" for n, v in zip(names, result.ic[-1])))
    print(decision(names, result, args.threshold))
    return EXIT_OK


if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "hardware_exploration"))
