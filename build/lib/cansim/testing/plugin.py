"""pytest plugin of cansim's backend conformance suite: the ``candidate`` and ``reference`` fixtures.

``candidate`` runs a test once per backend under test: the names given with
``--cansim-backend`` (comma-separated), else every available backend except the numpy
reference. Backends listed in the environment variable ``CANSIM_REQUIRE_BACKENDS`` fail
instead of being skipped when they cannot run (CI sets it). ``reference`` is the numpy
backend. See :mod:`cansim.testing.conformance`.
"""

from __future__ import annotations

import os

import pytest

from cansim.backends import available_backends, get_backend
from cansim.errors import BackendUnavailableError

__all__ = ["pytest_addoption", "pytest_generate_tests", "candidate", "reference"]

REFERENCE = "numpy"


def _required() -> set[str]:
    return {b for b in os.environ.get("CANSIM_REQUIRE_BACKENDS", "").split(",") if b}


def pytest_addoption(parser: pytest.Parser) -> None:
    """``--cansim-backend NAME[,NAME...]``: the backends the conformance suite tests."""
    parser.addoption("--cansim-backend", default="", help="backends under test (comma-separated); default: all available but numpy")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrise ``candidate`` over the backends under test."""
    if "candidate" not in metafunc.fixturenames:
        return
    given = [b for b in metafunc.config.getoption("--cansim-backend").split(",") if b]
    names = given or sorted((set(available_backends()) | _required()) - {REFERENCE})
    metafunc.parametrize("candidate", names, indirect=True)


@pytest.fixture
def candidate(request: pytest.FixtureRequest):
    """A backend under test (never the reference)."""
    try:
        return get_backend(request.param)
    except BackendUnavailableError as exc:
        if request.param in _required():
            pytest.fail(f"required backend {request.param!r} is unavailable: {exc}")
        pytest.skip(str(exc))


@pytest.fixture
def reference():
    """The numpy reference backend."""
    return get_backend(REFERENCE)
