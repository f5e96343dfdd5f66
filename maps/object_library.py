"""Object maps of several objects appended into one experience history (thesis Sec 5.2.2.2, Fig 5.16).

Each object is explored on its own (its own WhiskerRatSLAM run, its own object map).
For identification the maps are *appended*: experiences, links and histories are
concatenated with their ids shifted, and no link joins two objects ("sequential visits
to multiple objects with no topological connection between them", Fig 5.16). The
result is one :class:`~maps.object_map.ObjectMap` plus the *experience -> object* table
that :func:`maps.recognition.relocalisation_targets` reads: a later re-localisation to
experience ``e`` is an impulse into the leaky integrator of object ``exp_object[e]``.

Every map keeps its own pose frame (its first experience is at the identity) and its
own pose-cell locations (the maps share one pose-cell grid, each with its stored cells).
Local-view ids of map ``k`` are shifted by ``view_offsets[k]``, the number of regions
stored before it, so the caller appends the regions in the same order. The contact points
each map keeps (:meth:`~maps.object_map.ObjectMap.record_contacts`) are appended with
their experiences.

A library saves to one ``.npz`` file (:meth:`ObjectLibrary.save`, no pickle): the
appended map's fields (:meth:`~maps.object_map.ObjectMap.to_arrays`, prefixed ``map_``)
beside ``exp_object``, ``names`` (a unicode array) and ``history_object``.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np

from maps.object_map import ObjectMap
from whisker_io.persistence import naming_file, read_npz, write_npz
from whisker_io.errors import CorruptFileError, InvalidInputError

__all__ = ["ObjectLibrary", "append_object_maps"]


@dataclass(frozen=True)
class ObjectLibrary:
    """Appended object maps.

    Attributes
    ----------
    object_map : ObjectMap
        All experiences and links; the current experience is the last one appended.
    exp_object : ndarray (n_exp,) int64
        Object index of each experience.
    names : tuple of str
        Object names, index = object index.
    history_object : ndarray (n_iterations,) int64
        Object of each iteration of the appended experience history (Fig 5.16, top).
    """

    object_map: ObjectMap
    exp_object: np.ndarray
    names: tuple[str, ...]
    history_object: np.ndarray

    def with_explored(self, n_experiences: int) -> np.ndarray:
        """The experience -> object table after exploring an unknown object.

        Experiences beyond the library (the unknown object's new ones) get -1.

        Parameters
        ----------
        n_experiences : int
            Experiences in the map now (>= the library's).
        """
        n_lib = len(self.exp_object)
        if isinstance(n_experiences, bool) or not isinstance(n_experiences, (int, np.integer)) or n_experiences < n_lib:
            raise InvalidInputError(f"n_experiences must be an integer >= the library's {n_lib}, got {n_experiences!r}")
        return np.concatenate([self.exp_object, np.full(int(n_experiences) - n_lib, -1, dtype=np.int64)])

    # ----------------------------------------------------------- save / load
    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The library as named arrays: the map's (prefixed ``map_``), ``exp_object``, ``names``, ``history_object``."""
        arrays = self.object_map.to_arrays(prefix + "map_")
        arrays[prefix + "exp_object"] = np.asarray(self.exp_object, dtype=np.int64)
        arrays[prefix + "names"] = np.array(self.names, dtype=np.str_)
        arrays[prefix + "history_object"] = np.asarray(self.history_object, dtype=np.int64)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> "ObjectLibrary":
        """Rebuild a library from :meth:`to_arrays` output.

        Raises
        ------
        CorruptFileError
            A field is missing or disagrees with the map (named in the error): an
            object index outside the names, tables longer than the map's experiences or iterations, repeated
            or non-text names.
        """
        object_map = ObjectMap.from_arrays(arrays, prefix + "map_")

        def need(key: str) -> np.ndarray:
            if prefix + key not in arrays:
                raise CorruptFileError("missing", field=prefix + key)
            return np.asarray(arrays[prefix + key])

        names_arr = need("names")
        if names_arr.ndim != 1 or names_arr.dtype.kind != "U" or len(names_arr) == 0:
            raise CorruptFileError(f"expected a 1-D array of object names, got {names_arr.dtype} {names_arr.shape}",
                                   field=prefix + "names")
        names = tuple(str(n) for n in names_arr.tolist())
        if len(set(names)) != len(names):
            raise CorruptFileError(f"object names must be distinct, got {list(names)}", field=prefix + "names")
        # the map may have grown since the library was appended (the model explores on it): the
        # tables cover its first experiences and iterations
        for key, length in (("exp_object", object_map.n_experiences), ("history_object", object_map.n_recorded)):
            a = need(key)
            if a.ndim != 1 or not 1 <= len(a) <= length or a.dtype.kind != "i" or a.min() < 0 or a.max() >= len(names):
                raise CorruptFileError(f"expected 1 to {length} object indices in [0, {len(names)}), got {a.dtype} "
                                       f"{a.shape}", field=prefix + key)
        return cls(object_map, need("exp_object").astype(np.int64), names, need("history_object").astype(np.int64))

    def save(self, path: str | os.PathLike[str] | BinaryIO) -> None:
        """Write the library to ``path`` (``.npz``, no pickle); :meth:`load` reads it back bit-exactly.

        A file name is written to a temporary name beside it and renamed, so a crash never
        leaves a half-written library under that name; an open binary file is written as is.
        As :func:`numpy.savez`, ``.npz`` is added to a name without it (``save("lib")`` writes
        ``lib.npz``, which ``load("lib")`` reads).
        """
        write_npz(path, self.to_arrays())

    @classmethod
    def load(cls, path: str | os.PathLike[str] | BinaryIO) -> "ObjectLibrary":
        """Read a library written by :meth:`save`.

        Raises
        ------
        CorruptFileError
            The file is unreadable, or a field is missing or malformed.
        """
        arrays = read_npz(path)
        with naming_file(path):  # a fault met while rebuilding names the file
            return cls.from_arrays(arrays)


def append_object_maps(maps: Sequence[ObjectMap], names: Sequence[str], view_offsets: Sequence[int],
                       warn_empty: bool = True) -> ObjectLibrary:
    """Append object maps into one history with no links between objects (Fig 5.16).

    Parameters
    ----------
    maps : sequence of ObjectMap
        One map per object, all with the same configuration (pose-cell shape).
    names : sequence of str
        One distinct name per map.
    view_offsets : sequence of int
        Added to map ``k``'s local-view ids: the number of regions stored before map
        ``k`` in the appended region store (non-decreasing, >= 0).
    warn_empty : bool
        Warn of a map with no experience (Notes); False where the caller says it itself.

    Returns
    -------
    ObjectLibrary

    Notes
    -----
    A map with no experience (an object whose exploration observed no region, e.g. a flat
    object felt by fewer than 3 whiskers at every whisk) is kept under its name with no
    experience: nothing can re-localise into it, so it never gets an impulse (a
    ``UserWarning`` says so, once per process for the same maps).

    Raises
    ------
    InvalidInputError
        No map, lengths that disagree, a map that is not an ObjectMap, every map empty,
        maps with different configurations, repeated names, bad offsets.
    """
    maps, names, offs = list(maps), [str(n) for n in names], list(view_offsets)
    if not maps:
        raise InvalidInputError("append_object_maps needs at least one object map")
    if not (len(maps) == len(names) == len(offs)):
        raise InvalidInputError(f"maps, names and view_offsets differ in length: {len(maps)}, {len(names)}, {len(offs)}")
    if len(set(names)) != len(names):
        raise InvalidInputError(f"object names must be distinct, got {names}")
    for k, (m, o) in enumerate(zip(maps, offs)):
        if not isinstance(m, ObjectMap):
            raise InvalidInputError(f"map {k} is a {type(m).__name__}, not an ObjectMap")
        if isinstance(o, bool) or not isinstance(o, (int, np.integer)) or o < 0:
            raise InvalidInputError(f"view_offsets must be integers >= 0, got {o!r}")
        if m.config != maps[0].config:
            raise InvalidInputError(f"map {k} ({names[k]}) has another configuration than map 0; build all maps with one model configuration")
    if any(b < a for a, b in zip(offs, offs[1:])):
        raise InvalidInputError(f"view_offsets must be non-decreasing, got {offs}")
    empty = [n for m, n in zip(maps, names) if m.n_experiences == 0]
    if len(empty) == len(maps):
        raise InvalidInputError(f"every map is empty ({names}): explore the objects first (no experience to append)")
    if empty and warn_empty:  # a warning, not a log line: shown once per process however often it is built
        warnings.warn(f"{len(empty)} object map(s) without an experience appended (nothing can be recognised as them): "
                      f"{', '.join(empty)}", UserWarning, stacklevel=2)
    parts = [m.to_arrays() for m in maps]
    out = dict(ObjectMap(maps[0].config, maps[0].geometry).to_arrays())  # fresh accumulators and state
    n_exp = [len(p["exp_vt"]) for p in parts]
    start = np.concatenate([[0], np.cumsum(n_exp)[:-1]]).astype(np.int64)
    out["exp_pc"] = np.concatenate([p["exp_pc"] for p in parts])
    out["exp_vt"] = np.concatenate([p["exp_vt"] + o for p, o in zip(parts, offs)]).astype(np.int64)
    out["exp_pose"] = np.concatenate([p["exp_pose"] for p in parts])
    out["link_ends"] = np.concatenate([p["link_ends"] + s for p, s in zip(parts, start)]).astype(np.int64).reshape(-1, 2)
    out["link_data"] = np.concatenate([p["link_data"] for p in parts])
    last = int(sum(n_exp) - 1)
    out["state_i"] = np.array([last, last, 0], dtype=np.int64)
    hist = [np.where(p["history"] >= 0, p["history"] + s, -1) for p, s in zip(parts, start)]
    out["history"] = np.concatenate(hist).astype(np.int64)
    out["contact_points_m"] = np.concatenate([p["contact_points_m"] for p in parts]).reshape(-1, 3)
    out["contact_exp"] = np.concatenate([p["contact_exp"] + s for p, s in zip(parts, start)]).astype(np.int64)
    library = ObjectMap.from_arrays(out)
    exp_object = np.repeat(np.arange(len(maps), dtype=np.int64), n_exp)
    history_object = np.repeat(np.arange(len(maps), dtype=np.int64), [len(h) for h in hist])
    return ObjectLibrary(library, exp_object, tuple(names), history_object)
