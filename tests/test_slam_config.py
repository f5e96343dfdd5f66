"""The shared SLAM fields (cansim.models.slam_config.SlamConfig): declared once, one reader of saved configs.

``tests/data/saved_configs_0_1.json`` was written by ``to_dict`` of cansim 0.1 (before the
shared base): it must still load into the configs it was written from, built here by
their constructors.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cansim.errors import ConfigError
from cansim.frontends.visual import VisualTemplateConfig
from cansim.models.ratslam_config import RatSLAMConfig
from cansim.models.slam_config import SlamConfig
from cansim.models.whisker_ratslam import WhiskerRatSLAMConfig
from cansim.params import AttractorParams

SAVED = json.loads((Path(__file__).parent / "data" / "saved_configs_0_1.json").read_text())
SHARED = ("cell_size_m", "attractor", "lv_mode", "inject_energy", "active_decay", "decay_restore", "match_distance_cells",
          "correction", "relax_passes", "relax_budget", "backend", "dtype")


def test_shared_fields_are_declared_once():
    assert tuple(f.name for f in fields(SlamConfig)) == SHARED
    assert issubclass(RatSLAMConfig, SlamConfig)
    assert {f.name for f in fields(RatSLAMConfig)} >= set(SHARED)


def test_configs_saved_by_0_1_still_load():
    expected = {
        "RatSLAMConfig": [RatSLAMConfig(), RatSLAMConfig.thesis_ch3(inject_energy=0.05),
                          RatSLAMConfig.openratslam(frontend=VisualTemplateConfig(crop_x_max_px=100, panoramic=True),
                                                    attractor=AttractorParams(exc_width=(7, 7, 5)))],
        "WhiskerRatSLAMConfig": [WhiskerRatSLAMConfig(), WhiskerRatSLAMConfig.mapping(cell_size_m=0.03, lv_mode="learnt")],
    }
    for cls in (RatSLAMConfig, WhiskerRatSLAMConfig):
        assert [cls.from_dict(d) for d in SAVED[cls.__name__]] == expected[cls.__name__]
    assert SAVED["RatSLAMConfig"][0]["cell_size_m"] == 1.0 and SAVED["WhiskerRatSLAMConfig"][0]["inject_energy"] == 0.3


def _models():
    out = [RatSLAMConfig]
    if issubclass(WhiskerRatSLAMConfig, SlamConfig):  # once cansim/models/whisker_ratslam.py uses the base
        out.append(WhiskerRatSLAMConfig)
    return out


@pytest.mark.parametrize("cls", _models(), ids=lambda c: c.__name__)
@pytest.mark.parametrize("bad", [3, "x", None, {"attractor": {"no_such_kernel_field": 1}}, {"frontend": {"no_such": 1}}])
def test_a_malformed_description_is_a_config_error_naming_the_config(cls, bad):
    with pytest.raises(ConfigError, match=f"{cls.__name__}"):
        cls.from_dict(bad)


@pytest.mark.parametrize("cls", _models(), ids=lambda c: c.__name__)
def test_an_out_of_range_value_keeps_its_field_message(cls):
    with pytest.raises(ConfigError, match="cell_size_m"):
        cls.from_dict({**cls().to_dict(), "cell_size_m": -1.0})


@dataclass(frozen=True)
class _Toy(SlamConfig):
    grid_cells: int = 3


@given(cell=st.floats(1e-6, 1e3), energy=st.floats(0, 10), decay=st.floats(0, 5), restore=st.floats(0, 1),
       match=st.floats(0, 10), lv=st.sampled_from(["stored", "learnt"]), dtype=st.sampled_from(["float64", "float32"]),
       exc=st.sampled_from([1, 3, 5, (5, 5, 3)]))
def test_to_dict_from_dict_round_trip_through_json(cell, energy, decay, restore, match, lv, dtype, exc):
    cfg = _Toy(cell_size_m=cell, inject_energy=energy, active_decay=decay, decay_restore=restore, match_distance_cells=match,
               lv_mode=lv, dtype=dtype, attractor=AttractorParams(exc_width=exc), grid_cells=4)
    assert _Toy.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg


@given(name=st.sampled_from(["cell_size_m", "inject_energy", "active_decay", "decay_restore", "match_distance_cells"]),
       value=st.one_of(st.just(-1.0), st.just(math.nan), st.just(math.inf), st.text(max_size=2), st.none()))
def test_a_bad_shared_field_is_named(name, value):
    with pytest.raises(ConfigError, match=name):
        _Toy(**{name: value})


@pytest.mark.parametrize("make", [
    lambda: RatSLAMConfig(heading_cells=10**400),
    lambda: RatSLAMConfig(xy_cells=10**5),
    lambda: WhiskerRatSLAMConfig(grid_cells=30),
    lambda: WhiskerRatSLAMConfig(grid_cells=5, angle_cells=10**4),
])
def test_a_grid_too_large_is_refused_when_the_config_is_made(make):
    """heading_cells=10**400 passed validation and failed later with MemoryError (issue 25)."""
    from cansim.models.slam_config import MAX_POSE_CELLS

    with pytest.raises(ConfigError, match=str(MAX_POSE_CELLS)):
        make()


def test_the_largest_grids_in_use_are_accepted():
    RatSLAMConfig(xy_cells=61, heading_cells=36)
    WhiskerRatSLAMConfig(grid_cells=10)  # the 10**6-cell bench grid
