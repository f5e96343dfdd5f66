"""Small experiments for the sweep tests: ``run(params, seed) -> dict`` functions.

Importable on Dask workers as ``sweep_fixtures:NAME`` when ``tests/`` is on the path
(pytest puts it there; the cluster tests set ``PYTHONPATH``).
"""

from __future__ import annotations

import os
import time

import numpy as np


def fast(params: dict, seed: int) -> dict:
    """``value = 10 a + b`` and one standard-normal draw of ``default_rng(seed)``."""
    return {
        "value": 10 * params["a"] + params["b"],
        "noise": float(np.random.default_rng(seed).normal()),
        "label": f"a{params['a']}",
        "pid": os.getpid(),
    }


def flaky(params: dict, seed: int) -> dict:
    """As :func:`fast`, but raises for ``a == 2`` (or for every cell once ``SWEEP_FIXTURE_FIXED`` is unset)."""
    if params["a"] == 2 and not os.environ.get("SWEEP_FIXTURE_FIXED"):
        raise ValueError(f"a = {params['a']} is not allowed")
    return fast(params, seed)


def slow(params: dict, seed: int) -> dict:
    """As :func:`fast` after ``params["sleep_s"]`` seconds of work (for the kill-a-worker test)."""
    time.sleep(params.get("sleep_s", 0.5))
    return fast(params, seed)


def incomplete(params: dict, seed: int) -> dict:
    """Returns no ``noise`` key: a missing metric."""
    return {"value": 10 * params["a"] + params["b"]}


def mixed(params: dict, seed: int) -> dict:
    """``value`` is a number for ``a == 1`` and a string otherwise (an experiment with an untidy metric)."""
    value = 10 * params["a"] + params["b"]
    return {"value": value if params["a"] == 1 else f"v{value}"}


def no_seed(params: dict) -> dict:
    """Takes no seed: a wrong signature for an experiment."""
    return {"value": 1}


def keyword_seed(params: dict, *, seed: int = 0) -> dict:
    """The seed only by keyword: the sweep passes it by position, so a wrong signature too."""
    return {"value": 1}
