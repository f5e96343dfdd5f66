"""Whisk recordings on disk: per-whisk CSV files and the arm pose log (Sec 3.1.3).

The thesis logs "a series of .csv files, with each file capturing the data from a
single whisk cycle", four columns "angular sensor data, deflection in the
x-direction and deflection in the y-direction" and a spare placeholder column,
plus the end-effector pose (time, position, quaternion, name of the latest whisk
file). This module fixes that format precisely so the simulator, the hardware
recorder and the contact pipeline read and write the same files.

File format (decisions, where the thesis is silent)
----------------------------------------------------
Whisk file, one per whisk cycle per module, named ``whisk_{cycle:06d}_{module}.csv``
(e.g. ``whisk_000012_C2.csv``). UTF-8 text, ``,`` separated, ``\\n`` line ends,
one header line followed by one line per 2 kHz sample::

    angle_rad,x_deflection_counts,y_deflection_counts,spare
    -0.87266462599716477,3,-2,0
    ...

* ``angle_rad``: whisk angle theta in **radians** (Fig 2.15: -50 deg full
  retraction, +50 deg full protraction). Radians, not degrees, so that a value
  written with 17 significant digits reads back bit-identical and replay gives
  exactly the in-memory contacts.
* ``x_deflection_counts``, ``y_deflection_counts``: Hall-sensor deflection in
  ADC counts (the unit of the 500-count prominence of Sec 5.1.1.1.1); stored as
  floats, integral for real hardware.
* ``spare``: placeholder column (zeros unless a recorder fills it).

A file whose header names ``angle_deg`` instead of ``angle_rad`` is also read
(the angle is converted to radians). A file without a header line is read as the
canonical units. Values are written with ``%.17g``.

Pose log, one per session, ``pose_log.csv``, one header line and one line per
whisk cycle::

    time_s,x_m,y_m,z_m,qx,qy,qz,qw,whisk_file
    12.5,0.4,0.1,0.3,0,0,0,1,whisk_000012

* ``time_s``: seconds (any epoch), non-decreasing down the file.
* ``x_m, y_m, z_m``: end-effector position in the arm base frame, metres.
* ``qx, qy, qz, qw``: end-effector orientation, unit quaternion, **scalar last**
  (the order of ``geometry_msgs/Quaternion`` and of
  ``scipy.spatial.transform.Rotation.as_quat``). The line is read into a
  :class:`~whisker_io.pose.Pose`, so the package's one quaternion rule applies:
  a norm within 1e-3 of 1 is normalised, anything else is a corrupt line; the
  sign is made canonical (``qw >= 0``, the same rotation).
* ``whisk_file``: the stem of the cycle's whisk files; the cycle's module files
  are ``{whisk_file}_{module}.csv`` in the same directory.

Crash safety: every whisk file is written to a temporary name in the same
directory, flushed, fsynced and renamed (``os.replace``), so it is complete or
absent. The pose-log line of a cycle is appended (and fsynced) only after all of
the cycle's whisk files are on disk. A final pose-log line without its newline (a
write torn by a crash) is ignored with a warning; every other malformed line is
an error naming the file and the 1-based line number.

Example
-------
>>> import numpy as np, tempfile
>>> from whisker_io.pose import Pose
>>> from whisker_io.records.whisk_record import WhiskRecord
>>> from whisker_io.records.recording import RecordingWriter, replay
>>> rec = WhiskRecord("A1", np.zeros(4), np.zeros(4), np.ones(4), cycle=0)
>>> with tempfile.TemporaryDirectory() as d:
...     with RecordingWriter(d) as w:
...         _ = w.write_cycle([rec], time_s=0.0, pose=Pose([0, 0, 0], [0, 0, 0, 1]))
...     cycles = list(replay(d))
>>> cycles[0].records["A1"].y_counts.tolist()
[1.0, 1.0, 1.0, 1.0]
"""

from __future__ import annotations

import logging
import math
import os
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from whisker_io.errors import CorruptFileError, InvalidInputError
from whisker_io.persistence import sync_folder, write_atomically
from whisker_io.pose import PoseLike
from whisker_io.records.whisk_record import MODULE_NAME_RE, SAMPLE_RATE_HZ, PoseEntry, WhiskRecord

__all__ = [
    "WHISK_HEADER",
    "POSE_LOG_HEADER",
    "POSE_LOG_NAME",
    "ReplayedCycle",
    "whisk_file_stem",
    "whisk_file_name",
    "write_whisk_csv",
    "read_whisk_csv",
    "PoseLogWriter",
    "read_pose_log",
    "repair_last_line",
    "MAX_ANGLE_RAD",
    "MAX_POSE_DISTANCE_M",
    "RecordingWriter",
    "replay",
]

log = logging.getLogger(__name__)

#: Header line of a whisk CSV (canonical units).
WHISK_HEADER: tuple[str, ...] = ("angle_rad", "x_deflection_counts", "y_deflection_counts", "spare")
_WHISK_HEADER_DEG: tuple[str, ...] = ("angle_deg",) + WHISK_HEADER[1:]
#: Header line of the pose log.
POSE_LOG_HEADER: tuple[str, ...] = ("time_s", "x_m", "y_m", "z_m", "qx", "qy", "qz", "qw", "whisk_file")
#: File name of the pose log inside a session directory.
POSE_LOG_NAME: str = "pose_log.csv"
#: Largest whisk angle a whisk file holds, rad (2 pi): a whisk sweeps about +-0.9 rad and the USB frame's
#: angle field reaches +-3.28 rad, while a whisk in degrees goes far beyond.
MAX_ANGLE_RAD: float = 2.0 * math.pi
#: Largest distance of a pose-log position from the arm's base, m (no arm reaches farther: a larger one
#: is millimetres written as metres).
MAX_POSE_DISTANCE_M: float = 10.0

_FILE_RE = re.compile(r"^whisk_(\d+)_([A-Za-z0-9]+)\.csv$")


@dataclass(frozen=True, eq=False)
class ReplayedCycle:
    """One whisk cycle read back from a session: its pose and its module records.

    Attributes
    ----------
    entry : PoseEntry
        The pose-log line of the cycle (time, pose, whisk-file stem).
    records : Mapping[str, WhiskRecord]
        Module name -> record, in module-name order.
    """

    entry: PoseEntry
    records: Mapping[str, WhiskRecord]


def whisk_file_stem(cycle: int) -> str:
    """Stem shared by the whisk files of one cycle, e.g. ``whisk_000012``."""
    if not (isinstance(cycle, (int, np.integer)) and cycle >= 0):
        raise InvalidInputError(f"cycle must be an integer >= 0, got {cycle!r}")
    return f"whisk_{int(cycle):06d}"


def whisk_file_name(cycle: int, module: str) -> str:
    """File name of one module's whisk CSV, e.g. ``whisk_000012_C2.csv``."""
    if not isinstance(module, str) or not MODULE_NAME_RE.match(module):
        raise InvalidInputError(f"module name {module!r} must be letters and digits, e.g. 'C2'")
    return f"{whisk_file_stem(cycle)}_{module}.csv"


def write_whisk_csv(path: str | os.PathLike[str], record: WhiskRecord) -> Path:
    """Write one whisk record atomically (temporary file, fsync, rename).

    Parameters
    ----------
    path : path-like
        Destination file, or a directory, in which case the file is named
        :func:`whisk_file_name` ``(record.cycle, record.module)``.
    record : WhiskRecord
        The samples.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    if not isinstance(record, WhiskRecord):
        raise InvalidInputError(f"record must be a WhiskRecord, got {type(record).__name__}")
    p = Path(path)
    if p.is_dir():
        p = p / whisk_file_name(record.cycle, record.module)
    if not p.parent.is_dir():
        raise InvalidInputError(f"directory {p.parent} does not exist; create it before writing whisks")
    _refuse_degrees(record)  # a file its reader would refuse is never written
    cols = record.as_columns()
    body = "\n".join(",".join(format(v, ".17g") for v in row) for row in cols.tolist())
    text = ",".join(WHISK_HEADER) + "\n" + body + "\n"
    write_atomically(p, lambda fh: fh.write(text.encode("utf-8")))
    return p


def _read_lines(path: Path, what: str) -> list[str]:
    """The file's lines split on ``\\n`` (the last one empty when the file ends with a newline)."""
    try:
        return path.read_text(encoding="utf-8-sig").split("\n")  # a leading byte-order mark (Excel's "CSV UTF-8") dropped
    except FileNotFoundError:
        raise CorruptFileError(f"{path}: {what} not found") from None
    except UnicodeDecodeError as exc:
        raise CorruptFileError(f"{path}: not UTF-8 text ({exc.reason})") from None


def _parse_float(token: str, path: Path, lineno: int, column: str, what: str = "whisk file") -> float:
    try:
        value = float(token)
    except ValueError:
        raise CorruptFileError(
            f"{path}: line {lineno}: column '{column}' is not a number ({token.strip()!r}); "
            f"the file is corrupt or not a {'whisk CSV' if what == 'whisk file' else what}"
        ) from None
    if not math.isfinite(value):
        fix = "repair or drop this whisk file" if what == "whisk file" else f"repair this line of the {what}"
        raise CorruptFileError(f"{path}: line {lineno}: column '{column}' holds {token.strip()!r} (NaN/inf); {fix}")
    return value


def read_whisk_csv(
    path: str | os.PathLike[str],
    module: str | None = None,
    cycle: int | None = None,
    sample_rate_hz: float = SAMPLE_RATE_HZ,
) -> WhiskRecord:
    """Read one whisk CSV into a :class:`WhiskRecord`.

    Parameters
    ----------
    path : path-like
        The file.
    module, cycle : optional
        Module name and cycle index; taken from a ``whisk_{cycle}_{module}.csv``
        file name when not given.
    sample_rate_hz : float, default 2000
        Sampling rate, Hz (not stored in the file).

    Raises
    ------
    CorruptFileError
        Missing file, unknown header, a line without exactly 4 columns, a
        non-numeric or NaN/inf value, or no samples; the message names the file
        and the 1-based line.
    """
    p = Path(path)
    if module is None or cycle is None:
        m = _FILE_RE.match(p.name)
        if m is None:
            raise CorruptFileError(
                f"{p}: cannot tell module and cycle from the file name; name it "
                "whisk_{cycle:06d}_{module}.csv or pass module= and cycle="
            )
        cycle = int(m.group(1)) if cycle is None else cycle
        module = m.group(2) if module is None else module
    lines = _read_lines(p, "whisk file")
    if lines and lines[-1] == "":
        lines.pop()
    first_data = 0
    scale = 1.0
    if lines:
        head = tuple(t.strip() for t in lines[0].split(","))
        if head == WHISK_HEADER:
            first_data = 1
        elif head == _WHISK_HEADER_DEG:
            first_data, scale = 1, math.pi / 180.0
        elif head and head[0] and not _looks_numeric(head[0]):
            raise CorruptFileError(
                f"{p}: line 1: unexpected header {lines[0]!r}; expected {','.join(WHISK_HEADER)!r}"
            )
    rows = lines[first_data:]
    if not rows:
        raise CorruptFileError(f"{p}: line {first_data + 1}: no samples in whisk file")
    try:  # fast path; the slow path below locates the first bad line
        data = np.array([r.split(",") for r in rows], dtype=np.float64)
        ok = data.ndim == 2 and data.shape[1] == 4 and bool(np.all(np.isfinite(data)))
    except ValueError:
        ok = False
    if not ok:
        data = np.empty((len(rows), 4))
        for i, row in enumerate(rows):
            lineno = i + first_data + 1
            tokens = row.split(",")
            if len(tokens) != 4:
                raise CorruptFileError(
                    f"{p}: line {lineno}: expected 4 columns ({','.join(WHISK_HEADER)}), "
                    f"found {len(tokens)}"
                )
            for j, tok in enumerate(tokens):
                data[i, j] = _parse_float(tok, p, lineno, WHISK_HEADER[j])
    angle_rad = data[:, 0] * scale if scale != 1.0 else data[:, 0]
    k = _angle_beyond(angle_rad)
    if k is not None:  # degrees under an angle_rad header (or none)
        raise CorruptFileError(
            f"{p}: line {k + first_data + 1}: angle {float(data[k, 0])!r} lies beyond +-{MAX_ANGLE_RAD:.4g} rad (2 pi): "
            f"degrees? A whisk file holds radians under the header {','.join(WHISK_HEADER)!r}, or degrees under "
            f"{','.join(_WHISK_HEADER_DEG)!r}"
        )
    return WhiskRecord(
        module=module,
        angle_rad=angle_rad,
        x_counts=data[:, 1],
        y_counts=data[:, 2],
        sample_rate_hz=sample_rate_hz,
        cycle=cycle,
        spare=data[:, 3],
    )


def _angle_beyond(angle_rad: np.ndarray) -> int | None:
    """The first sample whose angle lies beyond :data:`MAX_ANGLE_RAD` (None: all within)."""
    beyond = np.flatnonzero(np.abs(np.asarray(angle_rad, dtype=float)) > MAX_ANGLE_RAD)
    return int(beyond[0]) if beyond.size else None


def _refuse_degrees(record: WhiskRecord) -> None:
    """Refuse to write a record whose angles :func:`read_whisk_csv` would refuse (beyond :data:`MAX_ANGLE_RAD`)."""
    k = _angle_beyond(record.angle_rad)
    if k is not None:
        raise InvalidInputError(f"{record.module}: sample {k} angle {float(record.angle_rad[k])!r} rad lies beyond "
                                f"+-{MAX_ANGLE_RAD:.4g} rad: degrees? WhiskRecord angles are radians")


def _looks_numeric(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _pose_line(entry: PoseEntry) -> str:
    vals = [entry.time_s, *entry.pose.position_m.tolist(), *entry.pose.quaternion_xyzw.tolist()]
    return ",".join(format(v, ".17g") for v in vals) + "," + entry.whisk_file + "\n"


class PoseLogWriter:
    """Appends pose-log lines, each flushed and fsynced before :meth:`append` returns.

    Parameters
    ----------
    path : path-like
        The pose log. A missing or empty file gets the header; an existing one is
        checked and appended to (resuming a session), and its last time stamp
        is the lower bound for the next line. Its last line, when it lacks its
        newline, is repaired first (:func:`repair_last_line`).

    Raises
    ------
    CorruptFileError
        If an existing log is malformed.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._last_time = -math.inf
        self._files: set[str] = set()  # whisk files the log names
        if self.path.exists() and self.path.stat().st_size > 0:
            repair_last_line(self.path)  # may leave nothing (a torn header): then the header is written below
        if self.path.exists() and self.path.stat().st_size > 0:
            entries = read_pose_log(self.path)
            self._files = {e.whisk_file for e in entries}
            if entries:
                self._last_time = entries[-1].time_s
            needs_header = False
        else:
            needs_header = True
        # unbuffered: once write() returns, the line is in the file (a Python buffer could hold it past an
        # interrupt, to be flushed on close after its cycle's files were removed as unlogged)
        self._fh = open(self.path, "ab", buffering=0)
        if needs_header:
            self._write(",".join(POSE_LOG_HEADER) + "\n")
            sync_folder(self.path.parent)

    def _write(self, text: str) -> None:
        data = memoryview(text.encode("utf-8"))
        while data:  # a raw write may take part of the bytes
            data = data[self._fh.write(data):]
        os.fsync(self._fh.fileno())

    def resync(self) -> None:
        """Take the log's last time and whisk files from the file again (after an append was interrupted, when
        its line may or may not have reached the file)."""
        entries = read_pose_log(self.path) if self.path.stat().st_size else []
        self._files = {e.whisk_file for e in entries}
        self._last_time = entries[-1].time_s if entries else -math.inf

    def append(
        self,
        time_s: float,
        pose: PoseLike,
        whisk_file: str,
    ) -> PoseEntry:
        """Validate and append one line.

        Parameters
        ----------
        time_s : float
            Time stamp, s.
        pose : PoseLike
            End-effector pose (see :func:`whisker_io.pose.as_pose`).
        whisk_file : str
            Stem of the cycle's whisk files.

        Raises
        ------
        InvalidInputError
            Bad pose values, or ``time_s`` earlier than the previous line (the
            log must be in time order). Nothing is written then.
        """
        if self._fh.closed:
            raise InvalidInputError(f"pose log {self.path} is closed; open a new PoseLogWriter")
        entry = PoseEntry(time_s, pose, whisk_file)
        self.check_entry(entry)
        self._write(_pose_line(entry))
        self._last_time = entry.time_s
        self._files.add(entry.whisk_file)
        return entry

    def check_time(self, time_s: float) -> None:
        """Raise :class:`InvalidInputError` if ``time_s`` is earlier than the last line's time."""
        if time_s < self._last_time:
            raise InvalidInputError(
                f"pose time {time_s!r} s is earlier than the previous line's {self._last_time!r} s; "
                "the pose log must be in time order"
            )

    def check_entry(self, entry: PoseEntry) -> None:
        """Raise :class:`InvalidInputError` for a line :func:`read_pose_log` would refuse after this log's lines:
        out of time order, a position beyond :data:`MAX_POSE_DISTANCE_M`, or a whisk file already named."""
        self.check_time(entry.time_s)
        reach = float(np.linalg.norm(entry.pose.position_m))
        if reach > MAX_POSE_DISTANCE_M:
            raise InvalidInputError(f"pose position {entry.pose.position_m.tolist()} lies {reach:.4g} m from the arm's "
                                    f"base, beyond {MAX_POSE_DISTANCE_M:g} m: give metres, not millimetres")
        if entry.whisk_file in self._files:
            raise InvalidInputError(f"whisk file {entry.whisk_file!r} is already in {self.path}; each line names its "
                                    "own cycle's files")

    def close(self) -> None:
        """Close the file (idempotent)."""
        if not self._fh.closed:
            self._fh.close()

    def __enter__(self) -> PoseLogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def repair_last_line(path: str | os.PathLike[str]) -> str:
    """Make a pose log end with a whole line before anything is appended to it.

    A last line without its newline is either a whole line (an edit that dropped the final
    newline: 9 columns naming whisk files that exist beside the log) - the newline is added,
    and :func:`read_pose_log` then reads it or refuses it with its reason - or a write torn by
    a crash - it is cut off, as :func:`read_pose_log` ignores it (the cycle's whisk files are
    then debris of an interrupted cycle; a torn header leaves an empty log). Either way a
    warning is logged; the next line would otherwise be glued onto it.

    Returns
    -------
    str
        ``"completed"``, ``"cut"`` or ``""`` (the log ended with a newline, or is empty).
    """
    p = Path(path)
    with open(p, "rb+") as fh:
        data = fh.read()
        if not data or data.endswith(b"\n"):
            return ""
        keep = data.rfind(b"\n") + 1
        tail = data[keep:].decode("utf-8", "replace")
        if _whole_line(p, tail):
            fh.write(b"\n")
            log.warning("%s: its last line lacked its newline; added (the line is whole and its whisk files exist)", p)
            what = "completed"
        else:
            fh.truncate(keep)
            log.warning("%s: cutting off the torn last line (%d bytes, no newline) before appending", p,
                        len(data) - keep)
            what = "cut"
        fh.flush()
        os.fsync(fh.fileno())
    return what


def _whole_line(path: Path, tail: str) -> bool:
    """Whether ``tail`` (the log's last line, without its newline) is a whole line: 9 columns naming whisk files that
    exist. A write torn inside its last column names none (the stems are ``whisk_`` and six digits or more); a line
    that is whole but wrong is kept, for :func:`read_pose_log` to refuse with its reason, never cut with its cycle."""
    tokens = tail.split(",")
    if len(tokens) != len(POSE_LOG_HEADER) or not re.fullmatch(r"whisk_\d+", tokens[8].strip()):
        return False
    return any(path.parent.glob(f"{tokens[8].strip()}_*.csv"))


def read_pose_log(path: str | os.PathLike[str]) -> list[PoseEntry]:
    """Read and validate a pose log.

    Returns
    -------
    list of PoseEntry
        In file order.

    Raises
    ------
    CorruptFileError
        Missing file, wrong header, a line without 9 columns, a non-numeric or
        non-finite value, a non-unit quaternion, a position farther than
        :data:`MAX_POSE_DISTANCE_M` from the base (millimetres written as metres),
        a whisk file named by an earlier line too, or a time stamp earlier than
        the line before (out of time order); the message names the file and the
        1-based line. A final line without a newline (a write torn by a crash) is
        ignored with a warning; a torn header is a log without lines.
    """
    p = Path(path)
    lines = _read_lines(p, "pose log")
    tail = lines.pop()  # "" when the file ends with a newline
    if tail:
        log.warning("%s: ignoring torn final line %d (no newline): %r", p, len(lines) + 1, tail)
        if not lines and ",".join(POSE_LOG_HEADER).startswith(tail.strip()):
            return []  # the header itself was torn: a log without lines
    if not lines:
        raise CorruptFileError(f"{p}: line 1: empty pose log; expected header {','.join(POSE_LOG_HEADER)!r}")
    if tuple(t.strip() for t in lines[0].split(",")) != POSE_LOG_HEADER:
        raise CorruptFileError(
            f"{p}: line 1: unexpected header {lines[0]!r}; expected {','.join(POSE_LOG_HEADER)!r}"
        )
    entries: list[PoseEntry] = []
    first_line: dict[str, int] = {}  # whisk file -> the line naming it
    for i, line in enumerate(lines[1:], start=2):
        tokens = line.split(",")
        if len(tokens) != len(POSE_LOG_HEADER):
            raise CorruptFileError(
                f"{p}: line {i}: expected {len(POSE_LOG_HEADER)} columns ({','.join(POSE_LOG_HEADER)}), "
                f"found {len(tokens)}"
            )
        vals = [_parse_float(tok, p, i, POSE_LOG_HEADER[j], "pose log") for j, tok in enumerate(tokens[:8])]
        try:
            entry = PoseEntry(vals[0], (vals[1:4], vals[4:8]), tokens[8].strip())
        except InvalidInputError as exc:
            raise CorruptFileError(f"{p}: line {i}: {exc}") from None
        reach = float(np.linalg.norm(vals[1:4]))
        if reach > MAX_POSE_DISTANCE_M:
            raise CorruptFileError(
                f"{p}: line {i}: position {vals[1:4]} lies {reach:.4g} m from the arm's base, beyond any arm's reach "
                f"({MAX_POSE_DISTANCE_M:g} m): millimetres? The pose log holds metres")
        if entry.whisk_file in first_line:
            raise CorruptFileError(
                f"{p}: line {i}: whisk file {entry.whisk_file!r} is line {first_line[entry.whisk_file]}'s too; each "
                "line names its own cycle's files")
        first_line[entry.whisk_file] = i
        if entries and entry.time_s < entries[-1].time_s:
            raise CorruptFileError(
                f"{p}: line {i}: time {entry.time_s!r} s is earlier than line {i - 1}'s "
                f"{entries[-1].time_s!r} s; the pose log is out of time order"
            )
        entries.append(entry)
    return entries


class RecordingWriter:
    """Writes a session: per-module whisk CSVs, then the cycle's pose-log line.

    Parameters
    ----------
    directory : path-like
        Session directory (created if missing). The pose log is
        ``directory / "pose_log.csv"``.

    Examples
    --------
    >>> with RecordingWriter(tmpdir) as w:                       # doctest: +SKIP
    ...     w.write_cycle(records, time_s=t, pose=pose)
    """

    def __init__(self, directory: str | os.PathLike[str]) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self._pose_log = PoseLogWriter(self.directory / POSE_LOG_NAME)

    def write_cycle(
        self,
        records: Iterable[WhiskRecord],
        time_s: float,
        pose: PoseLike,
    ) -> PoseEntry:
        """Write all module records of one cycle, then append its pose line.

        Parameters
        ----------
        records : iterable of WhiskRecord
            The cycle's module records.
        time_s : float
            Time stamp of the pose line, s.
        pose : PoseLike
            End-effector pose at the end of the cycle (see :func:`whisker_io.pose.as_pose`).

        All records must share one cycle index and have distinct modules. The
        pose is validated before any file is written, so a bad pose or an
        out-of-order time leaves the directory unchanged. Modules of unequal length, or an
        angle beyond :data:`MAX_ANGLE_RAD`, are refused before anything is written.

        Returns
        -------
        PoseEntry
            The appended pose-log line.
        """
        recs = list(records)
        if not recs:
            raise InvalidInputError("write_cycle needs at least one WhiskRecord")
        if not all(isinstance(r, WhiskRecord) for r in recs):
            raise InvalidInputError("records must all be WhiskRecord instances")
        cycles = {r.cycle for r in recs}
        if len(cycles) != 1:
            raise InvalidInputError(f"records of one cycle must share a cycle index, got {sorted(cycles)}")
        modules = [r.module for r in recs]
        if len(set(modules)) != len(modules):
            raise InvalidInputError(f"duplicate modules in one cycle: {sorted(modules)}")
        lengths = {r.module: r.n_samples for r in recs}
        if len(set(lengths.values())) > 1:  # replay refuses such a cycle: it is never written
            raise InvalidInputError(f"the modules of one whisk must hold the same number of samples, got {lengths}")
        for r in recs:  # before any file: write_whisk_csv would refuse it after the others were written
            _refuse_degrees(r)
        stem = whisk_file_stem(recs[0].cycle)
        entry = PoseEntry(time_s, pose, stem)
        self._pose_log.check_entry(entry)
        for r in recs:
            write_whisk_csv(self.directory / whisk_file_name(r.cycle, r.module), r)
        return self._pose_log.append(entry.time_s, entry.pose, stem)

    def resync(self) -> None:
        """:meth:`PoseLogWriter.resync` of the session's pose log (after an interrupted :meth:`write_cycle`)."""
        self._pose_log.resync()

    def close(self) -> None:
        """Close the pose log (idempotent)."""
        self._pose_log.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def replay(
    directory: str | os.PathLike[str],
    sample_rate_hz: float = SAMPLE_RATE_HZ,
    modules: Sequence[str] | None = None,
) -> Iterator[ReplayedCycle]:
    """Iterate a recorded session's whisk cycles in pose-log order.

    Parameters
    ----------
    directory : path-like
        Session directory holding ``pose_log.csv`` and the whisk files.
    sample_rate_hz : float, default 2000
        Sampling rate of the whisk files, Hz.
    modules : sequence of str, optional
        Only these modules (each must be present in every cycle).

    Yields
    ------
    ReplayedCycle
        Pose and module records of each cycle.

    Raises
    ------
    CorruptFileError
        A malformed pose log or whisk file (naming file and line), a pose
        line whose cycle has no whisk files / lacks a requested module, or a
        cycle whose modules hold different numbers of samples.
    """
    d = Path(directory)
    pose_path = d / POSE_LOG_NAME
    entries = read_pose_log(pose_path)
    for lineno, entry in enumerate(entries, start=2):
        files = sorted(d.glob(f"{entry.whisk_file}_*.csv"))
        by_module: dict[str, Path] = {}
        for f in files:
            module = f.name[len(entry.whisk_file) + 1 : -len(".csv")]
            if MODULE_NAME_RE.match(module):
                by_module[module] = f
        wanted = sorted(by_module) if modules is None else list(modules)
        missing = [m for m in wanted if m not in by_module]
        if not wanted or missing:
            names = [f"{entry.whisk_file}_{m}.csv" for m in missing] or [f"{entry.whisk_file}_*.csv"]
            raise CorruptFileError(f"{pose_path}: line {lineno}: whisk file(s) {', '.join(names)} missing in {d}")
        m = _FILE_RE.match(by_module[wanted[0]].name)
        cycle = int(m.group(1)) if m else 0
        records = {
            mod: read_whisk_csv(by_module[mod], module=mod, cycle=cycle, sample_rate_hz=sample_rate_hz)
            for mod in wanted
        }
        lengths = {mod: r.n_samples for mod, r in records.items()}
        if len(set(lengths.values())) > 1:  # one whisk samples every module together: a file was cut or mixed up
            shortest = min(lengths, key=lengths.__getitem__)
            raise CorruptFileError(
                f"{pose_path}: line {lineno}: the modules of {entry.whisk_file} hold different numbers of samples "
                f"({shortest}: {lengths[shortest]}, {max(lengths, key=lengths.__getitem__)}: {max(lengths.values())}): "
                f"{by_module[shortest].name} was cut short or belongs to another whisk")
        yield ReplayedCycle(entry=entry, records=MappingProxyType(records))
