"""Shared fixtures: the ``backend`` fixture runs a test once per available backend."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

from cansim.backends import available_backends, get_backend  # noqa: E402
from cansim.errors import BackendUnavailableError  # noqa: E402


@pytest.fixture(params=available_backends())
def backend(request):
    """A backend instance per importable backend; skipped when it has no device."""
    try:
        return get_backend(request.param)
    except BackendUnavailableError as exc:  # e.g. pyopencl without a platform
        pytest.skip(str(exc))


@pytest.fixture
def reference():
    """The numpy reference backend."""
    return get_backend("numpy")
