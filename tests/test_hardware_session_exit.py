"""examples/hardware_session.py: documented exit codes, one line on stderr, no traceback."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "examples" / "hardware_session.py"


def _run(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, str(SCRIPT), *args], env=env, capture_output=True, text=True, timeout=120)


def test_usage_error_exits_2():
    proc = _run("--no-such-option")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr


def test_invalid_envelope_argument_is_a_usage_error():
    proc = _run("--robot-ip", "127.0.0.3", "--tool-axis", "0", "0", "0")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "invalid safety envelope: --tool-axis" in proc.stderr


def test_the_envelope_file_is_the_one_the_platform_gets(tmp_path, monkeypatch, capsys):
    """--envelope FILE: the platform is opened with that file's limits (and --tool-axis in place of its axis); a file
    breaking a limit, of another format, or naming another axis than --tool-axis is a usage error naming the file."""
    sys.path.insert(0, str(ROOT / "examples"))
    import hardware_session as hs

    got = []

    def fake_open_platform(ip, envelope, layout, **kwargs):
        got.append(envelope)
        raise KeyboardInterrupt  # stop before anything else: the envelope is what is checked here

    monkeypatch.setattr(hs, "open_platform", fake_open_platform)
    path = tmp_path / "cell.json"
    path.write_text('{"workspace_min": [0.2, -0.4, 0.02], "workspace_max": [0.8, 0.4, 0.6], "max_tool_tilt": 2.0}')
    assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--envelope", str(path)]) == hs.EXIT_INTERRUPTED
    assert got[-1].workspace_min == (0.2, -0.4, 0.02) and got[-1].workspace_max == (0.8, 0.4, 0.6)
    assert got[-1].max_tool_tilt == 2.0 and got[-1].max_tcp_speed == 0.1  # a field left out keeps its default
    assert got[-1].tool_reference_axis == (0.0, 0.0, -1.0)
    assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--tool-axis", "1", "0", "0"]) == hs.EXIT_INTERRUPTED
    assert got[-1].tool_reference_axis == (1.0, 0.0, 0.0) and got[-1].workspace_min == (-0.5, -0.5, 0.05)
    capsys.readouterr()
    n_opened = len(got)
    for text, says in (('{"max_tool_tilt": 4.0}', "max_tool_tilt must be"), ("max_tool_tilt = 1", "not a JSON file"),
                       ('{"max_tool_tlt": 1.0}', "did you mean 'max_tool_tilt'")):
        path.write_text(text)
        assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--envelope", str(path)]) == hs.EXIT_USAGE
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err and str(path) in err and "Traceback" not in err
    path.write_text('{"tool_reference_axis": [0, 0, -1]}')
    assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--envelope", str(path),
                    "--tool-axis", "1", "0", "0"]) == hs.EXIT_USAGE
    assert "give the axis in one place" in capsys.readouterr().err
    path.write_text('{"tool_reference_axis": [0, 0, -2]}')  # the same direction, another length: no conflict
    assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--envelope", str(path),
                    "--tool-axis", "0", "0", "-1"]) == hs.EXIT_INTERRUPTED
    path.write_text('{"max_tool_tilt": 2.0}')  # a file that names no axis takes --tool-axis's (review)
    assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--envelope", str(path),
                    "--tool-axis", "0", "1", "0"]) == hs.EXIT_INTERRUPTED
    assert got[-1].tool_reference_axis == (0.0, 1.0, 0.0) and got[-1].max_tool_tilt == 2.0
    assert hs.main(["--robot-ip", "x", "--out", str(tmp_path / "s"), "--envelope", str(tmp_path / "none.json")]) == hs.EXIT_USAGE
    assert "none.json" in capsys.readouterr().err
    assert len(got) == n_opened + 2  # no refused envelope reached the platform


@pytest.mark.skipif(importlib.util.find_spec("rtde_receive") is None, reason='needs the hw extra (pip install -e ".[hw]")')
def test_no_robot_reachable_exits_3_with_one_line():
    # 127.0.0.3: loopback, where nothing listens (the fake RTDE server binds 127.0.0.1 only)
    proc = _run("--robot-ip", "127.0.0.3", "--out", "unused")
    assert proc.returncode == 3, proc.stderr
    err = proc.stderr.strip()
    assert err.count("\n") == 0 and "no robot reachable at 127.0.0.3" in err and "Traceback" not in err


@pytest.mark.skipif(importlib.util.find_spec("rtde_receive") is None or importlib.util.find_spec("usb") is None,
                    reason='needs the hw extra (pip install -e ".[hw]")')
@pytest.mark.parametrize("interrupt_at", [None, 2])
def test_a_session_on_the_test_doubles_and_ctrl_c_in_it(tmp_path, capsys, interrupt_at):
    """main(control_factory=, usb_backend=) runs on the fakes, as hardware_exploration's does; Ctrl-C during the third
    whisk ends with one line, status 130, the two whisks before it kept."""
    import numpy as np

    sys.path.insert(0, str(ROOT / "examples"))
    import hardware_session as hs

    from whisker_io.hw.usb_array import FrameLayout
    from whisker_io.records.recording import replay
    from whisker_io.testing.fake_rtde_server import FakeControlInterface, FakeServerError, fake_rtde_server
    from whisker_io.testing.fake_usb_backend import FakeUSBBackend

    def whisk(k):
        if k == interrupt_at:
            raise KeyboardInterrupt
        s = np.zeros((2000, 18, 3))
        s[:, :, 0] = np.linspace(-0.8727, 0.8727, 2000)[:, None]
        return s

    out = tmp_path / "session"
    try:
        with fake_rtde_server("stream"):
            rc = hs.main(["--robot-ip", "127.0.0.1", "--out", str(out), "--nx", "2", "--nz", "2"],
                         control_factory=lambda host: FakeControlInterface(),
                         usb_backend=FakeUSBBackend(FrameLayout(), source=whisk))
    except FakeServerError as exc:
        pytest.skip(f"cannot run the fake RTDE server on port 30004: {exc}")
    captured = capsys.readouterr()
    if interrupt_at is None:
        assert rc == hs.EXIT_OK and "4 whisks recorded" in captured.out
        assert len(list(replay(out))) == 4
    else:
        assert rc == hs.EXIT_INTERRUPTED and "Traceback" not in captured.err
        lines = [ln for ln in captured.err.splitlines() if "exploring:" not in ln and ln.strip()]  # the progress bar
        assert lines == [f"hardware_session: interrupted after 2 whisks, kept in {out}/"]
        assert len(list(replay(out))) == 2


def test_ctrl_c_before_the_session_is_one_line_and_130(capsys, monkeypatch):
    sys.path.insert(0, str(ROOT / "examples"))
    import hardware_session as hs

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(hs, "envelope_from_options", interrupted)
    assert hs.main(["--robot-ip", "127.0.0.3"]) == hs.EXIT_INTERRUPTED
    assert capsys.readouterr().err.strip() == "hardware_session: interrupted"
