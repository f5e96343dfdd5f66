"""Contact detection in one whisk cycle (thesis Sec 5.1.1.1.1, Ch.3 alternatives Sec 3.1.1).

Pipeline (:func:`detect_contact`), per module and whisk cycle:

1. moving average of span 100 samples on all signals (centred window, like
   MATLAB ``smooth``; :func:`moving_average`);
2. peaks of the smoothed y-deflection as ``scipy.signal.find_peaks`` with
   minimum width 100 samples and minimum prominence 500 counts would return
   them (``find_peaks`` + ``peak_prominences`` + ``peak_widths``, evaluated only
   for local maxima that can reach the prominence, for speed); the single most
   prominent peak is kept. Decision (sign): the deflection may be negative (a
   contact in retraction or the array pushing the whisker), so peaks of ``+y``
   and ``-y`` are both searched and the more prominent kept; its sign is reported;
3. onset: back-track from the peak to the nearest sample where the derivative
   of the smoothed signal changes sign; offset: the first sign change after the
   peak. Decisions: (a) the peak index is the first sample within
   ``plateau_tolerance_counts`` of the top, so a saturated (flat) top reports
   where saturation began, not the middle ``find_peaks`` returns; (b) the
   back-track starts where the rise crosses half the prominence (the forward
   search for the offset where the fall does) - otherwise noise on a saturated
   plateau or on the rounded top of a slow whisk stops it at once; (c) the
   sign change is located as the zero crossing of a line fitted to the
   derivative's rise (``refine_onset``), which removes the lag the rise needs to
   clear the noise; (d) the centred window makes the smoothed signal start
   rising ``ceil(span/2)`` samples before the raw signal and stop falling
   ``floor(span/2)`` samples after it, so those leads are added to / removed
   from the sign-change indices (``compensate_lead``, default on), which puts
   the onset on the first deflected sample rather than 25 ms early;
4. confirm: ``|peak - mean(last 100 raw samples)|`` (the free-whisking baseline)
   must exceed ``confirm_threshold_counts``.

The contact angle is the (raw) whisk angle at the onset (Sec 5.1.1.1.2; the
moving average of a fast cosine whisk is biased by up to a few degrees).
Ch.3's alternatives are :func:`max_angle` (largest angle of the cycle) and
:func:`threshold_contact_angle` (angle when ``|d deflection/dt|`` first crosses a
threshold).

Example
-------
>>> from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
>>> from whisker_io.contact.detection import detect_contact
>>> (rec,), (truth,) = simulate_whisk_cycle([WhiskContact(0.0, 0.05, 0.1)], seed=3)
>>> c = detect_contact(rec)
>>> abs(c.onset_index - truth.onset_index) <= 10, c.sign
(True, 1)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import peak_prominences, peak_widths

from whisker_io.contact._detection_numba import bounded_maxima, contact_extent, prominence_bound
from whisker_io.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_scalar, validate_fields, whole_number
from whisker_io.records.whisk_record import WhiskRecord

__all__ = [
    "DetectionParams",
    "DetectedContact",
    "moving_average",
    "detect_contact",
    "detect_contacts",
    "max_angle",
    "threshold_contact_angle",
    "warm_up_kernels",
]


@dataclass(frozen=True)
class DetectionParams(ConfigDataclass):
    """Parameters of the contact-detection pipeline (defaults: thesis Sec 5.1.1.1.1).

    Parameters
    ----------
    smoothing_span : int, default 100
        Moving-average span, samples.
    min_width_samples : float, default 100
        ``find_peaks`` minimum peak width (at half prominence), samples.
    min_prominence_counts : float, default 500
        ``find_peaks`` minimum prominence, counts.
    confirm_threshold_counts : float, default 500
        Minimum ``|peak - baseline|``, counts (the thesis gives no value;
        decision: the prominence threshold).
    baseline_samples : int, default 100
        Trailing samples forming the free-whisking baseline.
    plateau_tolerance_counts : float, default 20
        Samples within this of the top belong to a (saturated) plateau, counts.
    signs : tuple of int, default (1, -1)
        Deflection signs searched (``(1,)`` for positive peaks only).
    compensate_lead : bool, default True
        Undo the centred window's lead on the onset/offset indices.
    refine_onset : bool, default True
        Place the onset at the zero crossing of a line fitted to the smoothed
        derivative's rise after the sign change (sub-sample, noise-robust)
        instead of at the sign change itself.
    """

    smoothing_span: int = checked(100, int, minimum=1, error=InvalidInputError)
    min_width_samples: float = checked(100.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                       label="DetectionParams.min_width_samples")
    min_prominence_counts: float = checked(500.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                           label="DetectionParams.min_prominence_counts")
    confirm_threshold_counts: float = checked(500.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                              label="DetectionParams.confirm_threshold_counts")
    baseline_samples: int = checked(100, int, minimum=1, error=InvalidInputError)
    plateau_tolerance_counts: float = checked(20.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                              label="DetectionParams.plateau_tolerance_counts")
    signs: tuple[int, ...] = (1, -1)
    compensate_lead: bool = True
    refine_onset: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.signs, tuple) or not self.signs or any(s not in (1, -1) for s in self.signs):
            raise InvalidInputError(f"signs must be a non-empty tuple of +1/-1, got {self.signs!r}")


@dataclass(frozen=True)
class DetectedContact:
    """A contact found in one whisk cycle.

    Attributes
    ----------
    onset_index, peak_index, offset_index : int
        Sample indices of contact onset, deflection peak (start of a saturated
        top) and offset (contact lost), ``onset <= peak <= offset``.
    onset_time_s, peak_time_s, offset_time_s : float
        The same as times from the start of the cycle, seconds.
    contact_angle_rad : float
        Whisk angle at onset, radians.
    sign : int
        +1 for a positive y-deflection peak, -1 for a negative one.
    peak_counts : float
        Top of the smoothed y-deflection peak (signed), counts.
    baseline_counts : float
        Mean of the last ``baseline_samples`` raw y samples, counts.
    prominence_counts : float
        ``find_peaks`` prominence of the peak, counts.
    sample_rate_hz : float
        Sampling rate, Hz.
    """

    onset_index: int
    peak_index: int
    offset_index: int
    onset_time_s: float
    peak_time_s: float
    offset_time_s: float
    contact_angle_rad: float
    sign: int
    peak_counts: float
    baseline_counts: float
    prominence_counts: float
    sample_rate_hz: float

    @property
    def amplitude_counts(self) -> float:
        """Deflection of the peak above the baseline in the contact's direction, counts (>= 0)."""
        return self.sign * (self.peak_counts - self.baseline_counts)


#: A smoothing span up to this many samples is accepted for any signal; beyond it, at most
#: 8 x the signal length (a longer window only repeats the edge values, and costs memory).
MAX_FREE_SPAN = 100_000


def moving_average(signal: np.ndarray, span: int = 100) -> np.ndarray:
    """Centred moving average over the last axis (edges padded with the end values).

    Output ``k`` averages input samples ``k - ceil(span/2) + 1 .. k + floor(span/2)``
    for even spans shifted as in :func:`scipy.ndimage.uniform_filter1d`; shape kept.

    Raises
    ------
    InvalidInputError
        A span that is not a whole number >= 1 (0 would reach scipy as a
        RuntimeError), or an empty or non-finite signal.
    """
    size = whole_number(span, "smoothing span", minimum=1)
    arr = finite_array(signal, None, "signal")
    if arr.ndim == 0 or arr.shape[-1] == 0:
        raise InvalidInputError("cannot smooth an empty signal")
    limit = max(8 * arr.shape[-1], MAX_FREE_SPAN)  # the filter's work and memory grow with the span
    if size > limit:
        raise InvalidInputError(f"smoothing span {span!r} is too large for a signal of {arr.shape[-1]} samples "
                                f"(at most {limit}); use at most the signal length")
    return uniform_filter1d(arr, size=size, axis=-1, mode="nearest")


def _check_record(record: WhiskRecord) -> WhiskRecord:
    if not isinstance(record, WhiskRecord):
        raise InvalidInputError(f"expected a WhiskRecord, got {type(record).__name__}")
    return record


def _best_peak(ys: np.ndarray, params: DetectionParams) -> tuple[int, int, float] | None:
    """Most prominent peak of ``+ys`` / ``-ys`` passing width and prominence: (index, sign, prominence).

    Equivalent to ``find_peaks(z, width=..., prominence=...)`` but prominences and
    widths are computed only for local maxima that can reach the prominence: a
    peak's prominence is at most its height above the lower of the minima on
    either side, a bound that rejects free whisking, the opposite sign of a
    contact and the noise wiggles around a contact in one vectorised pass.
    """
    best: tuple[int, int, float] | None = None
    P, W = params.min_prominence_counts, params.min_width_samples
    if ys.size == 0 or float(ys.max()) - float(ys.min()) < P:  # a prominence never exceeds the range
        return None
    for sign in params.signs:
        bound = prominence_bound(ys, float(sign))
        if not np.any(bound >= P):
            continue
        peaks = bounded_maxima(ys, float(sign), bound, float(P))  # find_peaks(z)'s peaks that can reach P
        if not peaks.size:
            continue
        z = sign * ys
        prom, left, right = peak_prominences(z, peaks)
        keep = prom >= P
        if not keep.any():
            continue
        peaks, prom, left, right = peaks[keep], prom[keep], left[keep], right[keep]
        widths = peak_widths(z, peaks, rel_height=0.5, prominence_data=(prom, left, right))[0]
        keep = widths >= W
        if keep.any():
            j = int(np.argmax(np.where(keep, prom, -np.inf)))
            if best is None or prom[j] > best[2]:
                best = (int(peaks[j]), sign, float(prom[j]))
    return best


def warm_up_kernels() -> None:
    """Compile (or load from numba's disk cache) the detection's compiled scans now, so the first
    whisk with a contact does not pay for it (the signal-path chains call this when built)."""
    z = np.array([0.0, 1.0, 0.0])
    bound = prominence_bound(z, 1.0)
    bounded_maxima(z, 1.0, bound, 0.0)
    contact_extent(z, 1.0, 1, 0.5, 0.5)


def _refine_onset(d: np.ndarray, onset: int, rise_mid: int, span: int) -> int:
    """Zero crossing of a line fitted to the derivative's rise just after ``onset``.

    Behind a kink the centred moving average's derivative grows linearly over
    one span, so its zero crossing locates the kink to a fraction of a sample,
    where the first sign change lags by the samples the rise needs to clear
    the noise. The fit stops where the derivative first reaches 80 % of its
    maximum (a ramp shorter than the span, e.g. a quickly saturating contact
    near the base, makes the derivative level off early).
    """
    seg = d[onset : onset + span]
    m = min(span // 2, (rise_mid - onset) // 2, int(np.argmax(seg >= 0.8 * seg.max())) if seg.size else 0)
    if m < 3:
        return onset
    k = np.arange(m, dtype=np.float64)
    k_mean = 0.5 * (m - 1)  # k.mean(), exactly: the sum of 0..m-1 is exact and (m - 1) / 2 representable
    dk = d[onset : onset + m]
    dk_mean = dk.mean()
    kc = k - k_mean
    slope = float(np.dot(kc, dk - dk_mean) / np.dot(kc, kc))
    if not slope > 0:
        return onset
    k0 = onset + k_mean - float(dk_mean) / slope
    if not (onset - span // 2 <= k0 <= rise_mid):
        return onset
    return int(math.floor(k0)) + 1  # first sample with a positive derivative


def detect_contact(
    record: WhiskRecord,
    params: DetectionParams | None = None,
    smoothed: np.ndarray | None = None,
) -> DetectedContact | None:
    """Detect the contact in one whisk cycle (Sec 5.1.1.1.1), or ``None``.

    Parameters
    ----------
    record : WhiskRecord
        One module's whisk cycle (angle in radians, y in counts).
    params : DetectionParams, optional
        Thesis defaults when omitted.
    smoothed : ndarray, shape (T,), optional
        Pre-computed :func:`moving_average` of the record's y (used by
        :func:`detect_contacts` to smooth a batch at once).

    Returns
    -------
    DetectedContact or None
        ``None`` for a free-whisking cycle (no peak passing width, prominence and
        confirmation).
    """
    p = DetectionParams() if params is None else params
    rec = _check_record(record)
    if smoothed is None:
        y_s = moving_average(rec.y_counts, p.smoothing_span)
    else:
        y_s = np.ascontiguousarray(smoothed, dtype=np.float64)
    found = _best_peak(y_s, p)
    if found is None:
        return None
    top, sign, prom = found
    baseline = float(np.mean(rec.y_counts[-p.baseline_samples :]))
    if abs(y_s[top] - baseline) <= p.confirm_threshold_counts:
        return None
    z_top = sign * y_s[top]
    # runs above the plateau level and half the prominence around the top, and the sign changes of
    # diff(sign * y_s) before the rise (onset) and after the fall (offset), in one compiled scan
    peak, plateau_end, rise_mid, fall_mid, onset, offset = (int(v) for v in contact_extent(
        y_s, float(sign), int(top), float(z_top - p.plateau_tolerance_counts), float(z_top - 0.5 * prom)))
    if p.refine_onset:
        onset = _refine_onset(np.diff(sign * y_s), onset, rise_mid, p.smoothing_span)  # d[k] = z[k+1] - z[k]
    if p.compensate_lead:
        onset = min(onset + (p.smoothing_span + 1) // 2, peak)
        offset = max(offset - p.smoothing_span // 2, plateau_end)
    fs = rec.sample_rate_hz
    return DetectedContact(
        onset_index=onset,
        peak_index=peak,
        offset_index=offset,
        onset_time_s=onset / fs,
        peak_time_s=peak / fs,
        offset_time_s=offset / fs,
        contact_angle_rad=float(rec.angle_rad[onset]),
        sign=sign,
        peak_counts=float(y_s[top]),
        baseline_counts=baseline,
        prominence_counts=prom,
        sample_rate_hz=fs,
    )


def detect_contacts(
    records: Sequence[WhiskRecord], params: DetectionParams | None = None
) -> list[DetectedContact | None]:
    """:func:`detect_contact` for each record (e.g. the 18 modules of one array cycle).

    Records of equal length are smoothed together in one call.
    """
    return _detect_smoothed(records, params)[0]


def _detect_smoothed(
    records: Sequence[WhiskRecord], params: DetectionParams | None = None
) -> tuple[list[DetectedContact | None], list[np.ndarray]]:
    """:func:`detect_contacts` and the smoothed y of every record (views of one (n, T) array
    per record length), for callers that smooth the same records again (the SDA).

    Vectorised across modules: records of equal length are smoothed in one call, and one
    pass over the (n, T) smoothed array finds the modules whose range reaches the
    prominence; only those go through the per-module peak search (the range bounds the
    prominence, so the others have no peak: :func:`detect_contact` returns ``None`` for
    them at its first test).
    """
    p = DetectionParams() if params is None else params
    recs = [_check_record(r) for r in records]
    out: list[DetectedContact | None] = [None] * len(recs)
    smoothed = _smooth_by_length([r.y_counts for r in recs], p.smoothing_span)
    for i, y_s in enumerate(smoothed):
        if float(y_s.max()) - float(y_s.min()) >= p.min_prominence_counts:
            out[i] = detect_contact(recs[i], p, smoothed=y_s)
    return out, smoothed


def _smooth_by_length(signals: Sequence[np.ndarray], span: int) -> list[np.ndarray]:
    """:func:`moving_average` of each signal, the signals of equal length in one call (rows of one
    (n, T) result, returned as views); the same values as one call per signal."""
    out: list[np.ndarray] = [np.empty(0)] * len(signals)
    by_len: dict[int, list[int]] = {}
    for i, sig in enumerate(signals):
        by_len.setdefault(np.shape(sig)[-1] if np.ndim(sig) else 0, []).append(i)
    for idx in by_len.values():
        rows = moving_average(np.stack([signals[i] for i in idx]), span)
        for j, i in enumerate(idx):
            out[i] = rows[j]
    return out


def max_angle(record: WhiskRecord) -> float:
    """Ch.3 "max angle": the largest whisk angle of the cycle, radians (Sec 3.1.1)."""
    return float(np.max(_check_record(record).angle_rad))


def threshold_contact_angle(
    record: WhiskRecord,
    threshold_counts_per_s: float = 2500.0,
    smoothing_span: int = 100,
) -> float | None:
    """Ch.3 "contact angle": angle when ``|d deflection/dt|`` first crosses a threshold (Sec 3.1.1).

    The y-deflection and angle are smoothed (``smoothing_span``), the deflection
    rate is ``np.gradient(y) * fs``; no lead compensation (the method is, as the
    thesis notes, sensitive to noise).

    Parameters
    ----------
    record : WhiskRecord
    threshold_counts_per_s : float, default 2500
        Threshold on the deflection rate, counts/s (default ~20 sigma of the
        smoothed-derivative noise of the default simulator noise).
    smoothing_span : int, default 100

    Returns
    -------
    float or None
        Smoothed angle at the first crossing, radians; ``None`` if never crossed.
    """
    rec = _check_record(record)
    if not (math.isfinite(threshold_counts_per_s) and threshold_counts_per_s > 0):
        raise InvalidInputError(f"threshold_counts_per_s must be > 0, got {threshold_counts_per_s!r}")
    y_s = moving_average(rec.y_counts, smoothing_span)
    if y_s.size < 2:
        return None
    rate = np.abs(np.gradient(y_s)) * rec.sample_rate_hz
    hits = np.flatnonzero(rate > threshold_counts_per_s)
    if not hits.size:
        return None
    return float(moving_average(rec.angle_rad, smoothing_span)[hits[0]])
