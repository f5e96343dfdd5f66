"""The whisk angle at contact by the three strategies of Ch.3 (Sec 3.1.1, Sec 3.3.4).

The tactile image of Ch.3 turns each whisker's angle at contact into a height by
forward kinematics; the thesis compares ways of estimating that angle from one
whisk cycle. :class:`ContactAngleParams` selects one, :func:`contact_angle` applies
it to a record and :func:`contact_angles` to the modules of one array cycle:

* ``"onset"`` - the angle at the contact onset of the detection pipeline of
  Sec 5.1.1.1.1 (:func:`whisker_io.contact.detection.detect_contact`: moving
  average, the most prominent peak, back-tracking to the onset). No contact
  when the pipeline confirms none.
* ``"max_angle"`` - "the maximum whisker angle observed throughout the cycle"
  (Sec 3.1.1). The thesis notes that it registers fewer walls because "the whisker
  must remain in contact with the wall for the duration of the whisk cycle".
  Decision: a contact is registered when, at the sample of the largest angle,
  the smoothed y-deflection differs from the free-whisking baseline (mean of the
  last ``baseline_samples`` raw samples, as in the detection pipeline) by more
  than ``contact_threshold_counts`` - the 20-sigma contact threshold of
  Sec 3.2.2 (80 counts with the simulator's 4-count noise).
* ``"threshold"`` - the thesis' "contact angle": the angle "when the magnitude
  of the first derivative of the whisker deflection crosses a threshold"
  (:func:`whisker_io.contact.detection.threshold_contact_angle`).

Angles are radians (-50 deg full retraction, +50 deg full protraction); NaN marks
"no contact" in :func:`contact_angles`, which is what
:func:`whisker_io.features.tactile_image.tactile_image_from_angles` takes.

Example
-------
>>> from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle
>>> from whisker_io.contact.contact_angle import ContactAngleParams, contact_angles
>>> recs, _ = simulate_whisk_cycle([WhiskContact(0.2, 0.05, 0.1), None], seed=0)
>>> angles = contact_angles(recs, ContactAngleParams("max_angle"))
>>> round(float(angles[0]), 2), bool(angles[1] != angles[1])   # 50 deg; NaN = no contact
(0.87, True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from whisker_io.contact.detection import (
    DetectionParams,
    detect_contact,
    detect_contacts,
    moving_average,
    threshold_contact_angle,
)
from whisker_io.errors import InvalidInputError
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, validate_fields, whole_number

__all__ = ["CH3_DETECTION", "CONTACT_ANGLE_METHODS", "ContactAngleMethod", "ContactAngleParams", "contact_angle", "contact_angles"]

ContactAngleMethod = Literal["onset", "max_angle", "threshold"]

CONTACT_ANGLE_METHODS: tuple[str, ...] = ("onset", "max_angle", "threshold")
"""The accepted :attr:`ContactAngleParams.method` names."""

CH3_DETECTION = DetectionParams(min_prominence_counts=80.0, confirm_threshold_counts=80.0)
"""Detection pipeline of the ``"onset"`` strategy for the Ch.3 maze (:meth:`ContactAngleParams.ch3`).

The pipeline's defaults (Sec 5.1.1.1.1: 500 counts of prominence and confirmation) were
set for the Ch.5 objects; the low maze walls bend the whiskers by 150-400 counts, so with
them the onset strategy missed about three contacts in four (measured on the Ch.3 route:
274 of the 1015 contacts the 80-count pipeline finds open loop, 114 of 916 with RCP) and
left 46 % / 75 % of the images blank. Ch.3 uses Sec 3.2.2's contact threshold, 20 sigma
of the sensor noise = 80 counts, for both.
"""


@dataclass(frozen=True)
class ContactAngleParams(ConfigDataclass):
    """How the contact angle of a whisk cycle is estimated (see the module docstring).

    Parameters
    ----------
    method : {"onset", "max_angle", "threshold"}
        The strategy.
    detection : DetectionParams
        Detection pipeline of the ``"onset"`` method (thesis defaults).
    threshold_counts_per_s : float
        ``"threshold"``: level of ``|d y-deflection / dt|``, counts/s (default 2500,
        about 20 sigma of the smoothed derivative of the simulator's noise).
    contact_threshold_counts : float
        ``"max_angle"``: smallest ``|y - baseline|`` at the largest angle that counts as
        a contact, counts (default 80 = 20 x the simulator's noise std, Sec 3.2.2).
    smoothing_span : int
        Moving-average span of the ``"threshold"`` and ``"max_angle"`` methods, samples
        (default 100, as the detection pipeline).
    baseline_samples : int
        ``"max_angle"``: trailing raw samples forming the free-whisking baseline (100).
    """

    method: ContactAngleMethod = checked("onset", str, choices=CONTACT_ANGLE_METHODS, error=InvalidInputError,
                                         message=f"unknown contact-angle method {{value!r}}; choose one of "
                                                 f"{list(CONTACT_ANGLE_METHODS)}")
    detection: DetectionParams = field(default_factory=DetectionParams)
    threshold_counts_per_s: float = checked(2500.0, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                            message="{name} must be > 0, got {value!r}")
    contact_threshold_counts: float = checked(80.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                              message="{name} must be >= 0, got {value!r}")
    smoothing_span: int = checked(100, int, minimum=1, error=InvalidInputError, reader=whole_number)
    baseline_samples: int = checked(100, int, minimum=1, error=InvalidInputError, reader=whole_number)

    @classmethod
    def ch3(cls, method: ContactAngleMethod) -> "ContactAngleParams":
        """The strategy ``method`` as the Ch.3 maze study uses it: ``"onset"`` with :data:`CH3_DETECTION`."""
        return cls(method, detection=CH3_DETECTION)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.detection, DetectionParams):
            raise InvalidInputError(f"detection must be a DetectionParams, got {type(self.detection).__name__}")


def _check(record: object) -> WhiskRecord:
    if not isinstance(record, WhiskRecord):
        raise InvalidInputError(f"expected a WhiskRecord, got {type(record).__name__}")
    return record


def _max_angle_contact(record: WhiskRecord, params: ContactAngleParams) -> float | None:
    y_s = moving_average(record.y_counts, params.smoothing_span)
    baseline = float(np.mean(record.y_counts[-params.baseline_samples :]))
    k = int(np.argmax(record.angle_rad))
    if abs(float(y_s[k]) - baseline) > params.contact_threshold_counts:
        return float(record.angle_rad[k])
    return None


def contact_angle(record: WhiskRecord, params: ContactAngleParams | None = None) -> float | None:
    """The whisk angle at contact of one cycle, radians, or None without a contact.

    Parameters
    ----------
    record : WhiskRecord
        One module's whisk cycle.
    params : ContactAngleParams, optional
        Method and its parameters (default ``"onset"``).

    Returns
    -------
    float or None
    """
    p = ContactAngleParams() if params is None else params
    rec = _check(record)
    if p.method == "onset":
        found = detect_contact(rec, p.detection)
        return None if found is None else found.contact_angle_rad
    if p.method == "max_angle":
        return _max_angle_contact(rec, p)
    return threshold_contact_angle(rec, p.threshold_counts_per_s, p.smoothing_span)


def contact_angles(records: Sequence[WhiskRecord], params: ContactAngleParams | None = None) -> NDArray[np.float64]:
    """:func:`contact_angle` for the modules of one array cycle.

    Parameters
    ----------
    records : sequence of WhiskRecord, length N
        One record per module, in the array's module order.
    params : ContactAngleParams, optional

    Returns
    -------
    ndarray (N,)
        Contact angle per module, radians; NaN where there is no contact.
    """
    p = ContactAngleParams() if params is None else params
    recs = [_check(r) for r in records]
    if not recs:
        raise InvalidInputError("contact_angles needs at least one WhiskRecord")
    out = np.full(len(recs), math.nan)
    if p.method == "onset":
        for i, found in enumerate(detect_contacts(recs, p.detection)):
            if found is not None:
                out[i] = found.contact_angle_rad
        return out
    for i, rec in enumerate(recs):
        angle = _max_angle_contact(rec, p) if p.method == "max_angle" else threshold_contact_angle(rec, p.threshold_counts_per_s, p.smoothing_span)
        if angle is not None:
            out[i] = angle
    return out
