"""Figures of whisker signals: one whisk's traces (Fig 2.9/4.4), x-y gradient (Fig 5.2), SDA bars (Fig 5.13 B).

matplotlib is imported inside the functions only. Every function takes an
optional Axes and returns the Figure.

Example
-------
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
>>> from whisker_io.contact.detection import detect_contact
>>> from whisker_io.plots.signals import plot_whisk
>>> (rec,), _ = simulate_whisk_cycle([WhiskContact(0.0, 0.05, 0.1)], seed=0)
>>> fig = plot_whisk(rec, detect_contact(rec))
>>> fig.savefig("whisk.png")                                    # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from whisker_io.contact.detection import DetectedContact, moving_average
from whisker_io.errors import InvalidInputError
from whisker_io.plots.axes import figure_and_axes
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.features.sda import SlopeDistribution, contact_gradient, nmse

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_whisk", "plot_xy_gradient", "plot_sda"]


def plot_whisk(
    record: WhiskRecord,
    contact: DetectedContact | None = None,
    ax: Axes | None = None,
    adc_max_counts: float = 2047.0,
    smoothing_span: int = 100,
) -> Figure:
    """One whisk cycle: x/y deflection (scaled to +-1) and angle (deg, right axis), onset/offset marked.

    The style of Fig 4.4 of the thesis: raw deflections as thin lines, their
    moving averages (span ``smoothing_span``) on top, the whisk angle on a twin
    axis, contact onset (red) and offset (black) as vertical lines and the peak
    as a dot.

    Parameters
    ----------
    record : WhiskRecord
    contact : DetectedContact, optional
        Marks onset/peak/offset when given.
    ax : matplotlib Axes, optional
    adc_max_counts : float, default 2047
        Deflections are divided by this.
    smoothing_span : int, default 100

    Returns
    -------
    matplotlib.figure.Figure
    """
    if not isinstance(record, WhiskRecord):
        raise InvalidInputError(f"record must be a WhiskRecord, got {type(record).__name__}")
    fig, ax = figure_and_axes(ax, (8.0, 3.5))
    t = record.time_s
    for values, name, colour in ((record.y_counts, "y", "tab:blue"), (record.x_counts, "x", "tab:orange")):
        ax.plot(t, values / adc_max_counts, color=colour, lw=0.5, alpha=0.4)
        ax.plot(t, moving_average(values, smoothing_span) / adc_max_counts, color=colour, lw=1.5, label=f"{name}-deflection")
    ax.set_ylim(-1.05, 1.05)
    ax.set_xlabel("time in whisk cycle (s)")
    ax.set_ylabel(f"deflection (counts / {adc_max_counts:g})")
    ax2 = ax.twinx()
    ax2.plot(t, np.degrees(record.angle_rad), color="tab:green", lw=1.0, label="angle")
    ax2.set_ylabel("whisk angle (deg)")
    if contact is not None:
        ax.axvline(contact.onset_time_s, color="red", lw=1.2, label="onset")
        ax.axvline(contact.offset_time_s, color="black", lw=1.0, ls="--", label="offset")
        ax.plot([contact.peak_time_s], [contact.peak_counts / adc_max_counts], "o", color="red", ms=4, label="peak")
    handles = ax.get_legend_handles_labels()
    h2 = ax2.get_legend_handles_labels()
    ax.legend(handles[0] + h2[0], handles[1] + h2[1], loc="upper left", fontsize=8)
    ax.set_title(f"module {record.module}, cycle {record.cycle}")
    return fig


def plot_xy_gradient(
    record: WhiskRecord, contact: DetectedContact, ax: Axes | None = None, smoothing_span: int = 100
) -> Figure:
    """x- against y-deflection over the cycle, initial contact period highlighted, fitted line (Fig 5.2)."""
    fig, ax = figure_and_axes(ax, (4.0, 4.0))
    xs = moving_average(record.x_counts, smoothing_span)
    ys = moving_average(record.y_counts, smoothing_span)
    lo, hi = contact.onset_index, contact.peak_index + 1
    ax.plot(xs, ys, color="0.6", lw=0.8, label="whisk cycle")
    ax.plot(xs[lo:hi], ys[lo:hi], color="red", lw=1.5, label="onset -> peak")
    g = contact_gradient(record, contact, smoothing_span)
    if g is not None:
        xm, ym = xs[lo:hi].mean(), ys[lo:hi].mean()
        xl = np.array([xs[lo:hi].min(), xs[lo:hi].max()])
        ax.plot(xl, ym + g * (xl - xm), color="green", lw=1.5, label=f"gradient {g:.2f}")
    ax.set_xlabel("x-deflection (counts)")
    ax.set_ylabel("y-deflection (counts)")
    ax.legend(fontsize=8)
    ax.set_title(f"x against y deflection, module {record.module}, cycle {record.cycle}")
    return fig


def plot_sda(
    sda: SlopeDistribution,
    reference: SlopeDistribution | None = None,
    ax: Axes | None = None,
    labels: Sequence[str] = ("observed", "reference"),
) -> Figure:
    """Bar plot of a slope distribution array, one bar per module (Fig 5.13 B style).

    Masked modules (no contact / undefined slope) are drawn as grey hatched
    stubs. With a ``reference`` SDA, its bars are drawn alongside and the
    masked NMSE (Eq 5.3) appears in the title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_and_axes(ax, (8.0, 3.0))
    n = len(sda.modules)
    idx = np.arange(n)
    series = [(sda, labels[0], "tab:blue")]
    if reference is not None:
        if reference.modules != sda.modules:
            raise InvalidInputError("reference SDA must have the same modules in the same order")
        series.append((reference, labels[1], "tab:orange"))
    width = 0.8 / len(series)
    masked_named = False
    for j, (s, label, colour) in enumerate(series):
        pos = idx + (j - (len(series) - 1) / 2) * width
        ax.bar(pos[s.mask], s.slopes[s.mask], width, color=colour, label=label)
        ax.bar(pos[~s.mask], np.zeros((~s.mask).sum()) + 0.02, width, color="0.85", hatch="//", edgecolor="0.6",
               label="_masked" if masked_named or not np.any(~s.mask) else "no contact / no slope (masked)")
        masked_named = masked_named or bool(np.any(~s.mask))
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xticks(idx, sda.modules, fontsize=8)
    ax.set_xlabel("whisker module")
    ax.set_ylabel("slope (dy/dx)")
    title = "slope distribution array"
    if reference is not None:
        title += f"  NMSE = {nmse(reference.slopes, sda.slopes, reference.mask, sda.mask):.3g}"
    ax.set_title(title)
    ax.legend(fontsize=8)
    return fig
