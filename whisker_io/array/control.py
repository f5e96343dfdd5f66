"""Whisking controllers: open loop, RCP (Ch.3) and retract-at-sensor-maximum (Ch.4/6).

Sec 2.3.1, 3.2.2 / thesis Sec 2.3.1, 3.2.2, 4.1.1. A controller turns a whisking
pattern into per-whisker angle trajectories sampled at 2 kHz, and may change
them from the measured y-deflection:

* :class:`OpenLoop` - "a sinusoidal 1Hz pattern of fixed magnitude that moved
  the whiskers throughout their full range of motion" (Sec 3.2.2).
* :class:`RCP` - rapid cessation of protraction as implemented in Ch.3: the
  commanded amplitude is reduced by the mean ``|y-deflection|`` above the contact
  threshold (20 x the free-whisking noise std, from calibration), keeping the
  starting angle. Decision: the reduction is applied cycle to cycle (the
  deflection measured in cycle n sets the amplitude of cycle n+1), which keeps
  "the initial whisk angle at the start of each cycle constant".
* :class:`RetractAtMax` - the Ch.4/6 variant: "triggering an early retraction of
  the whisker in the event that a threshold in its deflection magnitude was
  crossed", the threshold being the sensor maximum (Sec 4.1.1). Decision: on the
  trigger the whisker stops (cessation) and retracts to the starting angle along
  a half cosine lasting half a whisk period, then rests there.

Every controller implements the :class:`WhiskController` protocol used by
:func:`whisker_io.sim.signals.simulate_whisk_cycle`: ``command`` (trajectories before
the cycle), ``respond`` (within-cycle reaction to the measured y-deflection; it
may only change samples after the one that triggered it) and ``end_cycle``.

Example
-------
>>> import numpy as np
>>> from whisker_io.array.control import WhiskPattern, OpenLoop
>>> pattern = WhiskPattern(frequency_hz=1.0)
>>> angles = OpenLoop(pattern).command(n_whiskers=18)
>>> angles.shape, round(float(np.rad2deg(angles.max())), 6)
((18, 2000), 50.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, validate_fields

__all__ = [
    "MAX_WHISK_FREQUENCY_HZ",
    "WhiskPattern",
    "WhiskController",
    "OpenLoop",
    "RCP",
    "RetractAtMax",
    "contact_threshold_from_noise",
]

#: Fastest whisking the module motor allows, Hz (Sec 2.2: "a whisking rate of up to 10Hz").
MAX_WHISK_FREQUENCY_HZ: float = 10.0


@dataclass(frozen=True)
class WhiskPattern(ConfigDataclass):
    """The global whisking pattern: one cosine cycle from retraction to protraction and back.

    ``theta(t) = retraction + A (1 - cos(2 pi f t)) / 2`` for ``t = k / fs``,
    ``k = 0 .. T-1``, ``T = round(fs / f)``; ``A`` defaults to the full range.

    Parameters
    ----------
    frequency_hz : float, default 1.0
        Whisking frequency f, Hz, in (0, 10] (Ch.3 uses 1 Hz, Ch.4 0.2-2.5 Hz).
    retraction_rad : float, default -50 deg
        Start (fully retracted) angle, radians (Fig 2.15).
    protraction_rad : float, default +50 deg
        Fully protracted angle, radians; ``protraction - retraction`` is the full
        amplitude (100 deg, Fig 2.8).
    sample_rate_hz : float, default 2000
        Sampling rate fs, Hz.
    """

    frequency_hz: float = checked(1.0, float, above=0, maximum=MAX_WHISK_FREQUENCY_HZ, error=InvalidInputError,
                                  reader=finite_scalar,
                                  message=f"{{name}} must be in (0, {MAX_WHISK_FREQUENCY_HZ}] Hz, got {{value!r}}")
    retraction_rad: float = checked(math.radians(-50.0), float, error=InvalidInputError, reader=finite_scalar)
    protraction_rad: float = checked(math.radians(50.0), float, error=InvalidInputError, reader=finite_scalar)
    sample_rate_hz: float = checked(2000.0, float, error=InvalidInputError, reader=finite_scalar)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not self.protraction_rad > self.retraction_rad:
            raise InvalidInputError(
                f"protraction_rad ({self.protraction_rad}) must exceed retraction_rad ({self.retraction_rad})"
            )
        if not self.sample_rate_hz >= 2 * self.frequency_hz:
            raise InvalidInputError(f"sample_rate_hz must be >= 2 x frequency_hz, got {self.sample_rate_hz!r}")

    @property
    def amplitude_rad(self) -> float:
        """Full whisking amplitude, radians."""
        return self.protraction_rad - self.retraction_rad

    @property
    def n_samples(self) -> int:
        """Samples per whisk cycle T."""
        return int(round(self.sample_rate_hz / self.frequency_hz))

    @property
    def period_s(self) -> float:
        """Whisk period 1/f, seconds."""
        return 1.0 / self.frequency_hz

    def angles(self, amplitude_rad: np.ndarray | float | None = None) -> np.ndarray:
        """Cosine angle trajectory.

        Parameters
        ----------
        amplitude_rad : float or array of shape (n,), optional
            Amplitude per whisker, radians (full range when ``None``).

        Returns
        -------
        ndarray
            Shape (T,) for a scalar amplitude, (n, T) for an array; radians.
        """
        phase = 0.5 * (1.0 - np.cos(2.0 * np.pi * self.frequency_hz * np.arange(self.n_samples) / self.sample_rate_hz))
        amp = self.amplitude_rad if amplitude_rad is None else np.asarray(amplitude_rad, dtype=np.float64)
        if np.ndim(amp) == 0:
            return self.retraction_rad + float(amp) * phase
        return self.retraction_rad + amp[:, None] * phase[None, :]


@runtime_checkable
class WhiskController(Protocol):
    """What :func:`whisker_io.sim.signals.simulate_whisk_cycle` needs from a controller."""

    pattern: WhiskPattern

    def command(self, n_whiskers: int) -> np.ndarray:
        """Angle trajectories for the next cycle, shape (n_whiskers, T), radians."""
        ...

    def respond(self, angles_rad: np.ndarray, y_counts: np.ndarray) -> np.ndarray:
        """Within-cycle reaction to the measured y-deflection (n, T); returns angles (n, T)."""
        ...

    def end_cycle(self, y_counts: np.ndarray) -> None:
        """Cycle-to-cycle update from the cycle's y-deflection (n, T)."""
        ...


def _check_n(n_whiskers: int) -> int:
    if not (isinstance(n_whiskers, (int, np.integer)) and n_whiskers >= 1):
        raise InvalidInputError(f"n_whiskers must be a positive integer, got {n_whiskers!r}")
    return int(n_whiskers)


def _check_y(y_counts: np.ndarray, n: int | None, T: int) -> np.ndarray:
    y = np.asarray(y_counts, dtype=np.float64)
    if y.ndim != 2 or y.shape[1] != T or (n is not None and y.shape[0] != n):
        raise InvalidInputError(f"y_counts must have shape ({n if n is not None else 'n'}, {T}), got {y.shape}")
    return y


def contact_threshold_from_noise(free_whisk_y_counts: np.ndarray, factor: float = 20.0) -> float:
    """Contact threshold from a free-whisking calibration recording (Sec 3.2.2).

    "calculated at time of calibration as +-20x the standard deviation of the
    recorded noise from the mean of the deflection data during free-whisking".

    Parameters
    ----------
    free_whisk_y_counts : array_like
        y-deflection samples recorded while whisking in free air, counts (any shape).
    factor : float, default 20
        Multiple of the noise standard deviation.

    Returns
    -------
    float
        Threshold on ``|y - mean|``, counts.
    """
    y = np.asarray(free_whisk_y_counts, dtype=np.float64).ravel()
    if y.size < 2 or not np.all(np.isfinite(y)):
        raise InvalidInputError("free-whisking calibration needs >= 2 finite samples")
    return float(factor * np.std(y))


@dataclass
class OpenLoop:
    """Open-loop whisking: every whisker follows the pattern at full amplitude (Sec 3.2.2)."""

    pattern: WhiskPattern = field(default_factory=WhiskPattern)

    def command(self, n_whiskers: int) -> np.ndarray:
        n = _check_n(n_whiskers)
        return np.broadcast_to(self.pattern.angles(), (n, self.pattern.n_samples)).copy()

    def respond(self, angles_rad: np.ndarray, y_counts: np.ndarray) -> np.ndarray:
        return angles_rad

    def end_cycle(self, y_counts: np.ndarray) -> None:
        return None


@dataclass
class RCP(ConfigDataclass):
    """Rapid cessation of protraction, Ch.3 form: amplitude reduced by the mean super-threshold ``|y|``.

    After each cycle, for each whisker, ``P = mean(``|y - b|``)`` over the samples with
    ``|y - b| > threshold_counts`` (``b`` = mean of the last 100 samples, the
    free-whisking baseline of Sec 5.1.1.1.1; ``P = 0`` without such samples), and
    the next cycle's amplitude is ``clip(A_full - gain * P, min_amplitude, A_full)``.
    The starting (retraction) angle is kept.

    Parameters
    ----------
    pattern : WhiskPattern
        The global pattern (full amplitude A_full).
    threshold_counts : float, default 80
        Contact threshold, counts; set it with :func:`contact_threshold_from_noise`
        (default = 20 x the 4-count noise std of :class:`whisker_io.sim.signals.SignalParams`).
    gain_rad_per_count : float, default 50 deg / 2047
        Amplitude reduction per count of mean deflection (assumption: a full-scale
        mean deflection halves the 100-deg amplitude).
    min_amplitude_rad : float, default 10 deg
        Smallest commanded amplitude.
    """

    pattern: WhiskPattern = field(default_factory=WhiskPattern)
    threshold_counts: float = checked(80.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar)
    gain_rad_per_count: float = checked(math.radians(50.0) / 2047.0, float, minimum=0, error=InvalidInputError,
                                        reader=finite_scalar)
    min_amplitude_rad: float = checked(math.radians(10.0), float, minimum=0, error=InvalidInputError,
                                       reader=finite_scalar)
    amplitudes_rad: np.ndarray | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.pattern, WhiskPattern):
            raise InvalidInputError(f"pattern must be a WhiskPattern, got {type(self.pattern).__name__}")
        if self.min_amplitude_rad > self.pattern.amplitude_rad:
            raise InvalidInputError("min_amplitude_rad must not exceed the pattern's full amplitude")

    def command(self, n_whiskers: int) -> np.ndarray:
        n = _check_n(n_whiskers)
        if self.amplitudes_rad is None or self.amplitudes_rad.shape != (n,):
            self.amplitudes_rad = np.full(n, self.pattern.amplitude_rad)
        return self.pattern.angles(self.amplitudes_rad)

    def respond(self, angles_rad: np.ndarray, y_counts: np.ndarray) -> np.ndarray:
        return angles_rad

    def perturbation_counts(self, y_counts: np.ndarray) -> np.ndarray:
        """Mean ``|y - baseline|`` over the super-threshold samples of each whisker, shape (n,), counts."""
        y = _check_y(y_counts, None, self.pattern.n_samples)
        dev = np.abs(y - y[:, -100:].mean(axis=1, keepdims=True))
        above = dev > self.threshold_counts
        count = above.sum(axis=1)
        total = np.where(above, dev, 0.0).sum(axis=1)
        return np.divide(total, count, out=np.zeros(y.shape[0]), where=count > 0)

    def end_cycle(self, y_counts: np.ndarray) -> None:
        p = self.perturbation_counts(y_counts)
        self.amplitudes_rad = np.clip(
            self.pattern.amplitude_rad - self.gain_rad_per_count * p,
            self.min_amplitude_rad,
            self.pattern.amplitude_rad,
        )


@dataclass
class RetractAtMax(ConfigDataclass):
    """Ch.4/6 RCP: retract as soon as ``|y-deflection|`` reaches the sensor maximum (Sec 4.1.1).

    Parameters
    ----------
    pattern : WhiskPattern
        The global pattern.
    threshold_counts : float, default 2000
        Trigger level on ``|y - b|`` (``b`` = mean of the first 100 samples, taken
        before any contact), counts. Default: 98 % of the 2047-count ADC maximum,
        so sensor noise at saturation still triggers.
    """

    pattern: WhiskPattern = field(default_factory=WhiskPattern)
    threshold_counts: float = checked(2000.0, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                      message="{name} must be > 0, got {value!r}")

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.pattern, WhiskPattern):
            raise InvalidInputError(f"pattern must be a WhiskPattern, got {type(self.pattern).__name__}")

    def command(self, n_whiskers: int) -> np.ndarray:
        return OpenLoop(self.pattern).command(n_whiskers)

    def respond(self, angles_rad: np.ndarray, y_counts: np.ndarray) -> np.ndarray:
        """Replace each triggered trajectory after its trigger sample by cessation + retraction.

        Parameters
        ----------
        angles_rad : ndarray, shape (n, T)
            Trajectories as run so far, radians.
        y_counts : ndarray, shape (n, T)
            Measured y-deflection, counts.

        Returns
        -------
        ndarray, shape (n, T)
            New trajectories (a copy; untouched rows identical).
        """
        angles = np.array(angles_rad, dtype=np.float64)
        T = self.pattern.n_samples
        if angles.ndim != 2 or angles.shape[1] != T:
            raise InvalidInputError(f"angles_rad must have shape (n, {T}), got {angles.shape}")
        y = _check_y(y_counts, angles.shape[0], T)
        dev = np.abs(y - y[:, :100].mean(axis=1, keepdims=True))
        hit = dev >= self.threshold_counts
        start = self.pattern.retraction_rad
        half = max(1, int(round(0.5 * self.pattern.n_samples)))
        for i in np.flatnonzero(hit.any(axis=1)):
            k = int(np.argmax(hit[i]))
            theta_k = angles[i, k]
            u = np.arange(1, T - k)
            ramp = np.where(u < half, 0.5 * (1.0 + np.cos(np.pi * np.minimum(u, half) / half)), 0.0)
            angles[i, k + 1 :] = start + (theta_k - start) * ramp
        return angles

    def end_cycle(self, y_counts: np.ndarray) -> None:
        return None
