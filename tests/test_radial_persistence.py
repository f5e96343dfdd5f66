"""Saving and loading radial-distance models without arbitrary pickle execution."""

from __future__ import annotations

import numpy as np
import pytest
import skops.io as sio

from whisker_io.radial.errors import FeatureMismatchError, CorruptFileError, ModelVersionError
from whisker_io.radial.features import FEATURE_NAMES, RadialDataset
from whisker_io.radial.models import TABLE_4_1, SearchParams, fit_model
from whisker_io.radial.persistence import FORMAT, FORMAT_VERSION, load_model, save_model

QUICK = SearchParams().quick()


@pytest.fixture(scope="module")
def trained():
    rng = np.random.default_rng(0)
    X = rng.uniform(0.1, 1.0, (120, 7))
    X[:, 6] = rng.choice([0.065, 0.107], 120)
    data = RadialDataset(X, X[:, 6] * X[:, 0], name="toy")
    return data, fit_model("svr10", *TABLE_4_1["svr10"], data, QUICK)


def test_round_trip_keeps_predictions_and_metadata(tmp_path, trained) -> None:
    data, model = trained
    path = save_model(model, tmp_path / "svr10.skops")
    loaded = load_model(path, expected_features=TABLE_4_1["svr10"][1])
    np.testing.assert_array_equal(loaded.predict(data.features), model.predict(data.features))
    assert loaded.label == "svr10" and loaded.family == "svr"
    assert loaded.features == ("CP", "CA", "DV", "DA", "AV")
    assert loaded.training_hash == data.fingerprint()
    assert not list(tmp_path.glob("*.tmp"))


def test_model_from_another_feature_set_is_refused(tmp_path, trained) -> None:
    _, model = trained
    path = save_model(model, tmp_path / "m.skops")
    with pytest.raises(FeatureMismatchError, match="CP-CA-DV-DA|\\['CP', 'CA', 'DV', 'DA', 'AV'\\]"):
        load_model(path, expected_features=TABLE_4_1["svr9"][1])


def _forge(tmp_path, model, **meta_changes):
    """A model file with a tampered metadata entry (as another library version would write)."""
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "label": "svr10",
        "family": "svr",
        "features": list(TABLE_4_1["svr10"][1]),
        "input_features": list(FEATURE_NAMES),
        "versions": {"numpy": np.__version__, "scikit-learn": __import__("sklearn").__version__},
    }
    meta.update(meta_changes)
    path = tmp_path / "forged.skops"
    sio.dump({"meta": meta, "estimator": model.estimator}, path)
    return path


def test_other_library_or_format_version_is_refused(tmp_path, trained) -> None:
    _, model = trained
    load_model(_forge(tmp_path, model))  # the untampered forgery loads
    with pytest.raises(ModelVersionError, match="scikit-learn"):
        load_model(_forge(tmp_path, model, versions={"numpy": np.__version__, "scikit-learn": "0.24.2"}))
    with pytest.raises(ModelVersionError, match="format version"):
        load_model(_forge(tmp_path, model, format_version=FORMAT_VERSION + 1))
    with pytest.raises(FeatureMismatchError):
        load_model(_forge(tmp_path, model, input_features=["CP", "CA", "DV", "DA", "AV", "WL"]))
    with pytest.raises(CorruptFileError):
        load_model(_forge(tmp_path, model, features=["CP", "CA"]))


class Payload:
    """A type outside the trusted list; loading it would call __setstate__."""

    executed = False

    def __setstate__(self, state):  # pragma: no cover - must never run
        Payload.executed = True
        self.__dict__.update(state)


def test_untrusted_types_are_refused_before_anything_runs(tmp_path, trained) -> None:
    _, model = trained
    path = tmp_path / "evil.skops"
    sio.dump({"meta": {"format": FORMAT}, "estimator": model.estimator, "x": Payload()}, path)
    with pytest.raises(CorruptFileError, match="trusted"):
        load_model(path)
    assert Payload.executed is False


def test_corrupt_or_missing_files(tmp_path) -> None:
    bad = tmp_path / "bad.skops"
    bad.write_bytes(b"not a zip file at all")
    with pytest.raises(CorruptFileError):
        load_model(bad)
    with pytest.raises(CorruptFileError):
        load_model(tmp_path / "missing.skops")
    other = tmp_path / "other.skops"
    sio.dump({"meta": {"format": "something else"}, "estimator": 1}, other)
    with pytest.raises(CorruptFileError, match="format"):
        load_model(other)
