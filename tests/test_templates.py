"""Tests of the local-view front ends: OpenRatSLAM visual templates and Ch.3 tactile templates (Eq 3.1)."""

import math

import numpy as np
import pytest

from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.frontends.tactile import TactileTemplateConfig, TactileTemplates, tactile_similarity
from cansim.frontends.visual import VisualTemplateConfig, VisualTemplates


def row(*values):
    return np.array([values], dtype=np.uint8)


def small(**kw):
    params = dict(template_width_blocks=4, template_height_blocks=1, shift_match_blocks=1, step_match_blocks=1, match_threshold=0.2)
    params.update(kw)
    return VisualTemplates(VisualTemplateConfig(**params))


def test_block_average_grey_rgb_and_crop():
    vt = VisualTemplates(VisualTemplateConfig(template_width_blocks=2, template_height_blocks=1, shift_match_blocks=0, step_match_blocks=1))
    img = np.array([[0, 255, 51, 51], [255, 255, 51, 51], [7, 7, 7, 7]], dtype=np.uint8)  # 3rd row: remainder, ignored? no: 3//1
    v = vt.view_template(img[:2])
    np.testing.assert_allclose(v, [[765 / 255 / 4, 0.2]])
    rgb = np.zeros((1, 2, 3), dtype=np.uint8)
    rgb[0, 0] = (255, 0, 0)
    vt_rgb = VisualTemplates(VisualTemplateConfig(template_width_blocks=2, template_height_blocks=1, shift_match_blocks=0))
    np.testing.assert_allclose(vt_rgb.view_template(rgb), [[1 / 3, 0.0]])
    # crop x in [1, 3): two 1-px blocks; 5 columns -> blocks of 2 px from x=0, the 5th ignored
    vc = VisualTemplates(VisualTemplateConfig(template_width_blocks=2, template_height_blocks=1, shift_match_blocks=0, crop_x_min_px=1, crop_x_max_px=3))
    np.testing.assert_allclose(vc.view_template(row(0, 255, 0, 9)), [[1.0, 0.0]])
    v5 = VisualTemplates(VisualTemplateConfig(template_width_blocks=2, template_height_blocks=1, shift_match_blocks=0))
    np.testing.assert_allclose(v5.view_template(row(255, 0, 0, 0, 255)), [[0.5, 0.0]])


def test_global_normalisation_and_black_image():
    vt = VisualTemplates(VisualTemplateConfig(template_width_blocks=2, template_height_blocks=1, shift_match_blocks=0, normalisation_mean=0.6))
    np.testing.assert_allclose(vt.view_template(row(51, 102)), [[0.4, 0.8]])
    # C++: 0 * N / 0 = NaN and std::max(0, std::min(NaN, 1)) = 0
    np.testing.assert_array_equal(vt.view_template(row(0, 0)), [[0.0, 0.0]])


def test_patch_normalisation_hand_example():
    vt = VisualTemplates(VisualTemplateConfig(template_width_blocks=3, template_height_blocks=1, shift_match_blocks=0, patch_half_width_blocks=1))
    # p = 1 over a 1-row template: 3x3 edge-clamped patches. Pixel 1: patch columns
    # 0,1,2 = {0,0,1} (x3 rows) -> mean 1/3, std sqrt(2)/3 -> z = (-1/3 / (sqrt(2)/3) + 3) / 6;
    # pixel 2: columns 1,2,2 = {0,1,1} -> mean 2/3 -> z = (1/3 / (sqrt(2)/3) + 3) / 6
    v = vt.view_template(row(0, 0, 255))
    assert v[0, 1] == pytest.approx((-(1 / 3) / (math.sqrt(2) / 3) + 3) / 6)
    assert v[0, 2] == pytest.approx(((1 / 3) / (math.sqrt(2) / 3) + 3) / 6)
    assert v[0, 0] == 1.0  # columns 0,0,1 = {0,0,0}: std 0 -> C++ std::min(1, NaN) = 1
    # a flat patch has std 0: C++ yields std::min(1, NaN) = 1
    flat = VisualTemplates(VisualTemplateConfig(template_width_blocks=3, template_height_blocks=1, shift_match_blocks=0, patch_half_width_blocks=1))
    np.testing.assert_array_equal(flat.view_template(row(9, 9, 9)), [[1.0, 1.0, 1.0]])


def test_sad_with_shifts_hand_examples():
    vt = small()
    a = vt.match(row(0, 255, 0, 0))
    assert (a.template_id, a.is_new, a.error) == (0, True, math.inf)
    # shifted one column: the view's centre [0, 1] equals template columns 0..1 -> SAD 0
    b = vt.match(row(0, 0, 255, 0))
    assert (b.template_id, b.is_new, b.error) == (0, False, 0.0)
    # centre [1, 128/255] vs template windows [0,1], [1,0], [0,0]: best 128/255 over 2 px
    c = vt.match(row(0, 255, 128, 0))
    assert c.is_new and c.template_id == 1
    assert c.error == pytest.approx((128 / 255) / 2)
    # mean filter: |0.5 - 0.25| > threshold + 0.005 -> template 0 not compared
    d = small(match_threshold=0.1)
    d.match(row(0, 255, 0, 0))
    assert d.match(row(255, 0, 0, 255)).error == math.inf


def test_denominator_uses_all_rows():
    img = np.array([[0, 255, 0, 0], [0, 255, 0, 0]], dtype=np.uint8)
    two = VisualTemplates(VisualTemplateConfig(template_width_blocks=4, template_height_blocks=2, shift_match_blocks=1, step_match_blocks=1, match_threshold=0.2))
    two.match(img)
    r = two.match(np.array([[0, 255, 128, 0], [0, 255, 128, 0]], dtype=np.uint8))
    assert r.error == pytest.approx(2 * (128 / 255) / (8 - 2 * 1 * 2))


def test_panoramic_circular_shift_and_relative_rotation():
    vt = small(panoramic=True, shift_match_blocks=0, match_threshold=0.01)
    vt.match(row(0, 255, 0, 0))
    r = vt.match(row(255, 0, 0, 0))  # data[c] == template[(c + 1) % 4]
    assert (r.template_id, r.is_new, r.error) == (0, False, 0.0)
    assert r.relative_rad == pytest.approx(math.pi / 2)
    r = vt.match(row(0, 0, 255, 0))  # offset 3 -> 3 pi / 2 -> wrapped to -pi / 2
    assert r.relative_rad == pytest.approx(-math.pi / 2)


def naive_best(view, templates, shift, step, thr):
    x = view.shape[1]
    best = (math.inf, 0)
    for t, tpl in enumerate(templates):
        if abs(view.mean() - tpl.mean()) > thr + 0.005:
            continue
        for o in range(0, 2 * shift + 1, step):
            sad = np.abs(view[:, shift : x - shift] - tpl[:, o : o + x - 2 * shift]).sum()
            if sad < best[0] - 1e-12:
                best = (sad, t)
    return best[0] / (view.size - 2 * shift * view.shape[0]), best[1]


def test_matches_naive_reference_on_many_templates():
    rng = np.random.default_rng(5)
    cfg = VisualTemplateConfig(template_width_blocks=16, template_height_blocks=4, shift_match_blocks=4, step_match_blocks=2, match_threshold=0.0)
    vt = VisualTemplates(cfg)
    images = rng.integers(100, 156, size=(300, 4, 16), dtype=np.uint8)
    for img in images:
        vt.match(img)  # threshold 0: each distinct image is new
    assert len(vt) == 300
    loose = VisualTemplates(VisualTemplateConfig(template_width_blocks=16, template_height_blocks=4, shift_match_blocks=4, step_match_blocks=2, match_threshold=0.05))
    loose.store = vt.store
    loose._means = vt._means
    loose.image_shape = vt.image_shape
    probe = np.clip(images[123].astype(int) + rng.integers(-3, 4, size=(4, 16)), 0, 255).astype(np.uint8)
    r = loose.match(probe)
    err, best = naive_best(loose.view_template(probe), vt.store.data, 4, 2, 0.05)
    assert r.template_id == best == 123 and r.error == pytest.approx(err)


def test_wrong_image_size_and_type_raise_and_keep_state():
    vt = small()
    vt.match(row(0, 255, 0, 0))
    with pytest.raises(ShapeError, match="shape"):
        vt.match(np.zeros((2, 4), dtype=np.uint8))
    with pytest.raises(InvalidInputError, match="uint8"):
        vt.match(np.zeros((1, 4)))
    assert len(vt) == 1
    with pytest.raises(ShapeError):
        small().match(row(0, 255))  # smaller than the template
    with pytest.raises(ConfigError, match="shift_match_blocks"):
        VisualTemplateConfig(template_width_blocks=4, shift_match_blocks=2)


def test_uninitialised_clear_emulation_adds_previous_view():
    vt = small(emulate_uninitialised_clear=True)
    vt.match(row(0, 255, 0, 0))
    v = vt.view_template(row(0, 0, 0, 0))
    np.testing.assert_allclose(v, [[0, 1 / 255, 0, 0]])  # (old view + block sum) / 255 / 1


def test_tactile_eq_3_1_hand_example():
    a = np.zeros((3, 6), dtype=np.uint8)
    b = a.copy()
    b[0, 0], b[2, 5] = 16, 9
    assert tactile_similarity(a, b) == pytest.approx(4 + 3)
    tt = TactileTemplates(TactileTemplateConfig(match_threshold=7.0))
    assert tt.match(a).is_new
    r = tt.match(b)
    assert (r.template_id, r.is_new, r.error) == (0, False, 7.0)
    strict = TactileTemplates(TactileTemplateConfig(match_threshold=6.9))
    strict.match(a)
    assert strict.match(b).is_new and len(strict) == 2


def test_tactile_no_shift_and_bad_input():
    tt = TactileTemplates(TactileTemplateConfig(match_threshold=1.0))
    a = np.zeros((3, 6), dtype=np.uint8)
    a[:, 0] = 200
    tt.match(a)
    r = tt.match(np.roll(a, 1, axis=1))  # a shifted image is a different place: 6 * sqrt(200)
    assert r.is_new and r.error == pytest.approx(6 * math.sqrt(200))
    with pytest.raises(ShapeError, match=r"\(3, 6\)"):
        tt.match(np.zeros((6, 3), dtype=np.uint8))
    with pytest.raises(InvalidInputError):
        tt.match(np.full((3, 6), 300))
    assert len(tt) == 2


def test_tactile_compiled_scan_equals_eq_3_1_reference():
    """The numba scan picks the same template and S as argmin of the numpy Eq 3.1."""
    rng = np.random.default_rng(7)
    stored = rng.integers(0, 256, size=(300, 3, 6), dtype=np.uint8)
    tt = TactileTemplates(TactileTemplateConfig(match_threshold=0.0))
    for img in stored:
        tt.match(img)
    assert len(tt) == 300
    probe_tt = TactileTemplates(TactileTemplateConfig(match_threshold=1e9))
    probe_tt.store = tt.store
    for _ in range(20):
        probe = rng.integers(0, 256, size=(3, 6), dtype=np.uint8)
        ref = tactile_similarity(stored, probe)
        m = probe_tt.match(probe)
        assert m.template_id == int(np.argmin(ref))
        assert m.error == pytest.approx(float(ref.min()), rel=1e-12)


@pytest.mark.parametrize("shape", [(math.inf, 80), ("a", 80), (60.5, 80), (0, 80), "ab", 5])
def test_a_bad_image_shape_is_a_typed_error(shape):
    # int(inf) / int("a") were OverflowError / ValueError, 60.5 was truncated to 60
    with pytest.raises(InvalidInputError):
        VisualTemplates(image_shape=shape)
    assert VisualTemplates(image_shape=(60.0, 80)).image_shape == (60, 80)  # an integral float is a count


def test_image_errors_name_the_fault():
    """An RGB frame after grey ones was "differs from the expected ... resize or crop it"; a view id given to the
    visual front end was "got dtype int64"; RGBA had no hint (a user's pass, session 47)."""
    vt = VisualTemplates(VisualTemplateConfig(template_width_blocks=4, template_height_blocks=2, shift_match_blocks=0))
    grey = np.zeros((8, 16), dtype=np.uint8)
    vt.match(grey)
    with pytest.raises(ShapeError, match=r"other channels than the first image's \(8, 16\) \(3 channels against grey"):
        vt.match(np.zeros((8, 16, 3), dtype=np.uint8))
    with pytest.raises(ShapeError, match="resize or crop"):  # another size is still a size
        vt.match(np.zeros((8, 12), dtype=np.uint8))
    with pytest.raises(InvalidInputError, match="a view id\\? .*frontend='ids'"):
        vt.match(np.int64(3))
    with pytest.raises(InvalidInputError) as exc:
        vt.match(np.zeros((8, 16), dtype=np.float32))  # an image of the wrong dtype is not called a view id
    assert "view id" not in str(exc.value)
    fresh = VisualTemplates(VisualTemplateConfig(template_width_blocks=4, template_height_blocks=2, shift_match_blocks=0))
    with pytest.raises(ShapeError, match=r"image\[\.\.\., :3\]"):
        fresh.match(np.zeros((8, 16, 4), dtype=np.uint8))


def test_an_rgba_image_after_rgb_ones_is_told_to_drop_alpha():
    vt = VisualTemplates(VisualTemplateConfig(template_width_blocks=4, template_height_blocks=2, shift_match_blocks=0))
    vt.match(np.zeros((8, 16, 3), dtype=np.uint8))
    with pytest.raises(ShapeError, match=r"4 channels against 3 channels.*image\[\.\.\., :3\]"):
        vt.match(np.zeros((8, 16, 4), dtype=np.uint8))
