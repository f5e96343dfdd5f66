"""The Ch.3 sensing chain: the array whisks over the maze along a planar path -> tactile images.

Sec 3.2 of the thesis constrains the array "to a plane set 77 mm above the maze"
and lets it "only rotate about its major axis", a yaw, so that RatSLAM's planar
model holds. :class:`PlanarChain` reproduces that set-up in simulation, one whisk
cycle per path pose:

1. :meth:`PlanarChain.pose` - the end-effector pose of a planar pose
   ``(x m, y m, yaw rad)`` (the mount, below);
2. :class:`whisker_io.sim.simulator.ArraySimulator` - the rigid sweep of every
   whisker against the maze mesh (Sec 4.1.2.3), the tapered-cantilever deflection
   signals (Eq 2.33-2.38) and the whisking controller: open loop or RCP (Sec 3.2.2);
3. :func:`whisker_io.features.whisk_tactile_image.tactile_image_from_records` -
   contact detection and the contact angle by one of the three strategies of
   Sec 3.3.4 (:mod:`whisker_io.contact.contact_angle`), forward kinematics
   (Eq 5.1-5.2, tip assumption) and the 3 x 6 tactile image (Sec 3.1.1).

The chain returns whisk records and tactile images; feeding them to RatSLAM is the
caller's business (``examples/ch3_maze.py``).

Mount (decision; the thesis shows a photograph, Fig 3.1): the array's major axis
(+y of the end-effector frame) points straight down at the floor, so a rotation
about it is the planar yaw; its +x axis (columns A and B) points along the yaw
heading, +z to the left. ``height_m`` (77 mm) is the height above the floor of
the array's rostral face, the row-1 whisk pivots; the other rows sit 20 and 40 mm
higher. At full protraction the whiskers point 50 deg below the horizontal (the
160 mm row-3 tips just reach the floor plane, which the maze mesh leaves out); at
full retraction 50 deg above it, so walls taller than the array are touched on
their sides. The path's ``(x, y)`` is the point where the major axis meets the
floor plane.

Timing (Sec 3.1.2; decision on the pairing): odometry and tactile images are
published at 1.5 Hz, the whiskers whisk at 1 Hz. :class:`WhiskSchedule` pairs them:
whisk cycle ``j`` runs over ``[j, j + 1) / f_whisk`` and is simulated at the path
pose of its middle, interpolated between iterations; iteration ``k`` (at
``k / f_odometry``) carries the image of the latest cycle completed by then, so
with 1.5 Hz and 1 Hz the cycles appear once, twice, once, twice... (the images
interleave) and the first iterations, before any cycle is complete, carry none.

Example
-------
>>> import numpy as np
>>> from whisker_io.sim.objects import make_maze
>>> from whisker_io.sim.planar_chain import PlanarChain
>>> chain = PlanarChain(make_maze(), control="rcp", seed=0)
>>> whisks = chain.whisk_path(np.array([[0.835, 0.125, 0.0], [0.85, 0.125, 0.0]]))
>>> chain.tactile_images(whisks).shape
(2, 3, 6)
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from whisker_io.array.control import RCP, OpenLoop, WhiskController, WhiskPattern
from whisker_io.array.geometry import WhiskerArray
from whisker_io.contact.contact_angle import ContactAngleParams
from whisker_io.errors import InvalidInputError
from whisker_io.features.tactile_image import TactileImageParams
from whisker_io.features.whisk_tactile_image import CH3_IMAGE_PARAMS, tactile_image_from_records
from whisker_io.pose import Pose
from whisker_io.sim.signals import SignalParams, free_whisking_threshold_counts
from whisker_io.sim.simulator import ArraySimulator, ArrayWhisk
from whisker_io.sim.sweep import MeshTarget, SweepParams
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_scalar, validate_fields

__all__ = ["PLANE_HEIGHT_M", "MAX_COORDINATE_M", "Control", "PlanarChain", "WhiskSchedule"]

PLANE_HEIGHT_M: float = 0.077
"""Height of the array's rostral face above the floor, metres (Sec 3.2: 77 mm)."""

MAX_COORDINATE_M: float = 1.0e3
"""Largest accepted ``|x|`` and ``|y|`` of a path pose, metres (a maze is metres across)."""

Control = Literal["open_loop", "rcp"]

# the mount: columns are the world images of the end-effector x, y, z axes at yaw 0
_MOUNT = Rotation.from_matrix(np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]))


def _planar_path(path: ArrayLike, name: str = "path") -> NDArray[np.float64]:
    arr = finite_array(path, (None, 3), name)
    if arr.shape[0] == 0:
        raise InvalidInputError(f"{name} is empty; give at least one (x m, y m, yaw rad) row")
    if np.any(np.abs(arr[:, :2]) > MAX_COORDINATE_M):
        raise InvalidInputError(f"{name} has |x| or |y| above {MAX_COORDINATE_M:g} m; give positions in metres in the maze frame")
    return arr


@dataclass(frozen=True)
class WhiskSchedule(ConfigDataclass):
    """Pairing of odometry iterations with whisk cycles (see the module docstring).

    Parameters
    ----------
    odometry_rate_hz : float
        Rate of odometry and tactile images, Hz (Sec 3.1.2: 1.5).
    whisk_rate_hz : float
        Whisking rate, Hz (Sec 3.2: 1).
    """

    odometry_rate_hz: float = checked(1.5, float, above=0, maximum=1e3, error=InvalidInputError, reader=finite_scalar,
                                      message="{name} must be in (0, 1000] Hz, got {value!r}")
    whisk_rate_hz: float = checked(1.0, float, above=0, maximum=1e3, error=InvalidInputError, reader=finite_scalar,
                                   message="{name} must be in (0, 1000] Hz, got {value!r}")

    def __post_init__(self) -> None:
        validate_fields(self)

    @property
    def iteration_s(self) -> float:
        """Duration of one odometry iteration, s."""
        return 1.0 / self.odometry_rate_hz

    def image_index(self, n_iterations: int) -> NDArray[np.int64]:
        """Whisk cycle shown at each iteration: ``floor(k f_whisk / f_odometry) - 1`` (-1 = none yet).

        Parameters
        ----------
        n_iterations : int
            Number of odometry iterations, 1 to 10 million.

        Returns
        -------
        ndarray (n_iterations,) int64
        """
        if isinstance(n_iterations, bool) or not isinstance(n_iterations, (int, np.integer)) or not 1 <= n_iterations <= 10**7:
            raise InvalidInputError(f"n_iterations must be an integer in [1, 1e7], got {n_iterations!r}")
        k = np.arange(int(n_iterations), dtype=np.float64)
        return (np.floor(k * self.whisk_rate_hz / self.odometry_rate_hz + 1e-9) - 1).astype(np.int64)

    def whisk_poses(self, path: ArrayLike) -> NDArray[np.float64]:
        """Planar pose at the middle of every whisk cycle completed along a path.

        Parameters
        ----------
        path : array (n, 3)
            Pose (x m, y m, yaw rad) at each iteration ``k`` (time ``k / f_odometry``).

        Returns
        -------
        ndarray (m, 3)
            One row per cycle ``j = 0 .. m-1`` shown by :meth:`image_index`; x and y
            interpolated linearly, yaw along the shorter arc.
        """
        p = _planar_path(path)
        m = int(self.image_index(p.shape[0])[-1]) + 1
        if m <= 0:
            return np.zeros((0, 3))
        u = (np.arange(m) + 0.5) * self.odometry_rate_hz / self.whisk_rate_hz  # fractional iteration
        k = np.arange(p.shape[0], dtype=np.float64)
        yaw = np.unwrap(p[:, 2])
        out = np.column_stack([np.interp(u, k, p[:, 0]), np.interp(u, k, p[:, 1]), np.interp(u, k, yaw)])
        out[:, 2] = (out[:, 2] + math.pi) % (2 * math.pi) - math.pi
        return out


class PlanarChain:
    """Simulated Ch.3 whisking over a mesh along a planar path; seeded and deterministic.

    Parameters
    ----------
    target : trimesh.Trimesh or MeshTarget
        The maze (world frame, metres, floor at z = 0), e.g.
        :func:`whisker_io.sim.objects.make_maze`.
    control : {"open_loop", "rcp"} or WhiskController
        Whisking control (Sec 3.2.2): 1-Hz open loop over the full range, or RCP with
        its contact threshold calibrated as 20 x the noise std of one free-whisking
        cycle of the simulator (:func:`whisker_io.array.control.contact_threshold_from_noise`).
        A controller instance is used as given (it keeps its state between cycles).
    height_m : float
        Height of the array's rostral face above the floor, metres (default 0.077).
    array : WhiskerArray, optional
        Array geometry (default the thesis array).
    signal_params : SignalParams, optional
    sweep_params : SweepParams, optional
    seed : int, optional
        Seed of the sensor noise (calibration and every cycle).

    Attributes
    ----------
    contact_threshold_counts : float
        The calibrated 20-sigma contact threshold, counts.
    simulator : ArraySimulator
    """

    def __init__(
        self,
        target: trimesh.Trimesh | MeshTarget,
        control: Control | WhiskController = "open_loop",
        *,
        height_m: float = PLANE_HEIGHT_M,
        array: WhiskerArray | None = None,
        signal_params: SignalParams | None = None,
        sweep_params: SweepParams | None = None,
        seed: int | None = None,
    ) -> None:
        if isinstance(target, trimesh.Trimesh):
            target = MeshTarget(target)
        if not isinstance(target, MeshTarget):
            raise InvalidInputError(f"target must be a trimesh.Trimesh or MeshTarget, got {type(target).__name__}")
        h = finite_scalar(height_m, "height_m")
        if not 0.0 < h <= 10.0:
            raise InvalidInputError(f"height_m must be in (0, 10] m, got {height_m!r}")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise InvalidInputError(f"seed must be a non-negative integer or None, got {seed!r}")
        arr = WhiskerArray.thesis() if array is None else array
        if not isinstance(arr, WhiskerArray):
            raise InvalidInputError(f"array must be a WhiskerArray, got {type(arr).__name__}")
        sp = SignalParams() if signal_params is None else signal_params
        rng = np.random.default_rng(seed)
        pattern = WhiskPattern(retraction_rad=arr.retraction_rad, protraction_rad=arr.protraction_rad, sample_rate_hz=sp.sample_rate_hz)
        self.contact_threshold_counts = free_whisking_threshold_counts(pattern, sp, arr.names, rng)
        controller: WhiskController
        if isinstance(control, str):
            if control == "open_loop":
                controller = OpenLoop(pattern)
            elif control == "rcp":
                controller = RCP(pattern, threshold_counts=self.contact_threshold_counts)
            else:
                raise InvalidInputError(f"control must be 'open_loop', 'rcp' or a WhiskController, got {control!r}")
        elif isinstance(control, WhiskController):
            controller = control
        else:
            raise InvalidInputError(f"control must be 'open_loop', 'rcp' or a WhiskController, got {type(control).__name__}")
        self.target = target
        self.array = arr
        self.height_m = h
        self._axis_height_m = h + float(np.max(arr.positions_m[:, 1]))
        self.simulator = ArraySimulator(arr, controller, sp, sweep_params, seed=rng)

    def pose(self, x_m: float, y_m: float, yaw_rad: float) -> Pose:
        """End-effector pose ``T_BE`` of the planar pose (x m, y m, yaw rad) (see the mount above)."""
        row = _planar_path([[x_m, y_m, yaw_rad]], "planar pose")[0]
        rot = Rotation.from_euler("z", float(row[2])) * _MOUNT
        return Pose.from_rotation([row[0], row[1], self._axis_height_m], rot)

    def whisk(self, x_m: float, y_m: float, yaw_rad: float) -> ArrayWhisk:
        """One whisk cycle of the whole array at a planar pose (records, sweep contacts, pose)."""
        return self.simulator.whisk(self.target, self.pose(x_m, y_m, yaw_rad))

    def whisk_path(self, path: ArrayLike, *, progress: bool = False) -> list[ArrayWhisk]:
        """One whisk cycle at every row of ``path`` (m, 3) = (x m, y m, yaw rad), in order.

        The path is validated before any cycle runs; RCP carries over from cycle to cycle.
        """
        p = _planar_path(path)
        rows: Iterable[NDArray[np.float64]] = p
        if progress:
            from tqdm import tqdm

            rows = tqdm(p, desc="whisks", unit="whisk", leave=False)
        return [self.whisk(float(x), float(y), float(yaw)) for x, y, yaw in rows]

    def tactile_images(
        self,
        whisks: Sequence[ArrayWhisk],
        angle_params: ContactAngleParams | None = None,
        image_params: TactileImageParams = CH3_IMAGE_PARAMS,
    ) -> NDArray[np.uint8]:
        """The tactile image of every whisk cycle, shape (m, 3, 6) ``uint8``.

        Parameters
        ----------
        whisks : sequence of ArrayWhisk
            From :meth:`whisk` / :meth:`whisk_path`.
        angle_params : ContactAngleParams, optional
            Contact-angle strategy (default ``"onset"``).
        image_params : TactileImageParams
            Height range (default 0-77 mm, :data:`~whisker_io.features.whisk_tactile_image.CH3_IMAGE_PARAMS`).
        """
        if not all(isinstance(w, ArrayWhisk) for w in whisks):
            raise InvalidInputError("whisks must be ArrayWhisk objects from PlanarChain.whisk")
        if not whisks:
            return np.zeros((0, 3, 6), dtype=np.uint8)
        return np.stack([tactile_image_from_records(self.array, w.records, w.pose, angle_params, image_params) for w in whisks])
