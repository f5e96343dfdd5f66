"""Object recognition by leaky integration of re-localisations (thesis Sec 5.2.2.2, 6.1.2.4; Fig 5.16, 6.4).

Object maps of several objects are appended into one experience history with no links
between objects (Fig 5.16); while an unknown object is explored, every re-localisation to
an experience of object ``k`` is an impulse into ``k``'s leaky integrator, the *raw
confidence* ``c_k``. Per iteration (one whisk; the time base is a parameter):

    c_k[t] = decay * c_k[t - 1] + impulse * [re-localised to object k at t]

and the *integrated confidence* is ``IC_k[t] = sum_{s <= t} c_k[s] * dt``. Two decisions:

* RC (Ch.5): the identity is the first object whose raw confidence reaches a threshold;
* IC (Ch.6): the first object whose integrated confidence reaches a threshold (300 in
  the thesis), which ignores a single spike of false re-localisations.

Ch.6's metrics (Sec 6.2): the *Identity Margin* ``IM = t(incorrect IC >= thr) -
t(correct IC >= thr)`` (the earliest incorrect identity; higher is better) and the
*Successful Recognition Time* ``SRT = t(correct IC >= thr)``. Decision for a run that
ends first (the thesis is silent): a crossing that never happens is censored at the end
of the run, ``t = n * dt`` (so IM is a lower bound when no incorrect identity crossed),
and the result says so.

The thesis does not print the impulse or the decay; the defaults (impulse 1, decay 0.75
per whisk) make the raw confidence of a steadily re-localising object settle at
``impulse / (1 - decay) = 4``, the 3-4 of Fig 6.4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from whisker_io.errors import ConfigError, InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, validate_fields

__all__ = [
    "MATCHERS",
    "LeakyIntegrator",
    "RecognitionResult",
    "relocalisation_targets",
    "confidence",
    "leaky_step",
    "confidence_from_impulses",
    "integrated_confidence",
    "first_crossing",
    "decide",
    "recognise",
]

#: Where the impulses come from: ``thesis``, a re-localisation to an object's map (Eq 5.5's
#: region match, this module's docstring); ``surface``, :class:`maps.surface_match.SurfaceMatcher`
#: on the objects' stored surfaces (issue 22: identification from a path the map never took).
MATCHERS = ("thesis", "surface")


@dataclass(frozen=True)
class LeakyIntegrator(ConfigDataclass):
    """Parameters of the per-object confidence.

    Parameters
    ----------
    impulse : float
        Added to ``c_k`` by one re-localisation to object ``k`` (> 0).
    decay : float
        Multiplies ``c_k`` every iteration, in [0, 1).
    dt : float
        Time of one iteration in the integral (1 = one whisk).
    """

    impulse: float = checked(1.0, float)
    decay: float = checked(0.75, float)
    dt: float = checked(1.0, float)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not self.impulse > 0 or not 0.0 <= self.decay < 1.0 or not self.dt > 0:
            raise ConfigError(f"need impulse > 0, 0 <= decay < 1 and dt > 0; got {self.impulse}, {self.decay}, {self.dt}")


def relocalisation_targets(exp_ids: np.ndarray, relocalised: np.ndarray, exp_object: np.ndarray) -> np.ndarray:
    """Object index re-localised to at each iteration, -1 where there was none.

    Parameters
    ----------
    exp_ids : (n,) int
        Current experience per iteration.
    relocalised : (n,) bool
        The iteration re-localised (to ``exp_ids[t]``).
    exp_object : (n_exp,) int
        The object each experience of the appended maps belongs to (-1: the unknown
        object's own new experiences).
    """
    e, r, eo = np.asarray(exp_ids), np.asarray(relocalised), np.asarray(exp_object)
    if e.ndim != 1 or r.shape != e.shape or eo.ndim != 1:
        raise ShapeError(f"exp_ids and relocalised must be (n,) and exp_object (n_exp,), got {e.shape}, {r.shape}, {eo.shape}")
    if e.dtype.kind not in "iu" or eo.dtype.kind not in "iu":
        raise InvalidInputError("exp_ids and exp_object must be integers")
    if len(e) and e.min() < -1:
        raise InvalidInputError(f"exp_ids must be experience ids >= 0 (or -1: none), got {int(e.min())}")
    if len(eo) and eo.min() < -1:
        raise InvalidInputError(f"exp_object must hold object indices >= 0 (or -1: the explored object's own), got {int(eo.min())}")
    hit = r.astype(bool) & (e >= 0)
    if hit.any() and e[hit].max() >= len(eo):
        raise InvalidInputError(f"exp_ids refer to experience {int(e[hit].max())}, exp_object covers {len(eo)}: "
                                "extend it with ObjectLibrary.with_explored(n_experiences) for the experiences the "
                                "exploration made")
    out = np.full(e.shape, -1, dtype=np.int64)
    out[hit] = eo[e[hit]]
    return out


def confidence(targets: np.ndarray, n_objects: int, params: LeakyIntegrator = LeakyIntegrator()) -> np.ndarray:
    """Raw confidence ``c`` (n, n_objects) from the per-iteration targets (-1 = no impulse)."""
    t = np.asarray(targets)
    if t.ndim != 1 or t.dtype.kind not in "iu":
        raise ShapeError(f"targets must be a 1-D integer array, got {t.shape} {t.dtype}")
    if isinstance(n_objects, bool) or not isinstance(n_objects, (int, np.integer)) or n_objects < 1:
        raise InvalidInputError(f"n_objects must be an integer >= 1, got {n_objects!r}")
    if len(t) and (t.max() >= n_objects or t.min() < -1):
        raise InvalidInputError(f"targets must lie in [-1, {n_objects}), got [{t.min()}, {t.max()}]")
    c = np.zeros((len(t), n_objects))
    level = np.zeros(n_objects)
    for i, k in enumerate(t.tolist()):
        level = level * params.decay
        if k >= 0:
            level[k] += params.impulse
        c[i] = level
    return c


def _check_level(level: np.ndarray, impulses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lv = np.asarray(level, dtype=np.float64)
    imp = np.asarray(impulses)
    if lv.ndim != 1 or imp.shape != lv.shape:
        raise ShapeError(f"level and impulses must both be (n_objects,), got {lv.shape}, {imp.shape}")
    if imp.dtype.kind not in "biu":
        raise InvalidInputError(f"impulses must be booleans or counts, got dtype {imp.dtype}")
    if imp.size and imp.dtype.kind == "i" and imp.min() < 0:
        raise InvalidInputError("impulse counts must be >= 0")
    if not np.isfinite(lv).all() or (lv.size and lv.min() < 0):
        raise InvalidInputError("level must be finite and >= 0 (a raw confidence)")
    return lv, imp.astype(np.float64)


def leaky_step(level: np.ndarray, impulses: np.ndarray, params: LeakyIntegrator = LeakyIntegrator()) -> np.ndarray:
    """One iteration of every object's integrator: ``c[t] = decay c[t-1] + impulse n_k[t]``.

    Several objects may receive an impulse in the same iteration (one model per object
    map, each re-localising on its own).

    Parameters
    ----------
    level : (n_objects,) float
        Raw confidence ``c[t-1]`` (>= 0).
    impulses : (n_objects,) bool or int
        Re-localisations ``n_k[t]`` to each object this iteration.

    Returns
    -------
    (n_objects,) float
        ``c[t]`` (a new array; ``level`` is not changed).
    """
    lv, imp = _check_level(level, impulses)
    return lv * params.decay + params.impulse * imp


def confidence_from_impulses(impulses: np.ndarray, params: LeakyIntegrator = LeakyIntegrator()) -> np.ndarray:
    """Raw confidence (n, n_objects) from per-iteration impulses (n, n_objects), bool or counts.

    :func:`leaky_step` over the rows from a zero level; with at most one impulse per row
    it equals :func:`confidence` of the corresponding targets.
    """
    a = np.asarray(impulses)
    if a.ndim != 2 or a.shape[1] < 1:
        raise ShapeError(f"impulses must be (n, n_objects) with n_objects >= 1, got {a.shape}")
    c = np.zeros(a.shape)
    level = np.zeros(a.shape[1])
    for i in range(len(a)):
        level = leaky_step(level, a[i], params)
        c[i] = level
    return c


def integrated_confidence(c: np.ndarray, params: LeakyIntegrator = LeakyIntegrator()) -> np.ndarray:
    """``IC[t] = sum_{s <= t} c[s] dt``, same shape as ``c`` (raw confidences: finite and >= 0)."""
    try:
        arr = np.asarray(c, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError("confidence must be an array of numbers") from None
    if arr.ndim == 0:
        raise ShapeError("confidence must be (n,) or (n, n_objects), got a scalar")
    if not np.isfinite(arr).all() or (arr.size and arr.min() < 0):
        raise InvalidInputError("confidence must be finite and >= 0 (raw confidences of the leaky integrators)")
    return np.cumsum(arr, axis=0) * params.dt


def _checked_trace(trace: np.ndarray, threshold: float, ndim: int) -> np.ndarray:
    try:
        tr = np.asarray(trace, dtype=np.float64)
        thr = float(threshold)
    except (TypeError, ValueError):
        raise InvalidInputError("trace must be an array of numbers and threshold a number") from None
    shape = "(n,)" if ndim == 1 else "(n, n_objects)"
    if tr.ndim != ndim:
        raise ShapeError(f"trace must be {shape}, got shape {tr.shape}")
    if np.isnan(tr).any() or np.isnan(thr):
        raise InvalidInputError("trace and threshold must not be NaN")
    return tr


def first_crossing(trace: np.ndarray, threshold: float) -> int | None:
    """First index at which a 1-D trace reaches ``threshold`` (None if never)."""
    hits = np.flatnonzero(_checked_trace(trace, threshold, 1) >= threshold)
    return int(hits[0]) if hits.size else None


def decide(trace: np.ndarray, threshold: float) -> int | None:
    """The object whose trace (n, n_objects) reaches ``threshold`` first (ties: the larger value, then the lower index)."""
    tr = _checked_trace(trace, threshold, 2)
    times = [first_crossing(tr[:, k], threshold) for k in range(tr.shape[1])]
    hit = [(t, -tr[t, k], k) for k, t in enumerate(times) if t is not None]
    return min(hit)[2] if hit else None


@dataclass(frozen=True)
class RecognitionResult:
    """Recognition of one run against one correct identity.

    Attributes
    ----------
    rc_identity, ic_identity : int or None
        Decisions by raw and integrated confidence.
    srt : float
        Successful Recognition Time (iterations x dt); censored at the run's end when
        the correct IC never reached the threshold (``correct_crossed`` False).
    im : float
        Identity Margin; censored likewise (``incorrect_crossed`` False: a lower bound).
    correct_first : bool
        The correct identity's IC reached the threshold before every other identity.
    max_confidence : ndarray (n_objects,)
        Peak raw confidence per object.
    final_ic : ndarray (n_objects,)
    """

    rc_identity: int | None
    ic_identity: int | None
    srt: float
    im: float
    correct_crossed: bool
    incorrect_crossed: bool
    correct_first: bool
    max_confidence: np.ndarray
    final_ic: np.ndarray


def recognise(
    targets: np.ndarray,
    n_objects: int,
    correct: int,
    *,
    rc_threshold: float = 3.0,
    ic_threshold: float = 300.0,
    params: LeakyIntegrator = LeakyIntegrator(),
) -> RecognitionResult:
    """RC and IC decisions, IM and SRT of one run (see the module docstring).

    Parameters
    ----------
    targets : (n,) int
        :func:`relocalisation_targets` of the run.
    n_objects : int
    correct : int
        Index of the presented object.
    rc_threshold, ic_threshold : float
        Thresholds of the two decisions (thesis: RC 3, Fig 6.4; IC 300, Sec 6.2).
    """
    if isinstance(correct, bool) or not isinstance(correct, (int, np.integer)) or not 0 <= correct < n_objects:
        raise InvalidInputError(f"correct must be an object index in [0, {n_objects}), got {correct!r}")
    for name, thr in (("rc_threshold", rc_threshold), ("ic_threshold", ic_threshold)):
        if not (math.isfinite(thr) and thr > 0):
            raise InvalidInputError(f"{name} must be finite and > 0, got {thr!r}")
    c = confidence(targets, n_objects, params)
    ic = integrated_confidence(c, params)
    n = len(c)
    end = n * params.dt
    t_ok = first_crossing(ic[:, correct], ic_threshold) if n else None
    others = [first_crossing(ic[:, k], ic_threshold) for k in range(n_objects) if k != correct] if n else []
    others = [t for t in others if t is not None]
    t_bad = min(others) if others else None
    srt = end if t_ok is None else t_ok * params.dt
    bad = end if t_bad is None else t_bad * params.dt
    return RecognitionResult(
        rc_identity=decide(c, rc_threshold) if n else None,
        ic_identity=decide(ic, ic_threshold) if n else None,
        srt=float(srt),
        im=float(bad - srt),
        correct_crossed=t_ok is not None,
        incorrect_crossed=t_bad is not None,
        correct_first=t_ok is not None and (t_bad is None or t_ok < t_bad),
        max_confidence=c.max(axis=0) if n else np.zeros(n_objects),
        final_ic=ic[-1] if n else np.zeros(n_objects),
    )
