"""Skip marks for tests that need an optional extra: on a base install (``pip install cansim``) they skip, saying which
extra brings what they need; CI installs every extra (``.ci/run``), where they run."""

from __future__ import annotations

import importlib.util

import pytest


def needs(module: str, extra: str) -> pytest.MarkDecorator:
    """Skip unless ``module`` can be imported (the pip extra ``extra`` installs it)."""
    try:
        found = importlib.util.find_spec(module) is not None
    except ImportError:  # a parent package is missing
        found = False
    return pytest.mark.skipif(not found, reason=f'needs the {extra} extra ({module}): pip install -e ".[{extra}]"')
