"""whisker_io.hw.platform: the arm and the array connected in order, failures named by device."""

from __future__ import annotations

import importlib.util

import pytest

from whisker_io.errors import (ArrayNotFoundError, CommandFailedError, ConnectionFailedError, HardwareError,
                               MissingDependencyError, RobotUnreachableError, SafetyViolationError)
from whisker_io.hw.platform import (EXIT_NO_ARRAY, EXIT_NO_EXTRA, EXIT_NO_ROBOT, EXIT_STOPPED, open_platform,
                                    session_failure)
from whisker_io.hw.safety import SafetyEnvelope

needs_hw = pytest.mark.skipif(importlib.util.find_spec("rtde_receive") is None or importlib.util.find_spec("usb") is None,
                              reason='needs the hw extra (pip install -e ".[hw]")')


def test_session_failure_maps_each_device_to_its_status():
    assert session_failure(MissingDependencyError("pip install cansim[hw]"), 0) == (EXIT_NO_EXTRA, "pip install cansim[hw]")
    assert session_failure(RobotUnreachableError("no robot reachable at 10.0.0.2"), 0)[0] == EXIT_NO_ROBOT
    assert session_failure(ArrayNotFoundError("no whisker array found"), 0)[0] == EXIT_NO_ARRAY
    for exc in (SafetyViolationError("tilt"), CommandFailedError("moveL"), ConnectionFailedError("lost")):
        status, message = session_failure(exc, 7)
        assert status == EXIT_STOPPED and message.startswith(f"stopped after 7 whisks ({type(exc).__name__})")
    assert len({EXIT_NO_ROBOT, EXIT_NO_ARRAY, EXIT_STOPPED, EXIT_NO_EXTRA} | {0, 1, 2}) == 7


@needs_hw
def test_no_robot_is_named_and_nothing_stays_open():
    # 127.0.0.3: loopback where nothing listens
    with pytest.raises(RobotUnreachableError, match="127.0.0.3"):
        with open_platform("127.0.0.3", SafetyEnvelope()):
            pytest.fail("the block must not run")


@needs_hw
def test_no_array_is_named_after_the_arm_connected():
    from whisker_io.testing.fake_rtde_server import FakeControlInterface, FakeServerError, fake_rtde_server
    from whisker_io.testing.fake_usb_backend import FakeUSBBackend

    control = FakeControlInterface()
    backend = FakeUSBBackend()
    backend.removed = True  # nothing on the bus
    try:
        with fake_rtde_server("stream"):
            with pytest.raises(ArrayNotFoundError, match="no whisker array"):
                with open_platform("127.0.0.1", SafetyEnvelope(), control_factory=lambda h: control, usb_backend=backend):
                    pytest.fail("the block must not run")
            # with a device present the block runs and an error inside it propagates unchanged
            backend.removed = False
            with pytest.raises(SafetyViolationError):
                with open_platform("127.0.0.1", SafetyEnvelope(), control_factory=lambda h: control,
                                   usb_backend=backend) as (arm, array):
                    assert arm is not None and array.layout is not None
                    raise SafetyViolationError("refused")
    except FakeServerError as exc:
        pytest.skip(f"cannot run the fake RTDE server on port 30004: {exc}")
    assert issubclass(RobotUnreachableError, HardwareError) and issubclass(ArrayNotFoundError, ConnectionFailedError)
