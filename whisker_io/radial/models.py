"""Radial-distance regressors of thesis Ch.4 as scikit-learn estimators.

Every model is a :class:`sklearn.pipeline.Pipeline` that takes the full contact
feature matrix (n, 7) in :data:`~whisker_io.radial.features.FEATURE_NAMES` order
and predicts the radial distance to contact in metres::

    SelectFeatures(features) -> StandardScaler -> TransformedTargetRegressor(reg, StandardScaler)

so one feature matrix feeds all twelve models of Table 4.1 and the baselines,
and each fitted model carries its own feature list. Standardising the target as
well makes the hyper-parameter grids (SVR epsilon, MLP regularisation) unit-free.

Model families (Sec 4.1.3 of the thesis):

* ``svr``  -- support vector regression; kernel (RBF or linear), C, epsilon and
  gamma searched by K-fold cross-validation (the thesis' fitrsvm search found the
  Gaussian kernel best).
* ``poly`` -- least-squares polynomial regression (polyfitn); order 2-6 chosen by
  10-fold CV (the thesis found 3).
* ``nn``   -- multi-layer perceptron with at most 2 hidden layers of at most
  58 nodes (the thesis' optimum was 2 x 58), structure searched by CV.
* baselines :class:`TipAssumption` (radial distance = whisker length) and
  :class:`UniformRandom` (uniform on [0, whisker length]), Sec 4.2.1.

Hyper-parameters are searched on the training set only (never the validation set).
"""

from __future__ import annotations

import logging
import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, TransformerMixin, clone
from sklearn.compose import TransformedTargetRegressor
from sklearn.exceptions import NotFittedError
from sklearn.linear_model import LinearRegression
from sklearn.experimental import enable_halving_search_cv  # noqa: F401  (enables the import below)
from sklearn.model_selection import HalvingGridSearchCV, KFold
from sklearn.neural_network import MLPRegressor
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import PolynomialFeatures, StandardScaler
from sklearn.svm import SVR
from threadpoolctl import threadpool_limits

from whisker_io.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, caller_stacklevel, checked, number_tuple, validate_fields
from whisker_io._deprecated import renamed_attributes
from whisker_io.radial.errors import EmptyDatasetError, ExtrapolationWarning, FeatureMismatchError, NotFittedModelError
from whisker_io.radial.features import FEATURE_NAMES, FEATURE_UNITS, RadialDataset, feature_indices

__all__ = [
    "TABLE_4_1",
    "BASELINES",
    "SearchParams",
    "SelectFeatures",
    "TipAssumption",
    "UniformRandom",
    "TrainedModel",
    "make_estimator",
    "make_search",
    "fit_model",
    "train_models",
    "model_features",
    "check_feature_matrix",
    "training_band",
]

log = logging.getLogger(__name__)

_F4 = ("CP", "CA", "DV", "DA")

#: Table 4.1 of the thesis: label -> (family, input features).
TABLE_4_1: Mapping[str, tuple[str, tuple[str, ...]]] = MappingProxyType(
    {
        "nn1": ("nn", _F4 + ("AV", "WL")),
        "nn2": ("nn", _F4 + ("AV",)),
        "nn3": ("nn", _F4 + ("WL",)),
        "nn4": ("nn", _F4),
        "poly5": ("poly", _F4 + ("AV", "WL")),
        "poly6": ("poly", _F4 + ("AV",)),
        "poly7": ("poly", _F4 + ("WL",)),
        "poly8": ("poly", _F4),
        "svr9": ("svr", _F4 + ("AV", "WL")),
        "svr10": ("svr", _F4 + ("AV",)),
        "svr11": ("svr", _F4 + ("WL",)),
        "svr12": ("svr", _F4),
    }
)

#: The two baselines of Sec 4.2.1: label -> (family, input features).
BASELINES: Mapping[str, tuple[str, tuple[str, ...]]] = MappingProxyType(
    {"tip": ("tip", ("WL",)), "random": ("random", ("WL",))}
)


def check_feature_matrix(X: Any, what: str = "X") -> np.ndarray:
    """Validate a contact-feature matrix: shape (n, 7), finite.

    Raises
    ------
    InvalidInputError
        On a wrong shape or NaN/inf values (the message gives the first bad cell).
    """
    arr = np.asarray(X, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != len(FEATURE_NAMES):
        raise FeatureMismatchError(
            f"{what} must have shape (n, {len(FEATURE_NAMES)}) with columns {FEATURE_NAMES}, "
            f"got {arr.shape}"
        )
    if not np.isfinite(arr).all():
        r, c = np.argwhere(~np.isfinite(arr))[0]
        raise InvalidInputError(
            f"{what} holds NaN/inf at row {r}, feature {FEATURE_NAMES[c]}; "
            "drop contacts whose features could not be extracted"
        )
    wl = arr[:, FEATURE_NAMES.index("WL")]
    if np.any(wl <= 0):
        r = int(np.argmax(wl <= 0))
        raise InvalidInputError(f"{what}: whisker length WL must be > 0 m, got {float(wl[r])!r} at row {r} "
                                "(columns in FEATURE_NAMES order, WL last)")
    return arr


#: How far outside a feature's training range an input lies before :meth:`TrainedModel.predict` warns: this
#: share of the range's width, or of the larger magnitude of its ends when that is larger (a narrow range far
#: from zero, e.g. whisker lengths of 65-137 mm, then allows 14 mm).
OUTSIDE_MARGIN = 0.1


def training_band(lo: float, hi: float) -> tuple[float, float]:
    """The inputs a model trained on ``[lo, hi]`` takes without an extrapolation warning: the range widened by
    :data:`OUTSIDE_MARGIN` of its width, or of its ends' larger magnitude when that is larger (same unit as ``lo``)."""
    pad = OUTSIDE_MARGIN * max(hi - lo, abs(hi), abs(lo), 1e-12)
    return lo - pad, hi + pad


def _warn_outside(label: str, X: np.ndarray, features: Sequence[str],
                  training_range: Mapping[str, tuple[float, float]]) -> bool:
    """One warning naming the features of ``X`` (rows) outside ``training_range`` by more than the margin;
    whether it was given."""
    outside, rows = [], np.zeros(len(X), dtype=bool)
    for f in features:
        if f not in training_range:
            continue
        lo, hi = training_range[f]
        low, high = training_band(lo, hi)
        col = X[:, FEATURE_NAMES.index(f)]
        bad = (col < low) | (col > high)
        if bad.any():
            rows |= bad
            worst = col[bad][np.argmax(np.abs(col[bad] - (lo + hi) / 2))]
            outside.append(f"{f} {worst:.4g} {FEATURE_UNITS[f]} (trained on {lo:.4g} to {hi:.4g})")
    if outside:
        warnings.warn(f"{int(rows.sum())} of {len(X)} contacts lie outside the data model {label!r} was trained on: "
                      + "; ".join(outside) + " - check the units (WL in m, AV in rad/s, AA in rad/s^2) and the "
                      "whisker lengths; estimates there are extrapolations (warned once per model)", ExtrapolationWarning,
                      stacklevel=caller_stacklevel())
    return bool(outside)


class SelectFeatures(TransformerMixin, BaseEstimator):
    """Pick the named columns of a full contact-feature matrix (n, 7).

    Parameters
    ----------
    features : tuple of str
        Names from :data:`FEATURE_NAMES`, in the order the regressor sees them.
    """

    def __init__(self, features: tuple[str, ...] = FEATURE_NAMES) -> None:
        self.features = features

    def fit(self, X: Any, y: Any = None) -> "SelectFeatures":
        """Validate ``X`` and the feature names; nothing is learnt."""
        check_feature_matrix(X)
        self.indices_ = np.asarray(feature_indices(self.features), dtype=np.intp)
        self.n_features_in_ = len(FEATURE_NAMES)
        return self

    def transform(self, X: Any) -> np.ndarray:
        """Columns ``features`` of ``X``, shape (n, len(features))."""
        if not hasattr(self, "indices_"):
            raise NotFittedModelError("SelectFeatures.transform called before fit")
        return check_feature_matrix(X)[:, self.indices_]

    def get_feature_names_out(self, input_features: Any = None) -> np.ndarray:
        return np.asarray(self.features, dtype=object)


class _LengthBaseline(RegressorMixin, BaseEstimator):
    """Shared fit/validation of the whisker-length baselines (feature WL only)."""

    features = ("WL",)

    def fit(self, X: Any, y: Any = None) -> "_LengthBaseline":
        arr = check_feature_matrix(X)
        if arr.shape[0] == 0:
            raise EmptyDatasetError("cannot fit on an empty feature matrix")
        self.n_features_in_ = len(FEATURE_NAMES)
        self.fitted_ = True
        return self

    def _lengths(self, X: Any) -> np.ndarray:
        if not getattr(self, "fitted_", False):
            raise NotFittedModelError(f"{type(self).__name__}.predict called before fit")
        return check_feature_matrix(X)[:, FEATURE_NAMES.index("WL")]


class TipAssumption(_LengthBaseline):
    """Baseline: the contact is at the whisker tip, d_m = WL (Sec 4.2.1, used in Ch.3)."""

    def predict(self, X: Any) -> np.ndarray:
        """Radial distance = whisker length, m, shape (n,)."""
        return self._lengths(X).copy()


class UniformRandom(_LengthBaseline):
    """Baseline: d_m ~ Uniform(0, WL) (Sec 4.2.1).

    Parameters
    ----------
    random_state : int
        Seed; the same input gives the same draws on every call.
    """

    def __init__(self, random_state: int = 0) -> None:
        self.random_state = random_state

    def predict(self, X: Any) -> np.ndarray:
        """Uniform draws on [0, WL], m, shape (n,)."""
        wl = self._lengths(X)
        return np.random.default_rng(self.random_state).uniform(0.0, 1.0, wl.shape) * wl


@dataclass(frozen=True)
class SearchParams(ConfigDataclass):
    """Hyper-parameter search settings (Sec 4.1.3); grids are in standardised units.

    Parameters
    ----------
    cv_folds : int
        K of the K-fold cross-validation (thesis: 10).
    seed : int
        Seed of the fold shuffling, MLP initialisation and search subsampling.
    max_search_samples : int or None
        If set and the training set is larger, the grid search runs on a seeded
        random subset of this many training contacts and the best configuration is
        then refitted on the whole training set (keeps SVR searches on 10^4
        contacts to seconds). ``None`` searches on everything.
    svr_kernels : tuple of str
        Kernels searched (thesis: linear, polynomial, Gaussian; Gaussian won).
    svr_C, svr_epsilon, svr_gamma : tuples
        SVR grids for the non-linear kernels; epsilon in units of the target's
        standard deviation, gamma in 1/(standardised feature units)^2 or ``"scale"``.
        C stops at 100: one RBF fit at C = 1000, epsilon = 0.01 takes ~15 s on
        1350 contacts (~0.4 s at C = 100), which would make the study take hours.
    svr_linear_C : tuple of float
        C grid of the linear kernel (kept small: libsvm's linear solver needs
        ~15x longer per fit at C = 100 than at C = 1).
    poly_degrees : tuple of int
        Polynomial orders searched (thesis: 2-6).
    mlp_hidden : tuple of tuples
        MLP hidden-layer structures searched (<= 2 layers, <= 58 nodes).
    mlp_alpha : tuple of float
        MLP L2 penalties searched.
    mlp_max_iter : int
        L-BFGS iterations per MLP fit.
    n_jobs : int
        Parallel jobs of the grid search (the study machine has 2 cores).
    blas_threads : int or None
        BLAS threads while fitting (``threadpoolctl``, restored afterwards). The
        matrices here are small, and multi-threaded BLAS on a busy 2-core machine
        made an MLP fit ~50x slower than single-threaded; ``None`` leaves it alone.
    """

    cv_folds: int = checked(10, int, minimum=2, maximum=1000, error=InvalidInputError)
    seed: int = checked(0, int, minimum=0, error=InvalidInputError)
    max_search_samples: int | None = checked(1500, int, minimum=1, optional=True, error=InvalidInputError)
    svr_kernels: tuple[str, ...] = ("rbf", "linear")
    svr_C: tuple[float, ...] = (1.0, 10.0, 100.0)
    svr_epsilon: tuple[float, ...] = (0.01, 0.05, 0.1)
    svr_gamma: tuple[float | str, ...] = ("scale", 0.5)
    svr_linear_C: tuple[float, ...] = (0.1, 1.0)
    poly_degrees: tuple[int, ...] = (2, 3, 4, 5, 6)
    mlp_hidden: tuple[tuple[int, ...], ...] = ((16,), (58,), (16, 16), (58, 58))
    mlp_alpha: tuple[float, ...] = (1e-3,)
    mlp_max_iter: int = checked(400, int, minimum=1, maximum=1_000_000, error=InvalidInputError)
    n_jobs: int = checked(1, int, minimum=1, maximum=1024, error=InvalidInputError)
    blas_threads: int | None = checked(1, int, minimum=1, maximum=1024, optional=True, error=InvalidInputError)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.svr_kernels, (tuple, list)) or not self.svr_kernels or any(
                k not in ("rbf", "linear", "poly", "sigmoid") for k in self.svr_kernels):
            raise InvalidInputError(f"svr_kernels must name kernels among rbf, linear, poly, sigmoid, got {self.svr_kernels!r}")
        for name in ("svr_C", "svr_epsilon", "svr_linear_C"):
            number_tuple(getattr(self, name), name, above=0)
        number_tuple(self.mlp_alpha, "mlp_alpha", minimum=0)
        if not isinstance(self.svr_gamma, (tuple, list)) or not self.svr_gamma or any(
                g not in ("scale", "auto") and not (isinstance(g, (int, float)) and not isinstance(g, bool)
                                                    and math.isfinite(g) and g > 0) for g in self.svr_gamma):
            raise InvalidInputError(f"svr_gamma must hold numbers > 0 or 'scale' / 'auto', got {self.svr_gamma!r}")
        number_tuple(self.poly_degrees, "poly_degrees", minimum=1, whole=True)
        if not isinstance(self.mlp_hidden, (tuple, list)) or not self.mlp_hidden:
            raise InvalidInputError(f"mlp_hidden must list hidden-layer structures, got {self.mlp_hidden!r}")
        for h in self.mlp_hidden:
            layers = number_tuple(h, "mlp_hidden", minimum=1, whole=True)
            if len(layers) > 2 or max(layers) > 58:
                raise InvalidInputError("mlp_hidden structures must have 1-2 layers of 1-58 nodes")

    def quick(self) -> "SearchParams":
        """A reduced copy for tests and smoke runs (3-fold CV, small grids)."""
        return replace(
            self,
            cv_folds=3,
            max_search_samples=600,
            svr_kernels=("rbf",),
            svr_C=(10.0, 100.0),
            svr_epsilon=(0.05,),
            svr_gamma=("scale",),
            poly_degrees=(2, 3, 4),
            mlp_hidden=((16, 16),),
            mlp_max_iter=200,
        )


def _pipeline(features: Sequence[str], reg: BaseEstimator, poly_degree: int | None = None) -> Pipeline:
    steps: list[tuple[str, Any]] = [
        ("select", SelectFeatures(tuple(features))),
        ("scale", StandardScaler()),
    ]
    if poly_degree is not None:
        steps.append(("poly", PolynomialFeatures(degree=poly_degree, include_bias=False)))
    steps.append(("reg", TransformedTargetRegressor(regressor=reg, transformer=StandardScaler())))
    return Pipeline(steps)


def make_estimator(
    family: str, features: Sequence[str], settings: SearchParams = SearchParams(), **params: Any
) -> BaseEstimator:
    """An unfitted radial-distance model of one family on ``features``.

    Parameters
    ----------
    family : {"svr", "poly", "nn", "tip", "random"}
    features : sequence of str
        Input features (names of :data:`FEATURE_NAMES`); ignored by the baselines,
        which use WL.
    settings : SearchParams
        Supplies the seed and MLP iterations.
    **params
        Fixed hyper-parameters: ``degree`` for poly (default 3, the thesis'
        optimum), sklearn SVR / MLPRegressor keywords otherwise.

    Returns
    -------
    estimator
        A Pipeline taking the full (n, 7) feature matrix, or a baseline estimator.
    """
    feature_indices(features)  # validates names
    if family == "svr":
        return _pipeline(features, SVR(**{"kernel": "rbf", **params}))
    if family == "poly":
        degree = int(params.pop("degree", 3))
        if params:
            raise InvalidInputError(f"poly takes only 'degree', got {sorted(params)}")
        return _pipeline(features, LinearRegression(), poly_degree=degree)
    if family == "nn":
        kw = {
            "hidden_layer_sizes": (58, 58),
            "solver": "lbfgs",
            "max_iter": settings.mlp_max_iter,
            "random_state": settings.seed,
            **params,
        }
        return _pipeline(features, MLPRegressor(**kw))
    if family == "tip":
        return TipAssumption()
    if family == "random":
        return UniformRandom(random_state=settings.seed)
    raise InvalidInputError(f"unknown model family {family!r}; use svr, poly, nn, tip or random")


def _grid(family: str, s: SearchParams) -> list[dict[str, list[Any]]]:
    if family == "svr":
        grids = []
        for k in s.svr_kernels:
            g: dict[str, list[Any]] = {
                "reg__regressor__kernel": [k],
                "reg__regressor__C": list(s.svr_linear_C if k == "linear" else s.svr_C),
                "reg__regressor__epsilon": list(s.svr_epsilon),
            }
            if k != "linear":
                g["reg__regressor__gamma"] = list(s.svr_gamma)
            grids.append(g)
        return grids
    if family == "poly":
        return [{"poly__degree": list(s.poly_degrees)}]
    if family == "nn":
        return [
            {
                "reg__regressor__hidden_layer_sizes": list(s.mlp_hidden),
                "reg__regressor__alpha": list(s.mlp_alpha),
            }
        ]
    raise InvalidInputError(f"family {family!r} has no hyper-parameter search")


def make_search(
    family: str, features: Sequence[str], settings: SearchParams = SearchParams()
) -> HalvingGridSearchCV:
    """K-fold cross-validated grid search (mean squared error) over one family's grid.

    Successive halving (scikit-learn's ``HalvingGridSearchCV``, factor 3): every
    candidate is scored by K-fold CV on a small random share of the training
    contacts, the best third go on to three times as many, and so on until the
    last round uses all of them (``min_resources="exhaust"``). It picks the same
    kind of optimum as an exhaustive grid at a fraction of the cost (the SVR grid
    has 24 candidates). Folds are shuffled with ``settings.seed``.
    """
    return HalvingGridSearchCV(
        make_estimator(family, features, settings),
        _grid(family, settings),
        factor=3,
        resource="n_samples",
        min_resources="exhaust",
        scoring="neg_mean_squared_error",
        cv=KFold(settings.cv_folds, shuffle=True, random_state=settings.seed),
        n_jobs=settings.n_jobs,
        refit=False,
        error_score="raise",
        random_state=settings.seed,
    )


def model_features(estimator: Any) -> tuple[str, ...]:
    """Input features a model of this module uses (``("WL",)`` for the baselines)."""
    if isinstance(estimator, Pipeline) and isinstance(estimator.steps[0][1], SelectFeatures):
        return tuple(estimator.steps[0][1].features)
    if isinstance(estimator, _LengthBaseline):
        return ("WL",)
    raise FeatureMismatchError(
        f"{type(estimator).__name__} is not a radial-distance model of whisker_io.radial.models"
    )


@dataclass(frozen=True)
class TrainedModel:
    """A fitted model with the outcome of its hyper-parameter search.

    Attributes
    ----------
    label : str
        Table 4.1 label (``"svr9"``) or baseline name.
    family : str
    features : tuple of str
    estimator : estimator
        Fitted; ``estimator.predict(X)`` with X of shape (n, 7) gives metres.
    best_params : dict
        Chosen hyper-parameters (empty for the baselines).
    cv_rmse_m : float
        Cross-validated root-mean-square error of the chosen configuration, m
        (NaN for the baselines).
    fit_seconds : float
        Wall time of search + refit.
    training_hash : str
        :meth:`RadialDataset.fingerprint` of the training set.
    training_range : mapping
        Feature name -> ``(min, max)`` over the training contacts, in the feature's units
        (:data:`~whisker_io.radial.features.FEATURE_UNITS`): :meth:`predict` warns of inputs
        outside it (empty for models saved before it was kept: no check).
    """

    label: str
    family: str
    features: tuple[str, ...]
    estimator: Any
    best_params: Mapping[str, Any] = field(default_factory=dict)
    cv_rmse_m: float = float("nan")
    fit_seconds: float = 0.0
    training_hash: str = ""
    training_range: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    warned: bool = field(default=False, repr=False, compare=False)

    def predict(self, X: Any, *, warn_outside: bool = True) -> np.ndarray:
        """Radial distance, m, shape (n,), from the full feature matrix (n, 7).

        Warns (``UserWarning``, once per model: ``warned`` then becomes True) when contacts
        lie outside the training data by more than :data:`OUTSIDE_MARGIN` - another whisker
        length, or another unit (mm for m, deg/s for rad/s): the estimate there is an
        extrapolation and can be far off. ``warn_outside=False`` for an extrapolation made on
        purpose (the Ch.4 study's unseen whisker lengths).

        Raises
        ------
        FeatureMismatchError, InvalidInputError
            ``X`` not of shape (n, 7), not finite, or a whisker length <= 0.
        NotFittedModelError
            The estimator was never fitted.
        """
        X = check_feature_matrix(X)
        if not len(X):
            return np.zeros(0)
        if warn_outside and not self.warned and _warn_outside(self.label, X, self.features, self.training_range):
            object.__setattr__(self, "warned", True)
        try:
            return np.asarray(self.estimator.predict(X), dtype=np.float64)
        except NotFittedError:
            raise NotFittedModelError(f"model {self.label!r} was never fitted; train it with fit_model / "
                                      "train_models, or load a saved one") from None


def fit_model(
    label: str,
    family: str,
    features: Sequence[str],
    train: RadialDataset,
    settings: SearchParams = SearchParams(),
    **fixed: Any,
) -> TrainedModel:
    """Search hyper-parameters by K-fold CV on ``train`` and fit the best model on all of it.

    Parameters
    ----------
    label : str
        Name stored with the model.
    family : {"svr", "poly", "nn", "tip", "random"}
    features : sequence of str
    train : RadialDataset
        Training contacts (never the validation set).
    settings : SearchParams
    **fixed
        If given, no search: these hyper-parameters are used as they are (for
        example ``degree=5`` for the Evans et al. 5th-order polynomial).

    Raises
    ------
    EmptyDatasetError
        If ``train`` has no rows, or fewer rows than CV folds.
    """
    train.require_nonempty(f"training {label}")
    t0 = time.perf_counter()
    X, y = train.features, train.radial_distance_m
    best: dict[str, Any] = {}
    cv_rmse = float("nan")
    if family in ("tip", "random") or fixed:
        est = make_estimator(family, features, settings, **fixed)
        best = dict(fixed)
    else:
        if len(train) < settings.cv_folds:
            raise EmptyDatasetError(
                f"training {label} needs at least {settings.cv_folds} contacts for "
                f"{settings.cv_folds}-fold CV, data set {train.name!r} has {len(train)}"
            )
        idx = np.arange(len(train))
        if settings.max_search_samples is not None and len(train) > settings.max_search_samples:
            idx = np.sort(
                np.random.default_rng(settings.seed).choice(
                    len(train), settings.max_search_samples, replace=False
                )
            )
        with threadpool_limits(limits=settings.blas_threads):
            search = make_search(family, features, settings).fit(X[idx], y[idx])
        best = dict(search.best_params_)
        cv_rmse = float(np.sqrt(-search.best_score_))
        est = clone(search.estimator).set_params(**best)
    with threadpool_limits(limits=settings.blas_threads):
        est.fit(X, y)
    dt = time.perf_counter() - t0
    log.info("fitted %s (%s on %s) in %.2f s: %s", label, family, "-".join(features), dt, best)
    used = tuple(features) if family not in ("tip", "random") else ("WL",)
    span = ({} if family in ("tip", "random") else  # the baselines do not extrapolate: nothing to warn of
            {f: (float(X[:, FEATURE_NAMES.index(f)].min()), float(X[:, FEATURE_NAMES.index(f)].max())) for f in used})
    return TrainedModel(
        label=label,
        family=family,
        features=tuple(features) if family not in ("tip", "random") else ("WL",),
        estimator=est,
        best_params=best,
        cv_rmse_m=cv_rmse,
        fit_seconds=dt,
        training_hash=train.fingerprint(),
        training_range=span,
    )


def train_models(
    train: RadialDataset,
    labels: Sequence[str] | None = None,
    settings: SearchParams = SearchParams(),
    progress: bool = False,
) -> dict[str, TrainedModel]:
    """Train the Table 4.1 models and the baselines ("one command trains all").

    Parameters
    ----------
    train : RadialDataset
    labels : sequence of str, optional
        Subset of ``TABLE_4_1`` and ``BASELINES`` keys; default all 12 + 2.
    settings : SearchParams
    progress : bool
        Show a tqdm progress bar.

    Returns
    -------
    dict
        label -> :class:`TrainedModel`, in the order of ``labels``.
    """
    catalogue = {**TABLE_4_1, **BASELINES}
    labels = list(catalogue) if labels is None else list(labels)
    unknown = [lab for lab in labels if lab not in catalogue]
    if unknown:
        raise InvalidInputError(f"unknown model labels {unknown}; known: {list(catalogue)}")
    train.require_nonempty("train_models")
    it: Any = labels
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(labels, desc="training radial models", unit="model")
    out: dict[str, TrainedModel] = {}
    for lab in it:
        family, feats = catalogue[lab]
        out[lab] = fit_model(lab, family, feats, train, settings)
    return out


#: ``SearchSettings``: the old name of :class:`SearchParams` (warns; removed in 0.3).
__getattr__ = renamed_attributes(__name__, {"SearchSettings": "SearchParams"}, globals())
