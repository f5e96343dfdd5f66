"""Tests of the whisk CSV / pose-log format (Sec 3.1.3): round trips, atomicity, typed errors."""

from __future__ import annotations

import logging
import math
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from whisker_io.errors import InvalidInputError, CorruptFileError, CansimError
from whisker_io.records.recording import (
    POSE_LOG_NAME,
    PoseLogWriter,
    RecordingWriter,
    read_pose_log,
    read_whisk_csv,
    replay,
    whisk_file_name,
    write_whisk_csv,
)
from whisker_io.records.whisk_record import WhiskRecord


def _record(module: str = "C2", cycle: int = 3, n: int = 50, seed: int = 0) -> WhiskRecord:
    rng = np.random.default_rng(seed)
    return WhiskRecord(
        module=module,
        angle_rad=np.linspace(-np.deg2rad(50), np.deg2rad(50), n) + rng.normal(0, 1e-3, n),
        x_counts=rng.integers(-2048, 2048, n).astype(float),
        y_counts=rng.normal(0, 300, n),
        cycle=cycle,
    )


def _identity_quat() -> list[float]:
    return [0.0, 0.0, 0.0, 1.0]


def test_whisk_csv_round_trip_is_bit_identical(tmp_path):
    rec = _record()
    path = write_whisk_csv(tmp_path, rec)
    assert path.name == "whisk_000003_C2.csv"
    back = read_whisk_csv(path)
    assert back.module == "C2" and back.cycle == 3 and back.sample_rate_hz == 2000.0
    for name in ("angle_rad", "x_counts", "y_counts"):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name))
    np.testing.assert_array_equal(back.spare, np.zeros(rec.n_samples))
    # header line + one line per sample, four columns each
    lines = path.read_text().splitlines()
    assert lines[0] == "angle_rad,x_deflection_counts,y_deflection_counts,spare"
    assert len(lines) == rec.n_samples + 1
    assert all(line.count(",") == 3 for line in lines)


def test_degree_header_and_headerless_files_are_read(tmp_path):
    p = tmp_path / "whisk_000001_A1.csv"
    p.write_text("angle_deg,x_deflection_counts,y_deflection_counts,spare\n90,1,2,0\n-45,3,4,0\n")
    rec = read_whisk_csv(p)
    np.testing.assert_allclose(rec.angle_rad, [math.pi / 2, -math.pi / 4])
    np.testing.assert_array_equal(rec.y_counts, [2, 4])
    q = tmp_path / "whisk_000001_A2.csv"
    q.write_text("0.5,1,2,0\n0.25,3,4,0\n")
    np.testing.assert_array_equal(read_whisk_csv(q).angle_rad, [0.5, 0.25])


def test_write_is_atomic_no_temp_file_left(tmp_path):
    write_whisk_csv(tmp_path, _record())
    assert sorted(os.listdir(tmp_path)) == ["whisk_000003_C2.csv"]


@pytest.mark.parametrize(
    ("content", "line", "what"),
    [
        ("angle_rad,x_deflection_counts,y_deflection_counts,spare\n0,1,2,0\n0,1,2\n", 3, "4 columns"),
        ("angle_rad,x_deflection_counts,y_deflection_counts,spare\n0,1,2,0\n0,1,abc,0\n", 3, "not a number"),
        ("angle_rad,x_deflection_counts,y_deflection_counts,spare\n0,1,2,0\n0,1,2,0\n0,nan,2,0\n", 4, "NaN"),
        ("angle,x,y\n0,1,2,0\n", 1, "header"),
        ("angle_rad,x_deflection_counts,y_deflection_counts,spare\n", 2, "no samples"),
    ],
)
def test_malformed_whisk_csv_names_file_and_line(tmp_path, content, line, what):
    p = tmp_path / "whisk_000000_B1.csv"
    p.write_text(content)
    with pytest.raises(CorruptFileError) as err:
        read_whisk_csv(p)
    msg = str(err.value)
    assert str(p) in msg and f"line {line}" in msg and what in msg
    assert isinstance(err.value, CansimError)


def test_unparseable_file_name_requires_module_and_cycle(tmp_path):
    p = tmp_path / "data.csv"
    p.write_text("0,1,2,0\n")
    with pytest.raises(CorruptFileError, match="file name"):
        read_whisk_csv(p)
    assert read_whisk_csv(p, module="F3", cycle=7).module == "F3"


def test_whisk_record_rejects_nan_and_ragged_columns():
    with pytest.raises(InvalidInputError, match="index 2"):
        WhiskRecord("A1", [0, 0, np.nan], [0, 0, 0], [0, 0, 0])
    with pytest.raises(InvalidInputError, match="different lengths"):
        WhiskRecord("A1", [0, 0, 0], [0, 0], [0, 0, 0])
    with pytest.raises(InvalidInputError, match="module name"):
        WhiskRecord("A 1", [0], [0], [0])
    rec = WhiskRecord("A1", [0.0, 1.0], [0, 0], [0, 0])
    with pytest.raises(ValueError):  # read-only arrays: a record cannot be changed behind a writer's back
        rec.angle_rad[0] = 5.0


def test_pose_log_round_trip_and_scalar_last_quaternion(tmp_path):
    path = tmp_path / POSE_LOG_NAME
    q = [0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8)]  # 45 deg about z, scalar last
    with PoseLogWriter(path) as w:
        w.append(1.0, ([0.1, 0.2, 0.3], _identity_quat()), "whisk_000000")
        w.append(2.5, ([0.4, 0.5, 0.6], q), "whisk_000001")
    entries = read_pose_log(path)
    assert [e.time_s for e in entries] == [1.0, 2.5]
    np.testing.assert_array_equal(entries[1].pose.position_m, [0.4, 0.5, 0.6])
    T = entries[1].pose.matrix
    np.testing.assert_allclose(T[:3, 0], [math.sqrt(0.5), math.sqrt(0.5), 0], atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [0.4, 0.5, 0.6])
    # resuming a session appends after the existing lines and keeps the time order check
    with PoseLogWriter(path) as w:
        with pytest.raises(InvalidInputError, match="time order"):
            w.append(2.0, ([0, 0, 0], _identity_quat()), "whisk_000002")
        w.append(3.0, ([0, 0, 0], _identity_quat()), "whisk_000002")
    assert len(read_pose_log(path)) == 3


def test_pose_log_out_of_time_order_is_a_typed_error_with_line(tmp_path):
    path = tmp_path / POSE_LOG_NAME
    path.write_text(
        "time_s,x_m,y_m,z_m,qx,qy,qz,qw,whisk_file\n"
        "1.0,0,0,0,0,0,0,1,whisk_000000\n"
        "3.0,0,0,0,0,0,0,1,whisk_000001\n"
        "2.0,0,0,0,0,0,0,1,whisk_000002\n"
    )
    with pytest.raises(CorruptFileError, match=r"line 4: .*out of time order"):
        read_pose_log(path)


@pytest.mark.parametrize(
    ("row", "what"),
    [
        ("1.0,0,0,0,0,0,1,whisk_000000", "9 columns"),
        ("1.0,0,x,0,0,0,0,1,whisk_000000", "not a number"),
        ("1.0,0,0,0,0,0,0,2,whisk_000000", "unit norm"),
        ("nan,0,0,0,0,0,0,1,whisk_000000", "NaN"),
        ("1.0,0,nan,0,0,0,0,1,whisk_000000", "repair this line of the pose log"),
        ("1.0,-80,-320,150,0,0,0,1,whisk_000000", "millimetres?"),  # mm written as m
    ],
)
def test_malformed_pose_log_line(tmp_path, row, what):
    path = tmp_path / POSE_LOG_NAME
    path.write_text("time_s,x_m,y_m,z_m,qx,qy,qz,qw,whisk_file\n" + row + "\n")
    with pytest.raises(CorruptFileError) as err:
        read_pose_log(path)
    assert f"{path}: line 2" in str(err.value) and what in str(err.value)


def test_torn_final_pose_line_is_ignored(tmp_path, caplog):
    path = tmp_path / POSE_LOG_NAME
    path.write_text("time_s,x_m,y_m,z_m,qx,qy,qz,qw,whisk_file\n1.0,0,0,0,0,0,0,1,whisk_000000\n2.0,0,0,0,0,0")
    with caplog.at_level(logging.WARNING):
        entries = read_pose_log(path)
    assert len(entries) == 1 and "torn" in caplog.text


def test_session_write_and_replay_in_pose_log_order(tmp_path):
    modules = ["A1", "B2", "F3"]
    times = [0.0, 1.0, 2.0]
    written = []
    with RecordingWriter(tmp_path) as w:
        for cycle, t in enumerate(times):
            recs = [_record(m, cycle, n=20 + cycle, seed=10 * cycle + i) for i, m in enumerate(modules)]
            w.write_cycle(recs, time_s=t, pose=([t, 0, 0], _identity_quat()))
            written.append(recs)
    cycles = list(replay(tmp_path))
    assert [c.entry.time_s for c in cycles] == times
    for c, recs in zip(cycles, written):
        assert list(c.records) == modules
        for r in recs:
            got = c.records[r.module]
            assert got.cycle == r.cycle
            np.testing.assert_array_equal(got.y_counts, r.y_counts)
            np.testing.assert_array_equal(got.angle_rad, r.angle_rad)


def test_write_cycle_out_of_order_leaves_directory_unchanged(tmp_path):
    with RecordingWriter(tmp_path) as w:
        w.write_cycle([_record("A1", 0)], time_s=5.0, pose=([0, 0, 0], _identity_quat()))
        before = sorted(os.listdir(tmp_path))
        with pytest.raises(InvalidInputError, match="time order"):
            w.write_cycle([_record("A1", 1)], time_s=4.0, pose=([0, 0, 0], _identity_quat()))
        with pytest.raises(InvalidInputError, match="duplicate"):
            w.write_cycle([_record("A1", 1), _record("A1", 1)], 6.0, ([0, 0, 0], _identity_quat()))
    assert sorted(os.listdir(tmp_path)) == before


def test_replay_reports_missing_whisk_files(tmp_path):
    with RecordingWriter(tmp_path) as w:
        w.write_cycle([_record("A1", 0)], 0.0, ([0, 0, 0], _identity_quat()))
        w.write_cycle([_record("A1", 1)], 1.0, ([0, 0, 0], _identity_quat()))
    os.remove(tmp_path / whisk_file_name(1, "A1"))
    it = replay(tmp_path)
    assert next(it).entry.whisk_file == "whisk_000000"
    with pytest.raises(CorruptFileError, match=r"line 3: .*missing"):
        next(it)


def test_from_float_arrays_equals_the_validating_constructor():
    rng = np.random.default_rng(0)
    a, x, y = rng.normal(size=(3, 50))
    fast = WhiskRecord.from_float_arrays("C2", a, x, y, sample_rate_hz=1000.0, cycle=4)
    slow = WhiskRecord("C2", a, x, y, sample_rate_hz=1000.0, cycle=4)
    for name in ("angle_rad", "x_counts", "y_counts"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
        with pytest.raises(ValueError):
            getattr(fast, name)[0] = 1.0  # read-only views
    assert (fast.module, fast.cycle, fast.sample_rate_hz, fast.spare) == ("C2", 4, 1000.0, None)
    np.testing.assert_array_equal(fast.as_columns(), slow.as_columns())
    # not 1-D float64: the validating constructor takes over
    ints = WhiskRecord.from_float_arrays("C2", [1, 2], [3, 4], [5, 6])
    assert ints.angle_rad.dtype == np.float64 and ints.angle_rad.tolist() == [1.0, 2.0]


def test_from_float_arrays_refuses_what_the_constructor_refuses():
    ok = np.zeros(5)
    bad = ok.copy()
    bad[3] = np.inf
    with pytest.raises(InvalidInputError, match="index 3"):
        WhiskRecord.from_float_arrays("A1", ok, bad, ok)
    with pytest.raises(InvalidInputError, match="equal length"):
        WhiskRecord.from_float_arrays("A1", ok, ok[:4], ok)
    with pytest.raises(InvalidInputError, match="equal length"):
        WhiskRecord.from_float_arrays("A1", ok[:0], ok[:0], ok[:0])
    with pytest.raises(InvalidInputError, match="module name"):
        WhiskRecord.from_float_arrays("A 1", ok, ok, ok)
    with pytest.raises(InvalidInputError, match="cycle"):
        WhiskRecord.from_float_arrays("A1", ok, ok, ok, cycle=-1)
    with pytest.raises(InvalidInputError, match="sample_rate_hz"):
        WhiskRecord.from_float_arrays("A1", ok, ok, ok, sample_rate_hz=0.0)


@settings(max_examples=80, deadline=None)
@given(arrays(np.float64, st.integers(0, 6), elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       arrays(np.float64, st.integers(0, 6), elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       st.text(max_size=4))
def test_from_float_arrays_is_typed_or_valid(a, b, module):
    try:
        rec = WhiskRecord.from_float_arrays(module, a, b, a)
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    assert a.size == b.size > 0 and np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and module.isalnum()
    np.testing.assert_array_equal(rec.x_counts, b)


def test_from_float_rows_equals_from_float_arrays_per_row():
    rng = np.random.default_rng(1)
    a, x, y = rng.normal(size=(3, 4, 30))
    rows = WhiskRecord.from_float_rows(["A1", "A2", "B1", "C3"], a, x, y, sample_rate_hz=500.0, cycle=2)
    for i, rec in enumerate(rows):
        one = WhiskRecord("A1 A2 B1 C3".split()[i], a[i], x[i], y[i], sample_rate_hz=500.0, cycle=2)
        assert (rec.module, rec.cycle, rec.sample_rate_hz, rec.spare) == (one.module, 2, 500.0, None)
        np.testing.assert_array_equal(rec.as_columns(), one.as_columns())
        with pytest.raises(ValueError):
            rec.y_counts[0] = 1.0  # read-only views
    lists = WhiskRecord.from_float_rows(["A1"], [[1, 2]], [[3, 4]], [[5, 6]])  # copied to float64
    assert lists[0].y_counts.dtype == np.float64 and lists[0].y_counts.tolist() == [5.0, 6.0]


def test_from_float_rows_refuses_with_the_row_named():
    ok = np.zeros((2, 5))
    bad = ok.copy()
    bad[1, 3] = np.nan
    with pytest.raises(InvalidInputError, match=r"A2\.x_counts.*index 3"):
        WhiskRecord.from_float_rows(["A1", "A2"], ok, bad, ok)
    with pytest.raises(InvalidInputError, match="one row per module name"):
        WhiskRecord.from_float_rows(["A1"], ok, ok, ok)
    with pytest.raises(InvalidInputError, match="one shape"):
        WhiskRecord.from_float_rows(["A1", "A2"], ok, ok[:, :4], ok)
    with pytest.raises(InvalidInputError, match="non-empty"):
        WhiskRecord.from_float_rows(["A1", "A2"], ok[:, :0], ok[:, :0], ok[:, :0])
    with pytest.raises(InvalidInputError, match="module name"):
        WhiskRecord.from_float_rows(["A1", "A 2"], ok, ok, ok)
    with pytest.raises(InvalidInputError, match="sequence of module names"):
        WhiskRecord.from_float_rows("A1", ok[:1], ok[:1], ok[:1])


@settings(max_examples=80, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 3), st.integers(0, 5)),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       st.lists(st.text(max_size=3), max_size=4), st.integers(-2, 3))
def test_from_float_rows_is_typed_or_valid(a, names, cycle):
    try:
        rows = WhiskRecord.from_float_rows(names, a, a, a, cycle=cycle)
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    assert a.shape[0] == len(names) and a.shape[1] > 0 and np.all(np.isfinite(a)) and cycle >= 0
    assert all(m.isalnum() for m in names) and [r.module for r in rows] == names
    for i, r in enumerate(rows):
        np.testing.assert_array_equal(r.angle_rad, a[i])


def test_a_whisk_file_named_by_two_pose_lines_is_refused_by_the_reader_and_the_writer(tmp_path):
    path = tmp_path / POSE_LOG_NAME
    path.write_text("time_s,x_m,y_m,z_m,qx,qy,qz,qw,whisk_file\n1.0,0,0,0,0,0,0,1,whisk_000000\n"
                    "2.0,0,0,0,0,0,0,1,whisk_000001\n3.0,0,0,0,0,0,0,1,whisk_000000\n")
    with pytest.raises(CorruptFileError, match="line 4: whisk file 'whisk_000000' is line 2's too"):
        read_pose_log(path)
    with PoseLogWriter(tmp_path / "other.csv") as w:
        w.append(1.0, ([0, 0, 0], _identity_quat()), "whisk_000000")
        with pytest.raises(InvalidInputError, match="already in"):
            w.append(2.0, ([0, 0, 0], _identity_quat()), "whisk_000000")
    assert len(read_pose_log(tmp_path / "other.csv")) == 1


def test_angles_in_degrees_under_the_radian_header_are_refused_naming_the_line(tmp_path):
    rec = _record(module="A1", cycle=0)
    path = tmp_path / whisk_file_name(0, "A1")
    body = "\n".join(f"{float(np.rad2deg(a))!r},{float(x)!r},{float(y)!r},0" for a, x, y in zip(rec.angle_rad, rec.x_counts, rec.y_counts))
    path.write_text("angle_rad,x_deflection_counts,y_deflection_counts,spare\n" + body + "\n")
    with pytest.raises(CorruptFileError, match=r"line 2: angle -49.99.*beyond \+-6.283 rad \(2 pi\): degrees\?"):
        read_whisk_csv(path)
    path.write_text(body + "\n")  # no header: read as radians, the same
    with pytest.raises(CorruptFileError, match="line 1: angle"):
        read_whisk_csv(path)
    path.write_text("angle_deg,x_deflection_counts,y_deflection_counts,spare\n" + body + "\n")  # said so: read
    np.testing.assert_allclose(read_whisk_csv(path).angle_rad, rec.angle_rad, rtol=0, atol=1e-12)


def test_a_byte_order_mark_before_the_header_is_read_past(tmp_path):
    rec = _record(module="A1", cycle=0)
    path = tmp_path / whisk_file_name(0, "A1")
    write_whisk_csv(path, rec)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())  # Excel's "CSV UTF-8"
    np.testing.assert_array_equal(read_whisk_csv(path).y_counts, rec.y_counts)


def test_a_cycle_whose_modules_hold_different_numbers_of_samples_is_refused(tmp_path):
    with RecordingWriter(tmp_path) as w:
        w.write_cycle([_record("A1", 0, n=40), _record("B1", 0, n=40)], 0.0, ([0, 0, 0], _identity_quat()))
    path = tmp_path / whisk_file_name(0, "B1")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:30]))  # a copy cut at a line boundary
    with pytest.raises(CorruptFileError, match=r"line 2: the modules of whisk_000000 hold different numbers of "
                                               r"samples \(B1: 29, A1: 40\): whisk_000000_B1.csv was cut short"):
        list(replay(tmp_path))


@settings(max_examples=60, deadline=None)
@given(position=st.lists(st.floats(-20.0, 20.0), min_size=3, max_size=3), times=st.lists(st.floats(0.0, 10.0), min_size=1,
       max_size=4), names=st.lists(st.sampled_from(["whisk_000000", "whisk_000001", "whisk_000002"]), min_size=4,
       max_size=4))
def test_what_the_pose_log_writer_takes_its_reader_reads_back(tmp_path_factory, position, times, names):
    """check_entry refuses exactly what read_pose_log would refuse after the lines before: every line written reads
    back, in order; a refused line leaves the file as it was."""
    path = tmp_path_factory.mktemp("log") / POSE_LOG_NAME
    written = []
    with PoseLogWriter(path) as w:
        for t, name in zip(times, names):
            before = path.read_bytes()
            try:
                written.append(w.append(t, (position, _identity_quat()), name))
            except InvalidInputError:
                assert path.read_bytes() == before
    back = read_pose_log(path)
    assert [(e.time_s, e.whisk_file) for e in back] == [(e.time_s, e.whisk_file) for e in written]


def test_the_writer_refuses_what_the_reader_refuses_before_writing_anything(tmp_path):
    """Angles beyond 2 pi (degrees) and modules of unequal length were written, then refused on replay (review, s48);
    an angle within the USB frame's +-3.28 rad is a whisk's, written and read back."""
    deg = _record("B1", 0)
    deg = WhiskRecord("B1", np.rad2deg(deg.angle_rad), deg.x_counts, deg.y_counts, cycle=0)
    short = _record("B1", 0, n=30)
    for bad, says in ((deg, "beyond"), (short, "same number of samples")):
        with RecordingWriter(tmp_path / says.replace(" ", "_")) as w:
            with pytest.raises(InvalidInputError, match=says):
                w.write_cycle([_record("A1", 0), bad], 0.0, ([0, 0, 0], _identity_quat()))
        assert sorted(p.name for p in (tmp_path / says.replace(" ", "_")).iterdir()) == [POSE_LOG_NAME]
    with pytest.raises(InvalidInputError, match="beyond"):
        write_whisk_csv(tmp_path, deg)
    base = _record("A1", 0)
    angles = base.angle_rad.copy()
    angles[3] = 3.2767  # the largest angle a USB frame holds
    path = write_whisk_csv(tmp_path, WhiskRecord("A1", angles, base.x_counts, base.y_counts, cycle=0))
    assert read_whisk_csv(path).angle_rad[3] == 3.2767
