"""The benchmark suite as a user tool: standard CAN workloads on every usable backend.

Workloads (one call each, timed):

* ``ring360`` - one :meth:`Population.step` of a 360-cell head-direction ring;
* ``21x21x36`` - one step of OpenRatSLAM's pose cells (:meth:`Population.openratslam`);
* ``5^6`` - one step of the 6-D WhiskerRatSLAM grid (:meth:`Population.whisker6d`);
* ``ratslam`` - one :meth:`RatSLAM.step` (view id front end, 21 x 21 x 36 pose cells,
  experience map) on a synthetic loop route;
* full mode only: ``61x61x36`` and ``10^6``.

Each population step injects energy at the grid's centre and moves the packet, the
motion alternating in sign so that it stays near the injection (a robot revisiting a
place), as ``bench/test_bench_step.py`` does. A workload is first settled (and its
kernels compiled), then timed with :func:`time.perf_counter` over ``rounds`` rounds of
``steps`` calls each; the report gives the median and the minimum time per call. For the
grids of :data:`SCALING_WORKLOADS` the numba backend is also timed with every pass
parallel on 1..N threads (``numba.set_num_threads``; N = ``numba.config.NUMBA_NUM_THREADS``).
numba splits a pass over threads only when the pass has enough lines for every thread,
and the 5^6 grid runs a serial kernel generated for its shape, so where the box of cells
around the packet is small the scaling is flat: that is what it measures.

This measures; it asserts nothing. :meth:`BenchReport.to_json` writes the figures with
the machine's description so that runs on different machines can be compared.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import platform
import socket
import statistics
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cansim.errors import InvalidInputError

_LOG = logging.getLogger(__name__)

__all__ = ["WORKLOADS", "SCALING_WORKLOADS", "BenchRecord", "BenchReport", "backend_threads", "machine_info", "run_suite",
           "format_tables"]

#: Seconds of settling after which the progress says kernels are compiling (s).
COMPILE_NOTICE_S = 3.0
#: A median above this multiple of the minimum marks a row whose rounds met a stall (another job, paging).
STALL_RATIO = 3.0
#: workload name -> cells (a RatSLAM iteration: its pose cells)
WORKLOADS = {"ring360": 360, "21x21x36": 21 * 21 * 36, "5^6": 5**6, "ratslam": 21 * 21 * 36}
_FULL_ONLY = {"61x61x36": 61 * 61 * 36, "10^6": 10**6}
#: grids whose numba step is also timed on 1..N threads
SCALING_WORKLOADS = ("21x21x36", "5^6", "61x61x36", "10^6")
FORMAT = "cansim-bench/1"


@dataclass(frozen=True)
class BenchRecord:
    """Time per call of one workload on one backend.

    Attributes
    ----------
    workload, backend : str
    threads : int or None
        Threads of a numba scaling run (every pass parallel); None for the backend's default.
    cells : int
    median_us, min_us : float
        Median and minimum over the rounds of the mean time per call, microseconds.
    rounds, steps : int
        Rounds timed, calls per round.
    """

    workload: str
    backend: str
    threads: int | None
    cells: int
    median_us: float
    min_us: float
    rounds: int
    steps: int


@dataclass
class BenchReport:
    """Records of one suite run, the machine and the versions."""

    records: list[BenchRecord]
    machine: dict[str, Any]
    backends: dict[str, dict[str, Any]]
    quick: bool
    created_utc: str = field(default_factory=lambda: _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))

    def to_dict(self) -> dict[str, Any]:
        """The JSON document: ``format``, ``created_utc``, ``quick``, ``machine``, ``backends``, ``results``."""
        return {"format": FORMAT, "created_utc": self.created_utc, "quick": self.quick, "machine": self.machine,
                "backends": self.backends, "results": [asdict(r) for r in self.records]}

    def to_json(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`to_dict` to ``path`` (UTF-8, indented); returns the path."""
        from whisker_io.persistence import write_atomically

        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps(self.to_dict(), indent=2) + "\n"
        write_atomically(p, lambda fh: fh.write(text.encode("utf-8")))  # an earlier report is never half replaced
        return p


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> dict[str, Any]:
    """Host, CPU, core counts, load, OS and library versions of this machine."""
    import cansim

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 1
    info: dict[str, Any] = {
        "hostname": socket.gethostname(),
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable,
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cansim": cansim.__version__,
        "numpy": np.__version__,
    }
    try:
        import numba

        info["numba"] = numba.__version__
        info["numba_max_threads"] = int(numba.config.NUMBA_NUM_THREADS)
        info["numba_jit"] = not numba.config.DISABLE_JIT
    except ImportError:
        info["numba"] = None
    return info


def backend_threads(name: str) -> int | None:
    """Threads a backend's default runs use here: numba's current count, numpy's 1, the OpenCL CPU runtime's
    (PoCL's ``POCL_MAX_PTHREAD_COUNT`` when set, else every usable CPU); None when unknown (a backend of one's own)."""
    if name == "numpy":
        return 1
    if name == "numba":
        try:
            import numba
        except ImportError:
            return None
        return int(numba.get_num_threads())
    if name == "opencl":
        pocl = os.environ.get("POCL_MAX_PTHREAD_COUNT", "").strip()
        if pocl.isdigit() and int(pocl) > 0:
            return int(pocl)
        try:
            return len(os.sched_getaffinity(0))
        except AttributeError:
            return os.cpu_count()
    return None


# ------------------------------------------------------------------ workloads
def _population(workload: str, backend: Any) -> tuple[Any, list[dict[str, Any]]]:
    from cansim.population import Population

    if workload == "ring360":
        pop = Population.head_direction(360, backend=backend)
        v, w = np.array([0.3 * 2 * np.pi / 360]), None
    elif workload in ("21x21x36", "61x61x36"):
        pop = Population.openratslam(int(workload.split("x")[0]), 36, backend=backend)
        v, w = 0.3, 0.2 * 2 * np.pi / 36
    elif workload in ("5^6", "10^6"):
        pop = Population.whisker6d(int(workload.split("^")[0]), 0.02, backend=backend)  # 0.02 m cells: the workload as measured since 0.1
        v, w = np.array([0.003, 0.002, 0.001]), np.array([0.1, 0.05, 0.02])
    else:
        raise InvalidInputError(f"unknown workload {workload!r}; known: {', '.join([*WORKLOADS, *_FULL_ONLY])}")
    centre = tuple(n // 2 for n in pop.shape)
    injection = (np.array([np.ravel_multi_index(centre, pop.shape)], dtype=np.int64), np.array([0.1]))

    def neg(x: Any) -> Any:
        return None if x is None else -np.asarray(x, dtype=np.float64) if not np.isscalar(x) else -x

    return pop, [dict(velocity=v, omega=w, injection=injection), dict(velocity=neg(v), omega=neg(w), injection=injection)]


def _step_fn(workload: str, backend: Any) -> Callable[[], Any]:
    if workload == "ratslam":
        from cansim.models.ratslam import RatSLAM, RatSLAMConfig
        from cansim.testing.worlds import LoopRoute, make_run

        run = make_run(LoopRoute(step_m=0.05), loops=(1,) * 3, seed=0)
        name = backend if isinstance(backend, str) else backend.name
        slam = RatSLAM(RatSLAMConfig(cell_size_m=0.05, xy_cells=21, inject_energy=0.05, backend=name))
        k = [0]

        def one() -> Any:
            i = k[0] % len(run)
            k[0] += 1
            return slam.step(float(run.vtrans[i]), float(run.vrot[i]), run.dt, int(run.view_ids[i]))

        return one
    pop, moves = _population(workload, backend)
    k = [0]

    def one_step() -> Any:
        k[0] += 1
        return pop.step(**moves[k[0] & 1])

    return one_step


def _time(fn: Callable[[], Any], rounds: int, settle: int, min_round_s: float,
          compiling: Callable[[], None] | None = None) -> tuple[float, float, int]:
    timer = threading.Timer(COMPILE_NOTICE_S, compiling) if compiling is not None else None
    if timer is not None:  # a settle this long is kernels compiling (a cold cache) or a slow machine: say so meanwhile
        timer.daemon = True
        timer.start()
    try:
        for _ in range(settle):  # settle the packet and compile
            fn()
    finally:
        if timer is not None:
            timer.cancel()
            timer.join()  # a notice already under way ends before the next workload's line
    t0 = time.perf_counter()
    fn()
    once = max(time.perf_counter() - t0, 1e-7)
    steps = int(min(max(1, round(min_round_s / once)), 10_000))
    per_call = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(steps):
            fn()
        per_call.append((time.perf_counter() - t0) / steps)
    return statistics.median(per_call) * 1e6, min(per_call) * 1e6, steps


def run_suite(
    *,
    quick: bool = False,
    backends: Sequence[str] | None = None,
    workloads: Sequence[str] | None = None,
    max_threads: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> BenchReport:
    """Time the standard workloads on every usable backend (module docstring).

    Parameters
    ----------
    quick : bool
        Fewer rounds, shorter rounds, no full-mode grids, threads 1 and N only.
    backends : sequence of str, optional
        Backends to time (default: every usable one, :func:`cansim.backends.available_backends`).
    workloads : sequence of str, optional
        Workloads to time (default: all of the mode; names in :data:`WORKLOADS`, full
        mode adds ``61x61x36`` and ``10^6``).
    max_threads : int, optional
        Largest thread count of the scaling runs (default: numba's maximum).
    progress : callable, optional
        Called with a short line before each measurement.

    Returns
    -------
    BenchReport

    Raises
    ------
    InvalidInputError
        An unknown backend or workload name, or a ``max_threads`` < 1.
    """
    from cansim.backends import backend_status, get_backend, registered_backends

    status = backend_status()
    if backends is None:
        chosen = [b for b, (ok, _) in status.items() if ok]
    else:
        chosen = list(backends)
        unknown = [b for b in chosen if b not in registered_backends()]
        if unknown:
            raise InvalidInputError(f"unknown backend(s) {unknown}; registered: {', '.join(registered_backends())}")
    if max_threads is not None and (isinstance(max_threads, bool) or not isinstance(max_threads, int) or max_threads < 1):
        raise InvalidInputError(f"max_threads must be an integer >= 1, got {max_threads!r}")
    rounds, settle, min_round_s = (5, 10, 0.005) if quick else (21, 40, 0.05)
    known = {**WORKLOADS, **_FULL_ONLY}
    if workloads is None:
        chosen_w = dict(WORKLOADS) if quick else known
    else:
        bad = [w for w in workloads if w not in known]
        if bad or not workloads:
            raise InvalidInputError(f"unknown workload(s) {bad or list(workloads)}; known: {', '.join(known)}")
        chosen_w = {w: known[w] for w in workloads}
    records: list[BenchRecord] = []
    say = progress or (lambda _line: None)
    for backend in chosen:
        if not status.get(backend, (False, ""))[0]:
            continue
        for name, cells in chosen_w.items():
            slow = backend != "numba" and cells >= 10**6
            say(f"{name} on {backend}")
            med, low, steps = _time(_step_fn(name, backend), 3 if slow else rounds, 2 if slow else settle, min_round_s,
                                    lambda name=name, backend=backend: say(
                                        f"{name} on {backend}: still settling after {COMPILE_NOTICE_S:g} s - its kernels "
                                        "compiling on a cold cache (up to a minute, once: kept on disk), or a slow "
                                        "machine"))
            records.append(BenchRecord(name, backend, None, cells, med, low, 3 if slow else rounds, steps))
    if "numba" in chosen and status.get("numba", (False, ""))[0]:
        records += _scaling(chosen_w, rounds, settle, min_round_s, quick, max_threads, say, get_backend)
    backends_json = {name: {"usable": ok, "reason": why, "threads": backend_threads(name) if ok else None}
                     for name, (ok, why) in status.items()}
    return BenchReport(records=records, machine=machine_info(), backends=backends_json, quick=quick)


def _scaling(workloads: dict[str, int], rounds: int, settle: int, min_round_s: float, quick: bool,
             max_threads: int | None, say: Callable[[str], None], get_backend: Any) -> list[BenchRecord]:
    import numba

    from cansim.backends.numba_backend import NumbaBackend

    most = int(numba.config.NUMBA_NUM_THREADS)
    if max_threads is not None and max_threads > most:  # said whatever the progress lines do
        _LOG.warning("max_threads %d is more than numba's %d (NUMBA_NUM_THREADS): the scaling runs go up to %d",
                     max_threads, most, most)
    top = most if max_threads is None else min(max_threads, most)
    counts = sorted({1, top}) if quick else list(range(1, top + 1))
    before = numba.get_num_threads()
    out = []
    try:
        for name in (w for w in SCALING_WORKLOADS if w in workloads):
            for n in counts:
                numba.set_num_threads(n)
                say(f"{name} on numba, {n} thread(s)")
                fn = _step_fn(name, NumbaBackend(parallel_work=0, threads=n))
                med, low, steps = _time(fn, rounds, settle, min_round_s)
                out.append(BenchRecord(name, "numba", n, workloads[name], med, low, rounds, steps))
    finally:
        numba.set_num_threads(before)
    return out


def _fmt(us: float) -> str:
    return f"{us:,.1f}" if us < 1000 else f"{us:,.0f}"


def format_tables(report: BenchReport) -> str:
    """Plain-text tables: workloads x backends (median / min us per call), then numba thread scaling."""
    recs = [r for r in report.records if r.threads is None]
    backends = list(dict.fromkeys(r.backend for r in recs))
    workloads = list(dict.fromkeys(r.workload for r in recs))
    by = {(r.workload, r.backend): r for r in recs}

    def on(b: str) -> str:
        n = report.backends.get(b, {}).get("threads")
        return "" if n is None else f", {n} thread{'s' if n != 1 else ''}"

    head = ["workload", "cells", *[f"{b}{on(b)}: median / min (us)" for b in backends]]
    rows = []
    for w in workloads:
        cells = next(r.cells for r in recs if r.workload == w)
        rows.append([w, f"{cells:,}", *[_cell(by[w, b]) if (w, b) in by else "-" for b in backends]])
    text = [_table(head, rows)]
    if any(r.median_us > STALL_RATIO * r.min_us for r in recs):
        text.append(f"! median over {STALL_RATIO:g}x the minimum: some rounds met a stall (another job on the cores?); "
                    "the minimum is the better guide, or run again")
    scal = [r for r in report.records if r.threads is not None]
    if scal:
        threads = sorted({r.threads for r in scal if r.threads is not None})
        sby = {(r.workload, r.threads): r for r in scal}
        head = ["numba, every pass split over threads", *[f"{n} thread(s) median (us)" for n in threads],
                f"speed-up {threads[0]} -> {threads[-1]}"]
        rows = []
        for w in dict.fromkeys(r.workload for r in scal):
            meds = [sby[w, n].median_us if (w, n) in sby else float("nan") for n in threads]
            rows.append([w, *[_fmt(m) for m in meds], f"{meds[0] / meds[-1]:.2f}x"])
        text.append(_table(head, rows))
    return "\n\n".join(text)


def _cell(r: BenchRecord) -> str:
    stall = " !" if r.median_us > STALL_RATIO * r.min_us else ""
    return f"{_fmt(r.median_us)} / {_fmt(r.min_us)}{stall}"


def _table(head: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows)]
    line = lambda cells: "  ".join(str(c).ljust(w) if i == 0 else str(c).rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))  # noqa: E731
    return "\n".join([line(head), "  ".join("-" * w for w in widths), *[line(r) for r in rows]])
