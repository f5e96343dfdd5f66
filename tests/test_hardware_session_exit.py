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
    assert proc.stderr.strip().count("\n") == 0 and "invalid --tool-axis" in proc.stderr


@pytest.mark.skipif(importlib.util.find_spec("rtde_receive") is None, reason='needs the hw extra (pip install -e ".[hw]")')
def test_no_robot_reachable_exits_3_with_one_line():
    # 127.0.0.3: loopback, where nothing listens (the fake RTDE server binds 127.0.0.1 only)
    proc = _run("--robot-ip", "127.0.0.3", "--out", "unused")
    assert proc.returncode == 3, proc.stderr
    err = proc.stderr.strip()
    assert err.count("\n") == 0 and "no robot reachable at 127.0.0.3" in err and "Traceback" not in err
