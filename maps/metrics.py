"""SLAM performance metrics of Ch.3 of the thesis: Experience Metric (Alg 1), Energy Metric (Eq 3.2-3.3), ATE.

* :func:`experience_metric` - Average Rate of Re-localisation (ARR) and Average
  Rate of Correct Re-localisation (ARCR), Alg 1 (Sec 3.2.3.1).
* :func:`energy_metric` - mean squared translational + rotational error of
  relative relations (Eq 3.2-3.3, Kuemmerle et al. 2009).
* :func:`absolute_trajectory_error` - RMSE of positions after the 2-D rigid
  alignment (rotation + translation, no scale) that minimises it (Horn/Umeyama).

Poses are planar: ``(x m, y m, theta rad)`` rows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from whisker_io.angles import wrap_to_pi
from whisker_io.errors import InvalidInputError

__all__ = [
    "AlignmentResult",
    "EnergyMetricResult",
    "ExperienceMetricResult",
    "absolute_trajectory_error",
    "energy_metric",
    "experience_metric",
    "relative_pose",
]


def _poses(name: str, poses: np.ndarray | Sequence[Sequence[float]], n: int | None = None) -> np.ndarray:
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InvalidInputError(f"{name} must have shape (n, 3) = (x m, y m, theta rad) rows, got {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise InvalidInputError(f"{name} has {arr.shape[0]} rows, expected {n} (one per log entry)")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name} holds NaN or infinite values; remove those samples first")
    return arr


@dataclass(frozen=True)
class ExperienceMetricResult:
    """Result of :func:`experience_metric` (Alg 1).

    Attributes
    ----------
    arr : float
        Average rate of re-localisation ``eta / eta_exp``.
    arcr : float
        Average rate of correct re-localisation ``eta_c / eta`` (NaN when eta = 0).
    n_relocalisations : int
        ``eta``.
    n_correct : int
        ``eta_c``.
    n_after_base : int
        ``eta_exp = len(E) - i_base``.
    relocalisation_indices : tuple of int
        0-based log indices counted as re-localisations.
    correct_indices : tuple of int
        0-based log indices counted as correct re-localisations.
    """

    arr: float
    arcr: float
    n_relocalisations: int
    n_correct: int
    n_after_base: int
    relocalisation_indices: tuple[int, ...]
    correct_indices: tuple[int, ...]


def experience_metric(
    experience_log: Sequence[int] | np.ndarray,
    ground_truth: np.ndarray | Sequence[Sequence[float]],
    base_end: int,
    pos_threshold: float = 0.1,
    angle_threshold_deg: float = 25.0,
    *,
    combine: Literal["or", "and"] = "or",
    wrap_angles: bool = True,
    perceived: Literal["first", "last"] = "first",
    inclusive: bool = True,
) -> ExperienceMetricResult:
    """Experience Metric: ARR and ARCR, Alg 1 of the thesis (Sec 3.2.3.1) read with its text.

    Parameters
    ----------
    experience_log : sequence of int, length n
        ``E``: the active experience id at every RatSLAM iteration.
    ground_truth : array (n, 3)
        ``P``: true pose (x m, y m, theta rad) at every iteration.
    base_end : int
        ``i_base``: the (1-based) index of the last entry of the base set, i.e.
        the number of log entries forming the initial loop (>= 1, < n).
    pos_threshold : float
        ``delta_p``, metres (default 0.1).
    angle_threshold_deg : float
        ``delta_theta``, degrees (default 25).
    combine : {"or", "and"}
        How line 25 combines ``c1`` (a re-localisation to a valid experience
        within the thresholds) and ``c2`` (staying on an experience that was
        correctly re-localised to). The printed Alg 1 says ``c1 and c2``; since
        ``R_c`` starts empty that can never be true and ARCR would always be 0,
        contradicting Fig 3.5, so the default is ``"or"``. ``"and"`` gives the
        literal text.
    wrap_angles : bool
        Line 22 takes ``abs(theta_true - theta_perceived)``; with True (default)
        the difference is wrapped to [-pi, pi) first, so headings either side
        of +-180 deg compare as close. False = literal.
    perceived : {"first", "last"}
        Which earlier pose of ``e_i`` is its "perceived" pose. The text of Sec 3.2.3.1
        says the true pose "at the time at which the experience was first generated":
        ``"first"`` (default). The printed line 18 takes the *last* earlier time ``e_i``
        was active: ``"last"``. They differ once an experience has been re-localised to
        from a drifted pose: with ``"last"`` a chain of small drifts each passes the
        thresholds while the experience wanders from where it was made.
    inclusive : bool
        True (default): a re-localisation is correct when its errors "do not exceed"
        ``pos_threshold`` and ``angle_threshold_deg`` (the text), i.e. ``<=``. False: the
        printed line 23's strict ``<``.

    Returns
    -------
    ExperienceMetricResult

    Notes
    -----
    Line by line (0-based here): the base set ``C`` is the set of ids in
    ``E[:i_base]``. For every later entry ``i`` it is a re-localisation
    (``r1 and not r2``) when ``e_i`` occurred before and it is not merely a
    stay on the previous experience that was not itself a re-localisation
    target. Each re-localisation is judged against the ground truth at the
    time ``e_i`` was first active (its "perceived" pose; ``perceived="last"``: the
    last earlier time). While the
    last judged re-localisation was correct (``rc``), the previous experience
    joins the valid set ``C``; after an incorrect one, new experiences are
    invalid until a correct re-localisation.
    """
    log = np.asarray(experience_log)
    if log.ndim != 1 or not np.issubdtype(log.dtype, np.integer):
        raise InvalidInputError(f"experience_log must be a 1-D sequence of integer ids, got dtype {log.dtype} shape {log.shape}")
    n = log.shape[0]
    truth = _poses("ground_truth", ground_truth, n)
    if not (isinstance(base_end, (int, np.integer)) and 1 <= base_end < n):
        raise InvalidInputError(f"base_end must be an integer in [1, {n - 1}] (entries in the base set), got {base_end!r}")
    if combine not in ("or", "and"):
        raise InvalidInputError(f"combine must be 'or' or 'and', got {combine!r}")
    if perceived not in ("first", "last"):
        raise InvalidInputError(f"perceived must be 'first' or 'last', got {perceived!r}")
    if not isinstance(inclusive, (bool, np.bool_)):
        raise InvalidInputError(f"inclusive must be True or False, got {inclusive!r}")
    if not (pos_threshold > 0 and angle_threshold_deg > 0):
        raise InvalidInputError("pos_threshold and angle_threshold_deg must be > 0")
    ang_thr = math.radians(angle_threshold_deg)
    ids = log.tolist()
    valid = set(ids[:base_end])  # C
    reloc_set: set[int] = set()  # R (membership is all Alg 1 needs)
    correct_set: set[int] = set()  # R_c
    seen: dict[int, int] = {}  # the perceived pose's index of every id seen: its first or its last time
    for j in range(base_end):
        if perceived == "last" or ids[j] not in seen:
            seen[ids[j]] = j
    within = (lambda err, limit: err <= limit) if inclusive else (lambda err, limit: err < limit)
    reloc_idx: list[int] = []
    correct_idx: list[int] = []
    rc = True
    for i in range(base_end, n):
        e_prev, e_i = ids[i - 1], ids[i]
        r1 = e_i in seen  # e_i in E_past = E[:i]
        r2 = e_i == e_prev and e_prev not in reloc_set
        if r1 and not r2:
            reloc_set.add(e_i)
            reloc_idx.append(i)
        if e_i in reloc_set:
            i_past = seen[e_i]
            eps_p = math.hypot(truth[i, 0] - truth[i_past, 0], truth[i, 1] - truth[i_past, 1])
            dth = truth[i, 2] - truth[i_past, 2]
            eps_th = abs(float(wrap_to_pi(dth))) if wrap_angles else abs(dth)
            c1 = e_i in valid and within(eps_p, pos_threshold) and within(eps_th, ang_thr)
            c2 = e_i == e_prev and e_prev in correct_set
            if (c1 or c2) if combine == "or" else (c1 and c2):
                correct_set.add(e_i)
                correct_idx.append(i)
                rc = True
            else:
                rc = False
        if rc and e_prev not in valid:
            valid.add(e_prev)
        if perceived == "last" or e_i not in seen:
            seen[e_i] = i
    eta, eta_c, eta_exp = len(reloc_idx), len(correct_idx), n - base_end
    return ExperienceMetricResult(
        arr=eta / eta_exp,
        arcr=eta_c / eta if eta else math.nan,
        n_relocalisations=eta,
        n_correct=eta_c,
        n_after_base=eta_exp,
        relocalisation_indices=tuple(reloc_idx),
        correct_indices=tuple(correct_idx),
    )


def relative_pose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``b (-) a`` in SE(2) (Eq 3.3): pose of ``b`` in the frame of ``a``, rows (x, y, theta).

    Parameters
    ----------
    a, b : array (..., 3)
        Poses (x m, y m, theta rad).

    Returns
    -------
    array (..., 3)
        ``(R(theta_a)^T (t_b - t_a), wrap(theta_b - theta_a))``.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_to_pi(b[..., 2] - a[..., 2])], axis=-1)


@dataclass(frozen=True)
class EnergyMetricResult:
    """Result of :func:`energy_metric`.

    Attributes
    ----------
    energy : float
        ``epsilon`` of Eq 3.2 = ``translational + rotational`` (m^2 + rad^2).
    translational : float
        Mean squared translational error of the relations, m^2.
    rotational : float
        Mean squared rotational error of the relations, rad^2.
    n_relations : int
        ``N``.
    """

    energy: float
    translational: float
    rotational: float
    n_relations: int


def energy_metric(
    estimated: np.ndarray | Sequence[Sequence[float]],
    ground_truth: np.ndarray | Sequence[Sequence[float]],
    pairs: np.ndarray | Sequence[tuple[int, int]] | None = None,
) -> EnergyMetricResult:
    """Energy Metric (Eq 3.2-3.3 of the thesis, Kuemmerle et al. 2009).

    ``epsilon = 1/N sum_(i,j) trans(d_ij (-) d*_ij)^2 + rot(d_ij (-) d*_ij)^2`` with
    ``d_ij = x_j (-) x_i`` the relative transformation between two estimated
    poses and ``d*_ij`` the same between the corresponding true poses.

    Parameters
    ----------
    estimated, ground_truth : array (n, 3)
        Estimated and true poses (x m, y m, theta rad), row k of both for the same sample.
    pairs : array (N, 2) of int, optional
        The relations (i, j); default the consecutive pairs (k, k+1).

    Returns
    -------
    EnergyMetricResult
    """
    est = _poses("estimated", estimated)
    truth = _poses("ground_truth", ground_truth, est.shape[0])
    if pairs is None:
        if est.shape[0] < 2:
            raise InvalidInputError("energy_metric needs at least 2 poses")
        idx = np.stack([np.arange(est.shape[0] - 1), np.arange(1, est.shape[0])], axis=1)
    else:
        idx = np.asarray(pairs)
        if idx.ndim != 2 or idx.shape[1] != 2 or idx.shape[0] == 0 or not np.issubdtype(idx.dtype, np.integer):
            raise InvalidInputError(f"pairs must be a non-empty (N, 2) integer array, got shape {idx.shape}")
        if idx.min() < 0 or idx.max() >= est.shape[0]:
            raise InvalidInputError(f"pairs index outside the {est.shape[0]} poses")
    d = relative_pose(est[idx[:, 0]], est[idx[:, 1]])
    d_true = relative_pose(truth[idx[:, 0]], truth[idx[:, 1]])
    err = relative_pose(d_true, d)
    trans = float(np.mean(err[:, 0] ** 2 + err[:, 1] ** 2))
    rot = float(np.mean(err[:, 2] ** 2))
    return EnergyMetricResult(energy=trans + rot, translational=trans, rotational=rot, n_relations=int(idx.shape[0]))


@dataclass(frozen=True)
class AlignmentResult:
    """Result of :func:`absolute_trajectory_error`.

    Attributes
    ----------
    rmse : float
        Root-mean-square position error after alignment, metres.
    rotation_rad : float
        Rotation of the best alignment applied to the estimate, rad.
    translation : tuple of float
        Translation (m) applied after the rotation.
    aligned : ndarray (n, 2)
        The aligned estimated positions.
    """

    rmse: float
    rotation_rad: float
    translation: tuple[float, float]
    aligned: np.ndarray


def absolute_trajectory_error(
    estimated_xy: np.ndarray | Sequence[Sequence[float]], true_xy: np.ndarray | Sequence[Sequence[float]]
) -> AlignmentResult:
    """Absolute trajectory error: RMSE after the best 2-D rigid alignment (Horn 1987 / Umeyama 1991, no scale).

    Finds ``R(phi), t`` minimising ``sum |R p_k + t - q_k|^2`` in closed form:
    ``phi = atan2(sum p'_k x q'_k, sum p'_k . q'_k)`` on centred points.

    Parameters
    ----------
    estimated_xy, true_xy : array (n, 2)
        Estimated and true positions, metres (extra columns such as theta are ignored).

    Returns
    -------
    AlignmentResult
    """
    p = np.asarray(estimated_xy, dtype=np.float64)
    q = np.asarray(true_xy, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] < 2 or q.shape[:1] != p.shape[:1] or q.ndim != 2 or q.shape[1] < 2 or p.shape[0] == 0:
        raise InvalidInputError(f"estimated_xy and true_xy must be (n, 2) arrays of equal n, got {p.shape} and {q.shape}")
    p, q = p[:, :2], q[:, :2]
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise InvalidInputError("trajectories hold NaN or infinite values")
    pc, qc = p - p.mean(axis=0), q - q.mean(axis=0)
    phi = math.atan2(float(np.sum(pc[:, 0] * qc[:, 1] - pc[:, 1] * qc[:, 0])), float(np.sum(pc[:, 0] * qc[:, 0] + pc[:, 1] * qc[:, 1])))
    rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
    t = q.mean(axis=0) - rot @ p.mean(axis=0)
    aligned = p @ rot.T + t
    rmse = float(np.sqrt(np.mean(np.sum((aligned - q) ** 2, axis=1))))
    return AlignmentResult(rmse=rmse, rotation_rad=phi, translation=(float(t[0]), float(t[1])), aligned=aligned)
