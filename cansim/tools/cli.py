"""The ``cansim`` command line (also ``python -m cansim``).

Subcommands: ``demo``, ``sweep``, ``study``, ``replay``, ``backends``, ``bench``; each
has ``--help``. Exit codes are :data:`EXIT_CODES` (also in ``cansim --help``): bad
input and failures print one line ``cansim <command>: error: ...`` on stderr, with no
traceback unless ``--debug`` is given.

The demos and the thesis studies are modules of :mod:`cansim.studies` (installed with
the package, no checkout needed), run through their ``main(argv)``; options after the
study's name (``cansim study ch5 --quick --objects mug box``) go to the study itself.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import tempfile
import textwrap
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from whisker_io import command_line
from whisker_io.command_line import CommandParser
from whisker_io.errors import CansimError, InvalidInputError

__all__ = ["main", "build_parser", "EXIT_CODES", "STUDIES", "DEMOS"]

EXIT_OK = 0
EXIT_INTERNAL = command_line.EXIT_INTERNAL  # 1
EXIT_USAGE = 2
EXIT_BAD_INPUT = command_line.EXIT_BAD_INPUT  # 3
EXIT_FAILED = command_line.EXIT_FAILED  # 4
EXIT_NOT_BUILT = 5
EXIT_MISSING_EXTRA = command_line.EXIT_MISSING_EXTRA  # 6
EXIT_INTERRUPTED = command_line.EXIT_INTERRUPTED  # 130

#: exit code -> meaning
EXIT_CODES = {
    EXIT_OK: "success",
    EXIT_INTERNAL: "internal error (a bug: the traceback is printed; please report it)",
    EXIT_USAGE: "usage error (unknown command or option, missing argument)",
    EXIT_BAD_INPUT: ("bad input: a malformed spec, config, bag or mesh file, a missing file, a value out of range in a "
                     "file or a call (an option's value out of range on the command line is a usage error, 2)"),
    EXIT_FAILED: "runtime failure: the run could not finish, or some sweep tasks failed",
    EXIT_NOT_BUILT: "not available here: the study is not built yet",
    EXIT_MISSING_EXTRA: ("an optional dependency is missing, or a backend asked for cannot run here (the message "
                         "names the pip extra or says why)"),
    EXIT_INTERRUPTED: "interrupted (Ctrl-C); a sweep resumes when run again",
}

#: study -> module of :mod:`cansim.studies` (each has ``main(argv)``)
STUDIES = {
    "ch3": "cansim.studies.ch3_maze",
    "ch4": "cansim.studies.ch4_radial_distance",
    "ch5": "cansim.studies.ch5_object_maps",
    "ch6": "cansim.studies.ch6_active_exploration",
    "recognition": "cansim.studies.recognition",
    "rat": "cansim.studies.rat_trajectories",
}
#: demo -> module of :mod:`cansim.studies`; the first is ``cansim demo`` without a name
DEMOS = {
    "whisker": "cansim.studies.whisker_ratslam_demo",
    "ratslam": "cansim.studies.ratslam_demo",
}
_STUDY_TITLES = {
    "ch3": "RatSLAM navigation with a whisker-sensor array",
    "ch4": "object shape reconstruction: radial distance to contact",
    "ch5": "WhiskerRatSLAM: 6-D localisation and object recognition",
    "ch6": "active whisker-array exploration for fast shape recognition",
    "recognition": "object recognition from new paths and viewpoints (benchmark, 12-50 objects)",
    "rat": "rate and spiking attractors on recorded rat trajectories: drift with and without re-anchoring",
}

log = logging.getLogger("cansim.tools.cli")


class CommandError(CansimError):
    """A failure the command reports in one line with its exit code (part of the one error tree)."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


def _run_main(module: ModuleType, argv: list[str], prog: str) -> int:
    """``module.main(argv)``, its usage lines and errors naming ``prog`` (argparse takes its name from ``sys.argv[0]``)."""
    saved = sys.argv[0] if sys.argv else None
    if sys.argv:
        sys.argv[0] = prog
    try:
        code = module.main(argv)
    except SystemExit as exc:  # an example's own argparse or sys.exit
        code = exc.code
    finally:
        if saved is not None:
            sys.argv[0] = saved
    if code is None:
        return EXIT_OK
    if isinstance(code, int):
        return code
    raise CommandError(str(code), EXIT_FAILED)


# ------------------------------------------------------------------ commands
def _writable(out: Path) -> None:
    """Make ``out`` and check that a file can be written in it, before any work (a read-only folder failed at the end)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise CommandError(f"cannot write to the output folder {out} ({exc.strerror or exc}); give a writable --out",
                           EXIT_BAD_INPUT) from None


def _asks_help(args: argparse.Namespace) -> bool:
    return any(o in ("-h", "--help") for o in args.options)


def _cmd_demo(args: argparse.Namespace) -> int:
    if not _asks_help(args):
        _writable(args.out)
    options = list(args.options)
    which = options.pop(0) if options and options[0] in DEMOS else next(iter(DEMOS))
    module = importlib.import_module(DEMOS[which])
    return _run_main(module, ["--seed", str(args.seed), "--out", str(args.out), *options], f"cansim demo {which}")


def _cmd_study(args: argparse.Namespace) -> int:
    if not _asks_help(args):
        _writable(args.out)
    module = importlib.import_module(STUDIES[args.chapter])
    argv = (["--quick"] if args.quick else []) + ["--out", str(args.out), *args.options]
    return _run_main(module, argv, f"cansim study {args.chapter}")


def _cmd_sweep(args: argparse.Namespace) -> int:
    from cansim.tools import sweep

    if not (args.verbose or args.debug):  # Dask's scheduler and workers log at INFO: quiet unless asked
        try:
            import distributed  # noqa: F401 - its import configures its loggers; set them after it
        except ImportError:
            pass  # sweep.run names the missing extra
        for name in ("distributed", "dask"):
            logging.getLogger(name).setLevel(logging.WARNING)
    spec = sweep.load_spec(args.spec)
    out = args.out if args.out is not None else Path.cwd() / spec.name
    result = sweep.run(
        spec, out=out, progress=not args.no_progress, scheduler=args.scheduler, workers=args.workers,
        retry_errors=args.retry_errors,
    )
    total = result.table.num_rows
    print(f"{spec.n_tasks} tasks ({spec.n_cells} cells): ran {result.ran}, already done {result.skipped}, "
          f"failed now {result.failed}; {total} rows in {result.path}")
    errors = result.n_errors
    if errors:
        raise CommandError(
            f"{errors} task(s) ended with an error (see the 'error' column of {result.path}); "
            "fix the cause and re-run with --retry-errors",
            EXIT_FAILED,
        )
    return EXIT_OK


def _cmd_replay(args: argparse.Namespace) -> int:
    from cansim.tools.bag_replay import replay, write_outputs

    bag = Path(args.bag)
    out = args.out if args.out is not None else Path.cwd() / f"{bag.stem or bag.name}_replay"
    result = replay(
        bag, args.config, odometry_topic=args.odom_topic, image_topic=args.image_topic, stamps=args.stamps,
        openratslam=args.openratslam,
        progress=not args.no_progress,
    )
    files = write_outputs(result, out, title=f"Experience map - {bag.name}")
    em = result.slam.experience_map
    print(f"{result.n_odometry} odometry messages ({result.topics.odometry}), {result.n_images} images "
          f"({result.topics.image}): {result.slam.n_views} view templates, {em.n_experiences} experiences, "
          f"{em.n_links} links")
    for name, path in files.items():
        print(f"  {name:10s} {path}")
    return EXIT_OK


def _cmd_backends(args: argparse.Namespace) -> int:
    from cansim.backends import backend_status

    status = backend_status(refresh=args.refresh)
    width = max(len("backend"), *(len(n) for n in status))
    print(f"{'backend':{width}s}  usable  why")
    for name, (ok, reason) in status.items():
        print(f"{name:{width}s}  {'yes' if ok else 'no':6s}  {reason}")
    return EXIT_OK


#: The names ``cansim warm-up --models`` takes: the default RatSLAM, WhiskerRatSLAM and Population presets.
WARM_UP_TARGETS = ("ratslam", "whisker", "population")


def _names(text: str | None) -> list[str] | None:
    """A comma-separated option as a list of names (None when the option was not given)."""
    return None if text is None else [t.strip() for t in text.split(",") if t.strip()]


def _cmd_warm_up(args: argparse.Namespace) -> int:
    import time

    import numpy as np

    from cansim.backends import backend_status
    from cansim.backends.kernel_cache import kernel_cache_dir

    names = _names(args.models) if args.models is not None else list(WARM_UP_TARGETS)
    bad = [n for n in names if n not in WARM_UP_TARGETS]
    if bad or not names:
        raise InvalidInputError(f"--models {args.models!r}: give some of {', '.join(WARM_UP_TARGETS)}")
    status = backend_status()
    if args.backend not in status:
        raise InvalidInputError(f"--backend {args.backend}: no such backend; give one of {', '.join(status)}")
    usable, why = status[args.backend]
    if not usable:  # a backend that exists but cannot run here: status 6, as cansim bench --backends says it
        from cansim.errors import BackendUnavailableError

        raise BackendUnavailableError(f"--backend {args.backend}: {why}")
    progress = not args.no_progress
    t_all = time.perf_counter()
    for name in names:
        t0 = time.perf_counter()
        if name == "ratslam":
            from cansim.models.ratslam import RatSLAM, RatSLAMConfig

            what = "RatSLAM (default config: 21 x 21 x 36 pose cells, view ids)"
            RatSLAM(RatSLAMConfig(backend=args.backend)).warm_up(progress=progress)
        elif name == "whisker":
            from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig

            what = "WhiskerRatSLAM (default and mapping configs: 6-D pose cells, regions, object map)"
            for cfg in (WhiskerRatSLAMConfig(backend=args.backend), WhiskerRatSLAMConfig.mapping(backend=args.backend)):
                WhiskerRatSLAM(cfg).warm_up(progress=progress)
        else:
            from cansim.population import Population

            what = "Population presets (360-cell ring, 21 x 21 x 36, 5^6), step and run"
            for pop, v, w in ((Population.head_direction(360, backend=args.backend), 0.01, None),
                              (Population.openratslam(21, 36, backend=args.backend), 0.3, 0.05),
                              (Population.whisker6d(5, 0.02, backend=args.backend), np.full(3, 0.003), np.full(3, 0.02))):
                pop.warm_up(v, w, run=True, progress=progress)
        print(f"{name}: {time.perf_counter() - t0:.1f} s - {what}")
    where = (f"; numba's cache: {os.environ.get('NUMBA_CACHE_DIR') or 'beside the installed modules (__pycache__)'}, "
             f"generated kernels: {kernel_cache_dir()} - a later process loads them instead of compiling"
             if args.backend == "numba" else "")
    print(f"warmed in {time.perf_counter() - t_all:.1f} s on {args.backend}{where}")
    return EXIT_OK


def _cmd_bench(args: argparse.Namespace) -> int:
    from cansim.tools.benchmark import format_tables, run_suite

    def say(line: str) -> None:
        if not args.no_progress:
            print(f"  timing {line}", file=sys.stderr, flush=True)

    out = Path(args.out)
    if out.is_dir():  # found before the timings, not after them (they were lost)
        raise InvalidInputError(f"--out {out} is a folder; give a file name, e.g. {out / 'cansim_bench.json'}")
    out.parent.mkdir(parents=True, exist_ok=True)
    if not os.access(out.parent, os.W_OK):
        raise InvalidInputError(f"--out {out}: cannot write into {out.parent}; give another file")
    asked = _names(args.backends)
    if asked is not None and not asked:
        raise InvalidInputError("--backends names no backend; give e.g. --backends numpy,numba (or leave it out: every "
                                "usable one)")
    report = run_suite(quick=args.quick, backends=asked, workloads=_names(args.workloads),
                       max_threads=args.max_threads, progress=say)
    m = report.machine
    print(f"{m['cpu']}, {m['usable_cpus']} usable CPU(s), load {m['load_average']}; cansim {m['cansim']}, "
          f"numpy {m['numpy']}, numba {m.get('numba')}, Python {m['python']} ({'quick' if report.quick else 'full'} run)")
    if m.get("numba_jit") is False:
        print("warning: NUMBA_DISABLE_JIT is set: the numba figures are interpreted Python, not compiled code")
    print(format_tables(report))
    for name, info in report.backends.items():
        if not info["usable"]:
            print(f"not timed: {name} - {info['reason']}")
    path = report.to_json(out)
    print(f"wrote {path}")
    untimed = [b for b in asked or () if not report.backends.get(b, {}).get("usable")]
    if untimed:  # asked for by name and not timed: not a success
        print(f"cansim bench: {', '.join(untimed)} asked for with --backends but not timed (above: why)", file=sys.stderr)
        return EXIT_MISSING_EXTRA
    return EXIT_OK


# ------------------------------------------------------------------ parser
class _Formatter(argparse.RawDescriptionHelpFormatter):
    pass


def _epilog() -> str:
    codes = "\n".join(f"  {code:3d}  {text}" for code, text in EXIT_CODES.items())
    return f"exit codes:\n{codes}\n\nRun 'cansim COMMAND --help' for a command's options."


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``cansim`` (all subcommands)."""
    parser = CommandParser(
        prog="cansim",
        description=textwrap.fill("cansim: continuous-attractor networks, RatSLAM and WhiskerRatSLAM - demos, thesis "
                                  "studies, parameter sweeps on Dask, ROS bag replay and the benchmark suite.", 88),
        epilog=_epilog(),
        formatter_class=_Formatter,
    )
    from cansim import __version__

    parser.add_argument("--version", action="version", version=f"cansim {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks and debug logging")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name: str, help_: str, description: str, usage: str | None = None) -> argparse.ArgumentParser:
        return sub.add_parser(name, help=help_, description=textwrap.fill(description, 88), epilog=_epilog(),
                              formatter_class=_Formatter, usage=usage)

    p = add("demo", "the main demo: WhiskerRatSLAM maps a mug (or 'demo ratslam': RatSLAM, 3-DoF)",
            "'cansim demo' (= 'cansim demo whisker'): the README's main demo - the simulated 18-whisker array explores "
            "an object (a mug by default; --object NAME or a mesh file) for two loops through the whole chain and "
            "WhiskerRatSLAM maps it; prints the map's error beside dead reckoning's and the step, writes "
            "whisker_ratslam_map.png, whisker_ratslam_experiences.png and whisker_ratslam_metrics.json. "
            "'cansim demo ratslam': RatSLAM (3-DoF) on a synthetic 5-loop route with the thesis' Ch.3 odometry noise; "
            "writes ratslam_map.png, ratslam_experience_ids*.png and ratslam_metrics.json. Options after these are "
            "passed to the demo ('python -m cansim.studies.whisker_ratslam_demo --help' lists them).",
            usage="cansim demo [-h] [--out DIR] [--seed SEED] [whisker|ratslam] [demo options]")
    p.add_argument("--out", type=Path, default=Path.cwd(), metavar="DIR", help="output folder (default: working directory)")
    p.add_argument("--seed", type=_non_negative_int, default=0, help="seed of the run (default 0)")
    p.set_defaults(func=_cmd_demo)

    p = add("sweep", "run a parameter sweep (TOML spec) on Dask",
            "Run every cell x seed of a sweep spec on dask.distributed - a local cluster of worker processes by "
            "default, or an existing cluster with --scheduler - writing each finished task to OUT/parts/ at once and "
            "OUT/results.parquet at the end. Run the same command again to resume: tasks already recorded are "
            "skipped. Spec keys: see the cansim.tools.sweep documentation.")
    p.add_argument("spec", type=Path, metavar="FILE.toml", help="sweep spec file (TOML)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR", help="output folder (default: ./<spec name>)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="address of a running Dask scheduler (overrides the spec's 'scheduler')")
    p.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                   help="worker processes of the local cluster (default: the usable CPUs)")
    p.add_argument("--retry-errors", action="store_true", help="run tasks recorded with an error again")
    p.add_argument("--verbose", action="store_true", help="show Dask's scheduler and worker log lines (quiet by default)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_sweep)

    p = add("study", "run a thesis study (ch3, ch4, ch5, ch6), the recognition benchmark or the rat-trajectory study",
            "Run one of the thesis' studies (modules of cansim.studies): "
            + "; ".join(f"{c} = {_STUDY_TITLES[c]}, {m}" for c, m in STUDIES.items())
            + ". Options after the chapter go to the study (e.g. 'cansim study ch5 --quick --objects mug box'; "
            "'python -m cansim.studies.ch5_object_maps --help' lists them).",
            usage="cansim study [-h] [--quick] [--out DIR] {ch3,ch4,ch5,ch6,recognition,rat} [study options]")
    p.add_argument("chapter", choices=list(STUDIES), help="the chapter's study")
    p.add_argument("--quick", action="store_true", help="the study's quick mode (its headline result, in minutes)")
    p.add_argument("--out", type=Path, default=Path.cwd(), metavar="DIR", help="output folder (default: working directory)")
    p.set_defaults(func=_cmd_study)

    p = add("replay", "replay a ROS1/ROS2 bag into RatSLAM (no ROS needed)",
            "Replay a ROS1 .bag (or a folder of them) or a ROS2 bag folder (sqlite3 or mcap) into RatSLAM: odometry "
            "(nav_msgs/Odometry, TwistStamped or Twist) and camera images (sensor_msgs/Image or CompressedImage) "
            "on OpenRatSLAM's topics <topic_root>/odom and <topic_root>/camera/image[/compressed]. Writes "
            "experience_map.npz, trajectory.csv and experience_map.png.")
    p.add_argument("bag", metavar="BAG_OR_DIR", help="a .bag file, a folder of .bag files, or a ROS2 bag folder")
    p.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="OpenRatSLAM config file (config_*.txt[.in]); its [general] topic_root names the topics")
    p.add_argument("--out", type=Path, default=None, metavar="DIR", help="output folder (default: ./<bag name>_replay)")
    p.add_argument("--odom-topic", default=None, help="odometry topic (default <topic_root>/odom)")
    p.add_argument("--image-topic", default=None, help="image topic (default <topic_root>/camera/image[/compressed])")
    p.add_argument("--stamps", choices=("header", "log"), default="header",
                   help="time odometry by header stamps (OpenRatSLAM, default) or by the bag's record times")
    p.add_argument("--openratslam", action="store_true",
                   help="the OpenRatSLAM preset: the C++ core's pose cells bit for bit (RatSLAMConfig.openratslam), "
                        "which refuses an odometry step of more than one cell (raise the file's cell size); "
                        "default: cansim's generic pose-cell engine with the config file's values")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_replay)

    p = add("backends", "which CAN backends run here, and why not",
            "List every registered backend (numpy, numba, opencl): usable here or why not, and what to install.")
    p.add_argument("--refresh", action="store_true", help="probe again instead of using this process' cached answer")
    p.set_defaults(func=_cmd_backends)

    p = add("warm-up", "compile the models' kernels into the disk cache now (for a CI or container image)",
            "Compile (or load) every kernel of the default RatSLAM, WhiskerRatSLAM and Population presets, so that a "
            "later process - a test run, a container built from this image - loads them from the disk cache instead "
            "of compiling for up to a minute in its first step. Configurations of other grid sizes compile their "
            "own generated kernels once, on their first use.")
    p.add_argument("--models", default=None, metavar="NAMES",
                   help=f"comma-separated, some of {', '.join(WARM_UP_TARGETS)} (default: all)")
    p.add_argument("--backend", default="numba", help="backend to warm (default numba)")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_warm_up)

    p = add("bench", "time the standard workloads on every backend",
            "The benchmark suite: a Population step on a 360 ring, 21x21x36 and 5^6 grids and a RatSLAM iteration on "
            "every usable backend (median and minimum per call), numba's scaling over 1..N threads for the large "
            "grids, and a JSON with the machine's description to compare machines.")
    p.add_argument("--quick", action="store_true", help="few short rounds (seconds); threads 1 and N only")
    p.add_argument("--out", type=Path, default=Path("cansim_bench.json"), metavar="FILE.json",
                   help="JSON output (default ./cansim_bench.json)")
    p.add_argument("--backends", default=None, help="comma-separated backends (default: every usable one)")
    p.add_argument("--workloads", default=None, help="comma-separated workloads (default: all of the mode)")
    p.add_argument("--max-threads", type=_positive_int, default=None, metavar="N",
                   help="largest thread count of the scaling runs (default: numba's maximum)")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_bench)
    return parser


def _forward_help(argv: list[str]) -> list[str]:
    """``argv`` without a ``-h`` / ``--help`` that follows a study's chapter or a demo's name (the study's or demo's
    own help is then shown, not ``cansim study``'s)."""
    at = next((i for i, a in enumerate(argv) if not a.startswith("-")), None)  # the subcommand (top options take no value)
    if at is None or argv[at] not in ("study", "demo"):
        return argv
    names = STUDIES if argv[at] == "study" else DEMOS
    rest = argv[at + 1:]
    named = next((i for i, a in enumerate(rest) if a in names), None)
    if named is None or not any(a in ("-h", "--help") for a in rest[named + 1:]):
        return argv
    return argv[:at + 1] + rest[:named + 1] + [a for a in rest[named + 1:] if a not in ("-h", "--help")]


def _int_at_least(minimum: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum`` (``what`` names it in the message)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = minimum - 1
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    return parse


_non_negative_int = _int_at_least(0, "an integer >= 0")
_positive_int = _int_at_least(1, "a positive integer")


# ------------------------------------------------------------------ main
def _classify(exc: BaseException) -> tuple[int, str]:
    if isinstance(exc, CommandError):
        return exc.code, str(exc)
    return command_line.error_status(exc)  # the classification the studies' and examples' scripts share


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``cansim`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    Usage errors raise ``SystemExit(2)`` (argparse).
    """
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    forwarded = _forward_help(argv)
    args, extra = parser.parse_known_args(forwarded)
    if len(argv) > len(forwarded):
        extra.append("--help")  # 'cansim study ch5 --help': the study's own options
    if extra and args.command not in ("demo", "study"):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.options = extra  # a demo's or study's own options, passed to its main(argv)
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.DEBUG if args.debug else logging.WARNING, format="cansim: %(levelname)s: %(message)s")
    command = args.command if args.command != "study" else f"study {args.chapter}"  # errors name the study

    def one_line_warning(message: Any, category: type, filename: str, lineno: int, file: Any = None, line: Any = None) -> None:
        print(f"cansim {command}: warning: {message}", file=sys.stderr)

    func: Callable[[argparse.Namespace], int] = args.func
    with warnings.catch_warnings():
        if not args.debug:
            warnings.showwarning = one_line_warning
        try:
            return func(args)
        except KeyboardInterrupt:
            print(f"cansim {command}: interrupted" + ("; run the same command again to resume" if command == "sweep" else ""),
                  file=sys.stderr)
            return EXIT_INTERRUPTED
        except Exception as exc:
            code, message = _classify(exc)
            if args.debug or code == EXIT_INTERNAL:
                import traceback

                traceback.print_exc()
            print(f"cansim {command}: error: {' '.join(message.split())}", file=sys.stderr)
            return code
