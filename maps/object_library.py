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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from maps.object_map import ObjectMap
from whisker_io.errors import InvalidInputError

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


def append_object_maps(maps: Sequence[ObjectMap], names: Sequence[str], view_offsets: Sequence[int]) -> ObjectLibrary:
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

    Returns
    -------
    ObjectLibrary

    Raises
    ------
    InvalidInputError
        No map, lengths that disagree, a map that is not an ObjectMap or is empty,
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
        if m.n_experiences == 0:
            raise InvalidInputError(f"map {k} ({names[k]}) has no experience: explore the object first")
        if isinstance(o, bool) or not isinstance(o, (int, np.integer)) or o < 0:
            raise InvalidInputError(f"view_offsets must be integers >= 0, got {o!r}")
        if m.config != maps[0].config:
            raise InvalidInputError(f"map {k} ({names[k]}) has another configuration than map 0; build all maps with one model configuration")
    if any(b < a for a, b in zip(offs, offs[1:])):
        raise InvalidInputError(f"view_offsets must be non-decreasing, got {offs}")
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
