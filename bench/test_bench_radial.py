"""Benchmarks of the radial-distance models (thesis Ch.4, issue 5).

* prediction of the radial distance for one array cycle (18 contacts) with a
  fitted SVR (svr10, the thesis' recommended model; target <= 1 ms), plus the
  same through the FK pipeline (contact points for 18 modules);
* training time of all 12 Table 4.1 models on the default training set
  (measured once: one round, one iteration).

Run: ``python -m pytest bench/test_bench_radial.py --benchmark-only``
"""

from __future__ import annotations

import numpy as np
import pytest

from whisker_io.radial.datasets import TrainingSetParams, make_training_set, validation_array
from whisker_io.radial.models import TABLE_4_1, SearchParams, fit_model, train_models
from whisker_io.radial.pipeline import contact_points_from_features


@pytest.fixture(scope="module")
def training():
    return make_training_set(TrainingSetParams())


@pytest.fixture(scope="module")
def svr10(training):
    return fit_model("svr10", *TABLE_4_1["svr10"], training, SearchParams())


def _cycle(training, n=18):
    rng = np.random.default_rng(0)
    return training.features[rng.choice(len(training), n, replace=False)]


def test_svr10_predict_one_array_cycle_18_contacts(benchmark, training, svr10):
    X = _cycle(training)
    out = benchmark(svr10.predict, X)
    assert out.shape == (18,)


def test_svr10_contact_points_one_array_cycle_18_modules(benchmark, training, svr10):
    arr = validation_array()
    X = _cycle(training)
    X[:, 6] = arr.lengths_m  # features of this array's whiskers
    theta = np.linspace(-0.5, 0.5, 18)
    pts = benchmark(contact_points_from_features, arr, np.eye(4), theta, X, svr10.estimator)
    assert pts.shape == (18, 3) and np.isfinite(pts).all()


def test_train_all_12_table_4_1_models_default_training_set(benchmark, training):
    models = benchmark.pedantic(
        train_models, args=(training, list(TABLE_4_1), SearchParams()), rounds=1, iterations=1
    )
    assert len(models) == 12
