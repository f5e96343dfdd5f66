"""RatSLAM.run / SlamLoop.run check every sample's odometry before applying the first; an error that only a step can
find (an observation, a state-dependent check) names its sample and says what was applied (a neuromorphic user's pass,
session 49: a NaN in the third sample left the model two samples on, and the message named no sample)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import InvalidInputError
from cansim.models.ratslam import RatSLAM, RatSLAMConfig


def _state(s: RatSLAM) -> tuple:
    return (s.iteration, s.n_views, s.experience_map.n_experiences, s.best_pc,
            np.asarray(s.pose_cells.activity).tobytes(), s.experience_map.poses.tobytes())


@settings(max_examples=15, deadline=None)
@given(n=st.integers(1, 6), bad=st.data(), value=st.sampled_from([math.nan, math.inf, -math.inf]),
       field=st.sampled_from(["vtrans", "vrot", "dt"]))
def test_a_non_finite_sample_anywhere_applies_nothing(n, bad, value, field):
    k = bad.draw(st.integers(0, n - 1))
    s = RatSLAM(RatSLAMConfig(backend="numpy"))
    s.step(0.25, 0.0, 0.2, 0)
    before = _state(s)
    cols = {"vtrans": [0.25] * n, "vrot": [0.05] * n, "dt": [0.2] * n}
    cols[field][k] = value
    with pytest.raises(InvalidInputError, match=rf"^sample {k}: .*nothing was applied"):
        s.run(cols["vtrans"], cols["vrot"], cols["dt"], list(range(1, n + 1)))
    assert _state(s) == before


def test_an_observation_only_a_step_can_refuse_names_its_sample_and_what_was_applied():
    s = RatSLAM(RatSLAMConfig(backend="numpy"))
    with pytest.raises(InvalidInputError, match=r"^sample 2: .*samples 0-1 were applied: the model holds their state"):
        s.run([0.25] * 3, [0.0] * 3, 0.2, [1, 2, "not a view id"])
    assert s.iteration == 2 and s.n_views == 2
    s.run([0.25], [0.0], 0.2, [3])  # and it goes on from there
    assert s.iteration == 3


def test_the_spiking_pose_cells_refuse_a_sample_of_no_duration_before_anything_changes():
    s = RatSLAM(RatSLAMConfig(pose_cells="spiking"))
    with pytest.raises(InvalidInputError, match=r"^sample 1: dt = 0 s; the spiking pose cells need dt > 0"):
        s.run([0.25] * 3, [0.0] * 3, [0.2, 0.0, 0.2], [0, 1, 2])
    assert s.iteration == 0 and s.n_views == 0
    with pytest.raises(InvalidInputError, match="need dt > 0"):
        s.step(0.25, 0.0, 0.0, 5)
    assert s.iteration == 0 and s.n_views == 0  # the view was not taken either
    rate = RatSLAM(RatSLAMConfig(backend="numpy"))
    rate.run([0.25] * 3, [0.0] * 3, [0.2, 0.0, 0.2], [0, 1, 2])  # the rate engines take a zero-duration sample
    assert rate.iteration == 3
