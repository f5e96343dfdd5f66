"""One vocabulary (issue 21): the engine takes the configs' names; 0.1's names still work, with a warning.

The renamed keywords go through one helper (:mod:`cansim._renamed`); the expected grids
below are written out by hand (sizes, steps), never computed by the preset under test.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cansim import Population
from cansim._renamed import renamed_keywords, take_renamed
from cansim.errors import ConfigError
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.models.posecell_network import PosecellNetwork
from cansim.models.ratslam_config import RatSLAMConfig
from cansim.models.whisker_ratslam import WhiskerRatSLAMConfig
from cansim.population import WHISKER6D_CELL_SIZE_M


def _grid(pop: Population) -> list[tuple[str, int, float]]:
    return [(a.name, a.size, a.step) for a in pop.axes]


# ---------------------------------------------------------------- presets: the configs' names
def test_openratslam_preset_takes_the_config_names():
    pop = Population.openratslam(xy_cells=11, heading_cells=8, cell_size_m=0.5, backend="numpy")
    assert _grid(pop) == [("x", 11, 0.5), ("y", 11, 0.5), ("theta", 8, pytest.approx(2 * math.pi / 8))]


def test_whisker6d_preset_takes_the_config_names():
    pop = Population.whisker6d(grid_cells=4, cell_size_m=0.03, angle_cells=6, backend="numpy")
    assert _grid(pop)[:3] == [("x", 4, 0.03), ("y", 4, 0.03), ("z", 4, 0.03)]
    assert [(n, s) for n, s, _ in _grid(pop)[3:]] == [("roll", 6), ("pitch", 6), ("yaw", 6)]
    assert all(step == pytest.approx(math.pi / 3) for *_, step in _grid(pop)[3:])


def test_preset_defaults_agree_with_the_configs():
    """The presets' defaults are the configs' defaults (21 x 21 x 36 at 1 m; 5^6 at 0.1 m)."""
    rs, ws = RatSLAMConfig(), WhiskerRatSLAMConfig()
    assert Population.openratslam(backend="numpy").shape == (rs.xy_cells, rs.xy_cells, rs.heading_cells) == (21, 21, 36)
    assert Population.openratslam(backend="numpy").axes[0].step == rs.cell_size_m == 1.0
    assert Population.whisker6d(backend="numpy").shape == ws.shape == (5,) * 6
    assert Population.whisker6d(backend="numpy").axes[0].step == ws.cell_size_m == WHISKER6D_CELL_SIZE_M == 0.1
    assert PosecellNetwork().shape == (rs.xy_cells, rs.xy_cells, rs.heading_cells)
    assert LocalViewParams().inject_energy == RatSLAMConfig().inject_energy == 0.15


# ---------------------------------------------------------------- 0.1's names: warn, same result
@pytest.mark.parametrize("old,new,grid", [
    ({"dim_xy": 9, "dim_th": 12, "cell_size": 0.25}, {"xy_cells": 9, "heading_cells": 12, "cell_size_m": 0.25},
     [("x", 9, 0.25), ("y", 9, 0.25), ("theta", 12, 2 * math.pi / 12)]),
])
def test_openratslam_old_keywords_warn_and_build_the_same_grid(old, new, grid):
    with pytest.warns(DeprecationWarning) as record:
        pop = Population.openratslam(**old, backend="numpy")
    assert sorted(str(w.message).split(":")[1].split("(")[0].strip() for w in record) == [
        "the keyword cell_size is now cell_size_m", "the keyword dim_th is now heading_cells",
        "the keyword dim_xy is now xy_cells"]
    assert {w.filename for w in record} == {__file__}  # the warnings point at the caller's line
    assert [(n, s, pytest.approx(st_)) for n, s, st_ in grid] == _grid(pop)
    assert _grid(Population.openratslam(**new, backend="numpy")) == _grid(pop)


def test_whisker6d_old_keywords_warn_and_build_the_same_grid():
    with pytest.warns(DeprecationWarning) as record:
        pop = Population.whisker6d(n=4, cell_size=0.02, n_angle=6, backend="numpy")
    assert len(record) == 3 and any("n_angle is now angle_cells" in str(w.message) for w in record)
    assert _grid(pop)[0] == ("x", 4, 0.02) and pop.shape == (4, 4, 4, 6, 6, 6)


def test_head_direction_old_keyword_warns_and_builds_the_same_ring():
    with pytest.warns(DeprecationWarning, match="n is now heading_cells") as record:
        pop = Population.head_direction(n=90, backend="numpy")
    assert len(record) == 1 and pop.shape == (90,)
    assert Population.head_direction(heading_cells=90, backend="numpy").shape == (90,)


def test_posecell_network_old_keywords_warn():
    with pytest.warns(DeprecationWarning) as record:
        pc = PosecellNetwork(dim_xy=9, dim_th=12, cell_size=0.5)
    assert len(record) == 3 and {w.filename for w in record} == {__file__}
    assert pc.shape == (9, 9, 12)
    assert "cell_size_m=0.5" in repr(pc)


def test_old_and_new_name_together_is_a_config_error():
    with pytest.raises(ConfigError, match="dim_xy is the old name of xy_cells; give xy_cells only"):
        Population.openratslam(dim_xy=9, xy_cells=9)
    with pytest.raises(ConfigError, match="inject_gain is the old name of inject_energy"):
        LocalViewParams(inject_gain=0.2, inject_energy=0.2)


def test_new_names_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Population.openratslam(9, 12, 0.5, backend="numpy")
        Population.whisker6d(4, 0.02, angle_cells=6, backend="numpy")
        PosecellNetwork(xy_cells=9, heading_cells=12, cell_size_m=0.5)
        LocalViewParams(mode="learnt", inject_energy=0.4)


# ---------------------------------------------------------------- one injection name
def test_learnt_injection_uses_inject_energy_as_delta():
    """Eq 2.17 with one active view whose weights are the packet P: dP = delta * P (delta = inject_energy)."""
    lv = LocalViewCells((4,), LocalViewParams(mode="learnt", inject_energy=0.5, recent_exclusion=0))
    lv.observe(0, np.array([1.0]))
    lv.learn(np.array([0.0, 0.25, 0.75, 0.0]))
    idx, vals = lv.injection()
    assert dict(zip(idx.tolist(), vals.tolist())) == {1: pytest.approx(0.125), 2: pytest.approx(0.375)}


def test_inject_gain_keyword_and_attribute_are_deprecated():
    with pytest.warns(DeprecationWarning, match="inject_gain is now inject_energy"):
        p = LocalViewParams(mode="learnt", inject_gain=0.7)
    assert p.inject_energy == 0.7
    with pytest.warns(DeprecationWarning, match="inject_gain is now inject_energy"):
        assert p.inject_gain == 0.7


def test_lv_interference_takes_inject_energy_and_the_old_name():
    from cansim.experiments import lv_interference

    assert "inject_energy" in lv_interference.DEFAULTS and "inject_gain" not in lv_interference.DEFAULTS
    with pytest.warns(DeprecationWarning, match="inject_gain is now inject_energy"):
        p = lv_interference.check_params({"inject_gain": 0.2})
    assert p["inject_energy"] == 0.2


# ---------------------------------------------------------------- one list of spiking backends
def test_spiking_backends_are_defined_once():
    import cansim.spiking as spiking
    import cansim.testing.conformance as conformance
    from cansim.axes import Axis
    from cansim.spiking import SpikingParams, SpikingPopulation

    assert spiking.SPIKING_BACKENDS == ("numpy", "numba")
    assert not hasattr(conformance, "SPIKING_BACKENDS")
    for name in spiking.SPIKING_BACKENDS:  # every listed backend builds a population
        SpikingPopulation((Axis.angle("a", 12),), SpikingParams(), backend=name)
    with pytest.raises(ConfigError, match="backend must be one of"):
        SpikingPopulation((Axis.angle("a", 12),), SpikingParams(), backend="opencl")


# ---------------------------------------------------------------- the helper's properties
_names = st.text(alphabet="abcdefgh_", min_size=1, max_size=6)


@given(renames=st.dictionaries(_names, _names, max_size=4), kwargs=st.dictionaries(_names, st.integers(), max_size=6))
def test_take_renamed_moves_each_old_value_to_its_new_name(renames, kwargs):
    renames = {old: new for old, new in renames.items() if old != new and new not in renames}  # a real rename table
    used = [old for old in renames if old in kwargs]
    clash = any(renames[old] in kwargs for old in used) or len({renames[o] for o in used}) < len(used)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        if clash:
            with pytest.raises(ConfigError):
                take_renamed(kwargs, renames, "f")
            return
        out = take_renamed(kwargs, renames, "f")
    assert len(record) == len(used) and all(issubclass(w.category, DeprecationWarning) for w in record)
    assert not set(used) & set(out)
    for key, value in kwargs.items():
        assert out[renames.get(key, key)] == value
    assert len(out) == len(kwargs)


def test_decorator_keeps_the_signature_and_positional_calls():
    @renamed_keywords(size="size_m")
    def f(size_m: float = 1.0, *, k: int = 0) -> tuple[float, int]:
        """Doc."""
        return size_m, k

    assert f.__name__ == "f" and f.__doc__ == "Doc." and f.__renamed_keywords__ == {"size": "size_m"}
    assert f(2.0, k=1) == (2.0, 1)
    with pytest.warns(DeprecationWarning, match="f: the keyword size is now size_m"):
        assert f(size=3.0) == (3.0, 0)
