"""Test doubles of the hardware, for tests and examples (not needed to use the library).

* :mod:`whisker_io.testing.fake_rtde_server` - a local RTDE server that the real
  ur-rtde client connects to, standing in for a UR controller's receive side (the
  robot states); the commands go to its :class:`~whisker_io.testing.fake_rtde_server.FakeControlInterface`,
  given in process (``hardware_exploration.main(argv, control_factory=lambda host: FakeControlInterface(),
  usb_backend=FakeUSBBackend(...))``; ``tests/test_hardware_exploration.py`` runs it so). The
  dashboard and control sides are not served, so ``--robot-ip 127.0.0.1`` on its own finds no robot;
* :mod:`whisker_io.testing.fake_usb_backend` - a pyusb-shaped backend the
  unmodified :class:`~whisker_io.hw.usb_array.USBArray` reads frames from.

They live in this explicit subpackage so that the drivers in :mod:`whisker_io.hw`
contain only code that talks to real devices.
"""
