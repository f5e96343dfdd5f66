"""Tests of the slope distribution array and NMSE (Sec 5.1.1.1.3, Eq 5.3-5.4)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from whisker_io.contact.detection import detect_contact, detect_contacts
from whisker_io.array.control import OpenLoop, WhiskPattern
from whisker_io.errors import InvalidInputError
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.features.sda import contact_gradient, nmse, slope_distribution
from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
from whisker_io.sim.simulator import ArraySimulator


def _tilted_contact(theta_c: float, tilt: float, a: float = 0.05) -> WhiskContact:
    n = [math.cos(theta_c) * math.cos(tilt), math.sin(theta_c) * math.cos(tilt), math.sin(tilt)]
    return WhiskContact(theta_c, a, 0.1, normal=n)


def test_gradient_of_exact_line_is_recovered():
    T = 2000
    k = np.arange(T, dtype=float)
    x = np.clip(k - 500, 0, 600) - np.clip(k - 1100, 0, 600) * 1.0  # up 600 samples, then down
    rec = WhiskRecord("B2", np.linspace(-0.8, 0.8, T), x, -2.5 * x)
    c = detect_contact(rec)
    assert c is not None and c.sign == -1
    assert contact_gradient(rec, c) == pytest.approx(-2.5, rel=1e-9)


def test_sda_recovers_sign_and_order_of_tilts():
    """Surfaces tilted about the shaft by +-20..50 deg: gradient = cot(tilt) (unsaturated contacts)."""
    tilts = np.radians([-50.0, -35.0, -20.0, 20.0, 35.0, 50.0])
    theta_c = math.radians(10.0)
    recs, _ = simulate_whisk_cycle(
        [_tilted_contact(theta_c, t, a=0.07) for t in tilts] + [None], OpenLoop(WhiskPattern(1.0)), seed=11
    )
    sda = slope_distribution(recs, detect_contacts(recs))
    assert sda.mask.tolist() == [True] * 6 + [False]
    got = sda.slopes[:6]
    expected = 1.0 / np.tan(tilts)
    assert np.array_equal(np.sign(got), np.sign(expected))
    assert np.array_equal(np.argsort(got), np.argsort(expected))
    np.testing.assert_allclose(got, expected, rtol=0.1)


def test_sda_masks_squarely_facing_surface():
    recs, _ = simulate_whisk_cycle([WhiskContact(0.0, 0.05, 0.1)], seed=0)  # normal in the whisk plane: x flat
    sda = slope_distribution(recs, detect_contacts(recs))
    assert not sda.mask[0] and sda.slopes[0] == 0.0


def _plane(tilt_rad: float, y0: float) -> trimesh.Trimesh:
    slab = trimesh.creation.box(extents=[1.0, 0.01, 1.0])
    slab.apply_transform(trimesh.transformations.rotation_matrix(tilt_rad, [1, 0, 0]))
    slab.apply_translation([0.0, y0, 0.0])
    return slab


def test_sda_on_tilted_plane_through_the_simulator_follows_geometry():
    """Through sweep + signals + detection: per whisker, SDA sign and order over tilts follow
    n_y / n_x of the plane normal on the sensor axes (closed-form from the contact frame)."""
    tilts = np.radians([10.0, 20.0, 30.0])
    got = np.full((len(tilts), 18), np.nan)
    expected = np.full((len(tilts), 18), np.nan)
    for j, tilt in enumerate(tilts):
        sim = ArraySimulator(seed=j)
        res = sim.whisk(_plane(tilt, 0.24), np.eye(4))
        sda = slope_distribution(res.records, detect_contacts(res.records))
        for i, sc in enumerate(res.sweep_contacts):
            if sc is None or not sda.mask[i]:
                continue
            n = sc.normal
            ny, nx = float(n @ sc.frame[:3, 0]), float(n @ sc.frame[:3, 2])
            if abs(nx) > 0.1 * abs(ny):  # well-defined slope
                got[j, i], expected[j, i] = sda.slopes[i], ny / nx
    both = np.isfinite(got) & np.isfinite(expected)
    assert both.sum() >= 20
    assert np.array_equal(np.sign(got[both]), np.sign(expected[both]))
    ordered = 0
    for i in range(18):
        ok = both[:, i]
        if ok.sum() >= 2:
            assert np.array_equal(np.argsort(got[ok, i]), np.argsort(expected[ok, i]))
            ordered += 1
    assert ordered >= 6


def test_nmse_hand_computed_and_masked():
    x = np.array([1.0, 2.0, 3.0, 4.0])
    y = np.array([1.0, 2.0, 5.0, 0.0])
    assert nmse(x, x) == 0.0
    assert nmse(x, y) == pytest.approx((0 + 0 + 4 + 16) / (1 + 4 + 9 + 16))
    mask = np.array([True, True, True, False])
    assert nmse(x, y, mask, mask) == pytest.approx(4 / 14)
    assert nmse(x, y, mask, np.array([False, True, False, True])) == pytest.approx(0.0)
    assert nmse(x, y, np.zeros(4, bool)) == math.inf
    assert nmse(np.zeros(2), np.zeros(2)) == 0.0 and nmse(np.zeros(2), np.ones(2)) == math.inf


def test_bad_input():
    with pytest.raises(InvalidInputError):
        nmse(np.ones(3), np.ones(4))
    with pytest.raises(InvalidInputError):
        nmse(np.array([np.nan, 1.0]), np.ones(2))
    with pytest.raises(InvalidInputError):
        slope_distribution([], [None])


def test_sda_plots_bars_per_module_and_nmse_title():
    import matplotlib

    matplotlib.use("Agg")
    from whisker_io.plots.signals import plot_sda, plot_xy_gradient

    tilts = np.radians([-35.0, 20.0, 50.0])
    recs, _ = simulate_whisk_cycle([_tilted_contact(math.radians(10.0), t, a=0.07) for t in tilts] + [None], seed=2)
    dets = detect_contacts(recs)
    sda = slope_distribution(recs, dets)
    fig = plot_sda(sda, reference=sda)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == [r.module for r in recs]
    assert "NMSE = 0" in ax.get_title()
    heights = sorted(p.get_height() for p in ax.patches if p.get_height() != 0.02)
    np.testing.assert_allclose(heights, sorted(np.repeat(sda.slopes[:3], 2)))
    fig2 = plot_xy_gradient(recs[0], dets[0])
    assert f"gradient {sda.slopes[0]:.2f}" in [t.get_text() for t in fig2.axes[0].get_legend().get_texts()]
    import matplotlib.pyplot as plt

    plt.close("all")


# ------------------------------------------------- issue 17: no NaN, typed errors
def test_nmse_near_the_float_limit_is_finite_hand_computed():
    # MSE = (1e200)^2, power = (1e200)^2: the ratio is 1, although both squares overflow
    assert nmse([1e200], [0.0]) == 1.0
    # x = (1e200, 0), y = (0, 1e200): MSE = 1e400, power = 1e400 / 2 -> 2
    assert nmse([1e200, 0.0], [0.0, 1e200]) == pytest.approx(2.0)
    assert nmse([1e-200], [0.0]) == 1.0  # and no underflow to 0/0 either
    for bad in ("abc", [["a"]], None):
        with pytest.raises(InvalidInputError):
            nmse(bad, [0.0])


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_vals = st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=18)


@settings(max_examples=100, deadline=None)
@given(_vals, st.integers(-250, 250), st.data())
def test_nmse_is_scale_free_and_never_nan(x, exp10, data):
    y = data.draw(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=len(x), max_size=len(x)))
    base = nmse(x, y)
    c = 10.0**exp10
    scaled = nmse(np.asarray(x) * c, np.asarray(y) * c)
    assert not math.isnan(base) and not math.isnan(scaled) and base >= 0
    if math.isfinite(base) and all(abs(v) * c > 1e-300 or v == 0 for v in x + y):
        assert scaled == pytest.approx(base, rel=1e-9, abs=1e-12)


def test_nmse_against_many_stored_arrays_equals_one_by_one():
    rng = np.random.default_rng(5)
    x = rng.normal(size=18)
    stored = rng.normal(size=(7, 18))
    stored[3] = x
    stored[5] = 0.0
    many = nmse(x, stored)
    assert many.shape == (7,)
    for k in range(7):
        assert many[k] == nmse(x, stored[k])
    assert many[3] == 0.0 and many[5] == pytest.approx(1.0)  # identical; all-zero stored -> MSE(x,0)/MSE(x,0)
    masks = rng.random((7, 18)) > 0.3
    many_m = nmse(x, stored, None, masks)
    for k in range(7):
        assert many_m[k] == nmse(x, stored[k], None, masks[k])


@pytest.mark.parametrize("scale", [1.0, 1e150, 1e300])
def test_the_gradient_is_scale_free_up_to_the_float_limit(scale):
    """Signals scaled to 1e300 gave NaN slopes marked valid (issue 25): the same line, any scale, the same gradient."""
    T = 2000
    k = np.arange(T, dtype=float)
    x = np.clip(k - 500, 0, 600) - np.clip(k - 1100, 0, 600) * 1.0
    base = WhiskRecord("B2", np.linspace(-0.8, 0.8, T), x, -2.5 * x)
    c = detect_contact(base)
    rec = WhiskRecord("B2", np.linspace(-0.8, 0.8, T), x * scale, -2.5 * x * scale)
    assert contact_gradient(rec, c) == pytest.approx(-2.5, rel=1e-9)
    sda = slope_distribution([rec], [c])
    assert sda.mask.tolist() == [True] and np.isfinite(sda.slopes).all()
