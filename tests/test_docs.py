"""The documentation builds with warnings as errors, and its tutorials run.

The build is the documented command ``python -m sphinx -W --keep-going -b html docs
docs/_build/html`` (here into a temporary directory). Each tutorial page's
``.. code-block:: python`` blocks run in order in one fresh interpreter, as a reader
following the page would run them.
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
TUTORIALS = sorted((DOCS / "tutorials").glob("*.rst"))
_HAVE_SPHINX = all(importlib.util.find_spec(m) is not None for m in ("sphinx", "numpydoc", "furo"))
_BLOCK = re.compile(r"^\.\. code-block:: python[ \t]*\n((?:[ \t]*\n|[ \t]+\S.*\n)+)", re.M)


def rst_python_blocks(text: str) -> list[str]:
    """Bodies of the ``.. code-block:: python`` directives of a reST text, dedented."""
    return [textwrap.dedent(m.group(1)).strip("\n") + "\n" for m in _BLOCK.finditer(text)]


def _env() -> dict[str, str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    return env


def test_block_extraction():
    text = "x\n\n.. code-block:: python\n\n   a = 1\n\n   b = 2\n\nnot code\n\n.. code-block:: bash\n\n   ls\n"
    assert rst_python_blocks(text) == ["a = 1\n\nb = 2\n"]


def test_every_tutorial_has_code():
    assert TUTORIALS, "docs/tutorials/ is empty"
    for page in TUTORIALS:
        assert rst_python_blocks(page.read_text(encoding="utf-8")), f"{page.name} has no python block"


@pytest.mark.slow  # runs whole tutorials (fast loop <= 4 min)
@pytest.mark.parametrize("page", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_runs_as_written(page, tmp_path):
    code = "\n".join(rst_python_blocks(page.read_text(encoding="utf-8")))
    script = tmp_path / f"{page.stem}.py"
    script.write_text(code, encoding="utf-8")
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_env(),
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"{page.name} failed:\n{proc.stderr[-3000:]}"


@pytest.mark.slow
@pytest.mark.skipif(not _HAVE_SPHINX, reason='the docs build needs the docs extra: pip install -e ".[docs]"')
def test_docs_build_with_warnings_as_errors(tmp_path):
    out = tmp_path / "html"
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
           "-d", str(tmp_path / "doctrees"), str(DOCS), str(out)]
    proc = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, f"sphinx failed:\n{proc.stderr[-5000:]}"
    assert (out / "index.html").is_file()
    api = {p.name for p in (out / "api").glob("*.html")}
    assert {"cansim.html", "maps.html", "whisker_io.html"} <= api  # the reference covers all three packages
    assert "cansim.population.html" in api or any(n.startswith("cansim.") for n in api - {"cansim.html"})
