"""Figures: an object with the whisker array and its contacts; a PFH (Fig 5.13 B style).

Every function takes an optional matplotlib Axes and returns the Figure;
matplotlib is imported inside the functions only. The ``draw_*`` functions
draw into a given Axes and return it, so they compose into bigger figures
(e.g. part B's SDA panel next to :func:`draw_pfh`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np
import trimesh
from numpy.typing import ArrayLike

from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import whisker_frames
from whisker_io.plots.axes import figure_and_axes
from whisker_io.pose import PoseLike, as_pose
from whisker_io.sim.sweep import SweepContact

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_scene", "draw_pfh", "plot_pfh", "plot_tactile_image"]


def plot_scene(
    mesh: trimesh.Trimesh,
    array: WhiskerArray,
    pose: PoseLike,
    contacts: Sequence[SweepContact | None] | None = None,
    ax: "Axes | None" = None,
    max_faces: int = 4000,
) -> "Figure":
    """3-D view of an object mesh, the array's whiskers and their contact points.

    Whiskers with a contact are drawn at their contact angle up to the contact
    point (red dot); the others at whisk angle 0 over their full length (grey).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The object in the world frame.
    array : WhiskerArray
    pose : PoseLike
        End-effector pose ``T_BE``.
    contacts : sequence of SweepContact or None, optional
        One per module (e.g. :func:`whisker_io.sim.sweep.sweep_array` output).
    ax : matplotlib 3-D Axes, optional
    max_faces : int
        Faces drawn at most (a regular subset of larger meshes), for speed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig, ax = figure_and_axes(ax, (6.0, 6.0), projection="3d")
    faces = np.arange(len(mesh.faces))
    if len(faces) > max_faces:
        faces = faces[:: int(np.ceil(len(faces) / max_faces))]
    tris = mesh.triangles[faces]
    shade = 0.35 + 0.5 * np.clip(mesh.face_normals[faces] @ np.array([0.3, -0.4, 0.87]), 0, 1)
    coll = Poly3DCollection(tris, facecolors=plt.cm.Blues(shade), edgecolors="none", alpha=0.35, label="object")
    ax.add_collection3d(coll)

    pose = as_pose(pose)
    n = len(array)
    contacts = list(contacts) if contacts is not None else [None] * n
    theta = np.array([0.0 if c is None else c.angle_rad for c in contacts])
    frames = whisker_frames(array, pose, theta)
    named: set[bool] = set()
    for i, c in enumerate(contacts):
        base = frames[i, :3, 3]
        reach = array.lengths_m[i] if c is None else c.radial_distance_m
        tip = base + reach * frames[i, :3, 1]
        label = "whisker without contact (at angle 0)" if c is None else "whisker in contact (up to the contact)"
        ax.plot(*np.c_[base, tip], color="0.5" if c is None else "k", lw=1,
                label=None if (c is None) in named else label)
        named.add(c is None)
    ax.scatter(*frames[:, :3, 3].T, color="k", s=8, label="whisker bases")
    hit = np.array([c.point for c in contacts if c is not None]).reshape(-1, 3)
    if len(hit):
        ax.scatter(*hit.T, color="tab:red", s=25, depthshade=False, label="contacts")
    pts = np.vstack([mesh.bounds, frames[:, :3, 3]])
    centre = pts.mean(axis=0)
    half = 0.5 * np.ptp(pts, axis=0).max()
    ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
           zlim=(centre[2] - half, centre[2] + half), xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
    ax.legend(loc="upper left", fontsize="small")
    ax.set_title(f"Whisker array at the object: {len(hit)} of {n} whiskers in contact")
    return fig


def draw_pfh(ax: "Axes", histogram: ArrayLike, color: str = "tab:blue", label: str | None = None) -> "Axes":
    """Draw a point feature histogram as bars over the flattened bin index (Fig 5.13 B).

    Parameters
    ----------
    ax : matplotlib Axes
    histogram : array_like (B,)
        Normalised histogram (:attr:`whisker_io.features.pfh.PointFeatureHistogram.histogram`).
    color, label : bar colour and legend label.

    Returns
    -------
    Axes
    """
    h = np.asarray(histogram, dtype=float)
    ax.bar(np.arange(h.size), h, width=1.0, color=color, label=label, alpha=0.8)
    ax.set_xlim(-0.5, h.size - 0.5)
    ax.set_xlabel("PFH bin (alpha, theta, phi, d)")
    ax.set_ylabel("fraction of pairs")
    return ax


def plot_pfh(histogram: ArrayLike, ax: "Axes | None" = None, title: str = "Point feature histogram") -> "Figure":
    """Figure of one PFH (:func:`draw_pfh`); returns the Figure."""
    created = ax is None
    _, ax = figure_and_axes(ax, (6.0, 2.5))
    draw_pfh(ax, histogram)
    ax.set_title(title)
    if created:
        ax.figure.tight_layout()
    return ax.figure


def plot_tactile_image(image: ArrayLike, ax: "Axes | None" = None) -> "Figure":
    """Grey-scale view of a tactile image (Fig 3.2 layout: columns A-F, rows 1-3), with its grey scale.

    Grey is the contact height scaled to 1-255, 0 = no contact
    (:mod:`whisker_io.features.tactile_image`).
    """
    img = np.asarray(image)
    _, ax = figure_and_axes(ax, (4.8, 2.2))
    im = ax.imshow(img, cmap="gray", vmin=0, vmax=255)
    ax.set_xticks(range(img.shape[1]), [chr(ord("A") + i) for i in range(img.shape[1])])
    ax.set_yticks(range(img.shape[0]), [str(i + 1) for i in range(img.shape[0])])
    ax.set_xlabel("whisker column")
    ax.set_ylabel("whisker row")
    ax.figure.colorbar(im, ax=ax, label="contact height\n(grey level, 0 = none)")
    ax.set_title("tactile image")
    return ax.figure
