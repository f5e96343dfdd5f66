"""Radial-distance models, baselines, evaluation metrics and bad input (thesis Ch.4).

The feature tables here come from a closed-form stand-in for the contact physics
(``r = WL * CP * AV``, Sec 4.1.2.4 names), so the truth a model must recover is
known exactly; the acceptance outcomes on simulated whisker data live in
``test_radial_acceptance.py``.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
import trimesh

from whisker_io.errors import InvalidInputError, CansimError
from whisker_io.radial.errors import EmptyDatasetError, ExtrapolationWarning, FeatureMismatchError
from whisker_io.radial.evaluation import (
    RESULT_COLUMNS,
    evaluate_models,
    evaluation_mask,
    ks_pvalue,
    pca_loadings,
    point_to_mesh_distance,
    radial_error,
    write_results_csv,
)
from whisker_io.radial.features import FEATURE_NAMES, RadialDataset
from whisker_io.radial.models import (
    TABLE_4_1,
    SearchParams,
    TipAssumption,
    UniformRandom,
    fit_model,
    model_features,
    train_models,
)

# the quick MLP search stops L-BFGS early on purpose
pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")

QUICK = SearchParams().quick()


def known_table(n: int, seed: int, lengths_mm=(65, 78, 87, 94, 107, 137)) -> RadialDataset:
    """Features from a known function: r = WL * s with CP = s / AV (so r = WL * CP * AV)."""
    rng = np.random.default_rng(seed)
    wl = rng.choice(np.asarray(lengths_mm) / 1e3, n)
    s = rng.uniform(0.2, 1.0, n)
    av = rng.uniform(0.5, 4.0, n)
    cp = s / av
    ca = 2000.0 * (1.2 - s)
    dv = ca / cp
    da = dv / cp
    aa = rng.normal(0.0, 1.0, n)
    X = np.column_stack([cp, ca, dv, da, av, aa, wl])
    return RadialDataset(X, wl * s, name=f"known-{seed}")


def test_table_4_1_matches_the_thesis() -> None:
    # Table 4.1 of the thesis, transcribed
    f4 = ("CP", "CA", "DV", "DA")
    expected = {}
    for fam, first in (("nn", 1), ("poly", 5), ("svr", 9)):
        for k, extra in enumerate((("AV", "WL"), ("AV",), ("WL",), ())):
            expected[f"{fam}{first + k}"] = (fam, f4 + extra)
    assert dict(TABLE_4_1) == expected


def test_baselines_tip_and_uniform_random() -> None:
    data = known_table(400, 1)
    X, wl = data.features, data.whisker_length_m
    np.testing.assert_array_equal(TipAssumption().fit(X).predict(X), wl)
    r1 = UniformRandom(random_state=3).fit(X).predict(X)
    r2 = UniformRandom(random_state=3).fit(X).predict(X)
    np.testing.assert_array_equal(r1, r2)
    assert np.all((r1 >= 0) & (r1 <= wl))
    # mean of U(0, WL) / WL is 1/2 (standard error ~ 0.29/sqrt(400) = 0.014)
    assert abs(np.mean(r1 / wl) - 0.5) < 0.05


def test_svr_recovers_known_function_better_than_tip_and_random() -> None:
    train, test = known_table(500, 2), known_table(300, 3)
    svr = fit_model("svr9", *TABLE_4_1["svr9"], train, QUICK)
    err = np.abs(radial_error(svr.predict(test.features), test.radial_distance_m, test.whisker_length_m))
    tip = np.abs(radial_error(test.whisker_length_m, test.radial_distance_m, test.whisker_length_m))
    assert np.median(err) < 0.03
    assert np.median(err) < 0.2 * np.median(tip)
    assert model_features(svr.estimator) == TABLE_4_1["svr9"][1]
    assert svr.training_hash == train.fingerprint()
    assert svr.best_params["reg__regressor__kernel"] == "rbf"


def test_fixed_polynomial_degree_is_used_without_search() -> None:
    train = known_table(200, 4)
    m = fit_model("evans", "poly", ("CA", "CP"), train, QUICK, degree=5)
    assert m.estimator.named_steps["poly"].degree == 5
    assert m.best_params == {"degree": 5}
    assert np.isnan(m.cv_rmse_m)


def test_train_models_all_labels_and_order() -> None:
    train = known_table(120, 5)
    labels = ["poly8", "nn4", "svr12", "tip", "random"]
    out = train_models(train, labels, QUICK)
    assert list(out) == labels
    for lab in labels:
        pred = out[lab].predict(train.features)
        assert pred.shape == (len(train),) and np.all(np.isfinite(pred))


def test_mlp_structure_limits_and_unknown_labels_rejected() -> None:
    with pytest.raises(InvalidInputError):
        SearchParams(mlp_hidden=((59,),))
    with pytest.raises(InvalidInputError):
        SearchParams(mlp_hidden=((10, 10, 10),))
    with pytest.raises(InvalidInputError):
        train_models(known_table(50, 0), ["svr13"], QUICK)


def test_radial_error_eq_4_1_and_selection_by_hand() -> None:
    # (0.08 - 0.05) / 0.1 = 0.3 ; (0.02 - 0.05) / 0.1 = -0.3
    np.testing.assert_allclose(radial_error([0.08, 0.02], [0.05, 0.05], [0.1, 0.1]), [0.3, -0.3])
    np.testing.assert_array_equal(
        evaluation_mask([0.069, 0.07, 0.0701, 0.1], [0.1] * 4), [True, True, False, False]
    )


def test_ks_pvalue() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(0, 1, 300)
    assert ks_pvalue(a, a) == pytest.approx(1.0)
    assert ks_pvalue(a, a + 1.0) < 1e-10
    with pytest.raises(EmptyDatasetError):
        ks_pvalue(a, [])


def test_point_to_mesh_distance_signed_on_unit_box() -> None:
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    pts = [[1.0, 0.0, 0.0], [0.25, 0.0, 0.0], [0.0, 0.0, -0.8]]
    np.testing.assert_allclose(point_to_mesh_distance(pts, box), [0.5, -0.25, 0.3], atol=1e-9)
    np.testing.assert_allclose(point_to_mesh_distance(pts, box, signed=False), [0.5, 0.25, 0.3], atol=1e-9)


def test_pca_loadings_after_standardisation() -> None:
    # CP and CA perfectly correlated (very different scales), the rest independent:
    # after standardisation PC1 = (CP + CA) / sqrt(2), explaining 2/7 of the variance.
    rng = np.random.default_rng(1)
    n = 4000
    X = rng.normal(size=(n, 7))
    X[:, 1] = 1e4 * X[:, 0]
    X[:, 6] = np.abs(X[:, 6]) + 0.05
    pca = pca_loadings(RadialDataset(X, np.ones(n)), n_components=3)
    # sample correlations of the independent columns are ~ 1/sqrt(n) = 0.016
    np.testing.assert_allclose(pca.components[0, :2], [2**-0.5, 2**-0.5], atol=0.01)
    np.testing.assert_allclose(pca.components[0, 2:], 0.0, atol=0.05)
    assert pca.explained_variance_ratio[0] == pytest.approx(2 / 7, abs=0.02)
    assert pca.feature_names == FEATURE_NAMES


def test_evaluate_models_on_hand_made_validation(tmp_path) -> None:
    # every contact at half the whisker length -> tip error exactly +0.5
    wl = np.array([0.05, 0.08, 0.1, 0.15] * 25)
    X = np.column_stack([np.ones((100, 6)), wl])
    val = RadialDataset(X, 0.5 * wl)
    models = train_models(RadialDataset(X, 0.5 * wl), ["tip", "random"], QUICK)
    scores = evaluate_models(models, val)
    tip = scores[0]
    assert tip.model == "tip" and tip.features == "WL" and tip.n_contacts == 100
    assert tip.median_error == pytest.approx(0.5) and tip.median_abs_error == pytest.approx(0.5)
    assert tip.ks_p_vs_tip == pytest.approx(1.0)
    assert scores[1].ks_p_vs_random == pytest.approx(1.0)
    # keep + the 0.7 rule: nothing left -> typed error
    with pytest.raises(EmptyDatasetError):
        evaluate_models(models, val, keep=np.zeros(100, bool))
    path = write_results_csv(scores, tmp_path / "radial_results.csv")
    rows = list(csv.DictReader(path.open()))
    assert tuple(rows[0]) == RESULT_COLUMNS and [r["model"] for r in rows] == ["tip", "random"]
    assert float(rows[0]["median_abs_error"]) == pytest.approx(0.5)
    assert rows[0]["cv_rmse_m"] == "" and "nan" not in path.read_text().lower()  # a baseline has no CV error: empty


# ---------------------------------------------------------------- bad input

def test_nan_features_are_typed_errors() -> None:
    data = known_table(60, 6)
    X = np.array(data.features)
    X[3, 2] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        RadialDataset(X, data.radial_distance_m)
    model = fit_model("svr12", *TABLE_4_1["svr12"], data, QUICK)
    with pytest.raises(InvalidInputError, match="DV"):
        model.predict(X)
    with pytest.raises(InvalidInputError):
        TipAssumption().fit(data.features).predict(X)
    with pytest.raises(FeatureMismatchError):
        model.predict(data.features[:, :6])


def test_empty_training_set_is_a_typed_error() -> None:
    empty = RadialDataset(np.zeros((0, 7)), np.zeros(0), name="empty")
    for call in (
        lambda: fit_model("svr9", *TABLE_4_1["svr9"], empty, QUICK),
        lambda: train_models(empty, ["svr9"], QUICK),
        lambda: fit_model("tip", "tip", ("WL",), empty, QUICK),
    ):
        with pytest.raises(EmptyDatasetError) as info:
            call()
        assert isinstance(info.value, CansimError) and isinstance(info.value, ValueError)
    tiny = known_table(5, 0)  # fewer contacts than CV folds
    with pytest.raises(EmptyDatasetError, match="10-fold CV"):
        fit_model("svr9", *TABLE_4_1["svr9"], tiny, SearchParams())


def test_dataset_validation() -> None:
    with pytest.raises(InvalidInputError):
        RadialDataset(np.ones((3, 6)), np.ones(3))
    with pytest.raises(InvalidInputError):
        RadialDataset(np.ones((3, 7)), np.ones(4))
    X = np.ones((3, 7))
    X[:, 6] = 0.0
    with pytest.raises(InvalidInputError, match="WL"):
        RadialDataset(X, np.ones(3))
    with pytest.raises(InvalidInputError):
        RadialDataset(np.ones((3, 7)), np.ones(3), meta={"module": np.arange(2)})
    with pytest.raises(FeatureMismatchError):
        known_table(10, 0).columns(["CP", "XX"])


# ----------------------------------------------------------------- inputs a model was not trained for (session 47)
def test_inputs_outside_the_training_data_are_warned_of_once_and_still_estimated(tmp_path) -> None:
    """A whisker length in mm, an angular velocity in deg/s or a 300-mm whisker gave a wrong estimate silently."""
    import warnings

    from whisker_io.radial.pipeline import estimate_radial_distance
    from whisker_io.radial.persistence import load_model, save_model

    train, test = known_table(300, 5), known_table(40, 6)
    svr = fit_model("svr9", *TABLE_4_1["svr9"], train, QUICK)
    X = train.features
    for f in ("CP", "AV", "WL"):  # the range of the training features, by hand
        assert svr.training_range[f] == (X[:, FEATURE_NAMES.index(f)].min(), X[:, FEATURE_NAMES.index(f)].max())
    assert svr.training_range["WL"] == (0.065, 0.137)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # inside the training data: silent
        inside = svr.predict(test.features)
    wrong_units = test.features.copy()
    wrong_units[:3, FEATURE_NAMES.index("AV")] *= 180 / np.pi  # deg/s
    wrong_units[5, FEATURE_NAMES.index("WL")] = 0.3  # a 300-mm whisker
    with pytest.warns(ExtrapolationWarning) as record:
        out = svr.predict(wrong_units)
    assert len(record) == 1 and record[0].filename == __file__  # pointing at the caller
    text = str(record[0].message)
    assert text.startswith("4 of 40 contacts lie outside the data model 'svr9' was trained on")
    assert "WL 0.3 m (trained on 0.065 to 0.137)" in text and "AV" in text and "rad/s" in text
    np.testing.assert_array_equal(out[6:], inside[6:])  # the others estimated as before
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per model: a study's thousands of whisks do not repeat it
        svr.predict(wrong_units)
        fresh = fit_model("svr9", *TABLE_4_1["svr9"], train, QUICK)
        fresh.predict(wrong_units, warn_outside=False)  # an extrapolation made on purpose
        tip = fit_model("tip", "tip", ("WL",), train, QUICK)
        assert tip.training_range == {}  # the baselines do not extrapolate
        tip.predict(wrong_units)
    loaded = load_model(save_model(svr, tmp_path / "svr9.skops"))
    assert loaded.training_range == svr.training_range
    with pytest.warns(UserWarning, match="4 of 40 contacts"):
        estimate_radial_distance(wrong_units, tmp_path / "svr9.skops")
    assert estimate_radial_distance(np.zeros((0, 7)), tmp_path / "svr9.skops").shape == (0,)  # no contacts


def test_a_whisker_length_of_zero_or_less_and_an_unfitted_model_are_typed_errors(tmp_path) -> None:
    from whisker_io.radial.errors import NotFittedModelError
    from whisker_io.radial.models import TrainedModel, make_estimator
    from whisker_io.radial.persistence import save_model

    test = known_table(5, 7)
    bad = test.features.copy()
    bad[2, FEATURE_NAMES.index("WL")] = -0.09
    svr = fit_model("svr9", *TABLE_4_1["svr9"], known_table(100, 8), QUICK)
    with pytest.raises(InvalidInputError, match=r"whisker length WL must be > 0 m, got -0.09 at row 2"):
        svr.predict(bad)
    raw = TrainedModel("svr9", "svr", TABLE_4_1["svr9"][1], make_estimator("svr", TABLE_4_1["svr9"][1], QUICK))
    with pytest.raises(NotFittedModelError, match="never fitted"):
        raw.predict(test.features)
    with pytest.raises(NotFittedModelError, match="nothing to save"):
        save_model(raw, tmp_path / "raw.skops")
    with pytest.raises(InvalidInputError, match="save_model takes a TrainedModel"):
        save_model(svr.estimator, tmp_path / "pipe.skops")
    assert not any(tmp_path.iterdir())  # nothing written


def test_the_training_band_of_the_whisker_lengths_by_hand():
    """65-137 mm: the margin is 10 % of the larger end, 13.7 mm (the width is 72 mm): 51.3-150.7 mm, so a 160-mm
    whisker is outside and a 60-mm one inside (the Ch.5 study's note rests on it)."""
    from whisker_io.radial.models import training_band

    low, high = training_band(0.065, 0.137)
    assert low == pytest.approx(0.0513) and high == pytest.approx(0.1507)
    assert low <= 0.060 <= high and not 0.160 <= high


@given(st.floats(-1e6, 1e6), st.floats(0.0, 1e6))
def test_the_training_band_holds_the_range_and_a_tenth_of_its_width_or_size_more(lo, width):
    from whisker_io.radial.models import training_band

    hi = lo + width
    low, high = training_band(lo, hi)
    pad = lo - low
    assert high - hi == pytest.approx(pad) and pad > 0
    assert pad >= 0.1 * width * (1 - 1e-12) and pad >= 0.1 * max(abs(lo), abs(hi)) * (1 - 1e-12)
