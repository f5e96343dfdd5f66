"""Every object a runner can be given, by one name: the thesis objects, the procedural shapes, a mesh file.

:func:`resolve_object` is what the demo, the Ch.5 and Ch.6 studies, the recognition
study and ``--object`` call: a registered name (:data:`whisker_io.sim.objects.OBJECT_NAMES`),
a procedural shape's name (:func:`whisker_io.sim.shapes.make_shape`, e.g. ``"duck"``,
``"torus_flat-v3"``), a mesh file or a ``trimesh`` mesh (:func:`whisker_io.sim.objects.load_object`,
which states and applies the conventions: metres, z up, resting on z = 0, centred).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import trimesh

from whisker_io.errors import InvalidInputError
from whisker_io.sim.objects import MESH_SUFFIXES, OBJECT_NAMES, LoadedObject, load_object, make_object
from whisker_io.sim.shapes import SHAPE_FAMILIES, is_shape_name, make_shape

__all__ = ["is_mesh_file", "object_file_name", "object_file_names", "object_labels", "object_name", "resolve_object"]


def resolve_object(spec: str | os.PathLike[str] | trimesh.Trimesh, *, scale_to_m: float | None = None,
                   up_axis: str | None = None) -> LoadedObject:
    """The object a runner was asked for: a registered name, a procedural shape's name, or a mesh.

    Parameters
    ----------
    spec : str, path-like or trimesh.Trimesh
        One of :data:`OBJECT_NAMES` (the thesis objects, aliases as in
        :func:`make_object`), a name of :func:`whisker_io.sim.shapes.make_shape`
        (``"duck"``, ``"torus_flat-v3"``), a mesh file (:data:`MESH_SUFFIXES`) or a
        mesh in memory.
    scale_to_m, up_axis
        As in :func:`load_object`. A named object is returned as built when both
        are left at their defaults; otherwise it passes through :func:`load_object`.

    Returns
    -------
    LoadedObject
        For a name: the built mesh with an identity record (``source`` is
        ``"registered object"`` or ``"procedural shape"``).

    Raises
    ------
    InvalidInputError
        A string that is neither a known name nor a mesh file; the message lists the
        registered names and shape families. Errors of :func:`load_object` for files.
    """
    if isinstance(spec, str) and not is_mesh_file(spec):
        name, source = object_name(spec)
        mesh = make_object(name) if source == "registered object" else make_shape(name)
        if scale_to_m is None and (up_axis is None or isinstance(up_axis, str) and up_axis.strip().lower() in ("z", "+z")):
            return LoadedObject(mesh, name, source, "+z", np.eye(3), 1.0, np.zeros(3), mesh.extents)
        return dataclasses.replace(load_object(mesh, scale_to_m=scale_to_m, up_axis=up_axis, name=name), source=source)
    return load_object(spec, scale_to_m=scale_to_m, up_axis=up_axis)


def is_mesh_file(spec: str | os.PathLike[str]) -> bool:
    """Whether an object spec names a mesh file (by its ending, :data:`MESH_SUFFIXES`) rather than an object."""
    return Path(spec).suffix.lower() in MESH_SUFFIXES


def object_name(spec: str) -> tuple[str, str]:
    """``(name, source)`` of a registered object's or a procedural shape's name, without building its mesh.

    ``name`` is what :func:`resolve_object` names the object (a registered name in its
    canonical spelling: ``"Box-Stack"`` -> ``"box_stack"``); ``source`` is ``"registered
    object"`` or ``"procedural shape"``.

    >>> object_name("Box-Stack"), object_name(" duck-v2 ")
    (('box_stack', 'registered object'), ('duck-v2', 'procedural shape'))

    Raises
    ------
    InvalidInputError
        Neither a known name nor a shape's; the message lists both and the mesh endings.
    """
    key = spec.strip().lower().replace("-", "_").replace(" ", "_")
    if key in OBJECT_NAMES:
        return key, "registered object"
    if is_shape_name(spec.strip()):
        return spec.strip(), "procedural shape"
    path = Path(spec)
    if path.is_dir():
        raise InvalidInputError(f"{spec} is a folder; give one mesh file ({', '.join(MESH_SUFFIXES)}) per object")
    if path.is_file():
        raise InvalidInputError(f"{spec}: {path.suffix or 'a file without an ending'} is not a mesh format read here; "
                                f"convert it to one of {', '.join(MESH_SUFFIXES)} (e.g. with trimesh or MeshLab)")
    raise InvalidInputError(
        f"{spec!r} is neither a registered object ({', '.join(OBJECT_NAMES)}), a procedural shape "
        f"(families {', '.join(SHAPE_FAMILIES)}, optionally '-v<N>' or '-h<N>') nor a mesh file "
        f"({', '.join(MESH_SUFFIXES)}); check the spelling or the path"
    )


def object_file_name(spec: str | os.PathLike[str]) -> str:
    """A file-name stem for an object name or mesh path: its stem with every character but letters,
    digits, ``-`` and ``_`` replaced by ``_`` (``"object"`` if nothing is left).

    >>> object_file_name("/data/my mug.obj")
    'my_mug'
    >>> object_file_name("torus_upright")
    'torus_upright'
    """
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in Path(spec).stem) or "object"


def object_labels(specs: Sequence[str | os.PathLike[str]]) -> dict[str, str]:
    """One name per object of a run, used for it everywhere: in its summary and figures, in the object
    columns of its CSVs, and as the stem of its map and copy files. Distinct and a file-name stem.

    Each object takes :func:`object_file_name` of itself (a mesh file's stem, a name as given); where
    two would be equal, letter case aside (``a/cup.obj``, ``b/Cup.stl``: one file on macOS and
    Windows), those take their folder (``a_cup``, ``b_Cup``), then their ending too
    (``a_cup_obj``), and only then a number by their place among ``specs`` (``cup_1``,
    ``cup_2``). The others keep their plain names.

    >>> object_labels(["a/cup.obj", "mug", "b/cup.stl"])
    {'a/cup.obj': 'a_cup', 'mug': 'mug', 'b/cup.stl': 'b_cup'}
    >>> object_labels(["/data/My Mug.obj", "torus_flat-v3"])
    {'/data/My Mug.obj': 'My_Mug', 'torus_flat-v3': 'torus_flat-v3'}

    Parameters
    ----------
    specs : sequence of str or path-like
        Objects as a runner was given them; one given twice is labelled once.

    Returns
    -------
    dict
        ``str(spec)`` -> label, in the order of ``specs``.
    """
    unique = list(dict.fromkeys(map(str, specs)))
    labels = {s: object_file_name(s) for s in unique}
    for step in ("folder", "ending", "number"):  # the clashing ones: with their folder, their ending, a number
        clash = _clashing(labels)
        if not clash:
            return labels
        for spec in clash:
            path = Path(spec)
            if step == "number":
                labels[spec] = f"{object_file_name(spec)}_{unique.index(spec) + 1}"
            elif is_mesh_file(spec):
                parts = [path.parent.name, path.stem, path.suffix.lstrip(".") if step == "ending" else ""]
                labels[spec] = object_file_name("_".join(p for p in parts if p))
    if _clashing(labels):  # a number made one equal to another's plain name: number them all
        return {s: f"{object_file_name(s)}_{i + 1}" for i, s in enumerate(unique)}
    return labels


def _clashing(labels: dict[str, str]) -> list[str]:
    """The objects whose labels are equal to another's, letter case aside (file names that differ only in case are
    one file on macOS and Windows)."""
    seen: dict[str, list[str]] = {}
    for spec, lab in labels.items():
        seen.setdefault(lab.casefold(), []).append(spec)
    return [spec for group in seen.values() if len(group) > 1 for spec in group]


def object_file_names(specs: Sequence[str | os.PathLike[str]]) -> list[str]:
    """:func:`object_labels` of several objects, in the order given: distinct file-name stems, so that no
    object's file overwrites another's and each file is named as the run's outputs name its object.

    >>> object_file_names(["a/mug.obj", "b/mug.stl"])
    ['a_mug', 'b_mug']
    >>> object_file_names(["box", "box_stack"])
    ['box', 'box_stack']
    """
    labels = object_labels(specs)
    return [labels[str(s)] for s in specs]
