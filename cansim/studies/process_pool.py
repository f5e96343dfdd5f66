"""Worker processes for the studies' independent jobs, one numba thread each.

A study maps objects, presents them and calibrates thresholds as independent jobs; with
``workers > 1`` they run in that many processes (one per core by default). Some kernels
split their work over numba's threads (the surface matcher's refinement,
``maps._surface_numba.refine``); in a worker process that would put ``workers x threads``
busy threads on ``workers`` cores, so each worker runs its kernels on one thread (the same
rule as the Dask sweeps, :mod:`cansim.tools.sweep`). Results do not depend on it: those
kernels give the same bits on any number of threads.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

__all__ = ["pool_map"]

J = TypeVar("J")
R = TypeVar("R")


def _one_numba_thread(quiet: tuple[type[Warning], ...] = ()) -> None:
    """Worker initialiser: this process's parallel kernels on one thread, the ``quiet`` warnings silenced."""
    import numba

    numba.set_num_threads(1)
    for category in quiet:
        warnings.simplefilter("ignore", category)


def pool_map(fn: Callable[[J], R], jobs: Sequence[J], workers: int, desc: str, progress: bool = True,
             quiet: tuple[type[Warning], ...] = ()) -> list[R]:
    """``[fn(j) for j in jobs]`` in order, in ``workers`` processes when ``workers > 1``.

    Parameters
    ----------
    fn : callable
        A module-level function (it is pickled to the workers).
    jobs : sequence
        Its arguments, one per call.
    workers : int
        Worker processes (<= 1: in this process, on its own numba threads).
    desc : str
        The progress bar's label (tqdm, on stderr).
    progress : bool
        Show the progress bar.
    quiet : tuple of Warning classes
        Warnings the jobs do not show (the caller says them once instead of once per job and process).

    Returns
    -------
    list
        The results in the order of ``jobs``.
    """
    from tqdm import tqdm

    quiet = (quiet,) if isinstance(quiet, type) else tuple(quiet)
    if workers <= 1:
        with warnings.catch_warnings():
            for category in quiet:
                warnings.simplefilter("ignore", category)
            return [fn(j) for j in tqdm(jobs, desc=desc, file=sys.stderr, disable=not progress)]
    with ProcessPoolExecutor(max_workers=workers, initializer=_one_numba_thread, initargs=(tuple(quiet),)) as pool:
        results: list[Any] = list(tqdm(pool.map(fn, jobs), total=len(jobs), desc=desc, file=sys.stderr,
                                       disable=not progress))
    return results
