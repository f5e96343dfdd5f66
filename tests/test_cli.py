"""The ``cansim`` command line: help, exit codes, and each subcommand end to end (small)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.tools import cli
from extras import needs
from cansim.backends import backend_status, registered_backends

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent
COMMANDS = ("demo", "sweep", "study", "replay", "backends", "bench", "warm-up")


def _env():
    return dict(os.environ, MPLBACKEND="Agg",
                PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), str(TESTS), os.environ.get("PYTHONPATH", "")])))


def cansim(*args, cwd=ROOT, timeout=120):
    return subprocess.run([sys.executable, "-m", "cansim", *args], cwd=cwd, env=_env(), capture_output=True, text=True,
                          timeout=timeout)


def _one_line_error(stderr, command):
    lines = [ln for ln in stderr.splitlines() if ln.strip() and ": warning: " not in ln]
    assert "Traceback" not in stderr
    assert len(lines) == 1 and lines[0].startswith(f"cansim {command}: error: "), stderr
    return lines[0]


def test_top_level_help_lists_every_command_and_the_exit_codes():
    proc = cansim("--help")
    assert proc.returncode == 0, proc.stderr
    for name in COMMANDS:
        assert re.search(rf"^\s+{name}\s+\S", proc.stdout, re.M), name
    for code in (0, 2, 3, 4, 5, 6, 130):
        assert re.search(rf"^\s+{code}\s+\S", proc.stdout, re.M), code


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help(command):
    proc = cansim(command, "--help")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"usage: cansim {command}")


@pytest.mark.parametrize("study", ["ch3", "ch4", "ch5", "ch6", "recognition", "rat"])
def test_every_study_takes_the_same_options_for_its_mode_folder_and_progress_bars(study):
    proc = cansim("study", study, "--help")
    assert proc.returncode == 0, proc.stderr
    for option in ("--quick", "--out", "--no-progress"):
        assert re.search(rf"^\s+{option}\b", proc.stdout, re.M), (study, option)


@pytest.mark.parametrize("argv,usage,option", [
    (("study", "ch5", "--help"), "usage: cansim study ch5", "--scale-to-m"),
    (("study", "--quick", "recognition", "-h"), "usage: cansim study recognition", "--roll-deg"),
    (("demo", "whisker", "--help"), "usage: cansim demo whisker", "--up-axis"),
])
def test_a_study_or_demo_named_before_help_shows_its_own_options(argv, usage, option):
    proc = cansim(*argv)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(usage) and option in proc.stdout


def test_help_is_shown_whatever_the_output_folder_and_only_for_the_subcommand(tmp_path):
    (tmp_path / "a_file").write_text("")
    proc = cansim("study", "--out", str(tmp_path / "a_file" / "x"), "ch5", "--help", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stdout.startswith("usage: cansim study ch5")  # help needs no output folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
    proc = cansim("sweep", "--out", "study", "ch5", "-h", cwd=tmp_path)  # 'study' is a value here, not the command
    assert proc.returncode == 0 and proc.stdout.startswith("usage: cansim sweep")


def test_a_studys_usage_error_names_the_command():
    proc = cansim("study", "ch6", "--objects", "box")
    assert proc.returncode == 2 and "cansim study ch6: error: argument --objects" in proc.stderr
    assert "__main__" not in proc.stderr


@pytest.mark.parametrize("argv,says", [
    (["study", "ch5", "--quick", "--objects", "box", "mug", "--novel", "mug"], "both a library object and a novel one"),
    (["study", "ch5", "--quick", "--objects", "box", "mug", "--novel", "skull", "plane", "Skull"], "given twice"),
    (["study", "ch6", "--quick", "--objects", "box", "box"], "given twice"),
    (["study", "ch6", "--quick", "--scale-to-m", "0.35"], "apply to mesh files"),
    (["demo", "--object", "mug", "--up-axis", "y"], "apply to mesh files"),
])
def test_objects_named_twice_or_options_without_a_mesh_are_refused_before_any_work(tmp_path, argv, says):
    proc = cansim(*argv, "--out", str(tmp_path), cwd=tmp_path, timeout=60)
    line = _one_line_error(proc.stderr, argv[0] if argv[0] == "demo" else f"{argv[0]} {argv[1]}")
    assert proc.returncode == 3 and says in line
    assert not any(tmp_path.iterdir())  # nothing written


def test_an_output_folder_that_cannot_be_written_is_refused_before_any_work(tmp_path):
    (tmp_path / "a_file").write_text("")
    for argv in (["study", "ch6", "--quick"], ["demo"]):
        proc = cansim(*argv, "--out", str(tmp_path / "a_file" / "out"), cwd=tmp_path, timeout=60)
        line = _one_line_error(proc.stderr, " ".join(argv[:2]) if argv[0] == "study" else "demo")
        assert proc.returncode == 3 and "cannot write to the output folder" in line


def test_usage_errors_exit_2():
    assert cansim("fly").returncode == 2
    proc = cansim("sweep")
    assert proc.returncode == 2 and "FILE.toml" in proc.stderr
    assert cansim("sweep", "x.toml", "--workers", "0").returncode == 2
    assert cansim("study", "ch9").returncode == 2


def test_a_malformed_spec_exits_3_with_one_line_naming_the_key(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text('experiment = "sweep_fixtures:fast"\nmetrics = ["value"]\n[grid]\na = 3\n')
    proc = cansim("sweep", str(spec), "--out", str(tmp_path / "out"))
    assert proc.returncode == 3
    assert "grid.a: " in _one_line_error(proc.stderr, "sweep")
    proc = cansim("sweep", str(tmp_path / "missing.toml"))
    assert proc.returncode == 3 and "no such sweep spec file" in _one_line_error(proc.stderr, "sweep")


@needs("distributed", "sweep")
@pytest.mark.parametrize("param, value", [("global_inhibition", -1.0), ("n_cells", -5), ("duration_steps", 0)])
def test_an_out_of_range_cell_exits_3_before_any_task_runs(tmp_path, param, value):
    """A negative parameter was caught only when each task ran (exit 4); now the experiment's
    check_params refuses it before the cluster starts (issue 25)."""
    spec = tmp_path / "bad_values.toml"
    spec.write_text(f'experiment = "bump"\nmetrics = ["fwhm_cells"]\n[grid]\n{param} = [{value}]\n')
    proc = cansim("sweep", str(spec), "--out", str(tmp_path / "out"), "--no-progress")
    assert proc.returncode == 3, proc.stderr
    assert param in _one_line_error(proc.stderr, "sweep")
    assert not (tmp_path / "out" / "parts").exists() or not any((tmp_path / "out" / "parts").iterdir())


@pytest.mark.slow  # starts two Dask clusters (fast loop <= 4 min)
def test_a_sweep_is_quiet_by_default_and_verbose_on_request(tmp_path):
    """Sweeps printed about 33 Dask INFO lines per run (issue 25): none by default, Dask's lines with --verbose."""
    spec = tmp_path / "small.toml"
    spec.write_text('experiment = "bump"\nmetrics = ["fwhm_cells"]\n[grid]\nn_cells = [60]\n')
    quiet = cansim("sweep", str(spec), "--out", str(tmp_path / "q"), "--no-progress", "--workers", "1")
    assert quiet.returncode == 0 and quiet.stderr.strip() == ""
    assert "1 tasks (1 cells): ran 1" in quiet.stdout
    loud = cansim("sweep", str(spec), "--out", str(tmp_path / "v"), "--no-progress", "--workers", "1", "--verbose")
    assert loud.returncode == 0 and "INFO" in loud.stderr


def test_a_huge_n_seeds_exits_3_at_once(tmp_path):
    """n_seeds = 2**63 - 1 used to enumerate every seed before starting (issue 25): now a ConfigError up front."""
    from cansim.tools.sweep import MAX_TASKS

    spec = tmp_path / "huge.toml"
    spec.write_text(f'experiment = "sweep_fixtures:fast"\nmetrics = ["value"]\nn_seeds = {2**63 - 1}\n[grid]\na = [1, 2]\n')
    proc = cansim("sweep", str(spec), "--out", str(tmp_path / "out"))  # subprocess.run's own timeout bounds it
    assert proc.returncode == 3
    assert f"more than the limit {MAX_TASKS}" in _one_line_error(proc.stderr, "sweep")
    assert not (tmp_path / "out").exists()


@needs("distributed", "sweep")
def test_a_sweep_with_failing_cells_exits_4_after_recording_every_row(tmp_path, capsys):
    spec = tmp_path / "flaky.toml"
    spec.write_text('experiment = "sweep_fixtures:flaky"\nmetrics = ["value"]\n[grid]\na = [1, 2]\nb = [0, 1]\n')
    code = cli.main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "--no-progress"])
    captured = capsys.readouterr()
    assert code == 4
    assert "4 tasks (4 cells): ran 4" in captured.out
    assert "2 task(s) ended with an error" in _one_line_error(captured.err, "sweep")
    import pyarrow.parquet as pq

    assert pq.read_table(tmp_path / "out" / "results.parquet").num_rows == 4


def test_interrupt_exits_130_and_says_how_to_resume(tmp_path, capsys, monkeypatch):
    from cansim.tools import sweep

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "run", interrupted)
    spec = tmp_path / "s.toml"
    spec.write_text('experiment = "sweep_fixtures:fast"\nmetrics = ["value"]\n')
    assert cli.main(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 130
    assert "run the same command again to resume" in capsys.readouterr().err


def test_a_missing_extra_exits_6_naming_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags", None)  # as if rosbags were not installed
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    (tmp_path / "r.bag").write_bytes(b"")
    assert cli.main(["replay", str(tmp_path / "r.bag"), "--out", str(tmp_path / "o")]) == 6
    assert 'pip install "cansim[bags]"' in _one_line_error(capsys.readouterr().err, "replay")


def test_demo_ratslam_writes_its_outputs(tmp_path, capsys):
    assert cli.main(["demo", "ratslam", "--out", str(tmp_path)]) == 0
    metrics = json.loads((tmp_path / "ratslam_metrics.json").read_text())
    assert metrics["ate_map"] < metrics["ate_dead_reckoning"]  # the map beats dead reckoning, as the README says
    for name in ("ratslam_map.png", "ratslam_experience_ids.png", "ratslam_experience_ids_kidnapped.png"):
        assert (tmp_path / name).stat().st_size > 10_000
    assert "ARR" in capsys.readouterr().out


def test_study_and_demo_options_reach_the_module(tmp_path, capsys, monkeypatch):
    """Options after the chapter (or the demo's name) are passed on to the module's main(argv)."""
    seen = {}

    def fake_main(argv):
        seen["argv"] = argv
        return 0

    import cansim.studies.ch3_maze as ch3
    import cansim.studies.whisker_ratslam_demo as demo

    monkeypatch.setattr(ch3, "main", fake_main)
    assert cli.main(["study", "ch3", "--quick", "--out", str(tmp_path), "--repetitions", "2"]) == 0
    assert seen["argv"] == ["--quick", "--out", str(tmp_path), "--repetitions", "2"]
    monkeypatch.setattr(demo, "main", fake_main)
    assert cli.main(["demo", "--out", str(tmp_path), "--object", "box", "--quick"]) == 0
    assert seen["argv"] == ["--seed", "0", "--out", str(tmp_path), "--object", "box", "--quick"]


def test_unknown_options_of_other_commands_are_usage_errors(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["backends", "--object", "box"])
    assert exc.value.code == 2
    assert "unrecognized arguments: --object box" in capsys.readouterr().err


@pytest.mark.slow  # ~10 s on a quiet machine; the other chapters' entry-point runs are slow too
@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_study_ch4_quick_runs_the_radial_distance_study(tmp_path):
    from entry_point import run_cansim

    done = run_cansim("study", "ch4", "--quick", "--out", str(tmp_path))  # the installed entry point
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "radial_results.csv").stat().st_size > 0
    assert (tmp_path / "radial_study_summary.txt").read_text().startswith("radial-distance study (quick)")


def test_backends_table_has_a_line_per_backend(capsys):
    from cansim.backends import backend_status

    assert cli.main(["backends"]) == 0
    out = capsys.readouterr().out.splitlines()
    status = backend_status()
    for name in registered_backends():
        line = next(ln for ln in out if ln.split()[0] == name)
        assert line.split()[1] == ("yes" if status[name][0] else "no")
        assert status[name][1] in line


def test_bench_quick_writes_a_comparable_json(tmp_path, capsys):
    pytest.importorskip("numba")
    out = tmp_path / "bench.json"
    code = cli.main(["bench", "--quick", "--backends", "numpy,numba", "--workloads", "ring360,21x21x36",
                     "--out", str(out), "--no-progress"])
    assert code == 0
    doc = json.loads(out.read_text())
    assert doc["format"] == "cansim-bench/1" and doc["quick"] is True
    assert {"hostname", "cpu", "usable_cpus", "python", "numpy", "cansim", "numba"} <= set(doc["machine"])
    assert set(doc["backends"]) == set(registered_backends())
    plain = {(r["workload"], r["backend"]) for r in doc["results"] if r["threads"] is None}
    assert plain == {(w, b) for w in ("ring360", "21x21x36") for b in ("numpy", "numba")}
    import numba

    threads = sorted(r["threads"] for r in doc["results"] if r["threads"] is not None)
    assert threads == sorted({1, int(numba.config.NUMBA_NUM_THREADS)})  # quick: 1 and N threads, 21x21x36 only
    for r in doc["results"]:
        assert 0 < r["min_us"] <= r["median_us"] and r["rounds"] == 5 and r["steps"] >= 1
    text = capsys.readouterr().out
    n = numba.get_num_threads()
    assert f"numba, {n} thread{'s' if n != 1 else ''}: median / min (us)" in text and "numpy, 1 thread:" in text
    assert doc["backends"]["numba"]["threads"] == n and doc["backends"]["numpy"]["threads"] == 1
    assert doc["machine"]["numba_jit"] is True
    assert cli.main(["bench", "--quick", "--backends", "cuda", "--out", str(out)]) == 3


def test_bench_checks_its_output_and_backends_before_timing_and_fails_when_asked_for_is_not_timed(tmp_path, capsys,
                                                                                                 monkeypatch):
    """A folder as --out failed after every timing (results lost); --backends "" and a requested backend that
    cannot run here timed nothing (or not it) and exited 0 (a benchmark user's pass, session 48)."""
    import cansim.tools.benchmark as benchmark

    timed = []
    monkeypatch.setattr(benchmark, "_time", lambda fn, *a: timed.append(fn) or (1.0, 1.0, 1))
    assert cli.main(["bench", "--quick", "--out", str(tmp_path), "--no-progress"]) == 3
    assert "is a folder" in capsys.readouterr().err and not timed
    assert cli.main(["bench", "--quick", "--backends", "", "--out", str(tmp_path / "b.json")]) == 3
    assert "names no backend" in capsys.readouterr().err and not timed
    status = dict(backend_status())
    status["opencl"] = (False, "no OpenCL platform here")
    monkeypatch.setattr("cansim.backends.backend_status", lambda **k: status)
    code = cli.main(["bench", "--quick", "--backends", "numpy,opencl", "--workloads", "ring360", "--out",
                     str(tmp_path / "b.json"), "--no-progress"])
    captured = capsys.readouterr()
    assert code == 6 and "opencl asked for with --backends but not timed" in captured.err
    assert "not timed: opencl - no OpenCL platform here" in captured.out
    assert json.loads((tmp_path / "b.json").read_text())["results"]  # what did run is kept


def test_replay_command_writes_map_trajectory_and_figure(tmp_path, capsys):
    pytest.importorskip("rosbags")
    from rosbags.typesys import Stores, get_typestore
    from test_bag_replay import CFG_TEXT, _messages, write_ros1

    from cansim.testing.worlds import LoopRoute, make_run, render_view, scatter_landmarks

    route = LoopRoute(step_m=0.1)
    run = make_run(route, loops=(1,), seed=2)
    lm = scatter_landmarks(route, seed=1)
    images = [render_view(p, lm, shape=(12, 48)) for p in run.truth]
    write_ros1(tmp_path / "loop.bag", _messages(run, images, False, True, get_typestore(Stores.ROS1_NOETIC), n=30))
    cfg = tmp_path / "config.txt"
    cfg.write_text(CFG_TEXT)
    code = cli.main(["replay", str(tmp_path / "loop.bag"), "--config", str(cfg), "--out", str(tmp_path / "o"),
                     "--no-progress"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "30 odometry messages (/irat_red/odom), 30 images" in captured.out
    warned = [ln for ln in captured.err.splitlines() if ln.strip()]
    assert warned == ["cansim replay: warning: 1 OpenRatSLAM config key not used by cansim's RatSLAM model (ROS topics, "
                      "drawing, visual odometry...), ignored: [draw] 'enable' (line 13)"]  # one line; topic_root is read
    rows = (tmp_path / "o" / "trajectory.csv").read_text().splitlines()
    assert rows[0] == "time_s,x_m,y_m,th_rad,exp_id" and len(rows) == 30
    assert (tmp_path / "o" / "experience_map.npz").exists() and (tmp_path / "o" / "experience_map.png").exists()
    assert cli.main(["replay", str(tmp_path / "loop.bag"), "--out", str(tmp_path / "o2")]) == 3  # no topic root
    assert "the bag has: /irat_red/camera/image" in _one_line_error(capsys.readouterr().err, "replay")
    assert cli.main(["replay", str(tmp_path / "nothing.bag")]) == 3


def test_readme_lists_every_command_and_exit_code():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Command line", 1)[1].split("\n## ", 1)[0]
    for name in COMMANDS:
        assert f"cansim {name}" in section, name
    for code in cli.EXIT_CODES:
        assert re.search(rf"\|\s*{code}\s*\|", section), code


@settings(max_examples=50, deadline=None)
@given(names=st.lists(st.text("abcdefxyz0123456789_^", min_size=1, max_size=8), min_size=1, max_size=3),
       which=st.sampled_from(["backends", "workloads"]))
def test_bench_refuses_unknown_names_before_timing_anything(names, which):
    from cansim.tools.benchmark import WORKLOADS, run_suite
    from cansim.errors import InvalidInputError

    known = set(registered_backends()) if which == "backends" else {*WORKLOADS, "61x61x36", "10^6"}
    if set(names) <= known:
        return
    with pytest.raises(InvalidInputError, match=f"unknown {which[:-1]}"):
        run_suite(quick=True, **{which: names})


def test_numba_with_its_jit_disabled_is_said_to_run_interpreted(monkeypatch):
    numba = pytest.importorskip("numba")
    from cansim.backends import _probe_numba

    monkeypatch.setattr(numba.config, "DISABLE_JIT", True)
    assert "NUMBA_DISABLE_JIT set: its kernels run as interpreted Python" in _probe_numba(None)
    monkeypatch.setattr(numba.config, "DISABLE_JIT", False)
    assert _probe_numba(None).endswith("compiles for this CPU")


def test_bench_says_when_max_threads_is_above_numbas_and_records_pocls_threads(tmp_path, monkeypatch, caplog):
    numba = pytest.importorskip("numba")
    import cansim.tools.benchmark as benchmark

    monkeypatch.setattr(benchmark, "_time", lambda fn, *a: (1.0, 1.0, 1))
    most = int(numba.config.NUMBA_NUM_THREADS)
    with caplog.at_level("WARNING", logger="cansim.tools.benchmark"):
        report = benchmark.run_suite(quick=True, backends=["numba"], workloads=["21x21x36"], max_threads=most + 3)
    assert f"max_threads {most + 3} is more than numba's {most}" in caplog.text
    assert max(r.threads for r in report.records if r.threads is not None) == most
    monkeypatch.setenv("POCL_MAX_PTHREAD_COUNT", "3")
    assert benchmark.backend_threads("opencl") == 3
    monkeypatch.setenv("POCL_MAX_PTHREAD_COUNT", "")
    assert benchmark.backend_threads("opencl") == len(os.sched_getaffinity(0))
    assert benchmark.backend_threads("numpy") == 1 and benchmark.backend_threads("mine") is None


def test_bench_says_when_it_compiles_and_marks_a_median_far_above_the_minimum(monkeypatch):
    import threading

    import cansim.tools.benchmark as benchmark

    monkeypatch.setattr(benchmark, "COMPILE_NOTICE_S", 0.01)
    said = threading.Event()
    first = []

    def slow_first_call():  # the first call waits until the notice has been given, as a compiling kernel would
        if not first:
            first.append(1)
            assert said.wait(timeout=30), "no compiling notice while the first call ran"

    benchmark._time(slow_first_call, 1, 2, 0.0, said.set)
    rec = lambda med, low: benchmark.BenchRecord("ring360", "numpy", None, 360, med, low, 5, 1)  # noqa: E731
    report = benchmark.BenchReport([rec(10.0, 9.0), rec(100.0, 9.0)], {}, {}, True)
    report.records[1] = benchmark.BenchRecord("21x21x36", "numpy", None, 15876, 100.0, 9.0, 5, 1)
    text = benchmark.format_tables(report)
    assert text.count(" !") == 1  # only the stalled row
    assert "100.0 / 9.0 !" in text and "some rounds met a stall" in text
    calm = benchmark.format_tables(benchmark.BenchReport([rec(10.0, 9.0)], {}, {}, True))
    assert "!" not in calm and "stall" not in calm


@settings(max_examples=25, deadline=None)
@given(models=st.lists(st.sampled_from(["ratslam", "whisker", "population", "pop", "", "RatSLAM"]), max_size=3))
def test_warm_up_warms_what_it_is_told_or_refuses_before_any_work(models):
    """cansim warm-up --models: each named model warmed and said, in order; anything else a usage error (3)."""
    import contextlib
    import io

    spec = ",".join(models)
    names = [m for m in models if m]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["warm-up", "--models", spec, "--backend", "numpy", "--no-progress"])
    valid = bool(names) and all(m in ("ratslam", "whisker", "population") for m in names)
    if valid:
        assert code == 0, err.getvalue()
        lines = out.getvalue().splitlines()
        assert [ln.split(":")[0] for ln in lines[:-1]] == names and lines[-1].startswith("warmed in")
    else:
        assert code == 3 and "give some of ratslam, whisker, population" in err.getvalue() and not out.getvalue()


def test_warm_up_refuses_a_backend_that_cannot_run_here(monkeypatch, capsys):
    status = dict(backend_status())
    status["opencl"] = (False, "no OpenCL platform here")
    monkeypatch.setattr("cansim.backends.backend_status", lambda **k: status)
    assert cli.main(["warm-up", "--backend", "opencl"]) == 6  # cannot run here: as cansim bench --backends says it
    assert "--backend opencl: no OpenCL platform here" in capsys.readouterr().err
    assert cli.main(["warm-up", "--backend", "cuda"]) == 3  # no such backend: bad input
    assert "--backend cuda: no such backend" in capsys.readouterr().err
