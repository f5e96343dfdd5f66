"""A backend of one's own, named with register_backend (a user's pass, session 47: only private names let one
register it, a population saved with it could not be loaded, pickled or configured by name)."""

from __future__ import annotations

import io
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cansim.backends as backends
from backend_fixtures import MineBackend
from cansim import InvalidInputError, Population
from cansim.backends.numpy_backend import NumpyBackend
from cansim.errors import UnknownBackendError


@pytest.fixture()
def registry(monkeypatch):
    """The registry as a copy for the test (registration is process-wide)."""
    monkeypatch.setattr(backends, "_REGISTRY", dict(backends._REGISTRY))
    monkeypatch.setattr(backends, "_status_cache", {})


def _moves(p):
    return np.array([p.step(v) for v in (0.3, 0.25, -0.7, 1.4)])


def test_a_registered_backend_is_a_name_everywhere(registry):
    backends.register_backend("mine", MineBackend)
    assert "mine" in backends.registered_backends() and backends.backend_status()["mine"] == (True, "imports")
    assert isinstance(backends.get_backend("mine"), MineBackend)
    mine, ref = Population.head_direction(36, backend="mine"), Population.head_direction(36, backend="numpy")
    np.testing.assert_array_equal(_moves(mine), _moves(ref))
    buf = io.BytesIO()
    mine.save(buf)
    buf.seek(0)
    back = Population.load(buf)
    assert back.backend == "mine" and type(back._backend) is MineBackend
    np.testing.assert_array_equal(_moves(back), _moves(mine))
    assert type(pickle.loads(pickle.dumps(mine))._backend) is MineBackend
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig

    slam = RatSLAM(RatSLAMConfig(backend="mine", frontend="ids"))
    slam.step(0.1, 0.05, 1.0, 0)
    assert slam.pose_cells.backend == "mine"


def test_a_file_naming_an_unregistered_backend_says_to_register_it(registry):
    backends.register_backend("mine", MineBackend)
    buf = io.BytesIO()
    Population.head_direction(12, backend="mine").save(buf)
    del backends._REGISTRY["mine"]
    buf.seek(0)
    with pytest.raises(UnknownBackendError, match="register_backend: register it before loading"):
        Population.load(buf)


def test_an_unregistered_instance_runs_and_pickles_but_is_not_written_by_name(registry, tmp_path):
    p = Population.head_direction(12, backend=MineBackend())
    p.step(0.4)
    assert pickle.loads(pickle.dumps(p)).backend == "mine"  # the instance itself travels
    with pytest.raises(InvalidInputError, match="is not the class the registry builds by its name.*register_backend"):
        p.save(tmp_path / "ring.npz")
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("name,cls,says", [
    ("numpy", MineBackend, "other than numpy"),
    ("", MineBackend, "non-empty"),
    ("mine", int, "subclass of cansim.backends.Backend"),
    ("other", MineBackend, "MineBackend.name is 'mine': set the class attribute name = 'other'"),
    ("abstract", backends.Backend, "does not implement decode, dynamics, inject, shift, shift_conditional"),
])
def test_registration_refuses_what_would_not_work(registry, name, cls, says):
    with pytest.raises(InvalidInputError, match=says):
        backends.register_backend(name, cls)
    assert name not in backends.registered_backends() or name == "numpy"


def test_a_class_defined_inside_a_function_is_refused(registry):
    def make():
        class Inner(NumpyBackend):
            name = "inner"
        return Inner

    with pytest.raises(InvalidInputError, match="top level of an importable module"):
        backends.register_backend("inner", make())


class NumpyNamed(NumpyBackend):
    """A subclass that keeps the built-in name: never to be swapped for the built-in class."""


def test_a_subclass_keeping_a_built_in_name_is_pickled_as_itself_and_not_saved_by_that_name(tmp_path):
    p = Population.head_direction(12, backend=NumpyNamed())
    assert p.backend == "numpy" and backends.registered_name(p._backend) is None
    assert type(pickle.loads(pickle.dumps(p))._backend) is NumpyNamed
    with pytest.raises(InvalidInputError, match="NumpyNamed .name 'numpy'. is not the class the registry builds"):
        p.save(tmp_path / "x.npz")
    assert backends.registered_name(NumpyBackend()) == "numpy"


@settings(max_examples=50, deadline=None)
@given(name=st.one_of(st.sampled_from(["numpy", "numba", "opencl", "", "  ", "mine"]), st.text(max_size=12)))
def test_only_a_new_name_that_the_class_carries_is_registered(name):
    """Registration never changes the registry on a refused name: built-in, empty, or not the class's own."""
    before = dict(backends._REGISTRY)
    try:
        backends.register_backend(name, MineBackend)
    except InvalidInputError:
        assert backends._REGISTRY == before
    else:
        assert name == "mine" and backends._REGISTRY["mine"].cls == "MineBackend"
        backends._REGISTRY.clear()
        backends._REGISTRY.update(before)


@settings(max_examples=40, deadline=None)
@given(name=st.text(min_size=0, max_size=8))
def test_a_model_config_names_its_backend_when_it_is_made(name):
    """RatSLAMConfig(backend="cuda") was accepted and failed only at RatSLAM(cfg) (a benchmark user's pass, s48)."""
    from cansim.backends import registered_backends
    from cansim.errors import ConfigError
    from cansim.models.ratslam_config import RatSLAMConfig
    from cansim.models.whisker_ratslam import WhiskerRatSLAMConfig

    for cls in (RatSLAMConfig, WhiskerRatSLAMConfig):
        if name in registered_backends():
            assert cls(backend=name).backend == name
        else:
            with pytest.raises(ConfigError, match="is not a backend here"):
                cls(backend=name)


def test_a_model_saved_with_an_unregistered_backend_says_to_register_it_not_corrupt(registry, tmp_path):
    from cansim.errors import UnknownBackendError
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig

    backends.register_backend("mine", MineBackend)
    RatSLAM(RatSLAMConfig(backend="mine", frontend="ids", xy_cells=9, heading_cells=12)).save(tmp_path / "m.npz")
    del backends._REGISTRY["mine"]
    with pytest.raises(UnknownBackendError, match="register it before loading") as exc:
        RatSLAM.load(tmp_path / "m.npz")
    assert "corrupt" not in str(exc.value) and "'mine'" in str(exc.value)
