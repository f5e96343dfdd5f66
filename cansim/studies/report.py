"""What the studies' summaries share: numbers that may be undefined.

A summary line can hold a figure no run defined - a median error with no
re-localisation, a test statistic over groups that do not vary - which NumPy and SciPy
give as NaN. :func:`fmt` prints it as ``undefined``, never ``nan``, as the JSON outputs
write ``null``.
"""

from __future__ import annotations

import math

__all__ = ["fmt"]


def fmt(value: float, spec: str = ".3f") -> str:
    """``value`` formatted with ``spec`` (a :func:`format` spec), or ``"undefined"`` when it is NaN or infinite.

    >>> fmt(0.12345), fmt(float("nan")), fmt(3.0, ".1f")
    ('0.123', 'undefined', '3.0')
    """
    return format(value, spec) if math.isfinite(value) else "undefined"
