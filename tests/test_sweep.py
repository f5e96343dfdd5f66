"""Rigid-whisker sweep simulator (Sec 4.1.2.3, 6.1.3.1, Sec 4.1.2.3) against closed-form geometry."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.array.geometry import WhiskerArray, WhiskerModule
from whisker_io.array.kinematics import whisker_base_transforms
from whisker_io.sim.objects import make_object
from whisker_io.sim.sweep import (
    ContactNoise,
    MeshTarget,
    SweepContact,
    SweepParams,
    add_contact_noise,
    embree_available,
    perturb_contacts,
    sweep_array,
)

ENGINES = ["embree", "triangle"] if embree_available() else ["triangle"]
ANGLE_TOL = np.deg2rad(0.5)
POINT_TOL = 1e-3


@pytest.fixture(scope="module")
def arr() -> WhiskerArray:
    return WhiskerArray.thesis()


def _wall(y0: float, front: bool = True) -> trimesh.Trimesh:
    """A 2 m x 2 m slab occupying y >= y0 (front) or y <= y0 (behind)."""
    m = trimesh.creation.box(extents=(2.0, 1.0, 2.0))
    m.apply_translation((0.0, y0 + 0.5 if front else y0 - 0.5, 0.0))
    return m


def _random_rigid(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    T[:3, 3] = rng.uniform(-1, 1, 3)
    return T


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("motion_seed", [None, 11])
def test_plane_in_front_matches_closed_form(arr, engine, motion_seed):
    """Wall y >= 0.25 m: the tip (the most rostral point of the shaft) reaches it first, at
    sin(theta) = (0.25 - p_y) / L; normal (0,-1,0) gives n_x = -cos(theta), n_y = sin(theta),
    slope = -tan(theta) (Eq 6.12-6.14). The same after moving scene and array together."""
    y0 = 0.25
    mesh, pose = _wall(y0), np.eye(4)
    M = np.eye(4) if motion_seed is None else _random_rigid(motion_seed)
    mesh.apply_transform(M)
    pose = M @ pose
    res = sweep_array(arr, MeshTarget(mesh, engine), pose)
    n_contacts = 0
    for m, c in zip(arr.modules, res):
        s = (y0 - m.base_position_m[1]) / m.length_m
        if abs(s) > np.sin(arr.protraction_rad):
            assert c is None, m.name
            continue
        n_contacts += 1
        theta = np.arcsin(s)
        radial = m.base_position_m * [1, 0, 1]
        radial /= np.linalg.norm(radial)
        p_local = m.base_position_m + m.length_m * (np.cos(theta) * radial + np.sin(theta) * np.array([0, 1, 0]))
        p = M[:3, :3] @ p_local + M[:3, 3]
        assert c.module == m.name
        assert abs(c.angle_rad - theta) < ANGLE_TOL
        assert abs(c.angle_rad - theta) < 1e-5  # refinement is far tighter than required
        assert np.linalg.norm(c.point - p) < POINT_TOL
        assert abs(c.radial_distance_m - m.length_m) < POINT_TOL
        np.testing.assert_allclose(c.normal, M[:3, :3] @ [0, -1, 0], atol=1e-9)
        assert abs(c.slope - (-np.tan(theta))) < 1e-3
        assert c.whisker_length_m == m.length_m
        np.testing.assert_allclose(c.frame[:3, 3] + c.radial_distance_m * c.frame[:3, 1], c.point, atol=1e-9)
    assert n_contacts == 12  # rows 2 and 3 reach the wall, row 1 does not


def test_wall_behind_gives_contact_at_retraction_limit(arr):
    """Slab y <= p_y - 0.05 behind row 3: already touched at -50 deg where the shaft
    crosses y0, r = (p_y - y0) / sin(50 deg); row 2 likewise; row 1 cannot reach."""
    y0 = 0.161946 - 0.05
    res = sweep_array(arr, _wall(y0, front=False), np.eye(4))
    for m, c in zip(arr.modules, res):
        r = (m.base_position_m[1] - y0) / np.sin(np.deg2rad(50))
        if r > m.length_m:
            assert c is None
        else:
            assert np.isclose(c.angle_rad, arr.retraction_rad)
            assert abs(c.radial_distance_m - r) < POINT_TOL


def _sphere_closed_form(T_BW, length, centre, rho, lo, hi):
    """First contact of a segment [0, L] rotating from lo to hi about the base frame's z
    with the circle the sphere cuts from the whisking plane. Returns (theta, r), None
    (never touched in range) or "skip" (not covered: touched before lo or base inside)."""
    b, X, Y, Z = T_BW[:3, 3], T_BW[:3, 0], T_BW[:3, 1], T_BW[:3, 2]
    cx, cy, cz = (centre - b) @ X, (centre - b) @ Y, (centre - b) @ Z
    if abs(cz) >= rho:
        return None
    rp = np.sqrt(rho**2 - cz**2)
    D = np.hypot(cx, cy)
    if D <= rp * 1.05:
        return "skip"
    psi = np.arctan2(-cx, cy)  # angle at which the shaft points at the circle centre
    tangent = np.sqrt(D**2 - rp**2)
    if tangent <= length:
        theta, r = psi - np.arcsin(rp / D), tangent
    elif D - rp <= length:
        theta, r = psi - np.arccos((length**2 + D**2 - rp**2) / (2 * length * D)), length
    else:
        return None
    if theta < lo:
        return "skip"
    if theta > hi:
        return None
    return theta, r


@pytest.fixture(scope="module")
def sphere_target():
    """A fine icosphere (327k faces, facet sag < 10 um) so a tangent contact's position is
    fixed to well under 1 mm by the mesh; Embree only (the fallback would take minutes)."""
    if not embree_available():
        pytest.skip("needs embree for a 327k-face sphere")
    m = trimesh.creation.icosphere(subdivisions=7, radius=0.08)
    return MeshTarget(m, "embree")


def test_sphere_matches_closed_form(arr, sphere_target):
    rho = 0.08
    kinds = {"tangent": 0, "tip": 0, "none": 0}
    for seed in range(12):
        rng = np.random.default_rng(seed)
        # place the array so its front faces the sphere at the origin, randomly offset
        R = Rotation.random(random_state=seed).as_matrix()
        pose = np.eye(4)
        pose[:3, :3] = R
        pose[:3, 3] = -R @ np.array([rng.uniform(-0.1, 0.1), rng.uniform(0.27, 0.33), rng.uniform(-0.1, 0.1)])
        res = sweep_array(arr, sphere_target, pose)
        T_BW = whisker_base_transforms(arr, pose)
        for i, (m, c) in enumerate(zip(arr.modules, res)):
            exp = _sphere_closed_form(T_BW[i], m.length_m, np.zeros(3), rho, arr.retraction_rad, arr.protraction_rad)
            if isinstance(exp, str):
                continue
            if exp is None:
                assert c is None, (seed, m.name)
                kinds["none"] += 1
                continue
            theta, r = exp
            assert c is not None, (seed, m.name)
            p = T_BW[i, :3, 3] + r * (np.cos(theta) * T_BW[i, :3, 1] - np.sin(theta) * T_BW[i, :3, 0])
            assert abs(c.angle_rad - theta) < ANGLE_TOL, (seed, m.name)
            assert np.linalg.norm(c.point - p) < POINT_TOL, (seed, m.name)
            assert abs(np.linalg.norm(c.point) - rho) < 1e-4  # on the sphere
            kinds["tip" if np.isclose(r, m.length_m) else "tangent"] += 1
    assert kinds["tangent"] >= 5 and kinds["tip"] >= 5 and kinds["none"] >= 5, kinds


@pytest.mark.parametrize("engine", ENGINES)
def test_thin_post_between_steps_found_by_tip_chords(engine):
    """A 0.6 mm post centred 0.1 mm inside the tip circle, half-way between two 1-deg shaft
    rays (tip spacing 2.8 mm): only the tip chords see it. Closed form: tangent contact at
    psi - asin(rho/D), r = sqrt(D^2 - rho^2)."""
    L, D, rho, psi = 0.16, 0.1599, 0.0003, np.deg2rad(10.5)
    one = WhiskerArray((WhiskerModule("P", "A", 3, [0.05, 0.2, 0.0], L),))
    # frame: x = -Y, y = +X, z = +Z, so the whisking plane is z = 0 and the shaft at psi is
    # cos(psi) X + sin(psi) Y
    centre = np.array([0.05, 0.2, 0.0]) + D * np.array([np.cos(psi), np.sin(psi), 0.0])
    post = trimesh.creation.cylinder(radius=rho, height=0.05, sections=128)
    post.apply_translation(centre)
    target = MeshTarget(post, engine)
    assert sweep_array(one, target, np.eye(4), SweepParams(tip_chords=False))[0] is None
    (c,) = sweep_array(one, target, np.eye(4))
    theta = psi - np.arcsin(rho / D)
    assert abs(c.angle_rad - theta) < ANGLE_TOL
    assert abs(c.radial_distance_m - np.sqrt(D**2 - rho**2)) < POINT_TOL


def kettle_pose(seed: int, distance: float) -> np.ndarray:
    """Array axis along a random direction, aimed at the kettle's middle from ``distance``."""
    R = Rotation.random(random_state=seed).as_matrix()
    pose = np.eye(4)
    pose[:3, :3] = R
    pose[:3, 3] = np.array([0.0, 0.0, 0.15]) - R[:, 1] * distance
    return pose


def test_engines_agree_on_kettle(arr):
    if not embree_available():
        pytest.skip("embree not installed")
    mesh = make_object("kettle")
    emb, tri = MeshTarget(mesh, "embree"), MeshTarget(mesh, "triangle")
    n = 0
    for seed, dist in [(262, 0.30), (59, 0.36), (209, 0.30)]:
        pose = kettle_pose(seed, dist)
        a = sweep_array(arr, emb, pose)
        b = sweep_array(arr, tri, pose)
        assert [x is None for x in a] == [x is None for x in b]
        for ca, cb in zip(a, b):
            if ca is None:
                continue
            n += 1
            assert abs(ca.angle_rad - cb.angle_rad) < 1e-4
            assert np.linalg.norm(ca.point - cb.point) < 1e-4
            assert abs(ca.radial_distance_m - cb.radial_distance_m) < 1e-4
            # a first touch of a convex faceted surface is often exactly on an edge or
            # vertex; then either adjacent face is a valid answer
            shared = set(mesh.faces[ca.face]) & set(mesh.faces[cb.face])
            assert ca.face == cb.face or shared, (ca.face, cb.face)
    assert n >= 25


def test_free_whisking_gives_none(arr):
    far = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    far.apply_translation((5.0, 5.0, 5.0))
    assert sweep_array(arr, far, np.eye(4)) == (None,) * 18


def test_bad_engine_and_params():
    with pytest.raises(InvalidInputError, match="engine"):
        MeshTarget(make_object("box"), "optix")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        SweepParams(step_rad=0.0)
    with pytest.raises(InvalidInputError):
        SweepParams(refine_subdivisions=1)
    with pytest.raises(InvalidInputError):
        ContactNoise(registration_probability=1.5)


def _contact(length=0.1, r=0.05, slope=0.5) -> SweepContact:
    frame = np.eye(4)
    return SweepContact("X", 0.1, r, np.array([0.0, r, 0.0]), np.array([0.0, -1.0, 0.0]), slope, length, frame, 0)


def test_noise_model_is_seeded_and_calibrated():
    n = 20000
    cs = [_contact()] * n
    a = add_contact_noise(cs, rng=5)
    b = add_contact_noise(cs, rng=5)
    assert [x is None for x in a] == [x is None for x in b]
    assert all(x is None or np.array_equal(x.point, y.point) for x, y in zip(a, b))
    kept = [x for x in a if x is not None]
    assert abs(len(kept) / n - 0.98) < 0.006  # 3 sigma of a binomial(20000, 0.98)
    slopes = np.array([x.slope for x in kept])
    assert abs(slopes.std() - 0.33) < 0.015 and abs(slopes.mean() - 0.5) < 0.015
    # shaft mode: points stay on the whisker, r within [0, L]
    pts = np.array([x.point for x in kept])
    r = np.array([x.radial_distance_m for x in kept])
    np.testing.assert_allclose(pts[:, [0, 2]], 0.0, atol=1e-15)
    np.testing.assert_allclose(pts[:, 1], r)
    assert r.min() >= 0.0 and r.max() <= 0.1
    # unclipped core has the thesis' spread 0.25 L: P(|e| < 0.025) = P(|z| < 1) = 0.683
    assert abs(np.mean(np.abs(r - 0.05) < 0.025) - 0.683) < 0.015
    assert cs[0].point[1] == 0.05  # inputs untouched


def test_isotropic_noise_and_none_passthrough():
    cs = [_contact(), None] * 5000
    out = add_contact_noise(cs, ContactNoise(position_mode="isotropic", registration_probability=1.0), rng=1)
    assert all(o is None for o in out[1::2])
    d = np.array([o.point - np.array([0, 0.05, 0]) for o in out[0::2]])
    np.testing.assert_allclose(d.std(axis=0), 0.025, rtol=0.05)


def test_perturb_contacts_hand_checked_cases():
    present = np.array([True, False, True, True])
    r = np.array([0.03, 0.0, 0.1, 0.05])
    slope = np.array([0.5, 0.0, -1.0, np.inf])
    L = np.array([0.06, 0.1, 0.1, 0.16])
    quiet = ContactNoise(position_sigma_fraction=0.0, slope_sigma=0.0, registration_probability=1.0)
    kept, r2, s2, off = perturb_contacts(present, r, slope, L, quiet, rng=0)
    np.testing.assert_array_equal(kept, present)
    np.testing.assert_array_equal(r2, r)
    np.testing.assert_array_equal(s2, slope)  # an infinite slope (n_x = 0) stays infinite
    assert not off.any()
    kept, *_ = perturb_contacts(present, r, slope, L, ContactNoise(registration_probability=0.0), rng=0)
    assert not kept.any()
    # isotropic mode: the radial distance is left alone, the offset carries the noise
    iso = ContactNoise(position_mode="isotropic", slope_sigma=0.0, registration_probability=1.0)
    kept, r3, _, off = perturb_contacts(present, r, slope, L, iso, rng=1)
    np.testing.assert_array_equal(r3, r)
    assert not off[1].any() and np.all(np.linalg.norm(off[present], axis=1) > 0)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 30), st.integers(0, 2**32 - 1), st.floats(0.0, 1.0), st.floats(0.0, 2.0))
def test_perturb_contacts_keeps_points_on_their_shafts(n, seed, sigma, slope_sigma):
    rng = np.random.default_rng(seed)
    present = rng.random(n) < 0.7
    L = rng.uniform(0.05, 0.2, n)
    r = rng.uniform(0.0, 1.0, n) * L
    slope = rng.normal(0.0, 1.0, n)
    noise = ContactNoise(position_sigma_fraction=sigma, slope_sigma=slope_sigma)
    kept, r2, s2, off = perturb_contacts(present, r, slope, L, noise, np.random.default_rng(seed))
    assert not (kept & ~present).any()  # never registers a contact that is not there
    assert np.all((r2[present] >= 0.0) & (r2[present] <= L[present]))
    np.testing.assert_array_equal(r2[~present], r[~present])
    assert np.all(np.isfinite(s2)) and not off.any()
    again = perturb_contacts(present, r, slope, L, noise, np.random.default_rng(seed))
    assert all(np.array_equal(u, v) for u, v in zip(again, (kept, r2, s2, off)))


def test_perturb_contacts_bad_input():
    ok = np.ones(3)
    with pytest.raises(InvalidInputError, match="booleans"):
        perturb_contacts(np.ones(3), ok, ok, ok)
    with pytest.raises(ShapeError):
        perturb_contacts(np.ones(3, dtype=bool), ok[:2], ok, ok)
    with pytest.raises(InvalidInputError, match="finite"):
        perturb_contacts(np.ones(3, dtype=bool), np.array([1.0, np.nan, 1.0]), ok, ok)
    with pytest.raises(InvalidInputError, match="ContactNoise"):
        perturb_contacts(np.ones(3, dtype=bool), ok, ok, ok, noise=0.25)  # type: ignore[arg-type]
