"""Library helpers shared by the Ch.5 and Ch.6 studies: per-run seeds (cansim.seeding), the
contact-noise scale (ContactNoise.scaled) and the T_pfh/T_sda calibration from same-pose
whisk pairs (whisker_io.features.match_thresholds)."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import CansimError, InvalidInputError
from cansim.seeding import derive_seed
from whisker_io.features.match_thresholds import (
    ThresholdCalibration,
    calibrate_match_thresholds,
)
from whisker_io.features.region import RegionFeatures
from whisker_io.sim.sweep import ContactNoise


# ------------------------------------------------------------------ derive_seed
def test_derive_seed_is_the_documented_hash():
    # the module docstring's rule, computed here with hashlib
    text = repr((7, ("sensor", "box", "lsr", True, 0.5)))
    expected = int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "little")
    assert derive_seed(7, "sensor", "box", "lsr", True, 0.5) == expected


def test_derive_seed_numpy_scalars_are_their_python_numbers():
    assert derive_seed(np.int64(3), np.float64(0.3), np.bool_(False), np.int32(2)) == derive_seed(3, 0.3, False, 2)


def test_derive_seed_separates_runs_and_keeps_order():
    seeds = {derive_seed(0, *p) for p in [("map", "box"), ("map", "box_stack"), ("box", "map"), ("map",), ()]}
    assert len(seeds) == 5
    assert derive_seed(0, "map", "box") != derive_seed(1, "map", "box")


@settings(max_examples=60, deadline=None)
@given(base=st.integers(-2**70, 2**70),
       parts=st.lists(st.one_of(st.text(max_size=5), st.integers(), st.booleans(),
                                st.floats(allow_nan=False, allow_infinity=False)), max_size=4))
def test_derive_seed_is_a_32_bit_function_of_its_inputs(base, parts):
    s = derive_seed(base, *parts)
    assert isinstance(s, int) and 0 <= s < 2**32
    assert derive_seed(base, *parts) == s


@settings(max_examples=60, deadline=None)
@given(bad=st.one_of(st.none(), st.lists(st.integers(), max_size=2), st.dictionaries(st.text(max_size=2), st.integers(), max_size=1),
                     st.sampled_from([math.nan, math.inf, -math.inf, object(), b"x", 1j, np.array([1, 2])])),
       where=st.sampled_from(["part", "base"]))
def test_derive_seed_refuses_bad_input(bad, where):
    with pytest.raises(InvalidInputError):
        derive_seed(0, "run", bad) if where == "part" else derive_seed(bad, "run")


@pytest.mark.parametrize("base", [1.0, "0", True, None])
def test_derive_seed_base_must_be_an_integer(base):
    with pytest.raises(InvalidInputError):
        derive_seed(base)


# ------------------------------------------------------------ ContactNoise.scaled
def test_scaled_noise_multiplies_both_standard_deviations():
    n = ContactNoise().scaled(0.3)
    assert n.position_sigma_fraction == pytest.approx(0.25 * 0.3)  # Sec 6.1.3.1.2: 0.25 x whisker length
    assert n.slope_sigma == pytest.approx(0.33 * 0.3)
    assert n.registration_probability == 0.98 and n.position_mode == "shaft"
    assert ContactNoise().scaled(1) == ContactNoise()
    iso = ContactNoise(position_mode="isotropic", registration_probability=0.5).scaled(2.0)
    assert (iso.position_mode, iso.registration_probability, iso.position_sigma_fraction) == ("isotropic", 0.5, 0.5)


@settings(max_examples=40, deadline=None)
@given(a=st.floats(0, 100), b=st.floats(0, 100))
def test_scaled_noise_composes(a, b):
    two = ContactNoise().scaled(a).scaled(b)
    one = ContactNoise().scaled(a * b)
    assert two.position_sigma_fraction == pytest.approx(one.position_sigma_fraction, rel=1e-12, abs=1e-300)
    assert two.slope_sigma == pytest.approx(one.slope_sigma, rel=1e-12, abs=1e-300)


@settings(max_examples=40, deadline=None)
@given(bad=st.one_of(st.floats(max_value=-1e-12), st.sampled_from([math.nan, math.inf, True, "1", None, [1.0], 1e308])))
def test_scaled_noise_refuses_bad_scales(bad):
    base = ContactNoise(slope_sigma=10.0)
    with pytest.raises(CansimError):
        base.scaled(bad)
    assert base.slope_sigma == 10.0  # the original is untouched


# ---------------------------------------------------- calibrate_match_thresholds
def _features(pfh_bins: dict[int, float], slopes: dict[int, float], n_contacts: int = 3) -> RegionFeatures:
    pfh = np.zeros(81)
    for k, v in pfh_bins.items():
        pfh[k] = v
    sda, mask = np.zeros(18), np.zeros(18, dtype=bool)
    for k, v in slopes.items():
        sda[k], mask[k] = v, True
    pts = np.tile([0.0, 0.2, 0.0], (n_contacts, 1))
    return RegionFeatures(pfh, sda, mask, n_contacts, pts)


def _flat(n_contacts: int = 3) -> RegionFeatures:
    return _features({0: 1.0} if n_contacts >= 3 else {}, {0: 1.0}, n_contacts)


class _Scripted:
    """A sensor returning a scripted whisk per call and logging the poses it was called at."""

    def __init__(self, whisks: list[RegionFeatures]) -> None:
        self.whisks, self.calls = list(whisks), []

    def __call__(self, pose: object) -> RegionFeatures:
        self.calls.append(pose)
        return self.whisks.pop(0)


def test_thresholds_are_quantiles_of_hand_computed_distances():
    # pose k: first whisk pfh [1, 0], second [1 - a_k, a_k]: chi2 = a^2/(2 - a) + a^2/a = a^2/(2 - a) + a
    # SDA: first (1, 0, ...), second (1, b_k, ...): NMSE = MSE(x, y) / MSE(x, 0) = (b^2 / 18) / (1 / 18) = b^2 (Eq 5.3)
    a = [0.5, 0.2, 1.0]
    b = [0.3, 0.1, 0.6]
    whisks = []
    for ak, bk in zip(a, b):
        whisks.append(_features({0: 1.0}, {0: 1.0}))
        whisks.append(_features({0: 1.0 - ak, 1: ak} if ak < 1 else {1: 1.0}, {0: 1.0, 1: bk}))
    sensor = _Scripted(whisks)
    cal = calibrate_match_thresholds(sensor, ["p0", "p1", "p2"], quantile=0.75)
    assert sensor.calls == ["p0", "p0", "p1", "p1", "p2", "p2"]
    chi = sorted(x * x / (2 - x) + x for x in a)  # 0.2222, 0.6667, 2.0
    nm = sorted(x * x for x in b)  # 0.01, 0.09, 0.36
    # linear quantile of 3 sorted values at 0.75: position 1.5 -> halfway between the 2nd and the 3rd
    assert cal.pfh_threshold == pytest.approx(0.5 * (chi[1] + chi[2]))
    assert cal.sda_threshold == pytest.approx(0.5 * (nm[1] + nm[2]))
    assert cal.same_chi2_median == pytest.approx(chi[1]) and cal.same_nmse_median == pytest.approx(nm[1])
    # every first whisk is the same: next-pose distances are all 0, all under the thresholds
    assert cal.next_chi2_median == 0 and cal.next_nmse_median == 0
    assert cal.next_chi2_below_threshold == 1.0 and cal.next_nmse_below_threshold == 1.0
    assert cal.n_pairs == 3 and cal.quantile == 0.75
    assert list(cal.as_row()) == ["quantile", "n_pairs", "pfh_threshold", "sda_threshold", "same_chi2_median",
                                  "next_chi2_median", "same_nmse_median", "next_nmse_median",
                                  "next_chi2_below_threshold", "next_nmse_below_threshold"]


def test_poses_without_three_observations_do_not_count():
    # pose 1's second whisk has 2 contacts; pose 2's first whisk too, which also drops pose 1 (its "next")
    whisks = [_flat(), _flat(), _flat(), _flat(2), _flat(2), _flat(), _flat(), _flat()]
    cal = calibrate_match_thresholds(_Scripted(whisks), [0, 1, 2, 3])
    assert cal.n_pairs == 2  # poses 0 and 3 (whose next is pose 0, the loop closes)
    assert cal.pfh_threshold == 0 and cal.sda_threshold == 0


def test_the_masked_comparison_ignores_whiskers_touched_in_one_whisk():
    whisks = [_features({0: 1.0}, {0: 1.0}), _features({0: 1.0}, {0: 1.0, 5: 2.0})] * 2
    plain = calibrate_match_thresholds(_Scripted(whisks), [0, 1])
    masked = calibrate_match_thresholds(_Scripted(whisks), [0, 1], use_sda_mask=True)
    assert plain.sda_threshold == pytest.approx(4.0)  # (2^2/18) / (1/18)
    assert masked.sda_threshold == 0.0


def test_simulated_thresholds_grow_with_the_quantile_and_the_noise():
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    mesh = make_object("mug")
    poses = object_trajectory(mesh, "A", 1)[:12]
    out = {}
    for scale in (0.1, 1.0):
        for q in (0.5, 0.9):
            chain = WhiskChain(mesh, contact_model="tip", contact_noise=ContactNoise().scaled(scale))
            rng = np.random.default_rng(0)
            out[scale, q] = calibrate_match_thresholds(lambda p, c=chain, r=rng: c.features(p, r), poses, q)
    for scale in (0.1, 1.0):
        assert out[scale, 0.5].pfh_threshold <= out[scale, 0.9].pfh_threshold
        assert out[scale, 0.5].sda_threshold <= out[scale, 0.9].sda_threshold
    assert out[0.1, 0.5].same_chi2_median < out[1.0, 0.5].same_chi2_median
    assert out[0.1, 0.5].same_nmse_median < out[1.0, 0.5].same_nmse_median


@settings(max_examples=50, deadline=None)
@given(quantile=st.one_of(st.floats(allow_nan=True), st.sampled_from([0.0, -0.5, 1.5, True, "0.5", None])),
       n_poses=st.integers(0, 3), kind=st.sampled_from(["ok", "not-features", "no-contact", "not-callable"]))
def test_calibration_refuses_bad_input(quantile, n_poses, kind):
    good_q = isinstance(quantile, float) and 0 < quantile <= 1
    if kind == "not-callable":
        sensor: object = "sensor"
    elif kind == "not-features":
        sensor = lambda p: np.zeros(81)
    else:
        sensor = lambda p: _flat(3 if kind == "ok" else 1)
    poses = list(range(n_poses))
    if good_q and n_poses >= 2 and kind == "ok":
        cal = calibrate_match_thresholds(sensor, poses, quantile)  # type: ignore[arg-type]
        assert isinstance(cal, ThresholdCalibration) and cal.n_pairs == n_poses
        assert all(math.isfinite(v) for v in cal.as_row().values())
    else:
        with pytest.raises(InvalidInputError):
            calibrate_match_thresholds(sensor, poses, quantile)  # type: ignore[arg-type]


def test_calibration_refuses_an_infinite_threshold():
    # masked SDAs with no whisker in common: every same-pose NMSE is inf
    whisks = [_features({0: 1.0}, {0: 1.0}), _features({0: 1.0}, {5: 1.0})] * 2
    with pytest.raises(InvalidInputError, match="infinite"):
        calibrate_match_thresholds(_Scripted(whisks), [0, 1], use_sda_mask=True)
    with pytest.raises(InvalidInputError):
        calibrate_match_thresholds(_Scripted(whisks), None)  # type: ignore[arg-type]
