"""End-to-end outcomes of the examples (run small, assert what they claim)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_ring_attractor_re_anchors_and_beats_dead_reckoning(tmp_path):
    ring = _load("ring_attractor")
    res = ring.run(steps=600, seed=3)
    late = slice(300, None)
    err_ring = np.abs(ring.wrap_deg(res["decoded"] - res["true"]))[late]
    err_dr = np.abs(ring.wrap_deg(res["dead_reckoning"] - res["true"]))[late]
    assert len(res["anchors"]) > 0
    assert err_ring.mean() < 10.0
    assert err_ring.mean() < 0.25 * err_dr.mean()
    assert ring.main(["--steps", "200", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "ring_attractor.png").stat().st_size > 10_000


def test_record_sim_session_takes_a_users_mesh_and_says_when_nothing_touched(tmp_path, monkeypatch, capsys):
    """--object took registered names only; a raster that touched nothing said '0 contacts' and nothing more."""
    import sys

    import trimesh

    rec = _load("record_sim_session")
    cup = trimesh.creation.cylinder(radius=60.0, height=200.0)  # millimetres
    cup.export(tmp_path / "cup.stl")
    monkeypatch.setattr(sys, "argv", ["record_sim_session.py", "--object", str(tmp_path / "cup.stl"), "--scale-to-m",
                                      "0.2", "--nx", "2", "--nz", "2", "--out", str(tmp_path / "s"), "--no-progress"])
    rec.main()
    out, err = capsys.readouterr()
    assert "4 whisks recorded" in out and "replay identical: True" in out
    monkeypatch.setattr(sys, "argv", ["record_sim_session.py", "--object", str(tmp_path / "cup.stl"), "--scale-to-m",
                                      "0.2", "--distance", "0.6", "--nx", "2", "--nz", "2", "--out", str(tmp_path / "far"),
                                      "--no-progress"])
    rec.main()
    out, err = capsys.readouterr()
    assert "0 contacts detected" in out and "warning: no whisker touched" in err



def test_record_sim_session_run_twice_goes_on_and_a_raster_outside_the_workspace_is_a_usage_error(tmp_path, monkeypatch,
                                                                                                      capsys):
    """Run twice into one folder, the second run ended in a traceback (the simulated arm's clock starts at 0 again);
    --distance 0.19 too (the raster leaves the workspace)."""
    import sys

    from whisker_io.records.recording import replay

    rec = _load("record_sim_session")
    argv = ["record_sim_session.py", "--nx", "2", "--nz", "1", "--out", str(tmp_path / "s"), "--no-progress"]
    for run in (1, 2):
        monkeypatch.setattr(sys, "argv", argv)
        rec.main()
        out = capsys.readouterr().out
        assert "2 whisks recorded" in out and "replay identical: True" in out  # this run's whisks, not the session's
    times = [c.entry.time_s for c in replay(tmp_path / "s")]
    assert len(times) == 4 and times == sorted(times) and times[2] > times[1]
    monkeypatch.setattr(sys, "argv", argv[:-3] + ["--distance", "0.19", "--out", str(tmp_path / "near")])
    with pytest.raises(SystemExit) as exc:
        rec.main()
    assert exc.value.code == 2 and "leaves the arm's workspace" in capsys.readouterr().err
    assert not (tmp_path / "near").exists()


def test_record_sim_session_ctrl_c_is_one_line_and_keeps_the_whisks(tmp_path, monkeypatch, capsys):
    import sys

    from whisker_io.records.recording import replay

    rec = _load("record_sim_session")
    real = rec.explore

    def explore_then_interrupt(arm, array, recorder, targets, **kw):
        real(arm, array, recorder, targets[:2], **kw)
        raise KeyboardInterrupt

    monkeypatch.setattr(rec, "explore", explore_then_interrupt)
    monkeypatch.setattr(sys, "argv", ["record_sim_session.py", "--nx", "2", "--nz", "2", "--out", str(tmp_path / "s"),
                                      "--no-progress"])
    with pytest.raises(SystemExit) as exc:
        rec.main()
    err = capsys.readouterr().err
    assert exc.value.code == 130 and "Traceback" not in err
    assert f"interrupted after 2 whisks, kept in {tmp_path / 's'}/" in err
    assert len(list(replay(tmp_path / "s"))) == 2


def test_record_sim_session_ctrl_c_before_the_whisking_is_one_line(tmp_path, monkeypatch, capsys):
    import sys

    rec = _load("record_sim_session")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt  # while the object loads

    monkeypatch.setattr(rec, "resolve_object", interrupted)
    monkeypatch.setattr(sys, "argv", ["record_sim_session.py", "--out", str(tmp_path / "s")])
    with pytest.raises(SystemExit) as exc:
        rec.main()
    assert exc.value.code == 130 and capsys.readouterr().err.strip() == "record_sim_session: interrupted"
