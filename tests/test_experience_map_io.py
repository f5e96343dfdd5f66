"""maps.experience_map_io: the map file format on its own, and the subclass hooks of ExperienceMap's persistence.

Truth is independent of the functions under test: arrays drawn by hypothesis must come
back unchanged byte for byte, damaged fields must be named, and a subclass that adds a
field through the documented hooks (``to_arrays`` / ``from_arrays``) round-trips through
``save`` / ``load``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from maps.experience_map import ExperienceMap, MapConfig
from maps.experience_map_io import FORMAT_VERSION, MapArrays, read_map_body, read_map_header, write_map_arrays
from maps.se2 import SE2Geometry
from whisker_io.errors import CorruptFileError

_finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@st.composite
def saved_maps(draw):
    """A valid SE(2) MapArrays: n experiences, a chain of distinct links, state inside the map."""
    n = draw(st.integers(1, 8))
    m = draw(st.integers(0, n - 1))
    arr = lambda shape: np.array(draw(st.lists(_finite, min_size=int(np.prod(shape)), max_size=int(np.prod(shape)))),  # noqa: E731
                                 dtype=np.float64).reshape(shape)
    pose = arr((n, 3))
    pose[:, 2] = np.clip(pose[:, 2], -3.0, 3.0)  # headings in (-pi, pi]
    ends = np.array([[k, k + 1] for k in range(m)], dtype=np.int64).reshape(m, 2)
    state_i = np.array([draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1)), draw(st.integers(0, 50))], dtype=np.int64)
    vt = np.array(draw(st.lists(st.integers(0, 100), min_size=n, max_size=n)), dtype=np.int64)
    return MapArrays(MapConfig(), SE2Geometry(), arr((n, 3)), vt, pose, ends, arr((m, 4)), arr((3 + 1 + 3,)), state_i)


@settings(max_examples=40, deadline=None)
@given(saved=saved_maps(), prefix=st.sampled_from(["", "em_", "x."]))
def test_write_then_read_returns_the_same_bytes(saved, prefix):
    arrays = write_map_arrays(saved, prefix)
    assert sorted(arrays) == sorted(prefix + k for k in ("format", "config", "exp_pc", "exp_vt", "exp_pose", "link_ends",
                                                          "link_data", "state_f", "state_i"))
    assert int(arrays[prefix + "format"]) == FORMAT_VERSION == 2
    config, geometry = read_map_header(arrays, prefix, MapConfig)
    assert config == saved.config and geometry.name == "se2" and geometry.params() == saved.geometry.params()
    back = read_map_body(arrays, prefix, config, geometry)
    for name in ("exp_pc", "exp_vt", "exp_pose", "link_ends", "link_data", "state_f", "state_i"):
        got, want = getattr(back, name), getattr(saved, name)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), name


@settings(max_examples=25, deadline=None)
@given(saved=saved_maps(), victim=st.sampled_from(["exp_pc", "exp_vt", "exp_pose", "link_data", "state_f", "state_i"]))
def test_a_damaged_field_is_named(saved, victim):
    arrays = write_map_arrays(saved, "em_")
    arrays["em_" + victim] = np.asarray(arrays["em_" + victim])[..., :0] if victim != "exp_vt" else np.array([-1] * len(saved.exp_vt))
    config, geometry = read_map_header(arrays, "em_", MapConfig)
    with pytest.raises(CorruptFileError, match="em_" + victim):
        read_map_body(arrays, "em_", config, geometry)


def test_a_duplicate_link_in_either_direction_is_named():
    saved = MapArrays(MapConfig(), SE2Geometry(), np.zeros((2, 3)), np.array([0, 1]), np.zeros((2, 3)),
                      np.array([[0, 1], [1, 0]]), np.zeros((2, 4)), np.zeros(7), np.array([0, 0, 0]))
    arrays = write_map_arrays(saved)
    with pytest.raises(CorruptFileError, match="duplicate link 1->0 at row 1"):
        read_map_body(arrays, "", *read_map_header(arrays, "", MapConfig))


class _TaggedMap(ExperienceMap):
    """A subclass saving one more field through the hooks ObjectMap uses."""

    tag = 0

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        arrays = super().to_arrays(prefix)
        arrays[prefix + "tag"] = np.int64(self.tag)
        return arrays

    @classmethod
    def from_arrays(cls, arrays, prefix: str = ""):
        em = super().from_arrays(arrays, prefix)
        em.tag = int(arrays[prefix + "tag"])
        return em


def test_subclass_hooks_round_trip_through_save_and_load(tmp_path):
    em = _TaggedMap()
    for t in range(6):
        em.on_odo(0.5, 0.3, 1.0)
        em.update([10.0 + t, 10.0, 18.0], t % 4, max(t - 1, 0) % 4)
    em.tag = 7
    em.save(tmp_path / "m.npz")
    back = _TaggedMap.load(tmp_path / "m.npz")
    assert type(back) is _TaggedMap and back.tag == 7
    assert em.n_experiences >= 2 and em.n_links >= 1  # something to save
    assert (back.n_experiences, back.n_links) == (em.n_experiences, em.n_links)
    assert back.poses.tobytes() == em.poses.tobytes()
    assert ExperienceMap.load(tmp_path / "m.npz").n_experiences == em.n_experiences  # the base ignores the extra field
