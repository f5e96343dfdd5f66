"""Shared fixtures: the ``backend`` fixture runs a test once per available backend."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

from cansim.backends import available_backends, get_backend  # noqa: E402
from cansim.errors import BackendUnavailableError  # noqa: E402

pytest_plugins = ["cansim.testing.plugin"]  # candidate / reference fixtures of the conformance suite


#: comma-separated backends that must run (CI sets it): their absence fails instead of skipping
REQUIRED = {b for b in os.environ.get("CANSIM_REQUIRE_BACKENDS", "").split(",") if b}


@pytest.fixture(params=sorted(set(available_backends()) | REQUIRED))
def backend(request):
    """A backend instance per importable backend; skipped when it has no device.

    Backends named in ``$CANSIM_REQUIRE_BACKENDS`` fail the test instead of skipping.
    """
    try:
        return get_backend(request.param)
    except BackendUnavailableError as exc:  # e.g. pyopencl without a platform
        if request.param in REQUIRED:
            pytest.fail(f"required backend {request.param!r} is unavailable: {exc}")
        pytest.skip(str(exc))


@pytest.fixture(scope="session")
def mug():
    """The simulated Mug (``whisker_io.sim.objects``), shared by the whisker tests that explore it."""
    from whisker_io.sim.objects import make_object

    return make_object("mug")
