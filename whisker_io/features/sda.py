"""Slope distribution array (SDA) and its similarity NMSE (thesis Sec 5.1.1.1.3, Eq 5.3-5.4).

"The slope of a contacted surface may be inferred by the gradient of the function
describing the change of the y-deflection signal against the x-deflection signal,
during the initial contact period" (Kim & Moeller 2007): per whisker, the
least-squares line ``y = g x + c`` is fitted to the (moving-average smoothed)
deflection samples from contact onset to the y-deflection peak, and the SDA is
the vector of the 18 gradients ``g`` in array order, with a mask for whiskers
without a contact.

Decisions: the fit uses the span-100 smoothed x and y (the same preprocessing as
detection); a whisker whose x-deflection does not vary over the window (a
surface squarely facing the whisk) has an undefined gradient and is masked out
(``min_x_spread_counts``). With the frictionless beam model of
:mod:`whisker_io.sim.signals` the gradient equals ``n_y / n_x``, the surface normal
on the sensor axes.

``NMSE(x, y) = MSE(x, y) / MSE(x, 0)`` with ``MSE(x, y) = ||x - y||^2 / n`` (Eq 5.3-5.4),
taken over the whiskers valid in both arrays.

Example
-------
>>> import numpy as np
>>> from whisker_io.features.sda import nmse
>>> round(nmse(np.array([1.0, 2.0]), np.array([1.0, 3.0])), 12)   # (0 + 1) / (1 + 4)
0.2
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from whisker_io.contact.detection import DetectedContact, _smooth_by_length, moving_average
from whisker_io.errors import InvalidInputError
from whisker_io.records.whisk_record import WhiskRecord

__all__ = ["SlopeDistribution", "contact_gradient", "slope_distribution", "nmse"]


@dataclass(frozen=True, eq=False)
class SlopeDistribution:
    """The SDA of one array whisk cycle.

    Attributes
    ----------
    slopes : ndarray, shape (N,)
        Gradient of y- against x-deflection per whisker (dimensionless, counts
        per count); 0 where masked.
    mask : ndarray of bool, shape (N,)
        True where the whisker had a contact with a defined gradient.
    modules : tuple of str
        Module names in array order.
    """

    slopes: np.ndarray
    mask: np.ndarray
    modules: tuple[str, ...]


def contact_gradient(
    record: WhiskRecord,
    contact: DetectedContact,
    smoothing_span: int = 100,
    min_x_spread_counts: float = 1.0,
) -> float | None:
    """Least-squares gradient dy/dx over onset..peak of one contact (Sec 5.1.1.1.3).

    Parameters
    ----------
    record : WhiskRecord
    contact : DetectedContact
    smoothing_span : int, default 100
        Moving-average span applied to x and y first, samples.
    min_x_spread_counts : float, default 1
        Minimum standard deviation of x over the window, counts; below it the
        gradient is undefined and ``None`` is returned.

    Returns
    -------
    float or None
        Gradient, counts/counts.
    """
    if not isinstance(record, WhiskRecord) or not isinstance(contact, DetectedContact):
        raise InvalidInputError("contact_gradient needs a WhiskRecord and a DetectedContact")
    lo, hi = contact.onset_index, contact.peak_index + 1
    if not (0 <= lo < hi <= record.n_samples):
        raise InvalidInputError(f"contact indices do not fit record {record.module} of {record.n_samples} samples")
    xs = moving_average(record.x_counts, smoothing_span)[lo:hi]
    ys = moving_average(record.y_counts, smoothing_span)[lo:hi]
    return _window_gradient(xs, ys, min_x_spread_counts)


def _window_gradient(xs: np.ndarray, ys: np.ndarray, min_x_spread_counts: float) -> float | None:
    """The least-squares gradient of :func:`contact_gradient` on smoothed onset..peak windows."""
    if xs.size < 2 or not (np.isfinite(xs).all() and np.isfinite(ys).all()):
        return None
    # scale-free: centred signals divided by their largest magnitude, so signals near the
    # float limit (1e300 counts) give their gradient, never an overflowed NaN marked valid
    xc, yc = xs - xs.mean(), ys - ys.mean()
    sx, sy = float(np.max(np.abs(xc))), float(np.max(np.abs(yc)))
    if not (np.isfinite(sx) and np.isfinite(sy)) or sx == 0.0 or sx * float(np.std(xc / sx)) < min_x_spread_counts:
        return None
    u, w = xc / sx, (yc / sy if sy > 0 else yc)
    g = float(np.dot(u, w) / np.dot(u, u)) * (sy / sx if sy > 0 else 1.0 / sx)
    return g if np.isfinite(g) else None


def slope_distribution(
    records: Sequence[WhiskRecord],
    contacts: Sequence[DetectedContact | None],
    smoothing_span: int = 100,
    min_x_spread_counts: float = 1.0,
) -> SlopeDistribution:
    """SDA of one array cycle: :func:`contact_gradient` per whisker, masked where undefined.

    Parameters
    ----------
    records : sequence of WhiskRecord, length N
        The array's whisk cycle in array order.
    contacts : sequence of DetectedContact or None, length N
        Detected contacts (``None``: no contact, masked).

    Returns
    -------
    SlopeDistribution
    """
    recs, dets = list(records), list(contacts)
    if len(recs) != len(dets):
        raise InvalidInputError(f"{len(recs)} records but {len(dets)} contacts; pass one contact (or None) per record")
    slopes = np.zeros(len(recs))
    mask = np.zeros(len(recs), dtype=bool)
    for i, (r, c) in enumerate(zip(recs, dets)):
        if c is None:
            continue
        g = contact_gradient(r, c, smoothing_span, min_x_spread_counts)
        if g is not None:
            slopes[i], mask[i] = g, True
    return SlopeDistribution(slopes=slopes, mask=mask, modules=tuple(r.module for r in recs))


def _slope_distribution_smoothed(
    records: Sequence[WhiskRecord],
    contacts: Sequence[DetectedContact | None],
    y_smoothed: Sequence[np.ndarray],
    smoothing_span: int,
    min_x_spread_counts: float = 1.0,
) -> SlopeDistribution:
    """:func:`slope_distribution` of checked records and their detections, given the smoothed y
    of contact detection (``y_smoothed[i]`` is ``moving_average(records[i].y_counts, smoothing_span)``);
    the x of the contacted modules is smoothed in one call. Same bits as :func:`slope_distribution`."""
    n = len(records)
    slopes = np.zeros(n)
    mask = np.zeros(n, dtype=bool)
    hit = [i for i, c in enumerate(contacts) if c is not None]
    xs = _smooth_by_length([records[i].x_counts for i in hit], smoothing_span)
    for i, x_s in zip(hit, xs):
        c = contacts[i]
        lo, hi = c.onset_index, c.peak_index + 1
        if not (0 <= lo < hi <= records[i].n_samples):
            raise InvalidInputError(f"contact indices do not fit record {records[i].module} "
                                    f"of {records[i].n_samples} samples")
        g = _window_gradient(x_s[lo:hi], y_smoothed[i][lo:hi], min_x_spread_counts)
        if g is not None:
            slopes[i], mask[i] = g, True
    return SlopeDistribution(slopes=slopes, mask=mask, modules=tuple(r.module for r in records))


def nmse(
    x: np.ndarray,
    y: np.ndarray,
    mask_x: np.ndarray | None = None,
    mask_y: np.ndarray | None = None,
) -> float | np.ndarray:
    """Normalised mean square error ``MSE(x, y) / MSE(x, 0)`` (Eq 5.3-5.4), masked.

    Parameters
    ----------
    x : array_like, shape (N,)
        The reference SDA (the normaliser is its own power; in region matching the
        current whisk, Eq 5.5).
    y : array_like, shape (N,) or (m, N)
        One SDA, or ``m`` stored SDAs compared with ``x`` at once.
    mask_x : array_like of bool, shape (N,), optional
    mask_y : array_like of bool, shape of ``y``, optional
        Valid entries (all when omitted); only entries valid in both count.

    Returns
    -------
    float or ndarray (m,)
        0 for identical arrays; ``inf`` when no entry is valid in both, or when
        ``x`` is all zero there and ``y`` is not (0 if both are). The ratio is
        scale-free, so it is computed on both arrays divided by their largest
        magnitude: values near the float limit (``nmse([1e200], [0])`` is 1)
        never overflow into NaN. A ratio beyond the float range is ``inf``.

    Raises
    ------
    InvalidInputError
        Non-numeric input, ``x`` not 1-D, ``y`` not (N,) or (m, N), a mask of
        another shape, or NaN/inf at a valid entry.
    """
    try:
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(y, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"x and y must be arrays of numbers, got {x!r} and {y!r}") from None
    if xa.ndim == 1 and xa.shape[0] == 0:
        raise InvalidInputError("an SDA needs at least one whisker")
    single = ya.ndim == 1
    if xa.ndim != 1 or ya.ndim not in (1, 2) or ya.shape[-1] != xa.shape[0]:
        raise InvalidInputError(f"x must be 1-D and y (N,) or (m, N) of the same length N, got {xa.shape} and {ya.shape}")
    y2 = ya.reshape(-1, xa.shape[0])
    both = np.ones(y2.shape, dtype=bool)
    for m, shape in ((mask_x, xa.shape), (mask_y, ya.shape)):
        if m is not None:
            ma = np.asarray(m, dtype=bool)
            if ma.shape != shape:
                raise InvalidInputError(f"mask shape {ma.shape} does not match {shape}")
            both &= ma.reshape(-1, xa.shape[0]) if ma.ndim == ya.ndim else ma
    mx = np.ones(xa.shape, dtype=bool) if mask_x is None else np.asarray(mask_x, dtype=bool)
    my = np.ones(y2.shape, dtype=bool) if mask_y is None else np.asarray(mask_y, dtype=bool).reshape(y2.shape)
    if not np.all(np.isfinite(np.broadcast_to(xa, y2.shape)[both])) or not np.all(np.isfinite(y2[both])):
        raise InvalidInputError("SDA entries must be finite where valid; mask out undefined slopes")
    from whisker_io.features._distances_numba import nmse_rows

    # C-contiguous and writable (a read-only input is copied): numba compiles a separate
    # specialisation for every mix of read-only and writable arrays
    out = nmse_rows(*(np.require(a, requirements=("C", "W")) for a in (xa, y2, mx, my)))
    return float(out[0]) if single else out
