"""pytest plugin: which numba functions a test run compiles, how often, and for how long.

Listens to numba's ``numba:compile`` events (one per compiled specialisation, i.e. per
distinct tuple of argument types; nested compilations of called functions included; a
specialisation loaded from numba's on-disk cache raises no event) and, at the end of the
session, prints per function the number of specialisations compiled and their compile
time without the nested compilations ("self"), largest first, and the total. With
``NUMBA_COMPILES_JSON=FILE`` every event (function, argument types, seconds, nesting
depth, test id) is also written to FILE.

Usage (from the checkout's root; a cold cache shows everything a fresh machine compiles)::

    NUMBA_CACHE_DIR=$(mktemp -d) PYTHONPATH=bench python -m pytest -q -p numba_compiles tests/test_x.py

A function listed several times with argument types that differ only in ``Literal[...]``
or ``readonly`` arrays is compiled more often than its work needs: pass it ``np.int64`` /
``np.bool_`` values and writable arrays instead. Seconds are wall time (the machine's
load inflates them); not collected by pytest (no ``test_`` prefix).
"""
from __future__ import annotations

import collections
import json
import os
import time

from numba.core import event

_RECORDS: list = []
_STARTS: list = []
_TEST = ["<collection>"]


class _Listener(event.Listener):
    def on_start(self, ev):
        _STARTS.append(time.perf_counter())

    def on_end(self, ev):
        t0 = _STARTS.pop()
        data = ev.data or {}
        func = getattr(data.get("dispatcher"), "py_func", None)
        name = f"{getattr(func, '__module__', '?')}.{getattr(func, '__qualname__', '?')}"
        _RECORDS.append(dict(func=name, args=str(data.get("args")), sec=time.perf_counter() - t0,
                             depth=len(_STARTS), test=_TEST[0]))


event.register("numba:compile", _Listener())


def pytest_runtest_setup(item):
    _TEST[0] = item.nodeid


def _self_times() -> dict:
    """Per function: [specialisations, seconds without nested compilations]."""
    by: dict = collections.defaultdict(lambda: [0, 0.0])
    nested: dict = collections.defaultdict(float)  # depth -> seconds of finished children
    for r in _RECORDS:  # events end children first
        d = r["depth"]
        own = r["sec"] - nested.pop(d + 1, 0.0)
        nested[d] += r["sec"]
        by[r["func"]][0] += 1
        by[r["func"]][1] += own
    return by


def pytest_terminal_summary(terminalreporter):
    by = _self_times()
    tr = terminalreporter
    tr.section("numba compilations (self seconds, specialisations)")
    for func, (n, sec) in sorted(by.items(), key=lambda kv: -kv[1][1])[:40]:
        tr.write_line(f"{sec:8.2f} s {n:4d}  {func}")
    tr.write_line(f"total: {sum(n for n, _ in by.values())} specialisations, "
                  f"{sum(s for _, s in by.values()):.1f} s compiling")
    out = os.environ.get("NUMBA_COMPILES_JSON")
    if out:
        with open(out, "w") as f:
            json.dump(_RECORDS, f)
