"""Procedural objects and the Ch.3 maze (whisker_io.sim.objects)."""

from __future__ import annotations

import numpy as np
import pytest

from whisker_io.errors import InvalidInputError
from whisker_io.sim.objects import MAZE_SIZE_M, OBJECT_NAMES, make_maze, make_object


@pytest.mark.parametrize("name", ["box", "box_stack", "barrel", "blob", "plane", "mug", "kettle", "skull"])
def test_objects_size_class(name):
    """Each object is about 20 x 20 x 35 cm (Fig 5.13 C), stands on z = 0, closed parts."""
    m = make_object(name)
    ext = m.extents
    assert np.isclose(m.bounds[0, 2], 0.0, atol=1e-9)
    assert 0.30 <= ext[2] <= 0.36
    assert 0.08 <= ext[0] <= 0.30 and 0.08 <= ext[1] <= 0.30
    assert m.is_watertight  # every part is a closed shell
    assert m.volume > 0  # outward normals


def test_names_and_aliases():
    assert set(OBJECT_NAMES) == {"box", "box_stack", "barrel", "blob", "plane", "mug", "kettle", "skull"}
    a, b = make_object("Box-Stack"), make_object("box_stack")
    np.testing.assert_array_equal(a.vertices, b.vertices)  # deterministic, alias accepted
    with pytest.raises(InvalidInputError, match="unknown object"):
        make_object("teapot")


def test_kettle_is_benchmark_sized():
    assert 4000 <= len(make_object("kettle").faces) <= 6000  # the "5k-triangle mesh"


def test_maze_footprint_and_heights():
    m = make_maze()
    lo, hi = m.bounds
    t = 0.01
    np.testing.assert_allclose(lo[:2], [-t / 2, -t / 2])
    np.testing.assert_allclose(hi[:2], [MAZE_SIZE_M[0] + t / 2, MAZE_SIZE_M[1] + t / 2])
    assert lo[2] == 0.0 and 0.2 <= hi[2] <= 0.3
    # walls and posts of varied height: distinct top heights of the parts
    tops = {round(b.bounds[1, 2], 3) for b in m.split(only_watertight=False)}
    assert len(tops) >= 5
    assert make_maze(floor=True).bounds[0, 2] < 0.0
