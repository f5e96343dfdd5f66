"""Whole-array whisk simulator: rigid sweep + beam-model signals + whisking controller (Sec 4.1.2.3, 6.1.3.1).

One call of :meth:`ArraySimulator.whisk` places the array at an end-effector
pose in front of a trimesh object, finds each whisker's first contact with the
rigid-whisker sweep of :mod:`whisker_io.sim.sweep` (Sec 4.1.2.3), turns every contact
into 2 kHz angle / x / y traces with the tapered-cantilever model of
:mod:`whisker_io.sim.signals` under the simulator's controller, and returns the 18
:class:`~whisker_io.records.whisk_record.WhiskRecord` s with the ground truth. The records go
through the same contact pipeline and recording format as real data.

The sweep's face normal (world frame, outward) is expressed in the whisker's
base frame for the signal model (:func:`whisk_contact_from_sweep`), so the x/y
split of the deflection follows the contacted surface's orientation.

Example
-------
>>> import numpy as np
>>> from whisker_io.sim.objects import make_object
>>> from whisker_io.sim.simulator import ArraySimulator
>>> sim = ArraySimulator(seed=0)
>>> pose = np.eye(4); pose[:3, 3] = [0.0, -0.45, 0.2]      # array axis +y toward the box
>>> result = sim.whisk(make_object("box"), pose)
>>> len(result.records), result.records[0].module
(18, 'A1')
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from whisker_io.array.control import OpenLoop, WhiskController, WhiskPattern
from whisker_io.errors import InvalidInputError
from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import rot_z
from whisker_io.pose import Pose, PoseLike, as_pose
from whisker_io.records.recording import RecordingWriter
from whisker_io.records.whisk_record import PoseEntry, WhiskRecord
from whisker_io.sim.signals import ContactTruth, SignalParams, WhiskContact, simulate_whisk_cycle
from whisker_io.sim.sweep import MeshTarget, SweepContact, SweepParams, sweep_array

__all__ = ["ArrayWhisk", "ArraySimulator", "whisk_contact_from_sweep"]

_MIN_RADIAL_M = 1e-4


def whisk_contact_from_sweep(contact: SweepContact) -> WhiskContact:
    """The signal model's view of a sweep contact: angle, radial distance, normal in the base frame.

    ``n_base = Rz(theta_c) F^T n_world`` where ``F = T_BWi Rz(theta_c)`` is the sweep's
    shaft frame at contact (Eq 5.1). The radial distance is clipped to
    ``[0.1 mm, L]`` (a tip contact found by a chord can round to just past L).
    """
    if not isinstance(contact, SweepContact):
        raise InvalidInputError(f"expected a SweepContact, got {type(contact).__name__}")
    R = np.asarray(contact.frame, dtype=np.float64)[:3, :3]
    n_base = rot_z(contact.angle_rad)[:3, :3] @ (R.T @ np.asarray(contact.normal, dtype=np.float64))
    L = float(contact.whisker_length_m)
    a = min(max(float(contact.radial_distance_m), _MIN_RADIAL_M), L)
    return WhiskContact(angle_rad=float(contact.angle_rad), radial_distance_m=a, whisker_length_m=L, normal=n_base)


@dataclass(frozen=True, eq=False)
class ArrayWhisk:
    """The result of one simulated array whisk cycle.

    Attributes
    ----------
    pose : Pose
        End-effector pose T_BE used.
    records : tuple of WhiskRecord
        One per module, array order, cycle index set.
    sweep_contacts : tuple of (SweepContact or None)
        Rigid-sweep contact per module (world frame).
    truths : tuple of (ContactTruth or None)
        Signal-level ground truth per module (``None``: no contact in this
        cycle, e.g. the sweep found none or RCP kept the whisker short of it).
    """

    pose: Pose
    records: tuple[WhiskRecord, ...]
    sweep_contacts: tuple[SweepContact | None, ...]
    truths: tuple[ContactTruth | None, ...]

    def pose_entry(self, time_s: float) -> PoseEntry:
        """The pose-log line of this cycle at ``time_s``."""
        return PoseEntry(time_s, self.pose, f"whisk_{self.records[0].cycle:06d}")

    def write(self, writer: RecordingWriter, time_s: float) -> PoseEntry:
        """Write this cycle (whisk CSVs + pose-log line) with a :class:`RecordingWriter`."""
        entry = self.pose_entry(time_s)
        return writer.write_cycle(self.records, entry.time_s, entry.pose)


class ArraySimulator:
    """Simulates whole-array whisk cycles against trimesh objects; seeded and deterministic.

    Parameters
    ----------
    array : WhiskerArray, optional
        Array geometry (default the thesis' 18 modules, Fig 2.15).
    controller : WhiskController, optional
        Whisking controller (default 1-Hz :class:`~whisker_io.array.control.OpenLoop` over
        the array's whisk range). Stateful controllers (RCP) carry over between cycles.
    signal_params : SignalParams, optional
        Beam / sensor parameters.
    sweep_params : SweepParams, optional
        Rigid-sweep parameters.
    seed : int or numpy Generator, optional
        Seed of the sensor noise; each cycle draws from the simulator's generator,
        so the same seed and calls give the same records.
    """

    def __init__(
        self,
        array: WhiskerArray | None = None,
        controller: WhiskController | None = None,
        signal_params: SignalParams | None = None,
        sweep_params: SweepParams | None = None,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        self.array = WhiskerArray.thesis() if array is None else array
        if not isinstance(self.array, WhiskerArray):
            raise InvalidInputError(f"array must be a WhiskerArray, got {type(self.array).__name__}")
        self.signal_params = SignalParams() if signal_params is None else signal_params
        self.sweep_params = SweepParams() if sweep_params is None else sweep_params
        if controller is None:
            controller = OpenLoop(
                WhiskPattern(
                    retraction_rad=self.array.retraction_rad,
                    protraction_rad=self.array.protraction_rad,
                    sample_rate_hz=self.signal_params.sample_rate_hz,
                )
            )
        if not isinstance(controller, WhiskController):
            raise InvalidInputError(f"controller must implement WhiskController, got {type(controller).__name__}")
        pat = controller.pattern
        if not (
            math.isclose(pat.retraction_rad, self.array.retraction_rad, abs_tol=1e-9)
            and math.isclose(pat.protraction_rad, self.array.protraction_rad, abs_tol=1e-9)
        ):
            raise InvalidInputError(
                "the controller's whisk range must equal the array's "
                f"({self.array.retraction_rad:.6f}, {self.array.protraction_rad:.6f}) rad, "
                f"got ({pat.retraction_rad:.6f}, {pat.protraction_rad:.6f})"
            )
        self.controller = controller
        self.rng = np.random.default_rng(seed)
        self.cycle = 0

    def whisk(
        self,
        target: trimesh.Trimesh | MeshTarget,
        pose: PoseLike,
        cycle: int | None = None,
        rng: np.random.Generator | None = None,
    ) -> ArrayWhisk:
        """Simulate one whisk cycle of the whole array at ``pose`` against ``target``.

        Parameters
        ----------
        target : trimesh.Trimesh or MeshTarget
            Object in the world frame (pass a MeshTarget to reuse its ray intersector).
        pose : PoseLike
            End-effector pose T_BE (a Pose, a 4x4 transform or (position_m, quaternion_xyzw)).
        cycle : int, optional
            Cycle index of the records (default: a counter starting at 0).
        rng : numpy Generator, optional
            Source of this cycle's sensor noise (default: the simulator's own
            generator, seeded at construction).

        Returns
        -------
        ArrayWhisk
        """
        pose = as_pose(pose)
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise InvalidInputError(f"rng must be a numpy Generator, got {type(rng).__name__}")
        if not isinstance(target, MeshTarget):
            if not isinstance(target, trimesh.Trimesh):
                raise InvalidInputError(f"target must be a trimesh.Trimesh or MeshTarget, got {type(target).__name__}")
            target = MeshTarget(target)
        index = self.cycle if cycle is None else int(cycle)
        sweep = sweep_array(self.array, target, pose, self.sweep_params)
        contacts = [None if c is None else whisk_contact_from_sweep(c) for c in sweep]
        records, truths = simulate_whisk_cycle(
            contacts, self.controller, self.signal_params, seed=self.rng if rng is None else rng, modules=self.array.names, cycle=index
        )
        self.cycle = index + 1
        return ArrayWhisk(pose=pose, records=tuple(records), sweep_contacts=tuple(sweep), truths=tuple(truths))
