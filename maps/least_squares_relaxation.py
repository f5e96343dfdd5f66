"""Least-squares relaxation of an SE(2) experience map over every traversal, with view ties (Ch.3 maze).

Eq 2.25 (:meth:`maps.experience_map.ExperienceMap.iterate`) moves each experience a
fraction of the way towards where its links put it, link by link, with every link
counted once whatever it carries. This module instead finds the map poses that
best explain all the odometry the map holds, in the weighted least-squares sense,
with scipy's sparse trust-region solver (:func:`scipy.optimize.least_squares`):

* **links** - a link ``a -> b`` (:attr:`~maps.experience_map.ExperienceMap.links`:
  ``d``, ``heading``, ``facing``, ``dt``) says where ``b`` lies in ``a``'s frame,
  ``(d cos heading, d sin heading)`` m, and how it faces, ``facing`` rad. Its
  standard deviation grows as the square root of the odometry steps it spans,
  ``max(dt / step_s, 1)``, and shrinks as the square root of the traversals averaged
  into it (:attr:`~maps.experience_map.ExperienceMap.link_traversals`,
  ``MapConfig(link_update="average")``, :mod:`maps.link_average`);
* **view ties** (``tie_views``) - experiences created with the same local view are
  the same place (RatSLAM makes a second experience of a view when the pose-cell
  packet has drifted more than ``match_distance_cells`` from the first, Eq 2.22-2.24),
  so each is tied to the view's first experience with zero displacement and facing,
  standard deviations ``tie_sigma_m`` and ``tie_sigma_deg``. Without the ties two
  experiences of one place share the odometry of the traversals only through the
  links that happen to join them;
* the gauge: experience 0 keeps its pose.

Defaults (:class:`LeastSquaresConfig`) are the odometry errors of Sec 3.1.2 at the
study's 1.5 Hz: linear ``Lognormal(-4.3, 0.45)`` m per step with a random sign, rms
0.0166 m; angular ``N(8.39e-4, 0.3)`` deg per step. The tie's 1 cm is the sequence
matcher's measured precision (:mod:`cansim.frontends.tactile_sequence`).

Measured (Ch.3 maze, 8-loop route, perfect recognition - view ids from the true
places - tuning seeds 1000-1029): map / dead-reckoning error mean 0.268, largest
0.508 with Eq 2.25 and averaged links; 0.250 and 0.461 here. What neither can remove
is the along-track odometry error of a loop averaged over the four traversals of
each direction (the two directions meet only where the agent turns).

View ties trust the views: with a front end that aliases places (Table 3.1's one-image
Eq 3.1 matcher on the Ch.3 maze, 8 anticlockwise loops, seed 1) the ties pull different
places together - 0.235 m against dead reckoning's 0.338 m, Eq 2.25 0.059 m - while
``tie_views=False`` gives 0.059 m and ``loss="cauchy"`` 0.033 m.

The map itself is not changed: :func:`relax_least_squares` returns the poses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix

from maps.experience_map import ExperienceMap
from maps.se2 import SE2Geometry
from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, finite_array, validate_fields, whole_number

__all__ = ["LOSSES", "LeastSquaresConfig", "map_edges", "relax_least_squares", "solve_se2_graph", "view_ties"]

#: Robust losses of :func:`scipy.optimize.least_squares` accepted by :class:`LeastSquaresConfig`.
LOSSES: tuple[str, ...] = ("linear", "soft_l1", "huber", "cauchy")


@dataclass(frozen=True)
class LeastSquaresConfig(ConfigDataclass):
    """Noise model and options of :func:`relax_least_squares`.

    Parameters
    ----------
    step_s : float
        Duration of one odometry step, s (> 0; default 1 / 1.5 s, the Ch.3 iteration).
    sigma_m : float
        Translation standard deviation of one odometry step, m (> 0; Sec 3.1.2: 0.0166).
    sigma_deg : float
        Rotation standard deviation of one odometry step, deg (> 0; Sec 3.1.2: 0.3).
    tie_views : bool
        Tie the experiences of one local view together (module docstring; default True).
    tie_sigma_m : float
        Standard deviation of a view tie's displacement, m (> 0; default 0.01).
    tie_sigma_deg : float
        Standard deviation of a view tie's facing, deg (> 0; default 5).
    loss : {"linear", "soft_l1", "huber", "cauchy"}
        Loss on the whitened residuals (:func:`scipy.optimize.least_squares`); default
        ``"linear"`` (plain least squares).
    max_evaluations : int
        Most residual evaluations of the solver (>= 1; default 200).
    """

    step_s: float = checked(1.0 / 1.5, float, above=0, hint="seconds of one odometry step")
    sigma_m: float = checked(0.0166, float, above=0)
    sigma_deg: float = checked(0.3, float, above=0)
    tie_views: bool = checked(True, bool)
    tie_sigma_m: float = checked(0.01, float, above=0)
    tie_sigma_deg: float = checked(5.0, float, above=0)
    loss: str = checked("linear", str, choices=LOSSES)
    max_evaluations: int = checked(200, int, minimum=1)

    def __post_init__(self) -> None:
        validate_fields(self)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def solve_se2_graph(initial_poses: Any, ends: Any, relative: Any, sigma_m: Any, sigma_rad: Any, *, fixed: int = 0,
                    loss: str = "linear", max_evaluations: int = 200) -> np.ndarray:
    """Weighted least-squares poses of an SE(2) pose graph.

    Minimises ``sum_k rho(|(R(-theta_a) (p_b - p_a) - t_k) / sigma_m_k|^2 + (wrap(theta_b - theta_a - phi_k) / sigma_rad_k)^2)``
    over the poses, node ``fixed`` held at its initial pose.

    Parameters
    ----------
    initial_poses : array (n, 3)
        Starting poses ``(x m, y m, theta rad)``, finite; n >= 1.
    ends : array (m, 2) of int
        Edge ends ``(a, b)``, node indices in ``[0, n)``; parallel edges are allowed (each counts).
    relative : array (m, 3)
        Measured pose of ``b`` in ``a``'s frame: ``(x m, y m, phi rad)``, finite.
    sigma_m, sigma_rad : array (m,)
        Standard deviations of each edge's translation (per axis, m) and rotation (rad), > 0.
    fixed : int
        Node held at its initial pose (the gauge), in ``[0, n)``.
    loss : {"linear", "soft_l1", "huber", "cauchy"}
        Loss on the whitened residuals.
    max_evaluations : int
        Most residual evaluations, >= 1.

    Returns
    -------
    ndarray (n, 3)
        The poses, angles wrapped to [-pi, pi).

    Raises
    ------
    ShapeError, InvalidInputError
        Arrays of the wrong shape, non-finite values, ends or ``fixed`` out of range,
        non-positive standard deviations, an unknown loss.
    """
    p0 = finite_array(initial_poses, (None, 3), "initial_poses")
    n = p0.shape[0]
    if n < 1:
        raise InvalidInputError("initial_poses needs at least one pose")
    e = np.asarray(ends)
    if e.ndim != 2 or e.shape[1] != 2:
        raise ShapeError(f"ends must have shape (m, 2), got {e.shape}")
    if e.size and (not np.issubdtype(e.dtype, np.integer) or e.min() < 0 or e.max() >= n):
        raise InvalidInputError(f"ends must be integer node indices in [0, {n}); got values {e.min()}..{e.max()} of dtype {e.dtype}")
    m = e.shape[0]
    rel = finite_array(relative, (m, 3), "relative")
    s_m, s_r = finite_array(sigma_m, (m,), "sigma_m"), finite_array(sigma_rad, (m,), "sigma_rad")
    if np.any(s_m <= 0) or np.any(s_r <= 0):
        raise InvalidInputError("sigma_m and sigma_rad must be > 0 (standard deviations)")
    fixed = whole_number(fixed, "fixed", minimum=0)
    if fixed >= n:
        raise InvalidInputError(f"fixed must be a node index in [0, {n}), got {fixed}")
    max_evaluations = whole_number(max_evaluations, "max_evaluations", minimum=1)
    if loss not in LOSSES:
        raise InvalidInputError(f"loss must be one of {list(LOSSES)}, got {loss!r}")
    if m == 0 or n == 1:  # nothing to move: no edges, or the gauge is the only node
        return p0.copy()
    a, b = e[:, 0].astype(np.int64), e[:, 1].astype(np.int64)
    w_t, w_r = 1.0 / s_m, 1.0 / s_r
    free = np.ones(3 * n, dtype=bool)
    free[3 * fixed: 3 * fixed + 3] = False  # the gauge: node ``fixed`` is not a variable

    def full(z: np.ndarray) -> np.ndarray:
        x = p0.reshape(-1).copy()
        x[free] = z
        return x.reshape(n, 3)

    def residuals(z: np.ndarray) -> np.ndarray:
        p = full(z)
        c, s = np.cos(p[a, 2]), np.sin(p[a, 2])
        dx, dy = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
        return np.concatenate([
            (c * dx + s * dy - rel[:, 0]) * w_t,
            (-s * dx + c * dy - rel[:, 1]) * w_t,
            _wrap(p[b, 2] - p[a, 2] - rel[:, 2]) * w_r,
        ])

    def jacobian(z: np.ndarray) -> Any:
        p = full(z)
        c, s = np.cos(p[a, 2]), np.sin(p[a, 2])
        dx, dy = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
        k = np.arange(m)
        # (residual row, variable column, derivative) for each non-zero: r_x = (c dx + s dy - t_x) w_t,
        # r_y = (-s dx + c dy - t_y) w_t, r_theta = (theta_b - theta_a - phi) w_r
        entries = [
            (k, 3 * a, -c * w_t), (k, 3 * a + 1, -s * w_t), (k, 3 * b, c * w_t), (k, 3 * b + 1, s * w_t),
            (k, 3 * a + 2, (-s * dx + c * dy) * w_t),
            (m + k, 3 * a, s * w_t), (m + k, 3 * a + 1, -c * w_t), (m + k, 3 * b, -s * w_t), (m + k, 3 * b + 1, c * w_t),
            (m + k, 3 * a + 2, (-c * dx - s * dy) * w_t),
            (2 * m + k, 3 * a + 2, -w_r), (2 * m + k, 3 * b + 2, w_r),
        ]
        rows, cols, vals = (np.concatenate(part) for part in zip(*entries))
        jac = coo_matrix((vals, (rows, cols)), shape=(3 * m, 3 * n)).tocsc()  # duplicates (a self-loop a == b) add up, as the derivative does
        return jac[:, free]

    sol = least_squares(residuals, p0.reshape(-1)[free], jac=jacobian, method="trf", loss=loss, x_scale="jac",
                        max_nfev=max_evaluations, tr_solver="lsmr")
    out = full(sol.x)
    out[:, 2] = _wrap(out[:, 2])
    return out


def view_ties(view_ids: Any) -> np.ndarray:
    """Pairs ``(first, other)`` of experiences created with the same view: each later one tied to the view's first.

    Parameters
    ----------
    view_ids : array (n,) of int
        The view id of every experience (:attr:`~maps.experience_map.ExperienceMap.view_ids`).

    Returns
    -------
    ndarray (k, 2) of int64
        In order of the later experience.

    Raises
    ------
    ShapeError, InvalidInputError
        Not a 1-D array of integers.
    """
    v = np.asarray(view_ids)
    if v.ndim != 1:
        raise ShapeError(f"view_ids must be 1-D, got shape {v.shape}")
    if v.size and not np.issubdtype(v.dtype, np.integer):
        raise InvalidInputError(f"view_ids must be integers, got dtype {v.dtype}")
    first: dict[int, int] = {}
    pairs = []
    for i, view in enumerate(v.tolist()):
        if view in first:
            pairs.append((first[view], i))
        else:
            first[view] = i
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def map_edges(experience_map: ExperienceMap, config: LeastSquaresConfig | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pose-graph edges of an SE(2) experience map: its links, then (with ``tie_views``) the view ties.

    Returns
    -------
    ends : ndarray (m, 2) int64
    relative : ndarray (m, 3)
        ``(x m, y m, phi rad)`` of the edge's target in its source's frame.
    sigma_m, sigma_rad : ndarray (m,)
        Standard deviations (module docstring).

    Raises
    ------
    InvalidInputError
        Not an SE(2) :class:`~maps.experience_map.ExperienceMap`.
    """
    _check_map(experience_map)
    cfg = config if config is not None else LeastSquaresConfig()
    ends, data = experience_map.links
    scale = np.sqrt(np.maximum(data[:, 3] / cfg.step_s, 1.0) / np.maximum(experience_map.link_traversals, 1))
    relative = np.column_stack([data[:, 0] * np.cos(data[:, 1]), data[:, 0] * np.sin(data[:, 1]), data[:, 2]])
    sigma_m, sigma_rad = cfg.sigma_m * scale, math.radians(cfg.sigma_deg) * scale
    if cfg.tie_views:
        ties = view_ties(experience_map.view_ids)
        k = ties.shape[0]
        ends = np.vstack([ends, ties])
        relative = np.vstack([relative, np.zeros((k, 3))])
        sigma_m = np.r_[sigma_m, np.full(k, cfg.tie_sigma_m)]
        sigma_rad = np.r_[sigma_rad, np.full(k, math.radians(cfg.tie_sigma_deg))]
    return ends.astype(np.int64), relative, sigma_m, sigma_rad


def relax_least_squares(experience_map: ExperienceMap, config: LeastSquaresConfig | None = None) -> np.ndarray:
    """Least-squares map poses of an SE(2) experience map (module docstring); the map is not changed.

    Parameters
    ----------
    experience_map : ExperienceMap
        With :class:`~maps.se2.SE2Geometry` (RatSLAM's map, ``slam.experience_map``).
    config : LeastSquaresConfig, optional
        Noise model and options (defaults: Sec 3.1.2 at 1.5 Hz, view ties on).

    Returns
    -------
    ndarray (n, 3)
        ``(x m, y m, theta rad)`` per experience, experience 0 at its map pose; (0, 3) for an empty map.

    Raises
    ------
    InvalidInputError
        Not an SE(2) :class:`~maps.experience_map.ExperienceMap`.
    """
    _check_map(experience_map)
    cfg = config if config is not None else LeastSquaresConfig()
    poses = experience_map.poses
    if poses.shape[0] < 2:
        return poses
    ends, relative, sigma_m, sigma_rad = map_edges(experience_map, cfg)
    return solve_se2_graph(poses, ends, relative, sigma_m, sigma_rad, fixed=0, loss=cfg.loss, max_evaluations=cfg.max_evaluations)


def _check_map(experience_map: Any) -> None:
    if not isinstance(experience_map, ExperienceMap) or not isinstance(experience_map.geometry, SE2Geometry):
        raise InvalidInputError(f"relax_least_squares needs an ExperienceMap with SE2Geometry (RatSLAM's map), got {type(experience_map).__name__}")
