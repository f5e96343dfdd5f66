"""Test objects of Ch.5-6 and the Ch.3 maze as trimesh meshes, and the user's own meshes.

The thesis' simulated objects (Fig 5.13 C: Barrel, Blob, Plane, Mug, Box,
Kettle, Skull; Fig 6.5: Box and Box-Stack) were CAD/Gazebo models with an
average bounding box of 20 x 20 x 35 cm. They are not distributed, so each is
rebuilt here procedurally from trimesh primitives (no downloads, no
randomness): same names, same size class, recognisably the same kind of shape
(:func:`make_object`). Procedural shapes beyond these live in
:mod:`whisker_io.sim.shapes`.

Conventions of every object the simulator is given
--------------------------------------------------
* **metres**;
* **z up**: the object's height runs along ``+z``;
* **resting on z = 0**: the lowest vertex has ``z = 0``;
* **centred on x = y = 0**: for the registered objects, the axis of the main
  body (the Mug's handle sticks out to +x); for a loaded mesh, the centre of
  its axis-aligned bounding box.

The registered objects are about 0.20 x 0.20 x 0.35 m. Parts are closed shells
with outward normals; composite objects are the concatenation of overlapping
closed parts (trimesh has no boolean backend in this project), so the outer
surface is correct for ray casting from outside but the mesh is not a single
watertight shell.

A mesh file (OBJ, STL, PLY, GLB/glTF) or a ``trimesh`` mesh is brought to these
conventions by :func:`load_object`, which checks it and records every change it
made in a :class:`LoadedObject`: the rotation that takes the file's up axis to
``+z``, the scale (``scale_to_m`` sets the largest bounding-box extent), and the
translation that rests it on ``z = 0`` centred on the z-axis. Its largest extent
must end up between :data:`MIN_EXTENT_M` and :data:`MAX_EXTENT_M`.
:func:`whisker_io.sim.catalogue.resolve_object` takes either a name (a registered
object or a procedural shape) or a mesh file, so every runner accepts both.
"""
from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import trimesh
from numpy.typing import NDArray
from trimesh.creation import box as _box
from trimesh.creation import cylinder as _cylinder
from trimesh.creation import icosphere as _icosphere
from trimesh.transformations import rotation_matrix

from whisker_io.errors import CorruptFileError, InvalidInputError
from whisker_io.sim.mesh_parts import joined, placed, revolved, tube
from whisker_io.validation import finite_scalar

__all__ = [
    "OBJECT_NAMES",
    "GLTF_SUFFIXES",
    "MAX_SCENE_M",
    "MIN_THICKNESS_M",
    "check_extent",
    "MAZE_SIZE_M",
    "make_object",
    "LoadedObject",
    "load_object",
    "MESH_SUFFIXES",
    "UP_AXES",
    "MIN_EXTENT_M",
    "MAX_EXTENT_M",
    "make_maze",
    "box",
    "box_stack",
    "barrel",
    "blob",
    "plane",
    "mug",
    "kettle",
    "skull",
]

_log = logging.getLogger(__name__)

def box() -> trimesh.Trimesh:
    """Box (Fig 6.5 b, Fig 5.13 C): 0.20 x 0.20 x 0.35 m."""
    return placed(_box(extents=(0.20, 0.20, 0.35)), (0, 0, 0.175))


def box_stack() -> trimesh.Trimesh:
    """Box-Stack (Fig 6.5 a): three boxes of decreasing size, each turned relative to
    the one below; same footprint and height as :func:`box`, ambiguous with it by design."""
    parts = [
        placed(_box(extents=(0.20, 0.20, 0.15)), (0, 0, 0.075)),
        placed(_box(extents=(0.15, 0.15, 0.12)), (0, 0, 0.21), angle=np.deg2rad(20.0)),
        placed(_box(extents=(0.10, 0.10, 0.08)), (0, 0, 0.31), angle=np.deg2rad(-15.0)),
    ]
    return joined(parts)


def barrel() -> trimesh.Trimesh:
    """Barrel: a solid of revolution bulging from r = 0.085 m at the ends to 0.10 m mid-height."""
    z = np.linspace(0.0, 0.35, 25)
    r = 0.085 + 0.015 * np.sin(np.pi * z / 0.35)
    profile = np.vstack([[0.0, 0.0], np.column_stack([r, z]), [0.0, 0.35]])
    return revolved(profile)


def blob() -> trimesh.Trimesh:
    """Blob: an ellipsoid (0.20 x 0.20 x 0.35 m) with smooth, fixed low-order bumps."""
    mesh = _icosphere(subdivisions=4, radius=1.0)
    v = mesh.vertices
    az = np.arctan2(v[:, 1], v[:, 0])
    el = np.arcsin(np.clip(v[:, 2], -1, 1))
    bump = 1.0 + 0.12 * np.sin(3 * az) * np.cos(el) + 0.08 * np.cos(2 * el + az) + 0.06 * np.sin(5 * el)
    v = v * bump[:, None]
    v = v / np.ptp(v, axis=0) * np.array([0.20, 0.20, 0.35])
    v[:, 2] -= v[:, 2].min()
    v[:, :2] -= (v[:, :2].max(axis=0) + v[:, :2].min(axis=0)) / 2
    out = trimesh.Trimesh(v, mesh.faces, process=True)
    out.fix_normals()
    return out


def plane() -> trimesh.Trimesh:
    """Toy aeroplane standing on its tail: fuselage along z (0.35 m), wings spanning
    0.20 m along x, tail plane and a fin along y."""
    from trimesh.creation import capsule

    parts = [
        placed(capsule(height=0.30, radius=0.025, count=(24, 24)), (0, 0, 0.175)),
        placed(_box(extents=(0.20, 0.012, 0.07)), (0, 0, 0.20)),  # wings
        placed(_box(extents=(0.09, 0.010, 0.04)), (0, 0, 0.045)),  # tail plane
        placed(_box(extents=(0.010, 0.09, 0.05)), (0, 0.03, 0.05)),  # fin
        placed(_cylinder(radius=0.018, height=0.05, sections=24), (0.06, 0.02, 0.20)),  # engine
        placed(_cylinder(radius=0.018, height=0.05, sections=24), (-0.06, 0.02, 0.20)),  # engine
    ]
    return joined(parts)


def mug() -> trimesh.Trimesh:
    """Mug: a hollow cylinder (outer r = 0.085 m, wall 8 mm, 0.35 m tall, open top)
    with a C-shaped handle reaching to x = 0.115 m."""
    ro, ri, h, floor = 0.085, 0.077, 0.35, 0.012
    profile = np.array([[0.0, 0.0], [ro, 0.0], [ro, h], [ri, h], [ri, floor], [0.0, floor]])
    body = revolved(profile)
    t = np.linspace(-np.pi / 2, np.pi / 2, 17)
    path = np.column_stack([0.080 + 0.05 * np.cos(t), np.zeros_like(t), 0.20 + 0.08 * np.sin(t)])
    handle = tube(path, 0.010)
    return joined([body, handle])


def kettle() -> trimesh.Trimesh:
    """Kettle (Fig 5.13 B): a bellied body of revolution with a lid knob, an arched
    handle over the top and a tilted spout; about 5k triangles."""
    z = np.linspace(0.0, 0.26, 30)
    r = 0.10 - 0.035 * (z / 0.26) ** 2 + 0.005 * np.sin(np.pi * z / 0.26)
    r[0] = 0.095
    profile = np.vstack(
        [[0.0, 0.0], np.column_stack([r, z]), [0.045, 0.27], [0.02, 0.275], [0.0, 0.275]]
    )
    body = revolved(profile, sections=48)
    knob = placed(_icosphere(subdivisions=2, radius=0.018), (0, 0, 0.285))
    t = np.linspace(0.0, np.pi, 13)
    arch = np.column_stack([-0.055 * np.cos(t), np.zeros_like(t), 0.25 + 0.08 * np.sin(t)])
    handle = tube(arch, 0.011, sections=12)
    spout = _cylinder(radius=0.016, height=0.11, sections=24)
    spout = placed(spout, angle=np.deg2rad(50.0), axis=(0, 1, 0))
    spout.apply_translation((0.115, 0.0, 0.17))
    return joined([body, knob, handle, spout])


def skull() -> trimesh.Trimesh:
    """Skull-like novel shape: a cranium ellipsoid, a narrower face, brow ridge,
    cheekbones and a jaw, standing 0.35 m tall, face toward +x."""

    def ellipsoid(radii, centre, sub=3):
        m = _icosphere(subdivisions=sub, radius=1.0)
        m.apply_scale(radii)
        m.apply_translation(centre)
        return m

    parts = [
        ellipsoid((0.10, 0.09, 0.11), (0.0, 0.0, 0.24), sub=4),  # cranium
        ellipsoid((0.07, 0.065, 0.08), (0.035, 0.0, 0.14)),  # face
        placed(_box(extents=(0.03, 0.13, 0.025)), (0.075, 0.0, 0.20)),  # brow ridge
        ellipsoid((0.03, 0.025, 0.02), (0.06, 0.06, 0.13)),  # cheekbone
        ellipsoid((0.03, 0.025, 0.02), (0.06, -0.06, 0.13)),  # cheekbone
        ellipsoid((0.06, 0.055, 0.045), (0.04, 0.0, 0.05)),  # jaw
        placed(_cylinder(radius=0.03, height=0.06, sections=24), (-0.01, 0.0, 0.03)),  # neck stump
    ]
    mesh = joined(parts)
    mesh.apply_translation((0.0, 0.0, -mesh.bounds[0, 2]))
    return mesh


_REGISTRY: dict[str, Callable[[], trimesh.Trimesh]] = {
    "box": box,
    "box_stack": box_stack,
    "barrel": barrel,
    "blob": blob,
    "plane": plane,
    "mug": mug,
    "kettle": kettle,
    "skull": skull,
}

OBJECT_NAMES: tuple[str, ...] = tuple(_REGISTRY)
"""Names accepted by :func:`make_object`."""


def make_object(name: str) -> trimesh.Trimesh:
    """Build one of the thesis' simulated objects by name.

    Parameters
    ----------
    name : str
        One of :data:`OBJECT_NAMES` (case-insensitive; ``"Box-Stack"`` and
        ``"box stack"`` are accepted for ``"box_stack"``).

    Returns
    -------
    trimesh.Trimesh
        A new mesh (metres, standing on z = 0, centred on the z-axis).
    """
    key = str(name).strip().lower().replace("-", "_").replace(" ", "_")
    try:
        factory = _REGISTRY[key]
    except KeyError:
        raise InvalidInputError(
            f"unknown object {name!r}; choose one of {list(OBJECT_NAMES)} "
            "(resolve_object also takes procedural shapes and mesh files)"
        ) from None
    return factory()


# --------------------------------------------------------------------------- #
# The user's own meshes
# --------------------------------------------------------------------------- #

MIN_EXTENT_M: float = 0.01
"""Smallest accepted largest extent of an object after scaling (1 cm), metres."""

MIN_THICKNESS_M: float = 0.001
"""Smallest accepted extent of a loaded object in its thinnest dimension (1 mm), metres: a flat
sheet has no volume to place a trajectory or a search round, and :func:`load_object` refuses it."""

MAX_EXTENT_M: float = 2.0
"""Largest accepted largest extent of an object after scaling (2 m), metres: the
arms of the thesis reach 0.85 m (UR5) and 1.3 m (UR10, Ch.3) (Sec 2.2.1), so
nothing larger can be explored around."""

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".stl", ".ply", ".glb", ".gltf")
"""File endings :func:`load_object` reads (via trimesh)."""

PLACEMENT_NOTE_M = 1e-3
"""A move onto the table (centred, resting on z = 0) of at least this much along an axis (m) is said in the notes."""

GLTF_SUFFIXES: tuple[str, ...] = (".glb", ".gltf")
"""Mesh files y-up by their specification (glTF 2.0)."""

_MAX_COORDINATE = 1e9  # in any unit: beyond this the file is not a model (its extents would overflow)
_MIN_SIZE = 1e-9  # in any unit: a smaller mesh is a point (scaling it would overflow)

_TURN = np.pi / 2
#: rotation taking each accepted up axis to +z: (angle rad, axis) applied about the origin
_UP_ROTATIONS: dict[str, tuple[float, tuple[int, int, int]]] = {
    "+z": (0.0, (1, 0, 0)),
    "-z": (np.pi, (1, 0, 0)),  # half turn about x: y -> -y, z -> -z
    "+y": (_TURN, (1, 0, 0)),  # quarter turn about x: y -> z, z -> -y (glTF's y-up to z-up)
    "-y": (-_TURN, (1, 0, 0)),  # y -> -z, z -> y
    "+x": (-_TURN, (0, 1, 0)),  # quarter turn about y: x -> z, z -> -x
    "-x": (_TURN, (0, 1, 0)),  # x -> -z, z -> x
}
MAX_SCENE_M: float = 20.0
"""Largest extent of any mesh the simulator whisks (a wall, a maze), metres: larger is a mesh in millimetres."""

UP_AXES: tuple[str, ...] = ("x", "y", "z", "-x", "-y", "-z")
"""Values of ``up_axis`` (``"+x"`` etc. and upper case are accepted too)."""


@dataclass(frozen=True)
class LoadedObject:
    """An object mesh in the simulator's conventions, with a record of what was changed.

    The output mesh is ``x_out = scale_factor * rotation @ x_in + translation_m``
    (:attr:`transform` as a 4 x 4 matrix), followed by the clean-ups listed in
    :attr:`notes`.

    Attributes
    ----------
    mesh : trimesh.Trimesh
        The object: metres, z up, resting on z = 0, centred on x = y = 0 (see the
        module docstring). A new mesh; the caller's input is never modified.
    name : str
        The object's name (the file's stem unless given).
    source : str
        Where it came from: the file path, ``"trimesh object"``, ``"registered object"``
        or ``"procedural shape"``.
    up_axis : str
        The input's up axis, one of ``"+x", "+y", "+z", "-x", "-y", "-z"``.
    rotation : ndarray, shape (3, 3)
        Rotation applied (takes ``up_axis`` to +z).
    scale_factor : float
        Isotropic scale applied (1 when ``scale_to_m`` was not given).
    translation_m : ndarray, shape (3,)
        Translation applied after rotating and scaling, metres.
    source_extents : ndarray, shape (3,)
        Bounding-box extents of the input, in its own units, before any change.
    notes : tuple of str
        One sentence per change or caveat (rotated, scaled, vertices merged,
        zero-area faces removed, normals re-oriented, not watertight ...).
    """

    mesh: trimesh.Trimesh
    name: str
    source: str
    up_axis: str
    rotation: NDArray[np.float64]
    scale_factor: float
    translation_m: NDArray[np.float64]
    source_extents: NDArray[np.float64]
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for field in ("rotation", "translation_m", "source_extents"):
            arr = np.array(getattr(self, field), dtype=np.float64)
            arr.flags.writeable = False
            object.__setattr__(self, field, arr)

    @property
    def transform(self) -> NDArray[np.float64]:
        """The 4 x 4 homogeneous transform from input to output coordinates."""
        out = np.eye(4)
        out[:3, :3] = self.scale_factor * self.rotation
        out[:3, 3] = self.translation_m
        return out

    @property
    def extents_m(self) -> NDArray[np.float64]:
        """Bounding-box extents of :attr:`mesh` (x, y, z), metres, shape (3,)."""
        return np.asarray(self.mesh.extents, dtype=np.float64)


def _up_axis_key(up_axis: object) -> str:
    if isinstance(up_axis, str):
        key = up_axis.strip().lower()
        key = key if key[:1] in "+-" else "+" + key
        if key in _UP_ROTATIONS:
            return key
    raise InvalidInputError(
        f"up_axis must be one of {list(UP_AXES)}, got {up_axis!r}; name the axis that points up in the "
        "file (glTF/GLB files are y-up by their specification, most CAD exports z-up)"
    )


def _scale_target(scale_to_m: object) -> float | None:
    if scale_to_m is None:
        return None
    size = finite_scalar(scale_to_m, "scale_to_m")
    if not MIN_EXTENT_M <= size <= MAX_EXTENT_M:
        raise InvalidInputError(
            f"scale_to_m must be between {MIN_EXTENT_M} and {MAX_EXTENT_M} m (the largest extent the "
            f"object should have), got {size!r}; the thesis objects are about 0.35 m"
        )
    return size


def check_extent(size_m: float, where: str, *, minimum_m: float = MIN_EXTENT_M, maximum_m: float = MAX_EXTENT_M) -> None:
    """Refuse an object whose largest extent ``size_m`` is outside [``minimum_m``, ``maximum_m``] m.

    The simulator works in metres; a mesh in millimetres is 1000 times too large. The
    message says what to pass to :func:`load_object` (and on the command line). The
    defaults are an object's range (:data:`MIN_EXTENT_M`, :data:`MAX_EXTENT_M`); a scene
    (a wall, the Ch.3 maze) is checked with a wider one (:data:`MAX_SCENE_M`).

    Raises
    ------
    InvalidInputError
        The size is not finite or out of range; ``where`` names the mesh.
    """
    if minimum_m <= size_m <= maximum_m:
        return
    if not math.isfinite(size_m):
        raise InvalidInputError(f"{where} has non-finite vertex coordinates (its size is {size_m}); repair or re-export it")
    # too large: a file in millimetres or centimetres (both common); suggest each unit that gives an object of a size
    # the whiskers can explore (5 cm - maximum_m), never a value scale_to_m would refuse
    units = [(f"{size_m / div:.3g}", unit) for div, unit in ((1000, "millimetres"), (100, "centimetres"))
             if size_m > maximum_m and 0.05 <= size_m / div <= maximum_m]
    if units:
        hint = "; ".join(f"if it is in {unit} it is {m} m across: pass scale_to_m={m} (--scale-to-m {m} on the "
                         "command line)" for m, unit in units)
        hint += "" if [m for m, _ in units] == ["0.35"] else ", or 0.35 for the thesis objects' size"
    else:
        hint = ("pass scale_to_m=0.35 (--scale-to-m 0.35 on the command line: the thesis objects' size) or its "
                "real size in metres")
    raise InvalidInputError(
        f"{where} is {size_m:.4g} m across (largest extent); it must be {minimum_m:g}-{maximum_m:g} m: {hint}"
    )


def _scene_meshes(scene: trimesh.Scene) -> list[trimesh.Trimesh]:
    """Every triangle mesh of a scene, placed by the scene graph (copies)."""
    parts = []
    for node in scene.graph.nodes_geometry:
        matrix, geometry_name = scene.graph[node]
        geometry = scene.geometry[geometry_name]
        if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces):
            parts.append(geometry.copy().apply_transform(matrix))
    return parts


def _read_mesh_file(path: Path) -> list[trimesh.Trimesh]:
    """Every triangle mesh of a file, placed by its scene graph."""
    if not path.is_file():
        raise InvalidInputError(f"no mesh file at {path}; check the path (a directory or a missing file)")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise InvalidInputError(
            f"{path}: cannot read {path.suffix or 'files without an ending'}; give a mesh file ending in "
            f"{', '.join(MESH_SUFFIXES)} (convert others with a mesh tool first)"
        )
    try:
        return _scene_meshes(trimesh.load_scene(path, process=False))
    except FileNotFoundError as exc:  # a .gltf (or .obj) names a buffer or texture file that is not beside it
        raise CorruptFileError(
            f"{path.name} needs {Path(str(exc.filename or exc)).name}, which is not beside it; copy the files it names "
            "into its folder, or export a single-file .glb", path=path
        ) from None
    except Exception as exc:  # trimesh's parsers raise every kind of error on a malformed file
        raise CorruptFileError(
            f"not a readable {path.suffix.lower()[1:].upper()} mesh ({type(exc).__name__}: {exc}); "
            "re-export it from the modelling tool", path=path
        ) from None


def _as_surface(source: object) -> tuple[trimesh.Trimesh, str, str, list[str]]:
    """(mesh copy, source text, default name, notes) of a path, a Trimesh or a Scene."""
    if isinstance(source, trimesh.Trimesh):
        return trimesh.Trimesh(source.vertices.copy(), source.faces.copy(), process=False), "trimesh object", "mesh", []
    if isinstance(source, trimesh.Scene):
        parts, where, stem = _scene_meshes(source), "trimesh scene", "mesh"
    elif isinstance(source, (str, os.PathLike)):
        path = Path(source)
        parts, where, stem = _read_mesh_file(path), str(path), path.stem
    else:
        raise InvalidInputError(f"expected a mesh file path or a trimesh.Trimesh, got {type(source).__name__}")
    if not parts:
        kind = f", or its content is not {path.suffix[1:].upper()} (check its format and its file ending)" \
            if isinstance(source, (str, os.PathLike)) else ""
        raise InvalidInputError(f"{where} holds no triangles: it is empty or holds points or lines only{kind}; "
                                "give a surface mesh")
    if len(parts) == 1:
        return parts[0], where, stem, []
    return trimesh.util.concatenate(parts), where, stem, [f"concatenated the {len(parts)} meshes of the scene"]


def _checked_surface(mesh: trimesh.Trimesh, where: str) -> trimesh.Trimesh:
    """The mesh's vertices and faces checked (finite, valid indices, some area) as a new mesh."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces)
    if len(vertices) == 0 or len(faces) == 0:
        raise InvalidInputError(f"{where} has no faces; give a surface mesh (triangles), not points or lines")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise InvalidInputError(
            f"{where} has {int(bad.sum())} vert{'ex' if bad.sum() == 1 else 'ices'} with NaN/inf coordinates (first: index "
            f"{int(np.flatnonzero(bad)[0])}); repair or re-export the mesh"
        )
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise InvalidInputError(f"{where} has faces that name no vertex; repair or re-export the mesh")
    reach = float(np.abs(vertices).max())
    if reach > _MAX_COORDINATE:
        raise InvalidInputError(
            f"{where} has coordinates up to {reach:.3g}, in no sensible unit; rescale or re-export the mesh"
        )
    if np.ptp(vertices, axis=0).max() < _MIN_SIZE:
        raise InvalidInputError(f"{where} is a single point (all vertices within {_MIN_SIZE:g}); give a mesh with a surface")
    return trimesh.Trimesh(vertices, faces, process=False)


def _bodies(mesh: trimesh.Trimesh, most: int = 200) -> tuple[int, float]:
    """(bodies, gap): the mesh's bodies (sets of faces joined by edges; a vertex no face uses is none) and the widest
    gap that splits them into two groups, metres (the longest edge of the minimum spanning tree over the distances
    between the bodies' bounding boxes: two objects of several parts each, far apart, are one such gap); 0 for one
    body or more than ``most``."""
    from scipy.sparse.csgraph import minimum_spanning_tree

    labels = trimesh.graph.connected_component_labels(mesh.edges_unique, node_count=len(mesh.vertices))
    used = np.unique(mesh.faces)
    _, body = np.unique(labels[used], return_inverse=True)
    n = int(body.max()) + 1
    if n < 2 or n > most:
        return n, 0.0
    lo, hi = np.full((n, 3), np.inf), np.full((n, 3), -np.inf)
    np.minimum.at(lo, body, mesh.vertices[used])
    np.maximum.at(hi, body, mesh.vertices[used])
    # distance between boxes i and j: the norm of the per-axis separation (0 where they overlap along an axis)
    sep = np.maximum(0.0, np.maximum(lo[:, None] - hi[None], lo[None] - hi[:, None]))
    dist = np.linalg.norm(sep, axis=2) + 1e-12  # csgraph reads 0 as "no edge": touching boxes are a tiny one
    np.fill_diagonal(dist, 0.0)
    return n, max(float(minimum_spanning_tree(dist).max()) - 1e-12, 0.0)


def load_object(
    path_or_trimesh: str | os.PathLike[str] | trimesh.Trimesh | trimesh.Scene,
    *,
    scale_to_m: float | None = None,
    up_axis: str | None = None,
    name: str | None = None,
) -> LoadedObject:
    """Read, check and bring a mesh to the simulator's conventions.

    Conventions (module docstring): metres, z up, resting on ``z = 0``, the
    bounding box centred on ``x = y = 0``. Steps, each recorded in the result:
    rotate ``up_axis`` to ``+z``; scale so the largest bounding-box extent is
    ``scale_to_m`` (if given); translate. When the mesh as given is not
    watertight (an STL file is a soup of separate triangles) its coincident
    vertices are merged; zero-area faces are removed; a watertight mesh gets
    outward normals.

    Parameters
    ----------
    path_or_trimesh : path-like, trimesh.Trimesh or trimesh.Scene
        An OBJ, STL, PLY or GLB/glTF file (every triangle mesh of a scene is placed
        by the scene graph and concatenated), or a mesh in memory (copied, never
        modified).
    scale_to_m : float, optional
        Largest bounding-box extent wanted, metres, between :data:`MIN_EXTENT_M`
        and :data:`MAX_EXTENT_M` (0.35 matches the thesis objects). ``None``: the
        file is already in metres.
    up_axis : {"z", "y", "x", "-z", "-y", "-x"}, optional
        The input's axis that points up (default ``"z"``). glTF/GLB files are y-up by
        their specification (trimesh keeps the file's axes): pass ``"y"`` for them
        unless they were written z-up. A glTF/GLB file read without ``up_axis`` is taken
        as z-up with a warning and a note in the record.
    name : str, optional
        The object's name; default the file's stem (``"mesh"`` for a mesh in memory).

    Returns
    -------
    LoadedObject
        The mesh and the record of what was changed.

    Raises
    ------
    InvalidInputError
        No such file, an unsupported ending, no triangles, NaN/inf vertices, no face
        with area, a flat sheet (under :data:`MIN_THICKNESS_M` thick), a bad ``up_axis``, ``name`` or
        ``scale_to_m``, or a largest extent
        (after scaling) outside [:data:`MIN_EXTENT_M`, :data:`MAX_EXTENT_M`]; the
        message says what to pass or repair.
    CorruptFileError
        The file cannot be parsed as its ending says.

    Examples
    --------
    >>> import trimesh
    >>> brick = trimesh.creation.box(extents=(100.0, 350.0, 200.0))  # millimetres, y up
    >>> obj = load_object(brick, scale_to_m=0.35, up_axis="y", name="brick")
    >>> obj.extents_m.round(3).tolist(), float(obj.mesh.bounds[0, 2])
    ([0.1, 0.2, 0.35], 0.0)
    """
    key = _up_axis_key("z" if up_axis is None else up_axis)
    target = _scale_target(scale_to_m)
    if name is not None and not (isinstance(name, str) and name.strip()):
        raise InvalidInputError(f"name must be a non-empty string, got {name!r}")
    raw, source, default_name, notes = _as_surface(path_or_trimesh)
    mesh = _checked_surface(raw, source)
    gltf = up_axis is None and isinstance(path_or_trimesh, (str, os.PathLike)) \
        and Path(path_or_trimesh).suffix.lower() in GLTF_SUFFIXES
    if gltf:
        warning = ("taken as z-up (no up axis given), although glTF/GLB files are y-up by their specification: "
                   "if the object lies on its side, pass up_axis='y' (--up-axis y)")
        notes.append(warning)
        _log.warning("%s: %s", source, warning)
    # what was assumed, not checked, is said, so that a y-up file or one in millimetres is noticed (a glTF file's
    # up axis has the warning above)
    assumed = [(what, option) for what, unsaid, option in (("in metres", scale_to_m is None, "scale_to_m (--scale-to-m)"),
                                                           ("z up", up_axis is None and not gltf, "up_axis (--up-axis)"))
               if unsaid]
    if assumed:
        notes.append(f"assumed {' and '.join(w for w, _ in assumed)} (not checked; otherwise give "
                     f"{' / '.join(o for _, o in assumed)})")
    source_extents = np.asarray(mesh.extents, dtype=np.float64)
    if not mesh.is_watertight:
        n_before = len(mesh.vertices)
        mesh.merge_vertices()
        if len(mesh.vertices) < n_before:
            notes.append(f"merged {n_before - len(mesh.vertices)} coincident vertices (the file stores its triangles "
                         "separately, as STL does, or repeats vertices)")

    angle, axis = _UP_ROTATIONS[key]
    rotation = rotation_matrix(angle, axis)[:3, :3] if angle else np.eye(3)
    rotation = np.round(rotation, 15)  # exact quarter turns: no 6e-17 residues
    if angle:
        notes.append(f"rotated {np.rad2deg(angle):+.0f} deg about {'xyz'[int(np.argmax(axis))]} to take {key} up to +z")
    largest = float(source_extents.max())
    scale = 1.0 if target is None else target / largest
    if target is not None:
        notes.append(f"scaled by {scale:.6g} (largest extent {largest:.6g} -> {target:.6g} m)")
    check_extent(largest * scale, source)
    linear = np.eye(4)
    linear[:3, :3] = scale * rotation
    mesh.apply_transform(linear)

    keep = mesh.nondegenerate_faces()
    if not keep.any():
        raise InvalidInputError(f"{source} has no face with non-zero area; give a mesh with a surface")
    if not keep.all():
        mesh.update_faces(keep)
        mesh.remove_unreferenced_vertices()
        notes.append(f"removed {int((~keep).sum())} zero-area faces")
    unique = mesh.unique_faces()  # the same triangle twice (an exporter's repeat): an edge shared by 4 faces, not watertight
    if not unique.all():
        mesh.update_faces(unique)
        notes.append(f"removed {int((~unique).sum())} duplicate faces")
    if mesh.is_watertight:
        faces_before = mesh.faces.copy()
        mesh.fix_normals(multibody=True)
        flipped = int((faces_before != mesh.faces).any(axis=1).sum())
        if flipped:
            notes.append(f"turned the normals of {flipped} faces outward")
    else:
        notes.append("not watertight (open or non-manifold edges): ray casting from outside works, volume is undefined")

    bodies, gap = _bodies(mesh)
    if bodies > 1:  # a scene of several parts, or separate objects: the simulator whisks them as one object
        far = gap > 0.5 * float(mesh.extents.max())
        notes.append(f"{bodies} separate bodies" + (f" up to {gap:.3g} m apart" if far else "") + ", whisked as one "
                     "object" + (": the trajectory runs around all of them and may touch none; give one object per file"
                                 if far else ""))
    lo, hi = mesh.bounds
    centred = mesh.vertices - mesh.vertices.mean(axis=0)
    thickness = float(np.ptp(centred @ np.linalg.svd(centred, full_matrices=False)[2][-1]))  # along its thinnest axis
    if thickness < MIN_THICKNESS_M:  # a tilted sheet too, whatever its bounding box
        reach = float(np.abs(mesh.vertices).max())
        far = (f"; its coordinates reach {reach:.3g}, far from its size: a file of single-precision coordinates "
               "(PLY, STL) loses the shape there - re-export it centred on the origin"
               if reach > 1e4 * max(float((hi - lo).max()), 1e-12) else "")
        raise InvalidInputError(f"{source} is flat: {thickness:.3g} m thick in its thinnest dimension "
                                f"(extents {np.round(hi - lo, 4).tolist()} m); the whisker simulation needs a solid at "
                                f"least {MIN_THICKNESS_M * 1000:g} mm thick - give the sheet a thickness (extrude it){far}")
    translation = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    mesh.vertices = mesh.vertices + translation  # a plain sum: the lowest vertex lands exactly on z = 0
    if np.abs(translation).max() >= PLACEMENT_NOTE_M:  # where the file's frame lies against the object's, in one line
        said = [0.0 if abs(v) < PLACEMENT_NOTE_M / 10 else float(v) for v in translation]  # no 1e-17 or -0
        notes.append(f"moved by ({', '.join(f'{v:.4g}' for v in said)}) m to stand centred on z = 0")
    result = LoadedObject(
        mesh=mesh,
        name=default_name if name is None else name.strip(),
        source=source,
        up_axis=key,
        rotation=rotation,
        scale_factor=scale,
        translation_m=translation,
        source_extents=source_extents,
        notes=tuple(notes),
    )
    _log.info("loaded object %r from %s: %s", result.name, source, "; ".join(notes) or "in the conventions as given")
    return result


MAZE_SIZE_M: tuple[float, float] = (1.35, 1.0)
"""Footprint of the Ch.3 maze, x by y, metres (Sec 3.1)."""

# Ch.3 maze layout (Sec 3.1, Fig 3.1/3.3): the thesis shows a photograph, not a
# plan, so this is a fixed layout in its spirit: a walled 1.35 x 1 m arena with
# plastic walls and posts of varied height (5-25 cm) spread over the floor.
# walls: (x0, y0, x1, y1, height); posts: (x, y, radius, height)
_MAZE_WALLS = (
    (0.30, 0.00, 0.30, 0.35, 0.12),
    (0.60, 0.25, 0.95, 0.25, 0.20),
    (1.05, 0.55, 1.35, 0.55, 0.08),
    (0.20, 0.70, 0.55, 0.70, 0.15),
    (0.80, 0.60, 0.80, 1.00, 0.25),
)
_MAZE_POSTS = (
    (0.15, 0.45, 0.020, 0.10),
    (0.50, 0.45, 0.025, 0.22),
    (0.70, 0.80, 0.015, 0.06),
    (1.10, 0.25, 0.030, 0.18),
    (1.20, 0.85, 0.020, 0.14),
    (0.95, 0.45, 0.020, 0.09),
)


def make_maze(wall_thickness_m: float = 0.01, border_height_m: float = 0.15, floor: bool = False) -> trimesh.Trimesh:
    """The Ch.3 maze as one mesh: border walls, inner walls and posts of varied height.

    Parameters
    ----------
    wall_thickness_m : float
        Thickness of every wall, metres. Default 0.01.
    border_height_m : float
        Height of the four border walls, metres. Default 0.15.
    floor : bool
        Add a 1 cm floor slab below ``z = 0``. Default False: in Sec 3.2 the array
        moves 77 mm above the floor precisely so that only walls are touched.

    Returns
    -------
    trimesh.Trimesh
        Floor corner at the origin, x in [0, 1.35], y in [0, 1.0], z up.
    """
    t = float(wall_thickness_m)
    if not (t > 0 and border_height_m > 0):
        raise InvalidInputError("wall_thickness_m and border_height_m must be positive")
    W, D = MAZE_SIZE_M
    walls = [
        (0.0, 0.0, W, 0.0, border_height_m),
        (0.0, D, W, D, border_height_m),
        (0.0, 0.0, 0.0, D, border_height_m),
        (W, 0.0, W, D, border_height_m),
        *_MAZE_WALLS,
    ]
    parts = []
    for x0, y0, x1, y1, h in walls:
        ex = abs(x1 - x0) + t
        ey = abs(y1 - y0) + t
        parts.append(placed(_box(extents=(ex, ey, h)), ((x0 + x1) / 2, (y0 + y1) / 2, h / 2)))
    for x, y, r, h in _MAZE_POSTS:
        parts.append(placed(_cylinder(radius=r, height=h, sections=24), (x, y, h / 2)))
    if floor:
        parts.append(placed(_box(extents=(W + t, D + t, 0.01)), (W / 2, D / 2, -0.005)))
    return joined(parts)
