"""The Ch.3 tactile image of one whisk cycle, from its module records (Sec 3.1.1, Fig 3.2).

One array whisk cycle - 18 module records (angle, x and y deflection at 2 kHz) and
the end-effector pose of the cycle - becomes one 3 x 6 ``uint8`` image:

1. the contact angle of every module by one of the Ch.3 strategies
   (:mod:`whisker_io.contact.contact_angle`: contact onset, max angle, threshold on
   ``|d deflection/dt|``);
2. forward kinematics (Eq 5.1-5.2) with the tip assumption of Ch.3 (the contact
   is at the whisker tip) gives each contact point;
3. its height above the floor is mapped to grey 1-255, 0 = no contact
   (:func:`whisker_io.features.tactile_image.tactile_image`).

:data:`CH3_IMAGE_PARAMS` maps heights 0-77 mm (the floor to the plane of the array,
Sec 3.2) linearly to 1-255, clipped: the decision recorded for Ch.3, since the
thesis only says the intensity is "proportional to the approximate vertical
height" of the obstacle.

The records may come from the simulator (:mod:`whisker_io.sim.planar_chain`) or from
a recorded session in the thesis' per-whisk CSV format
(:func:`tactile_images_from_recording`); both go through the same function, so a
replayed session gives exactly the images of the live run.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from whisker_io.array.geometry import WhiskerArray
from whisker_io.contact.contact_angle import ContactAngleParams, contact_angles
from whisker_io.errors import InvalidInputError
from whisker_io.features.tactile_image import TactileImageParams, tactile_image_from_angles
from whisker_io.pose import PoseLike
from whisker_io.records.recording import replay
from whisker_io.records.whisk_record import PoseEntry, WhiskRecord

__all__ = ["CH3_IMAGE_PARAMS", "RecordedTactileImages", "tactile_image_from_records", "tactile_images_from_recording"]

CH3_IMAGE_PARAMS = TactileImageParams(height_range_m=(0.0, 0.077))
"""Ch.3 grey scale: contact heights 0-77 mm (floor to the array's plane) -> 1-255."""


def _in_array_order(array: WhiskerArray, records: Sequence[WhiskRecord] | Mapping[str, WhiskRecord]) -> list[WhiskRecord]:
    names = list(array.names)
    if isinstance(records, Mapping):
        missing = [n for n in names if n not in records]
        if missing:
            raise InvalidInputError(f"records lack module(s) {missing}; a tactile image needs one record per module")
        recs = [records[n] for n in names]
    else:
        recs = list(records)
        if len(recs) != len(names):
            raise InvalidInputError(f"need one record per module ({len(names)}), got {len(recs)}")
    for name, rec in zip(names, recs):
        if not isinstance(rec, WhiskRecord):
            raise InvalidInputError(f"records must be WhiskRecord instances, got {type(rec).__name__}")
        if rec.module != name:
            raise InvalidInputError(f"record of module {rec.module!r} where the array has {name!r}; pass records in array order")
    return recs


def tactile_image_from_records(
    array: WhiskerArray,
    records: Sequence[WhiskRecord] | Mapping[str, WhiskRecord],
    pose: PoseLike,
    angle_params: ContactAngleParams | None = None,
    image_params: TactileImageParams = CH3_IMAGE_PARAMS,
) -> NDArray[np.uint8]:
    """Tactile image of one whisk cycle (Sec 3.1.1): contact angles -> FK (tip) -> heights -> grey.

    Parameters
    ----------
    array : WhiskerArray
    records : sequence of WhiskRecord in array order, or mapping module name -> record
        The cycle's module records.
    pose : PoseLike
        End-effector pose ``T_BE`` of the cycle (world frame, z up, floor at z = 0).
    angle_params : ContactAngleParams, optional
        Contact-angle strategy (default ``"onset"``).
    image_params : TactileImageParams
        Height range and vertical axis (default :data:`CH3_IMAGE_PARAMS`).

    Returns
    -------
    ndarray uint8 (3, 6)
        Rows 1-3, columns A-F; 0 = no contact.
    """
    recs = _in_array_order(array, records)
    angles = contact_angles(recs, angle_params)
    return tactile_image_from_angles(array, pose, angles, None, image_params)


@dataclass(frozen=True, eq=False)
class RecordedTactileImages:
    """Tactile images of a recorded session, one per pose-log line.

    Attributes
    ----------
    images : ndarray uint8 (m, 3, 6)
    entries : tuple of PoseEntry
        The pose-log lines (time, pose, whisk-file stem) of the cycles.
    """

    images: NDArray[np.uint8]
    entries: tuple[PoseEntry, ...]


def tactile_images_from_recording(
    directory: str | os.PathLike[str],
    array: WhiskerArray | None = None,
    angle_params: ContactAngleParams | None = None,
    image_params: TactileImageParams = CH3_IMAGE_PARAMS,
) -> RecordedTactileImages:
    """Tactile images of a recorded session (per-whisk CSVs + pose log, Sec 3.1.3).

    Parameters
    ----------
    directory : path-like
        Session directory (see :mod:`whisker_io.records.recording`).
    array : WhiskerArray, optional
        Array geometry (default the thesis array); every cycle must hold its modules.
    angle_params, image_params
        As :func:`tactile_image_from_records`.

    Returns
    -------
    RecordedTactileImages

    Raises
    ------
    CorruptFileError
        A malformed pose log or whisk file, or a cycle lacking a module.
    InvalidInputError
        An empty session.
    """
    arr = WhiskerArray.thesis() if array is None else array
    images: list[NDArray[np.uint8]] = []
    entries: list[PoseEntry] = []
    for cycle in replay(directory, modules=list(arr.names)):
        images.append(tactile_image_from_records(arr, cycle.records, cycle.entry.pose, angle_params, image_params))
        entries.append(cycle.entry)
    if not images:
        raise InvalidInputError(f"{directory}: the pose log lists no whisk cycle")
    return RecordedTactileImages(images=np.stack(images), entries=tuple(entries))
