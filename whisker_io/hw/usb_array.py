"""The whisker array behind one :class:`Array` interface.

* :class:`USBArray`: the array's FPGA over USB with ``pyusb`` (bulk
  transfers, device found by vendor/product id).
* :class:`SimArray`: the same interface fed by a simulator, whose whisks
  pass through the very same frame encoder/parser as USB data.

Both return one whisk cycle at a time as 18
:class:`~whisker_io.records.whisk_record.WhiskRecord` (one per module, angle in rad,
x/y deflection in ADC counts, 2 kHz; Sec 3.1.3 / Sec 5.1.1.1.1).

USB frame layout (device -> host, bulk-in endpoint, little-endian)
------------------------------------------------------------------
The thesis does not document the FPGA's packet format, so this layout is a
decision (every number is a :class:`FrameLayout` parameter)::

    offset  size       field
    0       2          magic b"WK"
    2       1          layout version (1)
    3       1          number of modules M (18)
    4       4          sequence number, uint32, +1 per frame, wraps at 2**32
    8       4          whisk cycle index, uint32
    12      2          frame index within the whisk cycle, uint16 (0 = first)
    14      2          number of samples S in this frame, uint16
    16      1          flags: bit 0 END_OF_WHISK, bit 1 OVERLOAD (FPGA RCP limit)
    17      3          reserved, 0
    20      6*S*M      samples, int16, sample-major: for s in S, for m in M:
                       angle (LSB = ``angle_lsb_rad``), x counts, y counts
    20+6SM  4          CRC-32 (``zlib.crc32``) of bytes [0, 20+6SM)

A whisk cycle is the run of frames from frame index 0 to the frame flagged
END_OF_WHISK. A frame is checked for length, magic, version, module count and
CRC, and its sequence number must be the previous one + 1.

Commands (host -> device, bulk-out endpoint, little-endian)::

    0  2  magic b"WC"      2  1  opcode      3  1  payload length L
    4  L  payload          4+L 2 CRC-16/CCITT (``binascii.crc_hqx``, init 0xFFFF)

opcodes: 0x01 SET_PATTERN (uint8 mode index in :data:`PATTERN_MODES`, float32
frequency Hz, float32 retraction angle rad, float32 protraction angle rad:
the fields of :class:`whisker_io.array.control.WhiskPattern`), 0x02
SET_RCP_THRESHOLD (float32 counts), 0x03 START, 0x04 STOP.

Faults raise typed errors and are counted in :class:`USBCounters`: a USB
timeout -> :class:`~whisker_io.errors.DeviceTimeoutError`; a frame shorter
than its header/declared length -> :class:`ShortFrameError`; a CRC mismatch ->
:class:`CRCMismatchError`; a sequence jump -> :class:`SequenceGapError`;
the device gone -> :class:`~whisker_io.errors.DeviceRemovedError`. After any
fault the partially received whisk is discarded (never returned) and the
reader re-synchronises on the next frame with index 0.
"""

from __future__ import annotations

import abc
import binascii
import contextlib
import errno
import logging
import math
import struct
import zlib
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Optional

import numpy as np

from whisker_io.errors import (ConnectionFailedError, CRCMismatchError, DeviceRemovedError, DeviceTimeoutError,
                               HardwareError, InvalidInputError, SequenceGapError, ShortFrameError, USBFrameError)
from whisker_io.array.control import WhiskPattern
from whisker_io.validation import ConfigDataclass, checked, validate_fields
from whisker_io.hw.optional import require
from whisker_io.records.whisk_record import SAMPLE_RATE_HZ, WhiskRecord

__all__ = [
    "Array", "USBArray", "SimArray", "FrameLayout", "Frame", "USBCounters", "PATTERN_MODES", "FRAME_RETRIES",
    "ShortFrameError", "CRCMismatchError", "SequenceGapError",
    "encode_frames", "parse_frame", "encode_command", "parse_command",
    "OP_SET_PATTERN", "OP_SET_RCP_THRESHOLD", "OP_START", "OP_STOP",
]

_LOG = logging.getLogger(__name__)

#: Retakes of a whisk after a transient USB frame fault (:meth:`Array.read_whisk_retrying`).
FRAME_RETRIES = 2

_HEADER = struct.Struct("<2sBBIIHHB3x")
_CRC = struct.Struct("<I")
_CMD_HEADER = struct.Struct("<2sBB")
FLAG_END_OF_WHISK = 0x01
FLAG_OVERLOAD = 0x02
OP_SET_PATTERN = 0x01
OP_SET_RCP_THRESHOLD = 0x02
OP_START = 0x03
OP_STOP = 0x04
#: Whisking modes of SET_PATTERN (Sec 2.3.1, 3.2.2): open-loop cosine, RCP amplitude
#: reduction (Ch.3), retract at the sensor maximum (Ch.4/6).
PATTERN_MODES = ("open_loop", "rcp", "retract_on_max")
_LIBUSB_ERROR_NO_DEVICE = -4




def _thesis_modules() -> tuple[str, ...]:
    from whisker_io.array.geometry import WhiskerArray
    return WhiskerArray.thesis().names


@dataclass(frozen=True)
class FrameLayout(ConfigDataclass):
    """Parameters of the USB device and its frame layout.

    Parameters
    ----------
    vendor_id, product_id : int
        USB ids of the array's FPGA (placeholders: the pid.codes test VID
        0x1209 and product 0x5748 "WH"; set them to your device's).
    modules : tuple of str
        Module names in frame order (default the thesis array A1..F3).
    angle_lsb_rad : float
        Whisk angle resolution, rad per int16 LSB (default 1e-4 rad).
    samples_per_frame : int
        Samples per module in a full frame (encoder side; the parser reads S
        from each header).
    interface, endpoint_in, endpoint_out : int
        Interface number and bulk endpoint addresses.
    sample_rate_hz : float
        Per-module sampling rate (2 kHz).
    """

    vendor_id: int = checked(0x1209, int, minimum=0, maximum=0xFFFF, error=InvalidInputError)
    product_id: int = checked(0x5748, int, minimum=0, maximum=0xFFFF, error=InvalidInputError)
    modules: tuple[str, ...] = field(default_factory=_thesis_modules)
    angle_lsb_rad: float = checked(1e-4, float, above=0, error=InvalidInputError)
    samples_per_frame: int = checked(100, int, minimum=1, maximum=0xFFFF, error=InvalidInputError)
    interface: int = checked(0, int, minimum=0, maximum=255, error=InvalidInputError)
    endpoint_in: int = checked(0x81, int, minimum=0, maximum=255, error=InvalidInputError)
    endpoint_out: int = checked(0x01, int, minimum=0, maximum=255, error=InvalidInputError)
    sample_rate_hz: float = checked(SAMPLE_RATE_HZ, float, above=0, error=InvalidInputError)
    version: int = checked(1, int, minimum=0, maximum=255, error=InvalidInputError)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.modules, (tuple, list)) or not (0 < len(self.modules) < 256) or not all(
                isinstance(m, str) and m for m in self.modules):
            raise InvalidInputError(f"modules must list 1..255 module names (text), got {self.modules!r}")

    @property
    def n_modules(self) -> int:
        return len(self.modules)

    def frame_size(self, n_samples: int) -> int:
        """Bytes of a frame holding ``n_samples`` samples per module."""
        return _HEADER.size + 6 * n_samples * self.n_modules + _CRC.size

    @property
    def max_frame_size(self) -> int:
        return self.frame_size(self.samples_per_frame)


@dataclass(frozen=True)
class Frame:
    """One parsed USB frame.

    Attributes
    ----------
    sequence, whisk, index : int
        Sequence number, whisk cycle index, frame index within the cycle.
    samples : numpy.ndarray, shape (S, M, 3)
        angle (rad), x (counts), y (counts) per sample and module, float64.
    end_of_whisk, overload : bool
        Header flags.
    """

    sequence: int
    whisk: int
    index: int
    samples: np.ndarray
    end_of_whisk: bool
    overload: bool


@dataclass
class USBCounters:
    """Running counts of the USB link (all start at 0)."""

    frames: int = 0
    bytes: int = 0
    whisks: int = 0
    timeouts: int = 0
    short_frames: int = 0
    crc_errors: int = 0
    bad_headers: int = 0
    sequence_gaps: int = 0
    lost_frames: int = 0
    removals: int = 0
    discarded_whisks: int = 0
    skipped_frames: int = 0


# ------------------------------------------------------------------- codec
def encode_frames(layout: FrameLayout, whisk: int, samples: np.ndarray, first_sequence: int,
                  overload: bool = False) -> list[bytes]:
    """Encode one whisk cycle into frames (the device side; used by the fakes).

    Parameters
    ----------
    samples : array_like, shape (T, M, 3)
        angle (rad), x, y (counts); angles are quantised to ``angle_lsb_rad``
        and deflections rounded, both saturated to int16.
    first_sequence : int
        Sequence number of the first frame.

    Returns
    -------
    list of bytes
        ``ceil(T / samples_per_frame)`` frames.
    """
    s = np.asarray(samples, dtype=float)
    if s.ndim != 3 or s.shape[1:] != (layout.n_modules, 3) or s.shape[0] == 0:
        raise InvalidInputError(f"samples must have shape (T, {layout.n_modules}, 3); got {s.shape}")
    raw = np.empty(s.shape, dtype="<i2")
    raw[..., 0] = np.clip(np.rint(s[..., 0] / layout.angle_lsb_rad), -32768, 32767)
    raw[..., 1:] = np.clip(np.rint(s[..., 1:]), -32768, 32767)
    frames = []
    starts = range(0, s.shape[0], layout.samples_per_frame)
    for k, start in enumerate(starts):
        chunk = raw[start:start + layout.samples_per_frame]
        last = start + layout.samples_per_frame >= s.shape[0]
        flags = (FLAG_END_OF_WHISK if last else 0) | (FLAG_OVERLOAD if overload and last else 0)
        head = _HEADER.pack(b"WK", layout.version, layout.n_modules,
                            (first_sequence + k) & 0xFFFFFFFF, whisk & 0xFFFFFFFF, k,
                            chunk.shape[0], flags)
        body = head + chunk.tobytes()
        frames.append(body + _CRC.pack(zlib.crc32(body)))
    return frames


def parse_frame(layout: FrameLayout, data: bytes) -> Frame:
    """Parse and check one frame.

    Raises
    ------
    ShortFrameError
        Fewer bytes than the header + CRC, or than the declared sample count.
    USBFrameError
        Wrong magic, version, module count, or trailing bytes.
    CRCMismatchError
        CRC-32 mismatch.
    """
    data = bytes(data)
    if len(data) < _HEADER.size + _CRC.size:
        raise ShortFrameError(f"USB frame of {len(data)} bytes is shorter than the "
                              f"{_HEADER.size + _CRC.size}-byte header+CRC")
    magic, version, n_mod, seq, whisk, index, n_samples, flags = _HEADER.unpack_from(data)
    if magic != b"WK" or version != layout.version or n_mod != layout.n_modules:
        raise USBFrameError(f"bad USB frame header (magic {magic!r}, version {version}, "
                            f"{n_mod} modules; expected b'WK', {layout.version}, "
                            f"{layout.n_modules}); wrong device or firmware?")
    expected = layout.frame_size(n_samples)
    if len(data) < expected:
        raise ShortFrameError(f"USB frame seq {seq} has {len(data)} bytes, header declares "
                              f"{n_samples} samples = {expected} bytes")
    if len(data) > expected:
        raise USBFrameError(f"USB frame seq {seq} has {len(data) - expected} trailing bytes")
    body = data[:-_CRC.size]
    (crc,) = _CRC.unpack_from(data, len(body))
    if zlib.crc32(body) != crc:
        raise CRCMismatchError(f"USB frame seq {seq}: CRC-32 mismatch (corrupted transfer)")
    raw = np.frombuffer(body, dtype="<i2", offset=_HEADER.size).reshape(n_samples, n_mod, 3)
    samples = raw.astype(np.float64)
    samples[..., 0] *= layout.angle_lsb_rad
    return Frame(seq, whisk, index, samples, bool(flags & FLAG_END_OF_WHISK),
                 bool(flags & FLAG_OVERLOAD))


def encode_command(opcode: int, payload: bytes = b"") -> bytes:
    """Encode a host -> device command with its CRC-16/CCITT."""
    if not (0 <= opcode < 256 and len(payload) < 256):
        raise InvalidInputError("opcode must be a byte and payload < 256 bytes")
    body = _CMD_HEADER.pack(b"WC", opcode, len(payload)) + payload
    return body + struct.pack("<H", binascii.crc_hqx(body, 0xFFFF))


def parse_command(data: bytes) -> tuple[int, bytes]:
    """Parse a command (the device side). Returns ``(opcode, payload)``.

    Raises :class:`USBFrameError` on a bad magic, length or CRC.
    """
    data = bytes(data)
    if len(data) < _CMD_HEADER.size + 2:
        raise ShortFrameError(f"command of {len(data)} bytes is too short")
    magic, opcode, length = _CMD_HEADER.unpack_from(data)
    if magic != b"WC" or len(data) != _CMD_HEADER.size + length + 2:
        raise USBFrameError("bad command magic or length")
    (crc,) = struct.unpack_from("<H", data, len(data) - 2)
    if binascii.crc_hqx(data[:-2], 0xFFFF) != crc:
        raise CRCMismatchError("command CRC-16 mismatch")
    return opcode, data[_CMD_HEADER.size:-2]


def _records(layout: FrameLayout, whisk: int, samples: np.ndarray) -> list[WhiskRecord]:
    return [WhiskRecord(name, samples[:, m, 0], samples[:, m, 1], samples[:, m, 2],
                        sample_rate_hz=layout.sample_rate_hz, cycle=whisk)
            for m, name in enumerate(layout.modules)]


def retake_count(value: object, name: str) -> int:
    """``value`` as a count of retakes (an int >= 0; a bool or a float is refused), or :class:`InvalidInputError`."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidInputError(f"{name} must be a count >= 0, got {value!r}")
    return int(value)


# --------------------------------------------------------------- interface
class Array(abc.ABC):
    """A whisker array delivering whisk cycles.

    Attributes
    ----------
    layout : FrameLayout
        Module names and data format.
    """

    layout: FrameLayout

    @abc.abstractmethod
    def read_whisk(self) -> list[WhiskRecord]:
        """Block until the next complete whisk cycle; one record per module
        (angle rad, x/y counts), all with the cycle index from the device."""

    def read_whisk_retrying(self, retries: int = FRAME_RETRIES) -> list[WhiskRecord]:
        """:meth:`read_whisk`, taken again (at most ``retries`` times) after a transient frame fault.

        A short frame, a CRC mismatch, a lost frame or a malformed header
        (:class:`~whisker_io.errors.USBFrameError`) discards the whisk in progress and the
        next read re-synchronises; the arm has not moved, so the whisk is simply taken
        again (a warning each time). A timeout or an unplugged array is no transient
        fault: it is raised at once, as is the frame fault after ``retries`` retakes.

        Raises
        ------
        InvalidInputError
            ``retries`` not a count >= 0.
        HardwareError
            As :meth:`read_whisk`.
        """
        retries = retake_count(retries, "retries")
        for attempt in range(retries + 1):
            try:
                return self.read_whisk()
            except USBFrameError as exc:
                if attempt == retries:
                    raise
                _LOG.warning("whisk discarded on a USB frame fault (%s): taking it again (retake %d of %d)", exc,
                             attempt + 1, retries)
        raise AssertionError("unreachable")  # pragma: no cover - the loop returns or raises

    @abc.abstractmethod
    def set_pattern(self, pattern: WhiskPattern, mode: str = "open_loop") -> None:
        """Command the whisking pattern (:class:`whisker_io.array.control.WhiskPattern`:
        frequency and whisk range) and mode, one of :data:`PATTERN_MODES`."""

    @abc.abstractmethod
    def set_rcp_threshold(self, counts: float) -> None:
        """Set the RCP contact threshold in ADC counts (Sec 2.3.1, 3.2.2)."""

    def start(self) -> None:
        """Start whisking/streaming (default: nothing to do)."""

    def stop(self) -> None:
        """Stop whisking/streaming (default: nothing to do)."""

    def close(self) -> None:
        """Release the device (default: nothing to do)."""

    @contextlib.contextmanager
    def whisking(self, pattern: Optional[WhiskPattern] = None, mode: str = "open_loop",
                 rcp_threshold_counts: Optional[float] = None) -> Iterator["Array"]:
        """Set the pattern (and RCP threshold), start whisking; stop on leaving the block.

        The array is stopped however the block ends. After a fault inside the block a
        failing stop is logged and the block's error propagates (it says what went
        wrong first); after a clean block a failing stop raises.

        Parameters
        ----------
        pattern : WhiskPattern, optional
            Frequency and whisk range (default :class:`WhiskPattern()`).
        mode : str
            One of :data:`PATTERN_MODES`.
        rcp_threshold_counts : float, optional
            RCP contact threshold, ADC counts (Sec 2.3.1); None keeps the device's.

        Raises
        ------
        InvalidInputError
            A bad pattern, mode or threshold (nothing is started).
        HardwareError
            The device refused a command or failed to stop.

        Examples
        --------
        >>> with array.whisking(mode="retract_on_max", rcp_threshold_counts=2000.0):  # doctest: +SKIP
        ...     cycle = array.read_whisk()
        """
        self.set_pattern(WhiskPattern() if pattern is None else pattern, mode)
        if rcp_threshold_counts is not None:
            self.set_rcp_threshold(rcp_threshold_counts)
        self.start()
        try:
            yield self
        except BaseException:
            try:
                self.stop()
            except HardwareError as stop_error:
                _LOG.warning("stopping the array after a fault failed too: %s", stop_error)
            raise
        self.stop()

    def __enter__(self) -> "Array":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _check_threshold(counts: float) -> float:
    v = float(counts)
    if not (math.isfinite(v) and 0 < v < 32768):
        raise InvalidInputError(f"RCP threshold must be in (0, 32768) counts; got {counts!r}")
    return v


def _pattern_payload(pattern: WhiskPattern, mode: str) -> bytes:
    if not isinstance(pattern, WhiskPattern):
        raise InvalidInputError("pattern must be a whisker_io.array.control.WhiskPattern")
    if mode not in PATTERN_MODES:
        raise InvalidInputError(f"mode must be one of {PATTERN_MODES}; got {mode!r}")
    return struct.pack("<Bfff", PATTERN_MODES.index(mode), pattern.frequency_hz,
                       pattern.retraction_rad, pattern.protraction_rad)


class _FrameAssembler:
    """Assembles whisk cycles from frames; shared by USBArray and SimArray."""

    def __init__(self, layout: FrameLayout, counters: USBCounters) -> None:
        self.layout = layout
        self.counters = counters
        self.expected_sequence: Optional[int] = None
        self.partial: list[Frame] = []
        self.resync = False

    def discard(self) -> None:
        if self.partial:
            self.counters.discarded_whisks += 1
        self.partial = []
        self.resync = True

    def feed(self, data: bytes) -> Optional[list[WhiskRecord]]:
        """Parse one transfer; return the records when it completes a whisk.
        On a frame fault, the partial whisk is discarded and the error raised."""
        c = self.counters
        try:
            frame = parse_frame(self.layout, data)
        except USBFrameError as exc:
            counter = ("short_frames" if isinstance(exc, ShortFrameError)
                       else "crc_errors" if isinstance(exc, CRCMismatchError) else "bad_headers")
            setattr(c, counter, getattr(c, counter) + 1)
            self.expected_sequence = None  # the frame's sequence number cannot be trusted
            self.discard()
            raise
        c.frames += 1
        c.bytes += len(data)
        expected = self.expected_sequence
        self.expected_sequence = (frame.sequence + 1) & 0xFFFFFFFF
        if expected is not None and frame.sequence != expected:
            lost = (frame.sequence - expected) & 0xFFFFFFFF
            c.sequence_gaps += 1
            c.lost_frames += lost
            self.discard()
            raise SequenceGapError(f"USB sequence gap: expected frame {expected}, got "
                                   f"{frame.sequence} ({lost} frames lost); whisk discarded", lost)
        if frame.index == 0:
            if self.partial:  # a new cycle began before the old one ended
                self.counters.discarded_whisks += 1
            self.partial = []
            self.resync = False
        elif self.resync or not self.partial or frame.whisk != self.partial[0].whisk \
                or frame.index != self.partial[-1].index + 1:
            c.skipped_frames += 1
            self.discard()
            return None
        self.partial.append(frame)
        if not frame.end_of_whisk:
            return None
        samples = np.concatenate([f.samples for f in self.partial], axis=0)
        whisk = self.partial[0].whisk
        self.partial = []
        c.whisks += 1
        return _records(self.layout, whisk, samples)


# ---------------------------------------------------------------- USBArray
class USBArray(Array):
    """The whisker array's FPGA over USB (pyusb).

    Parameters
    ----------
    layout : FrameLayout, optional
        Device ids and frame layout (defaults documented in the module).
    backend : usb.backend.IBackend, optional
        pyusb backend; default libusb1 found by pyusb. Tests pass
        :class:`~whisker_io.testing.fake_usb_backend.FakeUSBBackend`.
    timeout_ms : int
        Timeout of each bulk transfer in ms.

    Raises
    ------
    ConnectionFailedError
        No device with the layout's vendor/product id (or no USB backend).
    MissingDependencyError
        pyusb not installed (``pip install "cansim[hw]"``).

    Attributes
    ----------
    counters : USBCounters
        Frames, whisks and every fault seen so far.
    """

    def __init__(self, layout: Optional[FrameLayout] = None, *, backend: Any = None,
                 timeout_ms: int = 1000) -> None:
        self.layout = layout if layout is not None else FrameLayout()
        usb_core = require("usb.core", "USBArray")
        self._usb_core = usb_core
        self._usb_util = require("usb.util", "USBArray")
        self.timeout_ms = int(timeout_ms)
        self.counters = USBCounters()
        self._assembler = _FrameAssembler(self.layout, self.counters)
        ids = f"{self.layout.vendor_id:04x}:{self.layout.product_id:04x}"
        try:
            dev = usb_core.find(idVendor=self.layout.vendor_id, idProduct=self.layout.product_id,
                                backend=backend)
        except usb_core.NoBackendError as exc:
            raise ConnectionFailedError(f"no USB backend (libusb) available to open the whisker "
                                        f"array {ids}; install libusb-1.0") from exc
        if dev is None:
            raise ConnectionFailedError(f"no whisker array with USB id {ids} found; check the "
                                        "cable, power and udev permissions")
        self._dev = dev
        self._removed = False
        self._transfer(lambda: dev.set_configuration())
        self._transfer(lambda: self._usb_util.claim_interface(dev, self.layout.interface))

    def _transfer(self, fn: Callable[[], Any]) -> Any:
        if self._removed:
            raise DeviceRemovedError("the whisker array was unplugged; reconnect it and open a "
                                     "new USBArray")
        try:
            return fn()
        except self._usb_core.USBTimeoutError as exc:
            self.counters.timeouts += 1
            self._assembler.discard()
            raise DeviceTimeoutError(f"USB transfer timed out after {self.timeout_ms} ms; is the "
                                     "array powered and whisking?") from exc
        except self._usb_core.USBError as exc:
            if exc.errno == errno.ENODEV or exc.backend_error_code == _LIBUSB_ERROR_NO_DEVICE:
                self.counters.removals += 1
                self._removed = True
                self._assembler.discard()
                raise DeviceRemovedError("the whisker array was unplugged (USB device gone); "
                                         "every completed whisk is kept") from exc
            self._assembler.discard()
            raise HardwareError(f"USB I/O error: {exc}") from exc

    def read_whisk(self) -> list[WhiskRecord]:
        """Read frames until one whisk cycle is complete.

        Raises
        ------
        DeviceTimeoutError, DeviceRemovedError, ShortFrameError, CRCMismatchError,
        SequenceGapError, USBFrameError
            The partial whisk is discarded; the next call re-synchronises.
        """
        size = self.layout.max_frame_size
        while True:
            data = self._transfer(lambda: self._dev.read(self.layout.endpoint_in, size,
                                                         self.timeout_ms))
            records = self._assembler.feed(data)
            if records is not None:
                return records

    def _command(self, opcode: int, payload: bytes = b"") -> None:
        msg = encode_command(opcode, payload)
        self._transfer(lambda: self._dev.write(self.layout.endpoint_out, msg, self.timeout_ms))

    def set_pattern(self, pattern: WhiskPattern, mode: str = "open_loop") -> None:
        self._command(OP_SET_PATTERN, _pattern_payload(pattern, mode))

    def set_rcp_threshold(self, counts: float) -> None:
        self._command(OP_SET_RCP_THRESHOLD, struct.pack("<f", _check_threshold(counts)))

    def start(self) -> None:
        self._command(OP_START)

    def stop(self) -> None:
        self._command(OP_STOP)

    def close(self) -> None:
        """Release the interface and the device (safe after removal)."""
        try:
            self._usb_util.dispose_resources(self._dev)
        except Exception as exc:  # device may be gone already
            _LOG.debug("dispose_resources failed: %s", exc)


# ---------------------------------------------------------------- SimArray
class SimArray(Array):
    """Simulated array: whisks from a simulator, through the USB frame codec.

    Parameters
    ----------
    source : callable
        ``source(pose) -> samples`` with samples of shape (T, M, 3) (angle rad,
        x, y counts) in ``layout.modules`` order, or a list of M
        :class:`WhiskRecord` in that order (e.g. ``ArraySimulator.whisk``).
    pose_provider : callable
        Returns the current end-effector pose passed to ``source`` (e.g.
        ``arm.pose`` of a :class:`~whisker_io.hw.arm.SimArm`).
    layout : FrameLayout, optional
        Module names and quantisation (the simulator's whisks are quantised
        exactly as the FPGA's would be).

    Attributes
    ----------
    pattern : tuple of (WhiskPattern, str) or None
        Last commanded pattern and mode.
    rcp_threshold : float or None
        Last commanded RCP threshold (counts).
    """

    def __init__(self, source: Callable[[Any], Any], pose_provider: Callable[[], Any],
                 layout: Optional[FrameLayout] = None) -> None:
        self.layout = layout if layout is not None else FrameLayout()
        self._source = source
        self._pose_provider = pose_provider
        self.counters = USBCounters()
        self._assembler = _FrameAssembler(self.layout, self.counters)
        self._whisk = 0
        self._sequence = 0
        self.pattern: Optional[tuple[WhiskPattern, str]] = None
        self.rcp_threshold: Optional[float] = None

    @classmethod
    def from_simulator(cls, simulator: Any, target: Any, pose_provider: Callable[[], Any],
                       layout: Optional[FrameLayout] = None) -> "SimArray":
        """A SimArray whose whisks come from ``simulator.whisk(target, pose)``.

        Parameters
        ----------
        simulator : whisker_io.sim.simulator.ArraySimulator
            Seeded simulator (its controller does the whisking).
        target : trimesh.Trimesh or whisker_io.sim.sweep.MeshTarget
            The object, in the arm base frame.
        pose_provider : callable
            Returns the current :class:`~whisker_io.pose.Pose` (e.g. ``arm.pose``).
        """
        def source(pose: Any) -> Any:
            return list(simulator.whisk(target, pose).records)

        return cls(source, pose_provider, layout)

    def _samples(self, out: Any) -> np.ndarray:
        if isinstance(out, (list, tuple)) and out and isinstance(out[0], WhiskRecord):
            by_name = {r.module: r for r in out}
            missing = [m for m in self.layout.modules if m not in by_name]
            if missing:
                raise InvalidInputError(f"simulator gave no record for modules {missing}")
            return np.stack([np.column_stack([by_name[m].angle_rad, by_name[m].x_counts,
                                              by_name[m].y_counts])
                             for m in self.layout.modules], axis=1)
        return np.asarray(out, dtype=float)

    def read_whisk(self) -> list[WhiskRecord]:
        samples = self._samples(self._source(self._pose_provider()))
        frames = encode_frames(self.layout, self._whisk, samples, self._sequence)
        self._whisk += 1
        self._sequence = (self._sequence + len(frames)) & 0xFFFFFFFF
        records = None
        for data in frames:
            records = self._assembler.feed(data)
        if records is None:  # pragma: no cover - encode_frames always ends a whisk
            raise USBFrameError("simulated whisk did not complete")
        return records

    def set_pattern(self, pattern: WhiskPattern, mode: str = "open_loop") -> None:
        """Record the pattern (the simulator's own controller does the whisking)."""
        _pattern_payload(pattern, mode)
        self.pattern = (pattern, mode)

    def set_rcp_threshold(self, counts: float) -> None:
        self.rcp_threshold = _check_threshold(counts)
