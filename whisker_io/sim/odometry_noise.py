"""Odometry of the arm between two whisks, exact or with the noise model of Sec 6.1.3.1.1.

WhiskerRatSLAM's odometry input is ``o = [v, omega, dt]`` (Eq 5.7): a linear
velocity ``v`` (3,) in m/s, an angular velocity ``omega`` (3,) in rad/s (a
rotation-vector rate, ``omega = omega e``) and a duration ``dt`` in s. Both
vectors are expressed in the **body frame**: the end-effector frame at the start
of the step (the pose of the previous whisk). Integrating them as the object map
does (Alg 6 and the frame-correct Eq 5.13),

    q <- q * exp(omega dt),        d <- d + R(q_before) v dt,

that is ``pose_next = pose_prev @ Pose.from_rotvec(v dt, omega dt)``
(:func:`integrate_odometry`), reproduces the step exactly for
:func:`exact_odometry` and the noisy step ``T_{i-1} @ (delta_eta, R_eta)`` for
:func:`noisy_odometry`.

The noise model (Eq 6.4-6.11, in this order)
--------------------------------------------
1. ``T = T_{i-1}^-1 T_i`` (Eq 6.4); ``R = T[:3, :3]`` (Eq 6.5), ``delta = T[:3, 3]``.
2. ``omega ~ N(0.03, 0.0087)`` rad/s, the angular speed observed in the physical
   data set of Sec 5.2.
3. ``R_eta = R R_noise`` (Eq 6.6): ``R_noise`` from Euler angles each drawn from
   ``N(0, 2.5 deg)`` with scipy ``Rotation.from_euler("xyz", ...)`` (extrinsic
   roll-pitch-yaw, the convention used everywhere in this library), right-multiplied.
4. The axis-angle ``(e_eta, theta_eta)`` of ``R_eta``; ``omega_eta = omega e_eta`` (Eq 6.7).
5. ``dt = theta_eta / omega`` (Eq 6.8).
6. ``|delta_eta| = |delta| + N(0, 1 cm)``, ``delta_eta = delta |delta_eta| / |delta|`` (Eq 6.9).
7. ``v_eta = delta_eta / dt`` (Eq 6.10); the odometry is ``[v_eta, omega_eta, dt]`` (Eq 6.11).

Guards (decisions; the thesis does not meet these cases)
--------------------------------------------------------
* ``omega <= 0``: a draw that is not positive is drawn again (the normal
  truncated at 0; with a positive mean each draw is accepted with probability
  >= 1/2). After :data:`MAX_SPEED_DRAWS` rejections the mean is used.
* ``theta_eta ~ 0`` (no rotation, e.g. a pure translation without rotation
  noise): Eq 6.8 gives ``dt -> 0`` and Eq 6.10 an infinite ``v``. ``dt`` is
  floored at :attr:`OdometryNoise.min_dt_s` and ``omega_eta = theta_eta e_eta / dt``,
  which is Eq 6.7 whenever the floor is not active; ``omega_eta dt`` is the
  rotation ``R_eta`` either way, so the integrated step is unchanged.
* ``|delta| = 0`` (a pure rotation): the direction of Eq 6.9 is undefined; the
  displacement stays zero (no magnitude noise is added to a step that does not
  translate).
* ``|delta_eta| < 0`` (the noise exceeds the step, about 0.1 % of 3-cm steps): the
  magnitude is clipped at 0 (the step becomes a pure rotation; reflecting it
  would reverse the motion).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError
from whisker_io.pose import Pose, PoseLike, as_pose
from whisker_io.validation import ConfigDataclass, MAX_STEP_M, checked, finite_scalar, finite_vector, scaled_fields, validate_fields

__all__ = [
    "MAX_SPEED_DRAWS",
    "MAX_STEP_M",
    "OdometryNoise",
    "relative_motion",
    "exact_odometry",
    "noisy_odometry",
    "integrate_odometry",
]

#: Draws of the angular speed before :func:`noisy_odometry` falls back to the mean (guard ``omega <= 0``).
MAX_SPEED_DRAWS: int = 64

_ZERO_DISPLACEMENT_M = 1e-12


@dataclass(frozen=True)
class OdometryNoise(ConfigDataclass):
    """Parameters of the odometry noise of Sec 6.1.3.1.1 (Eq 6.4-6.11).

    Attributes
    ----------
    angular_speed_mean_rad_s : float
        Mean of the drawn angular speed ``omega``, rad/s (thesis 0.03). Must be > 0.
    angular_speed_std_rad_s : float
        Its standard deviation, rad/s (thesis 0.0087).
    euler_std_rad : float
        Standard deviation of each Euler angle of the rotation noise ``R_noise``,
        rad (thesis 2.5 deg).
    displacement_std_m : float
        Standard deviation of the displacement-magnitude noise, m (thesis 1 cm).
    min_dt_s : float
        Floor of ``dt`` (guard for ``theta_eta ~ 0``, see the module docstring), s.
        Default 0.01 s.

    :meth:`noise_free` gives the same model with every standard deviation 0.
    """

    angular_speed_mean_rad_s: float = checked(0.03, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                              message="{name} must be > 0 rad/s, got {value!r}")
    angular_speed_std_rad_s: float = checked(0.0087, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                             message="{name} must be >= 0, got {value!r}")
    euler_std_rad: float = checked(math.radians(2.5), float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                   message="{name} must be >= 0, got {value!r}")
    displacement_std_m: float = checked(0.01, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                        message="{name} must be >= 0, got {value!r}")
    min_dt_s: float = checked(0.01, float, above=0, error=InvalidInputError, reader=finite_scalar,
                              message="{name} must be > 0 s, got {value!r}")

    def __post_init__(self) -> None:
        validate_fields(self)

    def noise_free(self) -> OdometryNoise:
        """The same model without noise: ``omega`` = its mean, no rotation or displacement noise."""
        return OdometryNoise(self.angular_speed_mean_rad_s, 0.0, 0.0, 0.0, self.min_dt_s)

    def scaled(self, scale: float) -> OdometryNoise:
        """This noise with its rotation and displacement deviations multiplied by ``scale``.

        ``OdometryNoise().scaled(s)`` is ``s`` times Eq 6.6's and Eq 6.9's noise: each Euler
        angle N(0, 2.5 s deg), the displacement's magnitude N(0, s cm); the drawn angular speed
        (which sets ``dt``) is kept, as in :meth:`ContactNoise.scaled
        <whisker_io.sim.sweep.ContactNoise.scaled>`. ``scaled(0)`` is exact odometry, ``scaled(1)``
        an equal copy.

        Parameters
        ----------
        scale : float
            Factor, finite and >= 0 (dimensionless).

        Raises
        ------
        InvalidInputError
            A scale that is not a finite number >= 0 (or a bool), or that makes a deviation overflow.
        """
        return scaled_fields(self, scale, ("euler_std_rad", "displacement_std_m"))


def _generator(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise InvalidInputError(
            f"rng must be a numpy Generator (np.random.default_rng(seed)), got {type(rng).__name__}; "
            "pass one generator to every step so the noise differs between steps")
    return rng


def relative_motion(pose_prev: PoseLike, pose_next: PoseLike) -> tuple[NDArray[np.float64], Rotation]:
    """The step ``T_{i-1}^-1 T_i`` (Eq 6.4-6.5) in the body frame of ``pose_prev``.

    Returns
    -------
    delta_m : ndarray (3,)
        Displacement, m, in the end-effector frame of ``pose_prev``.
    rotation : scipy Rotation
        ``R = R_{i-1}^T R_i``.

    Raises
    ------
    InvalidInputError
        A pose that is not a valid :data:`~whisker_io.pose.PoseLike` (NaN/inf, a
        non-unit quaternion, a reflection), or a step longer than :data:`MAX_STEP_M`.
    """
    a, b = as_pose(pose_prev), as_pose(pose_next)
    inv = a.rotation.inv()
    with np.errstate(over="ignore", invalid="ignore"):
        delta = inv.apply(b.position_m - a.position_m)
    if not math.hypot(*delta) <= MAX_STEP_M:  # also catches an overflowing difference
        raise InvalidInputError(
            f"the step from {a} to {b} is longer than {MAX_STEP_M:g} m; poses of successive whisks "
            "must be close (check the units: metres)")
    return delta, inv * b.rotation


def exact_odometry(
    pose_prev: PoseLike, pose_next: PoseLike, dt: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Noise-free odometry of the step from ``pose_prev`` to ``pose_next`` over ``dt``.

    Parameters
    ----------
    pose_prev, pose_next : PoseLike
        End-effector poses ``T_BE`` of two successive whisks.
    dt : float, default 1
        Duration of the step, s (> 0).

    Returns
    -------
    v : ndarray (3,)
        ``delta / dt``, m/s, in the end-effector frame of ``pose_prev``.
    omega : ndarray (3,)
        ``rotvec(R) / dt``, rad/s, same frame (rotation angle in [0, pi]).
    dt : float
        s.

    :func:`integrate_odometry` ``(pose_prev, v, omega, dt)`` returns ``pose_next``
    (to rounding).

    Raises
    ------
    InvalidInputError
        Invalid poses, a step longer than :data:`MAX_STEP_M`, ``dt`` not a finite
        number > 0 or so small that the velocities overflow.
    """
    t = finite_scalar(dt, "dt")
    if not t > 0:
        raise InvalidInputError(f"dt must be > 0 s, got {dt!r}")
    delta, R = relative_motion(pose_prev, pose_next)
    with np.errstate(over="ignore"):  # an overflow is reported as a typed error below
        v, omega = delta / t, R.as_rotvec() / t
    return _finite_odometry(v, omega, t)


def _finite_odometry(v: NDArray[np.float64], omega: NDArray[np.float64], dt: float
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(omega))):
        raise InvalidInputError(f"the odometry overflows (dt = {dt!r} s is too short for the step); use a longer dt")
    return v, omega, dt


def _angular_speed(params: OdometryNoise, rng: np.random.Generator) -> float:
    mu, sigma = params.angular_speed_mean_rad_s, params.angular_speed_std_rad_s
    if sigma == 0.0:
        return mu
    draws = rng.normal(mu, sigma, size=MAX_SPEED_DRAWS)
    positive = np.flatnonzero(draws > 0.0)
    return float(draws[positive[0]]) if positive.size else mu


def noisy_odometry(
    pose_prev: PoseLike,
    pose_next: PoseLike,
    rng: np.random.Generator,
    params: OdometryNoise = OdometryNoise(),
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Noisy odometry of one step, Eq 6.4-6.11 (see the module docstring for order and guards).

    Parameters
    ----------
    pose_prev, pose_next : PoseLike
        End-effector poses ``T_BE`` of two successive whisks (ground truth).
    rng : numpy Generator
        Source of the noise; pass the same generator to every step. For given
        ``params`` each call draws the same number of variates
        (:data:`MAX_SPEED_DRAWS` angular speeds unless their deviation is 0, 3 Euler
        angles, 1 displacement), so a run is reproducible from its seed.
    params : OdometryNoise
        Noise parameters (thesis defaults).

    Returns
    -------
    v : ndarray (3,)
        Noisy linear velocity ``v_eta``, m/s, in the end-effector frame of ``pose_prev``.
    omega : ndarray (3,)
        Noisy angular velocity ``omega_eta``, rad/s (rotation-vector rate), same frame.
    dt : float
        ``theta_eta / omega`` (floored at ``params.min_dt_s``), s.

    With every standard deviation 0 (:meth:`OdometryNoise.noise_free`) the result
    equals ``exact_odometry(pose_prev, pose_next, dt)``.

    Raises
    ------
    InvalidInputError
        Invalid poses, a step longer than :data:`MAX_STEP_M`, ``rng`` not a
        Generator, ``params`` not an :class:`OdometryNoise`.
    """
    gen = _generator(rng)
    if not isinstance(params, OdometryNoise):
        raise InvalidInputError(f"params must be an OdometryNoise, got {type(params).__name__}")
    delta, R = relative_motion(pose_prev, pose_next)  # Eq 6.4-6.5
    # draws: always the same count per step, whatever the guards do
    omega = _angular_speed(params, gen)
    euler = gen.normal(0.0, 1.0, size=3) * params.euler_std_rad
    eta_m = float(gen.normal(0.0, 1.0)) * params.displacement_std_m
    R_eta = R * Rotation.from_euler("xyz", euler)  # Eq 6.6, right-multiplied
    rotvec = R_eta.as_rotvec()  # theta_eta e_eta
    theta = float(np.linalg.norm(rotvec))
    dt = max(theta / omega, params.min_dt_s)  # Eq 6.8 + guard theta_eta ~ 0
    omega_eta = rotvec / dt  # = omega e_eta (Eq 6.7) unless the floor is active
    length = math.hypot(*delta)
    if length <= _ZERO_DISPLACEMENT_M:  # guard |delta| = 0: a pure rotation stays one
        delta_eta = np.zeros(3)
    else:
        delta_eta = delta * (max(length + eta_m, 0.0) / length)  # Eq 6.9 + guard magnitude < 0
    return _finite_odometry(delta_eta / dt, omega_eta, dt)  # Eq 6.10-6.11


def integrate_odometry(pose: PoseLike, v: object, omega: object, dt: float) -> Pose:
    """Apply one odometry sample to a pose: ``pose @ Pose.from_rotvec(v dt, omega dt)``.

    The position moves by ``R(q) v dt`` (body-frame velocity rotated by the
    orientation at the start) and the orientation becomes ``q * exp(omega dt)``:
    the accumulation of the object map (Alg 6, frame-correct Eq 5.13). Dead
    reckoning is this applied step after step.

    Parameters
    ----------
    pose : PoseLike
        Pose at the start of the step.
    v : array_like (3,)
        Linear velocity, m/s, body frame.
    omega : array_like (3,)
        Angular velocity (rotation-vector rate), rad/s, body frame.
    dt : float
        Duration, s (>= 0).

    Returns
    -------
    Pose
    """
    start = as_pose(pose)
    t = finite_scalar(dt, "dt")
    if not t >= 0:
        raise InvalidInputError(f"dt must be >= 0 s, got {dt!r}")
    step = Pose.from_rotvec(finite_vector(v, 3, "v") * t, finite_vector(omega, 3, "omega") * t)
    return start @ step
