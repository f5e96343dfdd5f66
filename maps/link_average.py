"""Averaging the odometry of a repeated link (the experience map's ``link_update="average"``).

OpenRatSLAM gives a pair of experiences one link, holding the odometry of the first
traversal; a later traversal between the same two experiences (a re-localisation from
one end to the other) adds nothing. With ``MapConfig(link_update="average")``
:class:`maps.experience_map.ExperienceMap` instead replaces the link's transform by the
running mean over its traversals, so the noise of the dead reckoning along a path
driven ``n`` times shrinks as it would for a mean of ``n`` measurements. The relaxation
of Eq 2.25 is unchanged: it reads the (averaged) link as before.

An SE(2) link is ``(d m, heading rad, facing rad, dt s)`` (:mod:`maps.se2`): the
displacement of the target in the source's frame in polar form, the target's relative
facing and the elapsed time. The mean is taken on

* the displacement in Cartesian form, ``(d cos heading, d sin heading)`` (m), so that
  opposite headings cancel instead of their angles being averaged;
* the relative facing as a circular running mean: the old mean plus ``1 / n`` of the
  signed smallest rotation to the new value (rad), wrapped to (-pi, pi];
* the elapsed time (s), arithmetically.

A traversal in the link's reverse direction (from its target to its source) is inverted
into the link's direction first (:func:`invert_se2_link`).
"""

from __future__ import annotations

import math
from typing import Sequence

from maps.se2 import clip_rad_180, signed_delta_rad
from whisker_io.validation import finite_vector, whole_number

__all__ = ["LINK_UPDATES", "average_se2_link", "invert_se2_link"]

#: Values of ``MapConfig.link_update``: ``"first"`` (OpenRatSLAM: a link keeps its first
#: traversal) and ``"average"`` (running mean over traversals, this module).
LINK_UPDATES: tuple[str, ...] = ("first", "average")


def invert_se2_link(link: Sequence[float]) -> tuple[float, float, float, float]:
    """The same relative transform seen from the other end.

    Parameters
    ----------
    link : sequence of float, length 4
        ``(d m, heading rad, facing rad, dt s)`` from experience A to experience B.

    Returns
    -------
    tuple of float
        ``(d, heading + pi - facing, -facing, dt)`` (angles wrapped to (-pi, pi]): the
        link from B to A. B sees A at distance ``d`` in the world direction
        ``theta_A + heading + pi``, i.e. ``heading + pi - facing`` from B's facing
        ``theta_A + facing``.

    Raises
    ------
    ShapeError, InvalidInputError
        Not 4 finite values.
    """
    d, heading, facing, dt = finite_vector(link, 4, "link").tolist()
    return (d, clip_rad_180(heading + math.pi - facing), clip_rad_180(-facing), dt)


def average_se2_link(mean: Sequence[float], observed: Sequence[float], n_before: int) -> tuple[float, float, float, float]:
    """The running mean of a link after one more traversal.

    Parameters
    ----------
    mean : sequence of float, length 4
        The link's current mean ``(d m, heading rad, facing rad, dt s)`` over
        ``n_before`` traversals.
    observed : sequence of float, length 4
        The new traversal, in the link's direction (see :func:`invert_se2_link`).
    n_before : int
        Traversals in ``mean``, >= 1.

    Returns
    -------
    tuple of float
        ``(d, heading, facing, dt)`` over ``n_before + 1`` traversals (module docstring).

    Raises
    ------
    ShapeError, InvalidInputError
        ``mean`` or ``observed`` not 4 finite values, or ``n_before`` not an integer >= 1.
    """
    w = 1.0 / (whole_number(n_before, "n_before", minimum=1) + 1)
    d0, h0, f0, t0 = finite_vector(mean, 4, "mean link").tolist()
    d1, h1, f1, t1 = finite_vector(observed, 4, "observed link").tolist()
    x0, y0 = d0 * math.cos(h0), d0 * math.sin(h0)
    x = x0 + (d1 * math.cos(h1) - x0) * w
    y = y0 + (d1 * math.sin(h1) - y0) * w
    facing = clip_rad_180(f0 + signed_delta_rad(f0, f1) * w)
    return (math.hypot(x, y), math.atan2(y, x), facing, t0 + (t1 - t0) * w)
