"""The command-line options for the objects a demo or study is given: names, or mesh files and their conventions.

Every runner that takes objects - the demo's ``--object``, the Ch.5 study's ``--objects`` /
``--novel``, the Ch.6 study's ``--objects``, the recognition study's ``--objects`` /
``--novel`` - takes a registered name, a procedural shape's name or a mesh file
(:func:`whisker_io.sim.catalogue.resolve_object`). A mesh file must follow the
simulator's conventions (metres, z up; :func:`whisker_io.sim.objects.load_object` rests
it on z = 0 and centres it) unless the run is told otherwise with the two options added
by :func:`add_mesh_options`:

* ``--scale-to-m M``: every mesh file is scaled so that its largest extent is ``M`` metres
  (0.35 for the thesis objects' size; a file in millimetres is refused with the value to
  pass);
* ``--up-axis AXIS``: every mesh file's up axis (``x``, ``y``, ``z``, ``-x``, ``-y``,
  ``-z``; glTF/GLB files are y-up by their specification).

In a study, which takes several objects, each option takes one value for every mesh file
or one per mesh file in the order they are given (``--objects`` first, then ``--novel``):
``--objects part.stl scene.glb --up-axis z y`` (:func:`per_mesh_file`). A study runs its
objects in worker processes by name, so :func:`conform_objects` writes each mesh file it changed, in the conventions, to ``<out>/objects/<label>.ply``
(single-precision vertices: within a micrometre; the label of
:func:`~whisker_io.sim.catalogue.object_labels`) and hands on that path: the study's
``mesh_file`` columns name that file, which keeps the object exactly as run
(:func:`labelled_rows`). ``<out>/objects/sources.json`` says which file each copy was made from and
what was changed, and for a file run as it is what was assumed (:data:`SOURCES_FILE`; the same is
logged once per file as a warning).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from whisker_io.errors import InvalidInputError
from whisker_io.persistence import write_atomically
from whisker_io.sim.catalogue import is_mesh_file, object_file_name, object_file_names, object_labels, object_name, resolve_object
from whisker_io.sim.objects import GLTF_SUFFIXES, UP_AXES, load_object

__all__ = ["SOURCES_FILE", "add_mesh_options", "check_distinct", "check_mesh_options", "conform_objects",
           "is_mesh_file", "labelled_rows", "object_label", "object_labels", "per_mesh_file", "seed_name"]

log = logging.getLogger(__name__)

#: Written beside the copies by :func:`conform_objects`: a JSON list, one entry per mesh file, with
#: ``given`` (the file as given on the command line), ``given_path`` (its absolute path),
#: ``copy`` (the copy the run used; null for a file run as it is), ``changes`` (what
#: :func:`~whisker_io.sim.objects.load_object` assumed and changed, one sentence each),
#: ``scale_factor`` and ``extents_m`` (of the object as run, m).
SOURCES_FILE = "sources.json"


def add_mesh_options(ap: argparse.ArgumentParser, *, per_file: bool = False) -> None:
    """Add ``--scale-to-m M`` and ``--up-axis AXIS`` (module docstring) to a runner's parser.

    With ``per_file`` (a runner of several objects) each option takes one value for every
    mesh file or one per mesh file, in the order the files are given (:func:`per_mesh_file`).
    """
    many = {"nargs": "+"} if per_file else {}
    each = (" (one value for every mesh file, or one per mesh file in the order given: --objects, then --novel)"
            if per_file else "")
    axes = ("; a list with a negative axis as one word after '=': --up-axis=z,-y" if per_file else "")
    ap.add_argument("--scale-to-m", type=float, default=None, metavar="M", **many,
                    help="scale every mesh file so that its largest extent is M metres (e.g. 0.35, the thesis "
                         f"objects' size; needed for files in millimetres){each}")
    ap.add_argument("--up-axis", default=None, metavar="AXIS", **many,
                    help=f"the mesh files' up axis ({', '.join(UP_AXES)}; default z; glTF/GLB files are y-up by "
                         f"their specification){each}{axes}")


def per_mesh_file(specs: Sequence[str], value: Any, option: str) -> list[Any]:
    """``value`` for each object of ``specs``: None for a name, for a mesh file its value.

    Parameters
    ----------
    specs : sequence of str
        Objects as given (names or mesh files).
    value : None, a value, or a sequence of values
        None (the option not given), one value for every mesh file, or a sequence of one
        value (the same) or one per mesh file in the order they stand in ``specs``.
    option : str
        The option's name, for the message.

    Returns
    -------
    list, len(specs)

    Raises
    ------
    InvalidInputError
        A sequence of another length than 1 or the number of mesh files.
    """
    files = [i for i, spec in enumerate(specs) if is_mesh_file(spec)]
    out: list[Any] = [None] * len(specs)
    if value is None:
        return out
    values = list(value) if isinstance(value, (list, tuple)) else [value]
    # 'z,-y' as one word: argparse takes a '-y' standing alone for an option, so '--up-axis=z,-y' is how a
    # negative axis stands in a list
    values = [w.strip() for v in values for w in v.split(",")] if all(isinstance(v, str) for v in values) else values
    if len(values) == 1:
        values = values * len(files)
    elif len(values) != len(files):
        named = ", ".join(object_file_name(specs[i]) for i in files) or "none"
        raise InvalidInputError(f"{option} takes one value for every mesh file or one per mesh file, in their order "
                                f"({len(files)} here: {named}); got {len(values)}")
    for i, v in zip(files, values):
        out[i] = v
    return out


def object_label(spec: str | os.PathLike[str]) -> str:
    """A short name for one object in a message: a mesh file's stem (``"/data/my mug.obj"`` -> ``"my_mug"``), a name as
    given. A run's outputs name its objects by :func:`~whisker_io.sim.catalogue.object_labels` (distinct)."""
    return object_file_name(spec) if is_mesh_file(spec) else str(spec)


def check_mesh_options(specs: Sequence[str], *, scale_to_m: float | Sequence[float] | None = None,
                       up_axis: str | Sequence[str] | None = None) -> None:
    """Refuse ``--scale-to-m`` / ``--up-axis`` on a command whose objects hold no mesh file (they would be ignored),
    or with a list of values that is not one per mesh file (:func:`per_mesh_file`).

    Raises
    ------
    InvalidInputError
        An option given and no object of ``specs`` a mesh file; a list of values of another
        length than 1 or the number of mesh files.
    """
    if (scale_to_m is not None or up_axis is not None) and not any(is_mesh_file(s) for s in specs):
        given = ", ".join(map(str, specs)) or "the default objects"
        raise InvalidInputError(f"--scale-to-m / --up-axis apply to mesh files, and no object given is one ({given}); "
                                "leave them out for named objects")
    per_mesh_file(specs, scale_to_m, "--scale-to-m")
    per_mesh_file(specs, up_axis, "--up-axis")


def _identity(spec: str) -> tuple[str, str]:
    """What makes two objects of a command line the same: a mesh file's bytes (its path when unreadable), an
    object's own name."""
    if is_mesh_file(spec):
        return "file", _digest(spec) or str(Path(spec).resolve())
    return "name", object_name(spec)[0]  # the name resolve_object gives it, without building its mesh


def check_distinct(objects: Sequence[str], novel: Sequence[str] = ()) -> None:
    """Refuse an object given twice, or as both a library (mapped) object and a novel one, before any work.

    Raises
    ------
    InvalidInputError
        The object named twice, with what to do.
    """
    seen: dict[tuple[str, str], tuple[str, str]] = {}  # identity -> (role, spec as given first)
    for role, specs in (("library", objects), ("novel", novel)):
        for spec in map(str, specs):
            key = _identity(spec)
            if key in seen:
                first_role, first = seen[key]
                what = "given twice" if first_role == role else "both a library object and a novel one"
                spelt = f" ({first} and {spec})" if first != spec else ""
                raise InvalidInputError(f"{spec} is {what}{spelt}; name each object once "
                                        "(a novel object is one the library does not hold)")
            seen[key] = (role, spec)


def _digest(path: str | os.PathLike[str]) -> str:
    """The first 12 hex digits of the SHA-256 of a file's bytes ("" when it cannot be read)."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]
    except OSError:
        return ""


def seed_name(spec: str | os.PathLike[str]) -> str:
    """What an object contributes to the seeds of a study's runs: a name as given; for a mesh file its stem
    and a digest of its bytes.

    Where a file lies does not count: the same file named by a relative or an absolute path,
    or its copy in another ``--out``, gets the same noise (:func:`cansim.seeding.derive_seed`);
    two different files of one stem (``a/cup.obj``, ``b/cup.obj``) get different noise.
    """
    if not is_mesh_file(spec):
        return str(spec)
    digest = _digest(spec)
    return f"{object_file_name(spec)}-{digest}" if digest else object_file_name(spec)


def labelled_rows(rows: Sequence[Mapping[str, Any]], labels: Mapping[str, str], columns: Sequence[str],
                  of: str) -> list[dict[str, Any]]:
    """Rows of a study's CSV as written: objects named by their labels, with the mesh file of each row's object.

    Parameters
    ----------
    rows : sequence of mapping
        The study's rows, objects named as the run was given them (names or mesh files).
    labels : mapping
        Object as given -> its label (:func:`~whisker_io.sim.catalogue.object_labels` of every object of the run:
        the names its summary, figures and map files use).
    columns : sequence of str
        The columns that name an object (``presented``, ``decision``, ...); an empty value stays empty.
    of : str
        The column naming the row's own object, whose mesh file goes into ``mesh_file``.

    Returns
    -------
    list of dict
        Copies of ``rows``; ``mesh_file`` is the absolute path of the mesh file the run loaded for the row's
        object, empty for a registered object or a procedural shape.
    """
    out = []
    for row in rows:
        new = dict(row)
        for column in columns:
            if new[column] != "":
                new[column] = labels[str(new[column])]
        spec = str(row[of])
        new["mesh_file"] = os.path.abspath(spec) if is_mesh_file(spec) else ""
        out.append(new)
    return out


def _source_entry(spec: str, obj: Any, copy: str | None) -> dict[str, Any]:
    """One entry of :data:`SOURCES_FILE`: the file as given, the copy run (None: the file itself) and what
    :func:`~whisker_io.sim.objects.load_object` assumed and changed."""
    return {"given": spec, "given_path": str(Path(spec).resolve()), "copy": copy, "changes": list(obj.notes),
            "scale_factor": float(obj.scale_factor), "extents_m": [float(x) for x in obj.extents_m]}


def conform_objects(specs: Sequence[str], folder: str | os.PathLike[str], *,
                    scale_to_m: float | Sequence[float] | None = None,
                    up_axis: str | Sequence[str] | None = None) -> list[str]:
    """Check every object of a command line and bring its mesh files to the conventions when told to.

    Parameters
    ----------
    specs : sequence of str
        Objects as given: registered names, procedural shapes' names or mesh files.
    folder : path-like
        Where a changed mesh file is written, as ``<label>.ply`` (labels of
        :func:`~whisker_io.sim.catalogue.object_labels`: distinct); created when needed.
    scale_to_m, up_axis : optional
        As :func:`whisker_io.sim.objects.load_object`'s: one value for every mesh file, or a
        sequence of one per mesh file in the order they stand in ``specs`` (:func:`per_mesh_file`).

    Returns
    -------
    list of str
        ``specs`` with each mesh file as an absolute path (so the outputs that name it hold
        one path, whatever the working directory; a symbolic link is not followed: its name is
        the object's), and each changed one replaced by the absolute path of its copy in the
        conventions: every mesh file when an option is given, and a glTF/GLB file read
        without ``up_axis`` (taken as z-up with one warning, not one in every process
        that loads it); otherwise unchanged. What a copy changed is logged as a warning
        (the run uses the object as changed, not as given) and written, with the file it
        came from, to ``folder / SOURCES_FILE``.

    Raises
    ------
    InvalidInputError, CorruptFileError
        A name that is no object, a mesh file :func:`load_object` refuses (the message
        says what to pass), or ``scale_to_m`` / ``up_axis`` given with no mesh file to
        apply them to (:func:`check_mesh_options`).
    """
    specs = [str(s) for s in specs]
    if not isinstance(folder, (str, os.PathLike)):
        raise InvalidInputError(f"folder must be a path (str or pathlib.Path), got {type(folder).__name__}")
    folder = Path(folder)
    check_mesh_options(specs, scale_to_m=scale_to_m, up_axis=up_axis)
    scales, ups = per_mesh_file(specs, scale_to_m, "--scale-to-m"), per_mesh_file(specs, up_axis, "--up-axis")
    stems = object_file_names(specs)
    copied = [is_mesh_file(s) and (scales[i] is not None or ups[i] is not None
                                   or Path(s).suffix.lower() in GLTF_SUFFIXES) for i, s in enumerate(specs)]
    targets = {(folder / f"{stem}.ply").resolve() for stem, c in zip(stems, copied) if c}
    for spec in specs:  # before any copy is written: none may land on a file still to be read
        if is_mesh_file(spec) and Path(spec).resolve() in targets:
            raise InvalidInputError(f"{spec} is where this run writes a copy in its conventions (an earlier run's "
                                    "copy?); give the original file, or another --out")
    # every object is read and checked before anything is written: a bad name or mesh fails with its reason and
    # leaves no copy, and no record of one, behind
    loaded = {i: load_object(spec, scale_to_m=scales[i], up_axis=ups[i], name=stem)
              for i, (spec, stem, copy) in enumerate(zip(specs, stems, copied)) if copy}
    # mesh files run as given (each process loads them): what load_object assumed and changed is said too
    as_given: dict[int, Any] = {}
    for i, spec in enumerate(specs):
        if i not in loaded:
            obj = resolve_object(spec)
            if is_mesh_file(spec):
                as_given[i] = obj
    for i, obj in as_given.items():  # said once every object has passed its checks
        said = [n for n in obj.notes if n.startswith("assumed") or " m apart" in n]  # what may be wrong
        log.warning("%s: %s m%s", specs[i], " x ".join(f"{x:.3f}" for x in obj.extents_m),
                    "".join(f"; {n}" for n in said))
    record = folder / SOURCES_FILE
    record.unlink(missing_ok=True)  # this run's record or none: never an earlier run's
    out, sources = [], []
    for i, (spec, stem) in enumerate(zip(specs, stems)):
        if i not in loaded:  # a mesh file as an absolute path (links not followed: its name is the object's)
            out.append(os.path.abspath(spec) if is_mesh_file(spec) else spec)
            if i in as_given:
                sources.append(_source_entry(spec, as_given[i], None))
            continue
        path, obj = folder / f"{stem}.ply", loaded[i]
        folder.mkdir(parents=True, exist_ok=True)
        obj.mesh.export(path)
        sources.append(_source_entry(spec, obj, os.path.abspath(path)))
        changes = [n for n in obj.notes if n.startswith("rotated")]
        if obj.scale_factor != 1.0:
            changes += [n for n in obj.notes if n.startswith("scaled")]
        if changes:
            log.warning("%s: %s (%s m); run from %s", spec, "; ".join(changes),
                        " x ".join(f"{x:.3f}" for x in obj.extents_m), path)
        out.append(os.path.abspath(path))
    if sources:  # which file each copy came from (written whole, then renamed: never half a file)
        folder.mkdir(parents=True, exist_ok=True)
        text = json.dumps(sources, indent=2).encode()
        write_atomically(record, lambda fh: fh.write(text))
    return out
