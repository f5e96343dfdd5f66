"""Renamed configuration classes (the Params / Config / Spec rule, CONTRIBUTING.md): the old
names still give the new classes, with a DeprecationWarning, until 0.3."""

from __future__ import annotations

import importlib

import pytest


@pytest.mark.parametrize(("module", "old", "new"), [
    ("whisker_io.radial.models", "SearchSettings", "SearchParams"),
    ("cansim.studies.ch5_object_maps", "Settings", "StudyConfig"),
    ("cansim.studies.ch3_maze", "StudySettings", "StudyConfig"),
])
def test_old_names_warn_and_give_the_new_class(module: str, old: str, new: str) -> None:
    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=new):
        cls = getattr(mod, old)
    assert cls is getattr(mod, new)
    with pytest.raises(AttributeError):
        getattr(mod, old + "Nope")
