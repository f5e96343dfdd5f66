"""The installed ``cansim`` command, run as a user runs it (the studies' quick-mode tests)."""

from __future__ import annotations

import os


def run_cansim(*args: str, cwd=None, timeout: float = 1800.0):
    """Run the installed ``cansim`` entry point (the console script next to this Python) as a subprocess.

    The studies' quick modes are tested through it, as a user runs them (issue 25).
    """
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    script = Path(sys.executable).with_name("cansim")
    exe = [str(script)] if script.exists() else [shutil.which("cansim") or "cansim"]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([*exe, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
