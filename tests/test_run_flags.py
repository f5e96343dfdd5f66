"""``Population.run``'s ``record_activity`` flag: a bool, or a typed error (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim import Population
from cansim.errors import InvalidInputError


def test_an_empty_array_as_record_activity_is_a_typed_error_and_changes_nothing():
    """``record_activity=np.array([])`` reached ``bool()`` and raised numpy's ValueError."""
    pop = Population.head_direction(36, backend="numpy")
    before = pop.activity.copy()
    with pytest.raises(InvalidInputError, match="record_activity must be True or False"):
        pop.run(velocity=np.zeros(3), record_activity=np.array([]))
    assert pop.activity.tobytes() == before.tobytes()


@settings(max_examples=20, deadline=None)
@given(flag=st.one_of(st.integers(), st.floats(), st.text(max_size=3), st.none(),
                      st.lists(st.booleans(), max_size=3).map(np.array), st.just(np.array(True))))
def test_anything_but_a_bool_is_refused_before_a_step_runs(flag):
    pop = Population.head_direction(36, backend="numpy")
    before = pop.activity.copy()
    with pytest.raises(InvalidInputError, match="record_activity"):
        pop.run(velocity=np.zeros(2), record_activity=flag)
    assert pop.activity.tobytes() == before.tobytes()


@pytest.mark.parametrize("flag", [True, np.bool_(True)])
def test_a_bool_or_numpy_bool_records_one_activity_per_step(flag):
    pop = Population.head_direction(36, backend="numpy")
    decoded, history = pop.run(velocity=np.zeros(4), record_activity=flag)
    assert decoded.shape == (4, 1) and history.shape == (4, 36)
    assert history[-1].tobytes() == pop.activity.tobytes()  # the last recorded activity is the state
    plain = Population.head_direction(36, backend="numpy").run(velocity=np.zeros(4), record_activity=np.bool_(False))
    assert isinstance(plain, np.ndarray) and plain.shape == (4, 1)
