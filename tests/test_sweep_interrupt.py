"""Ctrl-C during a sweep: one line, exit 130, no worker tracebacks, resumable (issue 25).

A terminal's Ctrl-C sends SIGINT to the whole foreground process group - the ``cansim``
process and the local cluster's worker processes alike. The test starts ``cansim sweep``
in its own process group, waits (bounded) until a task has been recorded, and signals
the group as a terminal would.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from extras import needs

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent

pytestmark = [pytest.mark.skipif(not hasattr(os, "killpg"), reason="process groups are POSIX"), needs("distributed", "sweep")]


def _wait_for(condition, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"no {what} within {timeout_s:.0f} s")
        time.sleep(0.05)  # polling another process's progress, not a timing assumption


def test_ctrl_c_during_a_sweep_prints_one_line_and_no_worker_traceback(tmp_path):
    spec = tmp_path / "slow.toml"
    spec.write_text('experiment = "sweep_fixtures:slow"\nmetrics = ["value"]\nn_seeds = 30\n'
                    '[grid]\na = [1, 2]\nsleep_s = [0.5]\n')
    out = tmp_path / "out"
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), str(TESTS), os.environ.get("PYTHONPATH", "")])))
    proc = subprocess.Popen([sys.executable, "-m", "cansim", "sweep", str(spec), "--out", str(out), "--workers", "2",
                             "--no-progress"], cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        parts = out / "parts"
        # a finished part (a part being written is a temporary file until it is whole)
        _wait_for(lambda: proc.poll() is not None or (parts.is_dir() and any(parts.glob("*.parquet"))), 120, "recorded task")
        assert proc.poll() is None, f"the sweep ended before the interrupt:\n{proc.stderr.read()}"
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert lines == ["cansim sweep: interrupted; run the same command again to resume"], lines
    recorded = list((out / "parts").iterdir())
    assert all(p.suffix == ".parquet" for p in recorded), recorded  # no half-written part left behind
    assert 1 <= len(recorded) < 60  # the finished tasks are kept for the resume, the rest were not run
