"""Save and load fitted radial-distance models without arbitrary pickle execution.

Models are written with :mod:`skops.io` (a zip of JSON schema + numpy arrays).
Loading first lists the file's types with :func:`skops.io.get_untrusted_types`
(which executes nothing) and refuses the file unless every type outside skops'
own defaults (numpy, scipy, scikit-learn) is in :data:`TRUSTED_TYPES` — the
estimator classes of :mod:`whisker_io.radial.models`. The file also holds:

* ``features``: the model's input features, and ``input_features``: the column
  order of the feature matrix it expects (:data:`FEATURE_NAMES`);
* ``units``: unit of every input feature and of the prediction (m);
* ``versions``: numpy, scipy, scikit-learn, skops and whisker_io at save time;
* ``training_hash``: SHA-256 fingerprint of the training set
  (:meth:`RadialDataset.fingerprint`), hyper-parameters and CV error. The
  hyper-parameters are kept as they are when they are numbers, strings, booleans
  or None (numpy scalars as the Python number), as their ``repr`` string
  otherwise, so a loaded model saves the same metadata again (each save used to
  quote the loaded strings once more: ``'rbf'`` -> ``"'rbf'"`` -> ...).

A file written by another format version, scikit-learn major.minor or numpy
major version is refused with :class:`ModelVersionError` (scikit-learn does not
promise that fitted estimators survive version changes); a file whose features
differ from the ones the caller expects with :class:`FeatureMismatchError`.
Retraining with :func:`whisker_io.radial.models.train_models` fixes both.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import skops.io as sio
from sklearn.exceptions import NotFittedError
from sklearn.utils.validation import check_is_fitted

from whisker_io.errors import InvalidInputError
from whisker_io.persistence import write_atomically
from whisker_io.radial.errors import CorruptFileError, FeatureMismatchError, ModelVersionError, NotFittedModelError
from whisker_io.radial.features import FEATURE_NAMES, FEATURE_UNITS
from whisker_io.radial.models import TrainedModel, model_features

__all__ = ["FORMAT", "FORMAT_VERSION", "TRUSTED_TYPES", "library_versions", "save_model", "load_model"]

#: Identifier stored in every model file.
FORMAT = "whisker_io.radial.model"
#: Version of the file layout; bumped when the metadata changes incompatibly.
FORMAT_VERSION = 1
#: Types (besides skops' numpy/scipy/scikit-learn defaults) allowed in a model file.
TRUSTED_TYPES: tuple[str, ...] = (
    "whisker_io.radial.models.SelectFeatures",
    "whisker_io.radial.models.TipAssumption",
    "whisker_io.radial.models.UniformRandom",
)

_PACKAGES = ("numpy", "scipy", "scikit-learn", "skops", "cansim")


def library_versions() -> dict[str, str]:
    """Installed versions of the libraries a saved model depends on."""
    out = {}
    for pkg in _PACKAGES:
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:  # pragma: no cover - editable installs
            out[pkg] = "unknown"
    return out


def _plain_param(value: Any) -> Any:
    """A hyper-parameter as saved: plain Python scalars as they are, anything else as its ``repr``."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


def _major_minor(v: str, n: int) -> tuple[str, ...]:
    return tuple(v.split(".")[:n])


def _training_range(value: Any, path: Path) -> dict[str, tuple[float, float]]:
    """The ``training_range`` of a saved model's metadata (absent in files written before it: empty)."""
    try:
        out = {str(f): (float(lo), float(hi)) for f, (lo, hi) in dict(value).items()}
    except (TypeError, ValueError) as exc:
        raise CorruptFileError(f"{path}: malformed training_range ({exc})") from None
    if any(f not in FEATURE_NAMES or not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi) for f, (lo, hi) in out.items()):
        raise CorruptFileError(f"{path}: malformed training_range {value!r}")
    return out


def save_model(model: TrainedModel, path: str | os.PathLike[str]) -> Path:
    """Write a fitted model and its metadata to ``path`` (skops format, ``.skops``).

    Parameters
    ----------
    model : TrainedModel
        From :func:`~whisker_io.radial.models.fit_model` / ``train_models``.
    path : path-like
        Destination; written to a temporary name and renamed, so a crash never
        leaves a half-written model under ``path``.

    Returns
    -------
    Path
    """
    if not isinstance(model, TrainedModel):
        raise InvalidInputError(f"save_model takes a TrainedModel (from fit_model / train_models), got "
                                f"{type(model).__name__}; wrap a fitted estimator as TrainedModel(label, family, "
                                "features, estimator)")
    try:
        check_is_fitted(model.estimator)
    except NotFittedError:
        raise NotFittedModelError(f"model {model.label!r} was never fitted: nothing to save (fit_model / "
                                  "train_models fit it)") from None
    feats = model_features(model.estimator)
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "label": model.label,
        "family": model.family,
        "features": list(feats),
        "input_features": list(FEATURE_NAMES),
        "units": {**{f: FEATURE_UNITS[f] for f in FEATURE_NAMES}, "prediction": "m"},
        "versions": library_versions(),
        "training_hash": model.training_hash,
        "best_params": {str(k): _plain_param(v) for k, v in model.best_params.items()},
        "cv_rmse_m": float(model.cv_rmse_m),
        "fit_seconds": float(model.fit_seconds),
        "training_range": {str(f): [float(lo), float(hi)] for f, (lo, hi) in model.training_range.items()},
    }
    path = Path(path)
    data = _canonical_skops(sio.dumps({"meta": meta, "estimator": model.estimator}))
    write_atomically(path, lambda fh: fh.write(data))
    return path


#: Time stamp of every member of a saved model (the zip format's earliest date), so that
#: the same model saves to the same bytes.
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def _canonical_skops(data: bytes) -> bytes:
    """The same skops archive with reproducible bytes.

    skops names each object by its ``id()`` (the ``__id__`` of a schema node and the
    ``<id>.npy`` member of an array), and zip stamps the time: two saves of one model
    differ. The ids become 1, 2, 3, ... in the order the schema lists them (a shared
    object keeps one number, so shared references stay shared; each immutable JSON value
    gets its own, since whether Python interned equal strings is not part of the model),
    the members are sorted by name and carry one fixed time stamp: the same model, or
    a model loaded from the file, saves to the same bytes, and skops reads back the same
    content.
    """
    import io
    import json

    with zipfile.ZipFile(io.BytesIO(data)) as src:
        schema = json.loads(src.read("schema.json"))
        numbers: dict[int, int] = {}  # skops id -> its first new number (what a cached node refers to)
        issued = [0]  # numbers from 1: skops does not memoize an __id__ of 0

        def fresh() -> int:
            issued[0] += 1
            return issued[0]

        def number(skops_id: int) -> int:
            if skops_id not in numbers:
                numbers[skops_id] = fresh()
            return numbers[skops_id]

        def renumber(node: Any) -> Any:
            if isinstance(node, dict):
                out = {}
                for key, value in node.items():
                    if key == "__id__" and isinstance(value, int) and not isinstance(value, bool):
                        loader = node.get("__loader__")
                        if loader == "JsonNode":  # an immutable value: whether Python shared one object
                            out[key] = fresh()    # between equal values is irrelevant, so each gets its own
                            numbers.setdefault(value, out[key])
                        elif loader == "CachedNode":
                            out[key] = numbers.get(value, value)
                        else:
                            out[key] = number(value)
                    elif key == "file" and isinstance(value, str) and value.endswith(".npy") and value[:-4].isdigit():
                        out[key] = f"{number(int(value[:-4]))}.npy"
                    else:
                        out[key] = renumber(value)
                return out
            if isinstance(node, list):
                return [renumber(v) for v in node]
            return node

        schema = renumber(schema)
        members = []
        for info in src.infolist():
            name = info.filename
            if name.endswith(".npy") and name[:-4].isdigit():
                if int(name[:-4]) not in numbers:
                    raise CorruptFileError(f"skops wrote array member {name} that its schema does not name")
                members.append((f"{numbers[int(name[:-4])]}.npy", src.read(name), info.compress_type))
            elif name != "schema.json":
                members.append((name, src.read(name), info.compress_type))
        members.append(("schema.json", json.dumps(schema, indent=2).encode(), zipfile.ZIP_STORED))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as dst:
        for name, payload, compress in sorted(members, key=lambda m: m[0]):
            info = zipfile.ZipInfo(name, date_time=_ZIP_TIME)
            info.compress_type = compress
            info.external_attr = 0o644 << 16
            dst.writestr(info, payload)
    return out.getvalue()


def load_model(
    path: str | os.PathLike[str], expected_features: Sequence[str] | None = None
) -> TrainedModel:
    """Load a model written by :func:`save_model`, refusing anything unexpected.

    Parameters
    ----------
    path : path-like
    expected_features : sequence of str, optional
        The features the caller will supply the model with; if given and the
        model was trained on others, the file is refused.

    Returns
    -------
    TrainedModel
        ``best_params`` as saved (numbers, strings, booleans, None; other values as their ``repr``).

    Raises
    ------
    CorruptFileError
        Missing/corrupt file, not a radial model, or untrusted types inside.
    ModelVersionError
        Other format version, scikit-learn major.minor or numpy major version.
    FeatureMismatchError
        The model's features differ from ``expected_features``, or the file's
        feature-matrix layout differs from :data:`FEATURE_NAMES`.
    """
    path = Path(path)
    try:
        untrusted = sio.get_untrusted_types(file=path)
    except (OSError, zipfile.BadZipFile, KeyError, ValueError) as exc:
        raise CorruptFileError(f"{path}: not a readable skops model file ({exc})") from exc
    extra = sorted(set(untrusted) - set(TRUSTED_TYPES))
    if extra:
        raise CorruptFileError(
            f"{path}: refusing to load types outside the trusted list: {extra}; "
            "only whisker_io.radial models and numpy/scipy/scikit-learn types are accepted"
        )
    try:
        obj: Any = sio.load(path, trusted=list(untrusted))
    except Exception as exc:  # skops raises a variety of errors on malformed content
        raise CorruptFileError(f"{path}: could not load model ({type(exc).__name__}: {exc})") from exc
    if not isinstance(obj, dict) or not isinstance(obj.get("meta"), dict) or "estimator" not in obj:
        raise CorruptFileError(f"{path}: not a {FORMAT} file (no meta/estimator entries)")
    meta = obj["meta"]
    if meta.get("format") != FORMAT:
        raise CorruptFileError(f"{path}: format {meta.get('format')!r} is not {FORMAT!r}")
    if meta.get("format_version") != FORMAT_VERSION:
        raise ModelVersionError(
            f"{path}: file format version {meta.get('format_version')!r}, this library reads "
            f"version {FORMAT_VERSION}; retrain and save the model again"
        )
    saved = dict(meta.get("versions", {}))
    now = library_versions()
    for pkg, n in (("scikit-learn", 2), ("numpy", 1)):
        if _major_minor(str(saved.get(pkg, "?")), n) != _major_minor(now[pkg], n):
            raise ModelVersionError(
                f"{path}: saved with {pkg} {saved.get(pkg)!r}, installed is {now[pkg]}; "
                f"fitted estimators are not portable across {pkg} versions - retrain the model "
                "(examples/radial_distance_study.py) or install the saving version"
            )
    if list(meta.get("input_features", [])) != list(FEATURE_NAMES):
        raise FeatureMismatchError(
            f"{path}: model expects feature columns {meta.get('input_features')}, "
            f"this library provides {list(FEATURE_NAMES)}"
        )
    feats = tuple(meta.get("features", ()))
    est = obj["estimator"]
    if model_features(est) != feats:
        raise CorruptFileError(f"{path}: stored feature list {feats} disagrees with the estimator")
    if expected_features is not None and tuple(expected_features) != feats:
        raise FeatureMismatchError(
            f"{path}: model {meta.get('label')!r} was trained on features {list(feats)}, "
            f"expected {list(expected_features)}; load the model for those features or retrain"
        )
    return TrainedModel(
        label=str(meta.get("label", "")),
        family=str(meta.get("family", "")),
        features=feats,
        estimator=est,
        best_params=dict(meta.get("best_params", {})),
        cv_rmse_m=float(meta.get("cv_rmse_m", np.nan)),
        fit_seconds=float(meta.get("fit_seconds", 0.0)),
        training_hash=str(meta.get("training_hash", "")),
        training_range=_training_range(meta.get("training_range", {}), path),
    )

