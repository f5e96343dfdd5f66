"""USB frame layout, USBArray on a fake pyusb backend, injected faults.

The unmodified USBArray runs against FakeUSBBackend (a usb.backend.IBackend
subclass) through pyusb's own usb.core; no real device is touched.
"""

from __future__ import annotations

import binascii
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whisker_io.array.control import WhiskPattern
from whisker_io.errors import (ConnectionFailedError, DeviceRemovedError, DeviceTimeoutError,
                               HardwareError, InvalidInputError, USBFrameError)
from whisker_io.array.geometry import WhiskerArray
from whisker_io.hw.arm import SimArm
pytest.importorskip("usb", reason='the USB array tests need the hw extra (pyusb): pip install -e ".[hw]"')
from whisker_io.testing.fake_usb_backend import FakeUSBBackend  # noqa: E402
from whisker_io.pose import Pose
from whisker_io.hw.recorder import Recorder, explore
from whisker_io.hw.usb_array import (OP_SET_PATTERN, OP_SET_RCP_THRESHOLD, OP_START, OP_STOP,
                                     CRCMismatchError, FrameLayout, SequenceGapError,
                                     ShortFrameError, SimArray, USBArray, encode_command,
                                     encode_frames, parse_command, parse_frame)
from whisker_io.records.recording import read_pose_log, replay

LAYOUT = FrameLayout()
M = 18
T = 2000                      # one 1-Hz whisk at 2 kHz
FRAMES_PER_WHISK = T // 100   # samples_per_frame = 100


def whisk_samples(k: int) -> np.ndarray:
    """A recognisable whisk: angle ramp, x = module index, y = k*100 + sample % 7."""
    s = np.zeros((T, M, 3))
    s[:, :, 0] = np.linspace(-0.8727, 0.8727, T)[:, None]
    s[:, :, 1] = np.arange(M)[None, :]
    s[:, :, 2] = k * 100 + (np.arange(T) % 7)[:, None]
    return s


def quantised(s: np.ndarray) -> np.ndarray:
    q = s.copy()
    q[..., 0] = np.rint(q[..., 0] / 1e-4) * 1e-4
    return q


# ------------------------------------------------------------------ codec
def test_frame_size_and_header_bytes_hand_computed():
    frames = encode_frames(LAYOUT, whisk=7, samples=whisk_samples(0), first_sequence=41)
    assert len(frames) == FRAMES_PER_WHISK
    assert all(len(f) == 20 + 6 * 100 * 18 + 4 for f in frames)  # 10,824 bytes
    f = frames[1]
    assert f[:2] == b"WK" and f[2] == 1 and f[3] == 18
    assert struct.unpack_from("<IIHHB", f, 4) == (42, 7, 1, 100, 0)
    assert frames[-1][16] == 0x01  # END_OF_WHISK on the last frame only
    # first sample of frame 1 is sample 100: angle, x of module 0, y
    angle, x, y = struct.unpack_from("<hhh", f, 20)
    assert (x, y) == (0, 100 % 7)
    assert angle == round(np.linspace(-0.8727, 0.8727, T)[100] / 1e-4)


def test_parse_round_trip_quantises_angle_only():
    s = whisk_samples(3)
    frames = encode_frames(LAYOUT, 0, s, 0)
    got = np.concatenate([parse_frame(LAYOUT, f).samples for f in frames])
    assert np.array_equal(got, quantised(s))
    assert np.max(np.abs(got[..., 0] - s[..., 0])) <= 0.5e-4 + 1e-12


def test_crc_algorithms_are_the_documented_ones():
    # standard check values of CRC-32 and CRC-16/CCITT-FALSE over "123456789"
    import zlib
    assert zlib.crc32(b"123456789") == 0xCBF43926
    assert binascii.crc_hqx(b"123456789", 0xFFFF) == 0x29B1
    cmd = encode_command(OP_START)
    assert cmd[:4] == b"WC\x03\x00"
    assert struct.unpack("<H", cmd[4:])[0] == binascii.crc_hqx(b"WC\x03\x00", 0xFFFF)
    assert parse_command(cmd) == (OP_START, b"")
    with pytest.raises(CRCMismatchError):
        parse_command(cmd[:-1] + bytes([cmd[-1] ^ 1]))


@pytest.mark.parametrize("mutate,error", [
    (lambda f: f[:10], ShortFrameError),
    (lambda f: f[:-7], ShortFrameError),
    (lambda f: f + b"\x00", USBFrameError),
    (lambda f: b"XX" + f[2:], USBFrameError),
    (lambda f: f[:3] + b"\x11" + f[4:], USBFrameError),  # 17 modules
    (lambda f: f[:500] + bytes([f[500] ^ 0x10]) + f[501:], CRCMismatchError),
])
def test_parser_rejects_damaged_frames(mutate, error):
    f = encode_frames(LAYOUT, 0, whisk_samples(0), 0)[0]
    with pytest.raises(error):
        parse_frame(LAYOUT, mutate(f))


# --------------------------------------------------------------- USBArray
def open_array(n_whisks=0, source=None, timeout_ms=50):
    backend = FakeUSBBackend(LAYOUT, source=source)
    for k in range(n_whisks):
        backend.queue_whisk(whisk_samples(k))
    return USBArray(LAYOUT, backend=backend, timeout_ms=timeout_ms), backend


def test_usb_array_reads_whisks_as_records():
    arr, _ = open_array(2)
    for k in range(2):
        recs = arr.read_whisk()
        assert [r.module for r in recs] == list(WhiskerArray.thesis().names)
        q = quantised(whisk_samples(k))
        for m, r in enumerate(recs):
            assert r.cycle == k and r.n_samples == T and r.sample_rate_hz == 2000.0
            assert np.array_equal(r.angle_rad, q[:, m, 0])
            assert np.array_equal(r.x_counts, q[:, m, 1])
            assert np.array_equal(r.y_counts, q[:, m, 2])
    c = arr.counters
    assert (c.frames, c.whisks, c.bytes) == (40, 2, 40 * 10824)
    assert (c.timeouts, c.short_frames, c.sequence_gaps, c.crc_errors) == (0, 0, 0, 0)


def test_commands_reach_device_with_documented_payloads():
    arr, backend = open_array()
    arr.set_rcp_threshold(500)
    pattern = WhiskPattern(frequency_hz=2.0)
    arr.set_pattern(pattern, "retract_on_max")
    arr.start()
    (op1, p1), (op2, p2), (op3, p3) = backend.commands
    assert op1 == OP_SET_RCP_THRESHOLD and struct.unpack("<f", p1) == (500.0,)
    mode, freq, retr, prot = struct.unpack("<Bfff", p2)
    assert op2 == OP_SET_PATTERN and (mode, freq) == (2, 2.0)
    assert retr == pytest.approx(np.deg2rad(-50)) and prot == pytest.approx(np.deg2rad(50))
    assert (op3, p3) == (OP_START, b"")
    with pytest.raises(InvalidInputError):
        arr.set_rcp_threshold(float("nan"))
    with pytest.raises(InvalidInputError):
        arr.set_pattern(pattern, "wiggle")
    assert len(backend.commands) == 3


def test_missing_device_is_a_typed_error_naming_ids():
    backend = FakeUSBBackend(FrameLayout(vendor_id=0x1234, product_id=0x0001))
    with pytest.raises(ConnectionFailedError, match="1209:5748"):
        USBArray(LAYOUT, backend=backend)


FAULTS = {
    # fault: (typed error, the counter that counts it)
    "timeout": (DeviceTimeoutError, "timeouts"),
    "short": (ShortFrameError, "short_frames"),
    "gap": (SequenceGapError, "sequence_gaps"),
    "crc": (CRCMismatchError, "crc_errors"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_fault_mid_whisk_raises_counts_and_resyncs(fault):
    error, counter = FAULTS[fault]
    arr, backend = open_array(3)
    backend.inject(fault, after_frames=FRAMES_PER_WHISK + 7)  # inside whisk 1
    assert arr.read_whisk()[0].cycle == 0
    with pytest.raises(error):
        arr.read_whisk()
    assert getattr(arr.counters, counter) == 1
    assert arr.counters.discarded_whisks == 1
    recs = arr.read_whisk()  # whisk 1 is dropped whole, whisk 2 arrives complete
    assert recs[0].cycle == 2 and recs[0].n_samples == T
    assert np.array_equal(recs[5].y_counts, quantised(whisk_samples(2))[:, 5, 2])
    if fault == "gap":
        assert arr.counters.lost_frames == 1
    assert arr.counters.whisks == 2


def test_removal_is_permanent_and_typed():
    arr, backend = open_array(2)
    backend.inject("remove", after_frames=FRAMES_PER_WHISK + 3)
    arr.read_whisk()
    with pytest.raises(DeviceRemovedError, match="unplugged"):
        arr.read_whisk()
    with pytest.raises(DeviceRemovedError):
        arr.read_whisk()
    with pytest.raises(DeviceRemovedError):
        arr.set_rcp_threshold(100)
    assert arr.counters.removals == 1
    arr.close()  # safe after removal


def test_idle_device_times_out():
    arr, _ = open_array(0)
    with pytest.raises(DeviceTimeoutError, match="timed out after 50 ms"):
        arr.read_whisk()
    assert arr.counters.timeouts == 1


# ---------------------------------------------- faults with the recorder
def targets(n):
    return [Pose([0.4, -0.1 + 0.01 * k, 0.4], [1.0, 0.0, 0.0, 0.0]) for k in range(n)]


@pytest.mark.parametrize("fault,retries", [("timeout", 2), ("remove", 2), ("short", 0), ("gap", 0), ("crc", 0)])
def test_fault_during_session_leaves_only_complete_whisks(tmp_path, fault, retries):
    """A timeout or an unplugged array ends the session; so does a frame fault with no retakes (frame_retries=0)."""
    arr, backend = open_array(6)
    backend.inject(fault, after_frames=3 * FRAMES_PER_WHISK + 11)  # inside whisk 3
    arm = SimArm()
    with pytest.raises(HardwareError):
        with Recorder(tmp_path) as rec:
            explore(arm, arr, rec, targets(6), progress=False, frame_retries=retries)
    assert rec.closed and rec.n_cycles == 3
    assert arm.received[-1].kind == "stop"
    # exactly the 3 complete cycles are on disk, 18 files each, nothing partial
    assert len(read_pose_log(tmp_path / "pose_log.csv")) == 3
    names = sorted(p.name for p in tmp_path.iterdir())
    assert len([n for n in names if n.startswith("whisk_")]) == 3 * M
    assert not [n for n in names if n.endswith(".tmp") or n.startswith(".")]
    cycles = list(replay(tmp_path))
    for k, cyc in enumerate(cycles):
        assert np.array_equal(cyc.records["C2"].y_counts, quantised(whisk_samples(k))[:, 12, 2])
    counter = FAULTS.get(fault, (None, "removals"))[1]
    assert getattr(arr.counters, counter) == 1


@pytest.mark.parametrize("fault", ["short", "gap", "crc"])
def test_a_frame_fault_in_a_session_retakes_the_whisk_at_the_same_pose(tmp_path, fault, caplog):
    """One USB glitch ended the session (a robot lab's pass, session 48): the whisk in progress is discarded and
    taken again where the arm stands; the session goes on with every pose recorded."""
    arr, backend = open_array(7)
    backend.inject(fault, after_frames=3 * FRAMES_PER_WHISK + 11)  # inside whisk 3
    arm = SimArm()
    with caplog.at_level("WARNING"), Recorder(tmp_path) as rec:
        assert explore(arm, arr, rec, targets(6), progress=False) == 6
    assert "taking it again (retake 1 of 2)" in caplog.text
    cycles = list(replay(tmp_path))
    sent = [k for k in range(7) if k != 3]  # whisk 3 lost, whisk 4 taken at pose 3
    assert len(cycles) == 6
    for cyc, k in zip(cycles, sent):
        assert np.array_equal(cyc.records["C2"].y_counts, quantised(whisk_samples(k))[:, 12, 2])
    np.testing.assert_allclose([c.entry.pose.position_m for c in cycles], [t.position_m for t in targets(6)])
    assert getattr(arr.counters, FAULTS[fault][1]) == 1


def test_frame_faults_beyond_the_retakes_are_raised_and_bad_counts_refused():
    arr, backend = open_array(4)
    for whisk in (0, 1):  # a fault inside whisks 0 and 1: one retake is not enough, two are
        backend.inject("crc", after_frames=whisk * FRAMES_PER_WHISK + 5 + whisk)
    with pytest.raises(CRCMismatchError):
        arr.read_whisk_retrying(1)
    arr2, backend2 = open_array(4)
    for whisk in (0, 1):
        backend2.inject("crc", after_frames=whisk * FRAMES_PER_WHISK + 5 + whisk)
    assert arr2.read_whisk_retrying(2)[0].cycle == 2
    arr3, backend3 = open_array(2)
    backend3.inject("timeout", after_frames=3)
    with pytest.raises(DeviceTimeoutError):  # no transient frame fault: raised at once
        arr3.read_whisk_retrying(5)
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(InvalidInputError, match="retries must be a count"):
            arr3.read_whisk_retrying(bad)


# ---------------------------------------------------------------- SimArray
def test_sim_array_goes_through_the_same_codec():
    arm = SimArm()
    seen = []

    def source(pose):
        seen.append(pose)
        return whisk_samples(len(seen) - 1)

    arr = SimArray(source, arm.pose)
    recs = arr.read_whisk()
    assert seen == [arm.pose()]
    assert np.array_equal(recs[3].angle_rad, quantised(whisk_samples(0))[:, 3, 0])
    assert arr.read_whisk()[0].cycle == 1
    assert arr.counters.frames == 2 * FRAMES_PER_WHISK


def test_sim_array_from_simulator_gives_18_records():
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.simulator import ArraySimulator

    arm = SimArm(Pose([0.03, -0.32, 0.2], [0.0, 0.0, 0.0, 1.0]),
                 envelope=_upright_envelope())
    arr = SimArray.from_simulator(ArraySimulator(seed=1), make_object("box"), arm.pose)
    recs = arr.read_whisk()
    assert len(recs) == 18 and recs[0].n_samples == 2000
    assert max(np.abs(r.y_counts).max() for r in recs) > 500  # the box is touched


def _upright_envelope():
    from whisker_io.hw.safety import SafetyEnvelope
    return SafetyEnvelope(workspace_min=(-0.5, -0.5, 0.05), workspace_max=(0.5, 0.5, 0.7),
                          tool_reference_axis=(0.0, 0.0, 1.0))


def test_whisking_block_starts_and_always_stops():
    arr, backend = open_array(1)
    with arr.whisking(WhiskPattern(frequency_hz=2.0), "retract_on_max", 500.0):
        arr.read_whisk()
    ops = [op for op, _ in backend.commands]
    assert ops == [OP_SET_PATTERN, OP_SET_RCP_THRESHOLD, OP_START, OP_STOP]
    # a fault inside the block: the array is stopped and the fault propagates
    arr, backend = open_array(0, timeout_ms=5)
    with pytest.raises(DeviceTimeoutError):
        with arr.whisking():
            arr.read_whisk()
    assert [op for op, _ in backend.commands][-1] == OP_STOP
    # the device gone inside the block: the failed stop is logged, the first error is the one raised
    arr, backend = open_array(1)
    backend.inject("remove")
    with pytest.raises(DeviceRemovedError):
        with arr.whisking():
            arr.read_whisk()
    # bad arguments: nothing is started
    arr, backend = open_array()
    with pytest.raises(InvalidInputError):
        with arr.whisking(mode="wiggle"):
            pass
    assert backend.commands == []


@settings(max_examples=30, deadline=None)
@given(faults=st.lists(st.sampled_from(["short", "gap", "crc"]), max_size=3), retries=st.integers(0, 3),
       at=st.integers(1, FRAMES_PER_WHISK - 2))
def test_read_whisk_retrying_returns_the_first_whole_whisk_within_its_retakes(faults, retries, at):
    """k consecutive whisks spoiled by frame faults: within k <= retries retakes the next whole whisk (index k) comes
    back, its samples intact; beyond, the last fault is raised. Counted from the queue, not from the function."""
    arr, backend = open_array(len(faults) + 1)
    for k, fault in enumerate(faults):  # one fault inside each of whisks 0 .. k-1
        # inside the whisk: a lost last frame shows only at the next whisk's first, which is then lost too
        backend.inject(fault, after_frames=k * FRAMES_PER_WHISK + at)
    if len(faults) <= retries:
        recs = arr.read_whisk_retrying(retries)
        assert recs[0].cycle == len(faults)
        assert np.array_equal(recs[12].y_counts, quantised(whisk_samples(len(faults)))[:, 12, 2])
    else:
        with pytest.raises(USBFrameError):
            arr.read_whisk_retrying(retries)
    assert arr.counters.discarded_whisks == min(len(faults), retries + 1)
