"""Crash-safe recording of live sessions, and replay through the same pipeline.

:class:`Recorder` writes each whisk cycle as it arrives, with the session
format of :mod:`whisker_io.records.recording` (per-module whisk CSVs written to a
temporary name, fsynced and renamed; then the fsynced pose-log line). After a
crash or an unplugged cable every completed whisk is on disk, complete, and
readable by :func:`whisker_io.records.recording.replay`; a whisk in progress leaves
nothing behind.

A *pipeline* is any callable taking a
:class:`~whisker_io.records.recording.ReplayedCycle` (pose-log entry + module
records). The recorder hands every live cycle to it right after the cycle is
on disk, and :func:`replay_session` hands every recorded cycle to it in the
same form, so live and replayed data take the same path.

:func:`explore` is the acquisition loop shared by the simulated and the
hardware examples: move, whisk, record, guard.
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path
from types import MappingProxyType
from typing import Any, Callable, Iterable, Optional, Sequence

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.hw.arm import Arm, ArmState
from whisker_io.pose import Pose, PoseLike, as_pose
from whisker_io.hw.usb_array import FRAME_RETRIES, Array, retake_count
from whisker_io.records.recording import (
    POSE_LOG_NAME,
    RecordingWriter,
    ReplayedCycle,
    read_pose_log,
    repair_last_line,
    replay,
    whisk_file_stem,
)
from whisker_io.records.whisk_record import WhiskRecord

__all__ = ["Pipeline", "Recorder", "explore", "replay_session", "raster_poses"]

_LOG = logging.getLogger(__name__)


Pipeline = Callable[[ReplayedCycle], Any]
"""Consumer of whisk cycles, live or replayed."""


class Recorder:
    """Writes whisk cycles and poses to a session directory as they arrive.

    Parameters
    ----------
    directory : path-like
        Session directory (created if missing). An existing session is
        resumed: cycle numbering continues after its last pose-log line, and
        the debris of a killed recorder is removed: temporary files, the module
        files of the one cycle whose pose-log line was never written, and a torn
        last pose-log line (no newline). A folder with whisk files but no pose
        log, or with whisk files of cycles beyond the one in progress, is not a
        session this recorder left: it is refused and nothing is deleted.
    pipeline : callable, optional
        Called with each cycle (a ``ReplayedCycle``) once it is on disk; its
        return values are collected in :attr:`results`.

    Attributes
    ----------
    n_cycles : int
        Cycles written by this recorder.
    results : list
        Pipeline outputs, one per cycle.

    Notes
    -----
    Cycles are numbered by the recorder (0, 1, 2, ... in arrival order), not
    by the device, so a device restart cannot overwrite earlier files.
    The pose log's times are the arm's time stamps. When a resumed session's first
    new time stamp is earlier than the log's last (the arm's clock restarted: a
    rebooted controller, a new simulated arm), this recorder's times are written
    shifted by the log's last time, with a logged warning, so the session stays
    in time order and the intervals within each run are kept.
    Use as a context manager: on any exception the pose log is closed and
    everything written so far stays valid.
    """

    def __init__(self, directory: str | os.PathLike[str],
                 pipeline: Optional[Pipeline] = None) -> None:
        self.directory = Path(directory)
        _not_a_file(self.directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        state = _session_state(self.directory)  # a folder it did not leave is refused before anything changes
        log_path = self.directory / POSE_LOG_NAME
        # a whole last line keeps its cycle, a torn one's files are debris below: read again only when it changed
        if log_path.exists() and log_path.stat().st_size and repair_last_line(log_path):
            state = _session_state(self.directory)
        existing, self._next_cycle, unlogged = state
        self._last_logged_s = existing[-1].time_s if existing else None
        self._time_offset_s = 0.0
        for path in self.directory.glob(".whisk_*.tmp"):  # what a killed recorder can leave
            path.unlink(missing_ok=True)
        for path in unlogged:
            _LOG.warning("removing %s: its cycle was interrupted before its pose-log line", path)
            path.unlink(missing_ok=True)
        self._writer = RecordingWriter(self.directory)
        self._pipeline = pipeline
        self.n_cycles = 0
        self.results: list[Any] = []
        self.closed = False

    @staticmethod
    def check_folder(directory: str | os.PathLike[str]) -> None:
        """Raise what opening a :class:`Recorder` on ``directory`` would raise, without creating or changing
        anything: for a script to refuse a folder before it connects to an arm.

        Raises
        ------
        InvalidInputError
            A file (or a path through one) where the folder should be; whisk files without a
            pose log, or beyond the cycle in progress.
        CorruptFileError
            A malformed pose log.
        """
        _not_a_file(Path(directory))
        if Path(directory).is_dir():
            _session_state(Path(directory))

    def record(self, state: ArmState, records: Sequence[WhiskRecord]) -> ReplayedCycle:
        """Write one whisk cycle with the arm state it was taken at.

        Parameters
        ----------
        state : ArmState
            Its ``timestamp`` (s) and ``pose`` go to the pose log.
        records : sequence of WhiskRecord
            One per module, from :meth:`Array.read_whisk`.

        Returns
        -------
        ReplayedCycle
            The cycle exactly as :func:`replay_session` will yield it.

        Raises
        ------
        InvalidInputError
            Recorder closed, no records, or a time earlier than the previous
            cycle's; nothing is written then. If writing fails part-way (disk
            full, interrupt), the cycle's files written so far are removed, so
            the session holds only complete cycles.
        """
        if self.closed:
            raise InvalidInputError(f"recorder for {self.directory} is closed")
        cycle = self._next_cycle
        relabelled = [r if r.cycle == cycle else _with_cycle(r, cycle) for r in records]
        time_s = state.timestamp + self._time_offset_s
        last = self._last_logged_s
        if self.n_cycles == 0 and last is not None and time_s < last:  # the arm's clock restarted since the log's end
            self._time_offset_s = last
            time_s = state.timestamp + last
            _LOG.warning("%s: the arm's time %.6g s is earlier than the pose log's last %.6g s (its clock restarted): "
                         "this run's times are written %.6g s later, so the session stays in time order",
                         self.directory, state.timestamp, last, last)
        try:
            entry = self._writer.write_cycle(relabelled, time_s=time_s, pose=state.pose)
        except BaseException:
            if _logged(self.directory / POSE_LOG_NAME, whisk_file_stem(cycle)):
                # interrupted after its pose-log line was written: the cycle is complete, its files stay
                self._next_cycle += 1
                self.n_cycles += 1
                self._writer.resync()  # the writer's last time and files, whether or not its append finished
                raise
            # the cycle has no pose-log line: remove its module files written so far
            for path in self.directory.glob(f"{whisk_file_stem(cycle)}_*.csv"):
                path.unlink(missing_ok=True)
            raise
        self._next_cycle += 1
        self.n_cycles += 1
        item = ReplayedCycle(entry=entry, records=MappingProxyType(
            {r.module: r for r in sorted(relabelled, key=lambda r: r.module)}))
        if self._pipeline is not None:
            self.results.append(self._pipeline(item))
        return item

    def close(self) -> None:
        """Close the pose log (idempotent). Files already written stay valid."""
        if not self.closed:
            self._writer.close()
            self.closed = True

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _not_a_file(directory: Path) -> None:
    """Refuse a session folder that is a file (or a broken link), or lies below one."""
    for part in (directory, *directory.parents):
        if os.path.lexists(part) and not part.is_dir():
            raise InvalidInputError(f"{directory}: {part} is a file, not a folder; record into a folder")


def _logged(log_path: Path, stem: str) -> bool:
    """Whether the pose log's last whole line names ``stem`` (read after a failed :meth:`Recorder.record`)."""
    try:
        with open(log_path, "rb") as fh:
            fh.seek(max(0, os.fstat(fh.fileno()).st_size - 4096))
            tail = fh.read()
    except OSError:
        return False
    whole = tail[: tail.rfind(b"\n") + 1].decode("utf-8", "replace").splitlines()
    return bool(whole) and whole[-1].rsplit(",", 1)[-1].strip() == stem


def _session_state(directory: Path) -> tuple[list[Any], int, list[Path]]:
    """A session folder's pose-log entries, its next cycle and the module files of the one cycle in progress (what
    a killed recorder leaves); whisk files no recorder can have left there are refused, deleting nothing."""
    log_path = directory / POSE_LOG_NAME
    has_log = log_path.exists() and log_path.stat().st_size > 0
    existing = read_pose_log(log_path) if has_log else []
    numbers = [int(m.group(1)) for e in existing if (m := re.fullmatch(r"whisk_(\d+)", e.whisk_file))]
    next_cycle = max(numbers) + 1 if numbers else 0
    unlogged = []
    for path in directory.glob("whisk_*_*.csv"):
        m = re.match(r"whisk_(\d+)_", path.name)
        if m and int(m.group(1)) >= next_cycle:
            unlogged.append((int(m.group(1)), path))
    foreign = sorted(p.name for c, p in unlogged if not has_log or c > next_cycle)
    if foreign:
        why = (f"has no {POSE_LOG_NAME}" if not has_log else
               f"whose cycles lie beyond the pose log's last line (the next cycle is {next_cycle})")
        raise InvalidInputError(
            f"{directory} holds {len(foreign)} whisk file(s) ({', '.join(foreign[:3])}"
            f"{', ...' if len(foreign) > 3 else ''}) but {why}: not a session a recorder left here, so nothing "
            "is resumed or deleted; record into another folder, or move those files away")
    return existing, next_cycle, [p for _, p in unlogged]


def _with_cycle(record: WhiskRecord, cycle: int) -> WhiskRecord:
    return WhiskRecord(record.module, record.angle_rad, record.x_counts, record.y_counts,
                       sample_rate_hz=record.sample_rate_hz, cycle=cycle, spare=record.spare)


def replay_session(directory: str | os.PathLike[str], pipeline: Pipeline) -> list[Any]:
    """Drive ``pipeline`` with every cycle of a recorded session, in order.

    The pipeline receives the same :class:`ReplayedCycle` objects it received
    live from :class:`Recorder` (same poses, same samples, bit for bit).

    Returns
    -------
    list
        The pipeline's outputs, one per cycle.
    """
    return [pipeline(cycle) for cycle in replay(directory)]


def raster_poses(centre: PoseLike, width_m: float, height_m: float, n_x: int,
                 n_z: int) -> list[Pose]:
    """Poses on a boustrophedon raster across the array's view, same orientation.

    The raster lies in the plane of the end-effector's x- and z-axes through
    ``centre`` (the plane perpendicular to the array axis +y, Fig 2.15), so
    the array sweeps a face of the object in front of it.

    Parameters
    ----------
    centre : PoseLike
        Middle of the raster.
    width_m, height_m : float
        Extent along the end-effector x- and z-axes, metres (>= 0).
    n_x, n_z : int
        Number of poses along each axis (>= 1).

    Returns
    -------
    list of Pose
        ``n_x * n_z`` poses, rows along x alternating direction, bottom row first.
    """
    c = as_pose(centre)
    if not (n_x >= 1 and n_z >= 1 and width_m >= 0 and height_m >= 0):
        raise InvalidInputError("raster needs n_x, n_z >= 1 and non-negative extents")
    axes = c.rotation.as_matrix()
    xs = np.linspace(-width_m / 2, width_m / 2, n_x) if n_x > 1 else np.zeros(1)
    zs = np.linspace(-height_m / 2, height_m / 2, n_z) if n_z > 1 else np.zeros(1)
    poses = []
    for row, z in enumerate(zs):
        for x in (xs if row % 2 == 0 else xs[::-1]):
            poses.append(Pose(c.position_m + x * axes[:, 0] + z * axes[:, 2], c.quaternion_xyzw))
    return poses


def explore(arm: Arm, array: Array, recorder: Recorder, targets: Iterable[PoseLike], *,
            progress: bool = True, description: str = "exploring", frame_retries: int = FRAME_RETRIES) -> int:
    """Visit each target pose, take one whisk there, record it.

    For each target: ``arm.move_linear(target)`` (checked by the arm's
    safety envelope) -> ``array.read_whisk_retrying(frame_retries)`` (a whisk lost to a
    transient USB frame fault is taken again at the same pose) -> a fresh ``arm.state()``
    (stale or lost state raises here) -> ``recorder.record`` (on disk before
    anything else can fail) -> ``arm.guard_deflection`` (stops the arm on
    overload). This is the one loop used for the simulator and the robot.

    Parameters
    ----------
    progress : bool
        Show a tqdm progress bar.
    frame_retries : int
        Retakes of a whisk after a USB frame fault (0: the first fault ends the run).

    Returns
    -------
    int
        Number of cycles recorded.

    Raises
    ------
    HardwareError
        Any arm/array fault or safety refusal. The arm has been stopped and
        every cycle completed before the fault is on disk; close the recorder
        (or use it as a context manager) and inspect the error.
    """
    from tqdm.auto import tqdm

    retake_count(frame_retries, "frame_retries")  # before the arm moves
    targets = list(targets)
    n = 0
    try:
        for target in tqdm(targets, desc=description, disable=not progress, unit="whisk"):
            arm.move_linear(target)
            records = array.read_whisk_retrying(frame_retries)
            state = arm.state()
            recorder.record(state, records)
            n += 1
            for r in records:
                arm.guard_deflection(np.stack([r.x_counts, r.y_counts]))
    except BaseException:
        arm.safe_stop()
        raise
    return n
