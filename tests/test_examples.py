"""End-to-end outcomes of the examples (run small, assert what they claim)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_ring_attractor_re_anchors_and_beats_dead_reckoning(tmp_path):
    ring = _load("ring_attractor")
    res = ring.run(steps=600, seed=3)
    late = slice(300, None)
    err_ring = np.abs(ring.wrap_deg(res["decoded"] - res["true"]))[late]
    err_dr = np.abs(ring.wrap_deg(res["dead_reckoning"] - res["true"]))[late]
    assert len(res["anchors"]) > 0
    assert err_ring.mean() < 10.0
    assert err_ring.mean() < 0.25 * err_dr.mean()
    assert ring.main(["--steps", "200", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "ring_attractor.png").stat().st_size > 10_000
