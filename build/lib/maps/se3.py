"""SE(3) geometry of the 6-DoF object map (thesis Sec 5.1.2.4, Alg 6, Eq 5.13-5.15).

A map pose is a position (m) and a unit quaternion, stored as
``(x, y, z, qx, qy, qz, qw)`` - scalar-last, as ``scipy.spatial.transform.Rotation``
and every API boundary of this library (the thesis writes quaternions
scalar-first). The first experience sits at the identity.

Between experiences the odometry (body-frame ``v`` and ``omega``, Eq 5.7)
accumulates relative to the current experience:

* orientation, Alg 6 / Eq 5.14-5.15: ``q <- q * dq`` with ``dq`` the rotation of
  the rotation vector ``omega dt``;
* translation: ``d <- d + R(q_before) v dt``, the body-frame increment rotated into
  the experience's frame (the printed Eq 5.13 sums body-frame increments without
  rotating them and misprints the ``+``; this is the frame-correct form).

A new experience gets ``p = p_e + R(q_e) d`` and ``q = q_e * q``; a link stores
``(d, q)``: the translation in the source frame and the relative rotation. The
thesis says the map is "constantly adjusted" (Sec 6.1.2.1) without equations;
the decision here: positions relax as Eq 2.25 in 3-D and orientations move toward
the link-implied orientation by the same rate (a slerp), see
:func:`maps._se3_numba.relax_links_se3`.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from maps.odometry import SpatialOdometry

__all__ = ["SE3Geometry", "IDENTITY_XYZW"]

IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)


class SE3Geometry:
    """6-DoF map geometry for :class:`maps.experience_map.ExperienceMap` (see the module docstring)."""

    name = "se3"
    pose_width = 7
    link_width = 7
    accum_width = 7
    pose_fields = ("x_m", "y_m", "z_m", "qx", "qy", "qz", "qw")
    link_fields = ("dx_m", "dy_m", "dz_m", "qx", "qy", "qz", "qw")

    def params(self) -> dict[str, Any]:
        """Constructor arguments (none)."""
        return {}

    def odometry(self, *args: Any) -> SpatialOdometry:
        """Coerce ``(odometry)`` or ``(v (3,), omega (3,), dt)`` to a validated :class:`SpatialOdometry`."""
        if len(args) == 1 and isinstance(args[0], SpatialOdometry):
            return args[0]
        return SpatialOdometry(*args)

    def initial_accumulator(self) -> list[float]:
        """``[dx, dy, dz m, qx, qy, qz, qw]``: no displacement, identity rotation."""
        return [0.0, 0.0, 0.0, *IDENTITY_XYZW]

    def accumulate(self, acc: list[float], odo: SpatialOdometry) -> None:
        """Alg 6 and the frame-correct Eq 5.13 in place (see the module docstring).

        Compiled (:func:`maps._se3_numba.accumulate_se3`, checked against the same update
        written with scipy's ``Rotation`` in ``tests/test_map_se3.py``)."""
        from maps._se3_numba import accumulate_se3

        a = np.array(acc)
        accumulate_se3(a, odo.v, odo.omega, float(odo.dt))
        acc[:] = a.tolist()

    def offset_rotation(self, offset_cells: np.ndarray | None) -> float:
        """View offsets carry no panoramic rotation in 6-D."""
        return 0.0

    def new_pose(self, base: np.ndarray | None, acc: Sequence[float]) -> tuple[float, ...]:
        """``p_e + R(q_e) d`` and ``q_e * q``; relative to the identity before the first experience.

        Compiled (:func:`maps._se3_numba.compose_se3`, checked against scipy's ``Rotation``
        in ``tests/test_map_se3.py``)."""
        if base is None:
            return tuple(float(v) for v in acc)
        from maps._se3_numba import compose_se3

        out = np.empty(7)
        compose_se3(np.ascontiguousarray(base[:7], dtype=np.float64), np.array(acc, dtype=np.float64), out)
        return tuple(out.tolist())

    dead_reckoned = new_pose

    def link(self, from_pose: np.ndarray, acc: Sequence[float], rotation: float) -> tuple[float, ...]:
        """Link data: the accumulated translation (source frame) and relative rotation."""
        return tuple(float(v) for v in acc)

    def reset_accumulator(self, acc: list[float], pose: np.ndarray, rotation: float) -> None:
        """After switching to an experience: no displacement, identity rotation."""
        acc[:] = self.initial_accumulator()

    def relax(self, order: np.ndarray, ends: np.ndarray, links: np.ndarray, poses: np.ndarray, c: float, n: int, start: int) -> int:
        """``n`` Gauss-Seidel link updates in place from position ``start``; returns the next start."""
        from maps._se3_numba import relax_links_se3

        return int(relax_links_se3(order, ends, links, poses, c, n, start))

    def link_cost(self, link: np.ndarray) -> tuple[float, float]:
        """``(w_t m, w_r rad)`` of Eq 6.3: translation length and rotation angle of the link."""
        w_t = math.sqrt(float(link[0]) ** 2 + float(link[1]) ** 2 + float(link[2]) ** 2)
        w_r = float(Rotation.from_quat(link[3:7]).magnitude())
        return w_t, w_r

    def check_poses(self, poses: np.ndarray) -> str | None:
        """None when every saved quaternion is a unit quaternion, else the problem."""
        if len(poses) and np.abs(np.linalg.norm(poses[:, 3:7], axis=1) - 1.0).max() > 1e-6:
            return "holds quaternions that are not of unit norm"
        return None
