"""Rigid-whisker sweep simulator: where and at which angle each whisker first touches a mesh.

This is the "simulated ground truth" of Sec 4.1.2.3 of the thesis, also used
for the contact features of Ch.5-6 (Sec 4.1.2.3, 6.1.3.1): every whisker is treated as a
rigid straight segment of its length, swept about its base frame's z-axis from
the retraction limit (-50 deg) to the protraction limit (+50 deg). The contact
is the first touch nearest the retraction limit and, at that angle, nearest the
whisker base. The surface slope is the hit face's normal projected on the
shaft frame's x and y axes, ``slope = n_y / n_x`` (Eq 6.12-6.14).

Algorithm (documented decision)
-------------------------------
1. **Coarse pass, one ray batch.** For all N whiskers and all M angles
   (1-deg steps by default) cast one ray from the whisker base along the shaft
   (max length = whisker length: the hit distance is the radial distance), and
   one *chord* ray from the tip at step k to the tip at step k+1 (max length =
   chord length). The chord catches thin features that pass between two
   shaft rays near the tip (a 160 mm whisker's tip moves 2.8 mm per degree).
   Step interval k is in contact when the chord k or the shaft at k+1 hits;
   if the shaft already hits at the retraction limit the contact angle is the
   retraction limit.
2. **Refinement.** The first contacting interval ``[lo, hi]`` is split into
   ``refine_subdivisions`` parts and the same test (shafts + chords, one
   batch for all whiskers) repeated until it is narrower than
   ``angle_tolerance_rad``. The earliest contacting sub-interval is kept, so
   a non-monotone contact (a feature touched briefly) is not skipped. The
   contact is the shaft hit at ``hi`` (or, for a tip contact found only by a
   chord, the chord hit) and ``angle_rad = hi``, which is at most
   ``angle_tolerance_rad`` past the exact first-touch angle.

Limit: a feature that lies wholly inside one swept triangle (base, tip_k,
tip_k+1) without crossing its edges is missed by the coarse pass; at a 1-deg
step that means a feature narrower than about 1.7 % of its distance from the
base on every side. Reduce ``step_rad`` for such scenes. A whisker whose base
lies inside the mesh (the array pushed into the object) reports the face where
its shaft leaves the mesh; keep the array outside obstacles.

Ray casting uses trimesh: Embree (``trimesh.ray.ray_pyembree`` through the
``embreex`` package, float32 BVH, hit points recomputed in float64) when
available, otherwise the exact float64 test of ``trimesh.ray.ray_triangle``
(plane intersection + barycentric check) on candidate triangles from trimesh's
r-tree, queried in bulk with each segment's bounding box (about 50x slower than
Embree). :class:`MeshTarget` builds the intersector once.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import Literal, Sequence

import numpy as np
import trimesh
from numpy.typing import NDArray

from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, scaled_fields, validate_fields, whole_number
from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import rot_z, rotate_shaft, whisker_base_transforms
from whisker_io.pose import PoseLike
from whisker_io.sim.objects import MAX_SCENE_M, check_extent

__all__ = [
    "RayEngine",
    "embree_available",
    "MeshTarget",
    "SweepParams",
    "SweepContact",
    "sweep_array",
    "ContactNoise",
    "perturb_contacts",
    "add_contact_noise",
]

logger = logging.getLogger(__name__)

RayEngine = Literal["auto", "embree", "triangle"]


def embree_available() -> bool:
    """True when trimesh can use Embree (the ``embreex`` package imports)."""
    try:
        from trimesh.ray import ray_pyembree  # noqa: F401
        import embreex  # noqa: F401
    except Exception:  # pragma: no cover - depends on the install
        return False
    return True


class _EmbreeScene:
    """An Embree BVH of a mesh, built as ``trimesh.ray.ray_pyembree`` builds it (vertices
    shifted to the bounding-box corner and scaled to about 100 units for float32
    precision), queried directly so each segment's far end bounds the traversal."""

    def __init__(self, mesh: trimesh.Trimesh) -> None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        self.origin = vertices.min(axis=0)
        self.scale = 100.0 / float(mesh.scale)
        self.scene = rtcore_scene.EmbreeScene()
        self._geometry = TriangleMesh(
            scene=self.scene,
            vertices=((vertices - self.origin) * self.scale).astype(np.float32),
            indices=np.asarray(mesh.faces).astype(np.int32),
        )

    def first_faces(
        self, origins: NDArray[np.float64], directions: NDArray[np.float64], max_distance: NDArray[np.float64]
    ) -> NDArray[np.int64]:
        """Face of the first hit of each ray within (slightly more than) its max distance, -1 if none.

        The far end is padded by 1e-6 relative + 1e-6 scaled units, so a hit at the
        segment's end in float64 is still returned; the caller applies the exact bound.
        """
        with np.errstate(over="ignore", invalid="ignore"):  # a far-away segment overflows float32: no hit
            o = ((origins - self.origin) * self.scale).astype(np.float32)
            far = (np.asarray(max_distance, dtype=np.float64) * (self.scale * (1.0 + 1e-6)) + 1e-6).astype(np.float32)
        tri = self.scene.run(o, directions.astype(np.float32), dists=far)
        return np.asarray(tri, dtype=np.int64)


class MeshTarget:
    """A triangle mesh prepared for repeated ray casting.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The obstacle in the world frame (metres). Not copied; do not mutate
        it while this target is in use.
    engine : {"auto", "embree", "triangle"}
        Ray engine. ``"auto"`` picks Embree when available.

    Raises
    ------
    InvalidInputError
        Unknown engine, Embree requested but not installed, or an empty mesh.
    """

    def __init__(self, mesh: trimesh.Trimesh, engine: RayEngine = "auto") -> None:
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise InvalidInputError("mesh must be a non-empty trimesh.Trimesh")
        # in metres: a mesh in millimetres (1000 x too large) is refused, saying so; every whisk and trajectory
        # around a mesh goes through here
        check_extent(float(np.max(mesh.extents)), "the mesh (bring it to metres with whisker_io.sim.objects.load_object)",
                     minimum_m=0.001, maximum_m=MAX_SCENE_M)
        if engine not in ("auto", "embree", "triangle"):
            raise InvalidInputError(
                f"unknown ray engine {engine!r}; use 'auto', 'embree' or 'triangle'"
            )
        if engine == "auto":
            engine = "embree" if embree_available() else "triangle"
        if engine == "embree":
            if not embree_available():
                raise InvalidInputError(
                    "engine='embree' needs the 'embreex' package (pip install \"cansim[embree]\"); "
                    "use engine='triangle' or 'auto'"
                )
            self._embree = _EmbreeScene(mesh)
        self.mesh = mesh
        self.engine: str = engine
        self._bounds = np.asarray(mesh.bounds, dtype=float)
        self._normals = np.asarray(mesh.face_normals, dtype=float)
        self._v0 = np.asarray(mesh.triangles[:, 0], dtype=float)

    @property
    def face_normals(self) -> NDArray[np.float64]:
        """Unit face normals of the mesh, shape (F, 3)."""
        return self._normals

    def first_hits(
        self,
        origins: NDArray[np.float64],
        directions: NDArray[np.float64],
        max_distance: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
        """Nearest hit of each segment ``origin + t * direction, 0 <= t <= max_distance``.

        Parameters
        ----------
        origins, directions : ndarray, shape (R, 3)
            Directions must be unit vectors.
        max_distance : ndarray, shape (R,)

        Returns
        -------
        distance : ndarray (R,)
            Distance to the nearest hit, ``inf`` when none within ``max_distance``.
        face : ndarray (R,) int
            Hit face index, -1 when none.
        location : ndarray (R, 3)
            Hit point, NaN when none.
        """
        R = len(origins)
        distance = np.full(R, np.inf)
        face = np.full(R, -1, dtype=np.int64)
        location = np.full((R, 3), np.nan)
        if self.engine == "embree":
            tri = self._embree.first_faces(origins, directions, max_distance)
            ray = np.flatnonzero(tri >= 0)
            tri = tri[ray].astype(np.int64)
            # Embree (float32) picks the face; the hit point is recomputed in float64 on
            # that face's plane, as trimesh does
            nrm = self._normals[tri]
            o, dirs = origins[ray], directions[ray]
            denom = np.einsum("ij,ij->i", nrm, dirs)
            good = np.abs(denom) > 1e-12
            if not good.all():
                ray, tri, nrm, denom, o, dirs = ray[good], tri[good], nrm[good], denom[good], o[good], dirs[good]
            t = np.einsum("ij,ij->i", nrm, self._v0[tri] - o) / denom
            loc = o + t[:, None] * dirs
        else:
            ends = origins + directions * max_distance[:, None]
            lo, hi = np.minimum(origins, ends), np.maximum(origins, ends)
            tri, ray, loc = self._segment_candidates_hits(origins, directions, lo, hi)
        if len(ray) == 0:
            return distance, face, location
        d = np.einsum("ij,ij->i", loc - origins[ray], directions[ray])
        ok = (d >= -1e-12) & (d <= max_distance[ray] * (1.0 + 1e-12) + 1e-12)
        ray, d, tri, loc = ray[ok], d[ok], tri[ok], loc[ok]
        if len(ray) == 0:
            return distance, face, location
        if self.engine != "embree":  # nearest of possibly several hits per segment
            order = np.lexsort((d, ray))
            ray, d, tri, loc = ray[order], d[order], tri[order], loc[order]
            first = np.r_[True, ray[1:] != ray[:-1]]
            ray, d, tri, loc = ray[first], d[first], tri[first], loc[first]
        distance[ray] = np.maximum(d, 0.0)
        face[ray] = tri
        location[ray] = loc
        return distance, face, location

    def _segment_candidates_hits(
        self, origins: NDArray, directions: NDArray, lo: NDArray, hi: NDArray
    ) -> tuple[NDArray, NDArray, NDArray]:
        """All segment/triangle hits in float64, the test of ``trimesh.ray.ray_triangle``
        (plane intersection + barycentric inside check) on candidates from one bulk query
        of trimesh's r-tree of triangle bounds with each *segment's* bounding box (trimesh's
        own intersector uses the infinite ray's box, which makes it far slower here)."""
        from trimesh import intersections, triangles as tri_mod
        from trimesh.constants import tol

        pad = 1e-9
        cand, counts = self.mesh.triangles_tree.intersection_v(lo - pad, hi + pad)
        ray = np.repeat(np.arange(len(origins)), counts.astype(np.int64))
        cand = np.asarray(cand, dtype=np.int64)
        if cand.size == 0:
            return cand, ray, np.zeros((0, 3))
        tris = self.mesh.triangles[cand]
        loc, valid = intersections.planes_lines(
            plane_origins=tris[:, 0],
            plane_normals=self._normals[cand],
            line_origins=origins[ray],
            line_directions=directions[ray],
        )
        cand, ray, tris = cand[valid], ray[valid], tris[valid]
        if cand.size == 0:
            return cand, ray, np.zeros((0, 3))
        bary = tri_mod.points_to_barycentric(tris, loc)
        inside = np.all(bary > -tol.zero, axis=1) & np.all(bary < 1 + tol.zero, axis=1)
        return cand[inside], ray[inside], loc[inside]


@dataclass(frozen=True)
class SweepParams(ConfigDataclass):
    """Parameters of :func:`sweep_array`.

    Attributes
    ----------
    step_rad : float
        Coarse angular step, radians. Default 1 deg (Sec 4.1.2.3).
    refine : bool
        Refine the contact angle inside the first contacting step. Default True.
    refine_subdivisions : int
        Sub-intervals per refinement pass (>= 2). Default 32 (3 passes from 1 deg to 1e-6 rad).
    angle_tolerance_rad : float
        Refinement stops when the bracket is narrower than this. Default 1e-6 rad.
    tip_chords : bool
        Also cast tip-to-tip chord rays between consecutive angles (see module
        docstring). Default True.
    """

    step_rad: float = checked(float(np.deg2rad(1.0)), float, above=0, error=InvalidInputError, reader=finite_scalar,
                              message="{name} must be positive, got {value!r}")
    refine: bool = True
    refine_subdivisions: int = checked(32, int, minimum=2, error=InvalidInputError, reader=whole_number)
    angle_tolerance_rad: float = checked(1e-6, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                         message="{name} must be positive, got {value!r}")
    tip_chords: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)


@dataclass(frozen=True, eq=False)
class SweepContact:
    """First contact of one whisker during a sweep.

    Attributes
    ----------
    module : str
        Module name (e.g. ``"C2"``).
    angle_rad : float
        Whisk angle ``theta_c`` at contact, radians (+ = protraction).
    radial_distance_m : float
        Distance from the whisker base to the contact point along the shaft, metres.
    point : ndarray (3,)
        Contact point in the world frame, metres.
    normal : ndarray (3,)
        Unit normal of the hit mesh face in the world frame, as the mesh's
        winding orients it (outward for a watertight mesh). When the first touch
        is exactly on an edge or vertex (common for the first touch of a convex
        faceted surface) it is the normal of one of the faces meeting there;
        which one may differ between ray engines.
    slope : float
        ``n_y / n_x`` with ``n_x = -n . x_tc``, ``n_y = -n . y_tc`` the face normal
        projected on the shaft frame's axes at contact (Eq 6.12-6.14); ``+-inf``
        when ``n_x = 0`` (NaN when both are 0).
    whisker_length_m : float
        Length of the whisker, metres.
    frame : ndarray (4, 4)
        Shaft frame at contact ``T_BWi Rz(theta_c)`` in the world (Eq 5.1);
        ``point = frame[:3, 3] + radial_distance_m * frame[:3, 1]``.
    face : int
        Index of the hit mesh face.
    tip_contact : bool
        True when the contact was found by a tip chord rather than by the shaft
        (the contact point then lies at the tip, radial distance ~ length).
    """

    module: str
    angle_rad: float
    radial_distance_m: float
    point: NDArray[np.float64]
    normal: NDArray[np.float64]
    slope: float
    whisker_length_m: float
    frame: NDArray[np.float64]
    face: int
    tip_contact: bool = False


def _slope(normal: NDArray[np.float64], frame: NDArray[np.float64]) -> float:
    """Eq 6.12-6.14: ``slope = n_y / n_x`` in the shaft frame at contact."""
    nx = -float(normal @ frame[:3, 0])
    ny = -float(normal @ frame[:3, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.float64(ny) / np.float64(nx))


class _SweepRays:
    """Builds and casts the shaft + chord rays for a set of whiskers and angle grids."""

    def __init__(
        self, target: MeshTarget, base: NDArray, X: NDArray, Y: NDArray, L: NDArray, chords: bool
    ) -> None:
        self.target, self.base, self.X, self.Y, self.L = target, base, X, Y, L
        self.chords = chords

    def directions(self, idx: NDArray, phi: NDArray) -> NDArray:
        """Unit shaft directions (W, K, 3) of whiskers ``idx`` at angles ``phi`` (W, K)."""
        return rotate_shaft(self.X[idx, None], self.Y[idx, None], phi)

    def cast(self, idx: NDArray, phi: NDArray) -> dict[str, NDArray]:
        """Shaft rays at every ``phi`` column and chords between consecutive columns."""
        W, K1 = phi.shape
        d = self.directions(idx, phi)  # (W, K1, 3)
        base = np.broadcast_to(self.base[idx, None], d.shape)
        L = np.broadcast_to(self.L[idx, None], (W, K1))
        origins = [base.reshape(-1, 3)]
        dirs = [d.reshape(-1, 3)]
        maxd = [L.reshape(-1)]
        if self.chords and K1 > 1:
            tips = base + L[..., None] * d
            chord = tips[:, 1:] - tips[:, :-1]
            clen = np.linalg.norm(chord, axis=-1)
            cdir = np.divide(chord, clen[..., None], out=np.zeros_like(chord), where=clen[..., None] > 0)
            origins.append(tips[:, :-1].reshape(-1, 3))
            dirs.append(cdir.reshape(-1, 3))
            maxd.append(clen.reshape(-1))
        dist, face, loc = self.target.first_hits(
            np.concatenate(origins), np.concatenate(dirs), np.concatenate(maxd)
        )
        n_shaft = W * K1
        out = {
            "s_dist": dist[:n_shaft].reshape(W, K1),
            "s_face": face[:n_shaft].reshape(W, K1),
            "s_loc": loc[:n_shaft].reshape(W, K1, 3),
        }
        if self.chords and K1 > 1:
            out["c_face"] = face[n_shaft:].reshape(W, K1 - 1)
            out["c_loc"] = loc[n_shaft:].reshape(W, K1 - 1, 3)
        else:
            out["c_face"] = np.full((W, max(K1 - 1, 0)), -1, dtype=np.int64)
            out["c_loc"] = np.full((W, max(K1 - 1, 0), 3), np.nan)
        return out


def _first_interval(hits: dict[str, NDArray]) -> NDArray[np.int64]:
    """Index k of the first interval [phi_k, phi_k+1] in contact per row, -1 if none."""
    contact = (hits["s_face"][:, 1:] >= 0) | (hits["c_face"] >= 0)
    first = np.argmax(contact, axis=1)
    return np.where(contact.any(axis=1), first, -1)


def sweep_array(
    array: WhiskerArray,
    target: MeshTarget | trimesh.Trimesh,
    pose: PoseLike,
    params: SweepParams = SweepParams(),
) -> tuple[SweepContact | None, ...]:
    """Sweep every whisker from retraction to protraction and return its first contact.

    Parameters
    ----------
    array : WhiskerArray
        Array geometry (base frames, lengths, whisk range).
    target : MeshTarget or trimesh.Trimesh
        The obstacle in the world frame. Pass a :class:`MeshTarget` when sweeping
        the same mesh repeatedly (a bare mesh builds its intersector each call).
    pose : PoseLike
        End-effector pose ``T_BE`` (a Pose, a 4x4 transform, or (position_m, quaternion_xyzw)).
    params : SweepParams

    Returns
    -------
    tuple of (SweepContact or None), length N
        In array order; ``None`` for a whisker that touches nothing.
    """
    if not isinstance(target, MeshTarget):
        target = MeshTarget(target)
    T_BW = whisker_base_transforms(array, pose)
    base, X, Y = T_BW[:, :3, 3], T_BW[:, :3, 0], T_BW[:, :3, 1]
    L = array.lengths_m
    rays = _SweepRays(target, base, X, Y, L, params.tip_chords)
    N = len(array)
    all_idx = np.arange(N)

    grid = array.whisk_angles(params.step_rad)
    phi = np.broadcast_to(grid, (N, grid.size))
    hits = rays.cast(all_idx, phi)

    # per whisker: bracket [lo, hi] and the hit information at hi
    lo = np.full(N, np.nan)
    hi = np.full(N, np.nan)
    s_face = np.full(N, -1, dtype=np.int64)
    s_loc = np.full((N, 3), np.nan)
    c_face = np.full(N, -1, dtype=np.int64)
    c_loc = np.full((N, 3), np.nan)

    at_start = hits["s_face"][:, 0] >= 0
    k = _first_interval(hits)
    found = at_start | (k >= 0)
    for i in np.flatnonzero(at_start):
        lo[i] = hi[i] = grid[0]
        s_face[i], s_loc[i] = hits["s_face"][i, 0], hits["s_loc"][i, 0]
    refine_idx = np.flatnonzero(~at_start & (k >= 0))
    kk = k[refine_idx]
    lo[refine_idx] = grid[kk]
    hi[refine_idx] = grid[kk + 1]
    s_face[refine_idx] = hits["s_face"][refine_idx, kk + 1]
    s_loc[refine_idx] = hits["s_loc"][refine_idx, kk + 1]
    c_face[refine_idx] = hits["c_face"][refine_idx, kk]
    c_loc[refine_idx] = hits["c_loc"][refine_idx, kk]

    if params.refine:
        K = int(params.refine_subdivisions)
        active = refine_idx
        while active.size:
            active = active[(hi[active] - lo[active]) > params.angle_tolerance_rad]
            if not active.size:
                break
            frac = np.linspace(0.0, 1.0, K + 1)
            sub = lo[active, None] + (hi[active] - lo[active])[:, None] * frac
            h = rays.cast(active, sub)
            ks = _first_interval(h)
            lost = ks < 0
            if lost.any():  # sub-chords missed a sliver the parent chord hit: keep bracket
                logger.debug("refinement lost contact for modules %s", active[lost])
            ok = ~lost
            a, kk = active[ok], ks[ok]
            rows = np.flatnonzero(ok)
            lo[a] = sub[rows, kk]
            hi[a] = sub[rows, kk + 1]
            s_face[a] = h["s_face"][rows, kk + 1]
            s_loc[a] = h["s_loc"][rows, kk + 1]
            c_face[a] = h["c_face"][rows, kk]
            c_loc[a] = h["c_loc"][rows, kk]
            active = a

    frames = T_BW @ rot_z(np.nan_to_num(hi))
    normals = target.face_normals
    out: list[SweepContact | None] = []
    for i, module in enumerate(array.modules):
        if not found[i]:
            out.append(None)
            continue
        tip = s_face[i] < 0
        f = int(c_face[i] if tip else s_face[i])
        p = (c_loc[i] if tip else s_loc[i]).copy()
        r = float(np.linalg.norm(p - base[i]))
        n = normals[f].copy()
        out.append(
            SweepContact(
                module=module.name,
                angle_rad=float(hi[i]),
                radial_distance_m=r,
                point=p,
                normal=n,
                slope=_slope(n, frames[i]),
                whisker_length_m=float(L[i]),
                frame=frames[i].copy(),
                face=f,
                tip_contact=bool(tip),
            )
        )
    return tuple(out)


@dataclass(frozen=True)
class ContactNoise(ConfigDataclass):
    """Contact-feature noise of the Ch.6 simulation (Sec 6.1.3.1.2, Sec 4.1.2.3, 6.1.3.1).

    Attributes
    ----------
    position_sigma_fraction : float
        Standard deviation of the contact-position noise as a fraction of the
        whisker length (thesis: 0.25, "N(0, r_eta), r_eta = 25 % of the whisker's
        length").
    position_mode : {"shaft", "isotropic"}
        ``"shaft"`` (default, decision): the noise perturbs the radial distance
        along the shaft, because the estimated quantity is the radial distance
        (the angle is measured); the result is clipped to ``[0, length]`` so the
        point stays on the whisker. ``"isotropic"``: independent N(0, sigma) on
        each world coordinate. The clip biases the noise where a contact lies at
        an end of the shaft: a rigid sweep's first contact is often at the tip
        (r = length), where only the inward half survives - mean -0.40 sigma, sd
        0.58 sigma, half the contacts left exactly at the tip (at the thesis' sigma
        of 0.25 length: mean -0.10, sd 0.15 length). The thesis' N(0, r_eta) on
        the estimated location, unclipped, could put a point beyond the tip.
    slope_sigma : float
        Standard deviation of additive slope noise (thesis: 0.33).
    registration_probability : float
        Probability a contact is registered at all (thesis: 0.98).
    """

    position_sigma_fraction: float = checked(0.25, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                             message="noise standard deviations must be >= 0")
    position_mode: Literal["shaft", "isotropic"] = checked(
        "shaft", str, choices=("shaft", "isotropic"), error=InvalidInputError,
        message="{name} must be 'shaft' or 'isotropic', got {value!r}")
    slope_sigma: float = checked(0.33, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                 message="noise standard deviations must be >= 0")
    registration_probability: float = checked(0.98, float, minimum=0, maximum=1, error=InvalidInputError,
                                              reader=finite_scalar, message="{name} must be in [0, 1], got {value!r}")

    def __post_init__(self) -> None:
        validate_fields(self)

    def scaled(self, scale: float) -> ContactNoise:
        """This noise with both standard deviations multiplied by ``scale``.

        ``ContactNoise().scaled(s)`` is ``s`` times the Sec 6.1.3.1.2 noise: contact
        position N(0, 0.25 s x whisker length), slope N(0, 0.33 s); the registration
        probability and the position mode are kept. ``scaled(0)`` leaves only the
        missed registrations; ``scaled(1)`` is an equal copy.

        Parameters
        ----------
        scale : float
            Factor, finite and >= 0 (dimensionless).

        Raises
        ------
        InvalidInputError
            A scale that is not a finite number >= 0 (or a bool), or that makes a
            standard deviation overflow.
        """
        return scaled_fields(self, scale, ("position_sigma_fraction", "slope_sigma"))


def perturb_contacts(
    present: NDArray[np.bool_],
    radial_distance_m: NDArray[np.float64],
    slope: NDArray[np.float64],
    whisker_length_m: NDArray[np.float64],
    noise: ContactNoise = ContactNoise(),
    rng: np.random.Generator | int | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The Sec 6.1.3.1.2 noise model on per-whisker contact arrays (the core of :func:`add_contact_noise`).

    Parameters
    ----------
    present : ndarray of bool (N,)
        Whiskers with a contact.
    radial_distance_m, slope, whisker_length_m : ndarray (N,)
        Radial distance (m), slope and whisker length (m) per whisker; entries of
        absent whiskers are ignored.
    noise : ContactNoise
    rng : numpy Generator or int seed, optional

    Raises
    ------
    InvalidInputError, ShapeError
        Arrays of other shapes, a non-boolean ``present``, a non-finite radial
        distance or length of a present contact, ``noise`` not a ContactNoise.

    Returns
    -------
    registered : ndarray of bool (N,)
        ``present`` and kept with probability ``registration_probability``.
    radial_distance_m : ndarray (N,)
        ``"shaft"`` mode: ``clip(r + N(0, sigma L), 0, L)``; ``"isotropic"``: unchanged.
    slope : ndarray (N,)
        ``slope + N(0, slope_sigma)``.
    offset_m : ndarray (N, 3)
        ``"isotropic"`` mode: the N(0, sigma L) displacement of each contact point
        (any frame: the distribution is rotation-invariant); ``"shaft"``: zeros.

    Every whisker draws the same variates whether or not it has a contact or is
    kept (one uniform, three normals for the position, one for the slope), so
    the noise of one whisker does not depend on the others.
    """
    if not isinstance(noise, ContactNoise):
        raise InvalidInputError(f"noise must be a ContactNoise, got {type(noise).__name__}")
    present = np.asarray(present)
    if present.ndim != 1 or present.dtype != np.bool_:
        raise InvalidInputError(f"present must be a 1-D array of booleans, got {present.dtype} {present.shape}")
    n = present.shape[0]
    arrays = [np.asarray(a, dtype=np.float64) for a in (radial_distance_m, slope, whisker_length_m)]
    if any(a.shape != (n,) for a in arrays):
        raise ShapeError(f"radial_distance_m, slope and whisker_length_m must have shape ({n},), "
                         f"got {[a.shape for a in arrays]}")
    if not (np.all(np.isfinite(arrays[0][present])) and np.all(arrays[2][present] > 0)
            and np.all(np.isfinite(arrays[2][present]))):
        raise InvalidInputError("present contacts need a finite radial distance and a finite whisker length > 0")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    keep = gen.random(n) < noise.registration_probability
    e_pos = gen.normal(0.0, 1.0, size=(n, 3))
    e_slope = gen.normal(0.0, 1.0, size=n)
    r, slope_in, L = arrays[0].copy(), arrays[1], arrays[2]
    sigma = noise.position_sigma_fraction * np.where(present, L, 0.0)
    offset = np.zeros((n, 3))
    if noise.position_mode == "shaft":
        r = np.where(present, np.clip(r + sigma * e_pos[:, 0], 0.0, L), r)
    else:
        offset = np.where(present[:, None], sigma[:, None] * e_pos, 0.0)
    s = slope_in + noise.slope_sigma * e_slope
    return present & keep, r, s, offset


def add_contact_noise(
    contacts: Sequence[SweepContact | None],
    noise: ContactNoise = ContactNoise(),
    rng: np.random.Generator | int | None = None,
) -> tuple[SweepContact | None, ...]:
    """Apply the Sec 6.1.3.1.2 noise model to sweep contacts (new objects; inputs untouched).

    Each contact is dropped (``None``) with probability ``1 - registration_probability``;
    otherwise its position is perturbed (see :class:`ContactNoise`) and
    ``slope`` gets additive N(0, ``slope_sigma``) noise. Angle, normal and frame
    are kept (they are measured, not estimated). The draws are those of
    :func:`perturb_contacts`.

    Parameters
    ----------
    contacts : sequence of SweepContact or None
    noise : ContactNoise
    rng : numpy Generator or int seed, optional
        Source of randomness; pass a seed for reproducible noise.

    Returns
    -------
    tuple of (SweepContact or None), same length as ``contacts``
    """
    cs = list(contacts)
    present = np.array([c is not None for c in cs], dtype=bool)
    r = np.array([c.radial_distance_m if c is not None else 0.0 for c in cs])
    slope = np.array([c.slope if c is not None else 0.0 for c in cs])
    L = np.array([c.whisker_length_m if c is not None else 1.0 for c in cs])
    kept, r, slope, offset = perturb_contacts(present, r, slope, L, noise, rng)
    out: list[SweepContact | None] = []
    for i, c in enumerate(cs):
        if c is None or not kept[i]:
            out.append(None)
            continue
        base, shaft = c.frame[:3, 3], c.frame[:3, 1]
        if noise.position_mode == "shaft":
            point = base + r[i] * shaft
            radial = float(r[i])
        else:
            point = c.point + offset[i]
            radial = float((point - base) @ shaft)
        out.append(replace(c, point=point, radial_distance_m=radial, slope=float(slope[i])))
    return tuple(out)
