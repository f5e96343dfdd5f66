"""Explorer metrics (IM, SRT from hand-made IC traces) and a short simulated run through the safety envelope."""

import math

import numpy as np
import pytest

from cansim.errors import CansimError
from cansim.explore.explorer import ic_metrics


def test_im_srt_from_hand_made_traces():
    ic = np.array([[0, 0], [50, 10], [120, 40], [200, 90], [310, 150], [400, 310]], float)
    m = ic_metrics(ic, correct=0, threshold=300)
    assert (m.srt, m.im, m.identity, m.correct_first) == (4.0, 1.0, 0, True)
    m = ic_metrics(ic, correct=1, threshold=300)
    assert (m.srt, m.im, m.identity, m.correct_first) == (5.0, -1.0, 0, False)
    # never crossed: censored at n dt = 6
    m = ic_metrics(ic, correct=0, threshold=350)
    assert (m.srt, m.im, m.correct_first) == (5.0, 1.0, True)
    m = ic_metrics(ic, correct=0, threshold=1000, dt=0.5)
    assert (m.srt, m.im, m.identity, m.correct_first) == (3.0, 0.0, None, False)


@pytest.mark.parametrize("bad", [np.zeros(3), np.full((2, 2), np.nan), np.zeros((0, 2)).reshape(0, 2, 1)])
def test_bad_traces(bad):
    with pytest.raises(CansimError):
        ic_metrics(bad, 0, 300)
    with pytest.raises(CansimError):
        ic_metrics(np.zeros((3, 2)), 2, 300)
    with pytest.raises(CansimError):
        ic_metrics(np.zeros((3, 2)), 0, math.nan)
