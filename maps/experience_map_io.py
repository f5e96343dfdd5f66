"""The experience map's file format and its networkx export.

:class:`maps.experience_map.ExperienceMap` keeps the graph, the decision rule and the
relaxation; this module holds how a map is written and read and how it is exported:

* :func:`write_map_arrays` / :func:`read_map_header` + :func:`read_map_body`: the
  ``.npz`` fields below, validated field by field on reading (a bad field raises
  :class:`~whisker_io.errors.CorruptFileError` naming it). ``ExperienceMap.to_arrays``,
  ``from_arrays``, ``save`` and ``load`` delegate here.
* :func:`map_to_networkx`: a snapshot :class:`networkx.DiGraph` with the current poses,
  built from the map's public views (``ExperienceMap.to_networkx`` delegates here).

Saved file format (``.npz``, no pickle)
---------------------------------------
``format`` int64 (:data:`FORMAT_VERSION`); ``config`` JSON of
:class:`~maps.experience_map.MapConfig` plus the geometry's name and parameters;
``exp_pc`` float64 (n, ndim); ``exp_vt`` int64 (n,); ``exp_pose`` float64 (n, pose
width); ``link_ends`` int64 (m, 2); ``link_data`` float64 (m, link width + 1: the
geometry columns, then dt s); ``state_f`` float64 = the accumulator, the accumulated
time (s) and the view offset (cells); ``state_i`` int64 (3,) = current id, previous id,
relaxation cursor; ``link_traversals`` int64 (m,), only in maps with
``link_update="average"``: the traversals averaged into each link. The ``config`` JSON
omits ``link_update`` when it is the default ``"first"``, so a default map's file is the
same as before the option existed, and files without it load as ``"first"``. Floats are raw IEEE-754 doubles: a round trip is bit identical and a
resumed run equals an uninterrupted one. Every name may carry a prefix (``em_`` inside a
saved SLAM model).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from typing import Any, Callable, Mapping, Union

import numpy as np

from maps.se2 import SE2Geometry
from maps.se3 import SE3Geometry
from whisker_io.errors import ConfigError, CorruptFileError

__all__ = ["FORMAT_VERSION", "MapArrays", "write_map_arrays", "read_map_header", "read_map_body", "map_to_networkx"]

#: Version of the saved map format (the ``format`` field).
FORMAT_VERSION = 2

Geometry = Union[SE2Geometry, SE3Geometry]
#: Geometry name (the ``config`` JSON's ``geometry``) -> class.
GEOMETRIES: dict[str, type] = {"se2": SE2Geometry, "se3": SE3Geometry}


@dataclass(frozen=True)
class MapArrays:
    """A map's saved content: its configuration, geometry and the arrays of the file format.

    The arrays hold exactly the live experiences (n rows) and links (m rows); see the
    module docstring for their shapes and units.
    """

    config: Any
    geometry: Geometry
    exp_pc: np.ndarray
    exp_vt: np.ndarray
    exp_pose: np.ndarray
    link_ends: np.ndarray
    link_data: np.ndarray
    state_f: np.ndarray
    state_i: np.ndarray
    link_traversals: np.ndarray | None = None


def write_map_arrays(saved: MapArrays, prefix: str = "") -> dict[str, np.ndarray]:
    """The ``.npz`` fields of a map (module docstring), each name prefixed with ``prefix``."""
    geometry = saved.geometry
    map_fields = asdict(saved.config)
    if map_fields.get("link_update") == "first":  # the default: files as before the option existed
        del map_fields["link_update"]
    config = {"map": map_fields, "geometry": geometry.name, "geometry_params": geometry.params()}
    arrays = {
        "format": np.int64(FORMAT_VERSION),
        "config": np.array(json.dumps(config)),
        "exp_pc": saved.exp_pc,
        "exp_vt": saved.exp_vt,
        "exp_pose": saved.exp_pose,
        "link_ends": saved.link_ends,
        "link_data": saved.link_data,
        "state_f": saved.state_f,
        "state_i": saved.state_i,
    }
    if saved.link_traversals is not None:
        arrays["link_traversals"] = saved.link_traversals
    return {prefix + k: np.asarray(v) for k, v in arrays.items()}


def _field(arrays: Mapping[str, np.ndarray], prefix: str, name: str, kind: str, shape: tuple[int | None, ...]) -> np.ndarray:
    key = prefix + name
    if key not in arrays:
        raise CorruptFileError("missing", field=key)
    try:
        arr = np.asarray(arrays[key])
    except Exception as exc:  # zip/CRC/header errors of a damaged member
        raise CorruptFileError(f"unreadable ({exc})", field=key) from exc
    if arr.dtype.kind != kind:
        raise CorruptFileError(f"dtype {arr.dtype} where kind {kind!r} is required", field=key)
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise CorruptFileError(f"shape {arr.shape} where {shape} is required (None = any)", field=key)
    if kind == "f" and not np.all(np.isfinite(arr)):
        raise CorruptFileError("holds NaN or infinite values", field=key)
    return arr


def read_map_header(arrays: Mapping[str, np.ndarray], prefix: str, config_type: Callable[..., Any]) -> tuple[Any, Geometry]:
    """The map's configuration and geometry from the ``format`` and ``config`` fields.

    Parameters
    ----------
    arrays : mapping of str to ndarray
        The saved fields (e.g. an open ``.npz`` archive).
    prefix : str
        Prefix of the field names.
    config_type : callable
        Builds the configuration from the JSON's ``map`` entries
        (:class:`~maps.experience_map.MapConfig`).

    Raises
    ------
    CorruptFileError
        Another format version, or a configuration that does not parse or validate.
    """
    version = int(_field(arrays, prefix, "format", "i", ()))
    if version != FORMAT_VERSION:
        raise CorruptFileError(f"version {version}, this library reads version {FORMAT_VERSION}", field=prefix + "format")
    try:
        spec = json.loads(str(_field(arrays, prefix, "config", "U", ())))
        mc = dict(spec["map"])
        for k in ("pc_shape", "offset_axes"):
            mc[k] = tuple(mc[k])
        config = config_type(**mc)
        geometry = GEOMETRIES[spec["geometry"]](**spec["geometry_params"])
    except (json.JSONDecodeError, TypeError, KeyError, ValueError, ConfigError) as exc:
        raise CorruptFileError(f"not a valid map configuration JSON ({exc})", field=prefix + "config") from exc
    return config, geometry


def read_map_body(arrays: Mapping[str, np.ndarray], prefix: str, config: Any, geometry: Geometry) -> MapArrays:
    """The map's arrays, each checked against the configuration and geometry read by :func:`read_map_header`.

    Raises
    ------
    CorruptFileError
        A field is missing or has the wrong type, shape or value (named in the error): a
        non-finite float, an invalid pose, a negative view id, a link end or current id
        outside the experiences, a negative relaxation cursor, a duplicate link.
    """
    nd, g = len(config.pc_shape), geometry
    exp_pc = _field(arrays, prefix, "exp_pc", "f", (None, nd))
    n = exp_pc.shape[0]
    exp_vt = _field(arrays, prefix, "exp_vt", "i", (n,))
    exp_pose = _field(arrays, prefix, "exp_pose", "f", (n, g.pose_width))
    link_ends = _field(arrays, prefix, "link_ends", "i", (None, 2))
    m = link_ends.shape[0]
    link_data = _field(arrays, prefix, "link_data", "f", (m, g.link_width + 1))
    state_f = _field(arrays, prefix, "state_f", "f", (g.accum_width + 1 + nd,))
    state_i = _field(arrays, prefix, "state_i", "i", (3,))
    traversals = None
    if getattr(config, "link_update", "first") == "average":
        traversals = _field(arrays, prefix, "link_traversals", "i", (m,))
        if np.any(traversals < 1):
            raise CorruptFileError("a link with fewer than 1 traversal", field=prefix + "link_traversals")
    problem = g.check_poses(exp_pose)
    if problem:
        raise CorruptFileError(problem, field=prefix + "exp_pose")
    if np.any(exp_vt < 0):
        raise CorruptFileError("negative view id", field=prefix + "exp_vt")
    if m and (link_ends.min() < 0 or link_ends.max() >= n):
        raise CorruptFileError(f"link end outside the {n} experiences", field=prefix + "link_ends")
    if n and not (0 <= state_i[0] < n and 0 <= state_i[1] < n):
        raise CorruptFileError(f"current/previous id {state_i[:2].tolist()} outside the {n} experiences", field=prefix + "state_i")
    if state_i[2] < 0:
        raise CorruptFileError("negative relaxation cursor", field=prefix + "state_i")
    out: dict[int, set[int]] = {}
    for k, (f, t) in enumerate(link_ends.tolist()):
        if t in out.get(f, ()) or f in out.get(t, ()):
            raise CorruptFileError(f"duplicate link {f}->{t} at row {k}", field=prefix + "link_ends")
        out.setdefault(f, set()).add(t)
    return MapArrays(config, geometry, exp_pc, exp_vt, exp_pose, link_ends, link_data, state_f, state_i, traversals)


def map_to_networkx(em: Any) -> Any:
    """A snapshot :class:`networkx.DiGraph` of an experience map with its current map poses.

    Nodes: ``view_id``, ``pc_cells`` and the geometry's pose fields (SE(2): ``x_m``,
    ``y_m``, ``th_rad``); edges (from -> to, one per link): ``link_id``, the geometry's
    link fields (SE(2): ``d_m``, ``heading_rad``, ``facing_rad``) and ``dt_s``. Graph
    attribute ``current_id`` (-1 for an empty map).

    Parameters
    ----------
    em : ExperienceMap
        Read through its public views (``poses``, ``pc_coords``, ``view_ids``, ``links``).
    """
    import networkx as nx

    g = nx.DiGraph(current_id=int(em.current_id) if em.n_experiences else -1)
    geo = em.geometry
    pose, pc, vt = em.poses, em.pc_coords, em.view_ids
    ends, links = em.links
    for i in range(em.n_experiences):
        attrs = dict(zip(geo.pose_fields, (float(v) for v in pose[i])))
        g.add_node(i, view_id=int(vt[i]), pc_cells=tuple(float(v) for v in pc[i]), **attrs)
    for k in range(em.n_links):
        attrs = dict(zip(geo.link_fields + ("dt_s",), (float(v) for v in links[k])))
        g.add_edge(int(ends[k, 0]), int(ends[k, 1]), link_id=k, **attrs)
    return g
