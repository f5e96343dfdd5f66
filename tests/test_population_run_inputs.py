"""cansim.population_run.run_inputs: a run's per-step inputs as shifts (cells) and injections, checked up front.

Expected shifts are written from the definitions (a ring of n cells has a step of
2 pi / n rad, so omega dt rad is omega dt n / (2 pi) cells), not computed by the code
under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim import Population
from cansim.errors import InvalidInputError, ShapeError
from cansim.population_run import run_inputs


def _inputs(pop: Population, *args, n_steps=None):
    return run_inputs(pop.motion, pop.motion.bind(pop.axes), pop.ndim, pop.size, *args, n_steps)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(3, 72), v=st.lists(st.floats(-5, 5), min_size=1, max_size=12), dt=st.floats(0, 2))
def test_ring_shifts_are_omega_dt_over_the_cell(n, v, dt):
    pop = Population.head_direction(n, backend="numpy")
    inputs = _inputs(pop, v, None, dt, None)
    assert inputs.n_steps == len(v)
    np.testing.assert_allclose(inputs.uniform_shifts[:, 0], np.array(v) * dt * n / (2 * math.pi), rtol=1e-12, atol=1e-12)
    assert inputs.has_uniform.all() and not inputs.has_cond.any()
    assert inputs.inj_offsets.tolist() == [0] * (len(v) + 1)


def test_injections_are_concatenated_with_offsets():
    pop = Population.head_direction(10, backend="numpy")
    inputs = _inputs(pop, None, None, 1.0, [None, ([1, 2], [0.5, 0.25]), None, ([9], [1.0])])
    assert inputs.inj_offsets.tolist() == [0, 0, 2, 2, 3]
    assert inputs.inj_index.tolist() == [1, 2, 9] and inputs.inj_values.tolist() == [0.5, 0.25, 1.0]


@pytest.mark.parametrize("args,error,match", [
    (([0.1, 0.2], None, [1.0, 1.0, 1.0], None), ShapeError, "T rows"),
    (([0.1, float("nan")], None, 1.0, None), InvalidInputError, "step 1"),
    (([0.1, 0.2], None, [1.0, -1.0], None), InvalidInputError, "step 1"),
    ((None, None, 1.0, [None, ([10], [1.0])]), InvalidInputError, r"injections\[1\]"),
    ((None, None, 1.0, None), InvalidInputError, "n_steps"),
])
def test_bad_inputs_are_named_with_their_step(args, error, match):
    with pytest.raises(error, match=match):
        _inputs(Population.head_direction(10, backend="numpy"), *args)
