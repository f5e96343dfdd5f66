"""Building blocks of the procedural meshes: placed primitives, solids of revolution, tubes.

Shared by the thesis objects (:mod:`whisker_io.sim.objects`) and the procedural shape
families (:mod:`whisker_io.sim.shapes`). A composite mesh is the concatenation of
overlapping closed parts (no boolean backend), whose outer surface is right for ray
casting from outside. Lengths in metres, angles in radians.
"""

from __future__ import annotations

import numpy as np
import trimesh
from numpy.typing import NDArray
from trimesh.creation import cylinder as _cylinder
from trimesh.creation import icosphere as _icosphere
from trimesh.creation import revolve as _revolve
from trimesh.transformations import rotation_matrix, translation_matrix

__all__ = ["SECTIONS", "placed", "joined", "revolved", "tube"]

#: Angular resolution of solids of revolution (segments around the axis).
SECTIONS = 64


def placed(mesh: trimesh.Trimesh, xyz=(0.0, 0.0, 0.0), angle: float = 0.0, axis=(0, 0, 1)) -> trimesh.Trimesh:
    """Rotate ``mesh`` by ``angle`` about ``axis`` (through the origin), then translate."""
    mesh = mesh.copy()
    if angle:
        mesh.apply_transform(rotation_matrix(angle, axis))
    mesh.apply_transform(translation_matrix(xyz))
    return mesh


def joined(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh of overlapping closed parts, normals pointing out of each part."""
    mesh = trimesh.util.concatenate(parts)
    mesh.fix_normals(multibody=True)
    return mesh


def revolved(profile_rz: NDArray[np.float64], sections: int = SECTIONS) -> trimesh.Trimesh:
    """Solid of revolution about z of a closed (r, z) profile running from the axis to the axis."""
    mesh = _revolve(np.asarray(profile_rz, dtype=float), sections=sections)
    mesh.fix_normals()
    return mesh


def tube(path: NDArray[np.float64], radius: float, sections: int = 16) -> trimesh.Trimesh:
    """A tube of circular section along a 3-D polyline: cylinders between the
    vertices and spheres at the joints (overlapping closed parts)."""
    path = np.asarray(path, dtype=float)
    parts = [
        _cylinder(radius=radius, segment=path[i : i + 2], sections=sections)
        for i in range(len(path) - 1)
    ]
    parts += [placed(_icosphere(subdivisions=1, radius=radius), p) for p in path]
    return joined(parts)


