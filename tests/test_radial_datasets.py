"""The three simulated data sets of thesis Ch.4: layout, reproducibility, ground truth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from whisker_io.errors import InvalidInputError
from whisker_io.radial.datasets import (
    TRAINING_LENGTHS_MM,
    UNSEEN_LENGTHS_MM,
    EvansSetParams,
    TrainingSetParams,
    ValidationSetParams,
    make_evans_set,
    make_training_set,
    make_validation_set,
    validation_array,
)
from whisker_io.radial.evaluation import point_to_mesh_distance
from whisker_io.radial.features import FEATURE_NAMES
from whisker_io.radial.pipeline import dataset_contact_points

SMALL_TRAIN = replace(TrainingSetParams(), lengths_mm=(65, 137), frequencies_hz=(0.5, 2.0), whisks_per_setting=1)


def test_training_set_grid_and_reproducibility() -> None:
    a = make_training_set(SMALL_TRAIN)
    b = make_training_set(SMALL_TRAIN)
    np.testing.assert_array_equal(a.features, b.features)
    assert a.fingerprint() == b.fingerprint()
    c = make_training_set(replace(SMALL_TRAIN, seed=5))
    assert a.fingerprint() != c.fingerprint()
    # 2 lengths x 20 distances x 2 frequencies, almost all detected
    assert 0.95 * 80 <= len(a) <= 80
    for L in (0.065, 0.137):
        r = np.unique(a.radial_distance_m[np.isclose(a.whisker_length_m, L)])
        expected = np.linspace(0.025, L, 20)  # Sec 4.1.2.1: 20 equally spaced, 25 mm to the tip
        assert np.all(np.isin(np.round(r, 9), np.round(expected, 9)))
        assert len(r) >= 18
    assert set(np.unique(a.meta["frequency_hz"])) == {0.5, 2.0}


def test_training_features_follow_the_beam_model() -> None:
    # deflection rate per angular rate (DV / AV = G k(a)) falls with radial distance (Eq 2.37-2.38)
    data = make_training_set(replace(SMALL_TRAIN, lengths_mm=(107,), frequencies_hz=(1.0,)))
    ratio = data.columns(["DV"])[:, 0] / data.columns(["AV"])[:, 0]
    order = np.argsort(data.radial_distance_m)
    assert np.all(np.diff(ratio[order]) < 0)
    assert np.all(data.columns(["CA"]) > 0)


def test_validation_array_lengths() -> None:
    arr = validation_array()
    mm = np.round(arr.lengths_m * 1e3).astype(int)
    assert sorted(mm) == sorted(UNSEEN_LENGTHS_MM + TRAINING_LENGTHS_MM + (107,))
    rows = np.array([m.row for m in arr.modules])
    assert mm[rows == 1].max() <= mm[rows == 2].min() and mm[rows == 2].max() <= mm[rows == 3].min()
    with pytest.raises(InvalidInputError):
        validation_array((100,) * 17)


@pytest.fixture(scope="module")
def validation():
    return make_validation_set(ValidationSetParams().reduced())


def test_validation_ground_truth_lies_on_the_box(validation) -> None:
    data = validation.data
    assert len(validation.poses) == 18 and len(data) > 18
    # FK with the swept angle and the ground-truth radial distance lands on the surface
    true = type(data)(data.features, data.radial_distance_m, meta={**data.meta, "angle_rad": data.meta["true_angle_rad"]})
    pts = dataset_contact_points(validation.array, true, data.radial_distance_m)
    assert np.max(np.abs(point_to_mesh_distance(pts, validation.mesh))) < 1e-4
    # the detected onset angle is close to the swept contact angle (cf. Fig 4.3)
    err = np.rad2deg(data.meta["angle_rad"] - data.meta["true_angle_rad"])
    assert abs(np.median(err)) < 2.0
    assert np.all(data.radial_distance_m <= data.whisker_length_m + 1e-9)


def test_validation_covers_unseen_lengths_along_the_shaft(validation) -> None:
    data = validation.data
    shaft = data.radial_distance_m <= 0.7 * data.whisker_length_m
    seen_mm = set(np.round(data.whisker_length_m[shaft & validation.unseen] * 1e3).astype(int))
    assert len(seen_mm) >= 7  # most unseen lengths have contacts along the shaft
    assert seen_mm <= set(UNSEEN_LENGTHS_MM)
    assert not np.any(validation.unseen & np.isin(np.round(data.whisker_length_m * 1e3), TRAINING_LENGTHS_MM))


def test_evans_set_layout() -> None:
    p = replace(EvansSetParams(), distances_m=(0.08, 0.18, 5), speeds_m_s=(0.036, 0.216, 3), repeats=2)
    data = make_evans_set(p)
    assert len(data) == 5 * 3 * 2
    assert data.radial_distance_m.min() == pytest.approx(0.08) and data.radial_distance_m.max() == pytest.approx(0.18)
    np.testing.assert_allclose(data.whisker_length_m, 0.185)
    assert set(np.round(data.meta["speed_m_s"], 6)) == {0.036, 0.126, 0.216}
    # the whisker is still: angular velocity ~ 0 (angle-sensor noise only)
    assert np.max(np.abs(data.columns(["AV"]))) < 0.05
    # faster rod -> shorter contact period at the same distance
    cp = data.features[:, FEATURE_NAMES.index("CP")]
    at = np.isclose(data.radial_distance_m, 0.13)
    v = data.meta["speed_m_s"][at]
    assert cp[at][v == v.max()].max() < cp[at][v == v.min()].min()


def test_bad_parameters() -> None:
    with pytest.raises(InvalidInputError):
        TrainingSetParams(lengths_mm=(20,))
    with pytest.raises(InvalidInputError):
        TrainingSetParams(contact_angle_deg=(-60.0, 0.0))
    with pytest.raises(InvalidInputError):
        EvansSetParams(distances_m=(0.08, 0.3, 5))
    with pytest.raises(InvalidInputError):
        ValidationSetParams(n_waypoints=0)
