"""6-D localisation errors of WhiskerRatSLAM (thesis Sec 5.2.2.1) and the step size between whisks.

Poses are positions (m) and unit quaternions, scalar-last ``[x, y, z, w]``.

* position error: Euclidean distance (m);
* rotation error: the angle of ``q_est^-1 q_gt``, ``2 acos |<q_est, q_gt>|`` in [0, pi] rad.

Two readings of an experience log against ground truth:

* :func:`relocalisation_errors` (the primary one, frame-free like Alg 1): at each
  re-localisation to experience ``e``, the distance between the true pose now and the
  true pose when ``e`` was created - how far the array really is from the place the
  map says it has returned to;
* :func:`map_pose_errors`: the map pose of the current experience at every iteration
  against the true pose, both expressed relative to the first experience.

:func:`step_sizes` gives the translation and rotation between successive observation
poses: the thesis' pass mark is an error below the step size (~11 cm and 12 deg; Box
~3 cm and 3 deg).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError, ShapeError

__all__ = ["LocalisationErrors", "rotation_error_rad", "relocalisation_errors", "map_pose_errors", "step_sizes"]


def _positions(p: np.ndarray, name: str, n: int | None = None) -> np.ndarray:
    arr = np.asarray(p, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or (n is not None and arr.shape[0] != n):
        raise ShapeError(f"{name} must have shape ({'n' if n is None else n}, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise InvalidInputError(f"{name} must be finite")
    return arr


def _quats(q: np.ndarray, name: str, n: int | None = None) -> np.ndarray:
    arr = np.asarray(q, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 4 or (n is not None and arr.shape[0] != n):
        raise ShapeError(f"{name} must have shape ({'n' if n is None else n}, 4) (scalar-last quaternions), got {arr.shape}")
    if not np.isfinite(arr).all() or np.abs(np.linalg.norm(arr, axis=1) - 1.0).max(initial=0.0) > 1e-6:
        raise InvalidInputError(f"{name} must hold finite unit quaternions")
    return arr


def rotation_error_rad(q_est: np.ndarray, q_gt: np.ndarray) -> np.ndarray:
    """Angle of ``q_est^-1 q_gt`` (rad, in [0, pi]) for (n, 4) or (4,) scalar-last quaternions."""
    a, b = np.atleast_2d(q_est), np.atleast_2d(q_gt)
    a, b = _quats(a, "q_est"), _quats(b, "q_gt", len(a))
    dot = np.clip(np.abs(np.sum(a * b, axis=1)), 0.0, 1.0)
    out = 2.0 * np.arccos(dot)
    return out if np.ndim(q_est) == 2 else out[0]


@dataclass(frozen=True)
class LocalisationErrors:
    """Errors at selected iterations.

    Attributes
    ----------
    iterations : ndarray (k,) int64
        Where each error was taken.
    position_m : ndarray (k,)
    rotation_rad : ndarray (k,)
    """

    iterations: np.ndarray
    position_m: np.ndarray
    rotation_rad: np.ndarray

    @property
    def median_position_m(self) -> float:
        """Median position error (m); NaN when there is none."""
        return float(np.median(self.position_m)) if len(self.position_m) else float("nan")

    @property
    def median_rotation_deg(self) -> float:
        """Median rotation error (deg); NaN when there is none."""
        return float(np.degrees(np.median(self.rotation_rad))) if len(self.rotation_rad) else float("nan")


def _log(exp_ids: np.ndarray, n: int) -> np.ndarray:
    e = np.asarray(exp_ids)
    if e.shape != (n,) or e.dtype.kind not in "iu":
        raise ShapeError(f"exp_ids must be {n} integers (one per iteration), got {e.shape} {e.dtype}")
    return e.astype(np.int64)


def _truth_and_log(true_p: np.ndarray, true_q: np.ndarray, exp_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated ground truth (n, 3), (n, 4) and experience log (n,)."""
    p = _positions(true_p, "true_position_m")
    return p, _quats(true_q, "true_quaternion_xyzw", len(p)), _log(exp_ids, len(p))


def relocalisation_errors(
    exp_ids: np.ndarray, relocalised: np.ndarray, true_position_m: np.ndarray, true_quaternion_xyzw: np.ndarray
) -> LocalisationErrors:
    """At each re-localisation: true pose now vs true pose when that experience was created.

    Parameters
    ----------
    exp_ids : (n,) int
        Current experience per iteration (-1 before the first).
    relocalised : (n,) bool
        The iteration re-localised.
    true_position_m : (n, 3)
    true_quaternion_xyzw : (n, 4)
        Ground truth per iteration.
    """
    p, q, e = _truth_and_log(true_position_m, true_quaternion_xyzw, exp_ids)
    n = len(p)
    r = np.asarray(relocalised, dtype=bool)
    if r.shape != (n,):
        raise ShapeError(f"relocalised must have shape ({n},), got {r.shape}")
    first: dict[int, int] = {}
    for k, x in enumerate(e.tolist()):
        if x >= 0:
            first.setdefault(x, k)
    ks = np.array([k for k in np.flatnonzero(r) if e[k] >= 0], dtype=np.int64)
    made = np.array([first[int(e[k])] for k in ks], dtype=np.int64)
    if not len(ks):
        return LocalisationErrors(ks, np.zeros(0), np.zeros(0))
    return LocalisationErrors(ks, np.linalg.norm(p[ks] - p[made], axis=1), rotation_error_rad(q[ks], q[made]))


def map_pose_errors(
    exp_ids: np.ndarray, map_poses: np.ndarray, true_position_m: np.ndarray, true_quaternion_xyzw: np.ndarray
) -> LocalisationErrors:
    """Map pose of the current experience vs ground truth, both relative to the first experience.

    Parameters
    ----------
    exp_ids : (n,) int
        Current experience per iteration (-1 before the first).
    map_poses : (n_exp, 7)
        Object-map poses ``(x, y, z, qx, qy, qz, qw)`` (after relaxation).
    true_position_m, true_quaternion_xyzw : (n, 3), (n, 4)
        Ground truth per iteration.
    """
    p, q, e = _truth_and_log(true_position_m, true_quaternion_xyzw, exp_ids)
    mp = np.asarray(map_poses, dtype=np.float64)
    if mp.ndim != 2 or mp.shape[1] != 7:
        raise ShapeError(f"map_poses must have shape (n_exp, 7), got {mp.shape}")
    valid = np.flatnonzero(e >= 0)
    if not len(valid):
        return LocalisationErrors(valid, np.zeros(0), np.zeros(0))
    if e.max() >= len(mp):
        raise InvalidInputError(f"exp_ids refer to experience {int(e.max())} of a map with {len(mp)}")
    k0 = int(valid[0])
    m0 = Rotation.from_quat(mp[e[k0], 3:])
    t0 = Rotation.from_quat(q[k0])
    est_p = m0.inv().apply(mp[e[valid], :3] - mp[e[k0], :3])
    true_p = t0.inv().apply(p[valid] - p[k0])
    est_q = (m0.inv() * Rotation.from_quat(mp[e[valid], 3:])).as_quat()
    true_q = (t0.inv() * Rotation.from_quat(q[valid])).as_quat()
    return LocalisationErrors(valid.astype(np.int64), np.linalg.norm(est_p - true_p, axis=1), rotation_error_rad(est_q, true_q))


def step_sizes(position_m: np.ndarray, quaternion_xyzw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation (m) and rotation (rad) between successive poses, each (n - 1,)."""
    p = _positions(position_m, "position_m")
    q = _quats(quaternion_xyzw, "quaternion_xyzw", len(p))
    if len(p) < 2:
        return np.zeros(0), np.zeros(0)
    return np.linalg.norm(np.diff(p, axis=0), axis=1), rotation_error_rad(q[:-1], q[1:])
