"""The registration-refined proposal of the surface matcher (``SurfaceMatchConfig.refine_iterations``).

The refinement kernel (``maps._surface_numba.refine``) against the same Levenberg-Marquardt
step written out in numpy with a finite-difference Jacobian of scipy's trilinear interpolation;
its Laplace weight against a Monte-Carlo integral of the likelihood over the prior; the
field's gradient against finite differences; the matcher with the refinement pulling its
hypotheses onto the surface; refinement off is the blind proposal (the per-object reference of
``tests/test_surface_match.py``); typed errors for bad settings (hypothesis).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import RegularGridInterpolator
from scipy.spatial.transform import Rotation

from maps import _surface_numba
from maps.odometry import SpatialOdometry
from maps.surface_match import SurfaceLibrary, SurfaceMatchConfig, SurfaceMatcher
from whisker_io.errors import ConfigError

from test_surface_match import IDENTITY, _plane, _sphere  # noqa: E402  (the same test surfaces)


_LIBS: dict[str, SurfaceLibrary] = {}


def _lib(kind: str) -> SurfaceLibrary:
    """Stored surfaces built once per test session (a grid takes a few tenths of a second)."""
    if kind not in _LIBS:
        if kind == "ball":
            s = _sphere(0.10, n=1500, seed=1)
            _LIBS[kind] = SurfaceLibrary([s], ["ball"], [s * 2.0])
        else:
            _LIBS[kind] = SurfaceLibrary([_plane(0.0, n=21, half=0.25)], ["plate"], [_plane(0.3, n=21, half=0.25)])
    return _LIBS[kind]


def _signed_field(lib: SurfaceLibrary, k: int) -> RegularGridInterpolator:
    f = lib.fields
    axes = [f.lo[k, i] + f.config.cell_m * np.arange(f.shape[k, i]) for i in range(3)]
    grid = f.values[f.start[k]:f.start[k] + np.prod(f.shape[k])].reshape(f.shape[k])
    return RegularGridInterpolator(axes, grid, bounds_error=False, fill_value=np.nan)


def _args(lib: SurfaceLibrary) -> tuple:
    f = lib.fields
    return f.lo, f.shape, f.start, f.values, f.config.cell_m


def test_the_field_gradient_equals_finite_differences() -> None:
    lib = _lib("ball")
    field = _signed_field(lib, 0)
    rng = np.random.default_rng(2)
    checked = 0
    for x in _sphere(0.1, n=40, seed=3) * rng.uniform(0.9, 1.1, (40, 1)):
        f, ok, *g = _surface_numba._field_grad(x[0], x[1], x[2], 0, *_args(lib))
        assert ok and f == pytest.approx(float(field(x)[0]), abs=1e-12)
        h = 1e-7
        num = [(field(x + h * e)[0] - field(x - h * e)[0]) / (2 * h) for e in np.eye(3)]
        if abs(float(f)) < 0.025:  # off the clipped band the gradient is zero on both sides anyway
            np.testing.assert_allclose(g, num, rtol=1e-5, atol=1e-6)
            checked += 1
    assert checked > 30
    assert _surface_numba._field_grad(5.0, 0.0, 0.0, 0, *_args(lib))[1] is False  # off the grid


def _numpy_refine(lib: SurfaceLibrary, R: np.ndarray, t: np.ndarray, pts: np.ndarray, sd: np.ndarray, sigma: float,
                  outlier: float, cap: float, iterations: int) -> tuple[np.ndarray, np.ndarray, float]:
    """The refinement of the kernel's docstring in numpy: Jacobian by central differences of scipy's
    interpolation over the whitened body-frame step (u, omega), scipy rotations, np.linalg.solve / slogdet."""
    field = _signed_field(lib, 0)

    def pose(R0: np.ndarray, t0: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return R0 @ Rotation.from_rotvec(step[3:]).as_matrix(), t0 + R0 @ step[:3]

    def signed(R0: np.ndarray, t0: np.ndarray) -> np.ndarray:
        v = field(pts @ R0.T + t0)
        return np.where(np.isnan(v), cap, v)

    def system(R0: np.ndarray, t0: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        f = signed(R0, t0)
        r = np.minimum(np.abs(f), cap)
        inside = r < cap
        e = np.exp(-0.5 * (r / sigma) ** 2)
        ll = float(np.sum(np.where(inside, np.log(outlier + e), math.log(outlier + math.exp(-0.5 * (cap / sigma) ** 2)))))
        h = 1e-6
        J = np.stack([(signed(*pose(R0, t0, h * sd * d)) - signed(*pose(R0, t0, -h * sd * d))) / (2 * h) for d in np.eye(6)], axis=1)
        w = np.where(inside, e / (outlier + e) / sigma**2, 0.0)
        return ll, (J * w[:, None]).T @ J, (J * w[:, None]).T @ f, r

    ll, H, g, r = system(R, t)
    eta, lam = np.zeros(6), 1e-3
    for _ in range(iterations):
        d = np.linalg.solve(H + np.eye(6) + lam * np.diag(np.diag(H) + 1.0), -(g + eta))
        R2, t2 = pose(R, t, sd * d)
        ll2, H2, g2, r2 = system(R2, t2)
        if -ll2 + 0.5 * (eta + d) @ (eta + d) < -ll + 0.5 * eta @ eta:
            R, t, eta, ll, H, g, r, lam = R2, t2, eta + d, ll2, H2, g2, r2, lam * 0.1
        else:
            lam *= 10.0
    return R, t, ll - 0.5 * eta @ eta - 0.5 * np.linalg.slogdet(np.eye(6) + H)[1]


@pytest.mark.parametrize("iterations", [1, 3])
def test_the_refinement_kernel_equals_the_numpy_levenberg_marquardt(iterations: int) -> None:
    """Hypotheses 0-3 cm and 0-6 deg off a stored sphere, 6 contacts: the kernel's refined poses and
    Laplace log marginals equal the numpy steps with finite-difference Jacobians."""
    lib = _lib("ball")
    rng = np.random.default_rng(4)
    N = 12
    pts = _sphere(0.1, n=6, seed=5) + rng.normal(0, 0.002, (6, 3))  # contacts felt from the library's origin
    R = Rotation.from_rotvec(rng.normal(0, 0.05, (N, 3))).as_matrix()[None].copy()
    t = rng.normal(0, 0.015, (1, N, 3))
    sd = np.array([0.01, 0.01, 0.01, math.radians(2.5), math.radians(2.5), math.radians(2.5)]) * 2.0
    sigma, outlier, cap = 0.006, 0.05, 0.03
    R_k, t_k = R.copy(), t.copy()
    ll, res = _surface_numba.refine(R_k, t_k, pts, *_args(lib), sigma, outlier, cap, np.zeros(1, np.int64), sd, iterations, 1)
    moved = 0
    for n in range(N):
        R_n, t_n, ll_n = _numpy_refine(lib, R[0, n], t[0, n], pts, sd, sigma, outlier, cap, iterations)
        np.testing.assert_allclose(R_k[0, n], R_n, atol=1e-7)
        np.testing.assert_allclose(t_k[0, n], t_n, atol=1e-8)
        assert ll[0, n] == pytest.approx(ll_n, abs=1e-5)
        moved += int(np.abs(t_n - t[0, n]).max() > 1e-4)
    assert moved >= N // 2  # the steps are taken, not refused
    # the residuals returned are those of the refined poses (the likelihood kernel's)
    _, res_at = _surface_numba.likelihoods(R_k, t_k, pts, *_args(lib), sigma, outlier, cap, np.zeros(1, np.int64))
    np.testing.assert_allclose(res, res_at, atol=1e-12)


def test_the_refinement_does_not_depend_on_how_the_hypotheses_are_split_into_parallel_runs() -> None:
    """Two objects' 13 hypotheses each (some on the ball, some on the plate, some off both grids),
    refined in 1, 2, 3, 7 and 26 runs: every pose, weight and residual bit for bit the same."""
    ball, plate = _sphere(0.10, n=1500, seed=1), _plane(0.0, n=21, half=0.25)
    lib = SurfaceLibrary([ball, plate], ["ball", "plate"], [ball * 2.0, _plane(0.3, n=21, half=0.25)])
    rng = np.random.default_rng(11)
    N = 13
    pts = _sphere(0.1, n=7, seed=5) + rng.normal(0, 0.002, (7, 3))
    R = Rotation.from_rotvec(rng.normal(0, 0.05, (2 * N, 3))).as_matrix().reshape(2, N, 3, 3)
    t = rng.normal(0, 0.015, (2, N, 3))
    t[:, ::4] += 3.0  # every fourth hypothesis off both grids
    sd = np.array([0.01, 0.01, 0.01, math.radians(2.5), math.radians(2.5), math.radians(2.5)]) * 4.0
    rows = np.array([0, 1], dtype=np.int64)
    outputs = []
    for runs in (1, 2, 3, 7, 2 * N):
        R_k, t_k = R.copy(), t.copy()
        ll, res = _surface_numba.refine(R_k, t_k, pts, *_args(lib), 0.006, 0.05, 0.03, rows, sd, 2, runs)
        outputs.append((R_k, t_k, ll, res))
    assert not np.array_equal(outputs[0][1], t)  # hypotheses were moved
    for other in outputs[1:]:
        for a, b in zip(outputs[0], other):
            assert np.array_equal(a, b)
    assert _surface_numba.refine_chunks(1) == 1 and _surface_numba.refine_chunks(0) == 1
    assert 1 <= _surface_numba.refine_chunks(10_000) <= 10_000


def test_the_laplace_weight_is_the_likelihood_integrated_over_the_prior() -> None:
    """A stored plane, 5 contacts in a 10-cm cross, Gaussian likelihood (no outlier floor to speak
    of): the refined weight equals log E_prior[L] by Monte Carlo (400,000 draws of the body-frame
    correction from the prior), for hypotheses on the plane and 8-20 mm off it."""
    lib = _lib("plate")
    pts = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [-0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, -0.1, 0.0]])
    sd = np.array([0.01, 0.01, 0.01, math.radians(2.5), math.radians(2.5), math.radians(2.5)])
    sigma, outlier, cap = 0.006, 1e-12, 0.03
    rng = np.random.default_rng(7)
    draws = rng.normal(size=(400_000, 6)) * sd
    for dz, tilt in ((0.0, 0.0), (0.008, 0.02), (-0.02, -0.03)):
        R0 = Rotation.from_rotvec([tilt, 0.0, 0.0]).as_matrix()
        t0 = np.array([0.01, -0.02, dz])
        R, t = R0[None, None].copy(), t0[None, None].copy()
        ll, _ = _surface_numba.refine(R, t, pts, *_args(lib), sigma, outlier, cap, np.zeros(1, np.int64), sd, 5, 1)
        Rs = R0 @ Rotation.from_rotvec(draws[:, 3:]).as_matrix()
        ts = t0 + draws[:, :3] @ R0.T
        lik, _ = _surface_numba.likelihoods(Rs[None], ts[None], pts, *_args(lib), sigma, outlier, cap, np.zeros(1, np.int64))
        top = lik.max()
        mc = top + math.log(np.mean(np.exp(lik - top)))
        assert ll[0, 0] == pytest.approx(mc, abs=0.03), (dz, tilt)
        assert abs(t[0, 0, 2]) <= abs(dz) + 1e-9  # the refined hypothesis is no farther from the plane


def test_the_refined_matcher_pulls_its_hypotheses_onto_the_surface() -> None:
    """A whisk 15 mm above the stored plane by dead reckoning: the blind proposal keeps the hypotheses
    there (no motion noise), one refinement step with a 5-cm prior brings them within 1 mm."""
    lib = _lib("plate")
    pts = _plane(0.0, n=3, half=0.05) + [0.0, 0.0, -0.015]  # felt 15 mm lower than the start pose says
    for it, worst in ((0, 0.0149), (1, 0.001)):
        cfg = SurfaceMatchConfig(refine_iterations=it, refine_prior_scale=5.0, particles=20, displacement_sigma_m=0.01,
                                 rotation_sigma_deg=2.5)
        m = SurfaceMatcher(lib, IDENTITY, cfg)
        m.step(None, pts)
        if it == 0:
            assert m.last_scores_m[0] > worst
        else:
            assert m.last_scores_m[0] < worst
            assert np.abs(m._t[0, :, 2] - 0.015).max() < worst  # every hypothesis 15 mm up, where the contacts lie on the plane


def test_the_refinement_names_the_own_object_of_two() -> None:
    """A stored ball and plate; the arm stands 22 mm off the start pose it reports (no translation
    noise to undo it: it does not move). The blind proposal cannot find the ball; with the
    refinement the ball's evidence beats the plate's and it gets the impulses, the plate none."""
    ball = _sphere(0.10, n=1500, seed=1)
    lib = SurfaceLibrary([ball, _plane(0.0, n=21, half=0.25)], ["ball", "plate"], [ball * 2.0, _plane(0.3, n=21, half=0.25)])
    got = {}
    for it in (0, 1):
        rng = np.random.default_rng(8)
        cfg = SurfaceMatchConfig(refine_iterations=it, min_window_contacts=12, margin=2.0, tolerance_m=0.006)
        m = SurfaceMatcher(lib, IDENTITY, cfg)
        got[it] = np.zeros(2, dtype=int)
        for _ in range(12):
            whisk = ball[rng.choice(len(ball), 6, replace=False)] - [0.02, 0.0, -0.01]  # felt from (0.02, 0, -0.01)
            got[it] += m.step(SpatialOdometry(np.zeros(3), np.zeros(3), 1.0), whisk)
        if it:
            assert m.log_evidence[0] > m.log_evidence[1] + 10.0
    assert got[1][0] >= 8 and got[1][1] == 0, got
    assert got[0][0] <= 2, got


@pytest.mark.parametrize("seed", [0, 3])
def test_refinement_off_is_the_blind_proposal(seed: int) -> None:
    """``refine_iterations=0`` runs the likelihood kernel on the moved hypotheses: the same hypotheses,
    evidence and impulses as a matcher whose refinement kernel is replaced by a trap."""
    lib = _lib("ball")
    cfg = SurfaceMatchConfig(refine_iterations=0, particles=30, seed=seed, window_whisks=4, min_window_contacts=4)
    a = SurfaceMatcher(lib, IDENTITY, cfg)
    rng = np.random.default_rng(seed)
    stored = lib.points_m
    original = _surface_numba.refine

    def trap(*args: object) -> None:
        raise AssertionError("refine called with refine_iterations=0")

    _surface_numba.refine = trap
    try:
        for i in range(6):
            odo = None if i == 0 else SpatialOdometry([0.002, 0.0, 0.0], rng.normal(0, 0.02, 3), 1.0)
            a.step(odo, stored[rng.choice(len(stored), 4, replace=False)])
    finally:
        _surface_numba.refine = original
    assert np.isfinite(a.log_evidence).all()


_BAD = {"refine_iterations": [-1, 51, 1.5, 0.0, "x", True, None, float("nan")],
        "refine_prior_scale": [0, 0.0, -1.0, float("nan"), float("inf"), 101.0, "x", True, None]}


@settings(max_examples=25, deadline=None)
@given(st.sampled_from([(f, v) for f, vs in _BAD.items() for v in vs]))
def test_bad_refinement_settings_raise(case: tuple[str, object]) -> None:
    field, value = case
    with pytest.raises(ConfigError):
        SurfaceMatchConfig(**{field: value})
