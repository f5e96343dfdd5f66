"""Local-view cells: OpenRatSLAM stored-location rules (hand-computed) and learnt weights (Eq 2.17/2.18)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cansim import InvalidInputError, Population
from cansim.local_view import LocalViewCells, LocalViewParams, stored_injection_energy

SHAPE = (21, 21, 36)


def _energy(decay, zeta=0.15):
    return zeta / 30.0 * (30.0 - math.exp(1.2 * decay))


def test_eq_5_8_energy_and_clamp():
    assert stored_injection_energy(1.0, 0.15) == pytest.approx(0.15 / 30 * (30 - math.exp(1.2)))
    assert stored_injection_energy(1.0, 0.3) == pytest.approx(0.3 / 30 * (30 - 3.3201169227365472))
    assert stored_injection_energy(math.log(30) / 1.2 + 1e-9, 0.15) == 0.0
    assert stored_injection_energy(5.0, 0.15) == 0.0
    # a view matched hundreds of times in a row: exp(1.2 * decay) would overflow a float
    assert stored_injection_energy(1000.0, 0.15) == 0.0


def test_new_view_stores_location_and_injects_nothing():
    lv = LocalViewCells(SHAPE)
    flat, vals = lv.observe(0, [5.7, 7.2, 9.9])
    assert len(flat) == 0 and len(vals) == 0
    np.testing.assert_allclose(lv.locations, [[5.7, 7.2, 9.9]])
    assert lv.decay.tolist() == [1.0]  # created at active_decay, the floor keeps it there
    np.testing.assert_array_equal(lv.activity, [1.0])


def test_repeated_view_decay_sequence_matches_cpp():
    lv = LocalViewCells(SHAPE)
    lv.observe(0, [5.7, 7.2, 9.9])
    # same view again: decay 1.0 + 1.0 = 2.0 -> energy 0.15/30*(30 - e^2.4), at the truncated cell
    flat, vals = lv.observe(0, [0, 0, 0])
    assert vals.tolist() == pytest.approx([_energy(2.0)])
    assert flat.tolist() == [np.ravel_multi_index((5, 7, 9), SHAPE)]
    assert lv.decay[0] == pytest.approx(1.95)
    # again: 1.95 + 1 = 2.95 > ln(30)/1.2 -> no energy; then restored to 2.90
    flat, vals = lv.observe(0, [0, 0, 0])
    assert len(vals) == 0
    assert lv.decay[0] == pytest.approx(2.90)
    # a different view in between: no increment, energy at the current decay
    lv.observe(1, [1, 1, 1])  # new view; view 0 restores to 2.85
    flat, vals = lv.observe(0, [0, 0, 0])
    assert lv.decay[0] == pytest.approx(2.80)
    assert vals.tolist() == pytest.approx([_energy(2.85)] if _energy(2.85) > 0 else [])
    # restore continues to the floor of 1.0
    for _ in range(60):
        lv.observe(1, [1, 1, 1])
    assert lv.decay[0] == pytest.approx(1.0)


def test_recent_exclusion_and_unsigned_quirk():
    lv = LocalViewCells(SHAPE)
    for i in range(12):
        lv.observe(i, [i, i, i])
    assert len(lv.observe(5, [0, 0, 0])[0]) == 0  # 5 is not < 12 - 10
    assert len(lv.observe(1, [0, 0, 0])[0]) == 1  # 1 < 2 injects
    few = LocalViewCells(SHAPE)
    few.observe(0, [1, 1, 1])
    few.observe(1, [2, 2, 2])
    assert len(few.observe(0, [0, 0, 0])[0]) == 1  # unsigned size - 10 wraps: injects
    strict = LocalViewCells(SHAPE, LocalViewParams(cpp_unsigned_recent=False))
    strict.observe(0, [1, 1, 1])
    strict.observe(1, [2, 2, 2])
    assert len(strict.observe(0, [0, 0, 0])[0]) == 0


def test_panoramic_offset_wraps_theta():
    lv = LocalViewCells(SHAPE)
    lv.observe(0, [3.0, 4.0, 35.5])
    lv.observe(1, [0, 0, 0])
    flat, _ = lv.observe(0, [0, 0, 0], offset_cells=[0, 0, 1.0])
    assert np.unravel_index(flat[0], SHAPE) == (3, 4, 0)


def test_bad_view_ids_leave_state_unchanged():
    lv = LocalViewCells(SHAPE)
    lv.observe(0, [1, 2, 3])
    before = lv.to_arrays()
    for bad in (-1, 2, "x"):
        with pytest.raises(InvalidInputError):
            lv.observe(bad, [1, 2, 3])
    with pytest.raises(InvalidInputError):
        lv.observe(0, [1, np.nan, 3])
    after = lv.to_arrays()
    for k in before:
        np.testing.assert_array_equal(before[k], after[k])


@pytest.mark.parametrize("preset,centre", [("openratslam", (5, 17, 9)), ("whisker6d", (1, 3, 0, 4, 2, 1))])
def test_learnt_view_re_anchors_a_blank_network(preset, centre):
    pc = getattr(Population, preset)()
    pc.reset_cell(centre)
    for _ in range(20):
        pc.step()
    lv = LocalViewCells(pc.shape, LocalViewParams(mode="learnt"))
    lv.observe(0, pc.decode())
    lv.learn(pc.activity)
    assert lv.weights.nnz == int((pc.activity > 0).sum())
    blank = getattr(Population, preset)()
    blank.activity = np.zeros(blank.shape)
    lv2 = LocalViewCells.from_arrays(lv.to_arrays(), LocalViewParams(mode="learnt"))
    blank.inject_flat(*lv2.observe(0, np.zeros(len(centre))))
    blank.step()
    d = blank.decode()
    err = (d - np.array(centre) + np.array(blank.shape) / 2) % np.array(blank.shape) - np.array(blank.shape) / 2
    assert np.all(np.abs(err) < 0.5)


@pytest.mark.parametrize("rate, activity", [(1e300, [0.2, 0.0, 0.6, 0.0]), (1.0, [1e39, 0.0, 0.0, 0.0]),
                                            (1.0, ["a", 0.0, 0.0, 0.0]), (1.0, [math.nan, 0.0, 0.0, 0.0])])
def test_a_weight_beyond_float32_or_a_bad_activity_is_refused_unchanged(rate, activity):
    # 1e300 x 0.6 used to be cast to float32 inf (an overflow warning, inf injections later)
    lv = LocalViewCells((4,), LocalViewParams(mode="learnt", learning_rate=rate))
    lv.observe(0, [0.0])
    lv.learn(np.array([1e-290, 0.0, 0.0, 0.0]))  # a weight of 1e10 at most
    before = lv.weights.toarray()
    with pytest.raises(InvalidInputError):
        lv.learn(np.array(activity, dtype=object))
    np.testing.assert_array_equal(lv.weights.toarray(), before)
    assert np.isfinite(before).all()


def test_learning_is_elementwise_max_and_injection_averages_active_views():
    lv = LocalViewCells((4,), LocalViewParams(mode="learnt", learning_rate=0.5, inject_energy=1.0, trace_decay=0.5))
    lv.observe(0, [0.0])
    lv.learn(np.array([0.2, 0.0, 0.6, 0.0]))
    lv.learn(np.array([0.4, 0.0, 0.2, 0.0]))
    np.testing.assert_allclose(lv.weights.toarray(), [[0.2, 0.0, 0.3, 0.0]], rtol=1e-6)
    flat, vals = lv.observe(1, [0.0])  # new view 1 active with V=1, view 0 trace V=0.5
    dense = np.zeros(4)
    np.add.at(dense, flat, vals)
    # eta_act = 2 active views; view 1 has no weights yet: (1/2) * 0.5 * beta_0
    np.testing.assert_allclose(dense, [0.05, 0.0, 0.075, 0.0], rtol=1e-6)


def test_thesis_decay_rule_by_hand():
    """Ch.5 rule: energy at the current decay (floor 0), then +1 on every match, -0.05 per iteration."""
    p = LocalViewParams(mode="stored", inject_energy=0.3, recent_exclusion=0, rounding="round", decay_floor=0.0,
                        rise_on_every_match=True)
    lv = LocalViewCells((5, 5), p)
    lv.observe(0, (1.0, 2.0))  # new: decay 0, restore keeps the floor
    assert lv.decay.tolist() == [0.0]
    _, e = lv.observe(0, (0.0, 0.0))
    assert e[0] == pytest.approx(0.3 / 30 * (30 - 1.0))  # 0.29, the thesis' maximum
    assert lv.decay[0] == pytest.approx(0.95)
    lv.restore_decay()  # an iteration without an observation
    assert lv.decay[0] == pytest.approx(0.90)
    _, e = lv.observe(0, (0.0, 0.0))
    assert e[0] == pytest.approx(0.3 / 30 * (30 - math.exp(1.2 * 0.9)))
    for _ in range(40):
        lv.restore_decay()
    assert lv.decay[0] == 0.0  # floored at 0


@pytest.mark.parametrize("mode", ["stored", "learnt"])
def test_cells_without_a_view_round_trip(mode):
    """A model saved before its first view (e.g. whisks without contact) loads back empty."""
    lv = LocalViewCells((5, 5, 5), LocalViewParams(mode=mode))
    back = LocalViewCells.from_arrays(lv.to_arrays("lv_"), lv.params, prefix="lv_")
    assert back.n_views == 0 and back.shape == (5, 5, 5)
    assert back.observe(0, [1.0, 2.0, 3.0]) is not None and back.n_views == 1
