"""A pyusb backend that impersonates the whisker array's FPGA, for tests.

:class:`FakeUSBBackend` subclasses :class:`usb.backend.IBackend`, so the
*unmodified* :class:`~whisker_io.hw.usb_array.USBArray` runs against it via
``usb.core.find(..., backend=FakeUSBBackend(...))``. It serves a device
descriptor with the layout's vendor/product id, one configuration, one
interface with a bulk-in and a bulk-out endpoint, and bulk-in frames encoded
with :func:`~whisker_io.hw.usb_array.encode_frames` in the documented layout.

Faults are injected into the stream of bulk-in transfers with
:meth:`FakeUSBBackend.inject`:

* ``"timeout"``: the next read raises ``usb.core.USBTimeoutError``;
* ``"short"``: the next frame is truncated to half its length;
* ``"gap"``: the next frame is dropped (the host sees a sequence jump);
* ``"crc"``: one byte of the next frame's samples is flipped;
* ``"remove"``: the device disappears: this and every later call raises
  ``usb.core.USBError`` with ``errno.ENODEV`` (as libusb does).
"""

from __future__ import annotations

import array
import errno
from collections import deque
from types import SimpleNamespace
from typing import Any, Callable, Optional

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.hw.optional import require

require("usb", "the fake USB backend (it subclasses pyusb's backend)")  # a base install: say what to install
import usb.backend  # noqa: E402
import usb.core  # noqa: E402

from whisker_io.hw.usb_array import FrameLayout, encode_frames, parse_command

__all__ = ["FakeUSBBackend", "FAULTS"]

#: Fault kinds accepted by :meth:`FakeUSBBackend.inject`.
FAULTS = ("timeout", "short", "gap", "crc", "remove")

_BULK = 0x02


class FakeUSBBackend(usb.backend.IBackend):
    """In-memory pyusb backend serving one fake whisker array.

    Parameters
    ----------
    layout : FrameLayout, optional
        Device ids and frame layout.
    source : callable, optional
        ``source(whisk_index) -> samples (T, M, 3)`` called whenever the
        frame queue runs dry, to stream whisks on demand. Without it, reads
        on an empty queue time out (a device that is not streaming).

    Attributes
    ----------
    commands : list of (int, bytes)
        Parsed commands written by the host, ``(opcode, payload)``.
    removed : bool
        True once a ``"remove"`` fault fired.
    """

    def __init__(self, layout: Optional[FrameLayout] = None,
                 source: Optional[Callable[[int], np.ndarray]] = None) -> None:
        super().__init__()
        self.layout = layout if layout is not None else FrameLayout()
        self.source = source
        self._queue: deque[Any] = deque()
        self._whisk = 0
        self._sequence = 0
        self.commands: list[tuple[int, bytes]] = []
        self.removed = False
        self._config = 0
        self._device = SimpleNamespace(
            bLength=18, bDescriptorType=1, bcdUSB=0x0200, bDeviceClass=0xFF,
            bDeviceSubClass=0, bDeviceProtocol=0, bMaxPacketSize0=64,
            idVendor=self.layout.vendor_id, idProduct=self.layout.product_id,
            bcdDevice=0x0100, iManufacturer=0, iProduct=0, iSerialNumber=0,
            bNumConfigurations=1, address=1, bus=1, port_number=1, port_numbers=(1,),
            speed=3)

    # -------------------------------------------------------------- feeding
    def queue_whisk(self, samples: np.ndarray) -> int:
        """Encode one whisk cycle (T, M, 3) into frames and queue them.
        Returns the number of frames queued."""
        frames = encode_frames(self.layout, self._whisk, samples, self._sequence)
        self._whisk += 1
        self._sequence = (self._sequence + len(frames)) & 0xFFFFFFFF
        self._queue.extend(frames)
        return len(frames)

    def inject(self, fault: str, after_frames: int = 0) -> None:
        """Insert a fault before the ``after_frames``-th queued frame from now.

        Raises
        ------
        InvalidInputError
            Unknown fault kind or position beyond the queue.
        """
        if fault not in FAULTS:
            raise InvalidInputError(f"fault must be one of {FAULTS}; got {fault!r}")
        positions = [i for i, item in enumerate(self._queue) if isinstance(item, bytes)]
        if after_frames > len(positions):
            raise InvalidInputError(f"only {len(positions)} frames queued; cannot inject after "
                                    f"{after_frames}")
        index = positions[after_frames] if after_frames < len(positions) else len(self._queue)
        self._queue.insert(index, fault)

    @property
    def frames_queued(self) -> int:
        return sum(isinstance(item, bytes) for item in self._queue)

    # -------------------------------------------------------------- helpers
    def _check_present(self) -> None:
        if self.removed:
            raise usb.core.USBError("No such device (it may have been disconnected)",
                                    error_code=-4, errno=errno.ENODEV)

    def _next_frame(self) -> Optional[bytes]:
        if not self._queue and self.source is not None:
            self.queue_whisk(self.source(self._whisk))
        while self._queue:
            item = self._queue.popleft()
            if isinstance(item, bytes):
                return item
            if item == "timeout":
                raise usb.core.USBTimeoutError("Operation timed out", error_code=-7,
                                               errno=errno.ETIMEDOUT)
            if item == "remove":
                self.removed = True
                self._check_present()
            nxt = self._next_frame()
            if nxt is None:
                return None
            if item == "short":
                return nxt[: len(nxt) // 2]
            if item == "crc":
                b = bytearray(nxt)
                b[len(b) // 2] ^= 0xFF
                return bytes(b)
            if item == "gap":
                return self._next_frame()
        return None

    # ------------------------------------------------------- IBackend API
    def enumerate_devices(self):
        if not self.removed:
            yield "whisker-array-0"

    def get_device_descriptor(self, dev):
        return self._device

    def get_configuration_descriptor(self, dev, config):
        return SimpleNamespace(bLength=9, bDescriptorType=2, wTotalLength=32, bNumInterfaces=1,
                               bConfigurationValue=1, iConfiguration=0, bmAttributes=0x80,
                               bMaxPower=50, extra_descriptors=[])

    def get_interface_descriptor(self, dev, intf, alt, config):
        return SimpleNamespace(bLength=9, bDescriptorType=4,
                               bInterfaceNumber=self.layout.interface, bAlternateSetting=0,
                               bNumEndpoints=2, bInterfaceClass=0xFF, bInterfaceSubClass=0,
                               bInterfaceProtocol=0, iInterface=0, extra_descriptors=[])

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        address = (self.layout.endpoint_in, self.layout.endpoint_out)[ep]
        return SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=address,
                               bmAttributes=_BULK, wMaxPacketSize=512, bInterval=0, bRefresh=0,
                               bSynchAddress=0, extra_descriptors=[])

    def open_device(self, dev):
        self._check_present()
        return dev

    def close_device(self, dev_handle):
        pass

    def set_configuration(self, dev_handle, config_value):
        self._check_present()
        self._config = config_value

    def get_configuration(self, dev_handle):
        self._check_present()
        return self._config

    def claim_interface(self, dev_handle, intf):
        self._check_present()

    def release_interface(self, dev_handle, intf):
        pass

    def is_kernel_driver_active(self, dev_handle, intf):
        return False

    def bulk_write(self, dev_handle, ep, intf, data, timeout):
        self._check_present()
        self.commands.append(parse_command(bytes(data)))
        return len(data)

    def bulk_read(self, dev_handle, ep, intf, buff, timeout):
        self._check_present()
        frame = self._next_frame()
        if frame is None:
            raise usb.core.USBTimeoutError("Operation timed out", error_code=-7,
                                           errno=errno.ETIMEDOUT)
        n = min(len(frame), len(buff))
        buff[:n] = array.array("B", frame[:n])
        return n
