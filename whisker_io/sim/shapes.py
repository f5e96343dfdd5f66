"""Procedural shapes that do not fill their bounding box, and the object libraries of the recognition study.

The thesis' simulated objects (:mod:`whisker_io.sim.objects`, Fig 5.13 C) are
mostly extruded or box-like. These families add freeform, hollow and handled
shapes, all generated here from trimesh primitives and a seed (no downloads):

* ``superquadric`` - superellipsoids with varied exponents (0.7-2.4: from
  rounded boxes to pinched stars), tapered and twisted along z;
* ``star_blob`` - noisy star-convex blobs: a sphere whose radius is modulated
  by random smooth bumps;
* ``torus_flat`` / ``torus_upright`` - tori (elliptic in plan) lying flat or
  standing on their rim;
* ``bowl`` and ``vase`` - hollow solids of revolution, open at the top;
* ``jug`` - a bellied hollow body with a C-shaped handle;
* ``duck`` and ``bear`` - freeforms of joined ellipsoids;
* ``bent_tube`` - a tube along a helical arc of 150-320 deg, turned at random;
* ``stool`` - a seat on three or four splayed legs.

The families ``mushroom``, ``bucket``, ``knot`` and ``snowman`` never enter a
library: they are the novel objects of the study (:func:`novel_names`).

Names
-----
A shape is named by its family alone (``"duck"``: the canonical shape, every
parameter at the middle of its range), or by family and variant:
``"duck-v7"`` (library stream) or ``"duck-h7"`` (held-out stream, used only for
novel objects). A variant's parameters are drawn from
``numpy.random.default_rng([crc32(family), stream, variant])``, so a name
always builds the same mesh on every machine, and a held-out variant is never a
library variant.

Conventions
-----------
Every shape is scaled so that its largest bounding-box extent is
:data:`SHAPE_SIZE_M` (0.35 m, the height of the thesis objects), rests on
``z = 0`` and is centred on ``x = y = 0`` (the conventions of
:func:`whisker_io.sim.objects.load_object`). Every shape is watertight in
trimesh's sense: a closed shell, or the concatenation of overlapping closed
parts (no boolean union is available), whose outer surface is right for ray
casting and whose volume counts the overlaps twice.
"""

from __future__ import annotations

import re
import zlib
from collections.abc import Callable, Sequence

import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation
from trimesh.creation import cylinder as _cylinder
from trimesh.creation import icosphere as _icosphere
from trimesh.creation import torus as _torus_mesh

from whisker_io.errors import InvalidInputError
from whisker_io.sim.mesh_parts import joined, revolved, tube
from whisker_io.sim.objects import OBJECT_NAMES, load_object, make_object
from whisker_io.validation import whole_number

__all__ = [
    "SHAPE_SIZE_M",
    "SHAPE_FAMILIES",
    "LIBRARY_FAMILIES",
    "NOVEL_FAMILIES",
    "CORE_SHAPES",
    "is_shape_name",
    "make_shape",
    "library_names",
    "object_library",
    "novel_names",
    "novel_objects",
]

SHAPE_SIZE_M: float = 0.35
"""Largest bounding-box extent of every procedural shape, metres (the thesis objects' height)."""

_MAX_VARIANTS = 1000  # variants per family and seed: variant = 1000 * seed + j


class _Draw:
    """The parameters of one shape: uniform draws from a seeded generator, or, for the
    canonical shape (no generator), the middle of each range (a spread over the range
    for arrays, so that bumps and legs differ)."""

    def __init__(self, rng: np.random.Generator | None) -> None:
        self._rng = rng

    @property
    def canonical(self) -> bool:
        """True for the canonical shape (no generator)."""
        return self._rng is None

    def __call__(self, lo: float, hi: float, size: int | None = None):
        if self._rng is not None:
            return self._rng.uniform(lo, hi, size)
        return (lo + hi) / 2 if size is None else np.linspace(lo, hi, size)

    def directions(self, k: int) -> NDArray[np.float64]:
        """``k`` unit vectors: random, or a Fibonacci lattice for the canonical shape."""
        if self._rng is not None:
            v = self._rng.normal(size=(k, 3))
            return v / np.linalg.norm(v, axis=1, keepdims=True)
        i = np.arange(k) + 0.5
        z = 1 - 2 * i / k
        az = np.pi * (1 + 5**0.5) * i
        return np.column_stack([np.sqrt(1 - z**2) * np.cos(az), np.sqrt(1 - z**2) * np.sin(az), z])

    def rotation(self, max_angle: float) -> NDArray[np.float64]:
        """A rotation matrix of at most ``max_angle`` rad about a random axis (identity when canonical)."""
        if self._rng is None:
            return np.eye(3)
        axis = self.directions(1)[0]
        return Rotation.from_rotvec(axis * self._rng.uniform(0.0, max_angle)).as_matrix()


def _ellipsoid(radii, centre, rotation: NDArray[np.float64] | None = None, subdivisions: int = 3) -> trimesh.Trimesh:
    """A closed ellipsoid of semi-axes ``radii``, turned by ``rotation`` and centred on ``centre``."""
    mesh = _icosphere(subdivisions=subdivisions, radius=1.0)
    v = mesh.vertices * np.asarray(radii, dtype=float)
    if rotation is not None:
        v = v @ np.asarray(rotation).T
    return trimesh.Trimesh(v + np.asarray(centre, dtype=float), mesh.faces, process=False)


def _pitch(angle_rad: float) -> NDArray[np.float64]:
    """Rotation about y by ``angle_rad`` (positive tips +x down)."""
    return Rotation.from_euler("y", angle_rad).as_matrix()


def _radial_surface(radius_of: Callable[[NDArray[np.float64]], NDArray[np.float64]], subdivisions: int = 4) -> trimesh.Trimesh:
    """A star-shaped closed surface: each unit direction ``n`` of an icosphere moved to ``radius_of(n)``,
    a vector function of shape (k, 3) -> (k, 3) that keeps the topology (watertight, no fold)."""
    sphere = _icosphere(subdivisions=subdivisions, radius=1.0)
    return trimesh.Trimesh(radius_of(sphere.vertices), sphere.faces, process=False)


def _hollow(z: NDArray[np.float64], r_outer: NDArray[np.float64], wall: float, floor: float) -> trimesh.Trimesh:
    """A hollow solid of revolution open at the top: outer radius ``r_outer(z)``, wall and floor thickness."""
    inner = (z >= floor) & (r_outer - wall > 0)
    profile = np.vstack(
        [
            [0.0, z[0]],
            np.column_stack([r_outer, z]),
            np.column_stack([r_outer[inner] - wall, z[inner]])[::-1],
            [0.0, z[inner][0]],
        ]
    )
    return revolved(profile)


# --------------------------------------------------------------------------- #
# Families: each builds one shape (any size) from its parameter draws
# --------------------------------------------------------------------------- #


def _superquadric(d: _Draw) -> trimesh.Trimesh:
    e1, e2 = d(0.7, 2.4), d(0.7, 2.4)
    radii = np.array([1.0, d(0.55, 1.0), d(1.0, 1.8)])
    taper, twist = d(-0.5, 0.5), d(-0.8, 0.8)

    def signed_power(t, e):
        return np.sign(t) * np.abs(t) ** e

    def place(n):
        eta = np.arcsin(np.clip(n[:, 2], -1.0, 1.0))
        omega = np.arctan2(n[:, 1], n[:, 0])
        ce = signed_power(np.cos(eta), e1)
        v = np.column_stack([ce * signed_power(np.cos(omega), e2), ce * signed_power(np.sin(omega), e2), signed_power(np.sin(eta), e1)])
        v *= radii
        h = v[:, 2] / radii[2]  # -1 .. 1 along the height
        v[:, :2] *= (1.0 + taper * h)[:, None]
        c, s = np.cos(twist * h), np.sin(twist * h)
        return np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]])

    return _radial_surface(place)


def _star_blob(d: _Draw) -> trimesh.Trimesh:
    k = 12
    centres, amplitude, sharpness = d.directions(k), d(-0.4, 0.6, k), d(4.0, 16.0, k)
    stretch = np.array([1.0, d(0.6, 1.0), d(1.0, 1.6)])

    def place(n):
        log_r = (amplitude * np.exp(sharpness * (n @ centres.T - 1.0))).sum(axis=1)
        return n * np.exp(log_r)[:, None] * stretch

    return _radial_surface(place)


def _ring(d: _Draw, upright: bool) -> trimesh.Trimesh:
    mesh = _torus_mesh(major_radius=1.0, minor_radius=d(0.28, 0.5), major_sections=64, minor_sections=24)
    mesh.apply_scale((1.0, d(0.75, 1.0), 1.0))
    if upright:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    return mesh


def _bowl(d: _Draw) -> trimesh.Trimesh:
    depth, p, wall = d(0.35, 0.65), d(1.4, 3.0), d(0.04, 0.08)
    theta = np.linspace(0.35, np.pi / 2, 24)
    r = np.sin(theta) ** (2 / p)
    z = depth * (1.0 - np.cos(theta) ** (2 / p))
    return _hollow(z - z[0], r, wall, wall)


def _vase(d: _Draw) -> trimesh.Trimesh:
    z = np.linspace(0.0, 1.0, 32)
    base, bulge, waves, phase = d(0.22, 0.32), d(0.15, 0.45), d(0.8, 1.8), d(-0.5, 0.5)
    r = base * (1.0 + bulge * np.sin(np.pi * waves * z + phase))
    return _hollow(z, np.maximum(r, 0.1), d(0.02, 0.035), 0.04)


def _jug(d: _Draw) -> trimesh.Trimesh:
    z = np.linspace(0.0, 1.0, 32)
    belly, neck = d(0.3, 0.38), d(0.16, 0.24)
    r = neck + (belly - neck) * np.sin(np.pi * np.clip(z * d(0.9, 1.2), 0, 1)) ** 2
    r[0] = r[1] * 0.9
    body = _hollow(z, r, 0.025, 0.04)
    lo, hi = d(0.25, 0.4), d(0.7, 0.85)
    t = np.linspace(-np.pi / 2, np.pi / 2, 17)
    zc, half = (lo + hi) / 2, (hi - lo) / 2
    attach = np.interp([lo, hi], z, r).min() - 0.02  # reach into the wall at both ends
    path = np.column_stack([attach + d(0.15, 0.25) * np.cos(t), np.zeros_like(t), zc + half * np.sin(t)])
    return joined([body, tube(path, d(0.03, 0.045))])


def _duck(d: _Draw) -> trimesh.Trimesh:
    body = np.array([0.5, d(0.3, 0.38), d(0.24, 0.32)])
    head_r = d(0.16, 0.22)
    head = np.array([0.32, 0.0, body[2] + 0.3 + d(0.0, 0.15)])
    neck_lean = d(-0.3, 0.2)
    parts = [
        _ellipsoid(body, (0.0, 0.0, 0.3)),
        _ellipsoid((0.12, 0.12, 0.25), ((0.28 + head[0]) / 2, 0.0, (0.3 + head[2]) / 2), _pitch(neck_lean)),
        _ellipsoid((head_r, head_r * 0.9, head_r), head),
        _ellipsoid((d(0.12, 0.18), 0.07, 0.03), head + (head_r + 0.05, 0.0, -0.04)),  # beak
        _ellipsoid((0.16, 0.12, 0.05), (-0.42, 0.0, 0.42), _pitch(-d(0.3, 0.8))),  # tail
    ]
    return joined(parts)


def _bear(d: _Draw) -> trimesh.Trimesh:
    body = np.array([0.3, d(0.26, 0.32), d(0.34, 0.42)])
    head_r = d(0.2, 0.26)
    head_z = 2 * body[2] + head_r * 0.7
    arm = d(0.2, 1.0)
    parts = [
        _ellipsoid(body, (0.0, 0.0, body[2])),
        _ellipsoid((head_r, head_r, head_r * 0.95), (0.0, 0.0, head_z)),
        _ellipsoid((0.1, 0.08, 0.07), (head_r * 0.9, 0.0, head_z - 0.05)),  # snout
        _ellipsoid((0.08, 0.04, 0.08), (0.0, 0.7 * head_r, head_z + 0.8 * head_r)),  # ears
        _ellipsoid((0.08, 0.04, 0.08), (0.0, -0.7 * head_r, head_z + 0.8 * head_r)),
        _ellipsoid((0.2, 0.1, 0.1), (0.17, body[1] * 0.85, 0.1)),  # legs, forward along x
        _ellipsoid((0.2, 0.1, 0.1), (0.17, -body[1] * 0.85, 0.1)),
    ]
    for side in (1.0, -1.0):  # arms, hanging at the sides and raised by 'arm'
        rot = Rotation.from_euler("x", side * arm).as_matrix()
        shoulder = np.array([0.05, side * body[1] * 0.8, 1.5 * body[2]])
        parts.append(_ellipsoid((0.08, 0.08, 0.22), shoulder + rot @ (0.0, 0.0, -0.18), rot))
    return joined(parts)


def _bent_tube(d: _Draw) -> trimesh.Trimesh:
    span, rise = np.deg2rad(d(150.0, 320.0)), d(0.0, 1.2)
    t = np.linspace(-span / 2, span / 2, 25)
    arc = np.column_stack([np.sin(t), rise * t / span, np.cos(t)])  # an arc standing in the xz-plane, rising along y
    return tube(arc @ d.rotation(np.pi).T, d(0.14, 0.25), sections=20)


def _stool(d: _Draw) -> trimesh.Trimesh:
    legs = 3 if d(0.0, 1.0) < 0.5 else 4
    seat_r, height, splay = d(0.5, 0.7), d(0.8, 1.1), d(0.05, 0.25)
    seat = _cylinder(radius=seat_r, height=0.08, sections=48)
    seat.apply_translation((0.0, 0.0, height))
    parts = [seat]
    for a in np.arange(legs) * 2 * np.pi / legs + d(0.0, 1.0):
        top = 0.75 * seat_r * np.array([np.cos(a), np.sin(a), 0.0]) + (0, 0, height)
        foot = (0.75 * seat_r + splay) * np.array([np.cos(a), np.sin(a), 0.0])
        parts.append(_cylinder(radius=d(0.04, 0.06), segment=np.array([foot, top]), sections=16))
    return joined(parts)


def _mushroom(d: _Draw) -> trimesh.Trimesh:
    stem_r, stem_h, cap_r, cap_h = d(0.1, 0.18), d(0.5, 0.8), d(0.4, 0.6), d(0.2, 0.35)
    droop = d(0.0, 0.15)
    profile = [[0.0, 0.0], [1.3 * stem_r, 0.0], [stem_r, stem_h - droop], [cap_r, stem_h - droop]]
    a = np.linspace(0.0, np.pi / 2, 12)[1:]
    profile += [[cap_r * np.cos(x), stem_h - droop + (cap_h + droop) * np.sin(x)] for x in a]
    profile[-1][0] = 0.0
    return revolved(np.array(profile))


def _bucket(d: _Draw) -> trimesh.Trimesh:
    z = np.linspace(0.0, 1.0, 12)
    bottom, top = d(0.28, 0.35), d(0.38, 0.48)
    body = _hollow(z, bottom + (top - bottom) * z, 0.02, 0.03)
    t = np.linspace(0.0, np.pi, 17)
    arch = np.column_stack([np.zeros_like(t), (top - 0.01) * np.cos(t), 1.0 + d(0.25, 0.4) * np.sin(t)])
    return joined([body, tube(arch, 0.025)])


def _knot(d: _Draw) -> trimesh.Trimesh:
    t = np.linspace(0.0, 2 * np.pi, 73)[:-1]
    tube_r = d(0.22, 0.3)
    x = np.sin(t) + 2 * np.sin(2 * t)
    y = np.cos(t) - 2 * np.cos(2 * t)
    z = -np.sin(3 * t) * d(0.6, 1.2)
    path = np.column_stack([x, y, z]) @ (d.rotation(np.pi) @ _pitch(np.pi / 2)).T
    return tube(np.vstack([path, path[:1]]), tube_r, sections=16)


def _snowman(d: _Draw) -> trimesh.Trimesh:
    r = np.array([0.4, d(0.26, 0.32), d(0.16, 0.22)])
    z = np.array([r[0], 2 * r[0] + 0.8 * r[1], 2 * r[0] + 1.6 * r[1] + 0.8 * r[2]])
    parts = [_ellipsoid((ri, ri, ri), (0.0, 0.0, zi)) for ri, zi in zip(r, z)]
    parts.append(_ellipsoid((0.12, 0.03, 0.03), (r[2] + 0.08, 0.0, z[2])))  # nose
    hat = _cylinder(radius=0.7 * r[2], height=d(0.1, 0.25), sections=32)
    hat.apply_translation((0.0, 0.0, z[2] + 0.85 * r[2] + hat.extents[2] / 2))
    parts.append(hat)
    for side in (1.0, -1.0):
        lift = d(-0.3, 0.6)
        arm = np.array([[0.0, side * 0.8 * r[1], z[1]], [0.0, side * (r[1] + 0.35), z[1] + 0.35 * np.sin(lift) + 0.1]])
        parts.append(tube(arm, 0.025, sections=12))
    return joined(parts)


_FAMILIES: dict[str, Callable[[_Draw], trimesh.Trimesh]] = {
    "duck": _duck,
    "bear": _bear,
    "torus_upright": lambda d: _ring(d, upright=True),
    "jug": _jug,
    "superquadric": _superquadric,
    "star_blob": _star_blob,
    "torus_flat": lambda d: _ring(d, upright=False),
    "bowl": _bowl,
    "vase": _vase,
    "bent_tube": _bent_tube,
    "stool": _stool,
    "mushroom": _mushroom,
    "bucket": _bucket,
    "knot": _knot,
    "snowman": _snowman,
}

SHAPE_FAMILIES: tuple[str, ...] = tuple(_FAMILIES)
"""Every procedural family, library families first."""

NOVEL_FAMILIES: tuple[str, ...] = ("mushroom", "bucket", "knot", "snowman")
"""Families held out of every library: the study's novel objects."""

LIBRARY_FAMILIES: tuple[str, ...] = (
    "superquadric", "star_blob", "torus_flat", "bowl", "vase", "bent_tube", "stool",
    "duck", "bear", "torus_upright", "jug",
)
"""Families a library draws its variants from, in the order of :func:`library_names`
(the kinds not among the 12 first)."""

CORE_SHAPES: tuple[str, ...] = ("duck", "bear", "torus_upright", "jug")
"""The canonical freeform, hollow and handled shapes of the 12-object library."""

_NAME = re.compile(r"^(?P<family>[a-z_]+?)(?:-(?P<stream>[vh])(?P<variant>\d+))?$")
_STREAMS = {"v": 0, "h": 1}


def _parse(name: object) -> tuple[str, int | None, int] | None:
    """(family, stream, variant) of a shape name, or None."""
    if not isinstance(name, str):
        return None
    match = _NAME.match(name)
    if match is None or match["family"] not in _FAMILIES:
        return None
    if match["stream"] is None:
        return match["family"], None, 0
    return match["family"], _STREAMS[match["stream"]], int(match["variant"])


def is_shape_name(name: object) -> bool:
    """True when ``name`` names a procedural shape (``"duck"``, ``"knot-h3"``...)."""
    return _parse(name) is not None


def make_shape(name: str) -> trimesh.Trimesh:
    """Build a procedural shape by name (module docstring: names and conventions).

    Parameters
    ----------
    name : str
        ``"<family>"`` (canonical), ``"<family>-v<N>"`` (library variant N) or
        ``"<family>-h<N>"`` (held-out variant N); the family one of :data:`SHAPE_FAMILIES`.

    Returns
    -------
    trimesh.Trimesh
        A new watertight mesh, largest extent :data:`SHAPE_SIZE_M` m, resting on
        ``z = 0``, centred on ``x = y = 0``.

    Raises
    ------
    InvalidInputError
        An unknown family or a malformed name (the message lists the families).

    Examples
    --------
    >>> mesh = make_shape("torus_flat-v3")
    >>> round(float(mesh.extents.max()), 6), mesh.is_watertight
    (0.35, True)
    """
    parsed = _parse(name)
    if parsed is None:
        raise InvalidInputError(
            f"unknown shape {name!r}; give a family ({', '.join(SHAPE_FAMILIES)}), optionally with "
            "'-v<N>' (library variant) or '-h<N>' (held-out variant), e.g. 'duck-v3'"
        )
    family, stream, variant = parsed
    rng = None if stream is None else np.random.default_rng([zlib.crc32(family.encode()), stream, variant])
    raw = _FAMILIES[family](_Draw(rng))
    return load_object(raw, scale_to_m=SHAPE_SIZE_M, name=name).mesh


def _variant_names(families: Sequence[str], stream: str, count: int, seed: int) -> list[str]:
    """``count`` names cycling over ``families``: the j-th round uses variant ``1000 * seed + j``."""
    if count > _MAX_VARIANTS * len(families):
        raise InvalidInputError(f"at most {_MAX_VARIANTS * len(families)} variants of these families per seed, asked {count}")
    return [f"{families[k % len(families)]}-{stream}{_MAX_VARIANTS * seed + k // len(families)}" for k in range(count)]


def library_names(n: int, seed: int = 0) -> list[str]:
    """The names of an ``n``-object library, in a fixed order (prefixes are smaller libraries).

    The first 12 are the same for every seed: the thesis objects
    (:data:`whisker_io.sim.objects.OBJECT_NAMES`) and :data:`CORE_SHAPES`. Beyond
    12, library variants cycle over :data:`LIBRARY_FAMILIES`; round ``j`` of
    library ``seed`` uses variant ``1000 * seed + j`` (``"superquadric-v0"``,
    ``"star_blob-v0"``...). Every name resolves with
    :func:`whisker_io.sim.catalogue.resolve_object`.

    Parameters
    ----------
    n : int
        Library size, >= 1 (the study uses 12, 25 and 50).
    seed : int
        Library seed, >= 0: which variants fill the places beyond 12.

    Returns
    -------
    list of str
        ``n`` distinct names.
    """
    n = whole_number(n, "n", minimum=1)
    seed = whole_number(seed, "seed", minimum=0)
    core = list(OBJECT_NAMES) + list(CORE_SHAPES)
    return (core + _variant_names(LIBRARY_FAMILIES, "v", max(0, n - len(core)), seed))[:n]


def novel_names(n: int, seed: int = 0, families: Sequence[str] = NOVEL_FAMILIES) -> list[str]:
    """Names of ``n`` objects that no library holds (held-out variants ``"<family>-h<N>"``).

    Parameters
    ----------
    n : int
        How many, >= 1.
    seed : int
        Seed, >= 0 (round ``j`` uses held-out variant ``1000 * seed + j``).
    families : str or sequence of str
        Families to cycle over (a repeat counts once); default :data:`NOVEL_FAMILIES` (kinds of shape no
        library has). Library families give harder novel objects: other members of a
        family the library knows.

    Returns
    -------
    list of str
        ``n`` distinct names, none in any :func:`library_names` list.
    """
    n = whole_number(n, "n", minimum=1)
    seed = whole_number(seed, "seed", minimum=0)
    families = (families,) if isinstance(families, str) else tuple(dict.fromkeys(families))  # once each
    unknown = [f for f in families if f not in _FAMILIES]
    if not families or unknown:
        raise InvalidInputError(f"families must be some of {list(SHAPE_FAMILIES)}, got {list(families)}")
    return _variant_names(families, "h", n, seed)


def _build(names: list[str]) -> dict[str, trimesh.Trimesh]:
    return {name: (make_object(name) if name in OBJECT_NAMES else make_shape(name)) for name in names}


def object_library(n: int, seed: int = 0) -> dict[str, trimesh.Trimesh]:
    """The meshes of :func:`library_names` ``(n, seed)``, in order (name -> mesh)."""
    return _build(library_names(n, seed))


def novel_objects(n: int, seed: int = 0, families: Sequence[str] = NOVEL_FAMILIES) -> dict[str, trimesh.Trimesh]:
    """The meshes of :func:`novel_names` ``(n, seed, families)``, in order (name -> mesh)."""
    return _build(novel_names(n, seed, families))
