"""A study runs from an installed wheel, with no checkout (issue 21).

Builds the wheel of this checkout, installs it alone (``--no-deps``) into a fresh
folder, and runs ``python -m cansim study ch4 --quick`` from another folder with only
that install on the path (the dependencies come from the test's environment): the
studies are modules of the package, not scripts of the source tree.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wheel_site(tmp_path_factory) -> Path:
    # build from a copy, so that setuptools' build/ folder is not left in the checkout
    src = tmp_path_factory.mktemp("src") / "cansim"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "dist", "*.egg-info", ".hypothesis", "__pycache__", "_build", ".benchmarks", "out"))
    dist = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(src)],
                   check=True, capture_output=True, text=True)
    wheels = list(dist.glob("cansim-*.whl"))
    assert len(wheels) == 1
    site = tmp_path_factory.mktemp("site")
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), str(wheels[0])],
                   check=True, capture_output=True, text=True)
    return site


def _run(site: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(site), "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


def test_the_wheel_holds_the_studies_and_no_examples(wheel_site):
    assert (wheel_site / "cansim" / "studies" / "ch5_object_maps.py").is_file()
    assert (wheel_site / "cansim" / "tools" / "cli.py").is_file()
    assert not (wheel_site / "examples").exists()


def test_a_study_runs_from_the_installed_wheel(wheel_site, tmp_path):
    where = _run(wheel_site, tmp_path, "-c", "import cansim.studies.ch4_radial_distance as m; print(m.__file__)")
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(wheel_site)  # the wheel's copy, not the checkout's
    out = tmp_path / "out"
    done = _run(wheel_site, tmp_path, "-m", "cansim", "study", "ch4", "--quick", "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    assert (out / "radial_results.csv").stat().st_size > 0
