"""A rate Population saves, loads, pickles and deep-copies, and continues exactly (a user's pass, session 47:
pickle raised "Can't pickle local object", deepcopy a TypeError, and there was no save)."""

from __future__ import annotations

import copy
import io
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim import AttractorParams, Axis, InvalidInputError, Population
from cansim.errors import CorruptFileError
from cansim.path_integration import UniformMotion


def _save_load(p: Population) -> Population:
    buf = io.BytesIO()
    p.save(buf)
    buf.seek(0)
    return Population.load(buf)


COPIES = {"save": _save_load, "pickle": lambda p: pickle.loads(pickle.dumps(p)), "deepcopy": copy.deepcopy}


def _continue(p: Population, moves, **kw):
    return np.array([p.step(*m, **kw) for m in moves]), p.activity


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("make,moves", [
    (lambda: Population.head_direction(120, backend="numpy"), [(0.3,), (0.21,), (-0.4,)] * 4),
    (lambda: Population.openratslam(11, 12, 0.5, dtype=np.float64, frame="openratslam"), [(0.2, 0.1), (0.4, -0.3)] * 3),
    (lambda: Population([Axis.linear("x", 9, 0.1), Axis.angle("a", 8)], AttractorParams(exc_width=5, inh_width=3),
                        decode_window=2), [([0.05, 0.2],), ([-0.1, 0.5],)] * 3),
])
def test_a_copy_continues_exactly(how, make, moves):
    p = make()
    _continue(p, moves[:3])
    q = COPIES[how](p)
    assert repr(q) == repr(p) and q.motion == p.motion and q.params == p.params and q.dtype == p.dtype
    np.testing.assert_array_equal(q.activity, p.activity)
    np.testing.assert_array_equal(q.decode(), p.decode())
    got, want = _continue(q, moves), _continue(p, moves)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


def test_a_file_by_name_and_the_file_errors(tmp_path):
    p = Population.head_direction(36)
    p.step(0.5)
    p.save(tmp_path / "ring.npz")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["ring.npz"]
    np.testing.assert_array_equal(Population.load(tmp_path / "ring.npz").activity, p.activity)
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(CorruptFileError, match="population_format"):
        Population.load(tmp_path / "other.npz")
    arrays = dict(np.load(tmp_path / "ring.npz"))
    for field, value in (("activity", -np.ones(36, dtype=np.float32)), ("activity", np.ones(5, dtype=np.float32)),
                         ("population", np.array("{not json")), ("decoded", np.array([np.nan]))):
        np.savez(tmp_path / "bad.npz", **{**arrays, field: value})
        with pytest.raises(CorruptFileError, match=field):
            Population.load(tmp_path / "bad.npz")


def test_a_motion_model_of_ones_own_pickles_but_is_not_written_without_pickle(tmp_path):
    class Doubled(UniformMotion):
        pass

    p = Population.head_direction(36, motion=Doubled())
    with pytest.raises(InvalidInputError, match="Doubled cannot be saved to a file without pickle"):
        p.save(tmp_path / "x.npz")
    assert not any(tmp_path.iterdir())
    assert isinstance(copy.deepcopy(p).motion, Doubled)


@settings(max_examples=40, deadline=None)
@given(size=st.integers(4, 40), moves=st.lists(st.floats(-2.0, 2.0), min_size=1, max_size=12),
       split=st.integers(0, 12), dtype=st.sampled_from([np.float32, np.float64]))
def test_saved_at_any_step_a_ring_continues_as_the_original(size, moves, split, dtype):
    p = Population.head_direction(size, dtype=dtype, backend="numpy")
    for m in moves[:split]:
        p.step(m)
    q = _save_load(p)
    for m in moves[split:]:
        np.testing.assert_array_equal(q.step(m), p.step(m))
    np.testing.assert_array_equal(q.activity, p.activity)
    assert q.activity.dtype == np.dtype(dtype)
