"""Side by side with OpenRatSLAM's C++ core, built from the user's own checkout (issue 26 item 6).

OpenRatSLAM is not part of this repository: point the script at a checkout of its public
source (the ``davidmball/ratslam`` repository; the script needs ``src/ratslam/`` from it)
and it compiles ``bench/openratslam_cpp/driver.cpp`` - cansim's own driver, which only
calls the public ``PosecellNetwork`` and ``ExperienceMap`` classes - against the
checkout's unmodified ``posecell_network.cpp`` and ``experience_map.cpp`` with
``g++ -O2``. Boost's header-only ``property_tree`` and ``serialization`` headers are
needed (Debian/Ubuntu: ``apt-get install libboost-dev``; or ``--boost-include DIR``).

For every route and grid it writes one input sequence (per-step view id, panoramic
offset, odometry), then runs, alternately and ``--reps`` times: the C++ driver (a fresh
process; its step loop timed with ``std::chrono``, input/output excluded), cansim's
parity preset (``RatSLAMConfig.openratslam()``, the bit-identical ``PosecellNetwork``)
and the same config on the generic engine (``pose_cells="population"``), both timed
around the ``RatSLAM.step`` loop alone after an untimed warm-up run. It checks that the
C++ and parity outputs - decoded x, y, theta, experience id, counts and action per step,
final experience poses and links - are bit-identical, and prints the ratios
C++ time / cansim time (> 1: cansim faster) as the median of the per-repetition ratios,
with the load average, both commits and the compiler.

Routes:

``trace``
    the inputs of ``tests/data/openratslam_cpp_trace.csv`` (300 steps, 21x21x36, 0.25 m
    cells); the C++ output is also checked against the stored trace.
``circle``
    a single-packet route: a 3 m radius circle at 0.3 m/s with noisy odometry, the view
    being the circle's 32nd the robot is in (10 % of the steps without a view).
``walk``
    a several-packet route: a random walk on a 12 m x 12 m torus, the view being the
    2 m x 2 m tile the robot stands on; the torus wraps but the pose cells do not, so
    revisited tiles inject away from the packet and several packets live at once.

Usage (from the repository's root)::

    python bench/cpp_compare.py --openratslam ~/src/ratslam [--steps 2000] [--grid 21 --grid 61]
        [--reps 3] [--routes trace,circle,walk] [--seed 0] [--json out.json]

``--openratslam`` defaults to the ``CANSIM_OPENRATSLAM_SRC`` environment variable. Exit
status 0 when every parity check passed, 1 when one failed, 2 when the build could not be
made (the message says what to install or pass).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's cansim, not an installed one

DRIVER = ROOT / "bench" / "openratslam_cpp" / "driver.cpp"
TRACE = ROOT / "tests" / "data" / "openratslam_cpp_trace.csv"
CPP_FILES = (
    "src/ratslam/posecell_network.cpp", "src/ratslam/posecell_network.h",
    "src/ratslam/experience_map.cpp", "src/ratslam/experience_map.h", "src/utils/utils.h",
)
BOOST_HEADERS = ("boost/property_tree/ini_parser.hpp", "boost/serialization/vector.hpp")
BOOST_HELP = (
    "Boost headers not found (OpenRatSLAM's classes include boost/property_tree and "
    "boost/serialization; header-only, nothing to link). Install them - Debian/Ubuntu: "
    "`apt-get install libboost-dev`; Fedora: `dnf install boost-devel`; macOS: "
    "`brew install boost` - or pass --boost-include DIR, the folder that holds boost/."
)
# One step's input: has_vt, vt_id, vt_rad, vtrans (m/s), vrot (rad/s), dt (s).
StepInput = tuple[int, int, float, float, float, float]


class HarnessError(RuntimeError):
    """The comparison cannot run (no checkout, no compiler, no Boost, a failed build); the message says what to do."""


# ----------------------------------------------------------------------------- the build
def check_checkout(path: str | os.PathLike[str] | None) -> Path:
    """The checkout's root, after checking it holds the C++ files the driver compiles."""
    if not path:
        raise HarnessError(
            "no OpenRatSLAM checkout given: pass --openratslam PATH or set CANSIM_OPENRATSLAM_SRC "
            "to a clone of the public davidmball/ratslam repository")
    root = Path(path).expanduser().resolve()
    if not root.is_dir():
        raise HarnessError(f"OpenRatSLAM checkout {root} does not exist (clone davidmball/ratslam there)")
    missing = [f for f in CPP_FILES if not (root / f).is_file()]
    if missing:
        raise HarnessError(
            f"{root} is not an OpenRatSLAM checkout: missing {', '.join(missing)} "
            "(point --openratslam at the root of a davidmball/ratslam clone)")
    return root


def find_boost(boost_include: str | os.PathLike[str] | None = None) -> Path | None:
    """The include folder holding the Boost headers OpenRatSLAM needs, or None for the compiler's default.

    Raises HarnessError (what to install) when neither the given folder nor a usual one has them.
    """
    if boost_include is not None:
        d = Path(boost_include).expanduser()
        if all((d / h).is_file() for h in BOOST_HEADERS):
            return d.resolve()
        raise HarnessError(f"--boost-include {d}: no {BOOST_HEADERS[0]} there. " + BOOST_HELP)
    for d in ("/usr/include", "/usr/local/include", "/opt/homebrew/include", "/opt/local/include"):
        if all((Path(d) / h).is_file() for h in BOOST_HEADERS):
            return None if d == "/usr/include" else Path(d)
    raise HarnessError(BOOST_HELP)


def compile_driver(checkout: Path, build_dir: Path, boost_include: Path | None = None, cxx: str = "g++") -> Path:
    """Compile the driver against the checkout (``cxx -O2``); reuses a binary built from the same sources."""
    if shutil.which(cxx) is None:
        raise HarnessError(f"C++ compiler {cxx!r} not found: install g++ (Debian/Ubuntu: apt-get install g++) or pass --cxx")
    sources = [DRIVER, checkout / CPP_FILES[0], checkout / CPP_FILES[2]]
    cmd = [cxx, "-O2", "-w", "-I", str(checkout / "src")]
    if boost_include is not None:
        cmd += ["-isystem", str(boost_include)]
    digest = hashlib.sha256(" ".join(cmd[:2]).encode())
    for f in sources + [checkout / f for f in CPP_FILES]:
        digest.update(f.read_bytes())
    build_dir.mkdir(parents=True, exist_ok=True)
    binary = build_dir / f"openratslam_driver_{digest.hexdigest()[:12]}"
    if binary.is_file():
        return binary
    proc = subprocess.run(cmd + [str(s) for s in sources] + ["-o", str(binary)], capture_output=True, text=True)
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-15:])
        hint = ("\n" + BOOST_HELP) if "boost/" in proc.stderr and "No such file" in proc.stderr else ""
        raise HarnessError(f"compiling the driver failed ({' '.join(cmd)} ...):\n{tail}{hint}")
    return binary


def settings_ini(xy_cells: int, heading_cells: int, cell_size_m: float) -> str:
    """OpenRatSLAM's config text (``[ratslam]`` section) of the parity preset for one grid.

    Written by the project's adapter from ``RatSLAMConfig.openratslam()`` (every key, so the
    C++ prints no "not found" warnings and runs the same model the parity preset does).
    """
    from cansim.models.openratslam_config import write_openratslam_text
    from cansim.models.ratslam_config import RatSLAMConfig

    return write_openratslam_text(RatSLAMConfig.openratslam(xy_cells=xy_cells, heading_cells=heading_cells,
                                                            cell_size_m=cell_size_m))


# ----------------------------------------------------------------------------- the routes
def trace_inputs(path: Path = TRACE) -> list[StepInput]:
    """The per-step inputs of the stored C++ trace (or any file in its format)."""
    rows: list[StepInput] = []
    with open(path, encoding="ascii") as fh:
        for line in fh:
            f = line.rstrip("\n").split(",")
            if f[0] == "S":
                hx = float.fromhex
                rows.append((int(f[1]), int(f[2]), hx(f[3]), hx(f[4]), hx(f[5]), hx(f[6])))
    return rows


class _FirstSeen:
    """Numbers views in first-seen order, as OpenRatSLAM's local view cells do."""

    def __init__(self) -> None:
        self.ids: dict[int, int] = {}

    def __call__(self, place: int) -> int:
        return self.ids.setdefault(place, len(self.ids))


def circle_inputs(steps: int, seed: int, *, radius_m: float = 3.0, speed_m_s: float = 0.3,
                  segments: int = 32, view_rate: float = 0.9) -> list[StepInput]:
    """Single-packet route: laps of a circle, noisy odometry, the view = the segment the robot is in."""
    rng = np.random.default_rng(seed)
    number = _FirstSeen()
    rows: list[StepInput] = []
    angle = 0.0  # position on the circle, rad
    for _ in range(steps):
        dt = float(rng.uniform(0.9, 1.1))
        true_w = speed_m_s / radius_m
        angle = (angle + true_w * dt) % (2 * math.pi)
        vtrans = speed_m_s * (1.0 + float(rng.normal(0.0, 0.05)))
        vrot = true_w + float(rng.normal(0.0, 0.02))
        if rng.random() < view_rate:
            rows.append((1, number(int(angle / (2 * math.pi) * segments) % segments), 0.0, vtrans, vrot, dt))
        else:
            rows.append((0, 0, 0.0, vtrans, vrot, dt))
    return rows


def walk_inputs(steps: int, seed: int, *, room_m: float = 12.0, tile_m: float = 2.0,
                speed_m_s: float = 0.3) -> list[StepInput]:
    """Several-packet route: a random walk on a torus, the view = the tile the robot stands on."""
    rng = np.random.default_rng(seed)
    number = _FirstSeen()
    tiles = int(room_m // tile_m)
    rows: list[StepInput] = []
    x = y = room_m / 2
    th = 0.0
    for _ in range(steps):
        w = float(rng.normal(0.0, 0.4))
        th += w
        x = (x + speed_m_s * math.cos(th)) % room_m
        y = (y + speed_m_s * math.sin(th)) % room_m
        rows.append((1, number(int(x // tile_m) * tiles + int(y // tile_m)), 0.0, speed_m_s, w, 1.0))
    return rows


def write_inputs(path: Path, rows: Sequence[StepInput]) -> None:
    """Write inputs in the trace's format (its first seven columns)."""
    with open(path, "w", encoding="ascii") as fh:
        fh.write("kind,has_vt,vt_id,vt_rad,vtrans,vrot,dt\n")
        for has_vt, vid, rad, v, w, dt in rows:
            fh.write(f"S,{has_vt},{vid if has_vt else 0},{rad.hex()},{v.hex()},{w.hex()},{dt.hex()}\n")


# ----------------------------------------------------------------------------- running
@dataclass
class RunOutput:
    """What one run produced: per-step ``best`` (n, 3) float64 and ``counts`` (n, 4) int64
    (exp_id, n_exp, n_links, action); final experience ``poses`` (m, 3) and ``links`` (k, 6:
    from, to, d, heading, facing, dt)."""

    best: np.ndarray
    counts: np.ndarray
    poses: np.ndarray
    links: np.ndarray


def read_output(path: Path) -> RunOutput:
    """Parse a file in the trace's format (the driver's output or the stored trace)."""
    best, counts, poses, links = [], [], [], []
    hx = float.fromhex
    with open(path, encoding="ascii") as fh:
        for line in fh:
            f = line.rstrip("\n").split(",")
            if f[0] == "S":
                best.append([hx(v) for v in f[7:10]])
                counts.append([int(v) for v in f[10:14]])
            elif f[0] == "E":
                poses.append([hx(v) for v in f[1:4]])
            elif f[0] == "L":
                links.append([float(int(f[1])), float(int(f[2]))] + [hx(v) for v in f[3:7]])
    return RunOutput(np.array(best, dtype=np.float64).reshape(-1, 3), np.array(counts, dtype=np.int64).reshape(-1, 4),
                     np.array(poses, dtype=np.float64).reshape(-1, 3), np.array(links, dtype=np.float64).reshape(-1, 6))


def first_difference(a: RunOutput, b: RunOutput) -> str | None:
    """None when the two runs are bit-identical (float bit patterns compared), else where they first differ."""
    for name in ("best", "counts", "poses", "links"):
        x, y = getattr(a, name), getattr(b, name)
        if x.shape != y.shape:
            return f"{name}: shape {x.shape} != {y.shape}"
        same = x.view(np.uint64) == y.view(np.uint64) if x.dtype == np.float64 else x == y
        bad = np.flatnonzero(~same.all(axis=1))
        if bad.size:
            i = int(bad[0])
            return f"{name} row {i}: {x[i].tolist()} != {y[i].tolist()}"
    return None


def run_cpp(binary: Path, ini: Path, inputs: Path, output: Path) -> tuple[float, RunOutput]:
    """One fresh C++ process; returns its step-loop time (s) and its outputs."""
    proc = subprocess.run([str(binary), str(ini), str(inputs), str(output)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise HarnessError(f"the C++ driver failed ({proc.returncode}): {proc.stderr.strip()}")
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("loop_s ")), None)
    if line is None:
        raise HarnessError(f"the C++ driver printed no timing line: {proc.stdout[-500:]!r}")
    return float(line.split()[1]), read_output(output)


def run_cansim(rows: Sequence[StepInput], xy_cells: int, heading_cells: int, cell_size_m: float,
               engine: str) -> tuple[float, RunOutput]:
    """One cansim run (``RatSLAMConfig.openratslam``, ``pose_cells=engine``); the step loop alone is timed."""
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig

    slam = RatSLAM(RatSLAMConfig.openratslam(xy_cells=xy_cells, heading_cells=heading_cells,
                                             cell_size_m=cell_size_m, pose_cells=engine))
    em = slam.experience_map
    args = [(v, w, dt, (vid, rad) if has_vt else None) for has_vt, vid, rad, v, w, dt in rows]
    best = np.empty((len(rows), 3))
    counts = np.empty((len(rows), 4), dtype=np.int64)
    t0 = time.perf_counter()
    for k, (v, w, dt, obs) in enumerate(args):
        s = slam.step(v, w, dt, obs)
        best[k] = s.best_pc
        counts[k] = (s.exp_id, em.n_experiences, em.n_links, int(s.action))
    loop_s = time.perf_counter() - t0
    ends, data = em.links
    links = np.concatenate([ends.astype(np.float64), data], axis=1) if len(ends) else np.empty((0, 6))
    return loop_s, RunOutput(best, counts, em.poses, links)


@dataclass
class Case:
    """One route on one grid."""

    route: str
    xy_cells: int
    rows: list[StepInput]
    heading_cells: int = 36
    cell_size_m: float = 1.0
    times_s: dict[str, list[float]] = field(default_factory=lambda: {"cpp": [], "parity": [], "generic": []})
    parity_identical: bool = True
    parity_difference: str | None = None
    trace_identical: bool | None = None
    experiences: dict[str, int] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return f"{self.route} {self.xy_cells}x{self.xy_cells}x{self.heading_cells} ({len(self.rows)} steps)"

    def ratios(self, engine: str) -> list[float]:
        """C++ time / cansim time per repetition (> 1: cansim faster)."""
        return [c / p for c, p in zip(self.times_s["cpp"], self.times_s[engine])]


def build_cases(routes: Sequence[str], grids: Sequence[int], steps: int, seed: int) -> list[Case]:
    """The input sequences: the trace once (its own grid), each generated route on each grid."""
    cases = []
    for route in routes:
        if route == "trace":
            cases.append(Case("trace", 21, trace_inputs(), cell_size_m=0.25))
        elif route == "circle":
            cases += [Case("circle", g, circle_inputs(steps, seed)) for g in grids]
        elif route == "walk":
            cases += [Case("walk", g, walk_inputs(steps, seed)) for g in grids]
        else:
            raise HarnessError(f"unknown route {route!r}: use trace, circle or walk")
    return cases


def measure(case: Case, binary: Path, work: Path, reps: int, log=print) -> Case:
    """Run C++, parity and generic alternately ``reps`` times on one case; check parity every time."""
    tag = f"{case.route}_{case.xy_cells}"
    ini, inp, out = work / f"{tag}.ini", work / f"{tag}_in.csv", work / f"{tag}_out.csv"
    ini.write_text(settings_ini(case.xy_cells, case.heading_cells, case.cell_size_m), encoding="ascii")
    write_inputs(inp, case.rows)
    grid = (case.xy_cells, case.heading_cells, case.cell_size_m)
    warm = case.rows[: min(len(case.rows), 100)]
    for engine in ("openratslam", "population"):  # compile / load the kernels, untimed
        run_cansim(warm, *grid, engine)
    for r in range(reps):
        t_cpp, cpp = run_cpp(binary, ini, inp, out)
        t_par, par = run_cansim(case.rows, *grid, "openratslam")
        t_gen, gen = run_cansim(case.rows, *grid, "population")
        case.times_s["cpp"].append(t_cpp)
        case.times_s["parity"].append(t_par)
        case.times_s["generic"].append(t_gen)
        diff = first_difference(cpp, par)
        if diff is not None and case.parity_identical:
            case.parity_identical, case.parity_difference = False, diff
        if case.route == "trace" and r == 0:
            case.trace_identical = first_difference(cpp, read_output(TRACE)) is None
        case.experiences = {"cpp": len(cpp.poses), "parity": len(par.poses), "generic": len(gen.poses)}
        log(f"  {case.name} rep {r + 1}/{reps}: C++ {t_cpp * 1e3:.1f} ms, parity {t_par * 1e3:.1f} ms, "
            f"generic {t_gen * 1e3:.1f} ms{'' if diff is None else '  PARITY MISMATCH: ' + diff}")
    return case


# ----------------------------------------------------------------------------- reporting
def _git(args: Sequence[str], cwd: Path) -> str | None:
    try:
        p = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return p.stdout.strip() if p.returncode == 0 else None


def commit_of(path: Path) -> str:
    """Short commit of a git checkout, '-dirty' when tracked files are modified; 'unknown' outside git."""
    head = _git(["rev-parse", "--short", "HEAD"], path)
    if head is None:
        return "unknown (not a git checkout)"
    dirty = _git(["status", "--porcelain", "--untracked-files=no"], path)
    return head + ("-dirty" if dirty else "")


def table(cases: Sequence[Case]) -> str:
    """Markdown table: per case the C++ ms/step and the median paired ratios."""
    lines = ["| route, grid | C++ ms/step (median) | parity preset: C++ / cansim | generic engine: C++ / cansim "
             "| bit-identical | experiences (C++ / generic) |", "|---|---|---|---|---|---|"]
    for c in cases:
        n = len(c.rows)
        same = "yes" if c.parity_identical else f"NO ({c.parity_difference})"
        if c.trace_identical is not None:
            same += ", = stored trace" if c.trace_identical else ", DIFFERS from the stored trace"
        lines.append(
            f"| {c.name} | {statistics.median(c.times_s['cpp']) / n * 1e3:.3f} "
            f"| {statistics.median(c.ratios('parity')):.2f}x | {statistics.median(c.ratios('generic')):.2f}x "
            f"| {same} | {c.experiences.get('cpp')} / {c.experiences.get('generic')} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--openratslam", default=os.environ.get("CANSIM_OPENRATSLAM_SRC"),
                    help="root of a davidmball/ratslam checkout (default: $CANSIM_OPENRATSLAM_SRC)")
    ap.add_argument("--steps", type=int, default=2000, help="steps of the generated routes (default 2000)")
    ap.add_argument("--grid", type=int, action="append", choices=(21, 61),
                    help="xy cells of the generated routes, repeatable (default: 21 and 61)")
    ap.add_argument("--reps", type=int, default=3, help="alternating repetitions (default 3)")
    ap.add_argument("--routes", default="trace,circle,walk", help="comma-separated: trace, circle, walk")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generated routes")
    ap.add_argument("--boost-include", help="folder holding boost/ (default: the usual include folders)")
    ap.add_argument("--cxx", default="g++", help="C++ compiler (default g++)")
    ap.add_argument("--build-dir", help="where the driver binary and inputs go (default: a temporary folder)")
    ap.add_argument("--json", help="also write every time, ratio and the metadata to this file")
    a = ap.parse_args(argv)
    if a.steps < 1 or a.reps < 1:
        ap.error("--steps and --reps must be >= 1")
    grids = a.grid or [21, 61]
    log = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    routes = [r.strip() for r in a.routes.split(",") if r.strip()]
    unknown = [r for r in routes if r not in ("trace", "circle", "walk")]
    if unknown or not routes:  # before the checkout, Boost and the compiler are looked for
        ap.error(f"--routes {a.routes!r}: use trace, circle and/or walk")
    if routes == ["trace"] and (a.grid or a.steps != ap.get_default("steps")):
        log("--grid and --steps apply to the generated routes (circle, walk); the trace is fixed: 300 steps, 21x21x36")
    try:
        checkout = check_checkout(a.openratslam)
        boost = find_boost(a.boost_include)
        cases = build_cases(routes, grids, a.steps, a.seed)
        with tempfile.TemporaryDirectory(prefix="cansim_cpp_") as tmp:
            work = Path(a.build_dir) if a.build_dir else Path(tmp)
            log(f"compiling the driver against {checkout} ...")
            binary = compile_driver(checkout, work, boost, a.cxx)
            load_before = os.getloadavg()
            for case in cases:
                measure(case, binary, work, a.reps, log)
            load_after = os.getloadavg()
    except HarnessError as e:
        print(f"cpp_compare: {e}", file=sys.stderr)
        return 2
    cxx_version = subprocess.run([a.cxx, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    meta = {
        "date_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M"),
        "cansim_commit": commit_of(ROOT), "openratslam_commit": commit_of(checkout),
        "compiler": f"{cxx_version}, -O2", "machine": f"{platform.machine()}, {os.cpu_count()} cores",
        "load_1_5_15_before": [round(v, 2) for v in load_before], "load_1_5_15_after": [round(v, 2) for v in load_after],
        "command": "python bench/cpp_compare.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "reps": a.reps, "seed": a.seed,
    }
    print(table(cases))
    print(f"\nratio = C++ step-loop time / cansim step-loop time, median of {a.reps} paired repetitions "
          f"(> 1: cansim faster). cansim {meta['cansim_commit']}, OpenRatSLAM {meta['openratslam_commit']}, "
          f"{meta['compiler']}, {meta['machine']}, load average (1/5/15 min) {meta['load_1_5_15_before']} before, "
          f"{meta['load_1_5_15_after']} after, {meta['date_utc']} UTC.")
    if a.json:
        out = {"meta": meta, "cases": [
            {"route": c.route, "xy_cells": c.xy_cells, "heading_cells": c.heading_cells, "cell_size_m": c.cell_size_m,
             "steps": len(c.rows), "times_s": c.times_s, "ratio_parity": statistics.median(c.ratios("parity")),
             "ratio_generic": statistics.median(c.ratios("generic")), "parity_identical": c.parity_identical,
             "parity_difference": c.parity_difference, "trace_identical": c.trace_identical,
             "experiences": c.experiences} for c in cases]}
        Path(a.json).write_text(json.dumps(out, indent=1), encoding="utf-8")
    ok = all(c.parity_identical and c.trace_identical is not False for c in cases)
    if not ok:
        print("PARITY CHECK FAILED: see the table", file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
