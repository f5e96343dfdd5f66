"""Shared fixtures: the ``backend`` fixture runs a test once per available backend."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

from cansim.backends import available_backends, get_backend  # noqa: E402
from cansim.errors import BackendUnavailableError  # noqa: E402

from hypothesis import settings  # noqa: E402

#: Hypothesis profiles. "default" draws new examples on every run, so local runs keep
#: searching for bad inputs; "ci" (``.ci/run`` sets ``CANSIM_HYPOTHESIS_PROFILE=ci``) draws
#: the same examples on every machine, so a landing is judged on what was run before it.
settings.register_profile("ci", derandomize=True, print_blob=True)
settings.load_profile(os.environ.get("CANSIM_HYPOTHESIS_PROFILE", "default"))

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

