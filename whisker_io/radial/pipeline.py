"""Radial-distance models in the contact pipeline: features + FK -> contact points.

The thesis' contact point (Eq 5.1-5.2) needs the whisk angle at contact and the
radial distance along the shaft. Ch.3/5 assume the tip (``r = whisker length``);
Ch.4 estimates ``r`` from contact features. :func:`estimate_radial_distance`
and :func:`contact_points_from_features` accept either:

* ``"tip"`` -- the tip assumption (:class:`~whisker_io.radial.models.TipAssumption`);
* ``"random"`` -- uniform on [0, length] (a reference, not for use);
* a path to a model saved with :func:`~whisker_io.radial.persistence.save_model`
  (for example the ``svr10.skops`` the study writes), loaded with its checks;
* a :class:`~whisker_io.radial.models.TrainedModel` (e.g. ``models["svr10"]``);
* any fitted scikit-learn regressor taking the (n, 7) feature matrix in
  :data:`~whisker_io.radial.features.FEATURE_NAMES` order and returning metres.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Protocol, Union

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import contact_points
from whisker_io.pose import PoseLike
from whisker_io.radial.features import FEATURE_NAMES, RadialDataset
from whisker_io.radial.models import TipAssumption, UniformRandom, check_feature_matrix

__all__ = [
    "RadialPredictor",
    "RadialSource",
    "resolve_radial_model",
    "estimate_radial_distance",
    "contact_points_from_features",
    "dataset_contact_points",
]


class RadialPredictor(Protocol):
    """Anything with ``predict(X (n, 7)) -> radial distance (n,) in m``."""

    def predict(self, X: Any) -> Any: ...


RadialSource = Union[str, "os.PathLike[str]", RadialPredictor]


def resolve_radial_model(source: RadialSource) -> RadialPredictor:
    """Turn ``"tip"``, ``"random"``, a model file path or an estimator into a predictor.

    Raises
    ------
    InvalidInputError
        For an unknown name or an object without ``predict``.
    CorruptFileError, ModelVersionError, FeatureMismatchError
        From :func:`~whisker_io.radial.persistence.load_model` for a bad file.
    """
    if isinstance(source, str) and source in ("tip", "random"):
        est = TipAssumption() if source == "tip" else UniformRandom()
        return est.fit(np.ones((1, len(FEATURE_NAMES))))
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if not path.is_file():
            raise InvalidInputError(
                f"radial model {str(source)!r} is neither 'tip', 'random' nor an existing model file"
            )
        from whisker_io.radial.persistence import load_model

        return load_model(path)
    if not callable(getattr(source, "predict", None)):
        raise InvalidInputError(
            f"a radial model needs a predict(X) method; got {type(source).__name__}"
        )
    return source


def estimate_radial_distance(
    features: Any, model: RadialSource = "tip", clip: bool = True
) -> np.ndarray:
    """Radial distance to contact for each row of a contact-feature matrix.

    Parameters
    ----------
    features : array_like, shape (n, 7)
        CP, CA, DV, DA, AV, AA, WL per contact (units in
        :data:`~whisker_io.radial.features.FEATURE_UNITS`).
    model : RadialSource
        See the module docstring.
    clip : bool
        Clip estimates to [0, WL] (a regressor can extrapolate past the base or tip).

    Returns
    -------
    ndarray, shape (n,), m
    """
    X = check_feature_matrix(features, "features")
    predictor = resolve_radial_model(model)
    if not len(X):  # no contacts: no estimates (a scikit-learn estimator refuses an empty matrix)
        return np.zeros(0)
    r = np.asarray(predictor.predict(X), dtype=np.float64).reshape(-1)
    if clip:
        r = np.clip(r, 0.0, X[:, FEATURE_NAMES.index("WL")])
    return r


def contact_points_from_features(
    array: WhiskerArray,
    pose: PoseLike,
    contact_angle_rad: Any,
    features: Any,
    model: RadialSource = "tip",
    clip: bool = True,
) -> np.ndarray:
    """Contact points of one array cycle from contact angles and features (Eq 5.1-5.2).

    Parameters
    ----------
    array : WhiskerArray
        N modules.
    pose : PoseLike
        End-effector pose ``T_BE`` held during the whisk.
    contact_angle_rad : array_like, shape (N,)
        Whisk angle at contact onset per module; NaN for modules without contact.
    features : array_like, shape (N, 7)
        Contact features per module; rows of modules without contact are ignored
        (may be NaN).
    model : RadialSource
        ``"tip"``, ``"random"``, a saved model path or a fitted estimator.
    clip : bool
        Clip estimates to [0, whisker length].

    Returns
    -------
    ndarray, shape (N, 3)
        World contact points, m; NaN rows for modules without contact.
    """
    theta = np.asarray(contact_angle_rad, dtype=np.float64)
    F = np.asarray(features, dtype=np.float64)
    n = len(array)
    if theta.shape != (n,) or F.shape != (n, len(FEATURE_NAMES)):
        raise InvalidInputError(
            f"contact_angle_rad must have shape ({n},) and features ({n}, {len(FEATURE_NAMES)}); "
            f"got {theta.shape} and {F.shape}"
        )
    hit = np.isfinite(theta)
    if not np.allclose(F[hit, FEATURE_NAMES.index("WL")], array.lengths_m[hit], rtol=0, atol=5e-4):
        raise InvalidInputError(
            "feature WL disagrees with the array's whisker lengths (tolerance 0.5 mm); "
            "build the features with this array's lengths"
        )
    r = np.zeros(n)
    if hit.any():
        r[hit] = estimate_radial_distance(F[hit], model, clip=clip)
    pts = contact_points(array, pose, np.where(hit, theta, 0.0), r)
    pts[~hit] = np.nan
    return pts


def dataset_contact_points(
    array: WhiskerArray, data: RadialDataset, radial_distance_m: Any
) -> np.ndarray:
    """Contact points of every contact of a validation data set for given radial distances.

    ``data.meta`` must hold ``"pose"`` (n, 4, 4) end-effector poses, ``"module"``
    (n,) module indices into ``array`` and ``"angle_rad"`` (n,) contact angles, as
    :func:`whisker_io.radial.datasets.make_validation_set` writes them.

    Returns
    -------
    ndarray, shape (n, 3), m
    """
    for key in ("pose", "module", "angle_rad"):
        if key not in data.meta:
            raise InvalidInputError(f"data set {data.name!r} has no meta[{key!r}]; use a validation set")
    r = np.asarray(radial_distance_m, dtype=np.float64)
    if r.shape != (len(data),):
        raise InvalidInputError(f"radial_distance_m must have shape ({len(data)},), got {r.shape}")
    poses, modules, angles = data.meta["pose"], data.meta["module"].astype(int), data.meta["angle_rad"]
    out = np.empty((len(data), 3))
    # one FK call per distinct pose (a held-still waypoint), all modules at once
    _, group = np.unique(poses.reshape(len(data), -1), axis=0, return_inverse=True)
    for g in np.unique(group):
        pending = np.flatnonzero(group == g)
        while pending.size:  # several whisks at one waypoint: one module per batch
            _, first = np.unique(modules[pending], return_index=True)
            rows = pending[first]
            theta = np.zeros(len(array))
            rr = np.zeros(len(array))
            theta[modules[rows]] = angles[rows]
            rr[modules[rows]] = r[rows]
            out[rows] = contact_points(array, poses[rows[0]], theta, rr)[modules[rows]]
            pending = np.delete(pending, first)
    return out
