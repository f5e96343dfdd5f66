"""SimArm, and URArm against ur-rtde's real client (the Pose type itself: test_pose.py).

The receive path uses the unmodified ``rtde_receive.RTDEReceiveInterface``
talking to the fake RTDE server in a child process on 127.0.0.1 (ur-rtde's
fixed port 30004); the control path uses an injected fake. Nothing but
127.0.0.1 is contacted.
"""

from __future__ import annotations

import math
import socket
import sys
import time

import numpy as np
import pytest

from whisker_io.errors import (ConnectionFailedError, HardwareError, InvalidInputError,
                               SafetyViolationError, StaleStateError)
from whisker_io.hw import MissingDependencyError
from whisker_io.hw import arm as arm_module
from whisker_io.hw.arm import CommandFailedError, SimArm, URArm, probe_rtde
from whisker_io.testing.fake_rtde_server import (FakeControlInterface, FakeReceiveInterface,
                                            FakeServerError, fake_rtde_server)
from whisker_io.pose import Pose

HOST = "127.0.0.1"


# ---------------------------------------------------------------- SimArm
def down(x, y, z):
    return Pose([x, y, z], [1.0, 0.0, 0.0, 0.0])


def test_simarm_instant_move():
    arm = SimArm(down(0.4, 0.0, 0.4))
    target = down(0.4, 0.05, 0.4)
    assert arm.move_linear(target, 0.05, 0.2) is target
    assert arm.pose() == target
    assert [c.kind for c in arm.received] == ["moveL"]


def test_simarm_rate_limited_takes_distance_over_speed():
    arm = SimArm(down(0.4, 0.0, 0.4), rate_limited=True, control_period=0.01)
    arm.move_linear(down(0.4, 0.05, 0.4), speed=0.1)
    assert arm.time == pytest.approx(0.5)  # 5 cm at 0.1 m/s
    times = np.array([t for t, _ in arm.trajectory])
    ys = np.array([p.position_m[1] for _, p in arm.trajectory])
    assert np.all(np.diff(times) > 0)
    assert np.all(np.diff(ys) / np.diff(times) <= 0.1 + 1e-9)  # never faster than commanded
    assert np.allclose([p.position_m[[0, 2]] for _, p in arm.trajectory], [0.4, 0.4])
    assert len(arm.trajectory) == 51


def test_simarm_refuses_outside_start_and_after_close():
    with pytest.raises(InvalidInputError, match="inside the envelope"):
        SimArm(down(2.0, 0.0, 0.4))
    arm = SimArm()
    arm.close()
    with pytest.raises(ConnectionFailedError, match="closed"):
        arm.move_linear(down(0.4, 0.0, 0.4))


# ------------------------------------------------- URArm with injected fakes
def injected_arm(receive=None, control=None):
    receive = receive or FakeReceiveInterface()
    control = control or FakeControlInterface()
    arm = URArm(HOST, receive_factory=lambda h: receive, control_factory=lambda h: control)
    return arm, receive, control


def test_urarm_sends_converted_pose_and_refuses_unsafe():
    arm, _, ctl = injected_arm()
    target = Pose.from_ur([0.4, 0.02, 0.4, 0.0, math.pi, 0.0])
    arm.move_linear(target, 0.05, 0.3)
    assert ctl.calls == [("moveL", (target.as_ur(), 0.05, 0.3, False))]
    with pytest.raises(SafetyViolationError):
        arm.move_linear([0.4, 0.02, 5.0, 0.0, math.pi, 0.0], 0.05, 0.3)
    assert len(ctl.calls) == 1


def test_urarm_controller_refusal_is_typed():
    arm, _, _ = injected_arm(control=FakeControlInterface(ok=False))
    with pytest.raises(CommandFailedError, match="protective stop"):
        arm.move_linear([0.4, 0.02, 0.4, 0.0, math.pi, 0.0], 0.05, 0.3)


def test_urarm_stale_injected_within_1s_and_stops():
    arm, rx, ctl = injected_arm()
    arm.state()
    rx.frozen = True
    t0 = time.monotonic()
    n_ok = 0
    with pytest.raises(StaleStateError, match="stalled or dropped"):
        while True:  # a control loop polling the state
            arm.state()
            n_ok += 1
    elapsed = time.monotonic() - t0
    assert n_ok > 0  # a state younger than staleness_timeout is still accepted
    assert 0.9 * arm.envelope.staleness_timeout <= elapsed < 1.0
    assert ("stopL", (arm.stop_deceleration, False)) in ctl.calls


def test_urarm_observed_joint_overspeed_stops_arm():
    arm, rx, ctl = injected_arm()
    rx.qd = [0.0, 0.125, 0.0, 0.0, 0.0, 0.0]  # 0.1 rad/s x 1.25 tolerance: still allowed
    arm.state()
    rx.qd = [0.0, 0.0, -0.13, 0.0, 0.0, 0.0]
    with pytest.raises(SafetyViolationError, match="joint speeds"):
        arm.state()
    assert any(name == "stopL" for name, _ in ctl.calls)
    assert ctl.motions() == []


def test_urarm_link_down_is_connection_error():
    arm, rx, ctl = injected_arm()
    rx.connected = False
    with pytest.raises(ConnectionFailedError, match="link .* is down"):
        arm.move_linear([0.4, 0.0, 0.4, 0.0, math.pi, 0.0])
    assert ctl.motions() == []


def test_urarm_read_only_refuses_commands():
    rx = FakeReceiveInterface()
    arm = URArm(HOST, receive_factory=lambda h: rx, control=False)
    assert np.allclose(arm.pose().position_m, [0.4, 0.0, 0.4])
    with pytest.raises(CommandFailedError, match="read-only"):
        arm.move_linear([0.4, 0.0, 0.4, 0.0, math.pi, 0.0])


def test_urarm_missing_ur_rtde_names_hw_extra(monkeypatch):
    monkeypatch.setattr(arm_module, "probe_rtde", lambda *a, **k: None)
    monkeypatch.setitem(sys.modules, "rtde_receive", None)
    with pytest.raises(MissingDependencyError, match=r'pip install "cansim\[hw\]"'):
        URArm(HOST)


# --------------------------------------------- real ur-rtde vs fake server
def free_port():
    with socket.socket() as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


@pytest.fixture
def rtde_server(request):
    pytest.importorskip("rtde_receive", reason='the URArm client needs the hw extra (ur-rtde): pip install -e ".[hw]"')
    mode = getattr(request, "param", "stream")
    try:
        with fake_rtde_server(mode) as (proc, port):
            yield proc
    except FakeServerError as exc:
        pytest.skip(f"cannot run the fake RTDE server on port 30004: {exc}")


def test_nothing_listening_fails_fast():
    port = free_port()  # bound then released: nothing listens there
    t0 = time.monotonic()
    with pytest.raises(ConnectionFailedError, match="cannot connect"):
        probe_rtde(HOST, port, timeout=0.5)
    assert time.monotonic() - t0 < 0.5


def test_silent_server_caught_by_probe():
    with fake_rtde_server("silent", port=0) as (_, port):
        t0 = time.monotonic()
        with pytest.raises(ConnectionFailedError, match="did not answer within 0.3 s"):
            probe_rtde(HOST, port, timeout=0.3)
        assert time.monotonic() - t0 < 1.0


@pytest.mark.parametrize("rtde_server", ["silent"], indirect=True)
def test_urarm_on_silent_controller_fails_fast_instead_of_hanging(rtde_server):
    t0 = time.monotonic()
    with pytest.raises(ConnectionFailedError, match="did not answer"):
        URArm(HOST, probe_timeout=0.3, control=False)
    assert time.monotonic() - t0 < 1.0


def test_urarm_streams_poses_from_real_ur_rtde_client(rtde_server):
    arm = URArm(HOST, control=False)
    try:
        s1 = arm.state()
        deadline = time.monotonic() + 1.0
        s2 = arm.state()
        while s2.timestamp == s1.timestamp and time.monotonic() < deadline:
            s2 = arm.state()
        assert s2.timestamp > s1.timestamp
        for s in (s1, s2):
            # the fake robot moves on a 5 cm circle about (0.4, 0, 0.4), tool down
            assert np.hypot(s.pose.position_m[0] - 0.4, s.pose.position_m[1]) == pytest.approx(0.05)
            assert s.pose.position_m[2] == pytest.approx(0.4)
            assert np.allclose(s.pose.tool_axis(), [0, 0, -1])
            assert s.q.shape == (6,) and s.qd.shape == (6,)
    finally:
        arm.close()


def test_killed_server_raises_typed_error_within_1s_and_stops(rtde_server):
    ctl = FakeControlInterface()
    arm = URArm(HOST, control_factory=lambda h: ctl)
    try:
        arm.state()
        rtde_server.kill()
        t0 = time.monotonic()
        with pytest.raises((ConnectionFailedError, StaleStateError)):
            while time.monotonic() - t0 < 5.0:
                arm.state()
        assert time.monotonic() - t0 < 1.0
        assert any(c[0] == "stopL" for c in ctl.calls)
    finally:
        arm.close()


@pytest.mark.parametrize("rtde_server", ["freeze"], indirect=True)
def test_stalled_stream_detected_from_timestamps(rtde_server):
    """The socket stays open but no data comes: only the timestamps tell."""
    arm = URArm(HOST, control=False)
    try:
        t0 = time.monotonic()
        with pytest.raises(StaleStateError):
            while time.monotonic() - t0 < 5.0:
                arm.state()
        # 50 packages at 500 Hz stream for 0.1 s, then staleness_timeout (0.25 s)
        assert time.monotonic() - t0 < 1.0
    finally:
        rtde_server.kill()  # ends ur-rtde's blocked read so close() returns at once
        arm.close()


def test_hardware_errors_share_a_base():
    for cls in (ConnectionFailedError, StaleStateError, SafetyViolationError,
                CommandFailedError, MissingDependencyError):
        assert issubclass(cls, HardwareError)


def test_fake_server_waits_for_the_rtde_port_to_be_released():
    """ur-rtde only uses port 30004: a launch while another listener still holds it retries."""
    import threading

    from whisker_io.testing.fake_rtde_server import RTDE_PORT, fake_rtde_server

    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    holder.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        holder.bind((HOST, RTDE_PORT))
    except OSError:
        holder.close()
        pytest.skip("port 30004 is in use on this machine")
    holder.listen()
    release = threading.Timer(0.4, holder.close)
    release.start()
    try:
        t0 = time.monotonic()
        with fake_rtde_server("stream") as (proc, port):
            assert port == RTDE_PORT and proc.poll() is None
            assert time.monotonic() - t0 >= 0.3  # it really had to wait for the release
    finally:
        release.cancel()
        holder.close()


@pytest.mark.parametrize("z", [0.05, 0.07, 0.1])
def test_simarm_interpolated_poses_keep_the_limits_their_ends_keep(z):
    """Between two targets on the envelope's floor (z = 0.05) the simulated poses stayed at 0.049999... (issue 25)."""
    arm = SimArm(down(0.31, -0.17, z), rate_limited=True, control_period=0.003)
    for target in (down(0.43, 0.29, z), down(0.17, 0.07, z), down(0.41, -0.33, z)):
        arm.move_linear(target, speed=0.07)
    zs = np.array([p.position_m[2] for _, p in arm.trajectory])
    assert len(zs) > 100 and np.all(zs == z)  # exactly: both ends are at z


@pytest.mark.parametrize("speed", [5e-324, 1e-300, 1e-7])
def test_a_denormal_or_glacial_speed_is_refused_not_overflowed(speed):
    """A denormal speed reached int(ceil(inf)) in the simulated arm (OverflowError; issue 25)."""
    arm = SimArm(down(0.4, 0.0, 0.4), rate_limited=True, control_period=0.01)
    before = (arm.pose(), arm.time, len(arm.received))
    with pytest.raises(SafetyViolationError, match="TCP speed"):
        arm.move_linear(down(0.4, 0.05, 0.4), speed=speed)
    assert (arm.pose(), arm.time, len(arm.received)) == before
