"""Contact features CP, CA, DV, DA, AV, AA, WL of a detected contact (thesis Sec 4.1.2.4).

"Using a moving average filter, the deflection and angular sensor data for each
whisk-sample was smoothed and further processed to extract the following contact
features; deflection velocity, deflection acceleration, angular velocity, angular
acceleration, contact period and contact amplitude." Decision (Sec 5.1.1.1.1): all
are evaluated over the initial contact period, onset -> peak, rates as means.

Columns of the feature matrix (:data:`FEATURE_NAMES`, units :data:`FEATURE_UNITS`):

====  =================================================================  ==========
col   definition                                                         unit
====  =================================================================  ==========
CP    contact period: ``(peak - onset) / fs``                             s
CA    contact amplitude: ``sign * (top of y_s - baseline)``               counts
DV    deflection velocity: mean of ``sign * dy_s/dt`` over onset..peak    counts/s
DA    deflection acceleration: mean of ``sign * d2y_s/dt2``               counts/s^2
AV    angular velocity: mean of ``dtheta_s/dt`` over onset..peak          rad/s
AA    angular acceleration: mean of ``d2theta_s/dt2``                     rad/s^2
WL    whisker length                                                     m
====  =================================================================  ==========

``y_s`` and ``theta_s`` are the span-100 moving averages of the y-deflection and
angle, derivatives by ``numpy.gradient``, means over the samples onset..peak
inclusive; ``sign`` (+-1) is the detected deflection direction, so CA, DV > 0.

Example
-------
>>> from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
>>> from whisker_io.contact.detection import detect_contacts
>>> from whisker_io.contact.features import FEATURE_NAMES, contact_features
>>> recs, _ = simulate_whisk_cycle([WhiskContact(0.0, 0.04, 0.1), WhiskContact(0.0, 0.08, 0.1)], seed=0)
>>> F = contact_features(recs, detect_contacts(recs), [0.1, 0.1])
>>> F.shape, FEATURE_NAMES[2], bool(F[0, 2] > F[1, 2])   # nearer the base -> faster deflection
((2, 7), 'DV', True)
"""

from __future__ import annotations

from collections.abc import Sequence
from types import MappingProxyType

import numpy as np

from whisker_io.contact.detection import DetectedContact, moving_average
from whisker_io.errors import InvalidInputError
from whisker_io.records.whisk_record import WhiskRecord

__all__ = ["FEATURE_NAMES", "FEATURE_UNITS", "contact_features", "whisk_features"]

#: Column order of :func:`contact_features` (Sec 4.1.2.4).
FEATURE_NAMES: tuple[str, ...] = ("CP", "CA", "DV", "DA", "AV", "AA", "WL")
#: Unit of each column.
FEATURE_UNITS = MappingProxyType(
    {"CP": "s", "CA": "counts", "DV": "counts/s", "DA": "counts/s^2", "AV": "rad/s", "AA": "rad/s^2", "WL": "m"}
)


def _window_means(values: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Row-wise mean of ``values[i, start[i]:stop[i] + 1]`` via cumulative sums; (n, T) -> (n,)."""
    cs = np.concatenate([np.zeros((values.shape[0], 1)), np.cumsum(values, axis=1)], axis=1)
    rows = np.arange(values.shape[0])
    return (cs[rows, stop + 1] - cs[rows, start]) / (stop - start + 1)


def _rate(values: np.ndarray, fs: float) -> np.ndarray:
    """Time derivative along axis 1 (``np.gradient`` x fs; zeros for a single sample)."""
    return np.gradient(values, axis=1) * fs if values.shape[1] > 1 else np.zeros_like(values)


def contact_features(
    records: Sequence[WhiskRecord],
    contacts: Sequence[DetectedContact],
    whisker_lengths_m: Sequence[float] | np.ndarray,
    smoothing_span: int = 100,
) -> np.ndarray:
    """Feature matrix of a batch of detected contacts, vectorised per record length.

    Parameters
    ----------
    records : sequence of WhiskRecord, length n
        The whisk cycles.
    contacts : sequence of DetectedContact, length n
        Their detected contacts (filter out ``None`` first).
    whisker_lengths_m : array_like, shape (n,)
        Whisker length of each record, m (feature WL).
    smoothing_span : int, default 100
        Moving-average span, samples (as in detection).

    Returns
    -------
    ndarray, shape (n, 7)
        Columns :data:`FEATURE_NAMES`, units :data:`FEATURE_UNITS`.

    Raises
    ------
    InvalidInputError
        Mismatched lengths, a missing contact, indices outside a record, or a
        non-positive/non-finite whisker length.
    """
    recs, dets = list(records), list(contacts)
    wl = np.asarray(whisker_lengths_m, dtype=np.float64)
    n = len(recs)
    if len(dets) != n or wl.shape != (n,):
        raise InvalidInputError(
            f"records ({n}), contacts ({len(dets)}) and whisker_lengths_m {wl.shape} must have the same length"
        )
    if not (np.all(np.isfinite(wl)) and np.all(wl > 0)):
        raise InvalidInputError("whisker_lengths_m must be finite and > 0 (metres)")
    for i, (r, c) in enumerate(zip(recs, dets)):
        if not isinstance(r, WhiskRecord) or not isinstance(c, DetectedContact):
            raise InvalidInputError(
                f"entry {i}: need a WhiskRecord and a DetectedContact (drop whisks without contact first)"
            )
        if not (0 <= c.onset_index <= c.peak_index < r.n_samples):
            raise InvalidInputError(f"entry {i}: contact indices do not fit record {r.module} of {r.n_samples} samples")
    out = np.empty((n, len(FEATURE_NAMES)))
    out[:, 6] = wl
    groups: dict[tuple[int, float], list[int]] = {}
    for i, r in enumerate(recs):
        groups.setdefault((r.n_samples, r.sample_rate_hz), []).append(i)
    for (_, fs), idx in groups.items():
        ys = moving_average(np.stack([recs[i].y_counts for i in idx]), smoothing_span)
        th = moving_average(np.stack([recs[i].angle_rad for i in idx]), smoothing_span)
        on = np.array([dets[i].onset_index for i in idx])
        pk = np.array([dets[i].peak_index for i in idx])
        sign = np.array([dets[i].sign for i in idx], dtype=np.float64)
        dy = _rate(ys, fs)
        d2y = _rate(dy, fs)
        dth = _rate(th, fs)
        d2th = _rate(dth, fs)
        out[idx, 0] = (pk - on) / fs
        out[idx, 1] = [dets[i].amplitude_counts for i in idx]
        out[idx, 2] = sign * _window_means(dy, on, pk)
        out[idx, 3] = sign * _window_means(d2y, on, pk)
        out[idx, 4] = _window_means(dth, on, pk)
        out[idx, 5] = _window_means(d2th, on, pk)
    return out


def whisk_features(
    record: WhiskRecord, contact: DetectedContact, whisker_length_m: float, smoothing_span: int = 100
) -> np.ndarray:
    """Features of a single contact, shape (7,); see :func:`contact_features`."""
    return contact_features([record], [contact], [whisker_length_m], smoothing_span)[0]
