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
    with pytest.raises(InvalidInputError, match=r"^sample 1: dt = 0 s: the spiking pose cells need dt > 0 .*nothing was applied$"):
        s.run([0.25] * 3, [0.0] * 3, [0.2, 0.0, 0.2], [0, 1, 2])
    assert s.iteration == 0 and s.n_views == 0
    with pytest.raises(InvalidInputError, match="need dt > 0"):
        s.step(0.25, 0.0, 0.0, 5)
    assert s.iteration == 0 and s.n_views == 0  # the view was not taken either
    rate = RatSLAM(RatSLAMConfig(backend="numpy"))
    rate.run([0.25] * 3, [0.0] * 3, [0.2, 0.0, 0.2], [0, 1, 2])  # the rate engines take a zero-duration sample
    assert rate.iteration == 3


def test_a_step_strict_translation_refuses_is_refused_before_the_first_sample_too():
    """The model's own refusals (strict_translation's one cell a step) are checked up front as well (the review: a
    run applied two samples before refusing the third), and a sample of the wrong number of fields is a typed error."""
    s = RatSLAM(RatSLAMConfig(backend="numpy", strict_translation=True))
    s.step(0.01, 0.0, 0.2, 0)
    before = _state(s)
    with pytest.raises(InvalidInputError, match=r"^sample 2: vtrans\*dt = 20 m moves the packet .*nothing was applied"):
        s.run([0.01, 0.01, 100.0], [0.0] * 3, 0.2, [1, 2, 3])
    assert _state(s) == before
    with pytest.raises(InvalidInputError, match=r"^sample 1: odometry sample must be a PlanarOdometry or its fields"):
        s._checked_samples([(0.1, 0.0, 0.2), (0.1, 0.0)])


def test_an_error_told_at_its_sample_keeps_its_class_and_data():
    from whisker_io.errors import CorruptFileError, SequenceGapError

    from cansim.models.slam_loop import _at_sample

    e = CorruptFileError("bad member", path="a.npz", field="x")
    _at_sample(e, 3, "nothing was applied")
    assert str(e).startswith("sample 3: a.npz: field 'x': bad member") and e.path == "a.npz" and e.field == "x"
    g = SequenceGapError("frames lost", 4)
    _at_sample(g, 0, "nothing was applied")
    assert str(g) == "sample 0: frames lost; nothing was applied" and g.lost == 4


def test_a_run_of_values_that_are_no_numbers_is_typed_and_applies_nothing():
    s = RatSLAM(RatSLAMConfig(backend="numpy"))
    with pytest.raises(InvalidInputError, match="vtrans and vrot must be numbers"):
        s.run([0.25, "fast"], [0.0, 0.0], 0.2, [1, 2])
    with pytest.raises(InvalidInputError, match="dt must be a number or one per sample"):
        s.run([0.25, 0.25], [0.0, 0.0], [0.2, 0.2, 0.2], [1, 2])
    assert s.iteration == 0 and s.n_views == 0

