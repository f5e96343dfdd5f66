"""Sweeps on Dask (cansim.tools.sweep): real worker processes, resume, errors, a killed worker,
a separate ``dask scheduler`` + ``dask worker``, and the spec parser.

(``tests/test_sweep.py`` is whisker_io's rigid-whisker sweep; this file is the sweep engine.)
"""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cansim.tools import sweep
from cansim.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent

SPEC = {"experiment": "sweep_fixtures:fast", "grid": {"a": [1, 2], "b": [0, 1, 2, 3]}, "metrics": ["value", "noise", "pid"]}


def _rows(table):
    return table.to_pylist()


def _check_rows(rows):
    """Each row against the fixture's formula: value = 10 a + b, noise = one normal draw of default_rng(seed)."""
    for r in rows:
        assert r["status"] == "ok", r["error"]
        assert r["value"] == 10 * r["a"] + r["b"]
        assert r["noise"] == float(np.random.default_rng(r["seed"]).normal())
    assert sorted((r["a"], r["b"]) for r in rows) == [(a, b) for a in (1, 2) for b in range(4)]


@pytest.fixture(scope="module")
def threads_client():
    """An in-process cluster (threads) for the tests that are not about processes."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None)
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_eight_cells_on_a_two_process_local_cluster_then_a_rerun_adds_nothing(tmp_path):
    first = sweep.run(SPEC, out=tmp_path, workers=2, progress=False)
    assert (first.ran, first.skipped, first.failed) == (8, 0, 0)
    rows = _rows(first.table)
    assert len(rows) == 8
    _check_rows(rows)
    assert all(r["pid"] != os.getpid() for r in rows)  # ran in worker processes
    assert {r["cansim_version"] for r in rows} == {__import__("cansim").__version__}
    assert {r["numpy_version"] for r in rows} == {np.__version__}
    assert all(r["wall_time_s"] >= 0 and r["hostname"] for r in rows)
    assert not list((tmp_path / "parts").glob("*.parquet"))  # compacted

    import pyarrow.parquet as pq

    assert pq.read_table(tmp_path / "results.parquet").num_rows == 8
    again = sweep.run(SPEC, out=tmp_path, workers=2, progress=False)
    assert (again.ran, again.skipped) == (0, 8)
    assert again.table.num_rows == 8

    # every row is reproducible alone: the same task run here gives the same metrics
    task = next(t for t in sweep.expand(SPEC) if t.params == {"a": 2, "b": 3})
    row = next(r for r in rows if r["task_id"] == task.task_id)
    alone = sweep.run_task(task)
    assert (alone["value"], alone["noise"], alone["seed"]) == (row["value"], row["noise"], row["seed"])


def test_interrupted_sweep_resumes_with_the_tasks_not_yet_done(tmp_path, threads_client):
    seen = []

    def stop_after_three(row):
        seen.append(row["task_id"])
        if len(seen) == 3:
            raise KeyboardInterrupt  # what Ctrl-C does in the middle of the loop

    with pytest.raises(KeyboardInterrupt):
        sweep.run(SPEC, client=threads_client, out=tmp_path, progress=False, on_row=stop_after_three)
    assert len(list((tmp_path / "parts").glob("*.parquet"))) == 3  # each finished task is already on disk
    assert sweep.read_results(tmp_path).num_rows == 3
    resumed = sweep.run(SPEC, client=threads_client, out=tmp_path, progress=False)
    assert (resumed.ran, resumed.skipped) == (5, 3)
    _check_rows(_rows(resumed.table))


def test_a_failing_cell_is_recorded_and_retried_only_when_asked(tmp_path, threads_client, monkeypatch):
    spec = dict(SPEC, experiment="sweep_fixtures:flaky", metrics=["value", "noise"])
    res = sweep.run(spec, client=threads_client, out=tmp_path, progress=False)
    rows = _rows(res.table)
    assert len(rows) == 8 and res.failed == 4
    bad = [r for r in rows if r["status"] == "error"]
    assert {r["a"] for r in bad} == {2}
    assert all(r["error"] == "ValueError: a = 2 is not allowed" and r["value"] is None for r in bad)
    assert all(r["error"] == "" for r in rows if r["status"] == "ok")
    assert sweep.run(spec, client=threads_client, out=tmp_path, progress=False).ran == 0  # errors kept
    monkeypatch.setenv("SWEEP_FIXTURE_FIXED", "1")
    retried = sweep.run(spec, client=threads_client, out=tmp_path, progress=False, retry_errors=True)
    assert (retried.ran, retried.skipped, retried.failed) == (4, 4, 0)
    rows = _rows(retried.table)
    assert len(rows) == 8 and all(r["status"] == "ok" for r in rows)


def test_a_missing_metric_is_an_error_of_that_cell(tmp_path, threads_client, caplog):
    spec = dict(SPEC, experiment="sweep_fixtures:incomplete", metrics=["value", "noise"], grid={"a": [1, 2], "b": [0]})
    said_by_row = []  # how many such warnings had been given when each row came in

    def on_row(row):
        said_by_row.append(sum("missing from the experiment's result" in r.getMessage() for r in caplog.records))

    with caplog.at_level("WARNING", logger="cansim.tools.sweep"):
        rows = _rows(sweep.run(spec, client=threads_client, out=tmp_path, progress=False, on_row=on_row).table)
    assert said_by_row == [1, 1]  # at the first task's row already, and not again
    assert all(r["status"] == "error" and "metric 'noise' missing" in r["error"] for r in rows)
    # said as soon as the first task came back (a misspelt metric), once, not only in the results at the end
    warned = [r.getMessage() for r in caplog.records if "missing from the experiment's result" in r.getMessage()]
    assert len(warned) == 1 and "fix the spec's metrics" in warned[0] and "'noise'" in warned[0]


def test_a_metric_of_changing_type_is_kept_as_strings(tmp_path, threads_client):
    spec = dict(SPEC, experiment="sweep_fixtures:mixed", metrics=["value"], grid={"a": [1, 2], "b": [0]})
    rows = _rows(sweep.run(spec, client=threads_client, out=tmp_path, progress=False).table)
    assert sorted(r["value"] for r in rows) == ["10", "v20"]


def test_growing_a_grid_runs_only_the_new_cells_and_another_sweep_is_refused(tmp_path, threads_client):
    small = dict(SPEC, grid={"a": [1], "b": [0, 1, 2, 3]})
    assert sweep.run(small, client=threads_client, out=tmp_path, progress=False).ran == 4
    grown = sweep.run(SPEC, client=threads_client, out=tmp_path, progress=False)
    assert (grown.ran, grown.skipped) == (4, 4)
    _check_rows(_rows(grown.table))
    with pytest.raises(ConfigError, match="^metrics: .* holds a sweep with metrics"):
        sweep.run(dict(SPEC, metrics=["value"]), client=threads_client, out=tmp_path, progress=False)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:Port .* is already in use")  # the restarted worker's dashboard port
def test_killing_a_worker_mid_sweep_still_ends_with_every_row(tmp_path):
    from distributed import Client, LocalCluster

    spec = dict(SPEC, experiment="sweep_fixtures:slow", fixed={"sleep_s": 0.4})
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    killed = []

    def kill_one_worker(row):
        if not killed:  # both workers are busy with their next task now
            pids = client.run(os.getpid)
            victim = next(pid for pid in pids.values() if pid != row["pid"])
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)

    try:
        res = sweep.run(spec, client=client, out=tmp_path, progress=False, on_row=kill_one_worker)
    finally:
        client.close()
        cluster.close()
    assert killed
    rows = _rows(res.table)
    assert len(rows) == 8 and len({r["task_id"] for r in rows}) == 8
    _check_rows(rows)


@pytest.mark.slow
def test_a_separate_dask_scheduler_and_worker_via_the_command_line(tmp_path):
    """``dask scheduler`` and ``dask worker`` started as their own processes; the sweep goes through --scheduler."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(TESTS), os.environ.get("PYTHONPATH", "")]))
    sched_file = tmp_path / "scheduler.json"
    spec_file = tmp_path / "grid.toml"
    spec_file.write_text('experiment = "sweep_fixtures:fast"\nmetrics = ["value", "noise", "pid"]\n'
                         '[grid]\na = [1, 2]\nb = [0, 1, 2, 3]\n')
    procs = []
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
             "--scheduler-file", str(sched_file)], cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        _wait(lambda: sched_file.exists() and sched_file.stat().st_size > 0, 60, procs, "the scheduler file")
        import json

        address = json.loads(sched_file.read_text())["address"]
        assert re.match(r"^tcp://127\.0\.0\.1:\d+$", address)
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", address, "--nworkers", "1", "--nthreads", "1", "--host", "127.0.0.1",
             "--no-dashboard"], cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout=30) as c:
            c.wait_for_workers(1, timeout=60)
            worker_pids = set(c.run(os.getpid).values())
        out = tmp_path / "out"
        proc = subprocess.run([sys.executable, "-m", "cansim", "sweep", str(spec_file), "--scheduler", address,
                               "--out", str(out), "--no-progress"], cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=180)
        assert proc.returncode == 0, proc.stderr
        assert "8 tasks (8 cells): ran 8" in proc.stdout
        import pyarrow.parquet as pq

        rows = pq.read_table(out / "results.parquet").to_pylist()
        _check_rows(rows)
        assert {r["pid"] for r in rows} == worker_pids  # computed by the separate worker, not a local cluster
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=10)


def _wait(ready, timeout_s, procs, what):
    deadline = time.monotonic() + timeout_s
    while not ready():
        if any(p.poll() is not None for p in procs):
            pytest.fail(f"a dask process exited before {what} appeared")
        if time.monotonic() > deadline:
            pytest.fail(f"{what} did not appear within {timeout_s} s")
        time.sleep(0.05)  # polling interval, not a timing assumption


def test_unreachable_scheduler_is_a_config_error(tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ConfigError, match="^scheduler: cannot connect"):
        sweep.run(SPEC, out=tmp_path, scheduler=f"tcp://127.0.0.1:{port}", progress=False, connect_timeout_s=1)
    with pytest.raises(ConfigError, match=f"^scheduler: cannot connect to tcp://127.0.0.1:{port}"):  # the spec's key
        sweep.run(dict(SPEC, scheduler=f"tcp://127.0.0.1:{port}"), out=tmp_path, progress=False, connect_timeout_s=1)


# ------------------------------------------------------------------ spec parser
MALFORMED = [
    ({"grdi": {"a": [1]}}, "grdi"),
    ({"grid": {"a": 3}}, "grid.a"),
    ({"grid": {"a": []}}, "grid.a"),
    ({"grid": {"a": [1, 1]}}, "grid.a"),
    ({"grid": {"a": [float("nan")]}}, "grid.a"),
    ({"grid": {"a": [[1, 2]]}}, "grid.a"),
    ({"grid": {"a": [1, "x"]}}, "grid.a"),
    ({"grid": {"a": [True, 0]}}, "grid.a"),
    ({"grid": [1, 2]}, "grid"),
    ({"random": {"c": {"distribution": "uniform", "low": 0, "high": 1}}}, "random.n_samples"),
    ({"random": {"n_samples": 0, "c": {"distribution": "uniform", "low": 0, "high": 1}}}, "random.n_samples"),
    ({"random": {"n_samples": 2, "c": {"distribution": "gamma", "low": 0, "high": 1}}}, "random.c.distribution"),
    ({"random": {"n_samples": 2, "c": {"distribution": "uniform", "low": 1, "high": 1}}}, "random.c.high"),
    ({"random": {"n_samples": 2, "c": {"distribution": "loguniform", "low": 0, "high": 1}}}, "random.c.low"),
    ({"random": {"n_samples": 2, "c": {"distribution": "normal", "mean": 0}}}, "random.c.std"),
    ({"random": {"n_samples": 2, "c": {"distribution": "normal", "mean": 0, "std": 1, "sd": 2}}}, "random.c.sd"),
    ({"random": {"n_samples": 2, "c": {"distribution": "choice", "values": []}}}, "random.c.values"),
    ({"random": {"n_samples": 2, "c": {"distribution": "choice", "values": [1, "one"]}}}, "random.c.values"),
    ({"random": {"n_samples": 2, "a": {"distribution": "choice", "values": [1]}}}, "random.a"),
    ({"seeds": [1, 2], "n_seeds": 3}, "seeds"),
    ({"seeds": [1, -2]}, "seeds"),
    ({"seeds": [1, 1]}, "seeds"),
    ({"n_seeds": 0}, "n_seeds"),
    ({"n_seeds": True}, "n_seeds"),
    ({"base_seed": -1}, "base_seed"),
    ({"metrics": []}, "metrics"),
    ({"metrics": ["value", "value"]}, "metrics"),
    ({"metrics": ["status"]}, "metrics"),
    ({"metrics": ["a"]}, "metrics"),
    ({"grid": {"seed": [1]}}, "grid.seed"),
    ({"fixed": {"b": 1}}, "fixed.b"),
    ({"scheduler": "localhost:8786"}, "scheduler"),
    ({"experiment": "not a path"}, "experiment"),
    ({"experiment": 3}, "experiment"),
    ({"name": "a b"}, "name"),
]


@pytest.mark.parametrize("change,key", MALFORMED, ids=[k for _, k in MALFORMED])
def test_malformed_spec_raises_a_config_error_naming_the_key(change, key):
    data = {**SPEC, **change}
    with pytest.raises(ConfigError) as info:
        sweep.parse_spec(data)
    assert str(info.value).startswith(key), str(info.value)


def test_missing_metrics_and_unreadable_files_name_the_problem(tmp_path):
    with pytest.raises(ConfigError, match="^metrics: missing"):
        sweep.parse_spec({"experiment": "sweep_fixtures:fast"})
    bad = tmp_path / "bad.toml"
    bad.write_text('experiment = "sweep_fixtures:fast"\n[grid\n')
    with pytest.raises(ConfigError, match="not valid TOML"):
        sweep.load_spec(bad)
    with pytest.raises(ConfigError, match="no such sweep spec file"):
        sweep.load_spec(tmp_path / "missing.toml")
    typo = tmp_path / "typo.toml"
    typo.write_text('experiment = "sweep_fixtures:fast"\nmetrics = ["value"]\nseed = [1]\n')
    with pytest.raises(ConfigError, match=r"typo\.toml: seed: unknown sweep spec key"):
        sweep.load_spec(typo)
    with pytest.raises(ConfigError, match="^experiment: cannot import module 'no_such_module'"):
        sweep.run(dict(SPEC, experiment="no_such_module:run"), out=tmp_path / "x", progress=False)


@pytest.mark.parametrize("name", ["no_seed", "keyword_seed"])
def test_an_experiment_of_the_wrong_signature_is_refused_before_any_task(tmp_path, name):
    """It was caught per task, each row an error, after the cluster had started (a user's pass, session 47)."""
    with pytest.raises(ConfigError, match=rf"^experiment: 'sweep_fixtures:{name}' must take \(params: dict, seed: int\)"):
        sweep.run(dict(SPEC, experiment=f"sweep_fixtures:{name}"), out=tmp_path / "x", progress=False)
    assert not (tmp_path / "x").exists()
    assert sweep.resolve_experiment("sweep_fixtures:fast").__name__ == "fast"  # (params, seed): taken


def test_names_without_a_function_and_file_names():
    assert sweep.parse_spec(dict(SPEC, experiment="diffusion")).experiment == "cansim.experiments.diffusion:run"
    assert sweep.parse_spec(dict(SPEC, experiment="pkg.mod")).experiment == "pkg.mod:run"


def test_seeds_and_samples_by_hand():
    spec = sweep.parse_spec({**SPEC, "grid": {"a": [1]}, "seeds": [7, 3], "fixed": {"b": 5}})
    tasks = sweep.expand(spec)
    assert [(t.params, t.seed) for t in tasks] == [({"a": 1, "b": 5}, 7), ({"a": 1, "b": 5}, 3)]
    spec = sweep.parse_spec({**SPEC, "grid": {"a": [1, 2]}, "fixed": {"b": 0}, "random": {
        "n_samples": 3, "c": {"distribution": "choice", "values": ["x", "y"]},
        "d": {"distribution": "loguniform", "low": 1e-3, "high": 1e-1}}})
    tasks = sweep.expand(spec)
    assert len(tasks) == 6 == spec.n_tasks
    # the same 3 random samples are crossed with every grid value
    assert [(t.params["c"], t.params["d"]) for t in tasks[:3]] == [(t.params["c"], t.params["d"]) for t in tasks[3:]]
    assert all(1e-3 <= t.params["d"] <= 1e-1 and t.params["c"] in ("x", "y") for t in tasks)


# ------------------------------------------------------------------ hypothesis
numbers = st.one_of(st.integers(-5, 5), st.floats(-1e3, 1e3, allow_nan=False))
kinds = [numbers, st.text("abc", min_size=1, max_size=3), st.booleans()]
scalars = st.one_of(*kinds)
names = st.text("pqrstuvwxyz", min_size=1, max_size=4)


@st.composite
def specs(draw):
    pnames = draw(st.lists(names, min_size=0, max_size=3, unique=True))
    grid = {n: draw(st.lists(draw(st.sampled_from(kinds)), min_size=1, max_size=3, unique_by=lambda v: (type(v), v)))
            for n in pnames}
    data = {"experiment": "sweep_fixtures:fast", "metrics": ["value"], "grid": grid}
    if draw(st.booleans()):
        data["random"] = {"n_samples": draw(st.integers(1, 3)),
                          "rnd": {"distribution": "uniform", "low": -1.0, "high": draw(st.floats(-0.5, 10))}}
    if draw(st.booleans()):
        data["n_seeds"] = draw(st.integers(1, 3))
    else:
        data["seeds"] = draw(st.lists(st.integers(0, 100), min_size=1, max_size=3, unique=True))
    data["base_seed"] = draw(st.integers(0, 2**40))
    return data


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(specs())
def test_expansion_counts_ids_and_determinism(data):
    spec = sweep.parse_spec(data)
    tasks = sweep.expand(spec)
    n_seeds = len(data["seeds"]) if "seeds" in data else data["n_seeds"]
    n_samples = data["random"]["n_samples"] if "random" in data else 1
    assert len(tasks) == math.prod(len(v) for v in data["grid"].values()) * n_samples * n_seeds == spec.n_tasks
    assert len({t.task_id for t in tasks}) == len(tasks)
    assert [t.task_id for t in sweep.expand(data)] == [t.task_id for t in tasks]
    assert all(0 <= t.seed < 2**31 for t in tasks)
    if "random" in data:
        hi = data["random"]["rnd"]["high"]
        assert all(-1.0 <= t.params["rnd"] <= hi for t in tasks)
    if "seeds" in data:
        assert all(t.seed in data["seeds"] for t in tasks)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(specs(), st.data())
def test_a_cells_seeds_do_not_depend_on_the_rest_of_the_grid(data, more):
    """Each cell is reproducible alone: dropping the other grid values leaves its seeds and ids unchanged."""
    if not data["grid"]:
        return
    spec = sweep.parse_spec(data)
    tasks = sweep.expand(spec)
    pick = more.draw(st.sampled_from(tasks))
    alone = {**data, "grid": {n: [pick.params[n]] for n in data["grid"]}}
    assert {(t.task_id, t.seed) for t in tasks if t.cell_id == pick.cell_id} <= {
        (t.task_id, t.seed) for t in sweep.expand(alone)}


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["experiment", "grid", "random", "fixed", "seeds", "n_seeds", "base_seed",
                                        "metrics", "scheduler", "name", "other"]),
                       st.one_of(scalars, st.lists(scalars, max_size=3), st.dictionaries(names, st.one_of(
                           scalars, st.lists(scalars, max_size=3),
                           st.dictionaries(st.sampled_from(["distribution", "low", "high", "values", "mean", "std"]),
                                           st.one_of(scalars, st.sampled_from(["uniform", "normal", "choice"]))
                                           )), max_size=3)), max_size=8))
def test_any_mapping_parses_or_raises_config_error(data):
    """The parser never raises anything but ConfigError, and what it accepts expands."""
    try:
        spec = sweep.parse_spec(data)
    except ConfigError as exc:
        key = str(exc).split(":", 1)[0]
        assert key.split(".")[0] in data or key in ("experiment", "metrics", "random.n_samples")
        return
    assert len(sweep.expand(spec)) == spec.n_tasks


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.one_of(st.text(max_size=120), st.sampled_from([
    'experiment = "sweep_fixtures:fast"\nmetrics = ["value"]\n[grid]\na = [1, 2]\n',
    'experiment = "m:f"\nmetrics = ["v"]\n[random]\nn_samples = 2\nx = {distribution = "normal", mean = 0, std = 1}\n',
])))
def test_load_spec_reads_any_text_or_raises_config_error(tmp_path, text):
    path = tmp_path / "any.toml"
    path.write_text(text, encoding="utf-8")
    try:
        spec = sweep.load_spec(path)
    except ConfigError as exc:
        assert str(exc).startswith(str(path))
        return
    assert spec.name == "any" and len(sweep.expand(spec)) == spec.n_tasks


def test_a_busy_dashboard_port_is_not_reported_to_the_user(tmp_path):
    """The local cluster's scheduler serves HTTP on a free local port, not on Dask's 8787:
    with 8787 taken (another sweep or a Dask cluster running) nothing is warned about."""
    import socket

    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        holder.bind(("0.0.0.0", 8787))
        holder.listen(1)
    except OSError:
        pass  # already taken by someone else: just as busy
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = sweep.run(SPEC, out=tmp_path, workers=1, progress=False)
    finally:
        holder.close()
    assert res.ran == 8
    busy = [str(w.message) for w in caught if "already in use" in str(w.message)]
    assert not busy, busy
