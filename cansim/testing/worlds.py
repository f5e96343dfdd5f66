"""Synthetic planar worlds for RatSLAM tests and demos (Ch.3 setup of the thesis).

A closed route (a rounded rectangle) is split into ``n_places`` places of equal
arc length. The agent visits them loop after loop, counter-clockwise (+1) or
clockwise (-1); reversing turns on the spot at place 0. Every iteration yields
the true pose, noisy odometry and a view: a *template id* that is the same
each time a place is passed in the same direction (whisker views differ with
direction), optionally with perceptual aliasing, and on request a small
rendered image of landmarks for the visual front end.

Odometry noise (Sec 3.1.2): per step the linear displacement error is
Lognormal(-4.3, 0.45) m and the angular error N(8.39e-4, 0.3) deg. The thesis
reports the linear error as strictly positive - the *magnitude* of the
odometry/ground-truth difference. Applied always positive it would be a pure
scale bias (every step 1.5 cm too long), which no SLAM method can remove and
which Fig 3.3 does not show; the decision here is a random sign per step
(``linear_sign="random"``), with ``linear_sign="positive"`` for the literal
reading. The linear error is applied on translating steps only.

Kidnapping (Fig 3.5): at iteration ``at`` the agent is carried ``skip``
iterations forward along its route without odometry for the jump. The noise is
drawn for the un-kidnapped run first, so a clean and a kidnapped run with the
same seed differ only by the kidnapping.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from cansim.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, validate_fields

__all__ = ["LoopRoute", "Ch3OdometryNoise", "SyntheticRun", "ch3_loops", "dead_reckon", "make_run", "render_view", "scatter_landmarks"]


@dataclass(frozen=True)
class Ch3OdometryNoise(ConfigDataclass):
    """Per-step odometry error model of Sec 3.1.2 of the thesis.

    Parameters
    ----------
    linear_mu, linear_sigma : float
        Lognormal parameters (of ln metres) of the linear error magnitude per step.
    angular_mean_deg, angular_std_deg : float
        Normal angular error per step, degrees.
    linear_sign : {"random", "positive"}
        Sign of the linear error (see the module docstring).
    """

    linear_mu: float = checked(-4.3, float, error=InvalidInputError)
    linear_sigma: float = checked(0.45, float, minimum=0, error=InvalidInputError)
    angular_mean_deg: float = checked(8.39e-4, float, error=InvalidInputError)
    angular_std_deg: float = checked(0.3, float, minimum=0, error=InvalidInputError)
    linear_sign: Literal["random", "positive"] = checked("random", str, choices=("random", "positive"), error=InvalidInputError)

    def __post_init__(self) -> None:
        validate_fields(self)


@dataclass(frozen=True)
class LoopRoute(ConfigDataclass):
    """A closed rounded-rectangle route, centred on the origin.

    Parameters
    ----------
    width_m, height_m : float
        Outer size, metres.
    corner_radius_m : float
        Radius of the rounded corners, metres (< half the smaller side).
    step_m : float
        Desired distance between places (one iteration), metres; the actual
        step is ``perimeter / n_places``.
    """

    width_m: float = checked(2.0, float, above=0, maximum=1e4, error=InvalidInputError)
    height_m: float = checked(1.2, float, above=0, maximum=1e4, error=InvalidInputError)
    corner_radius_m: float = checked(0.3, float, minimum=0, error=InvalidInputError)
    step_m: float = checked(0.05, float, above=0, error=InvalidInputError)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not (0 <= self.corner_radius_m < 0.5 * min(self.width_m, self.height_m)):
            raise InvalidInputError("corner_radius_m must be in [0, min(width, height)/2)")
        if self.perimeter / self.step_m > 1e6:
            raise InvalidInputError(f"step_m = {self.step_m} m makes over 10^6 places on this route; use a larger step")

    @property
    def perimeter(self) -> float:
        """Length of the route, metres."""
        r = self.corner_radius_m
        return 2 * (self.width_m - 2 * r) + 2 * (self.height_m - 2 * r) + 2 * math.pi * r

    @property
    def n_places(self) -> int:
        """Number of places (iterations per loop)."""
        return max(4, int(round(self.perimeter / self.step_m)))

    def places(self) -> np.ndarray:
        """Place positions, shape (n_places, 2), metres, counter-clockwise from the middle of the bottom side."""
        r, w, h = self.corner_radius_m, self.width_m, self.height_m
        a, b = w / 2 - r, h / 2 - r
        pts = []
        n_arc = 64
        corners = [((a, -b), -math.pi / 2), ((a, b), 0.0), ((-a, b), math.pi / 2), ((-a, -b), math.pi)]
        pts.append((0.0, -h / 2))
        for (cx, cy), start in corners:
            for k in range(n_arc + 1):
                ang = start + 0.5 * math.pi * k / n_arc
                pts.append((cx + r * math.cos(ang), cy + r * math.sin(ang)))
        pts.append((0.0, -h / 2))
        poly = np.array(pts)
        seg = np.hypot(*np.diff(poly, axis=0).T)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        targets = np.arange(self.n_places) * (s[-1] / self.n_places)
        return np.stack([np.interp(targets, s, poly[:, 0]), np.interp(targets, s, poly[:, 1])], axis=1)


def ch3_loops() -> tuple[int, ...]:
    """Loop directions of a Ch.3 run: 3 clockwise, 3 anticlockwise, then one of each (Sec 3.2)."""
    return (-1, -1, -1, 1, 1, 1, -1, 1)


@dataclass(frozen=True)
class SyntheticRun:
    """One synthetic run; row ``k`` of every array is iteration ``k``.

    Attributes
    ----------
    truth : ndarray (n, 3)
        True pose (x m, y m, theta rad) after iteration k's motion.
    vtrans : ndarray (n,)
        Measured forward speed, m/s (iteration 0: 0).
    vrot : ndarray (n,)
        Measured yaw rate, rad/s.
    dt : float
        Iteration period, s.
    view_ids : ndarray (n,) of int
        View-template id observed at iteration k.
    places : ndarray (n,) of int
        True place index (-1 while turning on the spot).
    directions : ndarray (n,) of int
        +1 counter-clockwise, -1 clockwise.
    dead_reckoning : ndarray (n, 3)
        Odometry integrated rotate-then-translate from ``truth[0]``.
    n_places : int
        Places per loop.
    kidnap_indices : tuple of int
        Iterations at which the agent landed after being kidnapped.
    loop_starts : tuple of int
        Iteration at which each loop starts (place 0, facing the loop's direction).
    """

    truth: np.ndarray
    vtrans: np.ndarray
    vrot: np.ndarray
    dt: float
    view_ids: np.ndarray
    places: np.ndarray
    directions: np.ndarray
    dead_reckoning: np.ndarray
    n_places: int
    kidnap_indices: tuple[int, ...] = ()
    loop_starts: tuple[int, ...] = field(default=())

    def __len__(self) -> int:
        return int(self.truth.shape[0])


def dead_reckon(start: np.ndarray, vtrans: np.ndarray, vrot: np.ndarray, dt: float) -> np.ndarray:
    """Integrate odometry rotate-then-translate from ``start`` (x, y, theta); returns (n, 3)."""
    theta = start[2] + np.cumsum(vrot * dt)
    dist = vtrans * dt
    x = start[0] + np.cumsum(dist * np.cos(theta))
    y = start[1] + np.cumsum(dist * np.sin(theta))
    return np.stack([x, y, (theta + math.pi) % (2 * math.pi) - math.pi], axis=1)


def make_run(
    route: LoopRoute | None = None,
    loops: Sequence[int] = (1, 1, 1, 1, 1),
    *,
    noise: Ch3OdometryNoise | None = Ch3OdometryNoise(),
    seed: int = 0,
    dt: float = 1.0,
    turn_steps: int = 6,
    aliasing: float = 0.0,
    kidnap: tuple[int, int] | Sequence[tuple[int, int]] | None = None,
) -> SyntheticRun:
    """Generate a multi-loop run with noisy odometry and per-place views.

    Parameters
    ----------
    route : LoopRoute, optional
        The route (default :class:`LoopRoute`).
    loops : sequence of {+1, -1}
        Direction of each loop: +1 counter-clockwise, -1 clockwise
        (:func:`ch3_loops` gives the Ch.3 sequence).
    noise : Ch3OdometryNoise or None
        Odometry error model; None = perfect odometry.
    seed : int
        Seed of ``np.random.default_rng``.
    dt : float
        Iteration period, s.
    turn_steps : int
        Iterations of an on-the-spot 180 deg turn between loops of opposite direction.
    aliasing : float
        Probability that a view is replaced by the view of a random other place (perceptual aliasing).
    kidnap : (at, skip) or sequence of them, optional
        Carry the agent forward by ``skip`` iterations of its route at iteration ``at``
        (indices of the un-kidnapped run; Fig 3.5).

    Returns
    -------
    SyntheticRun
    """
    route = route if route is not None else LoopRoute()
    if not loops or any(d not in (1, -1) for d in loops):
        raise InvalidInputError(f"loops must be a non-empty sequence of +1/-1, got {loops!r}")
    if not (dt > 0 and math.isfinite(dt)):
        raise InvalidInputError(f"dt must be > 0 s, got {dt!r}")
    if not 0.0 <= aliasing <= 1.0:
        raise InvalidInputError(f"aliasing must be a probability in [0, 1], got {aliasing!r}")
    if turn_steps < 1:
        raise InvalidInputError("turn_steps must be >= 1")
    rng = np.random.default_rng(seed)
    pts = route.places()
    n = pts.shape[0]

    # ---- true place sequence, positions and headings
    xs: list[float] = []
    ys: list[float] = []
    ths: list[float] = []
    places: list[int] = []
    dirs: list[int] = []
    views: list[int] = []
    loop_starts: list[int] = []
    prev_dir = loops[0]
    heading = math.atan2(*(pts[1] - pts[0])[::-1]) if prev_dir == 1 else math.atan2(*(pts[-1] - pts[0])[::-1])
    xs.append(float(pts[0, 0]))
    ys.append(float(pts[0, 1]))
    ths.append(heading)
    places.append(0)
    dirs.append(prev_dir)
    views.append(0 if prev_dir == 1 else n)
    for d in loops:
        if d != prev_dir:
            for j in range(1, turn_steps + 1):
                xs.append(xs[-1])
                ys.append(ys[-1])
                ths.append(ths[-1] + math.pi / turn_steps)
                places.append(-1)
                dirs.append(d)
                views.append(2 * n + (j - 1) + (0 if d == 1 else turn_steps))
        prev_dir = d
        loop_starts.append(len(xs) - 1)
        for k in range(1, n + 1):
            p = (k * d) % n
            dx, dy = pts[p, 0] - xs[-1], pts[p, 1] - ys[-1]
            ths.append(math.atan2(dy, dx))
            xs.append(float(pts[p, 0]))
            ys.append(float(pts[p, 1]))
            places.append(p)
            dirs.append(d)
            views.append(p if d == 1 else n + p)
    truth = np.stack([xs, ys, np.unwrap(ths)], axis=1)
    # true per-step motion (rotate then translate): iteration 0 does not move
    dist = np.concatenate([[0.0], np.hypot(*np.diff(truth[:, :2], axis=0).T)])
    dtheta = np.concatenate([[0.0], np.diff(truth[:, 2])])
    place_arr = np.array(places)
    view_arr = np.array(views, dtype=np.int64)
    dir_arr = np.array(dirs)

    # ---- views with aliasing, noisy odometry (drawn for the whole un-kidnapped run, so a
    # kidnapped variant with the same seed sees the same noise at the same iterations)
    m = truth.shape[0]
    if aliasing > 0:
        swap = rng.random(m) < aliasing
        view_arr = view_arr.copy()
        view_arr[swap] = rng.integers(0, 2 * n, int(swap.sum()))
    meas_dist, meas_dth = dist.copy(), dtheta.copy()
    if noise is not None:
        lin = rng.lognormal(noise.linear_mu, noise.linear_sigma, m)
        if noise.linear_sign == "random":
            lin *= rng.choice([-1.0, 1.0], m)
        ang = np.radians(rng.normal(noise.angular_mean_deg, noise.angular_std_deg, m))
        meas_dist = np.where(dist > 0, dist + lin, 0.0)
        meas_dth = dtheta + ang
        meas_dth[0] = 0.0

    # ---- kidnapping: drop the skipped iterations; the odometry of the landing
    # iteration is the ordinary step the agent believes it made
    kidnap_indices: list[int] = []
    events = [] if kidnap is None else ([kidnap] if np.ndim(kidnap) == 1 else list(kidnap))
    removed = 0
    keep = np.ones(m, dtype=bool)
    odo_src = np.arange(m)
    last = 0
    for at, skip in sorted((int(a), int(b)) for a, b in events):
        if not (1 <= at and skip >= 1 and at > last and at + skip < m):
            raise InvalidInputError(
                f"kidnap (at={at}, skip={skip}) must satisfy 1 <= at, skip >= 1, at + skip < {m}, "
                "events in increasing order without overlap"
            )
        keep[at : at + skip] = False
        odo_src[at + skip] = at
        kidnap_indices.append(at - removed)
        removed += skip
        last = at + skip
    meas_dist, meas_dth = meas_dist[odo_src][keep], meas_dth[odo_src][keep]
    truth, place_arr, view_arr, dir_arr = truth[keep], place_arr[keep], view_arr[keep], dir_arr[keep]
    new_index = np.cumsum(keep) - 1
    loop_starts = [int(new_index[s_]) for s_ in loop_starts if keep[s_]]
    vtrans, vrot = meas_dist / dt, meas_dth / dt
    truth_wrapped = truth.copy()
    truth_wrapped[:, 2] = (truth[:, 2] + math.pi) % (2 * math.pi) - math.pi
    dr = dead_reckon(truth[0], vtrans, vrot, dt)
    return SyntheticRun(
        truth=truth_wrapped, vtrans=vtrans, vrot=vrot, dt=float(dt), view_ids=view_arr, places=place_arr,
        directions=dir_arr, dead_reckoning=dr, n_places=n, kidnap_indices=tuple(kidnap_indices), loop_starts=tuple(loop_starts),
    )


def scatter_landmarks(route: LoopRoute, n: int = 40, seed: int = 0, margin_m: float = 0.6) -> np.ndarray:
    """Random landmarks around a route: rows (x m, y m, brightness in [0.2, 1], height in [0.3, 1])."""
    rng = np.random.default_rng(seed)
    w, h = route.width_m / 2 + margin_m, route.height_m / 2 + margin_m
    return np.stack(
        [rng.uniform(-w, w, n), rng.uniform(-h, h, n), rng.uniform(0.2, 1.0, n), rng.uniform(0.3, 1.0, n)], axis=1
    )


def render_view(
    pose: Sequence[float], landmarks: np.ndarray, shape: tuple[int, int] = (20, 80), fov_rad: float = 2 * math.pi
) -> np.ndarray:
    """Render a small grey image of the landmarks seen from ``pose``.

    Column ``c`` looks at bearing ``theta + fov/2 - (c + 0.5) fov / W`` (left to
    right); a landmark at distance ``r`` appears as a vertical bar of angular
    width ~ 0.15 rad / (r + 0.3), height proportional to its height / (r + 0.3)
    and its brightness. With ``fov_rad = 2 pi`` the image is panoramic: turning
    the agent shifts the columns circularly.

    Parameters
    ----------
    pose : (x m, y m, theta rad)
    landmarks : array (L, 4)
        From :func:`scatter_landmarks`.
    shape : (H, W)
        Image size in pixels.
    fov_rad : float
        Horizontal field of view, rad.

    Returns
    -------
    uint8 array (H, W)
    """
    hgt, wid = int(shape[0]), int(shape[1])
    x, y, th = (float(v) for v in pose)
    bearings = th + fov_rad / 2 - (np.arange(wid) + 0.5) * fov_rad / wid
    dx, dy = landmarks[:, 0] - x, landmarks[:, 1] - y
    r = np.hypot(dx, dy) + 0.3
    ang = np.arctan2(dy, dx)
    diff = (bearings[None, :] - ang[:, None] + math.pi) % (2 * math.pi) - math.pi  # (L, W)
    width = 0.15 / r
    weight = np.exp(-0.5 * (diff / width[:, None]) ** 2) * landmarks[:, 2:3]  # (L, W)
    bar_top = np.clip(landmarks[:, 3] / r, 0.0, 1.0) * hgt  # rows covered from the bottom
    rows = (hgt - np.arange(hgt) - 0.5)[:, None, None]  # (H, 1, 1) height above bottom
    covered = (rows < bar_top[None, :, None]).astype(np.float64)  # (H, L, 1)
    img = 0.1 + (covered * weight[None, :, :]).max(axis=1)
    return np.clip(np.round(img * 255.0), 0, 255).astype(np.uint8)
