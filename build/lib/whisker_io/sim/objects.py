"""Procedural test objects of Ch.5-6 and the Ch.3 maze, as trimesh meshes.

The thesis' simulated objects (Fig 5.13 C: Barrel, Blob, Plane, Mug, Box,
Kettle, Skull; Fig 6.5: Box and Box-Stack) were CAD/Gazebo models with an
average bounding box of 20 x 20 x 35 cm. They are not distributed, so each is
rebuilt here procedurally from trimesh primitives (no downloads, no
randomness): same names, same size class, recognisably the same kind of shape.

Conventions: metres; each object stands on the plane ``z = 0``, centred on the
z-axis, height along ``+z``, about 0.20 x 0.20 x 0.35 m. Parts are closed
shells with outward normals; composite objects are the concatenation of
overlapping closed parts (trimesh has no boolean backend in this project), so
the outer surface is correct for ray casting from outside but the mesh is not
a single watertight shell.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import trimesh
from numpy.typing import NDArray
from trimesh.creation import box as _box
from trimesh.creation import cylinder as _cylinder
from trimesh.creation import icosphere as _icosphere
from trimesh.creation import revolve as _revolve
from trimesh.transformations import rotation_matrix, translation_matrix

from whisker_io.errors import InvalidInputError

__all__ = [
    "OBJECT_NAMES",
    "MAZE_SIZE_M",
    "make_object",
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

_SECTIONS = 64  # angular resolution of solids of revolution


def _at(mesh: trimesh.Trimesh, xyz=(0.0, 0.0, 0.0), angle: float = 0.0, axis=(0, 0, 1)) -> trimesh.Trimesh:
    """Rotate ``mesh`` by ``angle`` about ``axis`` (through the origin), then translate."""
    mesh = mesh.copy()
    if angle:
        mesh.apply_transform(rotation_matrix(angle, axis))
    mesh.apply_transform(translation_matrix(xyz))
    return mesh


def _join(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    mesh = trimesh.util.concatenate(parts)
    mesh.fix_normals(multibody=True)
    return mesh


def _revolved(profile_rz: NDArray[np.float64], sections: int = _SECTIONS) -> trimesh.Trimesh:
    """Solid of revolution about z of a closed (r, z) profile running from the axis to the axis."""
    mesh = _revolve(np.asarray(profile_rz, dtype=float), sections=sections)
    mesh.fix_normals()
    return mesh


def _tube(path: NDArray[np.float64], radius: float, sections: int = 16) -> trimesh.Trimesh:
    """A tube of circular section along a 3-D polyline: cylinders between the
    vertices and spheres at the joints (overlapping closed parts)."""
    path = np.asarray(path, dtype=float)
    parts = [
        _cylinder(radius=radius, segment=path[i : i + 2], sections=sections)
        for i in range(len(path) - 1)
    ]
    parts += [_at(_icosphere(subdivisions=1, radius=radius), p) for p in path]
    return _join(parts)


def box() -> trimesh.Trimesh:
    """Box (Fig 6.5 b, Fig 5.13 C): 0.20 x 0.20 x 0.35 m."""
    return _at(_box(extents=(0.20, 0.20, 0.35)), (0, 0, 0.175))


def box_stack() -> trimesh.Trimesh:
    """Box-Stack (Fig 6.5 a): three boxes of decreasing size, each turned relative to
    the one below; same footprint and height as :func:`box`, ambiguous with it by design."""
    parts = [
        _at(_box(extents=(0.20, 0.20, 0.15)), (0, 0, 0.075)),
        _at(_box(extents=(0.15, 0.15, 0.12)), (0, 0, 0.21), angle=np.deg2rad(20.0)),
        _at(_box(extents=(0.10, 0.10, 0.08)), (0, 0, 0.31), angle=np.deg2rad(-15.0)),
    ]
    return _join(parts)


def barrel() -> trimesh.Trimesh:
    """Barrel: a solid of revolution bulging from r = 0.085 m at the ends to 0.10 m mid-height."""
    z = np.linspace(0.0, 0.35, 25)
    r = 0.085 + 0.015 * np.sin(np.pi * z / 0.35)
    profile = np.vstack([[0.0, 0.0], np.column_stack([r, z]), [0.0, 0.35]])
    return _revolved(profile)


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
        _at(capsule(height=0.30, radius=0.025, count=(24, 24)), (0, 0, 0.175)),
        _at(_box(extents=(0.20, 0.012, 0.07)), (0, 0, 0.20)),  # wings
        _at(_box(extents=(0.09, 0.010, 0.04)), (0, 0, 0.045)),  # tail plane
        _at(_box(extents=(0.010, 0.09, 0.05)), (0, 0.03, 0.05)),  # fin
        _at(_cylinder(radius=0.018, height=0.05, sections=24), (0.06, 0.02, 0.20)),  # engine
        _at(_cylinder(radius=0.018, height=0.05, sections=24), (-0.06, 0.02, 0.20)),  # engine
    ]
    return _join(parts)


def mug() -> trimesh.Trimesh:
    """Mug: a hollow cylinder (outer r = 0.085 m, wall 8 mm, 0.35 m tall, open top)
    with a C-shaped handle reaching to x = 0.115 m."""
    ro, ri, h, floor = 0.085, 0.077, 0.35, 0.012
    profile = np.array([[0.0, 0.0], [ro, 0.0], [ro, h], [ri, h], [ri, floor], [0.0, floor]])
    body = _revolved(profile)
    t = np.linspace(-np.pi / 2, np.pi / 2, 17)
    path = np.column_stack([0.080 + 0.05 * np.cos(t), np.zeros_like(t), 0.20 + 0.08 * np.sin(t)])
    handle = _tube(path, 0.010)
    return _join([body, handle])


def kettle() -> trimesh.Trimesh:
    """Kettle (Fig 5.13 B): a bellied body of revolution with a lid knob, an arched
    handle over the top and a tilted spout; about 5k triangles."""
    z = np.linspace(0.0, 0.26, 30)
    r = 0.10 - 0.035 * (z / 0.26) ** 2 + 0.005 * np.sin(np.pi * z / 0.26)
    r[0] = 0.095
    profile = np.vstack(
        [[0.0, 0.0], np.column_stack([r, z]), [0.045, 0.27], [0.02, 0.275], [0.0, 0.275]]
    )
    body = _revolved(profile, sections=48)
    knob = _at(_icosphere(subdivisions=2, radius=0.018), (0, 0, 0.285))
    t = np.linspace(0.0, np.pi, 13)
    arch = np.column_stack([-0.055 * np.cos(t), np.zeros_like(t), 0.25 + 0.08 * np.sin(t)])
    handle = _tube(arch, 0.011, sections=12)
    spout = _cylinder(radius=0.016, height=0.11, sections=24)
    spout = _at(spout, angle=np.deg2rad(50.0), axis=(0, 1, 0))
    spout.apply_translation((0.115, 0.0, 0.17))
    return _join([body, knob, handle, spout])


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
        _at(_box(extents=(0.03, 0.13, 0.025)), (0.075, 0.0, 0.20)),  # brow ridge
        ellipsoid((0.03, 0.025, 0.02), (0.06, 0.06, 0.13)),  # cheekbone
        ellipsoid((0.03, 0.025, 0.02), (0.06, -0.06, 0.13)),  # cheekbone
        ellipsoid((0.06, 0.055, 0.045), (0.04, 0.0, 0.05)),  # jaw
        _at(_cylinder(radius=0.03, height=0.06, sections=24), (-0.01, 0.0, 0.03)),  # neck stump
    ]
    mesh = _join(parts)
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
            f"unknown object {name!r}; choose one of {list(OBJECT_NAMES)}"
        ) from None
    return factory()


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
        parts.append(_at(_box(extents=(ex, ey, h)), ((x0 + x1) / 2, (y0 + y1) / 2, h / 2)))
    for x, y, r, h in _MAZE_POSTS:
        parts.append(_at(_cylinder(radius=r, height=h, sections=24), (x, y, h / 2)))
    if floor:
        parts.append(_at(_box(extents=(W + t, D + t, 0.01)), (W / 2, D / 2, -0.005)))
    return _join(parts)
