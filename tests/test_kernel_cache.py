"""Generated kernels cached on disk (cansim.backends.kernel_cache) and the models' warm-up.

Compilations are counted with numba's compile events (a compile event fires only when a
function is compiled, not when it is loaded from the cache), never timed.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from cansim.backends import kernel_cache
from cansim.backends.kernel_cache import cached_module, module_key

ROOT = Path(__file__).resolve().parents[1]

#: a generated module in the style of cansim.backends._numba_small: one cached numba function
SOURCE = textwrap.dedent("""\
    from numba import njit

    @njit(cache=True)
    def triple_plus(x, k):
        return 3 * x + k
    """)


def _run(script: str, env_extra: dict) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT), **env_extra)
    out = subprocess.run([sys.executable, "-c", script], env=env, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()[-1]


#: counts compilations of functions of generated modules, then builds a 3x3 population's small-grid step
COUNTING_SCRIPT = textwrap.dedent("""\
    from numba.core import event
    count = [0]
    class Count(event.Listener):
        def on_start(self, ev):
            pass
        def on_end(self, ev):
            if ev.data["dispatcher"].py_func.__module__.startswith("_cansim_kernels"):
                count[0] += 1
    event.register("numba:compile", Count())
    import numpy as np
    from cansim.axes import Axis
    from cansim.population import Population
    p = Population([Axis.linear("x", 3, 1.0), Axis.linear("y", 3, 1.0)], backend="numba")
    p.step(np.array([0.3, 0.0]))
    print(count[0], repr(p.activity.tobytes().hex()))
    """)


@pytest.mark.slow  # subprocesses that compile (fast loop <= 4 min)
def test_second_process_compiles_no_generated_kernel(tmp_path):
    """The first process compiles the generated small-grid step; the second loads it: no compilation."""
    env = {"CANSIM_KERNEL_CACHE": str(tmp_path / "kernels")}
    first = _run(COUNTING_SCRIPT, env).split()
    second = _run(COUNTING_SCRIPT, env).split()
    assert int(first[0]) > 0  # a cold folder: the generated step and its passes compile
    assert int(second[0]) == 0
    assert first[1] == second[1]  # the loaded kernel gives the same activity, bit for bit
    files = list((tmp_path / "kernels").glob("small_3x3_*.py"))
    assert len(files) == 1 and "def step(" in files[0].read_text()


def test_cached_module_is_written_once_and_reused(tmp_path):
    m1 = cached_module(SOURCE, "demo", folder=tmp_path)
    assert m1 is not None and m1.triple_plus(2, 1) == 7
    path = tmp_path / f"demo_{module_key(SOURCE)}.py"
    assert path.read_text() == SOURCE
    assert path.stat().st_mode & 0o444 == 0o444  # readable by every user of a shared cache folder
    stamp = path.stat().st_mtime_ns
    assert cached_module(SOURCE, "demo", folder=tmp_path) is m1
    assert path.stat().st_mtime_ns == stamp  # an intact file is never rewritten (numba's index stamp stays valid)
    assert not list(tmp_path.glob("*.tmp"))


def test_key_depends_on_source_and_dependencies(tmp_path):
    dep = tmp_path / "dep.py"
    dep.write_text("a = 1\n")
    k1 = module_key(SOURCE, [dep])
    dep.write_text("a = 2\n")
    assert module_key(SOURCE, [dep]) != k1  # an edited dependency: a new file, a fresh compilation
    assert module_key(SOURCE + "\n") != module_key(SOURCE)


@pytest.mark.parametrize("garbage", [b"", b"from numba import njit\n\n@njit(cache=True)\ndef triple_plus(x", b"\x00\xff\xfe"])
def test_corrupt_module_is_replaced_and_recompiled(tmp_path, garbage):
    path = tmp_path / f"demo_{module_key(SOURCE)}.py"
    path.write_bytes(garbage)
    m = cached_module(SOURCE, "demo", folder=tmp_path)
    assert m is not None and m.triple_plus(5, -1) == 14
    assert path.read_text() == SOURCE


def test_competing_writer_keeps_the_first_copy(tmp_path, monkeypatch):
    """Two processes at once: the other one's link lands first; ours fails and its copy is kept."""
    path = tmp_path / f"demo_{module_key(SOURCE)}.py"
    real_link = os.link
    calls = []

    def link_after_competitor(src, dst):
        calls.append(dst)
        Path(dst).write_text(SOURCE)  # the competitor's complete copy appears first
        return real_link(src, dst)

    monkeypatch.setattr(kernel_cache.os, "link", link_after_competitor)
    m = cached_module(SOURCE, "demo", folder=tmp_path)
    assert calls and m is not None and m.triple_plus(1, 1) == 4
    assert path.read_text() == SOURCE
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == [path.name]  # no temporary file left


def test_concurrent_processes_write_one_intact_module(tmp_path):
    """Four processes write and import the same module at once: each imports it, one file, no leftovers."""
    script = textwrap.dedent(f"""\
        import sys
        from cansim.backends.kernel_cache import cached_module
        m = cached_module({SOURCE!r}, "race", folder=sys.argv[1])
        print(m.triple_plus(1, 2) if m is not None else "none")
        """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = [subprocess.Popen([sys.executable, "-c", script, str(tmp_path)], env=env, cwd=ROOT, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(4)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [o[0].strip() for o in outs] == ["5"] * 4, [o[1] for o in outs]
    files = [p.name for p in tmp_path.iterdir() if p.is_file()]
    assert files == [f"race_{module_key(SOURCE)}.py"]
    assert (tmp_path / files[0]).read_text() == SOURCE


def test_unwritable_folder_falls_back_with_one_warning(tmp_path, monkeypatch, caplog):
    """A read-only folder (writing fails) and a folder that cannot exist (a file is in the way)."""
    monkeypatch.setattr(kernel_cache, "_WARNED", set())

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(kernel_cache.tempfile, "mkstemp", refuse)
    with caplog.at_level(logging.WARNING, logger=kernel_cache.__name__):
        assert cached_module(SOURCE, "demo", folder=tmp_path) is None
        assert cached_module(SOURCE + "#\n", "demo", folder=tmp_path) is None
    assert len(caplog.records) == 1 and "in memory" in caplog.records[0].getMessage()
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert cached_module(SOURCE, "demo", folder=blocker / "kernels") is None


@pytest.mark.slow  # subprocesses that compile (fast loop <= 4 min)
def test_small_grid_step_works_without_a_cache_folder(tmp_path, monkeypatch, caplog):
    """No usable kernel cache: the generated step compiles in memory and gives the cached step's result."""
    from cansim.axes import Axis
    from cansim.backends import _numba_small
    from cansim.backends.numba_backend import NumbaBackend
    from cansim.population import Population

    def step(backend):
        p = Population([Axis.linear("x", 4, 1.0), Axis.linear("y", 4, 1.0)], backend=backend)
        p.activity = np.random.default_rng(5).random(p.shape).astype(p.dtype)
        p.step(np.array([0.3, -0.2]))
        return p.activity.tobytes()

    cached = step(NumbaBackend())
    blocker = tmp_path / "file"
    blocker.write_text("a file where the folder should be")
    monkeypatch.setenv("CANSIM_KERNEL_CACHE", str(blocker / "kernels"))
    monkeypatch.setattr(kernel_cache, "_WARNED", set())
    monkeypatch.setattr(_numba_small, "_STEPS", {})  # this process builds the kernels again
    with caplog.at_level(logging.WARNING, logger=kernel_cache.__name__):
        assert step(NumbaBackend()) == cached
    assert any("in memory" in r.getMessage() for r in caplog.records)
    assert all(ns["__name__"] == "_cansim_kernels_in_memory" for ns in _numba_small._STEPS.values())


# ------------------------------------------------------------------------ warm-up
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), vx=st.floats(-0.9, 0.9), run=st.booleans())
def test_population_warm_up_leaves_the_population_unchanged(seed, vx, run):
    from cansim.axes import Axis
    from cansim.population import Population

    p = Population([Axis.linear("x", 3, 1.0), Axis.linear("y", 3, 1.0)], backend="numba")
    rng = np.random.default_rng(seed)
    p.activity = rng.random(p.shape).astype(p.dtype)
    before = p.activity.copy()
    took = p.warm_up(np.array([vx, 0.0]), run=run)
    assert took >= 0.0
    assert p.activity.tobytes() == before.tobytes()
    q = Population([Axis.linear("x", 3, 1.0), Axis.linear("y", 3, 1.0)], backend="numba")
    q.activity = before
    assert p.step(np.array([vx, 0.0])).tobytes() == q.step(np.array([vx, 0.0])).tobytes()


def _whisk_loop(slam, n=14, seed=3):
    from maps.odometry import SpatialOdometry

    rng = np.random.default_rng(seed)
    states = []
    for k in range(n):
        pfh = rng.dirichlet(np.ones(slam.config.frontend.n_bins))
        sda = rng.normal(0, 1, slam.config.frontend.n_whiskers)
        odo = SpatialOdometry(rng.normal(0, 0.02, 3), rng.normal(0, 0.1, 3), 1.0)
        states.append(slam.step(odo, (pfh, sda) if k % 5 else None))
    return states


def test_whisker_ratslam_warm_up_does_not_change_the_run():
    """The warm-up runs on a scratch model: the states equal those of a model that never warmed up."""
    from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig

    cfg = WhiskerRatSLAMConfig.mapping(cell_size_m=0.05)
    warm, cold = WhiskerRatSLAM(cfg), WhiskerRatSLAM(cfg)
    assert warm.warm_up() >= 0.0
    cold._warm = True  # skip the automatic warm-up of the first step
    a, b = _whisk_loop(warm), _whisk_loop(cold)
    assert [(s.exp_id, s.relocalised, tuple(s.best_pc)) for s in a] == [(s.exp_id, s.relocalised, tuple(s.best_pc)) for s in b]
    assert np.array_equal(warm.object_map.poses, cold.object_map.poses)
    assert warm.pose_cells.activity.tobytes() == cold.pose_cells.activity.tobytes()


def test_first_step_warms_up_once(monkeypatch):
    from cansim.models import warm_up as wu
    from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig

    calls = []
    real = wu.warm_up_whisker
    monkeypatch.setattr(wu, "warm_up_whisker", lambda m, **kw: calls.append(m) or real(m, **kw))
    slam = WhiskerRatSLAM(WhiskerRatSLAMConfig.mapping(cell_size_m=0.05))
    _whisk_loop(slam, n=3)
    assert calls == [slam]


@pytest.mark.parametrize("frontend", ["ids", "camera", "tactile"])
def test_ratslam_warm_up_does_not_change_the_run(frontend):
    """RatSLAM's warm-up (explicit, or by the first step with its observation) runs on a scratch model:
    the states equal those of a model that never warmed up."""
    from cansim import RatSLAM
    from cansim.frontends.tactile import TactileTemplateConfig
    from cansim.frontends.visual import VisualTemplateConfig

    rng = np.random.default_rng(3)
    kw = dict(xy_cells=11, heading_cells=12, cell_size_m=0.1)
    if frontend == "camera":
        kw["frontend"] = VisualTemplateConfig(template_width_blocks=12, template_height_blocks=4, shift_match_blocks=3)
        views = [rng.integers(0, 256, (24, 60)).astype(np.uint8) for _ in range(5)]
    elif frontend == "tactile":
        kw["frontend"] = TactileTemplateConfig()
        views = [rng.integers(0, 256, (3, 6)).astype(np.uint8) for _ in range(5)]
    else:
        views = list(range(5))
    explicit, first_step, cold = RatSLAM(**kw), RatSLAM(**kw), RatSLAM(**kw)
    assert explicit.warm_up(views[0]) >= 0.0
    cold._warm = True  # skip the automatic warm-up of the first step

    def loop(slam):
        return [slam.step(0.05, 0.3, 1.0, None if k % 4 == 3 else views[k % 5]) for k in range(24)]

    a, b, c = loop(explicit), loop(first_step), loop(cold)
    key = [(s.exp_id, s.relocalised, tuple(s.best_pc)) for s in c]
    assert [(s.exp_id, s.relocalised, tuple(s.best_pc)) for s in a] == key
    assert [(s.exp_id, s.relocalised, tuple(s.best_pc)) for s in b] == key
    assert first_step._warm and np.array_equal(first_step.experience_map.poses, cold.experience_map.poses)


def test_ratslam_first_step_run_or_view_warms_up_once_with_the_first_observation(monkeypatch):
    from cansim import RatSLAM
    from cansim.models import warm_up as wu

    calls = []
    real = wu.warm_up_ratslam
    monkeypatch.setattr(wu, "warm_up_ratslam", lambda m, obs=None, **kw: calls.append((m, obs)) or real(m, obs, **kw))
    slam = RatSLAM(xy_cells=11, heading_cells=12, cell_size_m=0.1)
    for k in range(3):
        slam.step(0.05, 0.1, 1.0, 7 + k)
    ran = RatSLAM(xy_cells=11, heading_cells=12, cell_size_m=0.1)
    ran.run([0.05] * 3, [0.1] * 3, 1.0, [None, 4, 5])
    replayed = RatSLAM(xy_cells=11, heading_cells=12, cell_size_m=0.1)  # bag replay: on_view / on_odo calls
    replayed.on_view(9)
    replayed.on_odo(0.05, 0.1, 1.0)
    replayed.on_view(3)
    assert calls == [(slam, 7), (ran, 4), (replayed, 9)]


#: script prelude: counts numba compilations in ``count[0]``
COMPILE_COUNTER = textwrap.dedent("""\
    from numba.core import event
    count = [0]
    class Count(event.Listener):
        def on_start(self, ev):
            pass
        def on_end(self, ev):
            count[0] += 1
    event.register("numba:compile", Count())
    """)


RATSLAM_WARM_SCRIPT = COMPILE_COUNTER + textwrap.dedent("""\
    import numpy as np
    from cansim import RatSLAM
    from cansim.frontends.visual import VisualTemplateConfig
    slam = RatSLAM(xy_cells=15, heading_cells=18, cell_size_m=0.1, backend="numba",
                   frontend=VisualTemplateConfig(template_width_blocks=12, template_height_blocks=4, shift_match_blocks=3))
    rng = np.random.default_rng(7)
    images = [rng.integers(0, 256, (24, 60)).astype(np.uint8) for _ in range(6)]
    slam.warm_up(images[0])
    before = count[0]
    for k in range(40):
        slam.step(0.08, 0.4, 1.0, None if k % 7 == 3 else images[k % 6])
    print(before, count[0] - before, slam.experience_map.n_experiences)
    """)


@pytest.mark.slow
def test_nothing_compiles_in_a_ratslam_loop_after_warm_up_on_a_cold_cache(tmp_path):
    """Issue 26 item 4 for RatSLAM: a cold cache, a camera front end: the warm-up compiles, the loop nothing."""
    out = _run(RATSLAM_WARM_SCRIPT, {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}).split()
    assert int(out[0]) > 0
    assert int(out[1]) == 0


WARM_SCRIPT = COMPILE_COUNTER + textwrap.dedent("""\
    import numpy as np
    from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig
    from maps.odometry import SpatialOdometry
    slam = WhiskerRatSLAM(WhiskerRatSLAMConfig.mapping(cell_size_m=0.05, backend="numba"))
    slam.warm_up()
    before = count[0]
    rng = np.random.default_rng(7)
    places = [(rng.dirichlet(np.ones(81)), rng.normal(0, 1, 18)) for _ in range(9)]
    for k in range(40):
        obs = None if k % 7 == 3 else places[k % 9]
        slam.step(SpatialOdometry(np.array([0.05, 0.01, 0.0]), np.array([0.0, 0.05, 0.7]), 1.0), obs)
    print(before, count[0] - before, slam.object_map.n_experiences)
    """)


@pytest.mark.slow
def test_nothing_compiles_in_the_loop_after_warm_up_on_a_cold_cache(tmp_path):
    """A cold cache: the warm-up compiles; a loop with re-visits, re-localisations and blind whisks compiles nothing."""
    out = _run(WARM_SCRIPT, {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}).split()
    assert int(out[0]) > 0
    assert int(out[1]) == 0


@pytest.mark.slow  # subprocesses that compile (fast loop <= 4 min)
@pytest.mark.parametrize("which", ["nbi", "nbc"])
def test_corrupt_numba_cache_file_of_a_generated_module_recompiles(tmp_path, which, caplog):
    """A corrupt numba index or data file: a warning, a fresh compilation, the right result, a repaired cache."""
    src = SOURCE.replace("triple_plus", f"triple_plus_{which}")
    script = textwrap.dedent(f"""\
        import sys
        from numba.core import event
        count = [0]
        class Count(event.Listener):
            def on_start(self, ev):
                pass
            def on_end(self, ev):
                count[0] += 1
        event.register("numba:compile", Count())
        from cansim.backends.kernel_cache import cached_module
        m = cached_module({src!r}, "corrupt", folder=sys.argv[1])
        print(m.triple_plus_{which}(2, 3), count[0])
        """)
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"))

    def run():
        out = subprocess.run([sys.executable, "-c", script, str(tmp_path / "kernels")], env=env, cwd=ROOT,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        return out.stdout.split(), out.stderr

    assert run()[0] == ["9", "1"]  # cold: compiled once
    assert run()[0] == ["9", "0"]  # warm: loaded
    files = list((tmp_path / "numba").rglob(f"*.{which}"))
    assert files
    for f in files:
        f.write_bytes(b"garbage")
    (result, compiled), err = run()
    assert (result, compiled) == ("9", "1") and "corrupt numba cache" in err
    assert run()[0] == ["9", "0"]  # the entry was written anew


def test_warm_up_block_says_so_when_it_takes_longer_than_its_bound(capsys):
    """A block that outlasts ``after_s``: one INFO line when the bound passes, the progress line on stderr,
    and a closing line; a block within its bound says nothing. (Waits on the announcement, no sleeping.)"""
    import threading

    from cansim.warm_up import WarmUp

    seen = threading.Event()
    records = []

    class Catch(logging.Handler):
        def emit(self, record):
            records.append(record.getMessage())
            seen.set()

    logger = logging.getLogger("cansim.warm_up")
    handler = Catch(level=logging.INFO)
    logger.addHandler(handler)
    old = logger.level
    logger.setLevel(logging.INFO)
    try:
        with WarmUp("Model", progress=True, after_s=0.0) as w:
            w.stage("pose cells")
            assert seen.wait(60)  # the announcement arrives while the block runs
        assert w.elapsed_s > 0.0
        assert len(records) == 2 and "compiling" in records[0] and "kernels ready" in records[1]
        assert capsys.readouterr().err.count("Model: kernels ready") == 1  # drawn once (a log file shows every draw)
        records.clear()
        with WarmUp("Model", progress=True, after_s=3600.0):
            pass
        assert records == [] and capsys.readouterr().err == ""
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old)


@settings(max_examples=25, deadline=None)
@given(value=st.integers(-10**12, 10**12), stem=st.from_regex(r"[a-z][a-z0-9_]{0,12}", fullmatch=True))
def test_cached_module_round_trips_any_source(value, stem):
    """Whatever the source, the module imported is that source, stored under its key."""
    import tempfile

    source = f"VALUE = {value}\n"
    with tempfile.TemporaryDirectory() as folder:
        m = cached_module(source, stem, folder=Path(folder))
        assert m is not None and m.VALUE == value
        assert (Path(folder) / f"{stem}_{module_key(source)}.py").read_text() == source


def test_kernel_cache_dir_precedence(monkeypatch, tmp_path):
    monkeypatch.setenv("CANSIM_KERNEL_CACHE", str(tmp_path / "own"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert kernel_cache.kernel_cache_dir() == tmp_path / "own"
    monkeypatch.delenv("CANSIM_KERNEL_CACHE")
    assert kernel_cache.kernel_cache_dir() == tmp_path / "numba" / "cansim_generated"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert kernel_cache.kernel_cache_dir() == tmp_path / "xdg" / "cansim" / "kernels"


def test_every_cached_kernel_of_the_packages_reads_its_cache_tolerantly():
    """Every ``cache=True`` numba function in cansim, maps and whisker_io has the tolerant reader
    (a kernel module that forgets ``tolerate_corrupt_cache(__name__)`` fails here)."""
    import importlib
    import pkgutil
    import warnings

    from numba.core.caching import IndexDataCacheFile

    from whisker_io.numba_cache import TolerantIndex

    found, plain = 0, []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # moved-module shims warn on import
        for pkg in ("cansim", "maps", "whisker_io"):
            root = importlib.import_module(pkg)
            for info in pkgutil.walk_packages(root.__path__, pkg + "."):
                try:
                    module = importlib.import_module(info.name)
                except ImportError:  # an optional extra that is not installed
                    continue
                for name, value in vars(module).items():
                    cache_file = getattr(getattr(value, "_cache", None), "_cache_file", None)
                    if isinstance(cache_file, IndexDataCacheFile) and getattr(value, "__module__", None) == module.__name__:
                        found += 1
                        if type(cache_file) is not TolerantIndex:
                            plain.append(f"{module.__name__}.{name}")
    assert found > 50
    assert plain == []


CORRUPT_SCRIPT = COMPILE_COUNTER + textwrap.dedent("""\
    import numpy as np
    from whisker_io.contact.detection import prominence_bound
    print(prominence_bound(np.array([0.0, 1.0, 0.0]), 1.0), count[0])
    """)


@pytest.mark.slow  # subprocesses that compile (fast loop <= 4 min)
@pytest.mark.parametrize("which", ["nbi", "nbc"])
def test_a_corrupt_numba_cache_file_of_a_library_kernel_recompiles(tmp_path, which):
    """Issue 26 item 4: garbage in numba's index or data file of an ordinary library kernel (not a
    generated one): one warning, a fresh compilation, the right result, and the next process loads."""
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    first = _run(CORRUPT_SCRIPT, env).split()
    assert int(first[-1]) > 0
    files = list((tmp_path / "numba").rglob(f"*prominence_bound*.{which}"))
    assert files
    for f in files:
        f.write_bytes(b"garbage")
    out = subprocess.run([sys.executable, "-c", CORRUPT_SCRIPT], env=dict(os.environ, PYTHONPATH=str(ROOT), **env),
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    again = out.stdout.split()
    assert again[:-1] == first[:-1] and int(again[-1]) > 0 and "corrupt numba cache" in out.stderr
    assert _run(CORRUPT_SCRIPT, env).split()[-1] == "0"  # the entry was written anew


def _kernel_package(folder: Path, callee_value: int) -> None:
    """A package ``kp`` of two kernel modules: ``kp.b.g`` (cached) calls ``kp.a.f`` (cached) in another file."""
    (folder / "kp").mkdir(exist_ok=True)
    (folder / "kp" / "__init__.py").write_text("")
    (folder / "kp" / "a.py").write_text(textwrap.dedent(f"""\
        from numba import njit
        from whisker_io.numba_cache import tolerate_corrupt_cache

        @njit(cache=True)
        def f():
            return {callee_value}

        tolerate_corrupt_cache(__name__)
        """))
    (folder / "kp" / "b.py").write_text(textwrap.dedent("""\
        from numba import njit
        from kp.a import f
        from whisker_io.numba_cache import tolerate_corrupt_cache

        @njit(cache=True)
        def g():
            return f() + 10

        tolerate_corrupt_cache(__name__)
        """))


def test_a_cached_kernel_recompiles_when_a_kernel_it_calls_in_another_file_changes(tmp_path):
    """Numba stamps a function's cache with its own file only: without the kernel-source digest the
    second process returns 11 (the old callee compiled into ``g``) although ``f`` now returns 2."""
    _kernel_package(tmp_path, 1)
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    script = "from kp.b import g; from kp.a import f; print(g(), f())"

    def run() -> str:
        out = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                             env=dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(tmp_path)]), **env))
        assert out.returncode == 0, out.stderr
        return out.stdout.strip()

    assert run() == "11 1"
    assert list((tmp_path / "numba").rglob("*.nbi"))  # cached
    _kernel_package(tmp_path, 2)  # only kp/a.py changes
    assert run() == "12 2"


def test_the_kernel_digest_follows_kernel_files_only(tmp_path):
    from whisker_io.numba_cache import _kernel_sources_digest

    _kernel_package(tmp_path, 1)
    roots = (str(tmp_path / "kp"),)
    first = _kernel_sources_digest(roots)
    (tmp_path / "kp" / "notes.py").write_text("X = 1  # no compiled code here\n")
    _kernel_sources_digest.cache_clear()
    assert _kernel_sources_digest(roots) == first  # a file without numba does not key the kernels
    _kernel_package(tmp_path, 3)
    _kernel_sources_digest.cache_clear()
    assert _kernel_sources_digest(roots) != first
    _kernel_package(tmp_path, 1)
    _kernel_sources_digest.cache_clear()
    assert _kernel_sources_digest(roots) == first  # the contents, not the files' times


def test_library_kernels_are_stamped_with_the_kernel_digest():
    from cansim.backends import _numba_kernels, _numba_packets

    for fn in (_numba_kernels.rot_lines, _numba_packets.packets_step):
        stamp = fn._cache._cache_file._source_stamp
        assert isinstance(stamp, tuple) and len(stamp) == 2 and isinstance(stamp[1], str) and len(stamp[1]) == 64


@settings(max_examples=25, deadline=None)
@given(observation=st.one_of(st.none(), st.integers(-3, 40), st.text(max_size=5), st.booleans(),
                             st.tuples(st.integers(1, 30), st.integers(1, 70), st.sampled_from(["uint8", "float64", "int64"]))))
def test_ratslam_first_step_with_any_observation_warms_up_or_refuses_with_the_models_state_unchanged(observation):
    """A camera RatSLAM's first step: a usable image warms up and steps; anything else raises the
    project's error, and the model (its saved bytes and its not-yet-warm flag) is unchanged."""
    import io

    from cansim import RatSLAM
    from cansim.errors import CansimError
    from cansim.frontends.visual import VisualTemplateConfig

    if isinstance(observation, tuple):
        h, w, dtype = observation
        observation = np.random.default_rng(h * w).integers(0, 256, (h, w)).astype(dtype)
    slam = RatSLAM(xy_cells=11, heading_cells=12, cell_size_m=0.1,
                   frontend=VisualTemplateConfig(template_width_blocks=12, template_height_blocks=4, shift_match_blocks=3))
    before = io.BytesIO()
    slam.save(before)
    try:
        slam.step(0.05, 0.1, 1.0, observation)
    except CansimError:
        after = io.BytesIO()
        slam.save(after)
        assert after.getvalue() == before.getvalue() and not slam._warm
    else:
        assert slam._warm and slam.iteration == 1
