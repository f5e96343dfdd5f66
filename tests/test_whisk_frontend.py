"""The whisk front end: Eq 5.5 region matching (hand-computed), feature selection and update, persistence, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import ConfigError, CorruptFileError, InvalidInputError, ShapeError
from cansim.frontends.whisk import WhiskFrontEnd, WhiskFrontEndConfig


def region(pfh, sda):
    return (np.asarray(pfh, dtype=float), np.asarray(sda, dtype=float))


SMALL = dict(n_bins=4, n_whiskers=2)
F = np.eye(4)


def stored_three(**kw):
    """Three stored regions (made with strict thresholds so each is new), then the wanted config."""
    strict = WhiskFrontEnd(WhiskFrontEndConfig(**SMALL, pfh_threshold=1e-9, sda_threshold=1e-9))
    for f, s in ((F[0], [1.0, 0.0]), (F[1], [0.0, 1.0]), (0.5 * (F[0] + F[1]), [1.0, 1.0])):
        assert strict.match(region(f, s)).is_new
    fe = WhiskFrontEnd(WhiskFrontEndConfig(**SMALL, **kw))
    fe.from_arrays(strict.to_arrays("x_"), "x_")
    return fe


def test_eq_5_5_thresholds_and_smallest_sum_by_hand():
    fe = stored_three(pfh_threshold=1.0, sda_threshold=0.6)
    q = region(0.5 * (F[0] + F[1]), [1.0, 0.2])
    sc = fe.scores(*fe.parse(q))
    # chi2 to regions 0 and 1: (.5-1)^2/1.5 + .5^2/.5 = 2/3; to region 2: 0
    np.testing.assert_allclose(sc.chi2, [2 / 3, 2 / 3, 0.0])
    # NMSE(s_n, s_i) = |s_n - s_i|^2 / |s_n|^2 with |s_n|^2 = 1.04: 0.04/1.04, 1.64/1.04, 0.64/1.04
    np.testing.assert_allclose(sc.nmse, [0.04 / 1.04, 1.64 / 1.04, 0.64 / 1.04])
    assert sc.candidates.tolist() == [0]  # region 2 fails the SDA threshold, region 1 both
    m = fe.match(q)
    assert (m.view_id, m.is_new) == (0, False) and m.error == pytest.approx(2 / 3 + 0.04 / 1.04)


def test_no_candidate_makes_a_new_region_and_single_feature_modes():
    fe = stored_three(pfh_threshold=0.1, sda_threshold=0.1)
    m = fe.match(region(0.5 * (F[0] + F[1]), [1.0, 0.2]))  # chi2 0 to region 2 but NMSE 0.62
    assert m.is_new and m.view_id == 3 and math.isinf(m.error)
    pfh_only = stored_three(features="pfh", pfh_threshold=0.1)
    assert pfh_only.match(region(0.5 * (F[0] + F[1]), [1.0, 0.2])).view_id == 2  # the SDA is ignored
    sda_only = stored_three(features="sda", sda_threshold=0.1)
    assert sda_only.match(region(F[3], [1.0, 0.05])).view_id == 0  # the PFH is ignored


def test_feature_update_keeps_the_running_mean():
    fe = stored_three(pfh_threshold=1.0, sda_threshold=1.0, feature_update=True)
    fe.match(region(0.5 * F[0] + 0.5 * F[2], [1.0, 0.4]))  # matches region 0
    np.testing.assert_allclose(fe.pfh[0], [0.75, 0, 0.25, 0])
    np.testing.assert_allclose(fe.sda[0], [1.0, 0.2])
    off = stored_three(pfh_threshold=1.0, sda_threshold=1.0)
    off.match(region(0.5 * F[0] + 0.5 * F[2], [1.0, 0.4]))
    np.testing.assert_allclose(off.pfh[0], F[0])


def test_sda_mask_option_compares_common_contacts_only():
    fe = WhiskFrontEnd(WhiskFrontEndConfig(n_bins=4, n_whiskers=3, use_sda_mask=True, features="sda", sda_threshold=0.01))
    fe.match((F[0], np.array([1.0, 2.0, 0.0]), np.array([True, True, False])))
    m = fe.match((F[0], np.array([1.0, 2.0, 9.0]), np.array([True, True, True])))
    assert m.view_id == 0 and not m.is_new  # the third whisker was not in contact before


def test_persistence_round_trip_and_corrupt_fields():
    fe = stored_three(pfh_threshold=1.0, sda_threshold=1.0, feature_update=True)
    fe.match(region(F[0], [1.0, 0.1]))
    arrays = fe.to_arrays("vt_")
    back = WhiskFrontEnd(fe.config)
    back.from_arrays(arrays, "vt_")
    assert back.pfh.tobytes() == fe.pfh.tobytes() and back.sda.tobytes() == fe.sda.tobytes() and len(back) == 3
    bad = dict(arrays, vt_count=np.array([1, 0, 1]))
    with pytest.raises(CorruptFileError, match="vt_count"):
        WhiskFrontEnd(fe.config).from_arrays(bad, "vt_")
    with pytest.raises(CorruptFileError, match="vt_sda"):
        WhiskFrontEnd(fe.config).from_arrays({k: v for k, v in arrays.items() if k != "vt_sda"}, "vt_")


def test_bad_config_is_named():
    for kw, key in (({"features": "all"}, "features"), ({"pfh_threshold": 0.0}, "pfh_threshold"),
                    ({"sda_threshold": math.nan}, "sda_threshold"), ({"n_bins": 0}, "n_bins")):
        with pytest.raises(ConfigError, match=key):
            WhiskFrontEndConfig(**kw)


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(["nan", "shape_pfh", "shape_sda", "negative", "unnormalised", "huge", "type", "mask"]))
def test_bad_observations_raise_typed_errors_and_store_nothing(kind):
    fe = stored_three()
    before = (fe.pfh.tobytes(), fe.sda.tobytes(), len(fe))
    f, s = 0.25 * np.ones(4), np.array([0.5, 0.5])
    obs = {
        "nan": (f, np.array([math.nan, 0.0])),
        "shape_pfh": (np.ones(3) / 3, s),
        "shape_sda": (f, np.ones(3)),
        "negative": (np.array([0.5, 0.7, -0.2, 0.0]), s),
        "unnormalised": (2 * f, s),
        "huge": (f, np.array([1e300, 0.0])),
        "type": "a whisk",
        "mask": (f, s, np.array([1, 0])),
    }[kind]
    with pytest.raises((InvalidInputError, ShapeError)):
        fe.match(obs)
    assert (fe.pfh.tobytes(), fe.sda.tobytes(), len(fe)) == before


def test_pose_prior_restricts_candidates_and_breaks_near_ties_by_hand():
    # sums chi2 + NMSE to the three stored regions: 2/3 + 0.04/1.04, 2/3 + 1.64/1.04, 0 + 0.64/1.04
    q = region(0.5 * (F[0] + F[1]), [1.0, 0.2])
    sums = [2 / 3 + 0.04 / 1.04, 2 / 3 + 1.64 / 1.04, 0.64 / 1.04]
    fe = stored_three(pfh_threshold=2.0, sda_threshold=2.0)
    assert fe.match(q).view_id == 2  # Eq 5.5: the smallest sum
    fe.pose_prior = lambda n: (np.array([True, True, False]), np.array([0.2, 0.0, 0.0]))
    m = fe.match(q)  # region 2 is not pose-consistent; 0: sums[0] + 0.2 < sums[1]
    assert (m.view_id, m.is_new) == (0, False) and fe.last_scores.candidates.tolist() == [0, 1]
    fe.pose_prior = lambda n: (np.ones(n, dtype=bool), np.array([0.0, 0.0, 0.1]))
    assert sums[2] + 0.1 > sums[0] and fe.match(q).view_id == 0  # the pose cost flips a near tie
    assert fe.scores(*fe.parse(q)).best == 2  # scores() never applies the prior
    fe.pose_prior = lambda n: (np.zeros(n, dtype=bool), np.zeros(n))
    assert fe.match(q).is_new and len(fe) == 4  # nothing consistent: a new region


@pytest.mark.parametrize("prior", [
    lambda n: (np.ones(n + 1, dtype=bool), np.zeros(n + 1)),
    lambda n: (np.ones(n), np.zeros(n)),
    lambda n: (np.ones(n, dtype=bool), np.full(n, -1.0)),
    lambda n: (np.ones(n, dtype=bool), np.full(n, math.nan)),
])
def test_a_malformed_pose_prior_raises_and_stores_nothing(prior):
    fe = stored_three(pfh_threshold=2.0, sda_threshold=2.0)
    fe.pose_prior = prior
    before = (fe.pfh.tobytes(), len(fe))
    with pytest.raises((InvalidInputError, ShapeError)):
        fe.match(region(0.5 * (F[0] + F[1]), [1.0, 0.2]))
    assert (fe.pfh.tobytes(), len(fe)) == before


def _chi2_loop(q, v):
    """Eq 2.45 for one stored histogram, bin after bin in Python floats (bins with a zero sum skipped)."""
    acc = 0.0
    for a, b in zip(q.tolist(), v.tolist()):
        if a + b > 0:
            acc += (a - b) * (a - b) / (a + b)
    return acc


def _nmse_loop(x, y, valid):
    """Eq 5.3 for one stored SDA over the valid whiskers, on the pair scaled by its largest magnitude."""
    pairs = [(a, b) for a, b, ok in zip(x.tolist(), y.tolist(), valid) if ok]
    if not pairs:
        return math.inf
    scale = max(max(abs(a), abs(b)) for a, b in pairs)
    if scale == 0.0:
        return 0.0
    err = power = 0.0
    for a, b in pairs:
        xs, d = a / scale, a / scale - b / scale
        err += d * d
        power += xs * xs
    err, power = err / len(pairs), power / len(pairs)
    return err / power if power > 0 else (0.0 if err == 0.0 else math.inf)


@pytest.mark.parametrize("use_sda_mask", [False, True])
def test_scores_against_many_regions_equal_the_per_region_formulas_bit_for_bit(use_sda_mask):
    rng = np.random.default_rng(7)
    fe = WhiskFrontEnd(WhiskFrontEndConfig(n_bins=9, n_whiskers=5, pfh_threshold=1e-12, sda_threshold=1e-12,
                                           use_sda_mask=use_sda_mask))
    stored = []
    for k in range(70):  # more than the initial capacity: the stored columns grow
        f = rng.dirichlet(np.full(9, 0.3)) * (rng.random(9) > 0.3)
        f = f / f.sum() if f.sum() > 0 else np.eye(9)[k % 9]
        s = rng.normal(0, 10.0 ** rng.integers(-2, 3), 5) * (rng.random(5) > 0.2)
        m = rng.random(5) > 0.3
        assert fe.match((f, s, m)).is_new
        stored.append((f, s, m))
    q, x, mx = stored[3][0] * 0.5 + stored[4][0] * 0.5, rng.normal(0, 1, 5), rng.random(5) > 0.2
    sc = fe.scores(q, x, mx)
    np.testing.assert_array_equal(sc.chi2, [_chi2_loop(q, f) for f, _, _ in stored])
    want = [_nmse_loop(x, s, (mx & m) if use_sda_mask else [True] * 5) for _, s, m in stored]
    np.testing.assert_array_equal(sc.nmse, want)
    assert fe.pfh.shape == (70, 9) and np.array_equal(fe.pfh[5], stored[5][0]) and np.array_equal(fe.sda[6], stored[6][1])
