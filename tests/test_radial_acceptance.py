"""Issue acceptance for thesis Ch.4 on reduced simulated data sets (same generators as the study).

Sizes: training 8 lengths x 20 distances x 3 frequencies, validation 18 waypoints
x 2 whisks, Evans 26 distances x 9 speeds; hyper-parameters by 3-fold CV on the
training set (``SearchParams().quick()``). Nothing is fitted on validation data.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial

import numpy as np
import pytest

from whisker_io.radial.datasets import (
    UNSEEN_LENGTHS_MM,
    EvansSetParams,
    TrainingSetParams,
    ValidationSetParams,
    make_evans_set,
    make_training_set,
    make_validation_set,
)
from whisker_io.radial.evaluation import evaluate_models, evans_comparison, length_generalisation
from whisker_io.radial.models import SearchParams, train_models
from whisker_io.radial.pipeline import dataset_contact_points

# the quick MLP search stops L-BFGS early on purpose
pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")

SETTINGS = SearchParams().quick()


@pytest.fixture(scope="module")
def training():
    return make_training_set(TrainingSetParams().reduced())


@pytest.fixture(scope="module")
def scores(training):
    val = make_validation_set(ValidationSetParams().reduced())
    models = train_models(training, settings=SETTINGS)
    res = evaluate_models(
        models, val.data, keep=val.unseen, reconstruct=partial(dataset_contact_points, val.array), mesh=val.mesh
    )
    return {s.model: s for s in res}


@pytest.mark.parametrize("label", ["svr9", "svr10"])
def test_svr_beats_tip_and_random_on_unseen_lengths(scores, label) -> None:
    s = scores[label]
    assert s.n_contacts >= 20
    assert s.median_abs_error < 0.5 * scores["random"].median_abs_error
    assert s.median_abs_error < 0.1 * scores["tip"].median_abs_error
    # two-sample KS: the error distributions differ from tip and random at the 1 % level
    assert s.ks_p_vs_tip < 0.01 and s.ks_p_vs_random < 0.01
    # reconstruction fidelity (Fig 4.8): contacts closer to the Box than tip / random ones
    assert s.median_abs_mesh_distance_m < 0.25 * scores["tip"].median_abs_mesh_distance_m
    assert s.median_abs_mesh_distance_m < 0.5 * scores["random"].median_abs_mesh_distance_m
    assert s.mesh_ks_p_vs_tip < 0.01 and s.mesh_ks_p_vs_random < 0.01


def test_angular_velocity_is_needed(scores) -> None:
    # Table 4.1 / Fig 4.9: dropping AV (svr11, svr12) costs accuracy
    assert scores["svr10"].median_abs_error < scores["svr12"].median_abs_error
    assert scores["svr9"].median_abs_error < scores["svr11"].median_abs_error


def test_training_on_many_lengths_generalises_better(training) -> None:
    unseen = make_training_set(replace(TrainingSetParams().reduced(), lengths_mm=UNSEEN_LENGTHS_MM, seed=11))
    gen = length_generalisation(training, unseen, settings=SETTINGS)
    for name in ("svr ours (CP-CA-DV-DA)", "poly5 ours (CP-CA-DV-DA)"):
        assert np.median(gen["many"][name]) < np.median(gen["one"][name])


def test_evans_svr_on_our_features_beats_poly5_on_evans_features() -> None:
    ev = evans_comparison(make_evans_set(EvansSetParams().reduced()), SETTINGS)
    assert np.median(ev["svr ours (CP-CA-DV-DA)"]) < np.median(ev["poly5 Evans (CA-CP)"])
