"""Recorder: live cycles on disk as they arrive, replay through the same pipeline.

* a SimArm + SimArray session (simulated box, Ch.4/6 retract-at-maximum
  whisking) replays bit-identically into whisker_io.contact.detection;
* the fake RTDE server killed mid-session -> typed error within 1 s, recorder
  closed, every whisk before the fault readable.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whisker_io.contact.detection import detect_contacts
from whisker_io.array.control import RetractAtMax
from whisker_io.errors import (ConnectionFailedError, CorruptFileError, HardwareError, InvalidInputError,
                               StaleStateError)
from whisker_io.hw.arm import ArmState, SimArm, URArm
from whisker_io.testing.fake_rtde_server import (FakeControlInterface, FakeServerError,
                                            fake_rtde_server)
from whisker_io.pose import Pose
from whisker_io.hw.recorder import Recorder, explore, replay_session
from whisker_io.hw.safety import SafetyEnvelope
from whisker_io.hw.usb_array import SimArray
from whisker_io.records.recording import read_pose_log, replay
from whisker_io.records.whisk_record import WhiskRecord

UPRIGHT = SafetyEnvelope(tool_reference_axis=(0.0, 0.0, 1.0))  # array axis (+y) horizontal


def contact_pipeline(cycle):
    """The live/replay consumer: contacts of the 18 modules, in module order."""
    return detect_contacts([cycle.records[m] for m in sorted(cycle.records)])


def upright(x, y, z):
    return Pose([x, y, z], [0.0, 0.0, 0.0, 1.0])


def test_sim_session_replays_bit_identically_into_contact_pipeline(tmp_path):
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.simulator import ArraySimulator

    arm = SimArm(upright(0.0, -0.33, 0.15), envelope=UPRIGHT)
    array = SimArray.from_simulator(ArraySimulator(seed=3, controller=RetractAtMax()),
                                    make_object("box"), arm.pose)
    targets = [upright(x, -0.32, z) for x, z in [(-0.04, 0.1), (0.0, 0.2), (0.04, 0.3)]]
    live_cycles = []
    with Recorder(tmp_path, pipeline=lambda c: (live_cycles.append(c), contact_pipeline(c))[1]) as rec:
        assert explore(arm, array, rec, targets, progress=False) == 3
    live = rec.results
    assert sum(c is not None for cycle in live for c in cycle) >= 5  # the box was touched
    replayed = replay_session(tmp_path, contact_pipeline)
    assert replayed == live  # DetectedContact dataclasses compared field by field, exactly
    for a, b in zip(live_cycles, replay(tmp_path)):
        assert a.entry.time_s == b.entry.time_s and a.entry.whisk_file == b.entry.whisk_file
        assert a.entry.pose == b.entry.pose
        for m in a.records:
            for col in ("angle_rad", "x_counts", "y_counts"):
                assert np.array_equal(getattr(a.records[m], col), getattr(b.records[m], col))
    # the pose log holds the arm's poses at each whisk
    for entry, target in zip(read_pose_log(tmp_path / "pose_log.csv"), targets):
        assert np.array_equal(entry.pose.position_m, target.position_m)


def _small_whisk(k, n=200):
    s = np.zeros((n, 18, 3))
    s[:, :, 0] = np.linspace(-0.8, 0.8, n)[:, None]
    s[:, :, 2] = k
    return s


@pytest.fixture
def rtde_server():
    pytest.importorskip("rtde_receive", reason='the URArm client needs the hw extra (ur-rtde): pip install -e ".[hw]"')
    try:
        with fake_rtde_server("stream") as (proc, _):
            yield proc
    except FakeServerError as exc:
        pytest.skip(f"cannot run the fake RTDE server on port 30004: {exc}")


def test_killed_rtde_server_mid_session(tmp_path, rtde_server):
    ctl = FakeControlInterface()  # the control path is an injected fake
    arm = URArm("127.0.0.1", control_factory=lambda h: ctl)
    calls = []
    killed_at = []

    def source(pose):
        k = len(calls)
        calls.append(pose)
        if k == 3:  # the controller dies while whisk 3 is being taken
            rtde_server.kill()
            killed_at.append(time.monotonic())
        return _small_whisk(k)

    array = SimArray(source, lambda: None)
    targets = [Pose([0.4, 0.0, 0.4], [1.0, 0.0, 0.0, 0.0])] * 10_000
    with pytest.raises((ConnectionFailedError, StaleStateError)):
        with Recorder(tmp_path) as rec:
            explore(arm, array, rec, targets, progress=False)
    assert time.monotonic() - killed_at[0] < 1.0
    assert rec.closed and rec.n_cycles >= 3
    assert any(name == "stopL" for name, _ in ctl.calls)
    cycles = list(replay(tmp_path))
    assert len(cycles) == rec.n_cycles
    for k, cyc in enumerate(cycles):
        assert np.all(cyc.records["A1"].y_counts == k)  # each cycle whole and in order
        # poses come from the fake robot's 5 cm circle about (0.4, 0, 0.4)
        p = cyc.entry.pose.position_m
        assert math.hypot(p[0] - 0.4, p[1]) == pytest.approx(0.05)
    arm.close()


def _records(cycle, value=0.0):
    return [WhiskRecord(m, np.zeros(10), np.zeros(10), np.full(10, value), cycle=cycle)
            for m in ("A1", "B1")]


def _state(t):
    return ArmState(t, Pose([0.4, 0.0, 0.4], [1, 0, 0, 0]), np.zeros(6), np.zeros(6))


def test_recorder_resumes_numbering_and_relabels_device_cycles(tmp_path):
    with Recorder(tmp_path) as rec:
        rec.record(_state(0.0), _records(cycle=7))
        rec.record(_state(1.0), _records(cycle=7, value=1.0))  # device restarted its count
    # debris of a killed recorder: a temporary file, a module file without pose line
    (tmp_path / ".whisk_000002_A1.csv.k3j2.tmp").write_text("angle_rad,x_deflec")
    (tmp_path / "whisk_000002_C3.csv").write_text("angle_rad,x_deflection_counts,"
                                                   "y_deflection_counts,spare\n0,0,9,0\n")
    with Recorder(tmp_path) as rec:
        assert not (tmp_path / "whisk_000002_C3.csv").exists()
        assert not list(tmp_path.glob(".*.tmp"))
        item = rec.record(_state(2.0), _records(cycle=0, value=2.0))
    assert item.entry.whisk_file == "whisk_000002"
    cycles = list(replay(tmp_path))
    assert [c.entry.whisk_file for c in cycles] == ["whisk_000000", "whisk_000001", "whisk_000002"]
    assert [float(c.records["B1"].y_counts[0]) for c in cycles] == [0.0, 1.0, 2.0]
    assert all(sorted(c.records) == ["A1", "B1"] for c in cycles)


def test_recorder_refuses_time_reversal_and_closed_use(tmp_path):
    rec = Recorder(tmp_path)
    rec.record(_state(5.0), _records(0))
    with pytest.raises(InvalidInputError, match="time order"):
        rec.record(_state(4.0), _records(0))
    rec.close()
    with pytest.raises(InvalidInputError, match="closed"):
        rec.record(_state(6.0), _records(0))
    assert len(list(replay(tmp_path))) == 1
    assert sorted(p.name for p in tmp_path.glob("whisk_*")) == ["whisk_000000_A1.csv",
                                                                 "whisk_000000_B1.csv"]


def test_failed_cycle_write_leaves_no_orphan_files(tmp_path, monkeypatch):
    import whisker_io.records.recording as recording

    real = recording.write_whisk_csv
    calls = []

    def flaky(path, record):
        calls.append(record.module)
        if len(calls) == 4:  # second module of the second cycle: "disk full"
            raise OSError(28, "No space left on device")
        return real(path, record)

    monkeypatch.setattr(recording, "write_whisk_csv", flaky)
    with Recorder(tmp_path) as rec:
        rec.record(_state(0.0), _records(0))
        with pytest.raises(OSError):
            rec.record(_state(1.0), _records(1))
    assert sorted(p.name for p in tmp_path.glob("whisk_*")) == ["whisk_000000_A1.csv",
                                                                 "whisk_000000_B1.csv"]
    assert len(list(replay(tmp_path))) == 1


def test_explore_stops_arm_on_deflection_overload_after_recording(tmp_path):
    arm = SimArm()
    pinned = np.zeros((2000, 18, 3))
    pinned[:, 4, 2] = 2047.0  # module B2 pinned at the sensor maximum all cycle
    array = SimArray(lambda pose: pinned, arm.pose)
    with pytest.raises(HardwareError, match="overload"):
        with Recorder(tmp_path) as rec:
            explore(arm, array, rec, [Pose([0.4, 0.0, 0.4], [1, 0, 0, 0])] * 3, progress=False)
    assert rec.n_cycles == 1  # the overloading whisk itself is kept
    assert arm.received[-1].kind == "stop"


CHILD = """
import sys
import numpy as np
from whisker_io.hw.arm import ArmState
from whisker_io.pose import Pose
from whisker_io.hw.recorder import Recorder
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.array.geometry import WhiskerArray
names = WhiskerArray.thesis().names
pose = Pose([0.4, 0.0, 0.4], [1, 0, 0, 0])
with Recorder(sys.argv[1]) as rec:
    k = 0
    while True:
        recs = [WhiskRecord(m, np.zeros(2000), np.zeros(2000), np.full(2000, float(k)), cycle=k)
                for m in names]
        rec.record(ArmState(float(k), pose, np.zeros(6), np.zeros(6)), recs)
        print(k, flush=True)
        k += 1
"""


def test_recorder_process_killed_keeps_every_completed_whisk(tmp_path):
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp_path)], stdout=subprocess.PIPE,
                            text=True)
    try:
        reported = [int(proc.stdout.readline()) for _ in range(4)]  # cycles 0..3 are on disk
    finally:
        proc.kill()  # SIGKILL: no cleanup, possibly in the middle of writing cycle 4 or 5
        proc.wait()
        proc.stdout.close()
    assert reported == [0, 1, 2, 3]
    cycles = list(replay(tmp_path))
    assert len(cycles) >= 4
    for k, cyc in enumerate(cycles):
        assert len(cyc.records) == 18
        assert all(np.all(r.y_counts == k) and r.n_samples == 2000 for r in cyc.records.values())
    # resuming cleans the debris of the interrupted cycle and continues the numbering
    with Recorder(tmp_path) as rec:
        assert not list(tmp_path.glob(".*.tmp"))
        assert len(list(tmp_path.glob("whisk_*.csv"))) == 18 * len(cycles)
        item = rec.record(_state(float(len(cycles))), _records(0))
    assert item.entry.whisk_file == f"whisk_{len(cycles):06d}"


def _two_cycles(folder):
    with Recorder(folder) as rec:
        rec.record(_state(5.0), _records(0))
        rec.record(_state(6.0), _records(1, value=1.0))


def test_a_folder_of_whisk_files_without_a_pose_log_is_refused_and_nothing_is_deleted(tmp_path):
    _two_cycles(tmp_path)
    (tmp_path / "pose_log.csv").rename(tmp_path / "poses_elsewhere.csv")
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(InvalidInputError, match="has no pose_log.csv: not a session a recorder left"):
        Recorder(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # all four whisk files kept


def test_whisk_files_beyond_the_cycle_in_progress_are_refused_and_kept(tmp_path):
    _two_cycles(tmp_path)
    for cycle in (2, 3):  # 2 is what a killed recorder leaves; 3 it cannot have left
        (tmp_path / f"whisk_00000{cycle}_A1.csv").write_text("angle_rad,x_deflection_counts,y_deflection_counts,spare\n")
    with pytest.raises(InvalidInputError, match=r"whisk_000003_A1.csv\) but whose cycles lie beyond"):
        Recorder(tmp_path)
    assert (tmp_path / "whisk_000002_A1.csv").exists() and (tmp_path / "whisk_000003_A1.csv").exists()


def test_a_torn_last_pose_line_is_cut_off_before_the_resumed_session_appends(tmp_path, caplog):
    _two_cycles(tmp_path)
    log = tmp_path / "pose_log.csv"
    good = log.read_bytes()
    with open(log, "ab") as fh:  # a crash during the third line's append
        fh.write(b"7.0,0.4,0.0,0.4,1.0,0.0,0.0,0.0")
    (tmp_path / "whisk_000002_A1.csv").write_bytes((tmp_path / "whisk_000001_A1.csv").read_bytes())
    with caplog.at_level("WARNING"), Recorder(tmp_path) as rec:
        assert log.read_bytes() == good  # cut back to the last whole line
        rec.record(_state(8.0), _records(0, value=3.0))
    assert "torn final line" in caplog.text
    cycles = list(replay(tmp_path))
    assert [c.entry.time_s for c in cycles] == [5.0, 6.0, 8.0]
    assert [c.entry.whisk_file for c in cycles] == ["whisk_000000", "whisk_000001", "whisk_000002"]
    assert float(cycles[2].records["B1"].y_counts[0]) == 3.0  # the new cycle's files, not the interrupted one's


def test_a_resumed_session_whose_arm_clock_restarted_stays_in_time_order(tmp_path, caplog):
    _two_cycles(tmp_path)  # times 5 and 6 s
    with caplog.at_level("WARNING"), Recorder(tmp_path) as rec:
        rec.record(_state(0.5), _records(0, value=2.0))  # the arm's clock started again
        rec.record(_state(1.5), _records(0, value=3.0))
        with pytest.raises(InvalidInputError, match="time order"):  # within one run, time still only goes forward
            rec.record(_state(1.0), _records(0))
    assert "clock restarted" in caplog.text
    assert [c.entry.time_s for c in replay(tmp_path)] == [5.0, 6.0, 6.5, 7.5]  # shifted by the log's last time


def test_a_resumed_session_whose_clock_went_on_keeps_its_times(tmp_path):
    _two_cycles(tmp_path)
    with Recorder(tmp_path) as rec:
        rec.record(_state(9.0), _records(0))
    assert [c.entry.time_s for c in replay(tmp_path)] == [5.0, 6.0, 9.0]


@settings(max_examples=40, deadline=None)
@given(logged=st.integers(0, 3), files=st.lists(st.integers(0, 6), max_size=4), with_log=st.booleans())
def test_check_folder_refuses_exactly_what_the_recorder_refuses_and_changes_nothing(tmp_path_factory, logged, files,
                                                                                     with_log):
    import shutil

    folder = tmp_path_factory.mktemp("session")
    with Recorder(folder) as rec:
        for k in range(logged):
            rec.record(_state(float(k)), _records(k))
    if not with_log:
        (folder / "pose_log.csv").unlink()
    for cycle in files:
        (folder / f"whisk_{cycle:06d}_C3.csv").write_text("angle_rad,x_deflection_counts,y_deflection_counts,spare\n0,0,0,0\n")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    copy = tmp_path_factory.mktemp("copy")
    shutil.copytree(folder, copy, dirs_exist_ok=True)
    try:
        Recorder.check_folder(folder)
        checked = None
    except InvalidInputError as exc:
        checked = str(exc).replace(str(folder), "")
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before  # nothing created, changed or deleted
    try:
        Recorder(copy).close()
        opened = None
    except InvalidInputError as exc:
        opened = str(exc).replace(str(copy), "")
    assert checked == opened
    # with a log: files beyond the cycle in progress (the next one); without: any whisk file at all
    expect_refused = any(c > logged for c in files) if with_log else (logged > 0 or bool(files))
    assert (checked is not None) == expect_refused


def test_an_interrupt_after_the_pose_line_keeps_the_complete_cycle(tmp_path, monkeypatch):
    """Ctrl-C just after the pose-log line's fsync deleted the cycle's files and left the line: the session no
    longer replayed (the review of session 48)."""
    import whisker_io.records.recording as recording

    real = recording.PoseLogWriter.append
    calls = []

    def append_then_interrupt(self, *args, **kwargs):
        entry = real(self, *args, **kwargs)
        calls.append(entry.whisk_file)
        if len(calls) == 2:
            raise KeyboardInterrupt  # the line is on disk
        return entry

    monkeypatch.setattr(recording.PoseLogWriter, "append", append_then_interrupt)
    with pytest.raises(KeyboardInterrupt), Recorder(tmp_path) as rec:
        rec.record(_state(0.0), _records(0))
        rec.record(_state(1.0), _records(1, value=1.0))
    assert rec.n_cycles == 2
    cycles = list(replay(tmp_path))
    assert [c.entry.whisk_file for c in cycles] == ["whisk_000000", "whisk_000001"]
    assert float(cycles[1].records["B1"].y_counts[0]) == 1.0
    monkeypatch.setattr(recording.PoseLogWriter, "append", real)
    with Recorder(tmp_path) as rec:  # resumes after it
        assert rec.record(_state(2.0), _records(0)).entry.whisk_file == "whisk_000002"


@pytest.mark.parametrize("below", [False, True])
def test_a_file_given_as_the_session_folder_is_a_typed_error(tmp_path, below):
    (tmp_path / "notes.txt").write_text("mine")
    folder = tmp_path / "notes.txt" / "session" if below else tmp_path / "notes.txt"
    for check in (Recorder.check_folder, Recorder):
        with pytest.raises(InvalidInputError, match="notes.txt is a file, not a folder"):
            check(folder)
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_a_whole_last_pose_line_without_its_newline_keeps_its_cycle(tmp_path, caplog):
    """A hand edit that dropped the final newline: the whole line and its cycle were cut and deleted (review, s48)."""
    with Recorder(tmp_path) as rec:
        for k in range(3):
            rec.record(_state(float(k)), _records(k, value=float(k)))
    log = tmp_path / "pose_log.csv"
    log.write_bytes(log.read_bytes().rstrip(b"\n"))
    with caplog.at_level("WARNING"), Recorder(tmp_path) as rec:
        rec.record(_state(5.0), _records(0, value=5.0))
    assert "lacked its newline; added" in caplog.text
    cycles = list(replay(tmp_path))
    assert [c.entry.whisk_file for c in cycles] == [f"whisk_{k:06d}" for k in range(4)]
    assert [float(c.records["B1"].y_counts[0]) for c in cycles] == [0.0, 1.0, 2.0, 5.0]
    # the same line whose whisk files are gone is no whole cycle: cut, as a torn line is
    log.write_bytes(log.read_bytes().rstrip(b"\n"))
    for p in tmp_path.glob("whisk_000003_*.csv"):
        p.unlink()
    with Recorder(tmp_path) as rec:
        pass
    assert [c.entry.whisk_file for c in replay(tmp_path)] == [f"whisk_{k:06d}" for k in range(3)]


def test_an_interrupt_between_the_pose_lines_write_and_its_fsync_keeps_the_cycle_and_the_writer_in_step(tmp_path,
                                                                                                          monkeypatch):
    """The line written but not yet flushed sat in a Python buffer, the cycle's files were removed as unlogged and
    close() then wrote the line (second review of session 48): the log is unbuffered now."""
    import whisker_io.records.recording as recording

    real = recording.PoseLogWriter._write

    def write_then_interrupt(self, text):
        self._fh.write(text.encode("utf-8"))  # the bytes are in the file; the fsync never came
        if text.endswith(",whisk_000001\n"):
            raise KeyboardInterrupt
        os.fsync(self._fh.fileno())

    monkeypatch.setattr(recording.PoseLogWriter, "_write", write_then_interrupt)
    rec = Recorder(tmp_path)
    rec.record(_state(0.0), _records(0))
    with pytest.raises(KeyboardInterrupt):
        rec.record(_state(1.0), _records(1, value=1.0))
    monkeypatch.setattr(recording.PoseLogWriter, "_write", real)
    with pytest.raises(InvalidInputError, match="time order"):  # the writer knows the interrupted line
        rec.record(_state(0.5), _records(2))
    assert rec.record(_state(2.0), _records(2, value=2.0)).entry.whisk_file == "whisk_000002"
    rec.close()
    assert [float(c.records["B1"].y_counts[0]) for c in replay(tmp_path)] == [0.0, 1.0, 2.0]


def test_a_torn_header_is_a_log_without_lines_and_a_wrong_whole_last_line_is_refused_not_cut(tmp_path):
    torn = tmp_path / "torn"
    torn.mkdir()
    (torn / "pose_log.csv").write_text("time_s,x_m,y_m,z")  # a crash while the header was written
    Recorder.check_folder(torn)
    with Recorder(torn) as rec:
        rec.record(_state(0.0), _records(0))
    assert len(list(replay(torn))) == 1
    wrong = tmp_path / "wrong"
    with Recorder(wrong) as rec:
        rec.record(_state(5.0), _records(0))
        rec.record(_state(6.0), _records(1))
    log = wrong / "pose_log.csv"
    lines = log.read_text().splitlines()
    log.write_text("\n".join(lines[:-1] + [lines[-1].replace("6,", "4,", 1)]))  # whole, no newline, time earlier
    with pytest.raises(CorruptFileError, match="earlier than line 2"):
        Recorder(wrong)
    assert len(list(wrong.glob("whisk_000001_*.csv"))) == 2  # its cycle's files kept for the user to repair


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_explore_refuses_bad_frame_retries_before_the_arm_moves(tmp_path, bad):
    arm = SimArm()
    sent = len(arm.received)
    with pytest.raises(InvalidInputError, match="frame_retries must be a count"):
        with Recorder(tmp_path) as rec:
            explore(arm, SimArray(lambda pose: np.zeros((2000, 18, 3)), arm.pose), rec,
                    [Pose([0.4, -0.1, 0.4], [1.0, 0.0, 0.0, 0.0])], progress=False, frame_retries=bad)
    assert len(arm.received) == sent  # no command went to the arm


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 3), cut=st.floats(0.0, 1.0))
def test_a_last_line_torn_anywhere_resumes_with_every_whole_line_and_nothing_else(tmp_path_factory, n, cut):
    """A crash stops the log anywhere in its last line (a cycle's files come before its line, so no earlier line can
    be torn): the resumed session keeps that line when it is whole (with or without its newline), else drops it with
    its cycle's files, and appends after them."""
    folder = tmp_path_factory.mktemp("cut")
    with Recorder(folder) as rec:
        for k in range(n):
            rec.record(_state(float(k)), _records(k, value=float(k)))
    log = folder / "pose_log.csv"
    data = log.read_bytes()
    start = data.rstrip(b"\n").rfind(b"\n") + 1  # the last line's first byte
    at = start + int(cut * (len(data) - start))
    log.write_bytes(data[:at])
    whole = n - 1 + (at >= len(data) - 1)  # the last line is whole when at most its newline is missing
    with Recorder(folder) as rec:
        rec.record(_state(10.0), _records(0, value=10.0))
    values = [float(c.records["B1"].y_counts[0]) for c in replay(folder)]
    assert values == [float(k) for k in range(whole)] + [10.0]
    assert len(list(folder.glob("whisk_*.csv"))) == 2 * (whole + 1)  # no file of a dropped cycle is left
