"""Replay whisks through ``SurfaceMatcher`` with two copies of ``maps/_surface_numba.py`` and compare every output.

A speed change of the surface kernels must not change a bit of the matcher's results: this
script loads a reference copy of the kernel module (e.g. from an export of main) under another
module name, replays the same whisks through :class:`maps.surface_match.SurfaceMatcher` with
the reference kernels and with this tree's, and checks with ``np.array_equal`` after every
whisk: the impulses, log evidence, ``evidence_m``, ``last_scores_m``, the active set, the
window's contacts, every hypothesis ``R``, ``t`` and log weight; at the end the mean poses and
the generator's next draws. Libraries: ellipsoids of seeded sizes, some shifted away so that
their grids miss the contacts (off-grid hypotheses), 6 objects; whisks moving, standing,
missing, and some placed off every grid; pruning on and off, with and without initial spread,
refinement steps 0, 1 and 2.

Run (exit status 1 on the first difference)::

    git archive main | tar -x -C /tmp/base
    python bench/surface_kernels_equal.py /tmp/base/maps/_surface_numba.py --whisks 120
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

import maps.surface_match as sm
from maps.odometry import SpatialOdometry
from maps.surface_match import SurfaceLibrary, SurfaceMatchConfig, SurfaceMatcher


def _load(path: Path) -> Any:
    spec = importlib.util.spec_from_file_location("surface_numba_reference", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def _ellipsoid(rng: np.random.Generator, n: int, axes: np.ndarray, shift: np.ndarray) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return d * axes + [0.0, 0.0, axes[2]] + shift + rng.normal(0.0, 0.003, (n, 3))


def _library(seed: int) -> tuple[SurfaceLibrary, np.ndarray]:
    rng = np.random.default_rng(seed)
    axes = np.array([0.1, 0.1, 0.175]) * rng.uniform(0.6, 1.4, (6, 3))
    axes[0] = [0.1, 0.1, 0.175]
    shifts = np.zeros((6, 3))
    shifts[4] = [0.0, 0.45, 0.0]  # partly off the contacts
    shifts[5] = [1.0, 1.0, 0.0]  # its grid misses every contact
    pts = [_ellipsoid(rng, 600, a, s) for a, s in zip(axes, shifts)]
    return SurfaceLibrary(pts, [f"o{i}" for i in range(6)]), axes


def _whisks(seed: int, n: int, axes0: np.ndarray, start: np.ndarray) -> list[tuple[Any, Any]]:
    rng = np.random.default_rng(seed + 100)
    out: list[tuple[Any, Any]] = []
    for i in range(n):
        kind = i % 10
        if kind == 3:
            odo = SpatialOdometry([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0)
        else:
            odo = SpatialOdometry(rng.normal(0.0, 0.004, 3), rng.normal(0.0, 0.02, 3), 1.0)
        if i == 0:
            odo = None
        if kind == 5:
            contacts = None
        elif kind == 7:
            contacts = rng.normal(0.0, 0.05, (6, 3)) + [3.0, 3.0, 3.0]  # off every grid
        else:
            contacts = _ellipsoid(rng, int(rng.integers(3, 10)), axes0, np.zeros(3)) - start[:3]
        out.append((odo, contacts))
    return out


def _snapshot(m: SurfaceMatcher, imp: np.ndarray) -> list[np.ndarray]:
    return [imp, m.log_evidence, m.evidence_m, m.last_scores_m, m.active, np.array(m.window_contacts),
            m._R, m._t, m._logw]


NAMES = ["impulses", "log_evidence", "evidence_m", "last_scores_m", "active", "window_contacts", "R", "t", "logw"]


class _SerialReference:
    """A reference kernel module from before :func:`refine` took its number of parallel runs: the call
    without it (the runs do not change a result, so the comparison stays bit for bit)."""

    def __init__(self, module: Any) -> None:
        self._module = module

    def __getattr__(self, name: str) -> Any:
        return getattr(self._module, name)

    @staticmethod
    def refine_chunks(pairs: int) -> int:
        return 1

    def refine(self, *args: Any) -> Any:
        return self._module.refine(*args[:-1])


def _run(kernels: Any, lib: SurfaceLibrary, start: np.ndarray, cfg: SurfaceMatchConfig,
         whisks: list) -> list[list[np.ndarray]]:
    sm._kernels = lambda: kernels  # noqa: E731
    m = SurfaceMatcher(lib, start, cfg)
    snaps = []
    for odo, contacts in whisks:
        imp = m.step(odo, contacts)
        snaps.append([np.array(a, copy=True) for a in _snapshot(m, imp)])
    snaps.append([m.poses, m._rng.random(8)])
    return snaps


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reference", type=Path, help="the reference copy of maps/_surface_numba.py")
    ap.add_argument("--whisks", type=int, default=120)
    args = ap.parse_args()
    ref = _load(args.reference)
    if not hasattr(ref, "refine_chunks"):
        ref = _SerialReference(ref)
    from maps import _surface_numba as mine

    if Path(mine.__file__).resolve() == args.reference.resolve():
        print("the reference is this tree's own kernel module")
        return 1
    original = sm._kernels
    start = np.array([0.0, -0.3, 0.175, 0.0, 0.0, 0.0, 1.0])
    checked = 0
    for seed in (0, 1):
        lib, axes = _library(seed)
        whisks = _whisks(seed, args.whisks, axes[0], start)
        for refine in (0, 1, 2):
            for prune in (30.0, 1e9):
                for spread in (0.0, 0.01):
                    cfg = SurfaceMatchConfig(refine_iterations=refine, prune_margin=prune, initial_sigma_m=spread,
                                             initial_sigma_deg=spread * 300, particles=50, seed=seed)
                    a = _run(ref, lib, start, cfg, whisks)
                    b = _run(mine, lib, start, cfg, whisks)
                    sm._kernels = original
                    for w, (sa, sb) in enumerate(zip(a, b)):
                        names = NAMES if w < len(whisks) else ["poses", "next draws"]
                        for name, x, y in zip(names, sa, sb):
                            if not np.array_equal(x, y):
                                print(f"DIFFERENT: seed {seed} refine {refine} prune {prune} spread {spread} "
                                      f"whisk {w} {name}: max |diff| {np.max(np.abs(np.asarray(x, float) - y))}")
                                return 1
                            checked += 1
                    print(f"seed {seed} refine {refine} prune {prune:g} spread {spread}: {len(whisks)} whisks equal, "
                          f"{int(b[-2][4].sum())} objects left")
    print(f"all equal ({checked} arrays)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
