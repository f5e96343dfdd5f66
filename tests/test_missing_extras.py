"""A feature whose optional dependency is not installed says which extra to install, with the error tree's own
MissingExtraError (an ImportError too), never a bare ModuleNotFoundError (a base-install user's pass, session 49).

Each test hides the module (``sys.modules[name] = None`` makes ``import name`` fail) and calls the path that needs it.
"""

from __future__ import annotations

import importlib
import sys

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cansim.errors import CansimError, MissingExtraError
from whisker_io.command_line import EXIT_MISSING_EXTRA, run_command
from whisker_io.errors import MissingDependencyError, missing_extra

_NAME = st.text(st.characters(min_codepoint=97, max_codepoint=122), min_size=1, max_size=12)


@given(_NAME, _NAME, _NAME)
def test_the_error_names_what_needs_what_and_the_extra_to_install(what, module, extra):
    exc = missing_extra(what, module, extra)
    assert isinstance(exc, MissingExtraError) and isinstance(exc, ImportError) and isinstance(exc, CansimError)
    text = str(exc)
    assert text.startswith(what) and repr(module) in text and text.endswith(f'pip install "cansim[{extra}]"')


def _hidden(monkeypatch, *modules):
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)


@pytest.mark.parametrize("call, hide, extra", [
    ("cansim.tools.sweep:_pa", ("pyarrow", "pyarrow.parquet"), "sweep"),
    ("cansim.tools.sweep:_client", ("distributed",), "sweep"),
    ("cansim.tools.bag_replay:_need_rosbags", ("rosbags", "rosbags.highlevel", "rosbags.typesys"), "bags"),
    ("cansim.spiking.nir_io:_nir", ("nir",), "spiking"),
])
def test_a_missing_module_is_a_missing_extra_error_naming_the_extra(monkeypatch, call, hide, extra):
    module, name = call.split(":")
    fn = getattr(importlib.import_module(module), name)
    _hidden(monkeypatch, *hide)
    args = (None, None, 1.0) if name == "_client" else ()
    with pytest.raises(MissingExtraError, match=rf'pip install "cansim\[{extra}\]"'):
        fn(*args)


@pytest.mark.parametrize("module, hide, error, extra", [
    ("cansim.backends.opencl_backend", "pyopencl", MissingExtraError, "opencl"),
    ("whisker_io.testing.fake_usb_backend", "usb", MissingDependencyError, "hw"),
])
def test_a_module_that_needs_an_extra_says_so_when_imported(monkeypatch, module, hide, error, extra):
    _hidden(monkeypatch, hide, f"{hide}.backend", f"{hide}.core")
    monkeypatch.delitem(sys.modules, module, raising=False)  # imported afresh, then put back as it was
    with pytest.raises(error, match=rf'cansim\[{extra}\]'):
        importlib.import_module(module)


def test_a_script_ends_on_a_missing_extra_with_one_line_and_status_6(capsys):
    def needs_nir() -> int:
        raise missing_extra("writing spiking_ring.nir", "nir", "spiking")

    assert run_command(needs_nir, "spiking_ring") == EXIT_MISSING_EXTRA == 6
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("spiking_ring: writing spiking_ring.nir needs") and 'cansim[spiking]' in err
    assert run_command(lambda: 0, "x") == 0 and run_command(lambda: 3, "x") == 3
    with pytest.raises(ValueError):  # any other error is the script's own to report
        run_command(lambda: int("x"), "x")


@given(st.integers(-255, 255), _NAME)
def test_run_command_passes_a_status_through_and_ends_a_missing_extra_with_6(status, extra):
    assert run_command(lambda: status, "prog") == status
    def needs():
        raise missing_extra("it", "mod", extra)
    assert run_command(needs, "prog") == EXIT_MISSING_EXTRA
