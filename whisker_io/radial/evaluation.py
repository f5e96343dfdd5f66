"""Evaluation of radial-distance models (thesis Sec 4.1.2.3, 4.1.2.4.1, 4.2).

* :func:`radial_error` -- Eq 4.1, ``(d_m - d_gt) / d_wl``, on contacts with
  ``d_gt <= 0.7 d_wl`` (:func:`evaluation_mask`, Sec 4.2.1, which removes the
  bias toward tip contacts);
* :func:`point_to_mesh_distance` -- distance of reconstructed contact points to
  the object's surface (Fig 4.8), independent of the simulated ground truth;
* :func:`ks_pvalue` -- two-sample Kolmogorov-Smirnov test (scipy) against the
  tip and uniform-random baselines;
* :func:`evaluate_models` -- all of the above per model, as rows of the results
  table (:func:`write_results_csv`);
* :func:`pca_loadings` -- PCA after standardisation ("whitening", Fig 4.6);
* :func:`evans_comparison` -- Sec 4.2.2: 5th-order polynomial on the Evans et al.
  (2013) features (CA, CP) vs SVR on CP-CA-DV-DA, 70/30 split (Fig 4.10);
* :func:`length_generalisation` -- train on one whisker length (107 mm) vs on
  many, test on unseen lengths (Fig 4.11).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats
from sklearn.decomposition import PCA
from sklearn.model_selection import train_test_split
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from whisker_io.errors import InvalidInputError
from whisker_io.radial.errors import EmptyDatasetError
from whisker_io.radial.features import FEATURE_NAMES, RadialDataset
from whisker_io.radial.models import (
    SearchParams,
    TipAssumption,
    TrainedModel,
    UniformRandom,
    fit_model,
)

__all__ = [
    "EVANS_FEATURES",
    "OUR_FEATURES",
    "radial_error",
    "evaluation_mask",
    "ks_pvalue",
    "point_to_mesh_distance",
    "PCAResult",
    "pca_loadings",
    "ModelScore",
    "evaluate_models",
    "RESULT_COLUMNS",
    "write_results_csv",
    "evans_comparison",
    "length_generalisation",
]

#: Evans et al. (2013) inputs f1 (contact amplitude) and f2 (contact period), Sec 4.2.2.
EVANS_FEATURES: tuple[str, ...] = ("CA", "CP")
#: The thesis' features without angle sensing ("Our features", Sec 4.2.2).
OUR_FEATURES: tuple[str, ...] = ("CP", "CA", "DV", "DA")


def _predict(model: Any, X: np.ndarray) -> np.ndarray:
    """A model's estimates on an evaluation set, which holds whisker lengths it was not trained on on purpose
    (the generalisation tests): no training-range warning."""
    if isinstance(model, TrainedModel):
        return model.predict(X, warn_outside=False)
    return model.predict(X)


def radial_error(d_m: Any, d_gt: Any, d_wl: Any) -> np.ndarray:
    """Normalised radial-distance error, Eq 4.1 of the thesis: ``(d_m - d_gt) / d_wl``.

    Parameters
    ----------
    d_m : array_like, shape (n,)
        Model estimate of the radial distance, m.
    d_gt : array_like, shape (n,)
        Ground-truth radial distance, m.
    d_wl : array_like, shape (n,)
        Whisker length, m (> 0).

    Returns
    -------
    ndarray, shape (n,)
        Error as a fraction of whisker length; negative = underestimate.
    """
    d_m, d_gt, d_wl = (np.asarray(a, dtype=np.float64) for a in (d_m, d_gt, d_wl))
    if np.any(d_wl <= 0):
        raise InvalidInputError("whisker lengths d_wl must be > 0")
    return (d_m - d_gt) / d_wl


def evaluation_mask(d_gt: Any, d_wl: Any, max_fraction: float = 0.7) -> np.ndarray:
    """Contacts kept for evaluation: ``d_gt <= max_fraction * d_wl`` (Sec 4.2.1), shape (n,).

    The comparison is made on ``d_gt / d_wl`` with a 1e-12 tolerance, so a contact
    exactly at 0.7 of the length is kept despite float rounding.
    """
    ratio = np.asarray(d_gt, dtype=np.float64) / np.asarray(d_wl, dtype=np.float64)
    return ratio <= max_fraction + 1e-12


def ks_pvalue(a: Any, b: Any) -> float:
    """p-value of the two-sample Kolmogorov-Smirnov test (``scipy.stats.ks_2samp``).

    Small values mean the two samples come from different distributions.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.size == 0 or b.size == 0:
        raise EmptyDatasetError("the KS test needs two non-empty samples")
    return float(stats.ks_2samp(a, b).pvalue)


def point_to_mesh_distance(points: Any, mesh: Any, signed: bool = True) -> np.ndarray:
    """Distance from reconstructed contact points to the object surface (Fig 4.8).

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Contact points in the mesh's frame, m.
    mesh : trimesh.Trimesh
        The object (watertight for a meaningful sign).
    signed : bool
        If True, positive outside the object and negative inside (a point past
        the surface, as the tip assumption gives, is negative); otherwise the
        unsigned distance.

    Returns
    -------
    ndarray, shape (n,), m
    """
    import trimesh

    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not np.isfinite(p).all():
        raise InvalidInputError(f"points must be a finite (n, 3) array, got shape {p.shape}")
    if len(p) == 0:
        return np.zeros(0)
    if signed:
        # trimesh: positive inside the mesh
        return -np.asarray(trimesh.proximity.signed_distance(mesh, p), dtype=np.float64)
    return np.asarray(mesh.nearest.on_surface(p)[1], dtype=np.float64)


@dataclass(frozen=True)
class PCAResult:
    """Principal components of the standardised features (Fig 4.6).

    Attributes
    ----------
    feature_names : tuple of str
    components : ndarray, shape (k, n_features)
        Loadings (coefficients) of each component, unit vectors.
    explained_variance_ratio : ndarray, shape (k,)
    """

    feature_names: tuple[str, ...]
    components: np.ndarray
    explained_variance_ratio: np.ndarray


def pca_loadings(
    data: RadialDataset, n_components: int = 3, features: Sequence[str] = FEATURE_NAMES
) -> PCAResult:
    """PCA of the contact features after standardisation to unit variance (Sec 4.1.2.4.1).

    Each component's sign is fixed so that its largest-magnitude loading is
    positive (PCA signs are arbitrary).
    """
    data.require_nonempty("PCA")
    X = data.columns(features)
    if not 1 <= n_components <= X.shape[1]:
        raise InvalidInputError(f"n_components must be in [1, {X.shape[1]}], got {n_components}")
    pipe = make_pipeline(StandardScaler(), PCA(n_components=n_components)).fit(X)
    pca = pipe[-1]
    comps = pca.components_.copy()
    sign = np.sign(comps[np.arange(len(comps)), np.argmax(np.abs(comps), axis=1)])
    comps *= sign[:, None]
    return PCAResult(tuple(features), comps, pca.explained_variance_ratio_.copy())


#: Columns of the results table, in order.
RESULT_COLUMNS: tuple[str, ...] = (
    "model",
    "features",
    "n_contacts",
    "median_abs_error",
    "median_error",
    "std_error",
    "ks_p_vs_tip",
    "ks_p_vs_random",
    "median_abs_mesh_distance_m",
    "std_mesh_distance_m",
    "mesh_ks_p_vs_tip",
    "mesh_ks_p_vs_random",
    "cv_rmse_m",
    "fit_seconds",
)


@dataclass(frozen=True)
class ModelScore:
    """Validation scores of one model (one row of the results table).

    Errors are Eq 4.1 fractions of whisker length over the evaluated contacts;
    mesh distances are in metres (NaN when no mesh was given).
    """

    model: str
    features: str
    n_contacts: int
    median_abs_error: float
    median_error: float
    std_error: float
    ks_p_vs_tip: float
    ks_p_vs_random: float
    median_abs_mesh_distance_m: float = float("nan")
    std_mesh_distance_m: float = float("nan")
    mesh_ks_p_vs_tip: float = float("nan")
    mesh_ks_p_vs_random: float = float("nan")
    cv_rmse_m: float = float("nan")
    fit_seconds: float = float("nan")
    errors: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    mesh_distances_m: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    def row(self) -> dict[str, Any]:
        """The table row: :data:`RESULT_COLUMNS` -> value."""
        return {c: getattr(self, c) for c in RESULT_COLUMNS}


Reconstruct = Callable[[RadialDataset, np.ndarray], np.ndarray]


def evaluate_models(
    models: Mapping[str, TrainedModel],
    validation: RadialDataset,
    *,
    keep: np.ndarray | None = None,
    max_fraction: float = 0.7,
    reconstruct: Reconstruct | None = None,
    mesh: Any = None,
    seed: int = 0,
) -> list[ModelScore]:
    """Score fitted models on a validation set (Sec 4.2.1, Fig 4.8-4.9).

    Parameters
    ----------
    models : mapping label -> TrainedModel
    validation : RadialDataset
        Validation contacts with simulated ground truth.
    keep : ndarray of bool, shape (n,), optional
        Extra selection (for example the contacts of unseen whisker lengths),
        combined with the ``d_gt <= max_fraction * d_wl`` rule.
    max_fraction : float
        The 0.7 of Sec 4.2.1.
    reconstruct : callable (dataset, d_m) -> points (n, 3), optional
        Places contacts from radial distances (forward kinematics, see
        :func:`whisker_io.radial.pipeline.dataset_contact_points`); with ``mesh``
        adds the point-to-mesh columns.
    mesh : trimesh.Trimesh, optional
    seed : int
        Seed of the uniform-random reference distribution used in the KS tests.

    Returns
    -------
    list of ModelScore
        One per model, in the mapping's order. The KS references (tip and
        random) are always computed, whether or not they are in ``models``.

    Raises
    ------
    EmptyDatasetError
        If no contact survives the selection.
    """
    mask = evaluation_mask(validation.radial_distance_m, validation.whisker_length_m, max_fraction)
    if keep is not None:
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != mask.shape:
            raise InvalidInputError(f"keep must have shape {mask.shape}, got {keep.shape}")
        mask &= keep
    data = validation.subset(mask)
    data.require_nonempty("evaluation (after the d_gt <= 0.7 d_wl selection)")
    X, d_gt, wl = data.features, data.radial_distance_m, data.whisker_length_m

    def _dist(d_m: np.ndarray) -> np.ndarray:
        if reconstruct is None or mesh is None:
            return np.zeros(0)
        return point_to_mesh_distance(reconstruct(data, d_m), mesh)

    refs = {}
    for name, est in (("tip", TipAssumption()), ("random", UniformRandom(random_state=seed))):
        d_m = est.fit(X).predict(X)
        refs[name] = (radial_error(d_m, d_gt, wl), _dist(d_m))
    scores = []
    for label, model in models.items():
        d_m = _predict(model, X)
        err = radial_error(d_m, d_gt, wl)
        dist = _dist(d_m)
        mesh_cols: dict[str, float] = {}
        if dist.size:
            mesh_cols = dict(
                median_abs_mesh_distance_m=float(np.median(np.abs(dist))),
                std_mesh_distance_m=float(np.std(dist)),
                mesh_ks_p_vs_tip=ks_pvalue(dist, refs["tip"][1]),
                mesh_ks_p_vs_random=ks_pvalue(dist, refs["random"][1]),
            )
        scores.append(
            ModelScore(
                model=label,
                features="-".join(model.features),
                n_contacts=int(len(err)),
                median_abs_error=float(np.median(np.abs(err))),
                median_error=float(np.median(err)),
                std_error=float(np.std(err)),
                ks_p_vs_tip=ks_pvalue(err, refs["tip"][0]),
                ks_p_vs_random=ks_pvalue(err, refs["random"][0]),
                cv_rmse_m=float(model.cv_rmse_m),
                fit_seconds=float(model.fit_seconds),
                errors=err,
                mesh_distances_m=dist,
                **mesh_cols,
            )
        )
    return scores


def write_results_csv(scores: Sequence[ModelScore], path: str | os.PathLike[str]) -> Path:
    """Write the results table (:data:`RESULT_COLUMNS`, one row per model) as CSV.

    A figure a model does not have (the baselines' cross-validation error, a mesh distance
    without a mesh) is an empty cell, not ``nan``.
    """
    from whisker_io.persistence import write_csv

    path = Path(path)
    write_csv(path, RESULT_COLUMNS, ({k: ((f"{v:.6g}" if np.isfinite(v) else "") if isinstance(v, float) else v)
                                      for k, v in s.row().items()} for s in scores))
    return path


#: Models of Fig 4.10-4.11: (family, features); polynomials are 5th order as in Evans et al.
_COMPARISON: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("poly", EVANS_FEATURES),
    ("poly", OUR_FEATURES),
    ("svr", EVANS_FEATURES),
    ("svr", OUR_FEATURES),
)


def _compare(train: RadialDataset, test: RadialDataset, settings: SearchParams) -> dict[str, np.ndarray]:
    """Fit the four comparison models on ``train``; absolute Eq 4.1 errors on ``test``."""
    out = {}
    for fam, feats in _COMPARISON:
        who = "Evans" if feats == EVANS_FEATURES else "ours"
        name = f"{'poly5' if fam == 'poly' else 'svr'} {who} ({'-'.join(feats)})"
        extra = {"degree": 5} if fam == "poly" else {}
        model = fit_model(name, fam, feats, train, settings, **extra)
        out[name] = np.abs(
            radial_error(_predict(model, test.features), test.radial_distance_m, test.whisker_length_m)
        )
    return out


def evans_comparison(
    evans: RadialDataset,
    settings: SearchParams = SearchParams(),
    test_fraction: float = 0.3,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """Sec 4.2.2 / Fig 4.10: Evans et al. (2013) model vs ours on one whisker.

    The data set is split at random 70/30 (seeded); four models are trained on
    the 70 %: a 5th-order polynomial and an SVR (hyper-parameters by K-fold CV on
    the training part), each on the Evans features (CA, CP) and on ours
    (CP-CA-DV-DA).

    Returns
    -------
    dict
        ``{"poly5 Evans (CA-CP)", "poly5 ours (CP-CA-DV-DA)", "svr Evans (CA-CP)",
        "svr ours (CP-CA-DV-DA)"}`` -> absolute errors on the 30 % test part as a
        fraction of whisker length (thesis medians: poly5 Evans 3.37 %, svr ours 2.77 %).
    """
    evans.require_nonempty("the Evans comparison")
    if not 0.0 < test_fraction < 1.0:
        raise InvalidInputError(f"test_fraction must be in (0, 1), got {test_fraction}")
    tr, te = train_test_split(np.arange(len(evans)), test_size=test_fraction, random_state=seed)
    train, test = evans.subset(np.sort(tr), name="evans-train"), evans.subset(np.sort(te), name="evans-test")
    return _compare(train, test, settings)


def length_generalisation(
    train: RadialDataset,
    test: RadialDataset,
    reference_length_m: float = 0.107,
    settings: SearchParams = SearchParams(),
    max_fraction: float | None = None,
) -> dict[str, dict[str, np.ndarray]]:
    """Fig 4.11: train on one whisker length vs on many, test on other lengths.

    Parameters
    ----------
    train : RadialDataset
        Multi-length training set; the "one" scenario keeps only contacts whose
        WL equals ``reference_length_m`` (within 0.5 mm).
    test : RadialDataset
        Contacts on whisker lengths not in ``train`` (unseen lengths).
    reference_length_m : float
        The single training length (thesis: 107 mm).
    settings : SearchParams
    max_fraction : float, optional
        If given, only test contacts with ``d_gt <= max_fraction * d_wl`` count.

    Returns
    -------
    dict
        ``{"one": {...}, "many": {...}}``, each mapping model name (poly5 / svr on
        Evans and our features, as in :func:`evans_comparison`) to absolute errors
        (fraction of whisker length) on ``test``.
    """
    one = train.subset(np.abs(train.whisker_length_m - reference_length_m) < 5e-4, name="one-length")
    one.require_nonempty(f"training on the {reference_length_m * 1e3:.0f} mm whisker")
    if max_fraction is not None:
        test = test.subset(evaluation_mask(test.radial_distance_m, test.whisker_length_m, max_fraction))
    test.require_nonempty("the length-generalisation test")
    return {scenario: _compare(data, test, settings) for scenario, data in (("one", one), ("many", train))}
