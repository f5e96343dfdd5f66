"""Whisker sensor signals from a tapered-cantilever contact model (thesis Eq 2.33-2.38).

A whisker module reports, at 2 kHz, its whisk angle theta and the deflection of
the whisker base along two orthogonal sensor axes x and y in ADC counts
(Sec 2.2, Fig 3.1). This module synthesises those traces for a whole whisk cycle
(or for a rod driven into a still whisker, the Evans et al. 2013 set-up of
Sec 4.2.2) from the geometry of a contact.

Physics
-------
The shaft is a linearly tapered cone (Eq 2.36) of base radius ``r_b`` and tip
radius ``r_t``; it is exactly a cone of virtual length ``L' = L r_b / (r_b - r_t)``
cut at ``L``. Integrating Eq 2.33 with the moment of Eq 2.34 gives the deflection
at the contact (Eq 2.37 with ``L -> L'``), ``y(a) = F L' a^3 / (3 E I_b (L' - a))``,
so a base rotation ``dtheta`` past contact at radial distance ``a`` (contact point
displaced by ``a dtheta``) raises the base moment ``M = F a`` by

    dM/dtheta = k(a) = 3 E I_b (1/a - 1/L'),        I_b = pi r_b^4 / 4,

the tapered form of "3EI/a" (Eq 2.38 is the same relation solved for ``a`` with
``L' = L``; :func:`radial_distance_from_stiffness`). The Hall sensor reads the
base moment (deflection is proportional to moment, Evans et al. 2013) with gain
``adc_max / full_scale_moment``. So after contact at whisk angle ``theta_c``

    D(t) = G k(a) max(theta(t) - theta_c, 0)     [counts],

stiffer, steeper and saturating sooner for contacts near the base: the
deflection rate per angular rate ``DV/AV = G k(a)`` encodes ``a`` (Birdwell et
al. 2007), the rotation needed to reach the sensor limit (hence CP with a
retract-at-max controller, or CA when the whisk ends first) does too.

Split on the sensor axes (decision, frictionless contact): in the whisker base
frame of Fig 2.15 (z = whisk axis, shaft along ``Rz(theta) y``), the sensor
y-axis is ``Rz(theta_c) x`` (opposite to the protraction motion, so a contact
while protracting gives positive y) and the sensor x-axis is ``z``. With the
surface normal ``n`` (unit, pointing out of the surface at the whisker) projected
on them, ``n_y = n . Rz(theta_c) x``, ``n_x = n . z``, the surface constrains the
contact only along ``n``, which gives

    y = D n_y^2 / (n_x^2 + n_y^2),      x = D n_x n_y / (n_x^2 + n_y^2),

so the x-y gradient is ``y/x = n_y / n_x``, the slope of Eq 6.14 that the SDA
recovers (Sec 5.1.1.1.3). A normal with ``n_y <= 0`` does not resist protraction
and gives no deflection. Each axis saturates at the ADC limit, then Gaussian
sensor noise is added and the result is rounded to integer counts and clipped to
the ADC range. A free-whisking cycle gives noise only.

Validity: small-deflection beam theory (Birdwell et al. 2007 quote < 14 deg);
larger rotations past contact are extrapolated linearly until the sensor saturates.
Whisker inertia is not modelled; slipping off an edge is an option of
:class:`WhiskContact`.

Example
-------
>>> from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
>>> from whisker_io.array.control import OpenLoop, WhiskPattern
>>> contact = WhiskContact(angle_rad=0.0, radial_distance_m=0.05, whisker_length_m=0.1)
>>> records, truths = simulate_whisk_cycle([contact, None], OpenLoop(WhiskPattern(1.0)), seed=1)
>>> records[0].n_samples, truths[0].onset_index, truths[1] is None
(2000, 501, True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from whisker_io.array.control import OpenLoop, WhiskController, WhiskPattern, contact_threshold_from_noise
from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_scalar, finite_vector, validate_fields
from whisker_io.records.whisk_record import SAMPLE_RATE_HZ, WhiskRecord

#: Longest rod-push recording :func:`simulate_rod_contact` makes (about 83 min at 2 kHz).
_MAX_ROD_SAMPLES = 10_000_000

__all__ = [
    "SignalParams",
    "WhiskContact",
    "ContactTruth",
    "bending_stiffness",
    "radial_distance_from_stiffness",
    "deflection_counts",
    "add_sensor_noise",
    "simulate_whisk_cycle",
    "free_whisking_threshold_counts",
    "simulate_rod_contact",
]


@dataclass(frozen=True)
class SignalParams(ConfigDataclass):
    """Whisker shaft, Hall sensor and ADC parameters.

    Parameters
    ----------
    youngs_modulus_pa : float, default 3.0e9
        Young's modulus E of the shaft, Pa. Assumption: the thesis' NanoCure RC25
        photopolymer is not characterised; 3 GPa is typical of stiff acrylate resins.
    base_radius_m : float, default 1.0e-3
        Shaft radius at the base, m (thesis Sec 2.2: 2 mm base diameter).
    tip_radius_m : float, default 0.3e-3
        Shaft radius at the tip, m (0.6 mm tip diameter). 0 gives the perfect
        cone of Eq 2.36-2.38; equal to the base radius a uniform rod (3EI/a).
    full_scale_moment_nm : float, default 0.032
        Base moment that drives the ADC to full scale, N m. Assumption, chosen so
        that full scale is reached ~20 deg past a mid-shaft contact on a 100-mm
        whisker and at about 40 MPa base bending stress (near the resin's
        strength: the sensor limit doubles as the "do not break" limit of RCP).
    adc_max_counts : float, default 2047
        ADC limit, counts; samples are clipped to +-adc_max (12-bit signed).
    noise_std_counts : float, default 4
        Standard deviation of the additive deflection noise, counts (assumption;
        the 20-sigma contact threshold of Sec 3.2.2 is then 80 counts).
    angle_noise_std_rad : float, default 0.05 deg
        Standard deviation of the angle-sensor noise, radians (assumption).
    sample_rate_hz : float, default 2000
        Sampling rate, Hz.
    quantize : bool, default True
        Round deflections to integer counts.
    """

    youngs_modulus_pa: float = checked(3.0e9, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                       label="SignalParams.youngs_modulus_pa")
    base_radius_m: float = checked(1.0e-3, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                   label="SignalParams.base_radius_m")
    tip_radius_m: float = checked(0.3e-3, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                  label="SignalParams.tip_radius_m")
    full_scale_moment_nm: float = checked(0.032, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                          label="SignalParams.full_scale_moment_nm")
    adc_max_counts: float = checked(2047.0, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                    label="SignalParams.adc_max_counts")
    noise_std_counts: float = checked(4.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                      label="SignalParams.noise_std_counts")
    angle_noise_std_rad: float = checked(math.radians(0.05), float, minimum=0, error=InvalidInputError,
                                         reader=finite_scalar, label="SignalParams.angle_noise_std_rad")
    sample_rate_hz: float = checked(SAMPLE_RATE_HZ, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                    label="SignalParams.sample_rate_hz")
    quantize: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)
        if self.tip_radius_m > self.base_radius_m:
            raise InvalidInputError("SignalParams.tip_radius_m must not exceed base_radius_m")

    @classmethod
    def evans2013(cls) -> SignalParams:
        """Preset for the Evans et al. (2013) rod data set (Sec 4.2.2).

        ABS whisker (E = 2.2 GPa, typical for ABS), 2 mm -> 0.5 mm diameter (thesis
        Sec 4.2.2), and a full-scale moment of 5.5 mN m (assumption: full scale
        about 10 mm of rod travel at 80 mm radial distance on the 185-mm whisker).
        """
        return cls(youngs_modulus_pa=2.2e9, base_radius_m=1.0e-3, tip_radius_m=0.25e-3, full_scale_moment_nm=0.0055)

    @property
    def base_second_moment_m4(self) -> float:
        """I_b = pi r_b^4 / 4, m^4 (Eq 2.36 at x = 0)."""
        return math.pi * self.base_radius_m**4 / 4.0

    @property
    def gain_counts_per_nm(self) -> float:
        """Sensor gain G, counts per N m of base moment."""
        return self.adc_max_counts / self.full_scale_moment_nm

    def cone_length_m(self, whisker_length_m: np.ndarray | float) -> np.ndarray:
        """Virtual cone length L' = L r_b / (r_b - r_t), m (inf for an untapered rod)."""
        L = np.asarray(whisker_length_m, dtype=np.float64)
        taper = self.base_radius_m - self.tip_radius_m
        if taper <= 0:
            return np.full_like(L, np.inf)
        return L * self.base_radius_m / taper


_LENGTH_DOMAIN = "whisker_length_m must be > 0"
#: Longest whisker a :class:`WhiskContact` takes, m (the thesis' are 60-160 mm): a longer one is millimetres given as metres.
MAX_WHISKER_LENGTH_M = 1.0
_RADIAL_DOMAIN = "radial_distance_m must lie in (0, whisker_length_m]"


def _check_a_L(a: ArrayLike, L: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    a = finite_array(a, None, "radial_distance_m")
    L = finite_array(L, None, "whisker_length_m")
    if np.any(L <= 0):
        raise InvalidInputError(_LENGTH_DOMAIN)
    if np.any(a <= 0) or np.any(a > L):
        raise InvalidInputError(_RADIAL_DOMAIN)
    return a, L


def _stiffness(a: np.ndarray, L: np.ndarray, p: SignalParams) -> np.ndarray:
    """``3 E I_b (1/a - 1/L')`` for checked arrays (the formula of :func:`bending_stiffness`)."""
    return 3.0 * p.youngs_modulus_pa * p.base_second_moment_m4 * (1.0 / a - 1.0 / p.cone_length_m(L))


def bending_stiffness(
    radial_distance_m: np.ndarray | float,
    whisker_length_m: np.ndarray | float,
    params: SignalParams | None = None,
) -> np.ndarray:
    """Rate of change of base moment with rotation past contact, dM/dtheta (Eq 2.37-2.38).

    ``k(a) = 3 E I_b (1/a - 1/L')`` with ``L' = L r_b / (r_b - r_t)``; for a perfect
    cone (``r_t = 0``) this is Eq 2.38 solved for dM/dtheta, for a uniform rod 3EI/a.

    Parameters
    ----------
    radial_distance_m : float or array
        Radial distance a from the base to the contact, m, in (0, L].
    whisker_length_m : float or array
        Whisker length L, m (broadcast with ``a``).
    params : SignalParams, optional
        Shaft parameters.

    Returns
    -------
    ndarray
        k, N m / rad (broadcast shape).
    """
    p = SignalParams() if params is None else params
    a, L = _check_a_L(radial_distance_m, whisker_length_m)
    try:
        a, L = np.broadcast_arrays(a, L)
    except ValueError:
        raise ShapeError(f"radial_distance_m {a.shape} and whisker_length_m {L.shape} do not broadcast") from None
    return _stiffness(a, L, p)


def radial_distance_from_stiffness(
    stiffness_nm_per_rad: np.ndarray | float,
    whisker_length_m: np.ndarray | float,
    params: SignalParams | None = None,
) -> np.ndarray:
    """Radial distance from dM/dtheta, Eq 2.38: ``d = 3 E I_b L' / (3 E I_b + (dM/dtheta) L')``.

    The inverse of :func:`bending_stiffness` (with ``L_BT = L'``, the cone length).

    Returns
    -------
    ndarray
        Radial distance, m.
    """
    p = SignalParams() if params is None else params
    k = np.asarray(stiffness_nm_per_rad, dtype=np.float64)
    Lc = p.cone_length_m(whisker_length_m)
    c = 3.0 * p.youngs_modulus_pa * p.base_second_moment_m4
    with np.errstate(invalid="ignore"):
        return np.where(np.isinf(Lc), c / k, c * Lc / (c + k * Lc))


@dataclass(frozen=True, eq=False)
class WhiskContact:
    """Geometry of one whisker's contact, the input of the signal model.

    Parameters
    ----------
    angle_rad : float
        Whisk angle theta_c at which the (rigid) whisker first touches, radians.
    radial_distance_m : float
        Radial distance a from the base to the contact, m, in (0, L].
    whisker_length_m : float
        Whisker length L, m.
    normal : array_like, shape (3,), default Rz(theta_c) x
        Surface normal at the contact in the whisker base frame (Fig 2.15),
        pointing out of the surface toward the whisker; normalised here. The
        default faces the protracting whisker squarely (pure y-deflection).
    slip_rad : float, default inf
        Rotation past contact after which the whisker slips off the object (an
        edge or a steep face, Fig 4.5b): the deflection drops to zero and stays
        there for the rest of the cycle. ``inf``: no slip.
    """

    angle_rad: float
    radial_distance_m: float
    whisker_length_m: float
    normal: np.ndarray | None = field(default=None)
    slip_rad: float = math.inf

    def __post_init__(self) -> None:
        angle = finite_scalar(self.angle_rad, "WhiskContact.angle_rad")
        a = finite_scalar(self.radial_distance_m, "WhiskContact.radial_distance_m")
        L = finite_scalar(self.whisker_length_m, "WhiskContact.whisker_length_m")
        if not L > 0:
            raise InvalidInputError(_LENGTH_DOMAIN)
        if L > MAX_WHISKER_LENGTH_M:
            raise InvalidInputError(f"whisker_length_m = {L:g} m: a whisker is at most {MAX_WHISKER_LENGTH_M:g} m long - "
                                    f"metres are meant ({L:g} mm = {L / 1e3:g} m)")
        if abs(angle) > math.pi:
            raise InvalidInputError(f"angle_rad = {angle:g}: a whisk angle lies within +-pi rad - radians are meant "
                                    f"({angle:g} deg = {math.radians(angle):.4g} rad)")
        if not 0 < a <= L:
            raise InvalidInputError(_RADIAL_DOMAIN)
        if self.normal is None:
            n = np.array([math.cos(angle), math.sin(angle), 0.0])
        else:
            n = finite_vector(self.normal, 3, "WhiskContact.normal")
            norm = float(np.linalg.norm(n))
            if not 0 < norm < math.inf:
                raise InvalidInputError(f"normal must be a finite non-zero 3-vector, got {self.normal!r}")
            n = n / norm
        slip = self.slip_rad
        if isinstance(slip, (str, bytes, bool)) or not (isinstance(slip, (int, float, np.floating, np.integer))
                                                        and slip > 0):
            raise InvalidInputError(f"slip_rad must be > 0 (inf for no slip), got {self.slip_rad!r}")
        try:
            slip = float(slip)
        except OverflowError:  # an int too large for a float: refused like finite_scalar does, not a bare error
            raise InvalidInputError("slip_rad must be a float (inf for no slip), got an integer too large for a float"
                                    ) from None
        n.setflags(write=False)
        object.__setattr__(self, "slip_rad", slip)
        object.__setattr__(self, "angle_rad", angle)
        object.__setattr__(self, "radial_distance_m", a)
        object.__setattr__(self, "whisker_length_m", L)
        object.__setattr__(self, "normal", n)

    def sensor_split(self) -> tuple[float, float]:
        """Fractions (f_x, f_y) of the deflection magnitude on the sensor x and y axes.

        ``f_y = n_y^2 / (n_x^2 + n_y^2)``, ``f_x = n_x n_y / (n_x^2 + n_y^2)``, zero when
        ``n_y <= 0`` (see module docstring); ``f_y / f_x = n_y / n_x`` is the Eq 6.14 slope.
        """
        c, s = math.cos(self.angle_rad), math.sin(self.angle_rad)
        n_y = float(self.normal[0] * c + self.normal[1] * s)
        n_x = float(self.normal[2])
        den = n_x * n_x + n_y * n_y
        if n_y <= 0.0 or den <= 1e-12:
            return 0.0, 0.0
        return n_x * n_y / den, n_y * n_y / den

    @property
    def slope(self) -> float:
        """Expected y-against-x gradient ``n_y / n_x`` (Eq 6.14; inf for n_x = 0)."""
        fx, fy = self.sensor_split()
        return math.copysign(math.inf, fy) if fx == 0.0 else fy / fx


@dataclass(frozen=True)
class ContactTruth:
    """What the simulator knows about a contact, for scoring the detector.

    Attributes
    ----------
    onset_index : int
        First sample at which the whisker is past the contact angle (deflection starts).
    onset_time_s : float
        ``onset_index / sample_rate``, seconds from the start of the cycle.
    contact_angle_rad : float
        theta_c, radians.
    radial_distance_m, whisker_length_m : float
        a and L, m.
    peak_index : int
        Sample of the largest noise-free ``|y-deflection|``.
    peak_y_counts : float
        Noise-free y-deflection at ``peak_index`` (after saturation), counts.
    """

    onset_index: int
    onset_time_s: float
    contact_angle_rad: float
    radial_distance_m: float
    whisker_length_m: float
    peak_index: int
    peak_y_counts: float


def _check_angles(angles_rad: np.ndarray, n: int) -> np.ndarray:
    th = np.asarray(angles_rad, dtype=np.float64)
    if th.ndim != 2 or th.shape[0] != n:
        raise InvalidInputError(f"angles_rad must have shape (len(contacts)={n}, T), got {th.shape}")
    return th


def _contact_arrays(
    contacts: Sequence[WhiskContact | None], p: SignalParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per whisker: contact angle theta_c (inf: free), slip angle (inf: none), ``G k(a)``
    (0: free) and the sensor split ``fx``, ``fy`` of :meth:`WhiskContact.sensor_split`."""
    n = len(contacts)
    theta_c = np.full(n, np.inf)
    gain_k = np.zeros(n)
    fx = np.zeros(n)
    fy = np.zeros(n)
    slip = np.full(n, np.inf)
    a = np.ones(n)
    L = np.ones(n)
    for i, c in enumerate(contacts):
        if c is None:
            continue
        theta_c[i] = c.angle_rad
        slip[i] = c.slip_rad
        a[i], L[i] = c.radial_distance_m, c.whisker_length_m
        fx[i], fy[i] = c.sensor_split()
    hit = np.isfinite(theta_c)
    gain_k[hit] = p.gain_counts_per_nm * _stiffness(a[hit], L[hit], p)  # a, L checked by WhiskContact
    return theta_c, slip, gain_k, fx, fy


def deflection_counts(
    angles_rad: np.ndarray,
    contacts: Sequence[WhiskContact | None],
    params: SignalParams | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free, saturated x- and y-deflection for given angle trajectories.

    Parameters
    ----------
    angles_rad : ndarray, shape (n, T)
        True whisk angles, radians.
    contacts : sequence of WhiskContact or None, length n
        Contact of each whisker (``None``: free whisking).
    params : SignalParams, optional

    Returns
    -------
    x, y : ndarray, shape (n, T)
        Deflections, counts, clipped to +-adc_max.
    """
    p = SignalParams() if params is None else params
    th = _check_angles(angles_rad, len(contacts))
    theta_c, slip, gain_k, fx, fy = _contact_arrays(contacts, p)
    past = np.maximum(th - theta_c[:, None], 0.0)  # inf contact angle -> 0
    slipping = np.isfinite(slip)
    if slipping.any():
        gone = np.maximum.accumulate(past[slipping], axis=1) >= slip[slipping, None]
        past[slipping] = np.where(gone, 0.0, past[slipping])
    D = gain_k[:, None] * past
    lim = p.adc_max_counts
    return np.clip(D * fx[:, None], -lim, lim), np.clip(D * fy[:, None], -lim, lim)


def add_sensor_noise(
    x_counts: np.ndarray,
    y_counts: np.ndarray,
    angles_rad: np.ndarray,
    noise: tuple[np.ndarray, np.ndarray, np.ndarray],
    params: SignalParams | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Apply pre-drawn standard-normal noise, quantisation and ADC clipping.

    Parameters
    ----------
    x_counts, y_counts, angles_rad : ndarray, shape (n, T)
        Noise-free signals.
    noise : tuple of three ndarrays, shape (n, T)
        Standard-normal draws for x, y and angle (drawn once per cycle so a
        controller's re-run of the cycle sees the same noise).
    params : SignalParams, optional

    Returns
    -------
    x, y, angle : ndarray, shape (n, T)
        Measured signals (counts, counts, radians).
    """
    p = SignalParams() if params is None else params
    lim = p.adc_max_counts
    x = x_counts + p.noise_std_counts * noise[0]
    y = y_counts + p.noise_std_counts * noise[1]
    if p.quantize:
        x, y = np.rint(x), np.rint(y)
    return np.clip(x, -lim, lim), np.clip(y, -lim, lim), angles_rad + p.angle_noise_std_rad * noise[2]


def _truths(
    peaks: tuple[np.ndarray, np.ndarray, np.ndarray], contacts: Sequence[WhiskContact | None], fs: float
) -> list[ContactTruth | None]:
    """Ground truth per whisker from :func:`_synthesise`'s per-whisker scan: the onset is the first
    sample past the contact angle, the peak the largest noise-free ``|y|`` (``None``: no contact,
    the whisk never passes the contact angle, or no deflection)."""
    first_past, peak_index, peak_y = peaks
    out: list[ContactTruth | None] = []
    for i, c in enumerate(contacts):
        if c is None or first_past[i] < 0 or peak_y[i] == 0.0:
            out.append(None)
            continue
        onset = int(first_past[i])
        out.append(
            ContactTruth(
                onset_index=onset,
                onset_time_s=onset / fs,
                contact_angle_rad=c.angle_rad,
                radial_distance_m=c.radial_distance_m,
                whisker_length_m=c.whisker_length_m,
                peak_index=int(peak_index[i]),
                peak_y_counts=float(peak_y[i]),
            )
        )
    return out


def simulate_whisk_cycle(
    contacts: Sequence[WhiskContact | None],
    controller: WhiskController | None = None,
    params: SignalParams | None = None,
    seed: int | np.random.Generator | None = None,
    modules: Sequence[str] | None = None,
    cycle: int = 0,
) -> tuple[list[WhiskRecord], list[ContactTruth | None]]:
    """One whisk cycle of n whiskers: controller trajectories -> beam model -> sensor.

    The controller commands the cycle, the signals are synthesised, the
    controller may react within the cycle (e.g. :class:`~whisker_io.array.control.RetractAtMax`),
    the signals are re-synthesised with the same noise, and ``end_cycle`` is
    called (e.g. :class:`~whisker_io.array.control.RCP` adapts the next amplitude).

    Parameters
    ----------
    contacts : sequence of WhiskContact or None, length n
        Contact geometry per whisker; ``None`` for free whisking (noise only).
    controller : WhiskController, optional
        Defaults to 1-Hz :class:`~whisker_io.array.control.OpenLoop`. Its pattern's
        sampling rate must equal ``params.sample_rate_hz``.
    params : SignalParams, optional
    seed : int or numpy Generator, optional
        Noise seed (``np.random.default_rng(seed)``).
    modules : sequence of str, optional
        Module names of the records (default ``W0, W1, ...``).
    cycle : int, default 0
        Cycle index stored in the records.

    Returns
    -------
    records : list of WhiskRecord
        Measured angle, x and y per whisker.
    truths : list of ContactTruth or None
        Ground truth per whisker (``None`` where the whisk never reaches the contact).
    """
    p = SignalParams() if params is None else params
    ctrl = OpenLoop(WhiskPattern(sample_rate_hz=p.sample_rate_hz)) if controller is None else controller
    if not isinstance(ctrl, WhiskController):
        raise InvalidInputError(f"controller must implement WhiskController, got {type(ctrl).__name__}")
    if ctrl.pattern.sample_rate_hz != p.sample_rate_hz:
        raise InvalidInputError(
            f"controller samples at {ctrl.pattern.sample_rate_hz} Hz but params at {p.sample_rate_hz} Hz"
        )
    contacts = list(contacts)
    n = len(contacts)
    if n == 0:
        raise InvalidInputError("contacts must hold one entry (WhiskContact or None) per whisker")
    if any(c is not None and not isinstance(c, WhiskContact) for c in contacts):
        raise InvalidInputError("contacts must be WhiskContact or None")
    names = [f"W{i}" for i in range(n)] if modules is None else list(modules)
    if len(names) != n:
        raise InvalidInputError(f"modules has {len(names)} names for {n} contacts")
    rng = np.random.default_rng(seed)
    angles = _check_angles(ctrl.command(n), n)
    # x, y and angle noise in one draw: the same numbers in the same order as three draws of (n, T)
    noise = rng.standard_normal((3,) + angles.shape)
    per_whisker = _contact_arrays(contacts, p)
    x, y, th, peaks = _synthesise(angles, per_whisker, noise, p)
    new_angles = ctrl.respond(angles, y)
    if new_angles is not angles and not np.array_equal(new_angles, angles):
        angles = _check_angles(new_angles, n)
        x, y, th, peaks = _synthesise(angles, per_whisker, noise, p)
    ctrl.end_cycle(y)
    records = WhiskRecord.from_float_rows(names, th, x, y, sample_rate_hz=p.sample_rate_hz, cycle=cycle)
    return records, _truths(peaks, contacts, p.sample_rate_hz)


def _synthesise(
    angles: np.ndarray,
    per_whisker: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    noise: np.ndarray,
    p: SignalParams,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``add_sensor_noise(*deflection_counts(...), angles, noise)`` in one compiled pass (the same
    bits): measured x, y, angle, each (n, T), and per whisker the first sample past contact,
    the peak sample of the noise-free ``|y|`` and its value (:func:`_truths`)."""
    from whisker_io.sim._signals_numba import synthesise_cycle

    a = np.ascontiguousarray(angles, dtype=np.float64)
    if noise.shape != (3,) + a.shape:
        raise InvalidInputError(f"the controller's response has shape {a.shape}, not the commanded {noise.shape[1:]}")
    x, y, th = (np.empty(a.shape) for _ in range(3))
    n = a.shape[0]
    first_past, peak_index, peak_y = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n)
    theta_c, slip, gain_k, fx, fy = per_whisker
    synthesise_cycle(a, theta_c, slip, gain_k, fx, fy, float(p.adc_max_counts), noise, float(p.noise_std_counts),
                     float(p.angle_noise_std_rad), bool(p.quantize), x, y, th, first_past, peak_index, peak_y)
    return x, y, th, (first_past, peak_index, peak_y)



def free_whisking_threshold_counts(
    pattern: WhiskPattern,
    params: SignalParams,
    modules: Sequence[str],
    rng: np.random.Generator,
) -> float:
    """The Sec 3.2.2 contact threshold of a simulated sensor, counts.

    20 x the standard deviation of the y-deflection over one free-whisking (no contact)
    open-loop cycle of ``pattern`` on every whisker of ``modules``
    (:func:`~whisker_io.array.control.contact_threshold_from_noise`).

    Parameters
    ----------
    pattern : WhiskPattern
        The whisk pattern (its sampling rate must equal ``params.sample_rate_hz``).
    params : SignalParams
        The simulated sensor.
    modules : sequence of str
        One name per whisker.
    rng : numpy Generator
        Draws the cycle's sensor noise (advanced by the draw).

    Raises
    ------
    InvalidInputError
        Not a WhiskPattern / SignalParams, no whisker names, or inputs
        :func:`simulate_whisk_cycle` refuses.
    """
    if not isinstance(pattern, WhiskPattern) or not isinstance(params, SignalParams):
        raise InvalidInputError(f"give a WhiskPattern and SignalParams, got {type(pattern).__name__} and {type(params).__name__}")
    if isinstance(modules, str) or not isinstance(modules, Sequence) or len(modules) == 0 \
            or not all(isinstance(m, str) for m in modules):
        raise InvalidInputError(f"modules must name one or more whiskers (a sequence of str), got {modules!r}")
    free, _ = simulate_whisk_cycle([None] * len(modules), OpenLoop(pattern), params, seed=rng, modules=modules)
    return contact_threshold_from_noise(np.stack([r.y_counts for r in free]))


def simulate_rod_contact(
    radial_distance_m: float,
    whisker_length_m: float,
    speed_m_s: float,
    params: SignalParams | None = None,
    angle_rad: float = 0.0,
    threshold_counts: float | None = None,
    max_travel_m: float = 0.04,
    deceleration_m_s2: float = 5.0,
    lead_s: float = 0.25,
    tail_s: float = 0.25,
    seed: int | np.random.Generator | None = None,
    module: str = "W0",
    cycle: int = 0,
) -> tuple[WhiskRecord, ContactTruth]:
    """A rod driven linearly into a still whisker and back (Evans et al. 2013, Sec 4.2.2).

    The whisker rests at ``angle_rad``. After ``lead_s`` the rod, perpendicular to
    the shaft at radial distance a, advances at ``speed_m_s`` until ``|y|`` reaches
    ``threshold_counts`` (noise-free), then brakes at ``deceleration_m_s2`` (so
    the overshoot ``s^2 / 2A``, hence the peak, grows with speed, as in Fig 2.13;
    braking starts earlier if it would pass ``max_travel_m``) and withdraws
    along the mirror image of its approach; the record ends
    ``tail_s`` after the rod has left. A rod displacement ``delta`` bends the shaft
    like a rotation ``delta / a`` past contact: ``y = G k(a) delta / a``.

    Parameters
    ----------
    radial_distance_m, whisker_length_m : float
        a and L, m.
    speed_m_s : float
        Rod speed, m/s (Evans et al.: 36-216 mm/s).
    params : SignalParams, optional
        Use :meth:`SignalParams.evans2013` for the Evans whisker.
    angle_rad : float, default 0
        Resting whisk angle, radians.
    threshold_counts : float, optional
        Deflection at which the rod reverses, counts (default 60 % of
        ``adc_max``, assumption: below saturation so the overshoot is measured).
    max_travel_m : float, default 0.04
        Stroke limit of the rod, m.
    deceleration_m_s2 : float, default 5
        Braking (and re-acceleration) of the rod, m/s^2 (assumption).
    lead_s, tail_s : float, default 0.25
        Still time before contact and after release, s.
    seed : int or Generator, optional
    module : str, default "W0"
    cycle : int, default 0

    Returns
    -------
    record : WhiskRecord
    truth : ContactTruth
        ``onset_index`` = first sample of rod contact, ``contact_angle_rad`` = ``angle_rad``.
    """
    p = SignalParams() if params is None else params
    if not finite_scalar(speed_m_s, "speed_m_s") > 0:
        raise InvalidInputError(f"speed_m_s must be > 0, got {speed_m_s!r}")
    if not finite_scalar(max_travel_m, "max_travel_m") > 0:
        raise InvalidInputError(f"max_travel_m must be > 0, got {max_travel_m!r}")
    if not (finite_scalar(lead_s, "lead_s") >= 0 and finite_scalar(tail_s, "tail_s") >= 0):
        raise InvalidInputError("lead_s and tail_s must be >= 0")
    if not finite_scalar(deceleration_m_s2, "deceleration_m_s2") > 0:
        raise InvalidInputError(f"deceleration_m_s2 must be > 0, got {deceleration_m_s2!r}")
    thr = 0.6 * p.adc_max_counts if threshold_counts is None else finite_scalar(threshold_counts, "threshold_counts")
    if not thr > 0:
        raise InvalidInputError(f"threshold_counts must be > 0, got {threshold_counts!r}")
    stiffness = float(bending_stiffness(radial_distance_m, whisker_length_m, p))
    counts_per_m = p.gain_counts_per_nm * stiffness / radial_distance_m
    v, acc = float(speed_m_s), float(deceleration_m_s2)
    brake_at = max(0.0, min(thr / counts_per_m, max_travel_m - v * v / (2.0 * acc)))
    t_brake = brake_at / v
    t_top = t_brake + v / acc
    fs = p.sample_rate_hz
    duration_s = lead_s + 2.0 * t_top + tail_s
    if not duration_s * fs <= _MAX_ROD_SAMPLES:  # before any int(): lead_s = 1e308 s is inf samples
        raise InvalidInputError(
            f"the rod push would last {duration_s:.3g} s ({duration_s * fs:.3g} samples, more than "
            f"{_MAX_ROD_SAMPLES:.0e}); raise speed_m_s or deceleration_m_s2, or shorten lead_s/tail_s")
    onset = int(round(lead_s * fs))
    half = max(1, int(math.ceil(t_top * fs)))
    T = onset + 2 * half + int(round(tail_s * fs)) + 1
    k = np.arange(T) - onset
    u = np.clip(np.minimum(k, 2 * half - k) / fs, 0.0, None)  # time from contact, mirrored after the top
    ub = np.clip(u - t_brake, 0.0, v / acc)
    delta = np.minimum(u, t_brake) * v + v * ub - 0.5 * acc * ub * ub
    y_clean = np.minimum(counts_per_m * delta, p.adc_max_counts)[None, :]
    rng = np.random.default_rng(seed)
    angles = np.full((1, T), float(angle_rad))
    noise = (rng.standard_normal((1, T)), rng.standard_normal((1, T)), rng.standard_normal((1, T)))
    x, y, th = add_sensor_noise(np.zeros((1, T)), y_clean, angles, noise, p)
    record = WhiskRecord(module=module, angle_rad=th[0], x_counts=x[0], y_counts=y[0], sample_rate_hz=fs, cycle=cycle)
    peak = int(np.argmax(y_clean[0]))
    truth = ContactTruth(
        onset_index=onset + 1,  # first sample with the rod pressing (delta > 0)
        onset_time_s=(onset + 1) / fs,
        contact_angle_rad=float(angle_rad),
        radial_distance_m=float(radial_distance_m),
        whisker_length_m=float(whisker_length_m),
        peak_index=peak,
        peak_y_counts=float(y_clean[0, peak]),
    )
    return record, truth
