"""The studies' worker pool (``cansim.studies.process_pool.pool_map``): results in job order, one numba
thread per worker process, the jobs run in this process when ``workers <= 1``."""

from __future__ import annotations

import os
import warnings

import numba
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.studies.process_pool import pool_map


def _square_and_threads(x: int) -> tuple[int, int, int]:
    return x * x, numba.get_num_threads(), os.getpid()


def test_workers_return_results_in_job_order_on_one_numba_thread_each() -> None:
    out = pool_map(_square_and_threads, list(range(9)), workers=2, desc="test", progress=False)
    assert [r[0] for r in out] == [x * x for x in range(9)]
    assert {r[1] for r in out} == {1}  # every worker's kernels on one thread
    assert os.getpid() not in {r[2] for r in out}  # run in other processes


def test_one_worker_runs_the_jobs_here_on_this_process_threads() -> None:
    out = pool_map(_square_and_threads, [3, 1, 2], workers=1, desc="test", progress=False)
    assert [r[0] for r in out] == [9, 1, 4]
    assert {r[2] for r in out} == {os.getpid()}
    assert {r[1] for r in out} == {numba.get_num_threads()}  # this process' setting, untouched


@settings(max_examples=6, deadline=None)
@given(st.lists(st.integers(-1000, 1000), max_size=7), st.integers(0, 3))
def test_any_jobs_any_workers_give_the_in_order_results(jobs: list[int], workers: int) -> None:
    out = pool_map(_square_and_threads, jobs, workers=workers, desc="test", progress=False)
    assert [r[0] for r in out] == [x * x for x in jobs]


def _warn_twice(k: int) -> tuple[int, int]:
    """Warn a FutureWarning and a UserWarning (messages unique per job, so no once-per-place registry hides them);
    how many of each were shown."""
    with warnings.catch_warnings(record=True) as shown:
        warnings.warn(f"future {k}", FutureWarning)
        warnings.warn(f"user {k}", UserWarning)
    return sum(w.category is FutureWarning for w in shown), sum(w.category is UserWarning for w in shown)


def test_quiet_warnings_are_not_shown_by_the_jobs_here_or_in_the_workers() -> None:
    """quiet=(FutureWarning,): the jobs show no FutureWarning, in this process and in worker processes; other
    warnings still show; and this process' own filters are as they were afterwards."""
    before = list(warnings.filters)
    for workers in (1, 2):
        assert pool_map(_warn_twice, [0, 1, 2], workers, "test", False, quiet=(FutureWarning,)) == [(0, 1)] * 3
        assert pool_map(_warn_twice, [3, 4], workers, "test", False) == [(1, 1)] * 2
    assert warnings.filters == before

