"""One error tree: every exception class the packages define derives from CansimError (issue 25)."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest

from cansim._moved import MOVED
from whisker_io.errors import CansimError

PACKAGES = ("whisker_io", "maps", "cansim")


def _modules() -> list[str]:
    names = []
    for pkg in PACKAGES:
        module = importlib.import_module(pkg)
        names.append(pkg)
        for info in pkgutil.walk_packages(module.__path__, prefix=f"{pkg}."):
            if info.name.endswith("__main__") or info.name in MOVED:
                continue
            names.append(info.name)
    return names


def test_every_exception_class_is_in_the_tree():
    """Every error class derives from CansimError (a warning category is no error: it is never raised); a module
    that needs an extra which is not installed says so with the tree's own error when imported."""
    from whisker_io.errors import MissingExtraError

    outside = []
    for name in _modules():
        try:
            module = importlib.import_module(name)
        except MissingExtraError:  # e.g. the OpenCL backend or the fake USB backend on a base install
            continue
        for cls_name, cls in inspect.getmembers(module, inspect.isclass):
            if (cls.__module__ == name and issubclass(cls, BaseException) and not issubclass(cls, Warning)
                    and not issubclass(cls, CansimError)):
                outside.append(f"{name}.{cls_name}")
    assert outside == []


@pytest.mark.parametrize("path", ["cansim.tools.cli.CommandError", "whisker_io.testing.fake_rtde_server.FakeServerError"])
def test_the_two_that_were_outside(path):
    module, name = path.rsplit(".", 1)
    assert issubclass(getattr(importlib.import_module(module), name), CansimError)
