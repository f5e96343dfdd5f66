"""Radial-distance models plugged into forward kinematics (Eq 5.1-5.2), hand-computed geometry.

One module at (0.1, 0, 0) m in the end-effector frame: its shaft at theta = 0
points radially outward (+x_E); at theta = +90 deg it points to +y_E
(protraction, Fig 2.15). With the identity pose a contact at radial distance r
is at (0.1 + r, 0, 0) for theta = 0 and (0.1, r, 0) for theta = 90 deg.
"""

from __future__ import annotations

import numpy as np
import pytest

from whisker_io.errors import InvalidInputError
from whisker_io.array.geometry import WhiskerArray, WhiskerModule
from whisker_io.radial.features import RadialDataset
from whisker_io.radial.models import TrainedModel, make_estimator
from whisker_io.radial.persistence import save_model
from whisker_io.radial.pipeline import (
    contact_points_from_features,
    dataset_contact_points,
    estimate_radial_distance,
)

L = 0.08
ARRAY = WhiskerArray(
    (
        WhiskerModule("A1", "A", 1, (0.1, 0.0, 0.0), L),
        WhiskerModule("B1", "B", 1, (0.0, 0.0, 0.1), L),
    ),
    retraction_rad=-1.6,
    protraction_rad=1.6,
)


class Constant:
    """A fitted 'estimator' predicting a constant radial distance."""

    def __init__(self, r: float) -> None:
        self.r = r

    def predict(self, X):
        return np.full(len(X), self.r)


def feats(n: int = 2) -> np.ndarray:
    F = np.ones((n, 7))
    F[:, 6] = L
    return F


def test_tip_model_places_contacts_at_the_tip() -> None:
    pts = contact_points_from_features(ARRAY, np.eye(4), [0.0, 0.0], feats(), "tip")
    np.testing.assert_allclose(pts[0], [0.1 + L, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pts[1], [0.0, 0.0, 0.1 + L], atol=1e-12)


def test_fitted_estimator_and_protraction_angle() -> None:
    pts = contact_points_from_features(ARRAY, np.eye(4), [np.pi / 2, np.nan], feats(), Constant(0.03))
    np.testing.assert_allclose(pts[0], [0.1, 0.03, 0.0], atol=1e-12)
    assert np.all(np.isnan(pts[1]))  # no contact on B1


def test_estimates_are_clipped_to_the_shaft() -> None:
    np.testing.assert_allclose(estimate_radial_distance(feats(), Constant(0.5)), [L, L])
    np.testing.assert_allclose(estimate_radial_distance(feats(), Constant(-0.1)), [0.0, 0.0])
    np.testing.assert_allclose(estimate_radial_distance(feats(), Constant(0.5), clip=False), [0.5, 0.5])


def test_saved_model_file_as_source(tmp_path) -> None:
    X = feats(20)
    X[:, 0] = np.linspace(0.1, 1.0, 20)
    est = make_estimator("poly", ("CP",), degree=1).fit(X, 0.05 * X[:, 0])
    path = save_model(TrainedModel("lin", "poly", ("CP",), est), tmp_path / "lin.skops")
    q = feats(1)
    q[0, 0] = 0.6
    np.testing.assert_allclose(estimate_radial_distance(q, path), [0.03], atol=1e-9)


def test_bad_sources_and_shapes() -> None:
    with pytest.raises(InvalidInputError):
        estimate_radial_distance(feats(), "no-such-model")
    with pytest.raises(InvalidInputError):
        estimate_radial_distance(feats(), object())
    with pytest.raises(InvalidInputError):
        contact_points_from_features(ARRAY, np.eye(4), [0.0], feats(), "tip")
    wrong = feats()
    wrong[:, 6] = 0.1
    with pytest.raises(InvalidInputError, match="WL"):
        contact_points_from_features(ARRAY, np.eye(4), [0.0, 0.0], wrong, "tip")


def test_dataset_contact_points_two_whisks_at_one_waypoint() -> None:
    T = np.eye(4)
    T[:3, 3] = [1.0, 2.0, 3.0]  # pure translation of the end effector
    poses = np.stack([T, T, T])
    data = RadialDataset(
        feats(3), np.array([0.02, 0.04, 0.05]),
        meta={"pose": poses, "module": np.array([0, 0, 1]), "angle_rad": np.array([0.0, np.pi / 2, 0.0])},
    )
    pts = dataset_contact_points(ARRAY, data, data.radial_distance_m)
    expect = np.array([[1.12, 2.0, 3.0], [1.1, 2.04, 3.0], [1.0, 2.0, 3.15]])
    np.testing.assert_allclose(pts, expect, atol=1e-12)
